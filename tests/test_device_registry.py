"""The device registry (issue 40 item 1): every shipped device is a spec by name, and the tools
read the spec, not the name.

References: the preset and library tables of their own modules (what must be registered), the
energy balance of each device (input = output + losses + stores, closed by the stepper and
partitioned by the device's named ledger), and the former device classes' behaviour kept by
the golden circuit hashes (``tests/test_preset_circuit_golden.py``)."""

from __future__ import annotations

import numpy as np
import pytest

from afo_mj.circuits import library
from afo_mj.circuits.device import CircuitDevice
from afo_mj.circuits.device_spec import DeviceSpec
from afo_mj.devices import hafo, valve_afo
from afo_mj.devices.registry import (ALIASES, DeviceEntry, device_names, device_spec,
                                     register_device, unregister_device)
from afo_mj.experiments.bench_replay import BenchReplay
from afo_mj.hydraulics.params import ParameterError


def test_every_shipped_device_is_registered_once_and_aliases_resolve():
    shipped = list(hafo.PRESETS) + list(valve_afo.VALVE_PRESETS) + list(library.LIBRARY)
    assert sorted(device_names()) == sorted(shipped)
    assert device_spec("hafo_prototype").params == hafo.HAFO
    assert set(ALIASES.values()) <= set(device_names())
    with pytest.raises(ParameterError, match=r"device.preset = 'hafo_prototyp' is not a "
                                             r"registered device \(did you mean "
                                             r"'hafo_prototype'\?\); allowed: hafo, "):
        device_spec("hafo_prototyp")
    with pytest.raises(ParameterError, match="already registered"):
        register_device(DeviceEntry("hafo", lambda ov: device_spec("hafo")))


def _imposed(n=300, dt=1e-3):
    t = np.arange(n) * dt
    th = 0.15 * np.sin(2 * np.pi * 1.5 * t)
    return th, 0.15 * 2 * np.pi * 1.5 * np.cos(2 * np.pi * 1.5 * t)


@pytest.mark.parametrize("name", device_names())
def test_every_device_runs_imposed_and_its_ledger_closes_and_partitions(name):
    """Each registered device replays an imposed ankle motion under a torque reference (its
    open-loop command where it has no torque controller); its energy balance closes and its
    named ledger is a partition of the component ledger (every loss counted once)."""
    spec = device_spec(name)
    th, thd = _imposed()
    open_loop = not spec.torque_controlled
    dev = CircuitDevice(spec, torque_fn=lambda t, q, w: 0.0, open_loop=open_loop)
    cmd = np.full(len(th), 2.0 if open_loop else -10.0)     # V, or N·m of plantarflexion
    log = dev.run_imposed(cmd, th, thd, substeps=2)
    assert np.all(np.isfinite(log["torque_nm"]))
    led = dev.ledger(0)
    assert abs(led["balance_error_rel"]) < 1e-6
    comp = dev.component_ledger(0)
    assert sum(led["losses_j"].values()) == pytest.approx(sum(comp["losses_j"].values()),
                                                          rel=1e-12, abs=1e-12)
    assert sum(led["stored_change_j"].values()) == pytest.approx(
        sum(comp["stored_change_j"].values()), rel=1e-12, abs=1e-12)
    if spec.ledger is not None:
        assert set(led["losses_j"]) == set(spec.ledger.losses)
        assert led["hydraulic_j"] is not None
    if spec.masses is not None:
        assert dev.mass_total_kg == pytest.approx(sum(m.mass_kg for m in spec.masses
                                                      if m.site != "off_body"))


@pytest.mark.parametrize("name", device_names())
def test_every_device_replays_a_record_by_its_spec(name):
    """The bench replay takes any registered device: the record's command is the spec's first
    command channel; every output channel the spec offers comes back finite."""
    rep = BenchReplay(name)
    assert rep.spec.name == name and rep.commands == device_spec(name).commands
    t = np.arange(200) * 1e-3
    th, _ = _imposed(200)
    cmd = rep.commands[0]
    u = {"motor_voltage_v": 2.0, "valve_command": 0.1, "commanded_torque_nm": -5.0}[cmd]
    out = rep.simulate(t, {"ankle_angle_rad": th, cmd: np.full(200, u)})
    assert set(out) == set(rep.outputs) and rep.outputs
    for ch, v in out.items():
        assert v.shape == (200,) and np.all(np.isfinite(v)), ch


def test_a_device_registered_by_a_user_is_a_device_for_every_tool():
    """One entry (a library circuit renamed, with a longer hose) is enough for the replay and
    the coupled device; removed again, its name is refused."""
    def make(overrides=None):
        ov = {"components": {"hose_a": {"kind": "hose", "params": {"length_m": 1.5}}}}
        return DeviceSpec.from_circuit(library.lab_bench(ov), name="my_rig")
    register_device(DeviceEntry("my_rig", make, "a user's bench"))
    try:
        rep = BenchReplay("my_rig")
        assert rep.commands == ("motor_voltage_v",) and rep.described
        assert rep.value("hose_a.length") == pytest.approx(1.5)
        assert BenchReplay("lab_bench").value("hose_a.length") == pytest.approx(0.5)
        dev = CircuitDevice(device_spec("my_rig"), torque_fn=lambda t, q, w: 1.0,
                            open_loop=True)
        assert dev.spec.name == "my_rig" and dev.mass_total_kg is None
    finally:
        unregister_device("my_rig")
    with pytest.raises(ParameterError, match="'my_rig' is not a registered device"):
        device_spec("my_rig")


