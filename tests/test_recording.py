"""Rerun recordings: a short run is recorded, read back with rerun's own reader
(``rerun.chunk.RrdReader``) and checked for the entity paths the README documents, their
sample counts and units, and values equal to the simulation's own arrays."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

rr = pytest.importorskip("rerun")

from afo_mj.cli import main  # noqa: E402
from afo_mj.outputs.recording import (SIGNAL_TOLERANCE, RecordedRun,  # noqa: E402
                                      RecordingError, read_recording_index, write_recording)
from afo_mj.scenarios.walk_scenario import ScenarioError, load_scenario  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
SHORT = ("gait.strides=3", "gait.analyse_strides=[2, 3]")


def _scalars(path: Path, entity: str) -> tuple[np.ndarray, np.ndarray]:
    """(time_s, values) of one Scalars entity, read with rerun's reader."""
    store = rr.chunk.RrdReader(str(path)).stream().collect()
    ts, vs = [], []
    for ch in store.stream():
        if ch.entity_path.lstrip("/") != entity or ch.is_static:
            continue
        rb = ch.to_record_batch()
        t = rb.column("time").to_numpy()
        ts.append(t.astype("timedelta64[ns]").astype(np.int64) / 1e9 if t.dtype.kind == "m"
                  else np.asarray(t, dtype=float))
        vs.append(np.array([x[0] for x in rb.column("Scalars:scalars").to_pylist()]))
    order = np.argsort(np.concatenate(ts))
    return np.concatenate(ts)[order], np.concatenate(vs)[order]


@pytest.fixture(scope="module")
def walk_recording(tmp_path_factory):
    from afo_mj.gait.walk import simulate_walk
    sc = load_scenario(ROOT / "scenarios" / "walk_healthy.toml", overrides=SHORT)
    rec = simulate_walk(sc)
    path = tmp_path_factory.mktemp("rec") / "walk.rrd"
    info = write_recording(path, [RecordedRun("walk", rec)], sc.load_reference(),
                           title=sc.name, signal_rate_hz=250.0, transform_rate_hz=40.0)
    return rec, path, info, read_recording_index(path)


def test_walk_recording_paths_counts_units(walk_recording):
    rec, path, info, idx = walk_recording
    n = len(rec.time_s)
    dt = rec.sample_period_s
    n_sig = math.ceil(n / round(1 / (250.0 * dt)))
    n_tf = math.ceil(n / round(1 / (40.0 * dt)))
    assert info["path"] == str(path) and path.stat().st_size > 10_000
    # 3D: floor, every body's transform, its geoms as primitives, force arrows
    assert any(c.startswith("Boxes3D") for c in idx["world/floor"]["components"])
    for body in ("pelvis", "thigh_r", "shank_r", "foot_r", "thigh_l", "shank_l", "foot_l"):
        e = idx[f"world/walk/body/{body}"]
        assert e["rows"] == n_tf
        assert "Transform3D:translation" in e["components"]
        assert "Transform3D:quaternion" in e["components"]
    assert any(c.startswith("Capsules3D")
               for c in idx["world/walk/body/shank_r/shank_r"]["components"])
    assert any(c.startswith("Ellipsoids3D")
               for c in idx["world/walk/body/foot_r/heel_r"]["components"])
    for side in ("right", "left"):
        assert idx[f"world/walk/grf/{side}"]["rows"] == n_tf
        assert "Arrows3D:vectors" in idx[f"world/walk/grf/{side}"]["components"]
    # signals, with their units
    expected_units = {"angle_deg/ankle/right/walk": "deg", "angle_deg/hip/left/walk": "deg",
                      "moment_nm/knee/right/walk": "N*m", "joint_power_w/ankle/right/walk": "W",
                      "grf_n/vertical/right/walk": "N", "gait_phase/right/walk": "1",
                      "ankle_torque_nm/human/right/walk": "N*m"}
    for p, unit in expected_units.items():
        e = idx[f"signals/{p}"]
        # sampled at the signal rate, then thinned to the samples a plot needs
        assert info["entities"][f"signals/{p}"]["samples"] == n_sig, p
        assert 2 <= e["rows"] <= n_sig, p
        assert e["unit"] == unit, p
    # the normative band is mapped onto the measured strides only (fewer samples)
    band = idx["signals/angle_deg/ankle/normative/mean"]
    assert 0 < band["rows"] < n_sig and band["unit"] == "deg"
    # gait events as a text log: one row per heel strike, toe off, scuff and fall
    ev = rec.events
    n_ev = (sum(len(x) for x in ev.heel_strikes_s) + sum(len(x) for x in ev.toe_offs_s)
            + len(ev.swing_toe_contacts) + (ev.fall_time_s is not None))
    assert idx["events/walk"]["rows"] == n_ev
    # a blueprint travels with the file
    assert rr.chunk.RrdReader(str(path)).blueprints()


