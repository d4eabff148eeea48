"""Hydraulic fluid: density, viscosity–temperature law, effective bulk modulus, pressure floor.

Pressures in this library are **absolute** (Pa) unless a name says ``gauge``; the atmosphere is
:data:`ATMOSPHERIC_PRESSURE_PA`. Temperatures are in K.

Sources
-------
* Walther's equation / ASTM D341: ``log10(log10(nu + a)) = b - c*log10(T)``, ``nu`` in cSt
  (mm²/s), ``T`` in K, ``a = 0.7`` (seed eq. 2.3; ASTM D341-20).
* Effective bulk modulus with entrained air, seed eq. 2.5 (same form in Simscape's
  isothermal/polytropic liquid):
  ``B = B_L (1 + α (p_a/p)^(1/n)) / (1 + α p_a^(1/n) B_L / (n p^((n+1)/n)))``.
* Oil presets from published datasheet points (viscosity at 40 °C and 100 °C, ISO 3448 grade
  midpoints and a typical viscosity index ~100); the VG 46 density is the commercial figure in
  ``shared/reference/facts.md`` (879 kg/m³ at 15 °C).

The equations themselves are the compiled laws of :mod:`afo_mj.hydraulics.laws`
(``walther_viscosity_m2_s``, ``oil_density_kg_m3``, ``dynamic_viscosity_pa_s``,
``bulk_modulus_pa``, ``cavitation_factor``), which the simulated circuits and the design tool
evaluate too; this module holds the oil's parameters and evaluates the laws for them.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from . import laws
from .laws import walther_viscosity_m2_s
from .params import Parameters, ParameterError, effect, param

ATMOSPHERIC_PRESSURE_PA = 101_325.0
WALTHER_A_CST = 0.7
#: Walther's ``log10(log10(nu + a))`` (nu in cSt) is defined for ``nu + a > 1``: a datasheet
#: viscosity must exceed ``1 - a`` = 0.3 cSt (thinner than any hydraulic oil)
WALTHER_MIN_M2_S = (1.0 - WALTHER_A_CST) * 1e-6
CELSIUS_ZERO_K = 273.15


def walther_coefficients(t1_k: float, nu1_m2_s: float, t2_k: float, nu2_m2_s: float,
                         a_cst: float = WALTHER_A_CST) -> tuple[float, float]:
    """Walther/ASTM D341 constants ``(b, c)`` through two measured viscosity points.

    Solves ``log10(log10(nu_i + a)) = b - c log10(T_i)`` (nu in cSt) for ``i = 1, 2``.

    Example: ISO VG 46 datasheet, 46 cSt at 40 °C and 6.7 cSt at 100 °C:
    ``walther_coefficients(313.15, 46e-6, 373.15, 6.7e-6)`` → ``(9.513, 3.7225)``.
    """
    if not (t1_k > 0 and t2_k > 0 and t1_k != t2_k and nu1_m2_s > 0 and nu2_m2_s > 0):
        raise ParameterError(
            f"walther_coefficients needs two distinct positive temperatures and positive "
            f"viscosities; got T=({t1_k}, {t2_k}) K, nu=({nu1_m2_s}, {nu2_m2_s}) m²/s")
    y1 = math.log10(math.log10(nu1_m2_s * 1e6 + a_cst))
    y2 = math.log10(math.log10(nu2_m2_s * 1e6 + a_cst))
    x1, x2 = math.log10(t1_k), math.log10(t2_k)
    c = (y1 - y2) / (x2 - x1)
    b = y1 + c * x1
    return b, c


def effective_bulk_modulus_pa(pressure_pa, liquid_bulk_modulus_pa: float, air_fraction: float,
                              polytropic_index: float,
                              atmospheric_pressure_pa: float = ATMOSPHERIC_PRESSURE_PA):
    """Effective bulk modulus of a liquid with entrained air, seed eq. 2.5.

    ``B = B_L (1 + α (p_a/p)^(1/n)) / (1 + α p_a^(1/n) B_L / (n p^((n+1)/n)))``

    with ``p`` absolute pressure, ``α`` the gas volume fraction at ``p_a``, ``n`` the polytropic
    index (1 isothermal … 1.4 adiabatic). With ``α = 0`` it is ``B_L``. Evaluates the law
    :func:`afo_mj.hydraulics.laws.bulk_modulus_pa` (atmospheric pressure defaulted).

    Example (``B_L`` = 1.5 GPa, ``α`` = 0.01, ``n`` = 1.4): 0.49 GPa at 1 MPa abs, 1.14 GPa at
    3 MPa abs, 1.40 GPa at 7 MPa abs (``shared/reference/facts.md``).
    """
    return laws.bulk_modulus_pa(np.asarray(pressure_pa, dtype=float), liquid_bulk_modulus_pa,
                                air_fraction, polytropic_index, atmospheric_pressure_pa)


@dataclasses.dataclass(frozen=True)
class FluidParams(Parameters):
    """A hydraulic mineral oil. Viscosity follows Walther's law through two datasheet points."""

    name: str = "ISO VG 46 mineral oil"
    density_kg_m3: float = param(879.0, unit="kg/m^3", lo=500.0, hi=2000.0,
                                 doc="density at reference temperature and atmospheric pressure")
    reference_temperature_k: float = param(288.15, unit="K", lo=200.0, hi=450.0,
                                           doc="temperature at which density_kg_m3 holds")
    thermal_expansion_per_k: float = param(7.0e-4, unit="1/K", lo=0.0, hi=2e-3,
                                           doc="volumetric thermal expansion coefficient")
    viscosity_low_m2_s: float = param(46.0e-6, unit="m^2/s", lo=WALTHER_MIN_M2_S, hi=1e-2,
                                      lo_open=True,
                                      doc="kinematic viscosity at viscosity_low_temperature_k "
                                          "(Walther's law holds above 0.3 cSt)")
    viscosity_low_temperature_k: float = param(313.15, unit="K", lo=200.0, hi=450.0)
    viscosity_high_m2_s: float = param(6.7e-6, unit="m^2/s", lo=WALTHER_MIN_M2_S, hi=1e-2,
                                       lo_open=True,
                                       doc="kinematic viscosity at viscosity_high_temperature_k "
                                           "(Walther's law holds above 0.3 cSt)")
    viscosity_high_temperature_k: float = param(373.15, unit="K", lo=200.0, hi=450.0)
    liquid_bulk_modulus_pa: float = param(1.5e9, unit="Pa", lo=1e8, hi=5e9,
                                          doc="bulk modulus of the air-free liquid (B_L)")
    air_fraction: float = param(0.005, unit="-", lo=0.0, hi=1.0, hi_open=True,
                                doc="entrained gas volume fraction at atmospheric pressure (α)")
    polytropic_index: float = param(1.4, unit="-", lo=1.0, hi=1.4,
                                    doc="polytropic index of the entrained air (n)")
    specific_heat_j_kg_k: float = param(1900.0, unit="J/(kg K)", lo=500.0, hi=5000.0)
    pressure_floor_pa: float = param(2.0e3, unit="Pa", lo=0.0, hi=ATMOSPHERIC_PRESSURE_PA,
                                     lo_open=True,
                                     doc="absolute pressure below which the liquid cavitates "
                                         "(vapour/gas release); states are kept above it")
    cavitation_band_pa: float = param(2.0e4, unit="Pa", lo=1.0, hi=1e6,
                                      doc="width above the floor over which the cavitation "
                                          "rule softens the fluid")
    entrained_air_enabled: bool = effect(True,
                                         doc="entrained air lowers the bulk modulus (eq. 2.5)")

    def check(self) -> None:
        if self.viscosity_low_temperature_k >= self.viscosity_high_temperature_k:
            self.fail("viscosity_low_temperature_k",
                      f"must be below viscosity_high_temperature_k = "
                      f"{self.viscosity_high_temperature_k}")
        if self.viscosity_low_m2_s <= self.viscosity_high_m2_s:
            self.fail("viscosity_low_m2_s", "oil viscosity must fall with temperature: must exceed "
                      f"viscosity_high_m2_s = {self.viscosity_high_m2_s}")


