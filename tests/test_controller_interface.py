"""The human controller interface (issue 39 item 1): a controller declared against
:class:`afo_mj.gait.controller.HumanController` and registered by name is walked by every
entry point from a scenario, stepped by :class:`afo_mj.gait.controller_walk.ControllerWalk`.

* The reflex controller written against the interface
  (:class:`afo_mj.gait.reflex_controller.ReflexController`) walks what the muscle walker's
  dedicated stepper walks, bit for bit, with and without the HAFO circuit worn: the interface
  carries a real controller (muscles, delays, soft limits integrated implicitly, a coupled
  hydraulic device) without losing anything.
* A third controller written only against the interface (``tests/clock_controller.py``: a
  clock-driven torque-profile controller) runs through ``afo-mj run`` of a scenario naming it —
  plain and wearing the HAFO — with nothing in the walks, the loops or the application
  changed for it; its walk's cadence is its clock's (120 / cycle time), an independent figure.
* Registration refuses what it cannot honour, naming it.
"""

from __future__ import annotations

import dataclasses
import json
import sys
from pathlib import Path

import numpy as np
import pytest

from afo_mj.gait import controller as gc
from afo_mj.gait.controller_walk import ControllerWalk
from afo_mj.gait.muscle_walk import load_reflex_set, run_muscle_walk
from afo_mj.gait.reflex_controller import ReflexController, ReflexControllerParams, reflex_setup

sys.path.insert(0, str(Path(__file__).parent))
from clock_controller import NAME, ClockController  # noqa: E402
from cli_helpers import run_cli  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
SET_125 = ROOT / "afo_mj" / "data" / "reflex_params_1.25.json"


@pytest.fixture
def clock_registered():
    gc.register_controller(ClockController)
    yield ClockController
    gc.unregister_controller(NAME)


def _same_walk(muscle_walk, record):
    ra = muscle_walk.record
    for f in ra.array_fields():
        assert np.array_equal(getattr(ra, f), getattr(record, f)), f
    assert ra.events == record.events
    for name, arr in (("excitation", muscle_walk.excitation),
                      ("activation", muscle_walk.activation),
                      ("force_n", muscle_walk.force_n),
                      ("ce_velocity_m_s", muscle_walk.ce_velocity_m_s),
                      ("metabolic_umberger_w", muscle_walk.metabolic_umberger_w),
                      ("metabolic_bhargava_w", muscle_walk.metabolic_bhargava_w)):
        assert np.array_equal(arr, record.signals[name]), name


def test_reflex_controller_through_the_interface_walks_the_muscle_walk_bit_for_bit():
    P = load_reflex_set(SET_125)
    dedicated = run_muscle_walk(params=P, duration_s=2.0)
    c = ReflexController(ReflexControllerParams(gains=tuple(P)), reflex_setup())
    rec = ControllerWalk(c, 2.0).run()
    assert len(rec.time_s) == 2001 and rec.events.fall_time_s is None
    assert len(rec.events.heel_strikes_s[0]) >= 2          # it walked, not stood
    _same_walk(dedicated, rec)


def test_reflex_controller_with_the_hafo_worn_walks_the_muscle_walk_bit_for_bit():
    from afo_mj.experiments.muscle_assistance import Assistance, hafo_device
    P = load_reflex_set(SET_125)
    a = Assistance(kind="hafo")
    dur = 1.5
    dev1 = hafo_device(a, 1e-3, int(dur / 1e-3) + 4)
    dev2 = hafo_device(a, 1e-3, int(dur / 1e-3) + 4)
    worn = tuple(dev1.worn_masses())
    dedicated = run_muscle_walk(params=P, duration_s=dur, worn_masses=worn, device=dev1)
    c = ReflexController(ReflexControllerParams(gains=tuple(P)), reflex_setup())
    rec = ControllerWalk(c, dur, worn_masses=worn, device=dev2).run()
    assert np.abs(rec.device_moment_nm[:, 0]).max() > 1.0    # the device acted
    _same_walk(dedicated, rec)


def test_a_third_controller_runs_from_a_scenario_through_afo_mj_run(tmp_path, clock_registered):
    from afo_mj.gait.reference import load_normative
    sc = tmp_path / "clock.toml"
    sc.write_text(f'name = "clock_walk"\n[walker]\nmodel = "{NAME}"\n[gait]\n'
                  'reference = "winter"\ncondition = "normal"\nstrides = 4\n'
                  'analyse_strides = [2, 4]\n[controller]\nkp_nm_per_rad = 1000.0\n',
                  encoding="utf-8")
    rc, out, err = run_cli(["run", str(sc), "--out", str(tmp_path / "out")])
    assert rc == 0, err
    s = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert s["scenario"]["walker_model"] == NAME
    assert s["scenario"]["controller_effective"]["kp_nm_per_rad"] == 1000.0
    assert s["fell"] is False and s["completed_strides"] >= 4
    # the clock sets the cadence: 120 / Winter's cycle time (1.1396 s at 75 kg, 1.75 m)
    clock = 120.0 / load_normative("winter", "normal").cycle_time_s
    assert s["cadence_steps_per_min"]["mean"] == pytest.approx(clock, rel=0.01)
    assert s["cadence_steps_per_min"]["sd"] < 1.0


