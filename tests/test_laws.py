"""The compiled component laws (:mod:`afo_mj.hydraulics.laws`) against independent references.

References are hand calculations written out here (textbook formulas in their own form: the
mixture definition of the bulk modulus, Poiseuille's profile, Darcy–Weisbach, the defining
equation of Walther's law, a Stribeck peak at the breakaway speed …), the numbers of
``shared/reference/facts.md``, scipy root finding and quadrature on the laws' inverses and
integrals, finite differences for the laws that are derivatives of others, and ``np.interp``.
Never the code's own outputs.

Also: every law gives the same value called with scalars from an ``@numba.njit`` function and
with numpy arrays; and no module of the package but the laws (and the two old hand-written
kernels, exempt until the generated circuits replace them) defines a function named like a law
or like one of the copies that existed before the laws.
"""

from __future__ import annotations

import ast
import math
from pathlib import Path

import numba
import numpy as np
import pytest
from scipy.integrate import quad
from scipy.optimize import brentq

from afo_mj.hydraulics import laws as L

ROOT = Path(__file__).resolve().parents[1]
D_REV = 0.2e-6 / (2.0 * math.pi)          # 0.2 cm³/rev per radian


# ----------------------------------------------------------------------- smoothing functions

def test_smoothstep_and_ramp_hand_values():
    assert L.smoothstep01(0.5) == 0.5
    assert L.smoothstep01(0.25) == pytest.approx(0.25 ** 2 * (3 - 0.5), rel=1e-15)
    assert L.smoothstep01(-3.0) == 0.0 and L.smoothstep01(7.0) == 1.0
    # zero slope at both ends (C¹): (f(h) - f(0))/h → 0
    h = 1e-6
    assert L.smoothstep01(h) / h < 1e-5 and (1.0 - L.smoothstep01(1 - h)) / h < 1e-5
    assert L.ramp_c1(1.0, 4.0) == 1.0 / 8.0            # x²/(2b)
    assert L.ramp_c1(10.0, 4.0) == 8.0                  # x − b/2
    assert L.ramp_c1(-2.0, 4.0) == 0.0
    # value and slope continuous at x = b: b/2 and 1 from both sides
    b = 4.0
    assert L.ramp_c1(b - 1e-9, b) == pytest.approx(b / 2, abs=1e-8)
    assert (L.ramp_c1(b + 1e-6, b) - L.ramp_c1(b - 1e-6, b)) / 2e-6 == pytest.approx(1, rel=1e-6)


def test_soft_clip_is_a_smooth_min_max():
    r = 0.05
    # far from the corners: the hard clip, off by r²/(4 d) (hyperbola's asymptote)
    for x, ref in ((5.0, 1.0), (-5.0, -1.0), (0.3, 0.3)):
        d = min(abs(x - 1.0), abs(x + 1.0))
        assert L.soft_clip(x, -1.0, 1.0, r) == pytest.approx(ref, abs=r * r / (4 * d) * 1.01)
    assert L.soft_clip(0.0, -1.0, 1.0, r) == pytest.approx(0.0, abs=1e-3)
    # at a corner the hyperbola passes r/2 beyond it: lo + ½(0 + r) (the other end 1000 away
    # moves it by r²/4000 = 6e-7)
    assert L.soft_clip(-1.0, -1.0, 1e3, r) == pytest.approx(-1.0 + r / 2, abs=1e-6)
    assert L.soft_clip(1.0, -1e3, 1.0, r) == pytest.approx(1.0 - r / 2, abs=1e-6)
    # radius 0: exactly the hard clip
    xs = np.linspace(-3, 3, 61)
    np.testing.assert_array_equal(L.soft_clip(xs, -1.0, 1.0, 0.0), np.clip(xs, -1.0, 1.0))
    # monotone and C¹ (no jump in the finite-difference slope)
    x = np.linspace(-1.5, 1.5, 30001)
    y = L.soft_clip(x, -1.0, 1.0, r)
    slope = np.diff(y) / np.diff(x)
    assert np.all(slope >= 0) and np.max(np.abs(np.diff(slope))) < 0.01
    assert L.smooth_abs(3.0, 4.0) == 5.0 and L.smooth_abs(-3.0, 0.0) == 3.0


# ------------------------------------------------------------------------------------ fluid

@pytest.mark.parametrize("p_abs, expected_gpa", [(1e6, 0.49), (3e6, 1.14)])
def test_bulk_modulus_facts(p_abs, expected_gpa):
    """shared/reference/facts.md: B_L 1.5 GPa, α 0.01, n 1.4 → 0.49 GPa at 1 MPa abs and
    1.14 GPa at 3 MPa abs (two decimals)."""
    b = L.bulk_modulus_pa(p_abs, 1.5e9, 0.01, 1.4, 101325.0) / 1e9
    assert b == pytest.approx(expected_gpa, abs=0.006)


def test_bulk_modulus_is_the_mixtures_definition():
    """B = −V dp/dV of a unit liquid volume (compressibility 1/B_L) carrying the gas volume
    α (p_a/p)^(1/n) (polytropic): the derivative taken by central difference here."""
    pa, bl = 101325.0, 1.5e9
    for alpha, n, p in ((0.01, 1.4, 1e6), (0.005, 1.0, 0.3e6), (0.02, 1.2, 8e6)):
        def volume(q, p=p, alpha=alpha, n=n):
            return math.exp(-(q - p) / bl) + alpha * (pa / q) ** (1.0 / n)
        h = 1e-4 * p
        dvdp = (volume(p + h) - volume(p - h)) / (2 * h)
        assert L.bulk_modulus_pa(p, bl, alpha, n, pa) == pytest.approx(-volume(p) / dvdp,
                                                                       rel=1e-6)
    assert L.bulk_modulus_pa(2e6, bl, 0.0, 1.4, pa) == bl


