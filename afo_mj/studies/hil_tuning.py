"""Human-in-the-loop tuning in simulation: Zhang et al.'s (2017) experiment with the muscle
walker as the wearer.

Zhang et al. ("Human-in-the-loop optimization of exoskeleton assistance during walking",
*Science* 356:1280, 2017) tuned the four parameters of an ankle exoskeleton's torque profile
(peak torque, peak time, rise time, fall time; :func:`afo_mj.control.assistance.
zhang_profile`) by CMA-ES on each subject's measured metabolic rate while the subject walked
and adapted to every profile tried. Here the subject is the reflex-controlled muscle walker
and its adaptation is a CMA-ES search of its reflex parameters
(:mod:`afo_mj.studies.adaptation`).

**The search.** A wearer that adapts to every profile and a tuner that keeps the best profile
converge, when both minimise one cost, to ``min over profiles of min over reflexes`` of that
cost; one CMA-ES over the joint vector ``x = (z, u)`` minimises the same quantity in one
search (:func:`joint_search`): ``z`` the 29 reflex parameters as log factors on Geyer & Herr's
values (as :func:`~afo_mj.studies.gait_optimization.optimize_gait` searches them), ``u`` the
four profile parameters scaled onto ``[0, 1]`` between their bounds (:class:`ProfileBounds`,
:meth:`ProfileBounds.to_coords`). A coordinate outside its bound is clipped to it for the
walk (the profile walked is always admissible) and the distance outside is penalised
(``BOUND_PENALTY × Σ d²``, d in units of the bound's range: the repair-and-penalise bound
handling of CMA-ES). The profile coordinates get their own initial step, ``profile_sigma``
of the bounds' range (CMA-ES's per-coordinate ``CMA_stds``), the reflex ones ``sigma0``. The
nested alternative (an outer CMA-ES on the profile, each candidate scored after a short
warm-started re-adaptation, as the experiment's subjects re-adapt between updates) costs one
adaptation per profile tried: about 50 times this search's walks for the same number of
profile generations, which this machine does not afford.

**The objective** (the choice, documented): the joint search minimises the wearer's own
cost (:func:`~afo_mj.studies.gait_optimization.gait_cost`: speed held at 1.25 m/s, mean
joint-angle RMS against Winter's kinematics, and the effort term, the net metabolic cost of
transport by Umberger 2010), not the net metabolic rate alone as Zhang et al.'s tuner did.
One search has one objective; were it the metabolic rate alone, the reflexes (the wearer)
would also be searched for the cheapest walk whatever its speed and kinematics, which is not
the wearer the other conditions are. With the speed held, the effort term is the net
metabolic rate divided by the speed, so at unchanged kinematics the profile minimising the
wearer's cost is the one minimising its metabolic rate; where a profile trades kinematics
for effort the wearer's weights decide. The report gives the metabolic rate (the experiment's
outcome) and the kinematic terms, so that a reader sees which moved.

**The protocol** (:func:`tune_zhang`, resumable into one folder): three arms, each with
``restarts`` searches of the same budget (generations × popsize) and seeds (restart ``i``:
``seed + i``), scored by a fresh walk's net metabolic rate as the adaptation protocol scores
(:mod:`afo_mj.studies.adaptation`):

* ``control``: no device, the wearer adapted from ``control_start`` (``OUT/control``);
* ``generic``: the generic profile (default 0.5 N·m/kg at Zhang et al.'s published timing),
  the wearer adapted from ``start`` (``OUT/generic``);
* ``tuned``: the joint search from ``start``'s reflexes and the generic profile
  (``OUT/tuned/restart<i>``).

The tuned arm is compared with the generic one paired by restart (same start, same seed, same
budget: the profile's share), and both with the control. The result is a
:class:`HilTuningResult` (format ``afo_mj hil tuning v1``) written atomically to
``OUT/hil_tuning.json``.

**The HAFO's command profile, with the battery as a second objective**
(``HilProtocol(device="hafo", battery_weights=...)``). The same experiment with the ``hafo``
condition (:mod:`afo_mj.experiments.muscle_assistance`: the pump-driven orthosis, its
circuit stepped with the walk, commanding the Zhang profile): one code path, the device
the only difference. The peak is searched in N·m/kg as for the ideal torque and commanded as
``peak × body mass`` (``hafo_peak_torque_nm``); the generic HAFO profile is the shipped
40 N·m at the published timing (:data:`GENERIC_HAFO`), the start ``adapted/hafo.json``.
Each battery weight ``w`` is its own tuned arm (``OUT/tuned_w<w>``, result
``OUT/hil_tuning_hafo_w<w>.json``), all sharing the control and generic arms; the joint
search then minimises

    wearer's cost + w × E_bat / (m d)

with ``E_bat`` the energy the battery gave up over the scored strides (chemical, net of
what regeneration put back: :func:`~afo_mj.experiments.muscle_assistance.battery_use`), ``m``
the body mass and ``d`` the distance walked over those strides. The term is in the units of
the wearer's effort term (the net metabolic cost of transport, J/(kg·m)), so ``w = 1``
counts a battery joule as a metabolic joule; with the speed held it equals
``w × battery power / (m v)``, the weighted sum ``rate + w × P_bat/m`` (both W/kg) divided by
the speed. Weights scanned (e.g. 0, 0.25, 1) trace the convex part of the front between the
wearer's metabolic rate and the battery energy per stride; a weight other than 0 with the
ideal torque (no battery) is refused by name.

The choice and its known bias: one joint search has one objective, so the reflexes (the
wearer) see the battery term too and may trade a little of their own cost for battery
energy, e.g. by back-driving the pump, which charges the battery (a zero command at 0 N·m
regenerates about 2 J per stride on the shipped HAFO wearer). The nested protocol (an outer
search on the profile, each candidate re-adapted on the wearer's cost alone) has no such bias
but costs an adaptation per candidate, which this machine does not afford. Each tuned restart
therefore reports its best walk's wearer's cost without the battery term beside the search
cost, and every arm's scoring walk its battery energy per stride and mean electrical power.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import math
import pickle
import time
from pathlib import Path
from typing import ClassVar

import numpy as np

from afo_mj.experiments.muscle_assistance import ZHANG_TIMING_PCT, Assistance, battery_use
from afo_mj.metrics.document_base import Document, entry
from afo_mj.studies.adaptation import (AdaptationProtocol, AdaptCondition, ConditionResult,
                                       adapt_conditions, assistance_conditions, paired_changes,
                                       rate_spread, refuse_other_settings, score_walk,
                                       search_converged)
from afo_mj.studies.gait_optimization import (GaitObjective, _write_atomic, evaluate_batch,
                                              gait_cost, load_reflex_set, objective_walk)

__all__ = ["ProfileBounds", "ZhangSetting", "GENERIC", "GENERIC_HAFO", "DEVICES", "HilProtocol",
           "TunedRestart", "HilTuningResult", "joint_vector", "split_joint", "joint_search",
           "joint_cost", "profile_objective", "tune_profile", "tune_zhang", "HIL_FORMAT",
           "BOUND_PENALTY", "ZHANG_2017"]

HIL_FORMAT = "afo_mj hil tuning v1"
#: cost per squared unit (of a bound's range) that a profile coordinate lies outside its bound
BOUND_PENALTY = 100.0
#: the published figure this experiment is set beside, as issue 42 states it: Zhang et al.
#: (2017): net metabolic rate with the human-in-the-loop tuned profile against walking in the
#: device without torque, mean ± SD over the subjects
ZHANG_2017 = {"tuned_change_pct": -24.2, "tuned_change_sd_pct": 7.4,
              "source": "Zhang et al. 2017, Science 356:1280 (as issue 42 states it); their "
                        "generic-profile figure is not quoted here (no source at hand)"}


@dataclasses.dataclass(frozen=True)
class ZhangSetting:
    """One Zhang profile: peak torque per body mass and its timing in % of the stride
    (:func:`~afo_mj.control.assistance.zhang_profile`)."""

    peak_nm_per_kg: float
    peak_time_pct: float
    rise_time_pct: float
    fall_time_pct: float

    def __post_init__(self):
        for f in dataclasses.fields(self):
            v = getattr(self, f.name)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
                raise ValueError(f"ZhangSetting.{f.name} = {v!r}; allowed: a finite number")
        # the profile itself must be admissible (ValueError naming the key otherwise)
        self.assistance(Assistance("zhang"))

    @property
    def values(self) -> np.ndarray:
        return np.array([getattr(self, n) for n in PROFILE_NAMES], float)

    def assistance(self, base: Assistance, body_mass_kg: float | None = None) -> Assistance:
        """``base`` wearing this profile: a ``zhang`` condition (its sides and ramp) gets the
        peak per body mass as it is; a ``hafo`` condition commands ``peak × body_mass_kg``
        (N·m, rounded to 1e-9 N·m so that a round figure stays round in the state keys).
        ValueError for another kind, or a ``hafo`` one without the body mass."""
        timing = (float(self.peak_time_pct), float(self.rise_time_pct),
                  float(self.fall_time_pct))
        if base.kind == "zhang":
            return dataclasses.replace(base, zhang_peak_nm_per_kg=float(self.peak_nm_per_kg),
                                       zhang_timing_pct=timing)
        if base.kind == "hafo" and body_mass_kg is not None:
            return dataclasses.replace(
                base, hafo_peak_torque_nm=round(float(self.peak_nm_per_kg)
                                                * float(body_mass_kg), 9),
                zhang_timing_pct=timing)
        raise ValueError(f"ZhangSetting.assistance: assistance.kind = {base.kind!r} (body "
                         f"mass {body_mass_kg!r}); allowed: 'zhang', or 'hafo' with the "
                         "body mass")


#: the four profile parameters, in the joint vector's order
PROFILE_NAMES = tuple(f.name for f in dataclasses.fields(ZhangSetting))
#: the generic profile: the project's default Zhang torque at the published timing
GENERIC = ZhangSetting(0.5, *ZHANG_TIMING_PCT)
#: the devices whose command profile the experiment tunes: the ideal torque and the HAFO
DEVICES = ("zhang", "hafo")
#: the walker's body mass (kg) the HAFO's generic peak is given per (WalkerParams' default)
_BODY_MASS_KG = 75.0
#: the generic HAFO profile: the shipped 40 N·m (``Assistance.hafo_peak_torque_nm``, the
#: ``adapted/hafo.json`` wearer's device) per the 75 kg walker, at the published timing
GENERIC_HAFO = ZhangSetting(40.0 / _BODY_MASS_KG, *ZHANG_TIMING_PCT)


@dataclasses.dataclass(frozen=True)
class ProfileBounds:
    """The box the tuner searches, ``(low, high)`` per profile parameter. The peak torque is
    capped (default 0.6 N·m/kg, the issue's bound; at most 1.0 N·m/kg, about two thirds of
    the biological ankle moment's peak, is allowed). The timing bounds are chosen so that
    every profile in the box is admissible: onset ``peak − rise ≥ 0`` and end
    ``peak + fall ≤ 100 %`` at every corner."""

    peak_nm_per_kg: tuple = (0.0, 0.6)
    peak_time_pct: tuple = (40.0, 65.0)
    rise_time_pct: tuple = (10.0, 40.0)
    fall_time_pct: tuple = (5.0, 25.0)

    def __post_init__(self):
        limits = {"peak_nm_per_kg": (0.0, 1.0), "peak_time_pct": (0.0, 100.0),
                  "rise_time_pct": (0.1, 100.0), "fall_time_pct": (0.1, 100.0)}
        for name, (lo_ok, hi_ok) in limits.items():
            b = getattr(self, name)
            ok = (not isinstance(b, (str, bytes)) and hasattr(b, "__len__") and len(b) == 2
                  and all(not isinstance(v, bool) and isinstance(v, (int, float))
                          and math.isfinite(v) for v in b))
            if not ok or not lo_ok <= b[0] < b[1] <= hi_ok:
                raise ValueError(f"ProfileBounds.{name} = {b!r}; allowed: (low, high) with "
                                 f"{lo_ok:g} <= low < high <= {hi_ok:g}")
            object.__setattr__(self, name, (float(b[0]), float(b[1])))
        onset = self.peak_time_pct[0] - self.rise_time_pct[1]
        end = self.peak_time_pct[1] + self.fall_time_pct[1]
        if onset < 0.0 or end > 100.0:
            raise ValueError(f"ProfileBounds: earliest onset peak_time_pct low − rise_time_pct "
                             f"high = {onset:g} %, latest end peak_time_pct high + "
                             f"fall_time_pct high = {end:g} %; allowed: both within 0 … 100 % "
                             "(every profile in the box admissible)")

    @property
    def low(self) -> np.ndarray:
        return np.array([getattr(self, n)[0] for n in PROFILE_NAMES], float)

    @property
    def high(self) -> np.ndarray:
        return np.array([getattr(self, n)[1] for n in PROFILE_NAMES], float)

    def contains(self, s: ZhangSetting) -> bool:
        v = s.values
        return bool(np.all(v >= self.low) and np.all(v <= self.high))

    def to_coords(self, s: ZhangSetting) -> np.ndarray:
        """The profile's search coordinates: ``(value − low) / (high − low)``, 0 … 1 inside
        the box."""
        return (s.values - self.low) / (self.high - self.low)

    def from_coords(self, u) -> tuple[ZhangSetting, float]:
        """``(profile, violation)``: the coordinates clipped into ``[0, 1]`` and mapped back;
        ``violation`` the squared distance clipped away (0 inside the box). ValueError for
        a vector not of four finite numbers."""
        u = np.asarray(u, float)
        if u.shape != (len(PROFILE_NAMES),) or not np.all(np.isfinite(u)):
            raise ValueError(f"profile coordinates {u.tolist()!r}; allowed: "
                             f"{len(PROFILE_NAMES)} finite numbers")
        c = np.clip(u, 0.0, 1.0)
        v = self.low + c * (self.high - self.low)
        return ZhangSetting(*map(float, v)), float(np.sum((u - c) ** 2))


def joint_vector(z, u) -> np.ndarray:
    """The joint search vector: the reflex log factors ``z`` then the profile coordinates
    ``u``."""
    from afo_mj.gait import reflex_law as rl
    z, u = np.asarray(z, float), np.asarray(u, float)
    if z.shape != (rl.N_P,) or u.shape != (len(PROFILE_NAMES),):
        raise ValueError(f"joint_vector: z of {z.shape}, u of {u.shape}; allowed: "
                         f"({rl.N_P},) and ({len(PROFILE_NAMES)},)")
    return np.concatenate([z, u])


def split_joint(x, base, bounds: ProfileBounds) -> tuple[np.ndarray, ZhangSetting, float]:
    """``(reflex parameters base × exp(z), profile, bound violation)`` of a joint vector
    (:func:`joint_vector`). ValueError for a vector of another length."""
    from afo_mj.gait import reflex_law as rl
    x = np.asarray(x, float)
    n = rl.N_P + len(PROFILE_NAMES)
    if x.shape != (n,):
        raise ValueError(f"joint vector of shape {x.shape}; allowed: ({n},) "
                         f"({rl.N_P} reflex log factors, then {len(PROFILE_NAMES)} profile "
                         "coordinates)")
    setting, violation = bounds.from_coords(x[rl.N_P:])
    return np.asarray(base, float) * np.exp(x[:rl.N_P]), setting, violation


@dataclasses.dataclass(frozen=True)
class HilProtocol:
    """The tuning experiment's settings: the adaptation protocol every arm runs (restarts,
    generations, popsize, σ0 of the reflex coordinates, seed, convergence window, walks), the
    profile's bounds, the profile coordinates' initial step ``profile_sigma`` (a fraction of
    each bound's range) and the ``generic`` profile (the comparison arm and the tuned arm's
    start)."""

    adaptation: AdaptationProtocol = dataclasses.field(default_factory=AdaptationProtocol)
    bounds: ProfileBounds = dataclasses.field(default_factory=ProfileBounds)
    profile_sigma: float = 0.1
    #: None: :data:`GENERIC` for the ideal torque, :data:`GENERIC_HAFO` for the HAFO
    generic: ZhangSetting | None = None
    #: the device whose profile is tuned (:data:`DEVICES`)
    device: str = "zhang"
    #: the battery weights ``w``, one tuned arm each (module docstring); only ``(0.0,)`` for
    #: the ideal torque, which has no battery
    battery_weights: tuple = (0.0,)

    def __post_init__(self):
        if self.device not in DEVICES:
            raise ValueError(f"HilProtocol.device = {self.device!r}; allowed: "
                             f"{', '.join(DEVICES)}")
        if self.generic is None:
            object.__setattr__(self, "generic",
                               GENERIC if self.device == "zhang" else GENERIC_HAFO)
        if self.adaptation.groups != 1:
            raise ValueError(f"HilProtocol.adaptation.groups = {self.adaptation.groups!r}; "
                             "allowed: 1 (the tuned arms have no groups)")
        w = self.battery_weights
        ok = (not isinstance(w, (str, bytes)) and hasattr(w, "__len__") and len(w) >= 1
              and all(not isinstance(x, bool) and isinstance(x, (int, float))
                      and math.isfinite(x) and 0.0 <= x <= 100.0 for x in w)
              and len(set(float(x) for x in w)) == len(w))
        if not ok:
            raise ValueError(f"HilProtocol.battery_weights = {w!r}; allowed: one or more "
                             "distinct numbers 0 … 100")
        object.__setattr__(self, "battery_weights", tuple(float(x) for x in w))
        if self.device == "zhang" and self.battery_weights != (0.0,):
            raise ValueError(f"HilProtocol.battery_weights = {list(w)!r} with device 'zhang'; "
                             "allowed: [0.0] (the ideal torque source has no battery; "
                             "device 'hafo' takes battery weights)")
        v = self.profile_sigma
        if isinstance(v, bool) or not isinstance(v, (int, float)) \
                or not (math.isfinite(v) and 0.005 <= v <= 1.0):
            raise ValueError(f"HilProtocol.profile_sigma = {v!r}; allowed: 0.005 … 1 (a "
                             "fraction of each bound's range)")
        if not self.bounds.contains(self.generic):
            raise ValueError(f"HilProtocol.generic = {self.generic}; allowed: within the "
                             f"bounds {dataclasses.asdict(self.bounds)}")

    def fixed(self) -> dict:
        """What a resumed experiment must share with the one that started it."""
        a = self.adaptation
        out = {"popsize": a.popsize, "sigma0": a.sigma0, "seed": a.seed,
               "search_walk_s": a.search_walk_s, "settle_s": a.settle_s,
               "tracking_weight": a.tracking_weight, "profile_sigma": float(self.profile_sigma),
               "bounds": {k: list(v) for k, v in dataclasses.asdict(self.bounds).items()},
               "generic": dataclasses.asdict(self.generic)}
        # the ideal torque's keys stay those written before the HAFO was a device (its
        # saved folders resume); the battery weight is each tuned arm's own (its search key)
        if self.device != "zhang":
            out["device"] = self.device
        return out


# --------------------------------------------------------------------------- the search
def with_profile(objective: GaitObjective, setting: ZhangSetting) -> GaitObjective:
    """``objective`` with its device commanding ``setting``."""
    return dataclasses.replace(objective, assistance=setting.assistance(
        objective.assistance, objective.walker.body_mass_kg))


def joint_cost(params, objective: GaitObjective, battery_weight: float = 0.0
               ) -> tuple[float, dict]:
    """The joint search's objective of one walk (module docstring): the wearer's cost
    (:func:`~afo_mj.studies.gait_optimization.gait_cost`) plus, for a ``hafo`` condition
    that walked its scored strides, ``battery_weight × battery_cost_of_transport`` (J/(kg·m),
    :func:`~afo_mj.experiments.muscle_assistance.battery_use` of the same walk). The info
    carries ``wearer_cost`` (without the battery term) and, for the HAFO, the battery figures.
    ValueError for a weight other than 0 with a device that has no battery."""
    hafo = objective.assistance.kind == "hafo" and objective.scenario is None
    if battery_weight != 0.0 and not hafo:
        raise ValueError(f"joint_cost: battery_weight = {battery_weight!r} with assistance.kind "
                         f"= {objective.assistance.kind!r}; allowed: 0 (only 'hafo' has a "
                         "battery)")
    try:
        walk, dev = objective_walk(objective, params)
    except FloatingPointError as exc:
        return 2000.0, {"error": str(exc)}
    cost, info = gait_cost(params, objective, walk=walk)
    info = dict(info, wearer_cost=cost)
    if hafo and "speed_m_s" in info:
        bat = battery_use(walk, dev, objective.settle_s)
        if bat is not None:
            info.update(bat)
            cot = bat["battery_cost_of_transport_j_per_kg_m"]
            cost += battery_weight * (cot if math.isfinite(cot) else 100.0)
    return cost, info


def _evaluate_joint(packed):
    x, base, objective, bounds, weight = packed
    params, setting, violation = split_joint(x, base, bounds)
    cost, info = joint_cost(params, with_profile(objective, setting), weight)
    return cost + BOUND_PENALTY * violation, dict(info, profile=dataclasses.asdict(setting),
                                                  bound_violation=violation)


def _sha(params: np.ndarray) -> str:
    from afo_mj.gait import reflex_law as rl
    named = dict(zip(rl.PARAM_NAMES, np.asarray(params, float).tolist()))
    return hashlib.sha256(json.dumps(named, sort_keys=True).encode()).hexdigest()


def joint_search(out_dir, objective: GaitObjective, start_params, protocol: HilProtocol,
                 seed: int, workers: int | None = None, client=None, progress=None,
                 battery_weight: float = 0.0) -> dict:
    """CMA-ES over the joint vector (module docstring) from ``start_params`` (the reflexes)
    and ``protocol.generic`` (the profile), for ``protocol.adaptation.generations`` of
    ``popsize`` walks of ``objective`` (a condition of ``protocol.device``: its profile is
    replaced by each candidate's), on :func:`joint_cost` with ``battery_weight``. Resumable:
    the state is written atomically to ``out_dir/cma_state.pkl`` after every generation and
    a run with the same folder continues (ValueError for a folder of another objective,
    start, settings or battery weight). Writes ``out_dir/reflex_params.json`` (the best
    reflex set by name, readable by :func:`~afo_mj.gait.muscle_walk.load_reflex_set`, with
    its ``profile``) and returns its content."""
    import cma

    from afo_mj.gait import reflex_law as rl
    from afo_mj.gait.muscle_walk import reflex_params
    if objective.assistance.kind != protocol.device or objective.scenario is not None:
        raise ValueError(f"joint_search: objective.assistance.kind = "
                         f"{objective.assistance.kind!r}; allowed: {protocol.device!r} "
                         "(protocol.device, no scenario)")
    if battery_weight not in protocol.battery_weights:
        raise ValueError(f"joint_search: battery_weight = {battery_weight!r}; allowed: one of "
                         f"protocol.battery_weights {list(protocol.battery_weights)}")
    p = protocol.adaptation
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    base = reflex_params()
    start_params = np.asarray(start_params, float)
    key = {"objective": repr(objective), "start_sha256": _sha(start_params),
           "seed": int(seed), **protocol.fixed()}
    if protocol.device != "zhang":
        key["battery_weight"] = float(battery_weight)
    key = json.dumps(key, sort_keys=True)
    state_file = out / "cma_state.pkl"
    if state_file.exists():
        saved = pickle.loads(state_file.read_bytes())
        if saved.get("key") != key:
            raise ValueError(f"{out} holds a joint search of other settings ({saved.get('key')}"
                             f"); given {key}; allowed: the same (or another folder)")
        es = pickle.loads(saved["es"])
        best, best_info, history, wall_s = (saved["best"], saved["best_info"],
                                            saved["history"], saved["wall_s"])
    else:
        x0 = joint_vector(np.log(start_params / base), protocol.bounds.to_coords(
            protocol.generic))
        stds = np.ones(len(x0))
        stds[rl.N_P:] = protocol.profile_sigma / p.sigma0
        es = cma.CMAEvolutionStrategy(x0, p.sigma0, {"seed": int(seed), "verbose": -9,
                                                     "popsize": int(p.popsize),
                                                     "CMA_stds": stds.tolist()})
        best, best_info, history, wall_s = (math.inf, None), {}, [], 0.0
    t0, total_s = time.perf_counter(), wall_s
    while es.countiter < p.generations and not es.stop():
        X = es.ask()
        res = evaluate_batch(_evaluate_joint, [(x, base, objective, protocol.bounds,
                                                battery_weight) for x in X], workers, client)
        costs = [r.value[0] if r.ok else 3000.0 for r in res]
        es.tell(X, costs)
        i = int(np.argmin(costs))
        if costs[i] < best[0]:
            best = (float(costs[i]), np.asarray(X[i]).tolist())
            best_info = res[i].value[1] if res[i].ok else {}
        total_s = wall_s + time.perf_counter() - t0
        history.append({"generation": es.countiter, "best": best[0],
                        "generation_best": float(costs[i]), "evaluations": es.countevals,
                        "mean_profile": dataclasses.asdict(
                            protocol.bounds.from_coords(es.mean[rl.N_P:])[0])})
        _write_atomic(state_file, pickle.dumps({"key": key, "es": es.pickle_dumps(),
                                                "best": best, "best_info": best_info,
                                                "history": history, "wall_s": total_s}))
        if progress is not None:
            progress(es.countiter, p.generations, best[0])
    params, setting, violation = split_joint(best[1], base, protocol.bounds)
    doc = {"format": "afo_mj reflex parameters v1",
           "model": "Geyer & Herr 2010 reflex controller, 14 Hill-type MTUs",
           "parameters": dict(zip(rl.PARAM_NAMES, params.tolist())),
           "profile": dataclasses.asdict(setting), "bound_violation": violation,
           "cost": best[0], "quality": best_info,
           "assistance": dataclasses.asdict(with_profile(objective, setting).assistance),
           "battery_weight": float(battery_weight),
           "optimizer": {"method": "CMA-ES (joint: reflexes and profile)", "seed": int(seed),
                         "sigma0": p.sigma0, "profile_sigma": protocol.profile_sigma,
                         "generations": es.countiter, "evaluations": es.countevals,
                         "popsize": es.popsize},
           "history": history, "wall_s": total_s}
    _write_atomic(out / "reflex_params.json", json.dumps(doc, indent=1).encode())
    return doc


# --------------------------------------------------------------------------- documents
@dataclasses.dataclass(frozen=True)
class TunedRestart(Document):
    """One restart of the tuned arm: its joint search, the profile it found and its scoring
    walk."""

    restart: int = entry("int", "restart index (0 first)")
    seed: int = entry("int", "CMA-ES seed (protocol seed + restart)")
    out_dir: str = entry("str", "the search's resumable folder")
    generations: int = entry("int", "generations searched")
    walks: int = entry("int", "walks the search evaluated")
    search_cost: float = entry("number", "best objective value found (the wearer's cost)")
    converged: bool = entry("bool", "the best cost stopped moving (the window's test)")
    convergence: str = entry("str", "why converged or not")
    peak_nm_per_kg: float = entry("number", "tuned peak torque per body mass", "N·m/kg")
    peak_time_pct: float = entry("number", "tuned peak time", "% of stride")
    rise_time_pct: float = entry("number", "tuned rise time", "% of stride")
    fall_time_pct: float = entry("number", "tuned fall time", "% of stride")
    net_metabolic_w_per_kg: float | None = entry(
        "number?", "net metabolic rate of the scoring walk, Umberger 2010 (null: it fell)",
        "W/kg")
    fell_s: float | None = entry("number?", "time of the scoring walk's fall (null: none)",
                                 "s")
    speed_m_s: float | None = entry("number?", "speed of the scoring walk", "m/s")
    angle_rms_deg: float | None = entry("number?", "the search's best walk: mean hip, knee "
                                        "and ankle angle RMS against Winter's", "deg")
    wall_s: float = entry("number", "the search's wall time over all its runs", "s")
    cpu_s: float | None = entry("number?", "CPU time of the search measured by this "
                                "experiment's runs (null: not all of it)", "s")
    wearer_cost: float | None = entry(
        "number?", "HAFO only: the search's best walk's wearer's cost without the battery "
        "term", omit_none=True, default=None)
    battery_j_per_stride: float | None = entry(
        "number?", "HAFO only: battery energy per stride of the scoring walk (chemical, net "
        "of regeneration; null: it fell)", "J", omit_none=True, default=None)
    electrical_power_w: float | None = entry(
        "number?", "HAFO only: that energy per second of the scored strides", "W",
        omit_none=True, default=None)


@dataclasses.dataclass(frozen=True)
class HilTuningResult(Document):
    """``hil_tuning.json``: the in-silico human-in-the-loop tuning experiment
    (:mod:`afo_mj.studies.hil_tuning`)."""

    FORMAT: ClassVar[str] = HIL_FORMAT
    TITLE: ClassVar[str] = "Human-in-the-loop tuning of the Zhang profile, in simulation"

    protocol: dict = entry("object", "HilProtocol's settings (adaptation protocol, bounds, "
                           "profile step, generic profile)")
    objective: str = entry("str", "what the searches minimise and how the tuned profile is "
                           "judged")
    control_start: str = entry("str", "reflex set the control arm starts from")
    start: str = entry("str", "reflex set the generic and tuned arms start from")
    control: ConditionResult = entry(ConditionResult, "the control arm (no device)",
                                     tagged=False)
    generic: ConditionResult = entry(ConditionResult, "the generic profile's arm",
                                     tagged=False)
    tuned: tuple = entry("list", "the tuned arm's restarts", list_of=TunedRestart,
                         tagged=False)
    tuned_best_restart: int = entry("int", "the tuned wearer: the restart of the lowest "
                                    "search cost")
    tuned_net_metabolic_w_per_kg: float | None = entry("number?", "the tuned wearer's net "
                                                       "metabolic rate", "W/kg")
    tuned_spread_pct: float | None = entry("number?", "tuned restarts' rates, max − min, in "
                                           "% of their mean", "%")
    tuned_converged: bool = entry("bool", "every tuned restart converged and walks")
    tuned_vs_generic: dict = entry("object", "change of the rate, tuned against generic "
                                   "(paired by restart, mean, spread in points, best vs "
                                   "best, range over every pairing), %")
    tuned_vs_control: dict = entry("object", "the same, tuned against the control, %")
    generic_vs_control: dict = entry("object", "the same, generic against the control, %")
    published: dict = entry("object", "the published figures set beside these")
    walks: int = entry("int", "walks of every search")
    cpu_s: float | None = entry("number?", "CPU time of every search measured here (null: "
                                "some not measured)", "s")
    device: str | None = entry("str?", "the device whose profile is tuned, 'hafo' (absent: "
                               "the ideal Zhang torque)", omit_none=True, default=None)
    battery: dict | None = entry(
        "object?", "HAFO only: the battery weight w and term, and per arm (generic, tuned) "
        "the scoring walks' battery energy per stride (J) and mean electrical power (W) by "
        "restart, the wearer's and the spread (max − min)", omit_none=True, default=None)


OBJECTIVE_TEXT = (
    "every arm's search minimises the wearer's cost (gait_cost: speed at 1.25 m/s, mean "
    "joint-angle RMS vs Winter, net metabolic cost of transport by Umberger 2010); the tuned "
    "arm searches the reflexes and the four profile parameters jointly on that cost; arms are "
    "judged by a fresh walk's net metabolic rate (Umberger 2010, W/kg)")
#: what the HAFO's battery term is (module docstring)
BATTERY_TERM_TEXT = (
    "w × battery energy over the scored strides (chemical, net of regeneration) / (body mass "
    "× distance walked), J/(kg·m), added to the wearer's cost: w = 1 counts a battery joule "
    "as a metabolic joule")
BATTERY_OBJECTIVE_TEXT = (
    "; device: the HAFO (hafo_gait) commanding the profile, peak N·m/kg × body mass; the "
    "tuned arm's joint search adds " + BATTERY_TERM_TEXT + " (the reflexes see it too)")


# --------------------------------------------------------------------------- the protocol
def _cpu_s() -> float:
    import resource
    s, c = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN)
    return s.ru_utime + s.ru_stime + c.ru_utime + c.ru_stime


def _check_folder(out: Path, protocol: HilProtocol, starts: dict) -> None:
    path = out / "hil_protocol.json"
    fixed = dict(protocol.fixed(), **starts)
    if path.exists():
        refuse_other_settings(out, json.loads(path.read_text(encoding="utf-8")), fixed,
                              "an experiment")
    _write_atomic(path, json.dumps(fixed, indent=1).encode())


def profile_objective(protocol: HilProtocol) -> GaitObjective:
    """The generic arm's (and the tuned arms' starting) objective: the generic profile on
    ``protocol.device`` (the ideal torque on both ankles ramped on over 3 strides as the
    shipped adapted Zhang wearer was; the HAFO on the right ankle as the shipped HAFO
    wearer), the adaptation protocol's walk and weights."""
    a = protocol.adaptation
    base = GaitObjective(assistance=Assistance("zhang", ramp_strides=3)
                         if protocol.device == "zhang" else Assistance("hafo"),
                         duration_s=float(a.search_walk_s), settle_s=float(a.settle_s),
                         tracking_weight=float(a.tracking_weight))
    return with_profile(base, protocol.generic)


