"""The environment's mode="device" (issue 40): the scenario's own device, any HAFO or valve
preset or a described circuit, commanded by the action through its controller's torque
reference. On the HAFO it is the special case mode="hafo" bit for bit (the same device,
built the way ``afo-mj run`` builds a condition); a valve preset and described circuits
deliver about their command in stance; a scenario without a device, the ideal device and an
open-loop circuit are refused by name; the muscle walker wears it too."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from afo_mj.devices.registry import device_names
from afo_mj.experiments import walk_env as we

ROOT = Path(__file__).resolve().parents[1]
SC = ROOT / "scenarios"
SHORT = ["gait.strides=2", "gait.analyse_strides=[1, 2]"]
R_TAU = we.OBSERVATION_NAMES.index("right_ankle_device_torque_nm")
R_STANCE = we.OBSERVATION_NAMES.index("right_stance")


def test_device_mode_on_the_hafo_scenario_is_the_hafo_mode():
    """gait_assist_hafo.toml worn on both sides (as mode="hafo" wears its HAFO) with mode=
    "device": the same commands give equal observations, rewards and device states to
    mode="hafo" with the scenario's preset, step after step."""
    sc = str(SC / "gait_assist_hafo.toml")
    dev = we.AnkleAssistEnv(sc, mode="device",
                            overrides=SHORT + ['device.sides=["right", "left"]'])
    hafo = we.AnkleAssistEnv(sc, mode="hafo", hafo_preset="hafo_gait", overrides=SHORT)
    assert dev.observation_names == hafo.observation_names
    o1, _ = dev.reset(seed=0)
    o2, _ = hafo.reset(seed=0)
    np.testing.assert_array_equal(o1, o2)
    rng = np.random.default_rng(3)
    for _ in range(60):
        a = rng.uniform(-20.0, 10.0, 2)
        o1, r1, t1, u1, i1 = dev.step(a)
        o2, r2, t2, u2, i2 = hafo.step(a)
        np.testing.assert_array_equal(o1, o2)
        assert (t1, u1) == (t2, u2)
        np.testing.assert_array_equal(i1["device_delivered_torque_nm"],
                                      i2["device_delivered_torque_nm"])
    np.testing.assert_array_equal(dev.device.Y, hafo.device.Y)
    np.testing.assert_array_equal(dev.walk.record().qpos, hafo.walk.record().qpos)
    assert dev.walk.phys.body_mass_kg == hafo.walk.phys.body_mass_kg
    # the one difference: the electrical term books the energy drawn from the ledger
    led = [dev.device.ledger(k)["input_drawn_j"] for k in range(2)]
    assert all(x > 0.0 for x in led) and dev.last["energy"] >= 0.0


def _stance_delivery(env, command, steps):
    obs, _ = env.reset(seed=0)
    out = []
    for _ in range(steps):
        obs, r, term, trunc, info = env.step(np.array([command, 0.0]))
        assert np.isfinite(r) and not term
        assert env.observation_space.contains(obs)
        assert info["device_delivered_torque_nm"][0] == obs[R_TAU]
        if obs[R_STANCE] > 0.5:
            out.append(obs[R_TAU])
    return np.array(out), obs, info


def test_valve_preset_delivers_its_command_in_stance():
    """gait_assist_valve.toml (the servo-valve AFO on the right ankle): 300 control steps
    (3 s) of a -15 N·m command; the command reaches its controller, the delivered torque in
    stance is a plantarflexion torque of about that size, its states are observed by name,
    its worn masses are on the body and its ledger closes."""
    env = we.AnkleAssistEnv(str(SC / "gait_assist_valve.toml"), mode="device",
                            overrides=SHORT)
    tau, obs, info = _stance_delivery(env, -15.0, 300)
    d = env.device
    assert d.sides == ("right",) and np.all(d.W[0, d.k.W_CMD] == -15.0)
    assert info["device_commanded_torque_nm"].tolist() == [-15.0, 0.0]
    assert tau.size > 100 and -20.0 < np.median(tau) < -10.0
    names = env.observation_names
    assert len(obs) == len(names) == len(we.OBSERVATION_NAMES) + d.Y.size
    assert obs[names.index("right_device.rail")] == d.Y[0, d.cc.index("rail")]
    plain = we.AnkleAssistEnv(str(SC / "gait_assist_valve.toml"), overrides=SHORT)
    plain.reset()
    assert d.mass_total_kg > 0.5
    assert env.walk.phys.body_mass_kg == pytest.approx(plain.walk.phys.body_mass_kg
                                                       + d.mass_total_kg)
    led = d.ledger(0)
    assert abs(led["balance_error_rel"]) < 1e-9 and led["input_drawn_j"] > 0.0
    # the device's own log, as afo-mj run keeps it
    assert d.log.n == d.steps > 0


@pytest.mark.parametrize("name", ["gait_lab_bench.toml", "gait_spring_return.toml"])
def test_described_circuit_runs(name):
    """A [circuit] description (the lab bench under the pump_torque law; the spring-return
    circuit): it runs under the action, delivers about a -15 N·m command in stance, is
    observed by its own state names and adds no mass (a description has no worn-mass
    layout)."""
    env = we.AnkleAssistEnv(str(SC / name), mode="device", overrides=SHORT)
    tau, obs, _ = _stance_delivery(env, -15.0, 150)
    d = env.device
    assert env.device_config.circuit is not None
    assert tau.size > 50 and -20.0 < np.median(tau) < -10.0
    assert env.observation_names[len(we.OBSERVATION_NAMES):] == tuple(
        f"right_device.{n}" for n in d.cc.state_names)
    plain = we.AnkleAssistEnv(str(SC / name), overrides=SHORT)
    plain.reset()
    assert env.walk.phys.body_mass_kg == plain.walk.phys.body_mass_kg


