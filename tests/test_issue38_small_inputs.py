"""Issue 38 item 5: small input checks a new user hit (each test fails on the code before
its fix)."""

from __future__ import annotations

import pytest

from afo_mj.scenarios.walk_scenario import ScenarioError, parse_scenario

_DEVICE = """
name = "t"
[device]
preset = "hafo"
conditions = ["assist"]
"""


def _device_error(extra: str) -> str:
    from afo_mj.scenarios.device_scenario import device_config
    sc = parse_scenario(_DEVICE + extra, origin="t.toml")
    with pytest.raises(ScenarioError) as info:
        device_config(sc)
    return str(info.value)


def test_misspelt_assistance_key_suggests_the_key():
    msg = _device_error("[assistance]\npeak_torque_n = 30.0\n")
    assert "assistance.peak_torque_n" in msg
    assert "did you mean 'assistance.peak_torque_nm'?" in msg


def test_misspelt_device_key_suggests_the_key():
    sc_text = _DEVICE.replace('conditions = ["assist"]', 'conditons = ["assist"]')
    from afo_mj.scenarios.device_scenario import device_config
    with pytest.raises(ScenarioError) as info:
        device_config(parse_scenario(sc_text, origin="t.toml"))
    assert "did you mean 'device.conditions'?" in str(info.value)


def test_one_stride_says_the_start_up_stride_is_analysed():
    from afo_mj.scenarios.walk_scenario import strides_overrides
    sc = parse_scenario('name = "t"\n[gait]\nstrides = 10\nanalyse_strides = [4, 10]\n',
                        origin="t.toml", overrides=strides_overrides(1))
    assert sc.analyse_strides == (1, 1)
    assert any("start-up stride" in n and "gait.analyse_strides" in n for n in sc.notes)
    sc = parse_scenario('name = "t"\n[gait]\nstrides = 1\n', origin="t.toml")
    assert sc.analyse_strides == (1, 1)
    assert any("start-up stride" in n for n in sc.notes)


def test_windows_past_the_start_up_stride_carry_no_start_up_note():
    from afo_mj.scenarios.walk_scenario import strides_overrides
    for ov in ([], strides_overrides(2), strides_overrides(6)):
        sc = parse_scenario('name = "t"\n', origin="t.toml", overrides=ov)
        assert sc.analyse_strides[0] >= 2
        assert not any("start-up" in n for n in sc.notes)


def test_a_body_outside_the_human_range_is_noted():
    sc = parse_scenario('name = "t"\n', origin="t.toml",
                        overrides=["walker.body_mass_kg=10", "walker.height_m=2.2"])
    bmi = 10.0 / 2.2 ** 2                     # 2.07 kg/m², far below any human's
    note = [n for n in sc.notes if "body mass index" in n]
    assert len(note) == 1
    assert f"{bmi:.1f} kg/m^2" in note[0] and "10 kg" in note[0] and "2.2 m" in note[0]
    sc = parse_scenario('name = "t"\n', origin="t.toml",
                        overrides=["walker.body_mass_kg=200", "walker.height_m=1.2"])
    assert any("body mass index" in n for n in sc.notes)     # 139 kg/m²


@pytest.mark.parametrize("walker", ['body_preset = "child_4y"', 'body_preset = "adult_female"',
                                    "body_mass_kg = 75.0\nheight_m = 1.75",
                                    "body_mass_kg = 120.0\nheight_m = 1.8"])
def test_human_bodies_carry_no_body_size_note(walker):
    sc = parse_scenario(f'name = "t"\n[walker]\n{walker}\n', origin="t.toml")
    assert not any("body mass index" in n for n in sc.notes)


def _storage(path, cols, header):
    names = list(cols)
    lines = [path.name, "version=1", f"nRows={len(cols['time'])}",
             f"nColumns={len(names)}", header, "endheader", "\t".join(names)]
    lines += ["\t".join(f"{cols[c][k]:.8f}" for c in names) for k in range(len(cols["time"]))]
    path.write_text("\n".join(lines) + "\n")


