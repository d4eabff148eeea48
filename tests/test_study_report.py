"""The study report (``afo_mj.studies.study_analysis``, written by
``afo_mj.outputs.study_report``) on hand-made sweep tables (no simulation):
Pareto front, ranking, default metric, Sobol' indices of the Ishigami function (analytic
values), Morris screening of a linear function, figures, failed runs, unknown metrics."""

from __future__ import annotations

import json
import math

import numpy as np
import pandas as pd
import pytest

from afo_mj.outputs.study_figures import safe_name, unit_of
from afo_mj.outputs.study_report import write_study_report
from afo_mj.studies.study_analysis import (default_metric, load_results, pareto_front,
                                           pareto_metrics, ranked_table, sensitivity)

CHANGE = "comparison_vs_no_device.assist.human_ankle_positive_work_change_j_per_stride"
EPS = "device_conditions.assist.energy_per_stride.electrical_in_j"
PNG_MAGIC = b"\x89PNG\r\n\x1a\n"


def _param(key, levels=(), lo=None, hi=None, points=3):
    return {"key": key, "levels": list(levels), "lo": lo, "hi": hi,
            "points": len(levels) if levels else points, "scale": "linear", "integer": False}


def _study(name, kind, params, samples=16, seed=0):
    def bounds(p):
        return [0.0, float(len(p["levels"]))] if p["levels"] else [p["lo"], p["hi"]]
    return {"name": name, "description": "", "scenario": "/nonexistent/base.toml",
            "set": ["gait.strides=4"], "design": {"kind": kind, "samples": samples,
                                                  "seed": seed},
            "parameters": params, "output": {"format": "parquet"}, "optimize": {},
            "salib_problem": {"num_vars": len(params), "names": [p["key"] for p in params],
                              "bounds": [bounds(p) for p in params]}}


def _write(tmp_path, study, rows, fmt="parquet", shuffle_seed=None):
    """A sweep directory as ``afo-mj sweep`` leaves it: study.json + the results table."""
    d = tmp_path / study["name"]
    d.mkdir()
    (d / "study.json").write_text(json.dumps(study), encoding="utf-8")
    df = pd.DataFrame(rows)
    if shuffle_seed is not None:                       # finishing order != design order
        df = df.sample(frac=1.0, random_state=shuffle_seed).reset_index(drop=True)
    df["order"] = np.arange(1, len(df) + 1, dtype=float)
    if fmt == "parquet":
        df.to_parquet(d / "results.parquet", engine="pyarrow", index=False)
    else:
        df.to_csv(d / "results.csv", index=False)
    return d


def _row(i, params: dict, metrics: dict | None, error=""):
    r = {"run_id": f"run{i:04d}", "status": "ok" if metrics is not None else "failed",
         "exit_code": 0.0 if metrics is not None else 1.0, "error": error,
         "wall_time_s": 1.0}
    r.update({f"param:{k}": v for k, v in params.items()})
    r.update(metrics or {})
    return r


def _png_ok(path):
    assert path.is_file(), path
    assert path.read_bytes()[:8] == PNG_MAGIC
    import matplotlib.image as mpimg
    img = mpimg.imread(path)
    assert img.shape[0] > 100 and img.shape[1] > 100
    assert float(np.std(img[..., :3])) > 0.01          # not blank


# --------------------------------------------------------------------------- device grid

def _device_rows(fail=((40.0, 54.0),)):
    """3x3 grid over peak torque and peak time; change = -0.2*torque + 0.05*(t-52)^2,
    electrical energy per stride = 0.5*torque + 0.1*t."""
    rows = []
    i = 0
    for tq in (20.0, 30.0, 40.0):
        for t in (50.0, 52.0, 54.0):
            i += 1
            pt = {"assistance.peak_torque_nm": tq, "assistance.peak_time_pct": t}
            if (tq, t) in fail:
                rows.append(_row(i, pt, None, error="WalkNumericsError: fell at 1.2 s"))
                continue
            human0 = 22.0
            change = -0.2 * tq + 0.05 * (t - 52.0) ** 2
            rows.append(_row(i, pt, {
                CHANGE: change, EPS: 0.5 * tq + 0.1 * t,
                "human.ankle_positive_work_j_per_stride": human0 + change,
                "device_conditions.assist.human.ankle_positive_work_j_per_stride": human0 + change,
                "device_conditions.no_device.human.ankle_positive_work_j_per_stride": human0,
                "device.peak_torque_nm": 0.9 * tq, "speed_m_s.mean": 1.0,
                "ankle_angle_rms_error_deg.mean": 3.0 + 0.01 * tq,
                "fell": False}))
    return rows


