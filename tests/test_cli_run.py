"""``afo-mj run`` end to end with the simulation replaced by a synthetic Winter record."""

from __future__ import annotations

import csv
import json
import math
import os
from pathlib import Path

import pytest

from afo_mj import cli
from afo_mj.metrics.gait_metrics import analyse_gait
from afo_mj.gait.reference import load_normative
from afo_mj.outputs import gait_report
from afo_mj.outputs.gait_report import ReportError, write_run_outputs
from afo_mj.scenarios.walk_scenario import WalkScenario

from gait_fixtures import WinterSplines, synthetic_record

HEALTHY = Path(__file__).resolve().parents[1] / "scenarios" / "walk_healthy.toml"


def _as_walk(simulate):
    """A stand-in for ``simulate_walk(scenario)`` as the app's walk of a scenario
    (:func:`afo_mj.gait.walkers.walk_scenario`: the record and no muscle walk)."""
    return lambda scenario, *args, **kwargs: (simulate(scenario), None)


@pytest.fixture(scope="module")
def record():
    return synthetic_record(splines=WinterSplines())


@pytest.fixture
def fake_sim(monkeypatch, record):
    seen = []

    def simulate(scenario):
        assert isinstance(scenario, WalkScenario)
        seen.append(scenario)
        return record

    monkeypatch.setattr("afo_mj.gait.walkers.walk_scenario", _as_walk(simulate))
    return seen


def _strict_json(path: Path) -> dict:
    def no_constant(name):
        raise ValueError(f"non-finite JSON constant {name}")
    return json.loads(path.read_text(encoding="utf-8"), parse_constant=no_constant)


def test_run_writes_all_outputs(tmp_path, fake_sim, capsys):
    out = tmp_path / "runs" / "healthy"
    assert cli.main(["run", str(HEALTHY), "--out", str(out)]) == 0
    assert fake_sim and fake_sim[0].name == "walk_healthy"
    printed = capsys.readouterr().out
    assert "angle RMS error" in printed and str(out) in printed and "no fall" in printed

    s = _strict_json(out / "summary.json")
    for key in ("ankle_angle_rms_error_deg", "knee_angle_rms_error_deg", "hip_angle_rms_error_deg",
                "peak_ankle_plantarflexor_moment_nm_per_kg", "peak_ankle_power_w_per_kg",
                "ankle_push_off_positive_work_j_per_kg", "residual_force_rms_percent_body_weight",
                "speed_m_s", "cadence_steps_per_min", "stride_length_m", "min_toe_clearance_m"):
        assert set(s[key]) >= {"mean", "sd", "n"}, key
        assert s[key]["n"] == 14
    assert s["ankle_angle_rms_error_deg"]["mean"] < 0.05
    assert s["speed_m_s"]["mean"] == pytest.approx(1.325)
    assert s["fall_time_s"] is None and s["n_cycles_used"] == 14 and s["completed_strides"] == 12
    assert s["ankle_angle_within_1sd_fraction"] is None          # Winter: no SD
    assert s["scenario"]["name"] == "walk_healthy"

    with (out / "cycles.csv").open(encoding="utf-8") as f:
        rows = list(csv.DictReader(f))
    assert len(rows) == 14
    assert {r["leg"] for r in rows} == {"right", "left"}
    assert sorted({int(r["stride"]) for r in rows}) == list(range(4, 11))
    assert float(rows[0]["peak_ankle_plantarflexor_moment_nm_per_kg"]) == pytest.approx(
        1.69, abs=0.02)
    for col in ("cadence_steps_per_min", "stride_length_m", "ankle_positive_work_j_per_kg",
                "min_toe_clearance_m", "residual_force_rms_n"):
        assert col in rows[0]

    with (out / "gait_curves.csv").open(encoding="utf-8") as f:
        curves = list(csv.DictReader(f))
    assert len(curves) == 101 and "reference_ankle_angle_rad_mean" in curves[0]

    png = (out / "gait_curves.png").read_bytes()
    assert png[:8] == b"\x89PNG\r\n\x1a\n" and len(png) > 20_000
    assert ((out / "scenario.toml").read_text(encoding="utf-8")
            == HEALTHY.read_text(encoding="utf-8"))
    assert not [p for p in out.parent.iterdir() if p.name.startswith(".")]   # no temp dirs left
    umask = os.umask(0o022)
    os.umask(umask)
    assert out.stat().st_mode & 0o777 == 0o777 & ~umask       # an ordinary dir, not mkdtemp's 0700


