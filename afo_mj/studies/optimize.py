"""Optimisation of a study's parameters: the assistance profile (or any scenario values with
ranges) that minimises, or maximises, one run metric under bounds on others.

This is human-in-the-loop optimisation (Zhang et al. 2017, *Science* 356:1280, who tuned the
four parameters of an ankle exoskeleton's torque profile, peak torque, peak time, rise time
and fall time, to each wearer's metabolic rate with an evolution strategy) done in silico: every
evaluation is one ``afo-mj run`` of the study's base scenario with the suggested values, run
through the sweep's parallel runner (:class:`afo_mj.studies.sweep.Sweep`), so a whole
generation is one batch of parallel runs, every run is kept as a row in ``DIR/rows/`` and an
interrupted optimisation resumes cheaply: with the same seed it suggests the same points again
and reads their rows instead of simulating them.

The study file's ``[optimize]`` table::

    [optimize]
    metric = "human.ankle_positive_work_j_per_stride"   # a dotted summary.json metric, or
                                                        # "A / B" (a ratio of two)
    direction = "minimize"                              # or "maximize"
    method = "differential_evolution"                   # or "nelder_mead"
    budget = 40            # most runs (distinct points) the optimisation may simulate
    popsize = 8            # DE: individuals per generation (>= 5; default max(5, 2 x params))
    seed = 0
    penalty = 1e6          # objective of an infeasible point (failed runs: 2 x penalty)
    resolution = 1e-3      # suggestions are rounded to this fraction of each range
    initial = { "assistance.peak_torque_nm" = 40.0 }   # optional start (NM x0, a DE member)
    [[optimize.constraints]]
    metric = "device.peak_torque_nm"
    max = 60.0             # and/or min = ...

Methods. Differential evolution (Storn & Price 1997, *J. Global Optim.* 11:341), as
:func:`scipy.optimize.differential_evolution` with ``updating="deferred"`` so that each
generation is evaluated as one batch (its ``workers`` is a map-like callable that hands the
whole population to one ``Sweep.run``), a Latin-hypercube initial population of ``popsize``
members, no gradient polishing, and generations until the budget is spent or the population's
objective values agree (scipy's ``tol``). Nelder–Mead (Nelder & Mead 1965), as
:func:`scipy.optimize.minimize` with bounds, is sequential after its initial simplex (which is
run as one batch). Both search the unit cube: parameter ``u ∈ [0, 1]`` maps to the range
(linearly or, for ``scale = "log"``, geometrically; ``levels`` parameters become a categorical
choice, which suits DE better than Nelder–Mead), and a suggestion is rounded to a decimal step
no coarser than ``resolution`` × range, so that points the optimiser revisits hit the row cache.

Constraints and failures. An optimiser only ever sees finite numbers: a feasible point scores
its metric (negated for ``maximize``); a point that violates a constraint scores
``penalty × (1 + v / (1 + v))`` with ``v`` the summed violations relative to each bound (so
infeasible points rank by how far out they are, always behind feasible ones as long as
``|metric| < penalty``); a failed run (the walker fell, the simulation diverged, the metric is
NaN or absent) scores ``2 × penalty``. The result's best point is the best feasible one, or the
least infeasible one when none was feasible (``best_feasible = false``).
"""

from __future__ import annotations

import dataclasses
import difflib
import json
import math
import os
import sys
import time
from pathlib import Path
from typing import Any, Callable, Sequence

import numpy as np

from afo_mj.studies.study import Study, StudyError, StudyParameter

__all__ = ["OptimizeError", "OptimizeConfig", "Constraint", "parse_optimize",
           "optimize_study", "METHODS", "DEFAULT_METRIC", "Evaluator"]

METHODS = ("differential_evolution", "nelder_mead")
DIRECTIONS = ("minimize", "maximize")
DEFAULT_METRIC = "human.ankle_positive_work_j_per_stride"
_OPT_KEYS = ("metric", "direction", "constraints", "method", "budget", "popsize", "seed",
             "penalty", "resolution", "initial")
_CON_KEYS = ("metric", "max", "min")
RESULT_FILE = "optimization.json"

