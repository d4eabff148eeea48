"""Walking with an orthosis: the ``[device]`` and ``[assistance]`` tables of a scenario.

Schema (added to :mod:`afo_mj.scenarios.walk_scenario`)::

    [device]
    preset = "hafo"                   # the pump-controlled HAFO (afo_mj.devices.hafo); "ideal":
                                      # delivers exactly its command (afo_mj.devices.ideal)
    sides = ["right"]                 # worn on: ["right"], ["left"] or both
    conditions = ["no_device", "transparent", "assist"]   # run in this order; the last is
                                      # the run's headline result
    [device.params]                   # dotted overrides of the preset, e.g.
    "hose.length_m" = 2.2
    [assistance]
    profile = "zhang"                 # "zhang" (4 parameters) | "spline" (points) |
                                      # "impedance" | "clutched_spring" (preset "ideal" only)
    peak_torque_nm = 40.0             # plantarflexion, N·m
    peak_time_pct = 52.9
    rise_time_pct = 26.2
    fall_time_pct = 9.8
    points = [[0, 0], [40, 10], [53, 40], [62, 0]]   # profile = "spline": [% stride, N·m]
    spring_nm_per_rad = 180.0         # profile = "clutched_spring": stiffness, the clutch
    engage_pct = 10.0                 # engaging at this % of the stride (spring slack there)
    release_pct = 62.0                # and opening past this % or at toe off
    ratchet = false                   # true: the engaged clutch takes up slack
    ramp_strides = 3                  # preset "ideal": the torque ramps on linearly over the
                                      # first strides its phase estimator measures (0: at once)

Conditions: ``no_device`` (nothing worn), ``transparent`` (worn, zero commanded torque, so the
cost of wearing it shows: its mass and what the hydraulics resist), ``assist`` (the profile).
"""

from __future__ import annotations

import dataclasses
import math
from types import MappingProxyType
from typing import Any

import numpy as np

from afo_mj.control import assistance as asst
from afo_mj.hydraulics.params import ParameterError
from afo_mj.scenarios.schema import Key, ScenarioError, Table, check_table

CONDITIONS = ("no_device", "transparent", "assist")
#: ``[device]`` of a walking scenario (a bench's is its preset and params)
DEVICE = Table("device", (
    Key("preset", "string", default="hafo", doc="a registered device or the ideal source"),
    Key("sides", "list", default=("right",), doc='worn on: ["right"], ["left"] or both'),
    Key("conditions", "list", default=CONDITIONS, doc="run in this order; the last is the "
        "headline result"),
    Key("params", "table", default=MappingProxyType({}),
        doc="dotted overrides of the preset's parameters"),
    Key("variants", "table", default=MappingProxyType({}),
        doc="named tables of dotted overrides (one compare row each)")))
#: ``[assistance]``; ``group``: the profile a key belongs to (see :func:`device_config`)
ASSISTANCE = Table("assistance", (
    Key("profile", "string", default="zhang",
        doc='"zhang" | "spline" | "impedance" | "clutched_spring"'),
    Key("peak_torque_nm", "number", default=40.0, unit="N*m", group="zhang"),
    Key("peak_time_pct", "number", default=52.9, unit="% stride", group="zhang"),
    Key("rise_time_pct", "number", default=26.2, unit="% stride", group="zhang"),
    Key("fall_time_pct", "number", default=9.8, unit="% stride", group="zhang"),
    Key("points", "list", doc="[[phase_pct, torque_nm], ...]", group="spline"),
    Key("stiffness_nm_per_deg", "number", (0.0, 20.0), 2.5, "N*m/deg", group="impedance"),
    Key("damping_nm_s_per_deg", "number", (0.0, 5.0), 0.0, "N*m*s/deg", group="impedance"),
    Key("rest_angle_deg", "number", (-40.0, 40.0), 0.0, "deg", group="impedance"),
    Key("clutched", "bool", default=False, doc="engaged only past the rest angle in "
        "dorsiflexion", group="impedance"),
    Key("phases", "list", doc="[[end_pct, stiffness_nm_per_deg, damping_nm_s_per_deg, "
        "rest_angle_deg], ...]", group="impedance"),
    Key("stiffnesses_nm_per_deg", "list", doc="one condition assist_k<K> per stiffness",
        group="impedance"),
    Key("spring_nm_per_rad", "number", (0.0, 2000.0), 180.0, "N*m/rad",
        group="clutched_spring"),
    Key("engage_pct", "number", (0.0, 50.0), 10.0, "% stride", group="clutched_spring"),
    Key("release_pct", "number", (30.0, 100.0), 62.0, "% stride", group="clutched_spring"),
    Key("ratchet", "bool", default=False, doc="the engaged clutch takes up slack (the spring "
        "stretches from the stance's lowest angle after engagement)", group="clutched_spring"),
    Key("ramp_strides", "integer", (0, 100), 0, doc="the ideal device: strides over which "
        "the torque ramps on")))


