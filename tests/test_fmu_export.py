"""``afo-mj export-fmu``: the FMI 2.0 co-simulation FMU of a circuit, checked by a real FMI
client (FMPy): its model description validates, its parameters carry units and start values,
and simulated on a recorded joint motion (Winter's ankle angle over one stride) with a torque
command it reproduces the native replay (:meth:`CircuitDevice.run_imposed`) within Hopsan's
golden-trace tolerance, NRMSE <= 1 % per output.

FMPy's ``simulate_fmu`` holds the inputs over each communication step while the native replay
interpolates the recorded samples, a first-order difference in the step (worst output, the
lab bench's line A: 1.02 % at 1 ms, 0.90 % at 0.5 ms, 0.45 % at 0.25 ms): it is compared at
0.5 ms. Driven through FMPy's FMI calls with the inputs' derivatives
(``fmi2SetRealInputDerivatives``) the FMU interpolates as the native replay does and matches
it to rounding at 1 ms."""

from __future__ import annotations

import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

fmpy = pytest.importorskip("fmpy", reason="the FMU tests need FMPy (pip install -e .[test]: "
                                           "fmpy==0.3.32)")
if not (shutil.which("gcc") or shutil.which("cc")):
    pytest.skip("export-fmu compiles the FMU's library: no gcc/cc here", allow_module_level=True)

from fmpy.model_description import read_model_description  # noqa: E402
from fmpy.validation import validate_fmu  # noqa: E402

from afo_mj.app.errors import InvalidInput  # noqa: E402
from afo_mj.app.fmu import export_fmu, scenario_circuit  # noqa: E402
from afo_mj.circuits.device import CircuitDevice  # noqa: E402
from afo_mj.outputs.fmu_runtime import circuit_with  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
SCENARIO = ROOT / "scenarios" / "gait_lab_bench.toml"
STEP_S = 1e-3              # communication step = the replay's sample period
TIMESTEP_S = 5e-4          # internal step: two per 1 ms communication step
HELD_STEP_S = 5e-4         # simulate_fmu's communication step (held inputs)


@pytest.fixture(scope="module")
def lab_fmu(tmp_path_factory):
    out = tmp_path_factory.mktemp("fmu") / "lab_bench.fmu"
    info = export_fmu(str(SCENARIO), out, timestep_s=TIMESTEP_S, step_size_s=STEP_S)
    return out, info


def _gait_inputs(duration_s: float, step_s: float = STEP_S):
    """Winter's ankle angle and its velocity over ``duration_s`` of walking and the gait
    scenario's 20 N·m Zhang plantarflexion assistance as the torque command, sampled at the
    communication step."""
    from afo_mj.control.assistance import zhang_profile
    from afo_mj.gait.reference import load_normative
    ref = load_normative("winter", "normal")
    t = np.arange(int(round(duration_s / step_s)) + 1) * step_s
    phase = t / ref.cycle_time_s
    theta = ref.angles_rad(phase)[:, 2]
    theta_dot = ref.velocities_rad_s(phase)[:, 2]
    table = zhang_profile(20.0, 52.9, 26.2, 9.8)
    cmd = np.interp(np.mod(phase, 1.0), np.linspace(0.0, 1.0, table.shape[0]), table)
    return t, cmd, theta, theta_dot


def _simulate(path, t, cmd, theta, theta_dot, outputs, start_values=None):
    """FMPy's own master: inputs held over each communication step (``t``'s spacing)."""
    sig = np.array(list(zip(t, cmd, theta, theta_dot)),
                   dtype=[("time", float), ("command", float), ("joint_angle", float),
                          ("joint_angular_velocity", float)])
    return fmpy.simulate_fmu(str(path), start_time=0.0, stop_time=float(t[-1]),
                             output_interval=float(t[1] - t[0]), input=sig, output=outputs,
                             start_values=start_values or {})


def _native(circuit, cmd, theta, theta_dot, step_s: float = STEP_S):
    """The native replay: the circuit's own device, the recorded motion interpolated over
    the sub-steps (run_imposed), sample k the state at t_k."""
    dev = CircuitDevice(circuit, timestep_s=min(TIMESTEP_S, step_s))
    return dev.run_imposed(cmd[:-1], theta, theta_dot,
                           substeps=max(1, round(step_s / TIMESTEP_S)))


