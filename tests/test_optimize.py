"""Optimisation of a study's parameters (issue 8): [optimize] validation, the optimisers on
pure-Python objectives with known optima (an injected batch evaluator instead of simulations),
penalties for constraint violations and failed runs, the budget, determinism, and one tiny
end-to-end optimisation through the real sweep runner (resumed from its rows).

References: the analytic minimum of a quadratic, (3, -1), and its constrained minimum on the
boundary x = 2 (or x = 4 under a lower bound)."""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest

from afo_mj.studies.optimize import (DEFAULT_METRIC, OptimizeError, optimize_study,
                                      parse_optimize)
from afo_mj.studies.study import load_study, parse_study
from afo_mj.app.sweep_point import run_point
from afo_mj.studies.sweep import read_rows

ROOT = Path(__file__).resolve().parents[1]
WALK = ROOT / "scenarios" / "walk_healthy.toml"

PARAMS = '''
[[parameter]]
key = "a.x"
range = [0.0, 10.0]
[[parameter]]
key = "a.y"
range = [-5.0, 5.0]
'''


def _study(opt: str, params: str = PARAMS):
    return parse_study(f'name = "q"\nscenario = "{WALK.as_posix()}"\n' + params + opt,
                       origin="q.toml")


class Quadratic:
    """f = (x - 3)² + (y + 1)², c = x; counts the batches and the points it is given."""

    def __init__(self, fail=lambda p: False, nan=lambda p: False):
        self.batches: list[list[dict]] = []
        self.fail, self.nan = fail, nan

    def __call__(self, points):
        self.batches.append([dict(p) for p in points])
        rows = []
        for p in points:
            x, y = p["a.x"], p["a.y"]
            if self.fail(p):
                rows.append({"status": "failed", "error": "walker fell"})
                continue
            f = math.nan if self.nan(p) else (x - 3.0) ** 2 + (y + 1.0) ** 2
            rows.append({"status": "ok", "error": "", "f": f, "c": x, "num": 2.0 * f,
                         "den": 2.0})
        return rows

    @property
    def points(self):
        return [p for b in self.batches for p in b]


def _opt(tmp_path, body, ev=None, params=PARAMS):
    ev = ev or Quadratic()
    res = optimize_study(_study(body, params), tmp_path / "opt", evaluate=ev, progress=False)
    return res, ev


@pytest.mark.parametrize("method", ["differential_evolution", "nelder_mead"])
def test_finds_the_unconstrained_minimum(tmp_path, method):
    res, ev = _opt(tmp_path, f'[optimize]\nmetric = "f"\nmethod = "{method}"\n'
                             'budget = 150\npopsize = 10\nseed = 1\n')
    bx, by = res["best_point"]["a.x"], res["best_point"]["a.y"]
    assert abs(bx - 3.0) < 0.15 and abs(by + 1.0) < 0.15
    assert res["best_metric"] == pytest.approx((bx - 3) ** 2 + (by + 1) ** 2)
    assert res["best_feasible"] and res["method"] == method
    assert res["n_runs"] <= 150
    # every point run once: repeats are served from the cache, never re-run
    keys = [tuple(sorted(p.items())) for p in ev.points]
    assert len(keys) == len(set(keys)) == res["n_runs"]
    # the result is on disk, strict JSON
    on_disk = json.loads((tmp_path / "opt" / "optimization.json").read_text())
    assert on_disk["best_point"] == res["best_point"]
    assert len(on_disk["history"]) == res["n_evaluations"] >= res["n_runs"]


def test_de_evaluates_each_generation_as_one_batch(tmp_path):
    res, ev = _opt(tmp_path, '[optimize]\nmetric = "f"\nbudget = 40\npopsize = 8\n')
    assert len(ev.batches[0]) == 8                       # the initial population
    assert all(len(b) <= 8 for b in ev.batches)
    assert len(ev.batches) >= 4                           # generations, not single runs
    assert res["n_runs"] == 40 and res["state"] == "budget"
    assert not res["converged"] and "budget" in res["message"]


def test_points_are_rounded_to_the_resolution(tmp_path):
    res, ev = _opt(tmp_path, '[optimize]\nmetric = "f"\nbudget = 30\nresolution = 1e-3\n')
    for p in ev.points:
        assert p["a.x"] == round(p["a.x"], 2) and p["a.y"] == round(p["a.y"], 2)
        assert 0.0 <= p["a.x"] <= 10.0 and -5.0 <= p["a.y"] <= 5.0


