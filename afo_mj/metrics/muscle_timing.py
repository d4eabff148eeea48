"""Muscle on/off timing over the gait cycle, compared with the EMG timing of normal walking.

A simulated muscle is *on* where its stride-averaged excitation (the neural signal EMG
measures) exceeds ``threshold`` of its range over the cycle, ``min + threshold (max − min)``
(30 % by default; a relative threshold as EMG on/off detection uses, since a model's
excitation has no EMG amplitude scale). Strides are the right (or left) leg's heel strike to
heel strike, each resampled on ``n`` phase points before averaging.

Reference (:data:`PERRY_ON_PCT`): the on-intervals of normal walking in Perry & Burnfield,
*Gait Analysis: Normal and Pathological Function*, 2nd ed., SLACK 2010 (ch. 4, the ankle):
soleus from 7 % to 50 % of the cycle, gastrocnemius from 9 % to 50 %, tibialis anterior from
pre-swing (56 %) through swing to the end of loading response (12 %). The agreement is the
fraction of the cycle where the simulated and the reference state (on/off) are equal, with the
onset and offset errors of the first simulated on-interval that overlaps each reference one.
"""

from __future__ import annotations

import numpy as np

__all__ = ["PERRY_ON_PCT", "cycle_average", "on_intervals_pct", "timing_agreement"]

#: on-intervals (% of the gait cycle from heel strike) of normal walking (module docstring);
#: an interval may wrap past 100 %
PERRY_ON_PCT = {"soleus": ((7.0, 50.0),), "gastrocnemius": ((9.0, 50.0),),
                "tibialis_anterior": ((56.0, 112.0),)}


def cycle_average(signal: np.ndarray, time_s: np.ndarray, heel_strikes_s, n: int = 100,
                  after_s: float = 0.0) -> np.ndarray:
    """The mean over whole strides (heel strikes after ``after_s``) of ``signal`` (per
    sample) on ``n`` phase points ``k/n``. Needs at least one whole stride."""
    hs = np.asarray(heel_strikes_s, float)
    hs = hs[hs > after_s]
    if len(hs) < 2:
        raise ValueError(f"cycle_average: {len(hs)} heel strikes after {after_s} s; allowed: "
                         "at least 2 (one whole stride)")
    ph = np.arange(n) / n
    cycles = []
    for a, b in zip(hs[:-1], hs[1:]):
        x = (time_s - a) / (b - a)
        sel = (x >= 0.0) & (x < 1.0)
        cycles.append(np.interp(ph, x[sel], signal[sel]))
    return np.mean(cycles, axis=0)


def on_intervals_pct(avg: np.ndarray, threshold: float = 0.3) -> list[tuple[float, float]]:
    """On-intervals ``(start %, end %)`` of a cycle average (:func:`cycle_average`); an
    interval running through heel strike is reported once, its end past 100 %."""
    if not 0.0 < threshold < 1.0:
        raise ValueError(f"threshold = {threshold!r}; allowed: 0 < threshold < 1")
    n = len(avg)
    lo, hi = float(avg.min()), float(avg.max())
    on = avg > lo + threshold * (hi - lo)
    if on.all() or not on.any():
        return [(0.0, 100.0)] if on.all() else []
    # start the scan at an off sample so that a wrapping interval stays whole
    k0 = int(np.argmin(on))
    out = []
    start = None
    for j in range(n + 1):
        k = (k0 + j) % n
        if on[k] and start is None:
            start = k0 + j
        elif not on[k] and start is not None:
            out.append((100.0 * start / n, 100.0 * (k0 + j) / n))
            start = None
    out = [(a % 100.0, a % 100.0 + (b - a)) for a, b in out]
    return sorted(out)


def _state(intervals, n: int) -> np.ndarray:
    ph = 100.0 * np.arange(n) / n
    on = np.zeros(n, bool)
    for a, b in intervals:
        on |= ((ph >= a) & (ph < b)) | ((ph + 100.0 >= a) & (ph + 100.0 < b))
    return on


def timing_agreement(avg: np.ndarray, reference, threshold: float = 0.3) -> dict:
    """Compare a cycle average with reference on-intervals (% of cycle, e.g.
    ``PERRY_ON_PCT["soleus"]``): ``agreement`` (fraction of the cycle in the same state),
    the simulated ``on_pct`` intervals, and per reference interval the ``onset_error_pct`` and
    ``offset_error_pct`` of the simulated interval overlapping it most (None when none does)."""
    n = len(avg)
    sim = on_intervals_pct(avg, threshold)
    agree = float(np.mean(_state(sim, n) == _state(reference, n)))
    errors = []
    for a, b in reference:
        best, overlap = None, 0.0
        for c, d in sim:
            for shift in (-100.0, 0.0, 100.0):
                ov = min(b, d + shift) - max(a, c + shift)
                if ov > overlap:
                    best, overlap = (c + shift, d + shift), ov
        errors.append({"reference_pct": (a, b),
                       "onset_error_pct": None if best is None else best[0] - a,
                       "offset_error_pct": None if best is None else best[1] - b})
    return {"agreement": agree, "on_pct": sim, "intervals": errors}