def _trial(tmp_path, bad_file=None, bad_column=None, bad_row=None, bad_value="nan"):
    """A 4-stride trial at 100 Hz (Winter's cycle, T = 1.1 s; the left leg half a stride
    later) as OpenSim IK .sto, ID .sto and GRF .mot; ``bad_value`` written into one cell
    (data row ``bad_row``, 1-based) of one file."""
    import numpy as np

    from afo_mj.gait.reference import load_normative
    w = load_normative("winter", "normal")
    t = np.arange(0.0, 4.4 + 1e-9, 0.01)
    pr, pl = np.mod((t + 0.2) / 1.1, 1.0), np.mod((t + 0.2 - 0.55) / 1.1, 1.0)
    ar, al = np.degrees(w.angles_rad(pr)), np.degrees(w.angles_rad(pl))
    ik = {"time": t}
    id_ = {"time": t}
    for sfx, a, ph in (("r", ar, pr), ("l", al, pl)):
        ik.update({f"hip_flexion_{sfx}": a[:, 0], f"knee_angle_{sfx}": -a[:, 1],
                   f"ankle_angle_{sfx}": a[:, 2]})
        m = w.moments_nm_per_kg(ph) * 75.0
        id_.update({f"hip_flexion_{sfx}_moment": m[:, 0], f"knee_angle_{sfx}_moment": -m[:, 1],
                    f"ankle_angle_{sfx}_moment": m[:, 2]})

    def grf(ph):
        return np.where(ph < 0.6, 800.0 * np.sqrt(np.sin(np.pi * ph / 0.6).clip(0)), 0.0)
    gr = {"time": t, "ground_force_vy": grf(pr), "1_ground_force_vy": grf(pl),
          "ground_force_vx": 0.1 * grf(pr), "1_ground_force_vx": 0.1 * grf(pl)}
    paths = {"ik": tmp_path / "trial_ik.sto", "id": tmp_path / "trial_id.sto",
             "grf": tmp_path / "trial_grf.mot"}
    for key, cols, hdr in (("ik", ik, "inDegrees=yes"), ("id", id_, "inDegrees=no"),
                           ("grf", gr, "inDegrees=yes")):
        _storage(paths[key], cols, hdr)
        if key == bad_file:
            lines = paths[key].read_text().splitlines()
            labels = lines.index("endheader") + 1
            fields = lines[labels + bad_row].split("\t")
            fields[lines[labels].split("\t").index(bad_column)] = bad_value
            lines[labels + bad_row] = "\t".join(fields)
            paths[key].write_text("\n".join(lines) + "\n")
    return paths


def test_a_clean_trial_loads(tmp_path):
    from afo_mj.gait.measured_trial import load_measured_trial
    p = _trial(tmp_path)
    trial = load_measured_trial(p["ik"], p["grf"], id_path=p["id"], body_mass_kg=75.0)
    assert trial.n_cycles >= 4


@pytest.mark.parametrize("bad_file, column, row, value", [
    ("ik", "knee_angle_r", 5, "nan"),        # before the first heel strike: was ignored
    ("ik", "ankle_angle_l", 200, "nan"),     # inside a cycle
    ("id", "ankle_angle_r_moment", 3, "inf"),
    ("grf", "1_ground_force_vy", 120, "nan"),
])
def test_a_non_finite_value_in_a_trial_is_refused_naming_file_column_row_and_time(
        tmp_path, bad_file, column, row, value):
    from afo_mj.gait.measured_trial import load_measured_trial
    from afo_mj.gait.reference import ReferenceGaitError
    p = _trial(tmp_path, bad_file, column, row, value)
    with pytest.raises(ReferenceGaitError) as info:
        load_measured_trial(p["ik"], p["grf"], id_path=p["id"], body_mass_kg=75.0)
    msg = str(info.value)
    assert str(p[bad_file]) in msg and repr(column) in msg
    assert f"data row {row} " in msg and f"(time {(row - 1) * 0.01:g} s)" in msg


def test_a_nan_in_a_trial_refuses_the_scenario(tmp_path):
    _trial(tmp_path, "ik", "hip_flexion_r", 2, "nan")
    text = ('[gait]\nreference_path = "trial_ik.sto"\nreference_grf_path = "trial_grf.mot"\n')
    with pytest.raises(ScenarioError, match=r"gait.reference_path = 'trial_ik.sto' cannot be "
                       r"used: .*'hip_flexion_r' has the non-finite value nan at data row 2"):
        parse_scenario(text, origin="t.toml", base_dir=tmp_path)


