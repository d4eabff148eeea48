"""Stiffness metrics of torque–angle sweeps against closed-form references.

References (derived in the test docstrings, not taken from the code):
* linear spring τ = −K(θ − θ0): slope K, rest angle θ0, no loop;
* spring + viscous damper τ = −Kθ − Bθ̇ under θ = A sin ωt: loop area π B ω A² per cycle,
  loss factor η = Bω/K (Nashif, Jones & Henderson 1985 §2.2), r² = K²/(K² + B²ω²), peak torque
  A√(K² + B²ω²), loading work K A² + π B ω A²/2 per cycle;
* bilinear spring (−K1 θ below 0, −K2 θ above): least-squares slope (K1 + K2)/2 and rest angle
  −2A(K2 − K1)/(π(K1 + K2)) over whole cycles of a sinusoid;
* spring + Coulomb friction F: loop area 4 F A per cycle.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from afo_mj.metrics.stiffness_metrics import (StiffnessSweepError, sweep_stiffness,
                                               turning_points)

N_PER_CYCLE = 1000
A = 0.25                         # rad, ~14 deg each way
F_HZ = 0.5                       # a slow rig
W = 2 * math.pi * F_HZ


def _sine(cycles: float = 4.0, offset: float = 0.0):
    """θ = offset + A sin ωt, N_PER_CYCLE samples per period, and θ̇."""
    t = np.arange(int(round(cycles * N_PER_CYCLE)) + 1) / (N_PER_CYCLE * F_HZ)
    return t, offset + A * np.sin(W * t), A * W * np.cos(W * t)


def test_linear_spring_slope_rest_angle_and_no_loop():
    k, theta0 = 40.0, 0.05
    _, th, _ = _sine(offset=theta0)
    r = sweep_stiffness(th, -k * (th - theta0))
    assert r.stiffness_nm_per_rad == pytest.approx(k, rel=1e-12)
    assert r.stiffness_nm_per_deg == pytest.approx(k * math.pi / 180, rel=1e-12)
    assert r.rest_angle_rad == pytest.approx(theta0, abs=1e-12)
    assert r.r_squared == pytest.approx(1.0, abs=1e-12)
    assert r.dorsiflexing_stiffness_nm_per_rad == pytest.approx(k, rel=1e-12)
    assert r.plantarflexing_stiffness_nm_per_rad == pytest.approx(k, rel=1e-12)
    assert abs(r.hysteresis_energy_j) < 1e-12 * k * A ** 2
    assert r.loss_factor == pytest.approx(0.0, abs=1e-12)
    assert r.hysteresis_fraction == pytest.approx(0.0, abs=1e-12)
    assert r.max_torque_nm == pytest.approx(k * A, rel=1e-5)
    assert r.angle_amplitude_rad == pytest.approx(A, rel=1e-5)
    # 4 periods from a zero crossing: turning points at 1/4, 3/4, ... → 3 whole cycles, the
    # first dropped as start-up
    assert r.n_cycles == 2


def test_spring_damper_loop_area_and_loss_factor():
    k, b = 40.0, 3.0
    _, th, om = _sine()
    r = sweep_stiffness(th, -k * th - b * om, velocity_rad_s=om)
    assert r.stiffness_nm_per_rad == pytest.approx(k, rel=1e-9)
    assert r.rest_angle_rad == pytest.approx(0.0, abs=1e-9)
    assert r.hysteresis_energy_j == pytest.approx(math.pi * b * W * A ** 2, rel=1e-4)
    assert r.loss_factor == pytest.approx(b * W / k, rel=1e-4)
    assert r.r_squared == pytest.approx(k ** 2 / (k ** 2 + (b * W) ** 2), rel=1e-6)
    assert r.max_torque_nm == pytest.approx(A * math.hypot(k, b * W), rel=1e-4)
    w_load = k * A ** 2 + math.pi * b * W * A ** 2 / 2
    assert r.hysteresis_fraction == pytest.approx(math.pi * b * W * A ** 2 / w_load, rel=1e-3)
    # the branches are parallel (offset by the damper torque), each with slope K
    assert r.dorsiflexing_stiffness_nm_per_rad == pytest.approx(k, rel=1e-3)
    assert r.plantarflexing_stiffness_nm_per_rad == pytest.approx(k, rel=1e-3)


def test_velocity_from_the_samples_when_not_given():
    k, b = 40.0, 3.0
    _, th, om = _sine()
    r = sweep_stiffness(th, -k * th - b * om)
    assert r.loss_factor == pytest.approx(b * W / k, rel=1e-4)
    assert r.dorsiflexing_stiffness_nm_per_rad == pytest.approx(k, rel=1e-3)


def test_bilinear_clutched_spring():
    k1, k2 = 10.0, 70.0           # soft in plantarflexion, clutch engaged in dorsiflexion
    _, th, _ = _sine()
    tau = np.where(th > 0, -k2 * th, -k1 * th)
    r = sweep_stiffness(th, tau)
    assert r.stiffness_nm_per_rad == pytest.approx((k1 + k2) / 2, rel=1e-4)
    assert r.rest_angle_rad == pytest.approx(-2 * A * (k2 - k1) / (math.pi * (k1 + k2)),
                                             rel=1e-3)
    assert abs(r.loss_factor) < 1e-9 and abs(r.hysteresis_fraction) < 1e-9
    # fitting inside one region gives that region's stiffness exactly
    assert sweep_stiffness(th, tau, angle_window_rad=(0.0, A)).stiffness_nm_per_rad == \
        pytest.approx(k2, rel=1e-12)
    assert sweep_stiffness(th, tau, angle_window_rad=(-A, 0.0)).stiffness_nm_per_rad == \
        pytest.approx(k1, rel=1e-12)


def test_coulomb_friction_loop_area():
    """Spring K plus friction F: the loop is a parallelogram of height 2F and width 2A."""
    k, f = 40.0, 0.5
    _, th, om = _sine()
    r = sweep_stiffness(th, -k * th - f * np.sign(om), velocity_rad_s=om)
    assert r.hysteresis_energy_j == pytest.approx(4 * f * A, rel=2e-3)
    assert r.loss_factor == pytest.approx(4 * f / (math.pi * k * A), rel=2e-3)
    assert r.dorsiflexing_stiffness_nm_per_rad == pytest.approx(k, rel=1e-9)
    assert r.plantarflexing_stiffness_nm_per_rad == pytest.approx(k, rel=1e-9)


@pytest.mark.parametrize("seed", range(10))
def test_noise_robustness(seed):
    """1 % noise (SD) on torque (of the peak) and on angle (of the amplitude): K within 1 %."""
    rng = np.random.default_rng(seed)
    k, b = 40.0, 1.0
    _, th, om = _sine()
    tau = -k * th - b * om
    th_n = th + 0.01 * A * rng.standard_normal(th.size)
    tau_n = tau + 0.01 * np.abs(tau).max() * rng.standard_normal(th.size)
    r = sweep_stiffness(th_n, tau_n)
    assert r.stiffness_nm_per_rad == pytest.approx(k, rel=0.01)
    assert r.loss_factor == pytest.approx(b * W / k, abs=0.01)
    assert r.n_cycles == 2


def test_start_up_cycle_is_ignored():
    k = 40.0
    t, th, _ = _sine()
    tau = -k * th * np.where(t < 1.25 / F_HZ, 3.0, 1.0)   # a different first cycle
    r = sweep_stiffness(th, tau)
    assert r.stiffness_nm_per_rad == pytest.approx(k, rel=1e-12)
    assert r.n_cycles == 2


def test_one_way_sweep_gives_stiffness_without_loop():
    th = np.linspace(-0.2, 0.3, 200)
    r = sweep_stiffness(th, 1.5 - 25.0 * th)
    assert r.stiffness_nm_per_rad == pytest.approx(25.0, rel=1e-12)
    assert r.rest_angle_rad == pytest.approx(0.06, rel=1e-12)
    assert r.n_cycles == 0
    assert math.isnan(r.hysteresis_energy_j) and math.isnan(r.loss_factor)
    assert math.isnan(r.plantarflexing_stiffness_nm_per_rad)


def test_rig_applied_torque_gives_negative_k():
    """The convention is the orthosis torque on the ankle; a rig's applied torque is minus."""
    _, th, _ = _sine()
    assert sweep_stiffness(th, 40.0 * th).stiffness_nm_per_rad == pytest.approx(-40.0)


