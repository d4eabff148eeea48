"""Bench scenarios: a device on a bench rig instead of on a walker.

A bench scenario is a TOML file with a ``[bench]`` table (and no ``[walker]``/``[gait]``). It
names a device, ``[device] preset`` (any registered device,
:func:`afo_mj.devices.registry.device_names`, with dotted ``params`` overrides for a preset)
or a ``[circuit]`` description, and the bench protocols to run on it
(:data:`afo_mj.scenarios.bench_protocols.PROTOCOLS`) on one rig (``stand``: the MuJoCo ankle
test stand with a wearer's foot; ``load``: a simulated inertia on a spring inside the
compiled circuit)::

    name = "bench_hafo"
    description = "..."

    [device]
    preset = "hafo"
    [device.params]                 # optional dotted overrides, e.g. "hose.length_m" = 2.2

    [bench]
    rig = "stand"                   # default: stand for a [device], load for a [circuit]
    protocols = ["torque_velocity", "isometric_steps", "frequency_response", "position_step"]
    timestep_s = 2.5e-4             # optional; each protocol's default otherwise
    body_mass_kg = 75.0             # the stand's foot is sized for this wearer
    height_m = 1.75

Each protocol declares what it needs of the device (a torque controller, an open-loop motor
voltage, a PWM valve duty; :data:`~afo_mj.scenarios.bench_protocols.NEEDS`); one the device
cannot run is refused naming the protocol, the device and what it lacks.

Settings of the ``stand`` rig (:data:`STAND_KEYS`): ``timestep_s``, ``body_mass_kg``,
``height_m`` and, for the ``stiffness`` protocol, the sweep in the units a clinician writes::

    stiffnesses_nm_per_deg = [1.0, 2.5, 4.6]   # commanded springs, one sweep each, (0, 20]
    amplitude_deg = 12.0            # imposed sinusoid about neutral, (0, 30]
    frequency_hz = 0.25             # 0.01 … 5
    cycles = 3                      # whole cycles, 2 … 20 (the first is dropped)
    damping_nm_s_per_deg = 0.0      # optional commanded damping, 0 … 5
    rest_angle_deg = 0.0            # optional rest angle of the spring, −20 … 20

Settings of the ``load`` rig (:data:`LOAD_KEYS`): those of
:class:`~afo_mj.scenarios.bench_protocols.LoadBenchConfig` (the load, the protocols'
lengths). A setting of the other rig is refused.

Deprecated forms, still read (each adds a note to :attr:`BenchScenario.notes`, printed with
the run): ``bench.tests`` for ``bench.protocols``; ``bench.kind = "hafo"`` (the stand, the
four published HAFO protocols unless ``tests`` names others), ``"stiffness"`` (the stand,
``["stiffness"]``, the child's foot 25.8 kg / 1.28 m and 0.5 ms steps by default) and
``"circuit"`` (the load rig, ``tests`` or ``["torque_velocity", "frequency_response"]``).

``afo-mj run`` runs it through :func:`afo_mj.experiments.bench_run.run_bench_scenario` and
writes ``summary.json`` (the ``bench.*`` figures of the stand: ``bench.stall_torque_nm``,
``bench.no_load_speed_deg_s``, ``bench.bandwidth_hz``, ``bench.rise_time_s``, …, and
``stiffness.k<K>.*`` per commanded spring; the load rig's ``bench.<protocol>.*``), the energy
balance, the device masses, and the bench PNGs. ``--set bench.protocols='["torque_velocity"]'``
or ``--set device.params.hose.length_m=2.2`` override values as for walking scenarios.
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
    Key("device", "table", doc="the device on the bench (its preset and params)"),
    Key("bench", "table", doc="the protocols, the rig and its settings"),
    Key("circuit", "table", doc="a circuit description on the bench instead of [device]")),
    note="(a bench scenario has no walker or gait)")
#: ``[device]`` of a bench: the walking scenario's preset and params
DEVICE = WALK_DEVICE.only("preset", "params")
#: deprecated ``bench.kind`` values → the rig and protocols they stood for (None: ``tests``
#: or the rig's default)
BENCH_KINDS = {"hafo": ("stand", None), "stiffness": ("stand", ("stiffness",)),
               "circuit": ("load", None)}
#: the load rig's settings (:class:`~afo_mj.scenarios.bench_protocols.LoadBenchConfig`):
#: numbers, integers, lists of numbers, with their ranges
_LOAD_SETTINGS = tuple(
    Key(name, "number", rng) for name, rng in (
        ("load_inertia_kg_m2", (1e-4, 1.0)),
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
        ("duties", (0.01, 1.0))))
#: the stand's stiffness sweep (``amplitude_deg``'s range is open at 0)
_SWEEP_SETTINGS = (
    Key("stiffnesses_nm_per_deg", "list", (0.0, 20.0), (1.0, 2.5, 4.6), "N*m/deg",
        "commanded springs, one sweep each, (0, 20]"),
    Key("amplitude_deg", "number", (0.0, 30.0), 12.0, "deg", "imposed sinusoid about "
        "neutral, (0, 30]"),
    Key("frequency_hz", "number", (0.01, 5.0), 0.25, "Hz"),
    Key("cycles", "integer", (2, 20), 3, doc="whole cycles (the first is dropped)"),
    Key("damping_nm_s_per_deg", "number", (0.0, 5.0), 0.0, "N*m*s/deg"),
    Key("rest_angle_deg", "number", (-20.0, 20.0), 0.0, "deg"))
#: ``[bench]``: the protocols, the rig, the settings of both rigs (each refused on the other)
BENCH = Table("bench", (
    Key("protocols", "list", doc="bench protocols (afo_mj.scenarios.bench_protocols."
        "PROTOCOLS); default: the rig's"),
    Key("rig", "string", doc="stand | load; default: stand for a [device], load for a "
        "[circuit]"),
    Key("tests", "list", doc="deprecated: read as protocols"),
    Key("kind", "string", doc="deprecated: " + " | ".join(BENCH_KINDS)
        + " (the rig and protocols it stood for)"),
    Key("timestep_s", "number", (1e-5, 2e-3), unit="s", doc="default: each protocol's own "
        "(the load rig: 1e-4, at most 1e-3)"),
    Key("body_mass_kg", "number", (10.0, 200.0), 75.0, "kg", "the stand's foot is sized for "
        "this wearer"),
    Key("height_m", "number", (0.8, 2.2), 1.75, "m")) + _SWEEP_SETTINGS + _LOAD_SETTINGS)
#: the settings only the stand reads, and those only the load rig reads
STAND_KEYS = ("body_mass_kg", "height_m") + tuple(k.name for k in _SWEEP_SETTINGS)
LOAD_KEYS = tuple(k.name for k in _LOAD_SETTINGS)
_NAME_RE = re.compile(r"^[A-Za-z0-9_.\-]+$")


@dataclasses.dataclass(frozen=True)
class BenchScenario:
    """A validated bench scenario (see the module docstring)."""

    name: str
    description: str
    #: the device (:class:`~afo_mj.circuits.device_spec.DeviceSpec`)
    spec: Any
    #: the registered device's name, or ``circuit:<name>`` for a ``[circuit]``
    preset: str
    #: the preset's parameter set (None for a description)
    params: Any
    overrides: Mapping[str, Any]
    protocols: tuple[str, ...]
    #: ``stand`` or ``load``
    rig: str
    #: the stand's step (None: each protocol's own) or the load rig's
    timestep_s: float | None
    body_mass_kg: float
    height_m: float
    source_path: Path | None = None
    text: str = ""
    #: the stand's stiffness sweep (:class:`~afo_mj.scenarios.bench_protocols.
    #: StiffnessSweepConfig`) when the protocols include ``stiffness`` on the stand
    stiffness: Any = None
    #: the load rig's settings (:class:`~afo_mj.scenarios.bench_protocols.LoadBenchConfig`)
    load: Any = None
    #: the ``[circuit]`` description as given (a dict), or None
    circuit_spec: Any = None
    #: what the parser read in a deprecated form, one sentence each
    notes: tuple[str, ...] = ()

    def as_dict(self) -> dict:
        bench: dict = {"rig": self.rig, "protocols": list(self.protocols),
                       "timestep_s": self.timestep_s}
        if self.rig == "stand":
            bench.update(body_mass_kg=self.body_mass_kg, height_m=self.height_m)
        if self.stiffness is not None:
            c = self.stiffness
            deg = math.pi / 180.0
            r9 = lambda x: round(x, 9)  # noqa: E731  (undo the deg → rad → deg round trip)
            bench.update({
                "stiffnesses_nm_per_deg": [r9(k * deg) for k in c.stiffnesses_nm_per_rad],
                "amplitude_deg": r9(c.amplitude_rad / deg),
                "frequency_hz": c.frequency_hz, "cycles": c.cycles,
                "damping_nm_s_per_deg": r9(c.damping_nm_s_per_rad * deg),
                "rest_angle_deg": r9(c.rest_angle_rad / deg)})
        if self.load is not None:
            bench.update(dataclasses.asdict(self.load))
        out = {"name": self.name, "description": self.description, "kind": "bench",
               "file": None if self.source_path is None else str(self.source_path),
               "bench": bench, "notes": list(self.notes)}
        if self.circuit_spec is not None:
            out["circuit"] = self.circuit_spec
        else:
            out["device"] = {"preset": self.preset, "params": dict(self.overrides)}
        return out


def is_bench_document(text: str) -> bool:
    """Whether TOML ``text`` is a bench scenario (has a ``[bench]`` table)."""
    try:
        return "bench" in tomllib.loads(text)
    except tomllib.TOMLDecodeError:
        return False


def _device(doc, dev, origin, fail):
    """``(spec, preset, params, overrides, description)`` of the bench's device: the
    ``[circuit]`` description, or the ``[device]`` preset (any registered device; a library
    circuit by name takes no ``params``: write a ``[circuit]`` with ``library =`` for its
    overrides)."""
    from afo_mj.circuits.components import CircuitError
    from afo_mj.circuits.device_spec import DeviceSpec
    from afo_mj.devices.registry import device_entry, device_names, spec_of_params
    from afo_mj.hydraulics.params import ParameterError
    if "circuit" in doc:
        if dev:
            raise fail("device", dev, "nothing: the bench runs the [circuit] description "
                       "(give either [circuit] or [device])")
        from afo_mj.scenarios.circuit_scenario import load_circuit
        desc, cc = load_circuit(doc["circuit"], origin)
        return (DeviceSpec.from_circuit(cc.circuit), f"circuit:{cc.circuit.name}", None,
                {}, desc)
    if not isinstance(dev, dict):
        raise fail("device", dev, "a table")
    check_table(dev, DEVICE, origin)
    name = dev.get("preset", DEVICE.default("preset"))
    try:
        entry = device_entry(name) if isinstance(name, str) else None
    except ParameterError:
        entry = None
    if entry is not None and entry.from_params is None:
        if dev.get("params"):
            raise fail("device.params", dev["params"], f"nothing with the library circuit "
                       f"{name!r} (write a [circuit] with library = {name!r} and its "
                       "overrides)")
        try:
            return entry.make(None), name, None, {}, None
        except (CircuitError, ParameterError) as exc:
            raise ScenarioError(f"{origin}: device.preset = {name!r}: {exc}") from None
    preset, params, ov = device_params(dev, origin)
    try:
        spec = spec_of_params(preset, params, key=f"{origin}: device.preset")
    except ParameterError:
        raise fail("device.preset", preset, "a circuit device (" + " | ".join(device_names())
                   + f"); {preset!r} delivers its command ideally and has no bench") from None
    return spec, preset, params, ov, None


def _number(bench, key, fail, lo_open=False, default=None):
    k = BENCH[key]
    lo, hi = k.range
    unit = f" {k.unit}" if k.unit else ""
    v = bench.get(key, k.default if default is None else default)
    if v is None:
        return None
    bad_lo = (v <= lo if lo_open else v < lo) if isinstance(v, (int, float)) else True
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) \
            or bad_lo or v > hi:
        raise fail(f"bench.{key}", v, f"a number in {'(' if lo_open else '['}{lo:g}, "
                   f"{hi:g}]{unit}")
    return float(v)


def parse_bench_scenario(text: str, origin: str = "<bench>", default_name: str = "bench",
                         source_path: Path | None = None, overrides=()) -> BenchScenario:
    """Validate a bench scenario; raises :class:`ScenarioError` naming key, value, allowed."""
    from afo_mj.scenarios.bench_protocols import (LOAD_DEFAULT_PROTOCOLS, PROTOCOLS, RIGS,
                                                  STAND_DEFAULT_PROTOCOLS, protocol_problem)

    def fail(key, value, allowed):
        return ScenarioError(f"{origin}: {key} = {value!r} is not allowed; allowed: {allowed}")

    try:
        doc = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ScenarioError(f"{origin}: not valid TOML: {exc}") from None
    if (any(str(o).partition("=")[0].strip() == "bench.tests" for o in overrides)
            and isinstance(doc.get("bench"), dict)):
        # a command line's --set bench.tests=[...] (the deprecated name) replaces the file's
        # protocols, as it replaced its tests
        doc["bench"].pop("protocols", None)
    apply_overrides(doc, overrides, origin)
    check_table(doc, TOP, origin)
    name = doc.get("name", default_name)
    if not isinstance(name, str) or not _NAME_RE.match(name):
        raise fail("name", name, "letters, digits, _ . - (non-empty)")
    description = doc.get("description", TOP.default("description"))
    if not isinstance(description, str):
        raise fail("description", description, "a string")
    bench = doc.get("bench", {})
    if not isinstance(bench, dict):
        raise fail("bench", bench, "a table")
    check_table(bench, BENCH, origin)
    spec, preset, params, ov, desc = _device(doc, doc.get("device", {}), origin, fail)

    # the rig and the protocols (the deprecated kind / tests read with a note)
    notes = []
    kind = bench.get("kind")
    given = bench.get("protocols")
    if "tests" in bench:
        if given is not None:
            raise fail("bench.tests", bench["tests"], "nothing beside bench.protocols (tests "
                       "is its deprecated name)")
        given = bench["tests"]
        notes.append("bench.tests is deprecated: read as bench.protocols")
    if kind is not None:
        if kind not in BENCH_KINDS:
            raise fail("bench.kind", kind, " | ".join(f'"{k}"' for k in BENCH_KINDS)
                       + " (deprecated: give bench.rig and bench.protocols)")
        if "rig" in bench:
            raise fail("bench.kind", kind, "nothing beside bench.rig (kind is deprecated: "
                       "give bench.rig and bench.protocols)")
        rig, implied = BENCH_KINDS[kind]
        if implied is not None:
            if given is not None:
                raise fail("bench.kind", kind, "nothing beside bench.protocols (kind = "
                           f"{kind!r} stands for protocols = {list(implied)!r})")
            given = list(implied)
        if (kind == "circuit") != ("circuit" in doc):
            raise fail("bench.kind", kind, '"circuit" with a [circuit] description, "hafo" '
                       'or "stiffness" with a [device] (kind is deprecated: give bench.rig '
                       "and bench.protocols)")
        notes.append(f"bench.kind = {kind!r} is deprecated: read as bench.rig = {rig!r}, "
                     f"bench.protocols = "
                     f"{list(given) if given is not None else '(the default)'}")
    else:
        rig = bench.get("rig", "load" if "circuit" in doc else "stand")
        if rig not in RIGS:
            raise fail("bench.rig", rig, " | ".join(RIGS))
    default = STAND_DEFAULT_PROTOCOLS if rig == "stand" else LOAD_DEFAULT_PROTOCOLS
    protocols = list(default) if given is None else given
    key = "bench.tests" if "tests" in bench else "bench.protocols"
    if (not isinstance(protocols, list) or not protocols
            or len(set(protocols)) != len(protocols)
            or any(t not in PROTOCOLS for t in protocols)):
        raise fail(key, protocols, "a non-empty list of distinct " + ", ".join(PROTOCOLS))
    for t in protocols:
        why = protocol_problem(spec, t, rig)
        if why:
            raise fail(key, protocols, f"protocols device {spec.name!r} can run on the {rig} "
                       f"rig; {why}")
    other = LOAD_KEYS if rig == "stand" else STAND_KEYS
    for k in other:
        if k in bench:
            raise fail(f"bench.{k}", bench[k], f"nothing on the {rig} rig (a setting of the "
                       f"{'load' if rig == 'stand' else 'stand'} rig); the {rig} rig's "
                       "settings: timestep_s, "
                       + ", ".join(STAND_KEYS if rig == "stand" else LOAD_KEYS))
    common = dict(name=name, description=description, spec=spec, preset=preset,
                  params=params, overrides=MappingProxyType(dict(ov)),
                  protocols=tuple(protocols), rig=rig, source_path=source_path, text=text,
                  circuit_spec=desc, notes=tuple(notes))
    if rig == "load":
        cfg = _load_config(bench, fail, protocols)
        return BenchScenario(timestep_s=cfg.timestep_s, body_mass_kg=0.0, height_m=0.0,
                             load=cfg, **common)
    child = kind == "stiffness"       # the deprecated stiffness rig's own defaults
    mass = _number(bench, "body_mass_kg", fail, default=25.8 if child else None)
    height = _number(bench, "height_m", fail, default=1.28 if child else None)
    dt = _number(bench, "timestep_s", fail, default=5e-4 if child else None)
    sweep = None
    if "stiffness" in protocols:
        sweep = _sweep_config(bench, spec, 5e-4 if dt is None else dt, mass, height, fail,
                              origin)
    elif any(k.name in bench for k in _SWEEP_SETTINGS):
        k = next(k.name for k in _SWEEP_SETTINGS if k.name in bench)
        raise fail(f"bench.{k}", bench[k], "nothing without the stiffness protocol (a "
                   "setting of its sweep)")
    return BenchScenario(timestep_s=dt, body_mass_kg=mass, height_m=height, stiffness=sweep,
                         **common)


def _sweep_config(bench, spec, dt, mass, height, fail, origin):
    """The stand's stiffness sweep (module docstring), checked key by key in the units the
    user writes (deg, N·m/deg), then converted to SI; the stiffest spring's torque at the
    sweep's end must stay within the device's ``max_torque_nm`` where its parameters give
    one (beyond it the sweep measures the saturation, not the spring)."""
    from afo_mj.scenarios.bench_protocols import StiffnessBenchError, sweep_config
    ks = bench.get("stiffnesses_nm_per_deg",
                   list(BENCH.default("stiffnesses_nm_per_deg")))
    k_lo, k_hi = BENCH["stiffnesses_nm_per_deg"].range
    if (not isinstance(ks, list) or not ks or len(set(ks)) != len(ks)
            or any(isinstance(k, bool) or not isinstance(k, (int, float))
                   or not math.isfinite(k) or not k_lo < k <= k_hi for k in ks)):
        raise fail("bench.stiffnesses_nm_per_deg", ks,
                   f"a non-empty list of distinct numbers in ({k_lo:g}, {k_hi:g}] N*m/deg")
    amp = _number(bench, "amplitude_deg", fail, lo_open=True)
    f = _number(bench, "frequency_hz", fail)
    cycles = bench.get("cycles", BENCH.default("cycles"))
    c_lo, c_hi = BENCH["cycles"].range
    if isinstance(cycles, bool) or not isinstance(cycles, int) or not c_lo <= cycles <= c_hi:
        raise fail("bench.cycles", cycles, f"an integer in {c_lo} … {c_hi} (the first cycle "
                   "is dropped as start-up)")
    damping = _number(bench, "damping_nm_s_per_deg", fail)
    rest = _number(bench, "rest_angle_deg", fail)
    if f * dt > 1.0 / 200.0:
        raise fail("bench.timestep_s", dt, f"at most 1 / (200 x frequency_hz) = "
                   f"{1.0 / (200.0 * f):g} s (200 steps a cycle of the stiffness sweep)")
    max_torque = getattr(spec.params, "max_torque_nm", None)
    peak = max(ks) * (amp + abs(rest)) + damping * 2.0 * math.pi * f * amp
    if max_torque is not None and peak > max_torque:
        raise fail("bench.amplitude_deg", amp,
                   f"an amplitude at which the stiffest spring stays within the device's "
                   f"max_torque_nm = {max_torque:g} N*m (it asks {peak:.1f} N*m): "
                   f"max stiffness x (amplitude + |rest angle|) + damping x 2 pi f x "
                   f"amplitude <= {max_torque:g}")
    deg = math.pi / 180.0
    try:
        return sweep_config([k / deg for k in ks], amplitude_rad=amp * deg, frequency_hz=f,
                            cycles=cycles, damping_nm_s_per_rad=damping / deg,
                            rest_angle_rad=rest * deg, timestep_s=dt, body_mass_kg=mass,
                            height_m=height, max_torque_nm=max_torque)
    except StiffnessBenchError as exc:      # not reached after the checks above
        raise ScenarioError(f"{origin}: bench: {exc}") from None


def _load_config(bench, fail, protocols):
    """The load rig's settings (:class:`~afo_mj.scenarios.bench_protocols.LoadBenchConfig`),
    each checked against its declared range; absent keys take the config's defaults. The
    frequency range is checked against the step only when the frequency response runs."""
    from afo_mj.scenarios.bench_protocols import LoadBenchConfig
    kw = {}
    if "timestep_s" in bench:
        v = bench["timestep_s"]
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) \
                or not 1e-5 <= v <= 1e-3:
            raise fail("bench.timestep_s", v, "a number in [1e-05, 0.001] s (the load rig)")
        kw["timestep_s"] = float(v)
    for key in _LOAD_SETTINGS:
        k = key.name
        if k not in bench:
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
    cfg = LoadBenchConfig(**kw)
    if cfg.freq_max_hz <= cfg.freq_min_hz:
        raise fail("bench.freq_max_hz", cfg.freq_max_hz, f"above bench.freq_min_hz = "
                   f"{cfg.freq_min_hz:g}")
    if "frequency_response" in protocols and cfg.freq_max_hz * cfg.timestep_s > 0.05:
        raise fail("bench.timestep_s", cfg.timestep_s, f"at most 1 / (20 x freq_max_hz) = "
                   f"{0.05 / cfg.freq_max_hz:g} s (20 steps a cycle at the highest frequency)")
    return cfg


def load_bench_scenario(path, overrides=()) -> BenchScenario:
    p = Path(path)
    try:
        text = p.read_text(encoding="utf-8")
    except OSError as exc:
        raise ScenarioError(f"{p}: cannot read the scenario file ({exc.strerror or exc})") from None
    return parse_bench_scenario(text, origin=str(p), default_name=p.stem, source_path=p,
                                overrides=overrides)
