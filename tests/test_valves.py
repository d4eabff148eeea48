"""Orifice and valves against independent references.

References are hand formulas (the plain turbulent orifice law Q = C_d A sqrt(2 Δp / ρ), the
linear opening ramps, the second-order frequency response 1/(2ζ) at ω_n), small explicit or RK4
integrations written here, and scipy root finding; never the code's own outputs.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.optimize import brentq

from afo_mj.hydraulics.params import ParameterError
from afo_mj.hydraulics.orifice import (OrificeParams, orifice_area_for_flow, orifice_dp_for_flow,
                                       orifice_flow_m3_s)
from afo_mj.hydraulics.check_valve import CheckValveParams
from afo_mj.hydraulics.relief_valve import ReliefValveParams
from afo_mj.hydraulics.unloading_valve import UnloadingValveParams
from afo_mj.hydraulics.servo_valve import ServoValveParams
from afo_mj.hydraulics.onoff_valve import OnOffValveParams, pwm_command
from component_reference import (CheckValve, OnOffValve, Orifice, ReliefValve, ServoValve,
                                 UnloadingValve, smooth_ramp01)

RHO = 870.0
P_TANK = 0.1e6


def turbulent(dp, area, cd=0.61, rho=RHO):
    """The plain (unregularised) orifice law, written out by hand."""
    dp = np.asarray(dp, dtype=float)
    return cd * area * np.sqrt(2.0 * np.abs(dp) / rho) * np.sign(dp)


def _raises_naming(factory, *fields):
    with pytest.raises(ParameterError) as info:
        factory()
    for name in fields:
        assert name in str(info.value), (name, str(info.value))


def _assert_balanced(pf):
    scale = np.maximum(np.abs(pf.in_w), 1e-30)
    assert np.all(np.abs(pf.residual_w) <= 1e-9 * scale + 1e-18)
    assert np.all(np.asarray(pf.heat_w) >= 0.0)
    assert np.all(np.asarray(pf.in_w) >= 0.0) and np.all(np.asarray(pf.out_w) >= 0.0)


# --------------------------------------------------------------------------------- orifice

def test_orifice_matches_turbulent_law_at_large_dp():
    dp = np.array([-20e6, -3e6, -0.5e6, 0.5e6, 1e6, 5e6, 20e6])
    q = orifice_flow_m3_s(dp, 1.2e-6, 0.61, RHO, 1e4)
    np.testing.assert_allclose(q, turbulent(dp, 1.2e-6), rtol=5e-3)
    # 1 mm², 5 MPa by hand: 0.61e-6 * sqrt(1e7/870) = 6.5399e-5 m³/s
    assert orifice_flow_m3_s(5e6, 1e-6, 0.61, RHO, 1e4) == pytest.approx(6.5399e-5, rel=5e-3)


def test_orifice_finite_odd_monotonic_near_zero():
    pcr = 1e4
    dp = np.linspace(-5 * pcr, 5 * pcr, 2001)
    q = orifice_flow_m3_s(dp, 1e-6, 0.61, RHO, pcr)
    assert np.all(np.isfinite(q))
    np.testing.assert_allclose(q, -q[::-1], rtol=0, atol=1e-20)
    assert np.all(np.diff(q) > 0)
    assert q[1000] == 0.0
    # slope at zero: the law tends to C_d A sqrt(2/ρ) Δp / sqrt(p_cr)
    h = 1.0
    slope = (orifice_flow_m3_s(h, 1e-6, 0.61, RHO, pcr)
             - orifice_flow_m3_s(-h, 1e-6, 0.61, RHO, pcr)) / (2 * h)
    assert slope == pytest.approx(0.61e-6 * math.sqrt(2 / RHO) / math.sqrt(pcr), rel=1e-6)


def test_orifice_inverses():
    # sizing: 4 L/min at 3.5 MPa -> A = Q / (C_d sqrt(2 Δp / ρ))
    q = 4 / 60e3
    a = orifice_area_for_flow(q, 3.5e6, 0.61, RHO)
    assert a == pytest.approx(q / (0.61 * math.sqrt(2 * 3.5e6 / RHO)), rel=5e-3)
    # pressure drop: Δp = ρ/2 (Q / (C_d A))²
    qs = np.array([-1e-4, -2e-5, 3e-5, 1e-4])
    dp = orifice_dp_for_flow(qs, 1e-6, 0.61, RHO, 1e4)
    np.testing.assert_allclose(dp, np.sign(qs) * RHO / 2 * (qs / 0.61e-6) ** 2, rtol=5e-3)
    # exact inverse, including the regularised range
    dps = np.array([-1e6, -3e3, 0.0, 50.0, 2e4, 7e6])
    back = orifice_dp_for_flow(orifice_flow_m3_s(dps, 1e-6, 0.61, RHO, 1e4), 1e-6, 0.61, RHO, 1e4)
    np.testing.assert_allclose(back, dps, rtol=1e-9, atol=1e-6)


def test_orifice_class_flow_and_power():
    o = Orifice(OrificeParams(area_m2=2e-6))
    p_in = np.array([5e6, 0.2e6, 1e6, 3e6])
    p_out = np.array([0.1e6, 4e6, 1e6, 2.9e6])
    q = o.flow_m3_s(p_in, p_out, RHO)
    assert q.shape == (4,)
    np.testing.assert_allclose(q[:2], turbulent(p_in[:2] - p_out[:2], 2e-6), rtol=5e-3)
    assert q[2] == 0.0
    pf = o.power(p_in, p_out, RHO)
    _assert_balanced(pf)
    np.testing.assert_allclose(pf.heat_w, (p_in - p_out) * q, rtol=1e-12)
    assert (pf.in_w[0] == pytest.approx(p_in[0] * q[0])
            and pf.out_w[0] == pytest.approx(p_out[0] * q[0]))
    assert OrificeParams(area_m2=math.pi * 1e-6).diameter_m == pytest.approx(2e-3)


def test_smooth_ramp_is_c1_and_exact_outside_corners():
    s = np.linspace(-0.5, 1.5, 20001)
    r = smooth_ramp01(s, 0.05)
    outside = (np.abs(s) > 0.05) & (np.abs(s - 1) > 0.05)
    np.testing.assert_allclose(r[outside], np.clip(s[outside], 0, 1), atol=1e-15)
    d = np.diff(r) / np.diff(s)
    assert np.max(np.abs(np.diff(d))) < 0.01        # no jump in the slope
    np.testing.assert_array_equal(smooth_ramp01(s, 0.0), np.clip(s, 0, 1))


# ----------------------------------------------------------------------------- check valve

def test_check_valve_closed_below_cracking_except_leakage():
    p = CheckValveParams(cracking_pressure_pa=0.3e6, full_open_dp_pa=0.4e6, max_area_m2=3e-6,
                         leakage_area_m2=2e-10, opening_smoothing=0.05)
    v = CheckValve(p)
    band = p.opening_smoothing * p.full_open_dp_pa
    dp = np.linspace(0.15e6, p.cracking_pressure_pa - band, 7)   # Δp >> p_cr = 1e4
    q = v.flow_m3_s(P_TANK + dp, P_TANK, RHO)
    np.testing.assert_allclose(q, turbulent(dp, 2e-10), rtol=5e-3)
    np.testing.assert_array_equal(v.opening(dp), 0.0)
    # sharp corners: closed right up to the cracking pressure
    sharp = CheckValve(p.replace(opening_smoothing=0.0))
    assert sharp.opening(p.cracking_pressure_pa - 1.0) == 0.0
    no_leak = CheckValve(p.replace(leakage_enabled=False))
    np.testing.assert_array_equal(no_leak.flow_m3_s(P_TANK + dp, P_TANK, RHO), 0.0)


def test_check_valve_full_area_beyond_full_open_and_linear_between():
    p = CheckValveParams(cracking_pressure_pa=0.1e6, full_open_dp_pa=0.4e6, max_area_m2=3e-6,
                         leakage_area_m2=2e-10)
    v = CheckValve(p)
    band = p.opening_smoothing * p.full_open_dp_pa
    dp_full = np.array([0.5e6 + band, 1e6, 5e6])
    np.testing.assert_allclose(v.flow_m3_s(P_TANK + dp_full, P_TANK, RHO),
                               turbulent(dp_full, 3e-6), rtol=5e-3)
    dp_mid = np.linspace(0.1e6 + band, 0.5e6 - band, 9)
    area = 2e-10 + (3e-6 - 2e-10) * (dp_mid - 0.1e6) / 0.4e6
    np.testing.assert_allclose(v.area_m2(dp_mid), area, rtol=1e-12)
    np.testing.assert_allclose(v.flow_m3_s(P_TANK + dp_mid, P_TANK, RHO),
                               turbulent(dp_mid, area), rtol=5e-3)


def test_check_valve_reverse_flow_only_leakage():
    v = CheckValve(CheckValveParams(leakage_area_m2=2e-10))
    dp = -np.array([0.1e6, 1e6, 10e6])
    q = v.flow_m3_s(P_TANK + 10e6 + dp, P_TANK + 10e6, RHO)
    np.testing.assert_allclose(q, turbulent(dp, 2e-10), rtol=5e-3)
    assert np.all(q < 0)


# ----------------------------------------------------------------------------- relief valve

def test_relief_valve_flow_matches_analytic_characteristic():
    """The relief law (afo_mj.hydraulics.laws.relief_valve_area_m2, shared with the simulated
    circuits): seated below cracking, fully open from cracking + override, the cubic
    smoothstep s²(3 − 2s) of the normalised pressure between (written out here)."""
    p = ReliefValveParams(cracking_dp_pa=15e6, override_dp_pa=1.5e6, max_area_m2=2e-6,
                          leakage_area_m2=1e-10, opening_smoothing=0.0)
    v = ReliefValve(p)
    dp = np.linspace(1e6, 20e6, 96)
    u = np.clip((dp - 15e6) / 1.5e6, 0.0, 1.0)
    s = u * u * (3.0 - 2.0 * u)
    ref = turbulent(dp, 1e-10 + (2e-6 - 1e-10) * s)
    np.testing.assert_allclose(v.flow_m3_s(P_TANK + dp, P_TANK, RHO), ref, rtol=1e-4)
    # seated (leakage only) up to cracking, full area from cracking + override on
    np.testing.assert_array_equal(v.opening(np.array([1e6, 14.99e6, 15e6])), 0.0)
    np.testing.assert_array_equal(v.opening(np.array([16.5e6, 17e6, 30e6])), 1.0)
    # opening_smoothing belongs to a linear ramp; the smoothstep law does not use it
    vs = ReliefValve(p.replace(opening_smoothing=0.05))
    np.testing.assert_array_equal(vs.flow_m3_s(P_TANK + dp, P_TANK, RHO),
                                  v.flow_m3_s(P_TANK + dp, P_TANK, RHO))
    # half open at cracking + half the override; a quarter of the way: 0.25²(3 − 0.5)
    assert v.opening(15.75e6) == pytest.approx(0.5)
    assert v.opening(15.375e6) == pytest.approx(0.15625)


def test_relief_valve_reverse_and_leakage_switch():
    p = ReliefValveParams(leakage_area_m2=1e-10)
    q = ReliefValve(p).flow_m3_s(P_TANK, P_TANK + 5e6, RHO)
    assert q == pytest.approx(float(turbulent(-5e6, 1e-10)), rel=5e-3)
    assert ReliefValve(p.replace(leakage_enabled=False)).flow_m3_s(10e6, P_TANK, RHO) == 0.0


# -------------------------------------------------------------------------- unloading valve

def _simulate_unloading(valve, pilot, dt):
    x = np.zeros(pilot.shape[1])
    out = np.empty_like(pilot)
    for i, pp in enumerate(pilot):
        out[i] = x
        x = x + dt * valve.position_rate(x, pp)
    return out


def test_unloading_valve_hysteresis_explicit_loop():
    p = UnloadingValveParams(cut_out_pressure_pa=14e6, cut_in_pressure_pa=12e6,
                             time_constant_s=5e-3, switching_band_pa=0.1e6)
    v = UnloadingValve(p)
    dt = 5e-4
    t = np.arange(0.0, 2.0, dt)
    pilot = np.where(t < 1.0, 10e6 + 6e6 * t, 16e6 - 6e6 * (t - 1.0))   # up to 16, down to 10
    x = _simulate_unloading(v, pilot[:, None], dt)[:, 0]
    # hand-written relay: open once pilot >= cut-out, close once pilot <= cut-in
    relay = np.zeros_like(t)
    state = 0.0
    for i, pp in enumerate(pilot):
        state = 1.0 if pp >= 14e6 else (0.0 if pp <= 12e6 else state)
        relay[i] = state
    lag = 8 * p.time_constant_s * 6e6        # pilot travel within 8 τ of a switch (+ band)
    settled = ((np.abs(pilot - 14e6) > lag + 0.1e6) & (np.abs(pilot - 12e6) > lag + 0.1e6))
    np.testing.assert_allclose(x[settled], relay[settled], atol=1e-3)
    # it is open on the way down between cut-in and cut-out, closed on the way up there
    between = (pilot > 12.3e6) & (pilot < 13.7e6)
    assert np.all(x[between & (t > 1.0)] > 0.999)
    assert np.all(x[between & (t < 1.0)] < 1e-3)


def test_unloading_valve_holds_in_band_and_without_hysteresis():
    v = UnloadingValve(UnloadingValveParams(cut_out_pressure_pa=14e6, cut_in_pressure_pa=12e6))
    x = np.linspace(0.0, 1.0, 5)
    np.testing.assert_array_equal(v.position_rate(x, np.full(5, 13e6)), 0.0)
    tau = v.params.time_constant_s
    np.testing.assert_allclose(v.position_rate(x, 15e6), (1 - x) / tau)
    np.testing.assert_allclose(v.position_rate(x, 11e6), -x / tau)
    nh = UnloadingValve(v.params.replace(hysteresis_enabled=False))
    np.testing.assert_allclose(nh.position_rate(x, 13e6), -x / tau)   # closes below cut-out
    sharp = UnloadingValve(v.params.replace(switching_band_pa=0.0))
    assert sharp.position_rate(0.0, 14e6) == pytest.approx(1 / tau)
    assert sharp.position_rate(0.0, 14e6 - 1.0) == 0.0
    assert sharp.position_rate(1.0, 12e6) == pytest.approx(-1 / tau)
    assert sharp.position_rate(1.0, 12e6 + 1.0) == 0.0


def test_unloading_valve_flow():
    p = UnloadingValveParams(max_area_m2=5e-6, leakage_area_m2=1e-10)
    v = UnloadingValve(p)
    dp = np.array([0.2e6, 2e6, 14e6])
    np.testing.assert_allclose(v.flow_m3_s(np.ones(3), P_TANK + dp, P_TANK, RHO),
                               turbulent(dp, 5e-6), rtol=5e-3)
    np.testing.assert_allclose(v.flow_m3_s(np.zeros(3), P_TANK + dp, P_TANK, RHO),
                               turbulent(dp, 1e-10), rtol=5e-3)
    np.testing.assert_allclose(v.flow_m3_s(0.5, P_TANK + dp, P_TANK, RHO),
                               turbulent(dp, 1e-10 + 0.5 * (5e-6 - 1e-10)), rtol=5e-3)


# ------------------------------------------------------------------------------ servo valve

def _servo(**kw):
    base = dict(rated_flow_m3_s=4 / 60e3, rated_dp_pa=7e6, rated_density_kg_m3=RHO,
                natural_frequency_hz=150.0, damping_ratio=0.7, spool_max_m=0.3e-3,
                overlap_m=0.0, leakage_flow_m3_s=0.2 / 60e3, leakage_supply_dp_pa=21e6)
    base.update(kw)
    return ServoValve(ServoValveParams(**base))


@pytest.mark.parametrize("overlap", [0.0, 0.05e-3, -0.03e-3])
def test_servo_rated_load_flow(overlap):
    v = _servo(overlap_m=overlap)
    pp, pt = P_TANK + 7e6, P_TANK
    mid = 0.5 * (pp + pt)                 # load shorted: 3.5 MPa per land
    qa, qb, qp, qt = v.flows_m3_s(np.array([0.3e-3, -0.3e-3]), pp, pt, mid, mid, RHO)
    np.testing.assert_allclose(qa, [4 / 60e3, -4 / 60e3], rtol=1e-2)
    np.testing.assert_allclose(qb, [-4 / 60e3, 4 / 60e3], rtol=1e-2)
    np.testing.assert_allclose(qp - qt, qa + qb, rtol=0, atol=1e-15)


def test_servo_area_gradient_by_hand():
    v = _servo()
    w = (4 / 60e3) / (0.3e-3 * 0.61 * math.sqrt(7e6 / RHO))
    assert v.area_gradient_m == pytest.approx(w, rel=1e-3)
    a_pa, a_at, a_pb, a_bt = v.edge_areas_m2(np.array([0.1e-3, -0.2e-3, 1e-3]))
    leak = v.leakage_area_m2
    np.testing.assert_allclose(a_pa, [w * 0.1e-3 + leak, leak, w * 0.3e-3 + leak], rtol=1e-3)
    np.testing.assert_allclose(a_at, [leak, w * 0.2e-3 + leak, leak], rtol=1e-3)
    np.testing.assert_array_equal(a_pa, a_bt)
    np.testing.assert_array_equal(a_at, a_pb)


def test_servo_overlap_dead_band_passes_only_leakage():
    o = 0.05e-3
    v = _servo(overlap_m=o)
    pp, pt, pa, pb = P_TANK + 14e6, P_TANK, 9e6, 4e6
    x = np.linspace(-0.99 * o, 0.99 * o, 11)
    qa, qb, qp, qt = v.flows_m3_s(x, pp, pt, pa, pb, RHO)
    leak = (0.2 / 60e3) / (2 * 0.61 * math.sqrt(21e6 / RHO))      # per edge, by hand
    np.testing.assert_allclose(qa, turbulent(pp - pa, leak) - turbulent(pa - pt, leak), rtol=2e-2)
    np.testing.assert_allclose(qp, turbulent(pp - pa, leak) + turbulent(pp - pb, leak), rtol=2e-2)
    no_leak = _servo(overlap_m=o, leakage_enabled=False)
    for q in no_leak.flows_m3_s(x, pp, pt, pa, pb, RHO):
        np.testing.assert_array_equal(q, 0.0)
    # the overlap switch: critical centre opens at once
    crit = _servo(overlap_m=o, overlap_enabled=False, leakage_enabled=False)
    assert crit.flows_m3_s(0.5 * o, pp, pt, pa, pb, RHO)[0] > 0


def test_servo_centre_leakage_blocked_ports():
    v = _servo()
    pp, pt = P_TANK + 21e6, P_TANK
    pa = brentq(lambda p: float(v.flows_m3_s(0.0, pp, pt, p, 0.5 * (pp + pt), RHO)[0]), pt, pp,
                xtol=1.0)
    pb = brentq(lambda p: float(v.flows_m3_s(0.0, pp, pt, pa, p, RHO)[1]), pt, pp, xtol=1.0)
    qp = float(v.flows_m3_s(0.0, pp, pt, pa, pb, RHO)[2])
    assert qp == pytest.approx(0.2 / 60e3, rel=5e-2)


def _rk4_spool(valve, command, t_end, dt):
    n = int(round(t_end / dt))
    x = np.zeros(np.shape(command(0.0)))
    v = np.zeros_like(x)
    xs = np.empty((n + 1,) + x.shape)
    xs[0] = x
    for i in range(n):
        t = i * dt
        k1 = valve.spool_derivatives(x, v, command(t))
        k2 = valve.spool_derivatives(x + dt / 2 * k1[0], v + dt / 2 * k1[1], command(t + dt / 2))
        k3 = valve.spool_derivatives(x + dt / 2 * k2[0], v + dt / 2 * k2[1], command(t + dt / 2))
        k4 = valve.spool_derivatives(x + dt * k3[0], v + dt * k3[1], command(t + dt))
        x = x + dt / 6 * (k1[0] + 2 * k2[0] + 2 * k3[0] + k4[0])
        v = v + dt / 6 * (k1[1] + 2 * k2[1] + 2 * k3[1] + k4[1])
        xs[i + 1] = x
    return xs


@pytest.mark.parametrize("zeta", [0.4, 0.7])
def test_servo_spool_bode_magnitude_at_natural_frequency(zeta):
    fn = 150.0
    v = _servo(natural_frequency_hz=fn, damping_ratio=zeta)
    amp = 0.1
    periods = 30
    dt = 1 / fn / 200
    xs = _rk4_spool(v, lambda t: amp * np.sin(2 * math.pi * fn * t), periods / fn, dt)
    t = np.arange(xs.shape[0]) * dt
    last = t >= (periods - 5) / fn                       # transient gone (e^-ζω t tiny)
    basis = np.column_stack([np.sin(2 * math.pi * fn * t[last]),
                             np.cos(2 * math.pi * fn * t[last])])
    coef, *_ = np.linalg.lstsq(basis, xs[last], rcond=None)
    gain = math.hypot(*coef) / (amp * 0.3e-3)
    assert gain == pytest.approx(1 / (2 * zeta), rel=2e-2)
    # phase lag of a 2nd-order system at ω_n is 90°: x ∝ -cos
    assert abs(coef[0]) < 0.02 * abs(coef[1]) and coef[1] < 0


def test_servo_spool_step_overshoot_and_saturation():
    zeta = 0.5
    v = _servo(natural_frequency_hz=150.0, damping_ratio=zeta)
    xs = _rk4_spool(v, lambda t: np.array([0.5, 3.0]), 0.05, 1 / 150 / 200)
    overshoot = xs[:, 0].max() / (0.5 * 0.3e-3) - 1
    assert overshoot == pytest.approx(math.exp(-zeta * math.pi / math.sqrt(1 - zeta ** 2)),
                                      rel=1e-2)
    assert xs[-1, 1] == pytest.approx(0.3e-3, rel=1e-4)    # command 3 saturates at full stroke


# --------------------------------------------------------------------------- on/off valve

def _pwm_volume(valve, duties, freq, dt, dp=10e6):
    """Euler integration of x, trapezoid of Q over one period; also volume in the on-window."""
    period = 1 / freq
    n = int(round(period / dt))
    x = np.zeros_like(duties)
    q_prev = valve.flow_m3_s(x, P_TANK + dp, P_TANK, RHO)
    vol = np.zeros_like(duties)
    vol_on = np.zeros_like(duties)
    for i in range(n):
        t = i * dt
        x = x + dt * valve.position_rate(x, pwm_command(t, duties, freq))
        q = valve.flow_m3_s(x, P_TANK + dp, P_TANK, RHO)
        dv = 0.5 * dt * (q + q_prev)
        vol += dv
        vol_on += np.where(t + dt <= duties * period + 1e-12, dv, 0.0)
        q_prev = q
    return vol, vol_on


def test_onoff_pwm_average_with_negligible_switching_time():
    valve = OnOffValve(OnOffValveParams(switching_time_s=2e-5, approach_time_constant_s=1e-6,
                                        leakage_enabled=False))
    duties = np.array([0.1, 0.3, 0.5, 0.8])
    freq = 50.0
    vol, _ = _pwm_volume(valve, duties, freq, 1e-6)
    q_full = float(turbulent(10e6, valve.params.max_area_m2))
    np.testing.assert_allclose(vol * freq, duties * q_full, rtol=2e-2)


def test_onoff_pwm_finite_switching_time_ramp_volumes():
    ts, tau = 2e-3, 1e-4
    valve = OnOffValve(OnOffValveParams(switching_time_s=ts, approach_time_constant_s=tau,
                                        leakage_enabled=False))
    duties = np.array([0.2, 0.5, 0.7])
    freq = 50.0
    vol, vol_on = _pwm_volume(valve, duties, freq, 1e-6)
    q_full = float(turbulent(10e6, valve.params.max_area_m2))
    # opening: half a switching time of full flow missed (+ τ²/2T from the settling tail)
    missed = q_full * (ts / 2 + tau ** 2 / (2 * ts))
    np.testing.assert_allclose(duties / freq * q_full - vol_on, missed, rtol=2e-2)
    assert np.all(vol_on < duties / freq * q_full)
    # closing lags by the same amount, so the whole-period average is D·Q_full
    np.testing.assert_allclose(vol * freq, duties * q_full, rtol=2e-3)


def test_onoff_position_rate_limits_and_pwm_command():
    valve = OnOffValve(OnOffValveParams(switching_time_s=2e-3, approach_time_constant_s=1e-4))
    x = np.array([0.0, 0.5, 0.99995, 1.0, 0.3])
    r = valve.position_rate(x, np.array([1.0, 1.0, 1.0, 0.0, 0.0]))
    np.testing.assert_allclose(r, [500.0, 500.0, 0.5, -500.0, -500.0])
    t = np.arange(0.0, 1.0, 1e-5)
    cmd = pwm_command(t, 0.3, 40.0)
    assert cmd.mean() == pytest.approx(0.3, abs=1e-3)
    assert np.count_nonzero(np.diff(cmd) != 0) in (79, 80)         # 2 f events per second
    np.testing.assert_array_equal(pwm_command([0.0, 0.004, 0.006, 0.011], 0.5, 100.0),
                                  [1.0, 1.0, 0.0, 1.0])


def test_onoff_actuator_power():
    valve = OnOffValve(OnOffValveParams(switching_energy_j=0.05, holding_power_w=2.0))
    np.testing.assert_allclose(valve.actuator_power_w(np.array([0.0, 1.0]), np.array([100.0, 0.0])),
                               [5.0, 2.0])
    np.testing.assert_allclose(valve.pwm_actuator_power_w(np.array([0.0, 0.4, 1.0]), 50.0),
                               [0.0, 2.0 * 0.4 + 0.05 * 100, 2.0])
    # transition heat: ½ Δp Q_open T_sw by hand
    q_open = float(turbulent(10e6, 2e-6, rho=879.0))
    assert valve.transition_heat_j(10e6, 879.0) == pytest.approx(0.5 * 10e6 * q_open * 2e-3,
                                                                 rel=5e-3)


def test_onoff_flow_by_position():
    valve = OnOffValve(OnOffValveParams(max_area_m2=2e-6, leakage_area_m2=1e-11))
    dp = 10e6
    q = valve.flow_m3_s(np.array([0.0, 0.25, 1.0, 1.2]), P_TANK + dp, P_TANK, RHO)
    np.testing.assert_allclose(
        q, turbulent(dp, np.array([1e-11, 1e-11 + 0.25 * (2e-6 - 1e-11), 2e-6, 2e-6])), rtol=5e-3)


# ------------------------------------------------------------------------- power balances

_RNG = np.random.default_rng(7)
_PIN = _RNG.uniform(0.05e6, 20e6, 64)
_POUT = _RNG.uniform(0.05e6, 20e6, 64)
_X01 = _RNG.uniform(-0.1, 1.1, 64)


@pytest.mark.parametrize("make", [
    lambda: Orifice().power(_PIN, _POUT, RHO),
    lambda: CheckValve().power(_PIN, _POUT, RHO),
    lambda: ReliefValve(ReliefValveParams(cracking_dp_pa=5e6)).power(_PIN, _POUT, RHO),
    lambda: UnloadingValve().power(_X01, _PIN, _POUT, RHO),
    lambda: OnOffValve().power(_X01, _PIN, _POUT, RHO),
], ids=["orifice", "check", "relief", "unloading", "onoff"])
def test_two_port_power_balance(make):
    pf = make()
    assert np.shape(pf.in_w) == (64,)
    _assert_balanced(pf)


def test_servo_power_balance_and_port_power():
    v = _servo(overlap_m=-0.02e-3)
    x = _RNG.uniform(-0.35e-3, 0.35e-3, 64)
    pp = _RNG.uniform(5e6, 21e6, 64)
    pt = np.full(64, P_TANK)
    pa = _RNG.uniform(0.05e6, 22e6, 64)
    pb = _RNG.uniform(0.05e6, 22e6, 64)
    pf = v.power(x, pp, pt, pa, pb, RHO)
    _assert_balanced(pf)
    qa, qb, qp, qt = v.flows_m3_s(x, pp, pt, pa, pb, RHO)
    np.testing.assert_allclose(pf.heat_w, pp * qp - pt * qt - pa * qa - pb * qb,
                               rtol=1e-9, atol=1e-9 * np.max(np.abs(pf.in_w)))


def test_vectorised_shapes():
    k = 5
    dp = np.linspace(-1e6, 5e6, k)
    x = np.linspace(0, 1, k)
    pilot = np.linspace(10e6, 16e6, k)
    assert CheckValve().opening(dp).shape == (k,)
    assert ReliefValve().area_m2(dp).shape == (k,)
    assert UnloadingValve().position_rate(x, pilot).shape == (k,)
    assert UnloadingValve().flow_m3_s(x, P_TANK + dp, P_TANK, RHO).shape == (k,)
    sv = _servo()
    xs = np.linspace(-0.3e-3, 0.3e-3, k)
    dx, dv = sv.spool_derivatives(xs, np.zeros(k), np.linspace(-1, 1, k))
    assert dx.shape == dv.shape == (k,)
    assert all(a.shape == (k,) for a in sv.edge_areas_m2(xs))
    assert all(q.shape == (k,) for q in sv.flows_m3_s(xs, 10e6, P_TANK, 5e6, 4e6, RHO))
    ov = OnOffValve()
    assert ov.position_rate(x, np.ones(k)).shape == (k,)
    assert pwm_command(np.linspace(0, 0.1, k), 0.5, 20.0).shape == (k,)


# ------------------------------------------------------------------------------ bad inputs

@pytest.mark.parametrize("factory, field", [
    (lambda: OrificeParams(area_m2=0.0), "area_m2"),
    (lambda: OrificeParams(discharge_coefficient=1.2), "discharge_coefficient"),
    (lambda: OrificeParams(discharge_coefficient=0.0), "discharge_coefficient"),
    (lambda: OrificeParams(transition_pressure_pa=0.0), "transition_pressure_pa"),
    (lambda: CheckValveParams(cracking_pressure_pa=-1.0), "cracking_pressure_pa"),
    (lambda: CheckValveParams(full_open_dp_pa=0.0), "full_open_dp_pa"),
    (lambda: CheckValveParams(max_area_m2=0.0), "max_area_m2"),
    (lambda: CheckValveParams(leakage_area_m2=-1e-9), "leakage_area_m2"),
    (lambda: CheckValveParams(leakage_area_m2=3e-6, max_area_m2=3e-6), "leakage_area_m2"),
    (lambda: CheckValveParams(opening_smoothing=0.5), "opening_smoothing"),
    (lambda: CheckValveParams(leakage_enabled="yes"), "leakage_enabled"),
    (lambda: ReliefValveParams(cracking_dp_pa=0.0), "cracking_dp_pa"),
    (lambda: ReliefValveParams(override_dp_pa=0.0), "override_dp_pa"),
    (lambda: ReliefValveParams(leakage_area_m2=5e-6), "leakage_area_m2"),
    (lambda: ReliefValveParams(cracking_dp_pa=1e4, override_dp_pa=1e6), "opening_smoothing"),
    (lambda: ReliefValveParams(discharge_coefficient=-0.1), "discharge_coefficient"),
    (lambda: UnloadingValveParams(cut_in_pressure_pa=14.1e6), "cut_in_pressure_pa"),
    (lambda: UnloadingValveParams(cut_in_pressure_pa=15e6), "cut_in_pressure_pa"),
    (lambda: UnloadingValveParams(switching_band_pa=1e6), "switching_band_pa"),
    (lambda: UnloadingValveParams(time_constant_s=0.0), "time_constant_s"),
    (lambda: UnloadingValveParams(leakage_area_m2=1e-5), "leakage_area_m2"),
    (lambda: UnloadingValveParams(cut_out_pressure_pa=-1.0), "cut_out_pressure_pa"),
    (lambda: UnloadingValveParams(hysteresis_enabled=1), "hysteresis_enabled"),
    (lambda: ServoValveParams(overlap_m=0.3e-3), "overlap_m"),
    (lambda: ServoValveParams(overlap_m=-0.4e-3), "overlap_m"),
    (lambda: ServoValveParams(spool_max_m=0.0), "spool_max_m"),
    (lambda: ServoValveParams(damping_ratio=0.0), "damping_ratio"),
    (lambda: ServoValveParams(natural_frequency_hz=0.0), "natural_frequency_hz"),
    (lambda: ServoValveParams(rated_flow_m3_s=0.0), "rated_flow_m3_s"),
    (lambda: ServoValveParams(rated_dp_pa=-7e6), "rated_dp_pa"),
    (lambda: ServoValveParams(leakage_flow_m3_s=1e-3), "leakage_flow_m3_s"),
    (lambda: ServoValveParams(leakage_flow_m3_s=-1e-6), "leakage_flow_m3_s"),
    (lambda: ServoValveParams(opening_smoothing_m=0.2e-3), "opening_smoothing_m"),
    (lambda: ServoValveParams(overlap_enabled=None), "overlap_enabled"),
    (lambda: OnOffValveParams(switching_time_s=0.0), "switching_time_s"),
    (lambda: OnOffValveParams(approach_time_constant_s=2e-3), "approach_time_constant_s"),
    (lambda: OnOffValveParams(leakage_area_m2=2e-6), "leakage_area_m2"),
    (lambda: OnOffValveParams(switching_energy_j=-0.01), "switching_energy_j"),
    (lambda: OnOffValveParams(holding_power_w=-1.0), "holding_power_w"),
    (lambda: OnOffValveParams(max_area_m2=float("nan")), "max_area_m2"),
])
def test_bad_parameters_raise_naming_field(factory, field):
    _raises_naming(factory, field)
