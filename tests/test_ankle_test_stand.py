"""The ankle test stand against independent references.

References are written out here from the de Leva foot (:func:`scale_body`) and textbook
mechanics, never from the stand's own helpers:

* foot CoM in the foot frame (c_x, c_z) = (CoM from heel − heel-to-ankle, −ankle height / 2);
  rotated by q about −y its forward offset is x(q) = c_x cos q − c_z sin q, the gravity moment on
  the ankle (dorsiflexion positive) is τ_g = −m g x(q), and the foot hangs at x(q_eq) = 0 with the
  CoM below the axis: q_eq = atan2(−c_x, −c_z);
* compound pendulum T = 2π √(I_a / (m g d)), I_a = I_cm + m d² (parallel-axis theorem);
* torsional spring–mass ω_n = √(k_total / I_a), k_total = k + m g d (gravity linearised at q_eq),
  static deflection τ / k;
* Newton's second law about a fixed axis, I θ̈ = Σ τ.
"""

from __future__ import annotations

import math

import mujoco
import numpy as np
import pytest

from afo_mj.hydraulics.params import ParameterError
from afo_mj.human.anthropometry import scale_body
from afo_mj.human.test_stand import (AnkleTestStand, ImposedTrajectory, StandLoad,
                                     build_test_stand, write_default_xml)
from afo_mj.human.walker import build_walker

G = 9.81
MASS, HEIGHT = 75.0, 1.75


def foot_reference(mass=MASS, height=HEIGHT, added_mass=0.0, lever=0.0, added_inertia=0.0):
    """(m, c_x, c_z, I_a) of foot + point mass at (lever, 0, 0) + axis inertia, by hand."""
    b = scale_body(mass, height)
    mf = b.foot.mass_kg
    cxf = b.foot.com_from_proximal_m - b.heel_to_ankle_m
    czf = -0.5 * b.ankle_height_m
    m = mf + added_mass
    cx = (mf * cxf + added_mass * lever) / m
    cz = mf * czf / m
    i_a = (b.foot.inertia_kg_m2 + mf * (cxf ** 2 + czf ** 2) + added_mass * lever ** 2
           + added_inertia)
    return m, cx, cz, i_a


def gravity_moment(q, m, cx, cz):
    return -m * G * (cx * math.cos(q) - cz * math.sin(q))


def equilibrium(cx, cz):
    return math.atan2(-cx, -cz)


def crossing_times(t, y):
    """Times of upward zero crossings of y, linearly interpolated."""
    i = np.flatnonzero((y[:-1] < 0) & (y[1:] >= 0))
    return t[i] - y[i] * (t[i + 1] - t[i]) / (y[i + 1] - y[i])


def test_free_foot_hangs_and_swings_as_a_compound_pendulum():
    m, cx, cz, i_a = foot_reference()
    d = math.hypot(cx, cz)
    q_eq = equilibrium(cx, cz)
    assert q_eq < -0.5  # CoM ahead of the ankle: the free foot hangs plantarflexed
    stand = AnkleTestStand(load=StandLoad(kind="free"), initial_angle_rad=q_eq + 0.02)
    rec = stand.run(None, 3.0)
    tc = crossing_times(rec.time_s, rec.angle_rad - q_eq)
    assert len(tc) >= 3
    period = float(np.mean(np.diff(tc)))
    expected = 2 * math.pi * math.sqrt(i_a / (m * G * d))
    assert period == pytest.approx(expected, rel=0.02)
    # oscillates about q_eq: mean over whole periods is the equilibrium
    sel = (rec.time_s >= tc[0]) & (rec.time_s < tc[-1])
    assert float(np.mean(rec.angle_rad[sel])) == pytest.approx(q_eq, abs=1e-3)
    assert np.max(np.abs(rec.reaction_torque_nm)) < 1e-9  # nothing holds a free foot


def test_spring_natural_frequency_and_static_deflection():
    m, cx, cz, i_a = foot_reference()
    d = math.hypot(cx, cz)
    q_eq = equilibrium(cx, cz)
    k = 200.0  # m g d ≈ 0.58 N·m/rad: gravity is 0.3 % of k
    stand = AnkleTestStand(load=StandLoad(kind="spring", spring_stiffness_nm_per_rad=k,
                                          spring_rest_angle_rad=q_eq),
                           initial_angle_rad=q_eq + 0.01)
    rec = stand.run(None, 0.5)
    tc = crossing_times(rec.time_s, rec.angle_rad - q_eq)
    assert len(tc) >= 8
    omega = 2 * math.pi / float(np.mean(np.diff(tc)))
    assert omega == pytest.approx(math.sqrt((k + m * G * d) / i_a), rel=0.02)

    tau = 5.0
    damped = AnkleTestStand(load=StandLoad(kind="spring", spring_stiffness_nm_per_rad=k,
                                           spring_rest_angle_rad=q_eq,
                                           joint_damping_nm_s_per_rad=2 * math.sqrt(k * i_a)),
                            initial_angle_rad=q_eq)
    rec = damped.run(tau, 1.0)
    deflection = rec.angle_rad[-1] - q_eq
    assert abs(rec.velocity_rad_s[-1]) < 1e-6
    assert deflection == pytest.approx(tau / k, rel=0.01)
    # the spring's load cell reads the device torque less the gravity moment it carries
    assert rec.reaction_torque_nm[-1] == pytest.approx(k * deflection, rel=1e-3)