@pytest.mark.parametrize("method", ["differential_evolution", "nelder_mead"])
def test_constraint_moves_the_optimum_to_its_boundary(tmp_path, method):
    body = (f'[optimize]\nmetric = "f"\nmethod = "{method}"\nbudget = 200\npopsize = 10\n'
            '[[optimize.constraints]]\nmetric = "c"\nmax = 2.0\n')
    res, ev = _opt(tmp_path, body)
    assert res["best_feasible"]
    assert res["best_point"]["a.x"] <= 2.0
    assert res["best_point"]["a.x"] == pytest.approx(2.0, abs=0.15)
    assert res["best_point"]["a.y"] == pytest.approx(-1.0, abs=0.2)
    assert res["constraint_values"]["c"] == res["best_point"]["a.x"]
    infeasible = [h for h in res["history"] if h["constraints"]["c"] > 2.0]
    assert infeasible and all(not h["feasible"] and h["objective"] >= 1e6
                              for h in infeasible)
    # a larger violation is penalised more (the optimiser is led back to feasibility)
    worst = max(infeasible, key=lambda h: h["constraints"]["c"])
    least = min(infeasible, key=lambda h: h["constraints"]["c"])
    assert worst["objective"] > least["objective"]
    # a lower bound (min) works too
    body = ('[optimize]\nmetric = "f"\nmethod = "nelder_mead"\nbudget = 200\n'
            '[[optimize.constraints]]\nmetric = "c"\nmin = 4.0\nmax = 9.0\n')
    res, _ = _opt(tmp_path / "min", body)
    assert res["best_feasible"] and res["best_point"]["a.x"] == pytest.approx(4.0, abs=0.15)


def test_failed_and_nan_runs_get_a_finite_penalty(tmp_path):
    ev = Quadratic(fail=lambda p: p["a.x"] > 6.0, nan=lambda p: p["a.y"] > 3.0)
    res, ev = _opt(tmp_path, '[optimize]\nmetric = "f"\nbudget = 60\npenalty = 1000.0\n'
                             'seed = 3\n', ev)
    objs = [h["objective"] for h in res["history"]]
    assert all(math.isfinite(o) for o in objs)
    failed = [h for h in res["history"] if h["status"] == "failed"]
    assert failed and all(h["objective"] == 2000.0 and not h["feasible"] for h in failed)
    assert any("walker fell" in h["error"] for h in failed)
    assert any("no finite value of f" in h["error"] for h in failed)
    assert res["n_failed"] == len({h["run_id"] for h in failed})
    assert res["best_feasible"] and res["best_point"]["a.x"] <= 6.0
    json.loads((tmp_path / "opt" / "optimization.json").read_text())   # strict JSON


def test_all_infeasible_reports_the_least_violating_point(tmp_path):
    body = ('[optimize]\nmetric = "f"\nmethod = "nelder_mead"\nbudget = 30\n'
            '[[optimize.constraints]]\nmetric = "c"\nmax = -1.0\n')
    res, _ = _opt(tmp_path, body)
    assert not res["best_feasible"]
    assert "no feasible point" in res["message"]
    assert res["best_point"]["a.x"] == pytest.approx(0.0, abs=0.5)


def test_maximize_and_ratio_metric(tmp_path):
    params = '[[parameter]]\nkey = "a.x"\nrange = [0.0, 10.0]\n' \
             '[[parameter]]\nkey = "a.y"\nrange = [-5.0, 5.0]\n'
    # maximise -f  ==  minimise f; "num / den" = f
    res, _ = _opt(tmp_path, '[optimize]\nmetric = "num / den"\ndirection = "maximize"\n'
                            'method = "nelder_mead"\nbudget = 100\n', params=params)
    # the maximum of f on the box is at a corner: x = 10, y = 5 (49 + 36)
    assert res["best_point"] == {"a.x": 10.0, "a.y": 5.0}
    assert res["best_metric"] == pytest.approx(85.0)


def test_budget_is_respected_and_deterministic(tmp_path):
    body = '[optimize]\nmetric = "f"\nbudget = 23\npopsize = 6\nseed = 7\n'
    r1, e1 = _opt(tmp_path / "a", body)
    r2, e2 = _opt(tmp_path / "b", body)
    assert r1["n_runs"] == 23 == len(e1.points)
    assert e1.points == e2.points and r1["best_point"] == r2["best_point"]
    body = '[optimize]\nmetric = "f"\nmethod = "nelder_mead"\nbudget = 5\n'
    r3, e3 = _opt(tmp_path / "c", body)
    assert r3["n_runs"] == 5 == len(e3.points) and r3["state"] == "budget"
    assert len(e3.batches[0]) == 3                        # the initial simplex, one batch


