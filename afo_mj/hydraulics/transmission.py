"""The mechanical transmission between the cylinders and the ankle: cable compliance and play.

The piston-cable cylinders of the HAFO (seed ch. 6) pull a cable loop wrapped on the ankle
pulley of radius ``r``. The ideal transmission is rigid (``x = r θ``). Two departures from it are
common on a real orthosis and are available as switchable effects for calibration
(:mod:`afo_mj.calibration.effect_library`):

* **series (cable) compliance**: the cable, its terminations and the brace's shell stretch
  under load. With a rotational stiffness ``k`` (N·m/rad) at the ankle, the cylinders' side of
  the loop lags the ankle by ``τ_h/k``; for the hydraulics this is a differential capacitance
  ``c_s = r² A_e²/k`` between the two chambers (:func:`series_compliance_m3_pa`, the law
  :func:`afo_mj.hydraulics.laws.series_spring_capacitance_m3_pa`; the generated circuits'
  ``pulley_cylinders`` solve the two chambers together through it).
* **backlash** (play): slack in the loop or a loose pulley key lets the ankle turn through a
  dead band ``b`` before the cylinders follow. On an imposed-angle bench this is the classic
  play (backlash) operator on the kinematics (:func:`play_operator`, e.g. Tao & Kokotović,
  *Adaptive control of systems with actuator and sensor nonlinearities*, 1996, ch. 3).
"""

from __future__ import annotations

import numba
import numpy as np

from .laws import series_spring_capacitance_m3_pa
from .params import ParameterError


def series_compliance_m3_pa(pulley_radius_m: float, effective_area_m2: float,
                            stiffness_nm_rad: float) -> float:
    """Differential capacitance of a series spring, ``c_s = r² A_e² / k`` (m³/Pa).

    A pressure difference ``Δp`` across the pistons loads the spring with ``τ = r A_e Δp``, which
    stretches it by ``τ/k`` rad, moving the pistons by ``r τ/k`` and displacing
    ``A_e r τ/k = c_s Δp`` of oil. ``k = inf`` (rigid) gives 0.

    >>> round(series_compliance_m3_pa(0.04, 1.6e-4, 2000.0) * 1e15, 3)   # mm³/MPa·1e-3
    20.48
    """
    for name, v in (("pulley_radius_m", pulley_radius_m),
                    ("effective_area_m2", effective_area_m2)):
        if not v > 0.0:
            raise ParameterError(f"{name} = {v!r}; allowed: > 0")
    if not stiffness_nm_rad > 0.0:
        raise ParameterError(f"stiffness_nm_rad = {stiffness_nm_rad!r}; allowed: > 0 (inf for "
                             "a rigid cable)")
    return float(series_spring_capacitance_m3_pa(pulley_radius_m * effective_area_m2,
                                                 1.0 / stiffness_nm_rad))


@numba.njit(cache=True)
def _play(x, half, y):
    y[0] = x[0]
    for k in range(1, x.shape[0]):
        v = y[k - 1]
        lo = x[k] - half
        hi = x[k] + half
        if v < lo:
            v = lo
        elif v > hi:
            v = hi
        y[k] = v


def play_operator(x: np.ndarray, width: float) -> np.ndarray:
    """Backlash of total width ``width`` (same unit as ``x``): the output stays put while the
    input moves inside the dead band and follows it, ``width/2`` behind, once it pushes against
    either side: ``y_k = min(max(y_{k−1}, x_k − w/2), x_k + w/2)``, ``y_0 = x_0``.

    >>> play_operator(np.array([0.0, 0.1, 0.3, 0.2, -0.2]), 0.2).round(3).tolist()
    [0.0, 0.0, 0.2, 0.2, -0.1]
    """
    if not (width >= 0.0 and np.isfinite(width)):
        raise ParameterError(f"backlash width = {width!r}; allowed: finite and >= 0")
    x = np.ascontiguousarray(x, dtype=float)
    y = np.empty_like(x)
    if len(x):
        _play(x, 0.5 * width, y)
    return y
