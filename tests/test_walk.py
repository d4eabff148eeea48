"""The forward-dynamic walk against the issue's acceptance figures (Winter normal cadence).

References: Winter (2009) normal-cadence data as summarised in ../shared/data/README.md and
the shipped normative table: peak ankle plantarflexor moment 1.69 N·m/kg, peak ankle power
3.24 W/kg in push-off. Each walk takes a few seconds of wall time.
"""

from __future__ import annotations

import dataclasses
import os
from pathlib import Path

os.environ.setdefault("MUJOCO_GL", "egl")

import numpy as np  # noqa: E402
import pytest  # noqa: E402

from afo_mj.metrics.gait_metrics import analyse_gait, band_fraction  # noqa: E402
from afo_mj.gait.reference import load_normative  # noqa: E402
from afo_mj.gait.walk import simulate_walk  # noqa: E402
from afo_mj.scenarios.walk_scenario import load_scenario  # noqa: E402

SCENARIOS = Path(__file__).resolve().parents[1] / "scenarios"
WINTER_PEAK_MOMENT = 1.69
WINTER_PEAK_POWER = 3.24


def _walk(name: str, **walker_changes):
    sc = load_scenario(SCENARIOS / f"{name}.toml")
    if walker_changes:
        sc = dataclasses.replace(sc, walker=sc.walker.replace(**walker_changes))
    return sc, simulate_walk(sc)


@pytest.fixture(scope="module")
def healthy():
    sc, rec = _walk("walk_healthy")
    return sc, rec, analyse_gait(rec, sc.load_reference(), sc.analyse_strides)


def _mean(summary, key):
    return summary[key]["mean"]


def test_healthy_walk_meets_acceptance(healthy):
    sc, rec, an = healthy
    s = an.summary
    assert rec.events.fall_time_s is None
    assert s["completed_strides"] >= 10
    assert np.isfinite(rec.joint_angle_rad).all() and np.isfinite(rec.grf_n).all()
    for joint in ("hip", "knee", "ankle"):
        assert _mean(s, f"{joint}_angle_rms_error_deg") <= 5.0, joint
    assert _mean(s, "peak_ankle_plantarflexor_moment_nm_per_kg") == pytest.approx(
        WINTER_PEAK_MOMENT, rel=0.15)
    assert _mean(s, "peak_ankle_power_w_per_kg") == pytest.approx(WINTER_PEAK_POWER, rel=0.25)
    assert s["residual_force_rms_percent_body_weight"]["over_analysed_span"] <= 5.0
    assert _mean(s, "min_toe_clearance_m") >= 0.01
    # speed emerges from the kinematics (shorter planar stride than Winter's 1.51 m) and is
    # reported, not forced toward Winter's 1.325 m/s
    assert 0.7 < _mean(s, "speed_m_s") < 1.3


def test_contact_forces_carry_body_weight(healthy):
    """Over whole strides the mean vertical GRF equals body weight (momentum balance)."""
    sc, rec, an = healthy
    hs = rec.events.heel_strikes_s[0]
    i0, i1 = np.searchsorted(rec.time_s, [hs[3], hs[9]])
    fz = rec.grf_n[i0:i1, :, 1].sum(axis=1) + rec.residual_force_n[i0:i1, 1]
    weight = rec.body_mass_kg * 9.81
    assert fz.mean() == pytest.approx(weight, rel=0.02)
    # mid-stance (20–40 % of a right cycle): the walker stands on one foot, and the vertical
    # GRF is near body weight, as in Winter's data (8.3–10.8 N/kg)
    t0, t1 = hs[5], hs[6]
    j0, j1 = np.searchsorted(rec.time_s, [t0 + 0.2 * (t1 - t0), t0 + 0.4 * (t1 - t0)])
    mid = rec.grf_n[j0:j1, 0, 1].mean() / rec.body_mass_kg
    assert 7.0 < mid < 11.5


