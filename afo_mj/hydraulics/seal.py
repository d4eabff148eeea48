"""O-ring seal friction and leakage for small cylinders (seed §2.3).

Coulomb level (seed eqs. 2.6–2.7, Xia & Durfee 2014)
-----------------------------------------------------
Squeeze ratio ``λ = (d − W)/d`` with ``d`` the O-ring cross-section and ``W`` the gland depth
(seed eq. 2.6); 8–16 % is recommended for dynamic seals. The seed's friction model grows with the
friction coefficient, seal modulus, sliding diameter, cross-section and squeeze and is independent
of pressure (validated on 4, 6 and 9 mm bores). The extracted text of eq. 2.7 is garbled; we use

    F_C = k · μ_f · E · π · D · d · λ^(3/2)

the normal load per unit circumference ``E d λ^(3/2)`` being the leading term of Lindley's
O-ring compression law (Lindley 1967, J. Inst. Rubber Ind. 1:209) and ``k`` (``coulomb_scale``,
default 1) a fit factor for calibration. Example: μ_f = 0.4, E = 3.5 MPa, D = 10 mm,
d = 1.78 mm, λ = 0.12 → F_C ≈ 3.3 N.

Velocity dependence (Stribeck), ``shared/reference/facts.md`` / Simscape translational friction:

    F = √(2e)(F_brk − F_C) exp(−(v/v_St)²) v/v_St + F_C tanh(v/v_C) + f_v v,
    v_St = √2 v_brk,  v_C = v_brk/10

Optional pressure-dependent part (large-scale seals, seed ref. [48]):
``F_p = c_p |Δp_sealed| tanh(v/v_C)``, ``|Δp|`` rounded to ``√(Δp² + (10 kPa)²)``.

The equations are the laws :func:`~afo_mj.hydraulics.laws.oring_coulomb_force_n`,
:func:`~afo_mj.hydraulics.laws.seal_friction_n` and
:func:`~afo_mj.hydraulics.laws.seal_dragout_flow_m3_s`.

Leakage (seed eq. 2.8 depends on surface speed and contact pressure; its extracted constants are
unreadable). We use inverse hydrodynamic lubrication theory (Müller & Nau, *Fluid Sealing
Technology*, 1998): film thickness left on the rod ``h = √(8 μ |v| / (9 w))`` with ``w`` the
maximum contact-pressure gradient, estimated from a Hertz line contact of the squeezed
cross-section (``w ≈ σ_m / a``). The drag-out flow is ``Q = π D h v / 2``. The seed finds it
negligible at small scale; it is off by default (``leakage_enabled``).
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from . import laws
from .params import ParameterError, Parameters, effect, param
from .power import PowerFlow


@dataclasses.dataclass(frozen=True)
class OringSealParams(Parameters):
    """A dynamic O-ring on a piston or cable/rod."""

    cross_section_m: float = param(1.78e-3, unit="m", lo=0.0, hi=0.02, lo_open=True,
                                   doc="O-ring cross-section diameter d")
    squeeze_ratio: float = param(0.12, unit="-", lo=0.0, hi=0.4, lo_open=True,
                                 doc="radial squeeze λ = (d - W)/d; 0.08-0.16 recommended")
    friction_coefficient: float = param(0.4, unit="-", lo=0.0, hi=1.5,
                                        doc="μ_f, nitrile on smooth lubricated metal 0.3-0.5")
    elastic_modulus_pa: float = param(3.5e6, unit="Pa", lo=1e5, hi=1e9,
                                      doc="seal material modulus (nitrile ≈ 3.5 MPa)")
    coulomb_scale: float = param(1.0, unit="-", lo=0.0, hi=20.0,
                                 doc="fit factor on the eq. 2.7 Coulomb level")
    breakaway_ratio: float = param(1.5, unit="-", lo=1.0, hi=10.0,
                                   doc="breakaway / Coulomb force F_brk/F_C")
    breakaway_velocity_m_s: float = param(0.005, unit="m/s", lo=0.0, hi=1.0, lo_open=True,
                                          doc="velocity of peak (breakaway) friction v_brk")
    viscous_coefficient_n_s_m: float = param(5.0, unit="N s/m", lo=0.0, hi=1e5,
                                             doc="viscous friction f_v")
    pressure_coefficient_m2: float = param(0.0, unit="m^2", lo=0.0, hi=1e-2,
                                           doc="pressure-dependent friction c_p (N per Pa)")
    stribeck_enabled: bool = effect(True, doc="breakaway peak at low speed (Stribeck)")
    viscous_enabled: bool = effect(True, doc="friction rising with speed")
    pressure_friction_enabled: bool = effect(False, doc="friction growing with sealed pressure")
    leakage_enabled: bool = effect(False, doc="drag-out film leakage (seed eq. 2.8, negligible)")


def seal_law_args(params: OringSealParams, sliding_diameter_m, cross_section_m=None) -> tuple:
    """The arguments ``(F_C, g_St, v_St, v_C, f_v, c_p)`` of
    :func:`~afo_mj.hydraulics.laws.seal_friction_n` for one seal of ``params`` sliding on
    ``sliding_diameter_m`` (arrays broadcast; ``cross_section_m`` replaces the parameters' own,
    e.g. a piston ring chosen by bore). The module docstring's Stribeck form:
    ``F_C`` from :func:`~afo_mj.hydraulics.laws.oring_coulomb_force_n` (seed eq. 2.7),
    ``g_St = √(2e)(F_brk − F_C)`` with ``F_brk = ratio · F_C``, ``v_St = √2 v_brk``,
    ``v_C = v_brk/10``; each switched-off effect contributes 0.

    Example (defaults, D = 10 mm): ``F_C`` = 3.25 N, ``g_St`` = 3.79 N, ``v_St`` = 7.07 mm/s.
    """
    p = params
    cs = p.cross_section_m if cross_section_m is None else cross_section_m
    fc = laws.oring_coulomb_force_n(sliding_diameter_m, cs, p.squeeze_ratio,
                                    p.friction_coefficient, p.elastic_modulus_pa,
                                    p.coulomb_scale)
    breakaway = p.breakaway_ratio * fc
    gain = math.sqrt(2.0 * math.e) * (breakaway - fc) if p.stribeck_enabled else 0.0
    return (fc, gain, math.sqrt(2.0) * p.breakaway_velocity_m_s,
            p.breakaway_velocity_m_s / 10.0,
            p.viscous_coefficient_n_s_m if p.viscous_enabled else 0.0,
            p.pressure_coefficient_m2 if p.pressure_friction_enabled else 0.0)


def cylinder_seal_law_args(piston: tuple, rod: tuple, rods) -> tuple:
    """:func:`seal_law_args` of one piston seal plus ``rods`` rod or cable seals that slide at
    the piston's speed, lumped into one argument set of
    :func:`~afo_mj.hydraulics.laws.seal_friction_n`: the forces and coefficients add, the
    characteristic speeds are the piston seal's."""
    return (piston[0] + rods * rod[0], piston[1] + rods * rod[1], piston[2], piston[3],
            piston[4] + rods * rod[4], piston[5] + rods * rod[5])


