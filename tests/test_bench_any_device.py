"""One set of bench protocols over any device that drives a joint (issue 40 item 2): the
circuit a walking scenario wears (scenarios/gait_lab_bench.toml), a user's own TOML
description, and every registered device, each through a short protocol it can run; the
protocols it cannot run refused naming the protocol, the device and what it lacks.

References, independent of the simulation: the commanded torque (a torque controller's
steady state), hand figures of the current-limited stall (``K I_max / d · A r``; the pump's
displacement, the motor's torque constant and current limit, the cylinder's area and pulley
radius) and of the relief-capped stall (``Δp_crack · A r``), and conservation of energy (each
run's ledger closes)."""

from __future__ import annotations

import math
from pathlib import Path

import pytest

from afo_mj.devices.registry import device_names, device_spec
from afo_mj.experiments.bench_run import run_bench
from afo_mj.scenarios import bench_protocols as bp
from afo_mj.scenarios.bench_scenario import parse_bench_scenario
from afo_mj.scenarios.device_source import device_source

ROOT = Path(__file__).resolve().parents[1]
#: short runs: 0.2 s steps at 0.25 ms, two torque–velocity points
SHORT = bp.LoadBenchConfig(timestep_s=2.5e-4, step_torques_nm=(10.0,), step_duration_s=0.2,
                           tv_points=2)
#: the cylinder both the lab bench and the user's circuit below use: A r (m³/rad)
KTP = math.pi / 4 * (12e-3 ** 2 - 2e-3 ** 2) * 0.04
#: the library pump's 0.2 cm³/rev (m³/rad), the motor's torque constant and current limit
PUMP_D, K_T, I_MAX = 0.2e-6 / (2 * math.pi), 0.055, 6.2

USER_BENCH = """
name = "my_drive"
description = '''A user's own pump-controlled drive: battery, motor, pump, charge checks,
one cylinder on a 40 mm pulley, no hoses and no relief valve (the driver's current limit sets
the stall).'''

[circuit]
name = "my_drive"
options = { initial_pressure_pa = 0.3e6 }
controller = { kind = "pump_torque", motor = "motor", pump = "pump", actuator = "cylinder" }

[circuit.components]
battery = { kind = "battery", params = { "battery.capacity_ah" = 3.0 } }
pump = { kind = "pump" }
charge = { kind = "reservoir", params = { pressure_pa = 0.3e6 } }
check_a = { kind = "check_valve" }
check_b = { kind = "check_valve" }

[circuit.components.motor]
kind = "motor"
[circuit.components.motor.params]
"motor.resistance_ohm" = 0.6
"motor.inductance_h" = 1e-4
"motor.torque_constant_nm_a" = 0.055
"motor.rotor_inertia_kg_m2" = 5e-7
"motor.coulomb_torque_nm" = 0.004
"motor.viscous_coefficient_nm_s_rad" = 2e-6
"driver.current_limit_a" = 6.2

[circuit.components.cylinder]
kind = "pulley_cylinders"
[circuit.components.cylinder.params]
count = 1.0
pulley_radius_m = 0.04
"cylinder.bore_m" = 12e-3
"cylinder.rod_diameter_m" = 2e-3
"cylinder.stroke_m" = 0.06

[circuit.nodes]
bus = ["battery.bus", "motor.bus"]
shaft = ["motor.shaft", "pump.shaft"]
line_a = ["pump.a", "check_a.b", "cylinder.a"]
line_b = ["pump.b", "check_b.b", "cylinder.b"]
tank = ["charge.port", "check_a.a", "check_b.a"]
ankle = ["cylinder.joint"]

[bench]
protocols = ["isometric_steps", "torque_velocity"]
timestep_s = 2.5e-4
step_torques_nm = [10.0]
step_duration_s = 0.2
tv_points = 2
"""


def _closed(summary):
    return all(abs(v["balance_error_rel"]) <= 1e-7 for v in summary["ledger"].values())


