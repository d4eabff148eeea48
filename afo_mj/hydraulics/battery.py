"""Lithium-ion battery pack: open-circuit voltage vs state of charge behind a series resistance.

Model (the zeroth-order equivalent circuit, "Rint" model; Plett, *Battery Management Systems*,
vol. 1, 2015, §2.1–2.4):

    V_term = V_oc(SOC) − R I,        dSOC/dt = −I / (3600 C_Ah)

with ``I`` the pack current (positive discharging), ``R`` the pack internal resistance and
``V_oc = N_s · v_cell(SOC)`` for ``N_s`` cells in series. ``v_cell`` is a piecewise-linear
table (a parameter, :attr:`BatteryParams.ocv_soc` / :attr:`BatteryParams.ocv_cell_v`)
interpolated by the law :func:`afo_mj.hydraulics.laws.table_interp` (its array form
:func:`~afo_mj.hydraulics.laws.table_interp_array`); the current for a terminal power is the law
:func:`afo_mj.hydraulics.laws.battery_current_a`. The default table is a generic NMC/graphite cell,
3.0 V empty to 4.2 V full, 3.6–3.8 V over the middle of its range (mean over SOC 3.77 V; the
3.6–3.7 V "nominal" of datasheets is the average under a moderate discharge current);
its points are rounded from the shape of published low-rate OCV curves of NMC 18650/21700 cells
(e.g. LG INR21700-M50, Chen et al., J. Electrochem. Soc. 167 (2020) 080534). It is
representative, not calibrated to one cell: replace ``ocv_soc``/``ocv_cell_v`` with a measured
table where that matters.

Power convention (:meth:`Battery.power`): the chemical energy is the battery's **store**. With
``P_chem = V_oc I`` released from it, ``in_w = 0``, ``stored_w = −V_oc I`` (negative when
discharging), ``out_w = V_term I`` (electrical power to the bus, negative when charging) and
``heat_w = R I²``, so ``in = out + heat + stored`` holds:
``0 = V_term I + R I² − V_oc I``.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from . import laws
from .params import Parameters, param
from .power import PowerFlow

__all__ = ["NMC_OCV_SOC", "NMC_OCV_CELL_V", "BatteryParams", "Battery"]

#: State-of-charge points of the generic NMC open-circuit-voltage table.
NMC_OCV_SOC = (0.0, 0.05, 0.10, 0.20, 0.30, 0.40, 0.50, 0.60, 0.70, 0.80, 0.90, 1.0)
#: Cell open-circuit voltage (V) at :data:`NMC_OCV_SOC`.
NMC_OCV_CELL_V = (3.00, 3.45, 3.55, 3.62, 3.66, 3.70, 3.75, 3.81, 3.88, 3.96, 4.06, 4.20)


@dataclasses.dataclass(frozen=True)
class BatteryParams(Parameters):
    """A series string of lithium-ion cells.

    Defaults: a 6S 2.5 Ah pack for the 24 V bus (22.6 V mean open-circuit, 25.2 V full,
    56.5 Wh), 20 mΩ per cell (0.12 Ω pack), 20 A continuous, 0.33 kg (≈ 170 Wh/kg, typical
    of packs of 18650 cells).
    """

    name: str = "6S 2.5 Ah Li-ion NMC"
    capacity_ah: float = param(2.5, unit="A h", lo=0.0, hi=1e4, lo_open=True,
                               doc="C_Ah: charge between SOC = 0 and SOC = 1")
    cells_series: float = param(6.0, unit="-", lo=1.0, hi=1000.0,
                                doc="N_s: number of cells in series (a whole number)")
    internal_resistance_ohm: float = param(0.12, unit="ohm", lo=0.0, hi=100.0, lo_open=True,
                                           doc="R: pack internal resistance")
    max_current_a: float = param(20.0, unit="A", lo=0.0, hi=1e4, lo_open=True,
                                 doc="continuous current rating (flagged, not enforced)")
    mass_kg: float = param(0.33, unit="kg", lo=0.0, hi=1e4, lo_open=True)
    ocv_soc: tuple = NMC_OCV_SOC
    ocv_cell_v: tuple = NMC_OCV_CELL_V

    def check(self) -> None:
        if not float(self.cells_series).is_integer():
            self.fail("cells_series", "must be a whole number of cells")
        try:
            soc = tuple(float(s) for s in self.ocv_soc)
        except (TypeError, ValueError):
            self.fail("ocv_soc", "must be a sequence of numbers")
        try:
            volts = tuple(float(v) for v in self.ocv_cell_v)
        except (TypeError, ValueError):
            self.fail("ocv_cell_v", "must be a sequence of numbers")
        if len(soc) < 2 or not all(math.isfinite(s) for s in soc):
            self.fail("ocv_soc", "needs at least two finite points")
        if len(volts) != len(soc):
            self.fail("ocv_cell_v", f"must have as many points as ocv_soc ({len(soc)})")
        if soc[0] != 0.0 or soc[-1] != 1.0 or any(b <= a for a, b in zip(soc, soc[1:])):
            self.fail("ocv_soc", "must rise strictly from 0 to 1")
        if not all(math.isfinite(v) and 0.0 < v < 10.0 for v in volts):
            self.fail("ocv_cell_v", "cell voltages must lie in (0, 10) V")
        if any(b < a for a, b in zip(volts, volts[1:])):
            self.fail("ocv_cell_v", "open-circuit voltage must not fall with state of charge")
        object.__setattr__(self, "ocv_soc", soc)
        object.__setattr__(self, "ocv_cell_v", volts)


class Battery:
    """Rint equivalent circuit of a :class:`BatteryParams` pack (vectorised over SOC/current)."""

    def __init__(self, params: BatteryParams = BatteryParams()):
        self.params = p = params
        self._soc = np.asarray(p.ocv_soc, dtype=float)
        self._volts = np.asarray(p.ocv_cell_v, dtype=float)
        seg = np.diff(self._soc) * 0.5 * (self._volts[1:] + self._volts[:-1])
        #: ∫_0^{SOC_i} v_cell dSOC at the table points (V), exact for the piecewise-linear table.
        self._cum = np.concatenate(([0.0], np.cumsum(seg)))
        #: Charge in coulombs.
        self.capacity_c = 3600.0 * p.capacity_ah
        #: Energy between empty and full at zero current, ``N_s C_Ah ∫ v_cell dSOC`` (W h).
        self.energy_wh = p.cells_series * p.capacity_ah * float(self._cum[-1])
        #: Nominal voltage: the SOC-mean open-circuit voltage, ``energy_wh / capacity_ah``.
        self.nominal_voltage_v = p.cells_series * float(self._cum[-1])
        #: Specific energy of the pack (W h/kg).
        self.specific_energy_wh_kg = self.energy_wh / p.mass_kg

    def open_circuit_voltage_v(self, soc):
        """``V_oc = N_s · interp(SOC, table)``, SOC clipped to ``[0, 1]``.

        Example (defaults, 6S): ``open_circuit_voltage_v(0.5)`` → ``6·3.75 = 22.5`` V.
        """
        s = np.clip(np.asarray(soc, dtype=float), 0.0, 1.0)
        return self.params.cells_series * laws.table_interp_array(s, self._soc, self._volts)

    def terminal_voltage_v(self, soc, current_a):
        """``V_term = V_oc − R I`` (``I > 0`` discharging).

        Example (defaults): ``terminal_voltage_v(0.5, 10)`` → ``22.5 − 1.2 = 21.3`` V.
        """
        return self.open_circuit_voltage_v(soc) - self.params.internal_resistance_ohm * \
            np.asarray(current_a, dtype=float)

    def max_power_w(self, soc):
        """Largest terminal power the pack can deliver, ``V_oc² / (4R)`` (at ``I = V_oc/(2R)``,
        half the open-circuit voltage across the load; matched-load theorem).

        Example (defaults, SOC 0.5): ``22.5²/0.48`` = 1055 W.
        """
        v = self.open_circuit_voltage_v(soc)
        return v * v / (4.0 * self.params.internal_resistance_ohm)

    def power_limited(self, soc, power_w):
        """True where ``power_w`` exceeds :meth:`max_power_w` (the current is then clipped)."""
        return np.asarray(power_w, dtype=float) > self.max_power_w(soc)

    def current_for_power_a(self, soc, power_w):
        """Pack current that delivers terminal power ``P = V_term I`` (negative ``P`` charges).

        Root of ``R I² − V_oc I + P = 0`` on the stable branch,
        ``I = (V_oc − sqrt(V_oc² − 4 R P)) / (2R) = 2P / (V_oc + sqrt(V_oc² − 4 R P))``
        (the second form, used here, has no cancellation at small ``P``). ``P`` is first clipped
        to :meth:`max_power_w`, so the result is finite: ``V_oc/(2R)`` at and beyond the limit
        (see :meth:`power_limited`). The law :func:`afo_mj.hydraulics.laws.battery_current_a`.

        Example (defaults, SOC 0.5, 200 W): ``2·200/(22.5 + sqrt(22.5² − 96))`` = 9.36 A.
        """
        return laws.battery_current_a(np.asarray(power_w, dtype=float),
                                      self.open_circuit_voltage_v(soc),
                                      self.params.internal_resistance_ohm)

    def over_current(self, current_a):
        """True where ``|I|`` exceeds ``max_current_a``."""
        return np.abs(np.asarray(current_a, dtype=float)) > self.params.max_current_a

    def soc_rate_per_s(self, current_a):
        """``dSOC/dt = −I / (3600 C_Ah)`` (coulomb counting).

        Example (defaults): 10 A → ``−10/9000 = −1.11e-3`` 1/s.
        """
        return -np.asarray(current_a, dtype=float) / self.capacity_c

    def stored_energy_j(self, soc):
        """Chemical energy above empty, ``3600 C_Ah N_s ∫_0^SOC v_cell dSOC`` (J); its rate
        is ``V_oc dSOC/dt · 3600 C_Ah = −V_oc I`` = ``power().stored_w``.

        Example (defaults): ``stored_energy_j(1.0)`` = ``energy_wh · 3600`` ≈ 2.0e5 J.
        """
        s = np.clip(np.asarray(soc, dtype=float), 0.0, 1.0)
        i = np.clip(np.searchsorted(self._soc, s, side="right") - 1, 0, len(self._soc) - 2)
        s0 = self._soc[i]
        v0 = self._volts[i]
        v = laws.table_interp_array(s, self._soc, self._volts)
        cell = self._cum[i] + (s - s0) * 0.5 * (v0 + v)
        return self.capacity_c * self.params.cells_series * cell

    def power(self, soc, current_a) -> PowerFlow:
        """Power flows at ``(SOC, I)``: ``in = 0``, ``out = V_term I``, ``heat = R I²``,
        ``stored = −V_oc I`` (see the module docstring).

        Example (defaults, SOC 0.5, 10 A): out 213 W, heat 12 W, stored −225 W.
        """
        i = np.asarray(current_a, dtype=float)
        v_oc = self.open_circuit_voltage_v(soc)
        r = self.params.internal_resistance_ohm
        out = (v_oc - r * i) * i
        return PowerFlow(in_w=np.zeros_like(out), out_w=out, heat_w=r * i * i, stored_w=-v_oc * i)
