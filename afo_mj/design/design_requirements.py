"""Requirements of the minimum-weight design tool: the TOML file, validated, and the duty cycle.

A requirements file (``afo-mj design REQUIREMENTS.toml --out DIR``)::

    name = "hafo_requirements"
    description = "..."

    [requirement]
    # what the ankle must do -- one of three forms:
    profile = "corner"              # "corner" (default) | "normative" | "arrays"
    peak_torque_nm = 90.0           # corner: torque at stall ...
    peak_velocity_deg_s = 105.0     # ... and speed unloaded (corner = "separate"), or both
    corner = "separate"             # at once (corner = "simultaneous")
    # profile = "normative": the shipped normative ankle moment and velocity over a stride,
    #   body_mass_kg = 75.0, source = "winter", condition = "normal",
    #   cadence_steps_per_min = 105.3 (optional), torque_fraction = 1.0 (share delivered)
    # profile = "arrays": percent_cycle = [...] (or time_s = [...]), torque_nm = [...],
    #   velocity_deg_s = [...], cycle_time_s (with percent_cycle)
    range_of_motion_deg = 64.0      # ankle travel the cylinders' stroke covers
    moment_arm_m = [0.03, 0.06]     # pulley radius limits
    conduit_length_m = 1.1          # power supply (waist) to actuator (ankle), per hose
    operating_pressure_pa = 13.8e6  # fixed, or operating_pressure_range_pa = [lo, hi]
    runtime_h = 2.0                 # or runtime_strides = 8000
    walking_fraction = 1.0          # share of the runtime spent walking (the rest idles)
    ambient_temperature_k = 298.15
    max_surface_temperature_k = 316.15   # skin-safe contact limit, 43 °C
    architecture = "pump"           # "pump" | "valve" | "digital"
    battery_chemistry = "NMC"       # "NMC" | "NCA"
    cells_series = 6
    oil_grades = ["ISO_VG22", "ISO_VG32", "ISO_VG46"]
    min_state_of_charge = 0.2       # the speed must still be met at this charge
    body_mass_kg = 75.0             # the wearer (walking scenario; normative profile)

    [search]                        # optional: the grid (defaults shown)
    cylinder_bore_range_m = [4e-3, 25e-3]
    cylinder_bore_step_m = 0.1e-3
    moment_arm_points = 13
    hose_bore_range_m = [1.5e-3, 8e-3]
    hose_bore_points = 18
    pump_displacement_range_m3_rev = [0.05e-6, 2e-6]
    pump_displacement_points = 14
    motor_power_range_w = [10.0, 1000.0]
    motor_power_points = 16
    pressure_points = 13            # with operating_pressure_range_pa
    duty_samples = 100              # samples of the stride

Skin-safe surface temperature: 43 °C (316.15 K) is the limit IEC 60601-1:2005+A1:2012
(Table 24) sets for applied parts in contact with the skin for 10 min or more, and the
threshold of ISO 13732-1:2006 for long contact (8 h) with any material; a worn pack touches
the wearer for hours, so it is the default.

Every key is checked: unknown keys, wrong types and out-of-range values raise
:class:`DesignError` naming the file, the dotted key, the value and what is allowed.

The duty cycle (:func:`duty_cycle`): ``profile = "normative"`` or ``"arrays"`` give the torque
and velocity samples over a stride that every design must meet and whose energy sets the
battery; ``profile = "corner"`` gives constraint points (stall torque and unloaded speed, or
both at once) and, for the energy, the normative (Winter) stride shape scaled so that its
largest torque is ``peak_torque_nm`` and its largest velocity ``peak_velocity_deg_s`` (our
assumption of how a corner-specified device is used).
"""

from __future__ import annotations

import dataclasses
import math
import tomllib
from pathlib import Path
from typing import Any

import numpy as np

from afo_mj.design.design_models import CHEMISTRIES
from afo_mj.hydraulics.fluid import FLUID_PRESETS

__all__ = ["toml_dumps", "DesignError", "Requirements", "SearchGrid", "DutyCycle",
           "load_requirements", "parse_requirements", "duty_cycle", "ARCHITECTURES",
           "SKIN_SAFE_SURFACE_K"]

ARCHITECTURES = ("pump", "valve", "digital")
PROFILES = ("corner", "normative", "arrays")
CORNERS = ("separate", "simultaneous")
#: 43 °C: IEC 60601-1 Table 24 (applied parts, skin contact ≥ 10 min), ISO 13732-1 (8 h).
SKIN_SAFE_SURFACE_K = 316.15

