"""The circuit bench protocols (issue 18 item 7) on the valve-controlled presets as circuits:
what each valve circuit can run, and the digital circuit's flow vs PWM duty against the
seed's metering law (ch. 5)."""

from __future__ import annotations

import functools

import numpy as np
import pytest

from afo_mj.experiments import circuit_bench as cb
from afo_mj.scenarios import bench_protocols as bp
from afo_mj.circuits.codegen import build
from afo_mj.devices.valve_afo import VALVE_PRESETS, valve_circuit


@functools.lru_cache(maxsize=None)
def _cc(name):
    return build(valve_circuit(VALVE_PRESETS[name]))


def test_what_a_valve_circuit_can_run():
    servo, digital = valve_circuit(VALVE_PRESETS["valve"]), valve_circuit(VALVE_PRESETS["digital"])
    for circuit in (servo, digital):
        for test in ("isometric_steps", "position_step", "stiffness", "tracking"):
            assert bp.protocol_problem(circuit, test) is None, test
        # the motor feeds the valves: driving its voltage open loop moves no joint
        for test in ("torque_velocity", "frequency_response"):
            why = bp.protocol_problem(circuit, test)
            assert why and "valve" in why and circuit.name in why, why
    assert bp.protocol_problem(digital, "flow_vs_duty") is None
    why = bp.protocol_problem(servo, "flow_vs_duty")
    assert "digital_valve_torque" in why and "servo_valve_torque" in why


@pytest.mark.slow
def test_digital_flow_vs_duty_follows_the_seed_metering_law():
    """On a load of nearly constant pressure (a light foot, 0.001 kg m², against a bias
    torque and a damper) the delivered fraction of the pump's flow is, by the seed's
    argument (ch. 5), the duty less what passes while the valve travels:
    ``u − (1 − 2x*) T_sw f`` with ``0 ≤ x* ≤ 1``, so within ``T_sw f`` of ``u``; it is
    affine in ``u`` with unit slope. Measured: 0.142, 0.436, 0.730 at 0.2, 0.5, 0.8 (offset
    −0.06 = −0.6 T_sw f) and 0.982 at 1 (the shut valve's seat leakage and the lines'
    compliance)."""
    p = VALVE_PRESETS["digital"]
    tsw_f = p.switching_valve.switching_time_s * p.pwm_frequency_hz
    duties = (0.2, 0.5, 0.8)
    cfg = cb.CircuitBenchConfig(timestep_s=2.5e-4, flow_inertia_kg_m2=0.001, duties=duties)
    summary, series = cb.run_circuit_bench(_cc("digital"), ["flow_vs_duty"], cfg)
    f = summary["flow_vs_duty"]
    frac = np.array(f["flow_fraction"])
    assert np.all(np.abs(frac - np.array(duties)) <= tsw_f), (frac, tsw_f)
    assert np.all(frac < np.array(duties))          # the travel loses flow, never gains
    assert f["fit_slope"] == pytest.approx(1.0, abs=0.05)
    assert f["fit_r2"] > 0.999
    assert min(f["periods"]) >= 5
    # the pump runs at its set speed: its geometric flow is the preset's nominal flow
    assert np.allclose(f["pump_flow_m3_s"], p.nominal_pump_flow_m3_s, rtol=0.01)
    assert summary["energy"]["ledger_closed"]


def test_flow_vs_duty_refuses_a_step_that_does_not_divide_the_pwm_period():
    cfg = cb.CircuitBenchConfig(timestep_s=3e-4, duties=(0.5,))
    with pytest.raises(cb.CircuitBenchError, match="does not divide the PWM period"):
        cb.run_circuit_bench(_cc("digital"), ["flow_vs_duty"], cfg)


@pytest.mark.slow
def test_servo_valve_isometric_step_reaches_its_command():
    cfg = cb.CircuitBenchConfig(timestep_s=2.5e-4, step_torques_nm=(30.0,))
    summary, _ = cb.run_circuit_bench(_cc("valve"), ["isometric_steps"], cfg)
    s = summary["isometric_steps"]
    assert abs(s["steady_state_error_nm"]) < 0.05 * 30.0, s
    assert s["rise_time_s"] < 0.1
    assert summary["energy"]["ledger_closed"]
