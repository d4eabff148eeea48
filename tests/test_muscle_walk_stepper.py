"""The steppable muscle walk (afo_mj.gait.muscle_walk.MuscleWalkStepper, issue 39 item 2):
run_muscle_walk, now a loop over the stepper, returns what the Python loop it replaced returned,
bit for bit (that loop is frozen below as a second implementation): without a device, with a
device_torque callback, with a coupled ideal device and a coupled HAFO, and through a fall.
The stepper's accessors read the state the record holds; an action adds its torque."""

from __future__ import annotations

import dataclasses
import math

import mujoco
import numpy as np
import pytest

from afo_mj.gait import reflex_law as rl
from afo_mj.gait.muscle_walk import (FALL_DROP_M, FALL_TILT_RAD, GRAVITY_M_S2, MUSCLE_SIGNALS,
                                     MuscleWalk,
                                     MuscleWalkStepper, build_muscle_walker,
                                     load_reflex_set, muscle_table_scaled, reflex_params,
                                     run_muscle_walk)
from afo_mj.gait.record import GaitEvents, GaitRecord, phase_from_events
from afo_mj.human.walker import WalkerParams


def _frozen_run_muscle_walk(walker: WalkerParams | None = None, params: np.ndarray | None = None,
                    duration_s: float = 10.0, initial_speed_m_s: float = 1.3,
                    worn_masses=(), device_torque=None, device=None,
                    max_force_scale: dict | None = None) -> MuscleWalk:
    """The loop of run_muscle_walk before the stepper (commit 0a87b16), verbatim."""
    w = walker or WalkerParams()
    P = reflex_params() if params is None else np.asarray(params, dtype=float)
    if P.shape != (rl.N_P,) or not np.all(np.isfinite(P)):
        raise ValueError(f"params: shape {P.shape}; allowed: {rl.N_P} finite numbers "
                         f"(reflex_params)")
    if not (duration_s > 0 and math.isfinite(duration_s)):
        raise ValueError(f"duration_s = {duration_s!r}; allowed: finite > 0")
    if device is not None and device_torque is not None:
        raise ValueError("run_muscle_walk: both device and device_torque given; allowed: one")
    phys = build_muscle_walker(w, worn_masses)
    m, d = phys.model, phys.data
    h = float(m.opt.timestep)
    if device is not None and abs(device.timestep_s - h) > 1e-12:
        raise ValueError(f"device timestep_s = {device.timestep_s} differs from the walker's "
                         f"MuJoCo timestep {h}; allowed: equal")
    T = muscle_table_scaled(h, max_force_scale, w.height_m)
    mg = phys.body_mass_kg * GRAVITY_M_S2
    lq, lv = phys.leg_qpos, phys.leg_dof
    q = d.qpos
    start = np.radians([[40.0, 5.0, 0.0], [5.0, 5.0, 5.0]])       # [right swing, left stance]
    for s in range(2):
        q[lq[s]] = start[s]
    q[phys.pelvis_qpos[2]] = rl.DEFAULTS["trunk_lean_ref_rad"]
    d.qvel[phys.pelvis_dof[0]] = initial_speed_m_s * math.sqrt(w.height_m / 1.75)
    mujoco.mj_kinematics(m, d)
    q[phys.pelvis_qpos[1]] -= phys.contact_point_heights_m().min() - 0.0005
    mujoco.mj_forward(m, d)
    X = rl.initial_state(T, start, (False, True), (-0.5, 0.0), float(q[phys.pelvis_qpos[2]]))
    ring = np.zeros((rl.RING_LEN, rl.RING_COLS))
    n_max = int(duration_s / h) + 1
    z0 = float(q[phys.pelvis_qpos[1]])
    drop = FALL_DROP_M * w.height_m / 1.75
    buf = {k: np.zeros((n_max,) + shp) for k, shp in (
        ("time", ()), ("qpos", (m.nq,)), ("qvel", (m.nv,)), ("sens", (m.nsensordata,)),
        ("cz", (4,)), ("dev", (2,)), ("u", (2, 7)), ("a", (2, 7)), ("f", (2, 7)),
        ("v", (2, 7)), ("eu", (2, 7)), ("eb", (2, 7)), ("tau", (2, 3)))}
    events = GaitEvents()
    ctrl, ff = d.ctrl, phys.ff_act
    pt_q, pt_v = int(phys.pelvis_qpos[2]), int(phys.pelvis_dof[2])
    contact = phys.contact_geoms.ravel()
    dank = phys.leg_dof[:, 2]
    # knee and ankle dofs [side][knee, ankle]: the soft limits' damping joins their own
    dlim = phys.leg_dof[:, 1:3].copy()
    base_limit = m.dof_damping[dlim].copy()
    base_damping = base_limit[:, 1].copy()
    k = 0
    tau = X[rl.X_TAU:rl.X_TAU + 6]
    c_lim = X[rl.X_LIMIT_DAMP:rl.X_LIMIT_DAMP + 6].reshape(2, 3)[:, 1:3]
    tau_rec = np.zeros((2, 3))
    lim_was = False
    while k < n_max:
        t = d.time
        rl.reflex_step(t, h, q, d.qvel, d.sensordata, lq, lv, phys.touch_adr, pt_q, pt_v, P, T,
                       X, ring, mg)
        for s in range(2):
            code = X[rl.X_EVENT + s]
            if code == 1.0:
                events.heel_strikes_s[s].append(t)
            elif code == 2.0:
                events.toe_offs_s[s].append(t)
        ctrl[ff[0, 0]], ctrl[ff[0, 1]], ctrl[ff[0, 2]] = tau[0], tau[1], tau[2]
        ctrl[ff[1, 0]], ctrl[ff[1, 1]], ctrl[ff[1, 2]] = tau[3], tau[4], tau[5]
        # the soft limits' damping, integrated implicitly by MuJoCo (reflex_law, step 5);
        # written only while a limit is (or was, the step before) engaged
        lim_now = bool(c_lim.any())
        if lim_now or lim_was:
            m.dof_damping[dlim] = base_limit + c_lim
        lim_was = lim_now
        if device_torque is not None:
            dev = np.asarray(device_torque(t, q[lq[:, 2]], d.qvel[dank],
                                           X[rl.X_STANCE:rl.X_STANCE + 2] > 0.5), float)
            d.qfrc_applied[dank] = dev
            buf["dev"][k] = dev
        elif device is not None:
            # end-of-step torque = force − D q̇_{n+1}, D integrated implicitly by MuJoCo
            force2, extra2 = device.begin_step(t, q[lq[:, 2]], d.qvel[dank],
                                               X[rl.X_STANCE:rl.X_STANCE + 2] > 0.5)
            d.qfrc_applied[dank] = force2
            m.dof_damping[dank] = base_damping + c_lim[:, 1] + extra2
        mujoco.mj_step(m, d)
        if d.time < t:
            # MuJoCo met a huge or non-finite acceleration or control (a diverging muscle
            # state) and reset the state, time included
            raise FloatingPointError(f"muscle walk: the simulation diverged at t = {t:.4f} s "
                                     "(MuJoCo reset its state)")
        if device is not None:
            buf["dev"][k] = device.end_step(d.qvel[dank])
        buf["time"][k] = d.time
        buf["qpos"][k] = q
        buf["qvel"][k] = d.qvel
        buf["sens"][k] = d.sensordata
        buf["cz"][k] = d.geom_xpos[contact, 2]
        buf["u"][k] = X[rl.X_U:rl.X_U + 14].reshape(2, 7)
        buf["a"][k] = X[rl.X_ACT:rl.X_ACT + 14].reshape(2, 7)
        buf["f"][k] = X[rl.X_F:rl.X_F + 14].reshape(2, 7)
        buf["v"][k] = X[rl.X_VCE:rl.X_VCE + 14].reshape(2, 7)
        buf["eu"][k] = X[rl.X_EDOT_U:rl.X_EDOT_U + 14].reshape(2, 7)
        buf["eb"][k] = X[rl.X_EDOT_B:rl.X_EDOT_B + 14].reshape(2, 7)
        # the joint moment: the motors' and the limits' damping at the step's end velocity
        if lim_now:
            tau_rec[:] = tau.reshape(2, 3)
            tau_rec[:, 1:3] -= c_lim * d.qvel[dlim]
            buf["tau"][k] = tau_rec
        else:
            buf["tau"][k] = tau.reshape(2, 3)
        k += 1
        if not np.isfinite(q).all() or not np.isfinite(X).all():
            raise FloatingPointError(f"muscle walk: non-finite state at t = {d.time:.4f} s")
        if q[phys.pelvis_qpos[1]] < z0 - drop or abs(q[phys.pelvis_qpos[2]]) > FALL_TILT_RAD:
            events.fall_time_s = round(float(d.time), 9)   # the sum of steps, not 4.3419999
            break
    bad = [w_ for w_ in ("BADQACC", "BADQVEL", "BADCTRL")
           if d.warning[getattr(mujoco.mjtWarning, "mjWARN_" + w_)].number > 0]
    if bad:
        # MuJoCo met a non-finite or huge control or acceleration (a diverging muscle state)
        # and reset the state: what follows is not a walk
        raise FloatingPointError(f"muscle walk: the simulation diverged ({', '.join(bad)}) "
                                 f"before t = {d.time:.4f} s")
    b = {key: v[:k] for key, v in buf.items()}
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
        gait_phase=phase_from_events(b["time"], events), qpos=qq.copy(), model_xml=phys.xml)
    record.events = events
    return MuscleWalk(record, b["u"].copy(), b["a"].copy(), b["f"].copy(), b["v"].copy(),
                      b["eu"].copy(), b["eb"].copy())


