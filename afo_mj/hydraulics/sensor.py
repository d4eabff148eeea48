"""Sensors between the plant and the record: delay, gain and offset.

A transducer chain (sensor, amplifier, anti-alias filter, acquisition) reports
``y_meas(t) = g · y(t − d) + b``: a gain error ``g`` (calibration of the span), an offset ``b``
(zero drift, a mounting preload on a load cell) and a delay ``d`` (filter group delay,
acquisition latency between the input and output channels). These are the sensor effects of
the calibration library (:mod:`afo_mj.calibration.effect_library`). The delay is applied by
linear interpolation in time, holding the first sample before the record starts.
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
