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

:class:`BatteryParams` holds the table's figures (open-circuit voltage, stored energy); the
circuit component :class:`afo_mj.circuits.components.Battery` emits the model into the
generated stepper. Power convention (the component's ledger): the chemical energy is the
battery's **store**. With ``P_chem = V_oc I`` released from it, ``in_w = 0``,
``stored_w = −V_oc I`` (negative when discharging), ``out_w = V_term I`` (electrical power to
the bus, negative when charging) and ``heat_w = R I²``, so ``in = out + heat + stored`` holds:
``0 = V_term I + R I² − V_oc I``.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from . import laws
from .params import Parameters, param

__all__ = ["NMC_OCV_SOC", "NMC_OCV_CELL_V", "BatteryParams"]

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

    # -- the open-circuit table and what it holds ---------------------------------------------
    def _cell_energy_table(self) -> np.ndarray:
        """``∫_0^{SOC_i} v_cell dSOC`` (V) at the table points: the trapezoids of the
        piecewise-linear table, exact for it."""
        soc = np.asarray(self.ocv_soc, dtype=float)
        volts = np.asarray(self.ocv_cell_v, dtype=float)
        return np.concatenate(([0.0], np.cumsum(np.diff(soc) * 0.5 * (volts[1:] + volts[:-1]))))

    def open_circuit_voltage_v(self, soc):
        """``V_oc = N_s · interp(SOC, table)``, SOC clipped to ``[0, 1]`` (the law
        :func:`~afo_mj.hydraulics.laws.table_interp_array`, the generated circuits'
        ``table_interp``).

        Example (defaults, 6S): ``open_circuit_voltage_v(0.5)`` → ``6·3.75 = 22.5`` V.
        """
        s = np.clip(np.asarray(soc, dtype=float), 0.0, 1.0)
        return self.cells_series * laws.table_interp_array(
            s, np.asarray(self.ocv_soc, dtype=float), np.asarray(self.ocv_cell_v, dtype=float))

    @property
    def nominal_voltage_v(self) -> float:
        """The SOC-mean open-circuit voltage, ``N_s ∫_0^1 v_cell dSOC`` (V)."""
        return self.cells_series * float(self._cell_energy_table()[-1])

    @property
    def energy_wh(self) -> float:
        """Energy between empty and full at zero current, ``N_s C_Ah ∫_0^1 v_cell dSOC``
        (W h). Example (defaults): 6 · 2.5 · 3.767 = 56.5 W h."""
        return self.cells_series * self.capacity_ah * float(self._cell_energy_table()[-1])

    @property
    def specific_energy_wh_kg(self) -> float:
        """``energy_wh / mass_kg`` (W h/kg)."""
        return self.energy_wh / self.mass_kg

    def stored_energy_j(self, soc):
        """Chemical energy above empty, ``3600 C_Ah N_s ∫_0^SOC v_cell dSOC`` (J), exact for
        the piecewise-linear table; its rate is ``−V_oc I`` (coulomb counting,
        ``dSOC/dt = −I/(3600 C_Ah)``).

        Example (defaults): ``stored_energy_j(1.0)`` = ``energy_wh · 3600`` ≈ 2.0e5 J.
        """
        soc_t = np.asarray(self.ocv_soc, dtype=float)
        volts = np.asarray(self.ocv_cell_v, dtype=float)
        cum = self._cell_energy_table()
        s = np.clip(np.asarray(soc, dtype=float), 0.0, 1.0)
        i = np.clip(np.searchsorted(soc_t, s, side="right") - 1, 0, len(soc_t) - 2)
        v = laws.table_interp_array(s, soc_t, volts)
        cell = cum[i] + (s - soc_t[i]) * 0.5 * (volts[i] + v)
        return 3600.0 * self.capacity_ah * self.cells_series * cell
