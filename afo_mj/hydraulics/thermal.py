"""Lumped thermal-resistance network (thermal RC network) and convection helpers.

Each node ``i`` is an isothermal lump of heat capacity ``C_i`` (J/K) at temperature ``T_i``
(K), heated by ``Q_i`` (W, the losses of the components it holds). Nodes exchange heat with
each other and with the ambient through thermal resistances ``R`` (K/W). The node equations
(Incropera et al., *Fundamentals of Heat and Mass Transfer*, 7th ed., §3.1 and §5.2 lumped
capacitance; the same network form as Simscape's thermal library):

    C dT/dt = Q − G T + g_amb T_amb

with the conductance (Laplacian) matrix ``G`` — ``G_ii`` the sum of the conductances ``1/R``
at node ``i`` (those to the ambient included), ``G_ij = −1/R_ij`` — and ``g_amb,i`` the
conductance from node ``i`` to the ambient. The steady state solves ``G T = Q + g_amb T_amb``;
for constant ``Q`` the solution is exact with a matrix exponential
(:meth:`ThermalNetwork.advance_k`).

Every node must be connected, directly or through other nodes, to the ambient; otherwise its
heat has no way out and no steady state exists (``ParameterError`` at construction).

Convection helpers: :func:`convection_resistance_k_w` (``1/(h A)``), :func:`air_properties`
(dry air at 1 atm) and :func:`natural_convection_h_cylinder` (Churchill–Chu correlation).
"""

from __future__ import annotations

import dataclasses
import math
from typing import NamedTuple

import numpy as np

from .fluid import ATMOSPHERIC_PRESSURE_PA
from .params import Parameters, param
from .power import PowerFlow

__all__ = [
    "AMBIENT",
    "ThermalNodeParams",
    "ThermalNetworkParams",
    "ThermalNetwork",
    "fluid_only",
    "convection_resistance_k_w",
    "AirProperties",
    "air_properties",
    "natural_convection_h_cylinder",
    "STANDARD_GRAVITY_M_S2",
]

#: Name of the ambient (fixed-temperature) end of a resistance.
AMBIENT = "ambient"
STANDARD_GRAVITY_M_S2 = 9.80665
AIR_GAS_CONSTANT_J_KG_K = 287.05
AIR_SPECIFIC_HEAT_J_KG_K = 1007.0


@dataclasses.dataclass(frozen=True)
class ThermalNodeParams(Parameters):
    """One isothermal lump. Default: about 0.2 kg of oil (0.2 kg · 1900 J/(kg K) ≈ 400 J/K)."""

    name: str = "fluid"
    heat_capacity_j_k: float = param(400.0, unit="J/K", lo=0.0, hi=1e9, lo_open=True,
                                     doc="C: heat capacity of the lump (mass · specific heat)")
    initial_temperature_k: float = param(298.15, unit="K", lo=150.0, hi=1000.0)

    def check(self) -> None:
        if not isinstance(self.name, str) or not self.name:
            self.fail("name", "must be a non-empty string")
        if self.name == AMBIENT:
            self.fail("name", f"{AMBIENT!r} is reserved for the ambient end of a resistance")


@dataclasses.dataclass(frozen=True)
class ThermalNetworkParams(Parameters):
    """Nodes and the thermal resistances ``(node_a, node_b or 'ambient', R_k_w)`` between them.

    Lists given for ``nodes``/``resistances`` are stored as tuples. Default: one 400 J/K oil
    node with 5 K/W to a 298.15 K ambient (a 2000 s time constant).
    """

    ambient_temperature_k: float = param(298.15, unit="K", lo=150.0, hi=1000.0)
    nodes: tuple = (ThermalNodeParams(),)
    resistances: tuple = (("fluid", AMBIENT, 5.0),)

    def check(self) -> None:
        try:
            nodes = tuple(self.nodes)
        except TypeError:
            self.fail("nodes", "must be a sequence of ThermalNodeParams")
        if not nodes:
            self.fail("nodes", "needs at least one node")
        if not all(isinstance(n, ThermalNodeParams) for n in nodes):
            self.fail("nodes", "every node must be a ThermalNodeParams")
        names = [n.name for n in nodes]
        if len(set(names)) != len(names):
            self.fail("nodes", f"node names must be unique, got {names}")
        object.__setattr__(self, "nodes", nodes)

        links = []
        try:
            raw = tuple(self.resistances)
        except TypeError:
            self.fail("resistances", "must be a sequence of (node_a, node_b, resistance_k_w)")
        for item in raw:
            try:
                a, b, r = item
            except (TypeError, ValueError):
                self.fail("resistances", f"entry {item!r} is not (node_a, node_b, resistance_k_w)")
            if isinstance(r, bool) or not isinstance(r, (int, float)) \
                    or not math.isfinite(r) or r <= 0.0:
                self.fail("resistances", f"entry {item!r}: resistance_k_w must be a finite "
                          "number > 0 [K/W]")
            if a == AMBIENT:
                a, b = b, a
            for end in (a, b):
                if end != AMBIENT and end not in names:
                    self.fail("resistances", f"entry {item!r}: unknown node {end!r}; "
                              f"known: {names} and {AMBIENT!r}")
            if a == b:
                self.fail("resistances", f"entry {item!r} joins a node to itself")
            links.append((a, b, float(r)))
        object.__setattr__(self, "resistances", tuple(links))

        # Every node must reach the ambient (else G is singular: no steady state).
        reached = {AMBIENT}
        grown = True
        while grown:
            grown = False
            for a, b, _ in links:
                if (a in reached) != (b in reached):
                    reached.update((a, b))
                    grown = True
        isolated = [n for n in names if n not in reached]
        if isolated:
            self.fail("resistances", f"nodes {isolated} have no thermal path to {AMBIENT!r}; "
                      "their heat could not leave (no steady state)")


