"""Residual analysis (afo_mj.calibration.residual_analysis) against independent references:
analytic values, hand computations, direct O(n²) sums and synthetic signals with known noise,
delay, phase shape and frequency; every bad input refused with a ValueError naming the
argument. Synthetic numpy signals only (fast)."""

from __future__ import annotations

import json
import math
import re

import numpy as np
import pytest
from scipy import stats

from afo_mj.calibration import residual_analysis as ra

FS = 1000.0
N = 10_000                                   # 10 s at 1 kHz, 10 cycles of 1 s
T = np.arange(N) / FS
CYCLES = [(float(k), float(k + 1)) for k in range(10)]


def ringing(amplitude: float = 0.1, onset: float = 0.6, tau_s: float = 0.15) -> np.ndarray:
    """A 25 Hz decaying oscillation starting at ``onset`` of every 1 s cycle."""
    out = np.zeros(N)
    for t0, _ in CYCLES:
        tt = T - (t0 + onset)
        m = (tt >= 0) & (tt < 1.0 - onset)
        out[m] += amplitude * np.exp(-tt[m] / tau_s) * np.sin(2 * np.pi * 25.0 * tt[m])
    return out


# --------------------------------------------------------------------------- nrmse

def test_nrmse_of_a_known_offset_is_analytic():
    a, c = 2.0, 0.3
    measured = a * np.sin(2 * np.pi * 1.0 * T)          # 10 whole periods: SD = a/√2 exactly
    assert ra.nrmse(measured, measured - c) == pytest.approx(c / (a / math.sqrt(2)), rel=1e-9)
    assert ra.nrmse(measured, measured) == 0.0


def test_nrmse_refuses_a_constant_channel():
    with pytest.raises(ValueError, match="measured is constant"):
        ra.nrmse(np.full(100, 5.0e6), np.zeros(100))


# --------------------------------------------------------------------------- noise σ

@pytest.mark.parametrize("seed", [0, 1, 2])
def test_noise_sigma_recovers_white_noise_on_a_slow_sine(seed):
    rng = np.random.default_rng(seed)
    sigma = 0.02
    x = 3.0 * np.sin(2 * np.pi * 0.5 * np.arange(20_000) / FS) + sigma * rng.standard_normal(20_000)
    assert ra.noise_sigma_estimate(x) == pytest.approx(sigma, rel=0.05)


def test_noise_sigma_is_robust_to_a_few_steps():
    rng = np.random.default_rng(3)
    x = 0.01 * rng.standard_normal(20_000)
    x[::500] += 5.0                                     # 40 spikes: plain SD would be ruined
    assert ra.noise_sigma_estimate(x) == pytest.approx(0.01, rel=0.05)


# --------------------------------------------------------------------------- Ljung–Box

def test_ljung_box_equals_hand_computation():
    # x = [1, 3, 2, 5, 4]: mean 3, deviations [-2, 0, -1, 2, 1], Σ d² = 10;
    # lag 1: 0·(-2) + (-1)·0 + 2·(-1) + 1·2 = 0 → ρ1 = 0; lag 2: (-1)(-2) + 2·0 + 1·(-1) = 1
    # → ρ2 = 0.1; Q = 5·7·(0²/4 + 0.1²/3) = 7/60; χ²(2) survival = exp(-Q/2).
    q, p = ra.ljung_box(np.array([1.0, 3.0, 2.0, 5.0, 4.0]), 2)
    assert q == pytest.approx(7.0 / 60.0, rel=1e-12)
    assert p == pytest.approx(math.exp(-7.0 / 120.0), rel=1e-12)


def test_ljung_box_matches_direct_sum():
    x = np.random.default_rng(4).standard_normal(300)
    c = x - x.mean()
    n, h = x.size, 12
    rho = [np.dot(c[k:], c[:n - k]) / np.dot(c, c) for k in range(1, h + 1)]
    q_ref = n * (n + 2) * sum(r ** 2 / (n - k) for k, r in enumerate(rho, start=1))
    q, p = ra.ljung_box(x, h)
    assert q == pytest.approx(q_ref, rel=1e-10)
    assert p == pytest.approx(stats.chi2.sf(q_ref, h), rel=1e-9)