_TOP_KEYS = ("name", "description", "requirement", "search")
_REQ_KEYS = ("profile", "peak_torque_nm", "peak_velocity_deg_s", "corner", "body_mass_kg",
             "source", "condition", "cadence_steps_per_min", "torque_fraction",
             "percent_cycle", "time_s", "torque_nm", "velocity_deg_s", "cycle_time_s",
             "range_of_motion_deg", "moment_arm_m", "conduit_length_m", "operating_pressure_pa",
             "operating_pressure_range_pa", "runtime_h", "runtime_strides", "walking_fraction",
             "ambient_temperature_k", "max_surface_temperature_k", "architecture",
             "battery_chemistry", "cells_series", "oil_grades", "min_state_of_charge")
_SEARCH_KEYS = ("cylinder_bore_range_m", "cylinder_bore_step_m", "moment_arm_points",
                "hose_bore_range_m", "hose_bore_points", "pump_displacement_range_m3_rev",
                "pump_displacement_points", "motor_power_range_w", "motor_power_points",
                "pressure_points", "duty_samples")


class DesignError(ValueError):
    """Invalid requirements (naming key, value and what is allowed) or an impossible request."""


@dataclasses.dataclass(frozen=True)
class SearchGrid:
    """Where and how finely the design variables are searched (``[search]``)."""

    cylinder_bore_range_m: tuple[float, float] = (4e-3, 25e-3)
    cylinder_bore_step_m: float = 0.1e-3
    moment_arm_points: int = 13
    hose_bore_range_m: tuple[float, float] = (1.5e-3, 8e-3)
    hose_bore_points: int = 18
    pump_displacement_range_m3_rev: tuple[float, float] = (0.05e-6, 2e-6)
    pump_displacement_points: int = 14
    motor_power_range_w: tuple[float, float] = (10.0, 1000.0)
    motor_power_points: int = 16
    pressure_points: int = 13
    duty_samples: int = 100


@dataclasses.dataclass(frozen=True)
class Requirements:
    """Validated requirements (see the module docstring); SI units."""

    name: str = "design"
    description: str = ""
    profile: str = "corner"
    peak_torque_nm: float | None = 90.0
    peak_velocity_rad_s: float | None = math.radians(105.0)
    corner: str = "separate"
    body_mass_kg: float = 75.0
    source: str = "winter"
    condition: str = "normal"
    cadence_steps_per_min: float | None = None
    torque_fraction: float = 1.0
    profile_phase: tuple | None = None          # arrays: phase in [0, 1)
    profile_torque_nm: tuple | None = None
    profile_velocity_rad_s: tuple | None = None
    cycle_time_s: float | None = None
    range_of_motion_rad: float = math.radians(64.0)
    moment_arm_range_m: tuple[float, float] = (0.03, 0.06)
    conduit_length_m: float = 1.1
    pressure_range_pa: tuple[float, float] = (13.8e6, 13.8e6)
    runtime_h: float | None = 2.0
    runtime_strides: float | None = None
    walking_fraction: float = 1.0
    ambient_temperature_k: float = 298.15
    max_surface_temperature_k: float = SKIN_SAFE_SURFACE_K
    architecture: str = "pump"
    battery_chemistry: str = "NMC"
    cells_series: int = 6
    oil_grades: tuple[str, ...] = ("ISO_VG22", "ISO_VG32", "ISO_VG46")
    min_state_of_charge: float = 0.2
    search: SearchGrid = SearchGrid()
    source_path: Path | None = None

    @property
    def pressure_fixed(self) -> bool:
        return self.pressure_range_pa[0] == self.pressure_range_pa[1]

    def with_changes(self, **changes) -> "Requirements":
        """A copy with some fields changed (the studies scale the requirement this way)."""
        return dataclasses.replace(self, **changes)

    def as_dict(self) -> dict:
        """JSON-ready record in the file's units (deg where the file has deg)."""
        d = {"name": self.name, "description": self.description, "profile": self.profile,
             "architecture": self.architecture,
             "range_of_motion_deg": math.degrees(self.range_of_motion_rad),
             "moment_arm_m": list(self.moment_arm_range_m),
             "conduit_length_m": self.conduit_length_m,
             "operating_pressure_range_pa": list(self.pressure_range_pa),
             "runtime_h": self.runtime_h, "runtime_strides": self.runtime_strides,
             "walking_fraction": self.walking_fraction,
             "ambient_temperature_k": self.ambient_temperature_k,
             "max_surface_temperature_k": self.max_surface_temperature_k,
             "battery_chemistry": self.battery_chemistry, "cells_series": self.cells_series,
             "oil_grades": list(self.oil_grades), "min_state_of_charge": self.min_state_of_charge,
             "body_mass_kg": self.body_mass_kg,
             "file": None if self.source_path is None else str(self.source_path)}
        if self.profile == "corner":
            d.update(peak_torque_nm=self.peak_torque_nm,
                     peak_velocity_deg_s=math.degrees(self.peak_velocity_rad_s),
                     corner=self.corner)
        elif self.profile == "normative":
            d.update(source=self.source, condition=self.condition,
                     cadence_steps_per_min=self.cadence_steps_per_min,
                     torque_fraction=self.torque_fraction)
        else:
            d.update(samples=len(self.profile_phase), cycle_time_s=self.cycle_time_s)
        d["search"] = dataclasses.asdict(self.search)
        return d


