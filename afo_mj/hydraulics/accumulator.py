"""Hydraulic accumulators: gas-charged (bladder/diaphragm/piston) and spring-loaded piston.

State: the stored fluid volume ``Vf`` (m³), zero when the accumulator is empty (gas at its
precharge, or the spring piston on its bottom stop). Pressures are absolute Pa at the fluid
port.

Gas-charged accumulator (polytropic gas law, as in accumulator sizing in Esposito, *Fluid Power
with Applications*, ch. "Accumulators", and Simscape's "Gas-Charged Accumulator" block):

    p V_g^n = p0 V0^n,    V_g = V0 − Vf    ⇒    p = p0 (V0 / (V0 − Vf))^n      (0 <= Vf)

with ``V0`` the shell gas volume, ``p0`` the precharge pressure, ``n`` the polytropic index
(1 isothermal, slow cycles; 1.4 adiabatic nitrogen, fast cycles; up to 1.67 for a monatomic
gas). The usable (capacity) volume between precharge and maximum pressure is
``V0 (1 − (p0/p_max)^(1/n))``. The energy stored in the gas, the compression work from the
precharge state, is

    E = ∫_{V_g}^{V0} p dV = (p V_g − p0 V0)/(n − 1)  (n ≠ 1),   E = p0 V0 ln(V0/V_g)  (n = 1).

Spring accumulator (piston of area ``A`` against a spring of rate ``k`` and preload ``F0``,
vented to ``p_vent``): ``x = Vf/A``, ``p = p_vent + (F0 + k x)/A``, spring energy
``F0 x + ½ k x²``.

The gas and spring equations are the laws of :mod:`afo_mj.hydraulics.laws`
(``gas_accumulator_pressure_pa``, ``gas_accumulator_oil_volume_m3``,
``gas_accumulator_capacitance_m3_pa``, ``polytropic_gas_energy_j``,
``spring_accumulator_pressure_pa``, ``spring_accumulator_oil_volume_m3``,
``spring_accumulator_capacitance_m3_pa``, ``spring_accumulator_energy_j``). The simulated
component is :class:`afo_mj.circuits.components.GasAccumulator`: a capacitance at its node
(pressure the state; the gas law's ``dV/dp`` above the precharge, blended in over a band, none
below it) plus its port volume, its stored energy the node's ``∫p dV``. This module holds the
parameter sets; the volume-state evaluation with its stop and knee continuations
(``GAS_LAW_MIN_VOLUME_FRACTION``) is the test suite's reference (tests/component_reference.py).
"""

from __future__ import annotations

import dataclasses
import math

from .fluid import ATMOSPHERIC_PRESSURE_PA
from .params import Parameters, param

__all__ = ["GAS_LAW_MIN_VOLUME_FRACTION", "GasAccumulatorParams", "SpringAccumulatorParams"]

#: Residual gas volume (fraction of ``V0``) below which the gas law continues along its tangent.
GAS_LAW_MIN_VOLUME_FRACTION = 0.01