def test_ljung_box_white_noise_is_white_in_most_seeds():
    ps = [ra.ljung_box(np.random.default_rng(s).standard_normal(1000), 20)[1] for s in range(50)]
    assert sum(p > 0.01 for p in ps) >= 45
    assert 0.3 < float(np.mean(ps)) < 0.7                # p is uniform under the null


def test_ljung_box_rejects_ar1():
    rng = np.random.default_rng(5)
    e = rng.standard_normal(2000)
    x = np.zeros_like(e)
    for k in range(1, x.size):
        x[k] = 0.5 * x[k - 1] + e[k]
    assert ra.ljung_box(x, 20)[1] < 1e-6


# --------------------------------------------------------------------------- whiteness

def test_whiteness_decimates_and_reports():
    rng = np.random.default_rng(6)
    w = ra.whiteness(0.01 * rng.standard_normal(N), 0.01, FS)
    assert (w["decimation"], w["n_decimated"], w["lags"]) == (5, 2000, 20)
    assert w["decimated_fs_hz"] == pytest.approx(200.0)
    assert w["white"] and w["p_value"] > 0.01
    assert w["excess_ratio"] == pytest.approx(1.0, rel=0.05)
    short = ra.whiteness(rng.standard_normal(30), 1.0, FS)
    assert (short["decimation"], short["lags"]) == (1, 6)
    # an independent check of the block average: Ljung–Box of the block means by hand
    r = rng.standard_normal(4001)
    w2 = ra.whiteness(r, 1.0, FS, max_samples=1000)
    dec = r[:4000].reshape(800, 5).mean(axis=1)           # m = ceil(4001/1000) = 5
    assert w2["ljung_box_q"] == pytest.approx(ra.ljung_box(dec, 20)[0], rel=1e-12)


def test_whiteness_of_a_constant_residual_is_white():
    w = ra.whiteness(np.full(500, 0.2), 0.1, FS)
    assert w["white"] and w["ljung_box_q"] == 0.0 and w["p_value"] == 1.0
    assert w["excess_ratio"] == pytest.approx(2.0)


# --------------------------------------------------------------------------- correlations

def test_cross_correlation_matches_direct_sum():
    rng = np.random.default_rng(7)
    n = 60
    x, y = rng.standard_normal(n), rng.standard_normal(n) + 3.0
    lags, r = ra.cross_correlation(x, y, 7)
    xc, yc = x - x.mean(), y - y.mean()
    ref = [sum(xc[t] * yc[t - k] for t in range(n) if 0 <= t - k < n) / (n * x.std() * y.std())
           for k in range(-7, 8)]
    assert list(lags) == list(range(-7, 8))
    np.testing.assert_allclose(r, ref, atol=1e-12)


def test_cross_correlation_finds_a_known_delay():
    rng = np.random.default_rng(8)
    y = rng.standard_normal(5000)
    d = 37
    x = np.concatenate([rng.standard_normal(d), y[:-d]])   # x_t = y_{t−37}: x follows y
    lags, r = ra.cross_correlation(x, y, 100)
    assert lags[np.argmax(r)] == d
    assert r.max() == pytest.approx(1.0, abs=0.02)
    pk = ra.peak_cross_correlation(x, y, 100, 1.0 / FS)
    assert pk["lag_s"] == pytest.approx(d / FS)
    assert pk["r"] == pytest.approx(r.max())
    neg = ra.peak_cross_correlation(-y, x, 100, 1.0 / FS)  # y leads x: negative lag, r < 0
    assert neg["lag_s"] == pytest.approx(-d / FS) and neg["r"] < -0.98


def test_correlations_with_a_constant_are_zero_not_nan():
    x = np.random.default_rng(9).standard_normal(200)
    lags, r = ra.cross_correlation(x, np.ones(200), 10)
    assert np.all(r == 0.0)
    assert ra.peak_cross_correlation(x, np.ones(200), 10, 0.001) == {"r": 0.0, "lag_s": 0.0}
    sc = ra.signature_correlations(x, {"flat": np.full(200, 2.0), "same": 2 * x + 1,
                                       "other": np.cos(np.arange(200.0))})
    assert sc["flat"] == 0.0
    assert sc["same"] == pytest.approx(1.0)
    assert sc["other"] == pytest.approx(np.corrcoef(x, np.cos(np.arange(200.0)))[0, 1], rel=1e-12)
    assert ra.signature_correlations(np.zeros(200), {"same": x}) == {"same": 0.0}