# -- parsing ----------------------------------------------------------------------------------
class _Checker:
    def __init__(self, origin: str):
        self.origin = origin

    def fail(self, key: str, value: Any, allowed: str) -> DesignError:
        return DesignError(f"{self.origin}: {key} = {value!r} is not allowed; allowed: {allowed}")

    def number(self, tbl: dict, key: str, prefix: str, lo: float, hi: float, default=None, *,
               lo_open: bool = False, unit: str = "", required: bool = False):
        if key not in tbl:
            if required:
                raise DesignError(f"{self.origin}: {prefix}{key} is missing; allowed: a number "
                                  f"in {'(' if lo_open else '['}{lo:g}, {hi:g}]{unit}")
            return default
        v = tbl[key]
        ok = (not isinstance(v, bool) and isinstance(v, (int, float)) and math.isfinite(v)
              and (v > lo if lo_open else v >= lo) and v <= hi)
        if not ok:
            raise self.fail(prefix + key, v, f"a number in {'(' if lo_open else '['}{lo:g}, "
                            f"{hi:g}]{unit}")
        return float(v)

    def integer(self, tbl: dict, key: str, prefix: str, lo: int, hi: int, default: int) -> int:
        v = tbl.get(key, default)
        if isinstance(v, bool) or not isinstance(v, int) or not lo <= v <= hi:
            raise self.fail(prefix + key, v, f"an integer in {lo} … {hi}")
        return int(v)

    def choice(self, tbl: dict, key: str, prefix: str, allowed, default: str) -> str:
        v = tbl.get(key, default)
        if v not in allowed:
            raise self.fail(prefix + key, v, " | ".join(f'"{a}"' for a in allowed))
        return v

    def pair(self, tbl: dict, key: str, prefix: str, lo: float, hi: float, default, unit: str,
             allow_equal: bool = False):
        if key not in tbl:
            return default
        v = tbl[key]
        allowed = (f"[low, high] with {lo:g} <= low {'<=' if allow_equal else '<'} high "
                   f"<= {hi:g}{unit}")
        if (not isinstance(v, list) or len(v) != 2
                or any(isinstance(x, bool) or not isinstance(x, (int, float))
                       or not math.isfinite(x) for x in v)):
            raise self.fail(prefix + key, v, allowed)
        a, b = float(v[0]), float(v[1])
        if not (lo <= a <= hi and lo <= b <= hi and (a <= b if allow_equal else a < b)):
            raise self.fail(prefix + key, v, allowed)
        return (a, b)

    def array(self, tbl: dict, key: str, prefix: str, lo: float, hi: float, unit: str):
        v = tbl.get(key)
        allowed = f"a list of at least 4 numbers in [{lo:g}, {hi:g}]{unit}"
        if (not isinstance(v, list) or len(v) < 4
                or any(isinstance(x, bool) or not isinstance(x, (int, float))
                       or not math.isfinite(x) or not lo <= x <= hi for x in v)):
            raise self.fail(prefix + key, v, allowed)
        return np.asarray(v, dtype=float)