def check_thinned(t, v, t_full, v_full, rel_tol=SIGNAL_TOLERANCE):
    """A thinned signal read back from a recording against the full one: its samples are
    samples of the full signal (same times, same values), the first and last among them, and
    straight lines between them pass within ``rel_tol`` × the signal's range of every
    sample left out."""
    k = np.searchsorted(t_full, t - 1e-9)
    np.testing.assert_allclose(t, t_full[k], atol=1e-9)
    np.testing.assert_allclose(v, v_full[k], rtol=1e-12, atol=1e-12)
    assert k[0] == 0 and k[-1] == len(t_full) - 1
    err = np.abs(np.interp(t_full, t, v) - v_full).max()
    assert err <= rel_tol * np.ptp(v_full) * (1 + 1e-9) + 1e-12


def test_walk_recording_values_equal_the_record(walk_recording):
    rec, path, info, _idx = walk_recording
    t, v = _scalars(path, "signals/angle_deg/ankle/right/walk")
    step = round(1 / (250.0 * rec.sample_period_s))
    check_thinned(t, v, rec.time_s[::step], np.degrees(rec.joint_angle_rad[::step, 0, 2]))
    # a smooth joint angle needs a small share of its samples (measured: about 1 in 8)
    assert len(t) < 0.3 * len(rec.time_s[::step])


@pytest.fixture(scope="module")
def device_recording(tmp_path_factory):
    out = tmp_path_factory.mktemp("dev")
    rrd = out / "hafo.rrd"
    # what ``afo-mj run ... --rrd FILE`` does (the application layer), without the figures
    from afo_mj.app.run import record_run, run_scenario
    res = run_scenario(ROOT / "scenarios" / "gait_assist_hafo.toml", overrides=SHORT,
                       out_dir=out / "res", figures=False)
    info = record_run(res, rrd)
    assert info["path"] == str(rrd)
    return out, rrd, read_recording_index(rrd), info, res


def test_device_recording_has_orthosis_and_chain(device_recording):
    out, rrd, idx, info, _res = device_recording
    # every condition walks in its own lane
    for cond in ("no_device", "transparent", "assist"):
        assert f"world/{cond}/body/pelvis" in idx
        assert f"signals/angle_deg/ankle/right/{cond}" in idx
        assert f"events/{cond}" in idx
    for cond in ("transparent", "assist"):
        n = info["entities"][f"signals/ankle_torque_nm/device_delivered/right/{cond}"][
            "samples"]
        assert n > 100
        units = {"ankle_torque_nm/device_commanded": "N*m", "pressure_bar/line_a": "bar (gauge)",
                 "pressure_bar/chamber_b": "bar (gauge)", "flow_l_min/pump": "L/min",
                 "flow_l_min/cylinder": "L/min", "motor_current_a": "A",
                 "motor_speed_rpm": "rpm", "fluid_temperature_c": "degC",
                 "device_power_w/electrical": "W", "device_power_w/hydraulic": "W",
                 "device_power_w/ankle": "W", "running_efficiency": "1",
                 "piston_position_mm": "mm"}
        for p, unit in units.items():
            e = idx[f"signals/{p}/right/{cond}"]
            assert info["entities"][f"signals/{p}/right/{cond}"]["samples"] == n, p
            assert 2 <= e["rows"] <= n and e["unit"] == unit, p
        for c in ("a", "b"):
            oil = idx[f"world/{cond}/body/shank_r/afo/oil_{c}"]
            assert oil["rows"] > 10 and "Cylinders3D:colors" in oil["components"]
            assert f"world/{cond}/body/shank_r/afo/barrel_{c}" in idx
    assert "signals/pressure_bar/line_a/right/no_device" not in idx
    # pressures in the file are the device's own (gauge, bar) at the recorded times
    import csv
    with open(out / "res" / "device_timeseries.csv") as f:
        rows = list(csv.DictReader(f))
    t_csv = np.array([float(r["time_s"]) for r in rows])
    p_csv = np.array([float(r["chamber_a_pa"]) for r in rows]) / 1e5
    t, v = _scalars(rrd, "signals/pressure_bar/chamber_a/right/assist")
    np.testing.assert_allclose(v, np.interp(t, t_csv, p_csv), rtol=1e-6, atol=1e-4)  # csv digits
    # the running efficiency ends at the run's chain figure: positive ankle work / electrical
    _, eta = _scalars(rrd, "signals/running_efficiency/right/assist")
    e_pos = np.array([max(float(r["mechanical_power_w"]), 0.0) for r in rows])
    p_el = np.array([max(float(r["bus_voltage_v"]) * float(r["battery_current_a"]), 0.0)
                     for r in rows])
    dt = np.diff(t_csv, prepend=t_csv[0])
    assert eta[-1] == pytest.approx((e_pos * dt).sum() / (p_el * dt).sum(), rel=2e-2)


