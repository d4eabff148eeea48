"""Hill-type muscle–tendon units with compliant tendons (Geyer & Herr 2010), compiled.

A muscle–tendon unit (MTU) is a contractile element (CE) in series with a tendon (the series
elastic element, SE), with a parallel elastic element (PE) that resists stretch beyond the
optimum length and a buckling element (BE) that keeps the CE from collapsing. The model and
its shared constants are Geyer & Herr, "A muscle-reflex model that encodes principles of
legged mechanics produces human walking dynamics and muscle activities", IEEE Trans. Neural
Syst. Rehabil. Eng. 18 (2010) 263–273, and Geyer, Seyfarth & Blickhan, Proc. R. Soc. B 270
(2003) 2173 (the CE and SE relations):

* CE force ``F_CE = a · F_max · f_L(l_CE) · f_V(v_CE)``;
* force–length ``f_L = exp(c · |(l_CE − l_opt)/(l_opt · w)|³)``, ``w = 0.56``,
  ``c = ln 0.05`` (5 % force left at ``l_opt(1 ± w)``);
* force–velocity, ``v`` in ``l_opt/s`` (negative = shortening), ``v_max`` the maximum
  shortening speed: concentric ``f_V = (v_max + v)/(v_max − K v)``; eccentric
  ``f_V = N + (N − 1)(v_max − v)/(7.56 K v + v_max)`` (Geyer & Herr write these with the
  opposite sign of ``v``), ``N = 1.5`` the eccentric force enhancement, ``K = 5`` the curvature;
* tendon ``F_SE = F_max (ε/ε_ref)²`` for the strain ``ε = (l_SE − l_slack)/l_slack > 0``,
  ``ε_ref = 0.04`` (zero when slack): a stiffening spring that stores and returns energy;
* PE ``F_PE = F_max ((l_CE − l_opt)/(l_opt w))²`` beyond ``l_opt``; BE
  ``F_BE = F_max ((l_CE − l_opt(1 − w))/(l_opt w/2))²`` below ``l_opt(1 − w)``;
* equilibrium ``F_SE = F_CE + F_PE − F_BE`` gives ``f_V``, inverted to ``v_CE``;
* activation ``τ ȧ = u − a``, ``τ = 10 ms``, from the excitation (stimulation) ``u``.

Path geometry (Geyer & Herr 2010, section II-B): at an ankle or knee the moment arm is
``r(φ) = r_0 cos(φ − φ_max)`` and the MTU length changes by
``Δl = s ρ r_0 [sin(φ − φ_max) − sin(φ_ref − φ_max)]``; at the hip ``r = r_0`` and
``Δl = s ρ r_0 (φ − φ_ref)``; ``l_MTU = l_opt + l_slack + Σ Δl`` (so at every ``φ_ref`` the MTU
is exactly ``l_opt + l_slack`` long). ``φ`` are Geyer's internal joint angles: ankle
``φ_a = π/2 − θ_ankle`` (``θ`` dorsiflexion positive, as in the walker), knee
``φ_k = π − θ_knee``, hip ``φ_h = π − θ_hip`` (flexion positive). ``s = +1`` when the muscle
lengthens as ``φ`` grows (TA, GAS at the knee, HAM at the knee, HFL), ``−1`` otherwise; ``ρ``
accounts for pennation and fibre compliance in the length change. The joint torque, in the
walker's positive direction, is ``τ_θ = s · r(φ) · F`` (a plantarflexor, ``s = −1``, gives a
negative, plantarflexing torque).

The CE length is the MTU's state. Its ODE ``l̇_CE = v_CE(l_CE, a, l_MTU)`` is stiff when the
activation is low (a slack fibre relaxes in microseconds), so :func:`mtu_step` advances it by
backward Euler: the scalar equation ``x − l_CE,n − h v_CE(x, a_{n+1}, l_MTU,n+1) = 0`` solved by
a safeguarded Newton iteration with the analytic derivative (:func:`mtu_residual`) inside a
bracket (bisection where Newton leaves it), to a relative tolerance of 1e-12;
``tests/test_muscle.py`` checks the stepped ODE against scipy's Radau and
``tests/test_muscle_newton.py`` each solve against scipy's brentq.

Parameters of the seven muscles per leg (:data:`GEYER_HERR_2010`): ``F_max``, ``v_max``,
``l_opt``, ``l_slack``, ``r_0``, ``φ_max``, ``φ_ref``, ``ρ`` from the model's published
parameter set (Geyer & Herr 2010, Table I); muscle masses and slow-twitch fractions for the
metabolic models (:mod:`afo_mj.human.metabolics`) from Song & Geyer, J. Physiol. 593 (2015)
3493 (their metabolic extension of the same model).
"""

