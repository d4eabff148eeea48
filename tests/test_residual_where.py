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


def _summaries(t, residuals, sigmas, inputs, velocity=None):
    """analyse_channel summaries with a smooth model so that measured − model = residual; a
    line pair's broadband excess added as the calibration adds it."""
    model = 1e5 * np.sin(2 * np.pi * 0.5 * t)
    sig = {} if velocity is None else {"velocity": velocity}
    sums = {c: ra.analyse_channel(c, t, model + r, model, inputs, {}, sig, sigmas[c], None)
            for c, r in residuals.items()}
    for a, b in ra.line_pairs(sums):
        sums[a]["line_pair_high_band"] = ra.line_pair_high_band(
            residuals[a], residuals[b], sums[a]["fs_hz"], sigmas[a], sigmas[b], velocity)
    return sums


def _band_noise(rng, n, fs, f_lo, f_hi, sd):
    """White noise kept between f_lo and f_hi by zeroing its other FFT bins, scaled to SD
    ``sd`` over the record (the reference: its variance, computed in the time domain)."""
    spec = np.fft.rfft(rng.standard_normal(n))
    f = np.fft.rfftfreq(n, 1.0 / fs)
    spec[(f < f_lo) | (f >= f_hi)] = 0.0
    x = np.fft.irfft(spec, n)
    return sd * x / np.std(x)


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


@pytest.mark.parametrize("fs", RATES_HZ)
@pytest.mark.parametrize("sigma", SIGMAS_PA)
def test_aliased_vibration_of_the_piston_is_named_as_a_differential_broadband_excess(fs, sigma):
    # a vibration above the Nyquist folds into the top of the band; on the piston it moves the
    # two chambers apart: +h/2 on one line, −h/2 on the other
    rng = np.random.default_rng(int(fs) + int(sigma) + 5)
    t = np.arange(0.0, 10.0, 1.0 / fs)
    h = _band_noise(rng, t.size, fs, 0.25 * fs, 0.5 * fs, 2.0 * sigma)
    res = {"chamber_a_pa": 0.5 * h + sigma * rng.standard_normal(t.size),
           "chamber_b_pa": -0.5 * h + sigma * rng.standard_normal(t.size)}
    sums = _summaries(t, res, {c: sigma for c in res}, {})
    found = ra.where_findings(sums)
    assert [f["kind"] for f in found] == ["differential_high_band"], found
    f = found[0]
    assert f["channels"] == ["chamber_a_pa", "chamber_b_pa"]
    # reference: the injected differential's SD over the differential noise σ√2
    assert f["ratio"] == pytest.approx(np.std(h) / (sigma * math.sqrt(2)), rel=0.1)
    assert f["f_lo_hz"] == pytest.approx(0.2 * fs)
    where = ra.locate_structure(sums)
    assert "chamber_a_pa/chamber_b_pa: differential broadband residual above" in where
    assert "common mode within the noise's band" in where
    assert "stick-slip" not in where          # no velocity given: no localisation claimed


@pytest.mark.parametrize("fs", (1000.0, 2000.0))
def test_broadband_bursts_near_rest_read_as_friction_excited_vibration(fs):
    rng = np.random.default_rng(int(fs) + 17)
    sigma = 0.02e6
    t = np.arange(0.0, 12.0, 1.0 / fs)
    v = 0.5 * np.sin(2 * np.pi * 0.4 * t)                     # the joint's velocity, rad/s
    near_rest = np.abs(v) < 0.15
    h = _band_noise(rng, t.size, fs, 0.25 * fs, 0.5 * fs, 3.0 * sigma) * near_rest
    res = {"chamber_a_pa": 0.5 * h + sigma * rng.standard_normal(t.size),
           "chamber_b_pa": -0.5 * h + sigma * rng.standard_normal(t.size)}
    sums = _summaries(t, res, {c: sigma for c in res}, {}, velocity=v)
    found = [f for f in ra.where_findings(sums) if f["kind"] == "differential_high_band"]
    assert len(found) == 1, ra.where_findings(sums)
    # reference: the band power of the slowest fifth (inside the bursts: burst + noise) over
    # that of the rest (noise only), each from the injected signal's own variance
    band_noise = 2 * sigma ** 2 * (0.5 * fs - 0.2 * fs) / (0.5 * fs)
    slow = np.abs(v) <= np.quantile(np.abs(v), ra.SLOW_FRACTION)
    expect = (np.mean(h[slow] ** 2) + band_noise) / (np.mean(h[~slow] ** 2) + band_noise)
    assert found[0]["near_rest"] == pytest.approx(expect, rel=0.25)
    assert found[0]["near_rest"] > ra.SLOW_LOCALISATION
    assert "in bursts near rest" in found[0]["text"] and "stick-slip" in found[0]["text"]


@pytest.mark.parametrize("fs", RATES_HZ)
def test_a_single_high_tone_is_a_resonance_not_a_broadband_excess(fs):
    rng = np.random.default_rng(int(fs) + 23)
    sigma = 0.05
    t = np.arange(0.0, 10.0, 1.0 / fs)
    res = {"motor_current_a": 3 * sigma * np.sin(2 * np.pi * 0.35 * fs * t)
           + sigma * rng.standard_normal(t.size)}
    sums = _summaries(t, res, {"motor_current_a": sigma}, {})
    hb = sums["motor_current_a"]["high_band"]
    assert hb["ratio"] > ra.HIGH_BAND_MIN_RATIO          # the band holds the tone's power ...
    assert hb["peak_share"] > ra.HIGH_BAND_MAX_PEAK_SHARE and not hb["broadband"]
    assert [f["kind"] for f in ra.where_findings(sums)] == ["resonance"]


@pytest.mark.parametrize("sd_over_sigma, named", ((0.6, False), (2.0, True)))
def test_broadband_excess_threshold_against_the_docstring_example(sd_over_sigma, named):
    rng = np.random.default_rng(29)
    fs, sigma = 1000.0, 1.0
    n = 20000
    h = _band_noise(rng, n, fs, 0.25 * fs, 0.5 * fs, sd_over_sigma)
    hb = ra.high_band_excess(h + sigma * rng.standard_normal(n), fs, sigma)
    band_noise = sigma ** 2 * 0.6                        # white σ² over (0.2 … 0.5)·fs
    assert hb["ratio"] == pytest.approx(math.sqrt((band_noise + sd_over_sigma ** 2)
                                                  / band_noise), rel=0.05)
    assert hb["excess_ratio"] == pytest.approx(sd_over_sigma, rel=0.1)
    assert hb["broadband"] is named
