"""The walker model: anthropometry against published tables, sites, worn masses, strength limits."""

from __future__ import annotations

import math
import os

os.environ.setdefault("MUJOCO_GL", "egl")

import mujoco  # noqa: E402

import pytest  # noqa: E402

from afo_mj.hydraulics.params import ParameterError  # noqa: E402
from afo_mj.human.anthropometry import scale_body  # noqa: E402
from afo_mj.human.walker import WalkerParams, WalkerPhysics, WornMass, build_walker  # noqa: E402


def test_segments_follow_de_leva_and_winter_proportions():
    b = scale_body(75.0, 1.75)
    # de Leva (1996) Table 4, males: mass fractions 14.16 / 4.33 / 1.37 %.
    assert b.thigh.mass_kg == pytest.approx(0.1416 * 75, rel=1e-9)
    assert b.shank.mass_kg == pytest.approx(0.0433 * 75, rel=1e-9)
    assert b.foot.mass_kg == pytest.approx(0.0137 * 75, rel=1e-9)
    # Winter (2009) Fig. 4.1: hip (greater trochanter) height 0.530 H, foot length 0.152 H.
    assert b.hip_height_m / 1.75 == pytest.approx(0.530, rel=0.02)
    assert b.foot.length_m / 1.75 == pytest.approx(0.152, rel=0.04)
    # HAT (head, arms, trunk) = 1 − 2 × (thigh + shank + foot) = 60.28 % of body mass.
    assert b.hat.mass_kg / 75 == pytest.approx(0.6028, abs=1e-4)
    # Winter's HAT CoM lies 0.626 of the way from hip (GT) to shoulder (0.818 H − 0.530 H).
    assert b.hat.com_from_proximal_m / 1.75 == pytest.approx(0.626 * (0.818 - 0.530), rel=0.12)


def test_scaling_with_height_and_mass():
    a, b = scale_body(75.0, 1.75), scale_body(37.5, 1.40)
    assert b.thigh.length_m / a.thigh.length_m == pytest.approx(1.40 / 1.75)
    assert b.thigh.mass_kg / a.thigh.mass_kg == pytest.approx(0.5)
    # I = m (r L)^2 → scales as mass × length²
    assert b.thigh.inertia_kg_m2 / a.thigh.inertia_kg_m2 == pytest.approx(0.5 * (1.40 / 1.75) ** 2)


def test_model_mass_sites_and_clinical_signs():
    phys = WalkerPhysics(build_walker(WalkerParams(body_mass_kg=60.0, height_m=1.6)))
    assert phys.body_mass_kg == pytest.approx(60.0, rel=1e-6)
    m = phys.model
    for site in ("waist", "shank_cuff_r", "foot_plate_l", "ankle_axis_r"):
        assert mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_SITE, site) >= 0, site
    d = phys.data
    mujoco.mj_kinematics(m, d)
    toe0 = d.geom_xpos[phys.contact_geoms[0, 1]].copy()
    d.qpos[phys.qpos_adr["ankle_r"]] = 0.3         # dorsiflexion lifts the forefoot
    mujoco.mj_kinematics(m, d)
    assert d.geom_xpos[phys.contact_geoms[0, 1], 2] > toe0[2] + 0.02
    d.qpos[phys.qpos_adr["ankle_r"]] = 0.0
    d.qpos[phys.qpos_adr["hip_r"]] = 0.5           # hip flexion moves the knee forward
    mujoco.mj_kinematics(m, d)
    knee = d.xpos[mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, "shank_r")]
    assert knee[0] > 0.15


def test_worn_masses_are_added_where_worn():
    base = WalkerPhysics(build_walker())
    worn = WalkerPhysics(build_walker(worn_masses=[WornMass("waist", 2.33, "supply"),
                                                   WornMass("shank_cuff_r", 0.97, "ankle")]))
    assert worn.body_mass_kg - base.body_mass_kg == pytest.approx(3.3, abs=1e-6)
    shank = mujoco.mj_name2id(worn.model, mujoco.mjtObj.mjOBJ_BODY, "shank_r")
    assert (worn.model.body_subtreemass[shank] - base.model.body_subtreemass[shank]
            == pytest.approx(0.97, abs=1e-6))
    with pytest.raises(ParameterError, match="nowhere"):
        build_walker(worn_masses=[WornMass("nowhere", 1.0)])


def test_strength_limits_clamp_net_ankle_torque():
    p = WalkerParams(plantarflexor_strength_fraction=0.5)
    phys = WalkerPhysics(build_walker(p))
    limit = 0.5 * p.plantarflexor_strength_nm_per_kg * p.body_mass_kg
    assert phys.ankle_torque_limits_nm[0, 0] == pytest.approx(-limit)
    d = phys.data
    d.ctrl[phys.ff_act[0, 2]] = -500.0             # ask for far more plantarflexion torque
    mujoco.mj_forward(phys.model, d)
    assert phys.leg_actuator_torques_nm()[0, 2] == pytest.approx(-limit, rel=1e-9)


def test_bad_walker_parameter_names_key_and_range():
    with pytest.raises(ParameterError, match="plantarflexor_strength_fraction.*1.5"):
        WalkerParams(plantarflexor_strength_fraction=1.5)
    assert math.isfinite(WalkerParams().sole_pitch_rad)


def test_committed_mjcf_files_match_the_builders():
    from afo_mj.human import test_stand
    from afo_mj.human.walker import DEFAULT_XML_PATH
    assert DEFAULT_XML_PATH.read_text() == build_walker().to_xml_string()
    stand = test_stand.build_test_stand(75.0, 1.75, test_stand.StandLoad(kind="free"))
    assert test_stand.DEFAULT_XML_PATH.read_text() == stand.to_xml_string()
    model = mujoco.MjModel.from_xml_path(str(DEFAULT_XML_PATH))
    assert model.nq == 9 and model.nu == 15


def test_dynamic_scale_factors():
    from afo_mj.human.walker import DynamicScale
    ds = DynamicScale.of(37.5, 1.75 * 0.64)
    assert ds.time == pytest.approx(0.8) and ds.speed == pytest.approx(0.8)
    assert ds.torque == pytest.approx(0.5 * 0.64)
    assert ds.rotational_damping == pytest.approx(0.5 * 0.64 * 0.8)
    assert ds.linear_stiffness == pytest.approx(0.5 / 0.64)
    assert ds.linear_damping == pytest.approx(0.5 / 0.8)
    # strengths per kg are stated for 1.75 m and scale with stature
    p = WalkerParams(body_mass_kg=37.5, height_m=1.12)
    phys = WalkerPhysics(build_walker(p))
    assert -phys.ankle_torque_limits_nm[0, 0] == pytest.approx(2.5 * 37.5 * 0.64)