class OringSeal:
    """Friction force, heat and leakage of one :class:`OringSealParams` seal sliding on a
    surface of diameter ``sliding_diameter_m`` (the bore for a piston seal, the rod or cable for
    a rod seal; the cylinder supplies it)."""

    def __init__(self, params: OringSealParams, sliding_diameter_m: float):
        if not sliding_diameter_m > 0:
            raise ParameterError(f"OringSeal sliding_diameter_m = {sliding_diameter_m!r}; "
                                 "allowed: > 0 [m]")
        p = self.params = params
        self.sliding_diameter_m = float(sliding_diameter_m)
        fc, gain, self._v_st, self._v_c, self._fv, self._cp = seal_law_args(
            p, self.sliding_diameter_m)
        self.coulomb_force_n = float(fc)
        self.breakaway_force_n = p.breakaway_ratio * self.coulomb_force_n
        self._stribeck_gain = float(gain)
        # Hertz line contact of the squeezed cross-section (per unit circumference):
        # load w = E d λ^1.5, effective modulus E* = E/(1-ν²) with ν = 0.5,
        # half-width a = sqrt(4 w R / (π E*)), R = d/2, peak pressure σ_m = 2 w / (π a).
        load_n_m = p.elastic_modulus_pa * p.cross_section_m * p.squeeze_ratio ** 1.5
        e_star = p.elastic_modulus_pa / 0.75
        self.contact_half_width_m = math.sqrt(4.0 * load_n_m * p.cross_section_m / 2.0
                                              / (math.pi * e_star))
        self.peak_contact_pressure_pa = 2.0 * load_n_m / (math.pi * self.contact_half_width_m)

    def friction_force_n(self, velocity_m_s, sealed_dp_pa=0.0):
        """Friction opposing ``velocity_m_s`` (returned with the sign of the velocity): the
        law :func:`~afo_mj.hydraulics.laws.seal_friction_n` (its pressure part with ``|Δp|``
        rounded over 10 kPa)."""
        return laws.seal_friction_n(np.asarray(velocity_m_s, dtype=float),
                                    np.asarray(sealed_dp_pa, dtype=float), self.coulomb_force_n,
                                    self._stribeck_gain, self._v_st, self._v_c, self._fv,
                                    self._cp)

    def leakage_m3_s(self, velocity_m_s, dynamic_viscosity_pa_s):
        """Drag-out film flow ``π D h v / 2`` with ``h = √(8 μ |v| a / (9 σ_m))`` (0 if disabled;
        :func:`~afo_mj.hydraulics.laws.seal_dragout_flow_m3_s` with the pressure gradient
        ``σ_m / a``).

        Positive in the direction of motion.
        """
        v = np.asarray(velocity_m_s, dtype=float)
        if not self.params.leakage_enabled:
            return np.zeros_like(v)
        return laws.seal_dragout_flow_m3_s(v, dynamic_viscosity_pa_s, self.sliding_diameter_m,
                                           self.peak_contact_pressure_pa
                                           / self.contact_half_width_m)

    def power(self, velocity_m_s, sealed_dp_pa=0.0) -> PowerFlow:
        """All friction power turns into heat: ``in = F v``, ``out = 0``, ``heat = F v >= 0``."""
        pw = self.friction_force_n(velocity_m_s, sealed_dp_pa) * velocity_m_s
        return PowerFlow(pw, 0.0, pw, 0.0)
