"""OpenSim round trip (issue 43 item 2): OpenSim 4.6 itself reads the files of a simulated walk,
and its inverse dynamics tool, run on our coordinates (``_ik.mot``), ground reaction forces
(``_grf.mot`` + ``_grf.xml``) and model of the walker (``.osim``,
:mod:`afo_mj.outputs.opensim_model`), reproduces the walk's own joint moments and pelvis
residuals. The reference is the walk's record (what MuJoCo applied), not our files; OpenSim
computes its moments from the motion and the external loads alone.

Measured (``scenarios/walk_healthy.toml``, 3 strides, t = 0.5 s … the end − 0.1 s, 1 kHz,
OpenSim 4.6, no low-pass filter): RMS difference / peak |moment| hip 2.1 %, knee 1.4 %,
ankle 0.26 % (either side); pelvis residual forces RMS 2.5 N (forward), 10 N (vertical), 1.4 %
of body weight. Asserted: ≤ 5 % per joint. What remains is understood:

* heel strike: the contact force rises by hundreds of newtons within one 1 ms step, a kink in
  the joint velocities. OpenSim differentiates the coordinates through quintic splines (GCV,
  interpolating without a filter), whose second derivative rings for a few samples around the
  kink (up to 50 N·m at the hip for about 5 ms): most of the RMS;
* MuJoCo's ``implicitfast`` integrator takes the PD servos' damping at the end-of-step
  velocity, so the moment that acted is the recorded one (``qfrc_actuator``, at the start-of-step
  velocity) minus ``kv·(q̇ₖ − q̇ₖ₋₁)`` (``kv`` the servo damping, read here from the compiled
  model). With that term the median difference is below 0.05 N·m at every joint (asserted): the
  model's masses, inertias, frames and signs and the loads' points agree to rounding.

Without the one-step shift of the force files (:mod:`afo_mj.outputs.opensim_export`, Timing) the
hip misses by 8.6 % of its peak: that check fails. Skipped where opensim is not installed
(``pip install opensim==4.6``, in the ``test`` extra).
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest

from afo_mj.outputs.opensim_export import write_opensim
from afo_mj.outputs.opensim_model import OpenSimModelError, osim_model_xml
from cli_helpers import run_cli

ROOT = Path(__file__).resolve().parents[1]
COORDS = (("hip_flexion", "hip"), ("knee_angle", "knee"), ("ankle_angle", "ankle"))
G = 9.80665


def _opensim():
    osim = pytest.importorskip(
        "opensim", reason="opensim is not installed (pip install opensim==4.6): OpenSim round "
                          "trip skipped")
    osim.Logger.removeFileSink()        # no opensim.log in the working directory
    osim.Logger.setLevelString("warn")
    return osim


@pytest.fixture(scope="module")
def walk(tmp_path_factory):
    from afo_mj.gait.walk import simulate_walk
    from afo_mj.scenarios.walk_scenario import load_scenario
    sc = load_scenario(ROOT / "scenarios" / "walk_healthy.toml",
                       overrides=["gait.strides=3", "gait.analyse_strides=[2, 3]"])
    rec = simulate_walk(sc)
    out = tmp_path_factory.mktemp("osim_rt")
    return rec, write_opensim(rec, out, "walk")


@pytest.fixture(scope="module")
def inverse_dynamics(walk):
    """OpenSim's inverse dynamics of the walk: ``(labels, rows)`` of its output."""
    osim = _opensim()
    rec, paths = walk
    out = paths["ik"].parent
    model = osim.Model(str(paths["model"]))
    model.initSystem()
    tool = osim.InverseDynamicsTool()
    tool.setModel(model)
    tool.setCoordinatesFileName(str(paths["ik"]))
    tool.setExternalLoadsFileName(str(paths["grf_xml"]))
    tool.setStartTime(float(rec.time_s[0]) + 0.5)
    tool.setEndTime(float(rec.time_s[-1]) - 0.1)
    tool.setLowpassCutoffFrequency(-1.0)            # no filter: the spline through the samples
    tool.setResultsDir(str(out))
    tool.setOutputGenForceFileName("opensim_id.sto")
    assert tool.run()
    table = osim.TimeSeriesTable(str(out / "opensim_id.sto"))
    labels = list(table.getColumnLabels())
    t = np.array(table.getIndependentColumn())
    cols = {lab: table.getDependentColumn(lab).to_numpy() for lab in labels}
    return t, cols


def _rows(rec, t):
    """Indices of the record rows whose forces act at times ``t`` (one step later: the force
    of row k is computed at the state of row k − 1, module docstring)."""
    k = np.searchsorted(rec.time_s, t - 1e-9)
    np.testing.assert_allclose(rec.time_s[k], t, atol=1e-9)
    return k + 1


