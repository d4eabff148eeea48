"""A ``walker.model = "muscle"`` scenario walked by the muscle-driven walker
(:func:`afo_mj.gait.muscle_walk.run_muscle_walk`), with or without an orthosis: the one place
that turns such a scenario into the walk's arguments, for ``afo-mj run`` of a plain muscle
scenario and for every condition of a device scenario on the muscle walker
(:func:`afo_mj.experiments.device_walk.run_device_scenario`), and steppable
(:func:`muscle_scenario_stepper`) for the gymnasium environment.

What the scenario sets:

* ``walker.reflex_set``: the reflex parameters (a shipped set or an ``afo-mj optimize-gait``
  file, :func:`afo_mj.gait.muscle_walk.load_reflex_set`);
* ``gait.strides``: the walk lasts ``1 s + (strides + 2) ×`` the set's recorded stride time
  (``quality.stride_s`` of the file, 1.2 s without one), so that the requested right strides
  complete with a margin;
* ``[walker]`` body: mass, stature (muscles scaled by geometric similarity,
  :func:`afo_mj.gait.muscle_walk.muscle_table_scaled`);
* ``[impairment]`` strength fractions: the muscles' maximum-force factors (plantarflexor:
  soleus and gastrocnemius; dorsiflexor: tibialis anterior), floored at 0.01.
"""

from __future__ import annotations

import json
from pathlib import Path

__all__ = ["MuscleScenarioError", "muscle_walk_duration_s", "muscle_force_scale",
           "walk_muscle_scenario", "muscle_scenario_stepper"]

#: the stride time assumed for a reflex file that records none (s)
DEFAULT_STRIDE_S = 1.2


class MuscleScenarioError(ValueError):
    """The scenario's reflex set cannot be read (the message names ``walker.reflex_set``)."""


def _reflex_set(scenario):
    """``(parameter vector, file document)`` of the scenario's reflex set."""
    from afo_mj.gait.muscle_walk import load_reflex_set
    try:
        params = load_reflex_set(scenario.reflex_set)
        doc = json.loads(Path(scenario.reflex_set).read_text(encoding="utf-8"))
    except (OSError, ValueError, KeyError, TypeError) as exc:
        raise MuscleScenarioError(f"walker.reflex_set = {str(scenario.reflex_set)!r}: "
                                  f"{exc}") from None
    return params, doc


def muscle_walk_duration_s(scenario) -> float:
    """How long the scenario's muscle walk lasts (s): 1 s plus ``gait.strides + 2`` of its
    reflex set's recorded stride time."""
    _params, doc = _reflex_set(scenario)
    stride = float((doc.get("quality") or {}).get("stride_s") or DEFAULT_STRIDE_S)
    return 1.0 + (scenario.strides + 2) * stride


def muscle_force_scale(walker) -> dict | None:
    """The ``[impairment]`` strength fractions of ``walker`` as the muscles' maximum-force
    factors (None when all are 1)."""
    scale = {}
    for names, f in ((("soleus", "gastrocnemius"), walker.plantarflexor_strength_fraction),
                     (("tibialis_anterior",), walker.dorsiflexor_strength_fraction)):
        if f != 1.0:
            scale.update({n: max(float(f), 0.01) for n in names})
    return scale or None


def _walk_args(scenario, device, worn_masses) -> dict:
    """The arguments of the scenario's muscle walk (:func:`run_muscle_walk` and
    :class:`MuscleWalkStepper` take the same)."""
    if device is not None and not getattr(device, "coupled", False):
        raise ValueError(f"device {type(device).__name__}: an uncoupled AnkleDevice "
                         f"(torque_nm only) cannot be worn by the muscle walker, whose reflex "
                         f"controller estimates no gait phase to give it; allowed: a coupled "
                         f"device (begin_step/end_step: a CircuitDevice, an IdealDevice), or "
                         f"walker.model = 'torque'")
    params, _doc = _reflex_set(scenario)
    w = scenario.walker
    return dict(walker=w, params=params, duration_s=muscle_walk_duration_s(scenario),
                worn_masses=worn_masses, device=device, max_force_scale=muscle_force_scale(w))


def walk_muscle_scenario(scenario, device=None, worn_masses=()):
    """The muscle walk of ``scenario`` (a :class:`~afo_mj.gait.muscle_walk.MuscleWalk`),
    wearing ``device`` (a coupled orthosis stepped with MuJoCo, e.g. a
    :class:`~afo_mj.circuits.device.CircuitDevice`; its foot switch is the reflex
    controller's stance) and ``worn_masses`` when given."""
    from afo_mj.gait.muscle_walk import run_muscle_walk
    return run_muscle_walk(**_walk_args(scenario, device, worn_masses))


def muscle_scenario_stepper(scenario, device=None, worn_masses=()):
    """The same walk as :func:`walk_muscle_scenario`, steppable: a
    :class:`~afo_mj.gait.muscle_walk.MuscleWalkStepper` (stepped to its end, its record is
    that walk's)."""
    from afo_mj.gait.muscle_walk import MuscleWalkStepper
    return MuscleWalkStepper(**_walk_args(scenario, device, worn_masses))