def parse_requirements(text: str, origin: str = "<requirements>",
                       default_name: str = "design", source_path: Path | None = None
                       ) -> Requirements:
    """Validate a requirements document (module docstring); raises :class:`DesignError`."""
    import re
    c = _Checker(origin)
    try:
        doc = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise DesignError(f"{origin}: not valid TOML: {exc}") from None
    for k in doc:
        if k not in _TOP_KEYS:
            raise c.fail(k, doc[k], "top-level keys " + ", ".join(_TOP_KEYS))
    name = doc.get("name", default_name)
    if not isinstance(name, str) or not re.match(r"^[A-Za-z0-9_.\-]+$", name):
        raise c.fail("name", name, "letters, digits, _ . - (non-empty)")
    description = doc.get("description", "")
    if not isinstance(description, str):
        raise c.fail("description", description, "a string")
    req = doc.get("requirement")
    if not isinstance(req, dict):
        raise c.fail("requirement", req, "a [requirement] table")
    for k in req:
        if k not in _REQ_KEYS:
            raise c.fail(f"requirement.{k}", req[k], "keys " + ", ".join(_REQ_KEYS))
    P = "requirement."
    kw: dict[str, Any] = {"name": name, "description": description,
                          "source_path": source_path}
    profile = c.choice(req, "profile", P, PROFILES,
                       "arrays" if "torque_nm" in req else
                       "normative" if req.get("source") is not None
                       and "peak_torque_nm" not in req else "corner")
    kw["profile"] = profile
    kw["body_mass_kg"] = c.number(req, "body_mass_kg", P, 10.0, 200.0, 75.0, unit=" kg")
    foreign = {"corner": ("source", "condition", "cadence_steps_per_min", "torque_fraction",
                          "percent_cycle", "time_s", "torque_nm", "velocity_deg_s",
                          "cycle_time_s"),
               "normative": ("peak_torque_nm", "peak_velocity_deg_s", "corner",
                             "percent_cycle", "time_s", "torque_nm", "velocity_deg_s",
                             "cycle_time_s"),
               "arrays": ("peak_torque_nm", "peak_velocity_deg_s", "corner", "source",
                          "condition", "cadence_steps_per_min", "torque_fraction")}[profile]
    for k in foreign:
        if k in req:
            raise c.fail(P + k, req[k], f'no {k} with profile = "{profile}"')
    if profile == "corner":
        kw["peak_torque_nm"] = c.number(req, "peak_torque_nm", P, 0.0, 2000.0, lo_open=True,
                                        unit=" N*m", required=True)
        kw["peak_velocity_rad_s"] = math.radians(c.number(
            req, "peak_velocity_deg_s", P, 0.0, 2000.0, lo_open=True, unit=" deg/s",
            required=True))
        kw["corner"] = c.choice(req, "corner", P, CORNERS, "separate")
    elif profile == "normative":
        from afo_mj.gait.reference import ReferenceGaitError, load_normative
        src = req.get("source", "winter")
        cond = req.get("condition", {"winter": "normal"}.get(src, "Free"))
        try:
            load_normative(src, cond)
        except ReferenceGaitError:
            raise c.fail(P + "source/condition", f"{src}/{cond}",
                         '"winter"/"normal" or "schwartz2008"/VerySlow|Slow|Free|Fast|'
                         'VeryFast') from None
        kw.update(source=src, condition=cond, peak_torque_nm=None, peak_velocity_rad_s=None,
                  cadence_steps_per_min=c.number(req, "cadence_steps_per_min", P, 30.0, 200.0,
                                                 None, unit=" steps/min"),
                  torque_fraction=c.number(req, "torque_fraction", P, 0.0, 2.0, 1.0,
                                           lo_open=True))
    else:
        kw.update(peak_torque_nm=None, peak_velocity_rad_s=None)
        torque = c.array(req, "torque_nm", P, -2000.0, 2000.0, " N*m")
        vel = c.array(req, "velocity_deg_s", P, -2000.0, 2000.0, " deg/s")
        if ("percent_cycle" in req) == ("time_s" in req):
            raise c.fail(P + "percent_cycle/time_s", None, "exactly one of percent_cycle "
                         "(with cycle_time_s) or time_s")
        if "percent_cycle" in req:
            x = c.array(req, "percent_cycle", P, 0.0, 100.0, " %") / 100.0
            cyc = c.number(req, "cycle_time_s", P, 0.1, 20.0, required=True, unit=" s")
        else:
            t = c.array(req, "time_s", P, 0.0, 1e4, " s")
            if "cycle_time_s" in req:
                raise c.fail(P + "cycle_time_s", req["cycle_time_s"],
                             "no cycle_time_s with time_s (the cycle is the time span)")
            cyc = float(t[-1] - t[0])
            if not cyc > 0:
                raise c.fail(P + "time_s", req["time_s"], "increasing times")
            x = (t - t[0]) / cyc
        if not (len(x) == len(torque) == len(vel)):
            raise c.fail(P + "torque_nm", f"{len(torque)} samples",
                         f"as many samples as the phase ({len(x)}) and velocity_deg_s "
                         f"({len(vel)})")
        if np.any(np.diff(x) <= 0):
            raise c.fail(P + ("percent_cycle" if "percent_cycle" in req else "time_s"),
                         req.get("percent_cycle", req.get("time_s")), "strictly increasing")
        if np.max(np.abs(torque)) <= 0 or np.max(np.abs(vel)) <= 0:
            raise c.fail(P + "torque_nm", req["torque_nm"],
                         "some non-zero torque and velocity")
        kw.update(profile_phase=tuple(x), profile_torque_nm=tuple(torque),
                  profile_velocity_rad_s=tuple(np.radians(vel)), cycle_time_s=cyc)
    kw["range_of_motion_rad"] = math.radians(c.number(req, "range_of_motion_deg", P, 5.0, 120.0,
                                                      64.0, unit=" deg"))
    kw["moment_arm_range_m"] = c.pair(req, "moment_arm_m", P, 0.005, 0.2, (0.03, 0.06), " m",
                                      allow_equal=True)
    kw["conduit_length_m"] = c.number(req, "conduit_length_m", P, 0.05, 20.0, 1.1, unit=" m")
    if ("operating_pressure_pa" in req) == ("operating_pressure_range_pa" in req):
        raise c.fail(P + "operating_pressure_pa", req.get("operating_pressure_pa"),
                     "exactly one of operating_pressure_pa (fixed) or "
                     "operating_pressure_range_pa = [low, high]")
    if "operating_pressure_pa" in req:
        p = c.number(req, "operating_pressure_pa", P, 2e6, 35e6, unit=" Pa (above the 1.5 MPa "
                     "charge pressure, up to 35 MPa)")
        kw["pressure_range_pa"] = (p, p)
    else:
        kw["pressure_range_pa"] = c.pair(req, "operating_pressure_range_pa", P, 2e6, 35e6, None,
                                         " Pa")
    if ("runtime_h" in req) == ("runtime_strides" in req):
        raise c.fail(P + "runtime_h", req.get("runtime_h"),
                     "exactly one of runtime_h or runtime_strides")
    kw["runtime_h"] = c.number(req, "runtime_h", P, 0.0, 48.0, None, lo_open=True, unit=" h")
    kw["runtime_strides"] = c.number(req, "runtime_strides", P, 0.0, 1e6, None, lo_open=True)
    kw["walking_fraction"] = c.number(req, "walking_fraction", P, 0.0, 1.0, 1.0, lo_open=True)
    kw["ambient_temperature_k"] = c.number(req, "ambient_temperature_k", P, 253.15, 318.15,
                                           298.15, unit=" K")
    kw["max_surface_temperature_k"] = c.number(req, "max_surface_temperature_k", P, 293.15,
                                               353.15, SKIN_SAFE_SURFACE_K, unit=" K")
    if kw["max_surface_temperature_k"] <= kw["ambient_temperature_k"]:
        raise c.fail(P + "max_surface_temperature_k", kw["max_surface_temperature_k"],
                     f"above ambient_temperature_k = {kw['ambient_temperature_k']:g} K")
    kw["architecture"] = c.choice(req, "architecture", P, ARCHITECTURES, "pump")
    kw["battery_chemistry"] = c.choice(req, "battery_chemistry", P, tuple(CHEMISTRIES), "NMC")
    kw["cells_series"] = c.integer(req, "cells_series", P, 2, 14, 6)
    grades = req.get("oil_grades", list(FLUID_PRESETS))
    if (not isinstance(grades, list) or not grades or len(set(grades)) != len(grades)
            or any(g not in FLUID_PRESETS for g in grades)):
        raise c.fail(P + "oil_grades", grades,
                     "a non-empty list of distinct " + ", ".join(FLUID_PRESETS))
    kw["oil_grades"] = tuple(grades)
    kw["min_state_of_charge"] = c.number(req, "min_state_of_charge", P, 0.0, 0.9, 0.2)
    kw["search"] = _search(doc.get("search", {}), c)
    return Requirements(**kw)


