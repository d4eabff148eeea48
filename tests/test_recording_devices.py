"""Recordings of every device: each preset (HAFO and valve families) and each library
circuit walks a short assisted walk and is recorded; the file is read back with rerun's own
reader and must hold every device signal the device's log holds, with the log's values
(issue 38 item 2: valve circuits without an unloading valve crashed with ``KeyError:
'unloading_valve_position'``; described circuits had no ``params``).

The expected entities are derived here from the log's columns and the circuit's states, not
from the recording code: a column the log lacks must not be asked for, a column it has must
be in the file."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

rr = pytest.importorskip("rerun")

from afo_mj.circuits.library import LIBRARY  # noqa: E402
from afo_mj.devices.hafo import PRESETS  # noqa: E402
from afo_mj.devices.registry import device_names  # noqa: E402
from afo_mj.devices.valve_afo import VALVE_PRESETS  # noqa: E402
from afo_mj.outputs.recording import read_recording_index  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
SCN = ROOT / "scenarios"
SHORT = ["gait.strides=2", "gait.analyse_strides=[1, 2]", 'device.conditions=["assist"]']
SIGNAL_RATE_HZ = 500.0                  # the recording's default scalar rate
SIGNAL_TOLERANCE = 2e-3                 # its default thinning tolerance (fraction of a range)
#: the walking scenario each library circuit is worn in (its controller set for walking)
LIBRARY_SCENARIO = {"lab_bench": "gait_lab_bench.toml",
                    "pump_accumulator": "gait_pump_accumulator.toml",
                    "pump_accumulator_gait": "gait_pump_accumulator.toml",
                    "spring_return": "gait_spring_return.toml",
                    "spring_return_gait": "gait_spring_return.toml"}
#: documented display names of two valve-circuit pressure nodes
NODE_NAMES = {"pump_out": "pump", "rail": "supply"}



def _walk_case(name: str):
    """A walking scenario wearing registered device ``name``: a preset on the HAFO's or the
    valve AFO's assistance scenario, a library circuit in its own walking scenario."""
    if name in PRESETS:
        return pytest.param("gait_assist_hafo.toml", [f"device.preset={name}"],
                            id=f"preset-{name}")
    if name in VALVE_PRESETS:
        return pytest.param("gait_assist_valve.toml", [f"device.preset={name}",
                                                       "device.variants={}"],
                            id=f"preset-{name}")
    return pytest.param(LIBRARY_SCENARIO.get(name, "?"), [f'circuit.library="{name}"'],
                        id=f"circuit-{name}")


#: every registered device (issue 40: the registry enumerated through a 2-stride walk)
CASES = [_walk_case(name) for name in device_names()]


def _scalars(path: Path, entity: str) -> tuple[np.ndarray, np.ndarray]:
    """(time_s, values) of one Scalars entity, read with rerun's reader."""
    store = rr.chunk.RrdReader(str(path)).stream().collect()
    ts, vs = [], []
    for ch in store.stream():
        if ch.entity_path.lstrip("/") != entity or ch.is_static:
            continue
        rb = ch.to_record_batch()
        t = rb.column("time").to_numpy()
        ts.append(t.astype("timedelta64[ns]").astype(np.int64) / 1e9 if t.dtype.kind == "m"
                  else np.asarray(t, dtype=float))
        vs.append(np.array([x[0] for x in rb.column("Scalars:scalars").to_pylist()]))
    order = np.argsort(np.concatenate(ts))
    return np.concatenate(ts)[order], np.concatenate(vs)[order]


def _column(dev, L, generic: str):
    """The log column of a generic circuit name (a preset renames some), or None."""
    name = getattr(dev, "log_names", {}).get(generic, generic)
    return name if name in L else None


def test_every_library_circuit_has_a_walking_scenario():
    assert set(LIBRARY) == set(LIBRARY_SCENARIO)
    assert set(device_names()) == set(PRESETS) | set(VALVE_PRESETS) | set(LIBRARY)


