"""Forward-dynamic walking of the sagittal walker: controller, gait events and the run loop.

The human joint torques come from three parts, all saturated together by each joint's strength
(``actuatorfrcrange`` in the model, :mod:`afo_mj.human.walker`):

* a PD servo inside MuJoCo tracking the reference angle and velocity at the leg's gait phase
  (stiff at hip and knee, soft at the ankle so that a change of ankle torque, from weakness or
  from an orthosis, shows up in the kinematics instead of being compensated);
* feedforward of the reference joint moment (fraction ``*_feedforward`` of the normative moment
  per kg × body mass): the ankle is mostly feedforward;
* balance feedback in the style of SIMBICON (Yin, Loken & van de Panne, ACM TOG 26(3), 2007):
  the trunk is held upright through the stance hip(s) (τ = −k_p·θ_trunk − k_d·θ̇_trunk, the
  reaction of the hip torque on the pelvis), and the swing hip target moves with the deviation
  of the forward velocity from its stride-averaged value (foot placement).

Gait phase per leg is the time since that leg's last heel strike divided by the cycle time
(from the cadence): heel strike, detected from foot–floor contact force, resets it; the clock
never drives a heel strike. Contact stays on throughout swing, so scuffs happen and are
counted.

The pelvis carries weak residual actuators (forward, vertical, pitch) whose forces are
recorded, as OpenSim reports residuals: forward damping about the stride-mean speed (never a
pull toward a target speed), a soft vertical spring about the stride-mean pelvis height and a
soft pitch spring about upright.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Callable, Protocol

import mujoco
import numpy as np

from afo_mj.hydraulics.params import Parameters, param
from afo_mj.human.anthropometry import scale_body
from afo_mj.human.walker import hill_concentric_fraction, WalkerParams, WalkerPhysics, WornMass, build_walker
from afo_mj.gait.record import GaitEvents, GaitRecord

__all__ = ["ControllerParams", "WalkNumericsError", "run_walk", "simulate_walk",
           "ReferenceTable"]

GRAVITY_M_S2 = 9.81
#: contacts this soon after toe off are the forefoot's last touches, not scuffs
TOE_OFF_CHATTER_S = 0.03


class WalkNumericsError(RuntimeError):
    """The simulation produced a non-finite state (reported with the time it happened)."""


@dataclasses.dataclass(frozen=True)
class ControllerParams(Parameters):
    """Gains of the walking controller. Gains are for a 75 kg walker and scale with body mass."""

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
    trunk_kd_nm_s_per_rad: float = param(50.0, unit="N*m*s/rad", lo=0.0, hi=500.0)
    stance_hip_tracking: float = param(1.0, unit="1", lo=0.0, hi=1.0,
                                       doc="1: stance hip keeps its servo and adds the trunk torque; 0: SIMBICON, trunk torque only")
    swing_hip_position_gain_rad_per_m: float = param(0.0, unit="rad/m", lo=-5.0, hi=5.0,
                                                     doc="SIMBICON c_d: swing hip target per m of hip-over-stance-ankle deviation")
    swing_hip_velocity_gain_rad_s_per_m: float = param(0.2, unit="rad*s/m", lo=-5.0, hi=5.0,
                                                       doc="SIMBICON c_v: swing hip target per m/s deviation")
    foot_placement_speed_adaptation: float = param(1.0, unit="1", lo=0.0, hi=1.0,
                                                   doc="1: foot placement regulates around the walker's own stride-mean speed; 0: around the reference kinematics' speed")
    swing_clearance_m: float = param(0.01, unit="m", lo=0.0, hi=0.1,
                                     doc="forefoot clearance the swing leg keeps (flexion withdrawal below it)")
    swing_clearance_gain_rad_per_m: float = param(60.0, unit="rad/m", lo=0.0, hi=100.0,
                                                  doc="extra swing knee flexion per m of clearance deficit (hip gets half)")
    trunk_lean_gain_rad_s_per_m: float = param(1.0, unit="rad*s/m", lo=0.0, hi=5.0,
                                               doc="forward trunk lean per m/s the stride-mean speed lies below the reference kinematics' speed")
    max_trunk_lean_rad: float = param(0.35, unit="rad", lo=0.0, hi=0.8)
    residual_tx_damping_n_s_per_m: float = param(100.0, unit="N*s/m", lo=0.0, hi=5000.0)
    residual_tz_stiffness_n_per_m: float = param(500.0, unit="N/m", lo=0.0, hi=50000.0)
    residual_tz_damping_n_s_per_m: float = param(100.0, unit="N*s/m", lo=0.0, hi=5000.0)
    residual_tilt_stiffness_nm_per_rad: float = param(100.0, unit="N*m/rad", lo=0.0, hi=5000.0)
    residual_tilt_damping_nm_s_per_rad: float = param(10.0, unit="N*m*s/rad", lo=0.0, hi=500.0)
    contact_on_fraction: float = param(0.05, unit="1", lo=0.005, hi=0.5,
                                       doc="foot load / body weight that marks heel strike")
    contact_off_fraction: float = param(0.01, unit="1", lo=0.0, hi=0.5,
                                        doc="foot load / body weight below which the foot is off")
    min_swing_phase_for_heel_strike: float = param(0.85, unit="1", lo=0.5, hi=0.99,
                                                   doc="earliest gait phase a contact counts as heel strike")
    stance_phase_hold: float = param(0.999, unit="1", lo=0.3, hi=0.999,
                                     doc="a stance leg's phase waits here until the other foot lands (0.5 = reference's contralateral heel strike)")
    phase_sync_gain_per_s: float = param(0.0, unit="1/s", lo=0.0, hi=100.0,
                                         doc="pulls the gait phase toward the phase at which the reference has the hip this far ahead of the leading stance ankle")
    phase_rate_speed_exponent: float = param(0.0, unit="1", lo=0.0, hi=2.0,
                                             doc="phase runs at (v_mean / v_reference)^k of the cadence's rate")
    min_phase_rate: float = param(0.6, unit="1", lo=0.1, hi=1.0)
    max_phase_rate: float = param(1.1, unit="1", lo=1.0, hi=2.0)
    initial_speed_m_s: float = param(1.0, unit="m/s", lo=0.0, hi=3.0)
    warmup_cycles: float = param(2.0, unit="1", lo=0.0, hi=10.0,
                                 doc="cycles over which the residual gains fall from warmup_gain× to 1×")
    warmup_gain: float = param(10.0, unit="1", lo=1.0, hi=100.0,
                               doc="residual gain multiplier at the start (a supported start, like a treadmill hand-rail)")
    speed_filter_time_s: float = param(1.2, unit="s", lo=0.05, hi=20.0,
                                       doc="time constant of the stride-mean speed and height")


class ReferenceTable:
    """Reference angles, angular rates and moments tabulated on a phase grid for the hot loop.

    ``reference`` provides ``angles_rad(phase)`` and ``moments_nm_per_kg(phase)`` (…, 3) and a
    phase derivative of the angles (``angle_rates_per_phase`` or finite differences).
    Lookup is linear interpolation on ``n`` points (1000 points: < 0.01° error on Winter's
    splines).
    """

    def __init__(self, reference, n: int = 1000):
        ph = np.arange(n + 1) / n
        self.n = n
        self.angle = np.asarray(reference.angles_rad(ph), float)
        h = 1e-4
        self.rate = (np.asarray(reference.angles_rad((ph + h) % 1.0)) -
                     np.asarray(reference.angles_rad((ph - h) % 1.0))) / (2 * h)
        self.moment = np.asarray(reference.moments_nm_per_kg(ph), float)

    def set_leg(self, thigh_m: float, shank_m: float) -> None:
        """Tabulate the hip's horizontal offset ahead of the stance ankle, and its rate per
        phase, for an upright trunk (hip angle = thigh angle from vertical)."""
        h, k = self.angle[:, 0], self.angle[:, 1]
        self.hip_ahead = -(thigh_m * np.sin(h) + shank_m * np.sin(h - k))
        hr, kr = self.rate[:, 0], self.rate[:, 1]
        self.hip_ahead_rate = -(thigh_m * np.cos(h) * hr + shank_m * np.cos(h - k) * (hr - kr))
        stance = slice(0, int(0.6 * self.n) + 1)
        #: hip-ahead-of-ankle over early stance, monotonic: inverted to a phase estimate
        self.stance_ahead = self.hip_ahead[stance].copy()
        self.stance_phase = np.arange(self.n + 1)[stance] / self.n
        #: no-slip stride of the reference posture: twice the hip's travel over the leading
        #: ankle from heel strike (phase 0) to the other heel strike (phase 0.5), in m
        self.geometric_stride_m = 2.0 * float(self.hip_ahead[self.n // 2] - self.hip_ahead[0])
        single_support = (np.arange(self.n + 1) / self.n >= 0.12) & (np.arange(self.n + 1) / self.n <= 0.5)
        #: mean hip speed over the stance ankle in single support, per unit phase rate
        self.mean_ahead_rate = float(self.hip_ahead_rate[single_support].mean())

    def lookup(self, phase: np.ndarray):
        x = np.clip(phase, 0.0, 1.0) * self.n
        i = np.minimum(x.astype(np.int64), self.n - 1)
        f = (x - i)[:, None]
        a = self.angle[i] * (1 - f) + self.angle[i + 1] * f
        r = self.rate[i] * (1 - f) + self.rate[i + 1] * f
        m = self.moment[i] * (1 - f) + self.moment[i + 1] * f
        f = f[:, 0]
        d = self.hip_ahead[i] * (1 - f) + self.hip_ahead[i + 1] * f
        dr = self.hip_ahead_rate[i] * (1 - f) + self.hip_ahead_rate[i + 1] * f
        return a, r, m, d, dr


class AnkleDevice(Protocol):
    """What the walk loop needs of an orthosis (issue 4 supplies real ones)."""

    def torque_nm(self, t_s: float, angle_rad: np.ndarray, velocity_rad_s: np.ndarray,
                  phase: np.ndarray, stance: np.ndarray) -> np.ndarray: ...


def run_walk(walker: WalkerParams, reference, cycle_time_s: float, strides: int,
             controller: ControllerParams | None = None, worn_masses=(),
             device: AnkleDevice | None = None, max_time_s: float | None = None,
             record_every: int = 1) -> GaitRecord:
    """Walk ``strides`` right-leg cycles (or until a fall) and return the record.

    The walker starts at the reference posture at right heel strike with a forward speed of
    ``controller.initial_speed_m_s``; phase 0 of the left leg is half a cycle earlier.
    """
    c = controller or ControllerParams()
    m_body = walker.body_mass_kg
    scale = m_body / 75.0
    root = build_walker(walker, worn_masses,
                        kp={"hip": c.hip_kp_nm_per_rad, "knee": c.knee_kp_nm_per_rad,
                            "ankle": c.ankle_kp_nm_per_rad},
                        kv={"hip": c.hip_kv_nm_s_per_rad, "knee": c.knee_kv_nm_s_per_rad,
                            "ankle": c.ankle_kv_nm_s_per_rad})
    phys = WalkerPhysics(root)
    model, data = phys.model, phys.data
    table = ReferenceTable(reference)
    seg = scale_body(walker.body_mass_kg, walker.height_m)
    table.set_leg(seg.thigh.length_m, seg.shank.length_m)
    T = float(cycle_time_s)
    dt = model.opt.timestep
    mass = phys.body_mass_kg
    weight = mass * GRAVITY_M_S2

    # --- initial state: reference posture, right heel strike --------------------------------
    t_hs = np.array([0.0, -0.5 * T])
    phase = -t_hs / T
    a0, r0, _, _, _ = table.lookup(phase)
    data.qpos[phys.leg_qpos] = a0
    data.qvel[phys.leg_dof] = r0 / T
    data.qvel[phys.pelvis_dof[0]] = c.initial_speed_m_s
    mujoco.mj_kinematics(model, data)
    data.qpos[phys.pelvis_qpos[1]] -= phys.contact_point_heights_m().min() - 0.001
    mujoco.mj_forward(model, data)

    kp = np.array([c.hip_kp_nm_per_rad, c.knee_kp_nm_per_rad, c.ankle_kp_nm_per_rad]) * scale
    kv = np.array([c.hip_kv_nm_s_per_rad, c.knee_kv_nm_s_per_rad, c.ankle_kv_nm_s_per_rad]) * scale
    lead = np.where(kp > 0, kv / np.maximum(kp, 1e-12), 0.0)
    ff = np.array([c.hip_feedforward, c.knee_feedforward, c.ankle_feedforward]) * m_body
    trunk_kp, trunk_kd = c.trunk_kp_nm_per_rad * scale, c.trunk_kd_nm_s_per_rad * scale
    on_n, off_n = c.contact_on_fraction * weight, c.contact_off_fraction * weight
    alpha = dt / c.speed_filter_time_s
    warmup_s = max(c.warmup_cycles * T, 1e-9)
    # speed of the reference posture walked at the cadence without slip (emergent-speed
    # scale for foot placement and trunk lean; not a target the pelvis is driven to)
    v_ref = table.geometric_stride_m / T
    rate = 1.0

    max_time = max_time_s if max_time_s is not None else (strides + 1.5) * T + 1.0
    n_max = int(max_time / dt) + 2
    n_rec = n_max // record_every + 1
    rec = GaitRecord.allocate(n_rec, m_body, walker.height_m, dt * record_every)
    events = GaitEvents()
    swing = np.array([False, False])
    stance_started = np.array([0.0, -0.5 * T])
    scuffing = np.array([False, False])
    t_toe_off = np.array([-1.0, -1.0])
    v_mean = c.initial_speed_m_s
    pel_q, pel_d = phys.pelvis_qpos, phys.pelvis_dof
    z0 = phys.pelvis_height_offset_m
    z_mean = float(data.qpos[pel_q[1]])
    fall_dz = -0.45 * (z0 + z_mean)
    ctrl = data.ctrl
    pd_act, ff_act, res_act = phys.pd_act, phys.ff_act, phys.residual_act
    leg_q, leg_d = phys.leg_qpos, phys.leg_dof
    touch = phys.touch_adr
    foot_body = phys.foot_body
    ball_geoms = phys.contact_geoms[:, 1]
    ankle_jnt = phys.ankle_joint
    pf_iso = phys.ankle_torque_limits_nm[:, 0].copy()   # negative: plantarflexion
    radius = phys.contact_radius_m
    device_torque = np.zeros(2)
    right_strides = 0
    k = 0
    n = 0
    step = 0
    while step < n_max:
        t = data.time
        load = data.sensordata[touch]                      # (2, 2) heel, ball
        foot_load = load[:, 0] + load[:, 1]
        phase += dt * rate / T
        for s in (0, 1):
            if swing[s]:
                if foot_load[s] > on_n and phase[s] > c.min_swing_phase_for_heel_strike:
                    swing[s] = False
                    phase[s] = 0.0
                    events.heel_strikes_s[s].append(t)
                    scuffing[s] = False
                    if s == 0:
                        right_strides += 1
                elif foot_load[s] > on_n and t - t_toe_off[s] > TOE_OFF_CHATTER_S:
                    # a floor contact in swing (not the last touch of toe off): a scuff
                    if not scuffing[s]:
                        events.swing_toe_contacts.append((t, s))
                        scuffing[s] = True
                elif foot_load[s] <= off_n:
                    scuffing[s] = False
            elif foot_load[s] <= off_n and phase[s] > 0.4:
                swing[s] = True
                t_toe_off[s] = t
                events.toe_offs_s[s].append(t)
        if right_strides > strides:
            break
        np.minimum(phase, 0.999, out=phase)
        # A stance leg does not start its pre-swing (knee flexion, push-off) before the other
        # foot has landed: its phase waits at the reference's contralateral heel strike.
        for s in (0, 1):
            if not swing[s] and swing[1 - s] and phase[s] > c.stance_phase_hold:
                phase[s] = c.stance_phase_hold
        # Walkers who cannot keep the reference speed (weakness) step at a lower rate.
        rate = min(max((max(v_mean, 1e-3) / v_ref) ** c.phase_rate_speed_exponent,
                       c.min_phase_rate), c.max_phase_rate)
        if c.phase_sync_gain_per_s:
            # Phase follows the body's progression over the leading stance foot: the phase at
            # which the reference has the hip as far ahead of that ankle as it is now.
            lead_leg = 0 if phase[0] < phase[1] else 1
            if not swing[lead_leg] and phase[lead_leg] < 0.55:
                ahead_now = data.qpos[pel_q[0]] - data.xpos[foot_body[lead_leg], 0]
                geom_phase = np.interp(ahead_now, table.stance_ahead, table.stance_phase)
                rate = min(max(rate + c.phase_sync_gain_per_s * T * (geom_phase - phase[lead_leg]),
                               c.min_phase_rate), c.max_phase_rate)

        qa, qr, qm, ahead_ref, ahead_rate_ref = table.lookup(phase)
        vx = data.qvel[pel_d[0]]
        # Trunk strategy: a walker slower than the reference kinematics' speed leans its trunk
        # forward (a P law, so the speed still settles where the walker's strength allows).
        lean = min(max(c.trunk_lean_gain_rad_s_per_m * (v_ref - v_mean), 0.0), c.max_trunk_lean_rad)
        tilt, tilt_rate = data.qpos[pel_q[2]] - lean, data.qvel[pel_d[2]]
        v_mean += alpha * (vx - v_mean)
        z = data.qpos[pel_q[1]]
        z_mean += alpha * (z - z_mean)
        target = qa + lead * qr / T
        # SIMBICON foot placement: a swing leg steps further ahead when the hip is further
        # ahead of (or moving faster over) the other leg's ankle than the reference says at
        # that leg's phase.
        ankle_x = data.xpos[foot_body, 0]
        pelvis_x = data.qpos[pel_q[0]]
        ahead = pelvis_x - ankle_x[::-1]
        # The speed the walker is judged against is its own stride-mean speed, shaped over the
        # stride as the reference's hip-over-ankle speed: the walker is never pushed toward a
        # speed it cannot reach (a weak walker walks slower).
        v_level = c.foot_placement_speed_adaptation * v_mean + (1.0 - c.foot_placement_speed_adaptation) * v_ref
        v_target = v_level * ahead_rate_ref[::-1] / table.mean_ahead_rate
        dev = (c.swing_hip_position_gain_rad_per_m * (ahead - ahead_ref[::-1])
               + c.swing_hip_velocity_gain_rad_s_per_m * (vx - v_target))
        target[:, 0] += np.where(swing, dev, 0.0)
        if c.swing_clearance_gain_rad_per_m:
            # Toe-clearance reflex: in mid-swing a forefoot closer to the floor than
            # swing_clearance_m flexes knee and hip further (flexion withdrawal).
            ball_z = data.geom_xpos[ball_geoms, 2] - radius
            deficit = np.where(swing & (phase > 0.6) & (phase < 0.9),
                               np.maximum(c.swing_clearance_m - ball_z, 0.0), 0.0)
            target[:, 1] += c.swing_clearance_gain_rad_per_m * deficit
            target[:, 0] += 0.5 * c.swing_clearance_gain_rad_per_m * deficit
        torque = ff * qm
        stance = ~swing
        n_st = stance.sum()
        if n_st:
            # Trunk through the stance hip(s). A stance hip that tracks its reference angle by
            # the clock tilts the trunk back whenever the body lags the clock (the hip angle is
            # thigh-to-pelvis), so the stance hip servo blends its reference with the angle
            # that keeps the trunk upright (thigh angle from vertical = q_hip − tilt):
            # α = stance_hip_tracking; α = 0 is SIMBICON's stance hip, which only holds the
            # trunk. Feedback on trunk pitch adds through the stance hips by load share.
            q_hip, qd_hip = data.qpos[leg_q[:, 0]], data.qvel[leg_d[:, 0]]
            share = np.where(stance, foot_load, 0.0)
            total = share.sum()
            share = share / total if total > 0 else stance / n_st
            upright = q_hip - tilt + lead[0] * (qd_hip - tilt_rate)
            a = c.stance_hip_tracking
            target[:, 0] = np.where(stance, a * target[:, 0] + (1.0 - a) * upright, target[:, 0])
            torque[:, 0] = np.where(stance, a * torque[:, 0], torque[:, 0])
            torque[:, 0] += share * (-trunk_kp * tilt - trunk_kd * tilt_rate)
        if device is not None:
            device_torque = device.torque_nm(t, data.qpos[leg_q[:, 2]], data.qvel[leg_d[:, 2]],
                                             phase, stance)
        ctrl[pd_act] = target
        ctrl[ff_act] = torque
        g = scale * (1.0 + (c.warmup_gain - 1.0) * max(0.0, 1.0 - t / warmup_s))
        ctrl[res_act[0]] = -c.residual_tx_damping_n_s_per_m * g * (vx - v_mean)
        ctrl[res_act[1]] = (-c.residual_tz_stiffness_n_per_m * g * (z - z_mean)
                            - c.residual_tz_damping_n_s_per_m * g * data.qvel[pel_d[1]])
        ctrl[res_act[2]] = (-c.residual_tilt_stiffness_nm_per_rad * g * tilt
                            - c.residual_tilt_damping_nm_s_per_rad * g * tilt_rate)
        # Plantarflexor capacity falls with shortening speed (Hill): limit the net ankle
        # actuator torque in the plantarflexion direction accordingly.
        ankle_w = data.qvel[leg_d[:, 2]]
        model.jnt_actfrcrange[ankle_jnt, 0] = pf_iso * hill_concentric_fraction(
            -ankle_w, walker.plantarflexor_max_velocity_rad_s, walker.hill_curvature)
        mujoco.mj_step(model, data)
        step += 1
        if step % record_every == 0 and k < n_rec:
            rec.time_s[k] = data.time
            rec.joint_angle_rad[k] = data.qpos[leg_q]
            rec.joint_velocity_rad_s[k] = data.qvel[leg_d]
            rec.joint_moment_nm[k] = data.qfrc_actuator[leg_d]
            rec.device_moment_nm[k] = device_torque
            rec.contact_force_n[k] = data.sensordata[touch]
            rec.contact_height_m[k] = data.geom_xpos[phys.contact_geoms, 2] - phys.contact_radius_m
            rec.pelvis_position_m[k] = data.qpos[pel_q[:2]]
            rec.pelvis_position_m[k, 1] += z0
            rec.pelvis_velocity_m_s[k] = data.qvel[pel_d[:2]]
            rec.pelvis_tilt_rad[k] = data.qpos[pel_q[2]]
            rec.residual_force_n[k] = data.actuator_force[res_act[:2]]
            rec.residual_moment_nm[k] = data.actuator_force[res_act[2]]
            rec.gait_phase[k] = phase
            _foot_grf(model, data, phys, rec.grf_n[k])
            k += 1
        if not np.isfinite(data.qpos).all() or not np.isfinite(data.qvel).all():
            raise WalkNumericsError(f"non-finite walker state at t = {data.time:.4f} s "
                                    f"(qpos={data.qpos.tolist()})")
        if data.qpos[pel_q[1]] < fall_dz or abs(data.qpos[pel_q[2]]) > 1.0:
            events.fall_time_s = float(data.time)
            break
    out = rec.trimmed(k)
    out.events = events
    return out


def _foot_grf(model, data, phys: WalkerPhysics, out: np.ndarray) -> None:
    """Sum the contact forces of each foot's spheres in world x and z into ``out`` (2, 2)."""
    out[:] = 0.0
    f6 = _F6
    for i in range(data.ncon):
        con = data.contact[i]
        g = con.geom2 if con.geom1 == phys.floor_geom else con.geom1
        side = 0 if g in phys.contact_geoms[0] else (1 if g in phys.contact_geoms[1] else -1)
        if side < 0:
            continue
        mujoco.mj_contactForce(model, data, i, f6)
        frame = con.frame.reshape(3, 3)
        # The contact normal points from geom1 to geom2 and the force acts on geom2.
        world = frame.T @ f6[:3]
        if con.geom1 != phys.floor_geom:
            world = -world
        out[side, 0] += world[0]
        out[side, 1] += world[2]


_F6 = np.zeros(6)


def simulate_walk(scenario, device: AnkleDevice | None = None, worn_masses=()) -> GaitRecord:
    """Run a :class:`~afo_mj.scenarios.walk_scenario.WalkScenario` and return its record."""
    reference = scenario.load_reference()
    return run_walk(scenario.walker, reference, scenario.cycle_time_s(reference), scenario.strides,
                    scenario.controller_params(), worn_masses=worn_masses, device=device)
