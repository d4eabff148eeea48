"""Dose–response of an assistance by continuation of the adapted wearer.

The wearer's net metabolic rate is measured against one dose variable of one assistance
(:class:`~afo_mj.experiments.muscle_assistance.Assistance`): the Zhang profile's peak torque
or peak time, the clutched spring's stiffness or clutch engagement phase
(:data:`DOSE_VARIABLES`). Each dose is a condition the wearer adapts to by the adaptation
protocol (:mod:`afo_mj.studies.adaptation`: several CMA-ES restarts, their convergence
checked, each scored by a walk's net metabolic rate, Umberger 2010), made affordable by
*continuation* (the protocol of continuation methods, e.g. Allgower & Georg 1990: follow a
family of optima along a parameter by starting each solve from the neighbouring one):

* the rungs are the control (nothing worn) and then the dose levels in the study's order; a
  level whose dose means nothing worn (a Zhang peak of 0, a spring of 0 N·m/rad) is the
  control itself and must come first;
* the control's restart ``i`` starts from the study's start (a converged control) with CMA-ES
  seed ``seed + i``; rung ``k``'s restart ``i`` starts from rung ``k − 1``'s restart ``i``'s
  best set (recorded in its folder, ``continuation_start.json``), with the same seed, and a
  modest generation budget: an adjacent dose moves the optimum little, so a short search
  from there follows it;
* per level, every restart's rate, the band of the rates (min, mean, max over restarts), the
  change against the control paired by restart (rung ``k`` restart ``i`` against control
  restart ``i``, which it descends from) with its band (min, mean, max), and the convergence
  state (:func:`~afo_mj.studies.adaptation.search_converged`, the restarts' spread);
* each restart's best set is also walked with the device taken off: its rate against the
  control's restart measures what the search along the chain did to the wearer by itself
  (the chain's later rungs have been searched longer than the control), the part of the
  change the device is not needed for;
* with ``matched_control = true`` the control is also searched on with nothing worn, one
  rung per level (``control<k>``, restart ``i`` from the previous one's restart ``i``), and
  each level is compared with the control searched as long (``matched_change_pct``): the
  continuation's later rungs have had more generations than the control;
* the study is resumable: each rung × restart is its own search folder
  ``OUT/<rung>/restart<i>`` and each scoring walk is kept there (``dose_score.json``); the
  document is rewritten after every rung, so a stopped run leaves the rungs it finished.

Whether the response is monotone is judged on the bands (:func:`monotone_within_bands`):
a monotone curve passes through every level's band of paired changes.

The study file (TOML, :func:`load_dose_study`)::

    name = "dose_zhang_peak"
    description = "..."
    [dose_response]
    variable = "zhang_peak_nm_per_kg"     # a key of DOSE_VARIABLES (it names the kind)
    levels = [0.0, 0.15, 0.3, 0.45, 0.6]
    assistance = { ramp_strides = 3 }     # other Assistance fields, fixed for every level
    restarts = 2                          # AdaptationProtocol's fields ...
    generations = 16
    start = "../../afo_mj/data/adapted/none.json"   # optional, relative to the file

The result is a :class:`DoseResponseResult` (format ``afo_mj dose_response v1``) written
atomically to ``OUT/dose_response.json``.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import math
import tomllib
from pathlib import Path
from typing import ClassVar, Sequence

import numpy as np

from afo_mj.metrics.document_base import Document, entry
from afo_mj.studies.adaptation import (AdaptationProtocol, _cpu_s, _objective_kw, score_walk,
                                       _write_json, paired_changes, rate_spread,
                                       refuse_other_settings, search_converged)
from afo_mj.studies.gait_optimization import (GaitObjective, evaluate_batch,
                                              load_reflex_set, optimize_gait)

__all__ = ["DOSE_VARIABLES", "DOSE_RESPONSE_FORMAT", "DoseStudy", "Rung", "DoseRestart",
           "DoseLevel", "DoseResponseResult", "band", "monotone_within_bands",
           "parse_dose_study", "load_dose_study", "run_dose_response"]

DOSE_RESPONSE_FORMAT = "afo_mj dose_response v1"

#: dose variable -> (assistance kind, unit, axis label, the dose that means nothing worn);
#: each is an Assistance field but the peak time, the first of ``zhang_timing_pct``
DOSE_VARIABLES = {
    "zhang_peak_nm_per_kg": ("zhang", "N·m/kg", "peak torque (N·m/kg)", 0.0),
    "zhang_peak_time_pct": ("zhang", "%", "peak time (% of stride)", None),
    "spring_nm_per_rad": ("clutched_spring", "N·m/rad", "spring stiffness (N·m/rad)", 0.0),
    "spring_engage_phase": ("clutched_spring", "", "clutch engagement (fraction of stride)",
                            None),
}
_STUDY_KEYS = ("name", "description", "dose_response")
#: the adaptation protocol's settings a study file may set (not its groups: a rung's
#: restarts are chains, not replicates of one search)
_PROTOCOL_KEYS = tuple(f.name for f in dataclasses.fields(AdaptationProtocol)
                       if f.name != "groups")
_DOSE_KEYS = ("variable", "levels", "assistance", "start", "matched_control") + _PROTOCOL_KEYS
#: the protocol settings every rung's search must share with the one that began the study
_FIXED = ("popsize", "sigma0", "seed", "search_walk_s", "settle_s", "tracking_weight")
DEFAULT_START = Path(__file__).resolve().parents[1] / "data" / "adapted" / "none.json"


# --------------------------------------------------------------------------- the study
@dataclasses.dataclass(frozen=True)
class Rung:
    """One step of the continuation: its folder ``name``, its ``dose`` (None: the control
    off the dose axis), a ``label`` and the search's objective."""

    name: str
    dose: float | None
    label: str
    objective: GaitObjective