from __future__ import annotations

import dataclasses
import math

import numba
import numpy as np

from afo_mj.hydraulics.params import ParameterError, Parameters, param

__all__ = [
    "W_WIDTH", "C_RESIDUAL", "N_ECCENTRIC", "K_CURVATURE", "F_V_INFINITY", "EPS_REF",
    "TAU_ACTIVATION_S", "PREACTIVATION", "MuscleParams", "JointPath", "GEYER_HERR_2010",
    "MUSCLE_NAMES",
    "ce_force_length", "ce_force_velocity", "ce_velocity_from_force", "se_force_n",
    "pe_force_n", "be_force_n", "activation_step", "path_length_and_arm",
    "mtu_rate", "mtu_residual", "mtu_step", "mtu_step_pair", "equilibrium_ce_length_m",
    "to_geyer_angle",
]

#: force–length width (in l_opt) and the force left at its edges, ln(0.05)
W_WIDTH = 0.56
C_RESIDUAL = math.log(0.05)
#: eccentric force enhancement and force–velocity curvature
N_ECCENTRIC = 1.5
K_CURVATURE = 5.0
#: the lengthening force–velocity factor's limit as v → ∞
F_V_INFINITY = N_ECCENTRIC + (N_ECCENTRIC - 1.0) / (7.56 * K_CURVATURE)
#: tendon reference strain (F_SE = F_max at ε = ε_ref)
EPS_REF = 0.04
#: excitation–contraction time constant and the resting (pre-)activation
TAU_ACTIVATION_S = 0.01
PREACTIVATION = 0.01

#: joint codes of a path: 0 ankle, 1 knee, 2 hip
JOINTS = ("ankle", "knee", "hip")


@dataclasses.dataclass(frozen=True)
class JointPath:
    """How a muscle crosses one joint (Geyer & Herr 2010, section II-B): ``sign`` +1 when it
    lengthens as Geyer's internal angle grows, −1 otherwise; ``r0_m`` the moment arm
    (at ``phi_max``); ``phi_max_rad`` (ankle, knee; None at the hip: constant arm),
    ``phi_ref_rad`` where the MTU is ``l_opt + l_slack`` long; ``rho`` the length scaling."""

    joint: str
    sign: int
    r0_m: float
    phi_ref_rad: float
    rho: float
    phi_max_rad: float | None = None

    def __post_init__(self):
        if self.joint not in JOINTS:
            raise ParameterError(f"JointPath.joint = {self.joint!r}; allowed: {JOINTS}")
        if self.sign not in (-1, 1):
            raise ParameterError(f"JointPath.sign = {self.sign!r}; allowed: -1 or 1")
        if not (0.0 < self.r0_m <= 0.3):
            raise ParameterError(f"JointPath.r0_m = {self.r0_m!r}; allowed: (0, 0.3] m")
        if not (0.0 < self.rho <= 1.0):
            raise ParameterError(f"JointPath.rho = {self.rho!r}; allowed: (0, 1]")
        if (self.phi_max_rad is None) != (self.joint == "hip"):
            raise ParameterError(f"JointPath({self.joint}).phi_max_rad = {self.phi_max_rad!r}; "
                                 "allowed: a value at the ankle and knee, None at the hip")


@dataclasses.dataclass(frozen=True)
class MuscleParams(Parameters):
    """One muscle–tendon unit (Geyer & Herr 2010, Table I; metabolic figures Song & Geyer
    2015)."""

    max_force_n: float = param(1000.0, unit="N", lo=0.0, lo_open=True, hi=2e4)
    max_velocity_lopt_s: float = param(12.0, unit="l_opt/s", lo=0.0, lo_open=True, hi=30.0,
                                       doc="maximum shortening speed")
    optimal_length_m: float = param(0.05, unit="m", lo=0.0, lo_open=True, hi=0.5)
    slack_length_m: float = param(0.25, unit="m", lo=0.0, lo_open=True, hi=1.0)
    mass_kg: float = param(0.5, unit="kg", lo=0.0, lo_open=True, hi=10.0,
                           doc="muscle mass, for the metabolic models")
    slow_twitch_fraction: float = param(0.5, unit="1", lo=0.0, hi=1.0)


