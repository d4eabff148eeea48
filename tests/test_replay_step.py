"""The replay's step chosen by the numerical check before a calibration fits (issue 41; module
docstring of afo_mj/calibration/numerical_check.py, *The replay's step*), and the scenario's
``[calibration] replay_max_step_s`` that sets it instead.

The reference is analytic: a motor winding held still by a large rotor inertia is an RL
circuit, ``L di/dt = V − R i``. Under a voltage held over each 1 ms sample the exact current
steps by ``i ← V/R + (i − V/R) e^{−Δt R/L}`` per sample, and backward Euler with ``n`` equal
sub-steps ``h`` by ``i ← (i + h V/L)/(1 + h R/L)`` per sub-step; their RMS difference over σ
is the error the check must see at each step, and the step it must choose."""

from __future__ import annotations

import math

import numpy as np
import pytest

from afo_mj.calibration.calibrate import Calibration, load_calibration_scenario
from afo_mj.calibration.measured_data import write_measured
from afo_mj.calibration.numerical_check import STEP_RATIO, choose_replay_step
from afo_mj.hydraulics.params import ParameterError

R_OHM, L_H = 0.6, 1.0e-4          # L/R = 0.17 ms: not resolved by 0.5 ms sub-steps
FS_HZ, DURATION_S, SETTLE_S = 1000.0, 1.0, 0.1

RL_RIG = f"""
name = "rl_step_choice"
description = "a motor winding held still by a large rotor inertia: an RL circuit"

[circuit]
name = "rl_rig"
[circuit.fluid]
name = "ISO VG 32"
density_kg_m3 = 860.0
viscosity_low_m2_s = 32.0e-6
viscosity_high_m2_s = 5.4e-6
liquid_bulk_modulus_pa = 1.6e9
air_fraction = 0.005
[circuit.thermal]
ambient_temperature_k = 313.15
[circuit.options]
initial_pressure_pa = 5.0e5
supply_voltage_v = 24.0
[circuit.controller]
kind = "open_loop"

[circuit.components.motor]
kind = "motor"
[circuit.components.motor.params]
"motor.resistance_ohm" = {R_OHM}
"motor.inductance_h" = {L_H}
"motor.torque_constant_nm_a" = 0.055
"motor.rotor_inertia_kg_m2" = 10.0
"motor.coulomb_torque_nm" = 0.0
"motor.viscous_coefficient_nm_s_rad" = 0.0
"driver.current_limit_enabled" = false
"driver.on_resistance_ohm" = 0.0
"driver.max_duty" = 1.0

[circuit.components.pump]
kind = "pump"
[circuit.components.pump.params]
displacement_m3_rev = 2.0e-7
slip_coefficient = 6.9e-8
rotor_inertia_kg_m2 = 0.0
coulomb_friction_enabled = false
viscous_friction_enabled = false
drag_torque_nm = 0.0
[circuit.components.port_a]
kind = "volume"
params = {{ volume_m3 = 2.0e-6 }}
[circuit.components.port_b]
kind = "volume"
params = {{ volume_m3 = 2.0e-6 }}
[circuit.components.cylinder]
kind = "pulley_cylinders"
[circuit.components.cylinder.params]
count = 1.0
pulley_radius_m = 0.04
"cylinder.bore_m" = 14.0e-3
"cylinder.rod_diameter_m" = 2.0e-3
"cylinder.stroke_m" = 0.045

[circuit.nodes]
shaft = ["motor.shaft", "pump.shaft"]
bus = ["motor.bus"]
a = ["pump.a", "port_a.port", "cylinder.a"]
b = ["pump.b", "port_b.port", "cylinder.b"]
ankle = ["cylinder.joint"]

[calibration]
settle_s = {SETTLE_S}
"""


def _voltage(t):
    """±4 V held between samples, reversing every 50 ms."""
    return np.where(np.sin(2 * np.pi * 10.0 * t + 0.3) >= 0.0, 4.0, -4.0)


def _exact(v, dt):
    i = np.zeros(len(v))
    a = math.exp(-dt * R_OHM / L_H)
    for k in range(1, len(v)):
        i[k] = v[k - 1] / R_OHM + (i[k - 1] - v[k - 1] / R_OHM) * a
    return i