@dataclasses.dataclass(frozen=True)
class DoseStudy:
    """A dose–response study (module docstring): the ``variable``, its ``levels`` in the
    continuation's order, the other ``assistance`` fields fixed, the adaptation
    ``protocol`` and the ``start`` reflex set of the control's restarts."""

    name: str
    variable: str
    levels: tuple
    description: str = ""
    assistance: dict = dataclasses.field(default_factory=dict)
    protocol: AdaptationProtocol = dataclasses.field(default_factory=AdaptationProtocol)
    start: str = str(DEFAULT_START)
    #: also search the control on along the chain, one rung per level (nothing worn), so
    #: that each level is compared with a control searched as long
    matched_control: bool = False

    def __post_init__(self):
        from afo_mj.experiments.muscle_assistance import Assistance
        if not isinstance(self.matched_control, bool):
            raise ValueError(f"dose_response.matched_control = {self.matched_control!r}; "
                             "allowed: true, false")
        if self.variable not in DOSE_VARIABLES:
            raise ValueError(f"dose_response.variable = {self.variable!r}; allowed: "
                             f"{', '.join(DOSE_VARIABLES)}")
        lv = tuple(self.levels)
        if len(lv) < 2 or any(isinstance(x, bool) or not isinstance(x, (int, float))
                              or not math.isfinite(x) for x in lv):
            raise ValueError(f"dose_response.levels = {list(self.levels)!r}; allowed: at "
                             "least two finite numbers")
        if len(set(lv)) != len(lv):
            raise ValueError(f"dose_response.levels = {list(lv)!r} repeat a level; allowed: "
                             "each once")
        off = DOSE_VARIABLES[self.variable][3]
        if off is not None and off in lv[1:]:
            raise ValueError(f"dose_response.levels = {list(lv)!r}: the dose {off:g} (nothing "
                             "worn, the control) is not first; allowed: first or absent")
        object.__setattr__(self, "levels", tuple(float(x) for x in lv))
        fixed = dict(self.assistance)
        for k in ("kind", self.variable):
            if k in fixed:
                raise ValueError(f"dose_response.assistance.{k} = {fixed[k]!r}; allowed: not "
                                 "given (the variable sets it)")
        names = {f.name for f in dataclasses.fields(Assistance)}
        for k in fixed:
            if k not in names:
                raise ValueError(f"dose_response.assistance.{k}: unknown; allowed: "
                                 f"{', '.join(sorted(names - {'kind'}))}")
        for x in self.levels:       # every level a valid device (refused here, not mid-run)
            self._assistance(x)

    @property
    def kind(self) -> str:
        return DOSE_VARIABLES[self.variable][0]

    @property
    def unit(self) -> str:
        return DOSE_VARIABLES[self.variable][1]

    def _assistance(self, dose: float):
        from afo_mj.experiments.muscle_assistance import ZHANG_TIMING_PCT, Assistance
        fixed = dict(self.assistance)
        if "sides" in fixed:
            fixed["sides"] = tuple(fixed["sides"])
        if self.variable == "zhang_peak_time_pct":
            # the peak of Assistance.zhang_timing_pct (peak, rise, fall); rise and fall
            # Zhang et al.'s, or those of a zhang_timing_pct given
            timing = tuple(fixed.pop("zhang_timing_pct", ZHANG_TIMING_PCT))
            dosed = {"zhang_timing_pct": (dose, *timing[1:])}
        else:
            dosed = {self.variable: dose}
        try:
            return Assistance(self.kind, **fixed, **dosed)
        except (TypeError, ValueError) as exc:
            raise ValueError(f"dose_response level {dose:g}: {exc}") from None

    def rungs(self) -> list[Rung]:
        """The continuation's rungs: the control first, then each level (module
        docstring)."""
        from afo_mj.experiments.muscle_assistance import Assistance
        kw = _objective_kw(self.protocol)
        off = DOSE_VARIABLES[self.variable][3]
        control_dose = off if off is not None and self.levels[0] == off else None
        out = [Rung("control", control_dose, "control (nothing worn)",
                    GaitObjective(assistance=Assistance("none"), **kw))]
        for k, x in enumerate(self.levels):
            if control_dose is not None and k == 0:
                continue
            a = self._assistance(x)
            label = a.label + (f", clutch at {100 * x:g} %"
                               if self.variable == "spring_engage_phase" else "")
            out.append(Rung(f"level{len(out)}_{x:g}", x, label,
                            GaitObjective(assistance=a, **kw)))
        return out