def test_valve_recording_has_valve_signals(tmp_path):
    rrd = tmp_path / "valve.rrd"
    args = ["run", str(ROOT / "scenarios" / "gait_assist_valve.toml"), "--out",
            str(tmp_path / "res"), "--rrd", str(rrd), "--set",
            'device.conditions=["assist"]']
    for s in SHORT:
        args += ["--set", s]
    rc = main(args)
    assert rc == 0, "the valve scenario with device.conditions must run"
    assert rc == 0
    idx = read_recording_index(rrd)
    for p in ("valve/position", "valve/command", "valve/unloading", "pressure_bar/pump",
              "pressure_bar/supply"):
        assert idx[f"signals/{p}/right/assist"]["rows"] > 100, p


def test_scenario_output_record_writes_into_results(tmp_path):
    out = tmp_path / "res"
    args = ["run", str(ROOT / "scenarios" / "walk_healthy.toml"), "--out", str(out),
            "--set", "output.record=true", "--set", "output.signal_rate_hz=100",
            "--set", "gait.strides=2", "--set", "gait.analyse_strides=[1, 2]"]
    assert main(args) == 0
    idx = read_recording_index(out / "recording.rrd")
    n = len(idx)
    assert n > 30 and "signals/angle_deg/knee/right/walk" in idx
    assert not list(out.glob(".*tmp"))


def test_recording_errors_leave_nothing(tmp_path, walk_recording):
    rec = walk_recording[0]
    with pytest.raises(RecordingError, match="signal_rate_hz"):
        write_recording(tmp_path / "a.rrd", [RecordedRun("walk", rec)], signal_rate_hz=0.0)
    with pytest.raises(RecordingError, match=r"\.rrd"):
        write_recording(tmp_path / "a.txt", [RecordedRun("walk", rec)])
    with pytest.raises(RecordingError, match="unique"):
        write_recording(tmp_path / "a.rrd", [RecordedRun("w", rec), RecordedRun("w", rec)])
    import dataclasses
    bad = dataclasses.replace(rec, joint_angle_rad=rec.joint_angle_rad.copy())
    bad.joint_angle_rad[4:40, 0, 2] = np.nan
    with pytest.raises(RecordingError, match="non-finite"):
        write_recording(tmp_path / "b.rrd", [RecordedRun("walk", bad)])
    assert list(tmp_path.iterdir()) == []
    with pytest.raises(ScenarioError, match="output.record"):
        load_scenario(ROOT / "scenarios" / "walk_healthy.toml", overrides=["output.record=1"])
    with pytest.raises(ScenarioError, match="output.colour"):
        load_scenario(ROOT / "scenarios" / "walk_healthy.toml", overrides=["output.colour=1"])


def test_view_command(tmp_path, walk_recording, capsys):
    path = walk_recording[1]
    assert main(["view", str(path), "--print-command"]) == 0
    cmd = capsys.readouterr().out.strip().split()
    assert cmd[-1] == str(path) and Path(cmd[0]).name == "rerun" and Path(cmd[0]).exists()
    assert main(["view", str(tmp_path / "missing.rrd")]) == 2
    assert "not an existing .rrd" in capsys.readouterr().err


