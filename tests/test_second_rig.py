"""The second independent bench rig (tests/second_rig.py) against analytic references, and a
blind calibration of its records with its datasheet description
(scenarios/calibration/second_rig.toml).

(a) Physics, fast: the static balance under a held voltage (slip flow = pump flow, motor
torque = pump torque, load spring = hydraulic torque), volume conservation (the piston moves
the volume the pump swept), the cable–oil–foot resonance against the two-mass analytic
frequency, every effect switch, the record format and the rig's independence from afo_mj.
(b) Calibration, slow, in tests/test_second_rig_blind.py (the clean records) and
tests/test_second_rig_effects.py (a softer cable, backlash): files of their own so that the
suite's workers, which take whole files, can run them side by side.
"""

from __future__ import annotations

import ast
import dataclasses
import math
import warnings
from pathlib import Path

import numpy as np
import pytest
from scipy.optimize import brentq

import second_rig as R

ROOT = Path(__file__).resolve().parents[1]
SCENARIO = ROOT / "scenarios" / "calibration" / "second_rig.toml"
P = R.Rig2Params()


def _step(v0, t_on=0.0):
    return lambda t: v0 if t >= t_on else 0.0


# ---------------------------------------------------------------------------- (a) physics
def test_static_balance_under_a_held_voltage():
    """A constant voltage, the foot on its load spring, run to rest. With the piston still and
    no check-valve flow, the steady state solves (written out here, brentq on ω):
    ``V = R i + k ω``, ``k i = D Δp + T_c ω/√(ω²+ω_c²) + b ω``, ``D ω = C_s Δp`` (all the
    pump's flow slips back), no line flow (chamber Δp = port Δp), the cable carries ``A Δp``
    (seal friction vanishes at rest) and the spring holds it: ``k_L θ = −r A Δp``."""
    v0 = 2.0
    rig = R.Rig2(None, {}, _step(v0))
    t, Y = rig.simulate(6.0, hold_period_s=None, sample_rate_hz=100.0)
    ix = rig.ix
    D, C = P.displacement_m3_rad, P.slip_m3_s_pa

    def torque_gap(w):
        dp = D * w / C
        i = (v0 - P.motor_k * w) / P.resistance_ohm
        fric = P.motor_coulomb_nm * w / math.hypot(w, P.motor_friction_speed_rad_s)
        return P.motor_k * i - D * dp - fric - P.motor_viscous_nm_s * w

    w = brentq(torque_gap, 1e-6, v0 / P.motor_k)
    dp = D * w / C
    theta = -P.pulley_radius_m * P.area_m2 * dp / P.load_stiffness_nm_rad
    y = Y[:, -1]
    assert y[ix["omega_m"]] == pytest.approx(w, rel=2e-3)
    assert y[ix["p_a"]] - y[ix["p_b"]] == pytest.approx(dp, rel=2e-3)
    assert y[ix["p_1a"]] - y[ix["p_1b"]] == pytest.approx(dp, rel=2e-3)
    assert y[ix["i"]] == pytest.approx((v0 - P.motor_k * w) / P.resistance_ohm, rel=2e-3)
    assert y[ix["theta"]] == pytest.approx(theta, rel=2e-3)
    assert rig.algebraic(t[-1], y)["tau"] == pytest.approx(
        P.load_stiffness_nm_rad * theta, rel=2e-3)
    # the low line sits at the charge less the cracking pressure (its check valve just shut)
    assert min(y[ix["p_1a"]], y[ix["p_1b"]]) == pytest.approx(
        P.charge_pressure_pa - P.check_cracking_pa, abs=3e3)