def parse_dose_study(text: str, origin: str = "<study>", base_dir: Path | None = None
                     ) -> DoseStudy:
    """A :class:`DoseStudy` from a study file's TOML text; ValueError naming the key, the
    value and what is allowed (an unknown key, a bad level, a protocol setting out of
    range)."""
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ValueError(f"{origin}: not TOML ({exc})") from None
    for k in data:
        if k not in _STUDY_KEYS:
            raise ValueError(f"{origin}: key {k!r}; allowed: {', '.join(_STUDY_KEYS)}")
    dr = data.get("dose_response")
    if not isinstance(dr, dict):
        raise ValueError(f"{origin}: [dose_response] = {dr!r}; allowed: a table with "
                         "variable and levels")
    for k in dr:
        if k not in _DOSE_KEYS:
            raise ValueError(f"{origin}: dose_response.{k}; allowed: {', '.join(_DOSE_KEYS)}")
    for k in ("variable", "levels"):
        if k not in dr:
            raise ValueError(f"{origin}: dose_response.{k} missing; allowed: "
                             + (", ".join(DOSE_VARIABLES) if k == "variable"
                                else "a list of at least two numbers"))
    name = data.get("name", Path(origin).stem)
    if not isinstance(name, str) or not name:
        raise ValueError(f"{origin}: name = {name!r}; allowed: a non-empty string")
    try:
        protocol = AdaptationProtocol(**{k: dr[k] for k in _PROTOCOL_KEYS if k in dr})
    except ValueError as exc:
        raise ValueError(f"{origin}: {str(exc).replace('AdaptationProtocol.', 'dose_response.')}"
                         ) from None
    start = dr.get("start")
    if start is None:
        start = str(DEFAULT_START)
    elif not isinstance(start, str):
        raise ValueError(f"{origin}: dose_response.start = {start!r}; allowed: a path")
    elif base_dir is not None and not Path(start).is_absolute():
        start = str((base_dir / start).resolve())
    assistance = dr.get("assistance", {})
    if not isinstance(assistance, dict):
        raise ValueError(f"{origin}: dose_response.assistance = {assistance!r}; allowed: a "
                         "table of Assistance fields")
    levels = dr["levels"]
    if not isinstance(levels, list):
        raise ValueError(f"{origin}: dose_response.levels = {levels!r}; allowed: a list")
    try:
        return DoseStudy(name=name, variable=dr["variable"], levels=tuple(levels),
                         description=str(data.get("description", "")),
                         assistance=assistance, protocol=protocol, start=start,
                         matched_control=dr.get("matched_control", False))
    except ValueError as exc:
        raise ValueError(f"{origin}: {exc}") from None


def load_dose_study(path) -> DoseStudy:
    """:func:`parse_dose_study` of a file (its relative ``start`` resolved from the file's
    folder)."""
    p = Path(path)
    return parse_dose_study(p.read_text(encoding="utf-8"), str(p), p.parent)


