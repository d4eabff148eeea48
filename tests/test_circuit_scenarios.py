"""Scenarios built from circuit descriptions: the ``[circuit]`` table (walking and bench),
its errors through ``afo-mj run`` (exit 2, nothing written), and the bench-kind checks."""

from __future__ import annotations

from pathlib import Path

import pytest

from afo_mj import cli

SCEN = Path(__file__).resolve().parents[1] / "scenarios"


def _run(argv, capsys):
    rc = cli.main(argv)
    cap = capsys.readouterr()
    return rc, cap.out, cap.err


def test_the_stand_refuses_a_protocol_the_valve_preset_cannot_run(tmp_path, capsys):
    """The HAFO's protocols on the servo-valve preset: its motor feeds the valves, so the
    open-loop motor-voltage protocols are refused, naming the protocol, the device, what it
    lacks and what it can run on the stand instead."""
    out = tmp_path / "r"
    rc, _, err = _run(["run", str(SCEN / "bench_hafo.toml"), "--out", str(out),
                       "--set", "device.preset=valve"], capsys)
    assert rc == 2
    assert "'torque_velocity' cannot run on device 'valve'" in err
    assert "open-loop motor-voltage command" in err and "feeds the valve(s)" in err
    assert "isometric_steps, position_step, stiffness" in err
    assert not out.exists()


# ---- the [circuit] table: errors through the CLI ------------------------------------------------

_WALK = """
name = "w"
[gait]
strides = 2
analyse_strides = [1, 2]
[device]
conditions = ["transparent"]
"""

_MINIMAL = """
[circuit]
name = "t"
[circuit.components.supply]
kind = "reservoir"
params = { pressure_pa = 1e6 }
[circuit.components.hose]
kind = "hose"
[circuit.components.cyl]
kind = "spring_return_cylinder"
[circuit.nodes]
p = ["supply.port", "hose.a"]
c = ["hose.b", "cyl.a"]
ankle = ["cyl.joint"]
"""


@pytest.mark.parametrize("extra, overrides, match", [
    ("", ["circuit.nodes.c=[\"hose.b\"]"], "port 'cyl.a'"),                 # unconnected port
    ("", ["circuit.nodes.p=[\"supply.port\", \"hose.a\", \"nosuch.a\"]"],
     "unknown component 'nosuch'"),
    ("", ["circuit.nodes.c=[\"hose.b\", \"cyl.x\"]"], "has no port 'x'"),
    ("", ["circuit.components.hose.params.colour=3"], "colour"),           # unknown parameter
    ("[circuit.components.cv]\nkind = \"check_valve\"\n[circuit.components.cv2]\n"
     "kind = \"check_valve\"\n", ["circuit.nodes.mid=[\"cv.b\", \"cv2.a\"]",
                                  "circuit.nodes.p=[\"supply.port\", \"hose.a\", \"cv.a\"]",
                                  "circuit.nodes.c=[\"hose.b\", \"cyl.a\", \"cv2.b\"]"],
     "node 'mid' has no capacitance"),
    ("", ["circuit.components.w.kind=\"warp_drive\""], "warp_drive"),
])
def test_circuit_errors_exit_2_and_write_nothing(tmp_path, capsys, extra, overrides, match):
    f = tmp_path / "s.toml"
    f.write_text(_WALK + _MINIMAL + extra, encoding="utf-8")
    out = tmp_path / "r"
    argv = ["run", str(f), "--out", str(out)]
    for o in overrides:
        argv += ["--set", o]
    rc, _, err = _run(argv, capsys)
    assert rc == 2, err
    assert match in err
    assert err.count("\n") == 1                     # one error line
    assert not out.exists()


def test_two_drives_on_one_joint_exit_2(tmp_path, capsys):
    out = tmp_path / "r"
    rc, _, err = _run(["run", str(SCEN / "gait_pump_accumulator.toml"), "--out", str(out),
                       "--set", 'circuit.components.motor2.kind="motor"',
                       "--set", 'circuit.nodes.bus=["battery.bus", "motor.bus", "motor2.bus"]',
                       "--set", 'circuit.nodes.shaft=["motor.shaft", "pump.shaft", '
                                '"motor2.shaft"]'], capsys)
    assert rc == 2 and "two drives" in err and not out.exists()


