"""Measured data from a bench or a walker, in a documented format, with a validating loader.

Users who hold measurements of a hydraulic ankle-foot orthosis replay them through the model
(the next step of issue 7, "close the loop with measured data"). Before anything is fitted the
data must be *right*: a pressure logged in bar or an angle in degrees would otherwise be
fitted silently and wrongly. This module defines the format, reads and writes it, and refuses
(with :class:`MeasuredDataError`, naming the file, the key or channel, the value and what is
allowed) what would lead to a wrong fit. The full description is ``docs/measured_data.md``.

Format (version ``afo_mj measured data v1``)
--------------------------------------------
Two files side by side:

* the **data file**: CSV (header row of channel names, first column ``time_s``, one row per
  sample, ``,`` separated, UTF-8) or Parquet (the same columns, float64; read and written with
  pyarrow, imported only when needed). All numbers in SI units: s, Pa (gauge, relative to the
  atmosphere, as the model's kernels hold them), rad, rad/s, N·m, m, A, V, K; commands
  dimensionless.
* the **sidecar**: TOML with the same stem (``bench_01.csv`` → ``bench_01.toml``) or named
  explicitly::

      format = "afo_mj measured data v1"
      inputs = ["motor_voltage_v", "ankle_angle_rad"]     # channels that drive the model
      outputs = ["pressure_a_pa", "ankle_torque_nm"]      # channels the model must reproduce

      [source]                # at least one of scenario / preset
      scenario = "scenarios/bench_hafo.toml"
      preset = "hafo"
      description = "isometric steps, prototype 2"       # optional
      licence = "CC-BY-4.0"                               # optional
      origin = "lab X, 2026-03-02"                        # optional

      [noise]                 # optional: sensor noise standard deviation, channel's SI unit
      pressure_a_pa = 2.0e4
      ankle_torque_nm = 0.5

      [segments]              # optional: how to cut the record into whole pieces
      cycle_starts_s = [0.52, 1.61, 2.70]   # or: period_s = 1.09 (and phase_s = 0.52)
      boundaries_s = [0.0, 12.0, 24.0]      # starts of separate experiments

      [hold]                  # optional: how each input was produced between its samples
      motor_voltage_v = "zero_order"        # a digital command, stepped and held; or "linear"

Every column must be a channel of :data:`CHANNELS` (its name carries its SI unit).

Decisions on ambiguous cases (documented in ``docs/measured_data.md``)
----------------------------------------------------------------------
* Input and output at once: allowed only for channels whose spec says so
  (``ankle_angle_rad``: imposed by a bench motor and measured by the encoder;
  ``motor_speed_rad_s``: the reference of a speed loop and its measured speed). The column then
  drives the model and is also compared; the comparison means something only where the model
  imposes it through a compliance or a controller.
* Columns that are neither inputs nor outputs are kept (``channels``) and reported with a
  :class:`MeasuredDataWarning`; replay ignores them.
* Unit mistakes: an error where the magnitude is impossible in SI and typical of the other
  unit (pressure peak < 1000 Pa → bar or MPa; pressure minimum at 1 atm → absolute;
  |angle| > 1.5 rad → degrees; median time step ≥ 0.1 s → ms; temperature median
  < 150 K → °C; |piston position| > 0.5 m → mm; …); a :class:`UnitWarning` where the value is
  merely implausible (outside the channel's plausible range). ``unit_checks=False`` turns both
  off for a record that is known to be right.
* Sampling: ``time_s`` strictly increasing; every interval within 0.5…1.5 × the median
  interval (else an error naming the row and the largest gap); at least
  :data:`MIN_SAMPLES` samples; median interval < :data:`MAX_SAMPLE_PERIOD_S` (unit check: else
  time in ms). Jitter inside the tolerance is allowed: replay uses ``time_s``
  itself, ``sample_period_s`` is the median interval.
* Noise standard deviations must be finite and > 0 (zero would give a channel infinite weight)
  and name a channel present in the file.
* Cycles (``by="cycles"``) run from one start to the next; data before the first start and
  after the last whole cycle belong to no cycle. Segments (``by="segments"``) start at each
  boundary, the last runs to the end of the record.
"""

from __future__ import annotations

import dataclasses
import difflib
import json
import math
import os
import tomllib
import warnings
from pathlib import Path
from types import MappingProxyType
from typing import Mapping, Sequence

import numpy as np

__all__ = ["FORMAT", "MIN_SAMPLES", "ChannelSpec", "CHANNELS", "MeasuredDataError",
           "MeasuredDataWarning", "UnitWarning", "MeasuredData", "load_measured",
           "write_measured", "describe", "HOLD_VALUES"]

#: The ``format`` string of the sidecar this module reads and writes.
FORMAT = "afo_mj measured data v1"
#: Fewest samples a record may have (fewer cannot identify anything).
MIN_SAMPLES = 50
#: Sampling tolerance: each interval within ``[1 − tol, 1 + tol]`` × the median interval.
SAMPLING_TOLERANCE = 0.5
#: Longest median sample period [s] a record may have (with unit checks): slower sampling
#: resolves no hydraulic or gait dynamics and is typical of time logged in milliseconds.
MAX_SAMPLE_PERIOD_S = 0.1
#: Largest |ankle angle| [rad] an ankle reaches (≈ 86°); beyond it the angle is in degrees.
MAX_ANKLE_ANGLE_RAD = 1.5
#: Atmospheric pressure [Pa] and the band around it (altitude, weather) in which the minimum of
#: a pressure channel says "absolute, not gauge": a line at rest reads ≈ 0 Pa gauge.
ATMOSPHERE_PA = 101325.0
ABSOLUTE_PRESSURE_BAND_PA = (0.8e5, 1.1e5)