def test_mean_compliance_is_the_integral_of_one_over_b():
    """(∫ dp/B)/(p1 − p0) by scipy quadrature of the bulk-modulus law (clamped at the floor,
    the kink given to quad), in either order; a zero-width interval gives 1/B(p); the example."""
    pa, bl, fl = 101325.0, 1.5e9, 2e3
    for alpha, n, p0, p1 in ((0.01, 1.4, 0.4e6, 4.6e6), (0.01, 1.4, 4.6e6, 0.4e6),
                             (0.05, 1.2, 2e3, 1e7), (0.1, 1.0, 1e3, 3e5),
                             (0.01, 1.4, 500.0, 1500.0), (0.0, 1.4, 1e5, 2e7),
                             (0.01, 1.4, 3e5, 3e5 + 1.0), (0.05, 1.2, 1.1e5, 2.2e5),
                             (0.01, 1.4, 2.05e6, 1.0e6), (0.2, 1.0, 3e3, 5.5e3)):
        def inv_b(p, alpha=alpha, n=n):
            return 1.0 / L.bulk_modulus_pa(max(p, fl), bl, alpha, n, pa)
        lo, hi = min(p0, p1), max(p0, p1)
        ref = quad(inv_b, lo, hi, points=[fl] if lo < fl < hi else None, epsabs=0.0,
                   epsrel=1e-12, limit=400)[0] / (hi - lo)
        got = L.oil_mean_compliance_per_pa(p0, p1, bl, alpha, n, pa, fl)
        assert got == pytest.approx(ref, rel=5e-5), (alpha, n, p0, p1)
    # narrow intervals (p1/p0 <= 1.05) take the midpoint rule: within 5e-4 of the integral
    for alpha, n, p0, p1 in ((0.01, 1.4, 1e5, 1.049e5), (0.05, 1.2, 2.1e3, 2.2e3),
                             (0.01, 1.4, 4.0e6, 3.9e6), (0.001, 1.4, 2e5, 2.1e5)):
        def inv_b(p, alpha=alpha, n=n):
            return 1.0 / L.bulk_modulus_pa(max(p, fl), bl, alpha, n, pa)
        lo, hi = min(p0, p1), max(p0, p1)
        ref = quad(inv_b, lo, hi, epsabs=0.0, epsrel=1e-12)[0] / (hi - lo)
        got = L.oil_mean_compliance_per_pa(p0, p1, bl, alpha, n, pa, fl)
        assert got == pytest.approx(ref, rel=5e-4), (alpha, n, p0, p1)
        assert got == L.oil_mean_compliance_per_pa(p1, p0, bl, alpha, n, pa, fl)
    for p in (1e3, 0.2e6, 5e6):
        assert L.oil_mean_compliance_per_pa(p, p, bl, 0.01, 1.4, pa, fl) == \
            1.0 / L.bulk_modulus_pa(max(p, fl), bl, 0.01, 1.4, pa)
    # a tiny interval: the mean → the point value (no cancellation in the gas term)
    p = 0.2e6
    tiny = L.oil_mean_compliance_per_pa(p, p * (1 + 1e-10), bl, 0.01, 1.4, pa, fl)
    assert tiny == pytest.approx(1.0 / L.bulk_modulus_pa(p, bl, 0.01, 1.4, pa), rel=1e-8)
    assert L.oil_mean_compliance_per_pa(0.4e6, 4.6e6, bl, 0.01, 1.4, pa, fl) == pytest.approx(
        1.401e-9, rel=1e-3)


def test_walther_satisfies_astm_d341():
    """log10 log10(ν[cSt] + 0.7) = b − c log10 T, checked backwards from the law's ν."""
    b, c = 9.32, 3.65
    for t in (273.15, 313.15, 373.15):
        nu = L.walther_viscosity_m2_s(t, b, c)
        assert math.log10(math.log10(nu * 1e6 + 0.7)) == pytest.approx(b - c * math.log10(t),
                                                                         rel=1e-12)
    assert L.walther_viscosity_m2_s(313.15, 9.32, 3.65) == pytest.approx(4.13e-5, rel=0.01)


def test_density_conserves_mass_and_viscosity_is_their_product():
    # volume grows as 1 + β ΔT at constant mass: ρ(T) (1 + β ΔT) = ρ0
    rho = L.oil_density_kg_m3(311.0, 875.0, 7e-4, 288.15)
    assert rho * (1 + 7e-4 * (311.0 - 288.15)) == pytest.approx(875.0, rel=1e-14)
    assert rho == pytest.approx(861.2, abs=0.1)
    nu = (10 ** (10 ** (9.5 - 3.7 * math.log10(330.0))) - 0.7) * 1e-6
    assert L.dynamic_viscosity_pa_s(330.0, 9.5, 3.7, 875.0, 7e-4, 288.15) == pytest.approx(
        875.0 / (1 + 7e-4 * (330.0 - 288.15)) * nu, rel=1e-12)


def test_node_capacitance_and_cavitation_factor():
    assert L.node_capacitance_m3_pa(1e-6, 1.5e9, 0.0, 0.0) == pytest.approx(6.667e-16, rel=1e-3)
    # hose wall: ΔV = V_w Δp / K_wall on top of the oil's V Δp / B
    assert L.node_capacitance_m3_pa(2e-6, 1.5e9, 3e-6, 1 / 0.5e9) == pytest.approx(
        2e-6 / 1.5e9 + 3e-6 / 0.5e9, rel=1e-14)
    assert L.cavitation_factor(1e6, 2e3, 2e4) == 1.0
    assert L.cavitation_factor(2e3, 2e3, 2e4) == pytest.approx(1e-4, rel=1e-12)
    assert L.cavitation_factor(12e3, 2e3, 2e4) == pytest.approx(1e-4 + (1 - 1e-4) * 0.5)


# ---------------------------------------------------------------------- conduits, orifices

def test_reynolds_and_poiseuille():
    q, d, mu, rho = 1e-5, 4e-3, 0.04, 870.0
    v = q / (math.pi * d * d / 4)
    assert L.pipe_reynolds_number(-q, d, mu, rho) == pytest.approx(rho * v * d / mu, rel=1e-14)
    # Poiseuille: Q = π R⁴ Δp / (8 μ L)
    radius = d / 2
    assert L.laminar_resistance_pa_s_m3(1.0, d, mu) == pytest.approx(
        8 * mu * 1.0 / (math.pi * radius ** 4), rel=1e-14)
    assert L.laminar_resistance_pa_s_m3(1.0, d, mu) == pytest.approx(6.366e9, rel=1e-4)


def test_friction_factor_blasius_haaland_and_blend():
    assert L.friction_factor_ratio(1500.0, 0.0) == 1.0
    assert L.friction_factor_ratio(-2000.0, 1e-3) == 1.0
    re = 1e4
    assert L.friction_factor_ratio(re, 0.0) == pytest.approx(0.3164 * re ** -0.25 * re / 64,
                                                             rel=1e-13)
    assert L.friction_factor_ratio(re, 0.0) == pytest.approx(4.944, rel=1e-3)
    eps = 1e-3
    f_h = 1.0 / (-1.8 * math.log10((eps / 3.7) ** 1.11 + 6.9 / re)) ** 2
    assert L.friction_factor_ratio(re, eps) == pytest.approx(f_h * re / 64, rel=1e-13)
    # Haaland approximates Colebrook (solved here) to about 2 %
    def colebrook(x):
        return 1.0 / math.sqrt(x) + 2.0 * math.log10(eps / 3.7 + 2.51 / (re * math.sqrt(x)))
    f_c = brentq(colebrook, 1e-3, 0.2, xtol=1e-14)
    assert f_h == pytest.approx(f_c, rel=0.02)
    # blend: continuous at both ends of 2000…4000, and Δp ∝ φ Re rising through it
    r = np.linspace(1990.0, 4010.0, 20201)
    phi = L.friction_factor_ratio(r, 0.0)
    assert np.max(np.abs(np.diff(phi))) < 1e-3
    assert np.all(np.diff(phi * r) > 0)


def test_hose_loss_darcy_weisbach():
    length, d, rho = 2.0, 4e-3, 1000.0
    mu = 1e-3
    # laminar (Re 64): Hagen–Poiseuille
    q = 5e-8
    assert L.hose_pressure_loss_pa(q, length, d, mu, rho, 0.0, 1.0) == pytest.approx(
        128 * mu * length * q / (math.pi * d ** 4), rel=1e-13)
    # turbulent, Re = 1e4: Δp = f (L/D) ρ v²/2 with Blasius' f
    re = 1e4
    q = re * mu / rho * math.pi * d / 4
    v = q / (math.pi * d * d / 4)
    dp = 0.3164 * re ** -0.25 * length / d * rho * v * v / 2
    assert L.hose_pressure_loss_pa(q, length, d, mu, rho, 0.0, 1.0) == pytest.approx(dp, rel=1e-12)
    assert L.hose_pressure_loss_pa(-q, length, d, mu, rho, 0.0, 1.0) == pytest.approx(-dp,
                                                                                     rel=1e-12)
    # turbulence off: laminar whatever the Reynolds number
    assert L.hose_pressure_loss_pa(q, length, d, mu, rho, 0.0, 0.0) == pytest.approx(
        128 * mu * length * q / (math.pi * d ** 4), rel=1e-13)


