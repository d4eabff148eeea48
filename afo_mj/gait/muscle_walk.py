"""The muscle-driven walker: the planar skeleton moved by 14 Hill-type muscle–tendon units under
a reflex controller (Geyer & Herr 2010), with each muscle's metabolic rate.

Model: the same seven-segment MuJoCo walker as the torque-driven one
(:mod:`afo_mj.human.walker`), with its PD servos switched off (zero gains), its joint torque
motors carrying the muscles' torques (no strength clamp: the muscles' own force–length–
velocity relations and activations limit them), hinge limits active, and the pelvis residual
actuators at zero. The controller and the muscles are one compiled law,
:func:`afo_mj.gait.reflex_law.reflex_step`, declared as a human controller
(:class:`afo_mj.gait.reflex_controller.ReflexController`) and walked by the walk every
controller has (:class:`afo_mj.gait.controller_walk.ControllerWalk`): its loop (events, soft
limits, a coupled device, ``mj_step``, recording, checks) runs compiled
(:mod:`afo_mj.gait.controller_loop`, the controller's compiled step called by address, no
Python per step) where it can — no device or a coupled device with C entry points, and no
external action torque — and in Python otherwise (one compiled law call and one ``mj_step``
per 1 ms step). Both give the same walk bit for bit.

Start (Geyer & Herr 2010): the left leg in stance (hip 5° flexed, knee 5°, ankle 5°
dorsiflexed), the right leg swinging forward (hip 40°, knee 5°, ankle 0°), trunk leaning
6°, moving forward at ``initial_speed_m_s``; the lowest contact point on the floor.

The result (:class:`MuscleWalk`) holds a :class:`~afo_mj.gait.record.GaitRecord` (so every
gait metric and figure of the torque walker applies: heel strikes are stance onsets, toe offs
stance ends) and, per step and muscle, the excitation, activation, tendon force, CE velocity
and the metabolic rates by Umberger (2010) and Bhargava et al. (2004); whole-body rates add
the basal 1.2 W/kg.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from afo_mj.gait import reflex_law as rl
from afo_mj.gait.controller_walk import ControllerWalk
from afo_mj.gait.record import GaitRecord
from afo_mj.human.metabolics import basal_rate_w
from afo_mj.human.walker import WalkerParams, WalkerPhysics, build_walker

__all__ = ["MuscleWalk", "reflex_params", "build_muscle_walker", "muscle_table_scaled",
           "run_muscle_walk", "MuscleWalkStepper", "load_reflex_set", "MUSCLE_SOLE_PITCH_RAD"]

GRAVITY_M_S2 = 9.81
#: the muscle signals a muscle walk's record holds (``record.signals``), each ``(n, 2, 7)``,
#: in :class:`MuscleWalk`'s field order: excitation, activation, tendon force (N), CE velocity
#: (m/s), metabolic rate by Umberger 2010 and by Bhargava 2004 (W)
MUSCLE_SIGNALS = ("excitation", "activation", "force_n", "ce_velocity_m_s",
                  "metabolic_umberger_w", "metabolic_bhargava_w")
#: the stature Geyer & Herr's muscle lengths are for (m)
REFERENCE_HEIGHT_M = 1.75
#: fall: hip below this drop from its start (m, for a 1.75 m walker) or trunk beyond 1 rad
FALL_DROP_M = 0.25
FALL_TILT_RAD = 1.0
#: the muscle walker's heel–ball line at a 0 ankle angle: level, so that a flat foot under a
#: vertical shank reads 0 as in Winter's data (anatomical neutral). The torque walker pitches
#: it 6° toe-up (``WalkerParams.sole_pitch_rad``) so that its tracking controller loads the
#: heel at Winter's neutral; under the reflex controller that pitch put flat-foot stance at
#: −6° and was a third of the ankle's RMS against Winter.
MUSCLE_SOLE_PITCH_RAD = 0.0


def reflex_params(overrides: dict | None = None) -> np.ndarray:
    """The controller's parameter vector ``P``: Geyer & Herr's (2010) values
    (:data:`afo_mj.gait.reflex_law.DEFAULTS`) with ``overrides`` by name. A name not in the
    set, or a value that is not a finite number, raises ValueError naming it."""
    p = dict(rl.DEFAULTS)
    for k, v in (overrides or {}).items():
        if k not in p:
            raise ValueError(f"reflex parameter {k!r}; allowed: {', '.join(rl.PARAM_NAMES)}")
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
            raise ValueError(f"reflex parameter {k} = {v!r}; allowed: a finite number")
        p[k] = float(v)
    return np.array([p[n] for n in rl.PARAM_NAMES])


def load_reflex_set(path) -> np.ndarray:
    """The parameter vector of a ``reflex_params.json`` (``afo-mj optimize-gait``'s file: by
    name; missing names keep Geyer & Herr's values). A file of another format raises
    ValueError naming it."""
    import json
    from pathlib import Path
    doc = json.loads(Path(path).read_text(encoding="utf-8"))
    if doc.get("format") != "afo_mj reflex parameters v1":
        raise ValueError(f"{path}: format {doc.get('format')!r}; allowed: "
                         "'afo_mj reflex parameters v1'")
    return reflex_params(doc["parameters"])


def build_muscle_walker(walker: WalkerParams, worn_masses=()) -> WalkerPhysics:
    """The walker with zero PD gains, hinge limits on, torque motors unclamped (the
    strength parameters at their upper bounds: the muscles limit themselves) and the sole
    level at the neutral ankle (:data:`MUSCLE_SOLE_PITCH_RAD`)."""
    w = dataclasses.replace(walker, sole_pitch_rad=MUSCLE_SOLE_PITCH_RAD,
                            hip_knee_strength_nm_per_kg=6.0,
                            plantarflexor_strength_nm_per_kg=5.0,
                            dorsiflexor_strength_nm_per_kg=3.0,
                            plantarflexor_strength_fraction=1.0,
                            dorsiflexor_strength_fraction=1.0)
    zero = {"hip": 0.0, "knee": 0.0, "ankle": 0.0}
    root = build_walker(w, worn_masses, kp=zero, kv=zero)
    for s in ("r", "l"):
        for j in ("hip", "knee", "ankle"):
            root.find("joint", f"{j}_{s}").limited = "true"
            root.find("joint", f"{j}_{s}").actuatorfrclimited = "false"
    return WalkerPhysics(root)


@dataclasses.dataclass
class MuscleWalk:
    """A muscle-driven walk: the gait ``record`` and per step and muscle ``(n, 2, 7)``
    (:data:`afo_mj.gait.reflex_law.MUSCLES` order) excitation, activation, tendon force (N),
    CE velocity (m/s), metabolic rate (W) by Umberger 2010 and by Bhargava 2004."""

    record: GaitRecord
    excitation: np.ndarray
    activation: np.ndarray
    force_n: np.ndarray
    ce_velocity_m_s: np.ndarray
    metabolic_umberger_w: np.ndarray
    metabolic_bhargava_w: np.ndarray
    muscles: tuple = rl.MUSCLES

    def metabolic_rate_w(self, model: str = "umberger") -> np.ndarray:
        """(n,) whole-body metabolic rate: every muscle plus the basal rate."""
        arr = {"umberger": self.metabolic_umberger_w,
               "bhargava": self.metabolic_bhargava_w}.get(model)
        if arr is None:
            raise ValueError(f"model = {model!r}; allowed: 'umberger', 'bhargava'")
        return arr.sum(axis=(1, 2)) + basal_rate_w(self.record.body_mass_kg)

    def cost_of_transport(self, t0_s: float, t1_s: float, model: str = "umberger",
                          net: bool = True) -> float:
        """Metabolic energy per kg and metre walked between ``t0_s`` and ``t1_s`` (J/(kg m));
        ``net`` leaves out the basal rate."""
        r = self.record
        sel = (r.time_s > t0_s) & (r.time_s <= t1_s)
        if sel.sum() < 2:
            raise ValueError(f"[{t0_s}, {t1_s}] s holds fewer than 2 samples of the walk "
                             f"(0 … {r.time_s[-1]:.3f} s)")
        rate = self.metabolic_rate_w(model)[sel]
        if net:
            rate = rate - basal_rate_w(r.body_mass_kg)
        energy = float(rate.sum() * r.sample_period_s)
        dist = float(r.pelvis_position_m[sel][-1, 0] - r.pelvis_position_m[sel][0, 0])
        if not dist > 0:
            raise ValueError(f"the walker did not move forward between {t0_s} and {t1_s} s")
        return energy / (r.body_mass_kg * dist)


def muscle_table_scaled(timestep_s: float, max_force_scale: dict | None = None,
                        height_m: float = REFERENCE_HEIGHT_M) -> np.ndarray:
    """The compiled law's muscle table for a walker of stature ``height_m`` with each named
    muscle's maximum isometric force scaled (both legs), e.g. ``{"soleus": 0.5,
    "gastrocnemius": 0.5}`` for a plantarflexor weakness (masses, and so the metabolic
    models' scale, stay). A name not in :data:`afo_mj.gait.reflex_law.MUSCLES` or a factor
    outside (0, 2] raises ValueError.

    Body size by geometric similarity from Geyer & Herr's 1.75 m adult (their lengths):
    with ``s = height_m / 1.75`` the optimal fibre and slack lengths and the moment arms
    scale by ``s``, the maximum force by ``s²`` (cross-section) and the muscle mass by ``s³``
    (volume); maximum velocities are in optimal lengths per second and neural delays are
    kept. A body mass other than 75 kg at the same stature keeps the muscles (a heavier or
    lighter person of the same build carries it with the same muscles)."""
    T = rl.muscle_table(timestep_s)
    sc = float(height_m) / REFERENCE_HEIGHT_M
    if not 0.3 <= sc <= 1.5:
        raise ValueError(f"height_m = {height_m!r}; allowed: 0.5 … 2.6 m")
    if sc != 1.0:
        T[:, rl.T_LOPT] *= sc
        T[:, rl.T_LSLACK] *= sc
        T[:, rl.T_FMAX] *= sc * sc
        T[:, rl.T_MASS] *= sc ** 3
        for q in range(2):
            T[:, rl.T_PATH + rl.PATH_W * q + 2] *= sc          # r_0 of each path
    for name, f in (max_force_scale or {}).items():
        if name not in rl.MUSCLES:
            raise ValueError(f"max_force_scale[{name!r}]; allowed: {', '.join(rl.MUSCLES)}")
        if isinstance(f, bool) or not isinstance(f, (int, float)) or not 0.0 < f <= 2.0:
            raise ValueError(f"max_force_scale[{name!r}] = {f!r}; allowed: 0 < factor <= 2")
        T[rl.MUSCLES.index(name), rl.T_FMAX] *= float(f)
    return T


class MuscleWalkStepper(ControllerWalk):
    """A steppable walk of the muscle-driven walker: the reflex controller
    (:class:`afo_mj.gait.reflex_controller.ReflexController`) stepped by
    :class:`afo_mj.gait.controller_walk.ControllerWalk` — :meth:`reset`, :meth:`step` (one
    1 ms step: the reflex law, the device and one ``mj_step``), named accessors of the state,
    :attr:`done` and :meth:`record` (the :class:`MuscleWalk` of the steps so far).
    :func:`run_muscle_walk` is its :meth:`run` (every step to the end in one compiled call),
    so a walk stepped here to its end is what ``run_muscle_walk`` returns, bit for bit. The
    arguments are :func:`run_muscle_walk`'s.

    ``step(action)``: ``action`` an extra ankle torque per side (N·m, + dorsiflexion, right
    then left) applied for this step beside the muscles and any device (``device_torque``
    or ``device``), and recorded with the device's in ``device_moment_nm``; None applies
    nothing. The walk is over (:attr:`done`) when the walker fell or ``duration_s`` is
    walked; a diverging state raises FloatingPointError (from :meth:`step`, or from
    :meth:`record` for a warning MuJoCo raised without resetting).

    ``loop``: where a step runs: ``"compiled"`` (:mod:`afo_mj.gait.controller_loop`, the
    reflex controller's compiled step; refused, ValueError, with a ``device_torque`` callable
    or a device without ``native_coupling``, and ``step(action)`` with an action is then
    refused too), ``"python"`` (the reference step), ``"auto"`` (default) compiled where it
    applies — ``step()`` with no action and no action the step before — and Python otherwise.

    Example::

        w = MuscleWalkStepper(WalkerParams(), load_reflex_set(path), duration_s=5.0)
        while not w.done:
            w.step()
        walk = w.record()
    """

    def __init__(self, walker: WalkerParams | None = None, params: np.ndarray | None = None,
                 duration_s: float = 10.0, initial_speed_m_s: float = 1.3,
                 worn_masses=(), device_torque=None, device=None,
                 max_force_scale: dict | None = None, loop: str = "auto"):
        from afo_mj.gait.controller import ControllerSetup
        from afo_mj.gait.reflex_controller import ReflexController, ReflexControllerParams
        w = walker or WalkerParams()
        if loop not in ("auto", "compiled", "python"):
            raise ValueError(f"loop = {loop!r}; allowed: 'auto', 'compiled', 'python'")
        P = reflex_params() if params is None else np.asarray(params, dtype=float)
        if P.shape != (rl.N_P,) or not np.all(np.isfinite(P)):
            raise ValueError(f"params: shape {P.shape}; allowed: {rl.N_P} finite numbers "
                             f"(reflex_params)")
        if not (duration_s > 0 and math.isfinite(duration_s)):
            raise ValueError(f"duration_s = {duration_s!r}; allowed: finite > 0")
        if device is not None and device_torque is not None:
            raise ValueError("run_muscle_walk: both device and device_torque given; "
                             "allowed: one")
        if loop == "compiled" and device_torque is not None:
            raise ValueError("loop = 'compiled' needs no device_torque: a Python callable's "
                             "torque runs in the Python loop; allowed: 'auto', 'python'")
        self.walker, self.params = w, P
        ctl = ReflexController(
            ReflexControllerParams(gains=tuple(P), initial_speed_m_s=initial_speed_m_s,
                                   max_force_scale=tuple((max_force_scale or {}).items())),
            ControllerSetup(walker=w))
        dev = device if device_torque is None else _TorqueCallback(device_torque)
        super().__init__(ctl, duration_s, None, worn_masses, dev, loop)

    @property
    def _X(self) -> np.ndarray:
        """The reflex law's state (:mod:`afo_mj.gait.reflex_law` ``X_*`` offsets)."""
        return self.controller._X

    @property
    def stance(self) -> np.ndarray:
        """(2,) bool: the reflex controller's stance state per leg."""
        return self.controller.stance

    def run(self) -> MuscleWalk:
        """Step to the walk's end (in one call of the compiled loop where it applies) and
        return :meth:`record` (built once: :meth:`ControllerWalk.run` returns this class's
        :meth:`record`)."""
        return super().run()

    def record(self) -> MuscleWalk:
        """The :class:`MuscleWalk` of the steps so far (its record carries the muscles'
        signals in ``record.signals``, the same arrays). Raises FloatingPointError when MuJoCo
        met a non-finite or huge control or acceleration on the way."""
        rec = super().record()
        return MuscleWalk(rec, *(rec.signals[n] for n in MUSCLE_SIGNALS))


class _TorqueCallback:
    """A ``device_torque(t, angle2, velocity2, stance2)`` callable as the uncoupled device
    :class:`~afo_mj.gait.controller_walk.ControllerWalk` steps (no gait phase asked)."""

    coupled = False
    needs_phase = False

    def __init__(self, fn):
        self.fn = fn

    def torque_nm(self, t, angle2, velocity2, phase, stance2):
        return self.fn(t, angle2, velocity2, stance2)


def run_muscle_walk(walker: WalkerParams | None = None, params: np.ndarray | None = None,
                    duration_s: float = 10.0, initial_speed_m_s: float = 1.3,
                    worn_masses=(), device_torque=None, device=None,
                    max_force_scale: dict | None = None, loop: str = "auto") -> MuscleWalk:
    """Walk the muscle-driven walker for ``duration_s`` (or until it falls) under the reflex
    parameters ``params`` (:func:`reflex_params`; default Geyer & Herr's):
    :meth:`MuscleWalkStepper.run`.

    ``device_torque(t, angle2, velocity2, stance2) -> (2,)`` optionally adds an ankle torque
    per side (N·m, + dorsiflexion) beside the muscles (an ideal assistance profile).
    ``device``: a coupled orthosis (:class:`afo_mj.circuits.device.CircuitDevice`, e.g. the
    HAFO) stepped with MuJoCo as :func:`afo_mj.gait.walk.run_walk` steps it: each step its
    joint force and extra damping go to MuJoCo (the damping integrated implicitly) and the
    new ankle velocities close its step; its timestep must be the walker's. Its foot switch
    is the reflex controller's stance state. ``max_force_scale``: see
    :func:`muscle_table_scaled`.

    ``loop``: ``"compiled"`` runs the whole walk in one call of the compiled loop
    (:mod:`afo_mj.gait.controller_loop`; refused with a ``device_torque`` callable or a device
    without compiled entry points), ``"python"`` steps it in Python around the same compiled
    law, ``"auto"`` (default) the compiled loop where it applies. Both give the same walk bit
    for bit.
    """
    return MuscleWalkStepper(walker, params, duration_s, initial_speed_m_s, worn_masses,
                             device_torque, device, max_force_scale, loop).run()