def _cycle_csv(path, moment_scale=1.0, grf_scale=1.0):
    """Winter's cycle as a user CSV (percent_cycle, angles in degrees, moments and GRF per
    kg, the ankle moment and the GRF times the given scales); returns the largest |ankle
    moment| and |vertical GRF| written."""
    import numpy as np

    from afo_mj.gait.reference import load_normative
    w = load_normative("winter", "normal")
    ph = np.linspace(0.0, 1.0, 51)
    cols = {"percent_cycle": 100.0 * ph}
    for j, a in zip(("hip", "knee", "ankle"), np.degrees(w.angles_rad(ph)).T):
        cols[f"{j}_angle_deg"] = a
    for j, m in zip(("hip", "knee", "ankle"), w.moments_nm_per_kg(ph).T):
        cols[f"{j}_moment_nm_per_kg"] = (moment_scale if j == "ankle" else 1.0) * m
    cols["grf_z_n_per_kg"] = grf_scale * w.grf_n_per_kg(ph)[:, 1]
    lines = [",".join(cols)] + [",".join(f"{cols[c][k]:.6f}" for c in cols)
                                for k in range(ph.size)]
    path.write_text("\n".join(lines) + "\n")
    return (float(np.abs(np.round(cols["ankle_moment_nm_per_kg"], 6)).max()),
            float(np.abs(np.round(cols["grf_z_n_per_kg"], 6)).max()))


def test_a_per_kg_gait_file_loads(tmp_path):
    from afo_mj.gait.reference import load_reference_csv
    _cycle_csv(tmp_path / "gait.csv")
    ref = load_reference_csv(tmp_path / "gait.csv", body_mass_kg=75.0)
    assert ref.has("ankle_moment_nm_per_kg") and ref.has("grf_z_n_per_kg")


def test_moments_in_newton_metres_are_refused_with_the_column_value_and_limit(tmp_path):
    from afo_mj.gait.reference import ReferenceGaitError, load_reference_csv
    peak, _ = _cycle_csv(tmp_path / "gait.csv", moment_scale=75.0)    # N*m of a 75 kg adult
    assert peak > 100.0
    with pytest.raises(ReferenceGaitError) as info:
        load_reference_csv(tmp_path / "gait.csv", body_mass_kg=75.0)
    msg = str(info.value)
    assert "'ankle_moment_nm_per_kg'" in msg and f"{peak:.4g}" in msg.replace("-", "")
    assert "allowed: |value| <= 5 N*m/kg" in msg
    assert "divide the column by the body mass" in msg and "'unit': 'N*m'" in msg
    # the same file mapped with its unit declared loads, divided by the body mass
    from afo_mj.gait.reference import MOMENT_CHANNELS
    mapping = {f"{j}_angle_rad": {"column": f"{j}_angle_deg", "unit": "deg"}
               for j in ("hip", "knee", "ankle")}
    mapping.update({c: c for c in MOMENT_CHANNELS})
    mapping["ankle_moment_nm_per_kg"] = {"column": "ankle_moment_nm_per_kg", "unit": "N*m"}
    ref = load_reference_csv(tmp_path / "gait.csv", mapping=mapping, body_mass_kg=75.0)
    import numpy as np
    got = np.abs(ref.channel("ankle_moment_nm_per_kg", np.linspace(0, 1, 51))).max()
    assert got == pytest.approx(peak / 75.0, rel=1e-3)


def test_a_scenario_with_moments_in_newton_metres_is_refused(tmp_path):
    _cycle_csv(tmp_path / "gait.csv", moment_scale=75.0)
    with pytest.raises(ScenarioError, match=r"gait.reference_path = 'gait.csv' cannot be used: "
                       r".*'ankle_moment_nm_per_kg'.*allowed: \|value\| <= 5 N\*m/kg"):
        parse_scenario('[gait]\nreference_path = "gait.csv"\n', origin="t.toml",
                       base_dir=tmp_path)