def test_opensim_inverse_dynamics_reproduces_the_joint_moments(walk, inverse_dynamics):
    import mujoco
    rec, _ = walk
    t, cols = inverse_dynamics
    assert t.size > 3000                                          # ~4 s at 1 kHz
    k = _rows(rec, t)
    model = mujoco.MjModel.from_xml_string(rec.model_xml)
    kv = {model.actuator(a).name[3:]: -float(model.actuator_biasprm[a, 2])
          for a in range(model.nu) if model.actuator(a).name.startswith("pd_")}
    for s, sfx in enumerate("rl"):
        for j, (coord, joint) in enumerate(COORDS):
            ours = rec.joint_moment_nm[:, s, j] + (rec.device_moment_nm[:, s] if j == 2 else 0)
            theirs = cols[f"{coord}_{sfx}_moment"]
            err = theirs - ours[k]
            peak = float(np.max(np.abs(ours[k])))
            rms = math.sqrt(float(np.mean(err ** 2)))
            assert peak > 40.0, (coord, sfx, peak)                # a real gait moment
            assert rms <= 0.05 * peak, f"{coord}_{sfx}: RMS {rms:.2f} N*m of peak {peak:.1f}"
            # the implicit servo damping (module docstring) accounts for the rest outside
            # heel strikes
            qd = rec.joint_velocity_rad_s[:, s, j]
            acted = ours[k] - kv[f"{joint}_{sfx}"] * (qd[k] - qd[k - 1])
            assert np.median(np.abs(theirs - acted)) < 0.05, (coord, sfx)


def test_opensim_pelvis_forces_are_the_residuals(walk, inverse_dynamics):
    rec, _ = walk
    t, cols = inverse_dynamics
    k = _rows(rec, t)
    weight = rec.body_mass_kg * G
    for lab, ours in (("pelvis_tx_force", rec.residual_force_n[:, 0]),
                      ("pelvis_ty_force", rec.residual_force_n[:, 1]),
                      # pelvis_tilt is + posterior tilt: the walker's pitch negated
                      ("pelvis_tilt_moment", -rec.residual_moment_nm)):
        err = cols[lab] - ours[k]
        scale = weight * (rec.height_m if lab.endswith("moment") else 1.0)
        assert math.sqrt(float(np.mean(err ** 2))) < 0.03 * scale, lab
        assert np.median(np.abs(err)) < 0.001 * scale, lab


def test_opensim_reads_our_files_back(walk):
    osim = _opensim()
    rec, paths = walk
    ik = osim.TimeSeriesTable(str(paths["ik"]))
    assert ik.getTableMetaDataAsString("inDegrees") == "yes"
    assert ik.getNumRows() == rec.time_s.size
    np.testing.assert_allclose(np.array(ik.getIndependentColumn()), rec.time_s, atol=1e-9)
    np.testing.assert_allclose(np.radians(ik.getDependentColumn("knee_angle_l").to_numpy()),
                               rec.joint_angle_rad[:, 1, 1], atol=1e-9)
    np.testing.assert_allclose(np.radians(ik.getDependentColumn("pelvis_tilt").to_numpy()),
                               -rec.pelvis_tilt_rad, atol=1e-9)
    # every coordinate of the model is a column of the coordinates file
    model = osim.Model(str(paths["model"]))
    coords = [model.getCoordinateSet().get(i).getName()
              for i in range(model.getCoordinateSet().getSize())]
    assert sorted(coords) == sorted(ik.getColumnLabels())
    st = osim.Storage(str(paths["ik"]))
    assert st.isInDegrees() and st.getSize() == rec.time_s.size
    # the force files: one row fewer, on the coordinates' time grid
    idt = osim.TimeSeriesTable(str(paths["id"]))
    np.testing.assert_allclose(np.array(idt.getIndependentColumn()), rec.time_s[:-1],
                               atol=1e-9)
    np.testing.assert_allclose(idt.getDependentColumn("ankle_angle_r_moment").to_numpy(),
                               rec.joint_moment_nm[1:, 0, 2], atol=1e-8)
    grf = osim.TimeSeriesTable(str(paths["grf"])).packVec3(["x", "y", "z"])
    assert list(grf.getColumnLabels()) == [f"ground_{q}_{s}_{c}" for s in "rl"
                                           for q, c in (("force", "v"), ("force", "p"),
                                                        ("torque", ""))]
    force_l = grf.getDependentColumn("ground_force_l_v")
    row = int(np.argmax(rec.grf_n[1:, 1, 1]))
    v = force_l[row]
    np.testing.assert_allclose([v.get(0), v.get(1), v.get(2)],
                               [rec.grf_n[row + 1, 1, 0], rec.grf_n[row + 1, 1, 1], 0.0],
                               atol=1e-6)
    loads = osim.ExternalLoads(str(paths["grf_xml"]), True)
    assert {loads.get(i).get_applied_to_body() for i in range(loads.getSize())} == {
        "calcn_r", "calcn_l"}
    state = model.initSystem()
    assert model.getTotalMass(state) == pytest.approx(rec.body_mass_kg, rel=1e-9)


