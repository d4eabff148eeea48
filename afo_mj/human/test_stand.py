"""The ankle test stand: a fixed shank, a free-swinging foot on the ankle hinge, a selectable load.

A bench for orthosis tests (torque–velocity, step and frequency responses, stiffness). Built with
``dm_control.mjcf`` in the style of :mod:`afo_mj.human.walker`:

* ``shank`` is a static body (no joint: welded to the world), vertical, knee at the top, the
  ankle axis at its lower end. Gravity is on (−z).
* ``foot`` hangs on the hinge ``ankle`` with axis (0, −1, 0), so a positive angle is
  dorsiflexion (toes up), as in the walker. Its mass, CoM and inertia are the walker's foot
  (:func:`afo_mj.human.anthropometry.scale_body`, de Leva 1996): CoM ``com_x`` ahead of and
  half the ankle height below the axis in the foot frame. The foot does not touch anything.
* Sites ``shank_cuff``, ``foot_plate`` and ``ankle_axis`` sit where the walker's
  ``*_{side}`` sites sit, so a device attaches the same way.
* Actuator ``device_ankle`` (motor, gear 1, ctrl in N·m) is where an orthosis applies its torque
  (positive = dorsiflexing).

Loads (:class:`StandLoad`): ``free`` (foot swings under gravity), ``locked`` (joint equality
constraint q = ``locked_angle_rad``, isometric test), ``spring`` (joint stiffness with
``springref``: τ = −k·(q − q_rest)), ``inertia`` (free foot with a body of added inertia on the
axis and/or a point mass at a lever along the foot), ``imposed`` (joint equality constraint
whose target ``model.eq_data`` follows a prescribed trajectory every step: a position-controlled
drive). Added inertia/mass and joint damping may be combined with any kind.

Physics used (and checked in ``tests/test_ankle_test_stand.py``):

* Gravity moment of the foot about the axis (generalised force on ``ankle``): with the foot-frame
  CoM (c_x, c_z) rotated by q about −y, its forward offset is x(q) = c_x·cos q − c_z·sin q and
  τ_g(q) = −m·g·x(q) = −m·g·d·sin(q − q_eq), with d = √(c_x² + c_z²) and q_eq = atan2(−c_x, −c_z)
  the angle at which the CoM hangs straight below the axis (the foot hangs plantarflexed, since
  the CoM is ahead of the ankle).
* Small-amplitude compound pendulum: T = 2π·√(I_a / (m·g·d)), I_a = I_cm + m·d² (parallel-axis
  theorem; e.g. Meriam & Kraige, *Engineering Mechanics: Dynamics*, §8 compound pendulum).
* Torsional spring–mass: ω_n = √(k_total / I_a), k_total = k + m·g·d·cos(q − q_eq) (spring plus
  linearised gravity stiffness); static deflection Δq = τ / k_total ≈ τ / k when k ≫ m·g·d.

Reaction torque sign: :attr:`AnkleTestStand.reaction_torque_nm` is the torque the foot (with the
device) exerts on the lock, the drive or the spring, positive in the dorsiflexion direction: what
a load cell between the foot and the stand reads. For a lock at rest it equals device torque +
gravity moment τ_g(q_lock); for an imposed motion the drive applies its negative,
I_a·q̈ − τ_g(q) − τ_device.

Example
-------
>>> stand = AnkleTestStand(load=StandLoad(kind="locked", locked_angle_rad=0.1))
>>> rec = stand.run(20.0, 0.1)
>>> round(float(rec.reaction_torque_nm[-1]) - stand.gravity_torque_nm(0.1), 2)
20.0
"""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path
from typing import Callable, Sequence, Union

import mujoco
import numpy as np
from dm_control import mjcf

from afo_mj.hydraulics.params import ParameterError, Parameters, param
from afo_mj.human.anthropometry import scale_body
from afo_mj.human.walker import WalkerParams, add_foot_segment

__all__ = [
    "LOAD_KINDS",
    "ImposedTrajectory",
    "StandLoad",
    "StandRecord",
    "build_test_stand",
    "AnkleTestStand",
    "write_default_xml",
    "DEFAULT_XML_PATH",
]

#: The loads the stand can put on the foot.
LOAD_KINDS = ("free", "locked", "spring", "inertia", "imposed")