def test_resume_replays_cached_points_and_continues(tmp_path):
    """A row cache shared by two calls (what the sweep's rows/ are): the second call with a
    larger budget replays the first call's points from the cache and only runs new ones."""
    cache: dict = {}
    computed = []

    def cached(points):
        q = Quadratic()
        out = []
        for p in points:
            k = tuple(sorted(p.items()))
            if k not in cache:
                computed.append(p)
                cache[k] = q([p])[0]
            out.append(cache[k])
        return out

    r1, _ = _opt(tmp_path, '[optimize]\nmetric = "f"\nbudget = 20\npopsize = 6\n', cached)
    assert len(computed) == 20
    r2, _ = _opt(tmp_path, '[optimize]\nmetric = "f"\nbudget = 32\npopsize = 6\n', cached)
    assert len(computed) == 32 and r2["n_runs"] == 32
    first = [h["point"] for h in r1["history"]]
    assert [h["point"] for h in r2["history"]][:len(first)] == first
    assert r2["history"][-1]["objective"] <= 2e6


def test_interruption_and_evaluator_errors_propagate(tmp_path):
    from afo_mj.studies.sweep import SweepInterrupted
    q = Quadratic()

    def stop_second(points):
        if q.batches:
            raise SweepInterrupted("interrupted (SIGINT)")
        return q(points)

    with pytest.raises(SweepInterrupted):
        _opt(tmp_path, '[optimize]\nmetric = "f"\nbudget = 20\npopsize = 5\n', stop_second)
    saved = json.loads((tmp_path / "opt" / "optimization.json").read_text())
    assert saved["state"] == "interrupted" and saved["n_runs"] == 5

    def bad(points):
        raise ValueError("holds a sweep of another study")

    with pytest.raises(ValueError, match="another study"):          # not scipy's RuntimeError
        _opt(tmp_path / "v", '[optimize]\nmetric = "f"\nbudget = 20\npopsize = 5\n', bad)


def test_initial_point_and_levels(tmp_path):
    params = ('[[parameter]]\nkey = "a.x"\nrange = [0.0, 10.0]\n'
              '[[parameter]]\nkey = "a.y"\nlevels = [-3.0, -1.0, 4.0]\n')
    res, ev = _opt(tmp_path, '[optimize]\nmetric = "f"\nbudget = 40\npopsize = 8\n'
                             'initial = { "a.x" = 3.0, "a.y" = 4.0 }\n', params=params)
    assert ev.batches[0][0] == {"a.x": 3.0, "a.y": 4.0}
    assert all(p["a.y"] in (-3.0, -1.0, 4.0) for p in ev.points)
    assert res["best_point"]["a.y"] == -1.0 and abs(res["best_point"]["a.x"] - 3) < 0.5


def test_log_scale_parameter(tmp_path):
    params = '[[parameter]]\nkey = "a.x"\nrange = [0.1, 100.0]\nscale = "log"\n' \
             '[[parameter]]\nkey = "a.y"\nrange = [-5.0, 5.0]\n'
    res, ev = _opt(tmp_path, '[optimize]\nmetric = "f"\nmethod = "nelder_mead"\n'
                             'budget = 120\n', params=params)
    assert res["best_point"]["a.x"] == pytest.approx(3.0, rel=0.03)
    assert all(0.1 <= p["a.x"] <= 100.0 for p in ev.points)


def test_unknown_metric_is_named_with_close_matches(tmp_path):
    with pytest.raises(OptimizeError, match=r"optimize.constraints\[0\].metric.*'cc'.*close: c"):
        _opt(tmp_path, '[optimize]\nmetric = "f"\nbudget = 10\npopsize = 5\n'
                       '[[optimize.constraints]]\nmetric = "cc"\nmax = 1.0\n')
    with pytest.raises(OptimizeError, match=r"optimize.metric.*'g'"):
        _opt(tmp_path, '[optimize]\nmetric = "g"\nbudget = 10\npopsize = 5\n')


def test_defaults():
    cfg = parse_optimize({}, _study("").parameters)
    assert cfg.metric == DEFAULT_METRIC and cfg.direction == "minimize"
    assert cfg.method == "differential_evolution" and cfg.budget == 40
    assert cfg.population(2) == 5 and cfg.population(4) == 8
    assert cfg.constraints == () and cfg.penalty == 1e6 and cfg.seed == 0