def test_view_without_display_offers_the_web_viewer(tmp_path, monkeypatch, capsys):
    """Issue 19 item 14: with no display, ``afo-mj view`` opens nothing and exits 2 with the
    web viewer (``--web``: ``rerun --serve-web``) and the copy-to-a-display command."""
    import sys

    import afo_mj.app.viewer as viewer
    rrd = tmp_path / "walk.rrd"
    rrd.write_bytes(b"not opened")            # nothing may read it: the viewer is mocked
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    monkeypatch.setattr(sys, "platform", "linux")
    calls = []
    monkeypatch.setattr(viewer, "run_viewer", lambda cmd, *a, **k: calls.append(cmd) or 0)
    assert main(["view", str(rrd)]) == 2
    err = capsys.readouterr().err
    assert calls == [], "a window was opened"
    assert "no display" in err and "DISPLAY" in err
    assert f"afo-mj view {rrd.resolve()} --web" in err and "rerun --serve-web" in err
    assert "http://localhost:9090" in err and "scp " in err and str(rrd.resolve()) in err
    # --web serves the web viewer instead of a window
    assert main(["view", str(rrd), "--web"]) == 0
    assert len(calls) == 1 and calls[0][1:] == ["--serve-web", str(rrd)]
    assert Path(calls[0][0]).name == "rerun"
    # with a display the native viewer opens as before
    monkeypatch.setenv("DISPLAY", ":0")
    assert main(["view", str(rrd)]) == 0 and calls[-1][1:] == [str(rrd)]


def test_bench_recording_lays_experiments_end_to_end(tmp_path):
    from afo_mj.outputs.recording import BENCH_GAP_S, write_bench_recording
    t1 = np.arange(0.0, 0.5, 1e-3)
    t2 = np.arange(0.0, 0.2, 1e-3)
    series = {"isometric_step_20nm": {"time_s": t1, "command_nm": -20.0 + 0 * t1,
                                      "torque_nm": -20.0 * (1 - np.exp(-t1 / 0.03))},
              "sweeps": {"k1": {"time_s": t2, "angle_rad": np.sin(t2), "chamber_a_pa": 1e6 + t2,
                                "log_time_s": t2}},
              "frequency_response_torque": {"freq_hz": np.array([1.0, 2.0]),
                                            "gain": np.array([1.0, 0.5])}}
    info = write_bench_recording(tmp_path / "b.rrd", series, title="bench")
    idx = read_recording_index(tmp_path / "b.rrd")
    assert idx["bench/isometric_step_20nm/torque_nm"]["rows"] == len(t1)
    assert idx["bench/isometric_step_20nm/torque_nm"]["unit"] == "N*m"
    assert idx["bench/sweeps/k1/angle_rad"]["unit"] == "rad"
    assert idx["bench/sweeps/k1/chamber_a_pa"]["unit"] == "Pa"
    assert "bench/sweeps/k1/log_time_s" not in idx
    assert not any(k.startswith("bench/frequency_response") for k in idx)
    assert idx["bench/experiments"]["rows"] == 2
    t, v = _scalars(tmp_path / "b.rrd", "bench/sweeps/k1/angle_rad")
    assert t[0] == pytest.approx(t1[-1] - t1[0] + BENCH_GAP_S)
    np.testing.assert_allclose(v, np.sin(t2))
    assert info["path"] == str(tmp_path / "b.rrd")
    with pytest.raises(RecordingError, match="time-domain"):
        write_bench_recording(tmp_path / "c.rrd", {"x": {"freq_hz": [1.0]}})
    assert not (tmp_path / "c.rrd").exists()


def test_compare_recording_puts_devices_side_by_side(tmp_path):
    rrd = tmp_path / "cmp.rrd"
    rc = main(["compare", str(ROOT / "scenarios" / "gait_assist_hafo.toml"),
               str(ROOT / "scenarios" / "gait_assist_digital.toml"), "--strides", "3",
               "--out", str(tmp_path / "cmp"), "--rrd", str(rrd)])
    assert rc == 0
    idx = read_recording_index(rrd)
    for run in ("gait_assist_hafo", "gait_assist_digital"):
        assert f"world/{run}/body/pelvis" in idx
        assert idx[f"signals/ankle_torque_nm/device_delivered/right/{run}"]["rows"] > 100
    assert idx["signals/valve/command/right/gait_assist_digital"]["unit"] == "1"