# --------------------------------------------------------------------------- the measures
def band(values: Sequence[float | None]) -> tuple[float | None, float | None, float | None]:
    """``(min, mean, max)`` of ``values``; ``(None, None, None)`` when any is None (a walk
    fell) or there are none."""
    if not values or any(v is None for v in values):
        return None, None, None
    v = np.asarray(values, float)
    return float(v.min()), float(v.mean()), float(v.max())


def monotone_within_bands(lo: Sequence[float], hi: Sequence[float],
                          decreasing: bool = True) -> bool:
    """Whether a monotone sequence passes through every band ``[lo_k, hi_k]`` (in the dose's
    order): for a non-increasing one, no later band lies wholly above an earlier one
    (``lo_k <= hi_j`` for every ``j < k``); for a non-decreasing one, no later band wholly
    below (``hi_k >= lo_j``)."""
    n = len(lo)
    if n != len(hi):
        raise ValueError(f"bands: {n} lower and {len(hi)} upper ends; allowed: as many")
    for k in range(n):
        for j in range(k):
            if decreasing and lo[k] > hi[j]:
                return False
            if not decreasing and hi[k] < lo[j]:
                return False
    return True


# --------------------------------------------------------------------------- documents
@dataclasses.dataclass(frozen=True)
class DoseRestart(Document):
    """One restart of one rung: where it started, its search and its scoring walk."""

    restart: int = entry("int", "restart index (0 first)")
    seed: int = entry("int", "CMA-ES seed (protocol seed + restart)")
    out_dir: str = entry("str", "the search's resumable folder")
    started_from: str = entry("str", "the reflex set the search started from (the previous "
                              "rung's restart of the same index, or the study's start)")
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
    change_pct: float | None = entry("number?", "change of the rate against the control's "
                                     "restart of the same index (null for the control or a "
                                     "fall)", "%")
    device_off_w_per_kg: float | None = entry(
        "number?", "the same best set walked with the device taken off: what the search "
        "alone did to the wearer (null for the control, or it fell)", "W/kg")
    device_off_fell_s: float | None = entry("number?", "time of that walk's fall (null: "
                                            "none, or the control)", "s")
    device_off_speed_m_s: float | None = entry("number?", "speed of that walk", "m/s")
    device_off_change_pct: float | None = entry(
        "number?", "its rate against the control's restart of the same index: the part of "
        "change_pct the search along the chain would give without the device (null: the "
        "control or a fall)", "%")
    matched_control_w_per_kg: float | None = entry(
        "number?", "rate of the matched control's restart of the same index: the control "
        "searched on with nothing worn for as many rungs as this one (null: not run, or it "
        "fell)", "W/kg")
    matched_change_pct: float | None = entry("number?", "change of the rate against that "
                                             "matched control (null: as above)", "%")
    cpu_s: float | None = entry("number?", "CPU time of the search measured by this study's "
                                "runs (null: some of it was not measured)", "s")


@dataclasses.dataclass(frozen=True)
class DoseLevel(Document):
    """One rung: its dose, every restart, the bands and the convergence state."""

    name: str = entry("str", "rung (its folder)")
    label: str = entry("str", "the condition as tables name it")
    dose: float | None = entry("number?", "the dose (null: the control off the dose axis)")
    restarts: tuple = entry("list", "every restart", list_of=DoseRestart, tagged=False)
    rate_min: float | None = entry("number?", "lowest restart rate (null: a restart fell)",
                                   "W/kg")
    rate_mean: float | None = entry("number?", "mean restart rate", "W/kg")
    rate_max: float | None = entry("number?", "highest restart rate", "W/kg")
    spread_pct: float | None = entry("number?", "restarts' rates max − min in % of their "
                                     "mean", "%")
    change_pct_min: float | None = entry("number?", "lowest paired change against the "
                                         "control (null for the control or a fall)", "%")
    change_pct_mean: float | None = entry("number?", "mean paired change", "%")
    change_pct_max: float | None = entry("number?", "highest paired change", "%")
    searches_converged: int = entry("int", "restarts whose search converged")
    converged: bool = entry("bool", "every restart converged, walks, and the spread is "
                            "within the target")
    reason: str = entry("str", "why converged or not")
    matched_change_pct_min: float | None = entry(
        "number?", "lowest change against the matched control (null: no matched control, "
        "or a fall)", "%", default=None)
    matched_change_pct_mean: float | None = entry("number?", "mean change against the "
                                                  "matched control", "%", default=None)
    matched_change_pct_max: float | None = entry("number?", "highest change against the "
                                                 "matched control", "%", default=None)
    matched_control_walks: int = entry("int", "walks of the matched control's searches of "
                                       "this rung (0: none)", default=0)
    matched_control_cpu_s: float | None = entry(
        "number?", "CPU time of those searches measured by this study (null: none run, or "
        "not measured)", "s", default=None)