def _search(tbl, c: _Checker) -> SearchGrid:
    if not isinstance(tbl, dict):
        raise c.fail("search", tbl, "a table")
    for k in tbl:
        if k not in _SEARCH_KEYS:
            raise c.fail(f"search.{k}", tbl[k], "keys " + ", ".join(_SEARCH_KEYS))
    S, d = "search.", SearchGrid()
    g = SearchGrid(
        cylinder_bore_range_m=c.pair(tbl, "cylinder_bore_range_m", S, 2e-3, 0.1,
                                     d.cylinder_bore_range_m, " m"),
        cylinder_bore_step_m=c.number(tbl, "cylinder_bore_step_m", S, 1e-5, 5e-3,
                                      d.cylinder_bore_step_m, unit=" m"),
        moment_arm_points=c.integer(tbl, "moment_arm_points", S, 1, 101, d.moment_arm_points),
        hose_bore_range_m=c.pair(tbl, "hose_bore_range_m", S, 0.5e-3, 0.05,
                                 d.hose_bore_range_m, " m"),
        hose_bore_points=c.integer(tbl, "hose_bore_points", S, 3, 101, d.hose_bore_points),
        pump_displacement_range_m3_rev=c.pair(tbl, "pump_displacement_range_m3_rev", S, 1e-9,
                                              1e-4, d.pump_displacement_range_m3_rev,
                                              " m^3/rev"),
        pump_displacement_points=c.integer(tbl, "pump_displacement_points", S, 1, 101,
                                           d.pump_displacement_points),
        motor_power_range_w=c.pair(tbl, "motor_power_range_w", S, 1.0, 1e4,
                                   d.motor_power_range_w, " W"),
        motor_power_points=c.integer(tbl, "motor_power_points", S, 2, 101, d.motor_power_points),
        pressure_points=c.integer(tbl, "pressure_points", S, 2, 101, d.pressure_points),
        duty_samples=c.integer(tbl, "duty_samples", S, 16, 2000, d.duty_samples))
    n_bores = (g.cylinder_bore_range_m[1] - g.cylinder_bore_range_m[0]) / g.cylinder_bore_step_m
    if n_bores > 5000:
        raise c.fail("search.cylinder_bore_step_m", g.cylinder_bore_step_m,
                     "a step giving at most 5000 bores over cylinder_bore_range_m")
    return g