def _deg(x: float) -> float:
    return math.radians(x)


#: the seven muscles per leg of Geyer & Herr (2010): MTU parameters and their joint paths
GEYER_HERR_2010: dict[str, tuple[MuscleParams, tuple[JointPath, ...]]] = {
    "soleus": (MuscleParams(4000.0, 6.0, 0.04, 0.26, 0.70, 0.75),
               (JointPath("ankle", -1, 0.05, _deg(80), 0.5, _deg(110)),)),
    "gastrocnemius": (MuscleParams(1500.0, 12.0, 0.05, 0.40, 0.30, 0.50),
                      (JointPath("ankle", -1, 0.05, _deg(80), 0.7, _deg(110)),
                       JointPath("knee", 1, 0.05, _deg(165), 0.7, _deg(140)))),
    "tibialis_anterior": (MuscleParams(800.0, 12.0, 0.06, 0.24, 0.20, 0.70),
                          (JointPath("ankle", 1, 0.04, _deg(110), 0.7, _deg(80)),)),
    "vasti": (MuscleParams(6000.0, 12.0, 0.08, 0.23, 2.05, 0.50),
              (JointPath("knee", -1, 0.06, _deg(125), 0.7, _deg(165)),)),
    "hamstrings": (MuscleParams(3000.0, 12.0, 0.10, 0.31, 1.25, 0.60),
                   (JointPath("knee", 1, 0.05, _deg(180), 0.7, _deg(180)),
                    JointPath("hip", -1, 0.08, _deg(155), 0.7))),
    "gluteals": (MuscleParams(1500.0, 12.0, 0.11, 0.13, 0.70, 0.50),
                 (JointPath("hip", -1, 0.10, _deg(150), 0.5),)),
    "hip_flexors": (MuscleParams(2000.0, 12.0, 0.11, 0.10, 0.95, 0.55),
                    (JointPath("hip", 1, 0.10, _deg(180), 0.5),)),
}
MUSCLE_NAMES = tuple(GEYER_HERR_2010)


# ------------------------------------------------------------------------------ CE, SE, PE


@numba.njit(cache=True)
def ce_force_length(l_ce_m: float, l_opt_m: float) -> float:
    """``f_L = exp(c |(l_CE − l_opt)/(l_opt w)|³)`` (Geyer & Herr 2010, eq. in section II-A):
    1 at ``l_opt``, 0.05 at ``l_opt (1 ± w)``.

    >>> round(ce_force_length(0.04 * 1.56, 0.04), 6)
    0.05
    """
    x = abs((l_ce_m - l_opt_m) / (l_opt_m * W_WIDTH))
    return math.exp(C_RESIDUAL * x * x * x)


@numba.njit(cache=True)
def ce_force_velocity(v_lopt_s: float, v_max_lopt_s: float) -> float:
    """Hill's force–velocity factor ``f_V`` at the CE velocity ``v`` (l_opt/s, negative =
    shortening; Geyer & Herr 2010): ``(v_max + v)/(v_max − K v)`` shortening (0 at
    ``v = −v_max``), ``N + (N − 1)(v_max − v)/(7.56 K v + v_max)`` lengthening (1 at 0,
    tending to ``N``); below ``−v_max`` it is 0."""
    if v_lopt_s < 0.0:
        if v_lopt_s <= -v_max_lopt_s:
            return 0.0
        return (v_max_lopt_s + v_lopt_s) / (v_max_lopt_s - K_CURVATURE * v_lopt_s)
    return N_ECCENTRIC + (N_ECCENTRIC - 1.0) * (v_lopt_s - v_max_lopt_s) / (
        7.56 * K_CURVATURE * v_lopt_s + v_max_lopt_s)


@numba.njit(cache=True)
def ce_velocity_from_force(f_v: float, v_max_lopt_s: float) -> float:
    """The inverse of :func:`ce_force_velocity`: the CE velocity (l_opt/s) at which the
    force–velocity factor is ``f_v``; ``−v_max`` for ``f_v ≤ 0``. The lengthening branch
    tends to ``F_V∞ = N + (N − 1)/(7.56 K)`` as ``v → ∞``, so the returned speed is capped at
    ``10 v_max`` (reached just below ``F_V∞`` and kept above it: a continuous, monotone
    inverse)."""
    vm = v_max_lopt_s
    if f_v <= 0.0:
        return -vm
    if f_v <= 1.0:
        # (vm + v) = f (vm − K v)  →  v = vm (f − 1)/(1 + K f)
        return vm * (f_v - 1.0) / (1.0 + K_CURVATURE * f_v)
    if f_v >= F_V_INFINITY:
        return 10.0 * vm
    # f = N + (N − 1)(v − vm)/(7.56 K v + vm)  →  (f − N)(7.56 K v + vm) = (N − 1)(v − vm)
    d = f_v - N_ECCENTRIC
    v = -vm * (d + N_ECCENTRIC - 1.0) / (7.56 * K_CURVATURE * d - (N_ECCENTRIC - 1.0))
    return min(v, 10.0 * vm)