def fluid_only(heat_capacity_j_k: float, resistance_k_w: float, ambient_k: float,
               initial_temperature_k: float | None = None,
               name: str = "fluid") -> ThermalNetworkParams:
    """A single node (``name``) with one resistance to the ambient.

    Time constant ``R C``. Example: ``fluid_only(400.0, 5.0, 298.15)`` — 2000 s, and a 10 W
    loss settles 50 K above ambient.
    """
    t0 = ambient_k if initial_temperature_k is None else initial_temperature_k
    node = ThermalNodeParams(name=name, heat_capacity_j_k=heat_capacity_j_k,
                             initial_temperature_k=t0)
    return ThermalNetworkParams(ambient_temperature_k=ambient_k, nodes=(node,),
                                resistances=((name, AMBIENT, resistance_k_w),))


class ThermalNetwork:
    """Node equations of a :class:`ThermalNetworkParams` network.

    Temperature and heat arrays have the node axis first: shape ``(n,)`` or ``(n, k)`` for a
    batch of ``k`` states; node ``i`` is ``params.nodes[i]`` (see :meth:`index`).
    """

    def __init__(self, params: ThermalNetworkParams = ThermalNetworkParams()):
        self.params = params
        self.names = tuple(n.name for n in params.nodes)
        self._index = {name: i for i, name in enumerate(self.names)}
        n, m = len(self.names), len(params.resistances)
        self.heat_capacity_j_k = np.array([nd.heat_capacity_j_k for nd in params.nodes])
        self.initial_temperatures_k = np.array([nd.initial_temperature_k for nd in params.nodes])
        g = np.zeros((n, n))
        g_amb = np.zeros(n)
        incidence = np.zeros((m, n))
        to_ambient = np.zeros(m)
        resistance = np.zeros(m)
        for j, (a, b, r) in enumerate(params.resistances):
            ia = self._index[a]
            incidence[j, ia] = 1.0
            resistance[j] = r
            g[ia, ia] += 1.0 / r
            if b == AMBIENT:
                g_amb[ia] += 1.0 / r
                to_ambient[j] = 1.0
            else:
                ib = self._index[b]
                incidence[j, ib] = -1.0
                g[ib, ib] += 1.0 / r
                g[ia, ib] -= 1.0 / r
                g[ib, ia] -= 1.0 / r
        #: Conductance (Laplacian) matrix ``G`` (W/K), ambient links on the diagonal.
        self.conductance_w_k = g
        #: Conductance from each node straight to the ambient (W/K).
        self.ambient_conductance_w_k = g_amb
        self._incidence, self._to_ambient, self._resistance = incidence, to_ambient, resistance
        # Symmetric form S = C^-1/2 G C^-1/2 = V diag(lam) V^T for exact stepping.
        s = 1.0 / np.sqrt(self.heat_capacity_j_k)
        self._sqrt_c = np.sqrt(self.heat_capacity_j_k)
        self._eigval, self._eigvec = np.linalg.eigh(s[:, None] * g * s[None, :])
        #: Time constants ``1/λ`` of the network (s), longest first.
        self.time_constants_s = np.sort(1.0 / self._eigval)[::-1]

    def index(self, name: str) -> int:
        """Position of node ``name`` along the node axis."""
        return self._index[name]

    @staticmethod
    def _col(v: np.ndarray, ndim: int) -> np.ndarray:
        return v.reshape(v.shape + (1,) * (ndim - 1))

    def _heat(self, heat_inputs_w, ndim: int) -> np.ndarray:
        q = np.asarray(heat_inputs_w, dtype=float)
        if q.ndim == 0:
            q = np.full(len(self.names), float(q))
        return q.reshape(q.shape + (1,) * max(ndim - q.ndim, 0))

    def temperature_rates_k_s(self, temperatures_k, heat_inputs_w):
        """``dT/dt = C⁻¹ (Q − G T + g_amb T_amb)``.

        ``temperatures_k``: shape ``(n,)`` or ``(n, k)``; ``heat_inputs_w`` the same shape,
        or ``(n,)`` (same heat for the whole batch), or a scalar (same for every node).

        Example (default single node, 400 J/K, 5 K/W, at ambient, 10 W): ``0.025`` K/s.
        """
        t = np.asarray(temperatures_k, dtype=float)
        q = self._heat(heat_inputs_w, t.ndim)
        amb = self._col(self.ambient_conductance_w_k, t.ndim) * self.params.ambient_temperature_k
        return (q - self.conductance_w_k @ t + amb) / self._col(self.heat_capacity_j_k, t.ndim)

    def steady_state_k(self, heat_inputs_w):
        """Temperatures with constant heat inputs at equilibrium: ``G T = Q + g_amb T_amb``.

        ``heat_inputs_w`` shape ``(n,)`` or ``(n, k)`` (or a scalar for every node).

        Example (default): 10 W → ``298.15 + 10·5 = 348.15`` K.
        """
        q = np.asarray(heat_inputs_w, dtype=float)
        q = self._heat(q, max(q.ndim, 1))
        g_amb = self._col(self.ambient_conductance_w_k, q.ndim)
        rhs = q + g_amb * self.params.ambient_temperature_k
        return np.linalg.solve(self.conductance_w_k, rhs)

    def advance_k(self, temperatures_k, heat_inputs_w, dt_s: float):
        """Exact temperatures after ``dt_s`` with the heat inputs held constant:
        ``T(t+dt) = T_ss + exp(−C⁻¹G dt) (T − T_ss)``, evaluated through the symmetric
        eigen-decomposition of ``C^-½ G C^-½`` (stable for any ``dt_s``).

        Example (default, from ambient, 10 W, dt = R C = 2000 s): ``348.15 − 50/e`` = 329.76 K.
        """
        t = np.asarray(temperatures_k, dtype=float)
        q = self._heat(heat_inputs_w, t.ndim)
        if q.shape != t.shape:
            q = np.broadcast_to(q, t.shape)
        t_ss = self.steady_state_k(q)
        sc = self._col(self._sqrt_c, t.ndim)
        y = self._eigvec.T @ (sc * (t - t_ss))
        y = self._col(np.exp(-self._eigval * float(dt_s)), t.ndim) * y
        return t_ss + (self._eigvec @ y) / sc

    def heat_to_ambient_w(self, temperatures_k):
        """Total heat leaving to the ambient, ``Σ_i g_amb,i (T_i − T_amb)`` (W); shape ``()``
        or ``(k,)``."""
        t = np.asarray(temperatures_k, dtype=float)
        g = self._col(self.ambient_conductance_w_k, t.ndim)
        return np.sum(g * (t - self.params.ambient_temperature_k), axis=0)

    def link_heat_flows_w(self, temperatures_k):
        """Heat through each resistance, ``(T_a − T_b)/R`` from ``node_a`` to ``node_b``, in the
        order of ``params.resistances``; shape ``(m,)`` or ``(m, k)``."""
        t = np.asarray(temperatures_k, dtype=float)
        diff = self._incidence @ t - self._col(self._to_ambient, t.ndim) * \
            self.params.ambient_temperature_k
        return diff / self._col(self._resistance, t.ndim)

    def power(self, temperatures_k, heat_inputs_w) -> PowerFlow:
        """Network energy balance: ``in = Σ Q`` (losses received from the components),
        ``out`` = :meth:`heat_to_ambient_w`, ``heat = 0`` (no new dissipation inside),
        ``stored = Σ C dT/dt``."""
        t = np.asarray(temperatures_k, dtype=float)
        q = np.broadcast_to(self._heat(heat_inputs_w, t.ndim), t.shape)
        rates = self.temperature_rates_k_s(t, q)
        stored = np.sum(self._col(self.heat_capacity_j_k, t.ndim) * rates, axis=0)
        out = self.heat_to_ambient_w(t)
        return PowerFlow(in_w=np.sum(q, axis=0), out_w=out, heat_w=np.zeros_like(out),
                         stored_w=stored)


