"""The torque-driven walker's steppable walk: the tracking controller
(:class:`afo_mj.gait.tracking_controller.TrackingController`) walked by the walk every human
controller has (:class:`afo_mj.gait.controller_walk.ControllerWalk`: buffers, events, falls, a
worn device, an action torque, the record), with its own compiled 1 ms loop
(:func:`afo_mj.gait.walk_loop.walk_steps`: the same law, MuJoCo's C ``mj_step`` called
directly, a coupled device's C entry points, no Python per step) where it applies, and the
progress lines of a whole run.

The compiled loop and the Python step are the same walk bit for bit, so a walk may switch
between them (a step with an action torque, and the one after it, runs in Python).
"""

from __future__ import annotations

import numpy as np

from afo_mj import progress
from afo_mj.gait import control_law as law
from afo_mj.gait.controller import ControllerSetup
from afo_mj.gait.controller_walk import ControllerWalk, pack_native_device
from afo_mj.gait.record import GaitRecord
from afo_mj.gait.tracking_controller import ControllerParams, TrackingController
from afo_mj.human.walker import WalkerParams

__all__ = ["Walk", "WalkNumericsError", "WalkerModelError", "check_torque_walker",
           "PROGRESS_EVERY_S"]

#: simulated seconds between two progress updates of a walk (when a reporter is active)
PROGRESS_EVERY_S = 0.5
_LOOPS = ("auto", "compiled", "python")


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