@numba.njit(cache=True)
def se_force_n(l_se_m: float, l_slack_m: float, f_max_n: float) -> float:
    """Tendon force ``F_max (ε/ε_ref)²`` for strain ``ε = (l_SE − l_slack)/l_slack > 0``, else
    0 (Geyer & Herr 2010)."""
    eps = (l_se_m - l_slack_m) / l_slack_m
    if eps <= 0.0:
        return 0.0
    return f_max_n * (eps / EPS_REF) ** 2


@numba.njit(cache=True)
def pe_force_n(l_ce_m: float, l_opt_m: float, f_max_n: float) -> float:
    """Parallel elastic force ``F_max ((l_CE − l_opt)/(l_opt w))²`` beyond ``l_opt``."""
    if l_ce_m <= l_opt_m:
        return 0.0
    x = (l_ce_m - l_opt_m) / (l_opt_m * W_WIDTH)
    return f_max_n * x * x


@numba.njit(cache=True)
def be_force_n(l_ce_m: float, l_opt_m: float, f_max_n: float) -> float:
    """Buckling-element force ``F_max ((l_CE − l_opt(1 − w))/(l_opt w/2))²`` below
    ``l_opt (1 − w)`` (it keeps the CE from collapsing; Geyer & Herr 2010)."""
    lo = l_opt_m * (1.0 - W_WIDTH)
    if l_ce_m >= lo:
        return 0.0
    x = (l_ce_m - lo) / (l_opt_m * W_WIDTH * 0.5)
    return f_max_n * x * x


@numba.njit(cache=True)
def activation_step(a: float, u: float, h_s: float, tau_s: float) -> float:
    """Activation after ``h_s`` with the excitation ``u`` held: the exact solution of
    ``τ ȧ = u − a``, ``a + (u − a)(1 − e^{−h/τ})``."""
    return a + (u - a) * (1.0 - math.exp(-h_s / tau_s))


# ------------------------------------------------------------------------------ geometry


def to_geyer_angle(joint: str, theta_rad):
    """Geyer's internal angle from the walker's joint angle (ankle dorsiflexion, knee and
    hip flexion positive): ``π/2 − θ`` at the ankle, ``π − θ`` at the knee and hip."""
    if joint not in JOINTS:
        raise ValueError(f"joint = {joint!r}; allowed: {JOINTS}")
    return (0.5 * math.pi if joint == "ankle" else math.pi) - np.asarray(theta_rad, float)


@numba.njit(cache=True)
def path_length_and_arm(phi: float, sign: float, r0: float, phi_max: float, phi_ref: float,
                        rho: float, constant_arm: bool):
    """One joint's contribution to the MTU length and its moment arm (Geyer & Herr 2010,
    section II-B): ``(Δl, r)``; ``Δl = s ρ r_0 [sin(φ − φ_max) − sin(φ_ref − φ_max)]`` and
    ``r = r_0 cos(φ − φ_max)``, or, with a constant arm (the hip), ``Δl = s ρ r_0 (φ − φ_ref)``
    and ``r = r_0``. ``dΔl/dφ = s ρ r``."""
    if constant_arm:
        return sign * rho * r0 * (phi - phi_ref), r0
    return (sign * rho * r0 * (math.sin(phi - phi_max) - math.sin(phi_ref - phi_max)),
            r0 * math.cos(phi - phi_max))


# ------------------------------------------------------------------------------ dynamics


@numba.njit(cache=True)
def mtu_rate(l_ce: float, a: float, l_mtu: float, f_max: float, v_max: float, l_opt: float,
             l_slack: float) -> float:
    """``l̇_CE`` (m/s): the CE velocity at which the tendon force balances CE, PE and BE,
    ``F_SE = a F_max f_L f_V + F_PE − F_BE`` solved for ``f_V`` and inverted
    (:func:`ce_velocity_from_force`). The active force is floored at 1e-6 F_max so that the
    relation stays invertible."""
    f_se = se_force_n(l_mtu - l_ce, l_slack, f_max)
    f_pe = pe_force_n(l_ce, l_opt, f_max)
    f_be = be_force_n(l_ce, l_opt, f_max)
    act = max(a * f_max * ce_force_length(l_ce, l_opt), 1e-6 * f_max)
    f_v = (f_se - f_pe + f_be) / act
    return ce_velocity_from_force(f_v, v_max) * l_opt