# --------------------------------------------------------------------------- phase average

def test_phase_average_recovers_a_periodic_residual():
    rng = np.random.default_rng(10)
    shape = lambda ph: 0.5 * np.exp(-0.5 * ((ph - 0.63) / 0.05) ** 2)  # noqa: E731
    sigma = 0.05
    res = shape(T % 1.0) + sigma * rng.standard_normal(N)
    pa = ra.phase_average(res, T, CYCLES, bins=50)
    assert pa["n_cycles"] == 10 and np.all(pa["count"] == 200)
    np.testing.assert_allclose(pa["phase"], (np.arange(50) + 0.5) / 50)
    # reference: the shape averaged over each bin (fine quadrature), SE of a bin mean σ/√200
    fine = (np.arange(50)[:, None] + (np.arange(200)[None, :] + 0.5) / 200) / 50
    np.testing.assert_allclose(pa["mean"], shape(fine).mean(axis=1),
                               atol=5 * sigma / math.sqrt(200))
    assert pa["peak_phase"] == pytest.approx(0.63)
    assert pa["peak_value"] == pytest.approx(0.5, abs=0.02)
    flat = pa["sd"][np.abs(pa["phase"] - 0.63) > 0.3]     # where the shape is flat: SD = noise
    assert float(np.median(flat)) == pytest.approx(sigma, rel=0.1)


def test_phase_average_skips_cycles_outside_the_record():
    pa = ra.phase_average(0.5 + np.sin(2 * np.pi * T), T, CYCLES + [(50.0, 51.0)], bins=20)
    assert pa["n_cycles"] == 10
    assert pa["peak_phase"] in (0.225, 0.275)


# --------------------------------------------------------------------------- spectrum

def test_dominant_frequency_finds_25_hz_in_noise():
    rng = np.random.default_rng(11)
    x = 0.2 * np.sin(2 * np.pi * 25.0 * T + 0.4) + 0.5 * rng.standard_normal(N)
    assert ra.dominant_frequency(x, FS) == pytest.approx(25.0, abs=0.15)
    f, p = ra.residual_spectrum(x, FS)
    assert f[1] == pytest.approx(FS / 1024) and f[-1] == pytest.approx(FS / 2)
    # Parseval: the PSD integrates to the variance (0.2²/2 + 0.5²)
    assert float(np.sum(p) * f[1]) == pytest.approx(0.02 + 0.25, rel=0.05)


def test_dominant_frequency_respects_f_min():
    x = 1.0 * np.sin(2 * np.pi * 5.0 * T) + 0.1 * np.sin(2 * np.pi * 40.0 * T)
    assert ra.dominant_frequency(x, FS) == pytest.approx(5.0, abs=0.15)
    assert ra.dominant_frequency(x, FS, f_min_hz=10.0) == pytest.approx(40.0, abs=0.15)


# --------------------------------------------------------------------------- channel summary

def _channel(extra: np.ndarray, seed: int = 12, **kw):
    rng = np.random.default_rng(seed)
    model = 40.0 * np.sin(2 * np.pi * T)                  # a smooth 1 Hz "gait" torque
    measured = model + extra + 0.02 * rng.standard_normal(N)
    inputs = {"ankle_velocity_rad_s": np.cos(2 * np.pi * T),
              "ankle_angle_rad": 0.3 * np.sin(2 * np.pi * T)}
    states = {"ankle_angle_rad": inputs["ankle_angle_rad"],   # identical: skipped
              "ringing_state": np.roll(ringing(), 12)}        # the residual leads it by 12 ms
    kw.setdefault("signatures", {"ringing": ringing(), "flat": np.zeros(N)})
    kw.setdefault("noise_sigma", None)
    kw.setdefault("cycles", CYCLES)
    return ra.analyse_channel("ankle_torque_nm", T, measured, model, inputs, states, **kw)


