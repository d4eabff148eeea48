"""Response metrics of bench tests: step response, sine fit, bandwidth (pure numpy).

Definitions
-----------
Step response (:func:`step_metrics`), as in the standard control-engineering texts (Ogata,
*Modern Control Engineering*, 5th ed., §5-3; Franklin, Powell & Emami-Naeini, *Feedback
Control of Dynamic Systems*, §3.4) with the 10 %/90 % reference levels of IEEE Std 181-2011
(*Transitions, Pulses, and Related Waveforms*). All of them are taken relative to the
*transition* from the initial level ``y0`` (the sample at or just before ``t_step``) to the
final level ``y_f`` (mean over the last part of the record), so they apply equally to steps
downwards (negative torque):

* rise time: time from the first crossing of ``y0 + 0.1 (y_f − y0)`` to the first crossing
  of ``y0 + 0.9 (y_f − y0)`` (linear interpolation between samples);
* overshoot [%]: ``100 · max(0, (y_peak − y_f)/(y_f − y0))``, with ``y_peak`` the extreme
  value in the direction of the step;
* settling time: time from ``t_step`` until ``y`` last leaves the band
  ``y_f ± 0.02 |y_f − y0|`` (2 % criterion);
* steady-state error: ``target − y_f`` (in units of ``y``) and relative to the commanded
  step, ``(target − y_f)/(target − y0)``.

Sine response (:func:`sine_response`): the three-parameter least-squares sine fit at a known
frequency of IEEE Std 1057-2017 (*Digitizing Waveform Recorders*, §4.1.3.1 / Annex A):
``x(t) ≈ a sin ωt + b cos ωt + c``, amplitude ``√(a² + b²)``, phase ``atan2(b, a)``; applied to
input and output over the same whole number of cycles after a settling interval. Gain
``A_y / A_u``, phase ``φ_y − φ_u`` wrapped to (−180°, 180°].

Bandwidth (:func:`bandwidth_hz`): the lowest frequency at which the magnitude falls 3 dB below
its low-frequency value (the gain at the lowest measured frequency), the usual closed- or
open-loop bandwidth definition (Franklin et al. §6.1; Ogata §7-2); between measured points the
gain in dB is interpolated linearly in log₁₀ f (straight lines on the Bode plot).
"""

from __future__ import annotations

import math
import warnings

import numpy as np

__all__ = ["step_metrics", "sine_response", "bandwidth_hz", "first_crossing_s"]


def _series(name: str, x, n: int | None = None) -> np.ndarray:
    a = np.asarray(x, dtype=float)
    if a.ndim != 1:
        a = a.reshape(-1) if a.size and a.ndim == 2 and 1 in a.shape else a
    if a.ndim != 1:
        raise ValueError(f"{name} must be one-dimensional; got shape {np.shape(x)}")
    if a.size == 0:
        raise ValueError(f"{name} is empty; allowed: a 1-D array with at least 2 samples")
    if not np.all(np.isfinite(a)):
        bad = int(np.flatnonzero(~np.isfinite(a))[0])
        raise ValueError(f"{name} contains a non-finite value ({a[bad]!r} at index {bad}); "
                         "allowed: finite numbers only")
    if n is not None and a.size != n:
        raise ValueError(f"{name} has {a.size} samples but time_s has {n}; the lengths must match")
    return a


def _time(time_s) -> np.ndarray:
    t = _series("time_s", time_s)
    if t.size < 2:
        raise ValueError(f"time_s has {t.size} sample(s); allowed: at least 2")
    if np.any(np.diff(t) <= 0):
        raise ValueError("time_s must be strictly increasing")
    return t


def _scalar(name: str, v) -> float:
    try:
        f = float(v)
    except (TypeError, ValueError):
        raise ValueError(f"{name} = {v!r} is not a number") from None
    if not math.isfinite(f):
        raise ValueError(f"{name} = {v!r}; allowed: a finite number")
    return f


def first_crossing_s(time_s: np.ndarray, r: np.ndarray, level: float) -> float:
    """First time the (normalised, rising) signal ``r`` reaches ``level``, linearly
    interpolated between the bracketing samples; NaN if it never does."""
    idx = np.flatnonzero(r >= level)
    if idx.size == 0:
        return math.nan
    k = int(idx[0])
    if k == 0:
        return float(time_s[0])
    r0, r1 = r[k - 1], r[k]
    frac = (level - r0) / (r1 - r0) if r1 != r0 else 0.0
    return float(time_s[k - 1] + frac * (time_s[k] - time_s[k - 1]))


