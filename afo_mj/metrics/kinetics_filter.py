"""Low-pass filtering of joint moments and powers for display, as gait laboratories do.

A simulated contact delivers its impulse at heel strike and foot flat in a few milliseconds;
the joint moments from it (and the powers, moment × angular velocity) carry brief spikes a
force plate with marker-based inverse dynamics never shows, because laboratories low-pass
filter the data before they report it (Winter, *Biomechanics and Motor Control of Human
Movement*, 4th ed., 2009, ch. 2 on digital filtering; Kristianslund, Krosshaug & van den Bogert
2012, J. Biomech. 45:666, on filtering forces and kinematics alike to avoid impact
artefacts in joint moments). A spike of −5 W/kg lasting 10 ms then sets the figure's axes
and hides the curve's shape.

The filter used for the figures (:data:`KINETICS_CUTOFF_HZ`, :data:`KINETICS_FILTER_ORDER`):

* Butterworth low-pass, designed at 2nd order and run forward then backward over the whole
  record (``scipy.signal.filtfilt``): zero phase lag, 4th-order roll-off;
* the design cutoff is raised by the factor ``1 / C``, ``C = (2^(1/2) − 1)^(1/4) ≈ 0.802``,
  so that the two passes together are −3 dB at the stated cutoff (Winter's correction for a
  filter applied twice: each pass alone would be −3 dB there, both −6 dB);
* cutoff 6 Hz, at the low end of the 6–15 Hz commonly used for walking kinetics (Winter
  ch. 2 picks a cutoff by residual analysis of the data); a stride lasts ~1 s, so the
  moment and power curves of a stride lie well below it.

Only the figures use the filtered curves: every metric in ``summary.json`` and the curves in
``gait_curves.csv`` stay computed from the unfiltered record.
"""

from __future__ import annotations

import dataclasses
from typing import Sequence

import numpy as np

__all__ = ["KINETICS_CUTOFF_HZ", "KINETICS_FILTER_ORDER", "TWO_PASS_CUTOFF_CORRECTION",
           "KINETIC_CHANNELS", "lowpass_zero_lag", "filtered_kinetic_cycles", "filter_note"]

#: −3 dB cutoff of the displayed moments and powers (Hz).
KINETICS_CUTOFF_HZ = 6.0
#: Effective order of the zero-lag filter (a 2nd-order Butterworth passed twice).
KINETICS_FILTER_ORDER = 4
#: Winter's correction for a 2nd-order Butterworth run twice: design cutoff = cutoff / C.
TWO_PASS_CUTOFF_CORRECTION = (2.0 ** 0.5 - 1.0) ** 0.25

#: Cycle curves replaced by their filtered version (moments and powers, human and device).
KINETIC_CHANNELS = tuple(f"{j}_{k}" for k in ("moment_nm_per_kg", "power_w_per_kg")
                         for j in ("hip", "knee", "ankle")) + (
    "ankle_device_moment_nm_per_kg", "ankle_device_power_w_per_kg")


def filter_note(cutoff_hz: float = KINETICS_CUTOFF_HZ) -> str:
    """One line for a figure's caption stating the filter and that it is for display."""
    return (f"moments and powers low-pass filtered for display only: zero-lag Butterworth, "
            f"{KINETICS_FILTER_ORDER}th order (2nd order forward + backward), {cutoff_hz:g} Hz "
            f"(Winter 2009 ch. 2); metrics use the unfiltered record")


def lowpass_zero_lag(y, sample_period_s: float, cutoff_hz: float = KINETICS_CUTOFF_HZ,
                     axis: int = 0) -> np.ndarray:
    """``y`` low-pass filtered along ``axis`` with the zero-lag filter of the module docstring.

    ``sample_period_s``: the (uniform) sample spacing; the cutoff must lie below 0.8 × the
    Nyquist frequency after the two-pass correction.
    """
    from scipy.signal import butter, filtfilt
    fs = 1.0 / float(sample_period_s)
    design = float(cutoff_hz) / TWO_PASS_CUTOFF_CORRECTION
    if not (0.0 < design < 0.8 * 0.5 * fs):
        raise ValueError(f"cutoff {cutoff_hz!r} Hz at {fs:g} Hz sampling: the design cutoff "
                         f"{design:g} Hz must lie in (0, {0.4 * fs:g}) Hz")
    b, a = butter(KINETICS_FILTER_ORDER // 2, design, btype="low", fs=fs)
    return filtfilt(b, a, np.asarray(y, dtype=float), axis=axis)


def filtered_kinetic_cycles(record, cycles: Sequence, cutoff_hz: float = KINETICS_CUTOFF_HZ
                            ) -> list:
    """``cycles`` with their moment and power curves (:data:`KINETIC_CHANNELS`) recomputed
    from the low-pass filtered ``record`` (the whole record filtered once, so no cycle has
    filter start-up at its heel strike); angles, GRF, heights and every scalar unchanged.

    The record's powers are filtered as the product moment × angular velocity (the quantity
    drawn), per kg body mass as the cycles hold them.
    """
    from afo_mj.metrics.gait_metrics import PERCENT_CYCLE, JOINTS
    t = np.asarray(record.time_s, dtype=float)
    if t.size < 16 or not cycles:
        return list(cycles)
    dt = float(np.median(np.diff(t)))
    m = record.body_mass_kg
    lp = lambda y: lowpass_zero_lag(y, dt, cutoff_hz, axis=0)  # noqa: E731
    moment = lp(record.joint_moment_nm)
    power = lp(record.joint_moment_nm * record.joint_velocity_rad_s)
    dev_m = lp(record.device_moment_nm)
    dev_p = lp(record.device_moment_nm * record.joint_velocity_rad_s[:, :, 2])
    out = []
    for c in cycles:
        tg = c.start_s + PERCENT_CYCLE / 100.0 * (c.end_s - c.start_s)
        s = c.side
        new = {}
        for j, name in enumerate(JOINTS):
            new[f"{name}_moment_nm_per_kg"] = np.interp(tg, t, moment[:, s, j]) / m
            new[f"{name}_power_w_per_kg"] = np.interp(tg, t, power[:, s, j]) / m
        new["ankle_device_moment_nm_per_kg"] = np.interp(tg, t, dev_m[:, s]) / m
        new["ankle_device_power_w_per_kg"] = np.interp(tg, t, dev_p[:, s]) / m
        out.append(dataclasses.replace(c, curves={**c.curves, **new}))
    return out