# -- the model without OpenSim: it is the walker ------------------------------------------------
def _parse(xml: str):
    root = ET.fromstring(xml).find("Model")
    bodies = {b.get("name"): b for b in root.iter("Body")}
    joints = {j.get("name"): j for j in root.find("JointSet/objects")}
    return root, bodies, joints


def _vec(el, tag):
    return np.array([float(x) for x in el.findtext(tag).split()])


def _rot(euler):
    """Body-fixed X-Y-Z rotation (OpenSim's ``orientation``)."""
    a, b, c = euler
    rx = np.array([[1, 0, 0], [0, math.cos(a), -math.sin(a)], [0, math.sin(a), math.cos(a)]])
    ry = np.array([[math.cos(b), 0, math.sin(b)], [0, 1, 0], [-math.sin(b), 0, math.cos(b)]])
    rz = np.array([[math.cos(c), -math.sin(c), 0], [math.sin(c), math.cos(c), 0], [0, 0, 1]])
    return rx @ ry @ rz


def _walker_xml(worn=()):
    from afo_mj.human.walker import WalkerPhysics, WalkerParams, build_walker
    root = build_walker(WalkerParams(body_mass_kg=60.0, height_m=1.6), worn)
    return root, WalkerPhysics(root).model


def test_osim_model_segments_are_de_levas():
    """Masses, centres of mass, inertias and joint centres against the anthropometry the
    walker is scaled from (de Leva 1996 via afo_mj.human.anthropometry), in OpenSim's axes."""
    from afo_mj.human.anthropometry import scale_body
    seg = scale_body(60.0, 1.6)
    _, model = _walker_xml()
    root, bodies, joints = _parse(osim_model_xml(model, "w"))
    np.testing.assert_allclose(_vec(root, "gravity"), [0, -9.81, 0])
    assert set(bodies) == {"pelvis", "femur_r", "femur_l", "tibia_r", "tibia_l", "calcn_r",
                           "calcn_l"}
    total = sum(float(b.findtext("mass")) for b in bodies.values())
    assert total == pytest.approx(60.0, rel=1e-9)
    for name, s in (("pelvis", seg.hat), ("femur_r", seg.thigh), ("tibia_l", seg.shank),
                    ("calcn_r", seg.foot)):
        assert float(bodies[name].findtext("mass")) == pytest.approx(s.mass_kg, rel=1e-9)
    # thigh: CoM below the hip; MuJoCo's y (lateral) inertia is OpenSim's Z, its z is Y
    np.testing.assert_allclose(_vec(bodies["femur_r"], "mass_center"),
                               [0, -seg.thigh.com_from_proximal_m, 0], atol=1e-12)
    np.testing.assert_allclose(_vec(bodies["femur_r"], "inertia"),
                               [seg.thigh.inertia_kg_m2, 0.2 * seg.thigh.inertia_kg_m2,
                                seg.thigh.inertia_kg_m2, 0, 0, 0], atol=1e-12)
    np.testing.assert_allclose(_vec(bodies["pelvis"], "mass_center"),
                               [0, seg.hat.com_from_proximal_m, 0], atol=1e-12)
    assert joints["ground_pelvis"].tag == "PlanarJoint"
    assert [c.get("name") for c in joints["ground_pelvis"].iter("Coordinate")] == [
        "pelvis_tilt", "pelvis_tx", "pelvis_ty"]
    ty = joints["ground_pelvis"].findall("coordinates/Coordinate")[2]
    assert float(ty.findtext("default_value")) == pytest.approx(seg.hip_height_m, rel=1e-9)
    # hips 0.09 m × stature/1.75 either side, the right one at +Z; knee one thigh below;
    # hinge axes: hip and ankle +Z (flexion, dorsiflexion +), knee −Z (flexion +)
    hw = 0.09 * 1.6 / 1.75
    for side, z in (("r", hw), ("l", -hw)):
        for jname, coord, at, axis in (("hip", "hip_flexion", [0, 0, z], 1),
                                       ("knee", "knee_angle", [0, -seg.thigh.length_m, 0], -1),
                                       ("ankle", "ankle_angle", [0, -seg.shank.length_m, 0], 1)):
            j = joints[f"{jname}_{side}"]
            assert j.tag == "PinJoint"
            assert [c.get("name") for c in j.iter("Coordinate")] == [f"{coord}_{side}"]
            parent, child = j.findall("frames/PhysicalOffsetFrame")
            np.testing.assert_allclose(_vec(parent, "translation"), at, atol=1e-12)
            np.testing.assert_allclose(_vec(child, "translation"), 0.0, atol=1e-12)
            for f in (parent, child):
                np.testing.assert_allclose(_rot(_vec(f, "orientation"))[:, 2], [0, 0, axis],
                                           atol=1e-12)
    knee = joints["knee_r"].find("coordinates/Coordinate")
    np.testing.assert_allclose(_vec(knee, "range"), [-0.1, 2.3])


