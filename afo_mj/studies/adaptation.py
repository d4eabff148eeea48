"""The adapted wearer with its noise measured: several independent searches per condition.

A wearer adapting to a device is modelled as a CMA-ES search of the reflex parameters with the
device worn (:func:`afo_mj.studies.gait_optimization.optimize_gait`). One search per condition
compares the searches as much as the conditions (issue 42: 7–18 points between seeds). The
protocol here (:class:`AdaptationProtocol`, :func:`adapt_conditions`):

1. every condition, the control (no device) first, is searched ``restarts`` times from the
   same start (a converged control's reflex set), restart ``i`` with CMA-ES seed
   ``seed + i``: the restarts are independent searches, so their spread is the
   seed-to-seed spread of the search; each is resumable in ``OUT/<condition>/restart<i>``;
2. each restart's best set is walked again, ``score_walk_s`` long, with its condition, and
   scored by the net metabolic rate (Umberger 2010, W/kg, net of the basal rate:
   :func:`afo_mj.experiments.muscle_assistance.assistance_summary`, strides after
   ``settle_s``);
3. a restart has converged when its best cost fell by at most ``cost_tol`` over the last
   ``window`` generations (:func:`search_converged`); a condition has converged when every
   restart has, none falls in its scoring walk, and the restarts' rates agree: their spread
   (max − min) is at most ``spread_target_pct`` % of their mean (:func:`rate_spread`);
4. the condition's wearer is the restart of the lowest search cost (the objective the wearer
   minimises), and its effect is given against the control paired restart by restart
   (condition restart ``i`` against control restart ``i``: the same seed), with the spread of
   those paired changes, and best against best with the range over every pairing
   (:func:`paired_changes`);
5. with ``groups`` G > 1 the restarts are also split into G groups of R/G consecutive
   restarts (restart ``i`` in group ``i // (R/G)``), each group an independent replicate of
   the protocol with R/G restarts: its wearer is its lowest-cost restart ("best of R/G"), and
   the spread of the G group wearers' rates is the measured spread of that estimator
   (:func:`group_estimates`); the condition's agreement test then applies to it instead of
   to single restarts, and the change against the control is given group by group (group
   ``g``'s wearer against the control's group ``g`` wearer). The reported wearer is still the
   best of all R restarts: an estimator with G times the restarts of the one whose spread is
   measured. Measured (docs/muscle_walker.md): on the control the lowest-cost optima agree
   in rate better than single restarts do (best of 3: SD 0.48 % of the rate against 1.00 %
   for one restart); on the clutched spring, whose cost does not rank its rates, not.

The result is an :class:`AdaptationResult` (format ``afo_mj adaptation v1``), written
atomically to ``OUT/adaptation.json``. The protocol's fixed settings are kept in
``OUT/adaptation_protocol.json``: a rerun with other settings (popsize, step, seed, the
objective's walk, the start) is refused; more ``generations`` or ``restarts`` continue.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import math
import os
import resource
from pathlib import Path
from typing import ClassVar, Sequence

import numpy as np

from afo_mj.metrics.document_base import Document, entry
from afo_mj.studies.gait_optimization import (GaitObjective, evaluate_batch, load_reflex_set,
                                              objective_walk, optimize_gait,
                                              scenario_objective)

__all__ = ["AdaptationProtocol", "AdaptCondition", "RestartResult", "ConditionResult",
           "AdaptationResult", "search_converged", "rate_spread", "paired_changes",
           "assistance_conditions", "scenario_conditions", "adapt_conditions", "group_estimates",
           "refuse_other_settings",
           "ADAPTATION_FORMAT"]

ADAPTATION_FORMAT = "afo_mj adaptation v1"
#: the settings a resumed protocol must share with the one that started the searches
_FIXED = ("popsize", "sigma0", "seed", "search_walk_s", "settle_s", "tracking_weight")


@dataclasses.dataclass(frozen=True)
class AdaptationProtocol:
    """The settings of the adaptation protocol (module docstring). ``cost_tol`` is in the
    objective's own units (:func:`~afo_mj.studies.gait_optimization.gait_cost`, about 5 for a
    converged walk at 1.25 m/s); ``search_walk_s`` the length of every walk the search scores,
    ``score_walk_s`` of the walk that scores a restart's best set."""

    restarts: int = 3
    generations: int = 100
    popsize: int = 16
    sigma0: float = 0.04
    seed: int = 1
    window: int = 10
    cost_tol: float = 0.01
    spread_target_pct: float = 1.0
    search_walk_s: float = 16.0
    score_walk_s: float = 20.0
    settle_s: float = 3.0
    tracking_weight: float = 0.25
    #: replicates the restarts are split into for the best-of-(restarts/groups) estimator's
    #: spread (module docstring, step 5); 1: none
    groups: int = 1

    def __post_init__(self):
        ints = (("restarts", 1, 50), ("generations", 1, 10000), ("popsize", 4, 1000),
                ("seed", 0, 2**31 - 1), ("window", 1, 1000), ("groups", 1, 50))
        for name, lo, hi in ints:
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int) or not lo <= v <= hi:
                raise ValueError(f"AdaptationProtocol.{name} = {v!r}; allowed: an integer "
                                 f"{lo} … {hi}")
        floats = (("sigma0", 1e-4, 2.0), ("cost_tol", 0.0, 1e3),
                  ("spread_target_pct", 0.0, 100.0), ("search_walk_s", 2.0, 120.0),
                  ("score_walk_s", 2.0, 120.0), ("settle_s", 0.0, 60.0),
                  ("tracking_weight", 0.0, 100.0))
        for name, lo, hi in floats:
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, float)) \
                    or not (math.isfinite(v) and lo <= v <= hi):
                raise ValueError(f"AdaptationProtocol.{name} = {v!r}; allowed: {lo:g} … "
                                 f"{hi:g}")
        if self.restarts % self.groups:
            divisors = [d for d in range(1, self.restarts + 1) if self.restarts % d == 0]
            raise ValueError(f"AdaptationProtocol.groups = {self.groups!r} with restarts = "
                             f"{self.restarts}; allowed: a divisor of restarts "
                             f"({', '.join(map(str, divisors))})")
        for name in ("search_walk_s", "score_walk_s"):
            if self.settle_s >= getattr(self, name) - 1.0:
                raise ValueError(f"AdaptationProtocol.settle_s = {self.settle_s:g}; allowed: "
                                 f"at least 1 s below {name} ({getattr(self, name):g})")