@numba.njit(cache=True, inline="always")
def _residual(x, l_ce, a, l_mtu, hl, v_max, l_opt, l_slack, l_b, inv_lw, inv_lbw,
              inv_ls_eps):
    """:func:`mtu_residual` with its constants precomputed (``hl = h l_opt``,
    ``l_b = l_opt (1 − w)``, ``inv_lw = 1/(l_opt w)``, ``inv_lbw = 2/(l_opt w)``,
    ``inv_ls_eps = 1/(l_slack ε_ref)``); forces in units of ``F_max``."""
    # n = (F_SE − F_PE + F_BE)/F_max and dn/dx
    q = (l_mtu - x - l_slack) * inv_ls_eps                    # ε/ε_ref
    if q > 0.0:
        n = q * q
        dn = -2.0 * q * inv_ls_eps
    else:
        n = 0.0
        dn = 0.0
    y = (x - l_opt) * inv_lw                                   # (l_CE − l_opt)/(l_opt w)
    if y > 0.0:
        n -= y * y
        dn -= 2.0 * y * inv_lw
    if x < l_b:
        z = (x - l_b) * inv_lbw
        n += z * z
        dn += 2.0 * z * inv_lbw
    # d = max(a f_L, 1e-6) and dd/dx
    ay = abs(y)
    d = a * math.exp(C_RESIDUAL * ay * ay * ay)
    if d > 1e-6:
        dd = 3.0 * C_RESIDUAL * y * ay * inv_lw * d
    else:
        d = 1e-6
        dd = 0.0
    inv_d = 1.0 / d
    f = n * inv_d                                              # f_V
    df = (dn - f * dd) * inv_d
    # v = g(f) (ce_velocity_from_force) and dg/df
    if f <= 0.0:
        g = -v_max
        dg = 0.0
    elif f <= 1.0:
        inv = 1.0 / (1.0 + K_CURVATURE * f)
        g = v_max * (f - 1.0) * inv
        dg = v_max * (1.0 + K_CURVATURE) * inv * inv
    elif f >= F_V_INFINITY:
        g = 10.0 * v_max
        dg = 0.0
    else:
        dfn = f - N_ECCENTRIC
        inv = 1.0 / (7.56 * K_CURVATURE * dfn - (N_ECCENTRIC - 1.0))
        g = -v_max * (dfn + N_ECCENTRIC - 1.0) * inv
        if g >= 10.0 * v_max:
            g = 10.0 * v_max
            dg = 0.0
        else:
            dg = v_max * (N_ECCENTRIC - 1.0) * (1.0 + 7.56 * K_CURVATURE) * inv * inv
    return x - l_ce - hl * g, 1.0 - hl * dg * df


@numba.njit(cache=True)
def mtu_residual(x: float, l_ce: float, a: float, l_mtu: float, h: float, f_max: float,
                 v_max: float, l_opt: float, l_slack: float):
    """The backward-Euler residual of the CE length and its derivative, ``(R, dR/dx)``:
    ``R(x) = x − l_CE − h l_opt g(f(x))`` with ``f = (F_SE − F_PE + F_BE)/max(a F_max f_L,
    10⁻⁶ F_max)`` the force–velocity factor the force balance asks for at the CE length
    ``x`` (MTU length ``l_mtu``) and ``g`` its inverse (:func:`ce_velocity_from_force`), so
    that ``R = x − l_CE − h · mtu_rate(x)`` (Geyer & Herr 2010, the relations of this
    module). The derivative is analytic, piece by piece (every force is in units of ``F_max``,
    which cancels; ``y = (x − l_opt)/(l_opt w)``, ``q = ε/ε_ref``):

    * ``dF_SE/dx = −2 q/(l_slack ε_ref)`` while the tendon is stretched, 0 when slack;
    * ``dF_PE/dx = 2 y/(l_opt w)`` beyond ``l_opt``; ``dF_BE/dx = 2 z · 2/(l_opt w)`` below
      ``l_opt (1 − w)``, ``z = (x − l_opt(1 − w))/(l_opt w/2)``;
    * ``d(a f_L)/dx = a f_L · 3 c y |y|/(l_opt w)`` (0 where the floor 10⁻⁶ holds);
    * ``df/dx = (dn/dx − f dd/dx)/d`` for ``f = n/d``;
    * ``dg/df = v_max (1 + K)/(1 + K f)²`` shortening (``0 < f ≤ 1``),
      ``v_max (N − 1)(1 + 7.56 K)/(7.56 K (f − N) − (N − 1))²`` lengthening, 0 where ``g``
      is clamped (``f ≤ 0``: ``−v_max``; ``f ≥ F_V∞`` or beyond ``10 v_max``);
    * ``dR/dx = 1 − h l_opt (dg/df)(df/dx)``.

    At a branch point (``v = 0``, the tendon's slack length, ``l_opt``, the floor, the
    clamps) the value is continuous and the derivative is the one of the branch the value
    takes; ``f_max`` is accepted for the signature of :func:`mtu_rate` and cancels."""
    return _residual(x, l_ce, a, l_mtu, h * l_opt, v_max, l_opt, l_slack,
                     l_opt * (1.0 - W_WIDTH),
                     1.0 / (l_opt * W_WIDTH), 2.0 / (l_opt * W_WIDTH),
                     1.0 / (l_slack * EPS_REF))


