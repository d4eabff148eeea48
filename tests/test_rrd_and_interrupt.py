"""``afo-mj run/compare --rrd`` checked before anything is simulated, written with the results
(again and again into the same ``--out``), and Ctrl-C in ``run``/``render``: one line, exit
130, nothing written (issue 38 item 5)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from afo_mj import cli
from afo_mj.outputs.recording import RecordingError, read_recording_index
from afo_mj.outputs.result_dir import MANIFEST

ROOT = Path(__file__).resolve().parents[1]
HEALTHY = ROOT / "scenarios" / "walk_healthy.toml"
HAFO = ROOT / "scenarios" / "gait_assist_hafo.toml"
DIGITAL = ROOT / "scenarios" / "gait_assist_digital.toml"
#: the shortest walk that still has an analysed stride
SHORT = ["--set", "gait.strides=2", "--set", "gait.analyse_strides=[1, 2]"]


def _tree(root: Path) -> list[str]:
    """Every path under ``root`` (hidden ones included), relative, sorted."""
    return sorted(str(p.relative_to(root)) for p in root.rglob("*"))


def _messages(err: str) -> list[str]:
    """stderr's lines less the progress lines (``[afo-mj] ...``)."""
    return [ln for ln in err.splitlines() if not ln.startswith("[afo-mj]")]


def _main(argv) -> int:
    """``cli.main``; a KeyboardInterrupt escaping it fails the test (instead of stopping
    pytest)."""
    try:
        return cli.main(argv)
    except KeyboardInterrupt:
        pytest.fail("KeyboardInterrupt escaped afo-mj (a traceback for the user)")


@pytest.fixture
def no_simulation(monkeypatch):
    """Any simulation (a run's scenario, a comparison) fails the test."""
    def never(*args, **kwargs):
        raise AssertionError("simulated before --rrd was checked")
    monkeypatch.setattr("afo_mj.app.run.run_scenario", never)
    monkeypatch.setattr("afo_mj.gait.walkers.walk_scenario", never)
    monkeypatch.setattr("afo_mj.experiments.device_comparison.run_comparison", never)


def _bad_rrd(tmp_path: Path, kind: str) -> str:
    if kind == "directory":
        (tmp_path / "a_dir.rrd").mkdir()
        return str(tmp_path / "a_dir.rrd")
    if kind == "suffix":
        return str(tmp_path / "walk.txt")
    if kind == "not_a_recording":
        (tmp_path / "notes.rrd").write_text("my notes, not a recording\n")
        return str(tmp_path / "notes.rrd")
    if kind == "is_out":
        return str(tmp_path / "out.rrd")              # --out below is this very path
    if kind == "under_a_file":
        (tmp_path / "plain").write_text("x")
        return str(tmp_path / "plain" / "walk.rrd")
    raise AssertionError(kind)


KINDS = ["directory", "suffix", "not_a_recording", "is_out", "under_a_file"]


@pytest.mark.parametrize("command", ["run", "compare"])
@pytest.mark.parametrize("kind", KINDS)
def test_bad_rrd_exits_2_before_any_simulation(tmp_path, no_simulation, capsys, command,
                                               kind):
    rrd = _bad_rrd(tmp_path, kind)
    out = tmp_path / ("out.rrd" if kind == "is_out" else "out")
    before = _tree(tmp_path)
    scenarios = [str(HEALTHY)] if command == "run" else [str(HAFO), str(DIGITAL)]
    rc = _main([command, *scenarios, "--out", str(out), "--rrd", rrd, "--strides", "2"])
    err = capsys.readouterr().err
    assert rc == 2, err
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith(f"afo-mj {command}: --rrd {rrd!r}")
    assert "allowed:" in lines[0] and "nothing written" in lines[0]
    assert _tree(tmp_path) == before                   # nothing written, --out not made


