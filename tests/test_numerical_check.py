"""The calibration's numerical check (afo_mj/calibration/numerical_check.py) on a record of the
independent rig (tests/independent_rig.py: its own equations and solver, not afo_mj's): the
replay-vs-Radau difference per channel against the noise, growing with the replay's step; what
accounts for a channel beyond its noise multiple (Calibration.attribution) and the "where"."""

from __future__ import annotations

import sys
import types
from pathlib import Path

import numpy as np
import pytest

from afo_mj.calibration.calibrate import (Calibration, CalibrationOptions,
                                          load_calibration_scenario)
from afo_mj.calibration.numerical_check import numerical_error_check, numerical_where
from afo_mj.hydraulics.params import ParameterError

RIG_SCENARIO = Path(__file__).resolve().parents[1] / "scenarios" / "calibration" / "lab_rig.toml"


@pytest.fixture(scope="module")
def calibration(tmp_path_factory):
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    import independent_rig
    data = independent_rig.write_record(tmp_path_factory.mktemp("rec") / "clean.csv",
                                        duration_s=1.5, seed=3)
    setup = load_calibration_scenario(str(RIG_SCENARIO))
    cal = Calibration(data, "lab_rig", CalibrationOptions(uncalibrated_channels=()),
                      replay=setup.replay())
    return cal


def _check(cal, step):
    old = cal.replay.max_step_s
    cal.replay.max_step_s = step
    try:
        return numerical_error_check(cal, [], np.ones(len(cal.declared)), 1.0, 2.0)
    finally:
        cal.replay.max_step_s = old


def test_numerical_error_against_the_noise_grows_with_the_replay_step(calibration):
    """The datasheet model on 1 s of the independent rig's clean record: at the replay's
    0.5 ms the stepper's error is a visible part of the motor current's residual, at 1 ms more,
    and at 0.0625 ms it is below half the noise on every channel: the replay converges onto the
    Radau check, so what the check reports is the stepper's own error (measured: motor current
    4.06, 1.23, 0.17× its σ at 1, 0.5, 0.0625 ms; pressure_a 0.89, 0.53, 0.08×)."""
    coarse, default, fine = (_check(calibration, s) for s in (1e-3, 5e-4, 6.25e-5))
    for chk in (coarse, default, fine):
        assert chk["run"], chk
        assert set(chk["channels"]) | set(chk["not_compared"]) == set(calibration.outputs)
    for c in ("motor_current_a", "pressure_a_pa", "ankle_torque_nm"):
        assert coarse["channels"][c]["ratio"] > default["channels"][c]["ratio"] \
            > 2.0 * fine["channels"][c]["ratio"], c
    assert default["channels"]["motor_current_a"]["ratio"] > 0.5
    assert fine["max_ratio"] < 0.5, fine["max_ratio"]
    where = numerical_where(default)
    assert where is not None and "motor_current_a" in where and "Radau" in where
    assert numerical_where(fine) is None


def test_the_check_says_why_it_did_not_run(calibration):
    off = numerical_error_check(calibration, [], np.ones(len(calibration.declared)), 0.0, 2.0)
    assert off == {"run": False, "reason": "calibration.numerical_check_s = 0 (not asked for)"}
    short = numerical_error_check(calibration, [], np.ones(len(calibration.declared)), 0.2, 2.0)
    assert not short["run"] and "settle_s" in short["reason"]


@pytest.mark.parametrize("bad", [-1.0, 61.0, True])
def test_numerical_check_window_outside_its_range_is_refused(bad):
    with pytest.raises(ParameterError, match="numerical_check_s"):
        CalibrationOptions(numerical_check_s=bad)


def _summary(excess, drift=False, resonance=False):
    return {"structured": True, "whiteness": {"white": False}, "excess_ratio": excess,
            "drift": {"drift": drift, "window_means": [0.0, 1.0], "window_s": 1.0,
                      "ratio": 3.0, "change": 1.0, "noise_sigma": 1.0},
            "transient": {"transient": False},
            "resonance": {"resonance": resonance, "frequency_hz": 80.0, "rms": 1.0,
                          "ratio": 1.0}}


def test_structure_wrong_only_for_a_channel_nothing_accounts_for():
    """Four channels beyond 2× their floor: one the numerical check explains, one with a
    named resonance, one a data-driven discrepancy brings within 2σ, one with nothing: only
    the last is unexplained; a discrepancy that stays above 2σ does not count."""
    chans = ["motor_current_a", "ankle_torque_nm", "motor_speed_rad_s", "piston_position_m"]
    ns = types.SimpleNamespace(noise={c: 1.0 for c in chans})
    before = types.SimpleNamespace(baseline={"noise_multiple": 2.0,
                                             "ratio": {c: 3.0 for c in chans}})
    after = types.SimpleNamespace(channels={
        "motor_current_a": _summary(3.0), "ankle_torque_nm": _summary(3.0, resonance=True),
        "motor_speed_rad_s": _summary(3.0), "piston_position_m": _summary(3.0)})
    numerical = {"run": True, "explains_excess": ["motor_current_a"]}
    disc = {"motor_speed_rad_s": {"found": True, "held_out_rms_after": 1.5},
            "piston_position_m": {"found": True, "held_out_rms_after": 2.5}}
    att = Calibration.attribution(ns, before, after, numerical, disc)
    by = {c: v["explained_by"] for c, v in att["channels"].items()}
    assert by == {"motor_current_a": ["numerical_error"], "ankle_torque_nm": ["resonance"],
                  "motor_speed_rad_s": ["data_driven_discrepancy"], "piston_position_m": []}
    assert att["unexplained"] == ["piston_position_m"]