def test_bad_scenario_exit_2_and_nothing_written(tmp_path, fake_sim, capsys):
    bad = tmp_path / "bad.toml"
    bad.write_text(HEALTHY.read_text(encoding="utf-8").replace(
        "plantarflexor_strength_fraction = 1.0", "plantarflexor_strength_fraction = 2.0"),
        encoding="utf-8")
    out = tmp_path / "out"
    assert cli.main(["run", str(bad), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert "impairment.plantarflexor_strength_fraction = 2.0" in err and str(bad) in err
    assert not out.exists() and not fake_sim
    assert cli.main(["run", str(tmp_path / "missing.toml"), "--out", str(out)]) == 2
    assert not out.exists()


def test_fall_before_a_stride_is_a_reported_outcome(tmp_path, monkeypatch, capsys):
    monkeypatch.setattr("afo_mj.gait.walkers.walk_scenario",
                        _as_walk(lambda sc: synthetic_record(n_cycles=3, fall_time_s=0.9)))
    out = tmp_path / "out"
    assert cli.main(["run", str(HEALTHY), "--out", str(out)]) == 0
    assert "FELL at t = 0.90 s" in capsys.readouterr().out
    s = _strict_json(out / "summary.json")
    assert s["fell"] is True and s["fall_time_s"] == pytest.approx(0.9)
    assert s["completed_strides"] == 0
    assert not (out / "gait_curves.png").exists()


def test_numerics_failure_exit_1_and_nothing_written(tmp_path, monkeypatch, capsys):
    from afo_mj.gait.walk import WalkNumericsError

    def boom(sc):
        raise WalkNumericsError("non-finite walker state at t = 0.1230 s")
    monkeypatch.setattr("afo_mj.gait.walkers.walk_scenario", _as_walk(boom))
    out = tmp_path / "out"
    assert cli.main(["run", str(HEALTHY), "--out", str(out)]) == 1
    assert "non-finite walker state" in capsys.readouterr().err
    assert not out.exists()


@pytest.fixture(scope="module")
def analysis(record):
    ref = load_normative("winter", "normal")
    return analyse_gait(record, ref, (4, 10)), ref


def test_existing_dir_with_unrelated_files_is_refused(tmp_path, analysis, record):
    a, ref = analysis
    out = tmp_path / "out"
    out.mkdir()
    (out / "notes.txt").write_text("keep me", encoding="utf-8")
    (out / "summary.json").write_text("old", encoding="utf-8")
    with pytest.raises(ReportError, match=r"holds files afo-mj did not write \(notes.txt, "
                                          r"summary.json\)"):
        write_run_outputs(out, a.summary, a.cycles, ref, record, None)
    assert (out / "notes.txt").read_text(encoding="utf-8") == "keep me"
    assert (out / "summary.json").read_text(encoding="utf-8") == "old"


def test_failure_leaves_previous_results(tmp_path, analysis, record, monkeypatch):
    a, ref = analysis
    out = tmp_path / "out"
    monkeypatch.setattr(gait_report, "_plot", lambda path, *a, **k: path.write_bytes(b"png"))
    write_run_outputs(out, {**a.summary, "marker": "previous"}, a.cycles, ref, record, None)
    before = {p.name: p.read_bytes() for p in out.iterdir()}

    def broken_plot(*args, **kwargs):
        raise RuntimeError("plot failed")

    monkeypatch.setattr(gait_report, "_plot", broken_plot)
    with pytest.raises(RuntimeError, match="plot failed"):
        write_run_outputs(out, a.summary, a.cycles, ref, record, "x = 1\n")
    assert {p.name: p.read_bytes() for p in out.iterdir()} == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out"]      # temp dir removed
    with pytest.raises(RuntimeError):
        write_run_outputs(tmp_path / "new", a.summary, a.cycles, ref, record, None)
    assert not (tmp_path / "new").exists()


def test_nan_key_metric_raises_and_other_nan_becomes_null(tmp_path, analysis, record):
    a, ref = analysis
    bad = dict(a.summary, ankle_angle_rms_error_deg={"mean": math.nan, "sd": None, "n": 14})
    with pytest.raises(ReportError, match="ankle_angle_rms_error_deg"):
        write_run_outputs(tmp_path / "nan", bad, a.cycles, ref, record, None)
    assert not (tmp_path / "nan").exists()
    odd = dict(a.summary, extra_metric={"mean": math.nan, "sd": math.inf, "n": 0})
    write_run_outputs(tmp_path / "ok", odd, a.cycles, ref, record, None)
    assert _strict_json(tmp_path / "ok" / "summary.json")["extra_metric"] == {
        "mean": None, "sd": None, "n": 0}


# ------------------------------------------------------------------------------------------
# what a new user hit (issue 19)
# ------------------------------------------------------------------------------------------

@pytest.fixture
def no_png(monkeypatch):
    """Figures replaced by a stub file: these tests are about the command, not the plots."""
    monkeypatch.setattr(gait_report, "_plot", lambda path, *a, **k: path.write_bytes(b"png"))


def test_set_strides_moves_the_analysed_window(tmp_path, fake_sim, no_png, capsys):
    """`--set gait.strides=6` on a scenario analysing [4, 10] used to exit 2."""
    out = tmp_path / "out"
    assert cli.main(["run", str(HEALTHY), "--out", str(out), "--set", "gait.strides=6"]) == 0
    assert (fake_sim[0].strides, fake_sim[0].analyse_strides) == (6, (4, 6))
    assert "gait.analyse_strides = [4, 10] -> [4, 6]" in capsys.readouterr().err
    assert _strict_json(out / "summary.json")["scenario"]["analyse_strides"] == [4, 6]
    bad = tmp_path / "bad"
    assert cli.main(["run", str(HEALTHY), "--out", str(bad), "--set", "gait.strides=6",
                     "--set", "gait.analyse_strides=[4, 10]"]) == 2
    assert "gait.analyse_strides = [4, 10] is out of range" in capsys.readouterr().err
    assert not bad.exists()


def test_run_strides_option(tmp_path, fake_sim, no_png, capsys):
    out = tmp_path / "out"
    assert cli.main(["run", str(HEALTHY), "--out", str(out), "--strides", "5"]) == 0
    assert (fake_sim[0].strides, fake_sim[0].analyse_strides) == (5, (2, 5))
    assert cli.main(["run", str(HEALTHY), "--out", str(tmp_path / "z"), "--strides", "0"]) == 2
    assert "--strides = 0" in capsys.readouterr().err and not (tmp_path / "z").exists()


def test_device_key_on_a_walk_without_device_exit_2(tmp_path, fake_sim, capsys):
    out = tmp_path / "out"
    assert cli.main(["run", str(HEALTHY), "--out", str(out), "--set",
                     "device.params.hose.length_m=2.2"]) == 2
    err = capsys.readouterr().err
    assert "device.params.hose.length_m" in err and "has no device" in err
    assert not out.exists() and not fake_sim


def test_reused_out_holds_only_this_runs_files(tmp_path, fake_sim, no_png, monkeypatch):
    out = tmp_path / "out"
    assert cli.main(["run", str(HEALTHY), "--out", str(out), "--set", "gait.strides=3",
                     "--set", "gait.analyse_strides=[2, 3]"]) == 0
    assert (out / "gait_curves.png").exists()
    monkeypatch.setattr("afo_mj.gait.walkers.walk_scenario",
                        _as_walk(lambda sc: synthetic_record(n_cycles=3, fall_time_s=0.9)))
    assert cli.main(["run", str(HEALTHY), "--out", str(out), "--set", "gait.strides=3",
                     "--set", "gait.analyse_strides=[2, 3]"]) == 0
    names = {p.name for p in out.iterdir() if not p.name.startswith(".")}
    assert names == {"summary.json", "scenario.toml", "run_info.json"}     # no stale curves
    assert _strict_json(out / "summary.json")["fell"] is True
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".")]  # no temp dirs left