@pytest.mark.parametrize("scenario, overrides", CASES)
def test_every_device_is_recorded_with_what_its_log_holds(tmp_path, scenario, overrides):
    from afo_mj.app.run import record_run, run_scenario
    res = run_scenario(SCN / scenario, overrides=SHORT + overrides, figures=False)
    rec, _analysis, dev = res.results["assist"]
    rrd = tmp_path / "dev.rrd"
    info = record_run(res, rrd)
    assert info["path"] == str(rrd) and rrd.stat().st_size > 10_000
    assert [p.name for p in tmp_path.iterdir()] == ["dev.rrd"]       # no temporary left
    idx = read_recording_index(rrd)
    L = dev.log.arrays()
    cc = dev.cc
    circuit = cc.circuit
    step = max(1, int(round(1.0 / (SIGNAL_RATE_HZ * rec.sample_period_s))))
    n = math.ceil(dev.log.n / step)

    def entity(path):
        return f"signals/{path}/right/assist"

    # what the log holds, independently of the recording code
    expected = {"ankle_torque_nm/device_commanded": ("commanded_torque_nm", "N*m"),
                "ankle_torque_nm/device_delivered": ("delivered_torque_nm", "N*m"),
                "fluid_temperature_c": ("oil_temperature_k", "degC"),
                "device_power_w/electrical": (None, "W"),
                "device_power_w/ankle": ("mechanical_power_w", "W"),
                "running_efficiency": (None, "1"),
                "piston_position_mm": (None, "mm"),
                "flow_l_min/cylinder": (None, "L/min")}
    for label, kind in zip(cc.state_names, cc.state_kinds):
        if kind == "pressure":
            expected[f"pressure_bar/{NODE_NAMES.get(label, label)}"] = (
                _column(dev, L, label), "bar (gauge)")
    motor = [c.name for c in circuit.components if c.kind == "motor"]
    pumps = [c.name for c in circuit.components if c.kind in ("pump", "variable_pump")]
    assert motor and pumps
    expected["motor_current_a"] = (_column(dev, L, f"{motor[0]}.current_a"), "A")
    expected["motor_speed_rpm"] = (None, "rpm")
    expected["motor_voltage_v"] = (_column(dev, L, "actuated_input"), "V")
    expected["flow_l_min/pump"] = (None, "L/min")
    expected["device_power_w/hydraulic"] = (None, "W")
    valve = {"valve/position": ("valve_position", "servo.spool", "release.position"),
             "valve/command": ("valve_command", "controller.valve_command"),
             "valve/unloading": ("unloading_valve_position", "unloading.position",
                                 "switching.position")}
    for path, names in valve.items():
        col = next((c for c in (_column(dev, L, g) for g in names) if c is not None), None)
        if col is not None:
            expected[path] = (col, "1")
        else:                       # a valve the circuit lacks is not in the recording
            assert entity(path) not in idx, path
    for path, (col, unit) in expected.items():
        assert entity(path) in idx, f"{path} missing from the recording"
        e = idx[entity(path)]
        assert info["entities"][entity(path)]["samples"] == n, path
        assert 2 <= e["rows"] <= n and e["unit"] == unit, path
    # the values are the log's own, at the recorded times
    t_log = L["time_s"][:, 0]
    for path, (col, unit) in expected.items():
        if col is None:
            continue
        t, v = _scalars(rrd, entity(path))
        ref = L[col][:, 0]
        if unit == "bar (gauge)":
            ref = ref / 1e5
        elif unit == "degC":
            ref = ref - 273.15
        # thinned for display: samples of the log, within the tolerance of every other one
        full_t, full_v = t_log[::step], ref[::step]
        k = np.searchsorted(full_t, t - 1e-9)
        np.testing.assert_allclose(t, full_t[k], atol=1e-9, err_msg=path)
        np.testing.assert_allclose(v, full_v[k], rtol=1e-9, atol=1e-9, err_msg=path)
        err = np.abs(np.interp(full_t, t, v) - full_v).max()
        assert err <= SIGNAL_TOLERANCE * np.ptp(full_v) * (1 + 1e-9) + 1e-9, path
    # the worn orthosis in 3D: one oil column per cylinder chamber on the joint
    (cyl,) = [r.split(".")[0] for r in circuit.nodes[circuit.joint]]
    chambers = [p for p in ("a", "b") if (cyl, p) in circuit.port_node]
    for c in ("a", "b"):
        oil = f"world/assist/body/shank_r/afo/oil_{c}"
        if c in chambers:
            assert idx[oil]["rows"] > 5 and "Cylinders3D:colors" in idx[oil]["components"]
        else:
            assert oil not in idx


def _colours(path: Path, entity: str) -> tuple[np.ndarray, np.ndarray]:
    """(time_s, RGBA uint32 per row) of an entity's time-varying colours, read with rerun's
    reader."""
    store = rr.chunk.RrdReader(str(path)).stream().collect()
    ts, cs = [], []
    for ch in store.stream():
        if ch.entity_path.lstrip("/") != entity or ch.is_static:
            continue
        rb = ch.to_record_batch()
        col = [c for c in rb.schema.names if c.endswith(":colors")][0]
        t = rb.column("time").to_numpy()
        ts.append(t.astype("timedelta64[ns]").astype(np.int64) / 1e9)
        cs.append(np.array([x[0] for x in rb.column(col).to_pylist()], dtype=np.uint64))
    order = np.argsort(np.concatenate(ts))
    return np.concatenate(ts)[order], np.concatenate(cs)[order]


@pytest.mark.parametrize("scenario, overrides", [CASES[0], CASES[len(PRESETS)]])
def test_the_recording_carries_the_circuit_coloured_by_pressure(tmp_path, scenario, overrides):
    """Issue 43 item 1: the worn circuit's schematic is in the recording (every component, every
    node), and each pressure node's colour follows its logged pressure: ordered by the log's
    pressure, the colour's red minus blue never falls (blue empty → red at the relief)."""
    from afo_mj.app.run import record_run, run_scenario
    res = run_scenario(SCN / scenario, overrides=SHORT + overrides, figures=False)
    _rec, _analysis, dev = res.results["assist"]
    rrd = tmp_path / "dev.rrd"
    record_run(res, rrd)
    idx = read_recording_index(rrd)
    circuit = dev.cc.circuit
    root = "schematic/assist"
    assert f"{root}/components" in idx
    for node in circuit.nodes:
        assert f"{root}/nodes/{node}" in idx, node
    L = dev.log.arrays()
    t_log = L["time_s"][:, 0]
    kinds = dict(zip(dev.cc.state_names, dev.cc.state_kinds))
    checked = 0
    for node in circuit.nodes:
        if kinds.get(node) != "pressure":
            continue
        t, rgba = _colours(rrd, f"{root}/nodes/{node}")
        p = L[_column(dev, L, node)][np.searchsorted(t_log, t - 1e-9), 0]
        red, blue = (rgba >> 24) & 0xFF, (rgba >> 8) & 0xFF
        warmth = red.astype(float) - blue.astype(float)
        order = np.argsort(p, kind="stable")
        assert np.all(np.diff(warmth[order]) >= -1.0), node     # rounding of one unit
        checked += 1
    assert checked >= 2