def test_piston_moves_the_volume_the_pump_swept():
    """No slip, no leakage, no friction, no load spring, lines above the charge pressure
    (check valves shut): a voltage pulse, then rest. The pressures come back to where they
    started, so the oil is as compressed as it was, and the chamber volume gained equals the
    pump's swept volume, ``A x = D φ``; the cable carries nothing, ``x = −r θ``."""
    prm = dataclasses.replace(P, slip_m3_s_pa=0.0, piston_seal_n=0.0, cable_seal_n=0.0,
                              seal_viscous_n_s_m=0.0, load_stiffness_nm_rad=0.0,
                              motor_coulomb_nm=0.0)
    rig = R.Rig2(prm, {}, lambda t: 1.5 if t < 0.2 else 0.0)
    y0 = rig.initial_state(p_1a=2e6, p_ma=2e6, p_a=2e6, p_1b=2e6, p_mb=2e6, p_b=2e6)
    t, Y = rig.simulate(3.0, hold_period_s=None, y0=y0, sample_rate_hz=200.0)
    ix, y = rig.ix, Y[:, -1]
    swept = P.displacement_m3_rad * y[ix["phi_m"]]
    assert abs(swept) > 3e-7                     # it moved (> 0.3 cm³, 1.5 mm)
    assert min(Y[ix["p_1a"]].min(), Y[ix["p_1b"]].min()) > P.charge_pressure_pa
    for n in ("p_1a", "p_ma", "p_a", "p_1b", "p_mb", "p_b"):
        assert y[ix[n]] == pytest.approx(2e6, abs=2e3)
    assert P.area_m2 * y[ix["x_p"]] == pytest.approx(swept, rel=2e-3)
    assert y[ix["x_p"]] == pytest.approx(-P.pulley_radius_m * y[ix["theta"]], rel=1e-3)


def test_cable_oil_foot_resonance_matches_the_two_mass_frequency():
    """Chambers shut, motor held, no damping, air-free oil of constant modulus (integrated
    with LSODA, which switches to BDF when stiff: 1 s instead of Radau's 9 s): the foot (J,
    load spring k_L) and the piston (m, trapped oil K_oil = A² B (1/V_a + 1/V_b)) joined by
    the cable k_c. The lower root of ``det(K − ω² M) = 0`` with
    ``K = [[k_L + k_c r², k_c r], [k_c r, k_c + K_oil]]``, ``M = diag(J, m)`` against the
    free response's zero crossings."""
    prm = dataclasses.replace(P, piston_seal_n=0.0, cable_seal_n=0.0, seal_viscous_n_s_m=0.0,
                              load_damping_nm_s_rad=0.0, cable_damping_ratio=0.0,
                              air_fraction=0.0, bulk_modulus_slope=0.0)
    rig = R.Rig2(prm, {}, None, chambers_shut=True, motor_locked=True)
    r = P.pulley_radius_m
    v = rig.V_ch0 + P.area_m2 * P.stroke_m / 2
    k_oil = P.area_m2 ** 2 * P.liquid_bulk_modulus_pa * 2.0 / v
    kc = P.cable_stiffness_n_m
    K = np.array([[P.load_stiffness_nm_rad + kc * r * r, kc * r], [kc * r, kc + k_oil]])
    M = np.diag([P.foot_inertia_kg_m2, P.piston_mass_kg])
    a, b, c = M[0, 0] * M[1, 1], -(K[0, 0] * M[1, 1] + K[1, 1] * M[0, 0]), np.linalg.det(K)
    w2 = (-b - math.sqrt(b * b - 4 * a * c)) / (2 * a)
    f_ref = math.sqrt(w2) / (2 * math.pi)
    # start in the lower mode's shape (x/θ from its eigenvector), pressures balanced at x = 0
    th0 = 0.01
    x0 = -th0 * (K[0, 0] - w2 * M[0, 0]) / K[0, 1]
    y0 = rig.initial_state(theta=th0, x_p=x0, p_a=2e6, p_b=2e6)
    dp0 = P.liquid_bulk_modulus_pa * P.area_m2 * x0 / v      # the oil balanced at x = 0
    y0[rig.ix["p_a"]] -= dp0
    y0[rig.ix["p_b"]] += dp0
    t, Y = rig.simulate(0.3, hold_period_s=None, y0=y0, sample_rate_hz=5000.0, rtol=1e-9,
                        method="LSODA")
    th = Y[rig.ix["theta"]]
    th = th - 0.5 * (th.max() + th.min())      # about its (slightly shifted) equilibrium
    s = np.signbit(th)
    k = np.flatnonzero(s[1:] != s[:-1])
    tz = t[k] - th[k] * (t[k + 1] - t[k]) / (th[k + 1] - th[k])
    f_meas = (len(tz) - 1) / 2.0 / (tz[-1] - tz[0])
    assert 20.0 < f_ref < 60.0                      # the cable softens it well below the oil
    assert f_meas == pytest.approx(f_ref, rel=1e-3)