def test_a_parameter_no_component_uses_exit_2(tmp_path, capsys):
    out = tmp_path / "r"
    rc, _, err = _run(["run", str(SCEN / "bench_lab_bench.toml"), "--out", str(out),
                       "--set", "circuit.components.hose_a.params.length_mm=3"], capsys)
    assert rc == 2 and "length_mm" in err and not out.exists()


def test_unknown_library_and_preset_with_circuit_exit_2(tmp_path, capsys):
    out = tmp_path / "r"
    rc, _, err = _run(["run", str(SCEN / "gait_pump_accumulator.toml"), "--out", str(out),
                       "--set", 'circuit.library="nope"'], capsys)
    assert rc == 2 and "circuit.library = 'nope'" in err and "pump_accumulator" in err
    rc, _, err = _run(["run", str(SCEN / "gait_pump_accumulator.toml"), "--out", str(out),
                       "--set", 'device.preset="hafo"'], capsys)
    assert rc == 2 and "either [circuit] or device.preset" in err
    assert not out.exists()


def test_set_overrides_reach_the_circuit_parameters():
    from afo_mj.scenarios.circuit_scenario import load_circuit
    from afo_mj.scenarios.walk_scenario import apply_overrides
    doc = {"circuit": {"library": "lab_bench"}}
    apply_overrides(doc, ["circuit.components.hose_a.params.length_m=2.0",
                          "circuit.components.motor.params.motor.resistance_ohm=0.9"])
    spec, cc = load_circuit(doc["circuit"], "t")
    i = cc.param_labels.index("hose_a.length")
    assert cc.P[i] == 2.0
    assert cc.P[cc.param_labels.index("motor.R")] == 0.9
    # the other parameters of the overridden components are the library's
    assert spec["components"]["hose_a"]["params"]["bore_m"] == 3.2e-3
    assert spec["components"]["motor"]["params"]["driver.current_limit_a"] == 6.2


def test_assist_with_open_loop_circuit_is_refused(tmp_path, capsys):
    out = tmp_path / "r"
    rc, _, err = _run(["run", str(SCEN / "gait_lab_bench.toml"), "--out", str(out),
                       "--set", 'circuit.controller={kind="open_loop"}'], capsys)
    assert rc == 2 and "open_loop" in err and "torque profile" in err and not out.exists()


# ---- bench protocols -----------------------------------------------------------------------------

@pytest.mark.parametrize("test", ["isometric_steps", "position_step", "stiffness", "tracking",
                                  "flow_vs_duty"])
def test_protocols_the_controller_cannot_run_exit_2(tmp_path, capsys, test):
    out = tmp_path / "r"
    rc, _, err = _run(["run", str(SCEN / "bench_lab_bench.toml"), "--out", str(out),
                       "--set", f'bench.tests=["{test}"]'], capsys)
    assert rc == 2 and not out.exists()
    assert test in err
    assert f"'{test}' cannot run on device 'lab_bench'" in err
    assert ("PWM duty" if test == "flow_vs_duty" else "'open_loop'") in err


def test_flow_vs_duty_refused_for_a_pump_circuit(tmp_path, capsys):
    out = tmp_path / "r"
    rc, _, err = _run(["run", str(SCEN / "bench_pump_accumulator.toml"), "--out", str(out),
                       "--set", 'bench.tests=["flow_vs_duty"]'], capsys)
    assert rc == 2 and not out.exists()
    assert "'flow_vs_duty' cannot run on device 'pump_accumulator'" in err and "PWM" in err


def _lab_spec(**over):
    from afo_mj.scenarios.circuit_scenario import circuit_spec
    return circuit_spec({"library": "lab_bench", **over}, "t")


