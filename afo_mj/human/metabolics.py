"""Metabolic energy rate of a muscle: Umberger (2010) and Bhargava et al. (2004), compiled.

Both models give a muscle's rate of metabolic energy use (W) as heat plus the contractile
element's mechanical work rate, from its excitation ``u``, activation ``a``, CE length and
velocity and forces. Velocities are negative when the CE shortens. A whole-body rate adds
the basal rate, 1.2 W per kg of body mass (Umberger, Gerritsen & Martin 2003, p. 105), and
the net rate (what assistance studies report: Zhang et al. 2017, Collins et al. 2015) is
the gross rate less the standing or basal rate.

**Umberger 2010** — Umberger, "Stance and swing phase costs in human walking", J. R. Soc.
Interface 7 (2010) 1329, built on the 2003 model (Umberger, Gerritsen & Martin, Comput.
Methods Biomech. Biomed. Eng. 6 (2003) 99), in the form OpenSim's
``Umberger2010MuscleMetabolicsProbe`` computes by default and Uchida et al. (2016, PLoS ONE
11:e0150378) used: negative CE work counted, the 2003 model's lengthening heat ``4 α_ST``, the
total kept non-negative. Umberger's published 2010 form counts no negative work and lowers
the lengthening heat to ``0.3 α_ST``; :func:`umberger2010_terms_w` computes it too
(``negative_work=False``) for comparison, the walker records this one. Rates per kg of muscle,
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
import numpy as np

__all__ = ["AEROBIC_SCALE", "BASAL_W_PER_KG", "MIN_HEAT_W_PER_KG",
           "umberger2010_rate_w", "bhargava2004_rate_w", "bhargava_fibre_excitations",
           "bhargava2004_rate_from_fibres_w", "bhargava_length_factor",
           "basal_rate_w", "umberger2010_terms_w", "bhargava2004_terms_w",
           "UMBERGER_TERMS", "BHARGAVA_TERMS"]

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


# --- the models' terms, for analysis (not used by the compiled reflex law) -------------------

#: :func:`umberger2010_terms_w`'s terms, in order (their sum is the muscle's rate)
UMBERGER_TERMS = ("activation_maintenance", "shortening", "lengthening", "nonnegative_raise",
                  "heat_floor", "work_positive", "work_negative")
#: :func:`bhargava2004_terms_w`'s terms, in order (their sum is the muscle's rate)
BHARGAVA_TERMS = ("activation", "maintenance", "shortening", "heat_floor", "work")


def umberger2010_terms_w(u, a, l_norm, v_lopt_s, f_active_n, f_length, v_max_lopt_s,
                         l_opt_m, mass_kg, slow_twitch,
                         negative_work: bool = True) -> dict[str, np.ndarray]:
    """:func:`umberger2010_rate_w` split into its terms (W each), for arrays of muscle states
    (the arguments broadcast; :func:`umberger2010_rate_w`'s meanings). An analysis path, not
    the reflex law's: with ``negative_work`` (the default) the terms' sum is that function's
    total to rounding.

    ``negative_work=False`` gives the model as Umberger (2010) published it: negative CE
    work is not counted (``Ẇ ≥ 0``) and the lengthening heat is ``S A 0.3 α_ST v`` (a
    tenth-odd of the 2003 model's ``4 α_ST``), so no raise is needed to keep the total
    non-negative. The default (negative work counted, ``4 α_ST``, the total kept ≥ 0) is
    the variant Uchida et al. (2016, *PLoS ONE* 11:e0150378) used and OpenSim's
    ``Umberger2010MuscleMetabolicsProbe`` computes by default
    (``include_negative_mechanical_work`` true, ``forbid_negative_total_power`` true); both
    forms as implemented by Falisse et al.'s predictive-simulation code (3dpredictsim,
    ``getMetabolicEnergySmooth2010all`` and ``…2016all``) and by OpenSim's probe, which
    switches the lengthening coefficient between ``4`` and ``0.3 α_ST`` with the negative
    work.

    With ``S = 1.5``, ``A = u`` if ``u > a`` else ``(u + a)/2`` (Umberger et al. 2003, p. 104;
    Umberger 2010, eqs. A1–A6), per kg of muscle:

    * ``activation_maintenance``: ``Ḣ_AM = S A^0.6 (128 (1 − f_ST) + 25)``, beyond ``l_opt``
      ``S A^0.6 (0.4 + 0.6 f_L)(128 (1 − f_ST) + 25)``;
    * ``shortening`` (``v ≤ 0``): ``S A² [min(−α_ST v, 100) f_ST − α_FT v (1 − f_ST)]``,
      ``α_ST = 250/v_max``, ``α_FT = 153/v_max``; ``lengthening`` (``v > 0``):
      ``S A 4 α_ST v``; either × ``f_L`` beyond ``l_opt``;
    * ``nonnegative_raise``: what the shortening/lengthening heat is raised by where
      ``Ḣ_AM + Ḣ_SL + Ẇ`` would be negative (so the total is 0 before the floor; Umberger
      2010 counts negative work, and this keeps the total non-negative);
    * ``heat_floor``: what lifts the heat ``Ḣ_AM + Ḣ_SL`` to 1 W/kg where it is below
      (Umberger et al. 2003, p. 104);
    * ``work_positive``, ``work_negative``: ``Ẇ = −F_CE,active v_CE`` (``F_active`` at
      least 0) where positive (shortening) and where negative (lengthening: counted,
      Umberger 2010, unlike the 2003 model's ``Ẇ ≥ 0``).

    Each term × ``mass_kg`` (W). Returns ``{name: array}`` in :data:`UMBERGER_TERMS` order.
    """
    u, a, ln, v, fa, fl, vmax, lopt, m, fst = np.broadcast_arrays(*(
        np.asarray(x, dtype=float) for x in (u, a, l_norm, v_lopt_s, f_active_n, f_length,
                                             v_max_lopt_s, l_opt_m, mass_kg, slow_twitch)))
    A = np.maximum(np.where(u > a, u, 0.5 * (u + a)), 0.0)
    am0 = 128.0 * (1.0 - fst) + 25.0
    with np.errstate(divide="ignore"):
        a06 = np.exp(0.6 * np.log(A))
    am = np.where(ln <= 1.0, AEROBIC_SCALE * a06 * am0,
                  AEROBIC_SCALE * a06 * (0.4 * am0 + 0.6 * am0 * fl))
    inv_v_max = 1.0 / vmax
    a_st = 250.0 * inv_v_max
    a_ft = 153.0 * inv_v_max
    short = v <= 0.0
    st = np.minimum(-a_st * v, 100.0)
    k_len = 4.0 if negative_work else 0.3
    sl = np.where(short, AEROBIC_SCALE * A * A * (st * fst - a_ft * v * (1.0 - fst)),
                  AEROBIC_SCALE * A * (k_len * a_st * v))
    sl = np.where(ln > 1.0, sl * fl, sl)
    w = -np.maximum(fa, 0.0) * v * lopt / m
    if not negative_work:
        w = np.maximum(w, 0.0)
    raw = am + sl + w
    sl2 = np.where(raw < 0.0, sl - raw, sl)
    raise_ = sl2 - sl
    floor = np.maximum(MIN_HEAT_W_PER_KG - (am + sl2), 0.0)
    zero = np.zeros_like(sl)
    return {"activation_maintenance": am * m,
            "shortening": np.where(short, sl, zero) * m,
            "lengthening": np.where(short, zero, sl) * m,
            "nonnegative_raise": raise_ * m,
            "heat_floor": floor * m,
            "work_positive": np.maximum(w, 0.0) * m,
            "work_negative": np.minimum(w, 0.0) * m}


def bhargava2004_terms_w(u, l_norm, v_m_s, f_fiber_n, f_active_n, mass_kg,
                         slow_twitch) -> dict[str, np.ndarray]:
    """:func:`bhargava2004_rate_w` split into its terms (W each), for arrays of muscle states
    (the arguments broadcast; :func:`bhargava2004_rate_w`'s meanings). An analysis path, not
    the reflex law's: the terms' sum is that function's total to rounding.

    Bhargava, Pandy & Anderson (2004, eqs. 3–11), fibre excitations ``u_ST = f_ST sin(π u/2)``,
    ``u_FT = (1 − f_ST)(1 − cos(π u/2))`` (``u`` clipped to [0, 1];
    :func:`bhargava_fibre_excitations`' form):

    * ``activation``: ``m (40 u_ST + 133 u_FT)``;
    * ``maintenance``: ``m g(l_CE/l_opt) (74 u_ST + 111 u_FT)`` (:func:`bhargava_length_factor`);
    * ``shortening``: ``−0.25 F_CE v_CE`` while shortening (fibre force, active and passive),
      0 lengthening;
    * ``heat_floor``: what lifts the heat (the three above) to 1 W per kg of muscle where it
      is below;
    * ``work``: ``−F_CE,active v_CE`` while shortening, 0 lengthening (negative work is not
      counted).

    Returns ``{name: array}`` in :data:`BHARGAVA_TERMS` order.
    """
    u, ln, v, ff, fa, m, fst = np.broadcast_arrays(*(
        np.asarray(x, dtype=float) for x in (u, l_norm, v_m_s, f_fiber_n, f_active_n, mass_kg,
                                             slow_twitch)))
    uu = np.minimum(np.maximum(u, 0.0), 1.0)
    s4 = np.sin(0.25 * math.pi * uu)
    u_st = fst * (2.0 * s4 * np.sqrt(1.0 - s4 * s4))
    u_ft = (1.0 - fst) * (2.0 * s4 * s4)
    g = np.where(ln <= 0.5, 0.5, np.where(ln <= 1.0, 0.5 + (ln - 0.5),
                                          np.where(ln <= 1.5, 1.0 - 2.0 * (ln - 1.0), 0.0)))
    act = m * (40.0 * u_st + 133.0 * u_ft)
    main = m * g * (74.0 * u_st + 111.0 * u_ft)
    short = v <= 0.0
    sh = np.where(short, -0.25 * ff * v, 0.0)
    w = np.where(short, -fa * v, 0.0)
    floor = np.maximum(MIN_HEAT_W_PER_KG * m - (act + main + sh), 0.0)
    return {"activation": act, "maintenance": main, "shortening": sh, "heat_floor": floor,
            "work": w}