def test_render_command(tmp_path, capsys):
    pytest.importorskip("av")
    mp4 = tmp_path / "walk.mp4"
    rc = main(["render", str(ROOT / "scenarios" / "walk_healthy.toml"), "--mp4", str(mp4),
               "--set", "gait.strides=1", "--set", "gait.analyse_strides=[1, 1]",
               "--max-seconds", "0.3", "--width", "64", "--height", "48", "--fps", "10"])
    if rc == 2 and "GL" in capsys.readouterr().err:
        pytest.skip("no offscreen GL context")
    assert rc == 0 and mp4.stat().st_size > 0
    assert main(["render", str(ROOT / "scenarios" / "walk_healthy.toml"), "--mp4",
                 str(tmp_path / "x.mp4"), "--fps", "0"]) == 2
    assert "fps" in capsys.readouterr().err and not (tmp_path / "x.mp4").exists()


# -- a recording that shows the walk at a glance (issue 43 item 3) -----------------------------
def test_thinning_keeps_the_corners_of_a_polyline_and_bounds_the_rest():
    """The swing-door thinning against two references of its own: a polyline sampled densely
    needs exactly its corners (and its ends) at a tolerance below its features; a random
    walk, compared sample by sample with straight lines between the kept samples, is within
    the tolerance everywhere (and a tolerance of 0 keeps every sample)."""
    from afo_mj.outputs.series_thinning import thin_indices
    t = np.arange(0.0, 3.0 + 1e-9, 2e-3)
    corners_t = np.array([0.0, 0.5, 1.2, 2.0, 3.0])
    corners_v = np.array([0.0, 4.0, -1.0, -1.0, 2.5])
    v = np.interp(t, corners_t, corners_v)
    keep = thin_indices(t, v, 1e-6)
    np.testing.assert_allclose(t[keep], corners_t, atol=1e-12)
    rng = np.random.default_rng(7)
    walk = np.cumsum(rng.normal(size=4000))
    tt = np.arange(4000) * 1e-3
    for tol in (0.05, 0.5, 3.0):
        k = thin_indices(tt, walk, tol)
        assert k[0] == 0 and k[-1] == 3999
        assert np.abs(np.interp(tt, tt[k], walk[k]) - walk).max() <= tol * (1 + 1e-12)
    assert len(thin_indices(tt, walk, 3.0)) < len(thin_indices(tt, walk, 0.05)) < 4000
    assert len(thin_indices(tt, walk, 0.0)) == 4000
    with pytest.raises(ValueError, match="tol"):
        thin_indices(tt, walk, -1.0)


def _blueprint_views(rrd: Path) -> dict:
    """The views of the blueprint a recording carries, read back from the file:
    ``{view id: {"class", "origin", "legend_visible", "eye"}}``."""
    reader = rr.chunk.RrdReader(str(rrd))
    (bp,) = reader.blueprints()
    views: dict = {}
    for ch in reader.store(store=bp).stream():
        parts = ch.entity_path.strip("/").split("/")
        if len(parts) < 2 or parts[0] != "view":
            continue
        v = views.setdefault(parts[1], {"legend_visible": None, "eye": {}})
        rb = ch.to_record_batch()
        cols = {n: rb.column(n).to_pylist()[-1] for n in rb.schema.names}
        if "ViewBlueprint:class_identifier" in cols:
            v["class"] = cols["ViewBlueprint:class_identifier"][0]
            v["origin"] = cols["ViewBlueprint:space_origin"][0]
        if "PlotLegend:visible" in cols:
            v["legend_visible"] = cols["PlotLegend:visible"][0]
        for key in ("position", "look_target"):
            if f"EyeControls3D:{key}" in cols:
                v["eye"][key] = np.array(cols[f"EyeControls3D:{key}"][0], dtype=float)
    return views


