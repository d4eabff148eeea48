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

The area is :func:`afo_mj.hydraulics.geometry.annulus_area_m2`; the leakage, end-stop and seal
equations are the laws of :mod:`afo_mj.hydraulics.laws` (``annular_gap_conductance_m3``,
``laminar_gap_flow_m3_s``, ``end_stop_force_n``, ``end_stop_energy_j``; the seals' in
:mod:`.seal`).
:class:`CylinderParams` carries the derived geometry (areas, swept volume, leakage conductance);
the circuit components :class:`afo_mj.circuits.components.PulleyCylinders` and
``SpringReturnCylinder`` emit the equations above into the generated stepper.
"""

from __future__ import annotations

import dataclasses

from . import laws
from .geometry import annulus_area_m2
from .params import Parameters, effect, param
from .seal import OringSealParams

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
    seal_pressure_per_chamber: bool = effect(
        False, doc="each rod/cable seal's pressure friction grows with its own chamber's "
                   "pressure against the ambient (Parker ORD 5700), not with the pressure "
                   "difference across the piston, which stays the piston seal's")

    def check(self) -> None:
        if self.kind not in CYLINDER_KINDS:
            self.fail("kind", f"allowed: {', '.join(CYLINDER_KINDS)}")
        if self.rod_diameter_m >= self.bore_m:
            self.fail("rod_diameter_m", f"must be smaller than bore_m = {self.bore_m}")
        if (self.kind != "single_acting" and self.kind != "piston_cable"
                and self.rod_diameter_m == 0):
            self.fail("rod_diameter_m", "a double_acting (single-rod) cylinder needs a rod > 0")

    # -- derived geometry -----------------------------------------------------------------
    @property
    def area_a_m2(self) -> float:
        """Piston area on side a, ``π/4 (D² − d_a²)`` (:func:`~.geometry.annulus_area_m2`):
        the cable's side for a piston-cable cylinder, the full bore otherwise."""
        inner = self.rod_diameter_m if self.kind == "piston_cable" else 0.0
        return float(annulus_area_m2(self.bore_m, inner))

    @property
    def area_b_m2(self) -> float:
        """Piston area on side b: the rod's or cable's side, 0 for a single-acting cylinder
        (vented)."""
        if self.kind == "single_acting":
            return 0.0
        return float(annulus_area_m2(self.bore_m, self.rod_diameter_m))

    @property
    def swept_volume_m3(self) -> float:
        """Oil displaced by a full stroke on side a, ``A_a s``."""
        return self.area_a_m2 * self.stroke_m

    @property
    def leakage_conductance_m3(self) -> float:
        """Geometric conductance of the piston's clearance, ``π D δ³ / (12 L)``
        (:func:`~afo_mj.hydraulics.laws.annular_gap_conductance_m3`)."""
        return float(laws.annular_gap_conductance_m3(self.bore_m, self.radial_clearance_m,
                                                      self.land_length_m))
