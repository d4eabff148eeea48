"""Acceptance of the calibration (issue 7): blind runs on synthetic bench records.

Each record is written by :func:`afo_mj.calibration.synthetic_records.generate_record` with effects
the lean model does not declare, a mismatch of the declared parameters and white sensor noise;
``calibrate`` is told nothing but the record (its sidecar names the preset). The truth is known
here, so the tests check that the right effect is selected first, that the held-out NRMSE falls
by ≥ 70 %, that mismatch and noise alone add no effect, and that a resonance outside the library
is reported as ``unexplained_residual`` with where it lives.

The cases run in a pool of two processes (the suite's two cores), once per session.
"""

from __future__ import annotations

import concurrent.futures as cf
import json
import os
import subprocess
import sys
import warnings
from pathlib import Path

import pytest

from afo_mj.calibration.calibrate import (CalibrationOptions, calibrate, load_calibration_scenario,
                                          load_calibration_setup)
from afo_mj.calibration.synthetic_records import generate_record
from afo_mj.hydraulics.params import ParameterError

ROOT = Path(__file__).resolve().parents[1]
MISMATCH = {"seal_coulomb_force_n": 1.5, "liquid_bulk_modulus_pa": 0.8}
DURATION_S = 6.0

#: single undeclared effects: (kind, effect, parameters) — strong enough to matter
SINGLE = [
    ("hafo", "stribeck_friction", {"stribeck_force_n": 300.0, "stribeck_velocity_m_s": 0.01}),
    ("hafo", "pressure_friction", {"pressure_coefficient_m2": 3e-5}),
    ("hafo", "hose_wall_compliance", {"wall_compliance_1_pa": 4e-9}),
    ("hafo", "piston_leakage", {"leakage_conductance_m3": 8e-15}),
    ("hafo", "pump_leakage", {"extra_leakage_conductance_m3": 8e-15}),
    ("hafo", "motor_current_limit", {"current_limit_a": 4.0}),
    ("hafo", "series_compliance", {"compliance_rad_per_nm": 2e-3}),
    ("hafo", "sensor_delay", {"delay_s": 0.005}),
    ("valve", "valve_overlap", {"overlap": 0.1}),
    ("valve", "spool_lag", {"spool_time_constant_s": 0.01}),
]
PAIR = ("hafo", {"piston_leakage": {"leakage_conductance_m3": 8e-15},
                 "sensor_delay": {"delay_s": 0.005}})


def _case(args):
    name, kind, effects, extra, tmp = args
    warnings.simplefilter("ignore")
    data = generate_record(Path(tmp) / f"{name}.csv", kind, effects=effects, mismatch=MISMATCH,
                           duration_s=DURATION_S, seed=7, **extra)
    rep = calibrate(data)
    rep.pop("_series")
    return name, json.loads(json.dumps(rep, default=float))


@pytest.fixture(scope="module")
def results(tmp_path_factory):
    tmp = str(tmp_path_factory.mktemp("calibration"))
    single = [(f"{kind}-{eff}", kind, {eff: vals}, {}, tmp) for kind, eff, vals in SINGLE]
    valve = [c for c in single if c[1] == "valve"]
    # longest first, so that neither worker is left with a long case at the end: the valve
    # circuit's replays cost ~1.8x the HAFO's, the pair fits three rounds, the two cases
    # without a library effect one; a valve case and a HAFO case first, so that a cold cache
    # compiles the two circuits side by side, one per worker
    cases = [valve[0], ("pair", PAIR[0], PAIR[1], {}, tmp), *valve[1:],
             *[c for c in single if c[1] != "valve"],
             ("mismatch_only", "hafo", {}, {}, tmp),
             ("resonance", "hafo", {}, {"torque_sensor_resonance_hz": 25.0}, tmp)]
    workers = max(1, min(2, os.cpu_count() or 1))
    with cf.ProcessPoolExecutor(workers) as pool:
        return dict(pool.map(_case, cases))