@dataclasses.dataclass(frozen=True)
class DoseResponseResult(Document):
    """``dose_response.json``: a dose–response study's result (:mod:`afo_mj.studies.
    dose_response`)."""

    FORMAT: ClassVar[str] = DOSE_RESPONSE_FORMAT
    TITLE: ClassVar[str] = "The adapted wearer's net metabolic change against a dose"

    study: str = entry("str", "the study's name")
    description: str = entry("str", "the study's description")
    variable: str = entry("str", "the dose variable (an Assistance field)")
    unit: str = entry("str", "the dose's unit")
    kind: str = entry("str", "the assistance kind")
    assistance: dict = entry("object", "the Assistance fields fixed for every level")
    protocol: dict = entry("object", "AdaptationProtocol's settings (generations: each rung's "
                           "budget)")
    start: str = entry("str", "the reflex set the control's restarts start from")
    start_sha256: str = entry("str", "SHA-256 of the start's parameters (JSON)")
    levels: tuple = entry("list", "every rung run so far, the control first",
                          list_of=DoseLevel, tagged=False)
    complete: bool = entry("bool", "every rung of the study has been run")
    monotone_within_bands: bool | None = entry(
        "bool?", "a non-increasing curve passes through every level's band of paired changes "
        "(the control's 0 included when it is on the dose axis; levels where a restart fell "
        "left out, see monotone_left_out; null: fewer than two levels with a band)")
    monotone_means: bool | None = entry("bool?", "the mean paired changes fall at every "
                                        "step (the same levels; null: as above)")
    monotone_matched_within_bands: bool | None = entry(
        "bool?", "the same test on the bands of the changes against the matched control "
        "(null: no matched control, or fewer than two levels with a band)")
    monotone_left_out: tuple = entry("list", "levels left out of the two tests above: a "
                                     "restart's scoring walk fell, so the level has no band")
    monotone_per_restart: tuple = entry(
        "list", "per restart (its own chain of continuation): its paired changes never rise "
        "from one level to the next, over the levels where it walks (null: fewer than two)")
    walks: int = entry("int", "walks of every search")
    cpu_s: float | None = entry("number?", "CPU time of every search measured by this study, "
                                "the matched controls' included (null: some not measured)",
                                "s")

    def level(self, name: str) -> DoseLevel:
        """The rung called ``name``; KeyError naming the known ones."""
        for lv in self.levels:
            if lv.name == name:
                return lv
        raise KeyError(f"level {name!r}; known: {', '.join(lv.name for lv in self.levels)}")


# --------------------------------------------------------------------------- the runner
def _check_study(out: Path, study: DoseStudy, start_sha: str) -> None:
    """Refuse a folder begun with another study (variable, levels' order, fixed fields,
    fixed protocol settings, start); record them when new. More levels appended at the end,
    more generations or restarts continue."""
    path = out / "dose_protocol.json"
    fixed = {k: getattr(study.protocol, k) for k in _FIXED}
    fixed.update(start_sha256=start_sha, variable=study.variable,
                 assistance=json.loads(json.dumps(study.assistance)))
    levels = list(study.levels)
    if path.exists():
        saved = json.loads(path.read_text(encoding="utf-8"))
        refuse_other_settings(out, saved, fixed, "a study")
        old = saved.get("levels", [])
        n = min(len(old), len(levels))
        if old[:n] != levels[:n]:
            raise ValueError(f"{out} holds a study with levels {old!r}; given {levels!r}; "
                             "allowed: the same levels in the same order (more appended at "
                             "the end), or another output folder")
        if len(old) > len(levels):
            levels = old
    _write_json(path, dict(fixed, levels=levels))


