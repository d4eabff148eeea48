"""Progress on stderr (afo_mj.progress): throttling and time left with a fake clock, the walk
loop's updates, and ``afo-mj run``: stage lines on stderr, none with --quiet, stdout unchanged."""

from __future__ import annotations

import contextlib
import io
import math
import re
from pathlib import Path

import pytest

from afo_mj import progress
from afo_mj.progress import Reporter, fmt_duration

ROOT = Path(__file__).resolve().parents[1]
HEALTHY = ROOT / "scenarios" / "walk_healthy.toml"


class FakeClock:
    def __init__(self, t: float = 0.0):
        self.t = t

    def __call__(self) -> float:
        return self.t


def _rep(tty: bool, clock: FakeClock, **kw) -> tuple[Reporter, io.StringIO]:
    buf = io.StringIO()
    return Reporter(stream=buf, tty=tty, clock=clock, **kw), buf


# -- the reporter --------------------------------------------------------------------------------

def test_tty_updates_in_place_at_most_once_a_second():
    clock = FakeClock()
    rep, buf = _rep(True, clock)
    task = rep.task("simulating 10 strides", 100, "steps")
    assert buf.getvalue() == "[afo-mj] simulating 10 strides…\n"
    printed = []
    for k in range(1, 51):                       # an update every 0.1 s for 5 s
        clock.t = 0.1 * k
        before = buf.getvalue()
        task.update(k)
        if buf.getvalue() != before:
            printed.append(clock.t)
    assert len(printed) == 5, printed            # one per second, not one per update
    assert all(b - a >= 1.0 - 1e-9 for a, b in zip(printed, printed[1:]))
    out = buf.getvalue()
    assert out.count("\r") == 5 and out.count("\n") == 1   # in place, one line on screen
    task.close()
    assert buf.getvalue().endswith("\n[afo-mj] simulating 10 strides: done in 5.0 s\n")


def test_plain_lines_only_at_25_percent_steps_and_5_s_apart():
    clock = FakeClock()
    rep, buf = _rep(False, clock)
    task = rep.task("rendering 200 frames", 200, "frames")
    for k in range(1, 201):                      # 0.1 s per frame: 20 s
        clock.t = 0.1 * k
        task.update(k)
    task.close()
    lines = buf.getvalue().splitlines()
    assert "\r" not in buf.getvalue()
    assert lines[0] == "[afo-mj] rendering 200 frames…"
    assert [ln.split(": ")[1].split(" ")[0] for ln in lines[1:-1]] == [
        "50/200", "100/200", "150/200"]           # 25, 50, 75 %: each 5 s after the last
    assert lines[-1] == "[afo-mj] rendering 200 frames: done in 20 s"
    # fast work: the 25 % steps come sooner than 5 s apart, so some are skipped
    clock2 = FakeClock()
    rep2, buf2 = _rep(False, clock2)
    t2 = rep2.task("fast", 100)
    for k in range(1, 101):
        clock2.t = 0.06 * k                      # 6 s in all
        t2.update(k)
    assert len(buf2.getvalue().splitlines()) == 2    # stage line and one update (at 5 s+)


def test_time_left_from_the_work_done_after_the_first_update():
    """A first chunk that included a compilation (10 s for 1 unit) does not set the rate."""
    clock = FakeClock()
    rep, buf = _rep(True, clock)
    task = rep.task("walk", 10, "s simulated")
    assert math.isnan(task.time_left())           # nothing done yet: no estimate
    clock.t = 10.0
    task.update(1)                                # only one update: rate from the start
    assert task.time_left() == pytest.approx(90.0)
    clock.t = 11.0
    task.update(2)                                # 1 unit/s since the first update
    assert task.time_left() == pytest.approx(8.0)
    assert "2/10 s simulated (20%), 11 s elapsed, ~8.0 s left" in buf.getvalue()
    clock.t = 13.0
    task.update(6)                                # (6 - 1) units in 3 s
    assert task.time_left() == pytest.approx(4 * 3 / 5)


def test_quiet_writes_nothing_and_the_default_reporter_is_silent(capsys):
    clock = FakeClock()
    rep, buf = _rep(True, clock, quiet=True)
    task = rep.task("x", 10)
    rep.stage("y")
    for k in range(10):
        clock.t += 2
        task.update(k)
    task.close()
    assert buf.getvalue() == ""
    assert not progress.reporter().active         # library default: silent
    loud = Reporter()
    with progress.using(loud):
        assert progress.reporter() is loud
        progress.reporter().stage("to stderr")
    assert not progress.reporter().active
    out = capsys.readouterr()
    assert out.out == "" and out.err == "[afo-mj] to stderr\n"


def test_fmt_duration():
    assert [fmt_duration(s) for s in (0.04, 7.26, 17.4, 125, 3725, math.nan)] == [
        "0.0 s", "7.3 s", "17 s", "2 min 05 s", "1 h 02 min", "?"]


