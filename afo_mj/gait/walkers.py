"""The walker models, registered once: how a scenario naming ``walker.model`` is walked by every
entry point (``afo-mj run`` of plain and device walks, ``compare``, ``sweep``, ``walk_batch``,
``afo-mj render``) and stepped by the gymnasium environment
(:mod:`afo_mj.experiments.walk_env`). A model is added by one entry of :data:`WALKER_MODELS`,
not by branches in the callers:

* ``"torque"``: the tracking walker (:func:`afo_mj.gait.walk.run_walk`, its steppable
  :class:`~afo_mj.gait.walk.Walk`);
* ``"muscle"``: the reflex walker (:func:`afo_mj.gait.muscle_scenario.
  walk_muscle_scenario`, its steppable :class:`~afo_mj.gait.muscle_walk.MuscleWalkStepper`);
* any controller registered with :func:`afo_mj.gait.controller.register_controller`: stepped
  by :class:`afo_mj.gait.controller_walk.ControllerWalk` (:data:`CONTROLLER_WALKER`), built
  from the scenario's walker, reference, cycle time, strides and ``[controller]`` table.
"""

from __future__ import annotations

import dataclasses
from typing import Callable

__all__ = ["WalkerModel", "WALKER_MODELS", "CONTROLLER_WALKER", "walker_model", "walk_scenario",
           "walk_duration_s", "walker_models"]


@dataclasses.dataclass(frozen=True)
class WalkerModel:
    """One walker model.

    ``walk(scenario, reference, device, worn_masses, label) -> (record, muscle walk or None)``:
    the whole walk; ``duration(scenario, reference)``: the longest it lasts (s), what a worn
    device must be able to log; ``stepper(scenario, reference, device, worn_masses)``: a
    steppable walk (``step(action)``, ``done``, ``fallen``, ``steps``, ``time_s``,
    ``joint_angles_rad``, ``joint_velocities_rad_s``, ``phase``, ``stance``, ``grf_n``,
    ``pelvis_speed_m_s``, ``phys``, ``record()``); ``ankle_moments(stepper)``: the (human,
    device + action) ankle moments per side of its last step (N·m)."""

    walk: Callable
    duration: Callable
    stepper: Callable
    ankle_moments: Callable


def _walk_torque(scenario, reference, dev, worn, label):
    from afo_mj.gait.walk import run_walk
    rec = run_walk(scenario.walker, reference, scenario.cycle_time_s(reference),
                   scenario.strides, scenario.controller_params(), worn_masses=worn,
                   device=dev, label=label)
    return rec, None


def _torque_duration_s(scenario, reference) -> float:
    return (scenario.strides + 1.5) * scenario.cycle_time_s(reference) + 1.0


def _torque_stepper(scenario, reference, device, worn):
    from afo_mj.gait.walk import Walk
    return Walk(scenario.walker, reference, scenario.cycle_time_s(reference), scenario.strides,
                scenario.controller_params(), worn_masses=worn, device=device)




def _walk_muscle(scenario, reference, dev, worn, label):
    from afo_mj.gait.muscle_scenario import walk_muscle_scenario
    walk = walk_muscle_scenario(scenario, device=dev, worn_masses=worn)
    return walk.record, walk


def _muscle_duration_s(scenario, reference) -> float:
    from afo_mj.gait.muscle_scenario import muscle_walk_duration_s
    return muscle_walk_duration_s(scenario)


def _muscle_stepper(scenario, reference, device, worn):
    from afo_mj.gait.muscle_scenario import muscle_scenario_stepper
    return muscle_scenario_stepper(scenario, device=device, worn_masses=worn)


def _controller(scenario, reference):
    from afo_mj.gait.controller import ControllerSetup, controller_class
    cls = controller_class(scenario.walker_model)
    setup = ControllerSetup(scenario.walker, reference, scenario.cycle_time_s(reference),
                            scenario.strides)
    return cls(scenario.controller_params(), setup)


def _controller_stepper(scenario, reference, device, worn):
    from afo_mj.gait.controller_walk import ControllerWalk
    return ControllerWalk(_controller(scenario, reference),
                          _torque_duration_s(scenario, reference), scenario.strides,
                          worn_masses=worn, device=device)


def _walk_controller(scenario, reference, dev, worn, label):
    return _controller_stepper(scenario, reference, dev, worn).run(), None


def _controller_moments(w):
    return w.joint_moment_nm[:, 2], w.device_moment_nm


#: the walker of every registered controller (:mod:`afo_mj.gait.controller`): its walk lasts
#: as long as the torque walker's (``strides`` + 1.5 cycles + 1 s at most)
CONTROLLER_WALKER = WalkerModel(_walk_controller, _torque_duration_s, _controller_stepper,
                                _controller_moments)

#: The walker models by ``walker.model`` name.
WALKER_MODELS = {
    "torque": WalkerModel(_walk_torque, _torque_duration_s, _torque_stepper,
                          _controller_moments),
    "muscle": WalkerModel(_walk_muscle, _muscle_duration_s, _muscle_stepper,
                          _controller_moments),
}


def walker_models() -> tuple[str, ...]:
    """The walker models: the built-in ones and every registered controller."""
    from afo_mj.gait.controller import controller_names
    return tuple(WALKER_MODELS) + tuple(n for n in controller_names() if n not in WALKER_MODELS)


def walker_model(scenario, where: str = "") -> WalkerModel:
    """The entry of the model ``scenario`` names; an unregistered one raises ValueError
    naming it and the allowed ones (``where``: what refuses it)."""
    model = getattr(scenario, "walker_model", "torque")
    if model in WALKER_MODELS:
        return WALKER_MODELS[model]
    from afo_mj.gait.controller import BUILTIN, controller_names
    if model in controller_names() and model not in BUILTIN:
        return CONTROLLER_WALKER
    raise ValueError(f"walker.model = {model!r}; allowed{' in ' + where if where else ''}: "
                     + ", ".join(repr(m) for m in walker_models()))


def walk_scenario(scenario, device=None, worn_masses=(), label: str = "", reference=None):
    """Walk ``scenario`` on its walker, wearing ``device`` and ``worn_masses`` when given;
    returns ``(record, muscle walk or None)`` (the :class:`~afo_mj.gait.record.GaitRecord`,
    and the :class:`~afo_mj.gait.muscle_walk.MuscleWalk` with the muscles' signals on the
    muscle walker). ``label`` names the walk in progress lines; ``reference`` defaults to the
    scenario's."""
    ref = scenario.load_reference() if reference is None else reference
    return walker_model(scenario).walk(scenario, ref, device, tuple(worn_masses), label)


def walk_duration_s(scenario, reference=None) -> float:
    """The longest the scenario's walk lasts (s): what a device worn on it must be able to
    log."""
    ref = scenario.load_reference() if reference is None else reference
    return walker_model(scenario).duration(scenario, ref)