@pytest.mark.parametrize("name", ["walk_schwartz_free", "walk_schwartz_fast"])
def test_schwartz_cadences_report_band_fractions(name):
    sc, rec = _walk(name)
    assert rec.events.fall_time_s is None
    an = analyse_gait(rec, sc.load_reference(), sc.analyse_strides)
    (src, cond), = sc.band_references
    fr = band_fraction(an.cycles, load_normative(src, cond))
    for ch in ("hip_angle_rad", "knee_angle_rad", "ankle_angle_rad"):
        assert 0.0 <= fr[ch]["mean"] <= 1.0
    # the ankle is what the AFO acts on: most of its cycle lies inside the children's band
    assert fr["ankle_angle_rad"]["mean"] >= 0.5
    # the hip compared like for like (thigh from vertical; Schwartz's pelvis tilts ~12°
    # forward, the walker's stays level) lies mostly inside the band too
    assert fr["thigh_angle_rad"]["mean"] >= 0.7


@pytest.fixture(scope="module")
def weak():
    sc, rec = _walk("walk_weak_plantarflexors")
    return sc, rec


def test_plantarflexor_weakness_lowers_push_off(healthy, weak):
    """50 % plantarflexor strength, same controller and gains: push-off work down by ≥ 20 %,
    peak plantarflexion in push-off down by ≥ 3° (strides 4–10)."""
    _, _, an_h = healthy
    sc, rec = weak
    an_w = analyse_gait(rec, sc.load_reference(), sc.analyse_strides)
    h, w = an_h.summary, an_w.summary
    work_h = _mean(h, "ankle_push_off_positive_work_j_per_kg")
    work_w = _mean(w, "ankle_push_off_positive_work_j_per_kg")
    assert work_w <= 0.8 * work_h
    pf_h = _mean(h, "push_off_peak_plantarflexion_deg")
    pf_w = _mean(w, "push_off_peak_plantarflexion_deg")
    assert pf_w <= pf_h - 3.0
    cap = sc.walker.plantarflexor_strength_fraction * sc.walker.plantarflexor_strength_nm_per_kg
    assert _mean(w, "peak_ankle_plantarflexor_moment_nm_per_kg") <= cap + 1e-6


def test_weak_walker_completes_ten_strides_on_weak_residuals(weak):
    sc, rec = weak
    assert rec.events.fall_time_s is None
    an = analyse_gait(rec, sc.load_reference(), sc.analyse_strides)
    assert an.summary["completed_strides"] >= 10
    assert an.summary["residual_force_rms_percent_body_weight"]["over_analysed_span"] <= 8.0


def test_foot_drop_lowers_swing_dorsiflexion_and_clearance(healthy):
    """Dorsiflexors at 2 % strength, same controller: the swinging foot hangs, clears the floor
    less and catches it more often, yet the walker completes its strides (README's table
    reports all of them): no fall in the record or the summary."""
    _, rec_h, an_h = healthy
    sc, rec = _walk("walk_foot_drop")
    an = analyse_gait(rec, sc.load_reference(), sc.analyse_strides)
    h, d = an_h.summary, an.summary
    # the dropped foot hangs through mid-swing: its mean ankle angle there is lower
    assert _mean(d, "swing_mean_ankle_angle_deg") < _mean(h, "swing_mean_ankle_angle_deg") - 5.0
    assert _mean(d, "min_toe_clearance_m") < _mean(h, "min_toe_clearance_m") - 0.005
    assert d["swing_toe_contacts_in_analysed_span"] >= h["swing_toe_contacts_in_analysed_span"]
    assert rec.events.fall_time_s is None, rec.events.fall_time_s
    assert "fall_time_s" in d and d["fall_time_s"] is None


def test_fall_is_an_outcome_not_a_crash():
    """Dorsiflexors paralysed and no toe-clearance reflex: the walker trips; the run ends with
    the fall time recorded and the record trimmed to it."""
    sc = load_scenario(SCENARIOS / "walk_foot_drop.toml")
    sc = dataclasses.replace(sc, walker=sc.walker.replace(dorsiflexor_strength_fraction=0.0),
                             controller={"swing_clearance_gain_rad_per_m": 0.0})
    rec = simulate_walk(sc)
    assert rec.events.fall_time_s is not None
    assert rec.events.fall_time_s == pytest.approx(rec.time_s[-1], abs=2e-3)
    assert rec.events.swing_toe_contacts
    assert np.isfinite(rec.joint_angle_rad).all()