#: A batch evaluator: points (dicts dotted key → value) → rows in the same order, each with
#: ``status`` ("ok" or anything else for a failed run), ``error`` and the metrics by name.
Evaluator = Callable[[list[dict[str, Any]]], list[dict[str, Any]]]


class OptimizeError(StudyError):
    """An invalid ``[optimize]`` table, or a metric no run reports (the message names the key,
    the value and what is allowed)."""


@dataclasses.dataclass(frozen=True)
class Constraint:
    """``min <= metric <= max`` (either bound may be absent)."""

    metric: str
    max: float | None = None
    min: float | None = None

    def violation(self, value: float) -> float:
        """Violation relative to the bound (0 when satisfied)."""
        v = 0.0
        if self.max is not None and value > self.max:
            v += (value - self.max) / _scale(self.max)
        if self.min is not None and value < self.min:
            v += (self.min - value) / _scale(self.min)
        return v

    def as_dict(self) -> dict:
        return {"metric": self.metric, "max": self.max, "min": self.min}


def _scale(bound: float) -> float:
    return abs(bound) if bound != 0 else 1.0


@dataclasses.dataclass(frozen=True)
class OptimizeConfig:
    """A validated ``[optimize]`` table."""

    metric: str = DEFAULT_METRIC
    direction: str = "minimize"
    constraints: tuple[Constraint, ...] = ()
    method: str = "differential_evolution"
    budget: int = 40
    popsize: int | None = None
    seed: int = 0
    penalty: float = 1e6
    resolution: float = 1e-3
    initial: dict = dataclasses.field(default_factory=dict)

    def population(self, n_params: int) -> int:
        """DE members per generation: ``popsize``, or max(5, 2 × parameters) within the
        budget."""
        if self.popsize is not None:
            return self.popsize
        return max(5, min(2 * n_params, self.budget))

    def as_dict(self) -> dict:
        return {"metric": self.metric, "direction": self.direction,
                "constraints": [c.as_dict() for c in self.constraints],
                "method": self.method, "budget": self.budget, "popsize": self.popsize,
                "seed": self.seed, "penalty": self.penalty, "resolution": self.resolution,
                "initial": dict(self.initial)}


def _fail(origin, key, value, allowed) -> OptimizeError:
    return OptimizeError(f"{origin}: {key} = {value!r}; allowed: {allowed}")


def _is_int(x) -> bool:
    return isinstance(x, int) and not isinstance(x, bool)


def _is_num(x) -> bool:
    return isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x)


def _check_metric(origin, key, m) -> str:
    allowed = ('a dotted metric name of the run\'s summary.json, e.g. '
               f'"{DEFAULT_METRIC}", or a ratio "A / B" of two')
    if not isinstance(m, str) or not m.strip():
        raise _fail(origin, key, m, allowed)
    parts = [s.strip() for s in m.split("/")]
    if len(parts) > 2 or any(not s or any(c.isspace() for c in s) for s in parts):
        raise _fail(origin, key, m, allowed)
    return " / ".join(parts)