def _drive_with_derivatives(path, t, cmd, theta, theta_dot, outputs):
    """Step the FMU through FMPy's FMI 2.0 calls, giving each step the inputs' first
    derivatives over it (the samples' slopes; the command held)."""
    from fmpy import extract
    from fmpy.fmi2 import FMU2Slave
    md = read_model_description(str(path))
    assert md.coSimulation.canInterpolateInputs
    vr = {v.name: v.valueReference for v in md.modelVariables}
    ins = [vr["command"], vr["joint_angle"], vr["joint_angular_velocity"]]
    outs = [vr[o] for o in outputs]
    fmu = FMU2Slave(guid=md.guid, unzipDirectory=extract(str(path)),
                    modelIdentifier=md.coSimulation.modelIdentifier, instanceName="drive")
    fmu.instantiate()
    fmu.setupExperiment(startTime=0.0)
    fmu.enterInitializationMode()
    fmu.exitInitializationMode()
    rows = []
    for k in range(len(t) - 1):
        h = t[k + 1] - t[k]
        fmu.setReal(ins, [cmd[k], theta[k], theta_dot[k]])
        fmu.setRealInputDerivatives(ins, [1, 1, 1], [0.0, (theta[k + 1] - theta[k]) / h,
                                                     (theta_dot[k + 1] - theta_dot[k]) / h])
        fmu.doStep(currentCommunicationPoint=t[k], communicationStepSize=h)
        rows.append(fmu.getReal(outs))
    fmu.terminate()
    fmu.freeInstance()
    return {o: np.array(rows)[:, i] for i, o in enumerate(outputs)}


def _nrmse(fmu, native):
    span = float(np.max(native) - np.min(native))
    return float(np.sqrt(np.mean((fmu - native) ** 2))) / span


def test_fmpy_validates_the_fmu(lab_fmu, capsys):
    path, info = lab_fmu
    assert validate_fmu(str(path)) == []
    fmpy.dump(str(path))
    text = capsys.readouterr().out
    assert "Co-Simulation" in text and "linux64" in text
    md = read_model_description(str(path))
    assert md.fmiVersion == "2.0" and md.coSimulation.modelIdentifier == info["model_identifier"]
    causal = {v.name: v.causality for v in md.modelVariables}
    assert [n for n, c in causal.items() if c == "input"] == [
        "command", "joint_angle", "joint_angular_velocity"]
    for name in ("joint_torque", "pressure.line_a", "pressure.line_b", "pressure.chamber_a",
                 "pressure.chamber_b", "motor.current", "bus_voltage"):
        assert causal[name] == "output", name


def test_parameters_carry_units_and_start_values(lab_fmu):
    from afo_mj.scenarios.circuit_scenario import library_spec
    path, _ = lab_fmu
    md = read_model_description(str(path))
    units = {u.name: u for u in md.unitDefinitions}
    params = {v.name: v for v in md.modelVariables if v.causality == "parameter"}
    assert len(params) > 50
    for v in params.values():
        assert v.start is not None and v.unit in units, v.name
        assert v.variability == "fixed" and v.initial == "exact", v.name
    # SI base units written out by hand (FMI 2.0 BaseUnit exponents)
    pa = units["Pa"].baseUnit
    assert (pa.kg, pa.m, pa.s) == (1, -1, -2)
    nm = units["N.m"].baseUnit
    assert (nm.kg, nm.m, nm.s, nm.rad) == (1, 2, -2, 0)
    rev = units["m^3/rev"].baseUnit
    assert (rev.m, rev.rad) == (3, -1) and rev.factor == pytest.approx(1 / (2 * np.pi))
    # start values are the scenario's description: the library's lab bench
    spec = library_spec("lab_bench")
    assert float(params["hose_a.length_m"].start) == spec["components"]["hose_a"]["params"][
        "length_m"]
    assert params["hose_a.length_m"].unit == "m"
    assert float(params["options.initial_pressure_pa"].start) == spec["options"][
        "initial_pressure_pa"]
    # the scenario overrides the library's open-loop controller with the HAFO's torque loop
    assert params["controller.pressure_gain_rad_s_per_pa"].unit == "rad/s/Pa"
    cmd = next(v for v in md.modelVariables if v.name == "command")
    assert cmd.unit == "N.m"


PAIRS = {"joint_torque": "torque_nm", "pressure.line_a": "line_a",
         "pressure.line_b": "line_b", "pressure.chamber_a": "chamber_a",
         "pressure.chamber_b": "chamber_b", "motor.current": "motor.current_a",
         "speed.shaft": "shaft", "bus_voltage": "bus_voltage_v"}


def _compare(fmu: dict, log: dict) -> dict:
    """NRMSE per output (normalised by the native signal's range); a constant native
    signal (the ideal supply's bus voltage) must be matched exactly."""
    worst = {}
    for out, sig in PAIRS.items():
        got, nat = fmu[out], log[sig]
        assert got.shape == nat.shape and np.all(np.isfinite(got)), out
        if np.ptp(nat) == 0.0:
            assert np.allclose(got, nat, rtol=1e-12), out
            continue
        worst[out] = _nrmse(got, nat)
    return worst