def _search(d: Path, rung: Rung, start_set: dict, started_from: str, protocol, i: int,
            workers, client):
    """Run (or continue) one rung × restart search from ``start_set``; the start it began
    from is kept in ``continuation_start.json`` (a resumed search keeps its own)."""
    d.mkdir(parents=True, exist_ok=True)
    start_file = d / "continuation_start.json"
    if (d / "cma_state.pkl").exists() and start_file.exists():
        began = json.loads(start_file.read_text(encoding="utf-8"))
        started_from = began["from"]
    else:
        _write_json(start_file, {"from": started_from, "params": start_set})
    cost_file = d / "adaptation_cpu.json"
    fresh = not (d / "cma_state.pkl").exists()
    known = fresh or cost_file.exists()
    prior = (json.loads(cost_file.read_text(encoding="utf-8"))["cpu_s"]
             if cost_file.exists() else 0.0)
    t0 = _cpu_s()
    doc = optimize_gait(d, rung.objective, generations=protocol.generations,
                        popsize=protocol.popsize, seed=protocol.seed + i, start=start_set,
                        workers=workers, sigma0=float(protocol.sigma0), client=client)
    cpu = None
    if known and client is None:
        cpu = prior + _cpu_s() - t0
        _write_json(cost_file, {"cpu_s": cpu})
    return doc, cpu, started_from


def _scores(rung: Rung, dirs: list[Path], docs: list[dict], protocol, workers, client):
    """Each restart's scoring walk, and (not for the control) the same best set walked with
    the device taken off; both kept in ``dose_score.json`` for the best set they scored
    (walked again only when the search found a better one). Returns ``[(score, off), …]``
    (``off`` None for the control)."""
    from afo_mj.experiments.muscle_assistance import Assistance
    off_objective = (None if rung.objective.assistance.kind == "none" else
                     dataclasses.replace(rung.objective, assistance=Assistance("none")))
    saved, items, slots = [], [], []
    for i, (d, doc) in enumerate(zip(dirs, docs)):
        key = {"cost": float(doc["cost"]), "generations": int(doc["optimizer"]["generations"]),
               "score_walk_s": protocol.score_walk_s, "settle_s": protocol.settle_s}
        f = d / "dose_score.json"
        have = json.loads(f.read_text(encoding="utf-8")) if f.exists() else {}
        have = have if have.get("key") == key else {"key": key}
        saved.append(have)
        params = load_reflex_set(d / "reflex_params.json")
        for what, obj in (("score", rung.objective), ("off", off_objective)):
            if obj is not None and what not in have:
                items.append((obj, params, protocol.score_walk_s, protocol.settle_s))
                slots.append((i, what))
    for (i, what), r in zip(slots, evaluate_batch(score_walk, items, workers, client)):
        if not r.ok:
            raise RuntimeError(f"scoring walk of {rung.name} restart {i}: {r.error}")
        saved[i][what] = r.value
    for d, have in zip(dirs, saved):
        _write_json(d / "dose_score.json", have)
    return [(h["score"], h.get("off")) for h in saved]


def _level(rung: Rung, restarts: list[DoseRestart], protocol, control: DoseLevel | None
           ) -> DoseLevel:
    rates = [r.net_metabolic_w_per_kg for r in restarts]
    if control is not None:
        ctl = [r.net_metabolic_w_per_kg for r in control.restarts]
        ch = paired_changes(ctl, rates, 0, 0)["paired"]
        off = paired_changes(ctl, [r.device_off_w_per_kg for r in restarts], 0, 0)["paired"]
        restarts = [dataclasses.replace(r, change_pct=ch[i] if i < len(ch) else None,
                                        device_off_change_pct=off[i] if i < len(off) else None)
                    for i, r in enumerate(restarts)]
        cmin, cmean, cmax = band([r.change_pct for r in restarts])
    else:
        cmin = cmean = cmax = None
    lo, mean, hi = band(rates)
    _spread, spread_pct = rate_spread(rates)
    why = []
    if not all(r.converged for r in restarts):
        why.append("restart(s) " + ", ".join(str(r.restart) for r in restarts
                                              if not r.converged) + " still falling")
    if any(r is None for r in rates):
        why.append("restart(s) " + ", ".join(str(r.restart) for r in restarts
                                              if r.net_metabolic_w_per_kg is None)
                   + " fall or walk too few strides to score")
    elif spread_pct > protocol.spread_target_pct:
        why.append(f"restarts' spread {spread_pct:.2f} % > {protocol.spread_target_pct:g} %")
    reason = "; ".join(why) if why else (f"every restart converged and the spread "
                                         f"{spread_pct:.2f} % <= "
                                         f"{protocol.spread_target_pct:g} %")
    return DoseLevel(name=rung.name, label=rung.label, dose=rung.dose,
                     restarts=tuple(restarts), rate_min=lo, rate_mean=mean, rate_max=hi,
                     spread_pct=spread_pct, change_pct_min=cmin, change_pct_mean=cmean,
                     change_pct_max=cmax,
                     searches_converged=sum(1 for r in restarts if r.converged),
                     converged=not why, reason=reason)