def test_turning_points_alternate():
    _, th, _ = _sine(cycles=2.0)
    tp = turning_points(th)
    assert list(tp) == [250, 750, 1250, 1750]


@pytest.mark.parametrize("angle, torque, kw, match", [
    (np.arange(5.0), np.arange(5.0), {}, r"5 samples; allowed: at least 10"),
    (np.zeros(50), np.zeros(50), {}, r"does not move"),
    (np.r_[np.linspace(0, 1, 20), np.nan], np.zeros(21), {}, r"angle_rad .*non-finite.*index 20"),
    (np.linspace(0, 1, 20), np.r_[np.zeros(19), np.inf], {}, r"torque_nm .*non-finite.*index 19"),
    (np.linspace(0, 1, 20), np.zeros(19), {}, r"different lengths \(20 and 19\)"),
    (np.zeros((4, 5)), np.zeros((4, 5)), {}, r"one-dimensional"),
    (np.linspace(0, 1, 20), np.zeros(20), {"velocity_rad_s": np.ones(3)}, r"velocity_rad_s"),
    (np.linspace(0, 1, 20), np.zeros(20), {"angle_window_rad": (0.5, 0.2)}, r"lo < hi"),
    (np.linspace(0, 1, 20), np.zeros(20), {"angle_window_rad": (2.0, 3.0)}, r"holds 0 samples"),
    (np.linspace(0, 1, 20), np.zeros(20), {"angle_window_rad": "x"}, r"pair of numbers"),
])
def test_errors(angle, torque, kw, match):
    with pytest.raises(StiffnessSweepError, match=match):
        sweep_stiffness(angle, torque, **kw)