@dataclasses.dataclass(frozen=True)
class DeviceConfig:
    preset: str
    params: object
    sides: tuple[str, ...]
    conditions: tuple[str, ...]
    profile: np.ndarray | None
    #: named design variants (``[device.variants.<name>]``: dotted overrides applied on top of
    #: ``device.params``), each validated; ``afo-mj compare`` runs one row per variant
    variants: dict = dataclasses.field(default_factory=dict)
    #: impedance rows (phase_end, K N·m/rad, B N·m·s/rad, θ0 rad, clutched) replacing the
    #: assistance profile (``[assistance] profile = "impedance"``), or None
    impedance: list | None = None
    #: stiffness sweep: condition name → impedance rows (conditions ``assist_k<K>``)
    impedance_conditions: dict = dataclasses.field(default_factory=dict)
    #: a circuit description worn instead of a preset (``[circuit]``): the compiled circuit
    #: (:class:`afo_mj.circuits.codegen.CompiledCircuit`) and its description; else None
    circuit: Any = None
    circuit_spec: dict | None = None
    #: the clutched spring of ``[assistance] profile = "clutched_spring"``
    #: (:class:`afo_mj.devices.ideal.ClutchedSpring`, the ideal device only), or None
    spring: Any = None
    #: ``[assistance] ramp_strides`` (the ideal device only): the torque rises linearly over
    #: this many strides measured by the phase estimator, 0 = at once
    ramp_strides: int = 0

    def device_spec(self):
        """The worn device's :class:`~afo_mj.circuits.device_spec.DeviceSpec`: the
        ``[circuit]`` description's, or the registered device's built from :attr:`params`
        (a variant's, when :attr:`params` was replaced); None for the ideal source (no
        circuit)."""
        from afo_mj.circuits.device_spec import DeviceSpec
        from afo_mj.devices.ideal import PRESETS as IDEAL_PRESETS
        if self.circuit is not None:
            return DeviceSpec.from_circuit(self.circuit.circuit)
        if self.preset in IDEAL_PRESETS:
            return None
        from afo_mj.devices.registry import spec_of_params
        return spec_of_params(self.preset, self.params)