def test_out_with_foreign_files_or_a_file_is_refused_before_the_run(tmp_path, fake_sim,
                                                                   capsys):
    out = tmp_path / "out"
    out.mkdir()
    (out / "notes.txt").write_text("mine", encoding="utf-8")
    assert cli.main(["run", str(HEALTHY), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert "notes.txt" in err and "did not write" in err
    assert [p.name for p in out.iterdir()] == ["notes.txt"] and not fake_sim
    f = tmp_path / "afile"
    f.write_text("x", encoding="utf-8")
    assert cli.main(["run", str(HEALTHY), "--out", str(f)]) == 2
    assert "is not a directory" in capsys.readouterr().err
    assert f.read_text(encoding="utf-8") == "x" and not fake_sim


def test_errors_show_numbers_plainly(tmp_path, fake_sim, capsys):
    """A reference CSV whose time column repeats: the values, not np.float64(...) reprs."""
    ph = [i / 20 for i in range(21)]
    ph[5] = ph[4]
    csv_path = tmp_path / "ref.csv"
    csv_path.write_text("time_s,hip_angle_rad,knee_angle_rad,ankle_angle_rad\n" + "".join(
        f"{t},0.1,0.2,0.0\n" for t in ph), encoding="utf-8")
    sc = tmp_path / "mine.toml"
    sc.write_text('[gait]\nreference_path = "ref.csv"\n', encoding="utf-8")
    assert cli.main(["run", str(sc), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert "np.float64" not in err and "(0.2 then 0.2)" in err


def test_calibrate_unknown_preset_names_the_option(tmp_path, capsys):
    assert cli.main(["calibrate", "--scenario", "hafoo", "--data", str(tmp_path / "d.csv"),
                     "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert "--scenario = 'hafoo'" in err and "did you mean 'hafo'?" in err
    assert "source.preset" not in err
    assert cli.main(["make-bench-record", "--preset", "hafoo", "--out",
                     str(tmp_path / "r.csv")]) == 2
    assert "--preset = 'hafoo'" in capsys.readouterr().err
    assert list(tmp_path.iterdir()) == []


def test_unknown_set_key_suggests_the_close_one(tmp_path, fake_sim, capsys):
    assert cli.main(["run", str(HEALTHY), "--out", str(tmp_path / "o"), "--set",
                     "gait.stride=3"]) == 2
    assert "did you mean 'gait.strides'?" in capsys.readouterr().err


def test_empty_scenario_exit_2(tmp_path, fake_sim, capsys):
    empty = tmp_path / "empty.toml"
    empty.write_text("", encoding="utf-8")
    assert cli.main(["run", str(empty), "--out", str(tmp_path / "o")]) == 2
    assert "empty scenario" in capsys.readouterr().err
    assert not fake_sim and not (tmp_path / "o").exists()


def test_help_opens_with_a_description_and_version(capsys):
    import afo_mj
    with pytest.raises(SystemExit) as ex:
        cli.main(["--help"])
    assert ex.value.code == 0
    text = capsys.readouterr().out
    description = text.split("\n\n")[1]
    assert "Command-line interface" not in text and "``" not in text
    assert description.startswith("Simulate human walking in MuJoCo")
    with pytest.raises(SystemExit) as ex:
        cli.main(["--version"])
    assert ex.value.code == 0
    assert capsys.readouterr().out.strip() == f"afo-mj {afo_mj.__version__}"
