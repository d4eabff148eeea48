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
