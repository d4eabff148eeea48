"""Calibration report files (afo_mj.outputs.calibration_report) from a hand-made report."""

from __future__ import annotations

import copy
import json
import math

import numpy as np
import pytest

from afo_mj.outputs.calibration_report import (
    FIGURES, FORMAT, to_jsonable, verdict_sentence, write_calibration_report)

OUTPUTS = ("pressure_a_pa", "ankle_torque_nm")
NOISE = {"pressure_a_pa": 2.0e4, "ankle_torque_nm": 0.2}
FS = 500.0


def _series(seed=0):
    """12 s at 500 Hz: a measured record with a slow decay the declared model misses."""
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, 12.0, 1.0 / FS)
    truth = {"pressure_a_pa": 4e6 + 3e6 * np.sin(2 * np.pi * t),
             "ankle_torque_nm": 20.0 * np.sin(2 * np.pi * t + 0.3)}
    missing = {"pressure_a_pa": 2e5 * np.sin(2 * np.pi * t) ** 2,
               "ankle_torque_nm": 1.5 * np.sign(np.cos(2 * np.pi * t))}
    measured = {c: truth[c] + rng.normal(0.0, NOISE[c], t.size) for c in OUTPUTS}
    before = {c: truth[c] - missing[c] for c in OUTPUTS}
    after = {c: truth[c] + 0.05 * missing[c] for c in OUTPUTS}
    return {"time_s": t, "measured": measured, "before": before, "after": after,
            "i_cut": int(np.searchsorted(t, 8.0))}


def _whiteness(p, excess):
    return {"ljung_box_q": 12.5, "p_value": p, "lags": 20, "decimation": 1,
            "white": bool(p > 0.01), "rms": excess, "noise_sigma": 1.0,
            "excess_ratio": excess, "n_decimated": 2000, "decimated_fs_hz": FS}


def make_report(verdict="effect_found", with_series=True):
    eb = {"pressure_a_pa": np.float64(0.0300), "ankle_torque_nm": 0.0170}
    eb["overall"] = math.sqrt((eb["pressure_a_pa"] ** 2 + eb["ankle_torque_nm"] ** 2) / 2)
    ea = {"pressure_a_pa": 0.0110, "ankle_torque_nm": np.float32(0.0085)}
    ea["overall"] = math.sqrt((ea["pressure_a_pa"] ** 2 + float(ea["ankle_torque_nm"]) ** 2) / 2)
    effect = {"effect": "piston_leakage", "component": "cylinder",
              "equation": "Q = G_l Δp/μ across the piston (laminar gap)",
              "reference": "Merritt §3",
              "parameters": {"piston_leakage.leakage_conductance_m3": 3.1e-15},
              "uncertainties": {"piston_leakage.leakage_conductance_m3": 1.2e-16},
              "held_out_before": eb["overall"], "held_out_after": ea["overall"],
              "held_out_drop": 1 - ea["overall"] / eb["overall"],
              "delta_bic": -812.4, "delta_aic": -818.9}
    declared = {"motor_resistance_ohm": 0.61, "torque_constant_nm_a": 0.021,
                "seal_coulomb_force_n": 14.0, "liquid_bulk_modulus_pa": 1.4e9}
    found = verdict == "effect_found"
    r = {
        "kind": "hafo", "preset": "hafo", "outputs": list(OUTPUTS), "skipped_outputs": [],
        "inputs": ["ankle_angle_rad", "motor_voltage_v"], "split_by": "cycles",
        "train_window_s": [0.3, 8.0], "held_out_window_s": [8.0, 11.998], "settle_s": 0.3,
        "noise_sigma": dict(NOISE), "declared_effects": [],
        "error_preset": {k: 2 * float(v) for k, v in eb.items()},
        "error_before": eb, "error_after": ea if found else dict(eb),
        "error_drop": (1 - ea["overall"] / eb["overall"]) if found else 0.0,
        "declared_fit": declared,
        "effects_selected": [effect] if found else [],
        "parameters": dict(declared, **({"piston_leakage.leakage_conductance_m3": 3.1e-15}
                                        if found else {})),
        "parameter_sd": {"motor_resistance_ohm": 0.004, "torque_constant_nm_a": 1e-4,
                         "seal_coulomb_force_n": 0.5, "liquid_bulk_modulus_pa": 3e7,
                         "piston_leakage.leakage_conductance_m3": 1.2e-16},
        "candidates": {
            "piston_leakage": {"scores": [0.61], "best_score": 0.61, "selected": found,
                               "refits": [{"round": 1, "score": 0.61, "delta_bic": -812.4,
                                           "delta_aic": -818.9, "held_out_overall": 0.01,
                                           "held_out_drop": 0.59, "relative_se": [0.04],
                                           "max_correlation": 0.3, "identifiable": True,
                                           "pays": found,
                                           "parameters": {"piston_leakage.leakage_"
                                                          "conductance_m3": 3.1e-15}}]},
            "backlash": {"scores": [0.02], "best_score": 0.02, "selected": False},
            "sensor_delay": {"scores": [0.11], "best_score": 0.11, "selected": False,
                             "refit_error": "non-finite residual in the fit"},
        },
        "residual_whiteness_before": {c: _whiteness(1e-9, 3.4) for c in OUTPUTS},
        "residual_whiteness_after": {c: _whiteness(0.4, 1.02) for c in OUTPUTS},
        "channels_before": {c: {"structured": verdict != "no_missing_effect"}
                            for c in OUTPUTS},
        "channels_after": {c: {"structured": verdict == "unexplained_residual"}
                           for c in OUTPUTS},
        "verdict": verdict,
        "unexplained_where": ("ankle_torque_nm: residual 3.4× the noise, peaks at 63 % of "
                              "the cycle" if verdict == "unexplained_residual" else None),
        "evaluations": np.int64(412), "wall_time_s": 31.2,
    }
    if with_series:
        r["_series"] = _series()
    return r