def test_same_run_with_recording_inside_out_twice(tmp_path, capsys):
    """The recording inside --out is one of the results (listed in the manifest), so the
    identical command runs again; nothing is left beside the results."""
    out = tmp_path / "D"
    rrd = out / "walk.rrd"
    args = ["run", str(HEALTHY), "--out", str(out), "--rrd", str(rrd), *SHORT]
    for _ in range(2):
        rc = _main(args)
        cap = capsys.readouterr()
        assert rc == 0, cap.err
        assert f"results: {out}\n" in cap.out and f"recording: {rrd} (" in cap.out
        assert ".stage-" not in cap.out + cap.err and ".tmp-" not in cap.out + cap.err
    assert _tree(tmp_path) == ["D", *(f"D/{n}" for n in sorted(
        [MANIFEST, "walk.rrd", "summary.json", "scenario.toml", "run_info.json", "cycles.csv",
         "gait_curves.csv", "gait_curves.png"]))]
    assert "walk.rrd" in json.loads((out / MANIFEST).read_text())["files"]
    idx = read_recording_index(rrd)
    assert idx["signals/angle_deg/knee/right/walk"]["rows"] > 100
    assert "world/walk/body/pelvis" in idx
    # nothing written holds the staging directory's path (the results were moved)
    for p in out.iterdir():
        if p.suffix in (".json", ".toml", ".csv"):
            text = p.read_text()
            assert ".stage-" not in text and ".tmp-" not in text, p


@pytest.fixture
def synthetic_walk(monkeypatch):
    """The walk replaced by a synthetic record (no physics): fast."""
    from gait_fixtures import WinterSplines, synthetic_record
    rec = synthetic_record(splines=WinterSplines())
    monkeypatch.setattr("afo_mj.gait.walkers.walk_scenario",
                        lambda scenario, *a, **k: (rec, None))
    return rec


@pytest.mark.parametrize("where", ["inside", "outside"])
def test_failed_recording_leaves_no_results(tmp_path, synthetic_walk, monkeypatch, capsys,
                                            where):
    def fail(*args, **kwargs):
        raise RecordingError("recording path: disk full (test)")
    monkeypatch.setattr("afo_mj.app.run.write_rrd", fail)
    out = tmp_path / "runs" / "D"
    rrd = out / "walk.rrd" if where == "inside" else tmp_path / "recs" / "walk.rrd"
    rc = _main(["run", str(HEALTHY), "--out", str(out), "--rrd", str(rrd)])
    err = capsys.readouterr().err
    assert rc == 1 and "disk full (test)" in err and "nothing written" in err, err
    assert _tree(tmp_path) == []           # no results, no staging, no folders made


def test_ctrl_c_in_run_one_line_exit_130(tmp_path, monkeypatch, capsys):
    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt
    monkeypatch.setattr("afo_mj.app.run.run_scenario", interrupted)
    rc = _main(["run", str(HEALTHY), "--out", str(tmp_path / "D")])
    cap = capsys.readouterr()
    assert rc == 130
    assert cap.err == "afo-mj run: interrupted (SIGINT); nothing written\n"
    assert _tree(tmp_path) == []


@pytest.mark.parametrize("where", ["simulation", "recording"])
def test_ctrl_c_in_run_with_rrd_writes_nothing(tmp_path, synthetic_walk, monkeypatch, capsys,
                                               where):
    """Interrupted while simulating or while recording (the results already staged): the
    staging directory and the folders made for --out are gone."""
    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt
    monkeypatch.setattr("afo_mj.gait.walkers.walk_scenario" if where == "simulation"
                        else "afo_mj.app.run.write_rrd", interrupted)
    out = tmp_path / "runs" / "D"
    rc = _main(["run", str(HEALTHY), "--out", str(out), "--rrd", str(out / "walk.rrd")])
    assert rc == 130
    err = capsys.readouterr().err
    assert _messages(err) == ["afo-mj run: interrupted (SIGINT); nothing written"], err
    assert ".stage-" not in err and ".tmp-" not in err     # progress names --out itself
    assert _tree(tmp_path) == []


def test_ctrl_c_in_render_one_line_exit_130(tmp_path, monkeypatch, capsys):
    def interrupted(self, *args, **kwargs):
        raise KeyboardInterrupt
    monkeypatch.setattr("afo_mj.gait.walk.Walk.run", interrupted)
    mp4 = tmp_path / "walk.mp4"
    rc = _main(["render", str(HEALTHY), "--mp4", str(mp4), *SHORT])
    assert rc == 130
    assert capsys.readouterr().err == "afo-mj render: interrupted (SIGINT); nothing written\n"
    assert _tree(tmp_path) == []