def device_params(dev: dict, origin: str):
    """``(preset, params, overrides)`` from a scenario's ``[device]`` table: a registered
    device (:mod:`afo_mj.devices.registry`) or the ideal source
    (:data:`afo_mj.devices.ideal.PRESETS`) with its ``params`` dotted overrides, validated. A
    library circuit is worn through ``[circuit] library = "<name>"`` (its overrides are a
    description's)."""
    from afo_mj.devices.ideal import PRESETS as IDEAL_PRESETS, ideal_params
    from afo_mj.devices.registry import ALIASES, device_entry, device_names
    preset = dev.get("preset", DEVICE.default("preset"))
    overrides = dev.get("params", dict(DEVICE.default("params")))
    if not isinstance(overrides, dict):
        raise ScenarioError(f"{origin}: device.params = {overrides!r} is not allowed; allowed: "
                            "a table of dotted parameter names")
    if preset in IDEAL_PRESETS:
        try:
            return preset, ideal_params(overrides, preset), overrides
        except ParameterError as exc:
            raise ScenarioError(f"{origin}: device.params: {exc}") from None
    presets = [n for n in device_names() if device_entry(n).from_params is not None]
    allowed = presets + list(ALIASES) + list(IDEAL_PRESETS)
    try:
        entry = device_entry(preset)
    except ParameterError:
        raise ScenarioError(f"{origin}: device.preset = {preset!r} is not allowed; allowed: "
                            + " | ".join(allowed)) from None
    if entry.from_params is None:
        raise ScenarioError(f"{origin}: device.preset = {preset!r} is a library circuit; "
                            f"allowed: [circuit] library = {preset!r} (with the description's "
                            "overrides), or a preset: " + " | ".join(allowed))
    try:
        params = entry.params_of(overrides)
    except ParameterError as exc:
        raise ScenarioError(f"{origin}: device.params: {exc}") from None
    return preset, params, overrides


def device_config(scenario) -> DeviceConfig | None:
    """Validate a scenario's ``[device]``/``[assistance]`` tables (None without a device)."""
    dev, ass = dict(scenario.device), dict(scenario.assistance)
    circ = dict(getattr(scenario, "circuit", {}) or {})
    origin = str(scenario.source_path or scenario.name)
    if not dev and not circ:
        if ass:
            raise ScenarioError(f"{origin}: [assistance] is given without a [device]")
        return None

    def fail(key, value, allowed):
        return ScenarioError(f"{origin}: {key} = {value!r} is not allowed; allowed: {allowed}")

    check_table(dev, DEVICE, origin)
    check_table(ass, ASSISTANCE, origin)
    sides = dev.get("sides", list(DEVICE.default("sides")))
    if (not isinstance(sides, list) or not sides or len(set(sides)) != len(sides)
            or any(s not in ("right", "left") for s in sides)):
        raise fail("device.sides", sides, '["right"], ["left"] or ["right", "left"]')
    conds = dev.get("conditions", list(DEVICE.default("conditions")))
    if (not isinstance(conds, list) or not conds or any(c not in CONDITIONS for c in conds)
            or len(set(conds)) != len(conds)):
        raise fail("device.conditions", conds, "a list of distinct " + ", ".join(CONDITIONS))
    cc = spec = None
    if circ:
        both = [k for k in ("preset", "params", "variants") if k in dev]
        if both:
            raise fail(f"device.{both[0]}", dev[both[0]], "nothing: the scenario wears the "
                       "[circuit] description (give either [circuit] or device.preset)")
        from afo_mj.scenarios.circuit_scenario import load_circuit
        spec, cc = load_circuit(circ, origin)
        preset, params, base_overrides = f"circuit:{cc.circuit.name}", None, {}
        if "assist" in conds and ass.get("profile", "zhang") != "impedance" \
                and cc.circuit.controller.kind == "open_loop":
            raise fail("circuit.controller.kind", "open_loop", "a torque controller "
                       "(circuit.controller.kind = \"pump_torque\") for the assist condition: "
                       "open_loop passes the command through as the motor voltage, so a "
                       "torque profile cannot be commanded")
    else:
        preset, params, base_overrides = device_params(dev, origin)
    impedance, sweep = None, []
    variants_doc = dev.get("variants", dict(DEVICE.default("variants")))
    if not isinstance(variants_doc, dict) or any(not isinstance(v, dict)
                                                 for v in variants_doc.values()):
        raise fail("device.variants", variants_doc,
                   "a table of named tables of dotted parameter overrides")
    variants = {}
    for vname, vover in variants_doc.items():
        merged = {**base_overrides, **vover}
        _, vparams, _ = device_params({"preset": preset, "params": merged},
                                      f"{origin}: device.variants.{vname}")
        variants[vname] = vparams
    profile = spring = None
    kind = ass.get("profile", ASSISTANCE.default("profile"))
    stray = [k for k in ASSISTANCE.group("clutched_spring") if k in ass]
    if stray and kind != "clutched_spring":
        raise fail(f"assistance.{stray[0]}", ass[stray[0]],
                   'nothing unless assistance.profile = "clutched_spring"')
    ramp = ass.get("ramp_strides", ASSISTANCE.default("ramp_strides"))
    lo, hi = ASSISTANCE["ramp_strides"].range
    if isinstance(ramp, bool) or not isinstance(ramp, int) or not lo <= ramp <= hi:
        raise fail("assistance.ramp_strides", ramp, f"an integer {lo} … {hi}")
    if ramp and preset != "ideal":
        raise fail("assistance.ramp_strides", ramp, f"0 with device.preset = {preset!r} (its "
                   "compiled controller has no ramp; the ideal device, preset \"ideal\", "
                   "has one)")
    if "assist" in conds:
        try:
            if kind == "zhang":
                profile = asst.zhang_profile(*(ass.get(k, ASSISTANCE.default(k))
                                               for k in ASSISTANCE.group("zhang")))
            elif kind == "spline":
                pts = ass.get("points")
                if not isinstance(pts, list) or any(not isinstance(p, list) or len(p) != 2
                                                    for p in pts):
                    raise fail("assistance.points", pts, "a list of [phase_pct, torque_nm]")
                profile = asst.spline_profile([p[0] for p in pts], [p[1] for p in pts])
            elif kind == "impedance":
                impedance, sweep = _impedance_rows(ass, fail)
            elif kind == "clutched_spring":
                spring = _clutched_spring(ass, preset, fail)
            else:
                raise fail("assistance.profile", kind,
                           '"zhang" | "spline" | "impedance" | "clutched_spring"')
        except ParameterError as exc:
            raise ScenarioError(f"{origin}: {exc}") from None
    if impedance is not None and cc is not None and cc.circuit.controller.kind == "open_loop":
        raise fail("assistance.profile", "impedance", "a torque controller "
                   "(circuit.controller.kind = \"pump_torque\", \"servo_valve_torque\", …): "
                   "open_loop passes the command through as the motor voltage")
    if impedance is not None:
        from afo_mj.control.impedance import impedance_table
        for rows in [impedance] + [r for _, r in sweep]:
            try:
                impedance_table(rows)
            except ParameterError as exc:
                raise ScenarioError(f"{origin}: assistance: {exc}") from None
        if sweep:
            conds = [n for c in conds for n in ([n for n, _ in sweep] if c == "assist"
                                                 else [c])]
    return DeviceConfig(preset, params, tuple(sides), tuple(conds), profile, variants,
                        impedance, dict(sweep) if impedance is not None else {},
                        circuit=cc, circuit_spec=spec, spring=spring, ramp_strides=ramp)


