"""Direct-acting pressure-relief valve (static, pressure-balanced poppet).

Static model (the quasi-steady relief valve of system simulators, e.g. Simscape's "Pressure
Relief Valve (IL)", Hopsan's "Pressure relief valve" without dynamics; characteristic as in
Merritt 1967 §3 and maker's Δp–Q curves):

* opening ``s = smoothstep01((Δp − Δp_crack) / Δp_override)``, ``Δp = p_in − p_out``
  (protected line minus tank): 0 below the cracking pressure, 1 at ``Δp_crack + Δp_override``
  and above, the cubic ``s²(3 − 2s)`` between — C¹ at both ends, so an implicit integrator's
  Newton iteration sees a continuous Jacobian;
* area ``A = A_leak + (A_max − A_leak) s`` (seat leakage ``A_leak`` when closed): the law
  :func:`~afo_mj.hydraulics.laws.relief_valve_area_m2`, which the simulated circuits use;
* flow ``Q = C_d A √(2/ρ) Δp / (Δp² + p_cr²)^(1/4)``
  (:func:`~afo_mj.hydraulics.laws.orifice_flow_m3_s`).

(The poppet's force balance against a linear spring gives a lift linear in ``Δp``; the
smoothstep has the same end points and the same mid point, half open at
``Δp_crack + Δp_override/2``, and needs no corner rounding. ``opening_smoothing`` is kept in the
parameters for compatibility and validated, but the law does not use it.)

A reverse pressure drop keeps the poppet seated: reverse flow only through the leakage. All of
``Δp Q`` becomes heat.

Example: the default valve (cracks at 15 MPa, full open 1 MPa later, 2 mm²) at
``Δp = 15.5 MPa`` is half open, ``A ≈ 1 mm²``, ``Q ≈ 1.15e-4 m³/s`` (6.9 L/min) of VG 46.
"""

from __future__ import annotations

import dataclasses

from .orifice import DEFAULT_DISCHARGE_COEFFICIENT, DEFAULT_TRANSITION_PRESSURE_PA
from .params import Parameters, effect, param

__all__ = ["ReliefValveParams"]


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
                                     doc="corner rounding of a linear opening ramp, fraction "
                                         "of override_dp_pa (unused: the relief law's "
                                         "smoothstep has C¹ ends)")
    leakage_enabled: bool = effect(True, doc="seat leakage through leakage_area_m2 when closed")

    def check(self) -> None:
        if self.leakage_area_m2 >= self.max_area_m2:
            self.fail("leakage_area_m2", f"must be below max_area_m2 = {self.max_area_m2}")
        if self.opening_smoothing * self.override_dp_pa >= self.cracking_dp_pa:
            self.fail("opening_smoothing", "the rounded corner would open the valve at Δp <= 0: "
                      "opening_smoothing * override_dp_pa must be below cracking_dp_pa = "
                      f"{self.cracking_dp_pa}")
