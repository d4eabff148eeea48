"""The muscle-driven walker: the planar skeleton moved by 14 Hill-type muscle–tendon units under
a reflex controller (Geyer & Herr 2010), with each muscle's metabolic rate.

Model: the same seven-segment MuJoCo walker as the torque-driven one
(:mod:`afo_mj.human.walker`), with its PD servos switched off (zero gains), its joint torque
motors carrying the muscles' torques (no strength clamp: the muscles' own force–length–
velocity relations and activations limit them), hinge limits active, and the pelvis residual
actuators at zero. The controller and the muscles are one compiled law,
:func:`afo_mj.gait.reflex_law.reflex_step`. The loop around it (events, soft limits, a coupled
device, ``mj_step``, recording, checks) runs compiled
(:func:`afo_mj.gait.muscle_loop.muscle_walk_steps`, no Python per step) where it can: no
device or a coupled device with C entry points, and no external action torque; otherwise in
Python (:meth:`MuscleWalkStepper.step`'s reference step, one compiled call and one
``mj_step`` per 1 ms step). Both give the same walk bit for bit.

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

import copy
import dataclasses
import math

import mujoco
import numpy as np

from afo_mj.gait import muscle_loop as ml
from afo_mj.gait import reflex_law as rl
from afo_mj.gait.record import GaitEvents, GaitRecord, phase_from_events
from afo_mj.gait.stepped import SteppedWalk
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


class MuscleWalkStepper(SteppedWalk):
    """A steppable walk of the muscle-driven walker, as :class:`afo_mj.gait.walk.Walk` is of
    the torque-driven one: :meth:`reset`, :meth:`step` (one 1 ms step: the reflex law, the
    device and one ``mj_step``), named accessors of the state, :attr:`done` and
    :meth:`record` (the :class:`MuscleWalk` of the steps so far). :func:`run_muscle_walk` is
    its :meth:`run` (every step to the end in one compiled call), so a walk stepped here to
    its end is what ``run_muscle_walk`` returns, bit for bit. The arguments are
    :func:`run_muscle_walk`'s.

    ``step(action)``: ``action`` an extra ankle torque per side (N·m, + dorsiflexion, right
    then left) applied for this step beside the muscles and any device (``device_torque``
    or ``device``), and recorded with the device's in ``device_moment_nm``; None applies
    nothing. The walk is over (:attr:`done`) when the walker fell or ``duration_s`` is
    walked; a diverging state raises FloatingPointError (from :meth:`step`, or from
    :meth:`record` for a warning MuJoCo raised without resetting).

    ``loop``: where a step runs (module docstring): ``"compiled"``
    (:func:`afo_mj.gait.muscle_loop.muscle_walk_steps`; refused, ValueError, with a
    ``device_torque`` callable or a device without ``native_coupling``, and ``step(action)``
    with an action is then refused too), ``"python"`` (the reference step), ``"auto"``
    (default) compiled where it applies — ``step()`` with no action and no action the step
    before — and Python otherwise.

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
        native = None
        if loop != "python" and device is not None:
            coupling = getattr(device, "native_coupling", None)
            native = coupling() if coupling is not None else None
            if native is None and loop == "compiled":
                raise ValueError("loop = 'compiled' needs a device with compiled entry points "
                                 "(native_coupling); this device steps in Python (e.g. a "
                                 "Python torque_fn); allowed: 'auto', 'python'")
        self.loop = loop
        #: the compiled loop applies (no Python device callable; a device has C entry points)
        self.compiled = loop != "python" and device_torque is None and (
            device is None or native is not None)
        self._native = native
        self._args = (w, P, duration_s, initial_speed_m_s, tuple(worn_masses), device_torque,
                      device, max_force_scale)
        self._stepped = False
        self.reset()

    def reset(self) -> None:
        """Back to the start (Geyer & Herr's posture, a new MuJoCo and reflex state). A
        coupled ``device`` keeps its own state: with one, make a new stepper with a fresh
        device instead (refused here once stepped)."""
        (w, P, duration_s, initial_speed_m_s, worn_masses, device_torque, device,
         max_force_scale) = self._args
        if device is not None and self._stepped:
            raise RuntimeError("MuscleWalkStepper.reset: the device keeps its own state; "
                               "allowed: a new MuscleWalkStepper with a new device")
        phys = build_muscle_walker(w, worn_masses)
        m, d = phys.model, phys.data
        h = float(m.opt.timestep)
        if device is not None and abs(device.timestep_s - h) > 1e-12:
            raise ValueError(f"device timestep_s = {device.timestep_s} differs from the "
                             f"walker's MuJoCo timestep {h}; allowed: equal")
        T = muscle_table_scaled(h, max_force_scale, w.height_m)
        mg = phys.body_mass_kg * GRAVITY_M_S2
        lq, lv = phys.leg_qpos, phys.leg_dof
        q = d.qpos
        start = np.radians([[40.0, 5.0, 0.0], [5.0, 5.0, 5.0]])    # [right swing, left stance]
        for s in range(2):
            q[lq[s]] = start[s]
        q[phys.pelvis_qpos[2]] = rl.DEFAULTS["trunk_lean_ref_rad"]
        d.qvel[phys.pelvis_dof[0]] = initial_speed_m_s * math.sqrt(w.height_m / 1.75)
        mujoco.mj_kinematics(m, d)
        q[phys.pelvis_qpos[1]] -= phys.contact_point_heights_m().min() - 0.0005
        mujoco.mj_forward(m, d)
        X = rl.initial_state(T, start, (False, True), (-0.5, 0.0),
                             float(q[phys.pelvis_qpos[2]]))
        ring = np.zeros((rl.RING_LEN, rl.RING_COLS))
        n_max = int(duration_s / h) + 1
        z0 = float(q[phys.pelvis_qpos[1]])
        drop = FALL_DROP_M * w.height_m / 1.75
        buf = {k_: np.zeros((n_max,) + shp) for k_, shp in (
            ("time", ()), ("qpos", (m.nq,)), ("qvel", (m.nv,)), ("sens", (m.nsensordata,)),
            ("cz", (4,)), ("dev", (2,)), ("u", (2, 7)), ("a", (2, 7)), ("f", (2, 7)),
            ("v", (2, 7)), ("eu", (2, 7)), ("eb", (2, 7)), ("tau", (2, 3)))}
        events = GaitEvents()
        ctrl, ff = d.ctrl, phys.ff_act
        pt_q, pt_v = int(phys.pelvis_qpos[2]), int(phys.pelvis_dof[2])
        pz_q = int(phys.pelvis_qpos[1])
        contact = phys.contact_geoms.ravel()
        dank = phys.leg_dof[:, 2]
        # knee and ankle dofs [side][knee, ankle]: the soft limits' damping joins their own
        dlim = phys.leg_dof[:, 1:3].copy()
        base_limit = m.dof_damping[dlim].copy()
        base_damping = base_limit[:, 1].copy()
        tau = X[rl.X_TAU:rl.X_TAU + 6]
        c_lim = X[rl.X_LIMIT_DAMP:rl.X_LIMIT_DAMP + 6].reshape(2, 3)[:, 1:3]
        stance_x = X[rl.X_STANCE:rl.X_STANCE + 2]
        tau_rec = np.zeros((2, 3))
        reflex_step, mj_step, isfinite = rl.reflex_step, mujoco.mj_step, np.isfinite
        hs_s, to_s = events.heel_strikes_s, events.toe_offs_s
        b_time, b_qpos, b_qvel, b_sens, b_cz, b_dev = (buf[n] for n in (
            "time", "qpos", "qvel", "sens", "cz", "dev"))
        b_u, b_a, b_f, b_v, b_eu, b_eb, b_tau = (buf[n] for n in (
            "u", "a", "f", "v", "eu", "eb", "tau"))
        qvel, sens, gxpos, qfrc_applied, dof_damping = (d.qvel, d.sensordata, d.geom_xpos,
                                                        d.qfrc_applied, m.dof_damping)
        touch = phys.touch_adr
        k = 0
        lim_was = False
        acted = False
        done = [False]
        over = ("MuscleWalkStepper.step: the walk is over (fell or its duration walked); "
                "allowed: reset() (no device) or a new MuscleWalkStepper")

        def step_python(action=None):
            # the reference step: muscle_loop.muscle_walk_steps is this, compiled
            nonlocal k, lim_was, acted
            if done[0]:
                raise RuntimeError(over)
            t = d.time
            reflex_step(t, h, q, qvel, sens, lq, lv, touch, pt_q, pt_v, P, T, X, ring, mg)
            for s in range(2):
                code = X[rl.X_EVENT + s]
                if code == 1.0:
                    hs_s[s].append(t)
                elif code == 2.0:
                    to_s[s].append(t)
            ctrl[ff[0, 0]], ctrl[ff[0, 1]], ctrl[ff[0, 2]] = tau[0], tau[1], tau[2]
            ctrl[ff[1, 0]], ctrl[ff[1, 1]], ctrl[ff[1, 2]] = tau[3], tau[4], tau[5]
            # the soft limits' damping, integrated implicitly by MuJoCo (reflex_law, step 5);
            # written only while a limit is (or was, the step before) engaged
            lim_now = bool(c_lim.any())
            if lim_now or lim_was:
                dof_damping[dlim] = base_limit + c_lim
            lim_was = lim_now
            dev = None
            if device_torque is not None:
                dev = np.asarray(device_torque(t, q[lq[:, 2]], qvel[dank], stance_x > 0.5),
                                 float)
                qfrc_applied[dank] = dev
                b_dev[k] = dev
            elif device is not None:
                # end-of-step torque = force − D q̇_{n+1}, D integrated implicitly by MuJoCo
                dev, extra2 = device.begin_step(t, q[lq[:, 2]], qvel[dank], stance_x > 0.5)
                qfrc_applied[dank] = dev
                dof_damping[dank] = base_damping + c_lim[:, 1] + extra2
            if action is not None or acted:
                # an external ankle torque per side (N·m, + dorsiflexion) beside the device's
                a2 = (np.zeros(2) if action is None
                      else np.array([float(action[0]), float(action[1])]))
                qfrc_applied[dank] = a2 if dev is None else dev + a2
                acted = action is not None
            mj_step(m, d)
            if d.time < t:
                # MuJoCo met a huge or non-finite acceleration or control (a diverging muscle
                # state) and reset the state, time included
                done[0] = True
                raise FloatingPointError(f"muscle walk: the simulation diverged at t = "
                                         f"{t:.4f} s (MuJoCo reset its state)")
            if device is not None:
                b_dev[k] = device.end_step(qvel[dank])
            if acted:
                b_dev[k] += a2
            b_time[k] = d.time
            b_qpos[k] = q
            b_qvel[k] = qvel
            b_sens[k] = sens
            b_cz[k] = gxpos[contact, 2]
            b_u[k] = X[rl.X_U:rl.X_U + 14].reshape(2, 7)
            b_a[k] = X[rl.X_ACT:rl.X_ACT + 14].reshape(2, 7)
            b_f[k] = X[rl.X_F:rl.X_F + 14].reshape(2, 7)
            b_v[k] = X[rl.X_VCE:rl.X_VCE + 14].reshape(2, 7)
            b_eu[k] = X[rl.X_EDOT_U:rl.X_EDOT_U + 14].reshape(2, 7)
            b_eb[k] = X[rl.X_EDOT_B:rl.X_EDOT_B + 14].reshape(2, 7)
            # the joint moment: the motors' and the limits' damping at the step's end velocity
            if lim_now:
                tau_rec[:] = tau.reshape(2, 3)
                tau_rec[:, 1:3] -= c_lim * qvel[dlim]
                b_tau[k] = tau_rec
            else:
                b_tau[k] = tau.reshape(2, 3)
            k += 1
            if not isfinite(q).all() or not isfinite(X).all():
                done[0] = True
                raise FloatingPointError(f"muscle walk: non-finite state at t = "
                                         f"{d.time:.4f} s")
            if q[pz_q] < z0 - drop or abs(q[pt_q]) > FALL_TILT_RAD:
                events.fall_time_s = round(float(d.time), 9)   # the sum of steps
                done[0] = True
            elif k >= n_max:
                done[0] = True

        run_compiled = (_compiled_steps(phys, device, self._native, P, T, X, ring, mg,
                                        z0 - drop, buf, events, base_limit, base_damping, done,
                                        over)
                        if self.compiled else None)

        def run(k_end):
            # steps k … k_end − 1 (or to the walk's end) in the compiled loop
            nonlocal k, lim_was
            k, lim_was, err = run_compiled(k, k_end, lim_was)
            if err is not None:
                raise err

        def step(action=None):
            if action is None and run_compiled is not None and not acted:
                run(k + 1)
            else:
                step_python(action)

        self._step, self._done = step, done
        self._step_python, self._run_compiled = step_python, (
            run if run_compiled is not None else None)
        self._steps = lambda: k
        self._acted = lambda: acted
        self.walker, self.params, self.duration_s, self.n_max = w, P, duration_s, n_max
        self.phys, self.model, self.data = phys, m, d
        self.events, self.device = events, device
        self._X, self._buf, self._h = X, buf, h
        self._stepped = False

    # -- stepping --------------------------------------------------------------------------
    def step(self, action=None) -> None:
        """One 1 ms step (class docstring)."""
        if action is not None and self.loop == "compiled":
            raise ValueError("MuscleWalkStepper.step(action): an action torque steps in the "
                             "Python loop; allowed: step() with loop = 'compiled', or "
                             "loop = 'auto' or 'python'")
        self._stepped = True
        self._step(action)

    def run(self) -> MuscleWalk:
        """Step to the walk's end — in one call of the compiled loop where it applies
        (:attr:`compiled`), else the Python step — and return :meth:`record`."""
        self._stepped = True
        if self._run_compiled is not None and not self._acted():
            if not self._done[0]:
                self._run_compiled(self.n_max)
        else:
            step, done = self._step_python, self._done
            while not done[0]:
                step()
        return self.record()

    # -- named accessors (copies of the state) ------------------------------------------------
    @property
    def stance(self) -> np.ndarray:
        """(2,) bool: the reflex controller's stance state per leg."""
        return self._X[rl.X_STANCE:rl.X_STANCE + 2] > 0.5

    @property
    def phase(self) -> np.ndarray:
        """(2,) gait phase per leg now: time since its last heel strike over its last
        stride, clipped to [0, 1] (0 before its second heel strike): the record's
        ``gait_phase`` at the last step."""
        out = np.zeros(2)
        t = self.data.time
        for s in range(2):
            hs = self.events.heel_strikes_s[s]
            if len(hs) >= 2:
                out[s] = min(max((t - hs[-1]) / (hs[-1] - hs[-2]), 0.0), 1.0)
        return out

    @property
    def joint_moment_nm(self) -> np.ndarray:
        """(2, 3) the muscles' joint moments of the last step (N·m; zeros before one)."""
        k = self.steps
        return self._buf["tau"][k - 1].copy() if k else np.zeros((2, 3))

    @property
    def device_moment_nm(self) -> np.ndarray:
        """(2,) the ankle torque of the device and the action in the last step (N·m)."""
        k = self.steps
        return self._buf["dev"][k - 1].copy() if k else np.zeros(2)

    def record(self) -> MuscleWalk:
        """The :class:`MuscleWalk` of the steps so far. Raises FloatingPointError when
        MuJoCo met a non-finite or huge control or acceleration on the way.

        The muscles' signals (six ``(n, 2, 7)`` arrays, most of a record's bytes) are
        read-only views of the stepper's buffers, not copies: a row once stepped is never
        written again (a step writes the row after it; :meth:`reset` makes new buffers), so
        two records of one stepper share them unchanged; the rest of the record is copied."""
        d, phys, w, h = self.data, self.phys, self.walker, self._h
        bad = [w_ for w_ in ("BADQACC", "BADQVEL", "BADCTRL")
               if d.warning[getattr(mujoco.mjtWarning, "mjWARN_" + w_)].number > 0]
        if bad:
            # MuJoCo met a non-finite or huge control or acceleration (a diverging muscle
            # state) and reset the state: what follows is not a walk
            raise FloatingPointError(f"muscle walk: the simulation diverged "
                                     f"({', '.join(bad)}) before t = {d.time:.4f} s")
        k = self.steps
        events = self.events
        b = {key: v[:k] for key, v in self._buf.items()}
        qq, vv = b["qpos"], b["qvel"]
        record = GaitRecord(
            body_mass_kg=w.body_mass_kg, height_m=w.height_m, sample_period_s=h,
            time_s=b["time"].copy(), joint_angle_rad=qq[:, phys.leg_qpos],
            joint_velocity_rad_s=vv[:, phys.leg_dof], joint_moment_nm=b["tau"].copy(),
            device_moment_nm=b["dev"].copy(),
            grf_n=-b["sens"][:, np.stack([phys.foot_force_adr, phys.foot_force_adr + 2], 1)],
            contact_force_n=b["sens"][:, phys.touch_adr],
            contact_height_m=b["cz"].reshape(k, 2, 2) - phys.contact_radius_m,
            pelvis_position_m=np.column_stack([qq[:, phys.pelvis_qpos[0]],
                                               qq[:, phys.pelvis_qpos[1]]
                                               + phys.pelvis_height_offset_m]),
            pelvis_velocity_m_s=vv[:, phys.pelvis_dof[:2]],
            pelvis_tilt_rad=qq[:, phys.pelvis_qpos[2]].copy(),
            residual_force_n=np.zeros((k, 2)), residual_moment_nm=np.zeros(k),
            gait_phase=phase_from_events(b["time"], events), qpos=qq.copy(),
            model_xml=phys.xml)
        record.events = copy.deepcopy(events)
        sig = {name: _read_only(b[key]) for name, key in zip(MUSCLE_SIGNALS, (
            "u", "a", "f", "v", "eu", "eb"))}
        # the muscles' signals travel in the record too (the same arrays)
        record.signals = sig
        return MuscleWalk(record, *sig.values())