def parse_optimize(table: dict | None, parameters: Sequence[StudyParameter] = (),
                   origin: str = "<study>") -> OptimizeConfig:
    """Validate an ``[optimize]`` table (``study.optimize``) against the study's parameters;
    raises :class:`OptimizeError` naming the key, the value and what is allowed."""
    t = {} if table is None else table
    if not isinstance(t, dict):
        raise _fail(origin, "optimize", t, "a table")
    for k in t:
        if k not in _OPT_KEYS:
            raise _fail(origin, f"optimize.{k}", t[k], f"the keys {', '.join(_OPT_KEYS)}")
    metric = _check_metric(origin, "optimize.metric", t.get("metric", DEFAULT_METRIC))
    direction = t.get("direction", "minimize")
    if direction not in DIRECTIONS:
        raise _fail(origin, "optimize.direction", direction, ", ".join(DIRECTIONS))
    method = t.get("method", "differential_evolution")
    if method not in METHODS:
        raise _fail(origin, "optimize.method", method, ", ".join(METHODS))
    budget = t.get("budget", 40)
    if not (_is_int(budget) and 1 <= budget <= 100000):
        raise _fail(origin, "optimize.budget", budget, "an integer 1 … 100000 (most runs)")
    popsize = t.get("popsize")
    if popsize is not None and not (_is_int(popsize) and 5 <= popsize <= 10000):
        raise _fail(origin, "optimize.popsize", popsize,
                    "an integer 5 … 10000 (differential evolution members per generation)")
    seed = t.get("seed", 0)
    if not (_is_int(seed) and seed >= 0):
        raise _fail(origin, "optimize.seed", seed, "an integer >= 0")
    penalty = t.get("penalty", 1e6)
    if not (_is_num(penalty) and 0 < penalty <= 1e100):
        raise _fail(origin, "optimize.penalty", penalty, "a finite number > 0 (larger than "
                    "any value of the metric)")
    resolution = t.get("resolution", 1e-3)
    if not (_is_num(resolution) and 1e-9 <= resolution <= 0.1):
        raise _fail(origin, "optimize.resolution", resolution,
                    "a fraction of each range, 1e-9 … 0.1")
    raw = t.get("constraints", [])
    if not isinstance(raw, list):
        raise _fail(origin, "optimize.constraints", raw,
                    "a list of tables {metric, max and/or min}")
    cons = []
    for i, c in enumerate(raw):
        where = f"optimize.constraints[{i}]"
        if not isinstance(c, dict):
            raise _fail(origin, where, c, "a table {metric, max and/or min}")
        for k in c:
            if k not in _CON_KEYS:
                raise _fail(origin, f"{where}.{k}", c[k], f"the keys {', '.join(_CON_KEYS)}")
        if "metric" not in c:
            raise _fail(origin, f"{where}.metric", None, "a metric name (the constrained "
                        "summary.json value, e.g. device.peak_torque_nm)")
        m = _check_metric(origin, f"{where}.metric", c["metric"])
        hi, lo = c.get("max"), c.get("min")
        if hi is None and lo is None:
            raise _fail(origin, where, c, "max = ... and/or min = ... (finite numbers)")
        for k, v in (("max", hi), ("min", lo)):
            if v is not None and not _is_num(v):
                raise _fail(origin, f"{where}.{k}", v, "a finite number")
        if hi is not None and lo is not None and not lo < hi:
            raise _fail(origin, f"{where}.min", lo, f"less than max ({hi})")
        cons.append(Constraint(m, None if hi is None else float(hi),
                               None if lo is None else float(lo)))
    initial = t.get("initial", {})
    if not isinstance(initial, dict):
        raise _fail(origin, "optimize.initial", initial, "a table of parameter key = value")
    by_key = {p.key: p for p in parameters}
    for k, v in initial.items():
        if by_key and k not in by_key:
            raise _fail(origin, f"optimize.initial.{k}", v,
                        f"the study's parameters: {', '.join(by_key)}")
        p = by_key.get(k)
        if p is None:
            continue
        if p.levels:
            if v not in p.levels:
                raise _fail(origin, f"optimize.initial.{k}", v, f"one of {list(p.levels)}")
        elif not (_is_num(v) and p.lo <= v <= p.hi):
            raise _fail(origin, f"optimize.initial.{k}", v, f"a number in [{p.lo}, {p.hi}]")
    cfg = OptimizeConfig(metric=metric, direction=direction, constraints=tuple(cons),
                         method=method, budget=budget, popsize=popsize, seed=seed,
                         penalty=float(penalty), resolution=float(resolution),
                         initial=dict(initial))
    d = len(parameters)
    if d:
        if method == "differential_evolution" and budget < cfg.population(d):
            raise _fail(origin, "optimize.budget", budget,
                        f">= the population ({cfg.population(d)} members per generation) "
                        "for differential_evolution; or method = \"nelder_mead\"")
        if method == "nelder_mead" and budget < d + 1:
            raise _fail(origin, "optimize.budget", budget,
                        f">= {d + 1} (the initial simplex of {d} parameters) for nelder_mead")
    return cfg


# -- the unit cube ↔ parameter values ---------------------------------------------------------

