"""The torque-driven walker's tracking controller, declared as a human controller
(:class:`afo_mj.gait.controller.HumanController`, ``walker.model = "torque"``): its parameters
(:class:`ControllerParams`), the reference gait tabulated for the law (:class:`ReferenceTable`)
and the packing of the law's constant, address and state arrays. The per-step law itself is one
compiled function, :func:`afo_mj.gait.control_law.control_step`, called by :meth:`
TrackingController.step` (the Python loop of :class:`afo_mj.gait.controller_walk.
ControllerWalk`) and by the compiled 1 ms loop (:mod:`afo_mj.gait.walk_loop`, driven by
:class:`afo_mj.gait.tracking_walk.Walk`), so the two loops walk the same walk bit for bit.

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
"""

from __future__ import annotations

import dataclasses

import mujoco
import numpy as np

from afo_mj.gait import control_law as law
from afo_mj.gait.controller import ControllerSetup, HumanController
from afo_mj.human.anthropometry import scale_body
from afo_mj.human.walker import DynamicScale, WalkerPhysics, build_walker
from afo_mj.hydraulics.params import Parameters, param

__all__ = ["ControllerParams", "ReferenceTable", "TrackingController", "GRAVITY_M_S2",
           "TOE_OFF_CHATTER_S", "FALL_HEIGHT_FRACTION", "FALL_TILT_RAD"]

GRAVITY_M_S2 = 9.81
#: contacts this soon after toe off are the forefoot's last touches, not scuffs
TOE_OFF_CHATTER_S = 0.03
#: the walker has fallen when the hip drops below this fraction of its starting height or the
#: trunk pitches more than FALL_TILT_RAD
FALL_HEIGHT_FRACTION = 0.55
FALL_TILT_RAD = 1.0


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