def test_lab_bench_stall_and_no_load_against_hand_figures():
    """Relief raised out of the way: stall torque at the driver's current limit through the
    pump and the cylinder, K I_max (A r / d) less the pump's friction (a few %); no-load speed
    the motor's no-load speed at duty_max V_bus through d / (A r), less its friction."""
    import math

    from afo_mj.circuits.device_spec import DeviceSpec
    from afo_mj.experiments.bench_load import run_load_bench
    from afo_mj.scenarios.bench_protocols import LoadBenchConfig
    from afo_mj.circuits.circuit import Circuit
    relief = {"kind": "relief_valve", "params": {"cracking_dp_pa": 20e6}}
    spec = DeviceSpec.from_circuit(Circuit.from_dict(_lab_spec(
        components={"relief_ab": relief, "relief_ba": relief})))
    s, _ = run_load_bench(spec, ["torque_velocity"], LoadBenchConfig(tv_points=2))
    K, i_max = 0.055, 6.2
    d = 0.2e-6 / (2 * math.pi)
    area = math.pi / 4 * (12e-3 ** 2 - 2e-3 ** 2)           # piston less the cable
    ktp = area * 0.04
    stall_ref = K * i_max / d * ktp                        # 47.1 N*m
    tv = s["torque_velocity"]
    assert 0.9 * stall_ref < tv["stall_torque_nm"] < stall_ref
    speed_ref = 0.95 * 24.0 / K * d / ktp                   # 3.00 rad/s
    assert 0.95 * speed_ref < tv["no_load_speed_rad_s"] < speed_ref
    assert s["energy"]["ledger_closed"], s["ledger"]
    # the relief valve caps the shipped circuit's stall at its cracking pressure
    s2, _ = run_load_bench(DeviceSpec.from_circuit(Circuit.from_dict(_lab_spec())),
                           ["torque_velocity"], LoadBenchConfig(tv_points=2))
    assert s2["torque_velocity"]["stall_torque_nm"] == pytest.approx(10e6 * ktp, rel=0.03)


def test_lab_bench_resonance_against_inertia_on_oil_stiffness():
    """Air-free oil: the peak of the open-loop velocity response is the load inertia on the
    oil columns, f = √((K_h + K_load) / J) / 2π, K_h = (A r)² (1/C_a + 1/C_b) at mid-stroke
    (C = V / B + V_hose / K_wall; Merritt §5.3), the pump side held by the motor's EMF."""
    import math

    from afo_mj.circuits.device_spec import DeviceSpec
    from afo_mj.experiments.bench_load import run_load_bench
    from afo_mj.scenarios.bench_protocols import LoadBenchConfig
    from afo_mj.circuits.circuit import Circuit
    from afo_mj.hydraulics.fluid import Fluid
    circuit = Circuit.from_dict(_lab_spec(fluid={"air_fraction": 0.0}))
    cfg = LoadBenchConfig(load_inertia_kg_m2=0.05, load_stiffness_nm_rad=20.0,
                             freq_min_hz=10.0, freq_max_hz=300.0, freq_points=20)
    s, _ = run_load_bench(DeviceSpec.from_circuit(circuit), ["frequency_response"], cfg)
    fr = s["frequency_response"]
    assert len(fr["frequencies_hz"]) >= 15
    area = math.pi / 4 * (12e-3 ** 2 - 2e-3 ** 2)
    ktp = area * 0.04
    v_hose = math.pi / 4 * 3.2e-3 ** 2 * 0.5
    b = float(Fluid(circuit.fluid).bulk_modulus_pa(0.3e6 + 101325.0))
    v_a = 0.4e-6 + area * 0.03 + v_hose + 0.3e-6
    v_b = 0.6e-6 + area * 0.03 + v_hose + 0.3e-6
    k_h = ktp ** 2 * (1 / (v_a / b + v_hose / 1.5e9) + 1 / (v_b / b + v_hose / 1.5e9))
    f_ref = math.sqrt((k_h + 20.0) / 0.05) / (2 * math.pi)
    assert not fr["resonance_at_range_end"]
    assert fr["resonance_hz"] == pytest.approx(f_ref, rel=0.15), (fr["resonance_hz"], f_ref)
    assert fr["resonance_peak_db"] > 3.0
    assert s["energy"]["ledger_closed"]


