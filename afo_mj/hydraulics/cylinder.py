"""Hydraulic cylinders: single-acting, double-acting (single rod) and piston-cable.

The piston-cable cylinder (cable through both end caps, equal annular areas) is the actuator of
the seed's ankle orthoses: two of them pull a cable wrapped on the ankle pulley.

Geometry and force (Merritt 1967, ch. 5; seed §2.3)
----------------------------------------------------
* Annular areas ``A_a = π/4 (D² − d_a²)``, ``A_b = π/4 (D² − d_b²)``; ``d`` is the rod or cable
  diameter on that side (0 for a blind side).
* Chamber volumes with dead volume: ``V_a = V_a0 + A_a x``, ``V_b = V_b0 + A_b (s − x)``, ``x`` the
  piston position from the a-side end (0 … stroke ``s``). Positive ``x``/velocity extends
  (chamber a grows).
* Hydraulic force (absolute pressures, atmosphere on the rod ends):
  ``F_h = p_a A_a − p_b A_b − p_atm (A_a − A_b)``.
* Seal friction: the piston seal and one seal per rod/cable exit (:mod:`.seal`).
* Internal leakage across the piston through the radial clearance (laminar annular gap, Merritt
  §3.2): ``Q = π D δ³ (p_a − p_b) / (12 μ L)``, ``δ`` the radial clearance, ``L`` the land length.
* End stops: a stiff spring–damper engaging beyond 0 and ``s``:
  ``F = −k_s pen − c_s v_pen`` where ``pen`` is the penetration, with the damping force only while
  penetrating (and never pulling the piston into the stop).

The leakage, end-stop and seal equations are the laws of :mod:`afo_mj.hydraulics.laws`
(``annular_gap_conductance_m3``, ``laminar_gap_flow_m3_s``, ``end_stop_force_n``,
``end_stop_energy_j``; the seals' in :mod:`.seal`).
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from . import laws
from .fluid import ATMOSPHERIC_PRESSURE_PA
from .params import Parameters, effect, param
from .power import PowerFlow
from .seal import OringSeal, OringSealParams

CYLINDER_KINDS = ("double_acting", "single_acting", "piston_cable")


@dataclasses.dataclass(frozen=True)
class CylinderParams(Parameters):
    """One cylinder. ``kind``: ``double_acting`` (single rod on side b), ``single_acting``
    (side b vented to atmosphere) or ``piston_cable`` (cable through both caps)."""

    kind: str = "piston_cable"
    bore_m: float = param(12e-3, unit="m", lo=0.0, hi=0.2, lo_open=True, doc="piston diameter D")
    rod_diameter_m: float = param(2e-3, unit="m", lo=0.0, hi=0.2,
                                  doc="rod (double_acting) or cable (piston_cable) diameter")
    stroke_m: float = param(0.03, unit="m", lo=0.0, hi=2.0, lo_open=True, doc="stroke s")
    dead_volume_a_m3: float = param(0.2e-6, unit="m^3", lo=0.0, hi=1e-2, lo_open=True,
                                    doc="chamber a volume at x = 0 (ports, clearance)")
    dead_volume_b_m3: float = param(0.2e-6, unit="m^3", lo=0.0, hi=1e-2, lo_open=True,
                                    doc="chamber b volume at x = stroke")
    piston_mass_kg: float = param(0.02, unit="kg", lo=0.0, hi=100.0, lo_open=True,
                                  doc="piston (and rod/cable share) mass")
    radial_clearance_m: float = param(10e-6, unit="m", lo=0.0, hi=1e-3,
                                      doc="piston-bore radial clearance δ (internal leakage)")
    land_length_m: float = param(5e-3, unit="m", lo=0.0, hi=0.1, lo_open=True,
                                 doc="piston land length L (internal leakage)")
    end_stop_stiffness_n_m: float = param(5e7, unit="N/m", lo=1e3, hi=1e11)
    end_stop_damping_n_s_m: float = param(2e3, unit="N s/m", lo=0.0, hi=1e7)
    piston_seal: OringSealParams = dataclasses.field(default_factory=OringSealParams)
    rod_seal: OringSealParams = dataclasses.field(
        default_factory=lambda: OringSealParams(cross_section_m=1.0e-3))
    internal_leakage_enabled: bool = effect(True, doc="laminar leakage across the piston")
    end_stops_enabled: bool = effect(True, doc="stiff end stops at 0 and stroke")
    seal_friction_enabled: bool = effect(True, doc="O-ring seal friction")

    def check(self) -> None:
        if self.kind not in CYLINDER_KINDS:
            self.fail("kind", f"allowed: {', '.join(CYLINDER_KINDS)}")
        if self.rod_diameter_m >= self.bore_m:
            self.fail("rod_diameter_m", f"must be smaller than bore_m = {self.bore_m}")
        if (self.kind != "single_acting" and self.kind != "piston_cable"
                and self.rod_diameter_m == 0):
            self.fail("rod_diameter_m", "a double_acting (single-rod) cylinder needs a rod > 0")


class Cylinder:
    """Volumes, forces, leakage and power of one :class:`CylinderParams` cylinder."""

    def __init__(self, params: CylinderParams):
        p = self.params = params
        full = math.pi * p.bore_m ** 2 / 4.0
        rod = math.pi * p.rod_diameter_m ** 2 / 4.0
        if p.kind == "piston_cable":
            self.area_a_m2, self.area_b_m2, n_rod_seals = full - rod, full - rod, 2
        elif p.kind == "double_acting":
            self.area_a_m2, self.area_b_m2, n_rod_seals = full, full - rod, 1
        else:  # single_acting: side b vented, rod seal on the vented side
            self.area_a_m2, self.area_b_m2, n_rod_seals = full, 0.0, 0
        self.piston_seal = OringSeal(p.piston_seal, p.bore_m)
        self.rod_seal = OringSeal(p.rod_seal, max(p.rod_diameter_m, 1e-6))
        self.n_rod_seals = n_rod_seals
        self.leakage_conductance_m3 = float(laws.annular_gap_conductance_m3(
            p.bore_m, p.radial_clearance_m, p.land_length_m))

    def chamber_volumes_m3(self, position_m):
        """``(V_a, V_b)`` at piston position ``x``."""
        x = np.asarray(position_m, dtype=float)
        return (self.params.dead_volume_a_m3 + self.area_a_m2 * x,
                self.params.dead_volume_b_m3 + self.area_b_m2 * (self.params.stroke_m - x))

    def hydraulic_force_n(self, p_a_pa, p_b_pa):
        """``F_h = p_a A_a − p_b A_b − p_atm (A_a − A_b)`` (positive extends)."""
        return (self.area_a_m2 * (np.asarray(p_a_pa) - ATMOSPHERIC_PRESSURE_PA)
                - self.area_b_m2 * (np.asarray(p_b_pa) - ATMOSPHERIC_PRESSURE_PA))

    def friction_force_n(self, velocity_m_s, p_a_pa, p_b_pa):
        """Total seal friction (sign of velocity): piston seal sees ``p_a − p_b``, each rod or
        cable seal its chamber's gauge pressure."""
        if not self.params.seal_friction_enabled:
            return np.zeros_like(np.asarray(velocity_m_s, dtype=float))
        f = self.piston_seal.friction_force_n(velocity_m_s, np.asarray(p_a_pa) - p_b_pa)
        if self.n_rod_seals == 2:
            f = f + self.rod_seal.friction_force_n(velocity_m_s, np.asarray(p_a_pa)
                                                   - ATMOSPHERIC_PRESSURE_PA)
            f = f + self.rod_seal.friction_force_n(velocity_m_s, np.asarray(p_b_pa)
                                                   - ATMOSPHERIC_PRESSURE_PA)
        elif self.n_rod_seals == 1:
            f = f + self.rod_seal.friction_force_n(velocity_m_s, np.asarray(p_b_pa)
                                                   - ATMOSPHERIC_PRESSURE_PA)
        return f

    def internal_leakage_m3_s(self, p_a_pa, p_b_pa, dynamic_viscosity_pa_s):
        """Laminar annular-gap flow from chamber a to b (0 for single-acting or if disabled)."""
        dp = np.asarray(p_a_pa, dtype=float) - p_b_pa
        if not self.params.internal_leakage_enabled or self.params.kind == "single_acting":
            return np.zeros_like(dp)
        return laws.laminar_gap_flow_m3_s(dp, self.leakage_conductance_m3, dynamic_viscosity_pa_s)

    def end_stop_force_n(self, position_m, velocity_m_s):
        """Contact force of the end stops (pushes the piston back into 0 … stroke): the law
        :func:`~afo_mj.hydraulics.laws.end_stop_force_n`."""
        x = np.asarray(position_m, dtype=float)
        v = np.asarray(velocity_m_s, dtype=float)
        if not self.params.end_stops_enabled:
            return np.zeros_like(x)
        p = self.params
        return laws.end_stop_force_n(x, v, p.stroke_m, p.end_stop_stiffness_n_m,
                                     p.end_stop_damping_n_s_m)

    def end_stop_energy_j(self, position_m):
        """Elastic energy stored in the end stops, ``½ k pen²``
        (:func:`~afo_mj.hydraulics.laws.end_stop_energy_j`)."""
        x = np.asarray(position_m, dtype=float)
        if not self.params.end_stops_enabled:
            return np.zeros_like(x)
        return laws.end_stop_energy_j(x, self.params.stroke_m, self.params.end_stop_stiffness_n_m)

    def power(self, p_a_pa, p_b_pa, velocity_m_s, leakage_m3_s) -> PowerFlow:
        """Hydraulic → mechanical conversion with gauge pressures.

        ``in = F_h v + (p_a − p_b) Q_leak`` (displacement power plus the power carried by the
        leakage flow), ``out = (F_h − F_fric) v``, ``heat = F_fric v + (p_a − p_b) Q_leak``.
        """
        v = np.asarray(velocity_m_s, dtype=float)
        fh = self.hydraulic_force_n(p_a_pa, p_b_pa)
        ff = self.friction_force_n(v, p_a_pa, p_b_pa)
        leak = (np.asarray(p_a_pa) - p_b_pa) * leakage_m3_s
        return PowerFlow(fh * v + leak, (fh - ff) * v, ff * v + leak, 0.0)
