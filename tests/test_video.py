"""Offscreen video of a walk (afo_mj.outputs.video; loading and simulating: afo_mj.app.render):
frames not blank, MP4 decodes to the expected frames and size with the torque overlay, argument
errors named and no file left."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest

os.environ.setdefault("MUJOCO_GL", "egl")

from afo_mj.app.errors import InvalidInput  # noqa: E402
from afo_mj.app.render import render  # noqa: E402
from afo_mj.outputs import video  # noqa: E402
from afo_mj.outputs.video import RenderError, render_frames, render_record  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
HEALTHY = ROOT / "scenarios" / "walk_healthy.toml"
ASSIST = ROOT / "scenarios" / "gait_assist_hafo.toml"
BENCH = ROOT / "scenarios" / "bench_hafo.toml"
SHORT = ("gait.strides=1", "gait.analyse_strides=[1, 1]")


@pytest.fixture(scope="module")
def gl():
    """Skip when no offscreen OpenGL context can be created here."""
    import mujoco
    model = mujoco.MjModel.from_xml_string(
        "<mujoco><worldbody><geom type='sphere' size='0.1'/></worldbody></mujoco>")
    try:
        r = mujoco.Renderer(model, 16, 16)
    except Exception as exc:  # noqa: BLE001
        pytest.skip(f"no offscreen OpenGL context (MUJOCO_GL="
                    f"{os.environ.get('MUJOCO_GL')}): {exc}")
    r.close()
    return True


@pytest.fixture(scope="module")
def healthy_record():
    from afo_mj.gait.walk import simulate_walk
    from afo_mj.scenarios.walk_scenario import load_scenario
    return simulate_walk(load_scenario(HEALTHY, overrides=SHORT))


@pytest.fixture(scope="module")
def assist_record():
    from afo_mj.gait.walk import run_walk
    from afo_mj.experiments.device_walk import make_device
    from afo_mj.scenarios.device_scenario import device_config
    from afo_mj.scenarios.walk_scenario import load_scenario
    s = load_scenario(ASSIST, overrides=SHORT)
    cfg = device_config(s)
    ref = s.load_reference()
    T = s.cycle_time_s(ref)
    dt = s.walker.timestep_s
    dev = make_device(cfg, "assist", dt, int(((s.strides + 1.5) * T + 1.0) / dt) + 4)
    return run_walk(s.walker, ref, T, s.strides, s.controller_params(),
                    worn_masses=dev.worn_masses(), device=dev)


def _orange_in_strip(frame: np.ndarray) -> int:
    """Pixels of the orthosis-torque colour in the bottom strip."""
    h = frame.shape[0]
    strip = frame[h - int(round(video.STRIP_FRACTION * h)):].astype(int)
    r, g, b = strip[..., 0], strip[..., 1], strip[..., 2]
    return int(np.sum((np.abs(r - 245) < 30) & (np.abs(g - 130) < 30) & (b < 80)))


def test_frames_show_the_walker(gl, healthy_record):
    rec = healthy_record
    t = [rec.time_s[0] + 0.2, rec.time_s[0] + 0.7]
    frames = render_frames(rec, t, 160, 120)
    assert frames.shape == (2, 120, 160, 3) and frames.dtype == np.uint8
    scene = frames[:, : int(120 * (1 - video.STRIP_FRACTION))].astype(float)
    assert scene.std() > 20.0                           # not blank
    for f in scene:                                     # body + floor differ from the sky
        flat = f.reshape(-1, 3)
        colours, counts = np.unique(flat.astype(np.uint8), axis=0, return_counts=True)
        assert 1.0 - counts.max() / len(flat) > 0.3
        # the body (skin / shirt colours) occupies a decent patch of the picture
        skin = (flat[:, 0] > flat[:, 2] + 40) | (flat[:, 2] > flat[:, 0] + 60)
        assert skin.mean() > 0.01
    assert np.abs(scene[0] - scene[1]).mean() > 2.0     # it moves


def test_mp4_decodes_with_torque_overlay(gl, tmp_path, assist_record, healthy_record):
    import av
    out = tmp_path / "walk.mp4"
    calls = []
    facts = render(ASSIST, out, overrides=SHORT, condition="assist", fps=10,
                   width=160, height=120, max_seconds=1.0,
                   progress=lambda k, n: calls.append((k, n)))
    assert facts["frames"] == 11 and facts["fps"] == 10 and facts["condition"] == "assist"
    assert (facts["width"], facts["height"]) == (160, 120)
    assert facts["duration_s"] == pytest.approx(1.1)
    assert calls[-1] == (11, 11) and len(calls) == 11
    assert out.stat().st_size > 1000
    assert [p.name for p in tmp_path.iterdir()] == ["walk.mp4"]      # no temp file left
    with av.open(str(out)) as c:
        frames = [f.to_ndarray(format="rgb24") for f in c.decode(video=0)]
    assert len(frames) == 11 and frames[0].shape == (120, 160, 3)
    assert facts["codec"] in ("h264", "mpeg4")

    # the strip shows the orthosis torque when it is non-zero, and nothing orange without it
    rec = assist_record
    k = int(np.argmax(np.abs(rec.device_moment_nm[:, 0])))
    assert abs(rec.device_moment_nm[k, 0]) > 10.0
    f_dev = render_frames(rec, [rec.time_s[k]], 320, 240)[0]
    f_none = render_frames(healthy_record, [rec.time_s[k]], 320, 240)[0]
    assert _orange_in_strip(f_dev) > 30
    assert _orange_in_strip(f_none) < 5


@pytest.mark.parametrize("kwargs, key", [
    ({"scenario_path": ASSIST, "condition": "boost"}, "condition"),
    ({"scenario_path": HEALTHY, "condition": "assist"}, "condition"),
    ({"scenario_path": HEALTHY, "fps": 0}, "fps"),
    ({"scenario_path": HEALTHY, "fps": 500}, "fps"),
    ({"scenario_path": HEALTHY, "width": 8}, "width"),
    ({"scenario_path": HEALTHY, "height": 121}, "height"),
    ({"scenario_path": BENCH}, "bench"),
])
def test_errors_named_and_nothing_written(tmp_path, kwargs, key):
    out = tmp_path / "x.mp4"
    with pytest.raises(RenderError) as err:
        render(mp4_path=out, overrides=SHORT, **kwargs)
    assert isinstance(err.value, InvalidInput) and err.value.exit_code == 2
    msg = str(err.value)
    assert key in msg and "allowed" in msg
    if key == "condition" and kwargs["scenario_path"] == ASSIST:
        assert "no_device | transparent | assist" in msg
    assert list(tmp_path.iterdir()) == []


def test_failed_encode_leaves_no_file(gl, tmp_path, healthy_record):
    out = tmp_path / "walk.mp4"

    def boom(k, n):
        if k == 2:
            raise KeyboardInterrupt("stop")

    with pytest.raises(KeyboardInterrupt):
        render_record(healthy_record, out, fps=10, width=64, height=48, progress=boom)
    assert list(tmp_path.iterdir()) == []
    with pytest.raises(RenderError, match="mp4 path"):
        render_record(healthy_record, tmp_path / "walk.avi", fps=10, width=64, height=48)


def test_render_reports_frames_done_on_stderr(gl, tmp_path, healthy_record):
    """With a reporter installed (``afo-mj render`` without --quiet): a stage line, frames
    done / total and a closing line; nothing without one (the library default)."""
    import io

    from afo_mj import progress
    clock = iter(range(0, 10_000, 2))            # 2 s per reading: every update may print
    buf = io.StringIO()
    rep = progress.Reporter(stream=buf, tty=False, clock=lambda: float(next(clock)),
                            plain_interval_s=0.0)
    with progress.using(rep):
        info = render_record(healthy_record, tmp_path / "w.mp4", fps=10, width=64, height=48,
                             max_seconds=0.8)
    lines = buf.getvalue().splitlines()
    n = info["frames"]
    assert lines[0] == f"[afo-mj] rendering {n} frames to {tmp_path / 'w.mp4'}…"
    assert any(f"/{n} frames (" in ln and "left" in ln for ln in lines[1:-1]), lines
    assert lines[-1].startswith(f"[afo-mj] rendering {n} frames to") and "done in" in lines[-1]
    quiet = io.StringIO()
    with progress.using(progress.Reporter(stream=quiet, quiet=True)):
        render_record(healthy_record, tmp_path / "q.mp4", fps=10, width=64, height=48,
                      max_seconds=0.4)
    assert quiet.getvalue() == ""
