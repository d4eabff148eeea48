"""Metabolic energy rate of a muscle: Umberger (2010) and Bhargava et al. (2004), compiled.

Both models give a muscle's rate of metabolic energy use (W) as heat plus the contractile
element's mechanical work rate, from its excitation ``u``, activation ``a``, CE length and
velocity and forces. Velocities are negative when the CE shortens. A whole-body rate adds
the basal rate, 1.2 W per kg of body mass (Umberger, Gerritsen & Martin 2003, p. 105), and
the net rate (what assistance studies report: Zhang et al. 2017, Collins et al. 2015) is
the gross rate less the standing or basal rate.

**Umberger 2010** — Umberger, "Stance and swing phase costs in human walking", J. R. Soc.
Interface 7 (2010) 1329, the 2003 model (Umberger, Gerritsen & Martin, Comput. Methods
Biomech. Biomed. Eng. 6 (2003) 99) with negative CE work counted; rates per kg of muscle,
``S = 1.5`` for aerobic work, ``f_ST`` the slow-twitch fraction, ``A = u`` when ``u > a``,
else ``(u + a)/2``:

* activation–maintenance ``Ḣ_AM = S A^0.6 (128 (1 − f_ST) + 25)`` (for ``l_CE > l_opt`` the
  part ``0.6 Ḣ_AM`` scales with the force–length factor ``f_L``);
* shortening (``v ≤ 0``, ``v`` in l_opt/s): ``Ḣ_SL = S A² [−α_ST v f_ST − α_FT v (1 − f_ST)]``,
  ``α_ST = 100/v_max,ST``, ``α_FT = 153/v_max,FT``, ``v_max,FT = v_max``,
  ``v_max,ST = v_max/2.5``, the slow-twitch term at most 100 W/kg; lengthening
  ``Ḣ_SL = S A · 4 α_ST v``; beyond ``l_opt`` the whole ``Ḣ_SL`` scales with ``f_L``;
* work ``Ẇ = −F_CE,active v_CE`` (negative work included), per kg;
* the heat ``Ḣ_AM + Ḣ_SL`` is at least 1 W/kg, and where ``Ḣ + Ẇ`` would be negative the
  shortening heat is raised so that it is zero.

**Bhargava 2004** — Bhargava, Pandy & Anderson, "A phenomenological model for estimating
metabolic energy consumption in muscle contraction", J. Biomech. 37 (2004) 81, with the
excitations of the slow and fast fibres ``u_ST = f_ST sin(π u/2)``,
``u_FT = (1 − f_ST)(1 − cos(π u/2))``:

* activation ``Ȧ = m (40 u_ST + 133 u_FT)`` (W/kg constants, decay function 1 as in
  Anderson & Pandy 1999);
* maintenance ``Ṁ = m g(l_CE/l_opt) (74 u_ST + 111 u_FT)``, ``g`` piecewise linear through
  (0, 0.5), (0.5, 0.5), (1, 1), (1.5, 0), (2, 0);
* shortening ``Ṡ = −0.25 F_CE v_CE`` while shortening, 0 lengthening (``F_CE`` the fibre
  force, active and passive);
* work ``Ẇ = −F_CE,active v_CE`` while shortening, 0 lengthening;
* the heat ``Ȧ + Ṁ + Ṡ`` is at least 1 W per kg of muscle.

Muscle masses and slow-twitch fractions: :mod:`afo_mj.human.muscle` (Song & Geyer 2015).
"""

from __future__ import annotations

import math

import numba

__all__ = ["AEROBIC_SCALE", "BASAL_W_PER_KG", "MIN_HEAT_W_PER_KG",
           "umberger2010_rate_w", "bhargava2004_rate_w", "bhargava_fibre_excitations",
           "bhargava2004_rate_from_fibres_w", "bhargava_length_factor",
           "basal_rate_w"]

#: Umberger's S for aerobic activity (2003, p. 104)
AEROBIC_SCALE = 1.5
#: basal metabolic rate per kg of body mass (Umberger et al. 2003, p. 105)
BASAL_W_PER_KG = 1.2
#: lower bound of a muscle's heat rate (Umberger et al. 2003, p. 104)
MIN_HEAT_W_PER_KG = 1.0