def load_requirements(path) -> Requirements:
    """Read and validate a requirements TOML file (module docstring)."""
    p = Path(path)
    try:
        text = p.read_text(encoding="utf-8")
    except OSError as exc:
        raise DesignError(f"{p}: cannot read the requirements file "
                          f"({exc.strerror or exc})") from None
    return parse_requirements(text, origin=str(p), default_name=p.stem, source_path=p)


# -- duty cycle -------------------------------------------------------------------------------
@dataclasses.dataclass(frozen=True)
class DutyCycle:
    """Samples of one stride (``torque_nm``, ``velocity_rad_s`` at ``dt_s`` each, + dorsiflexion)
    for the energy, and the constraint points every design must reach."""

    torque_nm: np.ndarray
    velocity_rad_s: np.ndarray
    dt_s: np.ndarray
    stride_time_s: float
    constraint_torque_nm: np.ndarray
    constraint_velocity_rad_s: np.ndarray
    constraint_labels: tuple[str, ...]
    note: str

    @property
    def positive_work_j(self) -> float:
        p = self.torque_nm * self.velocity_rad_s
        return float(np.sum(np.maximum(p, 0.0) * self.dt_s))

    @property
    def peak_power_w(self) -> float:
        return float(np.max(np.abs(self.torque_nm * self.velocity_rad_s)))


def _normative_shape(source: str, condition: str, n: int, cadence: float | None,
                     body_scale: float, body_mass_kg: float):
    from afo_mj.gait.reference import load_normative
    g = load_normative(source, condition)
    phase = (np.arange(n) + 0.5) / n
    cyc = g.cycle_time_s if cadence is None else 120.0 / cadence
    tau = g.channel("ankle_moment_nm_per_kg", phase) * body_mass_kg * body_scale
    vel = g.velocities_rad_s(phase, cyc)[..., 2]
    return tau, vel, float(cyc)