class _PushOffAssist:
    """An ideal orthosis: a half-sine plantarflexion torque over 35–62 % of each stance leg's
    phase (peak ``peak_nm``), zero otherwise. Stands in for the hydraulic AFO of issue 4."""

    def __init__(self, peak_nm: float):
        self.peak_nm = peak_nm

    def torque_nm(self, t_s, angle_rad, velocity_rad_s, phase, stance):
        out = np.zeros(2)
        for s in (0, 1):
            if stance[s] and 0.35 < phase[s] < 0.62:
                out[s] = -self.peak_nm * np.sin(np.pi * (phase[s] - 0.35) / 0.27)
        return out


def test_orthosis_torque_changes_the_weak_walkers_kinematics(weak):
    """The ankle torque of a worn device reaches the kinematics: 20 N·m of push-off assistance
    gives the weak walker back push-off plantarflexion and speed; the device torque is recorded
    apart from the muscles' moment, which stays within their strength."""
    sc, rec_w = weak
    rec_a = simulate_walk(sc, device=_PushOffAssist(20.0))
    assert rec_a.events.fall_time_s is None
    ref = sc.load_reference()
    w = analyse_gait(rec_w, ref, sc.analyse_strides).summary
    a = analyse_gait(rec_a, ref, sc.analyse_strides).summary
    assert (_mean(a, "push_off_peak_plantarflexion_deg")
            >= _mean(w, "push_off_peak_plantarflexion_deg") + 3.0)
    assert _mean(a, "speed_m_s") > _mean(w, "speed_m_s") + 0.1
    assert _mean(a, "peak_device_plantarflexor_moment_nm_per_kg") == pytest.approx(
        20.0 / sc.walker.body_mass_kg, rel=0.05)
    cap = sc.walker.plantarflexor_strength_fraction * sc.walker.plantarflexor_strength_nm_per_kg
    assert _mean(a, "peak_ankle_plantarflexor_moment_nm_per_kg") <= cap + 1e-6


def test_child_walks_dynamically_similar():
    """A 25 kg, 1.2 m child at the Froude-scaled cadence walks like the adult in
    non-dimensional terms: angle errors as small, peak ankle moment per kg × (1.75 m /
    stature) and speed / √(g·stature) near the adult's, no fall."""
    sc, rec = _walk("walk_child_healthy")
    assert rec.events.fall_time_s is None
    s = analyse_gait(rec, sc.load_reference(), sc.analyse_strides).summary
    lam = sc.walker.height_m / 1.75
    assert sc.cycle_time_s() == pytest.approx(1.1396 * np.sqrt(lam), rel=1e-9)
    for joint in ("hip", "knee", "ankle"):
        assert _mean(s, f"{joint}_angle_rms_error_deg") <= 5.0, joint
    assert _mean(s, "peak_ankle_plantarflexor_moment_nm_per_kg") / lam == pytest.approx(
        WINTER_PEAK_MOMENT, rel=0.15)
    froude_speed = _mean(s, "speed_m_s") / np.sqrt(9.81 * sc.walker.height_m)
    assert froude_speed == pytest.approx(1.05 / np.sqrt(9.81 * 1.75), rel=0.1)


def test_users_kinematics_only_csv_reference_walks(tmp_path):
    """A user's gait from CSV with angles only (no inverse-dynamics moments, no cycle time):
    the walker tracks it on servo and balance alone (feedforward of the missing moments is 0)."""
    from afo_mj.gait.reference import load_reference_csv
    from afo_mj.gait.walk import run_walk
    from afo_mj.human.walker import WalkerParams

    winter = load_normative("winter", "normal")
    pct = np.arange(0, 101)
    deg = np.degrees(winter.angles_rad(pct / 100.0))
    path = tmp_path / "my_gait.csv"
    rows = ["percent_cycle,hip_angle_deg,knee_angle_deg,ankle_angle_deg"]
    rows += [f"{p},{a[0]:.6f},{a[1]:.6f},{a[2]:.6f}" for p, a in zip(pct, deg)]
    path.write_text("\n".join(rows) + "\n")
    ref = load_reference_csv(path)
    rec = run_walk(WalkerParams(), ref, 1.1396, 10)
    assert rec.events.fall_time_s is None
    s = analyse_gait(rec, ref, (4, 10)).summary
    # without the moments the stance knee tracks less well (about 11° RMS vs 2° with them)
    assert _mean(s, "hip_angle_rms_error_deg") <= 6.0
    assert _mean(s, "ankle_angle_rms_error_deg") <= 6.0
    assert _mean(s, "knee_angle_rms_error_deg") <= 15.0