SHIPPED = "afo_mj/data/reflex_params_1.25.json"


@pytest.fixture(scope="module")
def params():
    return load_reflex_set(SHIPPED)


def assert_same_walk(a: MuscleWalk, b: MuscleWalk) -> None:
    """Every array of the two walks and of their records equal (np.array_equal), the other
    fields and the gait events equal."""
    for f in dataclasses.fields(MuscleWalk):
        x, y = getattr(a, f.name), getattr(b, f.name)
        if isinstance(x, np.ndarray):
            assert x.shape == y.shape and np.array_equal(x, y), f.name
        elif f.name != "record":
            assert x == y, f.name
    for f in dataclasses.fields(GaitRecord):
        x, y = getattr(a.record, f.name), getattr(b.record, f.name)
        if isinstance(x, np.ndarray):
            assert x.shape == y.shape and np.array_equal(x, y), f.name
        elif f.name == "signals":
            # a record's muscle signals are its walk's muscle arrays (the frozen loop has none)
            for walk, sig in ((a, x), (b, y)):
                for name, arr in sig.items():
                    assert np.array_equal(arr, getattr(walk, name)), name
        else:
            assert x == y, f.name
    ea, eb = a.record.events, b.record.events
    assert ea.heel_strikes_s == eb.heel_strikes_s and ea.toe_offs_s == eb.toe_offs_s
    assert ea.fall_time_s == eb.fall_time_s


