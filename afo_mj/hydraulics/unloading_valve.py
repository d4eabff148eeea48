"""Unloading valve: dumps pump flow to tank while the accumulator is charged (hysteresis).

Function (accumulator charging circuits; Esposito, *Fluid Power with Applications*, ch. on
pressure-control valves / accumulator circuits): the pilot port senses the accumulator
pressure. When it reaches the **cut-out** pressure the valve opens and the pump's flow goes to
tank at low pressure (the pump is unloaded, a check valve holds the accumulator); the valve stays
open while the accumulator discharges, and closes again only when the pilot falls to the lower
**cut-in** pressure, so the pump recharges it. Between cut-in and cut-out the valve keeps its
present state: a hysteresis.

Model (ours, made for an implicit integrator). A switching valve is a discontinuous state
machine; here its position ``x ∈ [0, 1]`` is a continuous state with first-order dynamics

    dx/dt = [ σ_open(p) (1 − x) − σ_close(p) x ] / τ

* ``σ_open = 1`` for ``p ≥ p_out`` (cut-out), 0 for ``p ≤ p_out − b``, smoothstep between;
* ``σ_close = 1`` for ``p ≤ p_in`` (cut-in), 0 for ``p ≥ p_in + b``, smoothstep between;
* ``b`` the switching band (``b = 0``: sharp thresholds), ``τ`` the time constant.

So the target is 1 above cut-out and 0 below cut-in, and between ``p_in + b`` and ``p_out − b``
the rate is exactly 0: the valve holds whatever position it had (the hysteresis memory lives in
``x``). Without hysteresis (``hysteresis_enabled=False``) the valve closes as soon as the pilot
falls below cut-out: ``σ_close = 1 − σ_open``, ``dx/dt = (σ_open − x)/τ``.

Flow from ``in`` (pump line) to ``out`` (tank): ``A = A_leak + (A_max − A_leak) clip(x, 0, 1)``
through the regularised orifice law (:func:`~afo_mj.hydraulics.orifice.orifice_flow_m3_s`); all
of ``Δp Q`` is heat.

Example: default valve (cut-out 14.1 MPa, cut-in 12.5 MPa, τ = 5 ms). The pilot rising past
14.1 MPa drives ``x`` to 1 within ~5 τ = 25 ms; it stays 1 while the pilot falls through
13 MPa; at 12.5 MPa it closes (``x → 0``). Open, 5 mm², it passes 4 L/min with
``Δp ≈ 0.21 MPa``.
"""

from __future__ import annotations

import dataclasses

from .orifice import (DEFAULT_DISCHARGE_COEFFICIENT, DEFAULT_TRANSITION_PRESSURE_PA)
from .params import Parameters, effect, param

__all__ = ["UnloadingValveParams"]


@dataclasses.dataclass(frozen=True)
class UnloadingValveParams(Parameters):
    """A pilot-operated unloading valve from ``in`` (pump line) to ``out`` (tank)."""

    cut_out_pressure_pa: float = param(14.1e6, unit="Pa", lo=0.0, hi=1e8, lo_open=True,
                                       doc="absolute pilot pressure at which the valve opens "
                                           "(pump unloaded)")
    cut_in_pressure_pa: float = param(12.5e6, unit="Pa", lo=0.0, hi=1e8, lo_open=True,
                                      doc="absolute pilot pressure at which it closes again "
                                          "(must be < cut_out_pressure_pa)")
    max_area_m2: float = param(5.0e-6, unit="m^2", lo=0.0, hi=1e-2, lo_open=True,
                               doc="flow area fully open")
    leakage_area_m2: float = param(1.0e-10, unit="m^2", lo=0.0, hi=1e-2,
                                   doc="leakage area when closed (must be < max_area_m2)")
    discharge_coefficient: float = param(DEFAULT_DISCHARGE_COEFFICIENT, unit="-", lo=0.0,
                                         hi=1.0, lo_open=True, doc="C_d")
    transition_pressure_pa: float = param(DEFAULT_TRANSITION_PRESSURE_PA, unit="Pa", lo=0.0,
                                          hi=1e6, lo_open=True,
                                          doc="p_cr of the regularised orifice law")
    time_constant_s: float = param(5.0e-3, unit="s", lo=0.0, hi=10.0, lo_open=True,
                                   doc="τ of the first-order valve travel")
    switching_band_pa: float = param(0.1e6, unit="Pa", lo=0.0, hi=1e7,
                                     doc="pilot band below cut-out / above cut-in over which the "
                                         "switching rule blends in (0 = sharp)")
    leakage_enabled: bool = effect(True, doc="leakage through leakage_area_m2 when closed")
    hysteresis_enabled: bool = effect(True, doc="stay open until the pilot falls to cut-in "
                                                "(False: close below cut-out)")

    def check(self) -> None:
        if self.cut_in_pressure_pa >= self.cut_out_pressure_pa:
            self.fail("cut_in_pressure_pa",
                      f"must be below cut_out_pressure_pa = {self.cut_out_pressure_pa}")
        if 2.0 * self.switching_band_pa >= self.cut_out_pressure_pa - self.cut_in_pressure_pa:
            self.fail("switching_band_pa", "twice the band must be below cut_out_pressure_pa - "
                      f"cut_in_pressure_pa = {self.cut_out_pressure_pa - self.cut_in_pressure_pa}")
        if self.leakage_area_m2 >= self.max_area_m2:
            self.fail("leakage_area_m2", f"must be below max_area_m2 = {self.max_area_m2}")