def _translations(rrd: Path, entity: str) -> tuple[np.ndarray, np.ndarray]:
    """(time_s, translation (n, 3)) of one Transform3D entity, read with rerun's reader."""
    store = rr.chunk.RrdReader(str(rrd)).stream().collect()
    ts, xs = [], []
    for ch in store.stream():
        if ch.entity_path.lstrip("/") != entity or ch.is_static:
            continue
        rb = ch.to_record_batch()
        t = rb.column("time").to_numpy()
        ts.append(t.astype("timedelta64[ns]").astype(np.int64) / 1e9)
        xs.append(np.array(rb.column("Transform3D:translation").to_pylist(),
                           dtype=float).reshape(-1, 3))
    order = np.argsort(np.concatenate(ts))
    return np.concatenate(ts)[order], np.concatenate(xs)[order]


def test_3d_view_follows_and_frames_every_walker(device_recording):
    """The 3D view is set in the frame ``world/follow`` (a translation along x logged over
    time) with its eye fixed in that frame; every body of every condition's walker, at every
    logged time of the walk, lies within 20° of the eye's line of sight (the screenshots of
    ``tools/recording_screenshot.py`` show the walkers filling about half the view's height).
    Without the following frame the walkers leave the view within a few strides (the
    walk is over 5 m long against a view a few metres wide)."""
    _out, rrd, idx, _info, _res = device_recording
    views = _blueprint_views(rrd)
    (view,) = [v for v in views.values() if v.get("class") == "3D"]
    assert view["origin"] == "world/follow"
    eye, target = view["eye"]["position"], view["eye"]["look_target"]
    sight = (target - eye) / np.linalg.norm(target - eye)
    t_f, x_f = _translations(rrd, "world/follow")
    assert np.allclose(x_f[:, 1:], 0.0) and x_f[-1, 0] - x_f[0, 0] > 1.5   # it moves along x
    worst = 0.0
    for cond in ("no_device", "transparent", "assist"):
        bodies = [e for e in idx if e.startswith(f"world/{cond}/body/")
                  and e.count("/") == 3 and "Transform3D:translation" in idx[e]["components"]]
        assert len(bodies) >= 7
        for body in bodies:
            t, p = _translations(rrd, body)
            rel = p - np.column_stack([np.interp(t, t_f, x_f[:, 0]), np.zeros((len(t), 2))])
            d = rel - eye
            ang = np.degrees(np.arccos(np.clip(d @ sight / np.linalg.norm(d, axis=1), -1, 1)))
            worst = max(worst, float(ang.max()))
    assert worst < 20.0, f"a body is {worst:.1f} deg off the line of sight"


def test_plot_legends_leave_the_data_and_a_key_names_the_runs(device_recording):
    _out, rrd, idx, _info, _res = device_recording
    views = _blueprint_views(rrd)
    plots = [v for v in views.values() if v.get("class") == "TimeSeries"]
    assert len(plots) >= 10
    assert all(v["legend_visible"] is False for v in plots), "a legend is drawn over a plot"
    assert any(v.get("class") == "TextDocument" and v["origin"] == "key" for v in views.values())
    store = rr.chunk.RrdReader(str(rrd)).stream().collect()
    (text,) = [ch.to_record_batch().column("TextDocument:text").to_pylist()[0][0]
               for ch in store.stream() if ch.entity_path.lstrip("/") == "key"]
    for i, cond in enumerate(("no_device", "transparent", "assist")):
        assert f"`{cond}`" in text
        # the colour named is the one the run's lines carry
        style = [ch.to_record_batch() for ch in store.stream()
                 if ch.entity_path.lstrip("/") == f"signals/angle_deg/ankle/right/{cond}"
                 and ch.is_static]
        rgba = style[0].column("SeriesLines:colors").to_pylist()[0][0]
        r, g, b = (rgba >> 24) & 255, (rgba >> 16) & 255, (rgba >> 8) & 255
        assert f"`{cond}`: RGB {r}, {g}, {b}" in text
        # and each walker carries its name
        assert f"world/{cond}/body/pelvis/label" in idx