_TOP_KEYS = ("format", "source", "inputs", "outputs", "noise", "segments", "hold")
#: the values of a sidecar's ``[hold]`` table: ``"zero_order"`` (the input is a digital command
#: that steps at the sample instants and is held between them), ``"linear"`` (a sampled
#: continuous signal, interpolated between the samples)
HOLD_VALUES = ("zero_order", "linear")
_SOURCE_KEYS = ("scenario", "preset", "description", "licence", "origin")
_SEGMENT_KEYS = ("cycle_starts_s", "period_s", "phase_s", "boundaries_s")


class MeasuredDataError(ValueError):
    """A measured-data file or sidecar that would give a wrong fit. ``path`` and ``key`` say
    where (file, key or channel); the message says the value and what is allowed."""

    def __init__(self, path, key: str, message: str):
        self.path = None if path is None else str(path)
        self.key = key
        where = f"{self.path}: " if self.path else ""
        super().__init__(f"{where}{key}: {message}")


class MeasuredDataWarning(UserWarning):
    """Something in measured data that is allowed but probably not meant."""


class UnitWarning(MeasuredDataWarning):
    """A channel's magnitude is implausible for its SI unit (but not impossible)."""


@dataclasses.dataclass(frozen=True)
class ChannelSpec:
    """One known channel: its SI unit, what it is, how it may be used and the magnitudes that
    tell a unit mistake.

    ``plausible_min``/``plausible_max``: the range of a right record of a hydraulic AFO; values
    outside give a :class:`UnitWarning`. ``check`` names the unit-mistake test
    (:func:`_unit_check`) that raises on magnitudes impossible in SI. ``model_field``: the
    device log field (``LOG_FIELDS`` of the device kernels) the channel compares with, where
    one exists.
    """

    name: str
    unit: str
    description: str
    as_input: bool
    as_output: bool
    plausible_min: float
    plausible_max: float
    check: str
    input_and_output: bool = False
    model_field: str = ""


def _spec(name, unit, description, inp, out, lo, hi, check, both=False, field=""):
    return ChannelSpec(name, unit, description, inp, out, lo, hi, check, both, field)


_P_LO, _P_HI = -1.0e5, 4.0e7   # gauge pressure: vacuum … 400 bar
#: The known channels, by name. Each name ends in its SI unit.
CHANNELS: Mapping[str, ChannelSpec] = MappingProxyType({s.name: s for s in (
    # inputs (drive the model)
    _spec("motor_voltage_v", "V", "voltage commanded to / applied at the motor terminals",
          True, True, -100.0, 100.0, "voltage", field="motor_command_v"),
    _spec("motor_speed_rad_s", "rad/s", "motor shaft speed (input: speed-loop reference)",
          True, True, -2500.0, 2500.0, "motor_speed", both=True, field="motor_speed_rad_s"),
    _spec("valve_command", "1", "normalised valve command (servo ±1, on/off or duty 0…1)",
          True, True, -1.05, 1.05, "command", field="valve_command"),
    _spec("ankle_angle_rad", "rad", "ankle angle, dorsiflexion positive (bench: imposed)",
          True, True, -1.2, 1.2, "angle", both=True, field="ankle_angle_rad"),
    _spec("load_torque_nm", "N·m",
          "external torque on the ankle from the bench/load, dorsiflexion positive",
          True, False, -300.0, 300.0, "torque"),
    _spec("commanded_torque_nm", "N·m",
          "the controller's torque reference, dorsiflexion positive",
          True, True, -300.0, 300.0, "torque", field="commanded_torque_nm"),
    _spec("bus_voltage_v", "V", "supply (battery bus) voltage",
          True, True, 0.0, 100.0, "voltage", field="bus_voltage_v"),
    # outputs (the model must reproduce them)
    _spec("pressure_a_pa", "Pa", "gauge pressure at pump/actuator port A",
          False, True, _P_LO, _P_HI, "pressure", field="pressure_a_pa"),
    _spec("pressure_b_pa", "Pa", "gauge pressure at pump/actuator port B",
          False, True, _P_LO, _P_HI, "pressure", field="pressure_b_pa"),
    _spec("chamber_a_pa", "Pa", "gauge pressure in cylinder chamber A (after the hose)",
          False, True, _P_LO, _P_HI, "pressure", field="chamber_a_pa"),
    _spec("chamber_b_pa", "Pa", "gauge pressure in cylinder chamber B (after the hose)",
          False, True, _P_LO, _P_HI, "pressure", field="chamber_b_pa"),
    _spec("supply_pressure_pa", "Pa", "gauge supply (accumulator / valve P port) pressure",
          False, True, _P_LO, _P_HI, "pressure", field="supply_pa"),
    _spec("pump_pressure_pa", "Pa", "gauge pressure at the pump outlet",
          False, True, _P_LO, _P_HI, "pressure", field="pump_pa"),
    _spec("ankle_torque_nm", "N·m",
          "device torque at the ankle (torque sensor), dorsiflexion positive",
          False, True, -300.0, 300.0, "torque", field="measured_torque_nm"),
    _spec("ankle_velocity_rad_s", "rad/s", "ankle angular velocity, dorsiflexion positive",
          False, True, -15.0, 15.0, "joint_velocity", field="ankle_velocity_rad_s"),
    _spec("piston_position_m", "m", "piston (cable) position from its reference",
          False, True, -0.2, 0.2, "position"),
    _spec("motor_current_a", "A", "motor (phase / q-axis) current",
          False, True, -100.0, 100.0, "current", field="motor_current_a"),
    _spec("battery_current_a", "A", "current drawn from the battery bus",
          False, True, -100.0, 100.0, "current", field="battery_current_a"),
    _spec("valve_position", "1", "normalised valve spool position (±1 at full stroke)",
          False, True, -1.05, 1.05, "command", field="valve_position"),
    _spec("fluid_temperature_k", "K", "hydraulic fluid temperature",
          False, True, 250.0, 400.0, "temperature", field="oil_temperature_k"),
)})


