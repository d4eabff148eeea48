"""Sensors between the plant and the record: delay, gain and offset.

A transducer chain (sensor, amplifier, anti-alias filter, acquisition) reports
``y_meas(t) = g · y(t − d) + b``: a gain error ``g`` (calibration of the span), an offset ``b``
(zero drift, a mounting preload on a load cell) and a delay ``d`` (filter group delay,
acquisition latency between the input and output channels). These are the sensor effects of
the calibration library (:mod:`afo_mj.calibration.effect_library`). The delay is applied by
linear interpolation in time, holding the first sample before the record starts. A sensor's
own dynamics, a first-order lag, is :func:`first_order_lag`.
"""

from __future__ import annotations

import numpy as np

from .params import ParameterError


def sensor_reading(time_s: np.ndarray, signal: np.ndarray, gain: float = 1.0,
                   offset: float = 0.0, delay_s: float = 0.0) -> np.ndarray:
    """``g · y(t − d) + b`` sampled at ``time_s`` (``y`` given at the same times).

    >>> t = np.arange(5) * 0.01
    >>> sensor_reading(t, t * 100.0, gain=2.0, offset=1.0, delay_s=0.005).tolist()
    [1.0, 2.0, 4.0, 6.0, 8.0]
    """
    if not (np.isfinite(delay_s) and delay_s >= 0.0):
        raise ParameterError(f"sensor delay_s = {delay_s!r}; allowed: finite and >= 0")
    if not (np.isfinite(gain) and np.isfinite(offset)):
        raise ParameterError(f"sensor gain = {gain!r}, offset = {offset!r}; allowed: finite")
    y = signal if delay_s == 0.0 else np.interp(time_s - delay_s, time_s, signal)
    return gain * y + offset


def first_order_lag(time_s: np.ndarray, signal: np.ndarray, tau_s: float) -> np.ndarray:
    """A sensor's first-order lag ``τ ẏ_m = y − y_m`` (a transducer's or anti-alias filter's
    dominant pole; Doebelin, *Measurement Systems*, 5th ed., §3.3 first-order instruments),
    integrated exactly for an input linear between samples (the ramp-invariant discretisation,
    Franklin, Powell & Workman, *Digital Control*, §6.3.3), starting in equilibrium
    ``y_m(t_0) = y(t_0)``. ``tau_s = 0`` returns the signal.

    >>> t = np.arange(4) * 0.01
    >>> np.round(first_order_lag(t, np.array([0.0, 1.0, 1.0, 1.0]), 0.01), 4).tolist()
    [0.0, 0.3679, 0.7675, 0.9145]
    """
    if not (np.isfinite(tau_s) and tau_s >= 0.0):
        raise ParameterError(f"sensor lag tau_s = {tau_s!r}; allowed: finite and >= 0")
    y = np.asarray(signal, dtype=float)
    if tau_s == 0.0 or y.size < 2:
        return y.copy()
    t = np.asarray(time_s, dtype=float)
    out = np.empty_like(y)
    out[0] = y[0]
    h = np.diff(t)
    a = np.exp(-h / tau_s)
    # exact response to a ramp between samples: y_m' = a y_m + (1 − a) y_k
    #   + (y_{k+1} − y_k)(1 − τ (1 − a)/h)
    b = 1.0 - tau_s * (1.0 - a) / h
    if np.allclose(h, h[0], rtol=1e-9, atol=0.0):
        # uniform samples: the same recursion as one IIR filter,
        # y_m[k+1] = a y_m[k] + (1 − a − b) y[k] + b y[k+1]
        from scipy.signal import lfilter
        a0, b0 = float(a[0]), float(b[0])
        num, den = [b0, 1.0 - a0 - b0], [1.0, -a0]
        zi = np.array([a0 * out[0] + (1.0 - a0 - b0) * y[0]])
        out[1:] = lfilter(num, den, y[1:], zi=zi)[0]
        return out
    for k in range(y.size - 1):
        out[k + 1] = a[k] * out[k] + (1.0 - a[k]) * y[k] + (y[k + 1] - y[k]) * b[k]
    return out
