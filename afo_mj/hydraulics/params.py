"""Validated, frozen parameter sets addressable by dotted name.

Every component keeps its parameters in a frozen dataclass derived from :class:`Parameters`.
Each numeric field is declared with :func:`param`, which records its SI unit, its physically
allowed range and a one-line meaning. The range is checked when the object is built, so a bad
value fails at construction with one :class:`ParameterError` naming the field, the value and
what is allowed, never as a NaN later in a simulation. A subnormal float (non-zero, smaller in
magnitude than ``sys.float_info.min``) is refused in any range: an open bound at 0 would
admit it, and what is computed from it underflows to 0.

Physical effects that a model may or may not include are boolean fields declared with
:func:`effect` (names end in ``_enabled``). Calibration switches them on and off and fits the
numeric parameters that belong to them; :func:`flatten`, :func:`replace_named` and
:func:`effect_switches` give that access through dotted names such as
``"cylinder.seal.stribeck_enabled"`` or ``"pump.leakage_coefficient_m3"``.
"""

from __future__ import annotations

import dataclasses
import math
import sys
from typing import Any, Iterator, Mapping

__all__ = [
    "ParameterError",
    "Parameters",
    "param",
    "effect",
    "flatten",
    "replace_named",
    "effect_switches",
    "describe",
]


class ParameterError(ValueError):
    """A parameter value outside its physically allowed range (or of the wrong kind)."""


def param(
    default: float,
    *,
    unit: str,
    lo: float = -math.inf,
    hi: float = math.inf,
    lo_open: bool = False,
    hi_open: bool = False,
    doc: str = "",
) -> Any:
    """Declare a numeric parameter with its SI unit and allowed range.

    ``lo``/``hi`` are the bounds; ``lo_open``/``hi_open`` make them strict (e.g. a bore must be
    strictly positive: ``lo=0, lo_open=True``).
    """
    return dataclasses.field(
        default=default,
        metadata={"unit": unit, "lo": lo, "hi": hi, "lo_open": lo_open, "hi_open": hi_open,
                  "doc": doc, "kind": "number"},
    )


def effect(default: bool, *, doc: str) -> Any:
    """Declare a switch that includes (True) or removes (False) one physical effect."""
    return dataclasses.field(default=default, metadata={"doc": doc, "kind": "effect"})


def _range_text(name: str, md: Mapping[str, Any]) -> str:
    lo, hi = md["lo"], md["hi"]
    left = "" if lo == -math.inf else f"{lo:g} {'<' if md['lo_open'] else '<='} "
    right = "" if hi == math.inf else f" {'<' if md['hi_open'] else '<='} {hi:g}"
    unit = f" [{md['unit']}]" if md["unit"] else ""
    return f"{left}{name}{right}{unit}"


@dataclasses.dataclass(frozen=True)
class Parameters:
    """Base of every parameter set: range checks at construction, then :meth:`check`."""

    def __post_init__(self) -> None:
        cls = type(self).__name__
        for f in dataclasses.fields(self):
            value = getattr(self, f.name)
            kind = f.metadata.get("kind")
            if kind == "number":
                if isinstance(value, bool) or not isinstance(value, (int, float)):
                    raise ParameterError(
                        f"{cls}.{f.name} = {value!r} is not a number; "
                        f"allowed: {_range_text(f.name, f.metadata)}")
                v = float(value)
                md = f.metadata
                bad = ((not math.isfinite(v) and not (v == md["hi"] or v == md["lo"]))
                       or math.isnan(v))
                bad = bad or v < md["lo"] or (md["lo_open"] and v == md["lo"])
                bad = bad or v > md["hi"] or (md["hi_open"] and v == md["hi"])
                if bad:
                    raise ParameterError(
                        f"{cls}.{f.name} = {value!r} is out of range; "
                        f"allowed: {_range_text(f.name, md)}")
                if v != 0.0 and abs(v) < sys.float_info.min:
                    # a subnormal passes an open bound at 0, but products and powers of it
                    # underflow to 0 (a seal's contact width, a bore's area)
                    raise ParameterError(
                        f"{cls}.{f.name} = {value!r} is a subnormal float (magnitude below "
                        f"{sys.float_info.min:.3g}, no physical value); "
                        f"allowed: {_range_text(f.name, md)}, a normal float")
                object.__setattr__(self, f.name, v)
            elif kind == "effect":
                if not isinstance(value, bool):
                    raise ParameterError(
                        f"{cls}.{f.name} = {value!r} must be True or False (effect switch)")
        self.check()

    def check(self) -> None:
        """Cross-field rules (e.g. precharge below maximum pressure). Override and raise
        :class:`ParameterError` naming the fields involved."""

    def replace(self, **changes: Any) -> "Parameters":
        """A copy with some fields changed, validated again."""
        return dataclasses.replace(self, **changes)

    def fail(self, name: str, message: str) -> None:
        """Raise a :class:`ParameterError` for field ``name`` with its current value."""
        raise ParameterError(f"{type(self).__name__}.{name} = {getattr(self, name)!r}: {message}")


