"""The walk of any :class:`~afo_mj.gait.controller.HumanController`: a Python loop around the
controller's step, a worn device and MuJoCo's step, with the record every walk gives.

Per 1 ms step (the built-in walks, :class:`afo_mj.gait.walk.Walk` and
:class:`afo_mj.gait.muscle_walk.MuscleWalkStepper`, are this walk with compiled loops):

1. ``controller.step(t, phys)`` writes its actuators' controls and returns its events (heel
   strike, toe off, swing contact per side), which go to the record's
   :class:`~afo_mj.gait.record.GaitEvents`;
   the walk ends before stepping once the right leg has completed the requested strides;
2. extra joint damping the controller asks for (:meth:`~afo_mj.gait.controller.
   HumanController.joint_damping_nm_s_per_rad`, e.g. soft joint limits) is added to the
   model's base damping, so MuJoCo's implicit integrator applies it;
3. a worn device: a coupled one (``device.coupled``, e.g. a hydraulic circuit) gets the ankle
   angles, velocities and the controller's stance state (``begin_step``); its joint force
   goes to ``qfrc_applied`` and its extra damping onto the ankles' damping (the end-of-step
   torque ``F − D q̇ₙ₊₁``, :mod:`afo_mj.circuits.stepper`); an uncoupled one returns its
   torque (``torque_nm``); the controller hears of the torque (:meth:`~afo_mj.gait.controller.
   HumanController.answer_device`); an ``action`` (N·m per ankle, + dorsiflexion) adds to it;
4. ``mujoco.mj_step``; a coupled device closes its step with the new ankle velocities
   (``end_step``), the delivered torque is recorded;
5. the raw state, the controller's joint moments and its declared signals are recorded; a
   non-finite state raises FloatingPointError; the pelvis below or the trunk pitched past
   the controller's :meth:`~afo_mj.gait.controller.HumanController.fall_limits` is a fall
   (recorded with its time; the walk ends).

The record is a :class:`~afo_mj.gait.record.GaitRecord` (every gait metric, figure and export
applies); the controller's signals are in ``record.signals`` by name, ``(n,) + shape`` each.
"""

from __future__ import annotations

import copy
import math

import mujoco
import numpy as np

from afo_mj.gait.controller import (EV_HEEL_STRIKE, EV_SWING_CONTACT, EV_TOE_OFF,
                                    HumanController)
from afo_mj.gait.record import GaitEvents, GaitRecord, phase_from_events
from afo_mj.gait.stepped import SteppedWalk

__all__ = ["ControllerWalk"]


