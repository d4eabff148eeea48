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

Limits (both kinds). The circuit integrator may step a little past the physical ends of travel,
so :meth:`pressure_pa` is defined, finite and monotone for every ``Vf``:

* **Empty stop** (``Vf < 0``): the bladder/diaphragm/piston rests on its poppet or stop, and a
  further withdrawal only decompresses the liquid in the port volume ``V_port``:
  ``p = p_empty + (B_stop / V_port) Vf`` (``p_empty`` = precharge, or the spring cracking
  pressure). This is the usual stiff-stop rule of lumped simulators (Simscape's hard-stop on
  the separator). ``B_stop/V_port`` is :attr:`stop_stiffness_pa_m3`; :meth:`below_empty`
  flags the state. Far enough below, the formula gives pressures under the fluid's floor, which
  the circuit's cavitation clamp keeps out.
* **Gas above capacity** (``Vf > capacity``): the gas law continues (the shell tolerates its
  rated pressure, higher than the working maximum); :meth:`over_capacity` flags it. So that
  the law never diverges, below a residual gas volume of ``GAS_LAW_MIN_VOLUME_FRACTION · V0``
  the pressure continues along the tangent line (C¹), far beyond any working pressure.
* **Spring above full stroke** (``Vf > A·stroke``): the piston sits on its top stop and the
  liquid is compressed with the same stiffness ``B_stop/V_port``; :meth:`over_capacity` flags it.

The gas and spring equations are the laws of :mod:`afo_mj.hydraulics.laws`
(``gas_accumulator_pressure_pa``, ``gas_accumulator_oil_volume_m3``,
``polytropic_gas_energy_j``, ``spring_accumulator_pressure_pa``,
``spring_accumulator_oil_volume_m3``, ``spring_accumulator_capacitance_m3_pa``,
``spring_accumulator_energy_j``); the stop and knee continuations of the gas kind are this
module's.

Energy: :meth:`stored_energy_j` is the integral of the port pressure (minus the vent pressure
for the spring kind) over ``Vf`` from the empty state, so ``d E/d Vf`` equals the power per unit
flow reported by :meth:`power` in every region, limits included.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from . import laws
from .fluid import ATMOSPHERIC_PRESSURE_PA
from .params import Parameters, param
from .power import PowerFlow

__all__ = [
    "GAS_LAW_MIN_VOLUME_FRACTION",
    "GasAccumulatorParams",
    "GasAccumulator",
    "SpringAccumulatorParams",
    "SpringAccumulator",
]

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


class _Accumulator:
    """Shared flags and power report; subclasses define pressure and energy."""

    capacity_m3: float
    stop_stiffness_pa_m3: float

    def over_capacity(self, fluid_volume_m3):
        """True where ``Vf`` exceeds the usable capacity :attr:`capacity_m3`."""
        return np.asarray(fluid_volume_m3, dtype=float) > self.capacity_m3

    def below_empty(self, fluid_volume_m3):
        """True where ``Vf < 0`` (separator or piston on its empty stop)."""
        return np.asarray(fluid_volume_m3, dtype=float) < 0.0

    def _vent_pressure_pa(self) -> float:
        return 0.0

    def power(self, fluid_volume_m3, flow_in_m3_s) -> PowerFlow:
        """Power flows for fluid entering at ``flow_in_m3_s`` (negative when discharging).

        ``in = p Q``, ``out = p_vent Q`` (air pushed through the spring-side vent; 0 for the
        sealed gas kind), ``heat = 0`` (the polytropic law is reversible), ``stored = in − out``
        = ``d(stored_energy_j)/dt``.

        Example (gas defaults, empty, 1 cm³/s in): ``in_w = stored_w = 1.5e6·1e-6 = 1.5`` W.
        """
        p = self.pressure_pa(fluid_volume_m3)
        q = np.asarray(flow_in_m3_s, dtype=float)
        p_in = p * q
        p_out = self._vent_pressure_pa() * q
        return PowerFlow(in_w=p_in, out_w=p_out, heat_w=np.zeros_like(p_in),
                         stored_w=p_in - p_out)