@dataclasses.dataclass(frozen=True)
class AdaptCondition:
    """One condition the wearer adapts to: its ``name`` (its folder), a ``label`` for tables
    and the search's objective (the device worn is the objective's)."""

    name: str
    label: str
    objective: GaitObjective


# --------------------------------------------------------------------------- the measures
def search_converged(history: Sequence, window: int, tol: float) -> tuple[bool, str, float | None]:
    """Whether a search's best cost has stopped moving: ``history`` is
    :func:`~afo_mj.studies.gait_optimization.optimize_gait`'s (one entry per generation with
    the best cost so far, ``"best"``). Converged when the best fell by at most ``tol`` over the
    last ``window`` generations (the best after generation ``n − window`` against the best
    after generation ``n``). Returns ``(converged, reason, change)``; ``change`` is None when
    the search has fewer than ``window + 1`` generations (then not converged)."""
    best = [float(h["best"]) for h in history]
    if len(best) < window + 1:
        return False, (f"{len(best)} generations; the window needs {window + 1}"), None
    change = best[-1 - window] - best[-1]
    if not math.isfinite(change):
        return False, f"best cost {best[-1 - window]!r} -> {best[-1]!r}", None
    if change <= tol:
        return True, f"best cost fell {change:.4g} <= {tol:g} over {window} generations", change
    return False, f"best cost fell {change:.4g} > {tol:g} over the last {window} generations", \
        change


