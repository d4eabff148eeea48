"""Where a clutched ankle spring's energy goes on the muscle walker, measured per stride.

Collins, Wiggin & Sawicki (2015, *Nature* 522:212) put a spring in parallel with the calf behind
a clutch that locks at foot flat: as the shank rotates over the planted foot (the ankle
dorsiflexes under load from about 10 % to 45 % of the stride in Winter's data) the spring
stretches and takes part of the Achilles tendon's load, then returns its energy in push-off;
the calf fibres, relieved of force, spend less. How much the spring can store is set by that
loaded dorsiflexion: ``E = ½ k Δθ²``. This module measures, on a
:class:`~afo_mj.gait.muscle_walk.MuscleWalk`, what the spring and the two calf muscles did:

* :func:`spring_stride_energy`: the spring's absorbed and returned work per stride (J,
  ``∫ τ θ̇ dt`` split by sign, τ the device moment, + into the body), its peak moment, and the
  stride phases of its peak stored energy and of the end of its return;
* :func:`muscle_stride_work`: per stride, for each named muscle of one leg, the positive and
  negative work of its fibres (contractile and parallel elastic elements together, the work
  the fibre side does on the tendon) and of its series-elastic tendon, and the muscle's
  metabolic energy (Umberger 2010). With Geyer & Herr's (2010) series elastic element, a
  pure spring, the tendon's net work over whole strides is only the change in its stored
  energy (a test checks it is ≈ 0);
* :func:`ankle_stance_profile`: the stride-averaged ankle angle, its loaded dorsiflexion
  from the clutch's engagement to the peak in stance and that peak's phase, beside the
  same figures of a reference gait (Winter's by default).

Bookkeeping per 1 ms step ``k−1 → k``, consistent with the walker's solve
(:mod:`afo_mj.gait.reflex_law`): the muscle state recorded at ``k`` (tendon force ``F``,
contractile-element velocity ``v_ce``) was solved with the musculotendon length of the joint
angles the controller read, i.e. the record's sample ``k−1`` (Geyer & Herr's path model,
:func:`afo_mj.gait.reflex_law.mtu_length_and_arms`); so with ``Δl_ce = v_ce,k h`` and
``Δl_mtu = l_mtu(q_{k−1}) − l_mtu(q_{k−2})`` and the step's mean force ``F̄ = (F_{k−1} +
F_k)/2``:

``W_fibre = −F̄ Δl_ce``, ``W_tendon = −F̄ (Δl_mtu − Δl_ce)``, ``W_mtu = W_fibre + W_tendon``

(positive: the element shortens under load and does work on the skeleton's side).
"""

from __future__ import annotations

import dataclasses

import numpy as np

from afo_mj.gait import reflex_law as rl
from afo_mj.gait.muscle_walk import MuscleWalk, muscle_table_scaled

__all__ = ["SpringStride", "MuscleStride", "AnkleStance", "scored_strides",
           "spring_stride_energy", "muscle_stride_work", "ankle_stance_profile",
           "mtu_lengths_m"]

SIDES = {"right": 0, "left": 1}


def scored_strides(walk: MuscleWalk, settle_s: float = 3.0, side: str = "right") -> np.ndarray:
    """The heel strikes of ``side`` after ``settle_s`` that bound whole strides (s); fewer
    than 3 (two strides) raises ValueError naming what the walk had."""
    hs = np.asarray(walk.record.events.heel_strikes_s[SIDES[side]], float)
    hs = hs[hs > settle_s]
    if len(hs) < 3:
        raise ValueError(f"the walk has {max(len(hs) - 1, 0)} whole {side} strides after "
                         f"settle_s = {settle_s} s; at least 2 are needed "
                         f"(fell at {walk.record.events.fall_time_s} s)")
    return hs


def _window(walk: MuscleWalk, hs: np.ndarray) -> np.ndarray:
    t = walk.record.time_s
    return (t > hs[0]) & (t <= hs[-1])