class GasAccumulator(_Accumulator):
    """Polytropic gas-charged accumulator (see the module docstring for the limit rules)."""

    def __init__(self, params: GasAccumulatorParams = GasAccumulatorParams()):
        self.params = p = params
        v0, p0, n = p.gas_volume_m3, p.precharge_pressure_pa, p.polytropic_index
        #: ``B_stop / V_port``: pressure slope at the empty stop, Pa/m³.
        self.stop_stiffness_pa_m3 = p.stop_bulk_modulus_pa / p.port_volume_m3
        #: Residual gas volume where the gas law hands over to its tangent.
        self.knee_gas_volume_m3 = GAS_LAW_MIN_VOLUME_FRACTION * v0
        self.knee_fluid_volume_m3 = v0 - self.knee_gas_volume_m3
        self.knee_pressure_pa = float(laws.gas_accumulator_pressure_pa(
            self.knee_fluid_volume_m3, v0, p0, n))
        self.knee_stiffness_pa_m3 = n * self.knee_pressure_pa / self.knee_gas_volume_m3
        self.knee_energy_j = float(self._gas_energy(self.knee_gas_volume_m3))
        #: Usable fluid volume between precharge and maximum pressure,
        #: ``V0 (1 − (p0/p_max)^(1/n))``.
        self.capacity_m3 = float(laws.gas_accumulator_oil_volume_m3(p.max_pressure_pa, v0, p0, n))

    def gas_volume_m3(self, fluid_volume_m3):
        """``V_g = V0 − Vf`` clipped to ``[knee volume, V0]`` (where the gas law holds)."""
        p = self.params
        vf = np.asarray(fluid_volume_m3, dtype=float)
        return np.clip(p.gas_volume_m3 - vf, self.knee_gas_volume_m3, p.gas_volume_m3)

    def _gas_energy(self, gas_volume_m3):
        # E = p0 V0 (r^(n-1) - 1)/(n - 1), r = V0/Vg (laws.polytropic_gas_energy_j)
        p = self.params
        return laws.polytropic_gas_energy_j(np.asarray(gas_volume_m3, dtype=float),
                                            p.gas_volume_m3, p.precharge_pressure_pa,
                                            p.polytropic_index)

    def pressure_pa(self, fluid_volume_m3):
        """Absolute port pressure at stored volume ``Vf``.

        ``p = p0 (V0/(V0 − Vf))^n`` for ``0 <= Vf <= V0 − V_knee`` (``p V_g^n`` constant);
        ``p = p0 + (B_stop/V_port) Vf`` for ``Vf < 0`` (empty stop); the tangent line beyond
        the knee volume ``V_knee = 0.01 V0``.

        Example (defaults V0 = 75 cm³, p0 = 1.5 MPa, n = 1.4): ``pressure_pa(25e-6)`` →
        ``1.5e6·1.5^1.4 = 2.64e6`` Pa.
        """
        p = self.params
        vf = np.asarray(fluid_volume_m3, dtype=float)
        p_gas = laws.gas_accumulator_pressure_pa(np.clip(vf, 0.0, self.knee_fluid_volume_m3),
                                                 p.gas_volume_m3, p.precharge_pressure_pa,
                                                 p.polytropic_index)
        p_empty = p.precharge_pressure_pa + self.stop_stiffness_pa_m3 * vf
        dv = vf - self.knee_fluid_volume_m3
        p_knee = self.knee_pressure_pa + self.knee_stiffness_pa_m3 * dv
        return np.where(vf < 0.0, p_empty, np.where(vf > self.knee_fluid_volume_m3, p_knee, p_gas))

    def stiffness_pa_m3(self, fluid_volume_m3):
        """``dp/dVf``: ``n p / V_g`` on the gas law, the stop or tangent slope beyond it."""
        p = self.params
        vf = np.asarray(fluid_volume_m3, dtype=float)
        vg = self.gas_volume_m3(vf)
        k_gas = p.polytropic_index * self.pressure_pa(np.clip(vf, 0.0, None)) / vg
        return np.where(vf < 0.0, self.stop_stiffness_pa_m3,
                        np.where(vf > self.knee_fluid_volume_m3, self.knee_stiffness_pa_m3, k_gas))

    def fluid_volume_m3(self, pressure_pa):
        """Stored volume at absolute pressure ``p``: the inverse of :meth:`pressure_pa` for
        ``Vf >= 0``, ``Vf = V0 (1 − (p0/p)^(1/n))``, and 0 at or below the precharge.

        Example (defaults): ``fluid_volume_m3(6e6)`` = capacity = ``75e-6 (1 − 0.25^(1/1.4))``
        = 4.71e-5 m³.
        """
        p = self.params
        pr = np.asarray(pressure_pa, dtype=float)
        vf_gas = laws.gas_accumulator_oil_volume_m3(pr, p.gas_volume_m3, p.precharge_pressure_pa,
                                                    p.polytropic_index)
        vf_knee = self.knee_fluid_volume_m3 \
            + (pr - self.knee_pressure_pa) / self.knee_stiffness_pa_m3
        return np.where(pr > self.knee_pressure_pa, vf_knee, vf_gas)

    def stored_energy_j(self, fluid_volume_m3):
        """Gas compression energy from the precharge state, ``∫_0^Vf p dVf = ∫_{Vg}^{V0} p dV``.

        ``(p V_g − p0 V0)/(n − 1)`` for ``n ≠ 1``, ``p0 V0 ln(V0/V_g)`` for ``n = 1``; in the
        limit regions the integral of the continued pressure law (``p0 Vf + ½ s Vf²`` below
        empty, negative there).

        Example (defaults, ``Vf = 25`` cm³): ``(2.64e6·50e-6 − 1.5e6·75e-6)/0.4`` = 49.5 J.
        """
        vf = np.asarray(fluid_volume_m3, dtype=float)
        p0 = self.params.precharge_pressure_pa
        e_gas = self._gas_energy(self.gas_volume_m3(vf))
        e_empty = p0 * vf + 0.5 * self.stop_stiffness_pa_m3 * vf * vf
        dv = vf - self.knee_fluid_volume_m3
        e_knee = self.knee_energy_j + self.knee_pressure_pa * dv \
            + 0.5 * self.knee_stiffness_pa_m3 * dv * dv
        return np.where(vf < 0.0, e_empty, np.where(dv > 0.0, e_knee, e_gas))


