"""Measured trials (issue 23, first part): events, cycles and their mean on trials these tests
write themselves (OpenSim .sto/.mot with known heel strikes built from Winter's normative
cycle): a record starting mid-cycle, one too short for any complete cycle (composed from both
legs), a mis-cut record (refused cycles), noisy forces, and marker-based events."""

from __future__ import annotations

import math

import numpy as np
import pytest

from afo_mj.gait.measured_trial import (complete_cycles, events_from_grf, events_from_markers,
                                        grf_columns, load_measured_trial)
from afo_mj.gait.reference import ReferenceGaitError, load_normative

WINTER = load_normative("winter", "normal")
T = 1.1          # stride time of the synthetic walker (s)
STANCE = 0.6     # stance fraction


def _phase(t, first_hs):
    return np.mod((t - first_hs) / T, 1.0)


def _angles(phase):
    """Winter's angles (rad) at these phases: columns hip, knee, ankle."""
    return WINTER.angles_rad(phase)


def _grf(phase, rng, noise_n=3.0):
    f = np.where(phase < STANCE, 800.0 * np.sqrt(np.sin(np.pi * phase / STANCE).clip(0)), 0.0)
    return f + rng.normal(0.0, noise_n, phase.shape)


def _write_trial(tmp_path, t0, t1, right_hs, *, knee_sign=-1, offset_after=None,
                 noise_n=3.0, name="trial"):
    """A .sto (degrees, gait2392 knee sign) and a GRF .mot of a symmetric walker whose right
    heel strikes at ``right_hs + k T`` and left ones half a stride later."""
    rng = np.random.default_rng(5)
    t = np.arange(t0, t1 + 1e-9, 0.01)
    pr, pl = _phase(t, right_hs), _phase(t, right_hs + 0.5 * T)
    ar, al = np.degrees(_angles(pr)), np.degrees(_angles(pl))
    if offset_after is not None:              # a mis-cut record: the right hip jumps
        ar[t > offset_after, 0] += 12.0
    cols = {"time": t, "hip_flexion_r": ar[:, 0], "knee_angle_r": knee_sign * ar[:, 1],
            "ankle_angle_r": ar[:, 2], "hip_flexion_l": al[:, 0],
            "knee_angle_l": knee_sign * al[:, 1], "ankle_angle_l": al[:, 2]}
    _storage(tmp_path / f"{name}_ik.sto", cols, "inDegrees=yes")
    mr, ml = WINTER.moments_nm_per_kg(pr) * 75.0, WINTER.moments_nm_per_kg(pl) * 75.0
    ids = {"time": t}
    for sfx, m in (("r", mr), ("l", ml)):
        ids[f"hip_flexion_{sfx}_moment"] = m[:, 0]
        ids[f"knee_angle_{sfx}_moment"] = knee_sign * m[:, 1]
        ids[f"ankle_angle_{sfx}_moment"] = m[:, 2]
    _storage(tmp_path / f"{name}_id.sto", ids, "inDegrees=no")
    grf = {"time": t, "ground_force_vy": _grf(pr, rng, noise_n),
           "1_ground_force_vy": _grf(pl, rng, noise_n),
           "ground_force_vx": 0.1 * _grf(pr, rng, noise_n),
           "1_ground_force_vx": 0.1 * _grf(pl, rng, noise_n)}
    _storage(tmp_path / f"{name}_grf.mot", grf, "inDegrees=yes")
    return tmp_path / f"{name}_ik.sto", tmp_path / f"{name}_grf.mot"


def _storage(path, cols, extra):
    names = list(cols)
    n = len(cols["time"])
    lines = [path.name, "version=1", f"nRows={n}", f"nColumns={len(names)}", extra,
             "endheader", "\t".join(names)]
    for k in range(n):
        lines.append("\t".join(f"{cols[c][k]:.8f}" for c in names))
    path.write_text("\n".join(lines) + "\n")


def _rms_deg(ref, phase=np.linspace(0, 0.99, 100)):
    return np.degrees(np.sqrt(np.mean((ref.angles_rad(phase) - WINTER.angles_rad(phase)) ** 2,
                                      axis=0)))