def rate_spread(rates: Sequence[float | None]) -> tuple[float | None, float | None]:
    """``(max − min, 100 × (max − min) / mean)`` of the restarts' rates; ``(None, None)`` when
    any is None (a restart whose walk fell) or there are none."""
    if not rates or any(r is None for r in rates):
        return None, None
    r = np.asarray(rates, float)
    spread = float(r.max() - r.min())
    return spread, 100.0 * spread / float(r.mean())


def paired_changes(control: Sequence[float | None], condition: Sequence[float | None],
                   best_control: int, best_condition: int) -> dict:
    """The condition's change of the rate against the control's, in %: ``paired``: restart
    ``i`` against control restart ``i`` (for the restarts both have, None where either fell),
    ``paired_mean`` and ``paired_spread`` (max − min of the paired changes, points; None
    unless every pair walked), ``best``: best restart against best restart, and
    ``all_pairs_range``: ``[min, max]`` of the change over every pairing of a control restart
    with a condition restart (None unless every restart walked)."""
    def ch(c, x):
        return None if c is None or x is None else 100.0 * (x / c - 1.0)
    n = min(len(control), len(condition))
    paired = [ch(control[i], condition[i]) for i in range(n)]
    ok = [p for p in paired if p is not None]
    every = [ch(c, x) for c in control for x in condition]
    full = bool(paired) and len(ok) == len(paired)
    return {"paired": paired,
            "paired_mean": float(np.mean(ok)) if full else None,
            "paired_spread": float(max(ok) - min(ok)) if full else None,
            "best": ch(control[best_control], condition[best_condition]),
            "all_pairs_range": ([float(min(every)), float(max(every))]
                                if every and all(e is not None for e in every) else None)}


def group_estimates(costs: Sequence[float], rates: Sequence[float | None], groups: int,
                    control: dict | None = None) -> dict:
    """The restarts split into ``groups`` groups of consecutive restarts (``len(costs)`` a
    multiple of ``groups``), each group's wearer its lowest-``costs`` restart: ``size``
    (restarts per group), ``restarts`` (each group's indices), ``best_restart``,
    ``best_rate`` (W/kg; None where that restart fell), ``best_spread_pct`` (max − min of
    the groups' wearers' rates in % of their mean: the best-of-``size`` estimator's spread),
    ``mean_rate`` and ``mean_spread_pct`` (the same for each group's mean rate, None where a
    restart fell). With ``control`` (the control's own :func:`group_estimates`, same
    ``groups``): ``change_pct_best`` (group ``g``'s wearer against the control's group ``g``
    wearer, %), its ``change_pct_best_mean`` and ``change_pct_best_spread`` (max − min,
    points), and the same of the group means (``change_pct_mean``,
    ``change_pct_mean_spread``). A spread or mean is None unless every item it needs is."""
    n = len(costs)
    if groups < 1 or n % groups or len(rates) != n:
        raise ValueError(f"groups = {groups!r} for {n} restarts ({len(rates)} rates); "
                         "allowed: a divisor of the number of restarts, one rate per restart")
    size = n // groups
    idx = [list(range(g * size, (g + 1) * size)) for g in range(groups)]
    best = [min(ix, key=lambda i: costs[i]) for ix in idx]
    best_rate = [rates[i] for i in best]
    mean_rate = [None if any(rates[i] is None for i in ix)
                 else float(np.mean([rates[i] for i in ix])) for ix in idx]
    out = {"size": size, "restarts": idx, "best_restart": best, "best_rate": best_rate,
           "best_spread_pct": rate_spread(best_rate)[1], "mean_rate": mean_rate,
           "mean_spread_pct": rate_spread(mean_rate)[1]}
    if control is not None:
        for key, name in (("best_rate", "best"), ("mean_rate", "mean")):
            ch = paired_changes(control[key], out[key], 0, 0)
            out[f"change_pct_{name}"] = ch["paired"]
            if name == "best":
                out["change_pct_best_mean"] = ch["paired_mean"]
            out[f"change_pct_{name}_spread"] = ch["paired_spread"]
    return out