def _device_study():
    return _study("dev", "grid", [_param("assistance.peak_torque_nm", (20.0, 30.0, 40.0)),
                                  _param("assistance.peak_time_pct", (50.0, 52.0, 54.0))])


def _brute_front(x, y):
    keep = []
    for i in range(len(x)):
        dom = np.any((x <= x[i]) & (y <= y[i]) & ((x < x[i]) | (y < y[i])))
        if not dom:
            keep.append(i)
    return keep


def test_pareto_front_of_hand_made_set():
    pts = {"G": (0.5, 6.0), "A": (1.0, 5.0), "B": (2.0, 3.0), "C": (3.0, 4.0),
           "D": (4.0, 1.0), "E": (2.0, 3.0), "F": (5.0, 1.0), "K": (2.0, 3.5)}
    rows = [{"run_id": k, "status": "ok", "x.mean": x, "y_j": y} for k, (x, y) in pts.items()]
    rows.append({"run_id": "failed", "status": "failed", "x.mean": -10.0, "y_j": -10.0})
    rows.append({"run_id": "novalue", "status": "ok", "x.mean": -10.0, "y_j": math.nan})
    df = pd.DataFrame(rows)
    front = pareto_front(df, "x.mean", "y_j")
    # C dominated by B; F by D (same energy, more work); K by B; E duplicates B (kept)
    assert sorted(front["run_id"]) == sorted(["G", "A", "B", "E", "D"])
    assert list(front["x.mean"]) == sorted(front["x.mean"])


def test_pareto_front_matches_brute_force_on_random_set():
    rng = np.random.default_rng(3)
    x = np.round(rng.normal(size=300), 1)              # ties in both coordinates
    y = np.round(rng.normal(size=300), 1)
    df = pd.DataFrame({"run_id": [f"r{i}" for i in range(300)], "status": "ok",
                       "a": x, "b": y})
    front = pareto_front(df, "a", "b")
    assert sorted(front.index) == _brute_front(x, y)


def test_ranking_order_failed_after_and_top():
    rows = [_row(1, {"p": 1.0}, {"m_deg": 3.0}), _row(2, {"p": 2.0}, {"m_deg": 1.0}),
            _row(3, {"p": 3.0}, None, error="boom: solver diverged"),
            _row(4, {"p": 4.0}, {"m_deg": 2.0}), _row(5, {"p": 5.0}, {"m_deg": math.nan})]
    df = pd.DataFrame(rows)
    txt = ranked_table(df, "m_deg")
    ids = [ln.split()[1] for ln in txt.splitlines() if ln[:1].isdigit()]
    assert ids == ["run0002", "run0004", "run0001"]
    assert txt.index("run0004") < txt.index("Successful runs without a value") \
        < txt.index("run0005") < txt.index("Failed runs") < txt.index("run0003")
    assert "boom: solver diverged" in txt
    assert "(deg)" in txt                              # unit in the header
    desc = ranked_table(df, "m_deg", ascending=False, top=2)
    ids = [ln.split()[1] for ln in desc.splitlines() if ln[:1].isdigit()]
    assert ids == ["run0001", "run0004"]


def test_default_metric_by_study_kind():
    dev = pd.DataFrame(_device_rows())
    assert default_metric(dev) == CHANGE
    assert pareto_metrics(dev) == (CHANGE, EPS)
    no_base = dev.drop(columns=[CHANGE])
    assert default_metric(no_base) == "human.ankle_positive_work_j_per_stride"
    walk = pd.DataFrame([_row(1, {"walker.body_mass_kg": 60.0},
                              {"ankle_angle_rms_error_deg.mean": 2.5, "speed_m_s.mean": 1.0})])
    assert default_metric(walk) == "ankle_angle_rms_error_deg.mean"
    assert pareto_metrics(walk) is None


