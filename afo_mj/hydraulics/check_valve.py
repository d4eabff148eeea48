"""Check (non-return) valve: a spring-loaded poppet that opens with the forward pressure drop.

Static model (quasi-steady poppet; the usual lumped check valve of system simulators, e.g.
Simscape's "Check Valve (IL)" and Hopsan's "Check valve with spring"):

* opening ``s = ramp((Δp − p_crack) / Δp_full)``, ``Δp = p_in − p_out``, 0 below the cracking
  pressure, 1 from ``p_crack + Δp_full`` on, linear between (the spring force grows linearly
  with lift and the pressure force on the seat balances it); both corners are rounded over
  ``± opening_smoothing · Δp_full`` (:func:`~afo_mj.hydraulics.laws.poppet_opening_fraction`)
  so the flow has a continuous Jacobian;
* area ``A = A_leak + (A_max − A_leak) s`` (:func:`~afo_mj.hydraulics.laws.
  valve_opening_area_m2`): the seat leakage ``A_leak`` when closed (and for reverse flow),
  ``A_max`` at full lift;
* flow through the regularised orifice law ``Q = C_d A √(2/ρ) Δp / (Δp² + p_cr²)^(1/4)``
  (:func:`~afo_mj.hydraulics.laws.orifice_flow_m3_s`; Merritt 1967 §3.3).

A reverse pressure drop keeps the poppet on its seat, so reverse flow passes the leakage area
only. All of ``Δp Q`` is throttled to heat.

Example: the default valve (cracking 0.05 MPa, full open 0.3 MPa later, 3 mm² seat) with
``Δp = 0.2 MPa`` is half open, ``A ≈ 1.5 mm²``, ``Q ≈ 1.95e-5 m³/s`` (1.2 L/min) of VG 46.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from . import laws
from .orifice import (DEFAULT_DISCHARGE_COEFFICIENT, DEFAULT_TRANSITION_PRESSURE_PA,
                      orifice_flow_m3_s, throttle_power)
from .params import Parameters, effect, param
from .power import PowerFlow

__all__ = ["CheckValveParams", "CheckValve", "PoppetValve"]


class PoppetValve:
    """Shared static poppet law: opening ramp in ``Δp``, area, flow, power.

    Subclasses set ``self.params`` and the ramp start ``self._dp_start`` and width
    ``self._dp_width`` (Pa), ``self._leak_area`` (m²).
    """

    params: Parameters
    _dp_start: float
    _dp_width: float
    _leak_area: float

    def opening(self, dp_pa):
        """Poppet opening fraction ``s ∈ [0, 1]`` at pressure drop ``dp_pa = p_in − p_out``.

        ``s = ramp((Δp − Δp_start)/Δp_width)`` with rounded corners (see module docstring):
        the law :func:`afo_mj.hydraulics.laws.poppet_opening_fraction`.
        """
        return laws.poppet_opening_fraction(np.asarray(dp_pa, dtype=float), self._dp_start,
                                            self._dp_width, self.params.opening_smoothing)

    def area_m2(self, dp_pa):
        """Flow area ``A_leak + (A_max − A_leak) s(Δp)``
        (:func:`afo_mj.hydraulics.laws.valve_opening_area_m2`)."""
        return laws.valve_opening_area_m2(self.opening(dp_pa), self.params.max_area_m2,
                                          self._leak_area)

    def flow_m3_s(self, p_in_pa, p_out_pa, density_kg_m3):
        """Flow from ``in`` to ``out`` (negative = reverse flow, through the leakage only)."""
        p = self.params
        dp = np.asarray(p_in_pa, dtype=float) - p_out_pa
        return orifice_flow_m3_s(dp, self.area_m2(dp), p.discharge_coefficient, density_kg_m3,
                                 p.transition_pressure_pa)

    def power(self, p_in_pa, p_out_pa, density_kg_m3) -> PowerFlow:
        """Throttling power: ``in = p_up |Q|``, ``out = p_down |Q|``, ``heat = Δp Q ≥ 0``
        (:func:`~afo_mj.hydraulics.orifice.throttle_power`)."""
        return throttle_power(p_in_pa, p_out_pa, self.flow_m3_s(p_in_pa, p_out_pa, density_kg_m3))


@dataclasses.dataclass(frozen=True)
class CheckValveParams(Parameters):
    """A spring-loaded poppet check valve (flow allowed from ``in`` to ``out``)."""

    cracking_pressure_pa: float = param(0.05e6, unit="Pa", lo=0.0, hi=1e7,
                                        doc="differential pressure at which the poppet lifts")
    full_open_dp_pa: float = param(0.3e6, unit="Pa", lo=0.0, hi=1e7, lo_open=True,
                                   doc="extra Δp above cracking for full lift")
    max_area_m2: float = param(3.0e-6, unit="m^2", lo=0.0, hi=1e-2, lo_open=True,
                               doc="flow area at full lift")
    leakage_area_m2: float = param(1.0e-10, unit="m^2", lo=0.0, hi=1e-2,
                                   doc="seat leakage area when closed (must be < max_area_m2)")
    discharge_coefficient: float = param(DEFAULT_DISCHARGE_COEFFICIENT, unit="-", lo=0.0,
                                         hi=1.0, lo_open=True, doc="C_d")
    transition_pressure_pa: float = param(DEFAULT_TRANSITION_PRESSURE_PA, unit="Pa", lo=0.0,
                                          hi=1e6, lo_open=True,
                                          doc="p_cr of the regularised orifice law")
    opening_smoothing: float = param(0.05, unit="-", lo=0.0, hi=0.5, hi_open=True,
                                     doc="corner rounding of the opening ramp, fraction of "
                                         "full_open_dp_pa (0 = sharp corners)")
    leakage_enabled: bool = effect(True, doc="seat leakage through leakage_area_m2 when closed")

    def check(self) -> None:
        if self.leakage_area_m2 >= self.max_area_m2:
            self.fail("leakage_area_m2", f"must be below max_area_m2 = {self.max_area_m2}")


class CheckValve(PoppetValve):
    """Opening, area, flow and power of one :class:`CheckValveParams` valve.

    Methods: :meth:`opening`, :meth:`area_m2`, :meth:`flow_m3_s`, :meth:`power` (see
    :class:`PoppetValve`); all vectorised.
    """

    def __init__(self, params: CheckValveParams = CheckValveParams()):
        self.params = params
        self._dp_start = params.cracking_pressure_pa
        self._dp_width = params.full_open_dp_pa
        self._leak_area = params.leakage_area_m2 if params.leakage_enabled else 0.0
