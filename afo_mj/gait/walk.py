"""Forward-dynamic walking of the sagittal walker: controller, gait events and the run loop.

The human joint torques come from three parts, all saturated together by each joint's strength
(``actuatorfrcrange`` in the model, :mod:`afo_mj.human.walker`; the plantarflexor limit also
falls with shortening speed, Hill's torque–velocity relation):

* a PD servo inside MuJoCo tracking the reference angle and velocity at the leg's gait phase
  (stiff at hip and knee, softer at the ankle);
* feedforward of the reference joint moment (fraction ``*_feedforward`` of the normative
  moment per kg × body mass);
* balance feedback in the style of SIMBICON (Yin, Loken & van de Panne, ACM TOG 26(3), 2007):
  the trunk is held through the stance hip(s) (τ = −k_p·θ_trunk − k_d·θ̇_trunk: the reaction of
  a hip torque pitches the pelvis), and the swing hip target moves with the deviation of the
  forward velocity from a blend (``foot_placement_speed_adaptation``, default half and half)
  of the no-slip speed of the reference posture at the cadence and the walker's own
  stride-mean speed,
  shaped over the stride like the reference's hip-over-ankle speed (foot placement: a walker
  that is too fast steps further ahead);
* a trunk strategy: a walker slower than the no-slip speed of the reference posture at the
  cadence leans its trunk forward in proportion (a P law, so the speed still settles where
  strength allows: weak push-off gives a slower walk, not a pushed one);
* a toe-clearance reflex: a swinging forefoot closer to the floor than ``swing_clearance_m``
  in mid-swing flexes knee and hip further (the steppage response to foot drop);
* adaptation to an orthosis: its ankle torque is applied beside the muscles (outside their
  strength limit) and the wearer lowers their own ankle feedforward by
  ``assistance_adaptation`` × that torque. A healthy wearer then keeps their gait and hands
  push-off work to the device; a weak one, whose muscles stay at their limit, gets the
  device's torque added and walks closer to normal.

Gait phase per leg is the time since that leg's last heel strike divided by the cycle time
(from the cadence). Heel strike, detected from foot–floor contact force, resets it; the clock
never makes a heel strike: a late contact holds the swing leg at the end of its swing. Contact
stays on throughout swing, so scuffs happen and are counted.

The pelvis carries weak residual actuators (forward, vertical, pitch) whose forces are recorded
as OpenSim reports residuals: forward damping about the stride-mean speed (never a pull toward
a target speed), a soft vertical spring about the stride-mean pelvis height and a soft pitch
spring about the trunk's target. For the first ``warmup_cycles`` they are ``warmup_gain``
times stronger and fade out (a supported start, like a hand on a rail); analysis skips those
strides.

Hot loop: the whole 1 ms step runs in compiled code (:mod:`afo_mj.gait.walk_loop`): the
control law (:mod:`afo_mj.gait.control_law`) reads MuJoCo's state and writes ``data.ctrl`` and
the ankle's torque range, MuJoCo's C ``mj_step`` is called directly
(:mod:`afo_mj.gait.native_step`), events and the raw state go into preallocated buffers, which
become a :class:`~afo_mj.gait.record.GaitRecord` after the run; Python is entered only between
progress updates (``benchmarks/gait_step.py``: 1.16× a bare native ``mj_step``). A device whose
torque is a Python callback runs the same step in a Python loop (``loop="python"``), which
gives the same record bit for bit.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Protocol

import mujoco
import numpy as np

from afo_mj import progress
from afo_mj.gait import control_law as law
from afo_mj.gait.record import GaitEvents, GaitRecord
from afo_mj.gait.stepped import SteppedWalk
from afo_mj.human.anthropometry import scale_body
from afo_mj.human.walker import DynamicScale, WalkerParams, WalkerPhysics, build_walker
from afo_mj.hydraulics.params import Parameters, param

__all__ = ["ControllerParams", "ReferenceTable", "AnkleDevice", "WalkNumericsError",
           "WalkerModelError", "check_torque_walker", "run_walk", "simulate_walk"]

GRAVITY_M_S2 = 9.81
#: contacts this soon after toe off are the forefoot's last touches, not scuffs
TOE_OFF_CHATTER_S = 0.03
#: the walker has fallen when the hip drops below this fraction of its starting height or the
#: trunk pitches more than FALL_TILT_RAD
FALL_HEIGHT_FRACTION = 0.55
FALL_TILT_RAD = 1.0
#: simulated seconds between two progress updates of a walk (when a reporter is active)
PROGRESS_EVERY_S = 0.5


class WalkNumericsError(RuntimeError):
    """The simulation produced a non-finite state (reported with the time it happened)."""


class WalkerModelError(ValueError):
    """A scenario names a walker model (``[walker] model``) that this entry point cannot run:
    it steps the torque-driven walker only, and would walk that one in the named model's
    place. The message names the scenario, the model, the entry point and what runs it."""


def check_torque_walker(scenario, entry_point: str, index: int | None = None) -> None:
    """Refuse a scenario whose ``walker_model`` is not ``"torque"`` with one
    :class:`WalkerModelError` (``entry_point``: what refuses it, e.g. ``"walk_batch"``;
    ``index``: its place in a list of scenarios). :class:`Walk` and everything built on it
    step the torque-driven walker only; ``afo-mj run``
    (:func:`afo_mj.app.run.run_scenario`) runs the muscle walker."""
    model = getattr(scenario, "walker_model", "torque")
    if model == "torque":
        return
    src = getattr(scenario, "source_path", None)
    where = str(src) if src is not None else repr(getattr(scenario, "name", "scenario"))
    at = "" if index is None else f"scenarios[{index}] = "
    run = f"afo-mj run {src}" if src is not None else "afo-mj run SCENARIO"
    raise WalkerModelError(
        f"{at}{where}: walker.model = {model!r} cannot be run by {entry_point}: it steps the "
        f"torque-driven walker only (afo_mj.gait.walk.Walk) and would walk that one in the "
        f"{model} walker's place; allowed here: walker.model = 'torque'; a {model} scenario "
        f"runs with `{run}` (afo_mj.app.run.run_scenario)")


@dataclasses.dataclass(frozen=True)
class ControllerParams(Parameters):
    """Gains of the walking controller for the 75 kg, 1.75 m walker. Other body sizes get them
    scaled by dynamic similarity (:class:`afo_mj.human.walker.DynamicScale`): torque gains by
    mass × stature, damping by mass × stature^1.5, speed gains by 1/√stature, and so on."""

    hip_kp_nm_per_rad: float = param(600.0, unit="N*m/rad", lo=0.0, hi=5000.0)
    knee_kp_nm_per_rad: float = param(600.0, unit="N*m/rad", lo=0.0, hi=5000.0)
    ankle_kp_nm_per_rad: float = param(300.0, unit="N*m/rad", lo=0.0, hi=5000.0)
    hip_kv_nm_s_per_rad: float = param(30.0, unit="N*m*s/rad", lo=0.0, hi=500.0)
    knee_kv_nm_s_per_rad: float = param(30.0, unit="N*m*s/rad", lo=0.0, hi=500.0)
    ankle_kv_nm_s_per_rad: float = param(5.0, unit="N*m*s/rad", lo=0.0, hi=500.0)
    hip_feedforward: float = param(0.7, unit="1", lo=0.0, hi=1.5,
                                   doc="fraction of the reference hip moment fed forward")
    knee_feedforward: float = param(0.7, unit="1", lo=0.0, hi=1.5)
    ankle_feedforward: float = param(0.85, unit="1", lo=0.0, hi=1.5)
    trunk_kp_nm_per_rad: float = param(500.0, unit="N*m/rad", lo=0.0, hi=5000.0,
                                       doc="trunk pitch stiffness through the stance hip")
    trunk_kd_nm_s_per_rad: float = param(150.0, unit="N*m*s/rad", lo=0.0, hi=500.0)
    stance_hip_tracking: float = param(
        1.0, unit="1", lo=0.0, hi=1.0,
        doc="1: the stance hip tracks its reference and adds the trunk torque; 0: SIMBICON's "
            "stance hip, which only holds the trunk upright")
    swing_hip_velocity_gain_rad_s_per_m: float = param(
        0.25, unit="rad*s/m", lo=-5.0, hi=5.0,
        doc="SIMBICON c_v: swing hip target per m/s of speed above the stride-mean profile")
    foot_placement_speed_adaptation: float = param(
        0.5, unit="1", lo=0.0, hi=1.0,
        doc="speed the foot placement regulates about: 1 the walker's own stride-mean speed, "
            "0 the reference posture's no-slip speed, between a blend")
    trunk_lean_gain_rad_s_per_m: float = param(
        1.0, unit="rad*s/m", lo=0.0, hi=5.0,
        doc="forward trunk lean per m/s the stride-mean speed lies below the reference "
            "posture's no-slip speed")
    max_trunk_lean_rad: float = param(0.35, unit="rad", lo=0.0, hi=0.8)
    swing_clearance_m: float = param(0.01, unit="m", lo=0.0, hi=0.1,
                                     doc="forefoot clearance below which the swing leg flexes more")
    swing_clearance_gain_rad_per_m: float = param(
        60.0, unit="rad/m", lo=0.0, hi=200.0,
        doc="extra swing knee flexion per m of clearance deficit (the hip gets half)")
    assistance_adaptation: float = param(
        1.0, unit="1", lo=0.0, hi=1.0,
        doc="fraction of an orthosis' ankle torque by which the wearer lowers their own ankle "
            "feedforward (people walking with ankle assistance reduce their plantarflexor "
            "effort, e.g. Zhang et al. 2017); 0 adds the device on top of unchanged effort")
    residual_tx_damping_n_s_per_m: float = param(100.0, unit="N*s/m", lo=0.0, hi=5000.0)
    residual_tz_stiffness_n_per_m: float = param(500.0, unit="N/m", lo=0.0, hi=50000.0)
    residual_tz_damping_n_s_per_m: float = param(100.0, unit="N*s/m", lo=0.0, hi=5000.0)
    residual_tilt_stiffness_nm_per_rad: float = param(100.0, unit="N*m/rad", lo=0.0, hi=5000.0)
    residual_tilt_damping_nm_s_per_rad: float = param(10.0, unit="N*m*s/rad", lo=0.0, hi=500.0)
    contact_on_fraction: float = param(0.05, unit="1", lo=0.005, hi=0.5,
                                       doc="foot load / body weight that marks heel strike")
    contact_off_fraction: float = param(0.01, unit="1", lo=0.0, hi=0.5,
                                        doc="foot load / body weight below which the foot is off")
    min_swing_phase_for_heel_strike: float = param(
        0.85, unit="1", lo=0.5, hi=0.99, doc="earliest gait phase a contact counts as heel strike")
    initial_speed_m_s: float = param(1.0, unit="m/s", lo=0.0, hi=3.0)
    warmup_cycles: float = param(2.0, unit="1", lo=0.0, hi=10.0,
                                 doc="cycles over which the residual gains fall to 1x")
    warmup_gain: float = param(10.0, unit="1", lo=1.0, hi=100.0,
                               doc="residual gain multiplier at the start (a supported start)")
    speed_filter_time_s: float = param(1.2, unit="s", lo=0.05, hi=20.0,
                                       doc="time constant of the stride-mean speed and height")


# Columns of the reference table.
_ANGLE, _RATE, _MOMENT, _AHEAD, _AHEAD_RATE = slice(0, 3), slice(3, 6), slice(6, 9), 9, 10


class ReferenceTable:
    """The reference gait tabulated on ``n + 1`` phase points for the hot loop.

    Row ``i`` (phase i/n) holds the angles [rad], their rates per unit phase, the moments
    [N·m/kg], the hip's horizontal distance ahead of the stance ankle for an upright trunk and
    its rate per unit phase (leg lengths from :meth:`set_leg`). Linear interpolation on 1000
    points is within 0.01° of Winter's splines.
    """

    def __init__(self, reference, thigh_m: float, shank_m: float, n: int = 1000):
        ph = np.arange(n + 1) / n
        self.n = n
        has = getattr(reference, "has", lambda name: name != "pelvis_tilt_rad")
        #: the walker's pelvis and trunk stay level (upright), so where the reference gives
        #: a pelvic tilt (Schwartz 2008: 11–18° anterior) the hip tracks the thigh's angle
        #: from vertical, hip flexion − pelvic tilt, not the hip flexion measured from a
        #: tilted pelvis (that would flex the walker's thighs by the whole tilt)
        self.hip_from_thigh = bool(has("pelvis_tilt_rad"))

        def angles(p):
            a = np.array(reference.angles_rad(p), float)
            if self.hip_from_thigh:
                a[..., 0] -= reference.channel("pelvis_tilt_rad", p)
            return a

        angle = angles(ph)
        h = 1e-4
        rate = (angles((ph + h) % 1.0) - angles((ph - h) % 1.0)) / (2 * h)
        # A user reference may come without inverse-dynamics moments (kinematics only): the
        # missing moments are fed forward as zero, and the walk rests on the servo and balance.
        from afo_mj.gait.reference import MOMENT_CHANNELS
        #: moment channels the reference lacks (fed forward as zero)
        self.missing_moments = tuple(m for m in MOMENT_CHANNELS if not has(m))
        if self.missing_moments:
            moment = np.column_stack([reference.channel(m, ph) if has(m) else np.zeros_like(ph)
                                      for m in MOMENT_CHANNELS])
        else:
            moment = np.asarray(reference.moments_nm_per_kg(ph), float)
        # Hip ahead of the stance ankle: ankle x relative to the hip is
        # L_t·sin(hip) + L_s·sin(hip − knee) (thigh and shank angles from vertical).
        hip, knee = angle[:, 0], angle[:, 1]
        ahead = -(thigh_m * np.sin(hip) + shank_m * np.sin(hip - knee))
        ahead_rate = -(thigh_m * np.cos(hip) * rate[:, 0]
                       + shank_m * np.cos(hip - knee) * (rate[:, 0] - rate[:, 1]))
        self.table = np.column_stack([angle, rate, moment, ahead, ahead_rate])
        self.step = np.diff(self.table, axis=0)      # row i+1 − row i, for interpolation
        single_support = (ph >= 0.12) & (ph <= 0.5)
        #: mean hip speed over the stance ankle in single support, per unit phase rate
        self.mean_ahead_rate = float(ahead_rate[single_support].mean())
        #: no-slip stride of the reference posture: twice the hip's travel over the leading
        #: ankle from heel strike (phase 0) to the other heel strike (phase 0.5) [m]
        self.geometric_stride_m = 2.0 * float(ahead[n // 2] - ahead[0])

    def angles_rates_moments(self, phase: np.ndarray):
        """Angles, rates per phase and moments per kg at ``phase`` (2,), each (2, 3), by the
        same linear interpolation the compiled control law uses."""
        x = np.clip(np.asarray(phase, float), 0.0, 1.0) * self.n
        i = np.minimum(x.astype(np.int64), self.n - 1)
        r = self.table[i] + (x - i)[:, None] * self.step[i]
        return r[:, _ANGLE], r[:, _RATE], r[:, _MOMENT]


class AnkleDevice(Protocol):
    """What the walk loop needs of an orthosis (issue 4 supplies real ones): the ankle torque
    [N·m, + dorsiflexion] for each leg given time, ankle angle and velocity, gait phase and
    stance flags. The loop applies it to each ankle as a joint torque beside the muscles."""

    def torque_nm(self, t_s: float, angle_rad: np.ndarray, velocity_rad_s: np.ndarray,
                  phase: np.ndarray, stance: np.ndarray) -> np.ndarray: ...


class CoupledAnkleDevice(Protocol):
    """An orthosis with its own stiff dynamics, stepped implicitly with MuJoCo (``coupled =
    True``; :class:`afo_mj.devices.hafo.HafoDevice`). ``begin_step`` returns, per side, a
    joint force and an extra joint damping ``D ≥ 0`` so that the torque MuJoCo integrates is
    ``force − D q̇_{n+1}``, the device's end-of-step torque; ``end_step`` receives ``q̇_{n+1}``
    and returns the delivered torque."""

    coupled: bool
    timestep_s: float

    def begin_step(self, t_s: float, angle_rad: np.ndarray, velocity_rad_s: np.ndarray,
                   stance: np.ndarray) -> tuple[np.ndarray, np.ndarray]: ...

    def end_step(self, velocity_rad_s: np.ndarray) -> np.ndarray: ...


@dataclasses.dataclass
class _Buffers:
    """Raw per-step state, preallocated; turned into a GaitRecord after the run."""

    time: np.ndarray
    qpos: np.ndarray
    qvel: np.ndarray
    qfrc_actuator: np.ndarray
    actuator_force: np.ndarray
    sensors: np.ndarray
    contact_z: np.ndarray
    phase: np.ndarray
    device: np.ndarray

    @classmethod
    def allocate(cls, n: int, model) -> "_Buffers":
        z = np.zeros
        return cls(z(n), z((n, model.nq)), z((n, model.nv)), z((n, model.nv)), z((n, model.nu)),
                   z((n, model.nsensordata)), z((n, 4)), z((n, 2)), z((n, 2)))


class Walk(SteppedWalk):
    """A steppable walk of the torque-driven walker, in the manner of dm_control's ``Physics``:
    :meth:`reset`, :meth:`step` (one MuJoCo step of the controller, the device and the
    physics, returning that step's gait events), named accessors of the state and
    :meth:`record` (the :class:`~afo_mj.gait.record.GaitRecord` of the steps so far).
    :func:`run_walk` is a loop over it (or over the same steps compiled), so a walk stepped
    here to its end is the record ``run_walk`` returns, bit for bit.

    ``step(action)``: ``action`` an extra ankle torque per side (N·m, + dorsiflexion, right
    then left) applied beside the muscles and any device for this step, and recorded with the
    device's in ``device_moment_nm``; None applies nothing. The walk is over (:attr:`done`)
    when the walker fell, when ``strides`` right strides are done or at ``max_time_s``; a
    non-finite state raises :class:`WalkNumericsError`.

    Example::

        w = Walk(WalkerParams(), load_normative(), 1.1396, strides=4)
        while not w.done:
            events = w.step()                 # (right, left): 1 heel strike, 2 toe off, …
        rec = w.record()
    """

    #: event codes :meth:`step` returns per side
    NO_EVENT, HEEL_STRIKE, TOE_OFF, SWING_TOE_CONTACT = 0, 1, 2, 3

    @classmethod
    def from_scenario(cls, scenario, device: "AnkleDevice | CoupledAnkleDevice | None" = None,
                      worn_masses=(), max_time_s: float | None = None,
                      entry_point: str = "Walk.from_scenario") -> "Walk":
        """The walk of a :class:`~afo_mj.scenarios.walk_scenario.WalkScenario`: its walker,
        reference, cycle time, strides and controller. ``walker`` (a
        :class:`~afo_mj.human.walker.WalkerParams`) does not say which model walks, the
        scenario does: a ``walker.model`` other than ``"torque"`` raises
        :class:`WalkerModelError` (naming ``entry_point``) instead of walking the torque
        walker in its place."""
        check_torque_walker(scenario, entry_point)
        reference = scenario.load_reference()
        return cls(scenario.walker, reference, scenario.cycle_time_s(reference),
                   scenario.strides, scenario.controller_params(), worn_masses, device,
                   max_time_s)

    def __init__(self, walker: WalkerParams, reference, cycle_time_s: float, strides: int,
                 controller: ControllerParams | None = None, worn_masses=(),
                 device: "AnkleDevice | CoupledAnkleDevice | None" = None,
                 max_time_s: float | None = None):
        self._args = (walker, reference, cycle_time_s, strides, controller, tuple(worn_masses),
                      device, max_time_s)
        self._stepped = False
        self.reset()

    def reset(self) -> None:
        """Back to the start: the reference posture at right heel strike (a new MuJoCo state
        and a new controller state). A device keeps its own state: with a device, make a new
        Walk with a fresh device instead (refused here once stepped)."""
        (walker, reference, cycle_time_s, strides, controller, worn_masses, device,
         max_time_s) = self._args
        if device is not None and self._stepped:
            raise RuntimeError("Walk.reset: the device keeps its own state (pressures, "
                               "battery, phase estimate); allowed: a new Walk with a new device")

        c = controller or ControllerParams()
        m_body = walker.body_mass_kg
        ds = DynamicScale.of(m_body, walker.height_m)
        kp = (np.array([c.hip_kp_nm_per_rad, c.knee_kp_nm_per_rad, c.ankle_kp_nm_per_rad])
              * ds.torque)
        kv = (np.array([c.hip_kv_nm_s_per_rad, c.knee_kv_nm_s_per_rad, c.ankle_kv_nm_s_per_rad])
              * ds.rotational_damping)
        root = build_walker(walker, worn_masses,
                            kp=dict(zip(("hip", "knee", "ankle"), kp.tolist())),
                            kv=dict(zip(("hip", "knee", "ankle"), kv.tolist())))
        phys = WalkerPhysics(root)
        model, data = phys.model, phys.data
        seg = scale_body(walker.body_mass_kg, walker.height_m)
        table = ReferenceTable(reference, seg.thigh.length_m, seg.shank.length_m)
        T = float(cycle_time_s)
        dt = model.opt.timestep
        weight = phys.body_mass_kg * GRAVITY_M_S2

        # --- initial state: reference posture at right heel strike ------------------------------
        phase = np.array([0.0, 0.5])
        a0, r0, _ = table.angles_rates_moments(phase)
        data.qpos[phys.leg_qpos] = a0
        data.qvel[phys.leg_dof] = r0 / T
        data.qvel[phys.pelvis_dof[0]] = c.initial_speed_m_s * ds.speed
        mujoco.mj_kinematics(model, data)
        data.qpos[phys.pelvis_qpos[1]] -= phys.contact_point_heights_m().min() - 0.001
        mujoco.mj_forward(model, data)

        # --- constants of the loop ----------------------------------------------------------------
        lead_over_T = np.where(kp > 0, kv / np.maximum(kp, 1e-12), 0.0) / T
        lead_hip = float(lead_over_T[0] * T)
        # Reference moments per kg are for a 1.75 m body; a dynamically similar walker of another
        # stature needs them × λ (moment / (m·g·L) is invariant).
        ff = (np.array([c.hip_feedforward, c.knee_feedforward, c.ankle_feedforward]) * m_body
              * ds.length)
        trunk_kp = c.trunk_kp_nm_per_rad * ds.torque
        trunk_kd = c.trunk_kd_nm_s_per_rad * ds.rotational_damping
        alpha_track = c.stance_hip_tracking
        cv = c.swing_hip_velocity_gain_rad_s_per_m / ds.speed
        clear_m = c.swing_clearance_m * ds.length
        clear_gain = c.swing_clearance_gain_rad_per_m / ds.length
        on_n, off_n = c.contact_on_fraction * weight, c.contact_off_fraction * weight
        hs_phase = c.min_swing_phase_for_heel_strike
        alpha = dt / (c.speed_filter_time_s * ds.time)
        warmup_s = max(c.warmup_cycles * T, 1e-9)
        extra_gain = c.warmup_gain - 1.0
        res_tx = c.residual_tx_damping_n_s_per_m * ds.linear_damping
        res_tz = c.residual_tz_stiffness_n_per_m * ds.linear_stiffness
        res_tzd = c.residual_tz_damping_n_s_per_m * ds.linear_damping
        res_tk = c.residual_tilt_stiffness_nm_per_rad * ds.torque
        res_tkd = c.residual_tilt_damping_nm_s_per_rad * ds.rotational_damping
        # No-slip speed of the reference posture at this cadence: the scale of the trunk lean
        # (a P law toward it; the walker is never pushed toward it by a residual).
        v_ref = table.geometric_stride_m / T
        lean_gain, lean_max = c.trunk_lean_gain_rad_s_per_m / ds.speed, c.max_trunk_lean_rad
        ahead_norm = 1.0 / table.mean_ahead_rate
        pf_w_max = walker.plantarflexor_max_velocity_rad_s / ds.time
        hill_a = walker.hill_curvature
        pf_iso = phys.ankle_torque_limits_nm[:, 0].copy()      # negative: plantarflexion

        ctrl, qpos, qvel, qfrc_applied = data.ctrl, data.qpos, data.qvel, data.qfrc_applied
        sens, gxpos = data.sensordata, data.geom_xpos
        if phys.touch_adr.ravel().tolist() != [0, 1, 2, 3]:
            raise AssertionError("walker sensors: the four touch sensors must come first")
        (ank_r, ank_l) = phys.leg_qpos[:, 2].tolist()
        (dank_r, dank_l) = phys.leg_dof[:, 2].tolist()
        pz, pt = int(phys.pelvis_qpos[1]), int(phys.pelvis_qpos[2])
        contact_geoms = phys.contact_geoms.ravel()
        radius = phys.contact_radius_m

        const = np.zeros(law.N_CONST)
        const[[law.C_DT, law.C_INV_T, law.C_ON_N, law.C_OFF_N, law.C_HS_PHASE, law.C_CHATTER_S,
               law.C_ALPHA, law.C_V_REF, law.C_LEAN_GAIN, law.C_LEAN_MAX, law.C_AHEAD_NORM,
               law.C_CV,
               law.C_CLEAR_M, law.C_CLEAR_GAIN, law.C_RADIUS, law.C_TRACK, law.C_LEAD_HIP,
               law.C_TRUNK_KP, law.C_TRUNK_KD, law.C_EXTRA_GAIN, law.C_WARMUP_S, law.C_RES_TX,
               law.C_RES_TZ, law.C_RES_TZD, law.C_RES_TK, law.C_RES_TKD, law.C_PF_W_MAX,
               law.C_HILL_A, law.C_TABLE_N]] = [
            dt, 1.0 / T, on_n, off_n, hs_phase, TOE_OFF_CHATTER_S, alpha, v_ref, lean_gain,
            lean_max, ahead_norm, cv, clear_m, clear_gain, radius, alpha_track, lead_hip, trunk_kp,
            trunk_kd, extra_gain, warmup_s, res_tx, res_tz, res_tzd, res_tk, res_tkd, pf_w_max,
            hill_a, table.n]
        const[law.C_PF_ISO:law.C_PF_ISO + 2] = pf_iso
        const[law.C_LEAD:law.C_LEAD + 3] = lead_over_T
        const[law.C_FF:law.C_FF + 3] = ff
        const[law.C_SPEED_ADAPT] = c.foot_placement_speed_adaptation
        index = np.zeros(law.N_INDEX, dtype=np.int64)
        index[law.I_TOUCH:law.I_TOUCH + 4] = phys.touch_adr.ravel()
        index[law.I_HIP_Q:law.I_HIP_Q + 2] = phys.leg_qpos[:, 0]
        index[law.I_HIP_V:law.I_HIP_V + 2] = phys.leg_dof[:, 0]
        index[law.I_ANKLE_V:law.I_ANKLE_V + 2] = phys.leg_dof[:, 2]
        index[[law.I_PX, law.I_PZ, law.I_PT]] = phys.pelvis_qpos
        index[[law.I_DPX, law.I_DPZ, law.I_DPT]] = phys.pelvis_dof
        index[law.I_BALL:law.I_BALL + 2] = phys.contact_geoms[:, 1]
        index[law.I_ANKLE_J:law.I_ANKLE_J + 2] = phys.ankle_joint
        index[law.I_PD:law.I_PD + 6] = phys.pd_act.ravel()
        index[law.I_FF:law.I_FF + 6] = phys.ff_act.ravel()
        index[[law.I_RES_X, law.I_RES_Z, law.I_RES_T]] = phys.residual_act
        adapt = c.assistance_adaptation
        ff_ank_r, ff_ank_l = int(phys.ff_act[0, 2]), int(phys.ff_act[1, 2])
        state = np.zeros(law.N_STATE)
        state[law.S_PHASE:law.S_PHASE + 2] = (0.0, 0.5)
        state[law.S_TOE_OFF_T:law.S_TOE_OFF_T + 2] = -1.0
        state[law.S_V_MEAN] = c.initial_speed_m_s * ds.speed
        state[law.S_Z_MEAN] = qpos[pz]
        step_fn = law.control_step
        tab, tab_step = table.table, table.step
        actfrc = model.jnt_actfrcrange

        max_time = max_time_s if max_time_s is not None else (strides + 1.5) * T + 1.0
        n_max = int(max_time / dt) + 2
        buf = _Buffers.allocate(n_max, model)
        events = GaitEvents()
        fall_dz = -(1.0 - FALL_HEIGHT_FRACTION) * (phys.pelvis_height_offset_m + qpos[pz])
        device_torque = np.zeros(2)
        coupled = device is not None and getattr(device, "coupled", False)
        dof_damping = model.dof_damping
        base_damp = (float(dof_damping[dank_r]), float(dof_damping[dank_l]))
        stance2 = np.zeros(2, dtype=bool)
        if coupled:
            # the two ankles' angles and velocities as strided views of MuJoCo's state: the
            # device reads them in place (no copies per step); base damping as Python floats
            if ank_l <= ank_r or dank_l <= dank_r:
                raise AssertionError("walker joints: the left ankle must follow the right one")
            ang2 = qpos[ank_r:ank_l + 1:ank_l - ank_r]
            vel2 = qvel[dank_r:dank_l + 1:dank_l - dank_r]
            base_r, base_l = base_damp
        if coupled and abs(getattr(device, "timestep_s", dt) - dt) > 1e-12:
            raise ValueError(f"device timestep_s = {device.timestep_s} differs from the walker's "
                             f"MuJoCo timestep {dt}; allowed: equal")
        phases = state[law.S_PHASE:law.S_PHASE + 2]          # views into the controller state
        swing = state[law.S_SWING:law.S_SWING + 2]
        ev = state[law.S_EVENT:law.S_EVENT + 2]
        right_strides = 0
        k = 0
        done = [False]
        acted = [False]
        a_r = a_l = f_r = f_l = 0.0

        def step(action=None):
            nonlocal right_strides, k, device_torque, a_r, a_l, f_r, f_l
            if done[0]:
                raise RuntimeError("Walk.step: the walk is over (fell, its strides done or its "
                                   "time up); allowed: reset() (no device) or a new Walk")
            t = data.time
            step_fn(t, qpos, qvel, sens, gxpos, state, tab, tab_step, const, index, ctrl, actfrc)
            codes = (int(ev[0]), int(ev[1]))
            if ev[0] or ev[1]:
                for s in (0, 1):
                    code = ev[s]
                    if code == 1.0:
                        events.heel_strikes_s[s].append(t)
                        right_strides += s == 0
                    elif code == 2.0:
                        events.toe_offs_s[s].append(t)
                    elif code == 3.0:
                        events.swing_toe_contacts.append((t, s))
                if right_strides > strides:
                    done[0] = True
                    return codes
            if coupled:
                # Hydraulic device: end-of-step torque = force − D·q̇_{n+1}, D integrated
                # implicitly by MuJoCo (afo_mj.circuits.stepper).
                # (scalars as Python floats: cheaper than numpy scalars, the same IEEE arithmetic)
                stance2[0] = swing[0] < 0.5
                stance2[1] = swing[1] < 0.5
                force2, extra2 = device.begin_step(t, ang2, vel2, stance2)
                f_r, f_l = force2.tolist()
                d_r, d_l = extra2.tolist()
                qfrc_applied[dank_r] = f_r
                qfrc_applied[dank_l] = f_l
                dof_damping[dank_r] = base_r + d_r
                dof_damping[dank_l] = base_l + d_l
                if adapt:
                    # the wearer anticipates the torque at the present ankle velocity
                    v_r, v_l = vel2.tolist()
                    ctrl[ff_ank_r] -= adapt * (f_r - d_r * v_r)
                    ctrl[ff_ank_l] -= adapt * (f_l - d_l * v_l)
            elif device is not None:
                device_torque = device.torque_nm(t, qpos[[ank_r, ank_l]], qvel[[dank_r, dank_l]],
                                                 phases.copy(), swing < 0.5)
                # The orthosis acts on the ankle beside the muscles: as an applied joint torque,
                # outside the muscles' strength limit. The wearer lowers their own ankle effort by
                # `assistance_adaptation` of it (the muscles' limit still applies to what is left).
                qfrc_applied[dank_r], qfrc_applied[dank_l] = device_torque
                if adapt:
                    ctrl[ff_ank_r] -= adapt * device_torque[0]
                    ctrl[ff_ank_l] -= adapt * device_torque[1]

            if action is not None or acted[0]:
                # an external ankle torque per side (N·m, + dorsiflexion) beside the device's
                a_r, a_l = (0.0, 0.0) if action is None else (float(action[0]), float(action[1]))
                if coupled:
                    qfrc_applied[dank_r] = f_r + a_r
                    qfrc_applied[dank_l] = f_l + a_l
                elif device is not None:
                    qfrc_applied[dank_r] = device_torque[0] + a_r
                    qfrc_applied[dank_l] = device_torque[1] + a_l
                else:
                    qfrc_applied[dank_r] = a_r
                    qfrc_applied[dank_l] = a_l
                acted[0] = action is not None

            mujoco.mj_step(model, data)
            if coupled:
                device_torque = device.end_step(vel2)        # vel2 views the new q̇

            # --- record the raw state -------------------------------------------------------------
            buf.time[k] = data.time
            buf.qpos[k] = qpos
            buf.qvel[k] = qvel
            buf.qfrc_actuator[k] = data.qfrc_actuator
            buf.actuator_force[k] = data.actuator_force
            buf.sensors[k] = sens
            buf.contact_z[k] = gxpos[contact_geoms, 2]
            buf.phase[k] = phases
            buf.device[k] = device_torque
            if acted[0]:
                buf.device[k, 0] += a_r
                buf.device[k, 1] += a_l
            k += 1
            check = qpos.sum() + qvel.sum()
            if not math.isfinite(check):
                done[0] = True
                raise WalkNumericsError(f"non-finite walker state at t = {data.time:.4f} s "
                                        f"(qpos={qpos.tolist()}, qvel={qvel.tolist()})")
            if qpos[pz] < fall_dz or abs(qpos[pt]) > FALL_TILT_RAD:
                events.fall_time_s = round(float(data.time), 9)   # the sum of steps, not 4.3419999
                done[0] = True
            elif k >= n_max:
                done[0] = True
            return codes

        self._step = step
        self._done = done
        self.phys, self.model, self.data = phys, model, data
        self.walker, self.strides, self.n_max = walker, strides, n_max
        self.events = events
        self.device = device
        self.coupled = coupled
        self._steps = lambda: k
        self._state, self._buf = state, buf
        self._loop = (state, tab, tab_step, const, index, actfrc, contact_geoms, fall_dz,
                      step_fn, (ank_r, ank_l, dank_r, dank_l, ff_ank_r, ff_ank_l), base_damp,
                      adapt)
        self._radius, self._dt = radius, dt
        self._stepped = False

    # -- stepping --------------------------------------------------------------------------
    def step(self, action=None) -> tuple[int, int]:
        """One step (class docstring); returns the step's event code per side."""
        self._stepped = True
        return self._step(action)

    # -- named accessors (views of MuJoCo's state are copied) ------------------------------
    @property
    def phase(self) -> np.ndarray:
        """(2,) the controller's gait-phase estimate per leg, 0 … 1 from heel strike."""
        return self._state[law.S_PHASE:law.S_PHASE + 2].copy()

    @property
    def stance(self) -> np.ndarray:
        """(2,) bool: the foot is on the ground (the controller's foot switch)."""
        return self._state[law.S_SWING:law.S_SWING + 2] < 0.5

    def record(self) -> GaitRecord:
        """The record of the steps so far."""
        return _assemble(self._buf, self.steps, self.phys, self.walker, self.events,
                         self._radius, self._dt)

    # -- the whole walk ----------------------------------------------------------------------
    def run(self, loop: str = "auto", label: str = "") -> GaitRecord:
        """Step to the end (compiled or in Python, :func:`run_walk`) with progress; returns
        :meth:`record`."""
        if loop not in ("auto", "compiled", "python"):
            raise ValueError(f"loop = {loop!r}; allowed: 'auto', 'compiled', 'python'")
        if self._stepped:
            raise RuntimeError("Walk.run: already stepped; allowed: run() on a fresh Walk")
        device, coupled = self.device, self.coupled
        native = None
        if loop != "python" and coupled and hasattr(device, "native_coupling"):
            native = device.native_coupling()
        compiled = loop != "python" and (device is None or native is not None)
        if loop == "compiled" and not compiled:
            raise ValueError("loop = 'compiled' needs no device or a coupled device with "
                             "compiled entry points (native_coupling); a device whose torque "
                             "is a Python callback runs in the Python loop; allowed: 'auto', "
                             "'python'")
        (state, tab, tab_step, const, index, actfrc, contact_geoms, fall_dz, step_fn, addr,
         base_damp, adapt) = self._loop
        data, model, n_max = self.data, self.model, self.n_max
        T = float(self._args[2])
        rep = progress.reporter()
        # the compiled controller: compiled (first run) or loaded from numba's cache now, with
        # a stage line, rather than silently inside the first step
        progress.compile_stage(step_fn, (data.time, data.qpos, data.qvel, data.sensordata,
                                         data.geom_xpos, state, tab, tab_step, const, index,
                                         data.ctrl, actfrc),
                               "the walking controller", "~2 s")
        if rep.active:
            expected_s = min((self.strides + 1) * T, n_max * self._dt)
            task = rep.task(f"simulating {self.strides} strides"
                            + (f" ({label})" if label else ""), expected_s, "s simulated",
                            fmt=lambda v: f"{v:.1f}")
            report_every = max(int(round(PROGRESS_EVERY_S / self._dt)), 1)
        else:
            task, report_every = None, n_max + 1
        self._stepped = True
        try:
            if compiled:
                dev_args = None
                if native is not None:
                    dev_args = (native, device, addr, base_damp, adapt,
                                float(device.timestep_s))
                k = _compiled_loop(model, data, self._buf, self.events, state, tab, tab_step,
                                   const, index, actfrc, contact_geoms, self.strides, fall_dz,
                                   n_max, task, report_every, dev_args)
                self._steps = lambda: k
                self._done[0] = True
            else:
                step = self._step
                next_report = report_every
                while not self._done[0]:
                    step(None)
                    if self._steps() >= next_report:
                        task.update(min(data.time, task.total))
                        next_report += report_every
        except WalkNumericsError:
            if task is not None:
                task.abort()
            raise
        if task is not None:
            ev = self.events
            el = progress.fmt_duration(task.elapsed())
            task.close(f"{task.label}: {data.time:.1f} s simulated in {el}"
                       + (f" (fell at t = {ev.fall_time_s:.2f} s)"
                          if ev.fall_time_s is not None else ""))
        return self.record()


def run_walk(walker: WalkerParams, reference, cycle_time_s: float, strides: int,
             controller: ControllerParams | None = None, worn_masses=(),
             device: "AnkleDevice | CoupledAnkleDevice | None" = None,
             max_time_s: float | None = None,
             label: str = "", loop: str = "auto") -> GaitRecord:
    """Walk ``strides`` right-leg cycles (or until a fall) and return the record.

    The walker starts in the reference posture at right heel strike (left leg at phase 0.5)
    moving forward at ``controller.initial_speed_m_s``. A fall (hip below 55 % of its start
    height or trunk pitched beyond 1 rad) ends the run and is recorded with its time; a
    non-finite state raises :class:`WalkNumericsError`.

    Progress (:mod:`afo_mj.progress`, silent unless a command line installed a reporter):
    the controller's first compilation, and the simulated time every
    ``PROGRESS_EVERY_S`` simulated seconds (one integer comparison per step otherwise);
    ``label`` names the run in those lines (e.g. a device condition).

    ``loop``: ``"compiled"`` runs the per-step loop in compiled code
    (:mod:`afo_mj.gait.walk_loop`: controller, ``mj_step`` through MuJoCo's C library,
    events, recording, checks; no Python per step), ``"python"`` runs it in Python around the
    same compiled controller, ``"auto"`` (default) the compiled loop where it applies (no
    device, or a coupled device with compiled kernels) and Python otherwise (a device whose
    torque is a Python callback). Both give the same record bit for bit.
    """
    if loop not in ("auto", "compiled", "python"):
        raise ValueError(f"loop = {loop!r}; allowed: 'auto', 'compiled', 'python'")
    return Walk(walker, reference, cycle_time_s, strides, controller, worn_masses, device,
                max_time_s).run(loop, label)



def _compiled_loop(model, data, buf: _Buffers, events: GaitEvents, state, tab, tab_step, const,
                   index, actfrc, contact_geoms, strides: int, fall_dz: float, n_max: int,
                   task, report_every: int, dev_args=None) -> int:
    """Steps of the walk in :func:`afo_mj.gait.walk_loop.walk_steps`, in chunks of
    ``report_every`` when progress is shown (one call otherwise); fills ``buf`` and
    ``events``; returns the rows recorded. ``dev_args``: a coupled device's native coupling,
    the device, its ankle addresses, base damping, the adaptation and the device step."""
    from afo_mj.gait import walk_loop as wl
    from afo_mj.gait.native_step import native_step, time_view
    native = native_step()
    time1 = time_view(data)
    loop_const = np.zeros(wl.N_LOOP_CONST)
    loop_const[wl.L_STRIDES] = strides
    loop_const[wl.L_FALL_DZ] = fall_dz
    loop_const[wl.L_FALL_TILT] = FALL_TILT_RAD
    loop_index = np.zeros(wl.N_LOOP_INDEX, dtype=np.int64)
    loop_index[wl.LI_PZ] = index[law.I_PZ]
    loop_index[wl.LI_PT] = index[law.I_PT]
    loop_index[wl.LI_FN] = native.mj_step_address
    loop_index[wl.LI_MODEL] = model._address
    loop_index[wl.LI_DATA] = data._address
    ev_time = np.zeros(2 * n_max + 4)
    ev_code = np.zeros((2 * n_max + 4, 2), dtype=np.int64)
    dev_io = np.zeros(6)
    outs = (np.zeros(2), np.zeros(2), np.zeros(2))
    device = None
    if dev_args is not None:
        nc, device, addr, base_damp, adapt, dev_dt = dev_args
        log = nc.log
        if not (log.flags.c_contiguous and nc.buffer.flags.c_contiguous
                and nc.meta.flags.c_contiguous and log.ndim == 3):
            raise AssertionError("device coupling: buffer, layout and log must be C arrays")
        loop_index[wl.LI_DEV_BEGIN] = nc.begin_address
        loop_index[wl.LI_DEV_END] = nc.end_address
        loop_index[wl.LI_P_IO] = dev_io.ctypes.data
        loop_index[wl.LI_P_BUF] = nc.buffer.ctypes.data
        loop_index[wl.LI_P_META] = nc.meta.ctypes.data
        loop_index[wl.LI_P_LOG] = log.ctypes.data
        loop_index[wl.LI_LOG_N:wl.LI_LOG_S + 1] = log.shape
        loop_index[wl.LI_DEV_STEPS] = device.steps
        loop_index[wl.LI_ANK_R:wl.LI_FF_L + 1] = addr
        loop_const[wl.L_BASE_DAMP_R], loop_const[wl.L_BASE_DAMP_L] = base_damp
        loop_const[wl.L_ADAPT] = adapt
        loop_const[wl.L_DEV_DT] = dev_dt
        outs = (nc.force2, nc.damping2, nc.delivered2)
    steps0 = int(loop_index[wl.LI_DEV_STEPS])
    cz = buf.contact_z
    args = (time1, data.qpos, data.qvel, data.sensordata, data.geom_xpos, state, tab, tab_step,
            const, index, data.ctrl, actfrc, data.qfrc_actuator, data.actuator_force,
            np.ascontiguousarray(contact_geoms, dtype=np.int64), buf.time, buf.qpos, buf.qvel,
            buf.qfrc_actuator, buf.actuator_force, buf.sensors, cz, buf.phase, ev_time, ev_code,
            loop_const, loop_index, data.qfrc_applied, model.dof_damping, dev_io) + outs + (
            buf.device,)
    progress.compile_stage(wl.walk_steps, (0, 0) + args, "the walk loop", "~1 s")
    k = 0
    code = wl.CHUNK_DONE
    while k < n_max:
        k_end = min(k + report_every, n_max) if task is not None else n_max
        code, k = wl.walk_steps(k, k_end, *args)
        if task is not None:
            task.update(min(data.time, task.total))
        if code != wl.CHUNK_DONE:
            break
    if device is not None:
        done = int(loop_index[wl.LI_DEV_STEPS]) - steps0
        if code == wl.DEVICE_NON_FINITE and task is not None:
            task.abort()
        device.native_finished(done, float(loop_const[wl.L_DEV_LAST_T]),
                               failed=code == wl.DEVICE_NON_FINITE)
    for n in range(int(loop_index[wl.LI_N_EVENTS])):
        t, side, kind = float(ev_time[n]), int(ev_code[n, 0]), int(ev_code[n, 1])
        if kind == wl.EV_HEEL_STRIKE:
            events.heel_strikes_s[side].append(t)
        elif kind == wl.EV_TOE_OFF:
            events.toe_offs_s[side].append(t)
        else:
            events.swing_toe_contacts.append((t, side))
    if code == wl.NON_FINITE:
        if task is not None:
            task.abort()
        raise WalkNumericsError(f"non-finite walker state at t = {data.time:.4f} s "
                                f"(qpos={data.qpos.tolist()}, qvel={data.qvel.tolist()})")
    if code == wl.FELL:
        events.fall_time_s = round(float(data.time), 9)   # the sum of steps, not 4.3419999
    return k


def _assemble(buf: _Buffers, n: int, phys: WalkerPhysics, walker: WalkerParams,
              events: GaitEvents, radius: float, dt: float) -> GaitRecord:
    """Build the GaitRecord (named, SI) from the first ``n`` raw samples."""
    q, v = buf.qpos[:n], buf.qvel[:n]
    rec = GaitRecord(
        body_mass_kg=walker.body_mass_kg, height_m=walker.height_m, sample_period_s=dt,
        time_s=buf.time[:n].copy(),
        joint_angle_rad=q[:, phys.leg_qpos],
        joint_velocity_rad_s=v[:, phys.leg_dof],
        joint_moment_nm=buf.qfrc_actuator[:n][:, phys.leg_dof],
        device_moment_nm=buf.device[:n].copy(),
        # ground reaction force = − (force of the foot on the floor), world x and z
        grf_n=-buf.sensors[:n][:, np.stack([phys.foot_force_adr, phys.foot_force_adr + 2], 1)],
        contact_force_n=buf.sensors[:n][:, phys.touch_adr],
        contact_height_m=buf.contact_z[:n].reshape(n, 2, 2) - radius,
        pelvis_position_m=np.column_stack([
            q[:, phys.pelvis_qpos[0]],
            q[:, phys.pelvis_qpos[1]] + phys.pelvis_height_offset_m]),
        pelvis_velocity_m_s=v[:, phys.pelvis_dof[:2]],
        pelvis_tilt_rad=q[:, phys.pelvis_qpos[2]].copy(),
        residual_force_n=buf.actuator_force[:n][:, phys.residual_act[:2]],
        residual_moment_nm=buf.actuator_force[:n][:, phys.residual_act[2]].copy(),
        gait_phase=buf.phase[:n].copy(),
        qpos=q.copy(),
        model_xml=phys.xml,
    )
    rec.events = events
    return rec


def simulate_walk(scenario, device: AnkleDevice | None = None, worn_masses=()) -> GaitRecord:
    """Walk a :class:`~afo_mj.scenarios.walk_scenario.WalkScenario` on the walker it names
    (``walker.model``: the torque walker as :func:`run_walk`, the muscle walker, or a
    registered controller; :mod:`afo_mj.gait.walkers`, as ``afo-mj run`` walks it) and return
    its record. A muscle walk's record carries its muscles' signals in ``record.signals``."""
    from afo_mj.gait.walkers import walk_scenario
    return walk_scenario(scenario, device, tuple(worn_masses))[0]