def _read_only(a: np.ndarray) -> np.ndarray:
    """A read-only view of ``a``."""
    v = a.view()
    v.flags.writeable = False
    return v


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
    (:mod:`afo_mj.gait.muscle_loop`; refused with a ``device_torque`` callable or a device
    without compiled entry points), ``"python"`` steps it in Python around the same compiled
    law, ``"auto"`` (default) the compiled loop where it applies. Both give the same walk bit
    for bit.
    """
    return MuscleWalkStepper(walker, params, duration_s, initial_speed_m_s, worn_masses,
                             device_torque, device, max_force_scale, loop).run()


def _compiled_steps(phys, device, nc, P, T, X, ring, mg, fall_z, buf, events, base_limit,
                    base_damping, done, over):
    """The compiled loop of a :class:`MuscleWalkStepper` with its arguments bound once
    (``nc``: a coupled device's native coupling, or None); returns ``run(k, k_end,
    lim_was) -> (k, lim_was, error)``, which runs
    :func:`afo_mj.gait.muscle_loop.muscle_walk_steps` from row ``k``, moves the events, a
    coupled device's counters and the end of the walk on, and returns the error the
    Python step raises (FloatingPointError) or None."""
    from afo_mj.gait.native_step import native_step, time_view
    m, d = phys.model, phys.data
    lc = np.zeros(ml.N_LOOP_CONST)
    lc[ml.L_H] = float(m.opt.timestep)
    lc[ml.L_MG] = mg
    lc[ml.L_FALL_Z] = fall_z
    lc[ml.L_FALL_TILT] = FALL_TILT_RAD
    li = np.zeros(ml.N_LOOP_INDEX, dtype=np.int64)
    li[ml.LI_PZ] = int(phys.pelvis_qpos[1])
    li[ml.LI_PT_Q], li[ml.LI_PT_V] = int(phys.pelvis_qpos[2]), int(phys.pelvis_dof[2])
    li[ml.LI_FN] = native_step().mj_step_address
    li[ml.LI_MODEL], li[ml.LI_DATA] = m._address, d._address
    n_max = buf["time"].shape[0]
    ev_time = np.zeros(2 * n_max + 4)
    ev_code = np.zeros((2 * n_max + 4, 2), dtype=np.int64)
    dev_io = np.zeros(6)
    outs = (np.zeros(2), np.zeros(2), np.zeros(2))
    if nc is not None:
        log = nc.log
        if not (log.flags.c_contiguous and nc.buffer.flags.c_contiguous
                and nc.meta.flags.c_contiguous and log.ndim == 3):
            raise AssertionError("device coupling: buffer, layout and log must be C arrays")
        li[ml.LI_DEV_BEGIN], li[ml.LI_DEV_END] = nc.begin_address, nc.end_address
        li[ml.LI_P_IO] = dev_io.ctypes.data
        li[ml.LI_P_BUF] = nc.buffer.ctypes.data
        li[ml.LI_P_META] = nc.meta.ctypes.data
        li[ml.LI_P_LOG] = log.ctypes.data
        li[ml.LI_LOG_N:ml.LI_LOG_S + 1] = log.shape
        li[ml.LI_ANK_R], li[ml.LI_ANK_L] = phys.leg_qpos[:, 2]
        li[ml.LI_DANK_R], li[ml.LI_DANK_L] = phys.leg_dof[:, 2]
        lc[ml.L_BASE_DAMP_R], lc[ml.L_BASE_DAMP_L] = base_damping
        lc[ml.L_DEV_DT] = float(device.timestep_s)
        outs = (nc.force2, nc.damping2, nc.delivered2)
    args = (time_view(d), d.qpos, d.qvel, d.sensordata, d.geom_xpos, d.ctrl,
            d.qfrc_applied, m.dof_damping, P, T, X, ring, phys.leg_qpos, phys.leg_dof,
            phys.touch_adr, np.ascontiguousarray(phys.ff_act, dtype=np.int64),
            np.ascontiguousarray(phys.leg_dof[:, 1:3], dtype=np.int64), base_limit,
            np.ascontiguousarray(phys.contact_geoms.ravel(), dtype=np.int64),
            *(buf[n] for n in ("time", "qpos", "qvel", "sens", "cz", "dev", "u", "a", "f",
                               "v", "eu", "eb", "tau")),
            ev_time, ev_code, lc, li, dev_io, *outs)
    steps_fn = ml.muscle_walk_steps
    hs_s, to_s = events.heel_strikes_s, events.toe_offs_s

    def run(k, k_end, lim_was):
        if done[0]:
            raise RuntimeError(over)
        li[ml.LI_LIM_WAS] = 1 if lim_was else 0
        li[ml.LI_N_EVENTS] = 0
        steps0 = li[ml.LI_DEV_STEPS] = device.steps if nc is not None else 0
        code, k = steps_fn(k, min(k_end, n_max), *args)
        for n in range(int(li[ml.LI_N_EVENTS])):
            (hs_s if ev_code[n, 1] == 1 else to_s)[int(ev_code[n, 0])].append(
                float(ev_time[n]))
        lim_was = bool(li[ml.LI_LIM_WAS])
        err = None
        if code != ml.CHUNK_DONE:
            done[0] = True
        if nc is not None:
            try:
                # the device's own error (DEVICE_NON_FINITE), as its end_step raises it
                device.native_finished(int(li[ml.LI_DEV_STEPS]) - steps0,
                                       float(lc[ml.L_DEV_LAST_T]),
                                       failed=code == ml.DEVICE_NON_FINITE)
            except FloatingPointError as exc:
                err = exc
        if code == ml.DIVERGED:
            # MuJoCo met a huge or non-finite acceleration or control and reset its state
            err = FloatingPointError(f"muscle walk: the simulation diverged at t = "
                                     f"{lc[ml.L_T]:.4f} s (MuJoCo reset its state)")
        elif code == ml.NON_FINITE:
            err = FloatingPointError(f"muscle walk: non-finite state at t = "
                                     f"{d.time:.4f} s")
        elif code == ml.FELL:
            events.fall_time_s = round(float(d.time), 9)   # the sum of steps
        elif k >= n_max:
            done[0] = True
        return k, lim_was, err

    return run
