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

``afo-mj run`` runs it through :func:`afo_mj.experiments.hafo_bench.run_bench` and writes
``summary.json`` with the ``bench.*`` figures (``bench.stall_torque_nm``,
``bench.no_load_speed_deg_s``, ``bench.bandwidth_hz``, ``bench.rise_time_s``, …), the energy
balance of the worst run (``energy.balance_error_rel``), the device masses, the published
figures for comparison, and the bench PNGs. ``--set bench.tests='["torque_velocity"]'`` or
``--set device.params.hose.length_m=2.2`` override values as for walking scenarios.

Bench kinds (``bench.kind``):

* ``"hafo"`` (the default): the HAFO tests above (``tests``).
* ``"stiffness"``: a clinical stiffness rig (:mod:`afo_mj.experiments.stiffness_bench`) for a
  valve-circuit orthosis that emulates springs (``device.preset = "phafo"``)::

    [bench]
    kind = "stiffness"
    stiffnesses_nm_per_deg = [1.0, 2.5, 4.6]   # commanded springs, one sweep each, (0, 20]
    amplitude_deg = 12.0            # imposed sinusoid about neutral, (0, 30]
    frequency_hz = 0.25             # 0.01 … 5
    cycles = 3                      # whole cycles, 2 … 20 (the first is dropped)
    damping_nm_s_per_deg = 0.0      # optional commanded damping, 0 … 5
    rest_angle_deg = 0.0            # optional rest angle of the spring, −20 … 20
    timestep_s = 5e-4               # optional (default 0.5 ms)
    body_mass_kg = 25.8             # the stand's foot
    height_m = 1.28

  ``summary.json`` holds ``stiffness.k<K>.*`` per commanded stiffness
  (``stiffness.k2.5.emulated_nm_per_deg``, ``.error_rel``, ``.hysteresis_energy_j``,
  ``.peak_torque_nm``, ``.peak_pressure_pa``, ``.electrical_in_j``,
  ``.energy_balance_error_rel``, …), ``acceptance`` (every emulated stiffness within 10 % of
  its command) and ``energy.balance_error_rel`` (the worst run); the PNG
  ``stiffness_loops.png`` shows the torque–angle loops with the commanded lines.