class ControllerWalk(SteppedWalk):
    """A steppable walk of ``controller`` (module docstring) for ``duration_s`` or ``strides``
    right strides, whichever ends first, wearing ``worn_masses`` and ``device``.

    ``reset()``, ``step(action=None)``, the named accessors of
    :class:`~afo_mj.gait.stepped.SteppedWalk` plus :attr:`stance`, :attr:`phase`,
    :attr:`joint_moment_nm`, :attr:`device_moment_nm`, :attr:`done`, and :meth:`record`;
    :meth:`run` steps to the end.
    """

    def __init__(self, controller: HumanController, duration_s: float, strides: int | None = None,
                 worn_masses=(), device=None, loop: str = "auto"):
        if not isinstance(controller, HumanController):
            raise TypeError(f"controller {controller!r}; allowed: a HumanController")
        if not (isinstance(duration_s, (int, float)) and math.isfinite(duration_s)
                and duration_s > 0):
            raise ValueError(f"duration_s = {duration_s!r}; allowed: finite > 0")
        if strides is not None and (isinstance(strides, bool) or not isinstance(strides, int)
                                    or strides < 1):
            raise ValueError(f"strides = {strides!r}; allowed: an integer >= 1 or None")
        if loop not in ("auto", "compiled", "python"):
            raise ValueError(f"loop = {loop!r}; allowed: 'auto', 'compiled', 'python'")
        self.controller, self.duration_s, self.strides = controller, float(duration_s), strides
        self.device, self._worn, self.loop = device, tuple(worn_masses), loop
        self._stepped = False
        self.reset()

    def reset(self) -> None:
        """Back to the controller's start. A worn device keeps its own state: with one, make a
        new walk with a new device instead (refused here once stepped)."""
        if self.device is not None and self._stepped:
            cls = type(self).__name__
            raise RuntimeError(f"{cls}.reset: the device keeps its own state; allowed: a new "
                               f"{cls} with a new device")
        ctl, device = self.controller, self.device
        phys = ctl.build_physics(self._worn)
        m, d = phys.model, phys.data
        h = float(m.opt.timestep)
        coupled = device is not None and getattr(device, "coupled", False)
        if coupled and abs(float(device.timestep_s) - h) > 1e-12:
            raise ValueError(f"device timestep_s = {device.timestep_s} differs from the walker's "
                             f"MuJoCo timestep {h}; allowed: equal")
        ctl.start(phys)
        self.phys, self.model, self.data, self._h = phys, m, d, h
        self.events = GaitEvents()
        self.n_max = self._max_steps(h)
        n = self.n_max
        self._buf = {"time": np.zeros(n), "qpos": np.zeros((n, m.nq)),
                     "qvel": np.zeros((n, m.nv)), "sens": np.zeros((n, m.nsensordata)),
                     "cz": np.zeros((n, 4)), "dev": np.zeros((n, 2)), "tau": np.zeros((n, 2, 3)),
                     "res": np.zeros((n, 3))}
        # the declared signals side by side in one buffer (the compiled loop fills it too)
        self._sig_layout, off = {}, 0
        for name, (_unit, shape) in ctl.signals.items():
            size = int(np.prod(shape))
            self._sig_layout[name] = (off, tuple(shape))
            off += size
        self._sig = np.zeros((n, off))
        #: per signal, its columns of the buffer as an (n,) + shape view
        self._sig_views = {name: self._sig[:, o:o + int(np.prod(shape))].reshape((n,) + shape)
                           for name, (o, shape) in self._sig_layout.items()}
        self._dank = phys.leg_dof[:, 2].copy()
        self._ank_q = phys.leg_qpos[:, 2].copy()
        self._contact = phys.contact_geoms.ravel().copy()
        self._pelvis_dof = phys.pelvis_dof.copy()
        self._pz, self._pt = int(phys.pelvis_qpos[1]), int(phys.pelvis_qpos[2])
        self._k = 0
        self._right_strides = 0
        self._done = [False]
        self._steps = lambda: self._k
        self._acted = False
        self._coupled = coupled
        self._fall_z, self._fall_tilt = ctl.fall_limits(phys)
        self._dlim = phys.leg_dof[:, 1:3].copy()
        self._base_limit = m.dof_damping[self._dlim].copy()
        self._lim_was = False
        self._no_extra = np.zeros((2, 2))
        self._run_compiled = self._compiled_runner()

    def _max_steps(self, h: float) -> int:
        """The rows the walk may record (its buffers' length) at MuJoCo's step ``h``."""
        return int(self.duration_s / h) + 1

    @property
    def compiled(self) -> bool:
        """The walk runs in compiled code (:mod:`afo_mj.gait.controller_loop`): the controller
        has a compiled step, the device (if any) compiled entry points, and ``loop`` is not
        ``"python"``. A step with an action (and the one after it) runs in Python."""
        return self._run_compiled is not None

    def _compiled_runner(self):
        """The compiled loop bound to this walk's arrays, or None (refused with the reason
        when ``loop = "compiled"`` cannot be honoured)."""
        if self.loop == "python":
            return None
        ctl, device, phys = self.controller, self.device, self.phys
        cs = ctl.compiled(phys)
        why = None
        if cs is None:
            why = f"the controller {ctl.name or type(ctl).__name__} has no compiled step"
        elif device is not None and not self._coupled:
            why = (f"the device {type(device).__name__} is a Python callback of its torque "
                   f"(torque_nm), stepped in the Python loop")
        elif device is not None and not hasattr(device, "native_coupling"):
            why = (f"the device {type(device).__name__} has no compiled entry points "
                   f"(native_coupling); it steps in Python")
        nc = None
        if why is None and device is not None:
            nc = device.native_coupling()
            if nc is None:
                why = (f"the device {type(device).__name__} has no compiled entry points "
                       f"(native_coupling() gave none)")
        if why is not None:
            if self.loop == "compiled":
                raise ValueError(f"loop = 'compiled' cannot be honoured: {why}; allowed: "
                                 "'auto', 'python'")
            return None
        return _CompiledRun(self, cs, nc)

    # -- stepping --------------------------------------------------------------------------
    def step(self, action=None) -> None:
        """One step (module docstring): in compiled code where the walk is :attr:`compiled`
        and no action is given (nor was the step before), else in Python."""
        if self._done[0]:
            raise RuntimeError(f"{type(self).__name__}.step: the walk is over (fell, its "
                               f"strides or its duration walked); allowed: reset() (no device) "
                               f"or a new {type(self).__name__}")
        if action is not None and self.loop == "compiled":
            raise ValueError(f"{type(self).__name__}.step(action): an action torque steps in "
                             "the Python loop; allowed: step() with loop = 'compiled', or "
                             "loop = 'auto' or 'python'")
        self._stepped = True
        if action is None and self._run_compiled is not None and not self._acted:
            self._run_compiled(self._k + 1)
            return
        self._step_python(action)

    def _step_python(self, action=None) -> None:
        ctl, phys, device = self.controller, self.phys, self.device
        m, d = self.model, self.data
        t = float(d.time)
        codes = ctl.step(t, phys)
        for s in range(2):
            if codes[s] == EV_HEEL_STRIKE:
                self.events.heel_strikes_s[s].append(t)
                self._right_strides += s == 0
            elif codes[s] == EV_TOE_OFF:
                self.events.toe_offs_s[s].append(t)
            elif codes[s] == EV_SWING_CONTACT:
                self.events.swing_toe_contacts.append((t, s))
        if self.strides is not None and self._right_strides > self.strides:
            self._done[0] = True
            return
        dank, ank_q = self._dank, self._ank_q
        extra = ctl.joint_damping_nm_s_per_rad(phys)
        # written only while the controller asks for damping (or did the step before)
        if extra is None:
            extra, lim_now = self._no_extra, False
        else:
            lim_now = bool(extra.any())
        if lim_now or self._lim_was:
            m.dof_damping[self._dlim] = self._base_limit + extra
        self._lim_was = lim_now
        dev = None
        if self._coupled:
            # end-of-step torque = force − D q̇ₙ₊₁, D integrated implicitly by MuJoCo
            dev, extra2 = device.begin_step(t, d.qpos[ank_q], d.qvel[dank], ctl.stance)
            d.qfrc_applied[dank] = dev
            m.dof_damping[dank] = self._base_limit[:, 1] + extra[:, 1] + extra2
            ctl.answer_device(phys, dev - extra2 * d.qvel[dank])
        elif device is not None:
            phase = self.phase if getattr(device, "needs_phase", True) else None
            dev = np.asarray(device.torque_nm(t, d.qpos[ank_q], d.qvel[dank], phase,
                                              ctl.stance), float)
            d.qfrc_applied[dank] = dev
            ctl.answer_device(phys, dev)
        if action is not None or self._acted:
            a2 = np.zeros(2) if action is None else np.array([float(action[0]),
                                                               float(action[1])])
            d.qfrc_applied[dank] = a2 if dev is None else dev + a2
            self._acted = action is not None
        mujoco.mj_step(m, d)
        if d.time < t:
            self._done[0] = True
            raise FloatingPointError(f"{ctl.name} walk: the simulation diverged at t = "
                                     f"{t:.4f} s (MuJoCo reset its state)")
        k = self._k
        b = self._buf
        if self._coupled:
            b["dev"][k] = device.end_step(d.qvel[dank])
        elif dev is not None:
            b["dev"][k] = dev
        if self._acted:
            b["dev"][k] += a2
        b["time"][k] = d.time
        b["qpos"][k] = d.qpos
        b["qvel"][k] = d.qvel
        b["sens"][k] = d.sensordata
        b["cz"][k] = d.geom_xpos[self._contact, 2]
        b["tau"][k] = ctl.joint_moments_nm(phys)
        b["res"][k] = d.qfrc_actuator[self._pelvis_dof]
        views = self._sig_views
        for name, val in ctl.signal_values().items():
            views[name][k] = val
        self._k = k + 1
        state = ctl.state_array()
        # one sum per array: NaN or ±inf anywhere makes it non-finite (so does a sum beyond
        # 1e308, a state long diverged)
        if not (math.isfinite(d.qpos.sum() + d.qvel.sum())
                and (state is None or math.isfinite(state.sum()))):
            self._done[0] = True
            raise FloatingPointError(f"{ctl.name} walk: non-finite state at t = "
                                     f"{d.time:.4f} s")
        q = d.qpos
        if q[self._pz] < self._fall_z or abs(q[self._pt]) > self._fall_tilt:
            self.events.fall_time_s = round(float(d.time), 9)
            self._done[0] = True
        elif self._k >= self.n_max:
            self._done[0] = True

    def run(self) -> GaitRecord:
        """Step to the end — in one call of the compiled loop where the walk is
        :attr:`compiled`, else step by step in Python — and return :meth:`record`."""
        self._stepped = True
        if self._run_compiled is not None and not self._acted:
            if not self._done[0]:
                self._run_compiled(self.n_max)
        else:
            while not self._done[0]:
                self._step_python()
        return self.record()

    # -- named accessors ---------------------------------------------------------------------
    @property
    def stance(self) -> np.ndarray:
        """(2,) bool: the controller's stance state per leg."""
        return self.controller.stance

    @property
    def phase(self) -> np.ndarray:
        """(2,) gait phase per leg now: the controller's own estimate where it declares one
        (the signal ``gait_phase``), else from the recorded heel strikes (0 before a leg's
        second heel strike)."""
        if "gait_phase" in self._sig_layout:
            return np.array(self.controller.signal_values()["gait_phase"], dtype=float)
        t = np.array([self.data.time])
        return phase_from_events(t, self.events)[0]

    @property
    def joint_moment_nm(self) -> np.ndarray:
        """(2, 3) the human joint moments of the last step (N·m; zeros before one)."""
        k = self._k
        return self._buf["tau"][k - 1].copy() if k else np.zeros((2, 3))

    @property
    def device_moment_nm(self) -> np.ndarray:
        """(2,) the ankle torque of the device and the action in the last step (N·m)."""
        k = self._k
        return self._buf["dev"][k - 1].copy() if k else np.zeros(2)

    def record(self) -> GaitRecord:
        """The :class:`~afo_mj.gait.record.GaitRecord` of the steps so far. What is a column
        or block of the walk's buffers — time, ``qpos``, joint angles and velocities, joint
        and device moments, contact forces, pelvis velocity and tilt, the residuals and the
        controller's ``signals`` — is a read-only view of them, not a copy (a row once
        stepped is never written again; :meth:`reset` makes new buffers), so two records of
        one walk share them unchanged and a record copies nothing of the walk; the GRF, the
        contact heights, the pelvis position and the gait phase are computed (new arrays) —
        the gait phase from the heel strikes, or, for a controller that declares its own
        estimate as the signal ``gait_phase`` (2,), that signal's view (then not in
        ``signals``).
        Raises FloatingPointError when MuJoCo met a non-finite or huge control or
        acceleration on the way."""
        d, phys, k = self.data, self.phys, self._k
        bad = [w_ for w_ in ("BADQACC", "BADQVEL", "BADCTRL")
               if d.warning[getattr(mujoco.mjtWarning, "mjWARN_" + w_)].number > 0]
        if bad:
            raise FloatingPointError(f"{self.controller.name} walk: the simulation diverged "
                                     f"({', '.join(bad)}) before t = {d.time:.4f} s")
        b = {key: v[:k] for key, v in self._buf.items()}
        qq, vv, sens = b["qpos"], b["qvel"], b["sens"]
        w = self.controller.walker_params()
        pelvis = np.empty((k, 2))
        pelvis[:, 0] = qq[:, phys.pelvis_qpos[0]]
        np.add(qq[:, phys.pelvis_qpos[1]], phys.pelvis_height_offset_m, out=pelvis[:, 1])
        record = GaitRecord(
            body_mass_kg=w.body_mass_kg, height_m=w.height_m, sample_period_s=self._h,
            time_s=_read_only(b["time"]), joint_angle_rad=_columns(qq, phys.leg_qpos),
            joint_velocity_rad_s=_columns(vv, phys.leg_dof),
            joint_moment_nm=_read_only(b["tau"]), device_moment_nm=_read_only(b["dev"]),
            grf_n=np.negative(_columns(sens, np.stack([phys.foot_force_adr,
                                                       phys.foot_force_adr + 2], 1))),
            contact_force_n=_columns(sens, phys.touch_adr),
            contact_height_m=b["cz"].reshape(k, 2, 2) - phys.contact_radius_m,
            pelvis_position_m=pelvis,
            pelvis_velocity_m_s=_columns(vv, phys.pelvis_dof[:2]),
            pelvis_tilt_rad=_columns(qq, phys.pelvis_qpos[2]),
            residual_force_n=_read_only(b["res"][:, :2]),
            residual_moment_nm=_read_only(b["res"][:, 2]),
            gait_phase=None, qpos=_read_only(qq), model_xml=phys.xml,
            signals={name: _read_only(self._sig[:k, off:off + int(np.prod(shape))]
                                      .reshape((k,) + shape))
                     for name, (off, shape) in self._sig_layout.items()})
        # a controller's own phase estimate is the record's gait phase (not a signal beside it)
        own = record.signals.pop("gait_phase", None)
        record.gait_phase = (phase_from_events(b["time"], self.events) if own is None
                             else own)
        record.events = copy.deepcopy(self.events)
        return record