def test_writes_all_files_and_json_round_trips(tmp_path):
    rep = make_report()
    out = tmp_path / "cal"
    paths = write_calibration_report(rep, out, data_path=tmp_path / "rec.csv",
                                     command="afo-mj calibrate rec.csv")
    assert set(paths) == {"report.json", "report.md", *FIGURES}
    for p in paths.values():
        assert p.exists() and p.parent == out and p.stat().st_size > 0
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".cal.tmp")]
    with open(paths["report.json"]) as fh:
        doc = json.load(fh)
    for key in ("error_before", "error_after", "effects_selected", "candidates",
                "residual_whiteness_before", "residual_whiteness_after", "verdict"):
        assert key in doc
    assert "_series" not in doc
    assert doc["format"] == FORMAT
    assert doc["data"] == str(tmp_path / "rec.csv")
    assert doc["command"] == "afo-mj calibrate rec.csv"
    assert doc["evaluations"] == 412 and isinstance(doc["evaluations"], int)
    assert doc["error_before"]["pressure_a_pa"] == pytest.approx(0.03)
    assert doc["effects_selected"][0]["parameters"][
        "piston_leakage.leakage_conductance_m3"] == pytest.approx(3.1e-15)
    assert "NaN" not in paths["report.json"].read_text()


def test_nan_is_refused_naming_the_key_and_nothing_is_written(tmp_path):
    rep = make_report()
    rep["error_after"]["ankle_torque_nm"] = float("nan")
    out = tmp_path / "cal"
    with pytest.raises(ValueError, match=r"error_after\.ankle_torque_nm"):
        write_calibration_report(rep, out)
    assert not (out / "report.json").exists() and not (out / "report.md").exists()
    # an existing report is left as it was
    good = make_report(with_series=False)
    write_calibration_report(good, out)
    before = (out / "report.json").read_text()
    bad = make_report(with_series=False)
    bad["effects_selected"][0]["delta_bic"] = np.float64(np.inf)
    with pytest.raises(ValueError, match=r"effects_selected\[0\]\.delta_bic"):
        write_calibration_report(bad, out)
    assert (out / "report.json").read_text() == before
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".cal.tmp")]