@dataclasses.dataclass(frozen=True)
class GasAccumulatorParams(Parameters):
    """A gas-charged (bladder, diaphragm or piston) accumulator.

    Defaults: a 75 cm³ diaphragm accumulator (the smallest catalogue size of e.g. Hydac SBO
    series) precharged to 1.5 MPa abs and worked up to 6 MPa abs (compression ratio 4:1, the
    usual limit for diaphragm types).
    """

    gas_volume_m3: float = param(75e-6, unit="m^3", lo=0.0, hi=1.0, lo_open=True,
                                 doc="V0: total shell gas volume at precharge (empty)")
    precharge_pressure_pa: float = param(1.5e6, unit="Pa", lo=0.0, hi=1e8, lo_open=True,
                                         doc="p0: absolute gas precharge pressure")
    max_pressure_pa: float = param(6.0e6, unit="Pa", lo=0.0, hi=1e8, lo_open=True,
                                   doc="p_max: absolute maximum working pressure; the usable "
                                       "volume is the one stored between p0 and p_max")
    polytropic_index: float = param(1.4, unit="-", lo=1.0, hi=1.67,
                                    doc="n: 1 isothermal, 1.4 adiabatic N2, 1.67 monatomic gas")
    stop_bulk_modulus_pa: float = param(1.5e9, unit="Pa", lo=1e7, hi=5e9,
                                        doc="B_stop: liquid bulk modulus used for the empty "
                                            "stop (Vf < 0)")
    port_volume_m3: float = param(2e-6, unit="m^3", lo=0.0, hi=1.0, lo_open=True,
                                  doc="V_port: liquid volume at the port compressed at the "
                                      "empty stop")

    def check(self) -> None:
        if self.precharge_pressure_pa >= self.max_pressure_pa:
            self.fail("precharge_pressure_pa",
                      f"must be below max_pressure_pa = {self.max_pressure_pa!r} "
                      "(an accumulator precharged at or above its maximum pressure stores "
                      "nothing)")
        limit = (1.0 / GAS_LAW_MIN_VOLUME_FRACTION) ** self.polytropic_index
        if self.max_pressure_pa / self.precharge_pressure_pa >= limit:
            self.fail("max_pressure_pa",
                      f"ratio to precharge_pressure_pa = {self.precharge_pressure_pa!r} must be "
                      f"below {limit:.4g} (gas compressed to under "
                      f"{GAS_LAW_MIN_VOLUME_FRACTION:g} of gas_volume_m3 at "
                      f"polytropic_index = {self.polytropic_index!r})")


@dataclasses.dataclass(frozen=True)
class SpringAccumulatorParams(Parameters):
    """A spring-loaded piston accumulator vented to ``vent_pressure_pa`` on the spring side.

    Defaults: 25 mm bore (A = 4.909e-4 m²), 40 mm stroke (19.6 cm³), 200 N preload and
    10 kN/m spring: cracking at 0.41 MPa gauge, 1.22 MPa gauge at full stroke.
    """

    piston_area_m2: float = param(math.pi * 0.025 ** 2 / 4.0, unit="m^2", lo=0.0, hi=1.0,
                                  lo_open=True, doc="A: piston area")
    spring_rate_n_m: float = param(1.0e4, unit="N/m", lo=0.0, hi=1e9, lo_open=True,
                                   doc="k: spring rate")
    preload_n: float = param(200.0, unit="N", lo=0.0, hi=1e7,
                             doc="F0: spring force with the piston on its bottom stop (empty)")
    stroke_m: float = param(0.04, unit="m", lo=0.0, hi=10.0, lo_open=True,
                            doc="piston travel from empty to full")
    max_pressure_pa: float = param(2.0e6, unit="Pa", lo=0.0, hi=1e8, lo_open=True,
                                   doc="absolute pressure rating; the full-stroke pressure "
                                       "must not exceed it")
    vent_pressure_pa: float = param(ATMOSPHERIC_PRESSURE_PA, unit="Pa", lo=0.0, hi=1e6,
                                    doc="absolute pressure on the spring (vented) side")
    stop_bulk_modulus_pa: float = param(1.5e9, unit="Pa", lo=1e7, hi=5e9,
                                        doc="B_stop: liquid bulk modulus used at the stops")
    port_volume_m3: float = param(2e-6, unit="m^3", lo=0.0, hi=1.0, lo_open=True,
                                  doc="V_port: liquid volume compressed at the stops")

    @property
    def cracking_pressure_pa(self) -> float:
        """``p_vent + F0/A``: the pressure at which the piston leaves its bottom stop."""
        return self.vent_pressure_pa + self.preload_n / self.piston_area_m2

    @property
    def full_pressure_pa(self) -> float:
        """``p_vent + (F0 + k·stroke)/A``: the pressure at full stroke."""
        return self.vent_pressure_pa + (self.preload_n + self.spring_rate_n_m * self.stroke_m) \
            / self.piston_area_m2

    def check(self) -> None:
        if self.full_pressure_pa > self.max_pressure_pa:
            self.fail("max_pressure_pa",
                      f"is below the full-stroke pressure {self.full_pressure_pa:.6g} Pa = "
                      "vent_pressure_pa + (preload_n + spring_rate_n_m*stroke_m)/piston_area_m2; "
                      "lower the spring force or stroke, or raise the rating")