class Walk(ControllerWalk):
    """A steppable walk of the torque-driven walker, in the manner of dm_control's ``Physics``:
    :meth:`reset`, :meth:`step` (one MuJoCo step of the controller, the device and the
    physics, returning that step's gait events), named accessors of the state and
    :meth:`record` (the :class:`~afo_mj.gait.record.GaitRecord` of the steps so far).
    :func:`afo_mj.gait.walk.run_walk` is its :meth:`run`, so a walk stepped here to its end is
    the record ``run_walk`` returns, bit for bit.

    ``step(action)``: ``action`` an extra ankle torque per side (N·m, + dorsiflexion, right
    then left) applied beside the muscles and any device for this step, and recorded with the
    device's in ``device_moment_nm``; None applies nothing. The walk is over (:attr:`done`)
    when the walker fell, when ``strides`` right strides are done or at ``max_time_s``
    (default ``(strides + 1.5)`` cycles + 1 s); a non-finite state raises
    :class:`WalkNumericsError`.

    ``loop``: where a step runs, as for :class:`~afo_mj.gait.controller_walk.ControllerWalk`:
    ``"compiled"`` (:mod:`afo_mj.gait.walk_loop`; refused for a device whose torque is a
    Python callback), ``"python"``, ``"auto"`` (default: compiled where it applies).

    Example::

        w = Walk(WalkerParams(), load_normative(), 1.1396, strides=4)
        while not w.done:
            events = w.step()                 # (right, left): 1 heel strike, 2 toe off, …
        rec = w.record()
    """

    #: event codes :meth:`step` returns per side
    NO_EVENT, HEEL_STRIKE, TOE_OFF, SWING_TOE_CONTACT = 0, 1, 2, 3

    @classmethod
    def from_scenario(cls, scenario, device=None, worn_masses=(),
                      max_time_s: float | None = None,
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
                 controller: ControllerParams | None = None, worn_masses=(), device=None,
                 max_time_s: float | None = None, loop: str = "auto"):
        T = float(cycle_time_s)
        self.walker = walker
        self.max_time_s = max_time_s if max_time_s is not None else (strides + 1.5) * T + 1.0
        ctl = TrackingController(controller or ControllerParams(),
                                 ControllerSetup(walker, reference, T, strides))
        super().__init__(ctl, self.max_time_s, strides, worn_masses, device, loop)

    def _max_steps(self, h: float) -> int:
        return int(self.max_time_s / h) + 2

    def _compiled_runner(self):
        """The walk's compiled loop (:class:`_TrackingRun`), or None where it does not apply
        (refused with the reason when ``loop = "compiled"``)."""
        if self.loop == "python":
            return None
        device, nc = self.device, None
        if device is not None:
            nc = device.native_coupling() if (self._coupled and hasattr(
                device, "native_coupling")) else None
            if nc is None:
                if self.loop == "compiled":
                    raise ValueError(
                        f"loop = 'compiled' needs no device or a coupled device with compiled "
                        f"entry points (native_coupling); the device {type(device).__name__} "
                        f"is a Python callback of its torque (or has no compiled entry "
                        f"points) and runs in the Python loop; allowed: 'auto', 'python'")
                return None
        return _TrackingRun(self, nc)

    # -- stepping --------------------------------------------------------------------------
    def step(self, action=None) -> tuple[int, int]:
        """One step (:meth:`ControllerWalk.step`); returns the step's event code per side
        (:attr:`NO_EVENT`, :attr:`HEEL_STRIKE`, :attr:`TOE_OFF`, :attr:`SWING_TOE_CONTACT`)."""
        super().step(action)
        st = self.controller.state
        return int(st[law.S_EVENT]), int(st[law.S_EVENT + 1])

    def _step_python(self, action=None) -> None:
        try:
            super()._step_python(action)
        except FloatingPointError as exc:
            d = self.data
            raise WalkNumericsError(f"non-finite walker state at t = {d.time:.4f} s "
                                    f"(qpos={d.qpos.tolist()}, qvel={d.qvel.tolist()})") from exc

    # -- the whole walk ----------------------------------------------------------------------
    def run(self, loop: str | None = None, label: str = "") -> GaitRecord:
        """Step to the end — compiled or in Python (``loop``, default the walk's own;
        :func:`afo_mj.gait.walk.run_walk`) — with progress lines (``label`` names the walk in
        them); returns :meth:`record`. Refused on a walk already stepped."""
        if loop is not None and loop not in _LOOPS:
            raise ValueError(f"loop = {loop!r}; allowed: 'auto', 'compiled', 'python'")
        if self._stepped:
            raise RuntimeError("Walk.run: already stepped; allowed: run() on a fresh Walk")
        if loop is not None and loop != self.loop:
            self.loop = loop
            self._run_compiled = self._compiled_runner()
        runner, data, n_max = self._run_compiled, self.data, self.n_max
        ctl = self.controller
        # the compiled controller: compiled (first run) or loaded from numba's cache now, with
        # a stage line, rather than silently inside the first step
        progress.compile_stage(law.control_step, (data.time,) + ctl._args,
                               "the walking controller", "~2 s")
        if runner is not None:
            progress.compile_stage(runner.walk_steps, (0, 0) + runner.args, "the walk loop",
                                   "~1 s")
        rep = progress.reporter()
        if rep.active:
            expected_s = min((self.strides + 1) * ctl.setup.cycle_time_s, n_max * self._h)
            task = rep.task(f"simulating {self.strides} strides"
                            + (f" ({label})" if label else ""), expected_s, "s simulated",
                            fmt=lambda v: f"{v:.1f}")
            report_every = max(int(round(PROGRESS_EVERY_S / self._h)), 1)
        else:
            task, report_every = None, n_max + 1
        self._stepped = True
        try:
            next_report = report_every
            while not self._done[0]:
                if runner is not None:
                    runner(self._k + report_every)
                else:
                    self._step_python()
                if task is not None and (runner is not None or self._k >= next_report):
                    task.update(min(data.time, task.total))
                    next_report += report_every
        except Exception:
            if task is not None:
                task.abort()
            raise
        if task is not None:
            fall = self.events.fall_time_s
            el = progress.fmt_duration(task.elapsed())
            task.close(f"{task.label}: {data.time:.1f} s simulated in {el}"
                       + (f" (fell at t = {fall:.2f} s)" if fall is not None else ""))
        return self.record()