# ---------------------------------------------------------------------------------- checks


def _closest(name: str, known) -> str:
    near = difflib.get_close_matches(name, list(known), n=1, cutoff=0.5)
    return f" (did you mean {near[0]!r}?)" if near else ""


def _check_channel_name(path, where: str, name) -> None:
    if not isinstance(name, str):
        raise MeasuredDataError(path, where, f"channel names are strings, got {name!r}")
    if name not in CHANNELS:
        raise MeasuredDataError(
            path, where, f"unknown channel {name!r}{_closest(name, CHANNELS)}. "
            f"Known channels: {', '.join(CHANNELS)}")


def _unit_check(path, spec: ChannelSpec, x: np.ndarray) -> None:
    """Raise on magnitudes impossible in the channel's SI unit and typical of another unit;
    warn (:class:`UnitWarning`) on values outside the plausible range."""
    peak = float(np.max(np.abs(x)))
    name, kind = spec.name, spec.check

    def fail(msg):
        raise MeasuredDataError(path, name, msg + f" (expected {spec.unit}, plausible "
                                f"{spec.plausible_min:g}…{spec.plausible_max:g} {spec.unit})")

    if kind == "pressure" and 0.0 < peak < 1000.0:
        fail(f"largest |value| is {peak:g} Pa, i.e. below 0.01 bar everywhere: looks like bar "
             f"(multiply by 1e5) or MPa (multiply by 1e6); pressures are gauge Pa")
    if kind == "angle" and peak > MAX_ANKLE_ANGLE_RAD:
        fail(f"values {float(np.min(x)):g}…{float(np.max(x)):g} rad: |θ| up to {peak:g} rad "
             f"(> {MAX_ANKLE_ANGLE_RAD:g} rad ≈ {math.degrees(MAX_ANKLE_ANGLE_RAD):.0f}°, "
             f"beyond any ankle): looks like degrees (multiply by π/180 to give radians)")
    lo_atm, hi_atm = ABSOLUTE_PRESSURE_BAND_PA
    if kind == "pressure" and lo_atm <= float(np.min(x)) <= hi_atm:
        fail(f"values {float(np.min(x)):g}…{float(np.max(x)):g} Pa: the minimum sits at "
             f"atmospheric pressure ({lo_atm:g}…{hi_atm:g} Pa), typical of absolute pressure; "
             f"pressures are gauge Pa (subtract {ATMOSPHERE_PA:g} Pa, or the sensor's reading "
             f"at rest); a record known to be gauge can pass unit_checks=False")
    if kind == "joint_velocity" and peak > 50.0:
        fail(f"largest |value| is {peak:g} rad/s (> 50 rad/s, beyond any ankle): looks like "
             f"deg/s (multiply by π/180)")
    if kind == "motor_speed" and peak > 1.0e4:
        fail(f"largest |value| is {peak:g} rad/s (> 1e4 rad/s ≈ 95 000 rpm): looks like rpm "
             f"(multiply by 2π/60)")
    if kind == "temperature" and float(np.median(x)) < 150.0:
        fail(f"median is {float(np.median(x)):g} K (< 150 K): looks like °C "
             f"(add 273.15 to give kelvin)")
    if kind == "position" and peak > 0.5:
        fail(f"largest |value| is {peak:g} m (> 0.5 m for an ankle actuator): looks like mm "
             f"(multiply by 1e-3)")
    if kind == "torque" and peak > 2000.0:
        fail(f"largest |value| is {peak:g} N·m (> 2000 N·m at an ankle): looks like N·mm "
             f"(multiply by 1e-3)")
    if kind in ("voltage", "current") and peak > 1000.0:
        milli = "mV" if kind == "voltage" else "mA"
        fail(f"largest |value| is {peak:g} {spec.unit} (> 1000): looks like {milli} "
             f"(multiply by 1e-3)")
    if kind == "command" and peak > 1.5:
        hint = ("looks like percent (multiply by 0.01)" if peak <= 100.0 else
                "not a normalised command")
        fail(f"largest |value| is {peak:g} (normalised, |u| ≤ 1): {hint}")
    lo, hi = float(np.min(x)), float(np.max(x))
    if lo < spec.plausible_min or hi > spec.plausible_max:
        hint = {"pressure": "absolute instead of gauge, psi/kPa, or a sensor offset?",
                "angle": "degrees, or a reference offset?",
                "motor_speed": "rpm (multiply by 2π/60)?",
                "temperature": "°F, or °C?"}.get(kind, "wrong unit or scale?")
        warnings.warn(f"{path}: {name}: values {lo:g}…{hi:g} {spec.unit} lie outside the "
                      f"plausible {spec.plausible_min:g}…{spec.plausible_max:g} {spec.unit}: "
                      f"{hint}", UnitWarning, stacklevel=4)
    if kind == "pressure" and 1000.0 <= peak < 1.0e5:
        warnings.warn(f"{path}: {name}: largest |value| is {peak:g} Pa (< 1 bar): kPa or psi, "
                      f"or really a low-pressure line?", UnitWarning, stacklevel=4)


def _row(i: int, csv: bool) -> str:
    return f"row {i} (line {i + 2} of the CSV)" if csv else f"row {i}"