def _to_value(p: StudyParameter, u: float, resolution: float):
    """The rounded parameter value at ``u`` (clipped to [0, 1])."""
    u = min(max(float(u), 0.0), 1.0)
    if p.levels or p.integer:
        return p.from_unit(min(u, 1.0 - 1e-12))
    if p.scale == "log":
        x = math.exp(math.log(p.lo) + u * (math.log(p.hi) - math.log(p.lo)))
        sig = int(math.ceil(-math.log10(resolution))) + 1
        x = float(f"{x:.{sig}g}")
    else:
        x = p.lo + u * (p.hi - p.lo)
        step = 10.0 ** math.floor(math.log10(resolution * (p.hi - p.lo)))
        nd = max(0, -int(math.floor(math.log10(step))))
        x = round(round(x / step) * step, nd)
    x = min(max(x, p.lo), p.hi)
    return x + 0.0                                 # no -0.0


def _to_unit(p: StudyParameter, v) -> float:
    if p.levels:
        return (p.levels.index(v) + 0.5) / len(p.levels)
    if p.scale == "log":
        return (math.log(v) - math.log(p.lo)) / (math.log(p.hi) - math.log(p.lo))
    return (float(v) - p.lo) / (p.hi - p.lo)


def _finite(x) -> float | None:
    """A finite float, or None (missing, NaN, ±inf, non-numeric); a flag (bool, e.g.
    ``device.end_stop_contact``) is 1.0 or 0.0, so that a constraint ``max = 0`` forbids it."""
    if isinstance(x, bool):
        return float(x)
    if not isinstance(x, (int, float)):
        return None
    x = float(x)
    return x if math.isfinite(x) else None


def _metric_value(row: dict, name: str) -> tuple[float | None, bool]:
    """(value, present): a finite value or None, and whether every named column exists."""
    parts = name.split(" / ")
    if any(q not in row for q in parts):
        return None, False
    if len(parts) == 1:
        return _finite(row[parts[0]]), True
    a, b = _finite(row[parts[0]]), _finite(row[parts[1]])
    if a is None or b is None or b == 0:
        return None, True
    return _finite(a / b), True