def zhang_objective(protocol: HilProtocol) -> GaitObjective:
    """:func:`profile_objective` (its former name, when the ideal torque was the only
    device)."""
    return profile_objective(protocol)


def _tuned_dir(out: Path, protocol: HilProtocol, weight: float) -> Path:
    return out / ("tuned" if protocol.device == "zhang" else f"tuned_w{weight:g}")


def _result_path(out: Path, protocol: HilProtocol, weight: float) -> Path:
    return out / ("hil_tuning.json" if protocol.device == "zhang"
                  else f"hil_tuning_hafo_w{weight:g}.json")


def _score_with_battery(item):
    """:func:`~afo_mj.studies.adaptation.score_walk` and, for a HAFO walk that did not fall,
    the battery figures of the same walk (:func:`~afo_mj.experiments.muscle_assistance.
    battery_use`)."""
    objective, params, walk_s, settle_s = item
    out = score_walk(item)
    if objective.assistance.kind == "hafo" and out["fell_s"] is None:
        try:
            walk, dev = objective_walk(objective, params, walk_s)
        except FloatingPointError as exc:
            return {"fell_s": 0.0, "error": str(exc)}
        out.update(battery_use(walk, dev, settle_s) or {})
    return out


def _spread(values):
    v = [x for x in values if x is not None]
    return None if len(v) != len(values) or len(v) < 2 else float(max(v) - min(v))


