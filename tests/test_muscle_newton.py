"""The CE-length solve of the backward-Euler muscle step (afo_mj.human.muscle.mtu_step, Newton
with the analytic derivative of mtu_residual) against independent references: the residual
against ``x − l_CE − h · mtu_rate(x)`` (the rate function the ODE is written with) and its
derivative against central differences of that residual; each solve against scipy's brentq
on the same residual, to 1e-10 l_opt, over a grid of states that covers the branch points
(shortening and lengthening, the isometric balance v = 0, zero and near-zero activation,
a slack tendon and one at its slack length, the CE below the buckling length, beyond l_opt,
the maximum shortening and the capped lengthening speed); and any start (``v_guess``) lands
on the same root."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from scipy.optimize import brentq

from afo_mj.human import muscle as mu

H = 1e-3
NAMES = tuple(mu.GEYER_HERR_2010)


def _args(p):
    return p.max_force_n, p.max_velocity_lopt_s, p.optimal_length_m, p.slack_length_m


def _residual_ref(x, l_ce, a, l_mtu, p):
    """``R(x) = x − l_CE − h · mtu_rate(x)``, from the rate function alone."""
    return x - l_ce - H * mu.mtu_rate(x, a, l_mtu, *_args(p))


def _brentq_root(l_ce, a, l_mtu, p):
    """The root by brentq inside the bracket the rate's range gives (the rate lies in
    ``[−v_max, 10 v_max] l_opt``, so ``R < 0`` below ``l_CE − h v_max l_opt`` and ``R > 0``
    above ``l_CE + 10 h v_max l_opt``)."""
    lo_m = p.optimal_length_m
    vm = p.max_velocity_lopt_s
    lo = max(l_ce - 1.001 * H * vm * lo_m, 0.0)
    hi = min(l_ce + 10.01 * H * vm * lo_m, l_mtu)
    r_lo, r_hi = (_residual_ref(x, l_ce, a, l_mtu, p) for x in (lo, hi))
    assert r_lo <= 0.0 <= r_hi, (l_ce, a, l_mtu, r_lo, r_hi)
    return brentq(_residual_ref, lo, hi, args=(l_ce, a, l_mtu, p), xtol=1e-16 * lo_m,
                  rtol=1e-15, maxiter=500)


def _states():
    """(muscle, l_CE, a, l_MTU) over CE lengths either side of the buckling length
    ``l_opt (1 − w)`` and of ``l_opt``, activations from 0 (the 1e-6 floor of the active
    force) to 1, and tendon strains from slack through the slack length to twice ε_ref."""
    for name, rel_l, a, eps in itertools.product(
            NAMES, (0.3, 1.0 - mu.W_WIDTH, 0.7, 1.0, 1.3, 1.6),
            (0.0, 1e-7, 1e-4, 0.01, 0.2, 1.0),
            (-0.02, 0.0, 1e-6, 0.01, mu.EPS_REF, 0.08)):
        p = mu.GEYER_HERR_2010[name][0]
        l_ce = rel_l * p.optimal_length_m
        yield p, l_ce, a, l_ce + p.slack_length_m * (1.0 + eps)


def _isometric_states():
    """States at the isometric balance (``v_CE = 0`` at the start: the kink of the
    force–velocity relation between shortening and lengthening), with the MTU held or
    moving by ±1 mm, ±1 µm over the step."""
    for name, a, rel_mtu, dl in itertools.product(
            NAMES, (1e-4, 0.01, 0.3, 1.0), (0.95, 1.0, 1.05), (0.0, 1e-3, -1e-3, 1e-6, -1e-6)):
        p = mu.GEYER_HERR_2010[name][0]
        l0 = rel_mtu * (p.optimal_length_m + p.slack_length_m)
        l_ce = mu.equilibrium_ce_length_m(a, l0, p)
        yield p, l_ce, a, l0 + dl


def test_residual_is_the_rate_functions_and_its_derivative_the_numerical_one():
    """R and dR/dx (mtu_residual) against x − l_CE − h mtu_rate(x) (1e-13 l_opt) and its
    central difference (relative 1e-5, where no branch point lies within the difference)."""
    rng = np.random.default_rng(7)
    checked = 0
    for p, l_ce, a, l_mtu in _states():
        lo_m = p.optimal_length_m
        for x in l_ce + lo_m * rng.uniform(-0.012, 0.012, 3):
            r, dr = mu.mtu_residual(x, l_ce, a, l_mtu, H, *_args(p))
            assert abs(r - _residual_ref(x, l_ce, a, l_mtu, p)) < 1e-13 * lo_m
            d = 1e-7 * lo_m
            rp, rm = (_residual_ref(x + s * d, l_ce, a, l_mtu, p) for s in (1.0, -1.0))
            dr_plus = (rp - _residual_ref(x, l_ce, a, l_mtu, p)) / d
            dr_minus = (_residual_ref(x, l_ce, a, l_mtu, p) - rm) / d
            if abs(dr_plus - dr_minus) > 1e-4 * max(1.0, abs(dr_plus)):
                continue                    # a branch point (or curvature) within ±d
            assert dr == pytest.approx(0.5 * (dr_plus + dr_minus), rel=1e-5, abs=1e-5)
            checked += 1
    assert checked > 1500


@pytest.mark.parametrize("states", [_states, _isometric_states], ids=["grid", "isometric"])
def test_newton_solve_is_brentqs_root(states):
    """Every solve (cold start, and started 1 and 100 mm/s off) within 1e-10 l_opt of
    brentq's root of the same residual."""
    n = 0
    for p, l_ce, a, l_mtu in states():
        lo_m = p.optimal_length_m
        ref = _brentq_root(l_ce, a, l_mtu, p)
        for v_guess in (0.0, 1e-3, -1e-3, 0.1, -0.1):
            x = mu.mtu_step(l_ce, a, l_mtu, H, *_args(p), v_guess)
            assert abs(x - ref) < 1e-10 * lo_m, (p, l_ce, a, l_mtu, v_guess, x, ref)
            n += 1
    assert n >= 900