def _backward_euler(v, dt, n):
    h = dt / n
    i = np.zeros(len(v))
    x = 0.0
    for k in range(1, len(v)):
        for _ in range(n):
            x = (x + h * v[k - 1] / L_H) / (1.0 + h * R_OHM / L_H)
        i[k] = x
    return i


def _rig(tmp_path, sigma_a, options=""):
    scn = tmp_path / "rl.toml"
    scn.write_text(RL_RIG + options, encoding="utf-8")
    setup = load_calibration_scenario(str(scn))
    t = np.arange(0.0, DURATION_S, 1.0 / FS_HZ)
    v = _voltage(t)
    data = write_measured(tmp_path / "rl.csv", {
        "time_s": t, "motor_voltage_v": v, "ankle_angle_rad": np.zeros_like(t),
        "motor_current_a": _exact(v, 1.0 / FS_HZ)},
        inputs=["motor_voltage_v", "ankle_angle_rad"], outputs=["motor_current_a"],
        source={"scenario": str(scn), "description": "RL winding, analytic"},
        noise={"motor_current_a": sigma_a}, hold={"motor_voltage_v": "zero_order"})
    return Calibration(data, "rl_rig", setup.options, replay=setup.replay()), v


def test_the_step_is_halved_until_the_stepper_error_is_within_the_noise(tmp_path):
    """σ is set so that (analytically) backward Euler misses σ/4 at 0.5 and 0.25 ms and
    reaches it at 0.125 ms: the choice tries exactly those three steps, sees at each the
    analytic error (within 5 %), and keeps 0.125 ms."""
    t = np.arange(0.0, DURATION_S, 1.0 / FS_HZ)
    v = _voltage(t)
    exact = _exact(v, 1.0 / FS_HZ)
    scored = t >= SETTLE_S
    rms = {n: float(np.sqrt(np.mean((_backward_euler(v, 1e-3, n) - exact)[scored] ** 2)))
           for n in (2, 4, 8)}
    sigma = rms[8] / (0.8 * STEP_RATIO)     # 0.125 ms at 0.8 of the target ratio
    assert rms[4] / sigma > 1.5 * STEP_RATIO and rms[2] / sigma > 0.5   # the premise
    cal, _ = _rig(tmp_path, sigma)
    out = choose_replay_step(cal, DURATION_S, 2.0, start_s=5e-4)
    assert [s["max_step_s"] for s in out["tried"]] == [5e-4, 2.5e-4, 1.25e-4]
    assert [s["substeps"] for s in out["tried"]] == [2, 4, 8]
    for s in out["tried"]:
        got = s["ratios"]["motor_current_a"]
        assert got == pytest.approx(rms[s["substeps"]] / sigma, rel=0.05), s
    assert out["reached"] and not out["stalled"]
    assert out["max_step_s"] == 1.25e-4 and cal.replay.max_step_s == 1.25e-4


def test_the_choice_stops_at_its_floor(tmp_path):
    """A σ no step reaches: halved down to the floor, kept there, not reached."""
    cal, _ = _rig(tmp_path, 1e-6)
    out = choose_replay_step(cal, DURATION_S, 2.0, start_s=5e-4, floor_s=2.5e-4)
    assert [s["max_step_s"] for s in out["tried"]] == [5e-4, 2.5e-4]
    assert not out["reached"] and out["max_step_s"] == 2.5e-4


def test_a_step_stated_in_the_scenario_is_used_without_a_choice(tmp_path):
    cal, _ = _rig(tmp_path, 0.05, "replay_max_step_s = 2.0e-4\n")
    step = cal.choose_step()
    assert step["source"] == "scenario" and step["tried"] == []
    assert cal.replay.max_step_s == 2.0e-4


@pytest.mark.parametrize("bad", ["0.0", "-1e-4", "0.1", '"fast"', "true", "nan"])
def test_a_replay_step_outside_its_range_is_refused(tmp_path, bad):
    scn = tmp_path / "rl.toml"
    scn.write_text(RL_RIG + f"replay_max_step_s = {bad}\n", encoding="utf-8")
    with pytest.raises(ParameterError, match=r"calibration\.replay_max_step_s = .*; allowed: "
                                             r"a number of seconds 1e-06 … 0\.01"):
        load_calibration_scenario(str(scn))