@pytest.mark.parametrize("rough", [0.0, 2e-3])
def test_hose_flow_inverts_the_loss(rough):
    """hose_flow_m3_s against scipy's brentq on hose_pressure_loss_pa, from laminar through the
    transition to turbulent, both directions."""
    length, d, mu, rho = 1.0, 4e-3, 1e-3, 870.0
    for dp in (-3e6, -2e4, -50.0, 0.0, 10.0, 500.0, 2e3, 8e3, 3e4, 1e5, 5e6):
        q_lam = dp / L.laminar_resistance_pa_s_m3(length, d, mu)
        if dp == 0.0:
            assert L.hose_flow_m3_s(dp, length, d, mu, rho, rough, 1.0) == 0.0
            continue
        ref = brentq(lambda q: L.hose_pressure_loss_pa(q, length, d, mu, rho, rough, 1.0) - dp,
                     min(0.0, q_lam), max(0.0, q_lam), xtol=1e-18, rtol=1e-14)
        got = L.hose_flow_m3_s(dp, length, d, mu, rho, rough, 1.0)
        assert got == pytest.approx(ref, rel=1e-9)
    # example of the docstring: 1 m, 4 mm, 0.04 Pa s → 1e-5 m³/s at 63.66 kPa (laminar)
    assert L.hose_flow_m3_s(63661.977, 1.0, 4e-3, 0.04, 870.0, 0.0, 1.0) == pytest.approx(
        1e-5, rel=1e-7)


def test_orifice_law_and_inverse():
    cd, a, rho = 0.61, 1e-6, 870.0
    # turbulent limit C_d A √(2 Δp/ρ), relative error (p_cr/Δp)²/4
    assert L.orifice_flow_m3_s(1e6, a, cd, rho, 1e3) == pytest.approx(
        cd * a * math.sqrt(2e6 / rho), rel=1e-6)
    assert L.orifice_flow_m3_s(1e6, a, cd, rho, 1e3) == pytest.approx(2.925e-5, rel=1e-3)
    assert L.orifice_flow_m3_s(-1e6, a, cd, rho, 1e3) == -L.orifice_flow_m3_s(1e6, a, cd, rho, 1e3)
    # laminar-like near zero: slope C_d A √(2/ρ) / √p_cr
    h = 1e-3
    assert L.orifice_flow_m3_s(h, a, cd, rho, 1e4) / h == pytest.approx(
        cd * a * math.sqrt(2 / rho) / math.sqrt(1e4), rel=1e-9)
    for q in (-3e-5, -1e-9, 2e-7, 5e-5):
        ref = brentq(lambda dp: L.orifice_flow_m3_s(dp, a, cd, rho, 1e4) - q, -1e9, 1e9,
                     xtol=1e-9, rtol=1e-14)
        assert L.orifice_dp_for_flow_pa(q, a, cd, rho, 1e4) == pytest.approx(ref, rel=1e-10)
    assert L.orifice_dp_for_flow_pa(0.0, a, cd, rho, 1e4) == 0.0


def test_laminar_gap_and_annulus():
    assert L.laminar_gap_flow_m3_s(10e6, 1e-15, 0.03) == pytest.approx(3.333e-7, rel=1e-3)
    # plane Poiseuille flow between plates, per unit width δ³ Δp/(12 μ L), times π D
    d, delta, length, mu, dp = 12e-3, 10e-6, 5e-3, 0.03, 5e6
    per_width = delta ** 3 * dp / (12 * mu * length)
    g = L.annular_gap_conductance_m3(d, delta, length)
    assert L.laminar_gap_flow_m3_s(dp, g, mu) == pytest.approx(per_width * math.pi * d, rel=1e-13)


# ------------------------------------------------------------------------------------ valves

def test_relief_and_valve_areas():
    crack, over, amax, leak = 14e6, 1e6, 2e-6, 1e-10
    assert L.relief_valve_area_m2(10e6, crack, over, amax, leak) == leak
    assert L.relief_valve_area_m2(14.5e6, crack, over, amax, leak) == pytest.approx(
        leak + 0.5 * (amax - leak), rel=1e-14)
    assert L.relief_valve_area_m2(14.25e6, crack, over, amax, leak) == pytest.approx(
        leak + 0.15625 * (amax - leak), rel=1e-14)
    assert L.relief_valve_area_m2(20e6, crack, over, amax, leak) == amax
    assert L.valve_opening_area_m2(0.25, 2e-6, 1e-11) == pytest.approx(
        1e-11 + 0.25 * (2e-6 - 1e-11))
    assert L.valve_opening_area_m2(-0.5, 2e-6, 1e-11) == 1e-11
    assert L.valve_opening_area_m2(1.5, 2e-6, 1e-11) == 2e-6


def test_check_valve_conductance():
    g, band = 1e-9, 2e4
    assert L.check_valve_flow_m3_s(1e5, g, 0.0, band) == pytest.approx(g * (1e5 - band / 2))
    assert L.check_valve_flow_m3_s(-1e5, g, 0.0, band) == 0.0
    assert L.check_valve_flow_m3_s(4e4, g, 5e4, band) == 0.0          # below cracking
    assert L.check_valve_flow_m3_s(5e4 + 1e4, g, 5e4, band) == pytest.approx(
        g * 1e4 ** 2 / (2 * band))



def test_shuttle_valve_feeds_the_lower_line_only():
    """Flushing valve: far from the shift band the lower line sees the whole conductance
    from the supply and the higher line none; at equal line pressures each gets half."""
    g, b = 5e-12, 5e4

    def flow(p_line, p_other, p_s):
        return L.shuttle_valve_flow_m3_s(L.shuttle_valve_share(p_line, p_other, b), p_line,
                                         p_s, g)
    assert flow(1.0e6, 2.0e6, 1.5e6) == pytest.approx(g * 0.5e6, rel=1e-12)
    assert abs(flow(2.0e6, 1.0e6, 1.5e6)) < 1e-12 * g * 0.5e6
    assert flow(1.2e6, 1.2e6, 1.5e6) == pytest.approx(0.5 * g * 0.3e6, rel=1e-12)
    # one spool: the two shares add to one, and each is the other's mirror image
    for dp in (-3e5, -1e4, 0.0, 2e4, 7e5):
        s_a = L.shuttle_valve_share(1e6, 1e6 + dp, b)
        s_b = L.shuttle_valve_share(1e6 + dp, 1e6, b)
        assert s_a + s_b == pytest.approx(1.0, abs=1e-15)
        assert s_a == pytest.approx(0.5 * (1.0 + math.tanh(dp / b)), rel=1e-15)

def test_poppet_opening_linear_with_rounded_corners():
    start, width, w = 0.1e6, 0.4e6, 0.05
    dp = np.linspace(start + w * width, start + (1 - w) * width, 11)
    np.testing.assert_allclose(L.poppet_opening_fraction(dp, start, width, w),
                               (dp - start) / width, rtol=1e-13)
    # parabolic corner: (u + w)²/(4w), 1/4 of w at the start
    assert L.poppet_opening_fraction(start, start, width, w) == pytest.approx(w / 4, rel=1e-12)
    assert L.poppet_opening_fraction(start - 2 * w * width, start, width, w) == 0.0
    assert L.poppet_opening_fraction(start + 2 * width, start, width, w) == 1.0
    np.testing.assert_array_equal(L.poppet_opening_fraction(dp, start, width, 0.0),
                                  L.poppet_opening_fraction(dp, start, width, 0.0).clip(0, 1))
    u = np.linspace(-0.2, 1.2, 14001)
    s = L.poppet_opening_fraction(u, 0.0, 1.0, w)
    slope = np.diff(s) / np.diff(u)
    assert np.max(np.abs(np.diff(slope))) < 0.01                       # C¹


