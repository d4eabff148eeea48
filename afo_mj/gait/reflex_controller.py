"""The reflex muscle controller (Geyer & Herr 2010) written against the human controller
interface (:class:`afo_mj.gait.controller.HumanController`).

The law is :func:`afo_mj.gait.reflex_law.reflex_step` (stance detection, the delayed
reflexes, the muscles' activation and contraction dynamics, the soft joint limits and the
metabolic rates, its docstring); this class only declares it — the body it drives (the walker
with its servos off and its hinge limits on, :func:`afo_mj.gait.muscle_walk.
build_muscle_walker`), its start (Geyer & Herr's posture), what it reads, its actuators (the
six joint torque motors), its soft limits' damping (integrated implicitly by MuJoCo) and its
per-muscle signals — so that :class:`afo_mj.gait.controller_walk.ControllerWalk` can step it.
The dedicated stepper :class:`afo_mj.gait.muscle_walk.MuscleWalkStepper` (what ``walker.model =
"muscle"`` runs) is the same walk, so the two are a check on each other:
``tests/test_controller_interface.py`` asserts they record the same walk bit for bit.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from numba import carray

from afo_mj.gait import controller_loop as cl
from afo_mj.gait import reflex_law as rl
from afo_mj.numba_cache import cached_cfunc
from afo_mj.gait.controller import (CompiledStep, ControllerError, ControllerSetup,
                                    HumanController)

__all__ = ["ReflexController", "ReflexControllerParams", "reflex_setup"]


@dataclasses.dataclass(frozen=True)
class ReflexControllerParams:
    """The reflex controller's parameters: ``gains`` (the :data:`afo_mj.gait.reflex_law.
    PARAM_NAMES` vector, e.g. :func:`afo_mj.gait.muscle_walk.load_reflex_set`), the start
    speed (m/s for a 1.75 m walker) and per-muscle maximum-force factors
    (:func:`afo_mj.gait.muscle_walk.muscle_table_scaled`)."""

    gains: tuple = tuple(rl.DEFAULTS.values())
    initial_speed_m_s: float = 1.3
    max_force_scale: tuple = ()

    def __post_init__(self) -> None:
        g = tuple(float(v) for v in self.gains)
        if len(g) != rl.N_P or not all(math.isfinite(v) for v in g):
            raise ControllerError(f"ReflexControllerParams.gains: {len(g)} values; allowed: "
                                  f"{rl.N_P} finite numbers ({', '.join(rl.PARAM_NAMES)})")
        object.__setattr__(self, "gains", g)
        v = self.initial_speed_m_s
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not 0.0 <= v <= 3.0:
            raise ControllerError(f"ReflexControllerParams.initial_speed_m_s = {v!r}; "
                                  f"allowed: 0 … 3 m/s")
        object.__setattr__(self, "max_force_scale", tuple(
            (str(k), float(f)) for k, f in dict(self.max_force_scale).items()))


class ReflexController(HumanController):
    """Geyer & Herr's reflex controller (module docstring)."""

    #: the muscle walker's controller (not registered: ``walker.model = "muscle"`` is built
    #: in, :class:`afo_mj.gait.muscle_walk.MuscleWalkStepper`)
    name = "muscle"
    Params = ReflexControllerParams
    actuators = ("ff",)
    reads = ("time", "qpos", "qvel", "touch")
    signals = {name: (unit, (2, rl.N_MUSCLES)) for name, unit in (
        ("excitation", "1"), ("activation", "1"), ("force_n", "N"),
        ("ce_velocity_m_s", "m/s"), ("metabolic_umberger_w", "W"),
        ("metabolic_bhargava_w", "W"))}

    def build_physics(self, worn_masses=()):
        from afo_mj.gait.muscle_walk import build_muscle_walker
        return build_muscle_walker(self.walker_params(), worn_masses)

    def start(self, phys) -> None:
        """Geyer & Herr's start: left leg in stance (hip 5°, knee 5°, ankle 5°), right leg
        swinging (hip 40°, knee 5°, ankle 0°), trunk leaning 6°, moving forward at
        ``initial_speed_m_s`` × √(stature / 1.75 m); the lowest contact point on the floor."""
        import mujoco

        from afo_mj.gait.muscle_walk import GRAVITY_M_S2, muscle_table_scaled
        w, p = self.walker_params(), self.params
        m, d = phys.model, phys.data
        h = float(m.opt.timestep)
        self._T = muscle_table_scaled(h, dict(p.max_force_scale) or None, w.height_m)
        self._P = np.array(p.gains)
        self._mg = phys.body_mass_kg * GRAVITY_M_S2
        q = d.qpos
        start = np.radians([[40.0, 5.0, 0.0], [5.0, 5.0, 5.0]])
        for s in range(2):
            q[phys.leg_qpos[s]] = start[s]
        q[phys.pelvis_qpos[2]] = rl.DEFAULTS["trunk_lean_ref_rad"]
        d.qvel[phys.pelvis_dof[0]] = p.initial_speed_m_s * math.sqrt(w.height_m / 1.75)
        mujoco.mj_kinematics(m, d)
        q[phys.pelvis_qpos[1]] -= phys.contact_point_heights_m().min() - 0.0005
        mujoco.mj_forward(m, d)
        self._X = rl.initial_state(self._T, start, (False, True), (-0.5, 0.0),
                                   float(q[phys.pelvis_qpos[2]]))
        self._ring = np.zeros((rl.RING_LEN, rl.RING_COLS))
        self._h = h
        X = self._X
        self._tau = X[rl.X_TAU:rl.X_TAU + 6]
        self._c_lim = X[rl.X_LIMIT_DAMP:rl.X_LIMIT_DAMP + 6].reshape(2, 3)[:, 1:3]
        self._args = (h, d.qpos, d.qvel, d.sensordata, phys.leg_qpos, phys.leg_dof,
                      phys.touch_adr, int(phys.pelvis_qpos[2]), int(phys.pelvis_dof[2]),
                      self._P, self._T, X, self._ring, self._mg)

    def step(self, t: float, phys) -> tuple[int, int]:
        rl.reflex_step(t, *self._args)
        ctrl, ff, tau = phys.data.ctrl, phys.ff_act, self._tau
        ctrl[ff[0, 0]], ctrl[ff[0, 1]], ctrl[ff[0, 2]] = tau[0], tau[1], tau[2]
        ctrl[ff[1, 0]], ctrl[ff[1, 1]], ctrl[ff[1, 2]] = tau[3], tau[4], tau[5]
        X = self._X
        return int(X[rl.X_EVENT]), int(X[rl.X_EVENT + 1])

    @property
    def stance(self) -> np.ndarray:
        return self._X[rl.X_STANCE:rl.X_STANCE + 2] > 0.5

    def state_array(self) -> np.ndarray:
        """The reflex law's state ``X`` (checked for finiteness each step)."""
        return self._X

    def joint_damping_nm_s_per_rad(self, phys) -> np.ndarray:
        """The soft limits' damping on [knee, ankle] per side (reflex_law, step 5)."""
        return self._c_lim

    def joint_moments_nm(self, phys) -> np.ndarray:
        """The muscles' joint moments plus the soft limits' damping at the step's end
        velocity."""
        out = self._tau.reshape(2, 3).copy()
        if self._c_lim.any():
            out[:, 1:3] -= self._c_lim * phys.data.qvel[phys.leg_dof[:, 1:3]]
        return out

    def fall_limits(self, phys) -> tuple[float, float]:
        """The muscle walker's: the hip 0.25 m (× stature / 1.75 m) below its start, or the
        trunk beyond 1 rad."""
        from afo_mj.gait.muscle_walk import FALL_DROP_M, FALL_TILT_RAD
        z0 = float(phys.data.qpos[phys.pelvis_qpos[1]])
        return z0 - FALL_DROP_M * self.walker_params().height_m / 1.75, FALL_TILT_RAD

    def compiled(self, phys) -> CompiledStep:
        """The same step compiled (:func:`_reflex_cstep`): the law on this controller's own
        arrays (``X``, the ring, ``P``, ``T``), so the Python and the compiled step can take
        turns within one walk."""
        F = np.concatenate(([self._h, self._mg], self._P))
        idx = np.zeros((9, 3), dtype=np.int64)
        idx[0:2] = phys.leg_qpos
        idx[2:4] = phys.leg_dof
        idx[4:6, 0:2] = phys.touch_adr
        idx[6, 0:2] = int(phys.pelvis_qpos[2]), int(phys.pelvis_dof[2])
        idx[7:9] = phys.ff_act
        T, X, ring = self._T, self._X, self._ring
        for a in (T, X, ring):
            if not a.flags.c_contiguous:
                raise AssertionError("reflex controller: its arrays must be C-contiguous")
        m = phys.model
        block = np.array([m.nq, m.nv, m.nsensordata, F.ctypes.data, F.shape[0],
                          T.ctypes.data, T.shape[0], T.shape[1], X.ctypes.data, X.shape[0],
                          ring.ctypes.data, ring.shape[0], ring.shape[1], idx.ctypes.data,
                          m.nu], dtype=np.int64)
        index = {name: np.arange(off, off + 14).reshape(2, 7) for name, off in (
            ("excitation", rl.X_U), ("activation", rl.X_ACT), ("force_n", rl.X_F),
            ("ce_velocity_m_s", rl.X_VCE), ("metabolic_umberger_w", rl.X_EDOT_U),
            ("metabolic_bhargava_w", rl.X_EDOT_B))}
        return CompiledStep(_reflex_cstep.address, block, X, index, moments_from_out=True,
                            keep=(F, idx, T, X, ring))

    def signal_values(self):
        X = self._X
        return {name: X[off:off + 14].reshape(2, 7) for name, off in (
            ("excitation", rl.X_U), ("activation", rl.X_ACT), ("force_n", rl.X_F),
            ("ce_velocity_m_s", rl.X_VCE), ("metabolic_umberger_w", rl.X_EDOT_U),
            ("metabolic_bhargava_w", rl.X_EDOT_B))}


@cached_cfunc(cl.STEP_SIGNATURE, depends_on=(rl, cl), error_model="numpy")
def _reflex_cstep(t, qpos_p, qvel_p, sens_p, gxpos_p, blk, ctrl_p, out):  # pragma: no cover
    """The reflex controller's compiled step, of :data:`afo_mj.gait.controller_loop.
    STEP_SIGNATURE`: :func:`afo_mj.gait.reflex_law.reflex_step` on the controller's arrays,
    the six joint torques to the torque motors, and ``out`` (events, stance, the soft limits'
    damping, the joint torques). Its block: ``[nq, nv, nsensordata, F, len F, T, rows, cols,
    X, len X, ring, rows, cols, idx, nu]`` with ``F = [h, m g, P…]`` and ``idx`` (9, 3)
    int64: the legs' qpos and dof addresses, the touch sensors, the pelvis tilt's qpos and
    dof, the torque motors."""
    qpos = carray(qpos_p, (blk[0],))
    qvel = carray(qvel_p, (blk[1],))
    sens = carray(sens_p, (blk[2],))
    F = carray(cl.f64_ptr(blk[3]), (blk[4],))
    T = carray(cl.f64_ptr(blk[5]), (blk[6], blk[7]))
    X = carray(cl.f64_ptr(blk[8]), (blk[9],))
    ring = carray(cl.f64_ptr(blk[10]), (blk[11], blk[12]))
    idx = carray(cl.i64_ptr(blk[13]), (9, 3))
    ctrl = carray(ctrl_p, (blk[14],))
    rl.reflex_step(t, F[0], qpos, qvel, sens, idx[0:2], idx[2:4], idx[4:6, 0:2], idx[6, 0],
                   idx[6, 1], F[2:], T, X, ring, F[1])
    for s in range(2):
        for j in range(3):
            ctrl[idx[7 + s, j]] = X[rl.X_TAU + 3 * s + j]
            out[cl.OUT_TAU + 3 * s + j] = X[rl.X_TAU + 3 * s + j]
        out[cl.OUT_EVENT + s] = X[rl.X_EVENT + s]
        out[cl.OUT_STANCE + s] = 1.0 if X[rl.X_STANCE + s] > 0.5 else 0.0
        out[cl.OUT_DAMP + 2 * s] = X[rl.X_LIMIT_DAMP + 3 * s + 1]
        out[cl.OUT_DAMP + 2 * s + 1] = X[rl.X_LIMIT_DAMP + 3 * s + 2]


def reflex_setup(walker=None) -> ControllerSetup:
    """A setup for the reflex controller (it needs no reference or cycle time)."""
    return ControllerSetup(walker=walker)