def test_fmu_reproduces_the_native_replay(lab_fmu):
    """FMPy's simulate_fmu (held inputs, 0.5 ms) against the native replay of the recorded
    stride: NRMSE <= 1 % per output."""
    path, _ = lab_fmu
    circuit, _, _ = scenario_circuit(str(SCENARIO))
    t, cmd, theta, theta_dot = _gait_inputs(1.0, HELD_STEP_S)
    res = _simulate(path, t, cmd, theta, theta_dot, list(PAIRS))
    assert np.allclose(res["time"], t)
    log = _native(circuit, cmd, theta, theta_dot, HELD_STEP_S)
    worst = _compare({o: res[o][1:] for o in PAIRS}, log)
    assert max(worst.values()) <= 0.01, worst
    # the assistance loads the circuit: the replay is not trivially zero
    assert np.ptp(log["torque_nm"]) > 10.0 and np.ptp(log["line_a"]) > 1e6


def test_fmu_with_input_derivatives_is_the_native_step(lab_fmu):
    """With the inputs' derivatives the FMU interpolates the motion as the native replay
    does: the same compiled step, equal to rounding at a 1 ms communication step."""
    path, _ = lab_fmu
    circuit, _, _ = scenario_circuit(str(SCENARIO))
    t, cmd, theta, theta_dot = _gait_inputs(1.0)
    got = _drive_with_derivatives(path, t, cmd, theta, theta_dot, list(PAIRS))
    worst = _compare(got, _native(circuit, cmd, theta, theta_dot))
    assert max(worst.values()) <= 1e-9, worst


def test_a_parameter_set_through_fmpy_reaches_the_circuit(lab_fmu):
    path, _ = lab_fmu
    circuit, _, _ = scenario_circuit(str(SCENARIO))
    t, cmd, theta, theta_dot = _gait_inputs(0.7, HELD_STEP_S)
    longer = {"hose_a.length_m": 3.0, "hose_b.length_m": 3.0}
    res = _simulate(path, t, cmd, theta, theta_dot, ["pressure.line_a", "joint_torque"],
                    start_values=longer)
    base = _native(circuit, cmd, theta, theta_dot, HELD_STEP_S)
    changed = _native(circuit_with(circuit, longer), cmd, theta, theta_dot, HELD_STEP_S)
    for out, sig in (("pressure.line_a", "line_a"), ("joint_torque", "torque_nm")):
        assert _nrmse(res[out][1:], changed[sig]) <= 0.01, out
    # and 3 m hoses are not the 0.5 m ones: the parameter changed the response
    assert _nrmse(changed["line_a"], base["line_a"]) > 0.02


def test_battery_outputs_of_the_hafo(tmp_path):
    """The HAFO preset (a battery on the bus): battery power is bus voltage times battery
    current of the native replay."""
    out = tmp_path / "hafo.fmu"
    export_fmu("hafo", out, timestep_s=TIMESTEP_S, step_size_s=STEP_S)
    assert validate_fmu(str(out)) == []
    circuit, _, _ = scenario_circuit("hafo")
    t, cmd, theta, theta_dot = _gait_inputs(0.7, HELD_STEP_S)
    res = _simulate(out, t, 2.0 * cmd, theta, theta_dot,
                    ["battery_power", "battery_current", "joint_torque"])
    log = _native(circuit, 2.0 * cmd, theta, theta_dot, HELD_STEP_S)
    power = log["battery_current_a"] * log["bus_voltage_v"]
    assert _nrmse(res["battery_power"][1:], power) <= 0.01
    assert _nrmse(res["joint_torque"][1:], log["torque_nm"]) <= 0.01
    assert np.max(power) > 10.0


def test_bad_scenarios_are_refused(tmp_path):
    from afo_mj.cli import main
    out = tmp_path / "x.fmu"
    with pytest.raises(InvalidInput, match=r"no \[circuit\] and no \[device\]"):
        export_fmu(str(ROOT / "scenarios" / "walk_healthy.toml"), out)
    ideal = tmp_path / "ideal.toml"
    ideal.write_text((ROOT / "scenarios" / "gait_muscle_ideal_zhang.toml").read_text())
    with pytest.raises(InvalidInput, match=r"device.preset = 'ideal' is not a circuit"):
        export_fmu(str(ideal), out)
    with pytest.raises(InvalidInput, match=r"allowed: a file name ending in \.fmu"):
        export_fmu("hafo", tmp_path / "x.zip")
    assert main(["export-fmu", str(tmp_path / "missing.toml"), "--out", str(out)]) == 2
    assert not out.exists()


def test_shim_matches_the_standard_fmi2_header(tmp_path):
    """The shim's functions against FMPy's copy of the FMI 2.0 headers (a conflicting
    signature does not compile)."""
    from afo_mj.outputs.fmu_export import SHIM_SOURCE
    headers = Path(fmpy.__file__).parent / "c-code"
    cc = shutil.which("gcc") or shutil.which("cc")
    res = subprocess.run([cc, "-fsyntax-only", "-Wall", "-Werror", "-std=c99",
                          "-DAFO_MJ_STANDARD_HEADERS", f"-I{headers}", str(SHIM_SOURCE)],
                         capture_output=True, text=True)
    assert res.returncode == 0, res.stderr