def test_spool_edge_area():
    w, o, xmax = 4e-3, 0.05e-3, 0.3e-3
    assert L.spool_edge_area_m2(0.2e-3, xmax, o, w, 0.0, 0.0) == pytest.approx(w * 0.15e-3)
    assert L.spool_edge_area_m2(0.5e-3, xmax, o, w, 0.0, 1e-12) == pytest.approx(
        w * (xmax - o) + 1e-12)                                         # clipped at x_max
    assert L.spool_edge_area_m2(0.02e-3, xmax, o, w, 0.0, 1e-12) == 1e-12   # in the overlap
    eps = 0.01e-3
    assert L.spool_edge_area_m2(o, xmax, o, w, eps, 0.0) == pytest.approx(w * eps / 4, rel=1e-12)


def test_onoff_valve_rate():
    tau, tsw = 1e-4, 2e-3
    assert L.onoff_valve_rate_1_s(0.0, 1.0, tau, tsw, 0.0) == pytest.approx(1 / tsw)
    assert L.onoff_valve_rate_1_s(0.0, 3.0, tau, tsw, 0.0) == pytest.approx(1 / tsw)  # u ≤ 1
    assert L.onoff_valve_rate_1_s(1.0, 0.0, tau, tsw, 0.0) == pytest.approx(-1 / tsw)
    assert L.onoff_valve_rate_1_s(0.99995, 1.0, tau, tsw, 0.0) == pytest.approx(0.05e-3 / tau)
    # rounded corners: within (r²/4)/d of the sharp law away from them
    r = 0.05 / tsw
    assert L.onoff_valve_rate_1_s(0.5, 1.0, tau, tsw, 0.05) == pytest.approx(
        1 / tsw, abs=r * r / (4 * (0.5 / tau - 1 / tsw)) * 1.01)


def test_unloading_valve_drives_and_hysteresis():
    out, cin, band, tau = 14.1e6, 12.5e6, 0.1e6, 5e-3
    assert L.unloading_open_drive(14.05e6, out, band) == pytest.approx(0.5)
    assert L.unloading_open_drive(14.2e6, out, band) == 1.0
    assert L.unloading_open_drive(13.9e6, out, band) == 0.0
    assert L.unloading_close_drive(12.55e6, cin, band) == pytest.approx(0.5)
    assert L.unloading_close_drive(12.4e6, cin, band) == 1.0
    assert L.unloading_open_drive(out, out, 0.0) == 1.0
    assert L.unloading_open_drive(out - 1, out, 0.0) == 0.0
    # above cut-out: toward 1 at (1 − x)/τ; between the bands: holds; below cut-in: toward 0
    def rate(x, pilot, hyst=1.0):
        return L.unloading_valve_rate_1_s(x, pilot, out, cin, band, tau, hyst)
    assert rate(0.5, 15e6) == pytest.approx(0.5 / tau)
    for x in (0.0, 0.3, 1.0):
        assert rate(x, 13.3e6) == 0.0
    assert rate(0.5, 12e6) == pytest.approx(-0.5 / tau)
    # without hysteresis it closes as soon as the pilot is below cut-out − band
    assert rate(0.5, 13.3e6, 0.0) == pytest.approx(-0.5 / tau)


# ---------------------------------------------------------------------------- pump, motor

def test_valve_circuit_laws():
    """The laws the valve circuits add (issue 18): snap-action unloading valve, first-order
    spool, pressure compensator, PWM on-fraction."""
    tau = 2e-3
    args = (11.1e6, 9.6e6, 0.3e6, tau, 1.0)
    # pilot between the bands: the latch decides (open beyond 12 % of the travel, shut
    # below 2 %), where the plain law holds still
    assert L.unloading_valve_snap_rate_1_s(0.5, 10.3e6, *args) == pytest.approx(0.5 / tau)
    assert L.unloading_valve_snap_rate_1_s(0.01, 10.3e6, *args) == pytest.approx(-0.01 / tau)
    assert L.unloading_valve_rate_1_s(0.5, 10.3e6, *args) == 0.0
    # above cut-out it opens, below cut-in it shuts, whatever the latch says
    assert L.unloading_valve_snap_rate_1_s(0.01, 11.2e6, *args) == pytest.approx(0.99 / tau)
    assert L.unloading_valve_snap_rate_1_s(0.5, 9.5e6, *args) == pytest.approx(-0.5 / tau)
    # the spool lags its clipped command
    assert L.spool_lag_rate_1_s(0.2, 3.0, 8e-4) == pytest.approx(0.8 / 8e-4)
    assert L.spool_lag_rate_1_s(0.2, -0.1, 8e-4) == pytest.approx(-0.3 / 8e-4)
    # compensator: linear destroking inside the band, full and minimum stroke outside
    assert L.compensator_displacement_fraction(10.5e6, 11e6, 1e6, 0.03) == pytest.approx(
        0.5, abs=1e-3)
    assert L.compensator_displacement_fraction(5e6, 11e6, 1e6, 0.03) == pytest.approx(
        1.0, abs=1e-4)
    assert L.compensator_displacement_fraction(20e6, 11e6, 1e6, 0.03) == pytest.approx(
        0.03, abs=1e-4)
    # PWM: the on-fraction over a step is the step's overlap with the on-windows
    f, duty, h = 50.0, 0.3, 1e-3
    t = np.arange(0, 0.2, 1e-6)
    on = (np.mod(t * f, 1.0) < duty).astype(float)
    for t0 in (0.0, 0.0055, 0.0195, 0.1234):
        sel = (t >= t0) & (t < t0 + h)
        assert L.pwm_on_fraction(t0, h, duty, f) == pytest.approx(on[sel].mean(), abs=2e-3)
    assert L.pwm_on_fraction(0.005, 0.002, 0.3, 50.0) == pytest.approx(0.5, rel=1e-12)
    # over whole periods the fraction is the duty
    assert L.pwm_on_fraction(0.013, 0.1, 0.37, 50.0) == pytest.approx(0.37, rel=1e-12)
    assert L.pwm_on_fraction(0.01, h, 0.0, f) == 0.0 and L.pwm_on_fraction(0.01, h, 1.0, f) == 1.0