def test_orthosis_drawn_at_the_ankle_with_its_torque(device_recording):
    """The worn orthosis is drawn at the right ankle of the two conditions that wear it (a
    cuff on the shank, a plate under the foot) and its delivered torque as an arrow ending at
    the ball of the foot, 1 cm per N·m, in the sagittal plane, pointing down for plantarflexion:
    checked against the torque in the device's own log, the foot's logged pose and the ball
    sphere's place in the foot (the walker's model)."""
    import mujoco
    _out, rrd, idx, _info, res = device_recording
    store = rr.chunk.RrdReader(str(rrd)).stream().collect()
    for cond in ("transparent", "assist"):
        rec, _analysis, dev = res.results[cond]
        log = dev.log.arrays()
        t_log, tau_log = log["time_s"][:, 0], log["delivered_torque_nm"][:, 0]
        model = mujoco.MjModel.from_xml_string(rec.model_xml)
        ball_m = float(np.linalg.norm(model.geom("ball_r").pos))      # ankle → ball
        assert f"world/{cond}/body/shank_r/afo/cuff" in idx
        assert f"world/{cond}/body/foot_r/afo/plate" in idx
        arrows = [ch.to_record_batch() for ch in store.stream()
                  if ch.entity_path.lstrip("/") == f"world/{cond}/afo_torque/right"
                  and not ch.is_static]
        t = np.concatenate([a.column("time").to_numpy().astype("timedelta64[ns]")
                            .astype(np.int64) / 1e9 for a in arrows])
        vec = np.concatenate([np.array(a.column("Arrows3D:vectors").to_pylist(), dtype=float)
                              .reshape(-1, 3) for a in arrows])
        org = np.concatenate([np.array(a.column("Arrows3D:origins").to_pylist(), dtype=float)
                              .reshape(-1, 3) for a in arrows])
        order = np.argsort(t, kind="stable")
        t, vec, org = t[order], vec[order], org[order]
        assert len(t) > 50
        tau = tau_log[np.clip(np.searchsorted(t_log, t - 1e-9), 0, len(t_log) - 1)]
        np.testing.assert_allclose(np.linalg.norm(vec, axis=1), 0.01 * np.abs(tau),
                                   rtol=1e-5, atol=1e-6)
        np.testing.assert_allclose(vec[:, 1], 0.0, atol=1e-6)         # sagittal plane
        if cond == "assist":
            assert np.abs(tau).max() > 20.0
        t_foot, p_foot = _translations(rrd, f"world/{cond}/body/foot_r")
        ankle = p_foot[np.searchsorted(t_foot, t - 1e-9)]
        r = org + vec - ankle                       # the arrow ends at the ball
        np.testing.assert_allclose(np.linalg.norm(r, axis=1), ball_m, atol=1e-5)
        # a force along the arrow at the ball turns the foot as the torque does: its moment
        # about the ankle is along the joint's axis (−y; + = dorsiflexion), of sign tau
        moment_y = np.cross(r, vec)[:, 1]
        np.testing.assert_allclose(-moment_y, 0.01 * tau * ball_m, rtol=1e-4, atol=1e-7)
        push = tau < -5.0                       # plantarflexion: the forefoot pushed down
        assert np.all(vec[push & (np.abs(r[:, 2]) < 0.5 * ball_m), 2] < 0)
        assert cond != "assist" or push.sum() > 10
    assert "world/no_device/body/shank_r/afo/cuff" not in idx
    assert "world/no_device/afo_torque/right" not in idx


def test_recording_is_a_quarter_of_every_sample(device_recording, tmp_path):
    """The thinned recording of a short three-condition walk against the same walk with
    every signal sample kept (``signal_tolerance=0``, the signal content of recordings
    before the thinning): under 40 % of the bytes and of the rows (measured on this short
    run: 31 % and 17 %; on the default 10 strides 24 % and 17 %)."""
    _out, rrd, _idx, _info, res = device_recording
    sc = res.scenario
    full = tmp_path / "full.rrd"
    write_recording(full, res.recorded_runs(), res.reference, title=sc.name,
                    signal_tolerance=0.0)

    def rows(p):
        return sum(ch.num_rows for ch in rr.chunk.RrdReader(str(p)).stream().collect().stream())
    assert rrd.stat().st_size < 0.4 * full.stat().st_size
    assert rows(rrd) < 0.4 * rows(full)
    with pytest.raises(RecordingError, match="signal_tolerance"):
        write_recording(tmp_path / "x.rrd", res.recorded_runs(), signal_tolerance=0.5)
