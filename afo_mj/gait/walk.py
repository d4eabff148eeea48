"""Forward-dynamic walking of the sagittal torque-driven walker: the public entry points.

The walker's joints are driven by a tracking controller — PD servos on the reference gait at
each leg's gait phase, feedforward of the reference joint moments, SIMBICON-style balance and
foot placement, a trunk strategy, a toe-clearance reflex, weak pelvis residuals and a rule by
which the wearer hands ankle effort to a worn orthosis — described where it is declared,
:mod:`afo_mj.gait.tracking_controller` (:class:`ControllerParams`, :class:`ReferenceTable`,
:class:`~afo_mj.gait.tracking_controller.TrackingController`); its per-step law is one
compiled function, :func:`afo_mj.gait.control_law.control_step`.

The controller is a :class:`~afo_mj.gait.controller.HumanController` like every other human
model, and its steppable walk :class:`Walk` (:mod:`afo_mj.gait.tracking_walk`) is a
:class:`~afo_mj.gait.controller_walk.ControllerWalk` (buffers, events, falls, a worn device,
an action torque, the record) that keeps its own compiled 1 ms loop: the law, MuJoCo's C
``mj_step`` called directly (:mod:`afo_mj.gait.native_step`), a coupled device's C entry
points, events and the raw state into preallocated buffers (:mod:`afo_mj.gait.walk_loop`;
Python is entered only between progress updates; ``benchmarks/gait_step.py`` measures it
against a bare native ``mj_step``). A device whose torque is a Python callback runs the same
step in a Python loop (``loop="python"``), which gives the same record bit for bit.

This module keeps the names callers import: :func:`run_walk`, :func:`simulate_walk`,
:class:`Walk`, :class:`ControllerParams`, :class:`ReferenceTable`, the device protocols and
the errors.
"""

from __future__ import annotations

from typing import Protocol

import numpy as np

from afo_mj.gait.record import GaitRecord
from afo_mj.gait.tracking_controller import (FALL_HEIGHT_FRACTION, FALL_TILT_RAD, GRAVITY_M_S2,
                                             TOE_OFF_CHATTER_S, ControllerParams,
                                             ReferenceTable, TrackingController)
from afo_mj.gait.tracking_walk import (PROGRESS_EVERY_S, Walk, WalkerModelError,
                                       WalkNumericsError, check_torque_walker)
from afo_mj.human.walker import WalkerParams

__all__ = ["ControllerParams", "ReferenceTable", "TrackingController", "Walk", "AnkleDevice",
           "CoupledAnkleDevice", "WalkNumericsError", "WalkerModelError",
           "check_torque_walker", "run_walk", "simulate_walk", "GRAVITY_M_S2",
           "TOE_OFF_CHATTER_S", "FALL_HEIGHT_FRACTION", "FALL_TILT_RAD", "PROGRESS_EVERY_S"]


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
                max_time_s, loop).run(label=label)


def simulate_walk(scenario, device: AnkleDevice | None = None, worn_masses=()) -> GaitRecord:
    """Walk a :class:`~afo_mj.scenarios.walk_scenario.WalkScenario` on the walker it names
    (``walker.model``: the torque walker as :func:`run_walk`, the muscle walker, or a
    registered controller; :mod:`afo_mj.gait.walkers`, as ``afo-mj run`` walks it) and return
    its record. A muscle walk's record carries its muscles' signals in ``record.signals``."""
    from afo_mj.gait.walkers import walk_scenario
    return walk_scenario(scenario, device, tuple(worn_masses))[0]