def convection_resistance_k_w(area_m2, h_w_m2_k):
    """Thermal resistance of a convective surface, ``R = 1/(h A)`` (Newton's law of cooling,
    ``Q = h A (T_s − T_∞)``; Incropera §3.1.3).

    Typical ``h``: 2–25 W/(m² K) natural convection in air, 25–250 forced air (Incropera
    Table 1.1). Example: a 0.01 m² surface at 6 W/(m² K):
    ``convection_resistance_k_w(0.01, 6)`` = 16.7 K/W.
    """
    return 1.0 / (np.asarray(h_w_m2_k, dtype=float) * np.asarray(area_m2, dtype=float))


class AirProperties(NamedTuple):
    density_kg_m3: np.ndarray | float
    dynamic_viscosity_pa_s: np.ndarray | float
    thermal_conductivity_w_m_k: np.ndarray | float
    specific_heat_j_kg_k: np.ndarray | float
    kinematic_viscosity_m2_s: np.ndarray | float
    thermal_diffusivity_m2_s: np.ndarray | float
    prandtl: np.ndarray | float


def air_properties(temperature_k, pressure_pa=ATMOSPHERIC_PRESSURE_PA) -> AirProperties:
    """Dry-air properties from closed-form laws, for 200–600 K:

    * density: ideal gas ``ρ = p/(R T)``, ``R = 287.05`` J/(kg K);
    * viscosity: Sutherland, ``μ = 1.716e-5 (T/273.15)^1.5 (273.15 + 110.4)/(T + 110.4)``;
    * conductivity: Sutherland form, ``k = 0.0241 (T/273.15)^1.5 (273.15 + 194)/(T + 194)``
      (both from White, *Viscous Fluid Flow*, 3rd ed., Table 1-3);
    * specific heat constant ``c_p = 1007`` J/(kg K) (within 1 % from 250 to 400 K).

    Within about 1.5 % of Incropera Table A.4. Example at 300 K (table values in brackets):
    ρ 1.177 (1.161) kg/m³, μ 1.846e-5 (1.846e-5) Pa s, k 0.0262 (0.0263) W/(m K),
    Pr 0.709 (0.707).
    """
    t = np.asarray(temperature_k, dtype=float)
    rho = np.asarray(pressure_pa, dtype=float) / (AIR_GAS_CONSTANT_J_KG_K * t)
    tr = t / 273.15
    mu = 1.716e-5 * tr ** 1.5 * (273.15 + 110.4) / (t + 110.4)
    k = 0.0241 * tr ** 1.5 * (273.15 + 194.0) / (t + 194.0)
    cp = AIR_SPECIFIC_HEAT_J_KG_K
    return AirProperties(density_kg_m3=rho, dynamic_viscosity_pa_s=mu,
                         thermal_conductivity_w_m_k=k, specific_heat_j_kg_k=np.full_like(t, cp),
                         kinematic_viscosity_m2_s=mu / rho, thermal_diffusivity_m2_s=k / (rho * cp),
                         prandtl=mu * cp / k)


