"""Ankle test-stand scenarios: a device on the bench instead of on a walker.

A bench scenario is a TOML file with a ``[bench]`` table (and no ``[walker]``/``[gait]``)::

    name = "bench_hafo"
    description = "..."

    [device]
    preset = "hafo"                 # a device preset (afo_mj.devices.hafo.PRESETS)
    [device.params]                 # optional dotted overrides, e.g. "hose.length_m" = 2.2

    [bench]
    tests = ["torque_velocity", "isometric_steps", "frequency_response", "position_step"]
    timestep_s = 2.5e-4             # optional; each test's default otherwise
    body_mass_kg = 75.0             # the stand's foot is sized for this wearer
    height_m = 1.75

``afo-mj run`` runs it through :func:`afo_mj.scenarios.hafo_bench.run_bench` and writes
``summary.json`` with the ``bench.*`` figures (``bench.stall_torque_nm``,
``bench.no_load_speed_deg_s``, ``bench.bandwidth_hz``, ``bench.rise_time_s``, …), the energy
balance of the worst run (``energy.balance_error_rel``), the device masses, the published
figures for comparison, and the bench PNGs. ``--set bench.tests='["torque_velocity"]'`` or
``--set device.params.hose.length_m=2.2`` override values as for walking scenarios.
"""

from __future__ import annotations

import dataclasses
import math
import re
import tomllib
from pathlib import Path
from types import MappingProxyType
from typing import Any, Mapping

from afo_mj.scenarios.device_scenario import device_params
from afo_mj.scenarios.walk_scenario import ScenarioError, apply_overrides

TOP_KEYS = ("name", "description", "device", "bench")
DEVICE_KEYS = ("preset", "params")
BENCH_KEYS = ("tests", "timestep_s", "body_mass_kg", "height_m")
_NAME_RE = re.compile(r"^[A-Za-z0-9_.\-]+$")


@dataclasses.dataclass(frozen=True)
class BenchScenario:
    """A validated bench scenario (see the module docstring)."""

    name: str
    description: str
    preset: str
    params: Any                       # PumpAnkleParams
    overrides: Mapping[str, Any]
    tests: tuple[str, ...]
    timestep_s: float | None
    body_mass_kg: float
    height_m: float
    source_path: Path | None = None
    text: str = ""

    def as_dict(self) -> dict:
        return {"name": self.name, "description": self.description, "kind": "bench",
                "file": None if self.source_path is None else str(self.source_path),
                "device": {"preset": self.preset, "params": dict(self.overrides)},
                "bench": {"tests": list(self.tests), "timestep_s": self.timestep_s,
                          "body_mass_kg": self.body_mass_kg, "height_m": self.height_m}}


def is_bench_document(text: str) -> bool:
    """Whether TOML ``text`` is a bench scenario (has a ``[bench]`` table)."""
    try:
        return "bench" in tomllib.loads(text)
    except tomllib.TOMLDecodeError:
        return False


def parse_bench_scenario(text: str, origin: str = "<bench>", default_name: str = "bench",
                         source_path: Path | None = None, overrides=()) -> BenchScenario:
    """Validate a bench scenario; raises :class:`ScenarioError` naming key, value, allowed."""
    from afo_mj.scenarios.hafo_bench import BENCH_TESTS

    def fail(key, value, allowed):
        return ScenarioError(f"{origin}: {key} = {value!r} is not allowed; allowed: {allowed}")

    try:
        doc = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ScenarioError(f"{origin}: not valid TOML: {exc}") from None
    apply_overrides(doc, overrides, origin)
    for k in doc:
        if k not in TOP_KEYS:
            raise fail(k, doc[k], "top-level keys " + ", ".join(TOP_KEYS)
                       + " (a bench scenario has no walker or gait)")
    name = doc.get("name", default_name)
    if not isinstance(name, str) or not _NAME_RE.match(name):
        raise fail("name", name, "letters, digits, _ . - (non-empty)")
    description = doc.get("description", "")
    if not isinstance(description, str):
        raise fail("description", description, "a string")
    dev = doc.get("device", {})
    bench = doc.get("bench", {})
    for tbl, keys, label in ((dev, DEVICE_KEYS, "device"), (bench, BENCH_KEYS, "bench")):
        if not isinstance(tbl, dict):
            raise fail(label, tbl, "a table")
        for k in tbl:
            if k not in keys:
                raise fail(f"{label}.{k}", tbl[k], "keys " + ", ".join(keys))
    preset, params, ov = device_params(dev, origin)
    tests = bench.get("tests", list(BENCH_TESTS))
    if (not isinstance(tests, list) or not tests or len(set(tests)) != len(tests)
            or any(t not in BENCH_TESTS for t in tests)):
        raise fail("bench.tests", tests, "a non-empty list of distinct " + ", ".join(BENCH_TESTS))

    def number(key, lo, hi, default):
        v = bench.get(key, default)
        if v is None:
            return None
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) \
                or not lo <= v <= hi:
            raise fail(f"bench.{key}", v, f"a number in [{lo:g}, {hi:g}]")
        return float(v)

    return BenchScenario(name=name, description=description, preset=preset, params=params,
                         overrides=MappingProxyType(dict(ov)), tests=tuple(tests),
                         timestep_s=number("timestep_s", 1e-5, 2e-3, None),
                         body_mass_kg=number("body_mass_kg", 10.0, 200.0, 75.0),
                         height_m=number("height_m", 0.8, 2.2, 1.75),
                         source_path=source_path, text=text)


def load_bench_scenario(path, overrides=()) -> BenchScenario:
    p = Path(path)
    try:
        text = p.read_text(encoding="utf-8")
    except OSError as exc:
        raise ScenarioError(f"{p}: cannot read the scenario file ({exc.strerror or exc})") from None
    return parse_bench_scenario(text, origin=str(p), default_name=p.stem, source_path=p,
                                overrides=overrides)


def run_bench_scenario(bs: BenchScenario) -> tuple[dict, dict]:
    """Run the bench; returns ``(summary, series)`` with the ``bench.*`` names of issue 4."""
    from afo_mj.devices.hafo import HafoDevice
    from afo_mj.scenarios.hafo_bench import run_bench
    res, series = run_bench(bs.params, bs.tests, bs.body_mass_kg, bs.height_m,
                            timestep_s=bs.timestep_s)
    # wall time is not a result (it goes to run_info.json): a rerun gives the same summary
    res.pop("wall_time_s", None)
    scalars = {k: v for k, v in res.items()
               if isinstance(v, (int, float)) and not isinstance(v, bool)}
    detail = {k: v for k, v in res.items() if k not in scalars and k != "published"}
    dev = HafoDevice(bs.params)
    summary = {
        "format": "afo_mj bench summary v1",
        "scenario": bs.as_dict(),
        "bench": scalars,
        "bench_detail": detail,
        "published": res["published"],
        "device": {"preset": bs.preset, "mass_total_kg": dev.mass_total_kg,
                   "mass_at_ankle_kg": dev.mass_at_ankle_kg},
        "energy": {"balance_error_rel": res["energy_error_max"],
                   "note": "largest |residual| / max(|electrical in|, |mechanical out|) "
                           "over every bench run"},
    }
    return summary, series
