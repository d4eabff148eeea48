"""Sharp-edged orifice: the throttling law every valve in this library is built on.

Equation
--------
The standard turbulent orifice equation (Bernoulli across the vena contracta with a discharge
coefficient; Merritt, *Hydraulic Control Systems*, Wiley 1967, §3.2–3.3; seed §2.4;
``shared/reference/facts.md``):

    Q = C_d A √(2 |Δp| / ρ) sign(Δp)

has an infinite slope ``dQ/dΔp`` at ``Δp = 0``, which breaks Newton iterations of an implicit
integrator. System simulators regularise it near zero (e.g. the "critical pressure" form of
Hopsan's turbulent orifice and of Simscape's orifice blocks); this library uses

    Q = C_d A √(2/ρ) · Δp / (Δp² + p_cr²)^(1/4)

with ``p_cr`` the transition pressure. For ``|Δp| ≫ p_cr`` it equals the turbulent law (the
relative error is about ``(p_cr/Δp)²/4``: 2.5e-5 at ``Δp = 100 p_cr``); near zero it is linear,
``Q ≈ C_d A √(2/ρ) Δp / √p_cr``, like the laminar flow through a small opening. It is odd,
smooth (C^∞) and strictly increasing in ``Δp``, and linear in ``A`` (so a valve's flow is
proportional to its opening at a fixed pressure drop).

Power: all of ``Δp·Q`` is throttled to heat (no work is done), ``Δp Q ≥ 0`` because ``Q`` has the
sign of ``Δp``.

The law is :func:`afo_mj.hydraulics.laws.orifice_flow_m3_s` (re-exported here, all five
arguments required), with its inverse :func:`afo_mj.hydraulics.laws.orifice_dp_for_flow_pa`;
the simulated circuits and the design tool evaluate the same compiled functions.

Also here: the small smoothing helpers used by the valve modules (:func:`smooth_max0`,
:func:`smooth_ramp01`), which round the corners of valve opening laws so their Jacobian is
continuous.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from . import laws
from .laws import orifice_flow_m3_s
from .params import Parameters, param

__all__ = ["DEFAULT_DISCHARGE_COEFFICIENT", "DEFAULT_TRANSITION_PRESSURE_PA",
           "orifice_flow_m3_s", "orifice_area_for_flow", "orifice_dp_for_flow", "OrificeParams"]

#: Sharp-edged orifice, fully developed jet (Merritt 1967 §3.3: 0.611 from von Mises' ideal
#: two-dimensional jet, 0.6–0.65 measured).
DEFAULT_DISCHARGE_COEFFICIENT = 0.61
#: Regularisation pressure p_cr (0.1 bar): far below working drops (MPa), large enough to keep
#: the slope at Δp = 0 moderate.
DEFAULT_TRANSITION_PRESSURE_PA = 1.0e4


def orifice_area_for_flow(flow_m3_s, dp_pa, discharge_coefficient, density_kg_m3,
                          transition_pressure_pa=DEFAULT_TRANSITION_PRESSURE_PA):
    """Orifice area that passes ``|flow_m3_s|`` at ``|dp_pa|`` (sizing; inverse in ``A``).

    ``A = |Q| (Δp² + p_cr²)^(1/4) / (C_d √(2/ρ) |Δp|)``, i.e. ``|Q|`` over the law's flow
    through a unit area (``dp_pa`` must not be 0).

    Example: 4 L/min at 3.5 MPa, C_d 0.61, ρ 870: ``orifice_area_for_flow(4/60e3, 3.5e6, 0.61,
    870.0)`` → 1.218e-6 m² (a 1.25 mm diameter hole).
    """
    unit_flow = orifice_flow_m3_s(np.abs(np.asarray(dp_pa, dtype=float)), 1.0,
                                  discharge_coefficient, density_kg_m3, transition_pressure_pa)
    return np.abs(np.asarray(flow_m3_s, dtype=float)) / unit_flow


def orifice_dp_for_flow(flow_m3_s, area_m2, discharge_coefficient, density_kg_m3,
                        transition_pressure_pa=DEFAULT_TRANSITION_PRESSURE_PA):
    """Pressure drop that drives ``flow_m3_s`` through the orifice (inverse in ``Δp``).

    Squaring the law twice gives ``Δp⁴ = c (Δp² + p_cr²)`` with ``c = (Q/k)⁴``,
    ``k = C_d A √(2/ρ)``, so ``Δp = sign(Q) √((c + √(c² + 4 c p_cr²))/2)`` (exact inverse of
    :func:`orifice_flow_m3_s`; ``area_m2`` must be > 0): the law
    :func:`afo_mj.hydraulics.laws.orifice_dp_for_flow_pa`.

    Example: ``orifice_dp_for_flow(6.540e-5, 1e-6, 0.61, 870.0, 1e4)`` → 5.0e6 Pa.
    """
    return laws.orifice_dp_for_flow_pa(np.asarray(flow_m3_s, dtype=float), area_m2,
                                       discharge_coefficient, density_kg_m3,
                                       transition_pressure_pa)


@dataclasses.dataclass(frozen=True)
class OrificeParams(Parameters):
    """A fixed sharp-edged orifice (restrictor)."""

    area_m2: float = param(1.0e-6, unit="m^2", lo=0.0, hi=1e-2, lo_open=True,
                           doc="flow area A")
    discharge_coefficient: float = param(DEFAULT_DISCHARGE_COEFFICIENT, unit="-", lo=0.0, hi=1.0,
                                         lo_open=True, doc="discharge coefficient C_d")
    transition_pressure_pa: float = param(DEFAULT_TRANSITION_PRESSURE_PA, unit="Pa", lo=0.0,
                                          hi=1e6, lo_open=True,
                                          doc="p_cr: Δp below which the law turns linear")

    @property
    def diameter_m(self) -> float:
        """Diameter of a round hole of the same area."""
        return math.sqrt(4.0 * self.area_m2 / math.pi)