def test_what_cannot_be_commanded_is_refused():
    with pytest.raises(ValueError, match="wears no device .*allowed: a device scenario"):
        we.AnkleAssistEnv(str(SC / "walk_healthy.toml"), mode="device", overrides=SHORT)
    with pytest.raises(ValueError, match="device.preset = 'ideal'.*no torque-command input"):
        we.AnkleAssistEnv(str(SC / "gait_muscle_ideal_zhang.toml"), mode="device",
                          overrides=SHORT)
    with pytest.raises(ValueError, match="allowed: 'torque', 'hafo', 'device'"):
        we.AnkleAssistEnv(str(SC / "gait_assist_hafo.toml"), mode="valve")


def test_device_mode_on_the_muscle_walker():
    """gait_assist_hafo.toml on the muscle walker (the reflex set adapted to the HAFO): a few
    control steps with a plantarflexion command; the walker is the muscle stepper, the
    device's masses are on it and the command reaches the device."""
    from afo_mj.gait.muscle_walk import MuscleWalkStepper
    ov = SHORT + ["walker.model=muscle", "walker.reflex_set=adapted/hafo"]
    env = we.AnkleAssistEnv(str(SC / "gait_assist_hafo.toml"), mode="device", overrides=ov)
    env.reset(seed=0)
    for _ in range(20):
        obs, r, term, trunc, info = env.step(np.array([-10.0, 0.0]))
        assert np.isfinite(r) and not term and env.observation_space.contains(obs)
    assert isinstance(env.walk, MuscleWalkStepper)
    d = env.device
    assert np.all(d.W[0, d.k.W_CMD] == -10.0) and d.steps == env.walk.steps == 200
    plain = we.AnkleAssistEnv(str(SC / "gait_assist_hafo.toml"), overrides=ov)
    plain.reset()
    assert env.walk.phys.body_mass_kg == pytest.approx(plain.walk.phys.body_mass_kg
                                                       + d.mass_total_kg)


def _env_case(name: str):
    """The scenario and overrides that wear registered device ``name`` (as
    tests/test_recording_devices.py walks each)."""
    from afo_mj.devices.hafo import PRESETS
    from afo_mj.devices.valve_afo import VALVE_PRESETS
    if name in PRESETS:
        return "gait_assist_hafo.toml", [f"device.preset={name}"]
    if name in VALVE_PRESETS:
        return "gait_assist_valve.toml", [f"device.preset={name}", "device.variants={}"]
    scen = {"lab_bench": "gait_lab_bench.toml", "pump_accumulator": "gait_pump_accumulator.toml",
            "pump_accumulator_gait": "gait_pump_accumulator.toml",
            "spring_return": "gait_spring_return.toml",
            "spring_return_gait": "gait_spring_return.toml"}[name]
    return scen, [f'circuit.library="{name}"']


@pytest.mark.parametrize("name", device_names())
def test_every_registered_device_is_commanded_by_the_action(name):
    """Issue 40: the registry enumerated through the environment. Each device, worn as its
    walking scenario wears it, takes 0.1 s of a -10 N·m action through its controller; the
    observation stays in its space and the device's energy ledger closes."""
    scen, ov = _env_case(name)
    env = we.AnkleAssistEnv(str(SC / scen), mode="device", overrides=SHORT + ov)
    env.reset(seed=0)
    for _ in range(10):
        obs, r, _term, _trunc, info = env.step(np.array([-10.0, -10.0]))
        assert np.isfinite(r) and env.observation_space.contains(obs)
        assert np.all(np.isfinite(info["device_delivered_torque_nm"]))
    led = env.device.ledger(0)
    assert abs(led["balance_error_rel"]) < 1e-6 and led["input_drawn_j"] >= 0.0


def test_an_open_loop_circuit_takes_its_motor_voltage_as_the_action():
    """Issue 40: the environment's command comes from the device's spec. The lab bench under
    its own open-loop controller has no torque reference; the action is then the motor voltage
    (V), bounded by its ideal 24 V supply (the description's options.supply_voltage_v), and
    the voltage the motor gets each step is the action (clipped to the supply)."""
    env = we.AnkleAssistEnv(str(SC / "gait_lab_bench.toml"), mode="device",
                            overrides=SHORT + ['circuit.controller.kind="open_loop"',
                                               'device.conditions=["transparent"]'])
    assert env.command_channel == "motor_voltage_v" and env.action_limit == 24.0
    assert env.action_space.high[0] == 24.0
    env.reset(seed=0)
    for u in (6.0, -4.0, 30.0):
        for _ in range(3):
            obs, r, _t, _u, _i = env.step(np.array([u, 0.0]))
            assert np.isfinite(r) and env.observation_space.contains(obs)
    L = env.device.log.arrays()
    v = L["actuated_input"][:, 0]
    n = env.substeps * 3
    np.testing.assert_array_equal(v[:n], 6.0)
    np.testing.assert_array_equal(v[n:2 * n], -4.0)
    np.testing.assert_array_equal(v[2 * n:3 * n], 24.0)      # 30 V clipped to the supply
    assert abs(env.device.ledger(0)["balance_error_rel"]) < 1e-6
    # a torque bound means nothing for a voltage action: refused, not ignored
    with pytest.raises(ValueError, match="max_torque_nm = 40.0 with a device that takes no "
                                         "torque command"):
        we.AnkleAssistEnv(str(SC / "gait_lab_bench.toml"), mode="device", max_torque_nm=40.0,
                          overrides=SHORT + ['circuit.controller.kind="open_loop"',
                                             'device.conditions=["transparent"]'])