def test_ctrl_c_while_encoding_leaves_no_partial_mp4(tmp_path, monkeypatch, capsys):
    """Interrupted after some frames are in the file: the partial .mp4 is removed."""
    pytest.importorskip("av")
    from afo_mj.outputs import video
    encode = video.render_record
    seen = []

    def stop_at_frame_2(k, n):
        seen.append(k)
        if k == 2:
            raise KeyboardInterrupt

    def render_record(*args, **kwargs):
        return encode(*args, **{**kwargs, "progress": stop_at_frame_2})
    monkeypatch.setattr(video, "render_record", render_record)
    rc = _main(["render", str(HEALTHY), "--mp4", str(tmp_path / "sub" / "walk.mp4"),
                "--set", "gait.strides=1", "--set", "gait.analyse_strides=[1, 1]",
                "--max-seconds", "0.5", "--width", "64", "--height", "48", "--fps", "10"])
    err = capsys.readouterr().err
    if rc == 1 and "GL" in err:
        pytest.skip("no offscreen GL context")
    assert rc == 130 and seen == [1, 2], err
    assert err.endswith("afo-mj render: interrupted (SIGINT); nothing written\n")
    assert "Traceback" not in err
    assert not list(tmp_path.rglob("*.mp4"))


def _fake_recording(file: Path) -> dict:
    """A stand-in for a rerun writer: a file with a recording's first bytes."""
    Path(file).write_bytes(b"RRF2 test recording")
    return {"path": str(file), "entities": {"a": {}}}


def _write_results(path: Path) -> Path:
    from afo_mj.outputs.result_dir import write_atomically
    return write_atomically(path, lambda tmp: (tmp / "summary.json").write_text("{}\n"))


@pytest.mark.parametrize("inside", [True, False])
def test_results_with_recording_twice_and_listed(tmp_path, inside):
    """What ``afo-mj compare --rrd`` writes with (its results writer takes no more files)."""
    from afo_mj.outputs.recording import write_results_with_recording
    out = tmp_path / "cmp"
    rrd = out / "sub" / "all.rrd" if inside else tmp_path / "elsewhere" / "all.rrd"
    for _ in range(2):
        info = write_results_with_recording(out, rrd, _write_results, _fake_recording)
        assert info == {"path": str(rrd), "entities": {"a": {}}}
    files = json.loads((out / MANIFEST).read_text())["files"]
    assert files == (["sub", "summary.json"] if inside else ["summary.json"])
    assert rrd.read_bytes() == b"RRF2 test recording"
    expected = ["cmp", "cmp/.afo_mj_files.json", "cmp/summary.json"]
    expected += (["cmp/sub", "cmp/sub/all.rrd"] if inside
                 else ["elsewhere", "elsewhere/all.rrd"])
    assert _tree(tmp_path) == sorted(expected)        # no staging or temporary files left


@pytest.mark.parametrize("inside", [True, False])
@pytest.mark.parametrize("error", [RecordingError, KeyboardInterrupt])
def test_results_with_recording_failure_leaves_nothing(tmp_path, inside, error):
    from afo_mj.outputs.recording import write_results_with_recording
    out = tmp_path / "a" / "cmp"
    rrd = out / "all.rrd" if inside else tmp_path / "b" / "all.rrd"

    def fail(file):
        Path(file).write_bytes(b"RRF2 half")
        raise error("test")
    with pytest.raises(error):
        write_results_with_recording(out, rrd, _write_results, fail)
    assert _tree(tmp_path) == []


def test_no_recording_leaves_no_folder_for_it(tmp_path):
    """A run with nothing to record (a circuit bench): the results, and no empty folder made
    for the recording."""
    from afo_mj.outputs.recording import write_results_with_recording
    out = tmp_path / "res"
    for rrd in (tmp_path / "new" / "b.rrd", out / "sub" / "deeper" / "b.rrd"):
        assert write_results_with_recording(out, rrd, _write_results, lambda f: None) is None
        assert _tree(tmp_path) == ["res", "res/.afo_mj_files.json", "res/summary.json"]
