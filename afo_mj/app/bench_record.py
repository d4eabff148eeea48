"""A synthetic bench record with effects the lean model does not declare:
``afo-mj make-bench-record`` (test data for ``calibrate``; the generator is
:func:`afo_mj.calibration.synthetic_records.generate_record`)."""

from __future__ import annotations

import warnings
from typing import Mapping

from afo_mj.app.errors import InvalidInput

__all__ = ["make_bench_record"]


def parse_pairs(items, what: str) -> dict:
    """``NAME=VALUE`` strings as a dict of floats (:class:`InvalidInput` naming the bad one;
    ``what`` names the option)."""
    out = {}
    for it in items or []:
        k, sep, v = it.partition("=")
        if not sep:
            raise InvalidInput(f"{what} {it!r}; allowed: NAME=VALUE")
        try:
            out[k.strip()] = float(v)
        except ValueError:
            raise InvalidInput(f"{what} {it!r}: {v!r} is not a number") from None
    return out


def parse_effects(items) -> dict:
    """``NAME[:PARAM=VALUE,...]`` strings (``--effect``) as effect name → parameters."""
    effects = {}
    for spec in items or []:
        name, _, rest = spec.partition(":")
        effects[name.strip()] = parse_pairs([p for p in rest.split(",") if p], "--effect")
    return effects


def make_bench_record(out_path, kind: str = "hafo", effects: Mapping[str, Mapping] = (),
                      mismatch: Mapping[str, float] = (), preset: str | None = None,
                      noise_scale: float = 1.0, duration_s: float = 20.0,
                      fs_hz: float = 1000.0, seed: int = 0, resonance_hz: float = 0.0):
    """Write the record and its sidecar; returns the loaded record
    (:class:`afo_mj.calibration.measured_data.MeasuredRecord`). ``effects``: effect name →
    {parameter: value}; ``mismatch``: declared parameter → scale factor. Raises
    :class:`~afo_mj.app.errors.InvalidInput` naming what is not allowed."""
    from afo_mj.calibration.measured_data import MeasuredDataError
    from afo_mj.calibration.synthetic_records import generate_record
    from afo_mj.devices.registry import device_entry
    from afo_mj.hydraulics.params import ParameterError
    try:
        if preset is not None:
            device_entry(preset, key="--preset")
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            return generate_record(out_path, kind, dict(effects or {}), dict(mismatch or {}),
                                   noise_scale=noise_scale, duration_s=duration_s,
                                   fs_hz=fs_hz, seed=seed, preset=preset,
                                   torque_sensor_resonance_hz=resonance_hz)
    except (ParameterError, MeasuredDataError, OSError) as exc:
        raise InvalidInput(str(exc)) from None