# --------------------------------------------------------------------------- documents
@dataclasses.dataclass(frozen=True)
class RestartResult(Document):
    """One restart of one condition: its search and its best set's scoring walk."""

    restart: int = entry("int", "restart index (0 first)")
    seed: int = entry("int", "CMA-ES seed (protocol seed + restart)")
    out_dir: str = entry("str", "the search's resumable folder")
    generations: int = entry("int", "generations searched")
    walks: int = entry("int", "walks the search evaluated")
    search_cost: float = entry("number", "best objective value found")
    converged: bool = entry("bool", "the best cost stopped moving (the window's test)")
    convergence: str = entry("str", "why converged or not")
    best_cost_change: float | None = entry("number?", "best cost's fall over the window "
                                           "(null: the search is shorter than the window)")
    net_metabolic_w_per_kg: float | None = entry(
        "number?", "net metabolic rate of the best set's scoring walk, Umberger 2010 (null: "
        "it fell)", "W/kg")
    fell_s: float | None = entry("number?", "time of the scoring walk's fall (null: none)",
                                 "s")
    speed_m_s: float | None = entry("number?", "speed of the scoring walk", "m/s")
    wall_s: float = entry("number", "the search's wall time over all its runs", "s")
    cpu_s: float | None = entry("number?", "CPU time of the search measured by this "
                                "protocol's runs (this process and its worker processes; "
                                "null: some of the search ran elsewhere, outside the "
                                "protocol or on Dask workers)", "s")


@dataclasses.dataclass(frozen=True)
class ConditionResult(Document):
    """One condition's restarts, its wearer, its spread and its change against the
    control."""

    name: str = entry("str", "condition (its folder)")
    label: str = entry("str", "condition as tables name it")
    restarts: tuple = entry("list", "every restart", list_of=RestartResult, tagged=False)
    best_restart: int = entry("int", "the wearer: the restart of the lowest search cost")
    net_metabolic_w_per_kg: float | None = entry("number?", "the wearer's net metabolic rate",
                                                 "W/kg")
    spread_w_per_kg: float | None = entry("number?", "restarts' rates, max − min (null: one "
                                          "fell)", "W/kg")
    spread_pct: float | None = entry("number?", "that spread in % of the restarts' mean "
                                     "rate", "%")
    converged: bool = entry("bool", "every restart converged, walks, and the spread is "
                            "within the target")
    reason: str = entry("str", "why converged or not")
    change_pct_paired: tuple | None = entry(
        "list?", "change of the rate against the control, restart i against control restart "
        "i (null for the control; a null item: a walk fell)", "%")
    change_pct_paired_mean: float | None = entry("number?", "mean of the paired changes",
                                                 "%")
    change_pct_paired_spread: float | None = entry("number?", "paired changes, max − min",
                                                   "points")
    change_pct_best: float | None = entry("number?", "the wearer against the control's "
                                          "wearer", "%")
    change_pct_all_pairs_range: tuple | None = entry(
        "list?", "[min, max] of the change over every pairing of a control restart with a "
        "restart of this condition", "%")
    groups: dict | None = entry(
        "object?", "with the protocol's groups > 1: the restarts in groups, each group's "
        "wearer (its lowest-cost restart) and mean, their spreads (%) and, but for the "
        "control, the changes against the control group by group (%; group_estimates)",
        omit_none=True, default=None)


@dataclasses.dataclass(frozen=True)
class AdaptationResult(Document):
    """``adaptation.json``: the adaptation protocol's result (:mod:`afo_mj.studies.
    adaptation`)."""

    FORMAT: ClassVar[str] = ADAPTATION_FORMAT
    TITLE: ClassVar[str] = "The adapted wearers of several conditions, with their spread"

    protocol: dict = entry("object", "AdaptationProtocol's settings")
    start: str = entry("str", "the reflex set every search starts from")
    start_sha256: str = entry("str", "SHA-256 of the start's parameters (JSON)")
    control: str = entry("str", "the control condition (first of conditions)")
    conditions: tuple = entry("list", "every condition, the control first",
                              list_of=ConditionResult, tagged=False)
    converged: bool = entry("bool", "every condition converged")
    walks: int = entry("int", "walks of every search")
    cpu_s: float | None = entry("number?", "CPU time of every search measured by this "
                                "protocol (null: some not measured)", "s")

    def condition(self, name: str) -> ConditionResult:
        """The condition called ``name``; KeyError naming the known ones."""
        for c in self.conditions:
            if c.name == name:
                return c
        raise KeyError(f"condition {name!r}; known: {', '.join(c.name for c in self.conditions)}")