def step_metrics(time_s, y, target: float, t_step: float, *, settle_band: float = 0.02,
                 final_fraction: float = 0.1) -> dict:
    """Step-response metrics of ``y(t)`` for a step command to ``target`` applied at ``t_step``.

    Definitions in the module docstring (Ogata §5-3; IEEE Std 181-2011 10/90 % levels). The
    initial level ``y0`` is the sample at or just before ``t_step``; the final level ``y_f`` is
    the mean over the last ``final_fraction`` of the samples after ``t_step`` (so the record
    must be long enough to have settled). Returns a dict:

    ``initial``, ``final``, ``target``; ``rise_time_s`` (10–90 %), ``t10_s``/``t90_s`` (from
    the step), ``overshoot_pct``, ``peak`` (extreme value in the step direction),
    ``peak_time_s``; ``settling_time_s`` (``settle_band``, default 2 %);
    ``steady_state_error`` (= target − final, units of ``y``) and
    ``steady_state_error_rel`` (÷ (target − initial)). Times are NaN where a level is never
    reached.
    """
    t = _time(time_s)
    yy = _series("y", y, t.size)
    target = _scalar("target", target)
    t_step = _scalar("t_step", t_step)
    if not (t[0] <= t_step < t[-1]):
        raise ValueError(f"t_step = {t_step!r} is outside the record; allowed: "
                         f"{t[0]:g} <= t_step < {t[-1]:g} [s]")
    if not (0.0 < settle_band < 1.0):
        raise ValueError(f"settle_band = {settle_band!r}; allowed: 0 < settle_band < 1")
    if not (0.0 < final_fraction <= 0.5):
        raise ValueError(f"final_fraction = {final_fraction!r}; allowed: 0 < final_fraction <= 0.5")
    k0 = int(np.searchsorted(t, t_step, side="right")) - 1
    y0 = float(yy[k0])
    ta, ya = t[k0:] - t_step, yy[k0:]
    if ta.size < 3:
        raise ValueError("fewer than 3 samples after t_step; extend the record")
    n_fin = max(1, int(round(final_fraction * ta.size)))
    yf = float(np.mean(ya[-n_fin:]))
    span = yf - y0
    if target == y0:
        raise ValueError(f"target = {target!r} equals the initial level; no step to measure")
    out = {"initial": y0, "final": yf, "target": target,
           "steady_state_error": target - yf,
           "steady_state_error_rel": (target - yf) / (target - y0)}
    nan = math.nan
    if span == 0.0 or np.sign(span) != np.sign(target - y0):
        # The output never moved towards the target: no transition to measure.
        out.update(rise_time_s=nan, t10_s=nan, t90_s=nan, overshoot_pct=nan, peak=nan,
                   peak_time_s=nan, settling_time_s=nan)
        return out
    r = (ya - y0) / span                      # normalised transition, rising 0 → 1
    t10 = first_crossing_s(ta, r, 0.1)
    t90 = first_crossing_s(ta, r, 0.9)
    kp = int(np.argmax(r))
    outside = np.flatnonzero(np.abs(r - 1.0) > settle_band)
    if outside.size == 0:
        ts = 0.0
    elif outside[-1] == r.size - 1:
        ts = nan                              # still outside the band at the end
    else:
        ts = float(ta[outside[-1] + 1])
    out.update(rise_time_s=t90 - t10, t10_s=t10, t90_s=t90,
               overshoot_pct=100.0 * max(0.0, float(r[kp]) - 1.0),
               peak=float(ya[kp]), peak_time_s=float(ta[kp]), settling_time_s=ts)
    return out


def _fit3(t: np.ndarray, x: np.ndarray, w: float) -> tuple[float, float, float, float]:
    """IEEE 1057 three-parameter fit; returns (amplitude, phase_rad, offset, rms residual)."""
    m = np.column_stack((np.sin(w * t), np.cos(w * t), np.ones_like(t)))
    coef, *_ = np.linalg.lstsq(m, x, rcond=None)
    a, b, c = (float(v) for v in coef)
    res = x - m @ coef
    return math.hypot(a, b), math.atan2(b, a), c, float(np.sqrt(np.mean(res ** 2)))


