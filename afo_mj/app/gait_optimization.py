"""``afo-mj optimize-gait``: optimise the muscle-reflex walker's controller (CMA-ES,
:mod:`afo_mj.studies.gait_optimization`) for steady walking at a target speed, with progress
per generation; resumable (run again with the same ``--out`` to continue).

With ``--scenario FILE`` the wearer is re-optimised with that scenario's device worn
(:func:`afo_mj.studies.gait_optimization.scenario_objective`): its body and impairment, the
device of ``--condition`` (default its last listed condition), its ``walker.reflex_set`` the
warm start unless ``--start`` is given.

Raises :class:`~afo_mj.app.errors.InvalidInput` (exit 2, nothing written) for an option out
of range, a ``--start`` file that is not a reflex parameter set, an output folder that
holds an optimisation of another objective, a scenario that is not a muscle-walker scenario
or names no such condition, or an option the scenario sets itself (``--assistance``, the
body, the weakness, the ramp) given with ``--scenario``.
"""

from __future__ import annotations

import math
from pathlib import Path

from afo_mj.app.errors import InvalidInput

__all__ = ["optimize_reflex_gait"]


def optimize_reflex_gait(out, speed_m_s: float = 1.25, generations: int = 60,
                         popsize: int = 16, seed: int = 1, start: str | None = None,
                         workers: int | None = None, body_mass_kg: float | None = None,
                         height_m: float | None = None, assistance: str | None = None,
                         robust: bool = False, plantarflexor_strength: float | None = None,
                         sigma0: float = 0.2, tracking_weight: float = 1.0,
                         tracking_max_weight: float = 0.0, effort_weight: float = 1.0,
                         emg_weight: float = 0.0, duration_s: float = 12.0,
                         ramp_strides: int | None = None, scenario: str | None = None,
                         condition: str | None = None, overrides=None) -> dict:
    """Run (or continue) the optimisation into ``out``; returns ``reflex_params.json``'s
    content. ``assistance``: the condition worn while walking
    (:data:`afo_mj.experiments.muscle_assistance.KINDS`, its defaults); ``robust``: the
    perturbed walkers of :func:`~afo_mj.studies.gait_optimization.robustness_variants` must
    walk too; ``plantarflexor_strength``: the wearer's soleus and gastrocnemius maximum force
    as a fraction (a weakness, 0.05 … 1); ``sigma0`` CMA-ES's initial step; the weights and
    ``duration_s`` those of :class:`~afo_mj.studies.gait_optimization.GaitObjective`;
    ``ramp_strides``: the ideal torque's ramp-on (``Assistance.ramp_strides``). None for
    ``body_mass_kg``, ``height_m``, ``assistance``, ``plantarflexor_strength`` and
    ``ramp_strides``: not given (75 kg, 1.75 m, none, 1, 0). ``scenario``: a muscle-walker
    scenario file whose device (in ``condition``, default its last) is worn instead, with
    ``overrides`` (``KEY=VALUE``, as ``afo-mj run --set``) applied to it; those five are then
    the scenario's and may not be given."""
    given = {"--assistance": assistance, "--body-mass-kg": body_mass_kg,
             "--height-m": height_m, "--plantarflexor-strength": plantarflexor_strength,
             "--ramp-strides": ramp_strides}
    if scenario is not None:
        for name, value in given.items():
            if value is not None:
                raise InvalidInput(f"{name} = {value!r} with --scenario {scenario}; allowed: "
                                   "one of them (the scenario sets the device and the body: "
                                   "change them in its file or with --set KEY=VALUE)")
    elif condition is not None or overrides:
        what = "--condition" if condition is not None else "--set"
        raise InvalidInput(f"{what} = {condition if condition is not None else overrides!r} "
                           "without --scenario; allowed: with --scenario FILE only")
    body_mass_kg = 75.0 if body_mass_kg is None else body_mass_kg
    height_m = 1.75 if height_m is None else height_m
    assistance = "none" if assistance is None else assistance
    plantarflexor_strength = 1.0 if plantarflexor_strength is None else plantarflexor_strength
    ramp_strides = 0 if ramp_strides is None else ramp_strides
    from afo_mj import progress
    from afo_mj.hydraulics.params import ParameterError
    from afo_mj.human.walker import WalkerParams
    from afo_mj.experiments.muscle_assistance import Assistance
    from afo_mj.studies.gait_optimization import (GaitObjective, load_reflex_set,
                                                  optimize_gait, robustness_variants,
                                                  scenario_objective)
    from afo_mj.gait import reflex_law as rl
    checks = (("--speed", speed_m_s, 0.3 <= speed_m_s <= 2.5, "0.3 to 2.5 m/s"),
              ("--generations", generations, generations >= 1, ">= 1"),
              ("--popsize", popsize, popsize >= 4, ">= 4"),
              ("--workers", workers, workers is None or workers >= 1, ">= 1"),
              ("--plantarflexor-strength", plantarflexor_strength,
               0.05 <= plantarflexor_strength <= 1.0, "0.05 to 1"),
              ("--sigma0", sigma0, 0.0 < sigma0 <= 2.0, "(0, 2]"),
              ("--tracking-weight", tracking_weight, tracking_weight >= 0.0, ">= 0"),
              ("--tracking-max-weight", tracking_max_weight, tracking_max_weight >= 0.0,
               ">= 0"),
              ("--effort-weight", effort_weight, effort_weight >= 0.0, ">= 0"),
              ("--emg-weight", emg_weight, emg_weight >= 0.0, ">= 0"),
              ("--duration", duration_s, 5.0 <= duration_s <= 120.0, "5 to 120 s"))
    for name, value, ok, allowed in checks:
        if not ok or (isinstance(value, float) and not math.isfinite(value)):
            raise InvalidInput(f"{name} = {value!r}; allowed: {allowed}")
    from afo_mj.human.body_presets import SMALL_BODY_HEIGHT_M, default_timestep_s
    try:
        # a small body's dynamics are faster: its step as its scenarios take it
        kw = ({"timestep_s": default_timestep_s(float(height_m))}
              if isinstance(height_m, (int, float)) and height_m < SMALL_BODY_HEIGHT_M else {})
        walker = WalkerParams(body_mass_kg=body_mass_kg, height_m=height_m, **kw)
    except ParameterError as exc:
        raise InvalidInput(str(exc).replace("WalkerParams.body_mass_kg", "--body-mass-kg")
                           .replace("WalkerParams.height_m", "--height-m")) from None
    weights = dict(target_speed_m_s=float(speed_m_s), tracking_weight=float(tracking_weight),
                   tracking_max_weight=float(tracking_max_weight),
                   effort_weight=float(effort_weight), emg_weight=float(emg_weight),
                   duration_s=float(duration_s),
                   variants=robustness_variants() if robust else ())
    objective = None
    if scenario is not None:
        try:
            objective, sc = scenario_objective(scenario, condition, tuple(overrides or ()),
                                               **weights)
        except ValueError as exc:       # ScenarioError too: the message names file and key
            msg = str(exc)
            raise InvalidInput(f"--{msg}" if msg.startswith("condition =")
                               else f"--scenario {msg}") from None
        if start is None:               # the scenario's own wearer is the warm start
            start = str(sc.reflex_set)
    start_set = None
    if start is not None:
        try:
            start_set = dict(zip(rl.PARAM_NAMES, load_reflex_set(start).tolist()))
        except (OSError, ValueError, KeyError) as exc:
            raise InvalidInput(f"--start {start}: {exc}") from None
    try:
        device = Assistance(kind=assistance, ramp_strides=ramp_strides)
    except ValueError as exc:
        raise InvalidInput(str(exc).replace("assistance.kind", "--assistance")
                           .replace("assistance.ramp_strides", "--ramp-strides")) from None
    if objective is None:
        objective = GaitObjective(walker=walker, assistance=device,
                                  max_force_scale=(() if plantarflexor_strength == 1.0 else
                                                   (("soleus", float(plantarflexor_strength)),
                                                    ("gastrocnemius",
                                                     float(plantarflexor_strength)))),
                                  **weights)
    rep = progress.reporter()
    task = rep.task(f"optimising the reflex controller for {speed_m_s} m/s", generations,
                    "generations") if rep.active else None

    def tick(gen, total, best):
        if task is not None:
            task.update(gen)
    try:
        doc = optimize_gait(Path(out), objective, generations=generations, popsize=popsize,
                            seed=seed, start=start_set, workers=workers,
                            sigma0=float(sigma0), progress=tick)
    except ValueError as exc:
        if task is not None:
            task.abort()
        raise InvalidInput(str(exc)) from None
    if task is not None:
        task.close()
    return doc
