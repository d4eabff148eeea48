"""One walk of a scenario on the walker it names (``walker.model``), for every entry point that
walks a scenario without stepping it interactively: ``afo-mj run`` (plain and device walks),
``walk_batch``, ``afo-mj render``. The models are registered once, in
:data:`afo_mj.experiments.device_walk.WALKERS` (``"torque"``: the tracking walker's
:func:`~afo_mj.gait.walk.run_walk`; ``"muscle"``: the reflex walker through
:func:`~afo_mj.experiments.muscle_scenario.walk_muscle_scenario`); a model is added there, not
by a branch here.
"""

from __future__ import annotations

__all__ = ["walk_scenario", "walk_duration_s", "walker_models"]


def walker_models() -> tuple[str, ...]:
    """The registered walker models."""
    from afo_mj.experiments.device_walk import WALKERS
    return tuple(WALKERS)


def _entry(scenario):
    from afo_mj.experiments.device_walk import WALKERS
    model = getattr(scenario, "walker_model", "torque")
    if model not in WALKERS:
        raise ValueError(f"walker.model = {model!r}; allowed: "
                         + ", ".join(repr(m) for m in WALKERS))
    return WALKERS[model]


def walk_scenario(scenario, device=None, worn_masses=(), label: str = "", reference=None):
    """Walk ``scenario`` on its walker, wearing ``device`` and ``worn_masses`` when given;
    returns ``(record, muscle walk or None)`` (the :class:`~afo_mj.gait.record.GaitRecord`,
    and the :class:`~afo_mj.gait.muscle_walk.MuscleWalk` with the muscles' signals on the
    muscle walker). ``label`` names the walk in progress lines; ``reference`` defaults to the
    scenario's."""
    walk, _duration = _entry(scenario)
    ref = scenario.load_reference() if reference is None else reference
    return walk(scenario, ref, device, tuple(worn_masses), label)


def walk_duration_s(scenario, reference=None) -> float:
    """The longest the scenario's walk lasts (s): what a device worn on it must be able to
    log."""
    _walk, duration = _entry(scenario)
    ref = scenario.load_reference() if reference is None else reference
    return duration(scenario, ref)