def test_a_worn_mass_is_welded_into_its_segment():
    """A 1.5 kg mass at the right shank cuff: the tibia's mass, centre of mass and inertia
    become the pair's (parallel-axis theorem, computed here from the MJCF's numbers)."""
    from afo_mj.human.anthropometry import scale_body
    from afo_mj.human.walker import WornMass
    m_w = 1.5
    root, model = _walker_xml([WornMass("shank_cuff_r", m_w)])
    _, bodies, _ = _parse(osim_model_xml(model, "w"))
    sh = scale_body(60.0, 1.6).shank
    cuff = np.asarray(root.find("site", "shank_cuff_r").pos, float)      # MuJoCo x, y, z
    shank_com = np.array([0.0, 0.0, -sh.com_from_proximal_m])
    m = sh.mass_kg + m_w
    com = (sh.mass_kg * shank_com + m_w * cuff) / m
    i_worn = 1e-5 + 1e-3 * m_w
    d1, d2 = shank_com - com, cuff - com
    # about MuJoCo's lateral axis y (OpenSim Z): the in-plane (x, z) distances
    izz = (sh.inertia_kg_m2 + i_worn + sh.mass_kg * (d1[0] ** 2 + d1[2] ** 2)
           + m_w * (d2[0] ** 2 + d2[2] ** 2))
    tib = bodies["tibia_r"]
    assert float(tib.findtext("mass")) == pytest.approx(m, rel=1e-9)
    np.testing.assert_allclose(_vec(tib, "mass_center"), [com[0], com[2], -com[1]], atol=1e-12)
    inertia = _vec(tib, "inertia")
    assert inertia[2] == pytest.approx(izz, rel=1e-9)
    # x–z product of MuJoCo = −(x·z offsets): OpenSim's X–Y product
    ixy = -(sh.mass_kg * d1[0] * d1[2] + m_w * d2[0] * d2[2])
    assert inertia[3] == pytest.approx(ixy, rel=1e-9, abs=1e-15)
    assert float(bodies["tibia_l"].findtext("mass")) == pytest.approx(sh.mass_kg, rel=1e-9)


def test_a_model_that_is_not_the_walker_is_refused():
    import mujoco
    free = mujoco.MjModel.from_xml_string(
        "<mujoco><worldbody><body name='pelvis'><freejoint/><geom size='0.1'/></body>"
        "</worldbody></mujoco>")
    with pytest.raises(OpenSimModelError, match="lacks the bodies"):
        osim_model_xml(free)
    _, model = _walker_xml()
    model.jnt_axis[model.joint("knee_r").id] = [1.0, 0.0, 0.0]
    with pytest.raises(OpenSimModelError, match="'knee_r'.*not the lateral axis"):
        osim_model_xml(model)


def test_cli_export_osim(tmp_path):
    rc, out, err = run_cli(["export-osim", str(ROOT / "scenarios" / "walk_healthy.toml"),
                            "--out", str(tmp_path / "m"), "--quiet"])
    assert rc == 0, err
    path = tmp_path / "m" / "walk.osim"
    assert f"{path}" in out and "75.00 kg" in out
    _, bodies, _ = _parse(path.read_text(encoding="utf-8"))
    assert sum(float(b.findtext("mass")) for b in bodies.values()) == pytest.approx(75.0)
    rc, _, err = run_cli(["export-osim", str(ROOT / "scenarios" / "bench_hafo.toml"),
                          "--out", str(tmp_path / "b"), "--quiet"])
    assert rc == 2 and "bench scenario" in err and not (tmp_path / "b").exists()
