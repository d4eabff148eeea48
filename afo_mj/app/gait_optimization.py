"""``afo-mj optimize-gait``: optimise the muscle-reflex walker's controller (CMA-ES,
:mod:`afo_mj.studies.gait_optimization`) for steady walking at a target speed, with progress
per generation; resumable (run again with the same ``--out`` to continue).

Raises :class:`~afo_mj.app.errors.InvalidInput` (exit 2, nothing written) for an option out
of range, a ``--start`` file that is not a reflex parameter set, or an output folder that
holds an optimisation of another objective.
"""

from __future__ import annotations

import math
from pathlib import Path

from afo_mj.app.errors import InvalidInput

__all__ = ["optimize_reflex_gait"]


def optimize_reflex_gait(out, speed_m_s: float = 1.25, generations: int = 60,
                         popsize: int = 16, seed: int = 1, start: str | None = None,
                         workers: int | None = None, body_mass_kg: float = 75.0,
                         height_m: float = 1.75, assistance: str = "none",
                         robust: bool = False, plantarflexor_strength: float = 1.0,
                         sigma0: float = 0.2, tracking_weight: float = 1.0,
                         tracking_max_weight: float = 0.0, effort_weight: float = 1.0,
                         emg_weight: float = 0.0, duration_s: float = 12.0,
                         ramp_strides: int = 0) -> dict:
    """Run (or continue) the optimisation into ``out``; returns ``reflex_params.json``'s
    content. ``assistance``: the condition worn while walking
    (:data:`afo_mj.experiments.muscle_assistance.KINDS`, its defaults); ``robust``: the
    perturbed walkers of :func:`~afo_mj.studies.gait_optimization.robustness_variants` must
    walk too; ``plantarflexor_strength``: the wearer's soleus and gastrocnemius maximum force
    as a fraction (a weakness, 0.05 … 1); ``sigma0`` CMA-ES's initial step; the weights and
    ``duration_s`` those of :class:`~afo_mj.studies.gait_optimization.GaitObjective`;
    ``ramp_strides``: the ideal torque's ramp-on (``Assistance.ramp_strides``)."""
    from afo_mj import progress
    from afo_mj.hydraulics.params import ParameterError
    from afo_mj.human.walker import WalkerParams
    from afo_mj.experiments.muscle_assistance import Assistance
    from afo_mj.studies.gait_optimization import (GaitObjective, load_reflex_set,
                                                  optimize_gait, robustness_variants)
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
    objective = GaitObjective(target_speed_m_s=float(speed_m_s), walker=walker,
                              assistance=device, tracking_weight=float(tracking_weight),
                              tracking_max_weight=float(tracking_max_weight),
                              effort_weight=float(effort_weight), emg_weight=float(emg_weight),
                              duration_s=float(duration_s),
                              variants=robustness_variants() if robust else (),
                              max_force_scale=(() if plantarflexor_strength == 1.0 else
                                               (("soleus", float(plantarflexor_strength)),
                                                ("gastrocnemius",
                                                 float(plantarflexor_strength)))))
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
