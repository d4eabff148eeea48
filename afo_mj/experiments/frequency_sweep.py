"""Frequency grids for bench frequency responses that resolve a resonance.

A sweep of a dozen log-spaced frequencies (a factor of ~1.7 between neighbours) can put the
only points either side of a lightly damped peak, so the drawn Bode curve cuts the peak off
and the reported resonance is wherever a grid point fell. :func:`adaptive_log_sweep` measures
in two passes:

1. a coarse grid of ``n_coarse`` log-spaced frequencies over ``[f_min_hz, f_max_hz]``;
2. ``n_refine`` more log-spaced frequencies strictly inside the bracket of the feature:

   * the gain's maximum, when it lies inside the range (a resonance): the bracket is the
     maximum's two coarse neighbours;
   * otherwise (a low-pass response, maximum at an end of the range) the −``drop_db`` dB
     crossing relative to the lowest frequency (the bandwidth): the bracket is the two coarse
     frequencies either side of the crossing.

With the defaults (20 + 12) a sweep has 32 frequencies; the refined points are spaced
``(f_{k+1}/f_{k-1})^(1/13)``, about 4 % apart over two decades, so the peak is sampled on
both flanks. :func:`resonance_peak` then places the peak by a parabola through the largest
gain (in dB) and its two neighbours against log f.

The measurement is the caller's: ``measure(f_hz)`` returns the gain (any positive unit) or a
mapping with a ``"gain"`` entry plus whatever else the caller keeps (phase, distortion).
"""

from __future__ import annotations

import math
from typing import Any, Callable, Mapping

import numpy as np

__all__ = ["DEFAULT_COARSE_POINTS", "DEFAULT_REFINE_POINTS", "MIN_SWEEP_POINTS",
           "adaptive_log_sweep", "refinement_bracket", "resonance_peak"]

#: Coarse log-spaced frequencies of a default sweep.
DEFAULT_COARSE_POINTS = 20
#: Frequencies added inside the bracket of the peak (or of the bandwidth crossing).
DEFAULT_REFINE_POINTS = 12
#: The fewest frequencies a default sweep measures (coarse + refined).
MIN_SWEEP_POINTS = 30


def _gain_of(result: Any) -> float:
    if isinstance(result, Mapping):
        return float(result["gain"])
    return float(result)


def refinement_bracket(freqs_hz, gains, *, drop_db: float = 3.0) -> tuple[float, float, str]:
    """``(f_lo, f_hi, feature)``: the frequencies to refine between, and what lies there.

    ``feature`` is ``"peak"`` (the gain's maximum inside the range), ``"bandwidth"`` (the first
    fall ``drop_db`` below the lowest frequency's gain, when the maximum is at an end) or
    ``"top"`` (neither: the last coarse interval). ``freqs_hz`` sorted ascending.
    """
    f = np.asarray(freqs_hz, dtype=float)
    g = np.asarray(gains, dtype=float)
    if f.size < 3 or f.size != g.size or np.any(np.diff(f) <= 0):
        raise ValueError("refinement_bracket: need >= 3 strictly increasing frequencies with "
                         "one gain each")
    k = int(np.argmax(g))
    if 0 < k < f.size - 1:
        return float(f[k - 1]), float(f[k + 1]), "peak"
    db = 20.0 * np.log10(np.maximum(g, 1e-300) / g[0])
    below = np.flatnonzero(db <= -drop_db)
    if below.size and below[0] > 0:
        i = int(below[0])
        return float(f[i - 1]), float(f[i]), "bandwidth"
    return float(f[-2]), float(f[-1]), "top"


def adaptive_log_sweep(measure: Callable[[float], Any], f_min_hz: float, f_max_hz: float, *,
                       n_coarse: int = DEFAULT_COARSE_POINTS,
                       n_refine: int = DEFAULT_REFINE_POINTS,
                       drop_db: float = 3.0) -> tuple[np.ndarray, list, str]:
    """Measure a coarse log grid, then refine around the peak or the bandwidth crossing.

    Returns ``(freqs_hz, results, feature)``: the frequencies measured, ascending; the
    ``measure`` result of each, in the same order; and the refined feature (see
    :func:`refinement_bracket`).
    """
    if not (0.0 < f_min_hz < f_max_hz and math.isfinite(f_max_hz)):
        raise ValueError(f"adaptive_log_sweep: need 0 < f_min_hz < f_max_hz, got "
                         f"{f_min_hz!r}, {f_max_hz!r}")
    if n_coarse < 3 or n_refine < 0:
        raise ValueError(f"adaptive_log_sweep: n_coarse = {n_coarse} (>= 3), n_refine = "
                         f"{n_refine} (>= 0)")
    coarse = np.geomspace(f_min_hz, f_max_hz, int(n_coarse))
    measured = {float(f): measure(float(f)) for f in coarse}
    lo, hi, feature = refinement_bracket(coarse, [_gain_of(measured[float(f)]) for f in coarse],
                                         drop_db=drop_db)
    if n_refine:
        for f in np.geomspace(lo, hi, int(n_refine) + 2)[1:-1]:
            measured.setdefault(float(f), measure(float(f)))
    freqs = np.array(sorted(measured))
    return freqs, [measured[float(f)] for f in freqs], feature


def resonance_peak(freqs_hz, gains) -> tuple[float, float, bool]:
    """``(f_peak_hz, peak_gain_db_re_lowest, interior)`` of a measured gain curve.

    The peak frequency is the vertex of the parabola through the largest gain and its two
    neighbours in (ln f, dB) when the largest gain is inside the range and the parabola opens
    downwards; else the frequency of the largest gain. ``interior`` is False when the largest
    gain is at an end of the range (no resonance was found inside it).
    """
    f = np.asarray(freqs_hz, dtype=float)
    g = np.asarray(gains, dtype=float)
    order = np.argsort(f)
    f, g = f[order], g[order]
    db = 20.0 * np.log10(g / g[0])
    k = int(np.argmax(g))
    interior = 0 < k < f.size - 1
    f_peak, d_peak = float(f[k]), float(db[k])
    if interior:
        a, b, c = np.polyfit(np.log(f[k - 1:k + 2]), db[k - 1:k + 2], 2)
        if a < 0:
            x = -b / (2.0 * a)
            f_peak, d_peak = float(math.exp(x)), float(a * x * x + b * x + c)
    return f_peak, d_peak, interior