#: ISO VG 46 (commercial datasheet: 879 kg/m³ at 15 °C; 46 / 6.7 cSt at 40 / 100 °C).
ISO_VG46 = FluidParams()
#: ISO VG 32 (typical datasheet: 875 kg/m³ at 15 °C; 32 / 5.4 cSt at 40 / 100 °C, VI ≈ 100).
ISO_VG32 = FluidParams(name="ISO VG 32 mineral oil", density_kg_m3=875.0,
                       viscosity_low_m2_s=32.0e-6, viscosity_high_m2_s=5.4e-6)
#: ISO VG 22 (typical datasheet: 865 kg/m³ at 15 °C; 22 / 4.3 cSt at 40 / 100 °C).
ISO_VG22 = FluidParams(name="ISO VG 22 mineral oil", density_kg_m3=865.0,
                       viscosity_low_m2_s=22.0e-6, viscosity_high_m2_s=4.3e-6)

FLUID_PRESETS = {"ISO_VG22": ISO_VG22, "ISO_VG32": ISO_VG32, "ISO_VG46": ISO_VG46}
#: presets by name, so a dotted override can pick one (``device.params.fluid = "ISO_VG22"``)
FluidParams.PRESETS = FLUID_PRESETS


class Fluid:
    """Property evaluator for one :class:`FluidParams` (vectorised over numpy arrays)."""

    def __init__(self, params: FluidParams = ISO_VG46):
        self.params = params
        self.walther_b, self.walther_c = walther_coefficients(
            params.viscosity_low_temperature_k, params.viscosity_low_m2_s,
            params.viscosity_high_temperature_k, params.viscosity_high_m2_s)

    def kinematic_viscosity_m2_s(self, temperature_k):
        """Walther/ASTM D341 viscosity at ``temperature_k`` (see :func:`walther_viscosity_m2_s`)."""
        return walther_viscosity_m2_s(np.asarray(temperature_k, dtype=float), self.walther_b,
                                      self.walther_c)

    def density_kg_m3(self, pressure_pa=ATMOSPHERIC_PRESSURE_PA, temperature_k=None):
        """Equation of state ``ρ = ρ_T(T) (1 + (p − p_a)/B_L)``: the thermal law
        :func:`afo_mj.hydraulics.laws.oil_density_kg_m3` (``ρ_0/(1 + β (T − T_0))``, mass
        conserved as the volume grows by ``1 + β ΔT``) with the liquid's linearised
        compressibility."""
        p = self.params
        t = p.reference_temperature_k if temperature_k is None else temperature_k
        rho_t = laws.oil_density_kg_m3(np.asarray(t, dtype=float), p.density_kg_m3,
                                       p.thermal_expansion_per_k, p.reference_temperature_k)
        return rho_t * (1.0 + (np.asarray(pressure_pa) - ATMOSPHERIC_PRESSURE_PA)
                        / p.liquid_bulk_modulus_pa)

    def dynamic_viscosity_pa_s(self, temperature_k):
        """``μ = ρ(T) ν(T)`` at atmospheric pressure
        (:func:`afo_mj.hydraulics.laws.dynamic_viscosity_pa_s`)."""
        p = self.params
        return laws.dynamic_viscosity_pa_s(np.asarray(temperature_k, dtype=float), self.walther_b,
                                           self.walther_c, p.density_kg_m3,
                                           p.thermal_expansion_per_k, p.reference_temperature_k)

    def bulk_modulus_pa(self, pressure_pa):
        """Effective bulk modulus for the continuity equation: eq. 2.5 (if entrained air is
        enabled) times the cavitation factor of :meth:`cavitation_factor`."""
        p = self.params
        alpha = p.air_fraction if p.entrained_air_enabled else 0.0
        pf = np.maximum(np.asarray(pressure_pa, dtype=float), p.pressure_floor_pa)
        return effective_bulk_modulus_pa(pf, p.liquid_bulk_modulus_pa, alpha,
                                         p.polytropic_index) * self.cavitation_factor(pressure_pa)

    def cavitation_factor(self, pressure_pa):
        """Pressure-floor rule: a smooth factor in (0, 1] on the bulk modulus.

        Above ``floor + band`` it is 1. Between the floor and ``floor + band`` it falls as a
        cubic smoothstep to a small residual (1e-4), so that a chamber whose volume grows with
        no inflow (a cavitating suction side) changes pressure slowly and stops near the floor
        instead of going negative. This stands for vapour and gas release, which hold the
        pressure near the floor while the void grows (the usual lumped cavitation rule of
        system simulators such as Hopsan and Simscape). States below the floor are clamped by
        :meth:`clamp_pressure`.
        """
        p = self.params
        return laws.cavitation_factor(np.asarray(pressure_pa, dtype=float), p.pressure_floor_pa,
                                      p.cavitation_band_pa)

    def clamp_pressure(self, pressure_pa):
        """Pressures held at or above the floor: returns ``(clamped, n_clamped)``."""
        p = np.asarray(pressure_pa, dtype=float)
        low = p < self.params.pressure_floor_pa
        return np.where(low, self.params.pressure_floor_pa, p), int(np.count_nonzero(low))

    def compression_energy_density_j_m3(self, pressure_pa, n_points: int = 64):
        """Energy stored per unit volume when compressing from atmosphere to ``pressure_pa``:
        ``e(p) = ∫_{p_a}^{p} p'/B(p') dp'`` (from ``dV = -V dp / B``), trapezoidal in p."""
        p = np.asarray(pressure_pa, dtype=float)
        s = np.linspace(0.0, 1.0, n_points).reshape((-1,) + (1,) * p.ndim)
        pp = ATMOSPHERIC_PRESSURE_PA + s * (p - ATMOSPHERIC_PRESSURE_PA)
        integrand = pp / self.bulk_modulus_pa(pp)
        return np.trapezoid(integrand, pp, axis=0)