class SpringAccumulator(_Accumulator):
    """Spring-loaded piston accumulator (see the module docstring for the stop rules)."""

    def __init__(self, params: SpringAccumulatorParams = SpringAccumulatorParams()):
        self.params = p = params
        #: ``B_stop / V_port``: pressure slope on either stop, Pa/m³.
        self.stop_stiffness_pa_m3 = p.stop_bulk_modulus_pa / p.port_volume_m3
        #: Usable volume ``A · stroke``.
        self.capacity_m3 = p.piston_area_m2 * p.stroke_m

    def _vent_pressure_pa(self) -> float:
        return self.params.vent_pressure_pa

    def piston_position_m(self, fluid_volume_m3):
        """``x = Vf / A`` clipped to ``[0, stroke]``."""
        p = self.params
        return np.clip(np.asarray(fluid_volume_m3, dtype=float) / p.piston_area_m2, 0.0, p.stroke_m)

    def pressure_pa(self, fluid_volume_m3):
        """``p = p_vent + (F0 + k x)/A``, ``x = Vf/A`` on ``0 <= Vf <= A·stroke``; beyond either
        end the stop stiffness ``B_stop/V_port`` continues from the end pressure.

        Example (defaults, half stroke ``Vf = 9.82`` cm³): ``101325 + (200 + 1e4·0.02)/4.909e-4``
        = 9.16e5 Pa.
        """
        return laws.spring_accumulator_pressure_pa(np.asarray(fluid_volume_m3, dtype=float),
                                                   *self._law_args())

    def stiffness_pa_m3(self, fluid_volume_m3):
        """``dp/dVf``: ``k/A²`` in the stroke, ``B_stop/V_port`` on the stops (the inverse of
        :func:`~afo_mj.hydraulics.laws.spring_accumulator_capacitance_m3_pa` at the pressure
        of ``Vf``)."""
        return 1.0 / laws.spring_accumulator_capacitance_m3_pa(self.pressure_pa(fluid_volume_m3),
                                                               *self._law_args())

    def _law_args(self) -> tuple:
        p = self.params
        return (p.piston_area_m2, p.spring_rate_n_m, p.preload_n, p.stroke_m,
                p.vent_pressure_pa, self.stop_stiffness_pa_m3)

    def fluid_volume_m3(self, pressure_pa):
        """Inverse of :meth:`pressure_pa` for ``Vf >= 0``: ``A ((p − p_vent) A − F0)/k`` in the
        stroke, 0 below the cracking pressure, the top-stop line above the full pressure."""
        return laws.spring_accumulator_oil_volume_m3(np.asarray(pressure_pa, dtype=float),
                                                     *self._law_args())

    def stored_energy_j(self, fluid_volume_m3):
        """Spring energy ``F0 x + ½ k x²`` (``= ∫_0^Vf (p − p_vent) dVf``); on the stops the
        integral of the stop law is added (liquid compression), so it stays the integral of
        ``p − p_vent``.

        Example (defaults, full stroke): ``200·0.04 + ½·1e4·0.04²`` = 16 J.
        """
        return laws.spring_accumulator_energy_j(np.asarray(fluid_volume_m3, dtype=float),
                                                *self._law_args())
