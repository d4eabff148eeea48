"""The residual's "where" in the rig's terms (issue 41 item 3): slow drifts (windowed means;
common-mode vs differential line pressure), transients after input steps, resonances, each
with its size against the noise. Synthetic residuals at 500 Hz, 1 kHz and 2 kHz and two noise
levels; sizes checked against the values computed directly from the injected signal."""

from __future__ import annotations

import math

import numpy as np
import pytest

from afo_mj.calibration import residual_analysis as ra

RATES_HZ = (500.0, 1000.0, 2000.0)
SIGMAS_PA = (0.02e6, 0.05e6)


def _summaries(t, residuals, sigmas, inputs):
    """analyse_channel summaries with a smooth model so that measured − model = residual."""
    model = 1e5 * np.sin(2 * np.pi * 0.5 * t)
    return {c: ra.analyse_channel(c, t, model + r, model, inputs, {}, {}, sigmas[c], None)
            for c, r in residuals.items()}


@pytest.mark.parametrize("fs", RATES_HZ)
@pytest.mark.parametrize("sigma", SIGMAS_PA)
def test_common_mode_pressure_drift_is_named_with_its_size(fs, sigma):
    rng = np.random.default_rng(int(fs) + int(sigma))
    t = np.arange(0.0, 20.0, 1.0 / fs)
    drift = 7 * sigma * (t / t[-1]) ** 2           # the common level wanders away, quadratically
    res = {"pressure_a_pa": drift + sigma * rng.standard_normal(t.size),
           "pressure_b_pa": drift + sigma * rng.standard_normal(t.size)}
    sums = _summaries(t, res, {c: sigma for c in res}, {})
    found = ra.where_findings(sums)
    kinds = [f["kind"] for f in found]
    assert kinds == ["common_mode_drift"], found
    f = found[0]
    # reference: the injected drift's change between the first and the last of 5 windows
    m = t.size // ra.DRIFT_WINDOWS
    true_change = drift[4 * m: 5 * m].mean() - drift[:m].mean()
    sd = (sigma / math.sqrt(2)) * math.sqrt(2.0 / m)     # σ_cm √(2/m)
    assert f["change"] == pytest.approx(true_change, abs=5 * sd)
    assert f["ratio"] == pytest.approx(abs(true_change) / (sigma / math.sqrt(2)), rel=0.05)
    where = ra.locate_structure(sums)
    named = where.split("named, largest against the noise first: ")[1]
    assert named.startswith("pressure_a_pa/pressure_b_pa: common-mode pressure drift"), where
    assert "differential flat" in where and "MPa" in where


@pytest.mark.parametrize("fs", RATES_HZ)
@pytest.mark.parametrize("sigma", (0.15, 0.3))
def test_transient_after_command_reversals_is_named(fs, sigma):
    rng = np.random.default_rng(int(fs) + 7)
    t = np.arange(0.0, 12.0, 1.0 / fs)
    volts = np.where((t // 2.0) % 2 == 0, 32.0, -32.0)     # reversals every 2 s, held
    burst = np.zeros_like(t)
    for ts in np.arange(2.0, 12.0, 2.0):
        k = t >= ts
        tau = t[k] - ts
        burst[k] += 20 * sigma * np.exp(-tau / 0.05) * np.sin(2 * np.pi * 85.0 * tau)
    res = {"ankle_torque_nm": burst + sigma * rng.standard_normal(t.size)}
    sums = _summaries(t, res, {"ankle_torque_nm": sigma}, {"motor_voltage_v": volts})
    found = ra.where_findings(sums)
    tr = [f for f in found if f["kind"] == "step_transient"]
    assert len(tr) == 1, found
    f = tr[0]
    assert f["input"] == "motor_voltage_v"
    assert f["window_s"] == pytest.approx(0.2, abs=1.5 / fs)
    s = sums["ankle_torque_nm"]["transient"]
    assert s["n_steps"] == 5
    # reference: RMS of burst + noise in the 0.2 s windows, from the injected burst
    n_w = int(round(0.2 * fs))
    mask = np.zeros(t.size, bool)
    for ts in np.arange(2.0, 12.0, 2.0):
        k0 = int(np.searchsorted(t, ts))
        mask[k0 - 1: k0 + n_w] = True
    expect = math.sqrt(np.mean(burst[mask] ** 2) + sigma ** 2) / sigma
    assert f["ratio"] == pytest.approx(expect, rel=0.1)
    assert f["ringing_hz"] == pytest.approx(85.0, abs=5.0)
    assert not any(g["kind"].endswith("drift") for g in found)
    assert "after 5 step(s) of motor_voltage_v" in ra.locate_structure(sums)


@pytest.mark.parametrize("fs", RATES_HZ)
@pytest.mark.parametrize("sigma", SIGMAS_PA)
def test_white_noise_names_nothing(fs, sigma):
    rng = np.random.default_rng(int(fs) + 3)
    t = np.arange(0.0, 20.0, 1.0 / fs)
    volts = np.where((t // 2.0) % 2 == 0, 32.0, -32.0)
    res = {"pressure_a_pa": sigma * rng.standard_normal(t.size),
           "pressure_b_pa": sigma * rng.standard_normal(t.size)}
    sums = _summaries(t, res, {c: sigma for c in res}, {"motor_voltage_v": volts})
    assert ra.where_findings(sums) == []
    assert ra.locate_structure(sums).startswith("no structured residual: every channel")


@pytest.mark.parametrize("fs", RATES_HZ)
@pytest.mark.parametrize("sigma", (0.05, 0.2))
def test_resonance_is_named_at_its_frequency_and_size(fs, sigma):
    rng = np.random.default_rng(int(fs) + 11)
    t = np.arange(0.0, 10.0, 1.0 / fs)
    amp = 3 * sigma
    res = {"motor_current_a": amp * np.sin(2 * np.pi * 25.0 * t + 0.3)
           + sigma * rng.standard_normal(t.size)}
    sums = _summaries(t, res, {"motor_current_a": sigma}, {})
    found = ra.where_findings(sums)
    assert [f["kind"] for f in found] == ["resonance"], found
    assert found[0]["frequency_hz"] == pytest.approx(25.0, abs=fs / 1024)
    # a sine of amplitude A has RMS A/√2
    assert found[0]["ratio"] == pytest.approx(amp / math.sqrt(2) / sigma, rel=0.15)
    where = ra.locate_structure(sums)
    assert "motor_current_a: resonance at 25" in where and "dominant frequency" in where
