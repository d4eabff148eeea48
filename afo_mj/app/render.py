"""``afo-mj render SCENARIO --mp4 FILE``: simulate a walking scenario and render the walk.

Loading and simulating are here; the frames and the MP4 are :mod:`afo_mj.outputs.video`
(:func:`~afo_mj.outputs.video.render_record`, given the record of the walk).
"""

from __future__ import annotations

from pathlib import Path
from typing import Callable

from afo_mj.app.errors import InvalidInput
from afo_mj.outputs import video
from afo_mj.outputs.video import RenderError

__all__ = ["render", "InvalidRender"]


class InvalidRender(InvalidInput, RenderError):
    """A render request that is not allowed (option out of range, bench scenario, unknown
    condition, invalid scenario file): exit 2, nothing written. Both an
    :class:`afo_mj.app.errors.InvalidInput` and a :class:`afo_mj.outputs.video.RenderError`
    (a ValueError: what ``render_scenario`` raised before the application layer)."""


def render(scenario_path, mp4_path, overrides=(), condition: str | None = None,
           fps: int = 30, width: int = 640, height: int = 480,
           max_seconds: float | None = None,
           progress: Callable[[int, int], None] | None = None) -> dict:
    """Load a walking scenario, simulate it and render the walk to ``mp4_path``.

    A scenario with a ``[device]`` table runs one of its conditions (``condition``, default
    the last listed, the headline: usually ``assist``); a plain walk takes no condition. A
    bench scenario (``[bench]`` table) has no walk to render. The walk is the scenario's own
    walker (``walker.model``: the torque-driven or the muscle-driven one), walked as
    ``afo-mj run`` walks it (:func:`afo_mj.gait.walkers.walk_scenario`).
    ``fps``, ``width``, ``height``,
    ``max_seconds`` and ``progress`` as for :func:`afo_mj.outputs.video.render_record`,
    checked before the (slow) simulation.

    Returns :func:`~afo_mj.outputs.video.render_record`'s dict (``frames``, ``fps``,
    ``width``, ``height``, ``duration_s``, ``codec``, ``path``) plus ``condition``,
    ``scenario`` (its name) and ``fall_time_s`` (None unless the walker fell, which ends the
    video early). Raises :class:`InvalidRender` for a request that is not allowed, including
    an invalid scenario file (the :class:`~afo_mj.scenarios.walk_scenario.ScenarioError`'s
    message); a failure while rendering (no OpenGL context, unknown container) raises
    :class:`~afo_mj.outputs.video.RenderError` as :func:`~afo_mj.outputs.video.render_record`
    does. Nothing is written when either is raised.
    """
    from afo_mj.scenarios.bench_scenario import is_bench_document
    from afo_mj.scenarios.walk_scenario import ScenarioError, load_scenario

    try:
        video.check_render_options(fps, width, height, max_seconds)
    except RenderError as exc:
        raise InvalidRender(str(exc)) from None
    p = Path(scenario_path)
    try:
        text = p.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError):
        text = None                     # load_scenario reports it as a ScenarioError
    if text is not None and is_bench_document(text):
        raise InvalidRender(f"{p}: scenario = {p.name!r} is a bench scenario ([bench] table: "
                            "a device on a test stand, no walk); allowed: a walking scenario "
                            "(with or without a [device] table)")
    if condition is not None and not isinstance(condition, str):
        raise InvalidRender(f"condition = {condition!r} is not allowed; allowed: a string")
    video.choose_gl()                   # the GL backend, before MuJoCo is imported
    try:
        s = load_scenario(p, overrides=tuple(overrides))
    except ScenarioError as exc:
        raise InvalidRender(str(exc)) from None
    from afo_mj.experiments.device_walk import make_device
    from afo_mj.gait.muscle_scenario import MuscleScenarioError
    from afo_mj.gait.walkers import walk_duration_s, walk_scenario
    from afo_mj.scenarios.device_scenario import device_config
    try:
        cfg = device_config(s)
    except ScenarioError as exc:
        raise InvalidRender(str(exc)) from None
    ref = s.load_reference()
    if cfg is None:
        if condition is not None:
            raise InvalidRender(f"{p}: condition = {condition!r} is not allowed; allowed: "
                                "none (the scenario has no [device] table, so it has no "
                                "conditions)")
        dev, sides, label = None, (), s.name
    else:
        cond = cfg.conditions[-1] if condition is None else condition
        if cond not in cfg.conditions:
            raise InvalidRender(f"{p}: condition = {cond!r} is not allowed; allowed: "
                                + " | ".join(cfg.conditions))
        condition = cond
        dt = s.walker.timestep_s
        try:
            dev = (None if cond == "no_device" else
                   make_device(cfg, cond, dt, int(walk_duration_s(s, ref) / dt) + 4))
        except MuscleScenarioError as exc:
            raise InvalidRender(str(exc)) from None
        sides = () if dev is None else tuple(cfg.sides)
        label = f"{s.name} \u00b7 {cond}"
    try:
        # the scenario's own walker (walker.model), as afo-mj run walks it
        rec, _muscles = walk_scenario(s, dev, dev.worn_masses() if dev is not None else (),
                                      reference=ref)
    except MuscleScenarioError as exc:
        raise InvalidRender(str(exc)) from None
    facts = video.render_record(rec, mp4_path, fps=fps, width=width, height=height,
                                max_seconds=max_seconds, progress=progress,
                                device_sides=sides, label=label)
    facts.update(condition=condition, scenario=s.name, fall_time_s=rec.events.fall_time_s)
    return facts