@numba.njit(cache=True, inline="always")
def _newton_start(l_ce, l_mtu, h, v_max, l_opt, v_guess):
    """The solve's bracket and start (:func:`mtu_step`): ``(x, lo, hi)``."""
    hl = h * l_opt
    lo = max(l_ce - 1.001 * hl * v_max, 0.0)
    hi = min(l_ce + 10.01 * hl * v_max, l_mtu)
    if hi <= lo:                    # a CE longer than its MTU: the whole range
        lo = 0.0
        hi = l_mtu
    return min(max(l_ce + h * v_guess, lo + 1e-9 * l_opt), hi), lo, hi


@numba.njit(cache=True, inline="always")
def _newton_update(x, r, dr, lo, hi, last, tol):
    """One safeguarded Newton update of :func:`mtu_step` from ``R(x) = r``, ``R'(x) = dr``:
    ``(x_next, lo, hi, last, done)``; ``last`` the last Newton step's size (−1: none)."""
    hi = x if r > 0.0 else hi
    lo = x if r < 0.0 else lo
    if dr > 0.0:
        dx = -r / dr
        step = abs(dx)
        # converged: the step below tol, or θ/(1 − θ) · step below it, θ = step/last
        if step < tol or step * step < (last - step) * tol:
            return x + dx, lo, hi, last, True
        xn = x + dx
        if lo < xn < hi:
            return xn, lo, hi, step, False
    elif r == 0.0:
        return x, lo, hi, last, True
    if hi - lo < tol:
        return 0.5 * (lo + hi), lo, hi, -1.0, True
    return 0.5 * (lo + hi), lo, hi, -1.0, False


@numba.njit(cache=True)
def mtu_step(l_ce: float, a: float, l_mtu: float, h: float, f_max: float, v_max: float,
             l_opt: float, l_slack: float, v_guess: float = 0.0) -> float:
    """The CE length after a backward-Euler step ``h`` (activation ``a`` and MTU length
    ``l_mtu`` at the step's end): the root of ``R(x) = x − l_CE − h · mtu_rate(x)``
    (:func:`mtu_residual`) by Newton's method with the analytic derivative, started at
    ``l_CE + h v_guess`` (``v_guess`` m/s: a prediction of the CE velocity over the step,
    e.g. extrapolated from the last steps; 0 starts at ``l_CE``), inside a bracket: the rate
    lies in ``[−v_max, 10 v_max] l_opt``, so the root lies in ``[l_CE − h v_max l_opt,
    l_CE + 10 h v_max l_opt] ∩ [0, l_mtu]`` (bisection when a Newton step leaves the bracket
    or the slope is not positive; ``R`` increases with ``x`` for a muscle on the rising
    tendon curve). Converged when a Newton step is below 1e-12 ``l_opt``, or when the
    contraction ``θ = |Δx_k|/|Δx_{k−1}|`` of two successive Newton steps bounds the error
    left, ``θ/(1 − θ) |Δx_k|``, below it (Hairer & Wanner, Solving Ordinary Differential
    Equations II, section IV.8, the stopping rule of the simplified Newton iteration); the
    last step is taken. ``tests/test_muscle_newton.py`` checks it against scipy's brentq."""
    if l_mtu <= 0.0:
        return 1e-6 * l_opt
    tol = 1e-12 * l_opt
    x, lo, hi = _newton_start(l_ce, l_mtu, h, v_max, l_opt, v_guess)
    hl = h * l_opt
    l_b = l_opt * (1.0 - W_WIDTH)
    inv_lw = 1.0 / (l_opt * W_WIDTH)
    inv_lbw = 2.0 * inv_lw
    inv_ls_eps = 1.0 / (l_slack * EPS_REF)
    last = -1.0
    for _ in range(100):
        r, dr = _residual(x, l_ce, a, l_mtu, hl, v_max, l_opt, l_slack, l_b, inv_lw,
                          inv_lbw, inv_ls_eps)
        x, lo, hi, last, done = _newton_update(x, r, dr, lo, hi, last, tol)
        if done:
            break
    return x


