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
import math

import numpy as np

from . import laws
from .laws import (RE_LAMINAR_END, RE_TURBULENT_START, friction_factor_ratio,  # noqa: F401
                   laminar_resistance_pa_s_m3)
from .params import Parameters, effect, param
from .power import PowerFlow

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


class Hose:
    """Pressure loss, capacitance and inertance of one :class:`HoseParams` line."""

    def __init__(self, params: HoseParams):
        self.params = params
        self.area_m2 = math.pi * params.bore_m ** 2 / 4.0
        self.volume_m3 = self.area_m2 * params.length_m
        self.relative_roughness = params.roughness_m / params.bore_m

    def reynolds(self, flow_m3_s, kinematic_viscosity_m2_s):
        """``Re = |v| D / ν`` with ``v = Q / A`` (:func:`~afo_mj.hydraulics.laws.
        pipe_reynolds_number` with ``μ/ρ = ν``)."""
        return laws.pipe_reynolds_number(np.asarray(flow_m3_s, dtype=float), self.params.bore_m,
                                         kinematic_viscosity_m2_s, 1.0)

    def pressure_loss_pa(self, flow_m3_s, density_kg_m3, kinematic_viscosity_m2_s):
        """Δp from inlet to outlet for flow ``Q`` (same sign as Q): ``Δp = R_lam Q φ(Re)``
        (:func:`~afo_mj.hydraulics.laws.hose_pressure_loss_pa`)."""
        hp = self.params
        mu = np.asarray(density_kg_m3, dtype=float) * kinematic_viscosity_m2_s
        return laws.hose_pressure_loss_pa(np.asarray(flow_m3_s, dtype=float), hp.length_m,
                                          hp.bore_m, mu, density_kg_m3, self.relative_roughness,
                                          float(hp.turbulence_enabled))

    def flow_m3_s(self, dp_pa, density_kg_m3, kinematic_viscosity_m2_s):
        """Flow for a pressure drop ``Δp`` from inlet to outlet: the inverse of
        :meth:`pressure_loss_pa` (:func:`~afo_mj.hydraulics.laws.hose_flow_m3_s`)."""
        hp = self.params
        mu = np.asarray(density_kg_m3, dtype=float) * kinematic_viscosity_m2_s
        return laws.hose_flow_m3_s(np.asarray(dp_pa, dtype=float), hp.length_m, hp.bore_m, mu,
                                   density_kg_m3, self.relative_roughness,
                                   float(hp.turbulence_enabled))

    def capacitance_m3_pa(self, fluid_bulk_modulus_pa):
        """Lumped hydraulic capacitance ``C = V (1/B + 1/K_wall)`` (wall term if enabled;
        :func:`~afo_mj.hydraulics.laws.node_capacitance_m3_pa`)."""
        return laws.node_capacitance_m3_pa(self.volume_m3,
                                           np.asarray(fluid_bulk_modulus_pa, dtype=float),
                                           self.volume_m3, self.wall_compliance_inv_pa)

    @property
    def wall_compliance_inv_pa(self) -> float:
        """``1/K_wall`` with the wall compliance enabled, else 0 (a rigid wall)."""
        p = self.params
        return 1.0 / p.wall_bulk_modulus_pa if p.wall_compliance_enabled else 0.0

    @property
    def inertance_kg_m4(self) -> float:
        """``I = ρ L / A`` per unit density: multiply by density (kg/m³) to get Pa s²/m³."""
        return self.params.length_m / self.area_m2

    def power(self, p_in_pa, p_out_pa, flow_m3_s) -> PowerFlow:
        """Hydraulic power through the line; the pressure drop is dissipated as heat.

        ``in = p_in Q``, ``out = p_out Q``, ``heat = (p_in - p_out) Q`` (>= 0 for a resistive
        line; with inertance the difference also holds the column's kinetic power, passed as
        stored).
        """
        p_in = np.asarray(p_in_pa, dtype=float)
        p_out = np.asarray(p_out_pa, dtype=float)
        return PowerFlow(p_in * flow_m3_s, p_out * flow_m3_s, (p_in - p_out) * flow_m3_s, 0.0)