def _monotone(levels: list[DoseLevel]) -> tuple[bool | None, bool | None, list[str],
                                                 list[bool | None]]:
    """``(within bands, means, levels left out, per restart)`` over the rungs on the dose
    axis (the control's 0 change included when its dose is on the axis). A level where a
    restart fell has no band: it is left out of the first two (named in the third); each
    restart's own chain of paired changes is judged over the levels where it walks (None:
    fewer than two)."""
    pts, left_out = [], []
    chains: dict[int, list[float]] = {}
    for lv in levels:
        if lv.dose is None:
            continue
        if lv is levels[0]:
            pts.append((0.0, 0.0, 0.0))
            for r in lv.restarts:
                chains.setdefault(r.restart, []).append(0.0)
            continue
        for r in lv.restarts:
            if r.change_pct is not None:
                chains.setdefault(r.restart, []).append(r.change_pct)
        if lv.change_pct_min is None:
            left_out.append(lv.name)
        else:
            pts.append((lv.change_pct_min, lv.change_pct_mean, lv.change_pct_max))
    per_restart = [None if len(c) < 2 else all(b <= a for a, b in zip(c, c[1:]))
                   for _i, c in sorted(chains.items())]
    if len(pts) < 2:
        return None, None, left_out, per_restart
    lo, mean, hi = zip(*pts)
    return (monotone_within_bands(lo, hi, decreasing=True),
            all(b < a for a, b in zip(mean, mean[1:])), left_out, per_restart)


def _monotone_matched(levels: list[DoseLevel]) -> bool | None:
    """:func:`monotone_within_bands` (non-increasing) over the matched controls' bands, the
    control's 0 first when its dose is on the axis; None without two bands."""
    pts = [(0.0, 0.0)] if levels and levels[0].dose is not None else []
    pts += [(lv.matched_change_pct_min, lv.matched_change_pct_max) for lv in levels[1:]
            if lv.dose is not None and lv.matched_change_pct_min is not None]
    if len(pts) < 2 or not any(lv.matched_control_walks for lv in levels):
        return None
    lo, hi = zip(*pts)
    return monotone_within_bands(lo, hi, decreasing=True)


def run_dose_response(out_dir, study: DoseStudy, workers: int | None = None, client=None,
                      progress=None) -> DoseResponseResult:
    """Run (or continue) ``study`` into ``out_dir`` (module docstring); writes
    ``dose_response.json`` after every rung and returns the last
    :class:`DoseResponseResult`. ValueError: a start that is not a reflex set, a folder of
    another study."""
    from afo_mj.gait import reflex_law as rl
    protocol = study.protocol
    start_params = load_reflex_set(study.start)
    start_set = dict(zip(rl.PARAM_NAMES, start_params.tolist()))
    start_sha = hashlib.sha256(json.dumps(start_set, sort_keys=True).encode()).hexdigest()
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    _check_study(out, study, start_sha)
    rungs = study.rungs()
    prev = [(start_set, str(study.start))] * protocol.restarts
    sham_prev = None
    levels: list[DoseLevel] = []
    res = None
    for k, rung in enumerate(rungs):
        rows, prev = _run_rung(out, rung, prev, protocol, workers, client, progress)
        level = _level(rung, rows, protocol, levels[0] if levels else None)
        if k == 0:
            sham_prev = prev
        elif study.matched_control:
            sham = Rung(f"control{k}", None, f"control, searched on ({k})", rungs[0].objective)
            sham_rows, sham_prev = _run_rung(out, sham, sham_prev, protocol, workers, client,
                                             progress)
            level = _matched(level, sham_rows)
        levels.append(level)
        res = _result(study, start_sha, levels, complete=len(levels) == len(rungs))
        _write_json(out / "dose_response.json", res.to_json())
    return res