def test_analyse_channel_white_noise_is_not_structured():
    s = _channel(np.zeros(N))
    json.dumps(s, allow_nan=False)
    assert s["noise_sigma_source"] == "estimated"
    assert s["noise_sigma"] == pytest.approx(0.02, rel=0.05)
    assert s["whiteness"]["white"] and not s["structured"]
    assert s["excess_ratio"] == pytest.approx(1.0, rel=0.07)
    assert s["nrmse"] == pytest.approx(0.02 / (40 / math.sqrt(2)), rel=0.05)
    assert ra.locate_structure({"ankle_torque_nm": s}) == (
        "no structured residual: every channel is within 1.2× its noise and white")


def test_analyse_channel_ringing_is_structured_and_located():
    s = _channel(ringing(), noise_sigma=0.02)
    json.dumps(s, allow_nan=False)
    assert s["noise_sigma_source"] == "given"
    assert not s["whiteness"]["white"] and s["excess_ratio"] > 1.2 and s["structured"]
    assert s["dominant_frequency_hz"] == pytest.approx(25.0, abs=1.0)
    assert 0.6 <= s["peak_phase"] <= 0.65
    xc = s["cross_correlations"]
    assert len(xc) == 3 and [d["signal"] for d in xc].count("ankle_angle_rad") == 1
    assert xc[0]["signal"] == "ringing_state" and xc[0]["kind"] == "state"
    # r ≈ rms(ringing)/rms(residual) ≈ 0.7 with the sensor noise; negative lag: residual first
    assert xc[0]["lag_s"] == pytest.approx(-0.012, abs=1e-9) and xc[0]["r"] > 0.6
    assert s["signature_correlations"]["ringing"] > 0.6
    assert s["signature_correlations"]["flat"] == 0.0
    quiet = _channel(np.zeros(N), seed=13)
    text = ra.locate_structure({"pressure_a_pa": quiet, "ankle_torque_nm": s})
    assert text.startswith("ankle_torque_nm: residual ")
    assert "pressure_a_pa" not in text
    assert "dominant frequency 2" in text and " Hz" in text
    assert "most correlated with ringing_state" in text and "closest signature ringing" in text
    assert "peaks at 6" in text and "% of the cycle" in text


def test_locate_structure_orders_channels_and_notes_white_excess():
    worse = _channel(3 * ringing(), noise_sigma=0.02, cycles=None)
    bad = _channel(ringing(), noise_sigma=0.02, cycles=None)
    assert worse["peak_phase"] is None
    text = ra.locate_structure({"a": bad, "b": worse})
    assert text.index("b: residual") < text.index("a: residual")
    assert "peaks at" not in text
    offset = _channel(np.full(N, 0.1), noise_sigma=0.02)
    msg = ra.locate_structure({"ankle_torque_nm": offset})
    assert msg.startswith("no structured residual (")
    assert "ankle_torque_nm: residual 5.1× the noise but white" in msg


# --------------------------------------------------------------------------- bad input

X = np.random.default_rng(14).standard_normal(100)
NAN = np.where(np.arange(100) == 3, np.nan, X)


