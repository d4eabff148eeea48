"""Hoses and tubes: pressure loss (laminar → turbulent), wall compliance, fluid inertance.

Equations
---------
* Darcy–Weisbach: ``Δp = f (L/D) ρ v²/2`` with ``v = 4Q/(πD²)`` and ``Re = v D / ν``.
* Laminar (Hagen–Poiseuille): ``f = 64/Re``, i.e. ``Δp = 128 μ L Q / (π D⁴)``.
* Turbulent, smooth wall: Blasius ``f = 0.3164 Re^-0.25`` (Re < 1e5); rough wall: Haaland
  ``1/√f = -1.8 log10((ε/D/3.7)^1.11 + 6.9/Re)`` (Haaland 1983, J. Fluids Eng. 105:89).
* Transition: ``f`` blends from the laminar to the turbulent law with a cubic smoothstep over
  ``Re ∈ [2000, 4000]`` so the loss and its slope are continuous (our choice; the critical
  Reynolds number 2000 is from ``shared/reference/facts.md``).
* Hose wall compliance: the hose volume grows with pressure; the lumped capacitance of a line is
  ``C = V (1/B_fluid + 1/K_wall)`` with ``K_wall`` the hose's volumetric wall stiffness
  (``V dp / dV``). For a thin elastic tube ``K_wall = E t / D`` (Merritt 1967, §2.5); for
  braided thermoplastic hoses it is taken from the maker's volumetric expansion figure.
* Inertance: ``I = ρ L / A``, so ``Δp = I dQ/dt`` for the fluid column (Merritt 1967, §4).

The loss is written as ``Δp = R_lam Q φ(Re)`` with ``φ = f Re / 64`` (``φ = 1`` in the laminar
range), which stays finite with a finite slope at ``Q = 0``.

Each equation is a compiled law of :mod:`afo_mj.hydraulics.laws` (``laminar_resistance_pa_s_m3``,
``friction_factor_ratio``, ``pipe_reynolds_number``, ``hose_pressure_loss_pa``,
``hose_flow_m3_s``, ``node_capacitance_m3_pa``), shared with the simulated circuits and the
design tool; the first two are re-exported here.
"""

from __future__ import annotations

import dataclasses

from .laws import (RE_LAMINAR_END, RE_TURBULENT_START, friction_factor_ratio,  # noqa: F401
                   laminar_resistance_pa_s_m3)
from .geometry import annulus_area_m2
from .params import Parameters, effect, param

@dataclasses.dataclass(frozen=True)
class HoseParams(Parameters):
    """A hose or tube between two hydraulic nodes."""

    length_m: float = param(1.0, unit="m", lo=0.0, hi=50.0, lo_open=True, doc="conduit length")
    bore_m: float = param(4.0e-3, unit="m", lo=0.0, hi=0.1, lo_open=True, doc="inner diameter")
    roughness_m: float = param(0.0, unit="m", lo=0.0, hi=1e-3,
                               doc="wall roughness (0 = hydraulically smooth, Blasius)")
    wall_bulk_modulus_pa: float = param(1.0e9, unit="Pa", lo=1e6, hi=1e12,
                                        doc="volumetric wall stiffness K_wall = V dp/dV")
    wall_compliance_enabled: bool = effect(True, doc="hose wall expands with pressure")
    inertance_enabled: bool = effect(False, doc="fluid column inertance I = rho L / A")
    turbulence_enabled: bool = effect(True, doc="turbulent friction above Re 2000")

    @property
    def volume_m3(self) -> float:
        """Oil the line holds, ``π D²/4 · L`` (:func:`~.geometry.annulus_area_m2` of the bore
        times the length). Example (defaults): 4 mm, 1 m → 12.6 mL."""
        return float(annulus_area_m2(self.bore_m, 0.0)) * self.length_m