def _callback(t, angle2, velocity2, stance2):
    """A state-dependent ankle torque: a stance spring-damper, a small swing lift."""
    return np.where(stance2, -30.0 * angle2 - 0.8 * velocity2, 1.5 + 0.1 * t)


def test_no_device_is_the_frozen_loop(params):
    new = run_muscle_walk(params=params, duration_s=3.0)
    assert_same_walk(new, _frozen_run_muscle_walk(params=params, duration_s=3.0))
    assert len(new.record.time_s) == 3001 and new.record.events.fall_time_s is None
    assert len(new.record.events.heel_strikes_s[0]) >= 2


def test_scaled_walker_with_weakness_is_the_frozen_loop(params):
    kw = dict(walker=WalkerParams(body_mass_kg=60.0, height_m=1.6), params=params,
              duration_s=1.5, initial_speed_m_s=1.2, max_force_scale={"soleus": 0.7})
    assert_same_walk(run_muscle_walk(**kw), _frozen_run_muscle_walk(**kw))


def test_device_torque_callback_is_the_frozen_loop(params):
    new = run_muscle_walk(params=params, duration_s=2.5, device_torque=_callback)
    assert np.abs(new.record.device_moment_nm).max() > 1.0
    assert_same_walk(new, _frozen_run_muscle_walk(params=params, duration_s=2.5,
                                                  device_torque=_callback))


