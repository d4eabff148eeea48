"""Thinning a sampled signal for display within a stated tolerance: the samples a plot needs.

A plot draws a signal as straight lines between its samples. Most of a smooth gait signal's
samples at 500 Hz lie on those lines to well under a pixel, so a recording that keeps them
all is mostly redundant rows, which the viewer must still read, store and index. The
swing-door algorithm (Bristol, "Swinging door trending: adaptive trend recording?", ISA
National Conference 1990; the compression of process historians) keeps a sample only when
the line from the last kept sample could not otherwise pass within ``tol`` of every sample
in between:

from the last kept sample (t_a, y_a), every later sample i bounds the slope of a line that
passes within ``tol`` of it, ``(y_i − tol − y_a)/(t_i − t_a) ≤ s ≤ (y_i + tol − y_a)/(t_i −
t_a)``; sample k can end the segment while its own slope ``(y_k − y_a)/(t_k − t_a)`` lies
within the bounds of every sample between a and k. When it cannot, sample k − 1 (which
could) is kept and becomes the new start. One pass, O(n); the first and last samples are
always kept; kept values are the samples themselves (nothing is smoothed or moved), and
linear interpolation between kept samples reproduces every left-out sample within ``tol``.
"""

from __future__ import annotations

import numba
import numpy as np

__all__ = ["thin_indices"]


@numba.njit(cache=True, nogil=True)
def _swing_door(t, v, tol, keep):         # pragma: no cover - compiled
    n = len(t)
    keep[0] = True
    keep[n - 1] = True
    if n <= 2:
        return
    ta = t[0]
    ya = v[0]
    d = t[1] - ta
    up = (v[1] + tol - ya) / d
    lo = (v[1] - tol - ya) / d
    for k in range(2, n):
        d = t[k] - ta
        s = (v[k] - ya) / d
        if s > up or s < lo:
            keep[k - 1] = True
            ta = t[k - 1]
            ya = v[k - 1]
            d = t[k] - ta
            up = (v[k] + tol - ya) / d
            lo = (v[k] - tol - ya) / d
        else:
            u = (v[k] + tol - ya) / d
            w = (v[k] - tol - ya) / d
            if u < up:
                up = u
            if w > lo:
                lo = w


def thin_indices(t, v, tol: float) -> np.ndarray:
    """Indices of the samples of ``v`` (at strictly increasing times ``t``) to keep so that
    linear interpolation between them is within ``tol`` (same unit as ``v``, ≥ 0) of every
    sample; ``tol = 0`` keeps every sample. ``t`` and ``v`` finite, of one length."""
    t = np.ascontiguousarray(t, dtype=np.float64)
    v = np.ascontiguousarray(v, dtype=np.float64)
    if t.shape != v.shape or t.ndim != 1:
        raise ValueError(f"t and v must be 1-D of one length, got {t.shape} and {v.shape}")
    if not (tol >= 0.0 and np.isfinite(tol)):
        raise ValueError(f"tol = {tol!r}; allowed: a finite number >= 0")
    n = len(t)
    if n == 0 or tol == 0.0:
        return np.arange(n)
    if n > 1 and not np.all(np.diff(t) > 0):
        raise ValueError("t must be strictly increasing")
    keep = np.zeros(n, dtype=np.bool_)
    _swing_door(t, v, float(tol), keep)
    return np.flatnonzero(keep)