def pack_native_device(li: np.ndarray, L, nc, dev_io: np.ndarray) -> None:
    """Write a worn device's native coupling (``nc``: its compiled begin/end step addresses,
    buffer, layout and log) into a compiled walk loop's index array ``li``, with ``L`` the
    loop module naming the slots (``LI_DEV_BEGIN`` … ``LI_LOG_S``; the torque walker's
    :mod:`afo_mj.gait.walk_loop` and :mod:`afo_mj.gait.controller_loop` use the same names)
    and ``dev_io`` the 6-slot exchange array the loop shares with the device."""
    log = nc.log
    if not (log.flags.c_contiguous and nc.buffer.flags.c_contiguous
            and nc.meta.flags.c_contiguous and log.ndim == 3):
        raise AssertionError("device coupling: buffer, layout and log must be C arrays")
    li[L.LI_DEV_BEGIN], li[L.LI_DEV_END] = nc.begin_address, nc.end_address
    li[L.LI_P_IO] = dev_io.ctypes.data
    li[L.LI_P_BUF] = nc.buffer.ctypes.data
    li[L.LI_P_META] = nc.meta.ctypes.data
    li[L.LI_P_LOG] = log.ctypes.data
    li[L.LI_LOG_N:L.LI_LOG_S + 1] = log.shape