EFFECT_STATE = dict(i=6.0, omega_m=50.0, p_1a=3e6, p_ma=2.9e6, p_a=2.8e6, p_1b=0.5e6,
                    p_mb=0.6e6, p_b=0.7e6, x_p=1e-3, v_p=2e-3, theta=-0.0287, omega_f=-0.05)


SENSOR_EFFECTS = ("sensor_delay", "pressure_port_resonance")


@pytest.mark.parametrize("name", [n for n in R.EFFECTS if n not in SENSOR_EFFECTS])
def test_every_physical_effect_changes_the_dynamics(name):
    """Each effect switched on alone changes the right-hand side at a working state (t = 5 s,
    the piston moving, a pressure difference, 6 A, the cable within the play)."""
    clean = R.Rig2(None, {}, _step(3.0)).rhs(5.0, R.Rig2(None).initial_state(**EFFECT_STATE))
    on = R.Rig2(None, {name: True}, _step(3.0))
    dy = on.rhs(5.0, on.initial_state(**EFFECT_STATE))
    assert not np.allclose(dy, clean, rtol=1e-6, atol=0.0), name


def test_sensor_delay_shifts_the_outputs_only():
    rig = R.Rig2(None, {"sensor_delay": 2e-3}, R.voltage_command(0.5))
    t, Y = rig.simulate(0.5)
    late = R.measure(rig, t, Y, seed=1)
    now = R.measure(R.Rig2(None, {}, R.voltage_command(0.5)), t, Y, seed=1)
    np.testing.assert_array_equal(late["motor_voltage_v"], now["motor_voltage_v"])
    k = int(round(2e-3 * R.SAMPLE_RATE_HZ))
    np.testing.assert_allclose(late["motor_current_a"][k + 100:],
                               now["motor_current_a"][100:-k], atol=0.4)
    assert not np.allclose(late["motor_current_a"], now["motor_current_a"], atol=0.4)


def test_port_resonance_reads_through_a_second_order_system():
    """The transducers' port resonance against the closed-form step response of
    ``ω_n²/(s² + 2ζω_n s + ω_n²)`` (Ogata, *Modern Control Engineering*, §5-3): a 1 MPa step
    overshoots by ``exp(−πζ/√(1−ζ²))`` at ``t_p = π/(ω_n√(1−ζ²))``; only the pressures change."""
    f, z = 120.0, R.PORT_DAMPING_RATIO
    t = np.arange(0.0, 0.2, 1e-6)      # the step ramps over one sample: 1 µs
    p = np.where(t >= 0.01, 1.0e6, 0.0) + 2.0e5
    y = R.port_reading(t, p, f)
    wd = 2 * math.pi * f * math.sqrt(1 - z * z)
    tt = t[t >= 0.01] - 0.01
    exact = 2.0e5 + 1.0e6 * (1 - np.exp(-z * 2 * math.pi * f * tt)
                             * (np.cos(wd * tt) + z / math.sqrt(1 - z * z) * np.sin(wd * tt)))
    np.testing.assert_allclose(y[t >= 0.01], exact, atol=2e3)     # 0.2 % of the step
    assert y.max() - 1.2e6 == pytest.approx(
        1.0e6 * math.exp(-math.pi * z / math.sqrt(1 - z * z)), rel=0.01)
    rig = R.Rig2(None, {"pressure_port_resonance": True}, R.voltage_command(0.5))
    t, Y = rig.simulate(0.5)
    ring = R.measure(rig, t, Y, seed=1)
    now = R.measure(R.Rig2(None, {}, R.voltage_command(0.5)), t, Y, seed=1)
    for ch in R.OUTPUTS:
        same = np.array_equal(ring[ch], now[ch])
        assert same != ch.startswith("chamber_"), ch