def test_ground_reaction_forces_in_newtons_are_refused(tmp_path):
    from afo_mj.gait.reference import ReferenceGaitError, load_reference_csv
    _, peak = _cycle_csv(tmp_path / "gait.csv", grf_scale=75.0)
    with pytest.raises(ReferenceGaitError, match=r"'grf_z_n_per_kg'.* peaks at "
                       + f"{peak:.4g}".replace(".", r"\.") + r" N/kg.*<= 30 N/kg"):
        load_reference_csv(tmp_path / "gait.csv", body_mass_kg=75.0)


def test_trial_moments_divided_by_a_wrong_mass_are_refused(tmp_path):
    from afo_mj.gait.measured_trial import load_measured_trial
    from afo_mj.gait.reference import ReferenceGaitError
    p = _trial(tmp_path)                  # ID moments in N*m of a 75 kg adult
    with pytest.raises(ReferenceGaitError) as info:
        load_measured_trial(p["ik"], p["grf"], id_path=p["id"], body_mass_kg=1.0)
    msg = str(info.value)
    assert str(p["id"]) in msg and "_moment'" in msg and "<= 5 N*m/kg" in msg
    assert "body_mass_kg = 1 kg" in msg


def test_the_stiffness_study_ranks_every_run(tmp_path):
    """The shipped stiffness_foot_drop study, made tiny (two stiffnesses, one rest angle,
    3 strides): each run's headline condition is named after its K (assist_k1, assist_k2.5),
    and `afo-mj study` ranks every run on its own condition's value."""
    import contextlib
    import io
    import tomllib
    from pathlib import Path

    import pandas as pd

    from afo_mj import cli
    root = Path(__file__).resolve().parents[1]
    shipped = root / "scenarios" / "studies" / "stiffness_foot_drop.toml"
    doc = tomllib.loads(shipped.read_text(encoding="utf-8"))
    keys = [p["key"] for p in doc["parameter"]]
    assert keys == ["assistance.stiffnesses_nm_per_deg", "assistance.rest_angle_deg"]
    base = (shipped.parent / doc["scenario"]).resolve()
    study = tmp_path / "tiny.toml"
    study.write_text(f'name = "{doc["name"]}_tiny"\nscenario = "{base.as_posix()}"\n'
                     'set = ["gait.strides=3", "gait.analyse_strides=[2, 3]"]\n'
                     '[design]\nkind = "grid"\n'
                     f'[[parameter]]\nkey = "{keys[0]}"\nlevels = [[1.0], [2.5]]\n'
                     f'[[parameter]]\nkey = "{keys[1]}"\nlevels = [0.0]\n'
                     '[output]\nformat = "csv"\n', encoding="utf-8")
    out = tmp_path / "sweep"
    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
        assert cli.main(["sweep", str(study), "--out", str(out), "--workers", "1",
                         "--quiet"]) == 0
    buf = io.StringIO()
    with contextlib.redirect_stdout(buf):
        assert cli.main(["study", str(out)]) == 0
    # independent reference: each row's own condition's column of the results table
    table = pd.read_csv(out / "results.csv")
    change = "human_ankle_positive_work_change_j_per_stride"
    own = {}
    for _, row in table.iterrows():
        k = tomllib.loads(f"v = {row['param:' + keys[0]]}")["v"][0]
        own[row["run_id"]] = row[f"comparison_vs_no_device.assist_k{k:g}.{change}"]
    assert len(own) == 2 and all(v == v for v in own.values())       # both have a value
    summary = __import__("json").loads((out / "study" / "summary.json").read_text())
    assert summary["metric"].endswith(change)
    ranked = [(r["run_id"], r["value"]) for r in summary["top"]]
    assert [rid for rid, _ in ranked] == sorted(own, key=own.get)
    for rid, v in ranked:
        assert v == pytest.approx(own[rid], rel=1e-12)
    assert "without a value" not in (out / "study" / "ranking.txt").read_text()
    assert summary["pareto"] is not None and len(summary["pareto"]["runs"]) >= 1