def test_pump_flow_speed_and_torque():
    w, dp, cs, mu = 300.0, 10e6, 1e-8, 0.03
    q = L.pump_flow_m3_s(w, dp, D_REV, cs, 0.0, mu)
    assert q == pytest.approx(D_REV * w - cs * D_REV * dp / mu, rel=1e-14)
    assert q == pytest.approx(9.549e-6 - 1.061e-7, rel=1e-3)
    assert L.pump_flow_m3_s(w, dp, D_REV, 0.0, 2e-15, mu) == pytest.approx(
        D_REV * w - 2e-15 * dp / mu)
    ref = brentq(lambda om: L.pump_flow_m3_s(om, dp, D_REV, cs, 1e-16, mu) - q, -1e4, 1e4,
                 xtol=1e-12, rtol=1e-14)
    assert L.pump_speed_for_flow_rad_s(q, dp, D_REV, cs, 1e-16, mu) == pytest.approx(ref, rel=1e-10)
    cf, cv, t0, wc = 0.05, 1.8e4, 0.002, 1.0
    t = L.pump_friction_torque_nm(w, dp, D_REV, cf, cv, t0, wc, mu)
    assert t == pytest.approx((cf * D_REV * math.sqrt(dp ** 2 + 1e4 ** 2) + t0) * math.tanh(w / wc)
                              + cv * D_REV * mu * w, rel=1e-13)
    # friction always dissipates: T_f ω ≥ 0 in every quadrant
    for ww in (-400.0, -0.3, 0.3, 400.0):
        for pp in (-5e6, 0.0, 5e6):
            assert L.pump_friction_torque_nm(ww, pp, D_REV, cf, cv, t0, wc, mu) * ww > 0


def test_motor_friction_and_driver():
    assert L.motor_friction_torque_nm(100.0, 0.005, 1e-6, 1.0) == pytest.approx(
        0.005 * math.tanh(100.0) + 1e-4)
    assert L.motor_friction_torque_nm(-2.0, 0.005, 1e-6, 1.0) == pytest.approx(
        -0.005 * math.tanh(2.0) - 2e-6)
    # current limit: at stall a 12 V command gets R I_max = 5 V (to r²/(4d))
    assert L.driver_voltage_v(12.0, 0.0, 0.5, 10.0, 1.0, 0.95, 24.0) == pytest.approx(5.0, abs=2e-4)
    assert L.driver_voltage_v(12.0, 0.0, 0.5, 10.0, 0.0, 0.95, 24.0) == pytest.approx(
        12.0, abs=1e-4)                                  # limit off
    # duty limit of the bus, either sign
    assert L.driver_voltage_v(-50.0, -100.0, 0.5, 10.0, 1.0, 0.95, 24.0) == pytest.approx(
        -0.95 * 24.0, abs=2e-4)
    # inside both bands: the command
    assert L.driver_voltage_v(3.0, 2.0, 0.5, 10.0, 1.0, 0.95, 24.0) == pytest.approx(3.0, abs=1e-3)


# ------------------------------------------------------------------------ cylinder, seal

def test_seal_friction_stribeck_peak_at_breakaway():
    """With the Stribeck gain √(2e)(F_brk − F_C), v_St = √2 v_brk, v_C = v_brk/10, the
    friction is F_brk (plus the viscous part) at the breakaway speed v_brk."""
    fc, fbrk, vbrk, fv = 3.0, 4.5, 0.005, 5.0
    g = math.sqrt(2 * math.e) * (fbrk - fc)
    f = L.seal_friction_n(vbrk, 0.0, fc, g, math.sqrt(2) * vbrk, vbrk / 10, fv, 0.0)
    assert f == pytest.approx(fc * math.tanh(10.0) + (fbrk - fc) + fv * vbrk, rel=1e-12)
    assert f == pytest.approx(fbrk + fv * vbrk, rel=1e-6)
    assert L.seal_friction_n(-vbrk, 0.0, fc, g, math.sqrt(2) * vbrk, vbrk / 10, fv, 0.0) == -f
    # pressure part c_p √(Δp² + (10 kPa)²) tanh(v/v_C)
    fp = L.seal_friction_n(1.0, 5e6, 0.0, 0.0, 1.0, 1e-3, 0.0, 1e-6)
    assert fp == pytest.approx(1e-6 * math.sqrt(25e12 + 1e8) * math.tanh(1e3), rel=1e-13)
    assert L.oring_coulomb_force_n(10e-3, 1.78e-3, 0.12, 0.4, 3.5e6, 1.0) == pytest.approx(
        0.4 * 3.5e6 * math.pi * 10e-3 * 1.78e-3 * 0.12 ** 1.5, rel=1e-14)


def test_seal_dragout_film():
    mu, v, d, w = 0.03, 0.1, 10e-3, 1e10
    h = math.sqrt(8 * mu * v / (9 * w))
    assert L.seal_dragout_flow_m3_s(v, mu, d, w) == pytest.approx(math.pi * d * h * v / 2,
                                                                  rel=1e-14)
    assert L.seal_dragout_flow_m3_s(-v, mu, d, w) == -L.seal_dragout_flow_m3_s(v, mu, d, w)


def test_end_stops_push_back_and_store_the_spring_energy():
    s, k, c = 0.03, 5e7, 2e3
    assert L.end_stop_force_n(0.01, 0.5, s, k, c) == 0.0
    assert L.end_stop_force_n(-1e-4, 0.0, s, k, c) == pytest.approx(k * 1e-4)      # pushes +x
    assert L.end_stop_force_n(s + 1e-4, 0.0, s, k, c) == pytest.approx(-k * 1e-4)  # pushes −x
    assert L.end_stop_force_n(-1e-4, -0.1, s, k, c) == pytest.approx(k * 1e-4 + c * 0.1)
    # leaving the stop fast: the damper would pull, the stop does not
    assert L.end_stop_force_n(-1e-6, 10.0, s, k, c) == 0.0
    assert L.end_stop_force_n(s + 1e-6, -10.0, s, k, c) == 0.0
    # −dE/dx is the spring part of the force
    for x in (-2e-4, s + 3e-4):
        h = 1e-9
        dedx = (L.end_stop_energy_j(x + h, s, k) - L.end_stop_energy_j(x - h, s, k)) / (2 * h)
        assert -dedx == pytest.approx(L.end_stop_force_n(x, 0.0, s, k, 0.0), rel=1e-6)
    assert L.end_stop_energy_j(-1e-3, s, k) == pytest.approx(0.5 * k * 1e-6)


# ----------------------------------------------------------------------------- accumulators

def test_gas_accumulator_volume_pressure_capacitance_energy():
    v0, p0, n, band = 10e-6, 2e6, 1.4, 1e4
    # polytropic: p (V0 − Vf)^n = p0 V0^n
    for p in (2.5e6, 4e6, 9e6):
        vf = L.gas_accumulator_oil_volume_m3(p, v0, p0, n)
        assert p * (v0 - vf) ** n == pytest.approx(p0 * v0 ** n, rel=1e-12)
        assert L.gas_accumulator_pressure_pa(vf, v0, p0, n) == pytest.approx(p, rel=1e-12)
    assert L.gas_accumulator_oil_volume_m3(1.5e6, v0, p0, n) == 0.0
    assert L.gas_accumulator_capacitance_m3_pa(1.5e6, v0, p0, n, band) == 0.0
    # capacitance: the derivative of the oil volume (above the blend band)
    for p in (2.5e6, 4e6, 9e6):
        h = 1.0
        fd = (L.gas_accumulator_oil_volume_m3(p + h, v0, p0, n)
              - L.gas_accumulator_oil_volume_m3(p - h, v0, p0, n)) / (2 * h)
        assert L.gas_accumulator_capacitance_m3_pa(p, v0, p0, n, band) == pytest.approx(fd,
                                                                                        rel=1e-6)
    assert L.gas_accumulator_capacitance_m3_pa(4e6, v0, p0, n, band) == pytest.approx(1.088e-12,
                                                                                      rel=1e-3)
    # energy: ∫ p dV over the gas from V0 down to V_g
    for n_ in (1.0, 1.4):
        vg = 0.4 * v0
        ref, _ = quad(lambda v: p0 * (v0 / v) ** n_, vg, v0, epsabs=0.0, epsrel=1e-13)
        assert L.polytropic_gas_energy_j(vg, v0, p0, n_) == pytest.approx(ref, rel=1e-10)