@numba.njit(cache=True)
def umberger2010_rate_w(u: float, a: float, l_norm: float, v_lopt_s: float,
                        f_active_n: float, f_length: float, v_max_lopt_s: float,
                        l_opt_m: float, mass_kg: float, slow_twitch: float):
    """Umberger (2010) metabolic rate of one muscle (W): ``(total, heat, work)``.

    ``u``, ``a`` excitation and activation; ``l_norm = l_CE/l_opt``; ``v_lopt_s`` the CE
    velocity in l_opt/s (negative shortening); ``f_active_n`` the CE's active force
    ``a F_max f_L f_V``; ``f_length`` the force–length factor ``f_L``; ``v_max_lopt_s`` its
    maximum shortening speed; ``mass_kg``; ``slow_twitch`` the slow-twitch fraction.

    >>> round(umberger2010_rate_w(1.0, 1.0, 1.0, 0.0, 1000.0, 1.0, 12.0, 0.05, 1.0, 0.5)[0], 3)
    133.5
    """
    A = u if u > a else 0.5 * (u + a)
    A = max(A, 0.0)
    am0 = 128.0 * (1.0 - slow_twitch) + 25.0
    a06 = math.exp(0.6 * math.log(A))                          # A^0.6 (0 at A = 0)
    if l_norm <= 1.0:
        am = AEROBIC_SCALE * a06 * am0
    else:
        am = AEROBIC_SCALE * a06 * (0.4 * am0 + 0.6 * am0 * f_length)
    # α_ST = 100/v_max,ST = 100 · 2.5/v_max, α_FT = 153/v_max,FT = 153/v_max
    inv_v_max = 1.0 / v_max_lopt_s
    a_st = 250.0 * inv_v_max
    a_ft = 153.0 * inv_v_max
    v = v_lopt_s
    if v <= 0.0:
        st = min(-a_st * v, 100.0)
        sl = AEROBIC_SCALE * A * A * (st * slow_twitch - a_ft * v * (1.0 - slow_twitch))
    else:
        sl = AEROBIC_SCALE * A * (4.0 * a_st * v)
    if l_norm > 1.0:
        sl *= f_length
    w = -max(f_active_n, 0.0) * v * l_opt_m / mass_kg
    if am + sl + w < 0.0:
        sl -= am + sl + w
    heat = max(am + sl, MIN_HEAT_W_PER_KG)
    return (heat + w) * mass_kg, heat * mass_kg, w * mass_kg


@numba.njit(cache=True)
def bhargava_length_factor(l_norm: float) -> float:
    """Bhargava's maintenance-heat dependence on the normalised fibre length: piecewise
    linear through (0, 0.5), (0.5, 0.5), (1, 1), (1.5, 0), (2, 0)."""
    if l_norm <= 0.5:
        return 0.5
    if l_norm <= 1.0:
        return 0.5 + (l_norm - 0.5)
    if l_norm <= 1.5:
        return 1.0 - 2.0 * (l_norm - 1.0)
    return 0.0


@numba.njit(cache=True)
def bhargava_fibre_excitations(u: float, slow_twitch: float):
    """Bhargava et al.'s (2004) excitations of the slow and fast fibres from the excitation
    ``u`` (clipped to [0, 1]): ``(u_ST, u_FT) = (f_ST sin(π u/2), (1 − f_ST)(1 − cos(π u/2)))``,
    from ``s = sin(π u/4)`` (one sine; its cosine ``√(1 − s²) ≥ 1/√2`` on [0, π/4]):
    ``sin(π u/2) = 2 s √(1 − s²)`` and ``1 − cos(π u/2) = 2 s²`` (no cancellation at small
    ``u``). They depend on ``u`` alone: a caller whose ``u`` holds may keep them."""
    uu = min(max(u, 0.0), 1.0)
    s4 = math.sin(0.25 * math.pi * uu)
    return (slow_twitch * (2.0 * s4 * math.sqrt(1.0 - s4 * s4)),
            (1.0 - slow_twitch) * (2.0 * s4 * s4))


@numba.njit(cache=True)
def bhargava2004_rate_from_fibres_w(u_st: float, u_ft: float, l_norm: float, v_m_s: float,
                                    f_fiber_n: float, f_active_n: float, mass_kg: float):
    """:func:`bhargava2004_rate_w` from the fibres' excitations ``u_ST``, ``u_FT``
    (:func:`bhargava_fibre_excitations`): ``(total, heat, work)`` (W)."""
    act = mass_kg * (40.0 * u_st + 133.0 * u_ft)
    main = mass_kg * bhargava_length_factor(l_norm) * (74.0 * u_st + 111.0 * u_ft)
    if v_m_s <= 0.0:
        sh = -0.25 * f_fiber_n * v_m_s
        w = -f_active_n * v_m_s
    else:
        sh = 0.0
        w = 0.0
    heat = max(act + main + sh, MIN_HEAT_W_PER_KG * mass_kg)
    return heat + w, heat, w


@numba.njit(cache=True)
def bhargava2004_rate_w(u: float, l_norm: float, v_m_s: float, f_fiber_n: float,
                        f_active_n: float, mass_kg: float, slow_twitch: float):
    """Bhargava et al. (2004) metabolic rate of one muscle (W): ``(total, heat, work)``.

    ``u`` excitation; ``l_norm = l_CE/l_opt``; ``v_m_s`` the CE velocity (m/s, negative
    shortening); ``f_fiber_n`` the fibre force (active and passive), ``f_active_n`` its active
    part; ``mass_kg``; ``slow_twitch`` the slow-twitch fraction
    (:func:`bhargava_fibre_excitations`, then :func:`bhargava2004_rate_from_fibres_w`).

    >>> round(bhargava2004_rate_w(1.0, 1.0, 0.0, 1000.0, 1000.0, 1.0, 0.5)[0], 3)
    179.0
    """
    u_st, u_ft = bhargava_fibre_excitations(u, slow_twitch)
    return bhargava2004_rate_from_fibres_w(u_st, u_ft, l_norm, v_m_s, f_fiber_n, f_active_n,
                                           mass_kg)


def basal_rate_w(body_mass_kg: float) -> float:
    """Basal metabolic rate, ``1.2 W/kg × body mass`` (Umberger et al. 2003, p. 105)."""
    if not (body_mass_kg > 0 and math.isfinite(body_mass_kg)):
        raise ValueError(f"body_mass_kg = {body_mass_kg!r}; allowed: finite > 0")
    return BASAL_W_PER_KG * body_mass_kg