def natural_convection_h_cylinder(diameter_m, surface_temperature_k, ambient_temperature_k,
                                  pressure_pa=ATMOSPHERIC_PRESSURE_PA):
    """Mean natural-convection coefficient of a long horizontal cylinder in air (W/(m² K)).

    Churchill & Chu (1975), Int. J. Heat Mass Transfer 18, 1049; Incropera eq. 9.34, valid for
    ``Ra_D <= 1e12``:

        Nu_D = {0.60 + 0.387 Ra_D^(1/6) / [1 + (0.559/Pr)^(9/16)]^(8/27)}²,
        Ra_D = g β |T_s − T_∞| D³ / (ν α),   β = 1/T_f,   h = Nu_D k / D,

    with air properties (:func:`air_properties`) at the film temperature
    ``T_f = (T_s + T_∞)/2``. Symmetric in the sign of ``T_s − T_∞`` (a cold cylinder gains
    heat at the same rate); at zero difference it gives the conduction limit ``Nu = 0.36``.

    Example: a 30 mm cylinder at 313.15 K in 293.15 K air: ``Ra ≈ 4.9e4``, ``Nu ≈ 6.5``,
    ``h ≈ 5.7`` W/(m² K).
    """
    d = np.asarray(diameter_m, dtype=float)
    ts = np.asarray(surface_temperature_k, dtype=float)
    ta = np.asarray(ambient_temperature_k, dtype=float)
    tf = 0.5 * (ts + ta)
    air = air_properties(tf, pressure_pa)
    ra = STANDARD_GRAVITY_M_S2 / tf * np.abs(ts - ta) * d ** 3 / \
        (air.kinematic_viscosity_m2_s * air.thermal_diffusivity_m2_s)
    shape = (1.0 + (0.559 / air.prandtl) ** (9.0 / 16.0)) ** (8.0 / 27.0)
    nu = (0.60 + 0.387 * ra ** (1.0 / 6.0) / shape) ** 2
    return nu * air.thermal_conductivity_w_m_k / d
