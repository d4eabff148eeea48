"""Cross-section geometry the components share (areas and volumes of bores and annuli).

One place for the piston areas of :class:`~afo_mj.hydraulics.cylinder.CylinderParams`, the oil
volume of :class:`~afo_mj.hydraulics.conduit.HoseParams` and the design tool's sizing grids
(:mod:`afo_mj.design`), so a change here moves all of them together.
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["annulus_area_m2"]


def annulus_area_m2(outer_diameter_m, inner_diameter_m):
    """Area between two concentric circles, ``A = π D²/4 − π d²/4`` (0 where ``d ≥ D``): a
    piston's area on the side of its rod or cable (Merritt 1967 §5.1), a bore's flow area with
    ``d = 0``. Arrays broadcast (the design tool's grids); a plain numpy function, not a law
    of :mod:`afo_mj.hydraulics.laws`, because no generated circuit evaluates it: the circuits
    pack areas and volumes as parameters.

    Example: D = 12 mm, d = 2 mm → 1.0996e-4 m²; D = 4 mm, d = 0 → 1.2566e-5 m².
    """
    big = np.asarray(outer_diameter_m, dtype=float)
    small = np.asarray(inner_diameter_m, dtype=float)
    return np.maximum(math.pi * big ** 2 / 4.0 - math.pi * small ** 2 / 4.0, 0.0)