def duty_cycle(req: Requirements) -> DutyCycle:
    """The stride samples and constraint points of ``req`` (module docstring)."""
    n = req.search.duty_samples
    if req.profile == "normative":
        tau, vel, cyc = _normative_shape(req.source, req.condition, n,
                                         req.cadence_steps_per_min, req.torque_fraction,
                                         req.body_mass_kg)
        note = (f"{req.source}/{req.condition} ankle moment × {req.body_mass_kg:g} kg × "
                f"{req.torque_fraction:g} and ankle velocity, {n} samples over {cyc:.3f} s")
        return DutyCycle(tau, vel, np.full(n, cyc / n), cyc, tau, vel,
                         tuple(f"stride sample {k}" for k in range(n)), note)
    if req.profile == "arrays":
        x = np.asarray(req.profile_phase)
        ph = (np.arange(n) + 0.5) / n
        tau = np.interp(ph, x, np.asarray(req.profile_torque_nm), period=1.0)
        vel = np.interp(ph, x, np.asarray(req.profile_velocity_rad_s), period=1.0)
        cyc = float(req.cycle_time_s)
        # every given sample is a constraint point as well as the resampled ones
        ct = np.concatenate([np.asarray(req.profile_torque_nm), tau])
        cv = np.concatenate([np.asarray(req.profile_velocity_rad_s), vel])
        note = f"user profile, {len(x)} samples over {cyc:.3f} s, resampled to {n}"
        return DutyCycle(tau, vel, np.full(n, cyc / n), cyc, ct, cv,
                         tuple(f"profile sample {k}" for k in range(len(ct))), note)
    tau0, vel0, cyc = _normative_shape("winter", "normal", n, None, 1.0, 1.0)
    tau = tau0 / np.max(np.abs(tau0)) * req.peak_torque_nm
    vel = vel0 / np.max(np.abs(vel0)) * req.peak_velocity_rad_s
    T, W = req.peak_torque_nm, req.peak_velocity_rad_s
    # plantarflexion torque (negative) with plantarflexion velocity (negative): motoring
    if req.corner == "separate":
        ct, cv = np.array([-T, 0.0]), np.array([0.0, -W])
        labels = ("stall torque", "unloaded speed")
    else:
        ct, cv = np.array([-T, -T, 0.0]), np.array([-W, 0.0, -W])
        labels = ("torque at speed", "stall torque", "unloaded speed")
    note = (f"corner {T:g} N·m / {math.degrees(W):g} deg/s ({req.corner}); energy over "
            f"Winter's normal stride scaled to that torque and velocity ({cyc:.3f} s)")
    return DutyCycle(tau, vel, np.full(n, cyc / n), cyc, ct, cv, labels, note)


# -- a small TOML writer (tables of scalars, arrays and nested tables) --------------------------
def _toml_key(k: str) -> str:
    import re
    return k if re.match(r"^[A-Za-z0-9_\-]+$", k) else '"' + k.replace('"', '\\"') + '"'


def _toml_value(v) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, (int, np.integer)):
        return str(int(v))
    if isinstance(v, (float, np.floating)):
        x = float(v)
        if not math.isfinite(x):
            raise DesignError(f"cannot write the non-finite value {x!r} to TOML")
        return repr(x)
    if isinstance(v, str):
        return '"' + v.replace("\\", "\\\\").replace('"', '\\"') + '"'
    if isinstance(v, (list, tuple, np.ndarray)):
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    raise DesignError(f"cannot write {type(v).__name__} {v!r} to TOML")


def toml_dumps(doc: dict, _prefix: str = "") -> str:
    """TOML text of ``doc``: scalars first, then each nested table as ``[a.b]`` (keys that are
    not bare, such as dotted parameter names, are quoted)."""
    lines = []
    tables = []
    for k, v in doc.items():
        if isinstance(v, dict):
            tables.append((k, v))
        elif v is not None:
            lines.append(f"{_toml_key(k)} = {_toml_value(v)}")
    out = "\n".join(lines)
    for k, v in tables:
        name = f"{_prefix}{_toml_key(k)}"
        body = toml_dumps(v, name + ".")
        head = f"[{name}]"
        out += ("\n\n" if out else "") + head + ("\n" + body if body else "")
    return out + ("\n" if not _prefix and not out.endswith("\n") else "")
