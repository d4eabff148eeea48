"""Parameter studies: the study file, its parameters and its design (the points to run).

A study file (TOML) names a base scenario, the scenario values to vary by their dotted keys
(anything ``afo-mj run --set`` accepts: ``assistance.peak_torque_nm``,
``device.params.hose.bore_m``, ``walker.body_mass_kg``, ...), their ranges or levels, and a
design::

    name = "hafo_peak_torque_timing"
    description = "..."
    scenario = "../gait_assist_hafo.toml"      # relative to the study file
    set = ["gait.strides=6", "gait.analyse_strides=[3, 6]"]   # fixed for every run

    [design]
    kind = "grid"            # grid | random | lhs | sobol | saltelli | morris
    samples = 16             # random / lhs / sobol: points; saltelli: N (N(2D+2) runs);
                             # morris: trajectories (r(D+1) runs)
    seed = 0

    [[parameter]]
    key = "assistance.peak_torque_nm"
    levels = [20.0, 30.0, 40.0]              # explicit values (any design: grid uses them)
    [[parameter]]
    key = "assistance.peak_time_pct"
    range = [48.0, 56.0]                     # bounds (continuous designs)
    points = 3                               # grid points over the range
    scale = "linear"                         # or "log"

    [output]
    format = "parquet"       # or "csv"

Designs: the full factorial grid; uniform random; Latin hypercube (McKay, Beckman & Conover
1979) and scrambled Sobol' points (Sobol' 1967; Owen scrambling) from :mod:`scipy.stats.qmc`;
Saltelli's sampling for Sobol' sensitivity indices (Saltelli 2002, Saltelli et al. 2010) and
Morris elementary-effect trajectories (Morris 1991; Campolongo et al. 2007) from SALib, which
``afo-mj study`` then analyses. Levels of a parameter in a continuous design are sampled as a
categorical choice (uniform over the levels).

Every point has a ``run_id``: a hash of the base scenario's text, the fixed overrides and the
point's values, so that a resumed sweep recognises the runs it already has whatever order
they are scheduled in.
"""

from __future__ import annotations

import dataclasses
import hashlib
import itertools
import json
import math
import tomllib
from pathlib import Path
from typing import Any

import numpy as np

from afo_mj.hydraulics.params import ParameterError

__all__ = ["StudyParameter", "Study", "StudyError", "load_study", "parse_study", "DESIGNS"]

DESIGNS = ("grid", "random", "lhs", "sobol", "saltelli", "morris")
_TOP_KEYS = ("name", "description", "scenario", "set", "design", "parameter", "output",
             "optimize")
_PARAM_KEYS = ("key", "levels", "range", "points", "scale", "integer")
_DESIGN_KEYS = ("kind", "samples", "seed", "levels")
_OUTPUT_KEYS = ("format",)


class StudyError(ParameterError):
    """An invalid study file (the message names the key, the value and what is allowed)."""


@dataclasses.dataclass(frozen=True)
class StudyParameter:
    """One varied scenario value: explicit ``levels``, or a ``range`` (lo, hi) with ``points``
    for a grid and a ``scale`` (linear or log)."""

    key: str
    levels: tuple[float | int | str | bool, ...] = ()
    lo: float | None = None
    hi: float | None = None
    points: int = 3
    scale: str = "linear"
    integer: bool = False

    @property
    def continuous(self) -> bool:
        return not self.levels

    def grid_values(self) -> list:
        if self.levels:
            return list(self.levels)
        if self.scale == "log":
            v = np.geomspace(self.lo, self.hi, self.points)
        else:
            v = np.linspace(self.lo, self.hi, self.points)
        return [self._cast(x) for x in v]

    def from_unit(self, u: float):
        """The value at ``u ∈ [0, 1)`` of the unit interval (continuous designs)."""
        if self.levels:
            k = min(int(u * len(self.levels)), len(self.levels) - 1)
            return self.levels[k]
        if self.scale == "log":
            x = math.exp(math.log(self.lo) + u * (math.log(self.hi) - math.log(self.lo)))
        else:
            x = self.lo + u * (self.hi - self.lo)
        return self._cast(x)

    def _cast(self, x):
        return int(round(float(x))) if self.integer else float(x)

    def bounds(self) -> tuple[float, float]:
        """Bounds for SALib and the optimiser (levels: their index range)."""
        if self.levels:
            return 0.0, float(len(self.levels))
        return float(self.lo), float(self.hi)