@pytest.mark.parametrize("call, name", [
    (lambda: ra.nrmse(X, X[:50]), "model"),
    (lambda: ra.nrmse(NAN, X), "measured"),
    (lambda: ra.nrmse(X.reshape(10, 10), X), "measured"),
    (lambda: ra.nrmse("abc", X), "measured"),
    (lambda: ra.noise_sigma_estimate(X[:5]), "x"),
    (lambda: ra.noise_sigma_estimate(NAN), "x"),
    (lambda: ra.ljung_box(X, 0), "lags"),
    (lambda: ra.ljung_box(X, 100), "lags"),
    (lambda: ra.ljung_box(X, 2.5), "lags"),
    (lambda: ra.ljung_box(X, True), "lags"),
    (lambda: ra.ljung_box(np.ones(100), 5), "x"),
    (lambda: ra.ljung_box(NAN, 5), "x"),
    (lambda: ra.whiteness(X, 0.0, FS), "noise_sigma"),
    (lambda: ra.whiteness(X, math.nan, FS), "noise_sigma"),
    (lambda: ra.whiteness(X, 1.0, -1.0), "fs_hz"),
    (lambda: ra.whiteness(X, 1.0, FS, max_samples=5), "max_samples"),
    (lambda: ra.whiteness(X[:10], 1.0, FS), "residual"),
    (lambda: ra.whiteness(NAN, 1.0, FS), "residual"),
    (lambda: ra.cross_correlation(X, X[:99], 5), "y"),
    (lambda: ra.cross_correlation(X, X, -1), "max_lag"),
    (lambda: ra.cross_correlation(X, X, 100), "max_lag"),
    (lambda: ra.cross_correlation(X, NAN, 5), "y"),
    (lambda: ra.peak_cross_correlation(X, X, 5, 0.0), "dt_s"),
    (lambda: ra.signature_correlations(X, {"s": X[:10]}), "signatures['s']"),
    (lambda: ra.signature_correlations(X, {"s": NAN}), "signatures['s']"),
    (lambda: ra.signature_correlations(X, [X]), "signatures"),
    (lambda: ra.phase_average(X, np.arange(100.0), [(200.0, 201.0)]), "cycles"),
    (lambda: ra.phase_average(X, np.arange(100.0), [(5.0, 4.0)]), "cycles[0]"),
    (lambda: ra.phase_average(X, np.arange(100.0), [(0.0, math.nan)]), "cycles[0]"),
    (lambda: ra.phase_average(X, np.arange(100.0), []), "cycles"),
    (lambda: ra.phase_average(X, np.arange(100.0), None), "cycles"),
    (lambda: ra.phase_average(X, np.arange(100.0), [(0.0, 10.0)], bins=20), "bins"),
    (lambda: ra.phase_average(X, np.arange(100.0), [(0.0, 10.0)], bins=0), "bins"),
    (lambda: ra.phase_average(X, np.arange(99.0), [(0.0, 10.0)]), "residual"),
    (lambda: ra.residual_spectrum(X, 0.0), "fs_hz"),
    (lambda: ra.residual_spectrum(X[:4], FS), "residual"),
    (lambda: ra.dominant_frequency(np.ones(100), FS), "residual"),
    (lambda: ra.dominant_frequency(X, FS, f_min_hz=600.0), "f_min_hz"),
    (lambda: ra.dominant_frequency(X, FS, f_min_hz=-1.0), "f_min_hz"),
    (lambda: ra.analyse_channel("", T, T, T, {}, {}, {}, None, None), "name"),
    (lambda: ra.analyse_channel("c", T[::-1], T, T, {}, {}, {}, None, None), "time_s"),
    (lambda: ra.analyse_channel("c", np.r_[T[:5000], T[5000:] + 1.0], T, T, {}, {}, {}, None,
                                None), "time_s"),
    (lambda: ra.analyse_channel("c", T, np.ones(N), np.zeros(N), {}, {}, {}, 0.1, None),
     "measured"),
    (lambda: ra.analyse_channel("c", T, T, T - 1, {"u": X}, {}, {}, None, None), "inputs['u']"),
    (lambda: ra.analyse_channel("c", T, T, T - 1, {}, {"s": X}, {}, None, None), "states['s']"),
    (lambda: ra.analyse_channel("c", T, T, T - 1, {}, {}, {"g": X}, None, None),
     "signatures['g']"),
    (lambda: ra.analyse_channel("c", T, T, T - 1, {}, {}, {}, -1.0, None), "noise_sigma"),
    (lambda: ra.analyse_channel("c", T, np.round(T, 1), np.round(T, 1) - 1, {}, {}, {}, None,
                                None), "noise_sigma"),
    (lambda: ra.analyse_channel("c", T, T, T - 1, {}, {}, {}, 0.1, [(3.0, 2.0)]), "cycles"),
    (lambda: ra.locate_structure({}), "channel_summaries"),
    (lambda: ra.locate_structure({"c": 1.0}), "channel_summaries['c']"),
    (lambda: ra.locate_structure({"c": {"structured": "yes"}}), "channel_summaries['c']"),
    (lambda: ra.locate_structure({"c": {"structured": True, "whiteness": {"white": False},
                                        "excess_ratio": math.nan}}), "excess_ratio"),
])
def test_bad_input_raises_naming_the_argument(call, name):
    with pytest.raises(ValueError, match=re.escape(name)):
        call()


def test_analyse_channel_errors_name_the_channel():
    with pytest.raises(ValueError, match="channel 'ankle_torque_nm': measured is constant"):
        ra.analyse_channel("ankle_torque_nm", T, np.ones(N), np.zeros(N), {}, {}, {}, 0.1, None)
