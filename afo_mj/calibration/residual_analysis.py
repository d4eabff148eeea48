"""Residual analysis of a model replayed against a measured record (numpy + scipy only).

The residual of a channel is ``measured − model``, sampled uniformly. If the model captures
everything except sensor noise, the residual is white noise about as large as the sensor noise;
if a physical effect is missing, the residual has *structure*: it is larger than the noise, it
is autocorrelated, it correlates with some input or state (at some lag), it repeats at some
phase of the cycle, or it rings at some frequency. This module measures each of those so a
calibration loop can tell noise from a missing effect and say where the effect lives.

Definitions and sources
-----------------------
* NRMSE (:func:`nrmse`): ``RMS(measured − model) / SD(measured)``, population SD (ddof 0);
  the usual normalised root-mean-square error (e.g. Ljung, *System Identification*, 2nd ed.,
  1999, §16.6, where ``1 − NRMSE`` is the "fit" percentage). 0 is a perfect fit; 1 is no better
  than the measured mean.
* Sensor-noise σ (:func:`noise_sigma_estimate`): from second differences
  ``d_k = x[k+1] − 2x[k] + x[k−1]``. For ``x = s + e`` with ``e`` white of variance σ² and ``s``
  smooth at the sampling rate (its second difference ≈ ``s''·dt²`` negligible against σ),
  ``var d = (1 + 4 + 1) σ² = 6σ²``: the difference-based variance estimator of Gasser, Sroka &
  Jennen-Steinmetz (1986, *Biometrika* 73, 625–633; equally spaced three-point
  pseudo-residuals). The SD of ``d`` is taken robustly as 1.4826·MAD (median absolute deviation
  from the median; 1.4826 = 1/Φ⁻¹(3/4) makes it consistent for Gaussian data: Hampel 1974,
  *JASA* 69, 383–393; Rousseeuw & Croux 1993, *JASA* 88, 1273–1283), so occasional steps or
  spikes in ``s`` do not inflate it. σ ≈ 1.4826·MAD(d)/√6.
* Ljung–Box portmanteau test (:func:`ljung_box`): Ljung & Box (1978, *Biometrika* 65,
  297–303). With the mean removed, ``ρ_k = Σ_{t=k+1..n} x_t x_{t−k} / Σ_{t=1..n} x_t²`` and
  ``Q = n(n+2) Σ_{k=1..h} ρ_k²/(n−k)``, which under the null hypothesis of white noise is
  asymptotically χ² with ``h`` degrees of freedom; ``p = P(χ²_h > Q)``.
* Whiteness (:func:`whiteness`): Ljung–Box on the residual block-averaged over ``m`` samples
  (``m = ceil(n/max_samples)``), so that a long 1 kHz record is tested at a sensible sample
  count (with tens of thousands of samples any model error, however small, is "significant").
  A block mean of white noise is white, so the null hypothesis is unchanged; structure above
  ``fs/(2m)`` is attenuated by the block mean (a sinc low-pass) and aliased. ``h = min(20,
  n_dec // 5)`` lags (the n/5 cap follows Box, Jenkins & Reinsel, *Time Series Analysis*,
  4th ed., §8.2.2, on keeping h well below n). White when ``p > 0.01``.
* Cross-correlation (:func:`cross_correlation`): the biased normalised estimator
  ``r[k] = Σ_t (x_t − x̄)(y_{t−k} − ȳ) / (n σ_x σ_y)`` (Box, Jenkins & Reinsel §12.1.3; Bendat &
  Piersol, *Random Data*, 4th ed., §11.1), computed by FFT. ``|r| ≤ 1``; a positive lag ``k``
  means ``x`` follows ``y`` by ``k`` samples (``x_t ≈ y_{t−k}``).
* Pearson correlation (:func:`signature_correlations`): Pearson (1896) product-moment r.
* Residual spectrum (:func:`residual_spectrum`): Welch (1967, *IEEE Trans. Audio
  Electroacoust.* 15, 70–73) averaged periodogram, Hann window, 50 % overlap, segment length
  ``min(1024, n)``, one-sided PSD in (units)²/Hz. The dominant frequency
  (:func:`dominant_frequency`) is refined between bins by fitting a parabola to the log-PSD at
  the peak and its two neighbours (quadratic spectral-peak interpolation, Smith & Serra 1987,
  *PARSHL*, Proc. ICMC; Grandke 1983, *IEEE Trans. Instrum. Meas.* 32, 350–355).

Decisions
---------
* A signal whose SD is below ``1e-12·max(1, |mean|)`` is *constant*. A constant ``measured``
  cannot normalise the NRMSE (ValueError). A constant signal has no correlation with anything:
  cross- and signature correlations with it are defined as 0.0 (never NaN). Ljung–Box on a
  constant series is undefined (ValueError), but :func:`whiteness` reports a constant residual
  (a model that reproduces the record up to an offset) as white, ``Q = 0``, ``p = 1``.
* Sampling must be uniform to within ±50 % of the median interval (the tolerance of
  :mod:`afo_mj.calibration.measured_data`); the sample rate is 1/median interval.
* "Structured" (:func:`analyse_channel`) means *not white* and ``rms/noise_sigma > 1.2``. A
  white residual much larger than the noise (an offset, or extra broadband noise) is not
  "structured" in that sense; :func:`locate_structure` says so separately.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping

import numpy as np
from scipy import signal as sps
from scipy import stats

__all__ = ["nrmse", "noise_sigma_estimate", "ljung_box", "whiteness", "cross_correlation",
           "peak_cross_correlation", "signature_correlations", "phase_average",
           "residual_spectrum", "dominant_frequency", "analyse_channel", "locate_structure",
           "WHITE_P_VALUE", "STRUCTURE_EXCESS_RATIO", "windowed_drift", "line_pairs",
           "line_pair_drifts", "step_times", "step_transients", "resonance", "where_findings",
           "high_band_excess", "line_pair_high_band"]

#: Ljung–Box p-value above which a residual counts as white.
WHITE_P_VALUE = 0.01
#: ``rms/noise_sigma`` above which a non-white residual counts as structured.
STRUCTURE_EXCESS_RATIO = 1.2
#: Allowed deviation of a sampling interval from the median, as a fraction of the median
#: (same as :data:`afo_mj.calibration.measured_data.SAMPLING_TOLERANCE`).
SAMPLING_TOLERANCE = 0.5
#: Maximum lag of the residual's cross-correlations in :func:`analyse_channel` [s].
XCORR_MAX_LAG_S = 0.2
#: MAD → SD factor for Gaussian data, 1/Φ⁻¹(3/4).
MAD_TO_SD = 1.4826

_MIN_NOISE_SAMPLES = 10
_MIN_WHITENESS_SAMPLES = 20
_MIN_SPECTRUM_SAMPLES = 8


# --------------------------------------------------------------------------- validation

def _array(name: str, x, n: int | None = None, n_name: str = "", min_n: int = 1) -> np.ndarray:
    """``x`` as a finite 1-D float array (length ``n`` if given, at least ``min_n``)."""
    try:
        a = np.asarray(x, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"{name} is not an array of numbers (got {type(x).__name__}); "
                         "allowed: a 1-D array of finite floats") from None
    if a.ndim != 1:
        raise ValueError(f"{name} has shape {a.shape}; allowed: a 1-D array")
    if n is not None and a.size != n:
        raise ValueError(f"{name} has {a.size} samples but {n_name} has {n}; "
                         "the lengths must match")
    if a.size < min_n:
        raise ValueError(f"{name} has {a.size} samples; allowed: at least {min_n}")
    bad = np.flatnonzero(~np.isfinite(a))
    if bad.size:
        k = int(bad[0])
        raise ValueError(f"{name} contains a non-finite value ({a[k]!r} at index {k}, "
                         f"{bad.size} in all); allowed: finite numbers only")
    return a


def _positive(name: str, v, allow_zero: bool = False) -> float:
    if isinstance(v, bool):
        raise ValueError(f"{name} = {v!r}; allowed: a finite number > 0")
    try:
        f = float(v)
    except (TypeError, ValueError):
        raise ValueError(f"{name} = {v!r} is not a number; allowed: a finite number "
                         f"{'>= 0' if allow_zero else '> 0'}") from None
    if not math.isfinite(f) or f < 0 or (f == 0 and not allow_zero):
        raise ValueError(f"{name} = {v!r}; allowed: a finite number "
                         f"{'>= 0' if allow_zero else '> 0'}")
    return f


def _integer(name: str, v, lo: int, hi: int | None = None, what: str = "") -> int:
    if isinstance(v, (bool, np.bool_)) or not isinstance(v, (int, np.integer)):
        raise ValueError(f"{name} = {v!r}; allowed: an integer "
                         f"{lo} <= {name}" + (f" <= {hi}" if hi is not None else "") + what)
    i = int(v)
    if i < lo or (hi is not None and i > hi):
        raise ValueError(f"{name} = {v!r}; allowed: {lo} <= {name}"
                         + (f" <= {hi}" if hi is not None else "") + what)
    return i


def _is_constant(x: np.ndarray) -> bool:
    """True if the population SD of ``x`` is below ``1e-12·max(1, |mean|)``."""
    m = float(np.mean(x))
    return float(np.std(x)) < 1e-12 * max(1.0, abs(m))


def _sample_rate(time_s: np.ndarray) -> float:
    """1/median interval of a strictly increasing, near-uniform ``time_s`` [Hz]."""
    dt = np.diff(time_s)
    bad = np.flatnonzero(~(dt > 0))
    if bad.size:
        k = int(bad[0]) + 1
        raise ValueError(f"time_s is not strictly increasing at index {k} ({time_s[k]!r} s "
                         f"after {time_s[k - 1]!r} s); allowed: strictly increasing times [s]")
    med = float(np.median(dt))
    off = np.flatnonzero(np.abs(dt / med - 1.0) > SAMPLING_TOLERANCE)
    if off.size:
        k = int(off[0]) + 1
        raise ValueError(f"time_s is not uniformly sampled: {off.size} intervals outside "
                         f"{1 - SAMPLING_TOLERANCE:g}…{1 + SAMPLING_TOLERANCE:g} × the median "
                         f"{med:g} s, first before index {k} (t = {time_s[k]:g} s); "
                         "allowed: uniform sampling (resample first)")
    return 1.0 / med


# --------------------------------------------------------------------------- statistics

def nrmse(measured, model) -> float:
    """Normalised RMS error ``RMS(measured − model) / SD(measured)`` (population SD, ddof 0).

    The normalised root-mean-square error of system identification (Ljung 1999, §16.6): 0 for
    a perfect fit, 1 for a model no better than the measured mean. Raises ValueError if
    ``measured`` is constant (SD below ``1e-12·max(1, |mean|)``), which cannot be normalised.
    """
    y = _array("measured", measured, min_n=2)
    m = _array("model", model, y.size, "measured")
    if _is_constant(y):
        raise ValueError(f"measured is constant (SD {float(np.std(y)):g} about mean "
                         f"{float(np.mean(y)):g}); a constant channel cannot normalise the "
                         "NRMSE; allowed: a measured channel that varies")
    return float(np.sqrt(np.mean((y - m) ** 2)) / np.std(y))


def noise_sigma_estimate(x) -> float:
    """White-noise σ of ``x = smooth signal + white noise`` from robust second differences.

    ``d_k = x[k+1] − 2x[k] + x[k−1]`` has variance 6σ² for white noise of variance σ²
    (Gasser, Sroka & Jennen-Steinmetz 1986), so ``σ ≈ 1.4826·MAD(d)/√6`` with the MAD taken
    about the median (Hampel 1974; Rousseeuw & Croux 1993). Valid only when the signal is
    smooth at the sampling rate: its second difference ``s''·dt²`` must be small against σ
    (true for gait signals sampled at ≥ 100 Hz with noise above the quantisation step).
    Sharp features (impacts, valve switching) are tolerated as long as they occupy well under
    half the samples. A quantised signal whose second differences are mostly zero gives 0.0:
    use the quantisation step ``q/√12`` as the noise σ instead. ``x`` needs ≥ 10 samples.
    """
    a = _array("x", x, min_n=_MIN_NOISE_SAMPLES)
    d = a[2:] - 2.0 * a[1:-1] + a[:-2]
    mad = float(np.median(np.abs(d - np.median(d))))
    return MAD_TO_SD * mad / math.sqrt(6.0)


def ljung_box(x, lags: int) -> tuple[float, float]:
    """Ljung–Box portmanteau statistic and p-value (Ljung & Box 1978, *Biometrika* 65, 297).

    With the mean removed, ``ρ_k = Σ_{t=k+1..n} x_t x_{t−k} / Σ_t x_t²`` and
    ``Q = n(n+2) Σ_{k=1..h} ρ_k²/(n−k)`` with ``h = lags``; under the null hypothesis that
    ``x`` is white noise, Q is asymptotically χ²(h), so ``p = chi2.sf(Q, h)``. A small p means
    autocorrelation (structure). ``lags`` must satisfy ``1 <= lags < n``; a constant ``x``
    (no variance, ρ undefined) raises ValueError.
    """
    a = _array("x", x, min_n=2)
    n = a.size
    h = _integer("lags", lags, 1, n - 1, f" (n = {n} samples in x)")
    if _is_constant(a):
        raise ValueError("x is constant; its autocorrelation is undefined; allowed: a series "
                         "with non-zero variance")
    c = a - a.mean()
    nfft = 1 << int(math.ceil(math.log2(2 * n)))
    spec = np.fft.rfft(c, nfft)
    acov = np.fft.irfft(spec * np.conj(spec), nfft)[: h + 1]   # Σ_t c_t c_{t−k}, k = 0..h
    rho = acov[1:] / acov[0]
    k = np.arange(1, h + 1)
    q = float(n * (n + 2) * np.sum(rho ** 2 / (n - k)))
    return q, float(stats.chi2.sf(q, h))


def whiteness(residual, noise_sigma: float, fs_hz: float, max_samples: int = 2000) -> dict:
    """Is ``residual`` white, and how large is it against the sensor noise?

    The residual is block-averaged over ``m = ceil(n/max_samples)`` consecutive samples (the
    incomplete last block dropped), giving ``n_dec`` samples at ``fs_hz/m``; Ljung–Box
    (:func:`ljung_box`, Ljung & Box 1978) is applied with ``h = min(20, n_dec // 5)`` lags.
    Block means of white noise are white, so the null hypothesis is the same; content above
    ``fs_hz/(2m)`` is attenuated and aliased. ``white`` is ``p_value > 0.01``. ``rms`` is the
    RMS of the full-rate residual (mean included) and ``excess_ratio = rms/noise_sigma``
    (≈ 1 when the residual is only sensor noise). A constant residual is reported white
    (``Q = 0``, ``p = 1``).

    Returns ``{"ljung_box_q", "p_value", "lags", "decimation", "white", "rms",
    "noise_sigma", "excess_ratio", "n_decimated", "decimated_fs_hz"}``.
    """
    r = _array("residual", residual, min_n=_MIN_WHITENESS_SAMPLES)
    sigma = _positive("noise_sigma", noise_sigma)
    fs = _positive("fs_hz", fs_hz)
    ms = _integer("max_samples", max_samples, _MIN_WHITENESS_SAMPLES)
    n = r.size
    m = -(-n // ms)
    n_dec = n // m
    dec = r[: n_dec * m].reshape(n_dec, m).mean(axis=1)
    h = min(20, n_dec // 5)
    if _is_constant(dec):
        q, p = 0.0, 1.0
    else:
        q, p = ljung_box(dec, h)
    rms = float(np.sqrt(np.mean(r ** 2)))
    return {"ljung_box_q": q, "p_value": p, "lags": int(h), "decimation": int(m),
            "white": bool(p > WHITE_P_VALUE), "rms": rms, "noise_sigma": sigma,
            "excess_ratio": rms / sigma, "n_decimated": int(n_dec),
            "decimated_fs_hz": fs / m}


def cross_correlation(x, y, max_lag: int) -> tuple[np.ndarray, np.ndarray]:
    """Normalised cross-correlation ``r[k] = corr(x_t, y_{t−k})`` for ``k = −max_lag..max_lag``.

    ``r[k] = Σ_t (x_t − x̄)(y_{t−k} − ȳ) / (n σ_x σ_y)`` over the overlapping samples, with
    population SDs: the biased estimator of Box, Jenkins & Reinsel (§12.1.3) and Bendat &
    Piersol (§11.1), so ``|r| ≤ 1`` and ``r`` falls by ``(n − |k|)/n`` at large lags. Computed
    by FFT (``scipy.signal.correlate(method="fft")``). A positive ``k`` means ``x`` follows
    ``y`` by ``k`` samples. If ``x`` or ``y`` is constant, ``r`` is all zeros (no linear
    relation). ``max_lag`` is in samples, ``0 <= max_lag < n``. Returns ``(lags, r)`` with
    integer lags.
    """
    a = _array("x", x, min_n=2)
    b = _array("y", y, a.size, "x")
    n = a.size
    L = _integer("max_lag", max_lag, 0, n - 1, f" (n = {n} samples in x)")
    lags = np.arange(-L, L + 1)
    if _is_constant(a) or _is_constant(b):
        return lags, np.zeros(lags.size)
    ac, bc = a - a.mean(), b - b.mean()
    full = sps.correlate(ac, bc, mode="full", method="fft")   # full[j] = Σ_t x_t y_{t−lag_j}
    full_lags = sps.correlation_lags(n, n, mode="full")
    sel = (full_lags >= -L) & (full_lags <= L)
    r = full[sel] / (n * np.std(a) * np.std(b))
    return lags, np.clip(r, -1.0, 1.0)


def peak_cross_correlation(x, y, max_lag: int, dt_s: float) -> dict:
    """The largest-|r| value of :func:`cross_correlation` within ``±max_lag`` samples.

    Returns ``{"r": r at the |r| peak (signed), "lag_s": lag·dt_s}``; positive ``lag_s``
    means ``x`` follows ``y``. Ties go to the smallest lag (most negative); if ``r`` is all
    zero (a constant signal) the lag is 0.
    """
    dt = _positive("dt_s", dt_s)
    lags, r = cross_correlation(x, y, max_lag)
    if not np.any(r):
        return {"r": 0.0, "lag_s": 0.0}
    k = int(np.argmax(np.abs(r)))
    return {"r": float(r[k]), "lag_s": float(lags[k] * dt)}


def signature_correlations(residual, signatures: Mapping[str, np.ndarray]) -> dict[str, float]:
    """Pearson product-moment r (Pearson 1896) of ``residual`` with each signature.

    A signature is the predicted shape of a candidate missing effect (e.g. the torque a
    pressure-dependent friction would add). ``r`` is 0.0 where the signature or the residual
    is constant (no linear relation; never NaN).
    """
    r = _array("residual", residual, min_n=2)
    if not isinstance(signatures, Mapping):
        raise ValueError(f"signatures is a {type(signatures).__name__}; allowed: a mapping "
                         "of name to 1-D array")
    out: dict[str, float] = {}
    r_const = _is_constant(r)
    rc = r - r.mean()
    for name, s in signatures.items():
        if not isinstance(name, str):
            raise ValueError(f"signatures has a key {name!r}; allowed: str names")
        a = _array(f"signatures[{name!r}]", s, r.size, "residual")
        if r_const or _is_constant(a):
            out[name] = 0.0
            continue
        ac = a - a.mean()
        v = float(np.dot(rc, ac) / math.sqrt(float(np.dot(rc, rc)) * float(np.dot(ac, ac))))
        out[name] = min(1.0, max(-1.0, v))
    return out


def _cycles(cycles) -> list[tuple[float, float]]:
    if cycles is None or isinstance(cycles, (str, bytes)) or not isinstance(cycles, Iterable):
        raise ValueError(f"cycles = {cycles!r}; allowed: a list of (t_start, t_end) pairs [s]")
    out = []
    for i, c in enumerate(cycles):
        try:
            t0, t1 = (float(v) for v in c)
        except (TypeError, ValueError):
            raise ValueError(f"cycles[{i}] = {c!r}; allowed: a (t_start, t_end) pair of "
                             "numbers [s]") from None
        if not (math.isfinite(t0) and math.isfinite(t1)) or t1 <= t0:
            raise ValueError(f"cycles[{i}] = {c!r}; allowed: finite t_start < t_end [s]")
        out.append((t0, t1))
    if not out:
        raise ValueError("cycles is empty; allowed: at least one (t_start, t_end) pair [s]")
    return out


def _bin_index(t: np.ndarray, t0: float, t1: float, nb: int) -> np.ndarray:
    """Phase bin of each time in ``[t0, t1)``; a sample on a bin edge (up to rounding, 1e-9 of
    a bin) goes to the bin that starts there, so uniform samples fill bins evenly."""
    k = np.floor((t - t0) / (t1 - t0) * nb + 1e-9).astype(np.int64)
    return np.clip(k, 0, nb - 1)


def phase_average(residual, time_s, cycles, bins: int = 50) -> dict:
    """Mean and SD of the residual against normalised cycle phase 0…1 (ensemble average).

    Each cycle ``(t_start, t_end)`` takes the samples with ``t_start <= t < t_end`` at phase
    ``(t − t_start)/(t_end − t_start)``; phase 0…1 is cut into ``bins`` equal bins, and in each
    bin the samples of all cycles are pooled: ``mean`` is their mean, ``sd`` their population
    SD (ddof 0): the spread of the residual at that phase, noise plus cycle-to-cycle variation.
    The ensemble (phase-locked) average of periodic signals (e.g. Bendat & Piersol §1.4;
    Winter, *Biomechanics and Motor Control of Human Movement*, 4th ed., §2.2 for gait).

    Returns ``{"phase": bin centres, "mean", "sd", "count" (samples per bin), "n_cycles"
    (cycles with samples), "peak_phase" (centre of the bin of largest |mean|),
    "peak_value" (that mean, signed)}``. Raises if no cycle has samples, or if a bin has none
    (too many bins for the sampling rate).
    """
    t = _array("time_s", time_s, min_n=2)
    r = _array("residual", residual, t.size, "time_s")
    nb = _integer("bins", bins, 1)
    cyc = _cycles(cycles)
    sums = np.zeros(nb)
    sq = np.zeros(nb)
    count = np.zeros(nb, dtype=np.int64)
    used = 0
    for t0, t1 in cyc:
        sel = (t >= t0) & (t < t1)
        if not np.any(sel):
            continue
        used += 1
        k = _bin_index(t[sel], t0, t1, nb)
        sums += np.bincount(k, weights=r[sel], minlength=nb)
        count += np.bincount(k, minlength=nb)
    if used == 0:
        raise ValueError(f"cycles: none of the {len(cyc)} cycles holds a sample of time_s "
                         f"({t[0]:g}…{t[-1]:g} s); allowed: cycles inside the record")
    if np.any(count == 0):
        k = int(np.flatnonzero(count == 0)[0])
        raise ValueError(f"bins = {nb}: bin {k} (phase {k / nb:g}…{(k + 1) / nb:g}) holds no "
                         "sample of any cycle; allowed: fewer bins than samples per cycle")
    mean = sums / count
    for t0, t1 in cyc:
        sel = (t >= t0) & (t < t1)
        if np.any(sel):
            k = _bin_index(t[sel], t0, t1, nb)
            sq += np.bincount(k, weights=(r[sel] - mean[k]) ** 2, minlength=nb)
    sd = np.sqrt(sq / count)
    phase = (np.arange(nb) + 0.5) / nb
    kp = int(np.argmax(np.abs(mean)))
    return {"phase": phase, "mean": mean, "sd": sd, "count": count, "n_cycles": used,
            "peak_phase": float(phase[kp]), "peak_value": float(mean[kp])}


def residual_spectrum(residual, fs_hz: float) -> tuple[np.ndarray, np.ndarray]:
    """Welch (1967) PSD of the residual: Hann window, ``nperseg = min(1024, n)``, 50 % overlap,
    mean removed per segment, one-sided, in (units of residual)²/Hz. Returns
    ``(freq_hz, psd)``. Needs ≥ 8 samples."""
    r = _array("residual", residual, min_n=_MIN_SPECTRUM_SAMPLES)
    fs = _positive("fs_hz", fs_hz)
    f, p = sps.welch(r, fs=fs, nperseg=min(1024, r.size))
    return f, p


def dominant_frequency(residual, fs_hz: float, f_min_hz: float = 0.5) -> float:
    """Frequency [Hz] of the largest peak of the Welch PSD (:func:`residual_spectrum`) at or
    above ``f_min_hz``, refined between bins by a parabola through the log-PSD at the peak bin
    and its neighbours (quadratic peak interpolation, Smith & Serra 1987; Grandke 1983). The
    resolution without refinement is ``fs_hz/min(1024, n)``. Raises for a constant residual
    (no peak) and for ``f_min_hz`` at or above the Nyquist frequency."""
    r = _array("residual", residual, min_n=_MIN_SPECTRUM_SAMPLES)
    fs = _positive("fs_hz", fs_hz)
    fmin = _positive("f_min_hz", f_min_hz, allow_zero=True)
    if _is_constant(r):
        raise ValueError("residual is constant; it has no dominant frequency; allowed: a "
                         "residual that varies")
    f, p = residual_spectrum(r, fs)
    idx = np.flatnonzero(f >= fmin)
    if idx.size == 0:
        raise ValueError(f"f_min_hz = {f_min_hz!r} leaves no frequency bin; allowed: "
                         f"0 <= f_min_hz <= {f[-1]:g} Hz (Nyquist of fs_hz = {fs:g})")
    k = int(idx[np.argmax(p[idx])])
    fk = float(f[k])
    if 0 < k < f.size - 1 and p[k - 1] > 0 and p[k] > 0 and p[k + 1] > 0:
        a, b, c = np.log(p[k - 1]), np.log(p[k]), np.log(p[k + 1])
        den = a - 2 * b + c
        if den < 0:
            delta = float(np.clip(0.5 * (a - c) / den, -0.5, 0.5))
            fk += delta * float(f[1] - f[0])
    return fk


# --------------------------------------------------------------------------- channel summary

def _signals(arg: str, m, n: int) -> dict[str, np.ndarray]:
    if m is None:
        return {}
    if not isinstance(m, Mapping):
        raise ValueError(f"{arg} is a {type(m).__name__}; allowed: a mapping of name to "
                         "1-D array (or None)")
    out = {}
    for k, v in m.items():
        if not isinstance(k, str):
            raise ValueError(f"{arg} has a key {k!r}; allowed: str names")
        out[k] = _array(f"{arg}[{k!r}]", v, n, "time_s")
    return out


def analyse_channel(name: str, time_s, measured, model, inputs: Mapping[str, np.ndarray],
                    states: Mapping[str, np.ndarray], signatures: Mapping[str, np.ndarray],
                    noise_sigma: float | None, cycles) -> dict:
    """JSON-serialisable summary of the residual ``measured − model`` of one channel.

    ``time_s`` must be strictly increasing and uniform to ±50 % (sample rate 1/median
    interval). ``noise_sigma`` is the sensor noise σ of the channel (same units); None
    estimates it from ``measured`` with :func:`noise_sigma_estimate`. ``inputs``, ``states``
    and ``signatures`` map names to arrays as long as ``time_s`` (empty mappings or None are
    fine); ``cycles`` is a list of ``(t_start, t_end)`` [s] or None.

    Keys: ``channel``, ``n_samples``, ``fs_hz``, ``nrmse`` (:func:`nrmse`), ``rms`` and
    ``mean`` of the residual, ``noise_sigma`` and ``noise_sigma_source`` (``"given"`` or
    ``"estimated"``), ``whiteness`` (:func:`whiteness`), ``excess_ratio`` (rms/noise_sigma),
    ``structured`` (not white and excess_ratio > 1.2), ``cross_correlations`` (the 3 inputs or
    states with the largest |r| of :func:`peak_cross_correlation` with the residual within
    ±0.2 s, each ``{"signal", "kind": "input"|"state", "r", "lag_s"}``, positive lag: the
    residual follows the signal; a state identical to the input of the same name is skipped),
    ``signature_correlations`` (:func:`signature_correlations`), ``peak_phase`` and
    ``peak_value`` (:func:`phase_average` with 50 bins; None without cycles) and
    ``dominant_frequency_hz`` (:func:`dominant_frequency` above 0.5 Hz; None for a constant
    residual), ``drift`` (:func:`windowed_drift`), ``transient`` (:func:`step_transients`
    on the input whose steps leave the largest named transient, with its name under
    ``"input"``; None without inputs), ``resonance`` (:func:`resonance`) and ``high_band``
    (:func:`high_band_excess`, localised near rest by the ``"velocity"`` signature when
    given). ValueErrors name the channel.
    """
    if not isinstance(name, str) or not name:
        raise ValueError(f"name = {name!r}; allowed: a non-empty str (the channel name)")
    try:
        return _analyse_channel(name, time_s, measured, model, inputs, states, signatures,
                                noise_sigma, cycles)
    except ValueError as e:
        raise ValueError(f"channel {name!r}: {e}") from e


def _analyse_channel(name, time_s, measured, model, inputs, states, signatures, noise_sigma,
                     cycles) -> dict:
    t = _array("time_s", time_s, min_n=_MIN_WHITENESS_SAMPLES)
    fs = _sample_rate(t)
    y = _array("measured", measured, t.size, "time_s")
    m = _array("model", model, t.size, "time_s")
    ins = _signals("inputs", inputs, t.size)
    sts = _signals("states", states, t.size)
    sigs = _signals("signatures", signatures, t.size)
    if noise_sigma is None:
        sigma = noise_sigma_estimate(y)
        source = "estimated"
        if not sigma > 0:
            raise ValueError("noise_sigma = None and the estimate from measured is 0 (a "
                             "noise-free or quantised channel); allowed: pass noise_sigma > 0 "
                             "explicitly (e.g. the quantisation step / √12)")
    else:
        sigma = _positive("noise_sigma", noise_sigma)
        source = "given"
    res = y - m
    e = nrmse(y, m)
    w = whiteness(res, sigma, fs)
    constant = _is_constant(res)

    max_lag = min(int(round(XCORR_MAX_LAG_S * fs)), t.size - 1)
    xc = []
    for kind, group in (("input", ins), ("state", sts)):
        for sname, s in group.items():
            if kind == "state" and sname in ins and np.array_equal(ins[sname], s):
                continue
            pk = peak_cross_correlation(res, s, max_lag, 1.0 / fs)
            xc.append({"signal": sname, "kind": kind, "r": pk["r"], "lag_s": pk["lag_s"]})
    xc.sort(key=lambda d: -abs(d["r"]))

    if cycles is None:
        peak_phase = peak_value = None
    else:
        pa = phase_average(res, t, cycles, bins=50)
        peak_phase, peak_value = pa["peak_phase"], pa["peak_value"]

    transient = None
    for iname, u in ins.items():
        tr = step_transients(res, u, fs, sigma)
        tr["input"] = iname
        if transient is None or (tr["transient"], tr["ratio"] or 0.0, tr["n_steps"]) > (
                transient["transient"], transient["ratio"] or 0.0, transient["n_steps"]):
            transient = tr

    return {"channel": name, "n_samples": int(t.size), "fs_hz": float(fs),
            "nrmse": e, "rms": w["rms"], "mean": float(np.mean(res)),
            "noise_sigma": float(sigma), "noise_sigma_source": source,
            "whiteness": w, "excess_ratio": w["excess_ratio"],
            "structured": bool((not w["white"]) and w["excess_ratio"] > STRUCTURE_EXCESS_RATIO),
            "cross_correlations": xc[:3],
            "signature_correlations": signature_correlations(res, sigs),
            "peak_phase": peak_phase, "peak_value": peak_value,
            "dominant_frequency_hz": None if constant else dominant_frequency(res, fs, 0.5),
            "drift": windowed_drift(res, fs, sigma), "transient": transient,
            "resonance": resonance(res, fs, sigma),
            "high_band": high_band_excess(res, fs, sigma, sigs.get("velocity"))}


def _num(summary: dict, key: str, where: str, optional: bool = False):
    v = summary.get(key)
    if v is None and optional:
        return None
    if isinstance(v, bool) or not isinstance(v, (int, float, np.integer, np.floating)) \
            or not math.isfinite(float(v)):
        raise ValueError(f"{where}[{key!r}] = {v!r}; allowed: a finite number "
                         "(a summary from analyse_channel)")
    return float(v)


def locate_structure(channel_summaries: Mapping[str, dict]) -> str:
    """One plain-language sentence saying where the structured residual lives.

    ``channel_summaries`` maps channel names to :func:`analyse_channel` summaries. Structured
    channels are listed worst ``excess_ratio`` first, each with its excess over the noise, the
    phase of the cycle where the phase-averaged residual peaks, the input/state it correlates
    with most (and at what lag), its dominant frequency and, when signatures were given, the
    closest one; e.g. ``"ankle_torque_nm: residual 4.2× the noise, peaks at 63 % of the cycle,
    most correlated with ankle_velocity_rad_s (r = 0.41 at 0.012 s), dominant frequency
    25.0 Hz"``. Channels are separated by "; ". Without a structured channel: "no structured
    residual: every channel is within 1.2× its noise and white" when that is so, otherwise a
    sentence naming the channels that are white but larger than the noise, or not white but
    within it. When :func:`where_findings` names slow drifts (a line pair's common-mode or
    differential drift), transients after input steps or resonances, they follow as
    ``"; named, largest against the noise first: …"``, each with its size against σ in the
    channel's units.
    """
    if not isinstance(channel_summaries, Mapping):
        raise ValueError(f"channel_summaries is a {type(channel_summaries).__name__}; "
                         "allowed: a mapping of channel name to analyse_channel summary")
    if not channel_summaries:
        raise ValueError("channel_summaries is empty; allowed: at least one channel summary")
    rows = []
    for ch, s in channel_summaries.items():
        where = f"channel_summaries[{ch!r}]"
        if not isinstance(s, Mapping):
            raise ValueError(f"{where} is a {type(s).__name__}; allowed: a dict from "
                             "analyse_channel")
        st = s.get("structured")
        if not isinstance(st, (bool, np.bool_)):
            raise ValueError(f"{where}['structured'] = {st!r}; allowed: True or False "
                             "(a summary from analyse_channel)")
        w = s.get("whiteness")
        if not isinstance(w, Mapping) or not isinstance(w.get("white"), (bool, np.bool_)):
            raise ValueError(f"{where}['whiteness'] = {w!r}; allowed: the whiteness dict of "
                             "analyse_channel")
        rows.append((str(ch), dict(s), bool(st), bool(w["white"]),
                     _num(s, "excess_ratio", where), where))

    structured = sorted((r for r in rows if r[2]), key=lambda r: -r[4])
    findings = where_findings({ch: s for ch, s, *_ in rows})
    named = ("; named, largest against the noise first: "
             + "; ".join(f["text"] for f in findings)) if findings else ""
    if not structured:
        notes = []
        for ch, s, _, white, ex, where in rows:
            if white and ex > STRUCTURE_EXCESS_RATIO:
                mean = _num(s, "mean", where, optional=True)
                extra = f", mean {mean:.3g}" if mean is not None else ""
                notes.append(f"{ch}: residual {ex:.1f}× the noise but white{extra}")
            elif not white:
                notes.append(f"{ch}: residual not white but within "
                             f"{STRUCTURE_EXCESS_RATIO:g}× the noise ({ex:.2f}×)")
        if not notes and not findings:
            return (f"no structured residual: every channel is within "
                    f"{STRUCTURE_EXCESS_RATIO:g}× its noise and white")
        return ("no structured residual (no channel is both non-white and above "
                f"{STRUCTURE_EXCESS_RATIO:g}× its noise)" + "".join("; " + n for n in notes)
                + named)

    parts = []
    for ch, s, _, _, ex, where in structured:
        bits = [f"{ch}: residual {ex:.1f}× the noise"]
        ph = _num(s, "peak_phase", where, optional=True)
        if ph is not None:
            bits.append(f"peaks at {100 * ph:.0f} % of the cycle")
        xc = s.get("cross_correlations") or []
        if xc:
            best = max(xc, key=lambda d: abs(float(d["r"])))
            bits.append(f"most correlated with {best['signal']} (r = {float(best['r']):.2f} "
                        f"at {float(best['lag_s']):.4g} s)")
        f = _num(s, "dominant_frequency_hz", where, optional=True)
        if f is not None:
            bits.append(f"dominant frequency {f:.1f} Hz")
        sig = s.get("signature_correlations") or {}
        if sig:
            k = max(sig, key=lambda n: abs(float(sig[n])))
            bits.append(f"closest signature {k} (r = {float(sig[k]):.2f})")
        parts.append(", ".join(bits))
    return "; ".join(parts) + named


# --------------------------------------------------------------------------- where, in rig terms
#
# Three kinds of structure a missing effect leaves, each measured against the channel's sensor
# noise σ (the white-noise level of the residual when nothing is missing):
#
# * slow drift (:func:`windowed_drift`): the record is cut into ``n`` equal consecutive windows
#   of ``m`` samples and the residual's mean taken in each. For white noise each window mean
#   has SD σ/√m, so the change between the first and the last window has SD σ·√(2/m). A drift
#   is named when ``|last − first| > DRIFT_K·σ·√(2/m)`` (DRIFT_K = 5: a 5-SD event of white
#   noise) **and** ``|last − first| > DRIFT_MIN_FRACTION·σ`` (0.5: smaller than half the noise
#   floor it cannot move a channel's ratio to its floor), **and** the least-squares line through
#   the window means rises the same way (a trend, not one odd window).
# * common-mode vs differential (:func:`line_pair_drifts`): for a line pair (pressures at ports
#   A and B), ``(r_a + r_b)/2`` and ``r_a − r_b`` are judged by the same rule with
#   σ_cm = √(σ_a² + σ_b²)/2 and σ_dm = √(σ_a² + σ_b²) (independent sensor noise). A common-mode
#   drift with a flat differential is the signature of oil made up or lost through the charge
#   circuit (both lines move together), not of a leakage across the piston (which moves them
#   apart); issue 41.
# * transients after input steps (:func:`step_transients`): an input's step is a change over
#   ``STEP_SPAN_S`` larger than a quarter of its robust range (0.5–99.5 percentile) and than 8×
#   its own noise (:func:`noise_sigma_estimate`, √2 for the difference); the residual's RMS in
#   the ``window_s`` after each step is compared with σ and with the RMS elsewhere. Named when
#   ``RMS_in > 2σ`` (twice the floor, the acceptance's bound) and ``RMS_in > 1.5·RMS_out``
#   (localised) and the windows hold at most half the record. The ringing frequency there is
#   the peak of the summed, Hann-windowed, zero-padded periodograms of the windows above
#   ``2/window_s`` (at least two periods inside the window).
# * resonance (:func:`resonance`): the Welch peak of :func:`dominant_frequency`, its RMS
#   amplitude from the PSD within ±3 bins of the peak less the white-noise floor (the median
#   PSD), named when the peak stands 10× above the median PSD and its RMS exceeds 0.5σ.
# * broadband excess in the top of the band (:func:`high_band_excess`): the residual's power
#   between ``HIGH_BAND_FRACTION·fs`` and the Nyquist (the Welch PSD integrated over the band)
#   against white noise's share of it, ``σ²·(fs/2 − f_lo)/(fs/2)`` (a white sequence of
#   variance σ² spreads it evenly up to the Nyquist). Named when the band's RMS is
#   ``HIGH_BAND_MIN_RATIO``× the noise's, its excess ``√(P − P_noise)`` exceeds 0.5σ and no
#   single peak holds half of the excess (broadband, not a resonance). Flat power up to the
#   Nyquist that the model does not produce is an oscillation faster than the record resolves,
#   aliased into the band (Oppenheim & Schafer, *Discrete-Time Signal Processing*, §4.2), or a
#   train of sharp events: no replay at the record's rate follows it in phase. When it comes in
#   bursts while the joint is near rest (``SLOW_LOCALISATION``× the band power of the rest of
#   the record in its slowest ``SLOW_FRACTION``), it is the signature of friction-excited
#   vibration: a friction force that falls with sliding speed (Stribeck) acts as negative
#   damping on a lightly damped mode (a piston on its cable and oil), which then oscillates
#   about the sticking point (stick-slip; Armstrong-Hélouvry, Dupont & Canudas de Wit,
#   *Automatica* 30 (1994), §3). For a line pair the differential ``r_a − r_b`` and the
#   common-mode ``(r_a + r_b)/2`` are judged the same way (σ as for the drifts): a force on the
#   piston moves the two chambers apart.

#: Significance of a windowed-mean change, in SDs of white noise's window-mean difference.
DRIFT_K = 5.0
#: A drift smaller than this fraction of σ is not named.
DRIFT_MIN_FRACTION = 0.5
#: Number of windows a residual is cut into for its drift.
DRIFT_WINDOWS = 5
#: Span over which an input's change is judged a step [s].
STEP_SPAN_S = 0.01
#: Window after a step in which the residual's transient is measured [s].
TRANSIENT_WINDOW_S = 0.2
#: RMS in the windows after steps / σ above which a transient is named.
TRANSIENT_MIN_RATIO = 2.0
#: RMS in the windows after steps / RMS elsewhere above which a transient is named.
TRANSIENT_LOCALISATION = 1.5
#: Peak PSD / median PSD above which a spectral peak is a resonance.
RESONANCE_PROMINENCE = 10.0
#: Resonance RMS / σ above which it is named.
RESONANCE_MIN_RATIO = 0.5
#: The upper band judged for broadband excess starts at this fraction of the sample rate
#: (0.2: 200–500 Hz of a 1 kHz record).
HIGH_BAND_FRACTION = 0.2
#: Band RMS / the white noise's RMS in the band above which the band's excess is named.
HIGH_BAND_MIN_RATIO = 1.5
#: Excess RMS (beyond the noise's share of the band) / σ above which it is named.
HIGH_BAND_MIN_EXCESS = 0.5
#: Largest share of the band's excess one spectral peak (±3 Welch bins) may hold for the excess
#: to count as broadband (a larger share is a resonance's, :func:`resonance`).
HIGH_BAND_MAX_PEAK_SHARE = 0.5
#: The slowest fraction of the record (by |velocity|) in which bursts near rest are looked for.
SLOW_FRACTION = 0.2
#: Band power near rest / band power elsewhere above which the excess comes in bursts near rest.
SLOW_LOCALISATION = 2.0

_UNITS = (("_rad_s", "rad/s", 1.0), ("_pa", "MPa", 1e-6), ("_nm", "N·m", 1.0),
          ("_rad", "rad", 1.0), ("_a", "A", 1.0), ("_v", "V", 1.0), ("_k", "K", 1.0),
          ("_m", "m", 1.0), ("_n", "N", 1.0))


def _unit(channel: str) -> tuple[str, float]:
    """Display unit and SI→display factor of a channel from its name's unit suffix."""
    for suffix, unit, f in _UNITS:
        if channel.endswith(suffix):
            return unit, f
    return "", 1.0


def _q(channel: str, value: float) -> str:
    unit, f = _unit(channel)
    return f"{value * f:.3g}" + (f" {unit}" if unit else "")


def windowed_drift(residual, fs_hz: float, noise_sigma: float,
                   n_windows: int = DRIFT_WINDOWS) -> dict:
    """Slow drift of a residual: its mean over ``n_windows`` equal consecutive windows.

    Returns ``{"window_s", "window_samples", "window_centres_s" (from the first sample),
    "window_means", "change" (last − first window mean), "slope_per_s" (least-squares line
    through the window means), "threshold" (the rule of the module's "where" notes:
    max(DRIFT_K·σ·√(2/m), DRIFT_MIN_FRACTION·σ)), "ratio" (|change|/σ), "drift" (named)}``.
    """
    r = _array("residual", residual, min_n=_MIN_WHITENESS_SAMPLES)
    fs = _positive("fs_hz", fs_hz)
    sigma = _positive("noise_sigma", noise_sigma)
    nw = _integer("n_windows", n_windows, 2)
    m = r.size // nw
    if m < 2:
        raise ValueError(f"n_windows = {nw} leaves {m} samples per window of {r.size}; "
                         "allowed: at least 2 samples per window")
    means = r[: m * nw].reshape(nw, m).mean(axis=1)
    centres = (np.arange(nw) + 0.5) * m / fs
    slope = float(np.polyfit(centres, means, 1)[0])
    change = float(means[-1] - means[0])
    thr = max(DRIFT_K * sigma * math.sqrt(2.0 / m), DRIFT_MIN_FRACTION * sigma)
    trend = slope * float(centres[-1] - centres[0])
    drift = bool(abs(change) > thr and np.sign(trend) == np.sign(change)
                 and abs(trend) > 0.5 * thr)
    return {"window_s": m / fs, "window_samples": int(m),
            "window_centres_s": [float(c) for c in centres],
            "window_means": [float(v) for v in means], "change": change,
            "slope_per_s": slope, "threshold": float(thr), "noise_sigma": sigma,
            "ratio": abs(change) / sigma, "drift": drift}


def _drift_of_means(means, centres, m: int, sigma: float) -> dict:
    means = np.asarray(means, dtype=float)
    centres = np.asarray(centres, dtype=float)
    change = float(means[-1] - means[0])
    slope = float(np.polyfit(centres, means, 1)[0])
    trend = slope * float(centres[-1] - centres[0])
    thr = max(DRIFT_K * sigma * math.sqrt(2.0 / m), DRIFT_MIN_FRACTION * sigma)
    return {"first": float(means[0]), "last": float(means[-1]), "change": change,
            "slope_per_s": slope, "noise_sigma": sigma, "ratio": abs(change) / sigma,
            "threshold": float(thr),
            "drift": bool(abs(change) > thr and np.sign(trend) == np.sign(change)
                          and abs(trend) > 0.5 * thr)}


def line_pairs(channels: Iterable[str]) -> list[tuple[str, str]]:
    """Pairs of channels that are the two lines of one actuator: names equal but for
    ``_a_`` ↔ ``_b_`` (``pressure_a_pa``/``pressure_b_pa``, ``chamber_a_pa``/``chamber_b_pa``)."""
    names = list(channels)
    out = []
    for c in names:
        if "_a_" in c:
            other = c.replace("_a_", "_b_", 1)
            if other in names:
                out.append((c, other))
    return out


def line_pair_drifts(drift_a: Mapping, drift_b: Mapping) -> dict:
    """Common-mode ``(r_a + r_b)/2`` and differential ``r_a − r_b`` drift of a line pair, from
    the two channels' :func:`windowed_drift` (window means are linear, so the pair's window
    means are the same combinations of theirs). σ_cm = √(σ_a² + σ_b²)/2, σ_dm = √(σ_a² + σ_b²).
    Returns ``{"common_mode": …, "differential": …}`` with ``first``, ``last``, ``change``,
    ``slope_per_s``, ``noise_sigma``, ``ratio``, ``threshold`` and ``drift`` each."""
    ma = np.asarray(drift_a["window_means"], dtype=float)
    mb = np.asarray(drift_b["window_means"], dtype=float)
    if ma.size != mb.size or drift_a["window_samples"] != drift_b["window_samples"]:
        raise ValueError(f"line pair windows differ ({ma.size} vs {mb.size} windows); allowed: "
                         "two channels of the same record")
    m = int(drift_a["window_samples"])
    s = math.hypot(float(drift_a["noise_sigma"]), float(drift_b["noise_sigma"]))
    c = drift_a["window_centres_s"]
    return {"common_mode": _drift_of_means(0.5 * (ma + mb), c, m, 0.5 * s),
            "differential": _drift_of_means(ma - mb, c, m, s)}


def step_times(command, fs_hz: float, span_s: float = STEP_SPAN_S,
               min_gap_s: float = TRANSIENT_WINDOW_S) -> np.ndarray:
    """Sample indices of an input's steps (reversals included): where its change over
    ``span_s`` exceeds a quarter of its robust range (0.5–99.5 percentile) and 8·√2 × its
    noise (:func:`noise_sigma_estimate`); each step placed at its largest one-sample change,
    steps closer than ``min_gap_s`` merged. Empty for a constant or smooth input."""
    u = _array("command", command, min_n=_MIN_NOISE_SAMPLES)
    fs = _positive("fs_hz", fs_hz)
    w = max(1, int(round(span_s * fs)))
    if u.size <= w + 1 or _is_constant(u):
        return np.zeros(0, dtype=int)
    lo, hi = np.percentile(u, [0.5, 99.5])
    thr = max(0.25 * float(hi - lo), 8.0 * math.sqrt(2.0) * noise_sigma_estimate(u))
    if not thr > 0:
        return np.zeros(0, dtype=int)
    jump = np.abs(u[w:] - u[:-w]) > thr
    d1 = np.abs(np.diff(u))
    out: list[int] = []
    gap = max(1, int(round(min_gap_s * fs)))
    k = np.flatnonzero(jump)
    if k.size == 0:
        return np.zeros(0, dtype=int)
    starts = np.concatenate(([0], np.flatnonzero(np.diff(k) > 1) + 1))
    ends = np.concatenate((starts[1:], [k.size]))
    for s, e in zip(starts, ends):
        a, b = int(k[s]), int(k[e - 1]) + w
        j = a + int(np.argmax(d1[a:b]))
        if not out or j - out[-1] >= gap:
            out.append(j)
    return np.asarray(out, dtype=int)


def _ringing_hz(segments: list[np.ndarray], fs: float, f_min: float) -> float | None:
    n = max(s.size for s in segments)
    nfft = 1 << int(math.ceil(math.log2(max(8 * n, 1024))))
    p = np.zeros(nfft // 2 + 1)
    for s in segments:
        if s.size < 8:
            continue
        x = (s - s.mean()) * np.hanning(s.size)
        p += np.abs(np.fft.rfft(x, nfft)) ** 2
    f = np.fft.rfftfreq(nfft, 1.0 / fs)
    idx = np.flatnonzero(f >= f_min)
    if idx.size < 3 or not np.any(p[idx] > 0):
        return None
    k = int(idx[np.argmax(p[idx])])
    fk = float(f[k])
    if 0 < k < f.size - 1 and min(p[k - 1], p[k], p[k + 1]) > 0:
        a, b, c = np.log(p[k - 1]), np.log(p[k]), np.log(p[k + 1])
        den = a - 2 * b + c
        if den < 0:
            fk += float(np.clip(0.5 * (a - c) / den, -0.5, 0.5)) * float(f[1] - f[0])
    return fk


def step_transients(residual, command, fs_hz: float, noise_sigma: float,
                    window_s: float = TRANSIENT_WINDOW_S) -> dict:
    """The residual in the ``window_s`` after each step of ``command`` (:func:`step_times`)
    against the noise σ and against the residual elsewhere (rule in the module's "where"
    notes). Returns ``{"n_steps", "step_times_s", "window_s", "rms_in", "peak_in", "rms_out",
    "ratio" (rms_in/σ), "localisation" (rms_in/rms_out), "ringing_hz", "noise_sigma",
    "transient" (named)}``; without steps ``n_steps`` is 0 and ``transient`` False."""
    r = _array("residual", residual, min_n=_MIN_WHITENESS_SAMPLES)
    u = _array("command", command, r.size, "residual")
    fs = _positive("fs_hz", fs_hz)
    sigma = _positive("noise_sigma", noise_sigma)
    win = _positive("window_s", window_s)
    ks = step_times(u, fs, min_gap_s=win)
    n_w = max(2, int(round(win * fs)))
    mask = np.zeros(r.size, dtype=bool)
    segs = []
    for k in ks:
        mask[k: k + n_w] = True
        segs.append(r[k: k + n_w])
    out = {"n_steps": int(ks.size), "step_times_s": [float(k / fs) for k in ks],
           "window_s": n_w / fs, "noise_sigma": sigma, "rms_in": None, "peak_in": None,
           "rms_out": None, "ratio": None, "localisation": None, "ringing_hz": None,
           "transient": False}
    if ks.size == 0 or mask.all():
        return out
    rms_in = float(np.sqrt(np.mean(r[mask] ** 2)))
    rms_out = float(np.sqrt(np.mean(r[~mask] ** 2)))
    loc = rms_in / rms_out if rms_out > 0 else math.inf
    named = bool(rms_in > TRANSIENT_MIN_RATIO * sigma and loc > TRANSIENT_LOCALISATION
                 and mask.mean() <= 0.5)
    out.update({"rms_in": rms_in, "peak_in": float(np.max(np.abs(r[mask]))),
                "rms_out": rms_out, "ratio": rms_in / sigma,
                "localisation": loc if math.isfinite(loc) else None, "transient": named,
                "ringing_hz": _ringing_hz(segs, fs, 2.0 / win) if named else None})
    return out


def resonance(residual, fs_hz: float, noise_sigma: float, f_min_hz: float = 0.5) -> dict:
    """The residual's largest spectral peak (:func:`dominant_frequency`) with its RMS
    amplitude: the Welch PSD within ±3 bins of the peak, less the white floor (median PSD),
    integrated. Returns ``{"frequency_hz", "rms", "ratio" (rms/σ), "prominence" (peak PSD /
    median PSD), "resonance" (named: prominence > 10 and ratio > 0.5)}``."""
    r = _array("residual", residual, min_n=_MIN_SPECTRUM_SAMPLES)
    fs = _positive("fs_hz", fs_hz)
    sigma = _positive("noise_sigma", noise_sigma)
    if _is_constant(r):
        return {"frequency_hz": None, "rms": 0.0, "ratio": 0.0, "prominence": 0.0,
                "resonance": False}
    f, p = residual_spectrum(r, fs)
    fk = dominant_frequency(r, fs, f_min_hz)
    k = int(np.argmin(np.abs(f - fk)))
    floor = float(np.median(p[1:])) if p.size > 2 else 0.0
    band = slice(max(1, k - 3), min(p.size, k + 4))
    df = float(f[1] - f[0])
    power = float(np.sum(np.maximum(p[band] - floor, 0.0)) * df)
    rms = math.sqrt(power)
    prom = float(p[k] / floor) if floor > 0 else math.inf
    return {"frequency_hz": fk, "rms": rms, "ratio": rms / sigma,
            "prominence": prom if math.isfinite(prom) else None,
            "resonance": bool(prom > RESONANCE_PROMINENCE and rms / sigma > RESONANCE_MIN_RATIO)}


def high_band_excess(residual, fs_hz: float, noise_sigma: float, velocity=None) -> dict:
    """The residual's broadband power between ``f_lo = HIGH_BAND_FRACTION·fs_hz`` and the
    Nyquist against white noise of SD ``noise_sigma`` (module notes, "broadband excess").

    ``P`` is the Welch PSD (:func:`residual_spectrum`) integrated over the band, ``P_n =
    σ² (fs/2 − f_lo)/(fs/2)`` the white noise's share of it. Returns ``{"f_lo_hz",
    "band_rms", "noise_rms" (√P_n), "ratio" (band_rms/noise_rms), "excess_rms" (√max(P − P_n,
    0)), "excess_ratio" (excess_rms/σ), "peak_share" (the largest ±3-bin window's share of
    the band's excess power above the noise's level), "near_rest" (band power in the slowest
    ``SLOW_FRACTION`` of the samples by ``|velocity|`` over the band power elsewhere, from
    the residual high-passed at ``f_lo`` by a 4th-order Butterworth run forwards and
    backwards; None without ``velocity``), "broadband" (named: ratio ≥ HIGH_BAND_MIN_RATIO,
    excess_ratio ≥ HIGH_BAND_MIN_EXCESS, peak_share ≤ HIGH_BAND_MAX_PEAK_SHARE)}``.

    Example: white noise of σ = 1 (0.6 of its variance in the band) plus an independent
    sequence of SD 0.6 confined to 0.25–0.5·fs gives ratio √((0.6 + 0.36)/0.6) = 1.26, excess
    0.6: not named; of SD 2, ratio √((0.6 + 4)/0.6) = 2.77, excess 2: named.
    """
    r = _array("residual", residual, min_n=_MIN_SPECTRUM_SAMPLES)
    fs = _positive("fs_hz", fs_hz)
    sigma = _positive("noise_sigma", noise_sigma)
    nyq = 0.5 * fs
    f_lo = HIGH_BAND_FRACTION * fs
    noise_p = sigma * sigma * (nyq - f_lo) / nyq
    out = {"f_lo_hz": f_lo, "band_rms": 0.0, "noise_rms": math.sqrt(noise_p), "ratio": 0.0,
           "excess_rms": 0.0, "excess_ratio": 0.0, "peak_share": None, "near_rest": None,
           "broadband": False}
    if _is_constant(r):
        return out
    f, p = residual_spectrum(r, fs)
    band = f >= f_lo
    if np.count_nonzero(band) < 8:
        return out
    df = float(f[1] - f[0])
    power = float(np.sum(p[band]) * df)
    excess_p = max(power - noise_p, 0.0)
    white_psd = sigma * sigma / nyq
    above = np.maximum(p[band] - white_psd, 0.0) * df
    peak = 0.0
    if above.sum() > 0.0:
        win = np.convolve(above, np.ones(7), mode="same")
        peak = float(win.max() / above.sum())
    out.update({"band_rms": math.sqrt(power), "ratio": math.sqrt(power / noise_p),
                "excess_rms": math.sqrt(excess_p), "excess_ratio": math.sqrt(excess_p) / sigma,
                "peak_share": peak})
    if velocity is not None:
        v = np.abs(_array("velocity", velocity, r.size, "residual"))
        if not _is_constant(v) and r.size > 60:
            sos = sps.butter(4, f_lo / nyq, btype="highpass", output="sos")
            h2 = sps.sosfiltfilt(sos, r) ** 2
            slow = v <= np.quantile(v, SLOW_FRACTION)
            if 0 < np.count_nonzero(slow) < r.size:
                rest = float(np.mean(h2[~slow]))
                out["near_rest"] = float(np.mean(h2[slow]) / rest) if rest > 0 else None
    out["broadband"] = bool(out["ratio"] >= HIGH_BAND_MIN_RATIO
                            and out["excess_ratio"] >= HIGH_BAND_MIN_EXCESS
                            and peak <= HIGH_BAND_MAX_PEAK_SHARE)
    return out


def line_pair_high_band(residual_a, residual_b, fs_hz: float, sigma_a: float, sigma_b: float,
                        velocity=None) -> dict:
    """:func:`high_band_excess` of a line pair's common mode ``(r_a + r_b)/2`` (σ_cm =
    √(σ_a² + σ_b²)/2) and differential ``r_a − r_b`` (σ_dm = √(σ_a² + σ_b²)): independent
    sensor noise on the two lines. Returns ``{"common_mode": …, "differential": …}``."""
    a = _array("residual_a", residual_a, min_n=_MIN_SPECTRUM_SAMPLES)
    b = _array("residual_b", residual_b, a.size, "residual_a")
    s = math.hypot(_positive("sigma_a", sigma_a), _positive("sigma_b", sigma_b))
    return {"common_mode": high_band_excess(0.5 * (a + b), fs_hz, 0.5 * s, velocity),
            "differential": high_band_excess(a - b, fs_hz, s, velocity)}


def _high_band_text(what: str, hb: Mapping, channel: str, fs: float) -> str:
    rest = hb.get("near_rest")
    burst = (f", in bursts near rest ({rest:.1f}× the band's power elsewhere): friction-"
             f"excited vibration (stick-slip), a friction that falls with speed exciting a "
             f"mode of the piston" if rest is not None and rest >= SLOW_LOCALISATION else
             f": a vibration above the {0.5 * fs:.0f} Hz Nyquist (a lightly damped mode, "
             f"such as the piston on its cable and oil, excited by a friction that falls with "
             f"speed or by a sensor's own resonance), or sharp events")
    return (f"{what} broadband residual above {float(hb['f_lo_hz']):.0f} Hz, RMS "
            f"{_q(channel, float(hb['excess_rms']))} beyond the noise "
            f"({float(hb['ratio']):.1f}× the noise's share of the band), aliased into the "
            f"record{burst}; a replay at the record's rate cannot follow it in phase")


def where_findings(channel_summaries: Mapping[str, dict]) -> list[dict]:
    """The named findings of :func:`analyse_channel` summaries, largest against the noise
    first: ``{"kind": "common_mode_drift" | "differential_drift" | "drift" | "step_transient"
    | "resonance" | "high_band" | "differential_high_band" | "common_mode_high_band",
    "channels", "ratio" (size/σ), "text"}``. A line pair's common-mode or differential drift
    replaces the drifts of its two channels, and its common-mode or differential broadband
    excess (``line_pair_high_band`` in the first channel's summary,
    :func:`line_pair_high_band`) their broadband excesses (``high_band``,
    :func:`high_band_excess`). Summaries without these keys contribute nothing."""
    out: list[dict] = []
    covered: set[str] = set()
    for a, b in line_pairs(channel_summaries):
        da, db = channel_summaries[a].get("drift"), channel_summaries[b].get("drift")
        if not (isinstance(da, Mapping) and isinstance(db, Mapping)):
            continue
        pair = line_pair_drifts(da, db)
        cm, dm = pair["common_mode"], pair["differential"]
        w = float(da["window_s"])
        for kind, d, other, oname in (("common_mode", cm, dm, "differential"),
                                      ("differential", dm, cm, "common mode")):
            if not d["drift"]:
                continue
            flat = "" if other["drift"] else f"; {oname} flat ({other['ratio']:.1f}×)"
            label = "common-mode" if kind == "common_mode" else "differential"
            what = "pressure" if a.endswith("_pa") else "line"
            out.append({"kind": f"{kind}_drift", "channels": [a, b], "ratio": d["ratio"],
                        "change": d["change"], "noise_sigma": d["noise_sigma"],
                        "text": f"{a}/{b}: {label} {what} drift, residual mean "
                                f"{_q(a, d['first'])} in the first {w:.3g} s → "
                                f"{_q(a, d['last'])} in the last {w:.3g} s, "
                                f"{d['ratio']:.1f}× the noise σ {_q(a, d['noise_sigma'])}"
                                + flat})
            covered.update((a, b))
    broad: set[str] = set()
    for a, b in line_pairs(channel_summaries):
        pair = channel_summaries[a].get("line_pair_high_band")
        if not isinstance(pair, Mapping):
            continue
        fs = float(channel_summaries[a].get("fs_hz") or 0.0)
        for kind, d, other, oname in (
                ("differential", pair["differential"], pair["common_mode"], "common mode"),
                ("common_mode", pair["common_mode"], pair["differential"], "differential")):
            if not d["broadband"]:
                continue
            label = "common-mode" if kind == "common_mode" else "differential"
            flat = ("" if other["broadband"] else
                    f"; {oname} within the noise's band ({float(other['ratio']):.1f}×)")
            out.append({"kind": f"{kind}_high_band", "channels": [a, b],
                        "ratio": float(d["excess_ratio"]), "f_lo_hz": float(d["f_lo_hz"]),
                        "near_rest": d.get("near_rest"),
                        "text": f"{a}/{b}: " + _high_band_text(label, d, a, fs) + flat})
            broad.update((a, b))
    for ch, s in channel_summaries.items():
        hb = s.get("high_band")
        if isinstance(hb, Mapping) and hb.get("broadband") and ch not in broad:
            out.append({"kind": "high_band", "channels": [ch],
                        "ratio": float(hb["excess_ratio"]), "f_lo_hz": float(hb["f_lo_hz"]),
                        "near_rest": hb.get("near_rest"),
                        "text": f"{ch}: " + _high_band_text("a", hb, ch,
                                                           float(s.get("fs_hz") or 0.0))})
        d = s.get("drift")
        if isinstance(d, Mapping) and d.get("drift") and ch not in covered:
            m = d["window_means"]
            out.append({"kind": "drift", "channels": [ch], "ratio": float(d["ratio"]),
                        "change": float(d["change"]), "noise_sigma": float(d["noise_sigma"]),
                        "text": f"{ch}: slow drift, residual mean {_q(ch, m[0])} in the first "
                                f"{float(d['window_s']):.3g} s → {_q(ch, m[-1])} in the last, "
                                f"{float(d['ratio']):.1f}× the noise σ "
                                f"{_q(ch, float(d['noise_sigma']))}"})
        t = s.get("transient")
        if isinstance(t, Mapping) and t.get("transient"):
            ring = (f", ringing at ~{t['ringing_hz']:.0f} Hz" if t.get("ringing_hz") else "")
            out.append({"kind": "step_transient", "channels": [ch], "ratio": float(t["ratio"]),
                        "input": t.get("input"), "window_s": float(t["window_s"]),
                        "ringing_hz": t.get("ringing_hz"),
                        "text": f"{ch}: transient in the {float(t['window_s']):.3g} s after "
                                f"{t['n_steps']} step(s) of {t.get('input', 'the input')}, "
                                f"RMS {_q(ch, float(t['rms_in']))} (peak "
                                f"{_q(ch, float(t['peak_in']))}) against σ "
                                f"{_q(ch, float(t['noise_sigma']))}: "
                                f"{float(t['ratio']):.1f}× the noise, "
                                f"{float(t['localisation'] or math.inf):.1f}× the residual "
                                f"elsewhere" + ring})
        rz = s.get("resonance")
        if isinstance(rz, Mapping) and rz.get("resonance"):
            out.append({"kind": "resonance", "channels": [ch], "ratio": float(rz["ratio"]),
                         "frequency_hz": float(rz["frequency_hz"]),
                         "text": f"{ch}: resonance at {float(rz['frequency_hz']):.1f} Hz, "
                                 f"RMS {_q(ch, float(rz['rms']))}, "
                                 f"{float(rz['ratio']):.1f}× the noise"})
    out.sort(key=lambda d: -d["ratio"])
    return out