def _run_rung(out: Path, rung: Rung, prev: list, protocol, workers, client, progress):
    """One rung's searches (restart ``i`` from ``prev[i]``, ``(set, where from)``) and
    scoring walks; returns its :class:`DoseRestart` rows (changes not yet set) and the
    ``prev`` of the next rung."""
    from afo_mj.gait import reflex_law as rl
    dirs, docs, cpus, froms = [], [], [], []
    for i in range(protocol.restarts):
        if progress is not None:
            progress(f"{rung.label} restart {i}")
        d = out / rung.name / f"restart{i}"
        doc, cpu, began = _search(d, rung, prev[i][0], prev[i][1], protocol, i, workers,
                                  client)
        dirs.append(d)
        docs.append(doc)
        cpus.append(cpu)
        froms.append(began)
    scores = _scores(rung, dirs, docs, protocol, workers, client)
    rows = []
    for i, (d, doc, cpu, began, (s, off)) in enumerate(zip(dirs, docs, cpus, froms, scores)):
        conv, why, change = search_converged(doc["history"], protocol.window,
                                             protocol.cost_tol)
        fell = s["fell_s"]
        rows.append(DoseRestart(
            restart=i, seed=protocol.seed + i, out_dir=str(d), started_from=began,
            generations=int(doc["optimizer"]["generations"]),
            walks=int(doc["optimizer"]["evaluations"]), search_cost=float(doc["cost"]),
            converged=conv, convergence=why, best_cost_change=change,
            net_metabolic_w_per_kg=None if fell is not None else s["net_metabolic_w_per_kg"],
            fell_s=fell, speed_m_s=s.get("speed_m_s"), change_pct=None,
            device_off_w_per_kg=(None if off is None or off["fell_s"] is not None
                                 else off["net_metabolic_w_per_kg"]),
            device_off_fell_s=None if off is None else off["fell_s"],
            device_off_speed_m_s=None if off is None else off.get("speed_m_s"),
            device_off_change_pct=None, matched_control_w_per_kg=None,
            matched_change_pct=None, cpu_s=cpu))
    nxt = [({n: v for n, v in zip(rl.PARAM_NAMES,
                                  load_reflex_set(d / "reflex_params.json").tolist())},
            str(d / "reflex_params.json")) for d in dirs]
    return rows, nxt


def _matched(level: DoseLevel, sham: list[DoseRestart]) -> DoseLevel:
    """``level`` with each restart's rate set against the matched control's restart of the
    same index (the control searched on for as many rungs), and the band of those
    changes."""
    ctl = [r.net_metabolic_w_per_kg for r in sham]
    ch = paired_changes(ctl, [r.net_metabolic_w_per_kg for r in level.restarts], 0, 0)
    rows = tuple(dataclasses.replace(r, matched_control_w_per_kg=ctl[i],
                                     matched_change_pct=ch["paired"][i])
                 for i, r in enumerate(level.restarts))
    lo, mean, hi = band(ch["paired"])
    return dataclasses.replace(level, restarts=rows, matched_change_pct_min=lo,
                               matched_change_pct_mean=mean, matched_change_pct_max=hi,
                               matched_control_walks=sum(r.walks for r in sham),
                               matched_control_cpu_s=(None if any(r.cpu_s is None for r in sham)
                                                      else float(sum(r.cpu_s for r in sham))))


def _result(study: DoseStudy, start_sha: str, levels: list[DoseLevel], complete: bool
            ) -> DoseResponseResult:
    mono, means, left_out, per_restart = _monotone(levels)
    cpus = [r.cpu_s for lv in levels for r in lv.restarts] + [
        lv.matched_control_cpu_s for lv in levels if lv.matched_control_walks]
    return DoseResponseResult(
        study=study.name, description=study.description, variable=study.variable,
        unit=study.unit, kind=study.kind, assistance=json.loads(json.dumps(study.assistance)),
        protocol=dataclasses.asdict(study.protocol), start=str(study.start),
        start_sha256=start_sha, levels=tuple(levels), complete=complete,
        monotone_within_bands=mono, monotone_means=means, monotone_left_out=tuple(left_out),
        monotone_per_restart=tuple(per_restart),
        monotone_matched_within_bands=_monotone_matched(levels),
        walks=sum(r.walks for lv in levels for r in lv.restarts)
        + sum(lv.matched_control_walks for lv in levels),
        cpu_s=None if any(x is None for x in cpus) else float(sum(cpus)))