def test_to_jsonable_converts_numpy_and_refuses_nan_in_arrays():
    doc = to_jsonable({"a": np.arange(3), "b": (np.float32(1.5), np.bool_(True)),
                       "c": {"d": np.array([[1.0, 2.0]])}})
    assert doc == {"a": [0, 1, 2], "b": [1.5, True], "c": {"d": [[1.0, 2.0]]}}
    json.dumps(doc, allow_nan=False)
    with pytest.raises(ValueError, match=r"x\.y"):
        to_jsonable({"x": {"y": np.array([1.0, np.nan])}})
    with pytest.raises(ValueError, match="object"):
        to_jsonable({"k": object()})


def test_markdown_names_verdict_effect_and_parameter(tmp_path):
    paths = write_calibration_report(make_report(), tmp_path / "cal")
    md = paths["report.md"].read_text()
    first = md.split("## ")[0]
    assert "Effect found" in first and "piston_leakage (cylinder)" in first
    assert "0.0244 → 0.0098" in first and "−60 %" in first
    assert "leakage_conductance_m3" in md and "3.1e-15" in md and "1.2e-16" in md
    assert "m³" in md                                  # unit from the effect library
    assert "Q = G_l Δp/μ" in md
    assert "-812.4" in md                              # ΔBIC bought
    assert "motor_resistance_ohm" in md and "Ω" in md   # declared parameters
    # candidates sorted by best score, the failed refit said
    assert md.index("`piston_leakage`", md.index("## Candidates")) \
        < md.index("`sensor_delay`", md.index("## Candidates")) \
        < md.index("`backlash`", md.index("## Candidates"))
    assert "refit failed" in md
    assert "## Residual whiteness" in md and "3.40" in md and "1.02" in md
    for f in FIGURES:
        assert f"]({f})" in md


def test_pngs_are_valid_and_not_blank(tmp_path):
    import matplotlib.image as mpimg
    paths = write_calibration_report(make_report(), tmp_path / "cal")
    for name in FIGURES:
        img = mpimg.imread(paths[name])
        assert img.ndim == 3 and img.shape[0] > 200 and img.shape[1] > 200
        assert float(np.std(img[..., :3])) > 0.0


@pytest.mark.parametrize("verdict, words", [
    ("effect_found", ["Effect found", "piston_leakage"]),
    ("no_missing_effect", ["No missing effect", "noise level"]),
    ("unexplained_residual", ["Unexplained residual", "no candidate",
                              "peaks at 63 % of the cycle"]),
])
def test_each_verdict_renders_its_sentence(tmp_path, verdict, words):
    rep = make_report(verdict, with_series=False)
    paths = write_calibration_report(rep, tmp_path / verdict)
    assert set(paths) == {"report.json", "report.md"}      # no series: no figures
    md = paths["report.md"].read_text()
    head = md.split("## ")[0]
    for w in words:
        assert w in head
    assert words[0] in verdict_sentence(json.loads(paths["report.json"].read_text()))


def test_report_is_not_modified(tmp_path):
    rep = make_report()
    snapshot = copy.deepcopy({k: v for k, v in rep.items() if k != "_series"})
    write_calibration_report(rep, tmp_path / "cal")
    assert "_series" in rep
    assert json.dumps(to_jsonable({k: v for k, v in rep.items() if k != "_series"})) \
        == json.dumps(to_jsonable(snapshot))