def test_push_off_deficit_grows_with_weakness():
    """Dose–response, same controller: as plantarflexor strength falls from 100 % through 70 %
    to 50 %, push-off work, push-off plantarflexion and speed fall with it, and no level
    falls (the deficit is real, not a switch between walking and falling)."""
    out = []
    for fraction in (1.0, 0.7, 0.5):
        sc, rec = _walk("walk_healthy", plantarflexor_strength_fraction=fraction)
        assert rec.events.fall_time_s is None, fraction
        s = analyse_gait(rec, sc.load_reference(), sc.analyse_strides).summary
        out.append([_mean(s, "ankle_push_off_positive_work_j_per_kg"),
                    _mean(s, "push_off_peak_plantarflexion_deg"), _mean(s, "speed_m_s")])
    work, pf, speed = np.array(out).T
    assert work[0] > work[1] > work[2]
    assert pf[1] >= pf[0] - 0.5 and pf[1] > pf[2] + 1.0   # 70 % still reaches full push-off angle
    assert speed[0] > speed[1] > speed[2]


def test_opensim_reference_scenario_walks_through_the_cli(tmp_path):
    """A user of OpenSim: coordinates (.mot, gait2392 knee sign, degrees) and inverse dynamics
    (.sto, N·m) of one cycle, named in a scenario; `afo-mj run` walks it and writes results
    with the OpenSim cycle as the reference (Winter's numbers here, so the same figures)."""
    from afo_mj import cli

    winter = load_normative("winter", "normal")
    ph = np.arange(101) / 100.0
    t = 0.2 + ph * 1.1396
    ang = np.degrees(winter.angles_rad(ph))
    mom = winter.moments_nm_per_kg(ph) * 75.0

    def sto(path, name, labels, cols, in_degrees):
        head = [name, "version=1", f"nRows={len(t)}", f"nColumns={len(labels)}",
                f"inDegrees={in_degrees}", "endheader", "\t".join(labels)]
        rows = ["\t".join(f"{v:.10g}" for v in r) for r in np.column_stack(cols)]
        path.write_text("\n".join(head + rows) + "\n")

    sto(tmp_path / "ik.mot", "ik", ["time", "hip_flexion_r", "knee_angle_r", "ankle_angle_r"],
        [t, ang[:, 0], -ang[:, 1], ang[:, 2]], "yes")
    sto(tmp_path / "id.sto", "Inverse Dynamics",
        ["time", "hip_flexion_r_moment", "knee_angle_r_moment", "ankle_angle_r_moment"],
        [t, mom[:, 0], -mom[:, 1], mom[:, 2]], "no")
    (tmp_path / "mine.toml").write_text(
        'name = "mine"\n[walker]\nbody_mass_kg = 75.0\nheight_m = 1.75\n'
        '[gait]\nreference_path = "ik.mot"\nreference_id_path = "id.sto"\nstrides = 6\n'
        'analyse_strides = [3, 6]\n')
    out = tmp_path / "out"
    assert cli.main(["run", str(tmp_path / "mine.toml"), "--out", str(out)]) == 0
    import json
    s = json.loads((out / "summary.json").read_text())
    assert s["fell"] is False and s["reference"]["source"] == "opensim"
    assert s["knee_angle_rms_error_deg"]["mean"] <= 5.0
    assert s["peak_ankle_plantarflexor_moment_nm_per_kg"]["mean"] == pytest.approx(1.69, rel=0.15)