def test_spring_accumulator():
    a, k, f0, s, vent, kst = 3e-4, 2e4, 150.0, 0.03, 101325.0, 7.5e14
    args = (a, k, f0, s, vent, kst)
    x = 0.012
    p = vent + (f0 + k * x) / a                       # force balance on the piston
    assert L.spring_accumulator_pressure_pa(a * x, *args) == pytest.approx(p, rel=1e-14)
    assert L.spring_accumulator_oil_volume_m3(p, *args) == pytest.approx(a * x, rel=1e-12)
    assert L.spring_accumulator_oil_volume_m3(vent + 0.5 * f0 / a, *args) == 0.0
    assert L.spring_accumulator_pressure_pa(-1e-10, *args) == pytest.approx(
        vent + f0 / a - kst * 1e-10)                      # on the empty stop
    # capacitance: the derivative of the oil volume, A²/k in the stroke, 1/K_stop outside
    h = 10.0
    fd = (L.spring_accumulator_oil_volume_m3(p + h, *args)
          - L.spring_accumulator_oil_volume_m3(p - h, *args)) / (2 * h)
    assert L.spring_accumulator_capacitance_m3_pa(p, *args) == pytest.approx(fd, rel=1e-9)
    assert L.spring_accumulator_capacitance_m3_pa(vent, *args) == 1 / kst
    # energy: ∫ (p − p_vent) dV from empty, in the stroke and beyond either stop
    for vf in (0.5 * a * s, a * s + 2e-10, -1e-10):
        ref, _ = quad(lambda v: L.spring_accumulator_pressure_pa(v, *args) - vent, 0.0, vf,
                      points=[0.0, a * s] if vf > a * s else None, epsabs=0.0, epsrel=1e-12)
        assert L.spring_accumulator_energy_j(vf, *args) == pytest.approx(ref, rel=1e-8)
    assert L.spring_accumulator_energy_j(a * s, *args) == pytest.approx(f0 * s + 0.5 * k * s * s)


# --------------------------------------------------------------------------- battery, heat

def test_battery_current_solves_the_thevenin_power_balance():
    for v, r, p in ((22.5, 0.1, 100.0), (25.0, 0.12, 800.0), (21.0, 0.05, -150.0)):
        ref = brentq(lambda i: v * i - r * i * i - p, -1e3, v / (2 * r), xtol=1e-14, rtol=1e-14)
        assert L.battery_current_a(p, v, r) == pytest.approx(ref, rel=1e-11)
    assert L.battery_current_a(100.0, 22.5, 0.1) == pytest.approx(4.536, rel=1e-3)
    # beyond the matched-load power V²/(4R): capped at I = V/(2R)
    assert L.battery_current_a(5e3, 22.5, 0.1) == pytest.approx(22.5 / 0.2, rel=1e-12)


def test_lumped_temperature_rate():
    c, r, ta = 400.0, 5.0, 298.15
    assert L.lumped_temperature_rate_k_s(ta, 10.0, ta, r, c) == pytest.approx(0.025)
    # steady state T = T_a + Q R
    assert L.lumped_temperature_rate_k_s(ta + 50.0, 10.0, ta, r, c) == pytest.approx(0.0, abs=1e-15)


def test_table_interp_is_np_interp():
    rng = np.random.default_rng(3)
    xs = np.array([0.0, 0.05, 0.1, 0.2, 0.5, 0.9, 1.0])
    ys = np.array([3.0, 3.45, 3.55, 3.62, 3.75, 4.06, 4.2])
    x = np.concatenate([rng.uniform(-0.2, 1.2, 200), xs])
    ref = np.interp(x, xs, ys)
    got = np.array([L.table_interp(float(v), xs, ys) for v in x])
    np.testing.assert_allclose(got, ref, rtol=1e-14, atol=0)
    np.testing.assert_allclose(L.table_interp_array(x.reshape(9, 23), xs, ys),
                               ref.reshape(9, 23), rtol=1e-14, atol=0)


# ------------------------------------------------------- scalars in compiled code == arrays

