"""Records whose command hold is what their sidecar declares (issue 41, follow-ups of item 1).

* The synthetic records (:func:`afo_mj.calibration.synthetic_records.generate_record`) write the
  hold their command really has: by default a DAC-like command held zero-order between updates,
  or a band-limited continuous one (``command_hold="linear"``). Calibrated with the declared
  hold, the record raises no hold warning; declared wrong, it does (the reference is the
  detector of :mod:`afo_mj.calibration.sampling`, which looks only at the data).
* The independent rig (``tests/independent_rig.py``, its own equations and scipy's Radau)
  gains a stepped command held zero-order between digital updates, integrated interval by
  interval; calibrated blind with the declared hold its clean record reaches the noise floor,
  and the wrong (linear) hold leaves the larger current residual.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

from afo_mj.calibration.calibrate import Calibration, CalibrationOptions
from afo_mj.calibration.synthetic_records import generate_record
from afo_mj.hydraulics.params import ParameterError

ROOT = Path(__file__).resolve().parents[1]
OTHER = {"zero_order": "linear", "linear": "zero_order"}


@pytest.mark.parametrize("kind", ["hafo", "valve"])
@pytest.mark.parametrize("hold, update_s", [("zero_order", None), ("zero_order", 0.003),
                                            ("linear", None)])
def test_synthetic_record_declares_the_hold_it_has(tmp_path, kind, hold, update_s):
    data = generate_record(tmp_path / "r.csv", kind, duration_s=3.0, seed=7,
                           command_hold=hold, command_update_s=update_s)
    cmd = "motor_voltage_v" if kind == "hafo" else "valve_command"
    assert dict(data.hold) == {cmd: hold}
    cal = Calibration(data, options=CalibrationOptions())
    assert cal.hold_warnings == [], cal.hold_warnings
    assert cal.input_hold[cmd]["hold"] == hold and cal.input_hold[cmd]["detected"] == hold
    # the same record declared wrong (the scenario overrides the sidecar) is flagged
    wrong = Calibration(data, options=CalibrationOptions(hold={cmd: OTHER[hold]}))
    assert len(wrong.hold_warnings) == 1 and cmd in wrong.hold_warnings[0]
    assert f"data look {hold}" in wrong.hold_warnings[0]


def test_zero_order_command_is_held_between_updates(tmp_path):
    """A DAC updated every 3 ms logged at 1 kHz: runs of three equal samples, the values
    at the update instants being those of the every-sample command."""
    every = generate_record(tmp_path / "a.csv", duration_s=2.0, seed=3)
    slow = generate_record(tmp_path / "b.csv", duration_s=2.0, seed=3, command_update_s=0.003)
    u1 = np.asarray(every.channels["motor_voltage_v"])
    u3 = np.asarray(slow.channels["motor_voltage_v"])
    k = np.arange(len(u1))
    np.testing.assert_array_equal(u3, u1[(k // 3) * 3])


def test_linear_command_is_the_continuous_one_sampled(tmp_path):
    """The continuous command and the held one share the step schedule (same seed): they
    differ only within the 5 ms rise after each step, and the continuous one has no jumps
    larger than its rise allows."""
    held = np.asarray(generate_record(tmp_path / "a.csv", duration_s=3.0, seed=5)
                      .channels["motor_voltage_v"])
    cont = np.asarray(generate_record(tmp_path / "b.csv", duration_s=3.0, seed=5,
                                      command_hold="linear").channels["motor_voltage_v"])
    differ = np.abs(held - cont) > 1e-12
    assert 0.0 < differ.mean() < 0.05
    # a raised-cosine rise of 5 ms moves at most π/2 · step / 5 samples per sample (8 V steps)
    assert np.max(np.abs(np.diff(cont))) < np.pi / 2 * 8.0 / 5.0
    assert np.max(np.abs(np.diff(held))) > 1.0


@pytest.mark.parametrize("kw, match", [
    ({"command_hold": "step"}, "command_hold = 'step'; allowed: 'zero_order', 'linear'"),
    ({"command_update_s": 0.0025}, "command_update_s = 0.0025; allowed: a whole number"),
    ({"command_hold": "linear", "command_update_s": 0.002}, "only with"),
])
def test_generator_refuses_bad_hold_options(tmp_path, kw, match):
    with pytest.raises(ParameterError, match=match):
        generate_record(tmp_path / "r.csv", duration_s=2.0, **kw)


# ---------------------------------------------------------------- the independent rig, stepped
STEP_UPDATE_S = 2e-3


@pytest.fixture(scope="module")
def stepped_record(tmp_path_factory):
    """A clean 2 s record of the independent rig whose voltage is a digital command updated
    every 2 ms and held (logged at 1 kHz)."""
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    import independent_rig
    return independent_rig.write_record(tmp_path_factory.mktemp("stepped") / "clean.csv",
                                        duration_s=2.0, seed=3,
                                        command_update_s=STEP_UPDATE_S)


def _rig_setup(**options):
    from afo_mj.calibration.calibrate import load_calibration_scenario
    setup = load_calibration_scenario(str(ROOT / "scenarios" / "calibration" / "lab_rig.toml"))
    return type(setup)(setup.preset, setup.overrides,
                       CalibrationOptions(uncalibrated_channels=(),
                                          **({"max_effects": 1, "refit_top": 2} | options)),
                       setup.circuit, setup.load, setup.signals)


@pytest.mark.slow
def test_stepped_rig_record_reaches_the_floor_with_its_declared_hold(stepped_record):
    """Blind: the clean stepped-command record, replayed zero-order as its sidecar declares:
    no hold warning, ``no_missing_effect``, nothing named, every channel's held-out baseline
    within 2× its noise floor; the same record replayed with the wrong (linear) hold is flagged
    and leaves the larger motor-current residual (the smeared steps drive the fast current)."""
    from afo_mj.calibration.calibrate import calibrate_setup
    data = stepped_record
    assert dict(data.hold) == {"motor_voltage_v": "zero_order"}
    rep = calibrate_setup(data, _rig_setup())
    ratio = rep["baseline"]["ratio"]
    print("declared zero_order:", rep["verdict"], ratio)
    # the wrong hold shows in the declared fit already: no search for effects on it
    wrong = calibrate_setup(data, _rig_setup(hold={"motor_voltage_v": "linear"}, max_effects=0))
    print("wrong linear:", wrong["verdict"], wrong["baseline"]["ratio"])
    assert rep["hold_warnings"] == []
    assert len(wrong["hold_warnings"]) == 1
    assert wrong["baseline"]["ratio"]["motor_current_a"] > ratio["motor_current_a"]
    assert rep["verdict"] == "no_missing_effect" and rep["effects_selected"] == []
    assert max(ratio.values()) < 2.0, ratio