def test_open_loop_is_refused_where_the_device_has_no_open_loop_command():
    spec = device_spec("pump_accumulator")           # a torque controller, no voltage input
    assert spec.commands == ("commanded_torque_nm",)
    with pytest.raises(Exception, match="takes no open-loop command"):
        CircuitDevice(spec, torque_fn=lambda t, q, w: 0.0, open_loop=True)
    with pytest.raises(Exception, match="open_loop needs a torque_fn"):
        CircuitDevice(device_spec("hafo"), open_loop=True)


def test_the_hafo_open_loop_and_the_valve_switch_follow_the_spec():
    """``mode="voltage"`` of the HAFO steps its open-loop circuit; the valve circuits hand
    the valve to the command through their switch parameter."""
    h = hafo.HafoDevice(hafo.HAFO, mode="voltage", torque_fn=lambda t, q, w: 1.0)
    assert h.cc.circuit.controller.kind == "open_loop"
    v = valve_afo.ValveAfoDevice(valve_afo.VALVE_PRESETS["valve"], mode="valve_command",
                                 torque_fn=lambda t, q, w: 0.1)
    assert v.P[0, v.cc.param_labels.index("controller.valve_command_on")] == 1.0
    v2 = valve_afo.ValveAfoDevice(valve_afo.VALVE_PRESETS["valve"])
    assert v2.P[0, v2.cc.param_labels.index("controller.valve_command_on")] == 0.0


def test_a_scenario_names_a_library_circuit_through_its_circuit_table(tmp_path):
    from afo_mj.scenarios.device_scenario import device_params
    from afo_mj.scenarios.walk_scenario import ScenarioError
    with pytest.raises(ScenarioError, match=r"'lab_bench' is a library circuit; allowed: "
                                            r"\[circuit\] library = 'lab_bench'"):
        device_params({"preset": "lab_bench"}, "s.toml")
    preset, params, _ = device_params({"preset": "hafo_prototype"}, "s.toml")
    assert params == hafo.HAFO


def test_a_source_is_a_device_name_or_the_device_a_scenario_wears():
    """``device_source`` (schematic, export-fmu): names and scenario files of every sort give
    the spec the tools would build; what wears no circuit is refused naming why."""
    from pathlib import Path

    from afo_mj.scenarios.device_source import device_source
    from afo_mj.scenarios.walk_scenario import ScenarioError
    root = Path(__file__).resolve().parents[1] / "scenarios"
    spec, origin = device_source("digital")
    assert spec.params == valve_afo.VALVE_PRESETS["digital"] and origin == "digital"
    spec, _ = device_source("hafo", ["device.params.hose.length_m=2.0"])
    assert spec.params.hose.length_m == 2.0
    spec, _ = device_source(str(root / "gait_assist_hafo.toml"))
    assert spec.name == "hafo_gait"
    spec, _ = device_source(str(root / "bench_hafo.toml"))
    assert spec.params == hafo.HAFO
    spec, _ = device_source(str(root / "gait_lab_bench.toml"))
    assert spec.params is None and spec.circuit.name
    spec, _ = device_source(str(root / "calibration" / "lab_rig.toml"))
    assert spec.params is None and spec.commands
    with pytest.raises(ScenarioError, match="wears no device"):
        device_source(str(root / "walk_healthy.toml"))
    with pytest.raises(ScenarioError, match="'ideal' is not a circuit"):
        device_source(str(root / "gait_muscle_ideal_zhang.toml"))
    with pytest.raises(ScenarioError, match="is not a registered device"):
        device_source("no_such_device")
    with pytest.raises(ScenarioError, match="allowed: device.params.NAME=VALUE"):
        device_source("hafo", ["gait.strides=3"])


def test_published_figures_come_with_the_device_that_was_published():
    """The HAFO prototype's published 65 N·m stall and 105 deg/s no-load speed (facts.md) are
    what its presets are compared with; a valve circuit, whose parameter class extends the
    HAFO's, is compared with nothing (it was compared with the HAFO's figures when the bench
    asked the parameter class)."""
    from afo_mj.experiments.bench_run import published_figures
    from afo_mj.experiments.hafo_bench import torque_velocity
    from afo_mj.scenarios.bench_protocols import BenchError
    assert published_figures(device_spec("hafo")) == {"stall_torque_nm": 65.0,
                                                      "no_load_speed_deg_s": 105.0}
    for name in valve_afo.VALVE_PRESETS:
        assert published_figures(device_spec(name)) is None
    assert published_figures(device_spec("lab_bench")) is None
    with pytest.raises(BenchError, match="allowed: a PumpAnkleParams"):
        torque_velocity(valve_afo.VALVE_PRESETS["valve"])
