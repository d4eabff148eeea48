"""Parameter studies from the command line's point of view: ``afo-mj sweep`` and
``afo-mj optimize`` run a study (:mod:`afo_mj.studies`) with the application layer's
in-process point runner (:func:`afo_mj.app.sweep_point.run_point`: no figures).

Raises :class:`~afo_mj.app.errors.InvalidInput` for an invalid study (a key the scenario does
not accept is caught before any run) or option, and :class:`Interrupted` (exit 130) on
SIGINT/SIGTERM (finished runs are kept: run again to resume).
"""

from __future__ import annotations

import dataclasses
import time
from pathlib import Path
from typing import Callable

from afo_mj.app.errors import AppError, InvalidInput

__all__ = ["Interrupted", "SweepRun", "run_sweep", "run_optimization"]


class Interrupted(AppError):
    """The sweep or optimisation stopped on a signal; what finished is kept."""

    exit_code = 130


@dataclasses.dataclass(frozen=True)
class SweepRun:
    """A finished sweep: its rows, the results table and the wall time (every run failing
    is a result too: the command line exits 1 on it)."""

    study: object
    rows: list
    table_path: Path
    wall_time_s: float

    @property
    def failed(self) -> list:
        return [r for r in self.rows if r["status"] != "ok"]


def _check_workers(workers) -> None:
    if workers is not None and workers < 1:
        raise InvalidInput(f"--workers = {workers}; allowed: >= 1")


def _check_scheduler(scheduler) -> None:
    """An unreachable Dask scheduler refused at once, before anything is printed or written
    (:func:`afo_mj.studies.sweep.connect_scheduler`: a short connect timeout)."""
    from afo_mj.studies.sweep import connect_scheduler
    try:
        client = connect_scheduler(scheduler)
    except ValueError as exc:
        raise InvalidInput(str(exc)) from None
    if client is not None:
        client.close()


def run_sweep(study_path, out_dir, workers: int | None = None, scheduler: str | None = None,
              fmt: str | None = None, keep_runs: bool = False, progress: bool = True,
              on_start: Callable[[object, list, object], None] | None = None) -> SweepRun:
    """Run (or resume) the study ``study_path`` into ``out_dir``; ``on_start(study, points,
    sweep)`` is called once the study is checked, before the first run."""
    from afo_mj.app.sweep_point import run_point
    from afo_mj.studies.study import StudyError, load_study
    from afo_mj.studies.sweep import Sweep, SweepInterrupted, check_study_keys
    try:
        study = load_study(study_path)
        points = study.points()
        check_study_keys(study, points)
    except StudyError as exc:
        raise InvalidInput(f"invalid study: {exc}") from None
    _check_workers(workers)
    _check_scheduler(scheduler)
    try:
        sw = Sweep(study, out_dir, workers=workers, scheduler=scheduler, fmt=fmt,
                   keep_runs=keep_runs, progress=progress, runner=run_point)
    except ValueError as exc:
        raise InvalidInput(str(exc)) from None
    if on_start is not None:
        on_start(study, points, sw)
    t0 = time.perf_counter()
    try:
        rows = sw.run(points)
    except SweepInterrupted as exc:
        raise Interrupted(str(exc)) from None
    except ValueError as exc:
        raise InvalidInput(str(exc)) from None
    return SweepRun(study, rows, sw.table_path, time.perf_counter() - t0)


def run_optimization(study_path, out_dir, workers: int | None = None,
                     scheduler: str | None = None, progress: bool = True) -> dict:
    """Optimise the study's parameters (its ``[optimize]`` table); returns
    :func:`afo_mj.studies.optimize.optimize_study`'s result, with ``study_name``."""
    from afo_mj.app.sweep_point import run_point
    from afo_mj.studies.optimize import optimize_study
    from afo_mj.studies.study import StudyError, load_study
    from afo_mj.studies.sweep import SweepInterrupted
    _check_workers(workers)
    _check_scheduler(scheduler)
    try:
        study = load_study(study_path)
        res = optimize_study(study, out_dir, workers=workers, scheduler=scheduler,
                             progress=progress, runner=run_point)
    except SweepInterrupted as exc:
        raise Interrupted(str(exc)) from None
    except StudyError as exc:
        raise InvalidInput(f"invalid study: {exc}") from None
    except ValueError as exc:
        raise InvalidInput(str(exc)) from None
    return {**res, "study_name": study.name}