@dataclasses.dataclass(frozen=True)
class Study:
    """A validated study: base scenario, fixed overrides, parameters, design, output format."""

    name: str
    description: str
    scenario_path: Path
    fixed: tuple[str, ...]
    parameters: tuple[StudyParameter, ...]
    design: str
    samples: int
    seed: int
    output_format: str
    optimize: dict
    source_path: Path | None = None

    def scenario_text(self) -> str:
        return self.scenario_path.read_text(encoding="utf-8")

    def points(self) -> list[dict[str, Any]]:
        """The design's points: dicts key → value, in run order."""
        P = self.parameters
        d = len(P)
        if self.design == "grid":
            return [dict(zip([p.key for p in P], combo))
                    for combo in itertools.product(*[p.grid_values() for p in P])]
        if self.design in ("random", "lhs", "sobol"):
            u = _unit_samples(self.design, d, self.samples, self.seed)
            return [{p.key: p.from_unit(float(u[i, j])) for j, p in enumerate(P)}
                    for i in range(len(u))]
        problem = self.salib_problem()
        if self.design == "saltelli":
            from SALib.sample import sobol as salib_sobol
            x = salib_sobol.sample(problem, self.samples, calc_second_order=False,
                                   seed=self.seed)
        else:
            from SALib.sample import morris as salib_morris
            x = salib_morris.sample(problem, self.samples, num_levels=4, seed=self.seed)
        out = []
        for row in x:
            pt = {}
            for j, p in enumerate(P):
                lo, hi = p.bounds()
                pt[p.key] = p.from_unit(min(max((row[j] - lo) / (hi - lo), 0.0), 1.0 - 1e-12))
            out.append(pt)
        return out

    def salib_problem(self) -> dict:
        """The SALib problem dict (names, bounds) of the parameters."""
        return {"num_vars": len(self.parameters),
                "names": [p.key for p in self.parameters],
                "bounds": [list(p.bounds()) for p in self.parameters]}

    def overrides(self, point: dict[str, Any]) -> list[str]:
        """``--set`` strings for a point (fixed overrides first)."""
        return list(self.fixed) + [f"{k}={_toml_value(v)}" for k, v in point.items()]

    def run_id(self, point: dict[str, Any]) -> str:
        """A stable id of a run: hash of the base scenario, fixed overrides and the point."""
        h = hashlib.sha256()
        h.update(self.scenario_text().encode())
        h.update(json.dumps([list(self.fixed), sorted((k, repr(v)) for k, v in point.items())]
                            ).encode())
        return h.hexdigest()[:16]

    def as_dict(self) -> dict:
        return {"name": self.name, "description": self.description,
                "scenario": str(self.scenario_path), "set": list(self.fixed),
                "design": {"kind": self.design, "samples": self.samples, "seed": self.seed},
                "parameters": [{"key": p.key, "levels": list(p.levels), "lo": p.lo, "hi": p.hi,
                                "points": p.points, "scale": p.scale, "integer": p.integer}
                               for p in self.parameters],
                "output": {"format": self.output_format}, "optimize": self.optimize,
                "salib_problem": self.salib_problem()}


def _unit_samples(kind: str, d: int, n: int, seed: int) -> np.ndarray:
    from scipy.stats import qmc
    if kind == "random":
        return np.random.default_rng(seed).random((n, d))
    if kind == "lhs":
        return qmc.LatinHypercube(d=d, seed=seed).random(n)
    return qmc.Sobol(d=d, scramble=True, seed=seed).random(n)


def _toml_value(v) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, (int, float)):
        return repr(v)
    if isinstance(v, str):
        return json.dumps(v)
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    raise StudyError(f"value {v!r}: allowed numbers, booleans, strings or lists of them")


def _fail(origin, key, value, allowed) -> StudyError:
    return StudyError(f"{origin}: {key} = {value!r}; allowed: {allowed}")