# --------------------------------------------------------------------------- conditions
def _objective_kw(protocol: AdaptationProtocol) -> dict:
    return {"duration_s": float(protocol.search_walk_s), "settle_s": float(protocol.settle_s),
            "tracking_weight": float(protocol.tracking_weight)}


def assistance_conditions(kinds: Sequence[str], protocol: AdaptationProtocol
                          ) -> list[AdaptCondition]:
    """The :class:`~afo_mj.experiments.muscle_assistance.Assistance` kinds as conditions, the
    control ``none`` first (added when not listed) and each other kind once, with its
    defaults (``zhang`` ramped on over 3 strides, as ``tools/muscle_adapted.py`` does).
    ValueError naming an unknown or repeated kind."""
    from afo_mj.experiments.muscle_assistance import KINDS, Assistance
    kinds = list(kinds)
    for k in kinds:
        if k not in KINDS:
            raise ValueError(f"condition {k!r}; allowed: {', '.join(KINDS)} or a muscle-walker "
                             "scenario file")
    if len(set(kinds)) != len(kinds):
        raise ValueError(f"conditions {kinds!r} repeat one; allowed: each once")
    kinds = ["none"] + [k for k in kinds if k != "none"]
    out = []
    for k in kinds:
        a = Assistance(k, ramp_strides=3) if k == "zhang" else Assistance(k)
        out.append(AdaptCondition(k, a.label, GaitObjective(assistance=a,
                                                            **_objective_kw(protocol))))
    return out


def scenario_conditions(path, protocol: AdaptationProtocol, overrides=()
                        ) -> tuple[list[AdaptCondition], str]:
    """A muscle-walker scenario's conditions (its body, impairment and device,
    :func:`~afo_mj.studies.gait_optimization.scenario_objective`), ``no_device`` (the
    control, nothing worn) first, and the scenario's ``walker.reflex_set`` (the natural
    start). ValueError for a scenario that is not a muscle-walker one."""
    head, sc = scenario_objective(path, None, tuple(overrides or ()), **_objective_kw(protocol))
    _sc, cfg = head.scenario.config()
    names = ["no_device"] + [c for c in (cfg.conditions if cfg is not None else ())
                             if c != "no_device"]
    out = [AdaptCondition(c, f"{Path(path).stem}: {c}", dataclasses.replace(
        head, scenario=dataclasses.replace(head.scenario, condition=c))) for c in names]
    return out, str(sc.reflex_set)


# --------------------------------------------------------------------------- the protocol
def _cpu_s() -> float:
    """CPU time of this process and its finished child processes (s)."""
    s, c = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN)
    return s.ru_utime + s.ru_stime + c.ru_utime + c.ru_stime


def _write_json(path: Path, data) -> None:
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    tmp.write_text(json.dumps(data, indent=1), encoding="utf-8")
    os.replace(tmp, path)


def refuse_other_settings(out: Path, saved: dict, fixed: dict, what: str,
                          absent_ok: bool = False) -> None:
    """Refuse to resume in ``out`` a study (``what``: "searches", "a study", …) whose saved
    settings ``saved`` differ from the given ``fixed`` ones: one error naming the key, both
    values and what is allowed. ``absent_ok``: a key the saved file lacks (written before the
    setting existed) passes."""
    for k, v in fixed.items():
        if (k in saved or not absent_ok) and saved.get(k) != v:
            raise ValueError(f"{out} holds {what} with {k} = {saved.get(k)!r}; given {v!r}; "
                             "allowed: the same (or another output folder)")