def _clutched_spring(ass: dict, preset: str, fail):
    """The :class:`~afo_mj.devices.ideal.ClutchedSpring` of ``[assistance] profile =
    "clutched_spring"`` (phases given in % of the stride). Only the ideal device has it: a
    clutch latches the ankle angle at engagement, which the torque-controlled devices'
    commands (a profile, impedance rows about a fixed rest angle) cannot express."""
    from afo_mj.devices.ideal import PRESETS as IDEAL_PRESETS, ClutchedSpring
    if preset not in IDEAL_PRESETS:
        raise fail("assistance.profile", "clutched_spring",
                   f"only with device.preset = {' | '.join(map(repr, IDEAL_PRESETS))} (the "
                   f"ideal device; {preset!r} cannot latch the ankle angle at engagement: "
                   "emulate a spring on it with profile = \"impedance\", clutched = true)")
    vals = {}
    for key in (k for k in ASSISTANCE.group("clutched_spring")
                if ASSISTANCE[k].kind == "number"):
        v = ass.get(key, ASSISTANCE.default(key))
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
            raise fail(f"assistance.{key}", v, "a finite number")
        vals[key] = float(v)
    k, eng, rel = vals["spring_nm_per_rad"], vals["engage_pct"], vals["release_pct"]
    for key, v in vals.items():
        lo, hi = ASSISTANCE[key].range
        if not lo <= v <= hi:
            raise fail(f"assistance.{key}", v, f"{lo:g} … {hi:g}")
    if eng >= rel:
        raise fail("assistance.engage_pct", eng, f"below assistance.release_pct = {rel:g}")
    ratchet = ass.get("ratchet", False)
    if not isinstance(ratchet, bool):
        raise fail("assistance.ratchet", ratchet, "true or false")
    return ClutchedSpring(k, eng / 100.0, rel / 100.0, ratchet)


