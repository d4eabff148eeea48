"""Parameter studies (issue 8): designs, the sweep runner, resume, failures and Dask.

References: single ``afo-mj run`` calls with the same values (the sweep's rows must hold the
same metrics), the definition of a Latin hypercube (one point per stratum and dimension), and
the run-id bookkeeping (every run present exactly once after an interrupted sweep resumes)."""

from __future__ import annotations

import contextlib
import io
import json
import math
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from afo_mj import cli
from afo_mj.studies.study import StudyError, load_study, parse_study
from afo_mj.app.sweep_point import run_point
from afo_mj.studies.sweep import PARAM_PREFIX, Sweep, flatten_summary, read_rows

ROOT = Path(__file__).resolve().parents[1]
WALK = ROOT / "scenarios" / "walk_healthy.toml"


def _study(tmp_path, body, name="s"):
    p = tmp_path / f"{name}.toml"
    p.write_text(f'name = "{name}"\nscenario = "{WALK.as_posix()}"\n'
                 'set = ["gait.strides=3", "gait.analyse_strides=[2, 3]"]\n' + body)
    return load_study(p)


GRID = '''
[design]
kind = "grid"
[[parameter]]
key = "walker.height_m"
levels = [1.70, 1.80]
[[parameter]]
key = "controller.ankle_kp_nm_per_rad"
range = [250.0, 350.0]
points = 3
'''


def _single_run(study, point, tmp_path) -> dict:
    out = tmp_path / f"single-{study.run_id(point)}"
    argv = ["run", str(study.scenario_path), "--out", str(out)]
    for o in study.overrides(point):
        argv += ["--set", o]
    with contextlib.redirect_stdout(io.StringIO()):
        assert cli.main(argv) == 0
    return flatten_summary(json.loads((out / "summary.json").read_text()))


def _metrics(row):
    return {k: v for k, v in row.items()
            if not k.startswith(PARAM_PREFIX) and k not in
            ("order", "run_id", "status", "exit_code", "error", "wall_time_s")}


def _same(a, b):
    assert set(a) == set(b)
    for k in a:
        x, y = a[k], b[k]
        if isinstance(x, float) and math.isnan(x):
            assert isinstance(y, float) and math.isnan(y), k
        else:
            assert x == y, (k, x, y)