def _spring_device():
    from afo_mj.devices.ideal import ClutchedSpring, IdealDevice
    return IdealDevice(sides=("right", "left"), spring=ClutchedSpring(200.0))


def test_coupled_ideal_device_is_the_frozen_loop(params):
    new = run_muscle_walk(params=params, duration_s=4.0, device=_spring_device())
    assert np.abs(new.record.device_moment_nm).max() > 1.0       # the spring engaged
    assert_same_walk(new, _frozen_run_muscle_walk(params=params, duration_s=4.0,
                                                  device=_spring_device()))


def test_coupled_hafo_is_the_frozen_loop(params):
    from afo_mj.experiments import muscle_assistance as ma

    def run(fn):
        dev = ma.hafo_device(ma.Assistance("hafo"), 1e-3)
        return fn(params=params, duration_s=2.5, device=dev,
                  worn_masses=tuple(dev.worn_masses()))
    new = run(run_muscle_walk)
    assert np.abs(new.record.device_moment_nm).max() > 1.0
    assert_same_walk(new, run(_frozen_run_muscle_walk))


def test_fall_is_the_frozen_loop():
    """Geyer & Herr's own gains fall on this skeleton (before 6 s)."""
    new = run_muscle_walk(duration_s=6.0)
    assert new.record.events.fall_time_s is not None
    assert len(new.record.time_s) < 6000
    assert_same_walk(new, _frozen_run_muscle_walk(duration_s=6.0))


def test_stepper_accessors_read_the_recorded_state(params):
    w = MuscleWalkStepper(params=params, duration_s=2.6)
    assert w.steps == 0 and not w.done and w.time_s == 0.0
    assert np.array_equal(w.stance, [False, True])               # Geyer & Herr's start
    seen = []
    while not w.done:
        w.step()
        if w.steps % 173 == 0:
            seen.append((w.steps, w.time_s, w.joint_angles_rad, w.joint_velocities_rad_s,
                         w.stance, w.phase, w.grf_n, w.pelvis_speed_m_s, w.joint_moment_nm,
                         w.device_moment_nm))
    assert w.steps == 2601 and not w.fallen
    with pytest.raises(RuntimeError, match="over"):
        w.step()
    walk = w.record()
    assert_same_walk(walk, run_muscle_walk(params=params, duration_s=2.6))
    r = walk.record
    assert np.any([s[5] > 0 for s in seen])                      # two heel strikes met
    for k, t, ang, vel, stance, phase, grf, v, tau, dev in seen:
        i = k - 1
        assert t == r.time_s[i]
        assert np.array_equal(ang, r.joint_angle_rad[i])
        assert np.array_equal(vel, r.joint_velocity_rad_s[i])
        assert np.array_equal(phase, r.gait_phase[i])
        assert np.array_equal(grf, r.grf_n[i])
        assert v == r.pelvis_velocity_m_s[i, 0]
        assert np.array_equal(tau, r.joint_moment_nm[i])
        assert np.array_equal(dev, r.device_moment_nm[i]) and not dev.any()
        # stance: on the ground from the foot's contact force (the reflex foot switch)
        assert stance.dtype == bool and stance.shape == (2,)
    # the stance flags flip at the recorded heel strikes and toe offs
    ev = r.events
    assert len(ev.heel_strikes_s[0]) >= 2 and len(ev.toe_offs_s[0]) >= 2