"""

from __future__ import annotations

import dataclasses
import math
import re
import tomllib
from pathlib import Path
from types import MappingProxyType
from typing import Any, Mapping

from afo_mj.scenarios.device_scenario import DEVICE as WALK_DEVICE, device_params
from afo_mj.scenarios.schema import Key, ScenarioError, Table, check_table
from afo_mj.scenarios.walk_scenario import apply_overrides

#: the top level of a bench scenario file
TOP = Table("", (
    Key("name", "string", doc="letters, digits, _ . -; default: the file name without .toml"),
    Key("description", "string", default=""),
    Key("device", "table", doc="the device on the stand (its preset and params)"),
    Key("bench", "table", doc="the tests and the stand"),
    Key("circuit", "table", doc="a circuit description on the stand instead of [device]")),
    note="(a bench scenario has no walker or gait)")
#: ``[device]`` of a bench: the walking scenario's preset and params
DEVICE = WALK_DEVICE.only("preset", "params")
#: ``bench.kind`` values: the HAFO tests, the stiffness rig
BENCH_KINDS = ("hafo", "stiffness")
#: ``[bench]`` of ``bench.kind = "hafo"``
HAFO_BENCH = Table("bench", (
    Key("kind", "string", default="hafo", doc=" | ".join(BENCH_KINDS)),
    Key("tests", "list", doc="HAFO bench protocols (default: all of them)"),
    Key("timestep_s", "number", (1e-5, 2e-3), unit="s", doc="default: each test's own"),
    Key("body_mass_kg", "number", (10.0, 200.0), 75.0, "kg", "the stand's foot is sized for "
        "this wearer"),
    Key("height_m", "number", (0.8, 2.2), 1.75, "m")))
#: ``[bench]`` of ``bench.kind = "stiffness"`` (``amplitude_deg``'s range is open at 0)
STIFFNESS_BENCH = Table("bench", (
    Key("kind", "string", doc='"stiffness"'),
    Key("stiffnesses_nm_per_deg", "list", (0.0, 20.0), (1.0, 2.5, 4.6), "N*m/deg",
        "commanded springs, one sweep each, (0, 20]"),
    Key("amplitude_deg", "number", (0.0, 30.0), 12.0, "deg", "imposed sinusoid about "
        "neutral, (0, 30]"),
    Key("frequency_hz", "number", (0.01, 5.0), 0.25, "Hz"),
    Key("cycles", "integer", (2, 20), 3, doc="whole cycles (the first is dropped)"),
    Key("damping_nm_s_per_deg", "number", (0.0, 5.0), 0.0, "N*m*s/deg"),
    Key("rest_angle_deg", "number", (-20.0, 20.0), 0.0, "deg"),
    Key("timestep_s", "number", (1e-5, 2e-3), 5e-4, "s"),
    Key("body_mass_kg", "number", (10.0, 200.0), 25.8, "kg", "the stand's foot"),
    Key("height_m", "number", (0.8, 2.2), 1.28, "m")),
    note='(bench.kind = "stiffness")')
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
    #: ``bench.kind``: ``"hafo"`` (the tests above) or ``"stiffness"`` (the stiffness rig)
    bench_kind: str = "hafo"
    #: the stiffness rig's sweep (``bench_kind == "stiffness"``), else None
    stiffness: Any = None             # stiffness_bench.StiffnessSweepConfig
    #: ``bench_kind == "circuit"``: the compiled ``[circuit]``, its description and the
    #: protocols' settings (:class:`afo_mj.experiments.circuit_bench.CircuitBenchConfig`)
    circuit: Any = None
    circuit_spec: Any = None
    circuit_bench: Any = None

    def as_dict(self) -> dict:
        if self.bench_kind == "circuit":
            import dataclasses as _dc
            return {"name": self.name, "description": self.description, "kind": "bench",
                    "file": None if self.source_path is None else str(self.source_path),
                    "circuit": self.circuit_spec,
                    "bench": {"kind": "circuit", "tests": list(self.tests),
                              **_dc.asdict(self.circuit_bench)}}
        if self.bench_kind == "stiffness":
            c = self.stiffness
            deg = math.pi / 180.0
            r9 = lambda x: round(x, 9)  # noqa: E731  (undo the deg → rad → deg round trip)
            bench = {"kind": "stiffness",
                     "stiffnesses_nm_per_deg": [r9(k * deg) for k in c.stiffnesses_nm_per_rad],
                     "amplitude_deg": r9(c.amplitude_rad / deg),
                     "frequency_hz": c.frequency_hz, "cycles": c.cycles,
                     "damping_nm_s_per_deg": r9(c.damping_nm_s_per_rad * deg),
                     "rest_angle_deg": r9(c.rest_angle_rad / deg),
                     "timestep_s": c.timestep_s, "body_mass_kg": c.body_mass_kg,
                     "height_m": c.height_m}
        else:
            bench = {"tests": list(self.tests), "timestep_s": self.timestep_s,
                     "body_mass_kg": self.body_mass_kg, "height_m": self.height_m}
        return {"name": self.name, "description": self.description, "kind": "bench",
                "file": None if self.source_path is None else str(self.source_path),
                "device": {"preset": self.preset, "params": dict(self.overrides)},
                "bench": bench}


def is_bench_document(text: str) -> bool:
    """Whether TOML ``text`` is a bench scenario (has a ``[bench]`` table)."""
    try:
        return "bench" in tomllib.loads(text)
    except tomllib.TOMLDecodeError:
        return False


def parse_bench_scenario(text: str, origin: str = "<bench>", default_name: str = "bench",
                         source_path: Path | None = None, overrides=()) -> BenchScenario:
    """Validate a bench scenario; raises :class:`ScenarioError` naming key, value, allowed."""
    from afo_mj.scenarios.bench_protocols import BENCH_TESTS

    def fail(key, value, allowed):
        return ScenarioError(f"{origin}: {key} = {value!r} is not allowed; allowed: {allowed}")

    try:
        doc = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ScenarioError(f"{origin}: not valid TOML: {exc}") from None
    apply_overrides(doc, overrides, origin)
    check_table(doc, TOP, origin)
    name = doc.get("name", default_name)
    if not isinstance(name, str) or not _NAME_RE.match(name):
        raise fail("name", name, "letters, digits, _ . - (non-empty)")
    description = doc.get("description", TOP.default("description"))
    if not isinstance(description, str):
        raise fail("description", description, "a string")
    dev = doc.get("device", {})
    bench = doc.get("bench", {})
    if not isinstance(bench, dict):
        raise fail("bench", bench, "a table")
    if "circuit" in doc:
        return _parse_circuit_bench(doc, bench, name, description, origin, fail, source_path,
                                    text)
    kind = bench.get("kind", HAFO_BENCH.default("kind"))
    if kind not in BENCH_KINDS:
        raise fail("bench.kind", kind, " | ".join(f'"{k}"' for k in BENCH_KINDS))
    if kind == "stiffness":
        return _parse_stiffness_bench(doc, dev, bench, name, description, origin, fail,
                                      source_path, text)
    for tbl, schema in ((dev, DEVICE), (bench, HAFO_BENCH)):
        if not isinstance(tbl, dict):
            raise fail(schema.name, tbl, "a table")
        check_table(tbl, schema, origin)
    preset, params, ov = device_params(dev, origin)
    from afo_mj.devices.valve_afo import ValveAnkleParams
    if isinstance(params, ValveAnkleParams):
        # the HAFO protocols drive HafoDevice (pump-controlled kernel): a valve preset's
        # parameters would run through the pump kernel and be reported under its name
        from afo_mj.devices.hafo import PRESETS as HAFO_PRESETS
        raise fail("device.preset", preset,
                   "a pump-controlled preset for the HAFO bench protocols (bench.kind = "
                   f'"hafo"): {" | ".join(HAFO_PRESETS)}; preset {preset!r} is '
                   'valve-controlled: use bench.kind = "stiffness" (the stiffness rig)')
    tests = bench.get("tests", list(BENCH_TESTS))
    if (not isinstance(tests, list) or not tests or len(set(tests)) != len(tests)
            or any(t not in BENCH_TESTS for t in tests)):
        raise fail("bench.tests", tests, "a non-empty list of distinct " + ", ".join(BENCH_TESTS))

    def number(key):
        lo, hi = HAFO_BENCH[key].range
        v = bench.get(key, HAFO_BENCH.default(key))
        if v is None:
            return None
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) \
                or not lo <= v <= hi:
            raise fail(f"bench.{key}", v, f"a number in [{lo:g}, {hi:g}]")
        return float(v)

    return BenchScenario(name=name, description=description, preset=preset, params=params,
                         overrides=MappingProxyType(dict(ov)), tests=tuple(tests),
                         timestep_s=number("timestep_s"),
                         body_mass_kg=number("body_mass_kg"), height_m=number("height_m"),
                         source_path=source_path, text=text)


def _parse_stiffness_bench(doc, dev, bench, name, description, origin, fail, source_path,
                           text) -> BenchScenario:
    """The ``bench.kind = "stiffness"`` table (module docstring), checked key by key in the
    units the user writes (deg, N·m/deg), then converted to SI."""
    from afo_mj.devices.valve_afo import VALVE_PRESETS, ValveAnkleParams
    from afo_mj.scenarios.bench_protocols import StiffnessBenchError, sweep_config
    for tbl, schema in ((dev, DEVICE), (bench, STIFFNESS_BENCH)):
        if not isinstance(tbl, dict):
            raise fail(schema.name, tbl, "a table")
        check_table(tbl, schema, origin)
    preset, params, ov = device_params(dev, origin)
    if not isinstance(params, ValveAnkleParams):
        raise fail("device.preset", preset, "a valve-circuit preset that emulates springs "
                   '(bench.kind = "stiffness"): ' + " | ".join(VALVE_PRESETS))

    def number(key, lo_open=False):
        (lo, hi), unit = STIFFNESS_BENCH[key].range, " " + STIFFNESS_BENCH[key].unit
        v = bench.get(key, STIFFNESS_BENCH.default(key))
        bad_lo = (v <= lo if lo_open else v < lo) if isinstance(v, (int, float)) else True
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) \
                or bad_lo or v > hi:
            raise fail(f"bench.{key}", v, f"a number in {'(' if lo_open else '['}{lo:g}, "
                       f"{hi:g}]{unit}")
        return float(v)

    ks = bench.get("stiffnesses_nm_per_deg",
                   list(STIFFNESS_BENCH.default("stiffnesses_nm_per_deg")))
    k_lo, k_hi = STIFFNESS_BENCH["stiffnesses_nm_per_deg"].range
    if (not isinstance(ks, list) or not ks or len(set(ks)) != len(ks)
            or any(isinstance(k, bool) or not isinstance(k, (int, float))
                   or not math.isfinite(k) or not k_lo < k <= k_hi for k in ks)):
        raise fail("bench.stiffnesses_nm_per_deg", ks,
                   f"a non-empty list of distinct numbers in ({k_lo:g}, {k_hi:g}] N*m/deg")
    amp = number("amplitude_deg", lo_open=True)
    f = number("frequency_hz")
    cycles = bench.get("cycles", STIFFNESS_BENCH.default("cycles"))
    c_lo, c_hi = STIFFNESS_BENCH["cycles"].range
    if isinstance(cycles, bool) or not isinstance(cycles, int) or not c_lo <= cycles <= c_hi:
        raise fail("bench.cycles", cycles, f"an integer in {c_lo} … {c_hi} (the first cycle "
                   "is dropped as start-up)")
    damping = number("damping_nm_s_per_deg")
    rest = number("rest_angle_deg")
    dt = number("timestep_s")
    if f * dt > 1.0 / 200.0:
        raise fail("bench.timestep_s", bench.get("timestep_s",
                                                 STIFFNESS_BENCH.default("timestep_s")),
                   f"at most 1 / (200 x frequency_hz) = {1.0 / (200.0 * f):g} s (200 steps a "
                   "cycle)")
    mass = number("body_mass_kg")
    height = number("height_m")
    # beyond the device's torque limit the sweep measures the saturation, not the spring
    peak = max(ks) * (amp + abs(rest)) + damping * 2.0 * math.pi * f * amp
    if peak > params.max_torque_nm:
        raise fail("bench.amplitude_deg", amp,
                   f"an amplitude at which the stiffest spring stays within the device's "
                   f"max_torque_nm = {params.max_torque_nm:g} N*m (it asks {peak:.1f} N*m): "
                   f"max stiffness x (amplitude + |rest angle|) + damping x 2 pi f x "
                   f"amplitude <= {params.max_torque_nm:g}")
    deg = math.pi / 180.0
    try:
        cfg = sweep_config([k / deg for k in ks], amplitude_rad=amp * deg, frequency_hz=f,
                           cycles=cycles, damping_nm_s_per_rad=damping / deg,
                           rest_angle_rad=rest * deg, timestep_s=dt, body_mass_kg=mass,
                           height_m=height, max_torque_nm=params.max_torque_nm)
    except StiffnessBenchError as exc:      # not reached after the checks above
        raise ScenarioError(f"{origin}: bench: {exc}") from None
    return BenchScenario(name=name, description=description, preset=preset, params=params,
                         overrides=MappingProxyType(dict(ov)), tests=(),
                         timestep_s=cfg.timestep_s, body_mass_kg=cfg.body_mass_kg,
                         height_m=cfg.height_m, source_path=source_path, text=text,
                         bench_kind="stiffness", stiffness=cfg)


#: ``[bench]`` of a circuit bench (``[circuit]`` given): the protocols and the settings of
#: :class:`afo_mj.experiments.circuit_bench.CircuitBenchConfig` (numbers, then integers,
#: then lists of numbers), with their ranges; absent keys take the config's defaults
CIRCUIT_BENCH = Table("bench", (
    Key("kind", "string", default="circuit", doc='"circuit"'),
    Key("tests", "list", default=("torque_velocity", "frequency_response"),
        doc="protocols of afo_mj.experiments.circuit_bench")) + tuple(
    Key(name, "number", rng) for name, rng in (
        ("timestep_s", (1e-5, 1e-3)), ("load_inertia_kg_m2", (1e-4, 1.0)),
        ("load_stiffness_nm_rad", (0.0, 1e4)), ("load_damping_nm_s_rad", (0.0, 100.0)),
        ("step_duration_s", (0.1, 5.0)), ("freq_min_hz", (0.1, 100.0)),
        ("freq_max_hz", (1.0, 2000.0)), ("voltage_amplitude_v", (0.1, 100.0)),
        ("position_step_rad", (-0.6, 0.6)), ("position_kp_nm_rad", (0.0, 1e4)),
        ("position_kd_nm_s_rad", (0.0, 100.0)), ("torque_limit_nm", (1.0, 500.0)),
        ("position_duration_s", (0.1, 10.0)), ("stiffness_amplitude_rad", (0.01, 0.5)),
        ("stiffness_frequency_hz", (0.05, 10.0)), ("tracking_peak_torque_nm", (0.0, 200.0)),
        ("tracking_amplitude_rad", (0.0, 0.5)), ("tracking_frequency_hz", (0.1, 5.0)),
        ("flow_bias_pressure_pa", (0.0, 2e7)), ("flow_damping_nm_s_rad", (0.0, 100.0)),
        ("flow_inertia_kg_m2", (1e-4, 1.0)), ("flow_max_duration_s", (0.1, 20.0)))) + tuple(
    Key(name, "integer", rng) for name, rng in (
        ("freq_points", (15, 200)), ("freq_refine_points", (0, 100)), ("tv_points", (2, 40)),
        ("tracking_cycles", (2, 50)))) + tuple(
    Key(name, "list", rng) for name, rng in (
        ("step_torques_nm", (0.5, 200.0)), ("stiffnesses_nm_rad", (0.5, 1e4)),
        ("duties", (0.01, 1.0)))),
    note="(a [circuit] bench)")


def _parse_circuit_bench(doc, bench, name, description, origin, fail, source_path,
                         text) -> BenchScenario:
    """A ``[circuit]`` on the bench: the protocols of :mod:`afo_mj.experiments.circuit_bench`
    (``bench.tests``), each checked against what the circuit's controller can run."""
    from afo_mj.scenarios.bench_protocols import (PROTOCOLS, CircuitBenchConfig,
                                                  protocol_problem)
    from afo_mj.scenarios.circuit_scenario import load_circuit
    if doc.get("device"):
        raise fail("device", doc["device"], "nothing: the bench runs the [circuit] "
                   "description (give either [circuit] or [device])")
    check_table(bench, CIRCUIT_BENCH, origin)
    if bench.get("kind", CIRCUIT_BENCH.default("kind")) != "circuit":
        raise fail("bench.kind", bench["kind"], '"circuit" (the bench of a [circuit] '
                   "description)")
    spec, cc = load_circuit(doc["circuit"], origin)
    tests = bench.get("tests", list(CIRCUIT_BENCH.default("tests")))
    if (not isinstance(tests, list) or not tests or len(set(tests)) != len(tests)
            or any(t not in PROTOCOLS for t in tests)):
        raise fail("bench.tests", tests, "a non-empty list of distinct "
                   + ", ".join(PROTOCOLS))
    for t in tests:
        why = protocol_problem(cc.circuit, t)
        if why:
            raise fail("bench.tests", tests, f"protocols circuit {cc.circuit.name!r} can run; "
                       f"{why}")
    kw = {}
    for key in CIRCUIT_BENCH.keys:
        k = key.name
        if k in ("kind", "tests") or k not in bench:    # the config's settings only
            continue
        v, (lo, hi) = bench[k], key.range
        if key.kind == "number":
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) \
                    or not lo <= v <= hi:
                raise fail(f"bench.{k}", v, f"a number in [{lo:g}, {hi:g}]")
            kw[k] = float(v)
        elif key.kind == "integer":
            if isinstance(v, bool) or not isinstance(v, int) or not lo <= v <= hi:
                raise fail(f"bench.{k}", v, f"an integer in [{lo}, {hi}]")
            kw[k] = v
        else:
            if (not isinstance(v, list) or not v or any(
                    isinstance(x, bool) or not isinstance(x, (int, float))
                    or not lo <= x <= hi for x in v)):
                raise fail(f"bench.{k}", v, f"a non-empty list of numbers in [{lo:g}, {hi:g}]")
            kw[k] = tuple(float(x) for x in v)
    cfg = CircuitBenchConfig(**kw)
    if cfg.freq_max_hz <= cfg.freq_min_hz:
        raise fail("bench.freq_max_hz", cfg.freq_max_hz, f"above bench.freq_min_hz = "
                   f"{cfg.freq_min_hz:g}")
    if cfg.freq_max_hz * cfg.timestep_s > 0.05:
        raise fail("bench.timestep_s", cfg.timestep_s, f"at most 1 / (20 x freq_max_hz) = "
                   f"{0.05 / cfg.freq_max_hz:g} s (20 steps a cycle at the highest frequency)")
    return BenchScenario(name=name, description=description,
                         preset=f"circuit:{cc.circuit.name}", params=None,
                         overrides=MappingProxyType({}), tests=tuple(tests),
                         timestep_s=cfg.timestep_s, body_mass_kg=0.0, height_m=0.0,
                         source_path=source_path, text=text, bench_kind="circuit",
                         circuit=cc, circuit_spec=spec, circuit_bench=cfg)


def load_bench_scenario(path, overrides=()) -> BenchScenario:
    p = Path(path)
    try:
        text = p.read_text(encoding="utf-8")
    except OSError as exc:
        raise ScenarioError(f"{p}: cannot read the scenario file ({exc.strerror or exc})") from None
    return parse_bench_scenario(text, origin=str(p), default_name=p.stem, source_path=p,
                                overrides=overrides)