@pytest.fixture(scope="module")
def grid_sweep(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("grid")
    study = _study(tmp, GRID)
    rows = Sweep(study, tmp / "out", workers=2, progress=False, runner=run_point).run()
    return study, rows, tmp


@pytest.mark.slow
def test_grid_rows_equal_single_runs(grid_sweep, tmp_path):
    study, rows, tmp = grid_sweep
    assert len(rows) == 6 and all(r["status"] == "ok" for r in rows)
    assert len({r["run_id"] for r in rows}) == 6
    import pyarrow.parquet as pq
    table = pq.read_table(tmp / "out" / "results.parquet")
    assert table.num_rows == 6
    assert {PARAM_PREFIX + "walker.height_m",
            PARAM_PREFIX + "controller.ankle_kp_nm_per_rad"} <= set(table.column_names)
    for point, row in zip(study.points(), rows):
        assert row[PARAM_PREFIX + "walker.height_m"] == point["walker.height_m"]
        _same(_metrics(row), _single_run(study, point, tmp_path))
    # the parameters did act on the runs
    assert len({r["speed_m_s.mean"] for r in rows}) > 1


@pytest.mark.slow
def test_dask_local_cluster_gives_the_same_table(grid_sweep, tmp_path):
    pytest.importorskip("distributed")
    study, rows, _ = grid_sweep
    pts = study.points()[:4]
    drows = Sweep(study, tmp_path / "dask", workers=2, scheduler="local",
                  progress=False, runner=run_point).run(pts)
    assert [r["run_id"] for r in drows] == [r["run_id"] for r in rows[:4]]
    for a, b in zip(drows, rows[:4]):
        _same(_metrics(a), _metrics(b))


def test_a_failing_run_is_recorded_and_the_rest_complete(tmp_path):
    study = _study(tmp_path, '''
[[parameter]]
key = "walker.body_mass_kg"
levels = [70.0, -5.0, 80.0]
''')
    rows = Sweep(study, tmp_path / "out", workers=1, progress=False, runner=run_point).run()
    assert [r["status"] for r in rows] == ["ok", "failed", "ok"]
    bad = rows[1]
    assert "body_mass_kg" in bad["error"] and bad["exit_code"] == 2
    import pyarrow.parquet as pq
    t = pq.read_table(tmp_path / "out" / "results.parquet").to_pydict()
    assert sorted(t["status"]) == ["failed", "ok", "ok"]


@pytest.mark.slow
def test_interrupted_sweep_resumes_with_every_run_once(tmp_path):
    study = _study(tmp_path, '''
[design]
kind = "lhs"
samples = 6
seed = 3
[[parameter]]
key = "controller.ankle_kp_nm_per_rad"
range = [250.0, 350.0]
''', name="resume")
    out = tmp_path / "out"
    cmd = [sys.executable, "-m", "afo_mj.cli", "sweep", str(study.source_path), "--out",
           str(out), "--workers", "1", "--quiet", "--format", "csv"]
    env = dict(os.environ, MUJOCO_GL="egl")
    proc = subprocess.Popen(cmd, cwd=ROOT, env=env, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    deadline = time.time() + 120
    while time.time() < deadline:
        if len(list((out / "rows").glob("*.json"))) >= 2 if (out / "rows").is_dir() else False:
            break
        time.sleep(0.2)
    proc.send_signal(signal.SIGTERM)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 130, err
    assert "resume" in err
    first = {p.name: p.read_text() for p in (out / "rows").glob("*.json")}
    assert 2 <= len(first) < 6
    assert (out / "results.csv").is_file()
    r = subprocess.run(cmd, cwd=ROOT, env=env, capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    rows = read_rows(out)
    ids = [x["run_id"] for x in rows]
    assert sorted(ids) == sorted(study.run_id(p) for p in study.points())
    assert len(ids) == len(set(ids)) == 6
    # the runs finished before the interruption were not recomputed
    for name, text in first.items():
        assert (out / "rows" / name).read_text() == text
    import csv
    with open(out / "results.csv", newline="") as fh:
        table = list(csv.DictReader(fh))
    assert len(table) == 6 and len({t["run_id"] for t in table}) == 6


def test_designs(tmp_path):
    lhs = _study(tmp_path, '''
[design]
kind = "lhs"
samples = 8
[[parameter]]
key = "a.x"
range = [0.0, 8.0]
[[parameter]]
key = "a.y"
range = [1.0, 100.0]
scale = "log"
''', name="lhs")
    pts = lhs.points()
    assert len(pts) == 8
    # one point in each of the 8 strata of each dimension (McKay et al. 1979)
    assert sorted(int(p["a.x"]) for p in pts) == list(range(8))
    u = [math.log(p["a.y"]) / math.log(100.0) for p in pts]
    assert sorted(int(v * 8) for v in u) == list(range(8))
    sob = _study(tmp_path, '''
[design]
kind = "sobol"
samples = 16
[[parameter]]
key = "a.x"
range = [2.0, 3.0]
''', name="sob")
    xs = [p["a.x"] for p in sob.points()]
    assert len(xs) == 16 and all(2.0 <= x <= 3.0 for x in xs)
    sal = _study(tmp_path, '''
[design]
kind = "saltelli"
samples = 8
[[parameter]]
key = "a.x"
range = [0.0, 1.0]
[[parameter]]
key = "a.y"
range = [0.0, 1.0]
''', name="sal")
    assert len(sal.points()) == 8 * (2 + 2)           # N (D + 2) without second order
    grid = _study(tmp_path, GRID, name="grid")
    ids = [grid.run_id(p) for p in grid.points()]
    assert len(set(ids)) == 6 and ids == [grid.run_id(p) for p in grid.points()]
    assert grid.overrides(grid.points()[0])[-1].startswith("controller.ankle_kp_nm_per_rad=")


@pytest.mark.parametrize("body,needle", [
    ('[[parameter]]\nkey = "a.x"\nrange = [3.0, 1.0]\n', "range"),
    ('[[parameter]]\nkey = "a.x"\nlevels = [1]\nrange = [0.0, 1.0]\n', "exactly one"),
    ('[design]\nkind = "magic"\n[[parameter]]\nkey = "a.x"\nlevels = [1]\n', "design.kind"),
    ('[[parameter]]\nkey = "a.x"\nlevels = [1]\nwhat = 3\n', "what"),
    ('', "parameter"),
])
def test_bad_studies_are_refused(tmp_path, body, needle):
    with pytest.raises(StudyError, match=needle):
        _study(tmp_path, body)
    with pytest.raises(StudyError, match="scenario"):
        parse_study('scenario = "nope.toml"\n[[parameter]]\nkey = "a.x"\nlevels = [1]\n',
                    base_dir=tmp_path)


def test_shipped_studies_parse():
    # the [dose_response] studies have their own parser (tests/test_dose_response.py), and
    # this one refuses them naming their command
    files, dose = [], []
    for f in sorted((ROOT / "scenarios" / "studies").glob("*.toml")):
        (dose if f.name.startswith("dose_") else files).append(f)
    assert len(files) >= 3 and dose
    for f in dose:
        with pytest.raises(StudyError, match="afo-mj dose-response"):
            load_study(f)
    from afo_mj.scenarios.device_scenario import device_config
    from afo_mj.scenarios.walk_scenario import load_scenario
    for f in files:
        s = load_study(f)
        pts = s.points()
        assert pts and s.description
        for p in (pts[0], pts[-1]):         # every override is a valid scenario value
            sc = load_scenario(s.scenario_path, overrides=s.overrides(p))
            device_config(sc)


@pytest.mark.slow
def test_study_and_optimize_commands(grid_sweep, tmp_path):
    """``afo-mj study DIR`` on the grid sweep; ``afo-mj optimize`` refuses a bad study."""
    _, rows, tmp = grid_sweep
    buf = io.StringIO()
    with contextlib.redirect_stdout(buf):
        assert cli.main(["study", str(tmp / "out")]) == 0
    text = buf.getvalue()
    best = min(rows, key=lambda r: r["ankle_angle_rms_error_deg.mean"])
    assert best["run_id"] in text.split("Best run:")[1]
    assert (tmp / "out" / "study" / "metric_vs_parameters.png").stat().st_size > 0
    with contextlib.redirect_stderr(io.StringIO()) as err:
        assert cli.main(["study", str(tmp / "out"), "--metric", "no_such_metric"]) == 2
    assert "no_such_metric" in err.getvalue()
    bad = tmp_path / "bad.toml"
    bad.write_text(f'scenario = "{WALK.as_posix()}"\n[[parameter]]\nkey = "a.x"\n'
                   'range = [0.0, 1.0]\n[optimize]\nmethod = "magic"\n')
    with contextlib.redirect_stderr(io.StringIO()) as err:
        assert cli.main(["optimize", str(bad), "--out", str(tmp_path / "o")]) == 2
    assert "method" in err.getvalue()


def _study_file(tmp_path, body, fixed='["gait.strides=3", "gait.analyse_strides=[2, 3]"]'):
    p = tmp_path / "study.toml"
    p.write_text(f'name = "typo"\nscenario = "{WALK.as_posix()}"\nset = {fixed}\n' + body)
    return p


@pytest.mark.parametrize("body, fixed, key, suggestion", [
    ('[[parameter]]\nkey = "walker.body_mas_kg"\nlevels = [70.0]\n', None,
     "walker.body_mas_kg", "walker.body_mass_kg"),
    ('[[parameter]]\nkey = "controler.ankle_kp_nm_per_rad"\nlevels = [300.0]\n', None,
     "controler.ankle_kp_nm_per_rad", "controller.ankle_kp_nm_per_rad"),
    ('[[parameter]]\nkey = "walker.height_m"\nlevels = [1.7]\n', '["gait.stridez=3"]',
     "gait.stridez", "gait.strides"),
], ids=["parameter", "table", "fixed-set"])
def test_misspelt_key_is_refused_before_any_run(tmp_path, body, fixed, key, suggestion):
    """Issue 19 item 4: a misspelt key exits 2 naming it (with a difflib suggestion), before
    any run: no sweep directory is written."""
    path = _study_file(tmp_path, body, *(() if fixed is None else (fixed,)))
    out = tmp_path / "out"
    err = io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
        rc = cli.main(["sweep", str(path), "--out", str(out), "--workers", "1", "--quiet"])
    msg = err.getvalue()
    assert rc == 2, msg
    assert key in msg and "nothing was run" in msg
    if suggestion:
        assert f"did you mean {suggestion!r}" in msg
    assert not out.exists()
    with pytest.raises(StudyError, match=key.replace(".", r"\.")):   # the API checks too
        Sweep(load_study(path), out, workers=1, progress=False, runner=run_point).run()
    assert not out.exists()


@pytest.mark.parametrize("statuses, code, note", [
    (["failed", "failed"], 1, "every run failed (2 of 2)"),
    (["ok", "failed"], 0, "1 of 2 runs failed"),
])
def test_sweep_exit_code_reflects_failed_runs(tmp_path, monkeypatch, statuses, code, note):
    """Every run failed: exit 1; some failed: exit 0 with the failures reported on stderr."""
    def fake_run(self, points=None):
        return [{"run_id": f"r{i}", "status": s, "error": "" if s == "ok" else "boom"}
                for i, s in enumerate(statuses)]
    monkeypatch.setattr(Sweep, "run", fake_run)
    path = _study_file(tmp_path, '[[parameter]]\nkey = "walker.height_m"\n'
                                 'levels = [1.7, 1.8]\n')
    err = io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
        rc = cli.main(["sweep", str(path), "--out", str(tmp_path / "o"), "--quiet"])
    assert rc == code and note in err.getvalue()