#: Where :func:`write_default_xml` writes by default (repository ``models/mjcf``).
DEFAULT_XML_PATH = Path(__file__).resolve().parents[2] / "models" / "mjcf" / "ankle_test_stand.xml"

# Near-rigid equality constraint: impedance d = 0.9999 everywhere (flat solimp) so the steady
# violation (1 − d)/d · a_unconstrained / K is micro-radians; time constant 2·dt (MuJoCo's
# smallest stable value), critically damped.
_EQ_SOLIMP = [0.9999, 0.9999, 0.001, 0.5, 2.0]


@dataclasses.dataclass(frozen=True)
class ImposedTrajectory:
    """A prescribed ankle angle q(t) [rad] with its velocity q̇(t) [rad/s] (and optionally q̈).

    The acceleration, used only as a feedforward so the drive follows without lag, is the
    central difference of the velocity when not given.
    """

    angle_rad: Callable[[float], float]
    velocity_rad_s: Callable[[float], float]
    acceleration_rad_s2: Callable[[float], float] | None = None

    def __post_init__(self) -> None:
        for name in ("angle_rad", "velocity_rad_s"):
            if not callable(getattr(self, name)):
                raise ParameterError(f"ImposedTrajectory.{name} = {getattr(self, name)!r} "
                                     "is not callable; allowed: a function of time t [s]")
        if self.acceleration_rad_s2 is not None and not callable(self.acceleration_rad_s2):
            raise ParameterError(f"ImposedTrajectory.acceleration_rad_s2 = "
                                 f"{self.acceleration_rad_s2!r}; allowed: None or a function of t")

    def acceleration(self, t: float, h: float = 1e-4) -> float:
        if self.acceleration_rad_s2 is not None:
            return float(self.acceleration_rad_s2(t))
        return (float(self.velocity_rad_s(t + h)) - float(self.velocity_rad_s(t - h))) / (2 * h)

    @classmethod
    def sinusoid(cls, amplitude_rad: float, frequency_hz: float, offset_rad: float = 0.0,
                 phase_rad: float = 0.0) -> "ImposedTrajectory":
        """q(t) = offset + A·sin(2π f t + φ), with exact velocity and acceleration."""
        w = 2 * math.pi * frequency_hz
        return cls(lambda t: offset_rad + amplitude_rad * math.sin(w * t + phase_rad),
                   lambda t: amplitude_rad * w * math.cos(w * t + phase_rad),
                   lambda t: -amplitude_rad * w * w * math.sin(w * t + phase_rad))

    @classmethod
    def sampled(cls, time_s: Sequence[float], angle_rad: Sequence[float],
                velocity_rad_s: Sequence[float] | None = None) -> "ImposedTrajectory":
        """A sampled trajectory, linearly interpolated (held constant outside the samples).

        Without ``velocity_rad_s`` the velocity is the numerical gradient of the angle.
        """
        t = np.asarray(time_s, dtype=float)
        q = np.asarray(angle_rad, dtype=float)
        if t.ndim != 1 or t.shape != q.shape or t.size < 2 or np.any(np.diff(t) <= 0):
            raise ParameterError("ImposedTrajectory.sampled: time_s and angle_rad must be 1-D of "
                                 "equal length >= 2 with time_s strictly increasing; got shapes "
                                 f"{t.shape} and {q.shape}")
        v = np.gradient(q, t) if velocity_rad_s is None else np.asarray(velocity_rad_s, dtype=float)
        if v.shape != t.shape:
            raise ParameterError(f"ImposedTrajectory.sampled: velocity_rad_s shape {v.shape} "
                                 f"differs from time_s shape {t.shape}")
        a = np.gradient(v, t)
        return cls(lambda x: float(np.interp(x, t, q)), lambda x: float(np.interp(x, t, v)),
                   lambda x: float(np.interp(x, t, a)))


