"""Many independent runs at once, across the machine's cores.

:func:`run_unordered` maps a picklable function over items in worker processes and yields each
result as it finishes (index, value or the exception it raised); :func:`run_batch` collects
them in input order; :func:`walk_batch` runs walk scenarios
(:class:`~afo_mj.scenarios.walk_scenario.WalkScenario`, e.g. one per parameter set) and
returns their :class:`~afo_mj.gait.record.GaitRecord`\\ s. ``afo-mj sweep`` and
``afo-mj optimize`` run their points through :func:`run_unordered`
(:class:`afo_mj.studies.sweep.Sweep`).

Workers are started with ``fork`` where the platform has it (Linux): a forked worker inherits
the parent's imported modules and the numba code it has already compiled or loaded, so it
starts in milliseconds instead of re-importing (~1–2 s per worker with ``spawn``); elsewhere
``spawn``. Each worker runs one item at a time (a spawned worker also starts numba and BLAS
with one thread); a walk itself is single-threaded, so N independent walks scale with the
cores (``benchmarks/batch.py``).

Every walk is deterministic: the same scenario gives the same record bit for bit whichever
worker runs it and in whichever order (``tests/test_batch.py``).
"""

from __future__ import annotations

import concurrent.futures as cf
import contextlib
import dataclasses
import multiprocessing
import os
import signal
from typing import Any, Callable, Iterable, Iterator, Sequence

__all__ = ["BatchResult", "default_workers", "start_method", "call_packed", "run_unordered",
           "run_batch", "walk_batch"]

#: thread-count variables set to 1 in workers (one core per worker)
_THREAD_VARS = ("NUMBA_NUM_THREADS", "OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS",
                "MKL_NUM_THREADS")


@dataclasses.dataclass(frozen=True)
class BatchResult:
    """One item's outcome: its ``value``, or the ``error`` it raised (then ``value`` is
    None)."""

    value: Any = None
    error: BaseException | None = None

    @property
    def ok(self) -> bool:
        return self.error is None


def default_workers() -> int:
    """The cores this process may use (its CPU affinity where the platform reports it)."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:                      # not on Linux
        return max(1, os.cpu_count() or 1)


def start_method() -> str:
    """``"fork"`` where the platform offers it, else ``"spawn"``."""
    return "fork" if "fork" in multiprocessing.get_all_start_methods() else "spawn"


def _worker_init() -> None:
    """Workers ignore SIGINT (the parent decides when to stop and terminates them), render
    headless, and use one thread each."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    os.environ.setdefault("MUJOCO_GL", "egl")
    for v in _THREAD_VARS:
        os.environ[v] = "1"


def _check_workers(workers) -> int:
    if workers is None:
        return default_workers()
    if isinstance(workers, bool) or not isinstance(workers, int) or workers < 1:
        raise ValueError(f"workers = {workers!r}; allowed: an integer >= 1 or None (the "
                         f"cores available, {default_workers()})")
    return workers


def _terminate(pool) -> None:
    procs = getattr(pool, "_processes", None) or {}
    for proc in list(procs.values()):
        with contextlib.suppress(Exception):
            if proc.is_alive():
                proc.terminate()


def call_packed(packed: tuple):
    """``packed[0](*packed[1:])``: a picklable way to map a function of several arguments."""
    return packed[0](*packed[1:])


