"""``[walker] model = "muscle"`` scenarios (issue 22): parsing with named errors, a run through
``run_scenario`` equal to the muscle walk run directly, and its summary's muscle block against
the per-muscle arrays summed by hand."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from afo_mj.scenarios.walk_scenario import ScenarioError, muscle_reflex_sets, parse_scenario

ROOT = Path(__file__).resolve().parents[1]
BASE = """
[walker]
model = "muscle"
{extra}
[gait]
strides = 6
analyse_strides = [3, 6]
"""


def test_shipped_sets_and_default():
    sets = muscle_reflex_sets()
    assert {"1.0", "1.25", "1.5"} <= set(sets)
    sc = parse_scenario(BASE.format(extra=""))
    assert sc.walker_model == "muscle" and sc.reflex_set == sets["1.25"]
    assert parse_scenario("").walker_model == "torque" and parse_scenario("").reflex_set is None


@pytest.mark.parametrize("text, match", [
    ('[walker]\nmodel = "hill"', r"walker.model = 'hill'.*allowed: 'torque' \| 'muscle'"),
    ('[walker]\nreflex_set = "1.25"', r"walker.reflex_set = '1.25' is given for the torque"),
    (BASE.format(extra='reflex_set = "2.0"'), r"walker.reflex_set = '2.0' is neither a shipped"),
    (BASE.format(extra="") + "[controller]\nkp_hip_nm_per_rad = 100.0\n",
     r"controller = .* does not apply to walker.model = 'muscle'"),
])
def test_bad_muscle_scenarios_are_named(text, match):
    with pytest.raises(ScenarioError, match=match):
        parse_scenario(text)


def test_a_device_is_worn_by_the_muscle_walker():
    """[device] and [assistance] on walker.model = "muscle" parse (issue 39: any device on
    any walker); the adapted wearers are shipped sets by name."""
    from afo_mj.scenarios.device_scenario import device_config
    sc = parse_scenario(BASE.format(extra='reflex_set = "adapted/hafo"')
                        + '[device]\npreset = "hafo_gait"\n'
                        + '[assistance]\npeak_torque_nm = 30.0\n')
    assert sc.walker_model == "muscle" and sc.reflex_set == muscle_reflex_sets()["adapted/hafo"]
    cfg = device_config(sc)
    assert cfg.preset == "hafo_gait" and tuple(cfg.conditions) == ("no_device", "transparent",
                                                                   "assist")


def test_a_shipped_set_named_by_a_number_from_the_command_line():
    """``--set walker.reflex_set=1.25`` arrives as the number 1.25: it names the shipped set
    (it was refused as 'the wrong type (float)'); a number naming no set is still refused."""
    from afo_mj.scenarios.walk_scenario import load_scenario
    path = Path(__file__).resolve().parents[1] / "scenarios" / "walk_muscle_healthy.toml"
    for value, name in (("1.25", "1.25"), ("1.0", "1.0"), ("1", "1.0")):
        sc = load_scenario(path, overrides=[f"walker.reflex_set={value}"])
        assert sc.reflex_set == muscle_reflex_sets()[name]
    with pytest.raises(ScenarioError, match="walker.reflex_set = 3.5"):
        load_scenario(path, overrides=["walker.reflex_set=3.5"])


def test_reflex_set_path_relative_to_the_file(tmp_path):
    src = muscle_reflex_sets()["1.5"]
    (tmp_path / "mine.json").write_text(src.read_text())
    sc = parse_scenario(BASE.format(extra='reflex_set = "mine.json"'), base_dir=tmp_path)
    assert sc.reflex_set == tmp_path / "mine.json"


def test_run_scenario_is_the_muscle_walk_with_its_metabolics():
    from afo_mj.app.run import run_scenario
    from afo_mj.gait.muscle_walk import run_muscle_walk
    from afo_mj.studies.gait_optimization import load_reflex_set
    res = run_scenario(ROOT / "scenarios" / "walk_muscle_healthy.toml",
                       overrides=["gait.strides=6", "gait.analyse_strides=[3, 6]"])
    s = res.summary.to_json()
    assert not res.fell and s["completed_strides"] >= 6
    params = load_reflex_set(muscle_reflex_sets()["1.25"])
    direct = run_muscle_walk(None, params, float(res.record.time_s[-1]))
    n = min(len(direct.record.time_s), len(res.record.time_s))
    assert n >= len(res.record.time_s) - 1
    np.testing.assert_array_equal(direct.record.qpos[:n], res.record.qpos[:n])
    t0, t1 = s["analysed_span_s"]
    sel = (direct.record.time_s > t0) & (direct.record.time_s <= t1)
    m = s["muscle"]
    want = direct.metabolic_umberger_w[sel].sum(axis=(1, 2)).mean() / 75.0
    assert m["net_metabolic_umberger_w_per_kg"] == pytest.approx(want, rel=1e-12)
    sol = m["muscles"]["soleus"]
    assert sol["peak_activation"] == pytest.approx(direct.activation[sel, :, 0].max())
    assert set(m["emg_timing_right"]) == {"soleus", "gastrocnemius", "tibialis_anterior"}


def test_impairment_fractions_are_the_muscles_force_factors():
    """plantarflexor_strength_fraction 0.5 is the walk with soleus and gastrocnemius at half
    their maximum force (and the dorsiflexor fraction the tibialis anterior's)."""
    from afo_mj.app.run import run_scenario
    from afo_mj.gait.muscle_walk import run_muscle_walk
    from afo_mj.studies.gait_optimization import load_reflex_set
    res = run_scenario(ROOT / "scenarios" / "walk_muscle_healthy.toml",
                       overrides=["gait.strides=2", "gait.analyse_strides=[1, 2]",
                                  "impairment.plantarflexor_strength_fraction=0.5",
                                  "impairment.dorsiflexor_strength_fraction=0.8"])
    params = load_reflex_set(muscle_reflex_sets()["1.25"])
    scale = {"soleus": 0.5, "gastrocnemius": 0.5, "tibialis_anterior": 0.8}
    direct = run_muscle_walk(None, params, 1.0, max_force_scale=scale)
    n = len(direct.record.time_s)
    np.testing.assert_array_equal(direct.record.qpos, res.record.qpos[:n])
    healthy = run_muscle_walk(None, params, 1.0)
    assert not np.array_equal(healthy.record.qpos, direct.record.qpos)


def test_recording_of_a_muscle_walk_has_the_muscles(tmp_path):
    """[output] record = true on the muscle model: the rerun recording carries each muscle's
    activation, force and metabolic rate per side and the whole-body net rate, sampled from
    the run's samples (read back from the file)."""
    from afo_mj.app.run import run_scenario
    from afo_mj.outputs.recording import read_recording_index
    out = tmp_path / "res"
    res = run_scenario(ROOT / "scenarios" / "walk_muscle_healthy.toml", out_dir=out,
                       figures=False, overrides=["gait.strides=2", "gait.analyse_strides=[1, 2]",
                                                 "output.record=true"])
    idx = read_recording_index(out / "recording.rrd")
    n = len(res.record.time_s[::2])                    # 500 Hz signals of a 1 ms walk
    for key in ("signals/muscle_activation/soleus/right/walk",
                "signals/muscle_force_n/tibialis_anterior/left/walk",
                "signals/metabolic_w_per_kg/umberger/walk"):
        # thinned for display to the samples a plot needs (tests/test_recording.py)
        assert 2 <= idx[key]["rows"] <= n, key
    assert idx["signals/muscle_force_n/vasti/right/walk"]["unit"] == "N"