def _check_time(path, t: np.ndarray, csv: bool, unit_checks: bool = True) -> float:
    """Validate ``time_s``; return the median sample period [s]."""
    n = len(t)
    if n < MIN_SAMPLES:
        raise MeasuredDataError(path, "time_s", f"{n} samples; at least {MIN_SAMPLES} needed")
    dt = np.diff(t)
    bad = np.flatnonzero(~(dt > 0.0))
    if bad.size:
        i = int(bad[0]) + 1
        raise MeasuredDataError(
            path, "time_s", f"not strictly increasing at {_row(i, csv)}: {t[i]!r} s after "
            f"{t[i - 1]!r} s ({bad.size} such rows); time must strictly increase")
    med = float(np.median(dt))
    off = np.flatnonzero(np.abs(dt / med - 1.0) > SAMPLING_TOLERANCE)
    if off.size:
        k = int(np.argmax(dt))
        first = int(off[0]) + 1
        raise MeasuredDataError(
            path, "time_s", f"non-uniform sampling: {off.size} intervals outside "
            f"{1 - SAMPLING_TOLERANCE:g}…{1 + SAMPLING_TOLERANCE:g} × the median {med:g} s, "
            f"first before {_row(first, csv)} (t = {t[first]:g} s, interval "
            f"{dt[first - 1]:g} s); largest gap {dt[k]:g} s before {_row(k + 1, csv)} "
            f"(t = {t[k + 1]:g} s). Resample to a uniform rate or split the record")
    if unit_checks and med >= MAX_SAMPLE_PERIOD_S:
        raise MeasuredDataError(
            path, "time_s", f"median sample period {med:g} (values {t[0]:g}…{t[-1]:g}, "
            f"{n} samples, i.e. {1.0 / med:g} Hz and {t[-1] - t[0]:g} s if in seconds): "
            f"looks like milliseconds (multiply by 1e-3); expected s, sampled faster than "
            f"{1.0 / MAX_SAMPLE_PERIOD_S:g} Hz (period < {MAX_SAMPLE_PERIOD_S:g} s), as a "
            f"hydraulic or gait signal needs")
    return med


def _check_values(path, name: str, x: np.ndarray, csv: bool) -> None:
    bad = ~np.isfinite(x)
    if bad.any():
        i = int(np.argmax(bad))
        raise MeasuredDataError(
            path, name, f"{int(bad.sum())} non-finite values (NaN/inf), first {x[i]!r} at "
            f"{_row(i, csv)}; every value must be finite (cut the record or fill the gap)")


def _check_roles(path, inputs, outputs, columns) -> None:
    for key, names in (("inputs", inputs), ("outputs", outputs)):
        if not isinstance(names, (list, tuple)):
            raise MeasuredDataError(path, key, f"a list of channel names, got {names!r}")
        seen = set()
        for name in names:
            _check_channel_name(path, key, name)
            if name in seen:
                raise MeasuredDataError(path, key, f"{name!r} listed twice")
            seen.add(name)
            spec = CHANNELS[name]
            if key == "inputs" and not spec.as_input:
                ok = [c.name for c in CHANNELS.values() if c.as_input]
                raise MeasuredDataError(path, key, f"{name!r} cannot drive the model; "
                                        f"channels usable as inputs: {', '.join(ok)}")
            if key == "outputs" and not spec.as_output:
                ok = [c.name for c in CHANNELS.values() if c.as_output]
                raise MeasuredDataError(path, key, f"{name!r} is not a model output; "
                                        f"channels usable as outputs: {', '.join(ok)}")
            if name not in columns:
                raise MeasuredDataError(path, f"{key}: {name}", f"listed in {key} but not a "
                                        f"column of the data file; columns: "
                                        f"{', '.join(columns)}")
    if not outputs:
        raise MeasuredDataError(path, "outputs", "empty; at least one output channel needed")
    for name in set(inputs) & set(outputs):
        if not CHANNELS[name].input_and_output:
            ok = [c.name for c in CHANNELS.values() if c.input_and_output]
            raise MeasuredDataError(
                path, name, f"listed as both input and output; only {', '.join(ok)} may be "
                f"both (imposed and measured)")


def _check_noise(path, noise, channels: dict) -> dict[str, float]:
    if not isinstance(noise, Mapping):
        raise MeasuredDataError(path, "noise", f"a table channel = σ, got {noise!r}")
    out = {}
    for name, sigma in noise.items():
        _check_channel_name(path, "noise", name)
        if name not in channels:
            raise MeasuredDataError(path, f"noise.{name}", f"noise given for a channel not in "
                                    f"the data file; columns: {', '.join(channels)}")
        if isinstance(sigma, bool) or not isinstance(sigma, (int, float)) or \
                not math.isfinite(sigma) or sigma <= 0.0:
            raise MeasuredDataError(path, f"noise.{name}", f"{sigma!r}: the standard deviation "
                                    f"must be a finite number > 0 in {CHANNELS[name].unit}")
        x = channels[name]
        span = float(np.max(x) - np.min(x))
        if span > 0.0 and sigma > span:
            warnings.warn(f"{path}: noise.{name}: σ = {sigma:g} {CHANNELS[name].unit} exceeds "
                          f"the channel's whole span {span:g}: wrong unit?", UnitWarning,
                          stacklevel=3)
        out[name] = float(sigma)
    return out


def _check_hold(path, hold, inputs) -> dict[str, str]:
    """The sidecar's ``[hold]`` table: input channel → one of :data:`HOLD_VALUES`."""
    if not isinstance(hold, Mapping):
        raise MeasuredDataError(path, "hold", f"a table input channel = "
                                f"{' | '.join(repr(v) for v in HOLD_VALUES)}, got {hold!r}")
    out = {}
    for name, v in hold.items():
        _check_channel_name(path, "hold", name)
        if name not in inputs:
            raise MeasuredDataError(path, f"hold.{name}", f"hold declared for a channel that is "
                                    f"not an input; inputs: {', '.join(inputs) or '(none)'}")
        if v not in HOLD_VALUES:
            raise MeasuredDataError(path, f"hold.{name}", f"{v!r}; allowed: "
                                    f"{', '.join(repr(h) for h in HOLD_VALUES)}")
        out[name] = v
    return out