class TrackingController(HumanController):
    """The torque-driven walker's tracking controller (module docstring) for
    ``setup.walker`` tracking ``setup.reference`` at ``setup.cycle_time_s``. Unlike the base
    class it drives the PD servos too (their gains, scaled by dynamic similarity, are built
    into the model), starts in the reference posture at right heel strike moving at
    ``initial_speed_m_s``, keeps its own gait-phase estimate (the signal ``gait_phase``, which
    the walk records as the record's ``gait_phase``), detects scuffs (event code 3) and lowers
    the ankle feedforward by ``assistance_adaptation`` × a worn device's torque
    (:meth:`answer_device`). It gives no compiled step for the generic loop
    (:mod:`afo_mj.gait.controller_loop` has no device answer nor scuff events): walked by a
    plain ``ControllerWalk`` it steps in Python; :class:`afo_mj.gait.walk.Walk` walks it in
    its own compiled loop (:mod:`afo_mj.gait.walk_loop`), the same walk bit for bit."""

    name = "torque"
    Params = ControllerParams
    actuators = ("ff", "pd", "residual")
    reads = ("time", "qpos", "qvel", "touch")
    signals = {"gait_phase": ("1", (2,))}
    device_response_note = (
        "written-in rule: the wearer lowers their ankle feedforward by assistance_adaptation x "
        "the device's torque")

    def __init__(self, params: ControllerParams | None = None,
                 setup: ControllerSetup | None = None):
        super().__init__(params, setup)
        if setup is None or setup.reference is None or setup.cycle_time_s is None:
            raise ValueError(f"TrackingController: setup = {setup!r}; allowed: a "
                             f"ControllerSetup with a reference and a cycle_time_s")

    def _gains(self):
        c = self.params
        walker = self.walker_params()
        ds = DynamicScale.of(walker.body_mass_kg, walker.height_m)
        kp = (np.array([c.hip_kp_nm_per_rad, c.knee_kp_nm_per_rad, c.ankle_kp_nm_per_rad])
              * ds.torque)
        kv = (np.array([c.hip_kv_nm_s_per_rad, c.knee_kv_nm_s_per_rad, c.ankle_kv_nm_s_per_rad])
              * ds.rotational_damping)
        return ds, kp, kv

    def build_physics(self, worn_masses=()) -> WalkerPhysics:
        """The walker with ``worn_masses`` and the PD servos' gains of :attr:`params`."""
        _, kp, kv = self._gains()
        root = build_walker(self.walker_params(), worn_masses,
                            kp=dict(zip(("hip", "knee", "ankle"), kp.tolist())),
                            kv=dict(zip(("hip", "knee", "ankle"), kv.tolist())))
        return WalkerPhysics(root)

    def start(self, phys: WalkerPhysics) -> None:
        """The reference posture at right heel strike (left leg at phase 0.5), the pelvis at
        ``initial_speed_m_s`` (scaled), the lowest contact point 1 mm into the floor; then the
        law's packed arrays (:meth:`pack`)."""
        c, walker = self.params, self.walker_params()
        ds, kp, kv = self._gains()
        model, data = phys.model, phys.data
        seg = scale_body(walker.body_mass_kg, walker.height_m)
        table = ReferenceTable(self.setup.reference, seg.thigh.length_m, seg.shank.length_m)
        T = float(self.setup.cycle_time_s)
        a0, r0, _ = table.angles_rates_moments(np.array([0.0, 0.5]))
        data.qpos[phys.leg_qpos] = a0
        data.qvel[phys.leg_dof] = r0 / T
        data.qvel[phys.pelvis_dof[0]] = c.initial_speed_m_s * ds.speed
        mujoco.mj_kinematics(model, data)
        data.qpos[phys.pelvis_qpos[1]] -= phys.contact_point_heights_m().min() - 0.001
        mujoco.mj_forward(model, data)
        self.table = table
        self.const, self.index, self.state = self.pack(phys, table, T, ds, kp, kv)
        self._ff_ankle = phys.ff_act[:, 2].copy()
        d = data
        self._args = (d.qpos, d.qvel, d.sensordata, d.geom_xpos, self.state, table.table,
                      table.step, self.const, self.index, d.ctrl, model.jnt_actfrcrange)

    def pack(self, phys: WalkerPhysics, table: ReferenceTable, T: float, ds: DynamicScale,
             kp: np.ndarray, kv: np.ndarray):
        """The law's ``const`` (scalars, scaled by dynamic similarity), ``index`` (MuJoCo
        addresses) and initial ``state`` (:mod:`afo_mj.gait.control_law` layout), for the
        walker ``phys`` in its start posture, the reference ``table`` at cycle time ``T``."""
        c, walker = self.params, self.walker_params()
        model, qpos = phys.model, phys.data.qpos
        dt = model.opt.timestep
        weight = phys.body_mass_kg * GRAVITY_M_S2
        lead_over_T = np.where(kp > 0, kv / np.maximum(kp, 1e-12), 0.0) / T
        lead_hip = float(lead_over_T[0] * T)
        # Reference moments per kg are for a 1.75 m body; a dynamically similar walker of another
        # stature needs them × λ (moment / (m·g·L) is invariant).
        ff = (np.array([c.hip_feedforward, c.knee_feedforward, c.ankle_feedforward])
              * walker.body_mass_kg * ds.length)
        # No-slip speed of the reference posture at this cadence: the scale of the trunk lean
        # (a P law toward it; the walker is never pushed toward it by a residual).
        v_ref = table.geometric_stride_m / T
        if phys.touch_adr.ravel().tolist() != [0, 1, 2, 3]:
            raise AssertionError("walker sensors: the four touch sensors must come first")
        const = np.zeros(law.N_CONST)
        const[[law.C_DT, law.C_INV_T, law.C_ON_N, law.C_OFF_N, law.C_HS_PHASE, law.C_CHATTER_S,
               law.C_ALPHA, law.C_V_REF, law.C_LEAN_GAIN, law.C_LEAN_MAX, law.C_AHEAD_NORM,
               law.C_CV,
               law.C_CLEAR_M, law.C_CLEAR_GAIN, law.C_RADIUS, law.C_TRACK, law.C_LEAD_HIP,
               law.C_TRUNK_KP, law.C_TRUNK_KD, law.C_EXTRA_GAIN, law.C_WARMUP_S, law.C_RES_TX,
               law.C_RES_TZ, law.C_RES_TZD, law.C_RES_TK, law.C_RES_TKD, law.C_PF_W_MAX,
               law.C_HILL_A, law.C_TABLE_N]] = [
            dt, 1.0 / T, c.contact_on_fraction * weight, c.contact_off_fraction * weight,
            c.min_swing_phase_for_heel_strike, TOE_OFF_CHATTER_S,
            dt / (c.speed_filter_time_s * ds.time), v_ref,
            c.trunk_lean_gain_rad_s_per_m / ds.speed, c.max_trunk_lean_rad,
            1.0 / table.mean_ahead_rate, c.swing_hip_velocity_gain_rad_s_per_m / ds.speed,
            c.swing_clearance_m * ds.length, c.swing_clearance_gain_rad_per_m / ds.length,
            phys.contact_radius_m, c.stance_hip_tracking, lead_hip,
            c.trunk_kp_nm_per_rad * ds.torque, c.trunk_kd_nm_s_per_rad * ds.rotational_damping,
            c.warmup_gain - 1.0, max(c.warmup_cycles * T, 1e-9),
            c.residual_tx_damping_n_s_per_m * ds.linear_damping,
            c.residual_tz_stiffness_n_per_m * ds.linear_stiffness,
            c.residual_tz_damping_n_s_per_m * ds.linear_damping,
            c.residual_tilt_stiffness_nm_per_rad * ds.torque,
            c.residual_tilt_damping_nm_s_per_rad * ds.rotational_damping,
            walker.plantarflexor_max_velocity_rad_s / ds.time, walker.hill_curvature, table.n]
        # negative: the plantarflexion limit per side
        const[law.C_PF_ISO:law.C_PF_ISO + 2] = phys.ankle_torque_limits_nm[:, 0]
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
        state = np.zeros(law.N_STATE)
        state[law.S_PHASE:law.S_PHASE + 2] = (0.0, 0.5)
        state[law.S_TOE_OFF_T:law.S_TOE_OFF_T + 2] = -1.0
        state[law.S_V_MEAN] = c.initial_speed_m_s * ds.speed
        state[law.S_Z_MEAN] = qpos[int(phys.pelvis_qpos[1])]
        return const, index, state

    def step(self, t: float, phys) -> tuple[int, int]:
        """The law (:func:`afo_mj.gait.control_law.control_step`) at ``t``: writes the
        servos' targets, the motors' and residuals' torques and the ankle's torque range;
        returns this step's event codes (1 heel strike, 2 toe off, 3 scuff)."""
        law.control_step(t, *self._args)
        ev = self.state
        return int(ev[law.S_EVENT]), int(ev[law.S_EVENT + 1])

    @property
    def stance(self) -> np.ndarray:
        """(2,) bool: the law's foot switch (not in swing)."""
        return self.state[law.S_SWING:law.S_SWING + 2] < 0.5

    @property
    def phase(self) -> np.ndarray:
        """(2,) the law's gait-phase estimate per leg (a copy)."""
        return self.state[law.S_PHASE:law.S_PHASE + 2].copy()

    def signal_values(self):
        return {"gait_phase": self.state[law.S_PHASE:law.S_PHASE + 2]}

    def answer_device(self, phys, torque_nm: np.ndarray) -> None:
        """The wearer anticipates a worn device's ankle torque ``torque_nm`` (per side, at the
        present ankle velocity) and lowers their own ankle feedforward by
        ``assistance_adaptation`` × it (the muscles' limit still applies to what is left)."""
        adapt = self.params.assistance_adaptation
        if adapt:
            phys.data.ctrl[self._ff_ankle] -= adapt * torque_nm

    def fall_limits(self, phys) -> tuple[float, float]:
        """The hip below :data:`FALL_HEIGHT_FRACTION` of its start height above the floor, or
        the trunk beyond :data:`FALL_TILT_RAD`."""
        z0 = float(phys.data.qpos[phys.pelvis_qpos[1]])
        return -(1.0 - FALL_HEIGHT_FRACTION) * (phys.pelvis_height_offset_m + z0), FALL_TILT_RAD