@numba.njit(cache=True, inline="always")
def mtu_step_pair(l_ce0: float, a0: float, l_mtu0: float, v_guess0: float, l_ce1: float,
                  a1: float, l_mtu1: float, v_guess1: float, h: float, f_max: float,
                  v_max: float, l_opt: float, l_slack: float):
    """Two :func:`mtu_step` solves of one muscle (the same parameters: the left and right
    leg's) interleaved, so that their iterations overlap on the processor: ``(x0, x1)``, each
    bit for bit what :func:`mtu_step` returns (the same start, updates and stopping rule)."""
    tol = 1e-12 * l_opt
    x0, lo0, hi0 = _newton_start(l_ce0, l_mtu0, h, v_max, l_opt, v_guess0)
    x1, lo1, hi1 = _newton_start(l_ce1, l_mtu1, h, v_max, l_opt, v_guess1)
    done0 = l_mtu0 <= 0.0
    done1 = l_mtu1 <= 0.0
    if done0:
        x0 = 1e-6 * l_opt
    if done1:
        x1 = 1e-6 * l_opt
    hl = h * l_opt
    l_b = l_opt * (1.0 - W_WIDTH)
    inv_lw = 1.0 / (l_opt * W_WIDTH)
    inv_lbw = 2.0 * inv_lw
    inv_ls_eps = 1.0 / (l_slack * EPS_REF)
    last0 = -1.0
    last1 = -1.0
    for _ in range(100):
        if not done0:
            r, dr = _residual(x0, l_ce0, a0, l_mtu0, hl, v_max, l_opt, l_slack, l_b, inv_lw,
                              inv_lbw, inv_ls_eps)
            x0, lo0, hi0, last0, done0 = _newton_update(x0, r, dr, lo0, hi0, last0, tol)
        if not done1:
            r, dr = _residual(x1, l_ce1, a1, l_mtu1, hl, v_max, l_opt, l_slack, l_b, inv_lw,
                              inv_lbw, inv_ls_eps)
            x1, lo1, hi1, last1, done1 = _newton_update(x1, r, dr, lo1, hi1, last1, tol)
        if done0 and done1:
            break
    return x0, x1



@numba.njit(cache=True, inline="always")
def _solve_start(l_ce, l_mtu, h, v_max, l_opt, v_guess):
    """One :func:`mtu_step` solve before its first iteration: ``(x, lo, hi, last, done)``
    (an MTU of no length is done at ``10⁻⁶ l_opt``)."""
    x, lo, hi = _newton_start(l_ce, l_mtu, h, v_max, l_opt, v_guess)
    done = l_mtu <= 0.0
    if done:
        x = 1e-6 * l_opt
    return x, lo, hi, -1.0, done


@numba.njit(cache=True, inline="always")
def _solve_constants(h, l_opt, l_slack):
    """The constants of a muscle's residual (:func:`_residual`) and its tolerance, as
    :func:`mtu_step` computes them: ``(hl, l_b, inv_lw, inv_lbw, inv_ls_eps, tol)``."""
    inv_lw = 1.0 / (l_opt * W_WIDTH)
    return (h * l_opt, l_opt * (1.0 - W_WIDTH), inv_lw, 2.0 * inv_lw,
            1.0 / (l_slack * EPS_REF), 1e-12 * l_opt)