def test_spastic_ankle_narrows_ankle_motion_and_push_off(healthy):
    """Added passive ankle stiffness and damping (spasticity), same controller: the ankle's
    range of motion over the cycle narrows and push-off power falls."""
    _, _, an_h = healthy
    sc, rec = _walk("walk_spastic_ankle")
    assert rec.events.fall_time_s is None
    an = analyse_gait(rec, sc.load_reference(), sc.analyse_strides)

    def ankle_range_deg(analysis):
        a = np.stack([c.curves["ankle_angle_rad"] for c in analysis.cycles])
        return np.degrees(np.mean(a.max(axis=1) - a.min(axis=1)))

    assert ankle_range_deg(an) < ankle_range_deg(an_h) - 3.0
    assert (_mean(an.summary, "peak_ankle_power_w_per_kg")
            < 0.8 * _mean(an_h.summary, "peak_ankle_power_w_per_kg"))


def test_assisted_healthy_walker_hands_push_off_work_to_the_device():
    """A healthy wearer of 40 N·m push-off assistance lowers their own ankle effort by the
    device's torque (assistance_adaptation = 1, the default): the gait keeps its kinematics
    and the human's positive push-off work falls by at least 40 %."""
    sc = load_scenario(SCENARIOS / "walk_healthy.toml")
    ref = sc.load_reference()
    base = analyse_gait(simulate_walk(sc), ref, sc.analyse_strides).summary
    rec = simulate_walk(sc, device=_PushOffAssist(40.0))
    assert rec.events.fall_time_s is None
    a = analyse_gait(rec, ref, sc.analyse_strides).summary
    assert (_mean(a, "ankle_push_off_positive_work_j_per_kg")
            <= 0.6 * _mean(base, "ankle_push_off_positive_work_j_per_kg"))
    for joint in ("hip", "knee", "ankle"):
        assert _mean(a, f"{joint}_angle_rms_error_deg") <= 5.0
    assert _mean(a, "speed_m_s") == pytest.approx(_mean(base, "speed_m_s"), rel=0.05)


@pytest.mark.parametrize("worn", [
    (("shank_cuff_r", 0.50), ("foot_plate_r", 0.47)),
    (("waist", 2.33), ("shank_cuff_r", 0.50), ("foot_plate_r", 0.47)),
], ids=["0.97kg-at-right-ankle", "hafo-like-3.3kg"])
def test_walks_carrying_a_device_mass(worn):
    """A one-sided 0.97 kg at the ankle, and the HAFO's 3.3 kg (2.33 kg at the waist), are
    carried 10 strides without a fall, angle errors staying within 10°."""
    from afo_mj.gait.walk import run_walk
    from afo_mj.human.walker import WalkerParams, WornMass

    ref = load_normative("winter", "normal")
    masses = [WornMass(site, m, f"part{i}") for i, (site, m) in enumerate(worn)]
    rec = run_walk(WalkerParams(), ref, ref.cycle_time_s, 10, worn_masses=masses)
    assert rec.events.fall_time_s is None
    s = analyse_gait(rec, ref, (4, 10)).summary
    for joint in ("hip", "knee", "ankle"):
        assert _mean(s, f"{joint}_angle_rms_error_deg") <= 10.0, joint


@pytest.mark.parametrize("walker_changes, controller_changes", [
    ({"plantarflexor_strength_fraction": 0.45}, {}),
    ({"plantarflexor_strength_fraction": 0.40}, {}),
    ({}, {"initial_speed_m_s": 0.8}),
    ({}, {"initial_speed_m_s": 1.3}),
], ids=["weak-45", "weak-40", "start-0.8", "start-1.3"])
def test_walker_keeps_walking_at_the_edges(walker_changes, controller_changes):
    """The controller's basin (benchmarks/walker_robustness.py): deeper plantarflexor weakness
    and starts well off the settled speed still walk 10 strides with the default gains."""
    from afo_mj.gait.walk import ControllerParams, run_walk
    from afo_mj.human.walker import WalkerParams

    ref = load_normative("winter", "normal")
    rec = run_walk(WalkerParams(**walker_changes), ref, ref.cycle_time_s, 10,
                   ControllerParams(**controller_changes))
    assert rec.events.fall_time_s is None
    s = analyse_gait(rec, ref, (4, 10)).summary
    assert s["residual_force_rms_percent_body_weight"]["over_analysed_span"] <= 8.0