def test_action_is_an_ankle_torque_beside_the_muscles(params):
    """An action each step computed from the accessors walks as the same torque given as a
    device_torque callback; an action beside a callback adds to it. (The callback is
    called after the step's reflex update, so its stance flags may be one step newer than
    the accessor's: the torque here does not use them.)"""
    def spring(t, angle2, velocity2, stance2):
        return -10.0 * angle2 - 0.3 * velocity2 + 0.5 * t

    w = MuscleWalkStepper(params=params, duration_s=2.0)
    while not w.done:
        w.step(spring(w.time_s, w.joint_angles_rad[:, 2], w.joint_velocities_rad_s[:, 2],
                      w.stance))
    ref = run_muscle_walk(params=params, duration_s=2.0, device_torque=spring)
    assert np.abs(ref.record.device_moment_nm).max() > 1.0
    assert_same_walk(w.record(), ref)
    # an action for the first 0.5 s only, beside a callback: the callback plus the action
    half = 500
    w = MuscleWalkStepper(params=params, duration_s=1.0, device_torque=_callback)
    while not w.done:
        w.step([3.0, -2.0] if w.steps < half else None)

    def both(t, a2, v2, s2):
        extra = np.array([3.0, -2.0]) if t < 0.4995 else np.zeros(2)
        return _callback(t, a2, v2, s2) + extra
    assert_same_walk(w.record(), run_muscle_walk(params=params, duration_s=1.0,
                                                 device_torque=both))


def test_reset_walks_again_and_a_device_refuses_it(params):
    w = MuscleWalkStepper(params=params, duration_s=0.4)
    while not w.done:
        w.step()
    first = w.record()
    w.reset()
    assert w.steps == 0 and not w.done
    while not w.done:
        w.step()
    assert_same_walk(w.record(), first)
    d = MuscleWalkStepper(params=params, duration_s=0.4, device=_spring_device())
    d.step()
    with pytest.raises(RuntimeError, match="new MuscleWalkStepper"):
        d.reset()


def test_a_partial_record_does_not_change_as_the_walk_goes_on(params):
    w = MuscleWalkStepper(params=params, duration_s=2.0)
    for _ in range(1200):
        w.step()
    part = w.record()
    hs = [list(x) for x in part.record.events.heel_strikes_s]
    t_end = part.record.time_s.copy()
    while not w.done:
        w.step()
    assert [list(x) for x in part.record.events.heel_strikes_s] == hs
    assert np.array_equal(part.record.time_s, t_end) and len(t_end) == 1200
    full = w.record()
    assert np.array_equal(full.record.joint_angle_rad[:1200], part.record.joint_angle_rad)


def test_bad_arguments_are_named(params):
    with pytest.raises(ValueError, match="duration_s"):
        MuscleWalkStepper(params=params, duration_s=math.inf)
    with pytest.raises(ValueError, match="params"):
        MuscleWalkStepper(params=np.ones(3))
    with pytest.raises(ValueError, match="both device and device_torque"):
        MuscleWalkStepper(params=params, device=_spring_device(), device_torque=_callback)


def test_a_record_keeps_its_muscle_signals_while_the_walk_goes_on():
    """The muscles' signals of a record are read-only views of the stepper's buffers (no
    copy): a record taken mid-walk keeps its values while the stepper steps on (a step
    writes the row after the last), and equals the same rows of the finished walk's."""
    w = MuscleWalkStepper(params=load_reflex_set(SHIPPED), duration_s=0.3)
    for _ in range(120):
        w.step()
    early = w.record()
    kept = {name: getattr(early, name).copy() for name in MUSCLE_SIGNALS}
    done = w.run()
    for name in MUSCLE_SIGNALS:
        a, b = getattr(early, name), getattr(done, name)
        assert not a.flags.writeable and not b.flags.writeable
        assert a.shape == (120, 2, 7) and b.shape == (301, 2, 7)
        assert np.array_equal(a, kept[name]) and np.array_equal(a, b[:120])
        assert early.record.signals[name] is a
        with pytest.raises(ValueError):
            a[0, 0, 0] = 1.0