def _float_list(path, key, v) -> list[float]:
    if not isinstance(v, (list, tuple)) or not v or not all(
            isinstance(a, (int, float)) and not isinstance(a, bool) and math.isfinite(a)
            for a in v):
        raise MeasuredDataError(path, key, f"{v!r}: a non-empty list of finite times in s")
    a = [float(x) for x in v]
    if any(b <= c for c, b in zip(a, a[1:])):
        raise MeasuredDataError(path, key, f"{v!r}: times must strictly increase")
    return a


def _check_segments(path, seg, t: np.ndarray, dt: float) -> dict:
    if not isinstance(seg, Mapping):
        raise MeasuredDataError(path, "segments", f"a table, got {seg!r}")
    for k in seg:
        if k not in _SEGMENT_KEYS:
            raise MeasuredDataError(path, f"segments.{k}",
                                    f"unknown key{_closest(k, _SEGMENT_KEYS)}. "
                                    f"Allowed: {', '.join(_SEGMENT_KEYS)}")
    out = {}
    lo, hi = float(t[0]) - 0.01 * dt, float(t[-1]) + 1.01 * dt
    for key in ("cycle_starts_s", "boundaries_s"):
        if key in seg:
            a = _float_list(path, f"segments.{key}", seg[key])
            if a[0] < lo or a[-1] > hi:
                raise MeasuredDataError(path, f"segments.{key}", f"{seg[key]!r}: outside the "
                                        f"record {t[0]:g}…{t[-1]:g} s")
            out[key] = tuple(a)
    if "cycle_starts_s" in seg and "period_s" in seg:
        raise MeasuredDataError(path, "segments", "both cycle_starts_s and period_s given; "
                                "give one of them")
    if "phase_s" in seg and "period_s" not in seg:
        raise MeasuredDataError(path, "segments.phase_s", "needs period_s")
    for key in ("period_s", "phase_s"):
        if key in seg:
            v = seg[key]
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
                raise MeasuredDataError(path, f"segments.{key}", f"{v!r}: a finite time in s")
            out[key] = float(v)
    if "period_s" in out and out["period_s"] < 2.0 * dt:
        raise MeasuredDataError(path, "segments.period_s", f"{out['period_s']!r}: must be "
                                f"> 2 sample periods ({2 * dt:g} s)")
    return out


# ---------------------------------------------------------------------------------- data


