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

from .orifice import (DEFAULT_DISCHARGE_COEFFICIENT, DEFAULT_TRANSITION_PRESSURE_PA)
from .params import Parameters, effect, param

__all__ = ["CheckValveParams"]


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
