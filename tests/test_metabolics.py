"""Muscle metabolic rates (afo_mj.human.metabolics) against the published equations worked
by hand (Umberger 2010 / Umberger et al. 2003; Bhargava et al. 2004) and their stated
bounds: the heat floor of 1 W/kg, a non-negative total, the fibre-type and length
dependences."""

from __future__ import annotations

import math

import numpy as np
import pytest

from afo_mj.human import metabolics as me


def test_umberger_isometric_maximum_by_hand():
    """Full excitation, isometric at l_opt: Ḣ_AM = 1.5 (128 (1 − f_ST) + 25) W/kg, no
    shortening heat, no work: 133.5 W/kg at half slow-twitch, 37.5 W/kg all slow-twitch."""
    for f_st, expect in ((0.5, 133.5), (1.0, 37.5), (0.0, 229.5)):
        tot, heat, work = me.umberger2010_rate_w(1.0, 1.0, 1.0, 0.0, 1000.0, 1.0, 12.0, 0.05,
                                                 2.0, f_st)
        assert tot == pytest.approx(2.0 * expect) and heat == tot and work == 0.0


def test_umberger_shortening_by_hand():
    """u = a = 1, f_ST = 0.5, v = −2 l_opt/s, v_max = 12 l_opt/s, at l_opt: α_ST = 100/4.8,
    α_FT = 153/12; Ḣ_SL = 1.5 (2 α_ST · 0.5 + 2 α_FT · 0.5); work = F v l_opt / m."""
    m, f, lopt = 1.5, 800.0, 0.06
    tot, heat, work = me.umberger2010_rate_w(1.0, 1.0, 1.0, -2.0, f, 1.0, 12.0, lopt, m, 0.5)
    a_st, a_ft = 100 / 4.8, 153 / 12.0
    sl = 1.5 * (2 * a_st * 0.5 + 2 * a_ft * 0.5)
    assert heat == pytest.approx((133.5 + sl) * m)
    assert work == pytest.approx(f * 2.0 * lopt)
    assert tot == pytest.approx(heat + work)


def test_umberger_lengthening_counts_negative_work():
    """Lengthening at +1 l_opt/s: Ḣ_SL = 1.5 A · 4 α_ST v and the work rate is negative
    (Umberger 2010 counts it); where the negative work would exceed the heat, the heat is
    raised so that the total is zero."""
    m, lopt = 1.0, 0.1
    am = 1.5 * 0.6 ** 0.6 * 89.0
    sl = 1.5 * 0.6 * 4 * (100 / 4.8) * 1.0
    tot, heat, work = me.umberger2010_rate_w(0.6, 0.6, 1.0, 1.0, 500.0, 1.0, 12.0, lopt, m,
                                             0.5)
    assert heat == pytest.approx(am + sl)
    assert work == pytest.approx(-500.0 * lopt)
    assert tot == pytest.approx(am + sl - 50.0)
    tot, heat, work = me.umberger2010_rate_w(0.6, 0.6, 1.0, 1.0, 3000.0, 1.0, 12.0, lopt, m,
                                             0.5)
    assert work == pytest.approx(-300.0) and heat == pytest.approx(300.0) and tot == 0.0


def test_umberger_floor_and_non_negative_total():
    # at rest the heat is the 1 W/kg floor
    tot, heat, work = me.umberger2010_rate_w(0.0, 0.0, 1.0, 0.0, 0.0, 1.0, 12.0, 0.05, 0.7, 0.8)
    assert heat == pytest.approx(0.7 * me.MIN_HEAT_W_PER_KG) and work == 0.0
    rng = np.random.default_rng(0)
    for _ in range(500):
        u, a = rng.uniform(0, 1, 2)
        v = rng.uniform(-12, 12)
        tot, heat, work = me.umberger2010_rate_w(u, a, rng.uniform(0.5, 1.5), v,
                                                 rng.uniform(0, 4000), rng.uniform(0.05, 1),
                                                 12.0, 0.05, 1.0, rng.uniform(0, 1))
        assert tot >= -1e-9 and heat >= 1.0 - 1e-12
        assert math.isfinite(tot)