def test_record_starting_mid_cycle_gives_every_complete_cycle(tmp_path):
    # the record starts at 16 % of the right leg's cycle (the case the issue met) and lasts
    # five strides: right heel strikes at 0.924 + k T
    hs0 = -0.16 * T
    ik, grf = _write_trial(tmp_path, 0.0, 5.0 * T, hs0)
    trial = load_measured_trial(ik, grf)
    true_r = hs0 + T * np.arange(1, 6)
    true_r = true_r[true_r <= 5.0 * T]
    got = trial.events.heel_strikes_s["right"]
    assert len(got) == len(true_r)
    assert np.max(np.abs(got - true_r)) <= 0.011          # one sample at 100 Hz
    true_to = hs0 + T * (np.arange(0, 6) + STANCE)
    true_to = true_to[(true_to > 0.0) & (true_to <= 5.0 * T)]
    assert np.max(np.abs(trial.events.toe_offs_s["right"] - true_to)) <= 0.021
    assert len(trial.cycles["right"]) == len(true_r) - 1
    assert len(trial.cycles["left"]) >= 3 and not trial.refused["right"]
    assert trial.composed is None
    # the mean of the cycles is Winter's cycle; the spread is the resampling's only
    assert np.all(_rms_deg(trial.reference) < 0.5)
    sd = trial.reference.sd_splines
    assert set(sd) >= {"hip_angle_rad", "knee_angle_rad", "ankle_angle_rad"}
    assert max(np.degrees(np.abs(sd[c](np.linspace(0, 1, 50)))).max() for c in sd) < 1.0
    assert trial.reference.cycle_time_s == pytest.approx(T, abs=0.01)
    assert any("degrees (header inDegrees = yes)" in n for n in trial.notes)
    assert any("knee flexion sign -1" in n for n in trial.notes)


def test_record_without_a_complete_cycle_is_composed_from_both_legs(tmp_path):
    """1.35 s from 16 % of the right cycle: neither leg completes a cycle; the right leg's
    0–39 % and the left leg's rest make one cycle, its seam reported."""
    ik, grf = _write_trial(tmp_path, 0.0, 1.35, -0.16 * T, name="short")
    trial = load_measured_trial(ik, grf)
    assert trial.n_cycles == 0 and trial.composed is not None
    assert trial.composed["seam_phase"] == pytest.approx((1.35 - 0.84 * T) / T, abs=0.02)
    assert trial.composed["stride_time_s"] == pytest.approx(T, abs=0.02)
    assert math.degrees(trial.composed["largest_jump_rad"]) < 3.0
    assert np.all(_rms_deg(trial.reference) < 1.5)
    assert any("composed from both legs" in n for n in trial.notes)


def test_a_mis_cut_record_refuses_the_cycle_whose_ends_do_not_meet(tmp_path):
    ik, grf = _write_trial(tmp_path, 0.0, 5.0 * T, 0.05, offset_after=2.5, name="cut")
    trial = load_measured_trial(ik, grf)
    reasons = [r for *_, r in trial.refused["right"]]
    assert len(reasons) == 1 and "hip_angle_rad jumps +12.0 deg" in reasons[0]
    a, b, _ = trial.refused["right"][0]
    assert a < 2.5 < b
    assert len(trial.cycles["right"]) == 3


def test_nothing_usable_is_refused_with_the_reason(tmp_path):
    ik, grf = _write_trial(tmp_path, 0.0, 0.5, 0.2, name="tiny")
    with pytest.raises(ReferenceGaitError, match="no heel strike of the left leg"):
        load_measured_trial(ik, grf)
    with pytest.raises(ReferenceGaitError, match="no events"):
        load_measured_trial(ik)