def test_torque_protocols_on_spring_return_close_their_ledgers():
    from afo_mj.circuits.device_spec import DeviceSpec
    from afo_mj.experiments.bench_load import run_load_bench
    from afo_mj.scenarios.bench_protocols import LoadBenchConfig
    from afo_mj.circuits.library import spring_return_gait
    cfg = LoadBenchConfig(step_torques_nm=(20.0,), step_duration_s=0.3,
                             stiffnesses_nm_rad=(100.0,), tracking_cycles=2,
                             position_duration_s=0.5)
    s, series = run_load_bench(DeviceSpec.from_circuit(spring_return_gait()),
                               ["isometric_steps", "stiffness", "tracking",
                                "position_step"], cfg)
    iso = s["isometric_steps"]["steps"]["20nm"]
    assert iso["rise_time_s"] < 0.1 and abs(iso["steady_state_error"]) < 2.0
    assert s["stiffness"]["stiffness"]["k100"]["error_rel"] == pytest.approx(0.0, abs=0.2)
    assert s["tracking"]["rmse_nm"] < 6.0
    assert s["position_step"]["rise_time_s"] < 0.5
    assert all(abs(v["balance_error_rel"]) <= 1e-9 for v in s["ledger"].values()), s["ledger"]
    assert set(series) == {"isometric_steps", "stiffness", "tracking", "position_step"}


# ---- scenarios run end to end ------------------------------------------------------------------

def _summary(out):
    import json
    return json.loads((out / "summary.json").read_text(encoding="utf-8"))


def test_bench_lab_bench_scenario_runs(tmp_path, capsys):
    out = tmp_path / "r"
    rc, so, err = _run(["run", str(SCEN / "bench_lab_bench.toml"), "--out", str(out),
                        "--set", "bench.freq_points=15", "--set", "bench.tv_points=3"], capsys)
    assert rc == 0, err
    s = _summary(out)
    assert s["energy"]["ledger_closed"] and s["energy"]["balance_error_rel"] <= 1e-9
    assert s["bench"]["torque_velocity"]["stall_torque_nm"] > 30.0
    assert (out / "bench_frequency_response.png").is_file()
    assert "stall_torque_nm" in so


@pytest.mark.slow
@pytest.mark.parametrize("name", ["bench_pump_accumulator", "bench_spring_return"])
def test_pump_bench_scenarios_run(tmp_path, capsys, name):
    out = tmp_path / "r"
    rc, _, err = _run(["run", str(SCEN / f"{name}.toml"), "--out", str(out),
                       "--set", "bench.freq_points=15", "--set", "bench.tv_points=3",
                       "--set", "bench.tracking_cycles=2"], capsys)
    assert rc == 0, err
    s = _summary(out)
    assert set(s["bench"]) >= {"torque_velocity", "isometric_steps", "frequency_response",
                               "position_step", "stiffness", "tracking"}
    assert len(s["ledger"]) > 10
    assert s["energy"]["balance_error_rel"] == max(abs(v["balance_error_rel"])
                                                   for v in s["ledger"].values())
    if name == "bench_pump_accumulator":
        # known gap (reported, not hidden): with the gas accumulator the ledger closes to
        # ~4e-8 on the motor-voltage runs at the 0.1 ms step, not 1e-9
        assert not s["energy"]["ledger_closed"]
        assert s["energy"]["balance_error_rel"] < 1e-7
    else:
        assert s["energy"]["ledger_closed"]


@pytest.mark.slow
@pytest.mark.parametrize("name", ["gait_lab_bench", "gait_pump_accumulator",
                                  "gait_spring_return"])
def test_gait_circuit_scenarios_run(tmp_path, capsys, name):
    out = tmp_path / "r"
    rc, so, err = _run(["run", str(SCEN / f"{name}.toml"), "--out", str(out),
                        "--set", "gait.strides=4", "--set", "gait.analyse_strides=[2, 4]",
                        "--set", 'device.conditions=["assist"]'], capsys)
    assert rc == 0, err
    s = _summary(out)
    assert s["device_preset"].startswith("circuit:")
    assert abs(s["energy"]["balance_error_rel"]) <= 1e-9
    # the lab drive (0.2 cc/rev) cannot follow push-off: it brakes (RMSE ≈ 15 N·m)
    assert s["device"]["torque_tracking_rmse_nm"] < (10.0 if name != "gait_lab_bench"
                                                      else 25.0)
    assert (out / "circuit_torque.png").is_file()
