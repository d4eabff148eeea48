"""Issue 41 item 1: how a record's input was held between samples is declared (sidecar
``[hold]``, scenario ``[calibration.hold]``), detected from the data and checked, and the replay
honours it.

References: the detector's verdicts are checked on signals built here with a known hold (a
command updated at a known rate and held, a band-limited continuous signal); the replay's
hold is checked against the same circuit replayed on a grid eight times finer on which the
held command is exact (each fine sample holds the 1 kHz command), so the zero-order replay of
the 1 kHz record must come closer to it than the linear one.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.signal import butter, filtfilt

from afo_mj.calibration.calibrate import (
    Calibration, CalibrationOptions, load_calibration_scenario)
from afo_mj.calibration.measured_data import MeasuredDataError, load_measured, write_measured
from afo_mj.calibration.sampling import check_holds, detect_hold
from afo_mj.experiments.bench_replay import BenchReplay
from afo_mj.hydraulics.params import ParameterError

LAB_RIG = "scenarios/calibration/lab_rig.toml"


def held_command(fs_hz, update_hz, duration_s=2.0, quantum=None, noise=0.0, seed=0):
    """A digital command updated at ``update_hz`` and held, logged at ``fs_hz``: a sine plus
    a square wave evaluated at the update instants (runs of fs/update equal samples)."""
    rng = np.random.default_rng(seed)
    t = np.arange(int(duration_s * fs_hz)) / fs_hz
    tu = np.floor(t * update_hz + 1e-9) / update_hz
    u = 3.0 * np.sin(2 * np.pi * 1.3 * tu) + 2.0 * np.sign(np.sin(2 * np.pi * 0.7 * tu + 0.1))
    if quantum:
        u = np.round(u / quantum) * quantum
    return u + noise * rng.standard_normal(len(u))


def continuous(fs_hz, bandwidth_hz, duration_s=2.0, noise=0.0, quantum=None, seed=1):
    """Band-limited Gaussian noise (4th-order Butterworth, zero phase), unit SD."""
    rng = np.random.default_rng(seed)
    n = int(duration_s * fs_hz)
    b, a = butter(4, bandwidth_hz / (fs_hz / 2))
    y = filtfilt(b, a, rng.standard_normal(n))
    y /= np.std(y)
    if quantum:
        y = np.round(y / quantum) * quantum
    return y + noise * rng.standard_normal(n)


# ---------------------------------------------------------------------------- detector

@pytest.mark.parametrize("fs_hz, update_hz", [(1000, 100), (1000, 250), (2000, 100),
                                              (1000, 1000 / 3), (5000, 500), (500, 50)])
def test_held_command_is_zero_order(fs_hz, update_hz):
    run = fs_hz / update_hz
    ev = detect_hold(held_command(fs_hz, update_hz))
    assert ev.verdict == "zero_order", ev
    # runs of fs/update equal samples: the repeated fraction is 1 - 1/run
    assert ev.repeat_fraction == pytest.approx(1.0 - 1.0 / run, abs=0.02)
    assert ev.median_run_samples == pytest.approx(run, abs=1.0)
    # a 12-bit DAC over ±12 V: quantisation keeps the runs
    ev_q = detect_hold(held_command(fs_hz, update_hz, quantum=24.0 / 4096))
    assert ev_q.verdict == "zero_order", ev_q


@pytest.mark.parametrize("fs_hz, update_hz, noise", [(1000, 100, 0.01), (1000, 250, 0.03),
                                                     (2000, 100, 0.003), (5000, 500, 0.01)])
def test_held_command_with_sensor_noise_is_zero_order(fs_hz, update_hz, noise):
    ev = detect_hold(held_command(fs_hz, update_hz, noise=noise))
    assert ev.repeat_fraction < 0.01
    assert ev.verdict == "zero_order", ev
    # jumps happen only at updates: their spacing is at least one update interval
    assert ev.median_run_samples >= fs_hz / update_hz - 0.5


@pytest.mark.parametrize("fs_hz", [500, 1000, 5000])
@pytest.mark.parametrize("bandwidth_hz", [5.0, 20.0, 100.0])
def test_band_limited_signal_is_linear(fs_hz, bandwidth_hz):
    for noise in (0.0, 0.001, 0.01, 0.1):
        ev = detect_hold(continuous(fs_hz, bandwidth_hz, noise=noise))
        assert ev.verdict == "linear", (noise, ev)
    # a 12-bit ADC over ±2.5 SD: repeats where the signal is slow, each step one quantum
    ev = detect_hold(continuous(fs_hz, bandwidth_hz, quantum=5.0 / 4096))
    assert ev.verdict == "linear", ev


@pytest.mark.parametrize("fs_hz", [200, 1000, 10000])
def test_slow_ramp_and_constant(fs_hz):
    t = np.arange(2 * fs_hz) / fs_hz
    assert detect_hold(0.1 * t + 0.3).verdict == "linear"
    # quantised to 1/4096 while moving 0.01/s: runs of ~fs/41 samples, each step one quantum
    # (criterion 2)
    ramp_q = np.round(0.01 * t * 4096) / 4096
    ev = detect_hold(ramp_q)
    assert ev.repeat_fraction > 0.5 and ev.verdict == "linear", ev
    ev = detect_hold(np.full(len(t), 2.5))
    assert ev.verdict == "undecided" and ev.repeat_fraction == 1.0


def test_check_holds_warns_on_contradiction_only():
    u = held_command(1000, 100)
    report, warns = check_holds({"motor_voltage_v": u}, {"motor_voltage_v": "zero_order"},
                                {"motor_voltage_v": "declared in the record's sidecar [hold]"})
    assert warns == [] and report["motor_voltage_v"]["detected"] == "zero_order"
    report, warns = check_holds({"motor_voltage_v": u}, {"motor_voltage_v": "linear"},
                                {"motor_voltage_v": "declared in the record's sidecar [hold]"})
    assert len(warns) == 1
    assert "motor_voltage_v" in warns[0] and "linear" in warns[0] and "zero_order" in warns[0]
    assert "90 %" in warns[0] and "declaration is kept" in warns[0]
    assert report["motor_voltage_v"]["hold"] == "linear"


# ---------------------------------------------------------------------------- declaration

def _record(tmp_path, hold=None, name="rec.csv"):
    """A lab-rig record: the stepped voltage replayed zero-order (the truth of the replay
    test), its outputs as measured."""
    t, u, truth = _lab_truth(duration_s=0.5)
    data = {"time_s": t, "motor_voltage_v": u,
            "pressure_a_pa": truth["pressure_a_pa"], "motor_current_a": truth["motor_current_a"]}
    return write_measured(tmp_path / name, data, ["motor_voltage_v"],
                          ["pressure_a_pa", "motor_current_a"],
                          {"preset": "lab_rig"}, unit_checks=False, hold=hold)


def test_sidecar_hold_round_trip_and_errors(tmp_path):
    rec = _record(tmp_path, hold={"motor_voltage_v": "zero_order"})
    assert dict(rec.hold) == {"motor_voltage_v": "zero_order"}
    assert 'motor_voltage_v = "zero_order"' in (tmp_path / "rec.toml").read_text()
    back = load_measured(tmp_path / "rec.csv", unit_checks=False)
    assert dict(back.hold) == {"motor_voltage_v": "zero_order"}
    with pytest.raises(MeasuredDataError, match=r"hold.motor_voltage_v: 'step'; allowed: "
                                                r"'zero_order', 'linear'"):
        _record(tmp_path, hold={"motor_voltage_v": "step"}, name="bad.csv")
    with pytest.raises(MeasuredDataError, match=r"hold.pressure_a_pa: .*not an input"):
        _record(tmp_path, hold={"pressure_a_pa": "linear"}, name="bad2.csv")


def test_scenario_hold_is_validated():
    opts = CalibrationOptions(hold={"motor_voltage_v": "zero_order"})
    assert opts.hold == (("motor_voltage_v", "zero_order"),)
    with pytest.raises(ParameterError, match=r"calibration.hold.motor_voltage_v = 'held'; "
                                             r"allowed: zero_order, linear"):
        CalibrationOptions(hold={"motor_voltage_v": "held"})
    with pytest.raises(ParameterError, match=r"calibration.hold.motor_volts: unknown channel"):
        CalibrationOptions(hold={"motor_volts": "linear"})
    rep = BenchReplay("hafo")
    with pytest.raises(ParameterError, match=r"hold.ankle_angle_rad = 'zero_order'.*allowed: "
                                             r"linear"):
        rep.set_hold({"ankle_angle_rad": "zero_order"})


def test_scenario_file_hold_reaches_options(tmp_path):
    text = open(LAB_RIG, encoding="utf-8").read()
    text = text.replace("[calibration]\n",
                        "[calibration]\nhold = { motor_voltage_v = \"zero_order\" }\n")
    p = tmp_path / "rig.toml"
    p.write_text(text, encoding="utf-8")
    setup = load_calibration_scenario(str(p))
    assert dict(setup.options.hold) == {"motor_voltage_v": "zero_order"}


# ---------------------------------------------------------------------------- replay

def _lab_truth(duration_s=1.0, fs_hz=1000.0, up=8, seed=1):
    """The lab rig (simulated foot) driven by a stepped 1 kHz digital voltage, replayed on a
    grid ``up`` times finer where each fine sample holds the 1 kHz command (exact zero-order
    hold), outputs taken at the 1 kHz instants."""
    rng = np.random.default_rng(seed)
    n = int(duration_s * fs_hz)
    u = np.zeros(n)
    k = 0
    while k < n:
        run = int(rng.integers(20, 80))
        u[k:k + run] = rng.uniform(-6.0, 6.0)
        k += run
    t = np.arange(n) / fs_hz
    rep = load_calibration_scenario(LAB_RIG).replay()
    tf = np.arange((n - 1) * up + 1) / (fs_hz * up)
    fine = rep.simulate(tf, {"motor_voltage_v": np.repeat(u, up)[:len(tf)]})
    return t, u, {c: v[::up] for c, v in fine.items()}


def test_zero_order_replay_matches_a_zero_order_record_better():
    t, u, truth = _lab_truth()
    rep = load_calibration_scenario(LAB_RIG).replay()
    assert rep.default_hold == "linear"
    err = {}
    for hold in ("zero_order", "linear"):
        rep.set_hold({"motor_voltage_v": hold})
        assert rep.hold_of("motor_voltage_v") == hold
        out = rep.simulate(t, {"motor_voltage_v": u})
        err[hold] = {c: float(np.sqrt(np.mean((out[c] - truth[c]) ** 2)))
                     for c in ("motor_current_a", "pressure_a_pa", "ankle_angle_rad")}
    # the current follows the voltage within L/R = 0.17 ms: a 1 ms ramp instead of the step
    # is the largest error of a linear replay
    assert err["zero_order"]["motor_current_a"] < 0.3 * err["linear"]["motor_current_a"]
    for c in ("pressure_a_pa", "ankle_angle_rad"):
        assert err["zero_order"][c] < err["linear"][c]
    # the replay's constructor takes the declaration too
    rep2 = BenchReplay(circuit=rep.circuit, load=rep.load, hold={"motor_voltage_v": "zero_order"})
    out2 = rep2.simulate(t, {"motor_voltage_v": u})
    rep.set_hold({"motor_voltage_v": "zero_order"})
    np.testing.assert_array_equal(out2["motor_current_a"],
                                  rep.simulate(t, {"motor_voltage_v": u})["motor_current_a"])


def _calibration(rec, options=CalibrationOptions()):
    setup = load_calibration_scenario(LAB_RIG)
    return Calibration(rec, "lab_rig", options, replay=setup.replay())


def test_calibration_honours_declaration_and_warns(tmp_path):
    # undeclared: the described rig's default (linear) is kept, and the data contradict it
    cal = _calibration(_record(tmp_path))
    assert cal.replay.hold_of("motor_voltage_v") == "linear"
    assert cal.input_hold["motor_voltage_v"]["detected"] == "zero_order"
    assert len(cal.hold_warnings) == 1
    assert "motor_voltage_v" in cal.hold_warnings[0] and "default" in cal.hold_warnings[0]
    assert cal.hold_warnings[0] in cal.record_flags
    # declared zero-order in the sidecar: used, no warning
    cal = _calibration(_record(tmp_path, hold={"motor_voltage_v": "zero_order"}, name="z.csv"))
    assert cal.replay.hold_of("motor_voltage_v") == "zero_order"
    assert cal.hold_warnings == []
    assert cal.input_hold["motor_voltage_v"]["source"] == "declared in the record's sidecar [hold]"
    # the scenario overrides the sidecar; a declaration contradicting the data is honoured
    # and warned about, naming the declaration
    cal = _calibration(_record(tmp_path, hold={"motor_voltage_v": "zero_order"}, name="y.csv"),
                       CalibrationOptions(hold={"motor_voltage_v": "linear"}))
    assert cal.replay.hold_of("motor_voltage_v") == "linear"
    assert len(cal.hold_warnings) == 1
    w = cal.hold_warnings[0]
    assert "[calibration.hold]" in w and "declaration is kept" in w and "zero_order" in w


def test_preset_default_stays_zero_order():
    assert BenchReplay("hafo").hold_of("motor_voltage_v") == "zero_order"
    assert BenchReplay("hafo").hold_of("commanded_torque_nm") == "zero_order"