@numba.njit(cache=True, inline="always")
def mtu_step_quad(l_ce0: float, a0: float, l_mtu0: float, v_guess0: float, l_ce1: float,
                  a1: float, l_mtu1: float, v_guess1: float, v_max: float, l_opt: float,
                  l_slack: float, l_ce2: float, a2: float, l_mtu2: float, v_guess2: float,
                  l_ce3: float, a3: float, l_mtu3: float, v_guess3: float, v_max_b: float,
                  l_opt_b: float, l_slack_b: float, h: float):
    """Four :func:`mtu_step` solves interleaved — two of one muscle (``v_max, l_opt,
    l_slack``: solves 0 and 1, the left and right leg's) and two of another (``v_max_b,
    l_opt_b, l_slack_b``: solves 2 and 3) — so that their iterations overlap on the
    processor: ``(x0, x1, x2, x3)``, each bit for bit what :func:`mtu_step` returns (the same
    start, updates and stopping rule; :func:`mtu_step_pair` with two muscles)."""
    hl, l_b, inv_lw, inv_lbw, inv_ls_eps, tol = _solve_constants(h, l_opt, l_slack)
    hlb, l_bb, inv_lwb, inv_lbwb, inv_ls_epsb, tolb = _solve_constants(h, l_opt_b, l_slack_b)
    x0, lo0, hi0, last0, done0 = _solve_start(l_ce0, l_mtu0, h, v_max, l_opt, v_guess0)
    x1, lo1, hi1, last1, done1 = _solve_start(l_ce1, l_mtu1, h, v_max, l_opt, v_guess1)
    x2, lo2, hi2, last2, done2 = _solve_start(l_ce2, l_mtu2, h, v_max_b, l_opt_b, v_guess2)
    x3, lo3, hi3, last3, done3 = _solve_start(l_ce3, l_mtu3, h, v_max_b, l_opt_b, v_guess3)
    for _ in range(100):
        if not done0:
            r, dr = _residual(x0, l_ce0, a0, l_mtu0, hl, v_max, l_opt, l_slack, l_b, inv_lw,
                              inv_lbw, inv_ls_eps)
            x0, lo0, hi0, last0, done0 = _newton_update(x0, r, dr, lo0, hi0, last0, tol)
        if not done1:
            r, dr = _residual(x1, l_ce1, a1, l_mtu1, hl, v_max, l_opt, l_slack, l_b, inv_lw,
                              inv_lbw, inv_ls_eps)
            x1, lo1, hi1, last1, done1 = _newton_update(x1, r, dr, lo1, hi1, last1, tol)
        if not done2:
            r, dr = _residual(x2, l_ce2, a2, l_mtu2, hlb, v_max_b, l_opt_b, l_slack_b, l_bb,
                              inv_lwb, inv_lbwb, inv_ls_epsb)
            x2, lo2, hi2, last2, done2 = _newton_update(x2, r, dr, lo2, hi2, last2, tolb)
        if not done3:
            r, dr = _residual(x3, l_ce3, a3, l_mtu3, hlb, v_max_b, l_opt_b, l_slack_b, l_bb,
                              inv_lwb, inv_lbwb, inv_ls_epsb)
            x3, lo3, hi3, last3, done3 = _newton_update(x3, r, dr, lo3, hi3, last3, tolb)
        if done0 and done1 and done2 and done3:
            break
    return x0, x1, x2, x3


def equilibrium_ce_length_m(a: float, l_mtu: float, p: MuscleParams) -> float:
    """The CE length at which an MTU of length ``l_mtu`` held still with activation ``a`` is
    in equilibrium (``v_CE = 0``: ``F_SE = a F_max f_L + F_PE − F_BE``), by bisection on
    the force balance between a vanishing CE and the longest CE the tendon allows
    (``l_mtu − l_slack``, or 3 ``l_opt``), where the balance changes sign."""
    f, lo_m, ls = p.max_force_n, p.optimal_length_m, p.slack_length_m

    def g(x):
        return (se_force_n(l_mtu - x, ls, f) - a * f * ce_force_length(x, lo_m)
                - pe_force_n(x, lo_m, f) + be_force_n(x, lo_m, f))

    # g > 0 at small x (stretched tendon), g < 0 once the tendon is slack
    hi = min(l_mtu - ls, 3.0 * lo_m) if l_mtu > ls else 1e-9
    if g(hi) > 0.0:
        raise ValueError(f"l_mtu = {l_mtu!r} m: no equilibrium with a slack tendon below "
                         f"{hi:.4g} m of CE; allowed: an MTU the CE can balance")
    lo = 1e-9
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        if g(mid) > 0.0:
            lo = mid
        else:
            hi = mid
    return 0.5 * (lo + hi)