def parse_study(text: str, origin: str = "<study>", base_dir: Path | None = None,
                source_path: Path | None = None) -> Study:
    try:
        doc = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise StudyError(f"{origin}: not valid TOML ({exc})") from None
    if "dose_response" in doc:
        raise StudyError(f"{origin}: a [dose_response] study (the adapted wearer against a "
                         "dose); allowed here: a sweep or optimisation study; run it with "
                         "afo-mj dose-response")
    for k in doc:
        if k not in _TOP_KEYS:
            raise _fail(origin, k, doc[k], f"the keys {', '.join(_TOP_KEYS)}")
    base_dir = base_dir or Path.cwd()
    name = doc.get("name", source_path.stem if source_path else "study")
    if not isinstance(name, str) or not name:
        raise _fail(origin, "name", name, "a non-empty string")
    scen = doc.get("scenario")
    if not isinstance(scen, str):
        raise _fail(origin, "scenario", scen, "the path of the base scenario (TOML)")
    spath = (base_dir / scen).resolve()
    if not spath.is_file():
        raise _fail(origin, "scenario", scen, f"an existing scenario file (looked for {spath})")
    fixed = doc.get("set", [])
    if not (isinstance(fixed, list) and all(isinstance(x, str) and "=" in x for x in fixed)):
        raise _fail(origin, "set", fixed, 'a list of "dotted.key=value" strings')
    des = doc.get("design", {})
    if not isinstance(des, dict):
        raise _fail(origin, "design", des, "a table")
    for k in des:
        if k not in _DESIGN_KEYS:
            raise _fail(origin, f"design.{k}", des[k], f"the keys {', '.join(_DESIGN_KEYS)}")
    kind = des.get("kind", "grid")
    if kind not in DESIGNS:
        raise _fail(origin, "design.kind", kind, ", ".join(DESIGNS))
    samples = des.get("samples", 16)
    if not (isinstance(samples, int) and not isinstance(samples, bool) and 1 <= samples <= 100000):
        raise _fail(origin, "design.samples", samples, "an integer 1 … 100000")
    seed = des.get("seed", 0)
    if not (isinstance(seed, int) and not isinstance(seed, bool) and seed >= 0):
        raise _fail(origin, "design.seed", seed, "an integer >= 0")
    raw = doc.get("parameter", [])
    if not isinstance(raw, list) or not raw:
        raise _fail(origin, "parameter", raw, "one or more [[parameter]] tables")
    params = []
    for i, p in enumerate(raw):
        where = f"parameter[{i}]"
        if not isinstance(p, dict):
            raise _fail(origin, where, p, "a table")
        for k in p:
            if k not in _PARAM_KEYS:
                raise _fail(origin, f"{where}.{k}", p[k], f"the keys {', '.join(_PARAM_KEYS)}")
        key = p.get("key")
        if not (isinstance(key, str) and key and "=" not in key):
            raise _fail(origin, f"{where}.key", key, "a dotted scenario key, e.g. "
                        "assistance.peak_torque_nm")
        if any(q.key == key for q in params):
            raise _fail(origin, f"{where}.key", key, "each key once")
        levels = p.get("levels")
        rng = p.get("range")
        if (levels is None) == (rng is None):
            raise _fail(origin, f"{where} ({key})", p, "exactly one of levels = [...] or "
                        "range = [lo, hi]")
        scale = p.get("scale", "linear")
        if scale not in ("linear", "log"):
            raise _fail(origin, f"{where}.scale", scale, "linear, log")
        integer = bool(p.get("integer", False))
        points = p.get("points", 3)
        if not (isinstance(points, int) and 1 <= points <= 1000):
            raise _fail(origin, f"{where}.points", points, "an integer 1 … 1000")
        if levels is not None:
            if not (isinstance(levels, list) and levels):
                raise _fail(origin, f"{where}.levels", levels, "a non-empty list")
            params.append(StudyParameter(key, tuple(levels), points=len(levels),
                                         integer=integer))
            continue
        if not (isinstance(rng, list) and len(rng) == 2
                and all(isinstance(x, (int, float)) and not isinstance(x, bool) for x in rng)
                and math.isfinite(rng[0]) and math.isfinite(rng[1]) and rng[0] < rng[1]):
            raise _fail(origin, f"{where}.range", rng, "[lo, hi], finite numbers, lo < hi")
        if scale == "log" and rng[0] <= 0:
            raise _fail(origin, f"{where}.range", rng, "positive bounds for scale = log")
        params.append(StudyParameter(key, (), float(rng[0]), float(rng[1]), points, scale,
                                     integer))
    if kind in ("saltelli", "morris") and any(not p.continuous for p in params):
        raise _fail(origin, "design.kind", kind, "ranges for every parameter (levels are not "
                    "allowed in a sensitivity design)")
    out = doc.get("output", {})
    if not isinstance(out, dict) or any(k not in _OUTPUT_KEYS for k in out):
        raise _fail(origin, "output", out, "a table with format")
    fmt = out.get("format", "parquet")
    if fmt not in ("parquet", "csv"):
        raise _fail(origin, "output.format", fmt, "parquet, csv")
    opt = doc.get("optimize", {})
    if not isinstance(opt, dict):
        raise _fail(origin, "optimize", opt, "a table")
    return Study(name=name, description=str(doc.get("description", "")), scenario_path=spath,
                 fixed=tuple(fixed), parameters=tuple(params), design=kind, samples=samples,
                 seed=seed, output_format=fmt, optimize=dict(opt), source_path=source_path)


def load_study(path) -> Study:
    p = Path(path)
    try:
        text = p.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise StudyError(f"{p}: cannot read the study file ({exc})") from None
    return parse_study(text, origin=str(p), base_dir=p.resolve().parent, source_path=p)