def test_markdown_gives_the_replay_step_and_each_step_tried(tmp_path):
    """The report's ``replay_step`` (chosen by the numerical check) is its own section: the
    step chosen and, per step tried, each channel's replay − Radau RMS over σ; a step stated
    in the scenario is said as such."""
    rep = make_report()
    rep["replay_step"] = {
        "source": "numerical_check", "max_step_s": 1.25e-4, "start_s": 5e-4,
        "floor_s": 6.25e-5, "target_ratio": 0.25, "window_s": [0.0, 2.0], "reached": True,
        "stalled": False, "tried": [
            {"max_step_s": 5e-4, "substeps": 2, "max_ratio": 1.0,
             "ratios": {"motor_current_a": 1.0, "pressure_a_pa": 0.6}},
            {"max_step_s": 2.5e-4, "substeps": 4, "max_ratio": 0.5,
             "ratios": {"motor_current_a": 0.5, "pressure_a_pa": 0.3}},
            {"max_step_s": 1.25e-4, "substeps": 8, "max_ratio": 0.24,
             "ratios": {"motor_current_a": 0.24, "pressure_a_pa": 0.15}}]}
    md = write_calibration_report(rep, tmp_path / "a")["report.md"].read_text()
    sec = md.split("## Replay step")[1].split("## ")[0]
    assert "Chosen: **0.125 ms**" in sec and "0.25 of its noise σ" in sec
    assert "| 0.25 | 4 | 0.50 | 0.30 |" in sec and "`motor_current_a` / σ" in sec
    rep["replay_step"] = {"source": "scenario", "max_step_s": 2e-4, "tried": [],
                          "reason": "[calibration] replay_max_step_s (no choice made)"}
    md = write_calibration_report(rep, tmp_path / "b")["report.md"].read_text()
    assert "at most 0.2 ms: [calibration] replay_max_step_s" in md


def _deviation(explains, worst):
    return {"parameter": "fluid.liquid_bulk_modulus_pa", "unit": "Pa", "datasheet": 1.6e9,
            "fitted": 4.34e9, "relative_change": 1.71, "relative_sd": 0.21,
            "tolerance": 0.3, "in_tolerances": 5.7,
            "equivalent_to": ["pump_leakage (effect, similarity 0.99)"],
            "explains_record": explains, "final_worst_ratio": worst}


def test_declared_values_beyond_tolerance_name_nothing_when_the_model_misses_the_record():
    """A declared value beyond its tolerance in a model that explains the record (every
    channel within the noise multiple) is a finding; in one that still misses it (rig 2's
    brush drop: the angle 65.6× its floor) the fit bent it, and the report says so."""
    from afo_mj.calibration.calibrate import explains_record
    base = {"noise_multiple": 2.0,
            "noise_floor": {"ankle_angle_rad": 0.002, "motor_current_a": 0.01}}
    devs = explains_record([{"parameter": "x"}],
                           {"ankle_angle_rad": 0.1313, "motor_current_a": 0.015}, base)
    assert devs[0]["explains_record"] is False
    assert devs[0]["final_worst_ratio"] == pytest.approx(65.65)
    devs = explains_record([{"parameter": "x"}],
                           {"ankle_angle_rad": 0.0039, "motor_current_a": 0.0199}, base)
    assert devs[0]["explains_record"] is True          # 1.95× and 1.99×, both within 2×
    assert devs[0]["final_worst_ratio"] == pytest.approx(1.99)


@pytest.mark.parametrize("explains, words, not_words", [
    (True, "either a wrong datasheet value", "names nothing"),
    (False, "(worst channel 65.6× its noise floor) names nothing", "either a wrong"),
])
def test_markdown_deviations_section_says_whether_they_explain(tmp_path, explains, words,
                                                               not_words):
    rep = make_report("unexplained_residual", with_series=False)
    rep["declared_deviations"] = [_deviation(explains, 1.0 if explains else 65.63)]
    md = write_calibration_report(rep, tmp_path / "cal")["report.md"].read_text()
    sec = md.split("## Declared parameters beyond their datasheet tolerance")[1].split("## ")[0]
    assert words in sec and not_words not in sec
    assert "`fluid.liquid_bulk_modulus_pa`" in sec