def run_unordered(fn: Callable, items: Iterable, workers: int | None = None
                  ) -> Iterator[tuple[int, BatchResult]]:
    """``fn(item)`` for every item in worker processes; yields ``(index, BatchResult)`` as
    each finishes. ``workers = 1`` runs in this process, in order (no pool). A worker process
    that dies gives its item a :class:`BatchResult` whose error says so. Stopping the
    iteration (or an exception in the caller) terminates the workers."""
    workers = _check_workers(workers)
    items = list(items)
    if not items:
        return
    if workers == 1 or len(items) == 1:
        for i, item in enumerate(items):
            try:
                yield i, BatchResult(fn(item))
            except Exception as exc:             # noqa: BLE001 - reported per item
                yield i, BatchResult(error=exc)
        return
    ctx = multiprocessing.get_context(start_method())
    pool = cf.ProcessPoolExecutor(max_workers=min(workers, len(items)), mp_context=ctx,
                                  initializer=_worker_init)
    try:
        futs = {pool.submit(fn, item): i for i, item in enumerate(items)}
        for fut in cf.as_completed(futs):
            i = futs[fut]
            try:
                yield i, BatchResult(fut.result())
            except cf.process.BrokenProcessPool as exc:
                yield i, BatchResult(error=RuntimeError(f"worker process died: {exc}"))
            except Exception as exc:             # noqa: BLE001 - reported per item
                yield i, BatchResult(error=exc)
    finally:
        pool.shutdown(wait=False, cancel_futures=True)
        _terminate(pool)


def run_batch(fn: Callable, items: Sequence, workers: int | None = None) -> list[BatchResult]:
    """``fn(item)`` for every item across ``workers`` processes (default: every core);
    results in input order."""
    items = list(items)
    out: list[BatchResult | None] = [None] * len(items)
    for i, res in run_unordered(fn, items, workers):
        out[i] = res
    return out  # type: ignore[return-value]


def _simulate(scenario):
    """The scenario's walk on its own walker (``walker.model``), as ``afo-mj run`` walks it."""
    from afo_mj.gait.walkers import walk_scenario
    record, _muscles = walk_scenario(scenario)
    return record


def _simulate_summary(scenario) -> dict:
    from afo_mj.metrics.gait_metrics import analyse_gait
    record = _simulate(scenario)
    return analyse_gait(record, scenario.load_reference(), scenario.analyse_strides).summary


RESULTS = ("record", "summary")


def walk_batch(scenarios: Sequence, workers: int | None = None, *, result: str = "record",
               raise_errors: bool = True):
    """Walk every :class:`~afo_mj.scenarios.walk_scenario.WalkScenario` (no device) across
    ``workers`` processes; returns, in input order, their GaitRecords (``result="record"``)
    or their gait summaries (``"summary"``: :func:`afo_mj.metrics.gait_metrics.analyse_gait`
    over the scenario's analysed strides, computed in the worker; what a study keeps). A
    record is ~5 MB for 10 strides, and sending it back to this process costs more than
    the summary's analysis (``benchmarks/batch.py`` measures both). With ``raise_errors``
    (default) the first failed walk's error is raised (naming its index); otherwise failed
    walks give their :class:`BatchResult` in their place. Each scenario walks on the walker it
    names (``walker.model``: torque-driven or muscle-driven,
    :func:`afo_mj.gait.walkers.walk_scenario`), as ``afo-mj run`` walks it."""
    if result not in RESULTS:
        raise ValueError(f"result = {result!r}; allowed: {', '.join(map(repr, RESULTS))}")
    from afo_mj.gait.walkers import walker_models
    scenarios = list(scenarios)
    models = walker_models()
    for i, s in enumerate(scenarios):
        if not hasattr(s, "load_reference") or not hasattr(s, "walker"):
            raise ValueError(f"scenarios[{i}] = {type(s).__name__}; allowed: WalkScenario "
                             f"(afo_mj.scenarios.walk_scenario.load_scenario)")
        model = getattr(s, "walker_model", "torque")
        if model not in models:                            # before any worker starts
            raise ValueError(f"scenarios[{i}]: walker.model = {model!r}; allowed: "
                             + ", ".join(repr(m) for m in models))
    results = run_batch(_simulate if result == "record" else _simulate_summary, scenarios,
                        workers)
    out = []
    for i, r in enumerate(results):
        if r.ok:
            out.append(r.value)
        elif raise_errors:
            raise RuntimeError(f"walk {i} ({getattr(scenarios[i], 'name', '?')}) failed: "
                               f"{type(r.error).__name__}: {r.error}") from r.error
        else:
            out.append(r)
    return out
