"""The calibration takes any registered device by name (issue 40 acceptance): the library
circuit gait_lab_bench.toml wears (``lab_bench``, its open-loop motor-voltage description),
named as ``--scenario lab_bench``, calibrates a bench record of itself. The record is written
here from the replay of the description with a zero-order voltage protocol and sensor noise,
so the model is complete: the verdict must be no_missing_effect with every output within
twice its noise floor (the described-rig rule), and nothing named. A user's own TOML
description is calibrated in tests/test_rig_calibration.py."""

from __future__ import annotations

import numpy as np
import pytest

from afo_mj.calibration.calibrate import calibrate_setup, load_calibration_scenario
from afo_mj.calibration.measured_data import write_measured
from afo_mj.experiments.bench_replay import BenchReplay

NOISE = {"pressure_a_pa": 2.0e4, "pressure_b_pa": 2.0e4, "ankle_torque_nm": 0.2,
         "motor_current_a": 0.03, "motor_speed_rad_s": 2.0}


@pytest.mark.slow
def test_a_library_circuit_named_by_the_registry_calibrates_its_own_record(tmp_path):
    rep = BenchReplay("lab_bench")
    assert rep.described and rep.commands == ("motor_voltage_v",)
    fs, dur = 1000.0, 4.0
    t = np.arange(int(fs * dur)) / fs
    rng = np.random.default_rng(7)
    # a voltage held zero-order for 0.2 s at a time, and the ankle swung 0.1 rad at 1 Hz
    levels = rng.uniform(-6.0, 6.0, int(dur / 0.2) + 1)
    volts = levels[(t / 0.2).astype(int)]
    theta = 0.1 * np.sin(2 * np.pi * 1.0 * t)
    inputs = {"motor_voltage_v": volts, "ankle_angle_rad": theta}
    rep.set_hold({"motor_voltage_v": "zero_order"})
    out = rep.simulate(t, inputs)
    outputs = [c for c in NOISE if c in out]
    assert set(outputs) == set(NOISE)
    table = {"time_s": t, **inputs}
    for c in outputs:
        table[c] = out[c] + rng.normal(0.0, NOISE[c], len(t))
    data = write_measured(tmp_path / "rec.csv", table, inputs=list(inputs), outputs=outputs,
                          source={"preset": "lab_bench", "description": "lab bench replay "
                                  "with noise (test)", "origin": "afo_mj test"},
                          noise={c: NOISE[c] for c in outputs},
                          segments={"period_s": 1.0, "phase_s": 0.0},
                          hold={"motor_voltage_v": "zero_order"})
    report = calibrate_setup(data, load_calibration_scenario("lab_bench"))
    assert report["described"] and report["command_channel"] == "motor_voltage_v"
    assert report["verdict"] == "no_missing_effect", report["verdict"]
    assert not report["effects_selected"]
    ratio = report["baseline"]["ratio"]
    assert set(ratio) == set(outputs) and max(ratio.values()) <= 2.0, ratio
