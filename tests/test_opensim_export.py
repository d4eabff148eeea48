"""Writing a simulated walk as OpenSim storage files (issue 23): the files read back by
afo_mj's OpenSim reader equal the record (values, names, signs, units), and the measured-trial
machinery finds the walk's own gait events in the written ground reaction forces."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from afo_mj.gait.measured_trial import load_measured_trial
from afo_mj.gait.reference import read_opensim_storage
from afo_mj.outputs.opensim_export import write_opensim, write_storage

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def walk_record():
    from afo_mj.gait.walk import simulate_walk
    from afo_mj.scenarios.walk_scenario import load_scenario
    sc = load_scenario(ROOT / "scenarios" / "walk_healthy.toml",
                       overrides=["gait.strides=6", "gait.analyse_strides=[2, 6]"])
    return simulate_walk(sc)


def test_files_read_back_equal_the_record(walk_record, tmp_path):
    r = walk_record
    paths = write_opensim(r, tmp_path, "walk")
    assert {p.name for p in paths.values()} == {"walk_ik.mot", "walk_id.sto", "walk_grf.mot",
                                                 "walk_grf.xml", "walk.osim"}
    hdr, labels, data = read_opensim_storage(paths["ik"])
    assert hdr["inDegrees"] == "yes" and hdr["source"] == "afo_mj"
    col = {lab: data[:, i] for i, lab in enumerate(labels)}
    np.testing.assert_allclose(col["time"], r.time_s, rtol=1e-9)
    np.testing.assert_allclose(np.radians(col["knee_angle_r"]), r.joint_angle_rad[:, 0, 1],
                               rtol=1e-8, atol=1e-10)
    np.testing.assert_allclose(np.radians(col["ankle_angle_l"]), r.joint_angle_rad[:, 1, 2],
                               rtol=1e-8, atol=1e-10)
    np.testing.assert_allclose(np.radians(col["pelvis_tilt"]), -r.pelvis_tilt_rad, rtol=1e-8,
                               atol=1e-10)
    _, labels, data = read_opensim_storage(paths["id"])
    col = {lab: data[:, i] for i, lab in enumerate(labels)}
    # forces one step earlier than their row (the export's Timing): row k at time_s[k − 1]
    np.testing.assert_allclose(col["time"], r.time_s[:-1], rtol=1e-9)
    np.testing.assert_allclose(col["ankle_angle_r_moment"], r.joint_moment_nm[1:, 0, 2],
                               rtol=1e-8, atol=1e-8)
    _, labels, data = read_opensim_storage(paths["grf"])
    col = {lab: data[:, i] for i, lab in enumerate(labels)}
    np.testing.assert_allclose(col["time"], r.time_s[:-1], rtol=1e-9)
    np.testing.assert_allclose(col["ground_force_l_vy"], r.grf_n[1:, 1, 1], rtol=1e-8,
                               atol=1e-8)


def test_the_written_trial_gives_back_the_walks_events(walk_record, tmp_path):
    r = walk_record
    paths = write_opensim(r, tmp_path, "walk")
    trial = load_measured_trial(paths["ik"], paths["grf"])
    assert trial.reference.metadata["knee_flexion_sign"] == 1          # Rajagopal's sign
    for s, side in enumerate(("right", "left")):
        sim = np.asarray(r.events.heel_strikes_s[s])
        got = trial.events.heel_strikes_s[side]
        # every force-plate heel strike is one of the walk's own (its foot switch), within
        # a few samples (the switch is a contact, the plate a 50 N threshold); the plate also
        # sees the first landing of the supported start, before the walk counts strikes
        for h in got[got > sim[0] - 0.05]:
            assert np.min(np.abs(sim - h)) < 0.015, (side, h)
        assert len(got) >= len(sim) - 1
    assert trial.n_cycles >= 8
    # the trial's mean cycle is the walk's own: its knee within a degree of the record's
    # stride-averaged knee angle
    hs = trial.events.heel_strikes_s["right"]
    ph = np.linspace(0, 0.99, 50)
    mean = np.mean([np.interp(a + ph * (b - a), r.time_s, r.joint_angle_rad[:, 0, 1])
                    for a, b in trial.cycles["right"]], axis=0)
    both = trial.reference.angles_rad(ph)[:, 1]
    assert math.degrees(np.max(np.abs(both - mean))) < 3.0
    assert len(hs) >= 5


def test_a_record_not_sampled_every_step_is_refused(walk_record, tmp_path):
    """The force files are shifted by one MuJoCo step; a record whose rows are not one per
    step (here: claimed at 2 ms on a 1 ms model) cannot be shifted and is refused."""
    import dataclasses
    bad = dataclasses.replace(walk_record, sample_period_s=2 * walk_record.sample_period_s)
    with pytest.raises(ValueError, match="sample_period_s = 0.002.*one per MuJoCo step"):
        write_opensim(bad, tmp_path / "x", "walk")
    assert not (tmp_path / "x").exists()


def test_write_storage_refuses_bad_data(tmp_path):
    with pytest.raises(ValueError, match="'time' first"):
        write_storage(tmp_path / "x.sto", ["a", "time"], np.zeros((3, 2)), name="x",
                      in_degrees=False)
    with pytest.raises(ValueError, match="column 'b' has non-finite"):
        write_storage(tmp_path / "x.sto", ["time", "b"], [[0.0, math.nan]], name="x",
                      in_degrees=False)
    assert not list(tmp_path.iterdir())


def test_output_opensim_writes_every_run_into_the_results(tmp_path):
    from afo_mj.app.run import run_scenario
    out = tmp_path / "res"
    run_scenario(ROOT / "scenarios" / "walk_healthy.toml", out_dir=out, figures=False,
                 overrides=["gait.strides=3", "gait.analyse_strides=[2, 3]",
                            "output.opensim=true"])
    assert sorted(p.name for p in (out / "opensim").iterdir()) == [
        "walk.osim", "walk_grf.mot", "walk_grf.xml", "walk_id.sto", "walk_ik.mot"]
    from afo_mj.scenarios.walk_scenario import ScenarioError, parse_scenario
    with pytest.raises(ScenarioError, match="output.opensim = 'yes'"):
        parse_scenario('[output]\nopensim = "yes"')


def test_a_device_walk_on_the_muscle_walker_exports_every_condition(tmp_path):
    """OpenSim files serve both walkers: a HAFO walk on the muscle walker writes each
    condition's ik/id/grf, and the assist condition's read back equal its record (the
    muscle walker's joint angles and moments, not the torque walker's)."""
    from afo_mj.app.run import run_scenario
    out = tmp_path / "res"
    res = run_scenario(ROOT / "scenarios" / "gait_muscle_hafo.toml", out_dir=out,
                       figures=False,
                       overrides=["gait.strides=3", "gait.analyse_strides=[2, 3]",
                                  "output.opensim=true",
                                  'device.conditions=["no_device", "assist"]'])
    names = sorted(p.name for p in (out / "opensim").iterdir())
    assert names == sorted([f"{c}_{k}" for c in ("no_device", "assist")
                            for k in ("grf.mot", "grf.xml", "id.sto", "ik.mot")]
                           + ["no_device.osim", "assist.osim"])
    rec = res.results["assist"][0]
    _, labels, data = read_opensim_storage(out / "opensim" / "assist_ik.mot")
    col = {lab: data[:, i] for i, lab in enumerate(labels)}
    np.testing.assert_allclose(col["time"], rec.time_s, rtol=1e-9)
    np.testing.assert_allclose(np.radians(col["ankle_angle_r"]), rec.joint_angle_rad[:, 0, 2],
                               rtol=1e-8, atol=1e-10)
    _, labels, data = read_opensim_storage(out / "opensim" / "assist_id.sto")
    col = {lab: data[:, i] for i, lab in enumerate(labels)}
    # the force files one row fewer: row k's forces at time_s[k − 1] (the export's Timing)
    np.testing.assert_allclose(col["time"], rec.time_s[:-1], rtol=1e-9)
    np.testing.assert_allclose(col["ankle_angle_r_moment"], rec.joint_moment_nm[1:, 0, 2],
                               rtol=1e-8, atol=1e-8)
    np.testing.assert_allclose(col["ankle_angle_r_device_moment"], rec.device_moment_nm[1:, 0],
                               rtol=1e-8, atol=1e-8)
    # the assist condition's model carries the orthosis's worn masses (body + device)
    import xml.etree.ElementTree as ET
    model = ET.parse(out / "opensim" / "assist.osim").getroot()
    mass = sum(float(b.findtext("mass")) for b in model.iter("Body"))
    assert mass == pytest.approx(rec.body_mass_kg + sum(w.mass_kg for w in
                                                         res.results["assist"][2].worn_masses()))