@dataclasses.dataclass(frozen=True)
class StandLoad(Parameters):
    """The load on the foot. ``kind`` is one of :data:`LOAD_KINDS`.

    Only the fields of the chosen kind matter, except ``added_*`` and ``joint_damping_*``, which
    are attached for every kind (``inertia`` is a free foot that must have one of them).
    ``imposed`` needs ``trajectory`` (an :class:`ImposedTrajectory`).
    """

    kind: str = "free"
    locked_angle_rad: float = param(0.0, unit="rad", lo=-math.pi, hi=math.pi,
                                    doc="ankle angle held by the lock (locked)")
    spring_stiffness_nm_per_rad: float = param(100.0, unit="N*m/rad", lo=0.0, hi=1e5,
                                               doc="torsional spring stiffness (spring)")
    spring_rest_angle_rad: float = param(0.0, unit="rad", lo=-math.pi, hi=math.pi,
                                         doc="ankle angle at which the spring is relaxed (spring)")
    added_inertia_kg_m2: float = param(0.0, unit="kg*m^2", lo=0.0, hi=10.0,
                                       doc="added moment of inertia about the ankle axis")
    added_mass_kg: float = param(0.0, unit="kg", lo=0.0, hi=50.0,
                                 doc="added point mass on the foot")
    added_mass_lever_m: float = param(0.1, unit="m", lo=-0.5, hi=0.5,
                                      doc="added mass ahead (+) of the ankle axis along the foot "
                                          "x axis, at axis height")
    joint_damping_nm_s_per_rad: float = param(0.0, unit="N*m*s/rad", lo=0.0, hi=1e3,
                                              doc="viscous damping at the ankle (any kind)")
    trajectory: ImposedTrajectory | None = dataclasses.field(default=None, compare=False)

    def check(self) -> None:
        if self.kind not in LOAD_KINDS:
            raise ParameterError(
                f"StandLoad.kind = {self.kind!r} is not a known load kind; allowed: "
                + ", ".join(repr(k) for k in LOAD_KINDS))
        if self.kind == "imposed" and not isinstance(self.trajectory, ImposedTrajectory):
            self.fail("trajectory", "kind 'imposed' needs an ImposedTrajectory "
                      "(ImposedTrajectory.sinusoid / .sampled / callables)")
        if self.kind == "inertia" and self.added_inertia_kg_m2 == 0 and self.added_mass_kg == 0:
            self.fail("added_inertia_kg_m2", "kind 'inertia' needs added_inertia_kg_m2 > 0 or "
                      "added_mass_kg > 0")


def build_test_stand(body_mass_kg: float = 75.0, height_m: float = 1.75,
                     load: StandLoad | None = None, timestep_s: float = 1e-3) -> mjcf.RootElement:
    """Build the stand's MJCF (a ``dm_control.mjcf`` root) for a body size and load.

    The foot (inertial, sites) is built exactly as the walker's (:func:`afo_mj.human.walker.
    build_walker` with default :class:`WalkerParams` for sole geometry); the ankle hinge is
    unlimited so the foot can hang at its gravity equilibrium (≈ −54° for the default foot).
    """
    load = load or StandLoad()
    if not (1e-5 <= timestep_s <= 5e-3):
        raise ParameterError(f"timestep_s = {timestep_s!r} is out of range; "
                             "allowed: 1e-05 <= timestep_s <= 0.005 [s]")
    p = WalkerParams(body_mass_kg=body_mass_kg, height_m=height_m)
    seg = scale_body(p.body_mass_kg, p.height_m)
    s = p.height_m
    sh = seg.shank

    root = mjcf.RootElement(model="ankle_test_stand")
    root.compiler.angle = "radian"
    root.option.timestep = timestep_s
    root.option.integrator = "implicitfast"
    root.visual.headlight.ambient = [0.4, 0.4, 0.4]
    wb = root.worldbody
    wb.add("light", pos=[0, -2, 2], dir=[0, 1, -1])
    knee_z = sh.length_m + seg.ankle_height_m + 0.3  # foot hangs clear of z = 0
    shank = wb.add("body", name="shank", pos=[0, 0, knee_z])  # no joint: static
    shank.add("inertial", pos=[0, 0, -sh.com_from_proximal_m], mass=sh.mass_kg,
              diaginertia=[sh.inertia_kg_m2, sh.inertia_kg_m2, 0.15 * sh.inertia_kg_m2])
    shank.add("geom", name="shank", type="capsule", size=[0.045 * s / 1.75],
              fromto=[0, 0, 0, 0, 0, -sh.length_m], mass=0, contype=0, conaffinity=0,
              rgba=[0.8, 0.6, 0.5, 1])
    shank.add("site", name="shank_cuff", pos=[0.05 * s / 1.75, 0, -0.35 * sh.length_m],
              size=[0.01])
    shank.add("site", name="ankle_axis", pos=[0, 0, -sh.length_m], size=[0.012])

    foot = shank.add("body", name="foot", pos=[0, 0, -sh.length_m])
    foot.add("joint", name="ankle", type="hinge", axis=[0, -1, 0], limited="false",
             damping=load.joint_damping_nm_s_per_rad,
             stiffness=load.spring_stiffness_nm_per_rad if load.kind == "spring" else 0.0,
             springref=load.spring_rest_angle_rad if load.kind == "spring" else 0.0)
    add_foot_segment(foot, seg, p)

    if load.added_inertia_kg_m2 > 0:
        # A flywheel on the axis: inertia only (its 1 mg mass moves no CoM).
        foot.add("body", name="added_inertia", pos=[0, 0, 0]).add(
            "inertial", pos=[0, 0, 0], mass=1e-6, diaginertia=[load.added_inertia_kg_m2] * 3)
    if load.added_mass_kg > 0:
        am = foot.add("body", name="added_mass", pos=[load.added_mass_lever_m, 0, 0])
        am.add("inertial", pos=[0, 0, 0], mass=load.added_mass_kg,
               diaginertia=[1e-9 * load.added_mass_kg] * 3)  # a point mass
        am.add("geom", name="added_mass", type="sphere", size=[0.015], mass=0, contype=0,
               conaffinity=0, rgba=[0.2, 0.2, 0.2, 1])

    if load.kind in ("locked", "imposed"):
        q0 = (load.locked_angle_rad if load.kind == "locked"
              else float(load.trajectory.angle_rad(0.0)))
        root.equality.add("joint", name="ankle_drive", joint1="ankle", polycoef=[q0, 0, 0, 0, 0],
                          solref=[2 * timestep_s, 1.0], solimp=_EQ_SOLIMP)
    root.actuator.add("motor", name="device_ankle", joint="ankle", gear=[1])
    return root