def _impedance_rows(ass: dict, fail):
    """Impedance rows (SI: phase_end, K N·m/rad, B N·m·s/rad, θ0 rad, clutched) from the
    ``[assistance]`` table (``profile = "impedance"``) and the stiffness sweep, if any, as
    ``[(condition_name, rows)]``.

    Keys: ``stiffness_nm_per_deg`` (default 2.5), ``damping_nm_s_per_deg`` (0),
    ``rest_angle_deg`` (0), ``clutched`` (false: a spring on both sides of the rest angle;
    true: engaged only past it in dorsiflexion), or ``phases = [[end_pct, K_nm_per_deg,
    B_nm_s_per_deg, rest_deg], …]`` (a per-phase impedance state machine over the stride,
    the last ending at 100), and ``stiffnesses_nm_per_deg = [1, 2.5, 4.6]``: one condition
    ``assist_k<K>`` per stiffness instead of ``assist``."""
    deg = math.pi / 180.0
    clutched = ass.get("clutched", ASSISTANCE.default("clutched"))
    if not isinstance(clutched, bool):
        raise fail("assistance.clutched", clutched, "true | false")
    damping = ass.get("damping_nm_s_per_deg", ASSISTANCE.default("damping_nm_s_per_deg"))
    rest = ass.get("rest_angle_deg", ASSISTANCE.default("rest_angle_deg"))
    (k_lo, k_hi), (b_lo, b_hi), (r_lo, r_hi) = (
        ASSISTANCE[k].range for k in ("stiffness_nm_per_deg", "damping_nm_s_per_deg",
                                      "rest_angle_deg"))

    def single(k):
        if not isinstance(k, (int, float)) or not k_lo <= k <= k_hi:
            raise fail("assistance.stiffness_nm_per_deg", k,
                       f"a number in {k_lo:g} … {k_hi:g} N*m/deg")
        if not isinstance(damping, (int, float)) or not b_lo <= damping <= b_hi:
            raise fail("assistance.damping_nm_s_per_deg", damping,
                       f"a number in {b_lo:g} … {b_hi:g}")
        if not isinstance(rest, (int, float)) or not r_lo <= rest <= r_hi:
            raise fail("assistance.rest_angle_deg", rest, f"a number in {r_lo:g} … {r_hi:g} deg")
        return [(1e9, k / deg, damping / deg, rest * deg, 1.0 if clutched else 0.0)]

    if "phases" in ass:
        ph = ass["phases"]
        if (not isinstance(ph, list) or not ph
                or any(not isinstance(r, list) or len(r) != 4 for r in ph)):
            raise fail("assistance.phases", ph, "a list of [end_pct, stiffness_nm_per_deg, "
                       "damping_nm_s_per_deg, rest_angle_deg]")
        rows = [(r[0] / 100.0 if i < len(ph) - 1 else 1e9, r[1] / deg, r[2] / deg, r[3] * deg,
                 1.0 if clutched else 0.0) for i, r in enumerate(ph)]
        base = rows
    else:
        base = single(ass.get("stiffness_nm_per_deg", ASSISTANCE.default("stiffness_nm_per_deg")))
    sweep = []
    if "stiffnesses_nm_per_deg" in ass:
        ks = ass["stiffnesses_nm_per_deg"]
        if not isinstance(ks, list) or not ks:
            raise fail("assistance.stiffnesses_nm_per_deg", ks, "a non-empty list of N*m/deg")
        sweep = [(f"assist_k{k:g}", single(k)) for k in ks]
    return base, sweep
