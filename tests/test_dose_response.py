"""Dose–response by continuation (afo_mj.studies.dose_response, ``afo-mj dose-response``):
the continuation's wiring and resume with the search and the scoring walk replaced by
bookkeeping fakes, the bands and paired changes against hand-computed values, the
monotonicity test on hand-made bands, the study file's parsing and refusals, the shipped study
files, and one tiny real run through the command (about 5 s)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from afo_mj.app.errors import InvalidInput
from afo_mj.experiments.batch import BatchResult
from afo_mj.gait import reflex_law as rl
from afo_mj.studies import dose_response as dr

ROOT = Path(__file__).resolve().parents[1]
P0, P1 = rl.PARAM_NAMES[0], rl.PARAM_NAMES[1]
#: net metabolic rate (W/kg) the fake scoring walk gives, by (dose, restart); the control
#: is dose 0
RATES = {(0.0, 0): 5.0, (0.0, 1): 5.2, (0.15, 0): 4.9, (0.15, 1): 5.0,
         (0.3, 0): 4.6, (0.3, 1): 5.1}


START = {n: float(v) for n, v in zip(rl.PARAM_NAMES, dr.load_reflex_set(dr.DEFAULT_START))}


def _study(levels=(0.0, 0.15, 0.3), generations=3, **kw):
    return dr.DoseStudy(name="t", variable="zhang_peak_nm_per_kg", levels=levels,
                        assistance={"ramp_strides": 3},
                        protocol=dr.AdaptationProtocol(restarts=2, generations=generations,
                                                       window=1), **kw)


@pytest.fixture
def fakes(monkeypatch):
    """optimize_gait replaced: it records its call, and writes a best set that is its start
    with P0 raised by 1 (one per rung) and P1 set to the restart's seed, a state file and a
    flat history; the scoring walk gives RATES by the objective's dose and P1's seed."""
    calls = {"search": [], "score": 0, "rates": dict(RATES)}

    def optimize_gait(out_dir, objective, generations, popsize, seed, start, workers,
                      sigma0, client):
        out = Path(out_dir)
        state = out / "cma_state.pkl"
        params = dict(start)
        if state.exists():
            params = json.loads((out / "reflex_params.json").read_text())["parameters"]
        else:
            params[P0] = start[P0] + 1.0
            params[P1] = float(seed)
            state.write_bytes(b"x")
        calls["search"].append((out.parent.name, out.name, dict(start), seed, generations))
        (out / "reflex_params.json").write_text(json.dumps(
            {"format": "afo_mj reflex parameters v1", "parameters": params}))
        return {"cost": 5.0, "history": [{"best": 5.0}] * generations, "wall_s": 1.0,
                "optimizer": {"generations": generations, "evaluations": 4 * generations}}

    def evaluate_batch(fn, items, workers, client):
        out = []
        for objective, params, _walk_s, _settle_s in items:
            calls["score"] += 1
            a = objective.assistance
            dose = 0.0 if a.kind == "none" else a.zhang_peak_nm_per_kg
            restart = int(params[rl.PARAM_NAMES.index(P1)]) - 1
            rate = calls["rates"][dose, restart]         # None: the walk falls at 19 s
            if a.kind == "none":
                # nothing worn: the control's rate, less 0.1 W/kg per rung searched after it
                # (the best set walked with the device taken off)
                rungs = round(params[rl.PARAM_NAMES.index(P0)] - START[P0])
                rate -= 0.1 * (rungs - 1)
            out.append(BatchResult(value={"fell_s": None if rate is not None else 19.0,
                                          "speed_m_s": 1.25,
                                          "net_metabolic_w_per_kg": rate or 4.0}))
        return out

    monkeypatch.setattr(dr, "optimize_gait", optimize_gait)
    monkeypatch.setattr(dr, "evaluate_batch", evaluate_batch)
    return calls


def test_continuation_wiring_bands_and_paired_changes(tmp_path, fakes):
    study = _study()
    start = {n: float(v) for n, v in zip(rl.PARAM_NAMES, dr.load_reflex_set(study.start))}
    res = dr.run_dose_response(tmp_path, study)
    # rung by rung, restart by restart: the control, then 0.15, then 0.3
    assert [(c[0], c[1], c[3]) for c in fakes["search"]] == [
        ("control", "restart0", 1), ("control", "restart1", 2),
        ("level1_0.15", "restart0", 1), ("level1_0.15", "restart1", 2),
        ("level2_0.3", "restart0", 1), ("level2_0.3", "restart1", 2)]
    for k, (rung, restart, began, seed, _g) in enumerate(fakes["search"]):
        level = k // 2
        # the control's restarts from the study's start; rung k restart i from rung k-1
        # restart i's best set (P0 raised once per rung before it, P1 that restart's seed)
        assert began[P0] == pytest.approx(start[P0] + level)
        assert began[P1] == (start[P1] if level == 0 else float(seed))
        src = json.loads((tmp_path / rung / restart / "continuation_start.json").read_text())
        prev = ("control", "level1_0.15")[level - 1] if level else None
        assert src["from"] == (str(study.start) if prev is None
                               else str(tmp_path / prev / restart / "reflex_params.json"))
    assert [lv.name for lv in res.levels] == ["control", "level1_0.15", "level2_0.3"]
    ctl, l1, l2 = res.levels
    assert l1.restarts[1].started_from.endswith("control/restart1/reflex_params.json")
    # bands by hand: rates 4.9, 5.0 -> min 4.9, mean 4.95; paired 4.9/5.0 - 1 = -2 %,
    # 5.0/5.2 - 1 = -3.8462 %
    assert (l1.rate_min, l1.rate_mean, l1.rate_max) == pytest.approx((4.9, 4.95, 5.0))
    assert [r.change_pct for r in l1.restarts] == pytest.approx([-2.0, -3.846154], abs=1e-6)
    assert (l1.change_pct_min, l1.change_pct_mean, l1.change_pct_max) == pytest.approx(
        (-3.846154, -2.923077, -2.0), abs=1e-6)
    # 4.6/5.0 - 1 = -8 %, 5.1/5.2 - 1 = -1.9231 %: the band [-8, -1.92] overlaps
    # [-3.85, -2]: monotone within the bands, but the means (-2.92, -4.96) fall too
    assert [r.change_pct for r in l2.restarts] == pytest.approx([-8.0, -1.923077], abs=1e-6)
    assert l2.spread_pct == pytest.approx(100 * 0.5 / 4.85)
    assert ctl.change_pct_mean is None and ctl.dose == 0.0
    assert res.monotone_within_bands is True and res.monotone_means is True
    # each restart's own chain: 0, -2, -8 falls throughout; 0, -3.85, -1.92 rises once
    assert res.monotone_per_restart == (True, False) and res.monotone_left_out == ()
    # the best sets with the device taken off: 4.9/5.0 - 1 = -2 %, 5.1/5.2 - 1 = -1.9231 %
    # at 0.15; 4.8/5.0 and 5.0/5.2 at 0.3
    assert [r.device_off_w_per_kg for r in l1.restarts] == pytest.approx([4.9, 5.1])
    assert [r.device_off_change_pct for r in l1.restarts] == pytest.approx(
        [-2.0, -1.923077], abs=1e-6)
    assert [r.device_off_change_pct for r in l2.restarts] == pytest.approx(
        [-4.0, -3.846154], abs=1e-6)
    assert all(r.device_off_w_per_kg is None and r.device_off_change_pct is None
               for r in ctl.restarts)
    assert fakes["score"] == 2 + 2 * 4
    assert res.monotone_matched_within_bands is None and l1.matched_change_pct_mean is None
    assert res.complete and res.walks == 6 * 4 * 3
    assert all(r.converged for lv in res.levels for r in lv.restarts)   # flat histories
    # the spread 0.2/5.1 = 3.9 % > 1 %: no level converged as a whole
    assert not ctl.converged and "spread 3.92 % > 1 %" in ctl.reason
    saved = dr.DoseResponseResult.from_json(
        json.loads((tmp_path / "dose_response.json").read_text()))
    assert saved == res


def test_a_level_whose_restart_falls_has_no_band_and_is_left_out(tmp_path, fakes):
    fakes["rates"][0.15, 1] = None
    fakes["rates"][0.3, 1] = 5.3              # +1.92 %: restart 1's chain rises (0 -> +1.92)
    res = dr.run_dose_response(tmp_path, _study())
    l1, l2 = res.levels[1:]
    assert l1.restarts[1].net_metabolic_w_per_kg is None and l1.restarts[1].fell_s == 19.0
    assert l1.change_pct_min is None and l1.rate_mean is None and not l1.converged
    assert "restart(s) 1 fall" in l1.reason
    # the bands: [0, 0] and [-8, +1.92] (0.15 left out): a non-increasing curve fits
    assert res.monotone_left_out == ("level1_0.15",)
    assert res.monotone_within_bands is True and res.monotone_means is True
    assert res.monotone_per_restart == (True, False)


def test_the_matched_control_is_searched_on_along_the_chain(tmp_path, fakes):
    res = dr.run_dose_response(tmp_path, _study(matched_control=True))
    assert [(c[0], c[1]) for c in fakes["search"]][4:8] == [
        ("control1", "restart0"), ("control1", "restart1"),
        ("level2_0.3", "restart0"), ("level2_0.3", "restart1")]
    for rung, prev in (("control1", "control"), ("control2", "control1")):
        for i in range(2):
            src = json.loads((tmp_path / rung / f"restart{i}" / "continuation_start.json")
                             .read_text())
            assert src["from"] == str(tmp_path / prev / f"restart{i}" / "reflex_params.json")
    l1, l2 = res.levels[1:]
    # the matched controls walk 0.1 W/kg cheaper per rung searched on: 4.9, 5.1 after one
    # rung, 4.8, 5.0 after two; 4.9/4.9 - 1 = 0, 5.0/5.1 - 1 = -1.9608 %, 4.6/4.8 - 1 =
    # -4.1667 %, 5.1/5.0 - 1 = +2 %
    assert [r.matched_control_w_per_kg for r in l1.restarts] == pytest.approx([4.9, 5.1])
    assert [r.matched_change_pct for r in l1.restarts] == pytest.approx([0.0, -1.960784],
                                                                       abs=1e-6)
    assert [r.matched_change_pct for r in l2.restarts] == pytest.approx([-4.166667, 2.0],
                                                                       abs=1e-6)
    assert (l2.matched_change_pct_min, l2.matched_change_pct_max) == pytest.approx(
        (-4.166667, 2.0), abs=1e-6)
    # bands [0, 0], [-1.96, 0], [-4.17, +2]: the last reaches above -1.96 … 0, so a
    # non-increasing curve still fits (it may stay at 0)
    assert res.monotone_matched_within_bands is True
    assert l1.matched_control_walks == 2 * 4 * 3 and res.walks == (6 + 4) * 4 * 3
    assert l1.matched_control_cpu_s is not None and res.cpu_s == pytest.approx(sum(
        r.cpu_s for lv in res.levels for r in lv.restarts) + sum(
        lv.matched_control_cpu_s for lv in res.levels[1:]))
    assert fakes["score"] == 2 + 4 + 2 + 4 + 2


def test_resume_continues_and_reuses_the_scores(tmp_path, fakes):
    dr.run_dose_response(tmp_path, _study(levels=(0.0, 0.15)))
    assert fakes["score"] == 2 + 4                # the level's walks with and without
    # a level appended: every search continues, only the new rung and nothing else is
    # walked again (the same best sets keep their scores)
    res = dr.run_dose_response(tmp_path, _study(generations=3))
    assert fakes["score"] == 2 + 4 + 4
    assert [lv.name for lv in res.levels] == ["control", "level1_0.15", "level2_0.3"]
    # a resumed search keeps the start it began from
    assert res.levels[1].restarts[0].started_from.endswith("control/restart0/reflex_params.json")
    with pytest.raises(ValueError, match=r"levels \[0\.0, 0\.15, 0\.3\]; given \[0\.0, 0\.3"):
        dr.run_dose_response(tmp_path, _study(levels=(0.0, 0.3, 0.15)))
    other = dr.DoseStudy(name="t", variable="zhang_peak_nm_per_kg", levels=(0.0, 0.15),
                         protocol=dr.AdaptationProtocol(restarts=2, generations=3, window=1))
    with pytest.raises(ValueError, match="assistance = "):
        dr.run_dose_response(tmp_path, other)


def test_a_run_stopped_mid_rung_leaves_the_rungs_it_finished(tmp_path, fakes, monkeypatch):
    real = dr.optimize_gait

    def stop_at_level2(out_dir, *a, **k):
        if Path(out_dir).parent.name == "level2_0.3":
            raise KeyboardInterrupt
        return real(out_dir, *a, **k)
    monkeypatch.setattr(dr, "optimize_gait", stop_at_level2)
    with pytest.raises(KeyboardInterrupt):
        dr.run_dose_response(tmp_path, _study())
    doc = dr.DoseResponseResult.from_json(
        json.loads((tmp_path / "dose_response.json").read_text()))
    assert [lv.name for lv in doc.levels] == ["control", "level1_0.15"] and not doc.complete


def test_band_and_monotone_by_hand():
    assert dr.band([4.0, 5.0, 6.5]) == pytest.approx((4.0, 5.1666667, 6.5))
    assert dr.band([4.0, None]) == (None, None, None)
    assert dr.band([]) == (None, None, None)
    # non-increasing through bands: a later band may overlap an earlier one ...
    assert dr.monotone_within_bands([0, -3, -2.5, -9], [0, -1, -0.5, -4])
    # ... but not lie wholly above it (-0.5 > -1: the third band above the second)
    assert not dr.monotone_within_bands([0, -3, -0.5], [0, -1, 0.5])
    assert not dr.monotone_within_bands([0, -3, -2], [0, -2.5, -1])      # -2 > -2.5
    assert dr.monotone_within_bands([0, 1, 0.5], [0, 2, 3], decreasing=False)
    assert not dr.monotone_within_bands([0, 1, -1], [0, 2, 0.5], decreasing=False)
    with pytest.raises(ValueError, match="as many"):
        dr.monotone_within_bands([0, 1], [1])


def test_rungs_of_each_variable():
    s = dr.DoseStudy(name="s", variable="spring_nm_per_rad", levels=(0, 60, 180),
                     assistance={"spring_engage_phase": 0.02, "spring_ratchet": True})
    rungs = s.rungs()
    # stiffness 0 is the control itself (nothing worn), not a spring of 0 N·m/rad
    assert [(r.name, r.dose) for r in rungs] == [("control", 0.0), ("level1_60", 60.0),
                                                  ("level2_180", 180.0)]
    assert rungs[0].objective.assistance.kind == "none"
    a = rungs[2].objective.assistance
    assert (a.kind, a.spring_nm_per_rad, a.spring_ratchet, a.spring_engage_phase) == (
        "clutched_spring", 180.0, True, 0.02)
    t = dr.DoseStudy(name="t", variable="zhang_peak_time_pct", levels=(46.0, 56.5),
                     assistance={"zhang_peak_nm_per_kg": 0.45})
    rungs = t.rungs()
    # no dose means nothing worn: the control is prepended off the axis
    assert [(r.name, r.dose) for r in rungs] == [("control", None), ("level1_46", 46.0),
                                                  ("level2_56.5", 56.5)]
    assert rungs[1].objective.assistance.zhang_timing_pct == (46.0, 26.2, 9.8)
    assert "peak 46.0 %" in rungs[1].label


def test_the_profile_peaks_at_the_chosen_time():
    """A timing level's device table has its peak (−peak torque) at the chosen phase and
    none before onset = peak − 26.2 %: the level really moves the torque."""
    import numpy as np

    from afo_mj.experiments.muscle_assistance import ideal_device
    s = dr.DoseStudy(name="t", variable="zhang_peak_time_pct", levels=(46.0, 56.5),
                     assistance={"zhang_peak_nm_per_kg": 0.5})
    a = s.rungs()[1].objective.assistance
    assert a.zhang_timing_pct == (46.0, 26.2, 9.8)
    table = np.asarray(ideal_device(a, 80.0).profile)
    phase = np.linspace(0.0, 100.0, len(table))
    assert table.min() == pytest.approx(-40.0, rel=1e-3)
    assert phase[np.argmin(table)] == pytest.approx(46.0, abs=100.0 / (len(table) - 1))
    assert np.all(table[phase < 46.0 - 26.2] == 0.0)
    # a zhang_timing_pct given keeps its rise and fall; its peak is the level's
    s2 = dr.DoseStudy(name="t", variable="zhang_peak_time_pct", levels=(50.0, 56.5),
                      assistance={"zhang_timing_pct": [52.9, 20.0, 12.0]})
    assert s2.rungs()[2].objective.assistance.zhang_timing_pct == (56.5, 20.0, 12.0)
    with pytest.raises(ValueError, match=r"level 95: assistance.zhang_timing_pct"):
        dr.DoseStudy(name="t", variable="zhang_peak_time_pct", levels=(50.0, 95.0))


@pytest.mark.parametrize("text, match", [
    ("[dose_response]\nvariable = 'mass'\nlevels = [0, 1]", "variable = 'mass'; allowed: "
     "zhang_peak_nm_per_kg"),
    ("[dose_response]\nvariable = 'zhang_peak_nm_per_kg'\nlevels = [0.3]", "at least two"),
    ("[dose_response]\nvariable = 'zhang_peak_nm_per_kg'\nlevels = [0.3, 0.0]",
     "0 .nothing worn, the control. is not first"),
    ("[dose_response]\nvariable = 'zhang_peak_nm_per_kg'\nlevels = [0.0, 0.3, 0.3]", "repeat"),
    ("[dose_response]\nvariable = 'zhang_peak_nm_per_kg'\nlevels = [0.0, 4.0]",
     r"level 4: assistance.zhang_peak_nm_per_kg = 4.0; allowed: 0 … 3"),
    ("[dose_response]\nvariable = 'zhang_peak_nm_per_kg'\nlevels = [0.0, 0.3]\n"
     "assistance = { kind = 'hafo' }", "assistance.kind = 'hafo'; allowed: not given"),
    ("[dose_response]\nvariable = 'zhang_peak_nm_per_kg'\nlevels = [0.0, 0.3]\n"
     "assistance = { zhang_peak_nm_per_kg = 0.2 }", "allowed: not given"),
    ("[dose_response]\nvariable = 'zhang_peak_nm_per_kg'\nlevels = [0.0, 0.3]\n"
     "assistance = { stiffness = 2 }", "assistance.stiffness: unknown"),
    ("[dose_response]\nvariable = 'zhang_peak_nm_per_kg'\nlevels = [0.0, 0.3]\nrestarts = 0",
     r"dose_response.restarts = 0; allowed: an integer 1"),
    ("[dose_response]\nvariable = 'zhang_peak_nm_per_kg'\nlevels = [0.0, 0.3]\nseeds = 3",
     "dose_response.seeds; allowed: variable, levels"),
    ("[dose_response]\nvariable = 'zhang_peak_nm_per_kg'\nlevels = [0.0, 0.3]\ngroups = 2",
     "dose_response.groups; allowed: variable, levels"),
    ("[dose_response]\nlevels = [0.0, 0.3]", "variable missing"),
    ("[dose_response]\nvariable = 'zhang_peak_nm_per_kg'\nlevels = [0.0, 0.3]\n"
     "matched_control = 1", "matched_control = 1; allowed: true, false"),
    ("[sweep]\nx = 1", "key 'sweep'; allowed: name, description, dose_response"),
    ("[dose_response]\nvariable = 'spring_engage_phase'\nlevels = [0.02, 0.7]",
     "spring_engage_phase = 0.7; allowed: 0 … 0.5"),
])
def test_study_file_refusals(text, match):
    with pytest.raises(ValueError, match=match):
        dr.parse_dose_study(text, "s.toml")


def test_the_shipped_study_files():
    got = {}
    for p in sorted((ROOT / "scenarios" / "studies").glob("dose_*.toml")):
        s = dr.load_dose_study(p)
        got[s.name] = s
        assert Path(s.start).is_file()
    assert sorted(got) == ["dose_spring_engage", "dose_spring_stiffness", "dose_zhang_peak",
                           "dose_zhang_timing"]
    z = got["dose_zhang_peak"]
    # issue 42: at least 5 levels from 0 to at least 0.6 N·m/kg
    assert len(z.levels) >= 5 and z.levels[0] == 0.0 and max(z.levels) >= 0.6
    k = got["dose_spring_stiffness"]
    assert len(k.levels) >= 5 and k.levels[0] == 0.0 and max(k.levels) >= 250.0
    assert len(got["dose_zhang_timing"].levels) >= 5
    assert len(got["dose_spring_engage"].levels) >= 5


def test_command_refusals(tmp_path):
    from afo_mj.app.dose_response import dose_response
    with pytest.raises(InvalidInput, match="no such file"):
        dose_response(str(tmp_path / "missing.toml"), tmp_path / "a")
    bad = tmp_path / "bad.toml"
    bad.write_text("[dose_response]\nvariable = 'zhang_peak_nm_per_kg'\nlevels = [0.0]")
    with pytest.raises(InvalidInput, match="at least two"):
        dose_response(str(bad), tmp_path / "b")
    nostart = tmp_path / "nostart.toml"
    nostart.write_text("[dose_response]\nvariable = 'zhang_peak_nm_per_kg'\n"
                       "levels = [0.0, 0.3]\nstart = 'missing.json'")
    with pytest.raises(InvalidInput, match="dose_response.start"):
        dose_response(str(nostart), tmp_path / "c")
    with pytest.raises(InvalidInput, match="--workers = 0"):
        dose_response(str(nostart), tmp_path / "d", workers=0)
    assert not any((tmp_path / n).exists() for n in "abcd")


def test_tiny_real_run_through_the_command(tmp_path, capsys):
    """The control and one Zhang level, 2 restarts x 2 generations x 4 walks of 5 s: the
    level's restart i starts from the control's restart i's best set, and each change
    reported is that of the two best sets walked again here by the assistance module."""
    from afo_mj.cli import main
    from afo_mj.experiments.muscle_assistance import (Assistance, assistance_summary,
                                                      assistance_walk)
    study = tmp_path / "tiny.toml"
    study.write_text("name = 'tiny'\n[dose_response]\nvariable = 'zhang_peak_nm_per_kg'\n"
                     "levels = [0.0, 0.3]\nassistance = { ramp_strides = 3 }\nrestarts = 2\n"
                     "generations = 2\npopsize = 4\nwindow = 1\nsearch_walk_s = 5.0\n"
                     "score_walk_s = 5.0\n")
    out = tmp_path / "out"
    assert main(["dose-response", str(study), "--out", str(out), "--workers", "1",
                 "--quiet"]) == 0
    assert "afo-mj dose-response tiny" in capsys.readouterr().out
    res = dr.DoseResponseResult.from_json(json.loads((out / "dose_response.json").read_text()))
    assert (out / "dose_response.png").stat().st_size > 10_000
    rates = {}
    for lv, a in zip(res.levels, (Assistance("none"),
                                  Assistance("zhang", zhang_peak_nm_per_kg=0.3,
                                             ramp_strides=3))):
        for r in lv.restarts:
            best = Path(r.out_dir) / "reflex_params.json"
            walk, dev = assistance_walk(a, None, dr.load_reflex_set(best), 5.0)
            s = assistance_summary(walk, 3.0, dev)
            rates[lv.name, r.restart] = (None if s["fell_s"] is not None
                                         else s.get("net_metabolic_w_per_kg"))
            assert r.net_metabolic_w_per_kg == (
                None if rates[lv.name, r.restart] is None
                else pytest.approx(rates[lv.name, r.restart], rel=1e-12))
    for r in res.levels[1].restarts:
        start = json.loads((Path(r.out_dir) / "continuation_start.json").read_text())
        prev = out / "control" / f"restart{r.restart}" / "reflex_params.json"
        assert start["from"] == str(prev)
        assert start["params"] == pytest.approx(json.loads(prev.read_text())["parameters"])
        c0, c1 = rates["control", r.restart], rates["level1_0.3", r.restart]
        assert r.change_pct == (None if c0 is None or c1 is None
                                else pytest.approx(100 * (c1 / c0 - 1)))
