"""The bench replay's numerical check (afo_mj/experiments/replay_reference.py): the generic Radau
integration of a described circuit on a record's inputs, against the lab bench written out by
hand as one ODE (tests/circuit_reference.py, a second implementation that shares the laws but
neither the generated assembly nor the stepper), and the check's figure, the replay-vs-Radau
difference, growing with the replay's step."""

from __future__ import annotations

import numpy as np
import pytest
from circuit_reference import ROWS, nrmse, reference_lab_bench

from afo_mj.circuits.device import JointLoad
from afo_mj.circuits.library import lab_bench
from afo_mj.experiments.bench_replay import BenchReplay
from afo_mj.experiments.replay_reference import ReferenceUnavailable, reference_replay

INERTIA, K_LOAD, C_LOAD = 0.01, 20.0, 0.3
T_END = 0.2
#: a digital voltage command (switches on the 1 ms grid, held between samples)
SWITCHES = ((0.01, 6.0), (0.08, -8.0), (0.15, 3.0))


def _cmd(t: float) -> float:
    v = 0.0
    for ts, val in SWITCHES:
        if t >= ts - 1e-12:
            v = val
    return v


def _record():
    t = np.arange(int(round(T_END / 1e-3)) + 1) * 1e-3
    return t, {"motor_voltage_v": np.array([_cmd(x) for x in t])}


def _replay(**kw) -> BenchReplay:
    r = BenchReplay(circuit=lab_bench(), load=JointLoad(INERTIA, K_LOAD, C_LOAD))
    r.set_hold({"motor_voltage_v": "zero_order"})
    for k, v in kw.items():
        setattr(r, k, v)
    return r


@pytest.fixture(scope="module")
def hand_reference():
    return reference_lab_bench(lab_bench(), _cmd, T_END, INERTIA, K_LOAD, C_LOAD, rtol=1e-7)


#: the replay's output channel of each row of the hand-written reference
CHANNELS = {"motor_current_a": "motor.current_a", "motor_speed_rad_s": "shaft",
            "pressure_a_pa": "line_a", "pressure_b_pa": "line_b",
            "chamber_a_pa": "chamber_a", "chamber_b_pa": "chamber_b",
            "ankle_angle_rad": "angle_rad"}


def test_generic_radau_check_matches_the_hand_written_lab_bench(hand_reference):
    """The generic check on the lab bench (simulated load, zero-order voltage) agrees with the
    hand-written Radau reference to 1e-5 of each signal's range (measured against the hand
    reference at rtol 1e-9: ≤ 2.1e-9); the 0.5 ms replay is off by far more (measured 0.6 % of
    range on the angle, 1 % on the shaft speed, 11–13 % on the pressures and the current: the
    load's lightly damped mode on the oil spring, which the coupled semi-implicit Euler step
    damps), so the check resolves the stepper's own error."""
    t, inputs = _record()
    r = _replay()
    ref = reference_replay(r, t, inputs)
    rep = r.simulate(t, inputs)
    assert set(ref.not_compared) == {"battery_current_a", "bus_voltage_v"}
    assert ref.below_floor_samples == 0
    for ch, sig in CHANNELS.items():
        hand = hand_reference.y[ROWS[sig]]
        ours = ref.outputs[ch][1:]
        e_check = nrmse(ours, hand)
        e_replay = nrmse(rep[ch][1:], hand)
        assert e_check < 1e-5, (ch, e_check)
        assert e_replay > 100 * e_check, (ch, e_replay, e_check)


def test_numerical_error_grows_with_the_replay_step():
    """The replay-vs-Radau difference shrinks with the replay's step, about halving with it
    (first-order backward Euler; measured on pressure_a RMS: 337, 198, 115 kPa at 1, 0.5 and
    0.25 ms)."""
    t, inputs = _record()
    ref = reference_replay(_replay(), t, inputs).outputs["pressure_a_pa"]
    diffs = []
    for step in (1e-3, 5e-4, 2.5e-4):
        d = _replay(max_step_s=step).simulate(t, inputs)["pressure_a_pa"] - ref
        diffs.append(float(np.sqrt(np.mean(d ** 2))))
    assert diffs[0] > 1.5 * diffs[1] > 1.5 * 1.5 * diffs[2], diffs


def test_imposed_angle_replay_converges_to_the_check():
    """Without a load (the angle imposed), the replay at a smaller step approaches the
    check's answer: the error at 0.1 ms is below a third of that at 1 ms."""
    t = np.arange(151) * 1e-3
    inputs = {"motor_voltage_v": 5.0 * np.sin(2 * np.pi * 3.0 * t),
              "ankle_angle_rad": 0.1 * np.sin(2 * np.pi * 2.0 * t)}
    r = BenchReplay(circuit=lab_bench())
    ref = reference_replay(r, t, inputs).outputs["chamber_a_pa"]
    errs = []
    for step in (1e-3, 1e-4):
        r.max_step_s = step
        d = r.simulate(t, inputs)["chamber_a_pa"] - ref
        errs.append(float(np.sqrt(np.mean(d ** 2))))
    assert errs[1] < errs[0] / 3.0, errs


def test_a_torque_reference_is_refused_with_its_reason():
    t = np.arange(11) * 1e-3
    r = BenchReplay("hafo")
    with pytest.raises(ReferenceUnavailable, match="torque controller"):
        reference_replay(r, t, {"commanded_torque_nm": np.zeros(11),
                                "ankle_angle_rad": np.zeros(11)})


def test_rtol_outside_its_range_is_refused():
    t, inputs = _record()
    with pytest.raises(ValueError, match="rtol"):
        reference_replay(_replay(), t, inputs, rtol=0.1)