def test_grf_hysteresis_ignores_noise_about_a_threshold():
    """Swing noise about the 20 N off-threshold (never reaching 50 N) and stance noise about
    50 N after the load: one heel strike, one toe off, at the interpolated crossings."""
    t = np.arange(0.0, 3.0, 0.001)
    rng = np.random.default_rng(1)
    f = 20.0 + rng.normal(0.0, 5.0, t.size).clip(-15, 25)
    stance = (t > 1.0) & (t < 1.7)
    f[stance] = 50.0 + rng.normal(0.0, 5.0, stance.sum()).clip(-25, 25)
    f[(t > 1.05) & (t < 1.65)] = 700.0
    ev = events_from_grf(t, {"right": f})
    assert len(ev.heel_strikes_s["right"]) == 1 and len(ev.toe_offs_s["right"]) == 1
    assert 1.0 <= ev.heel_strikes_s["right"][0] <= 1.06
    assert 1.64 <= ev.toe_offs_s["right"][0] <= 1.71
    # a clean ramp: the crossings interpolated between samples
    t2 = np.arange(0.0, 1.0, 0.01)
    f2 = np.interp(t2, [0, 0.2, 0.3, 0.6, 0.7, 1.0], [0, 0, 500, 500, 0, 0])
    ev2 = events_from_grf(t2, {"left": f2})
    assert ev2.heel_strikes_s["left"][0] == pytest.approx(0.2 + 0.1 * 50 / 500)
    assert ev2.toe_offs_s["left"][0] == pytest.approx(0.7 - 0.1 * 20 / 500)
    with pytest.raises(ReferenceGaitError, match="off_n = 60"):
        events_from_grf(t, {"right": f}, on_n=50.0, off_n=60.0)


def test_marker_events_zeni():
    """Heel and toe moving sinusoidally about the pelvis: heel strike at the heel's most
    forward position, toe off at the toe's most backward (Zeni et al. 2008)."""
    t = np.arange(0.0, 4.0, 0.005)
    pelvis = 1.2 * t
    heel = pelvis + 0.3 * np.cos(2 * np.pi * (t - 0.4) / T)
    toe = pelvis - 0.35 * np.cos(2 * np.pi * (t - 0.4 - 0.6 * T) / T) + 0.1
    ev = events_from_markers(t, {"right": heel}, {"right": toe}, pelvis)
    np.testing.assert_allclose(ev.heel_strikes_s["right"], 0.4 + T * np.arange(0, 4),
                               atol=0.006)
    np.testing.assert_allclose(ev.toe_offs_s["right"], 0.4 + 0.6 * T + T * np.arange(0, 3),
                               atol=0.006)


def test_complete_cycles_duration_check():
    t = np.linspace(0, 6, 601)
    ang = {"hip_angle_rad": np.sin(2 * np.pi * t / 1.0)}
    cycles, refused = complete_cycles(t, ang, [0.5, 1.5, 2.5, 4.5, 5.5])
    assert cycles == [(0.5, 1.5), (1.5, 2.5), (4.5, 5.5)]
    assert len(refused) == 1 and "missed or extra event" in refused[0][2]


def test_grf_column_conventions():
    assert grf_columns(["time", "ground_force_vy", "1_ground_force_vy"]) == {
        "right": "ground_force_vy", "left": "1_ground_force_vy"}
    assert grf_columns(["time", "ground_force_r_vy", "ground_force_l_vy"]) == {
        "right": "ground_force_r_vy", "left": "ground_force_l_vy"}
    with pytest.raises(ReferenceGaitError, match="pass grf_columns="):
        grf_columns(["time", "plate1_force_vy", "plate2_force_vy"])


def test_a_trial_is_not_taken_for_one_cycle(tmp_path):
    """The issue's case: a 1.35 s record from 16 % of the right cycle loaded as a reference
    used to be taken as one cycle from heel strike; now its unmet ends refuse it, naming the
    way to load a trial."""
    from afo_mj.gait.reference import load_opensim_storage
    ik, _ = _write_trial(tmp_path, 0.0, 1.35, -0.16 * T, name="issue")
    with pytest.raises(ReferenceGaitError, match="ends do not meet.*load_measured_trial"):
        load_opensim_storage(ik)