def sine_response(time_s, u, y, freq_hz: float, settle_cycles: float = 2.0) -> dict:
    """Gain and phase of ``y`` relative to ``u`` at ``freq_hz`` by least-squares sine fits.

    Both signals are fitted with ``a sin 2πft + b cos 2πft + c`` (IEEE Std 1057 three-parameter
    fit at a known frequency) over the largest whole number of cycles that starts
    ``settle_cycles`` periods after the first sample. Returns ``gain`` (A_y/A_u),
    ``gain_db`` (20 log₁₀ gain), ``phase_deg`` (φ_y − φ_u in (−180, 180]),
    ``amplitude_u``/``amplitude_y``, ``offset_u``/``offset_y``, ``cycles`` (fitted) and
    ``distortion_y`` (RMS fit residual of y ÷ its RMS sine amplitude A_y/√2: a measure of
    non-sinusoidal content and noise).
    """
    t = _time(time_s)
    uu = _series("u", u, t.size)
    yy = _series("y", y, t.size)
    f = _scalar("freq_hz", freq_hz)
    if f <= 0:
        raise ValueError(f"freq_hz = {freq_hz!r}; allowed: freq_hz > 0 [Hz]")
    sc = _scalar("settle_cycles", settle_cycles)
    if sc < 0:
        raise ValueError(f"settle_cycles = {settle_cycles!r}; allowed: >= 0")
    period = 1.0 / f
    t_start = t[0] + sc * period
    # each sample stands for one sampling interval, so N uniform samples cover N·dt
    dt = float(np.median(np.diff(t)))
    cycles = int(math.floor((t[-1] + dt - t_start) / period + 1e-6))
    if cycles < 1:
        raise ValueError(f"the record ({t[-1] - t[0]:g} s) holds no whole cycle at {f:g} Hz after "
                         f"{sc:g} settling cycles; allowed: duration >= "
                         "(settle_cycles + 1)/freq_hz")
    t_end = t_start + cycles * period
    sel = (t >= t_start - 1e-6 * dt) & (t < t_end - 1e-6 * dt)
    if np.count_nonzero(sel) < 4:
        raise ValueError(f"fewer than 4 samples in the fitted cycles at {f:g} Hz; sample faster")
    w = 2 * math.pi * f
    ts = t[sel] - t_start
    au, pu, cu, _ = _fit3(ts, uu[sel], w)
    ay, py, cy, ry = _fit3(ts, yy[sel], w)
    if au == 0.0:
        raise ValueError(f"u has no component at {f:g} Hz (amplitude 0); cannot form a gain")
    gain = ay / au
    ph = math.degrees(py - pu)
    ph = (ph + 180.0) % 360.0 - 180.0
    if ph == -180.0:
        ph = 180.0
    return {"freq_hz": f, "gain": gain,
            "gain_db": 20 * math.log10(gain) if gain > 0 else -math.inf,
            "phase_deg": ph, "amplitude_u": au, "amplitude_y": ay, "offset_u": cu,
            "offset_y": cy, "cycles": cycles,
            "distortion_y": ry / (ay / math.sqrt(2)) if ay > 0 else math.inf}


def bandwidth_hz(freqs, gains_db, *, drop_db: float = 3.0, return_note: bool = False):
    """The −3 dB bandwidth: lowest frequency at which the gain falls ``drop_db`` below the
    gain at the lowest measured frequency (the low-frequency reference).

    Frequencies are sorted first; the crossing is interpolated linearly in (log₁₀ f, dB). If
    the gain never falls that far within the measured range the result is NaN and a
    ``RuntimeWarning`` says so (the bandwidth lies above the highest frequency measured). With
    ``return_note=True`` returns ``(bandwidth_hz, note)`` instead, ``note`` being '' or that
    explanation (no warning then).
    """
    f = _series("freqs", freqs)
    g = _series("gains_db", gains_db)
    if g.size != f.size:
        raise ValueError(f"gains_db has {g.size} values but freqs has {f.size}; the lengths "
                         "must match")
    if f.size < 2:
        raise ValueError(f"freqs has {f.size} value(s); allowed: at least 2")
    if np.any(f <= 0):
        raise ValueError("freqs must all be > 0 [Hz] (log interpolation)")
    if not (drop_db > 0):
        raise ValueError(f"drop_db = {drop_db!r}; allowed: drop_db > 0 [dB]")
    order = np.argsort(f)
    f, g = f[order], g[order]
    if np.any(np.diff(f) == 0):
        raise ValueError("freqs contains a repeated frequency")
    level = g[0] - drop_db
    below = np.flatnonzero(g <= level)
    note = ""
    if below.size == 0:
        bw = math.nan
        note = (f"gain never fell {drop_db:g} dB below its low-frequency value "
                f"({g[0]:.2f} dB at {f[0]:g} Hz) up to {f[-1]:g} Hz (minimum {g.min():.2f} dB): "
                f"bandwidth above the measured range")
    else:
        k = int(below[0])
        lf0, lf1 = math.log10(f[k - 1]), math.log10(f[k])
        frac = (g[k - 1] - level) / (g[k - 1] - g[k]) if g[k - 1] != g[k] else 1.0
        bw = 10 ** (lf0 + frac * (lf1 - lf0))
    if return_note:
        return bw, note
    if note:
        warnings.warn(note, RuntimeWarning, stacklevel=2)
    return bw