def _jsonable(x):
    if isinstance(x, float):
        return x if math.isfinite(x) else None
    if isinstance(x, dict):
        return {str(k): _jsonable(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_jsonable(v) for v in x]
    if isinstance(x, np.generic):
        return _jsonable(x.item())
    return x


def _write_json_atomic(path: Path, obj) -> None:
    tmp = path.with_name(f".{path.name}.tmp-{os.getpid()}")
    tmp.write_text(json.dumps(_jsonable(obj), indent=1, allow_nan=False), encoding="utf-8")
    os.replace(tmp, path)


class _BudgetSpent(Exception):
    """Raised through the optimiser when the next run would exceed the budget."""


class _Carried(Exception):
    """Carries a TypeError/ValueError out of scipy's map wrapper (which would turn it into a
    RuntimeError about the map-like callable)."""

    def __init__(self, exc: BaseException):
        super().__init__(str(exc))
        self.exc = exc


class _Optimizer:
    def __init__(self, study: Study, cfg: OptimizeConfig, evaluate: Evaluator, out_dir: Path,
                 progress: bool, table: str | None):
        self.study, self.cfg, self.evaluate = study, cfg, evaluate
        self.params = study.parameters
        self.out_dir = out_dir
        self.progress = progress
        self.table = table
        self.sign = 1.0 if cfg.direction == "minimize" else -1.0
        self.memo: dict[tuple, dict] = {}          # point key → scored evaluation
        self.history: list[dict] = []
        self._asked: set[str] = set()              # run ids the optimiser has asked for
        self.batches = 0
        self.t0 = time.perf_counter()
        self.state = "running"
        self.converged = False
        self.message = ""
        self.scipy_result: dict = {}

    # -- points ---------------------------------------------------------------------------
    def point(self, u) -> dict[str, Any]:
        return {p.key: _to_value(p, u[j], self.cfg.resolution)
                for j, p in enumerate(self.params)}

    @staticmethod
    def key(point: dict) -> tuple:
        return tuple((k, repr(v)) for k, v in point.items())

    def initial_unit(self) -> np.ndarray:
        x0 = np.full(len(self.params), 0.5)
        for j, p in enumerate(self.params):
            if p.key in self.cfg.initial:
                x0[j] = _to_unit(p, self.cfg.initial[p.key])
        return x0

    # -- evaluation -----------------------------------------------------------------------
    def run_points(self, points: list[dict], record: bool = True) -> list[dict]:
        """Score points (running those not scored yet as one batch, within the budget);
        raises _BudgetSpent after scoring what the budget allowed."""
        new, seen = [], set()
        for pt in points:
            k = self.key(pt)
            if k not in self.memo and k not in seen:
                seen.add(k)
                new.append(pt)
        room = self.cfg.budget - len(self.memo)
        spent = len(new) > room
        new = new[:max(room, 0)]
        if new:
            self.batches += 1
            rows = list(self.evaluate([dict(p) for p in new]))
            if len(rows) != len(new) or all("run_id" in r for r in rows):
                by_id = {r.get("run_id"): r for r in rows}   # sweep rows: match by run id
                rows = [by_id.get(self.study.run_id(p), {"status": "failed",
                                                         "error": "no row returned"})
                        for p in new]
            self._check_names(rows)
            for pt, row in zip(new, rows):
                self.memo[self.key(pt)] = self.score(pt, row, len(self.memo))
        out = []
        for pt in points:
            ev = self.memo.get(self.key(pt))
            if ev is None:
                continue
            if record:
                self.history.append({**ev, "evaluation": len(self.history),
                                     "batch": self.batches,
                                     "repeat": ev["run_id"] in self._asked})
                self._asked.add(ev["run_id"])
            out.append(ev)
        if new:
            self.report()
        if new or record:
            self.save()
        if spent:
            raise _BudgetSpent
        return out

    def _check_names(self, rows: list[dict]) -> None:
        ok = [r for r in rows if r.get("status") == "ok"]
        if not ok:
            return
        names = [("optimize.metric", self.cfg.metric)] + [
            (f"optimize.constraints[{i}].metric", c.metric)
            for i, c in enumerate(self.cfg.constraints)]
        for key, name in names:
            for part in name.split(" / "):
                if not any(part in r for r in ok):
                    cols = sorted({c for r in ok for c in r})
                    close = difflib.get_close_matches(part, cols, n=5, cutoff=0.5)
                    raise OptimizeError(
                        f"{key} = {name!r}: {part!r} is not a metric of the runs; allowed: a "
                        "dotted summary.json metric"
                        + (f" (close: {', '.join(close)})" if close else ""))

    def score(self, point: dict, row: dict, index: int) -> dict:
        cfg = self.cfg
        status = "ok" if row.get("status") == "ok" else "failed"
        error = str(row.get("error") or "")
        metric, present = _metric_value(row, cfg.metric)
        cons, viol, missing = {}, 0.0, []
        for c in cfg.constraints:
            v, _ = _metric_value(row, c.metric)
            cons[c.metric] = v
            if v is None:
                missing.append(c.metric)
            else:
                viol += c.violation(v)
        if status == "ok" and (metric is None or missing):
            status = "failed"
            bad = ([cfg.metric] if metric is None else []) + missing
            error = error or f"no finite value of {', '.join(bad)}"
        if status != "ok":
            objective, feasible = 2.0 * cfg.penalty, False
        elif viol > 0:
            objective, feasible = cfg.penalty * (1.0 + viol / (1.0 + viol)), False
        else:
            objective, feasible = self.sign * metric, True
        if not math.isfinite(objective):           # never happens; never let it through
            objective = 2.0 * cfg.penalty
        rid = row.get("run_id") or self.study.run_id(point)
        return {"point": dict(point), "run_id": rid, "status": status, "error": error,
                "metric": metric, "constraints": cons, "violation": viol,
                "feasible": feasible, "objective": float(objective), "run": index}

    def objective(self, u) -> float:
        return self.run_points([self.point(u)])[0]["objective"]

    def best(self) -> dict | None:
        evs = list(self.memo.values())
        feas = [e for e in evs if e["feasible"]]
        pool = feas or evs
        return min(pool, key=lambda e: (e["objective"], e["run"])) if pool else None

    # -- output ---------------------------------------------------------------------------
    def report(self) -> None:
        if not self.progress:
            return
        b = self.best()
        if b is None:
            return
        val = "none" if b["metric"] is None else f"{b['metric']:.5g}"
        tag = "" if b["feasible"] else " (no feasible point yet)"
        pts = ", ".join(f"{k.rsplit('.', 1)[-1]}={v}" for k, v in b["point"].items())
        print(f"afo-mj optimize: {len(self.memo)}/{self.cfg.budget} runs, best "
              f"{self.cfg.metric} = {val}{tag} at {pts}", file=sys.stderr, flush=True)

    def result(self) -> dict:
        b = self.best()
        cfg = self.cfg
        res = {
            "study": self.study.name,
            "method": cfg.method,
            "metric": cfg.metric,
            "direction": cfg.direction,
            "parameters": [{"key": p.key, "range": [p.lo, p.hi] if p.continuous else None,
                            "levels": list(p.levels) or None, "scale": p.scale}
                           for p in self.params],
            "constraints": [c.as_dict() for c in cfg.constraints],
            "best_point": b["point"] if b else None,
            "best_metric": b["metric"] if b else None,
            "best_run_id": b["run_id"] if b else None,
            "best_feasible": bool(b["feasible"]) if b else False,
            "best_objective": b["objective"] if b else None,
            "constraint_values": b["constraints"] if b else {},
            "n_runs": len(self.memo),
            "n_failed": sum(e["status"] != "ok" for e in self.memo.values()),
            "n_infeasible": sum(e["status"] == "ok" and not e["feasible"]
                                for e in self.memo.values()),
            "n_evaluations": len(self.history),
            "n_batches": self.batches,
            "budget": cfg.budget,
            "state": self.state,
            "converged": bool(self.converged),
            "message": self.message,
            "wall_time_s": time.perf_counter() - self.t0,
            "config": cfg.as_dict(),
            "scipy": self.scipy_result,
            "table": self.table,
            "history": self.history,
        }
        return _jsonable(res)

    def save(self) -> None:
        _write_json_atomic(self.out_dir / RESULT_FILE, self.result())

    # -- methods --------------------------------------------------------------------------
    def run(self) -> dict:
        d = len(self.params)
        try:
            if self.cfg.method == "differential_evolution":
                self._run_de(d)
            else:
                self._run_nm(d)
            self.state = "finished"
        except _Carried as c:
            if not isinstance(c.exc, OptimizeError):
                self.state = "failed"
                self.message = f"{type(c.exc).__name__}: {c.exc}"
                self.save()
            raise c.exc from None
        except OptimizeError:
            raise
        except _BudgetSpent:
            self.state = "budget"
            self.converged = False
            self.message = f"budget of {self.cfg.budget} runs spent"
        except BaseException:
            self.state = "interrupted"
            self.message = "interrupted; run the same command again to resume"
            self.save()
            raise
        b = self.best()
        if b is not None and not b["feasible"]:
            self.message += ("; " if self.message else "") + "no feasible point found"
        if b is not None and b["feasible"] and abs(b["objective"]) >= self.cfg.penalty:
            self.message += ("; " if self.message else "") + (
                "warning: |metric| >= penalty, raise optimize.penalty")
        self.save()
        return self.result()

    def _run_de(self, d: int) -> None:
        from scipy.optimize import differential_evolution
        from scipy.stats import qmc

        cfg = self.cfg
        S = cfg.population(d)
        init = qmc.LatinHypercube(d=d, seed=cfg.seed).random(S)
        if cfg.initial:
            init[0] = self.initial_unit()

        def batch_map(func, xs):                  # one generation = one Sweep.run
            xs = [np.asarray(x, dtype=float) for x in xs]
            pts = [self.point(x) for x in xs]
            try:
                evs = self.run_points(pts)
            except (TypeError, ValueError) as exc:
                raise _Carried(exc) from exc
            return [e["objective"] for e in evs]

        # maxiter: the generations the budget allows, with room for generations that
        # revisit cached points; the budget guard stops it exactly at `budget` runs
        maxiter = 2 * max(1, math.ceil(cfg.budget / S))
        res = differential_evolution(self.objective, bounds=[(0.0, 1.0)] * d,
                                     maxiter=maxiter, init=init, polish=False,
                                     updating="deferred", workers=batch_map,
                                     rng=np.random.default_rng(cfg.seed), tol=0.01)
        self.converged = bool(res.success)
        self.message = str(res.message)
        self.scipy_result = {"nit": int(res.nit), "nfev": int(res.nfev),
                             "fun": float(res.fun), "success": bool(res.success)}

    def _run_nm(self, d: int) -> None:
        from scipy.optimize import minimize

        cfg = self.cfg
        x0 = self.initial_unit()
        step = 0.2
        simplex = [x0.copy()]
        for j in range(d):
            v = x0.copy()
            v[j] = v[j] + step if v[j] + step <= 1.0 else v[j] - step
            simplex.append(v)
        simplex = np.array(simplex)
        self.run_points([self.point(v) for v in simplex], record=False)   # one batch
        res = minimize(self.objective, x0, method="Nelder-Mead", bounds=[(0.0, 1.0)] * d,
                       options={"initial_simplex": simplex, "xatol": cfg.resolution,
                                "fatol": 1e-9, "maxfev": 10 * cfg.budget + 10,
                                "maxiter": 10 * cfg.budget + 10, "adaptive": d > 2})
        self.converged = bool(res.success)
        self.message = str(res.message)
        self.scipy_result = {"nit": int(res.nit), "nfev": int(res.nfev),
                             "fun": float(res.fun), "success": bool(res.success)}


def _sweep_evaluator(study: Study, out_dir: Path, workers: int | None,
                     scheduler: str | None, progress: bool,
                     runner: Callable[..., dict] | None) -> tuple[Evaluator, str]:
    """Batches through the sweep runner: a batch of one point runs in this process (no
    worker start-up for Nelder–Mead's sequential steps) unless a Dask scheduler is given."""
    from afo_mj.studies.sweep import Sweep

    sw = Sweep(study, out_dir, workers=workers, scheduler=scheduler, progress=progress,
               runner=runner)
    one = sw if scheduler else Sweep(study, out_dir, workers=1, progress=False, runner=runner)

    def evaluate(points: list[dict]) -> list[dict]:
        return (one if len(points) == 1 else sw).run(points)
    return evaluate, str(sw.table_path)


def optimize_study(study: Study, out_dir, workers: int | None = None,
                   scheduler: str | None = None, progress: bool = True,
                   evaluate: Evaluator | None = None,
                   runner: Callable[..., dict] | None = None) -> dict:
    """Optimise the study's parameters as its ``[optimize]`` table says; returns the result
    (also written atomically to ``out_dir/optimization.json`` after every batch):

    ``best_point`` (dict key → value), ``best_metric``, ``best_run_id``, ``best_feasible``,
    ``constraint_values`` (constraint metric → value at the best point), ``history`` (every
    evaluation the optimiser asked for, in order: ``point``, ``run_id``, ``status``,
    ``metric``, ``constraints``, ``violation``, ``feasible``, ``objective``, ``repeat``),
    ``n_runs`` (distinct points run or read back; at most ``budget``), ``n_failed``,
    ``n_infeasible``, ``n_evaluations``, ``method``, ``state`` (``finished``: the optimiser
    stopped by itself; ``budget``: the budget is spent), ``converged``, ``message``,
    ``config`` and ``table`` (the sweep's results table).

    Runs go through :class:`~afo_mj.studies.sweep.Sweep` into ``out_dir`` (``workers`` local
    processes, or the Dask ``scheduler``), so a second call with the same study and
    ``out_dir`` replays the finished runs from their rows. ``evaluate`` replaces the sweep by
    any batch evaluator (points → rows with ``status`` and the metrics), e.g. in tests;
    otherwise ``runner`` runs each point (:func:`afo_mj.app.sweep_point.run_point`).
    Raises :class:`OptimizeError` for an invalid ``[optimize]`` table or a metric no run
    reports, ValueError (nothing written) when the Dask ``scheduler`` cannot be reached,
    and :class:`~afo_mj.studies.sweep.SweepInterrupted` on SIGINT/SIGTERM (the result so
    far is saved with ``state = "interrupted"``)."""
    origin = str(study.source_path) if study.source_path else study.name
    cfg = parse_optimize(study.optimize, study.parameters, origin)
    if evaluate is None and scheduler and scheduler != "local":
        from afo_mj.studies.sweep import connect_scheduler
        connect_scheduler(scheduler).close()     # unreachable: refused before any file
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    table = None
    if evaluate is None:
        evaluate, table = _sweep_evaluator(study, out, workers, scheduler, progress, runner)
    return _Optimizer(study, cfg, evaluate, out, progress, table).run()
