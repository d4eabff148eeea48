"""Direct-acting pressure-relief valve (static, pressure-balanced poppet).

Static model (the quasi-steady relief valve of system simulators, e.g. Simscape's "Pressure
Relief Valve (IL)", Hopsan's "Pressure relief valve" without dynamics; characteristic as in
Merritt 1967 §3 and maker's Δp–Q curves):

* opening ``s = ramp((Δp − Δp_crack) / Δp_override)``, ``Δp = p_in − p_out`` (protected line
  minus tank), 0 below the cracking pressure, 1 at ``Δp_crack + Δp_override`` and above, linear
  between (poppet force balance against a linear spring, flow forces neglected); corners rounded
  over ``± opening_smoothing · Δp_override``
  (:func:`~afo_mj.hydraulics.orifice.smooth_ramp01`);
* area ``A = A_leak + (A_max − A_leak) s`` (seat leakage ``A_leak`` when closed);
* flow ``Q = C_d A √(2/ρ) Δp / (Δp² + p_cr²)^(1/4)``
  (:func:`~afo_mj.hydraulics.orifice.orifice_flow_m3_s`).

A reverse pressure drop keeps the poppet seated: reverse flow only through the leakage. All of
``Δp Q`` becomes heat.

Example: the default valve (cracks at 15 MPa, full open 1 MPa later, 2 mm²) at
``Δp = 15.5 MPa`` is half open, ``A ≈ 1 mm²``, ``Q ≈ 1.15e-4 m³/s`` (6.9 L/min) of VG 46.
"""

from __future__ import annotations

import dataclasses

from .check_valve import PoppetValve
from .orifice import DEFAULT_DISCHARGE_COEFFICIENT, DEFAULT_TRANSITION_PRESSURE_PA
from .params import Parameters, effect, param

__all__ = ["ReliefValveParams", "ReliefValve"]


@dataclasses.dataclass(frozen=True)
class ReliefValveParams(Parameters):
    """A direct-acting relief valve from ``in`` (the protected line) to ``out`` (tank)."""

    cracking_dp_pa: float = param(15.0e6, unit="Pa", lo=0.0, hi=1e8, lo_open=True,
                                  doc="differential pressure at which the valve cracks open")
    override_dp_pa: float = param(1.0e6, unit="Pa", lo=0.0, hi=1e8, lo_open=True,
                                  doc="pressure override: Δp above cracking for full opening")
    max_area_m2: float = param(2.0e-6, unit="m^2", lo=0.0, hi=1e-2, lo_open=True,
                               doc="flow area fully open")
    leakage_area_m2: float = param(1.0e-10, unit="m^2", lo=0.0, hi=1e-2,
                                   doc="seat leakage area when closed (must be < max_area_m2)")
    discharge_coefficient: float = param(DEFAULT_DISCHARGE_COEFFICIENT, unit="-", lo=0.0,
                                         hi=1.0, lo_open=True, doc="C_d")
    transition_pressure_pa: float = param(DEFAULT_TRANSITION_PRESSURE_PA, unit="Pa", lo=0.0,
                                          hi=1e6, lo_open=True,
                                          doc="p_cr of the regularised orifice law")
    opening_smoothing: float = param(0.05, unit="-", lo=0.0, hi=0.5, hi_open=True,
                                     doc="corner rounding of the opening ramp, fraction of "
                                         "override_dp_pa (0 = sharp corners)")
    leakage_enabled: bool = effect(True, doc="seat leakage through leakage_area_m2 when closed")

    def check(self) -> None:
        if self.leakage_area_m2 >= self.max_area_m2:
            self.fail("leakage_area_m2", f"must be below max_area_m2 = {self.max_area_m2}")
        if self.opening_smoothing * self.override_dp_pa >= self.cracking_dp_pa:
            self.fail("opening_smoothing", "the rounded corner would open the valve at Δp <= 0: "
                      "opening_smoothing * override_dp_pa must be below cracking_dp_pa = "
                      f"{self.cracking_dp_pa}")


class ReliefValve(PoppetValve):
    """Opening, area, flow and power of one :class:`ReliefValveParams` valve.

    Methods: ``opening(dp_pa)``, ``area_m2(dp_pa)``, ``flow_m3_s(p_in_pa, p_out_pa,
    density_kg_m3)``, ``power(p_in_pa, p_out_pa, density_kg_m3) -> PowerFlow`` (see
    :class:`~afo_mj.hydraulics.check_valve.PoppetValve`); all vectorised.
    """

    def __init__(self, params: ReliefValveParams = ReliefValveParams()):
        self.params = params
        self._dp_start = params.cracking_dp_pa
        self._dp_width = params.override_dp_pa
        self._leak_area = params.leakage_area_m2 if params.leakage_enabled else 0.0