def test_headline_condition_with_transparent_and_dotted_names():
    rows = []
    for i, tq in enumerate((10.0, 20.0)):
        rows.append(_row(i, {"assistance.peak_torque_nm": tq}, {
            "human.ankle_positive_work_j_per_stride": 20.0 - tq / 10,
            "device_conditions.no_device.human.ankle_positive_work_j_per_stride": 22.0,
            "device_conditions.transparent.human.ankle_positive_work_j_per_stride": 21.0,
            "device_conditions.assist_k2.5.human.ankle_positive_work_j_per_stride":
                20.0 - tq / 10,
            "comparison_vs_no_device.transparent.human_ankle_positive_work_change_j_per_stride":
                -1.0,
            "comparison_vs_no_device.assist_k2.5.human_ankle_positive_work_change_j_per_stride":
                -2.0 - tq / 10,
            "device_conditions.assist_k2.5.energy_per_stride.electrical_in_j": tq}))
    df = pd.DataFrame(rows)
    m = default_metric(df)
    assert m == ("comparison_vs_no_device.assist_k2.5."
                 "human_ankle_positive_work_change_j_per_stride")
    assert pareto_metrics(df)[1] == ("device_conditions.assist_k2.5."
                                     "energy_per_stride.electrical_in_j")


def test_unknown_metric_raises_naming_it_and_close_names(tmp_path):
    d = _write(tmp_path, _device_study(), _device_rows())
    _, df = load_results(d)
    with pytest.raises(ValueError) as e:
        ranked_table(df, "speed_m_s.maen")
    assert "speed_m_s.maen" in str(e.value) and "speed_m_s.mean" in str(e.value)
    with pytest.raises(ValueError, match="device.peak_torque_nm"):
        write_study_report(d, metric="device.peak_torque")
    with pytest.raises(ValueError, match="no_such_metric"):
        pareto_front(df, "no_such_metric", EPS)
    with pytest.raises(ValueError, match="not numeric"):
        ranked_table(df.assign(**{"label_txt": "abc"}), "label_txt")
    assert not (d / "study").exists()                  # nothing written on an error


def test_device_report_files_figures_and_failed_run(tmp_path):
    d = _write(tmp_path, _device_study(), _device_rows())
    res = write_study_report(d)
    out = d / "study"
    assert res["dir"] == out
    for f in ("ranking.txt", "summary.json", "metric_vs_parameters.png",
              "heatmap_assistance_peak_torque_nm__assistance_peak_time_pct.png", "pareto.png"):
        assert f in res["files"], f
        assert (out / f).is_file(), f
    for f in res["files"]:
        if f.endswith(".png"):
            _png_ok(out / f)
    assert "sensitivity.png" not in res["files"]
    summ = json.loads((out / "summary.json").read_text(),
                      parse_constant=lambda c: pytest.fail(f"{c} in summary.json"))
    assert summ["metric"] == CHANGE and summ["ascending"] is True
    assert summ["failed"] == 1 and summ["failed_runs"][0]["error"].startswith("WalkNumerics")
    # best: largest torque (change -0.2*40) at peak time 52; (40, 54) failed
    assert summ["best"]["parameters"] == {"assistance.peak_torque_nm": 40.0,
                                          "assistance.peak_time_pct": 52.0}
    # the Pareto runs are the brute-force non-dominated set of the successful runs
    _, df = load_results(d)
    ok = df[df["status"] == "ok"].reset_index(drop=True)
    want = sorted(ok["run_id"].iloc[_brute_front(ok[CHANGE].to_numpy(), ok[EPS].to_numpy())])
    assert sorted(r["run_id"] for r in summ["pareto"]["runs"]) == want
    assert summ["pareto"]["x_metric"] == CHANGE and summ["pareto"]["y_metric"] == EPS
    assert summ["sensitivity"] is None
    assert "grid design does not support" in res["text"]
    assert "grid design does not support" in summ["sensitivity_note"]
    assert (out / "ranking.txt").read_text().count("run0") == 9
    assert "Failed runs (1)" in res["text"]


def test_report_when_every_run_failed(tmp_path):
    rows = [_row(i, {"walker.body_mass_kg": m}, None, error="exit code 1")
            for i, m in enumerate((60.0, 80.0))]
    d = _write(tmp_path, _study("allfail", "grid", [_param("walker.body_mass_kg",
                                                           (60.0, 80.0))]), rows, fmt="csv")
    res = write_study_report(d)
    assert "No successful run" in res["text"] and "exit code 1" in res["text"]
    assert (d / "study" / "summary.json").is_file()
    assert json.loads((d / "study" / "summary.json").read_text())["best"] is None


# --------------------------------------------------------------------------- sensitivity