@dataclasses.dataclass(frozen=True)
class SpringStride:
    """The ankle device's work per stride on one side (J, + into the body)."""

    absorbed_j: float            #: negative work (≤ 0): the spring being stretched
    returned_j: float            #: positive work: the spring recoiling
    peak_moment_nm: float        #: largest plantarflexing moment
    peak_energy_phase: float     #: stride phase where the stride-mean stored energy peaks
    strides: int


def spring_stride_energy(walk: MuscleWalk, settle_s: float = 3.0,
                         side: str = "right") -> SpringStride:
    """The device's absorbed and returned work per stride on ``side`` (module docstring):
    ``P = τ θ̇`` with ``τ`` the recorded device moment (N·m, + dorsiflexion) and ``θ̇`` the
    ankle velocity; the stored energy's stride profile is ``−∫ P`` from each heel strike."""
    hs = scored_strides(walk, settle_s, side)
    r = walk.record
    s = SIDES[side]
    sel = _window(walk, hs)
    h = r.sample_period_s
    p = r.device_moment_nm[:, s] * r.joint_velocity_rad_s[:, s, 2]
    n = len(hs) - 1
    ph = np.linspace(0.0, 1.0, 101)
    stored = np.zeros_like(ph)
    t = r.time_s
    for a, b in zip(hs[:-1], hs[1:]):
        w = (t > a) & (t <= b)
        e = -np.cumsum(p[w]) * h
        stored += np.interp(a + ph * (b - a), t[w], e) / n
    return SpringStride(absorbed_j=float(np.clip(p[sel], None, 0.0).sum() * h / n),
                        returned_j=float(np.clip(p[sel], 0.0, None).sum() * h / n),
                        peak_moment_nm=float(max(-r.device_moment_nm[sel, s].min(), 0.0)),
                        peak_energy_phase=float(ph[int(np.argmax(stored))]), strides=n)


def mtu_lengths_m(walk: MuscleWalk, muscle: str, side: str = "right") -> np.ndarray:
    """(n,) musculotendon length of ``muscle`` (a name in :data:`afo_mj.gait.reflex_law.
    MUSCLES`) at each recorded sample's joint angles (Geyer & Herr 2010 path model for the
    walk's stature)."""
    if muscle not in rl.MUSCLES:
        raise ValueError(f"muscle = {muscle!r}; allowed: {', '.join(rl.MUSCLES)}")
    r = walk.record
    T = muscle_table_scaled(r.sample_period_s, height_m=float(r.height_m))
    m = rl.MUSCLES.index(muscle)
    q = r.joint_angle_rad[:, SIDES[side], :]
    return np.array([rl.mtu_length_and_arms(T, m, *rl.geyer_angles(*qk))[0] for qk in q])


@dataclasses.dataclass(frozen=True)
class MuscleStride:
    """One muscle's work per stride (J) and metabolic energy per stride (J, Umberger 2010)."""

    muscle: str
    fibre_positive_j: float
    fibre_negative_j: float
    tendon_positive_j: float
    tendon_negative_j: float
    metabolic_j: float
    peak_force_n: float

    @property
    def fibre_net_j(self) -> float:
        return self.fibre_positive_j + self.fibre_negative_j

    @property
    def tendon_net_j(self) -> float:
        return self.tendon_positive_j + self.tendon_negative_j


def muscle_step_work(walk: MuscleWalk, muscle: str, side: str = "right",
                     lengths_m: np.ndarray | None = None):
    """Per recorded step ``(fibre, tendon)`` work (J, (n,) each, the first 2 steps 0) of
    ``muscle`` on ``side`` by the module docstring's bookkeeping."""
    r = walk.record
    s, m = SIDES[side], rl.MUSCLES.index(muscle)
    h = r.sample_period_s
    lm = mtu_lengths_m(walk, muscle, side) if lengths_m is None else lengths_m
    f = walk.force_n[:, s, m]
    n = len(f)
    fibre = np.zeros(n)
    tendon = np.zeros(n)
    f_mean = 0.5 * (f[1:-1] + f[2:])                # steps k = 2 … n−1
    d_ce = walk.ce_velocity_m_s[2:, s, m] * h
    d_mtu = np.diff(lm)[:-1]                      # l(q_{k−1}) − l(q_{k−2}) for k = 2 …
    fibre[2:] = -f_mean * d_ce
    tendon[2:] = -f_mean * (d_mtu - d_ce)
    return fibre, tendon