def tune_profile(out_dir, protocol: HilProtocol | None = None, control_start=None,
                 start=None, workers: int | None = None, client=None, progress=None
                 ) -> tuple:
    """Run (or continue) the experiment (module docstring) into ``out_dir``, restart by
    restart across the arms (a run stopped early leaves pairs): the control, the generic
    profile and one tuned arm per battery weight; returns one :class:`HilTuningResult` per
    weight, each written to ``out_dir`` (``hil_tuning.json`` for the ideal torque,
    ``hil_tuning_hafo_w<w>.json`` for the HAFO). ``control_start`` / ``start``: reflex sets
    (default the shipped ``adapted/none.json`` and ``adapted/zhang.json`` or
    ``adapted/hafo.json``). ValueError: a folder of other settings or starts, a start that
    is not a reflex set."""
    data = Path(__file__).resolve().parents[1] / "data" / "adapted"
    protocol = protocol or HilProtocol()
    control_start = str(control_start or data / "none.json")
    start = str(start or data / f"{protocol.device}.json")
    start_params = load_reflex_set(start)
    starts = {"control_start_sha256": _sha(load_reflex_set(control_start)),
              "start_sha256": _sha(start_params)}
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    _check_folder(out, protocol, starts)
    a = protocol.adaptation
    control_cond = assistance_conditions(["none"], a)
    objective = profile_objective(protocol)
    generic_cond = [AdaptCondition(protocol.device, objective.assistance.label, objective)]
    say = progress or (lambda text: None)
    weights = protocol.battery_weights
    searches = {w: [] for w in weights}
    for i in range(a.restarts):
        sub = dataclasses.replace(a, restarts=i + 1)
        control = adapt_conditions(out / "control", control_cond, control_start, sub, workers,
                                   client, say)
        generic = adapt_conditions(out / "generic", generic_cond, start, sub, workers, client,
                                   say)
        for w in weights:
            d = _tuned_dir(out, protocol, w) / f"restart{i}"
            say(f"tuned restart {i}" + ("" if protocol.device == "zhang"
                                        else f", battery weight {w:g}"))
            cost_file = d / "hil_cpu.json"
            known = not (d / "cma_state.pkl").exists() or cost_file.exists()
            prior = (json.loads(cost_file.read_text(encoding="utf-8"))["cpu_s"]
                     if cost_file.exists() else 0.0)
            t0 = _cpu_s()
            doc = joint_search(d, objective, start_params, protocol, a.seed + i, workers,
                               client, battery_weight=w)
            cpu = None
            if known and client is None:
                cpu = prior + _cpu_s() - t0
                _write_atomic(cost_file, json.dumps({"cpu_s": cpu}).encode())
            searches[w].append((d, doc, cpu))
    hafo = protocol.device == "hafo"
    c_arm, g_arm = control.conditions[0], generic.conditions[0]
    # every tuned restart's scoring walk, and for the HAFO the generic restarts' again (the
    # adaptation's scoring walk keeps no battery figures; the walk is the same)
    items, keys = [], []
    for w in weights:
        for i, (d, doc, _) in enumerate(searches[w]):
            items.append((with_profile(objective, ZhangSetting(**doc["profile"])),
                          load_reflex_set(d / "reflex_params.json"), a.score_walk_s,
                          a.settle_s))
            keys.append((w, i))
    if hafo:
        for r in g_arm.restarts:
            items.append((objective, load_reflex_set(Path(r.out_dir) / "reflex_params.json"),
                          a.score_walk_s, a.settle_s))
            keys.append(("generic", r.restart))
    scored = dict(zip(keys, evaluate_batch(_score_with_battery, items, workers, client)))
    for k, r in scored.items():
        if not r.ok:
            raise RuntimeError(f"scoring walk of {k[0]} restart {k[1]}: {r.error}")
    c_rates = [r.net_metabolic_w_per_kg for r in c_arm.restarts]
    g_rates = [r.net_metabolic_w_per_kg for r in g_arm.restarts]
    g_bat = [scored[("generic", r.restart)].value for r in g_arm.restarts] if hafo else []
    results = []
    for w in weights:
        rows = []
        for i, (d, doc, cpu) in enumerate(searches[w]):
            s = scored[(w, i)].value
            walked = s["fell_s"] is None
            conv, why, _change = search_converged(doc["history"], a.window, a.cost_tol)
            q = doc.get("quality") or {}
            rms = q.get("angle_rms_deg")
            rows.append(TunedRestart(
                restart=i, seed=a.seed + i, out_dir=str(d),
                generations=int(doc["optimizer"]["generations"]),
                walks=int(doc["optimizer"]["evaluations"]), search_cost=float(doc["cost"]),
                converged=conv, convergence=why, **doc["profile"],
                net_metabolic_w_per_kg=s["net_metabolic_w_per_kg"] if walked else None,
                fell_s=s["fell_s"], speed_m_s=s.get("speed_m_s"),
                angle_rms_deg=float(np.mean(list(rms.values()))) if rms else None,
                wall_s=float(doc["wall_s"]), cpu_s=cpu,
                wearer_cost=q.get("wearer_cost") if hafo else None,
                battery_j_per_stride=s.get("battery_j_per_stride") if hafo else None,
                electrical_power_w=s.get("electrical_power_w") if hafo else None))
        t_rates = [r.net_metabolic_w_per_kg for r in rows]
        t_best = int(np.argmin([r.search_cost for r in rows]))
        _spread_w, t_spread_pct = rate_spread(t_rates)
        cpus = ([r.cpu_s for r in c_arm.restarts] + [r.cpu_s for r in g_arm.restarts]
                + [r.cpu_s for r in rows])
        battery = None
        if hafo:
            g_j = [b.get("battery_j_per_stride") for b in g_bat]
            g_p = [b.get("electrical_power_w") for b in g_bat]
            t_j = [r.battery_j_per_stride for r in rows]
            t_p = [r.electrical_power_w for r in rows]
            battery = {
                "weight": w, "term": BATTERY_TERM_TEXT,
                "generic_j_per_stride": g_j, "generic_power_w": g_p,
                "generic_best_j_per_stride": g_j[g_arm.best_restart],
                "generic_best_power_w": g_p[g_arm.best_restart],
                "generic_spread_j_per_stride": _spread(g_j),
                "tuned_j_per_stride": t_j, "tuned_power_w": t_p,
                "tuned_best_j_per_stride": t_j[t_best], "tuned_best_power_w": t_p[t_best],
                "tuned_spread_j_per_stride": _spread(t_j),
                "tuned_wearer_cost": [r.wearer_cost for r in rows]}
        res = HilTuningResult(
            protocol={"adaptation": dataclasses.asdict(a),
                      **{k: v for k, v in protocol.fixed().items()
                         if k in ("profile_sigma", "bounds", "generic")}},
            objective=OBJECTIVE_TEXT if not hafo else OBJECTIVE_TEXT + BATTERY_OBJECTIVE_TEXT,
            control_start=control_start, start=start,
            control=c_arm, generic=g_arm, tuned=tuple(rows), tuned_best_restart=t_best,
            tuned_net_metabolic_w_per_kg=t_rates[t_best], tuned_spread_pct=t_spread_pct,
            tuned_converged=all(r.converged and r.net_metabolic_w_per_kg is not None
                                for r in rows),
            tuned_vs_generic=paired_changes(g_rates, t_rates, g_arm.best_restart, t_best),
            tuned_vs_control=paired_changes(c_rates, t_rates, c_arm.best_restart, t_best),
            generic_vs_control=paired_changes(c_rates, g_rates, c_arm.best_restart,
                                              g_arm.best_restart),
            published=dict(ZHANG_2017),
            walks=sum(r.walks for r in c_arm.restarts) + sum(r.walks for r in g_arm.restarts)
            + sum(r.walks for r in rows),
            cpu_s=None if any(x is None for x in cpus) else float(sum(cpus)),
            device="hafo" if hafo else None, battery=battery)
        _write_atomic(_result_path(out, protocol, w),
                      json.dumps(res.to_json(), indent=1).encode())
        results.append(res)
    return tuple(results)


def tune_zhang(out_dir, protocol: HilProtocol | None = None, control_start=None, start=None,
               workers: int | None = None, client=None, progress=None) -> HilTuningResult:
    """:func:`tune_profile` of the ideal Zhang torque (its one tuned arm's result).
    ValueError for a protocol of another device."""
    protocol = protocol or HilProtocol()
    if protocol.device != "zhang":
        raise ValueError(f"tune_zhang: protocol.device = {protocol.device!r}; allowed: 'zhang' "
                         "(tune_profile runs the HAFO)")
    return tune_profile(out_dir, protocol, control_start, start, workers, client,
                        progress)[0]