def _ishigami_dir(tmp_path, n=1024, fail_one=False):
    from SALib.sample import sobol as sobol_sample
    from SALib.test_functions import Ishigami
    keys = ["device.params.x1", "device.params.x2", "device.params.x3"]
    params = [_param(k, lo=-math.pi, hi=math.pi) for k in keys]
    study = _study("ishigami", "saltelli", params, samples=n, seed=7)
    X = sobol_sample.sample(study["salib_problem"], n, calc_second_order=False, seed=7)
    Y = Ishigami.evaluate(X)
    rows = [_row(i, dict(zip(keys, x)), {"speed_m_s.mean": y, "other_j": 1.0})
            for i, (x, y) in enumerate(zip(X, Y))]
    if fail_one:
        rows[5] = _row(5, dict(zip(keys, X[5])), None, error="failed")
    return _write(tmp_path, study, rows, shuffle_seed=1), study


def test_sobol_indices_of_ishigami_match_analytic(tmp_path):
    d, _ = _ishigami_dir(tmp_path)
    study, df = load_results(d)
    res = sensitivity(study, df, "speed_m_s.mean")
    assert res["method"] == "sobol" and res["n_runs"] == 1024 * 5
    s1 = [r["S1"] for r in res["indices"]]
    st = [r["ST"] for r in res["indices"]]
    assert np.allclose(s1, [0.314, 0.442, 0.0], atol=0.1), s1
    assert np.allclose(st, [0.558, 0.442, 0.244], atol=0.1), st
    assert all(r["S1_conf"] > 0 for r in res["indices"])
    rep = write_study_report(d, metric="speed_m_s.mean")
    assert "sensitivity.png" in rep["files"]
    _png_ok(d / "study" / "sensitivity.png")
    assert "Sobol' indices of speed_m_s.mean" in rep["text"]
    summ = json.loads((d / "study" / "summary.json").read_text())
    assert summ["sensitivity"]["indices"][1]["parameter"] == "device.params.x2"
    # continuous parameters of a Saltelli design: no grid, no heatmap
    assert not any(f.startswith("heatmap_") for f in rep["files"])


def test_sobol_skipped_when_a_run_failed(tmp_path):
    d, _ = _ishigami_dir(tmp_path, n=64, fail_one=True)
    study, df = load_results(d)
    res = sensitivity(study, df, "speed_m_s.mean")
    assert "indices" not in res and "1 failed" in res["skipped"]
    rep = write_study_report(d, metric="speed_m_s.mean")
    assert "not computed" in rep["text"] and "1 failed" in rep["text"]
    assert "sensitivity.png" not in rep["files"]


def _morris_dir(tmp_path, fail_point=None):
    from SALib.sample import morris as morris_sample
    keys = ["assistance.peak_torque_nm", "assistance.peak_time_pct",
            "device.params.hose.bore_m", "walker.body_mass_kg"]
    bounds = [(0.0, 1.0), (0.0, 2.0), (0.0, 1.0), (0.0, 1.0)]
    coef = np.array([10.0, 3.0, 1.0, 0.0])
    params = [_param(k, lo=a, hi=b) for k, (a, b) in zip(keys, bounds)]
    study = _study("morris", "morris", params, samples=12, seed=3)
    X = morris_sample.sample(study["salib_problem"], 12, num_levels=4, seed=3)
    rows, seen = [], set()
    for i, x in enumerate(X):
        if tuple(x) in seen:                           # the sweep runs a point once
            continue
        seen.add(tuple(x))
        ok = fail_point is None or not np.array_equal(x, X[fail_point])
        rows.append(_row(i, dict(zip(keys, x)),
                         {"device.peak_pressure_mpa": float(coef @ x) + 5.0} if ok else None))
    return _write(tmp_path, study, rows, fmt="csv", shuffle_seed=2), coef, bounds


def test_morris_ranks_linear_function_by_coefficient(tmp_path):
    d, coef, bounds = _morris_dir(tmp_path)
    study, df = load_results(d)
    res = sensitivity(study, df, "device.peak_pressure_mpa")
    assert res["method"] == "morris" and res["n_trajectories"] == 12
    mu_star = np.array([r["mu_star"] for r in res["indices"]])
    expect = coef * np.array([b - a for a, b in bounds])   # effect over the full range
    assert list(np.argsort(-mu_star)) == [0, 1, 2, 3]
    assert np.allclose(mu_star, expect, atol=1e-6)
    assert np.allclose([r["sigma"] for r in res["indices"]], 0.0, atol=1e-6)
    rep = write_study_report(d, metric="device.peak_pressure_mpa")
    _png_ok(d / "study" / "sensitivity.png")
    assert "Morris" in rep["text"]