def test_compile_stage_says_compiled_then_stays_silent():
    import numba
    import numpy as np

    @numba.njit(cache=False)
    def twice(x):
        return 2.0 * x

    rep, buf = _rep(False, FakeClock())
    with progress.using(rep):
        progress.compile_stage(twice, (np.ones(3),), "twice", "~1 s")
        lines = buf.getvalue().splitlines()
        assert lines[0] == "[afo-mj] compiling twice (first run only, ~1 s)…"
        assert lines[1].startswith("[afo-mj] compiled twice in ")
        progress.compile_stage(twice, (np.zeros(5),), "twice", "~1 s")   # same types
        assert len(buf.getvalue().splitlines()) == 2
    assert twice(np.ones(2))[0] == 2.0 and len(twice.overloads) == 1   # the call reused it


# -- the walk loop -------------------------------------------------------------------------------

def test_walk_reports_simulated_time_with_a_reporter_and_nothing_without():
    from afo_mj.gait import walk
    from afo_mj.gait.reference import load_normative
    from afo_mj.human.walker import WalkerParams

    ref = load_normative("winter", "normal")
    clock = FakeClock()

    def tick():                                   # every reading 3 s later
        clock.t += 3.0
        return clock.t

    buf = io.StringIO()
    rep = Reporter(stream=buf, tty=False, clock=tick)
    with progress.using(rep):
        rec = walk.run_walk(WalkerParams(), ref, ref.cycle_time_s, 2, walk.ControllerParams(),
                            label="test")
    lines = buf.getvalue().splitlines()
    assert lines[0] == "[afo-mj] simulating 2 strides (test)…", lines
    updates = [ln for ln in lines if "elapsed" in ln]
    assert updates and all("s simulated (" in ln and "left" in ln for ln in updates)
    assert len(updates) <= 3                      # 25 %, 50 %, 75 % at most
    assert re.fullmatch(r"\[afo-mj\] simulating 2 strides \(test\): "
                        rf"{rec.time_s[-1]:.1f} s simulated in \S+ (s|min \d+ s)", lines[-1])
    err = io.StringIO()
    with contextlib.redirect_stderr(err):
        walk.run_walk(WalkerParams(), ref, ref.cycle_time_s, 1, walk.ControllerParams())
    assert err.getvalue() == ""


# -- afo-mj run ----------------------------------------------------------------------------------

@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    """``afo-mj run walk_healthy --strides 2`` with and without --quiet (figures stubbed)."""
    from afo_mj import cli
    from afo_mj.outputs import gait_report
    tmp = tmp_path_factory.mktemp("progress_run")
    res = {}
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(gait_report, "_plot", lambda path, *a, **k: path.write_bytes(b"png"))
        for name, extra in (("loud", []), ("quiet", ["--quiet"])):
            out, err = io.StringIO(), io.StringIO()
            with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
                rc = cli.main(["run", str(HEALTHY), "--out", str(tmp / name), "--strides", "2",
                               *extra])
            res[name] = (rc, out.getvalue(), err.getvalue(), tmp / name)
    return res


def test_run_quiet_writes_nothing_to_stderr(runs):
    rc, _out, err, _d = runs["quiet"]
    assert rc == 0 and err == ""


def test_run_writes_stage_lines_to_stderr(runs):
    rc, _out, err, _d = runs["loud"]
    assert rc == 0
    lines = err.splitlines()
    assert lines and all(ln.startswith("[afo-mj] ") for ln in lines), lines
    assert "[afo-mj] simulating 2 strides…" in lines
    assert any(ln.startswith("[afo-mj] simulating 2 strides: ") and "simulated in" in ln
               for ln in lines)
    assert any(ln.startswith("[afo-mj] writing the results and figures to") for ln in lines)


def test_run_stdout_is_unchanged_by_progress(runs):
    """The results on stdout are the same with and without progress (which is on stderr
    only); only the wall time and the output directory differ."""
    def norm(s: str, d: Path) -> str:
        return re.sub(r"in \d+\.\d s wall", "in X s wall", s.replace(str(d), "DIR"))

    _, loud, _, d1 = runs["loud"]
    _, quiet, _, d2 = runs["quiet"]
    assert "[afo-mj]" not in loud and "\r" not in loud and "left" not in loud
    assert norm(loud, d1) == norm(quiet, d2)
    assert "angle RMS error" in loud


def test_every_command_takes_quiet():
    from afo_mj import cli
    for cmd in ("run", "render", "compare", "calibrate", "sweep", "optimize", "design",
                "make-bench-record"):
        buf = io.StringIO()
        with pytest.raises(SystemExit) as exc, contextlib.redirect_stdout(buf):
            cli.main([cmd, "--help"])
        assert exc.value.code == 0 and "--quiet" in buf.getvalue(), cmd