def test_the_circuit_a_walking_scenario_wears_on_both_rigs():
    """gait_lab_bench.toml wears the lab drive under the HAFO's pump_torque law: as a bench
    device it runs the torque protocols (its controller) and, being pump-controlled, the
    open-loop ones too (the bench drives its motor voltage)."""
    spec, _ = device_source(str(ROOT / "scenarios" / "gait_lab_bench.toml"))
    assert spec.circuit.controller.kind == "pump_torque"
    s, _ = run_bench(spec, ["isometric_steps", "torque_velocity"], "load", load=SHORT)
    step = s["isometric_steps"]["steps"]["10nm"]
    assert step["final"] == pytest.approx(10.0, rel=0.05), step
    # the shipped relief valves crack at 10 MPa: the stall is the relief's, Δp A r
    assert s["torque_velocity"]["stall_torque_nm"] == pytest.approx(10e6 * KTP, rel=0.03)
    assert _closed(s), s["ledger"]
    # the same device on the stand, its foot locked: one 15 N·m step
    from afo_mj.experiments.bench_stand import isometric_steps
    st, _ = isometric_steps(spec, levels_nm=(15.0,), duration_s=0.3)
    assert st["levels"]["15"]["final"] == pytest.approx(-15.0, rel=0.05), st
    assert st["energy_error_max"] < 1e-6


def test_a_users_toml_description_on_the_bench():
    bs = parse_bench_scenario(USER_BENCH, origin="my_drive.toml")
    assert (bs.rig, bs.protocols, bs.preset) == ("load", ("isometric_steps", "torque_velocity"),
                                                 "circuit:my_drive")
    s, _ = run_bench(bs.spec, bs.protocols, bs.rig, load=bs.load)
    assert s["isometric_steps"]["steps"]["10nm"]["final"] == pytest.approx(10.0, rel=0.05)
    # no relief: the driver's current limit sets the stall, K I_max / d · A r, less the
    # pump's and cylinder's friction (a few %)
    ref = K_T * I_MAX / PUMP_D * KTP
    assert 0.9 * ref < s["torque_velocity"]["stall_torque_nm"] < ref
    assert _closed(s), s["ledger"]
    # a protocol it cannot run is refused naming the protocol, the device and the lack
    with pytest.raises(Exception, match="'flow_vs_duty' cannot run on device 'my_drive'.*PWM"):
        parse_bench_scenario(USER_BENCH.replace('"isometric_steps", "torque_velocity"',
                                                '"flow_vs_duty"'), origin="my_drive.toml")


def _short_protocol(spec):
    for p in ("isometric_steps", "torque_velocity"):
        if bp.protocol_problem(spec, p, "load") is None:
            return p
    return None


@pytest.mark.parametrize("name", device_names())
def test_every_registered_device_runs_a_short_protocol(name):
    """Each registered device through a protocol it can run (a 10 N·m isometric step for a
    torque controller, else the open-loop stall), 0.2–2 s of simulated time at 0.25 ms; the
    protocols it cannot run are refused naming the protocol, the device and what it lacks."""
    spec = device_spec(name)
    proto = _short_protocol(spec)
    assert proto is not None, name
    s, _ = run_bench(spec, [proto], "load", load=SHORT)
    assert _closed(s), (name, s["ledger"])
    if proto == "isometric_steps":
        # plantarflexion, as commanded, and no runaway (the accumulator circuits are slower
        # than 0.2 s to reach it: their torque is on its way)
        final = s["isometric_steps"]["steps"]["10nm"]["final"]
        assert 0.5 < final < 1.3 * 10.0, (name, final)
    else:       # the open-loop lab drive: its relief caps the stall
        assert s["torque_velocity"]["stall_torque_nm"] == pytest.approx(10e6 * KTP, rel=0.03)
    caps = bp.device_capabilities(spec)
    for p in bp.PROTOCOLS:
        why = bp.protocol_problem(spec, p, "load")
        lacks = [n for n in ("joint",) + bp.NEEDS[p] if caps[n]]
        assert (why is None) == (not lacks), (name, p, why)
        if why:
            assert f"{p!r} cannot run on device {name!r}" in why
            assert bp.NEED_TEXT[lacks[0]] in why