#: Argument sets per law (every branch somewhere): used to call each law from an njit
#: function with scalars and, stacked, with numpy arrays.
SAMPLES = {
    "smoothstep01": [(-0.1,), (0.3,), (1.2,)],
    "ramp_c1": [(-1.0, 2.0), (1.0, 2.0), (5.0, 2.0)],
    "soft_clip": [(5.0, -1.0, 1.0, 0.05), (0.2, -1.0, 1.0, 0.05), (-3.0, -1.0, 1.0, 0.0)],
    "smooth_abs": [(-3.0, 4.0), (0.0, 0.1)],
    "bulk_modulus_pa": [(1e6, 1.5e9, 0.01, 1.4, 101325.0), (3e6, 1.5e9, 0.0, 1.4, 101325.0)],
    "oil_mean_compliance_per_pa": [(0.4e6, 4.6e6, 1.5e9, 0.01, 1.4, 101325.0, 2e3),
                                   (1e3, 3e5, 1.5e9, 0.1, 1.0, 101325.0, 2e3)],
    "walther_viscosity_m2_s": [(313.15, 9.32, 3.65), (353.0, 9.5, 3.7)],
    "oil_density_kg_m3": [(311.0, 875.0, 7e-4, 288.15)],
    "dynamic_viscosity_pa_s": [(330.0, 9.5, 3.7, 875.0, 7e-4, 288.15)],
    "node_capacitance_m3_pa": [(1e-6, 1.5e9, 2e-6, 1e-9)],
    "pipe_reynolds_number": [(-1e-5, 4e-3, 0.04, 870.0)],
    "laminar_resistance_pa_s_m3": [(1.0, 4e-3, 0.04)],
    "friction_factor_ratio": [(1500.0, 0.0), (3000.0, 0.0), (1e4, 0.0), (1e4, 1e-3)],
    "hose_pressure_loss_pa": [(1e-5, 1.0, 4e-3, 0.04, 870.0, 0.0, 1.0),
                              (-1e-4, 1.0, 4e-3, 1e-3, 870.0, 1e-3, 1.0),
                              (1e-4, 1.0, 4e-3, 1e-3, 870.0, 0.0, 0.0)],
    "hose_flow_m3_s": [(6e4, 1.0, 4e-3, 0.04, 870.0, 0.0, 1.0),
                       (-1e5, 1.0, 4e-3, 1e-3, 870.0, 1e-3, 1.0),
                       (1e5, 1.0, 4e-3, 1e-3, 870.0, 0.0, 0.0)],
    "orifice_flow_m3_s": [(1e6, 1e-6, 0.61, 870.0, 1e4), (-50.0, 1e-6, 0.61, 870.0, 1e4)],
    "laminar_gap_flow_m3_s": [(1e7, 1e-15, 0.03)],
    "relief_valve_area_m2": [(14.5e6, 14e6, 1e6, 2e-6, 1e-10), (1e6, 14e6, 1e6, 2e-6, 1e-10)],
    "check_valve_flow_m3_s": [(1e5, 1e-9, 0.0, 2e4), (-1e5, 1e-9, 0.0, 2e4)],
    "shuttle_valve_share": [(1.0e6, 2.0e6, 5e4), (2.0e6, 1.0e6, 5e4)],
    "shuttle_valve_flow_m3_s": [(1.0, 1.0e6, 1.5e6, 5e-12), (1e-9, 2.0e6, 1.5e6, 5e-12)],
    "pump_flow_m3_s": [(300.0, 1e7, D_REV, 1e-8, 1e-16, 0.03)],
    "pump_friction_torque_nm": [(300.0, 1e7, D_REV, 0.05, 1.8e4, 0.002, 1.0, 0.03),
                                (-3.0, 0.0, D_REV, 0.05, 1.8e4, 0.002, 1.0, 0.03)],
    "motor_friction_torque_nm": [(100.0, 0.005, 1e-6, 1.0)],
    "driver_voltage_v": [(12.0, 0.0, 0.5, 10.0, 1.0, 0.95, 24.0),
                         (12.0, 0.0, 0.5, 10.0, 0.0, 0.95, 24.0)],
    "seal_friction_n": [(0.005, 1e6, 3.0, 3.7, 0.007, 5e-4, 5.0, 1e-7),
                        (-0.02, 0.0, 3.0, 0.0, 0.007, 5e-4, 5.0, 0.0)],
    "seal_dragout_flow_m3_s": [(0.1, 0.03, 0.01, 1e10), (-0.1, 0.03, 0.01, 1e10)],
    "end_stop_force_n": [(-1e-4, -0.1, 0.03, 5e7, 2e3), (0.031, 0.1, 0.03, 5e7, 2e3),
                         (0.01, 0.1, 0.03, 5e7, 2e3)],
    "end_stop_energy_j": [(-1e-4, 0.03, 5e7), (0.01, 0.03, 5e7)],
    "gas_accumulator_capacitance_m3_pa": [(4e6, 1e-5, 2e6, 1.4, 1e4),
                                          (2.005e6, 1e-5, 2e6, 1.4, 1e4),
                                          (1e6, 1e-5, 2e6, 1.4, 1e4)],
    "gas_accumulator_oil_volume_m3": [(4e6, 1e-5, 2e6, 1.4), (1e6, 1e-5, 2e6, 1.4)],
    "battery_current_a": [(100.0, 22.5, 0.1), (5e3, 22.5, 0.1)],
    "lumped_temperature_rate_k_s": [(320.0, 10.0, 298.15, 5.0, 400.0)],
    "cavitation_factor": [(12e3, 2e3, 2e4), (1e6, 2e3, 2e4)],
    "orifice_dp_for_flow_pa": [(2.9e-5, 1e-6, 0.61, 870.0, 1e3), (-1e-8, 1e-6, 0.61, 870.0, 1e4)],
    "valve_opening_area_m2": [(0.25, 2e-6, 1e-11), (1.5, 2e-6, 1e-11)],
    "poppet_opening_fraction": [(0.1e6, 0.1e6, 0.4e6, 0.05), (0.3e6, 0.1e6, 0.4e6, 0.0)],
    "spool_edge_area_m2": [(0.2e-3, 0.3e-3, 0.05e-3, 4e-3, 0.0, 1e-12),
                           (-0.4e-3, 0.3e-3, -0.01e-3, 4e-3, 0.01e-3, 1e-12)],
    "onoff_valve_rate_1_s": [(0.0, 1.0, 1e-4, 2e-3, 0.05), (0.9, 0.0, 1e-4, 2e-3, 0.0)],
    "unloading_open_drive": [(14.05e6, 14.1e6, 0.1e6), (14.05e6, 14.1e6, 0.0)],
    "unloading_close_drive": [(12.55e6, 12.5e6, 0.1e6)],
    "unloading_valve_rate_1_s": [(0.5, 15e6, 14.1e6, 12.5e6, 0.1e6, 5e-3, 1.0),
                                 (0.5, 13e6, 14.1e6, 12.5e6, 0.1e6, 5e-3, 0.0)],
    "gas_accumulator_pressure_pa": [(25e-6, 75e-6, 1.5e6, 1.4)],
    "polytropic_gas_energy_j": [(50e-6, 75e-6, 1.5e6, 1.4), (50e-6, 75e-6, 1.5e6, 1.0)],
    "spring_accumulator_pressure_pa": [(5e-6, 3e-4, 2e4, 150.0, 0.03, 101325.0, 7.5e14),
                                       (-1e-10, 3e-4, 2e4, 150.0, 0.03, 101325.0, 7.5e14),
                                       (1e-5, 3e-4, 2e4, 150.0, 0.03, 101325.0, 7.5e14)],
    "spring_accumulator_oil_volume_m3": [(1e6, 3e-4, 2e4, 150.0, 0.03, 101325.0, 7.5e14),
                                         (5e6, 3e-4, 2e4, 150.0, 0.03, 101325.0, 7.5e14)],
    "spring_accumulator_capacitance_m3_pa": [(1e6, 3e-4, 2e4, 150.0, 0.03, 101325.0, 7.5e14),
                                             (1e5, 3e-4, 2e4, 150.0, 0.03, 101325.0, 7.5e14)],
    "spring_accumulator_energy_j": [(5e-6, 3e-4, 2e4, 150.0, 0.03, 101325.0, 7.5e14),
                                    (1e-5, 3e-4, 2e4, 150.0, 0.03, 101325.0, 7.5e14)],
    "unloading_valve_snap_rate_1_s": [(0.5, 10.3e6, 11.1e6, 9.6e6, 0.3e6, 2e-3, 1.0),
                                      (0.05, 11.0e6, 11.1e6, 9.6e6, 0.3e6, 2e-3, 0.0)],
    "spool_lag_rate_1_s": [(0.2, 3.0, 8e-4), (0.2, -3.0, 8e-4), (0.2, 0.1, 8e-4)],
    "compensator_displacement_fraction": [(10.5e6, 11e6, 1e6, 0.03), (20e6, 11e6, 1e6, 0.03)],
    "pwm_on_fraction": [(0.005, 0.002, 0.3, 50.0), (0.0, 1e-3, 0.0, 50.0),
                        (0.0, 1e-3, 1.0, 50.0)],
    "pump_speed_for_flow_rad_s": [(9.4e-6, 1e7, D_REV, 1e-8, 0.0, 0.03)],
    "oring_coulomb_force_n": [(0.01, 1.78e-3, 0.12, 0.4, 3.5e6, 1.0)],
    "annular_gap_conductance_m3": [(0.012, 10e-6, 5e-3)],
    "series_spring_capacitance_m3_pa": [(6.4e-6, 5e-4), (6.4e-6, 0.0)],
    "series_spring_stretch_m": [(0.04, 6.03e-6, 3.1e-4, 1e6), (0.04, 6.03e-6, 0.0, 1e6),
                                (0.04, 6.03e-6, 3.1e-4, -2e5)],
    "cable_stretch_m": [(0.035, 5.442e-4, 20.0), (0.035, 0.0, 20.0), (0.04, 3.1e-4, -7.0)],
    "chamber_seal_pressure_friction_n": [(0.01, 2e6, 0.5e6, 1e-6, 5e-4),
                                         (-0.01, -5e4, 3e3, 1e-6, 5e-4),
                                         (0.0, 2e6, 2e6, 1e-6, 5e-4)],
    "coupled_node_rate_pa_s": [(3e-6, -1e-6, 3e-15, 4e-15, 2e-15),
                               (-1e-6, 3e-6, 4e-15, 3e-15, 2e-15),
                               (3e-6, -1e-6, 3e-15, 4e-15, 0.0)],
}