#: cases the generated circuits do not pass yet, with the measured cause
KNOWN_FAILURES = {
    ("hafo", "hose_wall_compliance"): (
        "physically collinear with the fitted bulk modulus on this protocol: line and chamber "
        "relax through the hose in 0.28 ms (R_hose x series C at 25 C; corner above the 500 "
        "Hz Nyquist), so each side acts as one node, C = V_side(theta)/B + V_h k_wall; the "
        "two differ only through the piston's swing of V_side (rms 4.2 %), so 1 - rho ~ "
        "var(dV/V)/2 = 9e-4. Measured at "
        "the truth (jacobian of the training residuals, 0.2/1/3 % steps): generated circuit "
        "rho = 0.9992/0.9976/0.9916, old kernel 0.9917 (1 %), 0.986 (3 %). The old kernel's "
        "0.675 was finite-difference noise at its unconverged fit (B 0.54x, wall 3.4e-9; SSE "
        "2.121 vs 2.049 at the truth; rho there -0.66/0.67/0.98 at 0.2/1/3 % steps). Round 1 "
        "takes entrained_air (a = 0.088), round 2 the hose wall (4.0e-9 1/Pa, truth 4e-9)"),
}


@pytest.mark.slow
@pytest.mark.parametrize("kind,effect,values", [
    pytest.param(k, e, v, marks=[pytest.mark.xfail(strict=True, reason=KNOWN_FAILURES[k, e])]
                 if (k, e) in KNOWN_FAILURES else []) for k, e, v in SINGLE],
    ids=[f"{k}-{e}" for k, e, _ in SINGLE])
def test_undeclared_effect_is_found_first(results, kind, effect, values):
    rep = results[f"{kind}-{effect}"]
    chosen = [s["effect"] for s in rep["effects_selected"]]
    assert rep["verdict"] == "effect_found", (rep["verdict"], rep["unexplained_where"])
    assert chosen[0] == effect, chosen
    drop = 1.0 - rep["error_after"]["overall"] / rep["error_before"]["overall"]
    assert drop >= 0.70, (effect, rep["error_before"]["overall"], rep["error_after"]["overall"])
    # the first effect's fitted parameters are the truth's, within 4 of their standard errors
    # or 30 % (the noise, the mismatch and the lean model's other effects all leave a bias)
    first = rep["effects_selected"][0]
    for pname, truth in values.items():
        key = f"{effect}.{pname}"
        got = first["parameters"][key]
        sd = first["uncertainties"][key] or 0.0
        assert abs(got - truth) <= max(4 * sd, 0.3 * abs(truth)), (key, got, sd, truth)


@pytest.mark.slow
def test_collinear_hose_wall_is_still_found_with_its_value(results):
    """The hose wall is collinear with the fitted bulk modulus on this protocol (the xfail
    above): it cannot come first, but it must not be lost: it is selected in a later round with
    the truth's compliance (within 30 %), and the held-out error still falls by ≥ 70 %."""
    rep = results["hafo-hose_wall_compliance"]
    assert rep["verdict"] == "effect_found", rep["unexplained_where"]
    sel = {s["effect"]: s for s in rep["effects_selected"]}
    assert "hose_wall_compliance" in sel, list(sel)
    got = sel["hose_wall_compliance"]["parameters"]["hose_wall_compliance.wall_compliance_1_pa"]
    assert abs(got - 4e-9) <= 0.3 * 4e-9, got
    drop = 1.0 - rep["error_after"]["overall"] / rep["error_before"]["overall"]
    assert drop >= 0.70, drop


@pytest.mark.slow
def test_at_least_eight_effects_on_both_circuits(results):
    found = {(k, e) for k, e, _ in SINGLE
             if [s["effect"] for s in results[f"{k}-{e}"]["effects_selected"]][:1] == [e]}
    assert len(found) >= 8
    assert {k for k, _ in found} == {"hafo", "valve"}


@pytest.mark.slow
def test_two_effects_at_once_are_both_found(results):
    rep = results["pair"]
    chosen = {s["effect"] for s in rep["effects_selected"]}
    assert set(PAIR[1]) <= chosen, chosen
    assert rep["error_after"]["overall"] <= 0.3 * rep["error_before"]["overall"]


@pytest.mark.slow
def test_mismatch_and_noise_alone_add_no_effect(results):
    rep = results["mismatch_only"]
    assert rep["verdict"] == "no_missing_effect", rep["unexplained_where"]
    assert rep["effects_selected"] == []
    # the declared fit found the mismatched parameters
    fit = rep["declared_fit"]
    assert fit["liquid_bulk_modulus_pa"] == pytest.approx(0.8 * 1.5e9, rel=0.05)
    # ... and what is left is the sensor noise: every channel white, within 1.2x its σ
    for ch, w in rep["residual_whiteness_before"].items():
        assert w["excess_ratio"] < 1.2, (ch, w)


