"""Hill-type muscle–tendon units (afo_mj.human.muscle) against independent references: the
published relations' defining values (Geyer & Herr 2010), analytic integrals (tendon
energy), the exact activation solution, scipy's Radau on the same ODE (a second, adaptive
integrator), a force balance solved by bisection, and numerical derivatives of the path."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import quad, solve_ivp

from afo_mj.human import muscle as mu

SOL = mu.GEYER_HERR_2010["soleus"][0]
VAS = mu.GEYER_HERR_2010["vasti"][0]


def test_force_length_defining_values():
    assert mu.ce_force_length(0.04, 0.04) == 1.0
    for side in (-1, 1):
        assert mu.ce_force_length(0.04 * (1 + side * mu.W_WIDTH), 0.04) == pytest.approx(0.05)
    # symmetric and below 1 away from the optimum
    assert mu.ce_force_length(0.05, 0.04) == pytest.approx(mu.ce_force_length(0.03, 0.04))
    assert mu.ce_force_length(0.05, 0.04) < 1.0


def test_force_velocity_defining_values_and_inverse():
    vm = 12.0
    assert mu.ce_force_velocity(-vm, vm) == 0.0
    assert mu.ce_force_velocity(0.0, vm) == 1.0
    assert mu.ce_force_velocity(1e6, vm) == pytest.approx(mu.F_V_INFINITY, rel=1e-5)
    # Hill's hyperbola: at a third of v_max the force is (1 − 1/3)/(1 + K/3)
    assert mu.ce_force_velocity(-vm / 3, vm) == pytest.approx((2 / 3) / (1 + mu.K_CURVATURE / 3))
    v = np.concatenate([np.linspace(-vm * 0.999, 0, 50), np.linspace(0, 20 * vm, 80)[1:]])
    f = np.array([mu.ce_force_velocity(x, vm) for x in v])
    assert np.all(np.diff(f) > 0)                       # strictly increasing
    back = np.array([mu.ce_velocity_from_force(x, vm) for x in f])
    inside = v <= 10 * vm
    assert np.allclose(back[inside], v[inside], rtol=1e-9, atol=1e-9)
    assert np.all(back[~inside] == 10 * vm)             # the cap


def test_tendon_force_and_stored_energy():
    """F_SE = F_max at 4 % strain; the energy stored to strain ε is
    F_max l_slack ε³ / (3 ε_ref²) (the integral of the quadratic spring, by hand)."""
    f, ls = SOL.max_force_n, SOL.slack_length_m
    assert mu.se_force_n(ls * 1.04, ls, f) == pytest.approx(f)
    assert mu.se_force_n(ls * 0.99, ls, f) == 0.0
    eps = 0.05
    stored, _ = quad(lambda x: mu.se_force_n(x, ls, f), ls, ls * (1 + eps))
    assert stored == pytest.approx(f * ls * eps ** 3 / (3 * mu.EPS_REF ** 2), rel=1e-9)


def test_activation_step_is_the_exact_exponential():
    a, t = 0.01, 0.0
    for _ in range(37):
        a = mu.activation_step(a, 1.0, 1e-3, mu.TAU_ACTIVATION_S)
        t += 1e-3
    assert a == pytest.approx(1.0 - 0.99 * math.exp(-t / mu.TAU_ACTIVATION_S), rel=1e-12)


def test_isometric_activation_settles_on_the_force_balance():
    """An MTU held at l_opt + l_slack, activation stepped from 0.01 to 1: the CE shortens
    against the tendon until F_SE = F_CE + F_PE; the stepped CE length equals the balance
    found by bisection (a separate solution of the static equation) to 1e-9."""
    l_mtu = SOL.optimal_length_m + SOL.slack_length_m
    x = mu.equilibrium_ce_length_m(0.01, l_mtu, SOL)
    a = 0.01
    for _ in range(3000):          # 3 s: the CE creeps to balance with τ ≈ 0.12 s here
        a = mu.activation_step(a, 1.0, 1e-3, mu.TAU_ACTIVATION_S)
        x = mu.mtu_step(x, a, l_mtu, 1e-3, SOL.max_force_n, SOL.max_velocity_lopt_s,
                        SOL.optimal_length_m, SOL.slack_length_m)
    target = mu.equilibrium_ce_length_m(a, l_mtu, SOL)
    assert x == pytest.approx(target, rel=1e-9)
    # the tendon then carries the active force: most of F_max at this length
    f_se = mu.se_force_n(l_mtu - x, SOL.slack_length_m, SOL.max_force_n)
    assert 0.6 * SOL.max_force_n < f_se < SOL.max_force_n


def _radau_reference(p, l_mtu_fn, a_fn, x0, t_end):
    def rhs(t, y):
        return [mu.mtu_rate(y[0], a_fn(t), l_mtu_fn(t), p.max_force_n, p.max_velocity_lopt_s,
                            p.optimal_length_m, p.slack_length_m)]
    return solve_ivp(rhs, (0.0, t_end), [x0], method="Radau", rtol=1e-10, atol=1e-13,
                     dense_output=True, max_step=1e-3)


@pytest.mark.parametrize("name", ["soleus", "vasti"])
def test_backward_euler_against_radau(name):
    """A stretch–shorten cycle of the MTU (±2 cm at 2 Hz) under a rising then falling
    activation: the backward-Euler CE length at 1 ms and 0.25 ms against scipy's Radau at
    1e-10. Error below 0.5 % of l_opt at 1 ms and falling at least twofold with a fourfold
    smaller step (first order; measured: 0.056 % → 0.023 % for the soleus)."""
    p = mu.GEYER_HERR_2010[name][0]
    l0 = p.optimal_length_m + p.slack_length_m

    def l_mtu(t):
        return l0 + 0.02 * math.sin(2 * math.pi * 2.0 * t)

    def a_of(t):
        return 0.05 + 0.9 * math.sin(math.pi * min(t / 0.5, 1.0)) ** 2

    x0 = mu.equilibrium_ce_length_m(a_of(0.0), l_mtu(0.0), p)
    t_end = 0.5
    ref = _radau_reference(p, l_mtu, a_of, x0, t_end)
    errs = []
    for h in (1e-3, 2.5e-4):
        n = int(round(t_end / h))
        x, err = x0, 0.0
        for k in range(1, n + 1):
            t = k * h
            x = mu.mtu_step(x, a_of(t), l_mtu(t), h, p.max_force_n, p.max_velocity_lopt_s,
                            p.optimal_length_m, p.slack_length_m)
            err = max(err, abs(x - ref.sol(t)[0]))
        errs.append(err / p.optimal_length_m)
    assert errs[0] < 0.005, errs
    assert errs[1] < errs[0] / 2.0, errs


def test_path_moment_arm_is_the_length_derivative():
    """For every muscle and joint: dΔl/dφ = s ρ r(φ) (central differences), and Δl = 0 at
    φ_ref (the MTU is l_opt + l_slack long there)."""
    for name, (p, paths) in mu.GEYER_HERR_2010.items():
        for jp in paths:
            const = jp.phi_max_rad is None
            pm = 0.0 if const else jp.phi_max_rad
            for phi in np.linspace(jp.phi_ref_rad - 0.6, jp.phi_ref_rad + 0.6, 7):
                d = 1e-6
                lp, _ = mu.path_length_and_arm(phi + d, jp.sign, jp.r0_m, pm, jp.phi_ref_rad,
                                               jp.rho, const)
                lm, _ = mu.path_length_and_arm(phi - d, jp.sign, jp.r0_m, pm, jp.phi_ref_rad,
                                               jp.rho, const)
                _, r = mu.path_length_and_arm(phi, jp.sign, jp.r0_m, pm, jp.phi_ref_rad,
                                              jp.rho, const)
                assert (lp - lm) / (2 * d) == pytest.approx(jp.sign * jp.rho * r, rel=1e-6,
                                                             abs=1e-12), (name, jp.joint)
            l_ref, _ = mu.path_length_and_arm(jp.phi_ref_rad, jp.sign, jp.r0_m, pm,
                                              jp.phi_ref_rad, jp.rho, const)
            assert l_ref == 0.0


def test_muscle_actions_in_walker_angles():
    """In the walker's convention (τ_θ = s r F): soleus and gastrocnemius plantarflex,
    tibialis anterior dorsiflexes, vasti extend the knee, hamstrings and gastrocnemius flex
    it, gluteals and hamstrings extend the hip, hip flexors flex it; and dorsiflexing the
    ankle lengthens the soleus (Geyer's ankle angle falls)."""
    expect = {("soleus", "ankle"): -1, ("gastrocnemius", "ankle"): -1,
              ("tibialis_anterior", "ankle"): 1, ("vasti", "knee"): -1,
              ("hamstrings", "knee"): 1, ("gastrocnemius", "knee"): 1,
              ("hamstrings", "hip"): -1, ("gluteals", "hip"): -1, ("hip_flexors", "hip"): 1}
    for (name, joint), sign in expect.items():
        jp = next(j for j in mu.GEYER_HERR_2010[name][1] if j.joint == joint)
        # torque in the walker's angle = s · r · F, r > 0 near φ_ref
        assert jp.sign == sign, (name, joint)
    # dorsiflexion (θ up) lowers Geyer's ankle angle and lengthens the soleus
    jp = mu.GEYER_HERR_2010["soleus"][1][0]
    lengths = [mu.path_length_and_arm(float(mu.to_geyer_angle("ankle", th)), jp.sign, jp.r0_m,
                                      jp.phi_max_rad, jp.phi_ref_rad, jp.rho, False)[0]
               for th in (-0.2, 0.0, 0.2)]
    assert lengths[0] < lengths[1] < lengths[2]


def test_tendon_returns_its_energy_over_a_cycle():
    """A stretch–shorten cycle of the MTU with the activation held high: the tendon's net
    work over the closed cycle is ~0 (it is elastic: what it stores while the MTU is
    stretched it returns while it shortens), while it stores a sizeable energy at the peak."""
    p = SOL
    l0 = p.optimal_length_m + p.slack_length_m
    h = 2.5e-4
    n = int(round(0.5 / h))
    x = mu.equilibrium_ce_length_m(0.8, l0, p)
    l_se_prev = l0 - x
    f_prev = mu.se_force_n(l_se_prev, p.slack_length_m, p.max_force_n)
    work, peak = 0.0, 0.0
    for k in range(1, n + 1):
        l_mtu = l0 + 0.015 * math.sin(2 * math.pi * 2.0 * k * h)
        x = mu.mtu_step(x, 0.8, l_mtu, h, p.max_force_n, p.max_velocity_lopt_s,
                        p.optimal_length_m, p.slack_length_m)
        l_se = l_mtu - x
        f = mu.se_force_n(l_se, p.slack_length_m, p.max_force_n)
        work += 0.5 * (f + f_prev) * (l_se - l_se_prev)          # trapezoid on the path
        stored = p.max_force_n * p.slack_length_m * max(l_se / p.slack_length_m - 1, 0) ** 3 \
            / (3 * mu.EPS_REF ** 2)
        peak = max(peak, stored)
        l_se_prev, f_prev = l_se, f
    # the CE does not end exactly where it started; the tendon's work equals its stored
    # energy's change (elastic), checked against the analytic potential
    start = p.max_force_n * p.slack_length_m * max((l0 - mu.equilibrium_ce_length_m(
        0.8, l0, p)) / p.slack_length_m - 1, 0) ** 3 / (3 * mu.EPS_REF ** 2)
    end = p.max_force_n * p.slack_length_m * max(l_se_prev / p.slack_length_m - 1, 0) ** 3 \
        / (3 * mu.EPS_REF ** 2)
    assert work == pytest.approx(end - start, abs=1e-3 * peak)
    assert peak > 5.0                                              # J


@pytest.mark.parametrize("kwargs, name", [
    (dict(max_force_n=-1.0), "max_force_n"),
    (dict(slow_twitch_fraction=1.5), "slow_twitch_fraction"),
    (dict(optimal_length_m=0.0), "optimal_length_m"),
])
def test_bad_parameters_name_the_field(kwargs, name):
    with pytest.raises(mu.ParameterError, match=name):
        mu.MuscleParams(**kwargs)


def test_bad_path_names_the_field():
    with pytest.raises(mu.ParameterError, match="sign"):
        mu.JointPath("ankle", 0, 0.05, 1.4, 0.5, 1.9)
    with pytest.raises(mu.ParameterError, match="phi_max_rad"):
        mu.JointPath("hip", 1, 0.05, 3.0, 0.5, 2.0)
    with pytest.raises(ValueError, match="joint"):
        mu.to_geyer_angle("elbow", 0.0)