def _check_protocol(out: Path, protocol: AdaptationProtocol, start_sha: str,
                    names: list[str]) -> None:
    """Refuse a folder whose searches were started with other fixed settings; record them
    (and the conditions) when new."""
    path = out / "adaptation_protocol.json"
    fixed = {k: getattr(protocol, k) for k in _FIXED}
    fixed["start_sha256"] = start_sha
    if path.exists():
        saved = json.loads(path.read_text(encoding="utf-8"))
        refuse_other_settings(out, saved, fixed, "searches", absent_ok=True)
        names = list(dict.fromkeys(list(saved.get("conditions", [])) + names))
    _write_json(path, dict(fixed, conditions=names))


def score_walk(item):
    """The scoring walk of one restart's best set (``(objective, params, walk_s,
    settle_s)``): its net metabolic rate and speed, or the fall. Shared by the adaptation,
    the dose-response and the human-in-the-loop tuning (any objective whose
    ``objective_walk`` walks its parameters)."""
    from afo_mj.experiments.muscle_assistance import assistance_summary
    objective, params, walk_s, settle_s = item
    try:
        walk, dev = objective_walk(objective, params, walk_s)
    except FloatingPointError as exc:
        return {"fell_s": 0.0, "error": str(exc)}
    s = assistance_summary(walk, settle_s, dev)
    return {"fell_s": s["fell_s"], "net_metabolic_w_per_kg": s.get("net_metabolic_w_per_kg"),
            "speed_m_s": s.get("speed_m_s")}