class _TrackingRun:
    """The compiled loop (:func:`afo_mj.gait.walk_loop.walk_steps`) bound to a :class:`Walk`'s
    arrays once; ``run(k_end)`` runs it from the walk's row on (to ``k_end`` at most) and moves
    the walk's counters, events, a coupled device's counters and its end on, raising what the
    Python step raises."""

    def __init__(self, walk: Walk, nc):
        from afo_mj.gait import walk_loop as wl
        from afo_mj.gait.native_step import native_step, time_view
        self.walk, self.nc, self.wl, self.walk_steps = walk, nc, wl, wl.walk_steps
        ctl, phys, device = walk.controller, walk.phys, walk.device
        m, d = phys.model, phys.data
        lc = np.zeros(wl.N_LOOP_CONST)
        lc[wl.L_STRIDES] = walk.strides
        lc[wl.L_FALL_DZ], lc[wl.L_FALL_TILT] = walk._fall_z, walk._fall_tilt
        li = np.zeros(wl.N_LOOP_INDEX, dtype=np.int64)
        li[wl.LI_PZ], li[wl.LI_PT] = walk._pz, walk._pt
        li[wl.LI_FN] = native_step().mj_step_address
        li[wl.LI_MODEL], li[wl.LI_DATA] = m._address, d._address
        n_max = walk.n_max
        self.ev_time = np.zeros(2 * n_max + 4)
        self.ev_code = np.zeros((2 * n_max + 4, 2), dtype=np.int64)
        dev_io = np.zeros(6)
        outs = (np.zeros(2), np.zeros(2), np.zeros(2))
        if nc is not None:
            pack_native_device(li, wl, nc, dev_io)
            li[wl.LI_ANK_R], li[wl.LI_ANK_L] = walk._ank_q
            li[wl.LI_DANK_R], li[wl.LI_DANK_L] = walk._dank
            li[wl.LI_FF_R], li[wl.LI_FF_L] = ctl._ff_ankle
            lc[wl.L_BASE_DAMP_R], lc[wl.L_BASE_DAMP_L] = walk._base_limit[:, 1]
            lc[wl.L_ADAPT] = ctl.params.assistance_adaptation
            lc[wl.L_DEV_DT] = float(device.timestep_s)
            outs = (nc.force2, nc.damping2, nc.delivered2)
        b = walk._buf
        i64 = lambda a: np.ascontiguousarray(a, dtype=np.int64)  # noqa: E731
        (qpos, qvel, sens, gxpos, state, tab, tab_step, const, index, ctrl,
         actfrc) = ctl._args
        self.args = (time_view(d), qpos, qvel, sens, gxpos, state, tab, tab_step, const, index,
                     ctrl, actfrc, d.qfrc_actuator, i64(walk._contact), i64(phys.leg_dof),
                     i64(phys.pelvis_dof), b["time"], b["qpos"], b["qvel"], b["tau"], b["res"],
                     b["sens"], b["cz"], walk._sig, self.ev_time, self.ev_code, lc, li,
                     d.qfrc_applied, m.dof_damping, dev_io) + outs + (b["dev"],)
        self.lc, self.li = lc, li

    def __call__(self, k_end: int) -> None:
        walk, wl, li, lc, nc = self.walk, self.wl, self.li, self.lc, self.nc
        ev = walk.events
        li[wl.LI_N_EVENTS] = 0
        li[wl.LI_RIGHT_STRIDES] = walk._right_strides
        steps0 = li[wl.LI_DEV_STEPS] = walk.device.steps if nc is not None else 0
        code, k = self.walk_steps(walk._k, min(k_end, walk.n_max), *self.args)
        walk._k = k
        for n in range(int(li[wl.LI_N_EVENTS])):
            t, side, kind = float(self.ev_time[n]), int(self.ev_code[n, 0]), \
                int(self.ev_code[n, 1])
            if kind == wl.EV_HEEL_STRIKE:
                ev.heel_strikes_s[side].append(t)
            elif kind == wl.EV_TOE_OFF:
                ev.toe_offs_s[side].append(t)
            else:
                ev.swing_toe_contacts.append((t, side))
        walk._right_strides = int(li[wl.LI_RIGHT_STRIDES])
        if code != wl.CHUNK_DONE or k >= walk.n_max:
            walk._done[0] = True
        if nc is not None:
            walk.device.native_finished(int(li[wl.LI_DEV_STEPS]) - steps0,
                                        float(lc[wl.L_DEV_LAST_T]),
                                        failed=code == wl.DEVICE_NON_FINITE)
        d = walk.data
        if code == wl.NON_FINITE:
            raise WalkNumericsError(f"non-finite walker state at t = {d.time:.4f} s "
                                    f"(qpos={d.qpos.tolist()}, qvel={d.qvel.tolist()})")
        if code == wl.FELL:
            ev.fall_time_s = round(float(d.time), 9)   # the sum of steps, not 4.3419999