def _walk(obj: Parameters, prefix: str) -> Iterator[tuple[str, dataclasses.Field, Any]]:
    for f in dataclasses.fields(obj):
        value = getattr(obj, f.name)
        name = f"{prefix}{f.name}"
        if isinstance(value, Parameters):
            yield from _walk(value, name + ".")
        elif f.metadata.get("kind") in ("number", "effect"):
            yield name, f, value


def flatten(obj: Parameters) -> dict[str, float | bool]:
    """All numeric parameters and effect switches of ``obj`` (nested sets included) by dotted
    name."""
    return {name: value for name, _, value in _walk(obj, "")}


def effect_switches(obj: Parameters) -> dict[str, bool]:
    """The effect switches of ``obj`` (nested sets included) by dotted name."""
    return {name: value for name, f, value in _walk(obj, "") if f.metadata["kind"] == "effect"}


def describe(obj: Parameters) -> list[dict[str, Any]]:
    """One record per parameter: name, value, unit, allowed range and meaning (for tables/UIs)."""
    rows = []
    for name, f, value in _walk(obj, ""):
        md = f.metadata
        rows.append({
            "name": name, "value": value, "unit": md.get("unit", ""),
            "lo": md.get("lo"), "hi": md.get("hi"), "doc": md.get("doc", ""),
            "kind": md["kind"],
        })
    return rows


def replace_named(obj: Parameters, changes: Mapping[str, Any]) -> Parameters:
    """A copy of ``obj`` with parameters changed by dotted name; every level is re-validated.

    >>> replace_named(circuit_params, {"cylinder.bore_m": 0.02, "pump.leakage_enabled": False})

    A parameter set whose class has a ``PRESETS`` mapping can be replaced by a preset's name
    (``{"fluid": "ISO_VG22", "fluid.air_fraction": 0.002}``: the preset, then its changes).
    """
    grouped: dict[str, dict[str, Any]] = {}
    direct: dict[str, Any] = {}
    known = {f.name: f for f in dataclasses.fields(obj)}
    for key, value in changes.items():
        head, _, rest = key.partition(".")
        if head not in known:
            raise ParameterError(
                f"{type(obj).__name__} has no parameter {head!r} (from {key!r}); "
                f"known: {', '.join(sorted(known))}")
        if rest:
            sub = getattr(obj, head)
            if not isinstance(sub, Parameters):
                raise ParameterError(f"{type(obj).__name__}.{head} is not a parameter set; "
                                     f"cannot address {key!r}")
            grouped.setdefault(head, {})[rest] = value
        else:
            cur = getattr(obj, head)
            if isinstance(cur, Parameters):
                # a named preset of that parameter set (e.g. fluid = "ISO_VG22")
                presets = getattr(type(cur), "PRESETS", None)
                if isinstance(value, str) and presets:
                    if value not in presets:
                        raise ParameterError(f"{key} = {value!r}; allowed: "
                                             f"{', '.join(presets)}")
                    direct[head] = presets[value]
                    continue
                raise ParameterError(f"{key!r} names a parameter set, not a value"
                                     + (f" (or one of its presets: {', '.join(presets)})"
                                        if presets else ""))
            direct[head] = value
    for head, sub_changes in grouped.items():
        direct[head] = replace_named(direct.get(head, getattr(obj, head)), sub_changes)
    return dataclasses.replace(obj, **direct)