def adapt_conditions(out_dir, conditions: Sequence[AdaptCondition], start,
                     protocol: AdaptationProtocol | None = None, workers: int | None = None,
                     client=None, progress=None) -> AdaptationResult:
    """Run (or continue) the protocol (module docstring) for ``conditions`` (the first is the
    control) from ``start`` (a ``reflex_params.json`` path) into ``out_dir``; writes and
    returns ``adaptation.json``'s :class:`AdaptationResult`. ``workers`` local processes or
    the Dask ``client`` walk each generation and the scoring walks; ``progress(text)`` is
    told of each search as it starts. ValueError: a condition named twice, a start that is
    not a reflex set, a folder of other settings."""
    from afo_mj.gait import reflex_law as rl
    protocol = protocol or AdaptationProtocol()
    conditions = list(conditions)
    names = [c.name for c in conditions]
    if not conditions or len(set(names)) != len(names):
        raise ValueError(f"conditions {names!r}; allowed: at least one, each once")
    start = str(start)
    start_params = load_reflex_set(start)
    start_set = dict(zip(rl.PARAM_NAMES, start_params.tolist()))
    start_sha = hashlib.sha256(json.dumps(start_set, sort_keys=True).encode()).hexdigest()
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    _check_protocol(out, protocol, start_sha, names)
    searches = {}
    # restart by restart, every condition in each: a run stopped early leaves pairs
    for i in range(protocol.restarts):
        for c in conditions:
            d = out / c.name / f"restart{i}"
            if progress is not None:
                progress(f"{c.name} restart {i}")
            cost_file = d / "adaptation_cpu.json"
            fresh = not (d / "cma_state.pkl").exists()
            known = fresh or cost_file.exists()
            prior = (json.loads(cost_file.read_text(encoding="utf-8"))["cpu_s"]
                     if cost_file.exists() else 0.0)
            t0 = _cpu_s()
            doc = optimize_gait(d, c.objective, generations=protocol.generations,
                                popsize=protocol.popsize, seed=protocol.seed + i,
                                start=start_set, workers=workers,
                                sigma0=float(protocol.sigma0), client=client)
            cpu = None
            if known and client is None:
                cpu = prior + _cpu_s() - t0
                _write_json(cost_file, {"cpu_s": cpu})
            searches[(c.name, i)] = (d, doc, cpu)
    items, keys = [], []
    for c in conditions:
        for i in range(protocol.restarts):
            d, doc, _ = searches[(c.name, i)]
            items.append((c.objective, load_reflex_set(d / "reflex_params.json"),
                          protocol.score_walk_s, protocol.settle_s))
            keys.append((c.name, i))
    scored = evaluate_batch(score_walk, items, workers, client)
    scores = {}
    for k, r in zip(keys, scored):
        if not r.ok:
            raise RuntimeError(f"scoring walk of {k[0]} restart {k[1]}: {r.error}")
        scores[k] = r.value
    results = []
    control_rates, control_best, control_groups = None, 0, None
    for c in conditions:
        rows = []
        for i in range(protocol.restarts):
            d, doc, cpu = searches[(c.name, i)]
            conv, why, change = search_converged(doc["history"], protocol.window,
                                                 protocol.cost_tol)
            s = scores[(c.name, i)]
            fell = s["fell_s"]
            rows.append(RestartResult(
                restart=i, seed=protocol.seed + i, out_dir=str(d),
                generations=int(doc["optimizer"]["generations"]),
                walks=int(doc["optimizer"]["evaluations"]), search_cost=float(doc["cost"]),
                converged=conv, convergence=why, best_cost_change=change,
                net_metabolic_w_per_kg=None if fell is not None
                else s["net_metabolic_w_per_kg"],
                fell_s=fell, speed_m_s=s.get("speed_m_s"), wall_s=float(doc["wall_s"]),
                cpu_s=cpu))
        rates = [r.net_metabolic_w_per_kg for r in rows]
        costs = [r.search_cost for r in rows]
        best = int(np.argmin(costs))
        spread, spread_pct = rate_spread(rates)
        grp = (group_estimates(costs, rates, protocol.groups, control_groups)
               if protocol.groups > 1 else None)
        why = []
        if not all(r.converged for r in rows):
            why.append("restart(s) " + ", ".join(str(r.restart) for r in rows
                                                  if not r.converged) + " still falling")
        if any(r.net_metabolic_w_per_kg is None for r in rows):
            why.append("restart(s) " + ", ".join(str(r.restart) for r in rows
                                                  if r.net_metabolic_w_per_kg is None)
                       + " fall or walk too few strides to score")
        elif grp is not None:
            if grp["best_spread_pct"] > protocol.spread_target_pct:
                why.append(f"best-of-{grp['size']} spread over {protocol.groups} groups "
                           f"{grp['best_spread_pct']:.2f} % > {protocol.spread_target_pct:g} %")
        elif spread_pct > protocol.spread_target_pct:
            why.append(f"restarts' spread {spread_pct:.2f} % > {protocol.spread_target_pct:g} %")
        agreed = (f"best-of-{grp['size']} spread over {protocol.groups} groups "
                  f"{grp['best_spread_pct']:.2f} %" if grp is not None
                  else f"spread {spread_pct:.2f} %") if not why else ""
        reason = "; ".join(why) if why else (f"every restart converged and the {agreed} <= "
                                             f"{protocol.spread_target_pct:g} %")
        ch = {}
        if control_rates is None:
            control_rates, control_best, control_groups = rates, best, grp
        else:
            ch = paired_changes(control_rates, rates, control_best, best)
        results.append(ConditionResult(
            name=c.name, label=c.label, restarts=tuple(rows), best_restart=best,
            net_metabolic_w_per_kg=rates[best], spread_w_per_kg=spread, spread_pct=spread_pct,
            converged=not why, reason=reason,
            change_pct_paired=tuple(ch["paired"]) if ch else None,
            change_pct_paired_mean=ch.get("paired_mean"),
            change_pct_paired_spread=ch.get("paired_spread"),
            change_pct_best=ch.get("best"),
            change_pct_all_pairs_range=(tuple(ch["all_pairs_range"])
                                        if ch.get("all_pairs_range") else None),
            groups=grp))
    cpus = [r.cpu_s for c in results for r in c.restarts]
    res = AdaptationResult(
        protocol=dataclasses.asdict(protocol), start=start, start_sha256=start_sha,
        control=conditions[0].name, conditions=tuple(results),
        converged=all(c.converged for c in results),
        walks=sum(r.walks for c in results for r in c.restarts),
        cpu_s=None if any(x is None for x in cpus) else float(sum(cpus)))
    _write_json(out / "adaptation.json", res.to_json())
    return res