@pytest.mark.slow
def test_resonance_outside_the_library_is_unexplained_and_located(results):
    rep = results["resonance"]
    assert rep["verdict"] == "unexplained_residual", [s["effect"] for s in
                                                      rep["effects_selected"]]
    where = rep["unexplained_where"]
    assert "ankle_torque_nm" in where
    f = rep["channels_before"]["ankle_torque_nm"]["dominant_frequency_hz"]
    assert f == pytest.approx(25.0, rel=0.1)


@pytest.mark.slow
def test_report_has_the_issue_keys(results):
    rep = results["hafo-piston_leakage"]
    for key in ("error_before", "error_after", "effects_selected", "candidates",
                "residual_whiteness_before", "residual_whiteness_after", "verdict"):
        assert key in rep
    assert len(rep["candidates"]) >= 10
    s = rep["effects_selected"][0]
    assert {"parameters", "uncertainties", "held_out_drop"} <= set(s)


def test_bad_setup_is_refused(tmp_path):
    with pytest.raises(ParameterError, match="preset"):
        load_calibration_setup("no_such_preset")
    bad = tmp_path / "s.toml"
    bad.write_text('[device]\npreset = "hafo"\n[calibration]\nheld_out = 0.3\n')
    with pytest.raises(ParameterError, match="held_out"):
        load_calibration_setup(str(bad))
    with pytest.raises(ParameterError, match="held_out_fraction"):
        CalibrationOptions(held_out_fraction=1.5)
    for f in sorted((ROOT / "scenarios" / "calibration").glob("*.toml")):
        setup = load_calibration_scenario(str(f))
        if setup.circuit is not None:       # a rig described as a circuit
            assert setup.preset is None and setup.load is not None
            with pytest.raises(ParameterError, match="device.preset"):
                load_calibration_setup(str(f))
            continue
        preset, ov, opts = load_calibration_setup(str(f))
        assert preset == f.stem and opts.max_effects == 3
        assert (setup.preset, setup.options) == (preset, opts)


@pytest.mark.slow
def test_cli_end_to_end(tmp_path):
    """make-bench-record then calibrate through the command line: report files, verdict."""
    env = dict(os.environ, MUJOCO_GL="egl")
    rec = tmp_path / "bench.csv"
    r = subprocess.run([sys.executable, "-m", "afo_mj.cli", "make-bench-record", "--kind",
                        "hafo", "--effect", "piston_leakage:leakage_conductance_m3=1e-14",
                        "--duration-s", "5", "--out", str(rec)], capture_output=True,
                       text=True, env=env, cwd=ROOT)
    assert r.returncode == 0, r.stderr
    out = tmp_path / "cal"
    # the plumbing, not the search (the acceptance cases above search the whole library):
    # a setup file that narrows the candidates
    setup = tmp_path / "setup.toml"
    setup.write_text('[device]\npreset = "hafo"\n[calibration]\ncandidates = '
                     '["piston_leakage", "pump_leakage", "sensor_delay"]\n')
    r = subprocess.run([sys.executable, "-m", "afo_mj.cli", "calibrate", "--scenario",
                        str(setup), "--data", str(rec),
                        "--out", str(out)], capture_output=True, text=True, env=env, cwd=ROOT)
    assert r.returncode == 0, r.stderr
    assert json.loads(r.stdout.strip().splitlines()[-1])["effects"][0] == "piston_leakage"
    rep = json.loads((out / "report.json").read_text())
    assert rep["verdict"] == "effect_found"
    for f in ("report.md", "fit_before_after.png", "residual_before_after.png"):
        assert (out / f).stat().st_size > 0
    # bad data: nothing written, exit 2
    r = subprocess.run([sys.executable, "-m", "afo_mj.cli", "calibrate", "--scenario", "hafo",
                        "--data", str(tmp_path / "missing.csv"), "--out",
                        str(tmp_path / "none")], capture_output=True, text=True, env=env,
                       cwd=ROOT)
    assert r.returncode == 2 and not (tmp_path / "none").exists()
    assert "missing" in r.stderr and "sidecar" in r.stderr