def test_morris_drops_incomplete_trajectory(tmp_path):
    d, coef, _ = _morris_dir(tmp_path, fail_point=6)
    study, df = load_results(d)
    res = sensitivity(study, df, "device.peak_pressure_mpa")
    assert res["dropped_trajectories"] >= 1 and res["n_trajectories"] <= 11
    mu_star = np.array([r["mu_star"] for r in res["indices"]])
    assert list(np.argsort(-mu_star)) == [0, 1, 2, 3]


def test_grid_and_lhs_designs_have_no_sensitivity(tmp_path):
    d = _write(tmp_path, _device_study(), _device_rows())
    study, df = load_results(d)
    assert sensitivity(study, df, CHANGE) is None
    study["design"]["kind"] = "lhs"
    assert sensitivity(study, df, CHANGE) is None


# --------------------------------------------------------------------------- helpers

def test_file_names_and_units():
    assert safe_name("param:assistance.peak_torque_nm") == "param_assistance_peak_torque_nm"
    assert unit_of("assistance.peak_torque_nm") == "N·m"
    assert unit_of(CHANGE) == "J/stride"
    assert unit_of(EPS) == "J/stride"
    assert unit_of("speed_m_s.mean") == "m/s"
    assert unit_of("energy.losses_j.motor_copper") == "J"
    assert unit_of("device.peak_pressure_mpa") == "MPa"
    assert unit_of("ankle_angle_rms_error_deg.mean") == "deg"


def test_walk_study_report_has_no_pareto_and_lhs_has_no_heatmap(tmp_path):
    params = [_param("walker.body_mass_kg", lo=60.0, hi=80.0),
              _param("controller.ankle_kp_nm_per_rad", lo=250.0, hi=350.0)]
    rng = np.random.default_rng(0)
    rows = [_row(i, {"walker.body_mass_kg": m, "controller.ankle_kp_nm_per_rad": k},
                 {"ankle_angle_rms_error_deg.mean": 2.0 + m / 100 - k / 1000, "fell": False})
            for i, (m, k) in enumerate(zip(rng.uniform(60, 80, 12), rng.uniform(250, 350, 12)))]
    d = _write(tmp_path, _study("walk_lhs", "lhs", params), rows)
    res = write_study_report(d)
    assert res["summary"]["metric"] == "ankle_angle_rms_error_deg.mean"
    assert res["files"] == ["ranking.txt", "summary.json", "metric_vs_parameters.png"]
    assert res["summary"]["pareto"] is None
    assert "a lhs design does not support them" in res["text"]


def test_device_study_without_energy_values_has_no_pareto_figure(tmp_path):
    rows = _device_rows(fail=())
    for r in rows:
        r[EPS] = math.nan
    d = _write(tmp_path, _device_study(), rows)
    res = write_study_report(d)
    assert "pareto.png" not in res["files"] and res["summary"]["pareto"] is None
    assert "no successful run has both" in res["text"]


METABOLIC = "comparison_vs_no_device.assist.net_metabolic_umberger_change_pct"


def test_muscle_walker_studies_rank_by_the_wearers_metabolic_change(tmp_path):
    """A device study on the muscle walker ranks by the wearer's net metabolic change (%), its
    Pareto front is that change against the electrical energy, labelled with their units,
    and the report gives the runs' spread on the metric (mean, sample SD, range) computed
    here with the statistics module."""
    import statistics

    from afo_mj.studies.study_analysis import metric_spread
    changes = [-1.97, 0.21, 0.49]
    rows = [{**r, METABOLIC: c} for r, c in zip(_device_rows()[:3], changes)]
    dev = pd.DataFrame(rows)
    assert default_metric(dev) == METABOLIC
    assert pareto_metrics(dev) == (METABOLIC, EPS)
    # without a value in any successful run the human work change is the metric again
    assert default_metric(dev.assign(**{METABOLIC: np.nan})) == CHANGE
    sp = metric_spread(changes + [math.nan])
    assert sp["n"] == 3 and sp["mean"] == pytest.approx(statistics.mean(changes), rel=1e-12)
    assert sp["sd"] == pytest.approx(statistics.stdev(changes), rel=1e-12)
    assert (sp["min"], sp["max"]) == (-1.97, 0.49)
    assert metric_spread([1.0])["sd"] is None and metric_spread([])["n"] == 0
    study = _study("seeds", "grid", [_param("walker.reflex_set", levels=["a", "b", "c"])])
    d = _write(tmp_path, study, rows)
    rep = write_study_report(d)
    assert "(%) vs " in rep["text"] and "Over the 3 runs with a value: mean" in rep["text"]
    assert rep["summary"]["spread"]["n"] == 3