@dataclasses.dataclass(frozen=True)
class StandRecord:
    """Time series of one :meth:`AnkleTestStand.run`; sample k is the state at the start of
    step k with the torques acting during it."""

    time_s: np.ndarray
    angle_rad: np.ndarray
    velocity_rad_s: np.ndarray
    device_torque_nm: np.ndarray
    reaction_torque_nm: np.ndarray
    acceleration_rad_s2: np.ndarray


TorqueInput = Union[None, float, Callable[[float, float, float], float]]


class AnkleTestStand:
    """A compiled ankle test stand with named accessors and a minimal-Python step loop.

    ``initial_angle_rad=None`` starts at rest where the load holds the foot: the lock angle, the
    imposed q(0) (with q̇(0)), the spring–gravity equilibrium, or the gravity equilibrium.
    """

    def __init__(self, body_mass_kg: float = 75.0, height_m: float = 1.75,
                 load: StandLoad | None = None, timestep_s: float = 1e-3,
                 initial_angle_rad: float | None = None):
        self.load = load or StandLoad()
        self.root = build_test_stand(body_mass_kg, height_m, self.load, timestep_s)
        self.xml = self.root.to_xml_string()
        self.model = mujoco.MjModel.from_xml_string(self.xml, self.root.get_assets())
        self.data = mujoco.MjData(self.model)
        m = self.model
        jid = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, "ankle")
        self.qpos_adr = int(m.jnt_qposadr[jid])
        self.dof_adr = int(m.jnt_dofadr[jid])
        self.act = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_ACTUATOR, "device_ankle")
        self.eq = (mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_EQUALITY, "ankle_drive")
                   if m.neq else -1)
        self.foot_body = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, "foot")
        self.site = {n: mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_SITE, n)
                     for n in ("shank_cuff", "foot_plate", "ankle_axis")}
        self.timestep_s = float(m.opt.timestep)
        # Foot subtree (foot + added bodies) mass and CoM in the foot frame, from the model at q=0.
        self.data.qpos[self.qpos_adr] = 0.0
        mujoco.mj_kinematics(m, self.data)
        mujoco.mj_comPos(m, self.data)
        self.moving_mass_kg = float(m.body_subtreemass[self.foot_body])
        c = self.data.subtree_com[self.foot_body] - self.data.xpos[self.foot_body]
        self._com_x, self._com_z = float(c[0]), float(c[2])
        self._g = float(-m.opt.gravity[2])
        #: foot CoM distance from the ankle axis [m] and angle at which it hangs below the axis.
        self.com_distance_m = math.hypot(self._com_x, self._com_z)
        self.equilibrium_angle_rad = math.atan2(-self._com_x, -self._com_z)
        self._traj = self.load.trajectory if self.load.kind == "imposed" else None
        self._ff_gain = (0.0, 0.0)
        self.reset(initial_angle_rad)

    # -- state -----------------------------------------------------------------------------
    def reset(self, angle_rad: float | None = None, velocity_rad_s: float = 0.0) -> None:
        """Back to t = 0 at ``angle_rad`` (None: where the load holds the foot, see class doc)."""
        mujoco.mj_resetData(self.model, self.data)
        if angle_rad is None:
            angle_rad, velocity_rad_s = self._rest_state()
        self.data.qpos[self.qpos_adr] = angle_rad
        self.data.qvel[self.dof_adr] = velocity_rad_s
        if self._traj is not None:
            self._set_target(0.0)
        mujoco.mj_forward(self.model, self.data)
        if self._traj is not None:
            # Reference-acceleration gains of the drive row: a_ref = −B·q̇ − K·imp·(q − target).
            row = int(np.flatnonzero(self.data.efc_id[:self.data.nefc] == self.eq)[0]) \
                if self.data.nefc else -1
            if row >= 0:
                k, b, imp, _ = self.data.efc_KBIP[row]
                self._ff_gain = (float(b), float(k * imp))
            self._set_target(0.0)
            mujoco.mj_forward(self.model, self.data)

    def _rest_state(self) -> tuple[float, float]:
        ld = self.load
        if ld.kind == "locked":
            return ld.locked_angle_rad, 0.0
        if ld.kind == "imposed":
            return float(ld.trajectory.angle_rad(0.0)), float(ld.trajectory.velocity_rad_s(0.0))
        if ld.kind == "spring" and ld.spring_stiffness_nm_per_rad > 0:
            # Newton on k·(q − q_r) − τ_g(q) = 0 (monotone: k + m g d cos > 0 near the answer).
            k, q = ld.spring_stiffness_nm_per_rad, ld.spring_rest_angle_rad
            mgd = self.moving_mass_kg * self._g * self.com_distance_m
            for _ in range(50):
                f = k * (q - ld.spring_rest_angle_rad) - self.gravity_torque_nm(q)
                df = k + mgd * math.cos(q - self.equilibrium_angle_rad)
                step = f / df if df > 0 else 0.0
                q -= step
                if abs(step) < 1e-14:
                    break
            return q, 0.0
        return self.equilibrium_angle_rad, 0.0

    def _set_target(self, t: float) -> None:
        tr = self._traj
        b, k = self._ff_gain
        q = float(tr.angle_rad(t))
        if k > 0:  # feedforward so that q follows with the drive's error dynamics at rest
            q += (b * float(tr.velocity_rad_s(t)) + tr.acceleration(t, self.timestep_s)) / k
        self.model.eq_data[self.eq, 0] = q

    def gravity_torque_nm(self, angle_rad: float) -> float:
        """Gravity moment of the foot (and added mass) on the ankle, dorsiflexion positive:
        τ_g = −m·g·(c_x·cos q − c_z·sin q) = −m·g·d·sin(q − q_eq)."""
        x = self._com_x * math.cos(angle_rad) - self._com_z * math.sin(angle_rad)
        return -self.moving_mass_kg * self._g * x

    # -- named accessors -------------------------------------------------------------------
    @property
    def angle_rad(self) -> float:
        """Ankle angle [rad], positive = dorsiflexion."""
        return float(self.data.qpos[self.qpos_adr])

    @property
    def velocity_rad_s(self) -> float:
        return float(self.data.qvel[self.dof_adr])

    @property
    def time_s(self) -> float:
        return float(self.data.time)

    @property
    def reaction_torque_nm(self) -> float:
        """Torque the foot exerts on the lock/drive/spring-damper [N·m], load-cell sign
        (dorsiflexion positive), evaluated at the start of the last step: −(constraint +
        passive joint torque). Zero for a free foot without damping."""
        i = self.dof_adr
        return -float(self.data.qfrc_constraint[i] + self.data.qfrc_passive[i])

    @property
    def device_torque_nm(self) -> float:
        return float(self.data.ctrl[self.act])

    def apply_device_torque(self, nm: float) -> None:
        """Set the orthosis torque on the ankle [N·m], positive dorsiflexing; held until changed."""
        self.data.ctrl[self.act] = nm

    def step(self) -> None:
        """One MuJoCo step (the imposed drive's target is set for the current time first)."""
        if self._traj is not None:
            self._set_target(self.data.time)
        mujoco.mj_step(self.model, self.data)

    def run(self, torque_fn: TorqueInput, duration_s: float) -> StandRecord:
        """Step for ``duration_s`` with device torque ``torque_fn(t, angle, velocity)`` (or a
        constant, or None for zero) and record the series (see :class:`StandRecord`)."""
        n = int(round(duration_s / self.timestep_s))
        m, d = self.model, self.data
        qa, va, act = self.qpos_adr, self.dof_adr, self.act
        out = np.empty((6, n))
        const = torque_fn is None or not callable(torque_fn)
        tau = 0.0 if torque_fn is None else (float(torque_fn) if const else 0.0)
        traj = self._traj
        qpos, qvel, qacc, ctrl = d.qpos, d.qvel, d.qacc, d.ctrl
        qfc, qfp = d.qfrc_constraint, d.qfrc_passive
        for k in range(n):
            t, q, v = d.time, qpos[qa], qvel[va]
            if not const:
                tau = torque_fn(t, q, v)
            ctrl[act] = tau
            if traj is not None:
                self._set_target(t)
            mujoco.mj_step(m, d)
            out[0, k] = t
            out[1, k] = q
            out[2, k] = v
            out[3, k] = tau
            out[4, k] = -(qfc[va] + qfp[va])
            out[5, k] = qacc[va]
        return StandRecord(*out)

    def run_device(self, device, duration_s: float) -> StandRecord:
        """Step for ``duration_s`` with a coupled hydraulic device on the ankle (a
        :class:`afo_mj.devices.hafo.HafoDevice`, worn on the ``right`` side here): each step
        the device linearises its hydraulics about the current state and hands MuJoCo its
        end-of-step torque as a joint force plus extra joint damping, which MuJoCo's
        implicitfast integrator treats implicitly (see
        :mod:`afo_mj.circuits.stepper`); after the step the new ankle velocity
        closes the device's step. ``device_torque_nm`` records the delivered torque."""
        n = int(round(duration_s / self.timestep_s))
        m, d = self.model, self.data
        qa, va = self.qpos_adr, self.dof_adr
        base = float(self.load.joint_damping_nm_s_per_rad)
        out = np.empty((6, n))
        traj = self._traj
        qpos, qvel, qacc, qfa = d.qpos, d.qvel, d.qacc, d.qfrc_applied
        qfc, qfp = d.qfrc_constraint, d.qfrc_passive
        damp = m.dof_damping
        ang, vel, vnew = np.zeros(2), np.zeros(2), np.zeros(2)
        stance = np.zeros(2, dtype=bool)
        self.data.ctrl[self.act] = 0.0
        try:
            for k in range(n):
                t = d.time
                ang[0] = qpos[qa]
                vel[0] = qvel[va]
                force, extra = device.begin_step(t, ang, vel, stance)
                qfa[va] = force[0]
                damp[va] = base + extra[0]
                if traj is not None:
                    self._set_target(t)
                mujoco.mj_step(m, d)
                vnew[0] = qvel[va]
                tau = device.end_step(vnew)[0]
                out[0, k] = t
                out[1, k] = ang[0]
                out[2, k] = vel[0]
                out[3, k] = tau
                out[4, k] = -(qfc[va] + qfp[va])
                out[5, k] = qacc[va]
        finally:
            damp[va] = base
            qfa[va] = 0.0
        return StandRecord(*out)


def write_default_xml(path: str | Path = DEFAULT_XML_PATH) -> Path:
    """Write the default stand (75 kg, 1.75 m, free load, 1 ms) as MJCF XML; returns the path."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(build_test_stand(75.0, 1.75, StandLoad(kind="free")).to_xml_string())
    return path