def _read_only(a: np.ndarray) -> np.ndarray:
    """A read-only view of ``a``."""
    v = a.view()
    v.flags.writeable = False
    return v


def _columns(a: np.ndarray, index) -> np.ndarray:
    """``a[:, index]`` (``a`` 2-D, ``index`` an integer or an integer array of any shape):
    a read-only strided view of ``a`` where ``index`` steps evenly along each of its axes
    (e.g. a leg's hip, knee, ankle at consecutive addresses), else the gathered copy; the
    same values either way."""
    idx = np.asarray(index, dtype=np.int64)
    if idx.ndim == 0:
        return _read_only(a[:, int(idx)])
    steps = []
    for ax in range(idx.ndim):
        step_ax = np.diff(idx, axis=ax)
        step = int(step_ax.flat[0]) if step_ax.size else 0
        if step < 0 or not (step_ax == step).all():
            return a[:, idx]
        steps.append(step)
    if idx.size == 0:
        return a[:, idx]
    return np.lib.stride_tricks.as_strided(
        a[:, int(idx.flat[0]):], shape=(a.shape[0],) + idx.shape,
        strides=(a.strides[0],) + tuple(st * a.strides[1] for st in steps), writeable=False)


class _CompiledRun:
    """The compiled loop (:func:`afo_mj.gait.controller_loop.controller_steps`) bound to a
    :class:`ControllerWalk`'s arrays once; ``run(k_end)`` runs it from the walk's row on and
    moves the walk's counters, events, a coupled device's counters and its end on, raising
    what the Python step raises."""

    def __init__(self, walk: ControllerWalk, cs, nc):
        from afo_mj.gait import controller_loop as cl
        from afo_mj.gait.native_step import native_step, time_view
        self.walk, self.cs, self.nc, self.cl = walk, cs, nc, cl
        phys, device = walk.phys, walk.device
        m, d = phys.model, phys.data
        lc = np.zeros(cl.N_LOOP_CONST)
        lc[cl.L_STRIDES] = 0.0 if walk.strides is None else float(walk.strides)
        lc[cl.L_FALL_Z], lc[cl.L_FALL_TILT] = walk._fall_z, walk._fall_tilt
        li = np.zeros(cl.N_LOOP_INDEX, dtype=np.int64)
        out = np.zeros(cl.N_OUT)
        out[cl.OUT_MOMENT_SOURCE] = 1.0 if cs.moments_from_out else 0.0
        li[cl.LI_STEP], li[cl.LI_BLOCK] = int(cs.address), cs.block.ctypes.data
        li[cl.LI_PZ], li[cl.LI_PT] = int(phys.pelvis_qpos[1]), int(phys.pelvis_qpos[2])
        li[cl.LI_FN] = native_step().mj_step_address
        li[cl.LI_MODEL], li[cl.LI_DATA] = m._address, d._address
        li[cl.LI_OUT] = out.ctypes.data
        n_max = walk.n_max
        ev_time = np.zeros(2 * n_max + 4)
        ev_code = np.zeros((2 * n_max + 4, 2), dtype=np.int64)
        dev_io = np.zeros(6)
        outs = (np.zeros(2), np.zeros(2), np.zeros(2))
        if nc is not None:
            pack_native_device(li, cl, nc, dev_io)
            lc[cl.L_DEV_DT] = float(device.timestep_s)
            outs = (nc.force2, nc.damping2, nc.delivered2)
        sig_index = np.concatenate(
            [np.asarray(cs.signal_index[name], dtype=np.int64).ravel()
             for name in walk._sig_layout] or [np.zeros(0, dtype=np.int64)])
        if sig_index.shape[0] != walk._sig.shape[1]:
            raise ValueError(f"{walk.controller.name}: compiled signal_index covers "
                             f"{sig_index.shape[0]} values; its signals declare "
                             f"{walk._sig.shape[1]}")
        # the recorded entries as contiguous runs (first entry, first column, length)
        runs = []
        for col, src in enumerate(sig_index.tolist()):
            if runs and runs[-1][0] + runs[-1][2] == src and runs[-1][1] + runs[-1][2] == col:
                runs[-1][2] += 1
            else:
                runs.append([src, col, 1])
        sig_runs = np.array(runs, dtype=np.int64).reshape(-1, 3)
        b = walk._buf
        i64 = lambda a: np.ascontiguousarray(a, dtype=np.int64)  # noqa: E731
        self.args = (time_view(d), d.qpos, d.qvel, d.sensordata, d.geom_xpos, d.ctrl,
                     d.qfrc_applied, m.dof_damping, d.qfrc_actuator, cs.state, sig_runs,
                     i64(phys.leg_dof), i64(phys.leg_qpos[:, 2]), i64(walk._dlim),
                     np.ascontiguousarray(walk._base_limit), i64(phys.contact_geoms.ravel()),
                     i64(phys.pelvis_dof), b["time"], b["qpos"], b["qvel"], b["sens"], b["cz"],
                     b["dev"], b["tau"], b["res"], walk._sig, ev_time, ev_code, out, lc, li,
                     dev_io, *outs)
        self.lc, self.li, self.ev_time, self.ev_code = lc, li, ev_time, ev_code

    def __call__(self, k_end: int) -> None:
        walk, cl, li, lc, nc = self.walk, self.cl, self.li, self.lc, self.nc
        ev = walk.events
        li[cl.LI_LIM_WAS] = 1 if walk._lim_was else 0
        li[cl.LI_N_EVENTS] = 0
        li[cl.LI_RIGHT_STRIDES] = walk._right_strides
        steps0 = li[cl.LI_DEV_STEPS] = walk.device.steps if nc is not None else 0
        code, k = cl.controller_steps(walk._k, min(k_end, walk.n_max), *self.args)
        walk._k = k
        for n in range(int(li[cl.LI_N_EVENTS])):
            side, c = int(self.ev_code[n, 0]), int(self.ev_code[n, 1])
            (ev.heel_strikes_s if c == 1 else ev.toe_offs_s)[side].append(
                float(self.ev_time[n]))
        walk._right_strides = int(li[cl.LI_RIGHT_STRIDES])
        walk._lim_was = bool(li[cl.LI_LIM_WAS])
        if code != cl.CHUNK_DONE:
            walk._done[0] = True
        err = None
        if nc is not None:
            try:
                walk.device.native_finished(int(li[cl.LI_DEV_STEPS]) - steps0,
                                            float(lc[cl.L_DEV_LAST_T]),
                                            failed=code == cl.DEVICE_NON_FINITE)
            except FloatingPointError as exc:
                err = exc
        name = walk.controller.name
        d = walk.data
        if code == cl.DIVERGED:
            err = FloatingPointError(f"{name} walk: the simulation diverged at t = "
                                     f"{lc[cl.L_T]:.4f} s (MuJoCo reset its state)")
        elif code == cl.NON_FINITE:
            err = FloatingPointError(f"{name} walk: non-finite state at t = {d.time:.4f} s")
        elif code == cl.FELL:
            ev.fall_time_s = round(float(d.time), 9)
        elif k >= walk.n_max:
            walk._done[0] = True
        if err is not None:
            raise err
