"""The walk of any :class:`~afo_mj.gait.controller.HumanController`: a Python loop around the
controller's step, a worn device and MuJoCo's step, with the record every walk gives.

Per 1 ms step (the order the built-in walks use, :mod:`afo_mj.gait.walk` and
:mod:`afo_mj.gait.muscle_walk`):

1. ``controller.step(t, phys)`` writes its actuators' controls and returns its events (heel
   strike, toe off per side), which go to the record's :class:`~afo_mj.gait.record.GaitEvents`;
   the walk ends before stepping once the right leg has completed the requested strides;
2. extra joint damping the controller asks for (:meth:`~afo_mj.gait.controller.
   HumanController.joint_damping_nm_s_per_rad`, e.g. soft joint limits) is added to the
   model's base damping, so MuJoCo's implicit integrator applies it;
3. a worn device: a coupled one (``device.coupled``, e.g. a hydraulic circuit) gets the ankle
   angles, velocities and the controller's stance state (``begin_step``); its joint force
   goes to ``qfrc_applied`` and its extra damping onto the ankles' damping (the end-of-step
   torque ``F − D q̇ₙ₊₁``, :mod:`afo_mj.circuits.stepper`); an uncoupled one returns its
   torque (``torque_nm``); an ``action`` (N·m per ankle, + dorsiflexion) adds to it;
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

from afo_mj.gait.controller import EV_HEEL_STRIKE, EV_TOE_OFF, HumanController
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
                 worn_masses=(), device=None):
        if not isinstance(controller, HumanController):
            raise TypeError(f"controller {controller!r}; allowed: a HumanController")
        if not (isinstance(duration_s, (int, float)) and math.isfinite(duration_s)
                and duration_s > 0):
            raise ValueError(f"duration_s = {duration_s!r}; allowed: finite > 0")
        if strides is not None and (isinstance(strides, bool) or not isinstance(strides, int)
                                    or strides < 1):
            raise ValueError(f"strides = {strides!r}; allowed: an integer >= 1 or None")
        self.controller, self.duration_s, self.strides = controller, float(duration_s), strides
        self.device, self._worn = device, tuple(worn_masses)
        self._stepped = False
        self.reset()

    def reset(self) -> None:
        """Back to the controller's start. A worn device keeps its own state: with one, make a
        new walk with a new device instead (refused here once stepped)."""
        if self.device is not None and self._stepped:
            raise RuntimeError("ControllerWalk.reset: the device keeps its own state; allowed: "
                               "a new ControllerWalk with a new device")
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
        self.n_max = int(self.duration_s / h) + 1
        n = self.n_max
        self._buf = {"time": np.zeros(n), "qpos": np.zeros((n, m.nq)),
                     "qvel": np.zeros((n, m.nv)), "sens": np.zeros((n, m.nsensordata)),
                     "cz": np.zeros((n, 4)), "dev": np.zeros((n, 2)), "tau": np.zeros((n, 2, 3)),
                     "res": np.zeros((n, 3))}
        self._sig = {name: np.zeros((n,) + tuple(shape))
                     for name, (_unit, shape) in ctl.signals.items()}
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

    # -- stepping --------------------------------------------------------------------------
    def step(self, action=None) -> None:
        """One step (module docstring)."""
        if self._done[0]:
            raise RuntimeError("ControllerWalk.step: the walk is over (fell, its strides or its "
                               "duration walked); allowed: reset() (no device) or a new walk")
        self._stepped = True
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
        if self.strides is not None and self._right_strides > self.strides:
            self._done[0] = True
            return
        dank = phys.leg_dof[:, 2]
        extra = ctl.joint_damping_nm_s_per_rad(phys)
        if extra is None:
            extra = self._no_extra
        # written only while the controller asks for damping (or did the step before)
        lim_now = bool(extra.any())
        if lim_now or self._lim_was:
            m.dof_damping[self._dlim] = self._base_limit + extra
        self._lim_was = lim_now
        dev = None
        if self._coupled:
            # end-of-step torque = force − D q̇ₙ₊₁, D integrated implicitly by MuJoCo
            dev, extra2 = device.begin_step(t, d.qpos[phys.leg_qpos[:, 2]], d.qvel[dank],
                                            ctl.stance)
            d.qfrc_applied[dank] = dev
            m.dof_damping[dank] = self._base_limit[:, 1] + extra[:, 1] + extra2
        elif device is not None:
            dev = np.asarray(device.torque_nm(t, d.qpos[phys.leg_qpos[:, 2]], d.qvel[dank],
                                              self.phase, ctl.stance), float)
            d.qfrc_applied[dank] = dev
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
        b["cz"][k] = d.geom_xpos[phys.contact_geoms.ravel(), 2]
        b["tau"][k] = ctl.joint_moments_nm(phys)
        b["res"][k] = d.qfrc_actuator[phys.pelvis_dof]
        for name, val in ctl.signal_values().items():
            self._sig[name][k] = val
        self._k = k + 1
        if not (np.isfinite(d.qpos).all() and np.isfinite(d.qvel).all()):
            self._done[0] = True
            raise FloatingPointError(f"{ctl.name} walk: non-finite state at t = "
                                     f"{d.time:.4f} s")
        q = d.qpos
        if q[phys.pelvis_qpos[1]] < self._fall_z or abs(q[phys.pelvis_qpos[2]]) > self._fall_tilt:
            self.events.fall_time_s = round(float(d.time), 9)
            self._done[0] = True
        elif self._k >= self.n_max:
            self._done[0] = True

    def run(self) -> GaitRecord:
        """Step to the end; returns :meth:`record`."""
        while not self._done[0]:
            self.step()
        return self.record()

    # -- named accessors ---------------------------------------------------------------------
    @property
    def stance(self) -> np.ndarray:
        """(2,) bool: the controller's stance state per leg."""
        return self.controller.stance

    @property
    def phase(self) -> np.ndarray:
        """(2,) gait phase per leg now from the recorded heel strikes (0 before a leg's second
        heel strike)."""
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
        """The :class:`~afo_mj.gait.record.GaitRecord` of the steps so far, with the
        controller's signals in ``signals``. Raises FloatingPointError when MuJoCo met a
        non-finite or huge control or acceleration on the way."""
        d, phys, k = self.data, self.phys, self._k
        bad = [w_ for w_ in ("BADQACC", "BADQVEL", "BADCTRL")
               if d.warning[getattr(mujoco.mjtWarning, "mjWARN_" + w_)].number > 0]
        if bad:
            raise FloatingPointError(f"{self.controller.name} walk: the simulation diverged "
                                     f"({', '.join(bad)}) before t = {d.time:.4f} s")
        b = {key: v[:k] for key, v in self._buf.items()}
        qq, vv = b["qpos"], b["qvel"]
        w = self.controller.walker_params()
        record = GaitRecord(
            body_mass_kg=w.body_mass_kg, height_m=w.height_m, sample_period_s=self._h,
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
            residual_force_n=b["res"][:, :2].copy(), residual_moment_nm=b["res"][:, 2].copy(),
            gait_phase=phase_from_events(b["time"], self.events), qpos=qq.copy(),
            model_xml=phys.xml,
            signals={name: v[:k].copy() for name, v in self._sig.items()})
        record.events = copy.deepcopy(self.events)
        return record