def muscle_stride_work(walk: MuscleWalk, muscles=("soleus", "gastrocnemius"),
                       settle_s: float = 3.0, side: str = "right") -> dict[str, MuscleStride]:
    """Each of ``muscles``' fibre and tendon work per stride and metabolic energy per stride
    on ``side`` (module docstring)."""
    hs = scored_strides(walk, settle_s, side)
    sel = _window(walk, hs)
    n = len(hs) - 1
    h = walk.record.sample_period_s
    out = {}
    for name in muscles:
        fibre, tendon = muscle_step_work(walk, name, side)
        m = rl.MUSCLES.index(name)
        out[name] = MuscleStride(
            muscle=name,
            fibre_positive_j=float(np.clip(fibre[sel], 0.0, None).sum() / n),
            fibre_negative_j=float(np.clip(fibre[sel], None, 0.0).sum() / n),
            tendon_positive_j=float(np.clip(tendon[sel], 0.0, None).sum() / n),
            tendon_negative_j=float(np.clip(tendon[sel], None, 0.0).sum() / n),
            metabolic_j=float(walk.metabolic_umberger_w[sel, SIDES[side], m].sum() * h / n),
            peak_force_n=float(walk.force_n[sel, SIDES[side], m].max()))
    return out


@dataclasses.dataclass(frozen=True)
class AnkleStance:
    """The stride-mean ankle angle (101 points, rad, + dorsiflexion) and its stance figures:
    the angle at ``engage_phase``, the peak dorsiflexion between there and 60 % of the stride
    and that peak's phase, the lowest angle between ``engage_phase`` and the peak, and the
    loaded dorsiflexion (peak − lowest: how far a spring slack at the lowest angle would be
    stretched; a clutch locked at ``engage_phase`` without a ratchet stretches it by
    ``peak − angle_at_engage``)."""

    angle_rad: np.ndarray
    engage_phase: float
    angle_at_engage_rad: float
    lowest_rad: float
    peak_rad: float
    peak_phase: float

    @property
    def loaded_dorsiflexion_rad(self) -> float:
        return self.peak_rad - self.lowest_rad

    @classmethod
    def from_profile(cls, angle_rad: np.ndarray, engage_phase: float) -> "AnkleStance":
        angle_rad = np.asarray(angle_rad, float)
        ph = np.linspace(0.0, 1.0, len(angle_rad))
        i0 = int(round(engage_phase * (len(ph) - 1)))
        i1 = int(round(0.60 * (len(ph) - 1)))
        k = i0 + int(np.argmax(angle_rad[i0:i1 + 1]))
        return cls(angle_rad, engage_phase, float(angle_rad[i0]),
                   float(angle_rad[i0:k + 1].min()), float(angle_rad[k]), float(ph[k]))


def ankle_stance_profile(walk: MuscleWalk, engage_phase: float = 0.10, settle_s: float = 3.0,
                         side: str = "right") -> AnkleStance:
    """The walk's stride-mean ankle angle on ``side`` and its loaded dorsiflexion from
    ``engage_phase`` (:class:`AnkleStance`)."""
    hs = scored_strides(walk, settle_s, side)
    r = walk.record
    ph = np.linspace(0.0, 1.0, 101)
    ang = np.zeros_like(ph)
    a = r.joint_angle_rad[:, SIDES[side], 2]
    for t0, t1 in zip(hs[:-1], hs[1:]):
        ang += np.interp(t0 + ph * (t1 - t0), r.time_s, a) / (len(hs) - 1)
    return AnkleStance.from_profile(ang, engage_phase)


def reference_stance_profile(reference, engage_phase: float = 0.10) -> AnkleStance:
    """:class:`AnkleStance` of a reference gait's ankle angle (e.g.
    :func:`afo_mj.gait.reference.load_normative`)."""
    ph = np.linspace(0.0, 1.0, 101)
    return AnkleStance.from_profile(np.asarray(reference.channel("ankle_angle_rad", ph), float),
                                    engage_phase)