@pytest.mark.parametrize("body, key", [
    ('bogus = 1', "optimize.bogus"),
    ('metric = 3', "optimize.metric"),
    ('metric = "a / b / c"', "optimize.metric"),
    ('direction = "down"', "optimize.direction"),
    ('method = "cma"', "optimize.method"),
    ('budget = 0', "optimize.budget"),
    ('budget = 4.5', "optimize.budget"),
    ('budget = 4', "optimize.budget"),                       # < DE population (5)
    ('method = "nelder_mead"\nbudget = 2', "optimize.budget"),  # < simplex (3)
    ('popsize = 3', "optimize.popsize"),
    ('seed = -1', "optimize.seed"),
    ('penalty = 0', "optimize.penalty"),
    ('penalty = inf', "optimize.penalty"),
    ('resolution = 0.5', "optimize.resolution"),
    ('constraints = 1', "optimize.constraints"),
    ('constraints = [{metric = "c"}]', "optimize.constraints[0]"),
    ('constraints = [{max = 1.0}]', "optimize.constraints[0].metric"),
    ('constraints = [{metric = "c", max = "1"}]', "optimize.constraints[0].max"),
    ('constraints = [{metric = "c", max = 1.0, min = 2.0}]', "optimize.constraints[0].min"),
    ('constraints = [{metric = "c", maximum = 1.0}]', "optimize.constraints[0].maximum"),
    ('initial = { "a.z" = 1.0 }', "optimize.initial.a.z"),
    ('initial = { "a.x" = 11.0 }', "optimize.initial.a.x"),
])
def test_bad_optimize_tables_name_the_key(body, key):
    study = _study("[optimize]\n" + body + "\n")
    with pytest.raises(OptimizeError) as exc:
        parse_optimize(study.optimize, study.parameters, "q.toml")
    msg = str(exc.value)
    assert f"{key} = " in msg and "allowed:" in msg and msg.startswith("q.toml:")
    with pytest.raises(OptimizeError):
        optimize_study(study, "/nonexistent/never-created", evaluate=Quadratic())


def test_shipped_study_parses():
    study = load_study(ROOT / "scenarios" / "studies" / "optimize_zhang_profile.toml")
    cfg = parse_optimize(study.optimize, study.parameters)
    assert [p.key for p in study.parameters] == [
        "assistance.peak_torque_nm", "assistance.peak_time_pct", "assistance.rise_time_pct",
        "assistance.fall_time_pct"]
    assert cfg.metric == "human.ankle_positive_work_j_per_stride" and cfg.budget == 40
    names = {c.metric: c for c in cfg.constraints}
    assert names["device.peak_torque_nm"].max == 35.0
    assert names["device.peak_pressure_mpa"].max == 14.0


def _must_not_run(*args, **kwargs):
    raise AssertionError("a resumed optimisation simulated a point it had a row for")


def test_end_to_end_real_runs_resume_from_rows(tmp_path):
    """Three-stride walks through the sweep runner: Nelder–Mead on the ankle gain, 4 runs;
    a second call with the same directory reads the rows back instead of simulating."""
    p = tmp_path / "opt.toml"
    p.write_text(f'name = "e2e"\nscenario = "{WALK.as_posix()}"\n'
                 'set = ["gait.strides=3", "gait.analyse_strides=[2, 3]"]\n'
                 '[[parameter]]\nkey = "controller.ankle_kp_nm_per_rad"\n'
                 'range = [150.0, 450.0]\n'
                 '[optimize]\nmetric = "ankle_angle_rms_error_deg.mean"\n'
                 'method = "nelder_mead"\nbudget = 4\n'
                 '[[optimize.constraints]]\nmetric = "speed_m_s.mean"\nmin = 0.5\n')
    study = load_study(p)
    out = tmp_path / "out"
    res = optimize_study(study, out, workers=1, progress=False, runner=run_point)
    assert res["n_runs"] == 4 and res["n_failed"] == 0
    rows = read_rows(out)
    assert len(rows) == 4 and all(r["status"] == "ok" for r in rows)
    best = next(r for r in rows if r["run_id"] == res["best_run_id"])
    assert res["best_metric"] == pytest.approx(best["ankle_angle_rms_error_deg.mean"])
    assert res["best_metric"] == min(r["ankle_angle_rms_error_deg.mean"] for r in rows)
    assert res["constraint_values"]["speed_m_s.mean"] > 0.5 and res["best_feasible"]
    assert 150.0 <= res["best_point"]["controller.ankle_kp_nm_per_rad"] <= 450.0
    assert (out / "optimization.json").is_file() and (out / "results.parquet").is_file()
    again = optimize_study(study, out, workers=1, progress=False, runner=_must_not_run)
    assert len(read_rows(out)) == 4
    assert again["best_point"] == res["best_point"] and again["history"] == res["history"]