@pytest.mark.parametrize("q_lock", [0.1, -0.3])
@pytest.mark.parametrize("tau", [20.0, 40.0])
def test_locked_reaction_reads_back_device_torque(tau, q_lock):
    m, cx, cz, _ = foot_reference()
    stand = AnkleTestStand(load=StandLoad(kind="locked", locked_angle_rad=q_lock))
    rec = stand.run(tau, 0.2)
    assert np.max(np.abs(rec.angle_rad - q_lock)) < 1e-3
    expected = tau + gravity_moment(q_lock, m, cx, cz)
    assert rec.reaction_torque_nm[-1] == pytest.approx(expected, rel=0.01)
    assert stand.reaction_torque_nm == pytest.approx(expected, rel=0.01)
    # and the opposite direction (plantarflexing device)
    stand.reset()
    rec = stand.run(-tau, 0.2)
    assert rec.reaction_torque_nm[-1] == pytest.approx(-tau + gravity_moment(q_lock, m, cx, cz),
                                                       rel=0.01)


def test_added_inertia_and_mass_slow_the_torque_step():
    i_add, m_add, lever = 0.02, 0.5, 0.1
    m, cx, cz, i_a = foot_reference(added_mass=m_add, lever=lever, added_inertia=i_add)
    q_eq = equilibrium(cx, cz)  # the added mass moves the hanging angle
    stand = AnkleTestStand(load=StandLoad(kind="inertia", added_inertia_kg_m2=i_add,
                                          added_mass_kg=m_add, added_mass_lever_m=lever),
                           initial_angle_rad=q_eq)
    # at rest at q_eq: gravity holds no torque, so the foot does not move without the device
    rec0 = stand.run(None, 0.05)
    assert np.max(np.abs(rec0.angle_rad - q_eq)) < 1e-6
    stand.reset(q_eq)
    tau = 2.0
    rec = stand.run(tau, 0.010)  # 10 ms: Δq ≈ 3 mrad, gravity change < 0.2 % of τ
    alpha = (rec.velocity_rad_s[-1] + stand.timestep_s * rec.acceleration_rad_s2[-1]) / 0.010
    assert alpha == pytest.approx(tau / i_a, rel=0.02)
    # plain foot is clearly faster: the test would notice a missing added body
    _, _, _, i_foot = foot_reference()
    assert tau / i_foot > 2 * alpha


def test_imposed_sinusoid_is_followed_and_drive_torque_matches_dynamics():
    m, cx, cz, i_a = foot_reference()
    amp, f, off = 0.3, 2.0, -0.5
    w = 2 * math.pi * f
    traj = ImposedTrajectory.sinusoid(amp, f, off)
    stand = AnkleTestStand(load=StandLoad(kind="imposed", trajectory=traj))
    device = lambda t, q, v: 0.2 * math.sin(2 * math.pi * 3.0 * t)  # noqa: E731
    rec = stand.run(device, 1.5)
    t = rec.time_s
    q_ref = off + amp * np.sin(w * t)
    acc_ref = -amp * w * w * np.sin(w * t)
    assert np.max(np.abs(rec.angle_rad - q_ref)) < 1e-3
    sel = t > 0.1
    # drive torque (= −reaction, load-cell sign) = I_a θ̈ − τ_g(θ) − τ_device
    grav = np.array([gravity_moment(q, m, cx, cz) for q in q_ref])
    drive_expected = i_a * acc_ref - grav - rec.device_torque_nm
    err = np.max(np.abs(-rec.reaction_torque_nm[sel] - drive_expected[sel]))
    assert err < 0.05 * np.max(np.abs(drive_expected[sel]))


def test_sampled_imposed_trajectory_is_followed():
    tt = np.linspace(0.0, 1.0, 201)
    qq = -0.4 + 0.2 * np.sin(2 * math.pi * 1.5 * tt) ** 2
    stand = AnkleTestStand(load=StandLoad(kind="imposed",
                                          trajectory=ImposedTrajectory.sampled(tt, qq)))
    rec = stand.run(None, 1.0)
    assert np.max(np.abs(rec.angle_rad - np.interp(rec.time_s, tt, qq))) < 1e-3


def test_bad_load_kind_names_key_value_and_allowed():
    with pytest.raises(ParameterError) as e:
        StandLoad(kind="clamped")
    msg = str(e.value)
    assert "kind" in msg and "clamped" in msg
    for allowed in ("free", "locked", "spring", "inertia", "imposed"):
        assert allowed in msg
    with pytest.raises(ParameterError, match="trajectory"):
        StandLoad(kind="imposed")
    with pytest.raises(ParameterError, match="spring_stiffness_nm_per_rad"):
        StandLoad(kind="spring", spring_stiffness_nm_per_rad=-1.0)


def test_foot_and_sites_match_the_walker(tmp_path):
    walker = build_walker()
    stand = build_test_stand()
    for name in ("shank_cuff", "foot_plate", "ankle_axis"):
        np.testing.assert_allclose(stand.find("site", name).pos,
                                   walker.find("site", f"{name}_r").pos)
    wi = walker.find("body", "foot_r").inertial
    si = stand.find("body", "foot").inertial
    assert si.mass == wi.mass
    np.testing.assert_allclose(si.pos, wi.pos)
    np.testing.assert_allclose(si.diaginertia, wi.diaginertia)
    path = write_default_xml(tmp_path / "stand.xml")
    model = mujoco.MjModel.from_xml_path(str(path))
    assert model.nu == 1 and model.njnt == 1 and model.neq == 0
    assert model.actuator(0).name == "device_ankle"