@pytest.mark.parametrize("command, body", [
    ("sweep", '[[parameter]]\nkey = "walker.height_m"\nlevels = [1.7, 1.8]\n'),
    ("optimize", '[[parameter]]\nkey = "walker.height_m"\nrange = [1.7, 1.8]\n'
                 '[optimize]\nmetric = "speed_m_s.mean"\nmethod = "nelder_mead"\nbudget = 2\n'),
])
def test_an_unreachable_dask_scheduler_is_refused_with_nothing_written(tmp_path, monkeypatch,
                                                                     command, body):
    import contextlib
    import io
    from pathlib import Path

    from afo_mj import cli
    from afo_mj.studies import sweep
    monkeypatch.setattr(sweep, "SCHEDULER_CONNECT_TIMEOUT_S", 1.0, raising=False)
    walk = Path(__file__).resolve().parents[1] / "scenarios" / "walk_healthy.toml"
    study = tmp_path / "s.toml"
    study.write_text(f'name = "s"\nscenario = "{walk.as_posix()}"\n'
                     'set = ["gait.strides=2", "gait.analyse_strides=[2, 2]"]\n' + body)
    out = tmp_path / "out"
    err, std = io.StringIO(), io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(std):
        rc = cli.main([command, str(study), "--out", str(out), "--scheduler",
                       "tcp://127.0.0.1:1", "--quiet"])
    msg = err.getvalue()
    assert rc == 2, msg
    assert "Traceback" not in msg and len(msg.strip().splitlines()) == 1
    assert "tcp://127.0.0.1:1" in msg and "cannot reach the Dask scheduler" in msg
    assert "allowed:" in msg and std.getvalue() == ""
    assert not out.exists()


def _gone(pid: int) -> bool:
    """Whether process ``pid`` has ended (absent, or a zombie waiting to be reaped)."""
    from pathlib import Path
    try:
        status = Path(f"/proc/{pid}/status").read_text()
    except OSError:
        return True
    return any(ln.split()[1:2] == ["Z"] for ln in status.splitlines()
               if ln.startswith("State:"))


@pytest.mark.skipif(not __import__("sys").platform.startswith("linux"), reason="/proc, signals")
@pytest.mark.parametrize("signame", ["SIGTERM", "SIGINT"])
def test_view_web_server_dies_with_afo_mj(tmp_path, signame):
    """`afo-mj view --web` runs `rerun --serve-web`, a wrapper whose own child serves: a
    signal to afo-mj must end that server too (it used to keep serving at 100 % CPU). A
    fake `rerun` on PATH stands in for the wrapper and its server (a `sleep`)."""
    import os
    import signal
    import subprocess
    import sys
    import time
    from pathlib import Path

    bindir = tmp_path / "bin"
    bindir.mkdir()
    pidfile = tmp_path / "server.pid"
    fake = bindir / "rerun"
    fake.write_text(f"#!/bin/sh\nsleep 300 &\necho $! > {pidfile}.tmp\n"
                    f"mv {pidfile}.tmp {pidfile}\nwait\n")
    fake.chmod(0o755)
    rrd = tmp_path / "walk.rrd"
    rrd.write_bytes(b"")
    env = {**os.environ, "PATH": f"{bindir}{os.pathsep}{os.environ.get('PATH', '')}"}
    root = Path(__file__).resolve().parents[1]
    proc = subprocess.Popen([sys.executable, "-c", "import sys; from afo_mj.cli import main; "
                             "sys.exit(main())", "view", str(rrd), "--web"], env=env,
                            cwd=root, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    server = None
    try:
        for _ in range(600):                         # until the fake server has started
            if pidfile.exists():
                break
            assert proc.poll() is None, proc.stderr.read().decode()
            time.sleep(0.05)
        server = int(pidfile.read_text())
        assert not _gone(server)
        proc.send_signal(getattr(signal, signame))
        rc = proc.wait(timeout=60)
        for _ in range(200):                         # the group was signalled; let it end
            if _gone(server):
                break
            time.sleep(0.05)
        assert _gone(server), "rerun's server outlived afo-mj view"
        assert rc == 128 + getattr(signal, signame)
    finally:
        if proc.poll() is None:
            proc.kill()
        if server is not None and not _gone(server):
            os.kill(server, signal.SIGKILL)