def test_every_law_has_samples():
    """A new law gets argument samples here (so the scalar/array test covers it)."""
    assert sorted(set(L.LAWS) - set(SAMPLES)) == []
    for name, sets in SAMPLES.items():
        assert name in L.LAWS, name
        n = L.LAWS[name].nin
        assert all(len(a) == n for a in sets), name


def _compiled_caller():
    """One @njit function calling every law with scalars (read from an array, so nothing is
    folded at compile time): ``out[k] = LAW(args[k, 0], …)`` for the flattened samples."""
    names = sorted(SAMPLES)
    lines, k = ["def call(a, out):"], 0
    for name in names:
        n = L.LAWS[name].nin
        for _ in SAMPLES[name]:
            args = ", ".join(f"a[{k}, {j}]" for j in range(n))
            lines.append(f"    out[{k}] = {name}({args})")
            k += 1
    ns = {name: L.LAWS[name] for name in names}
    exec("\n".join(lines), ns)   # noqa: S102  (generated from the registry above)
    return numba.njit(ns["call"]), names, k


@pytest.mark.slow
def test_laws_from_compiled_code_equal_the_array_form():
    call, names, total = _compiled_caller()
    width = max(L.LAWS[n].nin for n in names)
    a = np.zeros((total, width))
    k = 0
    for name in names:
        for args in SAMPLES[name]:
            a[k, :len(args)] = args
            k += 1
    out = np.full(total, np.nan)
    call(a, out)
    k = 0
    for name in names:
        sets = SAMPLES[name]
        cols = [np.array(c, dtype=float) for c in zip(*sets)]
        arr = L.LAWS[name](*cols)                       # numpy arrays, broadcast ufunc
        assert isinstance(arr, np.ndarray) and arr.shape == (len(sets),), name
        np.testing.assert_allclose(out[k:k + len(sets)], arr, rtol=1e-15, atol=0, err_msg=name)
        assert np.all(np.isfinite(arr)), name
        # and broadcasting one array argument against scalars gives the same values
        first = L.LAWS[name](cols[0], *[c[0] for c in cols[1:]])
        assert first[0] == arr[0], name
        k += len(sets)

    @numba.njit
    def interp_scalar(x, xs, ys):
        return L.table_interp(x, xs, ys)

    xs, ys = np.array([0.0, 0.5, 1.0]), np.array([3.0, 3.7, 4.2])
    assert interp_scalar(0.75, xs, ys) == L.table_interp_array(0.75, xs, ys) == pytest.approx(3.95)


# ------------------------------------------------------------------------- one copy of each

#: Everything in the package evaluates the laws (the hand-written kernels the generated
#: circuits replaced live on only as the tests' reference, tests/kernel_reference).
EXEMPT = {"afo_mj/hydraulics/laws.py"}
#: Names the copies of the laws had before laws.py (besides the laws' own names).
OLD_COPIES = {"soft_clip", "seal_force_n", "seal_force", "bulk_modulus", "ramp_c1",
              "smoothstep", "smoothstep01", "relief_flow", "seal_coulomb_force_n",
              "orifice", "smooth_ramp", "onoff_rate", "onoff_area", "battery_ocv",
              "viscosity_pa_s", "accumulator_capacitance", "table_interp"}


def _function_defs(tree: ast.AST):
    """Functions defined in a module, module level or nested, but not methods of a class."""
    methods = {id(f) for node in ast.walk(tree) if isinstance(node, ast.ClassDef)
               for f in node.body if isinstance(f, (ast.FunctionDef, ast.AsyncFunctionDef))}
    for node in ast.walk(tree):
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)) and id(node) not in methods:
            yield node


def test_no_module_defines_a_copy_of_a_law():
    names = set(L.LAWS) | OLD_COPIES
    forbidden = names | {"_" + n for n in names}
    found = []
    for path in sorted((ROOT / "afo_mj").rglob("*.py")):
        rel = path.relative_to(ROOT).as_posix()
        if rel in EXEMPT:
            continue
        for fn in _function_defs(ast.parse(path.read_text(encoding="utf-8"))):
            if fn.name in forbidden:
                found.append(f"{rel}:{fn.lineno} def {fn.name}")
    assert found == [], "copies of laws (call afo_mj.hydraulics.laws instead):\n" + \
        "\n".join(found)


def test_the_copy_finder_finds_copies():
    """The finder itself: a module-level copy and a nested one are found, a method is not."""
    src = ("def _soft_clip(x):\n    pass\n"
           "def outer():\n    def seal_force_n(v):\n        pass\n"
           "class C:\n    def bulk_modulus_pa(self):\n        pass\n")
    got = [f.name for f in _function_defs(ast.parse(src))]
    assert "_soft_clip" in got and "seal_force_n" in got and "bulk_modulus_pa" not in got


def test_series_spring_couples_two_chambers():
    """The differential capacitance and the coupled rates against the 2×2 system solved by
    numpy: (C_a + c_s) ṗ_a − c_s ṗ_b = n_a, −c_s ṗ_a + (C_b + c_s) ṗ_b = n_b."""
    cs = L.series_spring_capacitance_m3_pa(0.04 * 1.6e-4, 1.0 / 2000.0)
    assert cs == pytest.approx((0.04 * 1.6e-4) ** 2 / 2000.0, rel=1e-14)
    na, nb, ca, cb = 3e-6, -1e-6, 3e-15, 4e-15
    ref = np.linalg.solve([[ca + cs, -cs], [-cs, cb + cs]], [na, nb])
    assert L.coupled_node_rate_pa_s(na, nb, ca, cb, cs) == pytest.approx(ref[0], rel=1e-12)
    assert L.coupled_node_rate_pa_s(nb, na, cb, ca, cs) == pytest.approx(ref[1], rel=1e-12)
    assert L.coupled_node_rate_pa_s(na, nb, ca, cb, 0.0) == pytest.approx(na / ca, rel=1e-15)
    from afo_mj.hydraulics.params import ParameterError
    from afo_mj.hydraulics.transmission import series_compliance_m3_pa
    assert series_compliance_m3_pa(0.04, 1.6e-4, 2000.0) == pytest.approx(cs, rel=1e-14)
    with pytest.raises(ParameterError, match="stiffness_nm_rad"):
        series_compliance_m3_pa(0.04, 1.6e-4, 0.0)


def test_cable_stretch_and_chamber_seal_friction_examples():
    """The docstrings' examples, by hand: the cable 1/(r² (1/k)) = 1.5 MN/m stretched by 20 N
    (Hooke: 13.33 µm); two cable seals of f_h = 1e-6 N/Pa on 2 and 0.5 MPa chambers, each
    rounded 5 kPa low above 10 kPa, at a speed far past the Coulomb corner: 2.49 N."""
    k_lin = 1.0 / (0.035 ** 2 * 5.442e-4)
    assert k_lin == pytest.approx(1.5e6, rel=1e-3)
    assert L.cable_stretch_m(0.035, 5.442e-4, 20.0) == pytest.approx(20.0 / k_lin, rel=1e-12)
    assert L.chamber_seal_pressure_friction_n(0.01, 2e6, 0.5e6, 1e-6, 5e-4) == \
        pytest.approx(1e-6 * (1.995e6 + 0.495e6), rel=1e-9)
    # a chamber below the atmosphere loads its seal with nothing; opposite speed, opposite sign
    assert L.chamber_seal_pressure_friction_n(-0.01, -5e4, 2e6, 1e-6, 5e-4) == \
        pytest.approx(-1e-6 * 1.995e6, rel=1e-9)