def test_the_speed_limits_are_roots_too():
    """At zero activation with a stretched tendon the CE lengthens at the rate's cap
    (10 v_max); with a slack tendon beyond l_opt it shortens at v_max: the solve lands on
    ``l_CE + 10 h v_max l_opt`` and ``l_CE − h v_max l_opt``."""
    p = mu.GEYER_HERR_2010["soleus"][0]
    lo_m, vm = p.optimal_length_m, p.max_velocity_lopt_s
    l_ce = lo_m
    x = mu.mtu_step(l_ce, 0.0, l_ce + 1.04 * p.slack_length_m, H, *_args(p))
    assert x == pytest.approx(l_ce + 10.0 * H * vm * lo_m, abs=1e-12 * lo_m)
    l_ce = 1.3 * lo_m
    x = mu.mtu_step(l_ce, 0.0, l_ce + 0.9 * p.slack_length_m, H, *_args(p), 0.05)
    assert x == pytest.approx(l_ce - H * vm * lo_m, abs=1e-12 * lo_m)


def test_the_pair_solve_is_two_single_solves_bit_for_bit():
    """mtu_step_pair (the reflex law's left and right solves interleaved) returns exactly
    what two mtu_step calls return, over the grid (each state paired with the next)."""
    states = list(_states())
    for (p, l0, a0, m0), (_, l1, a1, m1) in zip(states[:-1], states[1:]):
        g0, g1 = 0.01, -0.02
        x0, x1 = mu.mtu_step_pair(l0, a0, m0, g0, l1, a1, m1, g1, H, *_args(p))
        assert x0 == mu.mtu_step(l0, a0, m0, H, *_args(p), g0)
        assert x1 == mu.mtu_step(l1, a1, m1, H, *_args(p), g1)


def test_the_quad_solve_is_four_single_solves_bit_for_bit():
    """mtu_step_quad (two muscles' left and right solves interleaved, as the reflex law
    calls it) returns exactly what four mtu_step calls return: a state of the grid with the
    next (one muscle) and the same two of the following muscle (the other), every 5th."""
    states = list(_states())
    n = len(states) // len(NAMES)                 # states per muscle, muscle by muscle
    g = (0.01, -0.02, 0.0, 0.3)
    checked = 0
    for i in range(0, len(states) - n - 1, 5):
        four = (states[i], states[i + 1], states[i + n], states[i + n + 1])
        if not (four[0][0] is four[1][0] and four[2][0] is four[3][0]):
            continue                              # a pair across two muscles
        (p, l0, a0, m0), (_, l1, a1, m1), (q, l2, a2, m2), (_, l3, a3, m3) = four
        xs = mu.mtu_step_quad(l0, a0, m0, g[0], l1, a1, m1, g[1], *_args(p)[1:],
                              l2, a2, m2, g[2], l3, a3, m3, g[3], *_args(q)[1:], H)
        for x, (pp, lc, a, lm), gg in zip(xs, four, g):
            assert x == mu.mtu_step(lc, a, lm, H, *_args(pp), gg)
        checked += 1
    assert checked > 100