@dataclasses.dataclass(frozen=True, eq=False)
class MeasuredData:
    """A validated measured record. Arrays are read-only; times in s, channels in the units of
    :data:`CHANNELS`.

    ``channels``: every data column but ``time_s``; ``inputs``/``outputs``: channel names
    (a subset of ``channels``); ``noise``: channel → σ in its unit; ``source``: the sidecar's
    ``[source]`` table; ``sample_period_s``: the median interval; ``segments``: the validated
    ``[segments]`` table; ``path``: the data file (``None`` for a record made in memory);
    ``hold``: the sidecar's ``[hold]`` table, input channel → ``"zero_order"`` or
    ``"linear"`` (how the input was produced between its samples; undeclared channels absent).
    """

    time_s: np.ndarray
    channels: Mapping[str, np.ndarray]
    inputs: tuple[str, ...]
    outputs: tuple[str, ...]
    noise: Mapping[str, float]
    source: Mapping[str, str]
    sample_period_s: float
    segments: Mapping[str, object]
    path: Path | None = None
    hold: Mapping[str, str] = dataclasses.field(default_factory=lambda: MappingProxyType({}))

    @property
    def n_samples(self) -> int:
        return len(self.time_s)

    @property
    def duration_s(self) -> float:
        """Time covered: last − first sample plus one period."""
        return float(self.time_s[-1] - self.time_s[0]) + self.sample_period_s

    def window(self, t0_s: float, t1_s: float) -> "MeasuredData":
        """The samples with ``t0_s ≤ t < t1_s`` (half-open, so adjacent windows share no
        sample), with segment times inside the window kept. Time is not shifted."""
        tol = 0.01 * self.sample_period_s
        i0 = int(np.searchsorted(self.time_s, t0_s - tol, "left"))
        i1 = int(np.searchsorted(self.time_s, t1_s - tol, "left"))
        if i1 - i0 < 2:
            raise MeasuredDataError(self.path, "window", f"[{t0_s:g}, {t1_s:g}) s holds "
                                    f"{max(i1 - i0, 0)} samples; at least 2 needed (record "
                                    f"{self.time_s[0]:g}…{self.time_s[-1]:g} s)")
        seg = dict(self.segments)
        for key in ("cycle_starts_s", "boundaries_s"):
            if key in seg:
                kept = tuple(s for s in seg[key] if t0_s - tol <= s <= t1_s + tol)
                if kept:
                    seg[key] = kept
                else:
                    del seg[key]
        return dataclasses.replace(
            self, time_s=_ro(self.time_s[i0:i1]),
            channels=MappingProxyType({k: _ro(v[i0:i1]) for k, v in self.channels.items()}),
            segments=MappingProxyType(seg))

    def cycles_s(self) -> list[tuple[float, float]]:
        """The whole cycles ``[start, end)`` in s from ``cycle_starts_s`` or
        ``period_s``/``phase_s``; a cycle is whole when the record covers it to its end."""
        dt = self.sample_period_s
        t_first, t_end = float(self.time_s[0]), float(self.time_s[-1]) + dt
        seg = self.segments
        if "cycle_starts_s" in seg:
            b = list(seg["cycle_starts_s"])
        elif "period_s" in seg:
            period, phase = seg["period_s"], seg.get("phase_s", t_first)
            k0 = math.ceil((t_first - phase) / period - 1e-6)
            count = int((t_end - t_first) / period) + 3
            b = [phase + k * period for k in range(k0, k0 + count)]
        else:
            raise MeasuredDataError(self.path, "segments", "split by cycles needs "
                                    "segments.cycle_starts_s or segments.period_s")
        tol = 0.01 * dt
        b = [x for x in b if t_first - tol <= x <= t_end + tol]
        return list(zip(b, b[1:]))

    def segments_s(self) -> list[tuple[float, float]]:
        """The segments ``[start, end)`` in s from ``boundaries_s`` (the last runs to the
        record's end)."""
        if "boundaries_s" not in self.segments:
            raise MeasuredDataError(self.path, "segments", "split by segments needs "
                                    "segments.boundaries_s")
        b = list(self.segments["boundaries_s"])
        t_end = float(self.time_s[-1]) + self.sample_period_s
        return [(a, c) for a, c in zip(b, b[1:] + [t_end]) if c > a]

    def split(self, held_out_fraction: float = 0.3, by: str = "cycles"
              ) -> tuple["MeasuredData", "MeasuredData"]:
        """(train, test): the record cut once, test the last ``held_out_fraction`` of it.

        ``by="cycles"``: whole cycles (``round(fraction · n)``, at least 1 and at most n − 1
        of them held out); ``"segments"``: whole segments likewise; ``"tail"``: the last
        fraction of the samples. Never interleaved samples: train and test are each one
        contiguous block, train before test, so that correlated neighbours of test samples
        are not fitted.
        """
        if not (isinstance(held_out_fraction, (int, float))
                and 0.0 < held_out_fraction < 1.0):
            raise MeasuredDataError(self.path, "held_out_fraction",
                                    f"{held_out_fraction!r}: must lie in (0, 1)")
        if by == "tail":
            n = self.n_samples
            k = min(max(int(round(n * (1.0 - held_out_fraction))), 2), n - 2)
            t = self.time_s
            return (self.window(float(t[0]), float(t[k])),
                    self.window(float(t[k]), float(t[-1]) + self.sample_period_s))
        if by == "cycles":
            pieces = self.cycles_s()
        elif by == "segments":
            pieces = self.segments_s()
        else:
            raise MeasuredDataError(self.path, "by", f"{by!r}: one of 'cycles', 'segments', "
                                    f"'tail'")
        n = len(pieces)
        if n < 2:
            raise MeasuredDataError(self.path, "segments", f"{n} whole {by} in the record; "
                                    f"at least 2 needed to hold one out")
        n_test = min(max(int(round(n * held_out_fraction)), 1), n - 1)
        cut = pieces[n - n_test][0]
        return (self.window(pieces[0][0], cut), self.window(cut, pieces[-1][1]))


def _ro(a: np.ndarray) -> np.ndarray:
    """A read-only float array (a copy where the given one is writeable)."""
    a = np.asarray(a, dtype=float)
    if a.flags.writeable:
        a = a.copy()
        a.flags.writeable = False
    return a


def _build(path, side, table: dict[str, np.ndarray], meta: Mapping, csv: bool,
           unit_checks: bool) -> MeasuredData:
    """Validate the columns ``table`` of the data file ``path`` (``time_s`` first) against the
    sidecar ``meta`` (from ``side``: errors in it name that file)."""
    cols = list(table)
    if not cols or cols[0] != "time_s":
        where = cols.index("time_s") if "time_s" in cols else None
        raise MeasuredDataError(path, "time_s", "the first column must be time_s; " + (
            f"found at column {where}" if where is not None else
            f"no time_s column (columns: {', '.join(cols)})"))
    for name in cols[1:]:
        _check_channel_name(path, "columns", name)
    for name, x in table.items():
        _check_values(path, name, x, csv)
    t = table["time_s"]
    dt = _check_time(path, t, csv, unit_checks)
    channels = {k: v for k, v in table.items() if k != "time_s"}
    inputs, outputs = meta.get("inputs", []), meta.get("outputs", [])
    _check_roles(side, inputs, outputs, list(channels))
    noise = _check_noise(side, meta.get("noise", {}), channels)
    segments = _check_segments(side, meta.get("segments", {}), t, dt)
    source = _check_source(side, meta.get("source"))
    hold = _check_hold(side, meta.get("hold", {}), list(inputs))
    if unit_checks:
        for name, x in channels.items():
            _unit_check(path, CHANNELS[name], x)
    unused = [c for c in channels if c not in inputs and c not in outputs]
    if unused:
        warnings.warn(f"{path}: columns {', '.join(unused)} are neither inputs nor outputs; "
                      f"kept but replay ignores them", MeasuredDataWarning, stacklevel=3)
    return MeasuredData(
        time_s=_ro(t), channels=MappingProxyType({k: _ro(v) for k, v in channels.items()}),
        inputs=tuple(inputs), outputs=tuple(outputs), noise=MappingProxyType(noise),
        source=MappingProxyType(source), sample_period_s=dt,
        segments=MappingProxyType(segments), path=None if path is None else Path(path),
        hold=MappingProxyType(hold))