def test_umberger_excitation_above_activation_counts():
    """A = u when the excitation leads the activation, else the mean: a rising excitation
    costs more than the same activation held."""
    rising = me.umberger2010_rate_w(1.0, 0.2, 1.0, 0.0, 100.0, 1.0, 12.0, 0.05, 1.0, 0.5)[0]
    held = me.umberger2010_rate_w(0.2, 0.2, 1.0, 0.0, 100.0, 1.0, 12.0, 0.05, 1.0, 0.5)[0]
    falling = me.umberger2010_rate_w(0.0, 0.4, 1.0, 0.0, 100.0, 1.0, 12.0, 0.05, 1.0, 0.5)[0]
    assert rising == pytest.approx(1.5 * 89.0)
    assert held == pytest.approx(1.5 * 0.2 ** 0.6 * 89.0)
    assert falling == pytest.approx(held)


def test_bhargava_by_hand():
    """u = 1, f_ST = 0.5, at l_opt, isometric: Ȧ = 40·0.5 + 133·0.5, Ṁ = 74·0.5 + 111·0.5
    (W/kg); shortening at 0.1 m/s with 500 N: Ṡ = 0.25 F v, Ẇ = F v."""
    tot, heat, work = me.bhargava2004_rate_w(1.0, 1.0, 0.0, 1000.0, 1000.0, 2.0, 0.5)
    assert tot == pytest.approx(2.0 * (86.5 + 92.5)) and work == 0.0
    tot, heat, work = me.bhargava2004_rate_w(1.0, 1.0, -0.1, 500.0, 450.0, 2.0, 0.5)
    assert heat == pytest.approx(2.0 * 179.0 + 0.25 * 500.0 * 0.1)
    assert work == pytest.approx(450.0 * 0.1)
    # half excitation: the slow fibres are recruited first (sin vs 1 − cos)
    tot_half = me.bhargava2004_rate_w(0.5, 1.0, 0.0, 0.0, 0.0, 1.0, 0.5)[0]
    u_st, u_ft = 0.5 * math.sin(math.pi / 4), 0.5 * (1 - math.cos(math.pi / 4))
    assert tot_half == pytest.approx(40 * u_st + 133 * u_ft + 74 * u_st + 111 * u_ft)
    assert u_st > u_ft


def test_bhargava_from_the_fibres_is_the_rate():
    """The rate from the fibres' excitations (the reflex law keeps them while u holds) is
    bhargava2004_rate_w bit for bit; the excitations are Bhargava's sin and 1 − cos."""
    rng = np.random.default_rng(3)
    for _ in range(200):
        u, ln, v, f, fa, m, st = (rng.uniform(-0.1, 1.1), rng.uniform(0.3, 1.8),
                                  rng.uniform(-0.5, 0.5), rng.uniform(0, 3000),
                                  rng.uniform(0, 3000), rng.uniform(0.1, 2), rng.uniform(0, 1))
        u_st, u_ft = me.bhargava_fibre_excitations(u, st)
        uu = min(max(u, 0.0), 1.0)
        assert u_st == pytest.approx(st * math.sin(0.5 * math.pi * uu), rel=1e-14, abs=1e-16)
        assert u_ft == pytest.approx((1 - st) * (1 - math.cos(0.5 * math.pi * uu)),
                                     rel=1e-12, abs=1e-16)
        assert (me.bhargava2004_rate_from_fibres_w(u_st, u_ft, ln, v, f, fa, m)
                == me.bhargava2004_rate_w(u, ln, v, f, fa, m, st))


def test_bhargava_length_factor_and_floor():
    pts = {0.0: 0.5, 0.5: 0.5, 0.75: 0.75, 1.0: 1.0, 1.25: 0.5, 1.5: 0.0, 2.0: 0.0}
    for x, y in pts.items():
        assert me.bhargava_length_factor(x) == pytest.approx(y)
    tot, heat, work = me.bhargava2004_rate_w(0.0, 1.0, 0.0, 0.0, 0.0, 0.3, 0.5)
    assert heat == pytest.approx(0.3) and tot == pytest.approx(0.3)
    # lengthening: no shortening heat, no work
    tot, heat, work = me.bhargava2004_rate_w(1.0, 1.0, 0.2, 1000.0, 1000.0, 1.0, 0.5)
    assert work == 0.0 and heat == pytest.approx(179.0)


def test_basal_rate():
    assert me.basal_rate_w(75.0) == pytest.approx(90.0)
    with pytest.raises(ValueError, match="body_mass_kg"):
        me.basal_rate_w(-1.0)