def test_a_third_controller_wears_the_hafo_from_a_scenario(clock_registered):
    """The device scenario's own path (afo_mj.app.run.run_scenario, what afo-mj run calls;
    nothing written, no figures) with walker.model naming the registered controller."""
    from afo_mj.app.run import run_scenario
    res = run_scenario(ROOT / "scenarios" / "gait_assist_hafo.toml",
                       overrides=[f"walker.model={NAME}", "gait.strides=3",
                                  "gait.analyse_strides=[2, 3]",
                                  'device.conditions=["no_device", "assist"]'],
                       figures=False)
    s = res.summary.to_json()
    assert s["scenario"]["walker_model"] == NAME
    assist = s["device_conditions"]["assist"]
    # the device's ledger closes (electrical in = every named loss + work out + stored)
    assert abs(s["energy"]["balance_error_rel"]) <= 1e-9
    assert set(s["energy"]["losses_j"]) >= {"motor_copper", "pump_volumetric", "line",
                                           "seal_friction"}
    assert assist["device"]["peak_torque_nm"] > 10.0
    assert s["human_response"]["walker_model"] == NAME
    assert s["human_response"]["rule"] is None


def test_scenario_refuses_an_unregistered_model_and_bad_controller_keys(tmp_path,
                                                                       clock_registered):
    from afo_mj.scenarios.walk_scenario import ScenarioError, load_scenario
    p = tmp_path / "s.toml"
    p.write_text('[walker]\nmodel = "nobody"\n', encoding="utf-8")
    with pytest.raises(ScenarioError, match=r"walker.model.*nobody.*clock_profile_test"):
        load_scenario(p)
    p.write_text(f'[walker]\nmodel = "{NAME}"\n[controller]\nkp_nm_per_radd = 1.0\n',
                 encoding="utf-8")
    with pytest.raises(ScenarioError, match="kp_nm_per_radd"):
        load_scenario(p)
    p.write_text(f'[walker]\nmodel = "{NAME}"\n[controller]\nkp_nm_per_rad = -1.0\n',
                 encoding="utf-8")
    with pytest.raises(ScenarioError, match=r"kp_nm_per_rad.*-1.0.*allowed"):
        load_scenario(p)
    p.write_text(f'[walker]\nmodel = "{NAME}"\nreflex_set = "1.25"\n', encoding="utf-8")
    with pytest.raises(ScenarioError, match="reflex_set"):
        load_scenario(p)


def test_registration_refuses_what_it_cannot_honour(clock_registered):
    class NoStep(gc.HumanController):
        name = "no_step"
    with pytest.raises(gc.ControllerError, match="step"):
        gc.register_controller(NoStep)

    class Builtin(ClockController):
        name = "muscle"
    with pytest.raises(gc.ControllerError, match="built in"):
        gc.register_controller(Builtin)

    class Taken(ClockController):
        pass
    with pytest.raises(gc.ControllerError, match="already registered"):
        gc.register_controller(Taken)

    class BadActuator(ClockController):
        name = "bad_actuator"
        actuators = ("ff", "jetpack")
    with pytest.raises(gc.ControllerError, match="jetpack"):
        gc.register_controller(BadActuator)

    class BadSignal(ClockController):
        name = "bad_signal"
        signals = {"x": ("N", (0,))}
    with pytest.raises(gc.ControllerError, match="signals"):
        gc.register_controller(BadSignal)

    @dataclasses.dataclass
    class Mutable:
        k: float = 1.0

    class MutableParams(ClockController):
        name = "mutable_params"
        Params = Mutable
    with pytest.raises(gc.ControllerError, match="frozen"):
        gc.register_controller(MutableParams)
    with pytest.raises(gc.ControllerError, match="not registered"):
        gc.unregister_controller("nobody")
    assert NAME in gc.controller_names() and "torque" in gc.controller_names()


def test_controller_walk_refuses_bad_arguments():
    c = ReflexController(None, reflex_setup())
    with pytest.raises(ValueError, match="duration_s"):
        ControllerWalk(c, 0.0)
    with pytest.raises(ValueError, match="strides"):
        ControllerWalk(c, 1.0, strides=0)
    with pytest.raises(gc.ControllerError, match="ReflexControllerParams"):
        ReflexController(object(), reflex_setup())


def test_walk_batch_and_the_environment_walk_a_registered_controller(tmp_path,
                                                                     clock_registered):
    """walk_batch's forked workers and the gymnasium environment step the registered
    controller, not the torque walker: their cadence is the clock's."""
    import gymnasium as gym

    import afo_mj.experiments.walk_env  # noqa: F401  (registers the environment)
    from afo_mj.experiments.batch import walk_batch
    from afo_mj.gait.reference import load_normative
    from afo_mj.metrics.gait_metrics import analyse_gait
    from afo_mj.scenarios.walk_scenario import load_scenario
    p = tmp_path / "clock.toml"
    p.write_text(f'[walker]\nmodel = "{NAME}"\n[gait]\nstrides = 4\nanalyse_strides = [2, 4]\n',
                 encoding="utf-8")
    sc = load_scenario(p)
    clock = 120.0 / load_normative("winter", "normal").cycle_time_s
    recs = walk_batch([sc, sc], workers=2)
    for rec in recs:
        s = analyse_gait(rec, sc.load_reference(), sc.analyse_strides).summary
        assert s["cadence_steps_per_min"]["mean"] == pytest.approx(clock, rel=0.01)
    env = gym.make("afo_mj/AnkleAssist-v0", scenario=str(p), mode="torque")
    env.reset(seed=0)
    inner = env.unwrapped
    done, n = False, 0
    while not done and n < 3000:
        _, _, term, trunc, _ = env.step(np.zeros(inner.action_space.shape))
        done, n = term or trunc, n + 1
    hs = inner.walk.events.heel_strikes_s[0]
    assert type(inner.walk).__name__ == "ControllerWalk"
    assert len(hs) >= 3
    assert 120.0 / np.diff(hs[1:]).mean() == pytest.approx(clock, rel=0.01)