def _check_source(path, source) -> dict[str, str]:
    if source is None:
        raise MeasuredDataError(path, "source", "missing [source] table; give scenario = "
                                "\"...\" and/or preset = \"...\"")
    if not isinstance(source, Mapping):
        raise MeasuredDataError(path, "source", f"a table, got {source!r}")
    for k, v in source.items():
        if k not in _SOURCE_KEYS:
            raise MeasuredDataError(path, f"source.{k}",
                                    f"unknown key{_closest(k, _SOURCE_KEYS)}. "
                                    f"Allowed: {', '.join(_SOURCE_KEYS)}")
        if not isinstance(v, str) or not v.strip():
            raise MeasuredDataError(path, f"source.{k}", f"{v!r}: a non-empty string")
    if "scenario" not in source and "preset" not in source:
        raise MeasuredDataError(path, "source", "needs scenario = \"...\" (the scenario file) "
                                "and/or preset = \"...\" (the device preset)")
    return dict(source)


# ---------------------------------------------------------------------------------- reading


def _pyarrow():
    try:
        import pyarrow
        import pyarrow.parquet
    except ImportError as exc:  # pragma: no cover - pyarrow comes with rerun-sdk
        raise ImportError("Parquet measured data needs pyarrow (pip install pyarrow; it comes "
                          "with rerun-sdk), or write the data as CSV") from exc
    return pyarrow


def _kind(path: Path) -> str:
    suffix = path.suffix.lower()
    if suffix == ".csv":
        return "csv"
    if suffix in (".parquet", ".pq"):
        return "parquet"
    raise MeasuredDataError(path, "file", f"suffix {path.suffix!r}: the data file must be "
                            f".csv or .parquet")


def _read_csv(path: Path) -> dict[str, np.ndarray]:
    with open(path, encoding="utf-8-sig", newline="") as f:
        text = f.read()
    lines = text.splitlines()
    if not lines or not lines[0].strip():
        raise MeasuredDataError(path, "header", "empty file; the first line must name the "
                                "columns, first time_s")
    names = [c.strip() for c in lines[0].split(",")]
    dup = sorted({c for c in names if names.count(c) > 1})
    if dup:
        raise MeasuredDataError(path, "header", f"columns named twice: {', '.join(dup)}")
    body = [ln for ln in lines[1:]]
    while body and not body[-1].strip():
        body.pop()
    rows = np.empty((len(body), len(names)))
    for i, ln in enumerate(body):
        fields = ln.split(",")
        if len(fields) != len(names):
            raise MeasuredDataError(path, f"line {i + 2}", f"{len(fields)} fields, the header "
                                    f"has {len(names)}")
        try:
            rows[i] = [float(x) for x in fields]
        except ValueError:
            for j, x in enumerate(fields):
                try:
                    float(x)
                except ValueError:
                    raise MeasuredDataError(path, names[j], f"{x.strip()!r} at {_row(i, True)}"
                                            f" is not a number (SI units, no unit suffixes)"
                                            ) from None
    return {n: rows[:, j].copy() for j, n in enumerate(names)}


def _read_parquet(path: Path) -> dict[str, np.ndarray]:
    pa = _pyarrow()
    try:
        table = pa.parquet.read_table(path)
    except Exception as exc:
        raise MeasuredDataError(path, "file", f"not a readable Parquet file ({exc})") from exc
    out = {}
    for name in table.column_names:
        col = table.column(name)
        if not (pa.types.is_floating(col.type) or pa.types.is_integer(col.type)):
            raise MeasuredDataError(path, name, f"column type {col.type}; numbers (float64) "
                                    f"needed")
        out[name] = col.to_numpy(zero_copy_only=False).astype(float)
    if len(set(table.column_names)) != len(table.column_names):
        raise MeasuredDataError(path, "header", "a column is named twice")
    return out


def _read_sidecar(path: Path) -> dict:
    if not path.is_file():
        raise MeasuredDataError(path, "sidecar", "missing; every data file needs its TOML "
                                "sidecar (same stem, .toml) or one given explicitly")
    try:
        with open(path, "rb") as f:
            meta = tomllib.load(f)
    except tomllib.TOMLDecodeError as exc:
        raise MeasuredDataError(path, "sidecar", f"not valid TOML: {exc}") from exc
    for k in meta:
        if k not in _TOP_KEYS:
            raise MeasuredDataError(path, k, f"unknown key{_closest(k, _TOP_KEYS)}. Allowed: "
                                    f"{', '.join(_TOP_KEYS)}")
    if meta.get("format") != FORMAT:
        raise MeasuredDataError(path, "format", f"{meta.get('format')!r}; this reader "
                                f"reads format = {FORMAT!r}")
    return meta


def load_measured(path, sidecar=None, *, unit_checks: bool = True) -> MeasuredData:
    """Read and validate a measured record: the data file ``path`` (``.csv`` or ``.parquet``)
    and its sidecar (``sidecar``, default ``path`` with the suffix ``.toml``).

    Raises :class:`MeasuredDataError` on anything that would give a wrong fit (the message
    names the file, the key or channel, the value and what is allowed); warns
    (:class:`UnitWarning`, :class:`MeasuredDataWarning`) on what is merely implausible.
    ``unit_checks=False`` skips the magnitude tests for a record known to be right.

    Example: ``d = load_measured("bench_01.csv"); train, test = d.split(0.3)``.
    """
    path = Path(path)
    kind = _kind(path)
    side = Path(sidecar) if sidecar is not None else path.with_suffix(".toml")
    meta = _read_sidecar(side)
    if not path.is_file():
        raise MeasuredDataError(path, "file", "missing data file")
    table = _read_csv(path) if kind == "csv" else _read_parquet(path)
    return _build(path, side, table, meta, kind == "csv", unit_checks)


# ---------------------------------------------------------------------------------- writing


def _toml_value(v) -> str:
    if isinstance(v, str):
        return json.dumps(v, ensure_ascii=False)
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, (int, np.integer)):
        return str(int(v))
    if isinstance(v, (float, np.floating)):
        return repr(float(v))
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    raise TypeError(f"cannot write {v!r} to TOML")