@pytest.mark.parametrize("v0", [1.5, -1.5, 0.15])
def test_brush_drop_at_stall_against_the_armature_balance(v0):
    """Motor held, a constant voltage: at rest ``V = R i + V_b i/√(i² + I_lin²)`` (the
    armature balance with the brushes' drop, no back-EMF; solved here by brentq). Above the
    drop the current is about ``(V − V_b)/R`` (4.01 A at 1.5 V, against 5.02 A without
    brushes); below it the brushes pass only a small current (0.15 V: about 0.05 A instead of
    0.50 A), odd in the voltage."""
    vb = R.EFFECTS["brush_drop"].default
    i_lin = R.BRUSH_LINEAR_CURRENT_A

    def gap(i):
        return P.resistance_ohm * i + vb * i / math.sqrt(i * i + i_lin * i_lin) - v0

    ref = brentq(gap, -abs(v0) / P.resistance_ohm, abs(v0) / P.resistance_ohm)
    got = {}
    for fx in ({}, {"brush_drop": True}):
        rig = R.Rig2(None, fx, _step(v0), motor_locked=True)
        t, Y = rig.simulate(0.02, hold_period_s=None, sample_rate_hz=1000.0)
        got[bool(fx)] = Y[rig.ix["i"], -1]
    assert got[True] == pytest.approx(ref, rel=1e-4)
    assert got[False] == pytest.approx(v0 / P.resistance_ohm, rel=1e-4)
    if abs(v0) > vb:
        assert got[True] == pytest.approx((v0 - math.copysign(vb, v0)) / P.resistance_ohm,
                                          rel=1e-3)
    else:
        assert abs(got[True]) < 0.15 * abs(v0) / P.resistance_ohm


def test_refusals_name_the_value():
    with pytest.raises(ValueError, match="effect 'air' unknown; allowed: internal_leakage"):
        R.resolve_effects({"air": True})
    with pytest.raises(ValueError, match=r"effect backlash = -0.1; allowed: a finite number"):
        R.resolve_effects({"backlash": -0.1})
    with pytest.raises(ValueError, match=r"Rig2Params.bore_m = 0.0; allowed"):
        R.Rig2Params(bore_m=0.0)
    with pytest.raises(ValueError, match="duration_s"):
        R.Rig2().simulate(-1.0)


def test_record_format_hold_and_sensors(tmp_path):
    """The record (written by the rig itself) loads with afo_mj's validating loader without a
    warning; the command is held for 5 samples (200 Hz updates, 1 kHz log) and declared
    zero-order; the encoder and the ADCs are quantised to their steps."""
    from afo_mj.calibration.measured_data import load_measured
    path = R.write_record(tmp_path / "r.csv", duration_s=1.0, seed=2)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        data = load_measured(path)
    assert dict(data.hold) == {"motor_voltage_v": "zero_order"}
    assert set(data.outputs) == set(R.OUTPUTS) and list(data.inputs) == ["motor_voltage_v"]
    u = np.asarray(data.channels["motor_voltage_v"])
    k = np.arange(len(u))
    np.testing.assert_array_equal(u, u[(k // 5) * 5])
    assert len(np.unique(u)) > 20
    q = R.quantum(P)
    for ch, step in q.items():
        x = np.asarray(data.channels[ch]) / step
        np.testing.assert_allclose(x, np.round(x), atol=1e-6)
    assert data.noise["ankle_angle_rad"] == pytest.approx(q["ankle_angle_rad"] / math.sqrt(12))


def test_rig_is_independent_of_afo_mj():
    tree = ast.parse((ROOT / "tests" / "second_rig.py").read_text(encoding="utf-8"))
    mods = [a.name for n in ast.walk(tree) if isinstance(n, ast.Import) for a in n.names]
    mods += [n.module or "" for n in ast.walk(tree) if isinstance(n, ast.ImportFrom)]
    assert mods and not [m for m in mods if m.split(".")[0] in ("afo_mj", "independent_rig")]