def test_scenario_reference_from_a_trial(tmp_path):
    """gait.reference_path + gait.reference_grf_path: the walk is scored against the mean of
    the trial's cycles."""
    from afo_mj.scenarios.walk_scenario import ScenarioError, parse_scenario
    _write_trial(tmp_path, 0.0, 5.0 * T, -0.16 * T)
    text = ('[gait]\nreference_path = "trial_ik.sto"\nreference_grf_path = "trial_grf.mot"\n'
            'strides = 4\nanalyse_strides = [2, 4]\n')
    sc = parse_scenario(text, base_dir=tmp_path)
    ref = sc.load_reference()
    assert ref.source == "trial" and ref.cycle_time_s == pytest.approx(T, abs=0.01)
    assert np.all(_rms_deg(ref) < 0.5)
    with pytest.raises(ScenarioError, match="gait.reference_grf_path = 'nope.mot'"):
        parse_scenario(text.replace("trial_grf.mot", "nope.mot"), base_dir=tmp_path)
    with pytest.raises(ScenarioError, match="given without gait.reference_path"):
        parse_scenario('[gait]\nreference_grf_path = "trial_grf.mot"\n', base_dir=tmp_path)


def test_moments_and_forces_of_the_trial(tmp_path):
    """With the ID file and the body mass the trial's mean cycle has the moments it was built
    from (knee sign as the angles'), and each foot's forces per kg."""
    ik, grf = _write_trial(tmp_path, 0.0, 5.0 * T, -0.16 * T)
    trial = load_measured_trial(ik, grf, id_path=tmp_path / "trial_id.sto", body_mass_kg=75.0)
    ref = trial.reference
    ph = np.linspace(0, 0.99, 100)
    err = np.abs(ref.moments_nm_per_kg(ph) - WINTER.moments_nm_per_kg(ph))
    assert err.max() < 0.05                                   # N·m/kg
    want = 800.0 * np.sqrt(np.sin(np.pi * 0.3 / STANCE)) / 75.0
    assert ref.grf_n_per_kg(np.array([0.3]))[0, 1] == pytest.approx(want, rel=0.02)
    assert ref.grf_n_per_kg(np.array([0.3]))[0, 0] == pytest.approx(0.1 * want, rel=0.05)
    with pytest.raises(ReferenceGaitError, match="moments need body_mass_kg"):
        load_measured_trial(ik, grf, id_path=tmp_path / "trial_id.sto")


def test_a_run_scored_against_a_measured_trial(tmp_path):
    """A walk scenario whose reference is a trial (angles, ID moments, forces) runs and is
    analysed against the trial's mean cycle by the same metrics as against a normative table
    (its moments and forces included)."""
    from afo_mj.app.run import run_scenario
    _write_trial(tmp_path, 0.0, 5.0 * T, -0.16 * T)
    sc = tmp_path / "vs_trial.toml"
    sc.write_text('[gait]\nreference_path = "trial_ik.sto"\nreference_grf_path = '
                  '"trial_grf.mot"\nreference_id_path = "trial_id.sto"\nstrides = 4\n'
                  'analyse_strides = [2, 4]\n')
    res = run_scenario(sc)
    s = res.summary.to_json()
    assert s["reference"]["source"] == "trial"
    assert s["ankle_moment_rms_error_nm_per_kg"]["mean"] < 0.5
    assert s["knee_angle_rms_error_deg"]["mean"] < 15.0


def test_ground_reaction_forces_from_csv(tmp_path):
    """The same trial with its forces in a CSV (time, right/left …force…vy columns) gives
    the same events as the .mot."""
    ik, grf = _write_trial(tmp_path, 0.0, 4.0 * T, 0.1)
    from afo_mj.gait.reference import read_opensim_storage
    _, labels, data = read_opensim_storage(grf)
    csv = tmp_path / "grf.csv"
    rename = {"ground_force_vy": "R_force_vy", "1_ground_force_vy": "L_force_vy"}
    keep = [i for i, lab in enumerate(labels) if lab == "time" or lab in rename]
    head = ",".join(rename.get(labels[i], labels[i]) for i in keep)
    np.savetxt(csv, data[:, keep], delimiter=",", header=head, comments="", fmt="%.8f")
    a = load_measured_trial(ik, grf)
    b = load_measured_trial(ik, csv)
    for side in ("right", "left"):
        np.testing.assert_allclose(a.events.heel_strikes_s[side], b.events.heel_strikes_s[side],
                                   atol=1e-9)