def _sidecar_text(inputs, outputs, source, noise, segments, hold=None) -> str:
    lines = [f"format = {_toml_value(FORMAT)}", f"inputs = {_toml_value(list(inputs))}",
             f"outputs = {_toml_value(list(outputs))}", "", "[source]"]
    lines += [f"{k} = {_toml_value(v)}" for k, v in source.items()]
    for name, table in (("noise", noise), ("segments", segments), ("hold", hold)):
        if table:
            lines += ["", f"[{name}]"] + [f"{k} = {_toml_value(v)}" for k, v in table.items()]
    return "\n".join(lines) + "\n"


def write_measured(path, data_dict: Mapping[str, Sequence[float]], inputs: Sequence[str],
                   outputs: Sequence[str], source: Mapping[str, str],
                   noise: Mapping[str, float] | None = None,
                   segments: Mapping[str, object] | None = None, fmt: str | None = None,
                   *, unit_checks: bool = True,
                   hold: Mapping[str, str] | None = None) -> MeasuredData:
    """Write a measured record: the data file ``path`` and its sidecar (same stem, ``.toml``).

    ``data_dict``: ``time_s`` and channels → 1-D arrays of equal length (written in this
    order, ``time_s`` first); ``fmt``: ``"csv"`` or ``"parquet"``, by default from the suffix
    of ``path`` (which must agree); ``hold``: the sidecar's ``[hold]`` table (input channel →
    ``"zero_order"`` or ``"linear"``). Everything is validated exactly as :func:`load_measured`
    would before a byte is written; both files are written to temporary names and moved into
    place with :func:`os.replace`, so a failure leaves no half-written file. Returns the
    validated record.
    """
    path = Path(path)
    kind = _kind(path)
    if fmt is not None and fmt != kind:
        raise MeasuredDataError(path, "fmt", f"{fmt!r} but the suffix says {kind!r}; use "
                                f".csv for 'csv', .parquet for 'parquet'")
    if "time_s" not in data_dict:
        raise MeasuredDataError(path, "time_s", "data_dict has no time_s")
    order = ["time_s"] + [k for k in data_dict if k != "time_s"]
    table = {}
    for k in order:
        a = np.asarray(data_dict[k], dtype=float)
        if a.ndim != 1:
            raise MeasuredDataError(path, k, f"shape {a.shape}; 1-D arrays needed")
        table[k] = a
    lengths = {k: len(v) for k, v in table.items()}
    if len(set(lengths.values())) != 1:
        raise MeasuredDataError(path, "data_dict", f"channels differ in length: {lengths}")
    meta = {"inputs": list(inputs), "outputs": list(outputs), "source": dict(source),
            "noise": dict(noise or {}), "segments": dict(segments or {}),
            "hold": dict(hold or {})}
    side = path.with_suffix(".toml")
    data = _build(path, side, table, meta, kind == "csv", unit_checks)
    text = _sidecar_text(data.inputs, data.outputs, data.source, data.noise,
                         {k: list(v) if isinstance(v, tuple) else v
                          for k, v in data.segments.items()}, dict(data.hold))
    tmp_data = path.with_name(f".{path.name}.tmp{os.getpid()}")
    tmp_side = side.with_name(f".{side.name}.tmp{os.getpid()}")
    try:
        if kind == "csv":
            with open(tmp_data, "w", encoding="utf-8", newline="") as f:
                f.write(",".join(order) + "\n")
                cols = np.column_stack([table[k] for k in order])
                for row in cols.tolist():
                    f.write(",".join(map(repr, row)) + "\n")
        else:
            pa = _pyarrow()
            pa.parquet.write_table(pa.table({k: table[k] for k in order}), tmp_data)
        with open(tmp_side, "w", encoding="utf-8") as f:
            f.write(text)
        os.replace(tmp_data, path)
        os.replace(tmp_side, side)
    finally:
        for tmp in (tmp_data, tmp_side):
            if tmp.exists():
                tmp.unlink()
    return dataclasses.replace(data, path=path)


# ---------------------------------------------------------------------------------- summary


def describe(data: MeasuredData) -> str:
    """A short human summary: file, source, duration, rate, and each channel with its role,
    unit, range and noise."""
    src = ", ".join(f"{k} {v!r}" for k, v in data.source.items()
                    if k in ("scenario", "preset"))
    lines = [f"measured data {data.path if data.path else '(in memory)'}",
             f"  source: {src}",
             f"  {data.n_samples} samples, {data.duration_s:.4g} s from {data.time_s[0]:.4g} s, "
             f"{1.0 / data.sample_period_s:.4g} Hz (period {data.sample_period_s:.4g} s)"]
    if data.segments:
        seg = []
        if "cycle_starts_s" in data.segments or "period_s" in data.segments:
            seg.append(f"{len(data.cycles_s())} whole cycles")
        if "boundaries_s" in data.segments:
            seg.append(f"{len(data.segments_s())} segments")
        lines.append("  " + ", ".join(seg))
    width = max(len(k) for k in data.channels)
    for name, x in data.channels.items():
        spec = CHANNELS[name]
        role = ("in+out" if name in data.inputs and name in data.outputs else
                "in" if name in data.inputs else "out" if name in data.outputs else "unused")
        noise = f", σ {data.noise[name]:.3g}" if name in data.noise else ""
        noise += f", hold {data.hold[name]}" if name in data.hold else ""
        lines.append(f"  {name:<{width}}  {role:<6} [{spec.unit}] "
                     f"{float(np.min(x)):.4g} … {float(np.max(x)):.4g}{noise}")
    return "\n".join(lines)
