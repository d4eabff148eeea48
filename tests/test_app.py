"""The application layer (issue 19): typed results, nothing written on error, sweeps in-process
without figures, and a command line that only parses and prints.

References: the results directory ``afo-mj run`` writes (the application call must hold the
same summary, read back from ``summary.json``), the list of files the command writes with
figures, and the exit codes the command line documents (2 invalid input, 1 failed run)."""

from __future__ import annotations

import ast
import contextlib
import io
import json
import math
from pathlib import Path

import pytest

from afo_mj import cli
from afo_mj.app.errors import InvalidInput, RunFailed
from afo_mj.app.run import BenchRun, WalkRun, run_scenario
from afo_mj.app.sweep_point import run_point

ROOT = Path(__file__).resolve().parents[1]
HEALTHY = ROOT / "scenarios" / "walk_healthy.toml"
SHORT = ["gait.strides=3", "gait.analyse_strides=[2, 3]"]


def _same(a, b, path=""):
    """Equal JSON documents, floats to 1e-12 relative (a JSON round trip)."""
    if isinstance(a, dict):
        assert set(a) == set(b), path
        for k in a:
            _same(a[k], b[k], f"{path}.{k}")
    elif isinstance(a, list):
        assert len(a) == len(b), path
        for i, (x, y) in enumerate(zip(a, b)):
            _same(x, y, f"{path}[{i}]")
    elif isinstance(a, float) and isinstance(b, float):
        assert math.isclose(a, b, rel_tol=1e-12, abs_tol=1e-15) or (a != a and b != b), path
    else:
        assert a == b, path


@pytest.fixture(scope="module")
def walk_written(tmp_path_factory):
    """``afo-mj run`` of a short healthy walk: the results directory it writes."""
    out = tmp_path_factory.mktemp("app") / "cli"
    with contextlib.redirect_stdout(io.StringIO()):
        rc = cli.main(["run", str(HEALTHY), "--out", str(out), "--quiet"]
                      + sum((["--set", s] for s in SHORT), []))
    assert rc == 0
    return out


def test_run_scenario_returns_the_summary_the_command_writes(walk_written, tmp_path):
    from afo_mj.outputs.gait_report import json_ready
    res = run_scenario(HEALTHY, overrides=SHORT)
    assert isinstance(res, WalkRun) and res.out_dir is None
    assert not any(tmp_path.iterdir())
    written = json.loads((walk_written / "summary.json").read_text())
    _same(json.loads(json.dumps(json_ready(res.summary.to_json()))), written)
    assert res.record.time_s.size > 1000 and res.analysis is not None


def test_figures_false_writes_the_numbers_only(walk_written, tmp_path):
    res = run_scenario(HEALTHY, overrides=SHORT, out_dir=tmp_path / "nofig", figures=False)
    with_figs = {p.name for p in walk_written.iterdir()}
    without = {p.name for p in res.out_dir.iterdir()}
    assert "gait_curves.png" in with_figs
    assert without == {n for n in with_figs if not n.endswith(".png")}


def test_invalid_input_and_failed_runs_write_nothing(tmp_path, monkeypatch):
    out = tmp_path / "o"
    with pytest.raises(InvalidInput, match=r"gait\.stridez.*did you mean") as exc:
        run_scenario(HEALTHY, overrides=["gait.stridez=3"], out_dir=out)
    assert exc.value.exit_code == 2 and not out.exists()
    with pytest.raises(InvalidInput, match="strides"):
        run_scenario(HEALTHY, strides=0, out_dir=out)
    (tmp_path / "file").write_text("x")
    with pytest.raises(InvalidInput, match="not a directory"):
        run_scenario(HEALTHY, out_dir=tmp_path / "file")
    # a simulation that breaks down numerically fails before anything is written
    from afo_mj.gait.walk import WalkNumericsError

    def boom(scenario):
        raise WalkNumericsError("qacc not finite at t = 0.5 s")
    monkeypatch.setattr("afo_mj.gait.walkers.walk_scenario",
                        lambda scenario, *a, **k: boom(scenario))
    with pytest.raises(RunFailed, match="qacc not finite") as exc:
        run_scenario(HEALTHY, overrides=SHORT, out_dir=out)
    assert exc.value.exit_code == 1 and not out.exists()


def test_sweep_point_runs_in_process_without_figures(walk_written, tmp_path):
    row = run_point(str(HEALTHY), SHORT, "r1", {"x": 1.0}, keep_dir=str(tmp_path))
    assert row["status"] == "ok" and row["exit_code"] == 0 and row["error"] == ""
    assert row["param:x"] == 1.0
    written = json.loads((walk_written / "summary.json").read_text())
    assert row["speed_m_s.mean"] == pytest.approx(written["speed_m_s"]["mean"], rel=1e-12)
    kept = {p.name for p in (tmp_path / "r1").iterdir()}
    assert "summary.json" in kept and not any(n.endswith(".png") for n in kept)
    bad = run_point(str(HEALTHY), ["gait.stridez=3"], "r2", {})
    assert bad["status"] == "failed" and bad["exit_code"] == 2
    assert "gait.stridez" in bad["error"]


def test_a_bench_scenario_gives_a_bench_run(tmp_path):
    bench = ROOT / "scenarios" / "bench_hafo.toml"
    with pytest.raises(InvalidInput, match="bench scenario"):
        run_scenario(bench, strides=3)
    res = run_scenario(bench, overrides=['bench.tests=["isometric_steps"]'],
                       out_dir=tmp_path / "b", figures=False)
    assert isinstance(res, BenchRun)
    assert 0.0 < res.summary["bench"]["rise_time_s"] < 0.5
    written = json.loads((tmp_path / "b" / "summary.json").read_text())
    assert written["bench"]["rise_time_s"] == pytest.approx(res.summary["bench"]["rise_time_s"])
    assert not any(p.suffix == ".png" for p in (tmp_path / "b").iterdir())
    from afo_mj.app.run import run_bench
    with pytest.raises(InvalidInput, match="not a bench scenario"):
        run_bench(HEALTHY, out_dir=tmp_path / "c")
    assert not (tmp_path / "c").exists()


def test_cli_only_parses_and_prints():
    """cli.py stays a thin layer: under 300 lines, no simulation, analysis or file writing of
    its own (it imports the application layer, the console text and the grammar)."""
    src = (ROOT / "afo_mj" / "cli.py").read_text()
    assert len(src.splitlines()) < 300
    allowed = ("afo_mj", "afo_mj.app", "afo_mj.outputs.console", "afo_mj.cli_args",
               "afo_mj.outputs.comparison_report", "afo_mj.outputs.study_report",
               "afo_mj.outputs.video", "afo_mj.design.design_requirements", "afo_mj.human")
    for node in ast.walk(ast.parse(src)):
        if isinstance(node, ast.ImportFrom) and node.module and node.module.startswith(
                "afo_mj"):
            assert node.module.startswith(allowed), node.module
