"""What a gait figure draws of its reference, and how it names it.

Every figure that compares a simulation with a reference gait draws the reference mean and,
where the reference carries a standard deviation (Schwartz et al. 2008; a user's CSV with
``<column>_sd``), the mean ± 1 SD band; it names the band and its source in its legend and
title. The shipped Winter table has no SD column (``afo_mj/data/normative_gait.csv``, source
``winter``: mean only), so a Winter figure draws the mean alone and says so: no title may
claim a band that is not drawn.

:func:`reference_curve` gives the arrays to draw (the data tests check), :func:`reference_label`
the legend text and :func:`reference_band_note` the sentence for a title.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from afo_mj.metrics.gait_metrics import reference_band

__all__ = ["ReferenceCurve", "reference_curve", "reference_has_band", "reference_label",
           "reference_band_note", "SOURCE_NAMES"]

#: Human-readable source of each shipped normative reference.
SOURCE_NAMES = {
    "winter": "Winter, Biomechanics and Motor Control of Human Gait (adult, normal cadence)",
    "schwartz2008": "Schwartz, Rozumalski & Trost 2008, J. Biomech. 41:1639 "
                    "(typically developing children)",
}


@dataclasses.dataclass(frozen=True)
class ReferenceCurve:
    """A reference channel on the 0..100 % grid, scaled as drawn: ``mean``, and ``lower`` /
    ``upper`` = the mean ∓ 1 SD (ordered after scaling) or None without an SD."""

    mean: np.ndarray
    lower: np.ndarray | None
    upper: np.ndarray | None

    @property
    def has_band(self) -> bool:
        return self.lower is not None


def reference_curve(reference, channel: str, scale: float = 1.0) -> ReferenceCurve | None:
    """The reference's ``channel`` as drawn (× ``scale``), or None if it lacks the channel."""
    band = reference_band(reference, channel)
    if band is None:
        return None
    mean, sd = band
    if sd is None:
        return ReferenceCurve(scale * mean, None, None)
    a, b = scale * (mean - sd), scale * (mean + sd)
    return ReferenceCurve(scale * mean, np.minimum(a, b), np.maximum(a, b))


def reference_has_band(reference, channels) -> bool:
    """Whether the reference has an SD for any of ``channels`` (a band will be drawn)."""
    return any((c := reference_curve(reference, ch)) is not None and c.has_band
               for ch in channels)


def _name(reference) -> str:
    src = getattr(reference, "source", "reference")
    cond = getattr(reference, "condition", "")
    full = SOURCE_NAMES.get(src, src)
    return f"{full}, {cond}" if cond and cond not in ("normal", "user") else full


def reference_label(reference, band: bool) -> str:
    """Legend text: the reference's source and whether the band drawn is its ± 1 SD."""
    if band:
        return f"reference mean ± 1 SD (between subjects): {_name(reference)}"
    return f"reference mean (no SD in the source data, no band): {_name(reference)}"


def reference_band_note(reference, band: bool) -> str:
    """A sentence for a figure title saying what the reference drawn is."""
    short = (f"{getattr(reference, 'source', 'reference')} "
             f"{getattr(reference, 'condition', '')}").strip()
    if band:
        return f"grey band: reference {short} mean ± 1 SD (dashed: its mean)"
    return f"dashed: reference {short} mean; it has no SD, so no band is drawn"
