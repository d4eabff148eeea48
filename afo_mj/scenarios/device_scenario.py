"""Walking with an orthosis: the ``[device]`` and ``[assistance]`` tables of a scenario.

Schema (added to :mod:`afo_mj.scenarios.walk_scenario`)::

    [device]
    preset = "hafo"                   # the pump-controlled HAFO (afo_mj.devices.hafo)
    sides = ["right"]                 # worn on: ["right"], ["left"] or both
    conditions = ["no_device", "transparent", "assist"]   # run in this order; the last is
                                      # the run's headline result
    [device.params]                   # dotted overrides of the preset, e.g.
    "hose.length_m" = 2.2
    [assistance]
    profile = "zhang"                 # "zhang" (4 parameters) | "spline" (points)
    peak_torque_nm = 40.0             # plantarflexion, N·m
    peak_time_pct = 52.9
    rise_time_pct = 26.2
    fall_time_pct = 9.8
    points = [[0, 0], [40, 10], [53, 40], [62, 0]]   # profile = "spline": [% stride, N·m]

Conditions: ``no_device`` (nothing worn), ``transparent`` (worn, zero commanded torque, so the
cost of wearing it shows: its mass and what the hydraulics resist), ``assist`` (the profile).
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import numpy as np

from afo_mj.control import assistance as asst
from afo_mj.hydraulics.params import ParameterError
from afo_mj.scenarios.walk_scenario import ScenarioError, did_you_mean

DEVICE_KEYS = ("preset", "sides", "conditions", "params", "variants")
ASSIST_KEYS = ("profile", "peak_torque_nm", "peak_time_pct", "rise_time_pct", "fall_time_pct",
               "points", "stiffness_nm_per_deg", "damping_nm_s_per_deg", "rest_angle_deg",
               "clutched", "phases", "stiffnesses_nm_per_deg")
CONDITIONS = ("no_device", "transparent", "assist")


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


def device_params(dev: dict, origin: str):
    """``(preset, params, overrides)`` from a scenario's ``[device]`` table: the preset
    (:data:`afo_mj.devices.hafo.PRESETS`) with its ``params`` dotted overrides, validated."""
    from afo_mj.devices.hafo import PRESETS as HAFO_PRESETS, hafo_params
    from afo_mj.devices.valve_afo import VALVE_PRESETS, valve_params
    DEVICE_PRESETS = {**HAFO_PRESETS, **VALVE_PRESETS}
    preset = dev.get("preset", "hafo")
    if preset not in DEVICE_PRESETS:
        raise ScenarioError(f"{origin}: device.preset = {preset!r} is not allowed; allowed: "
                            + " | ".join(DEVICE_PRESETS))
    overrides = dev.get("params", {})
    if not isinstance(overrides, dict):
        raise ScenarioError(f"{origin}: device.params = {overrides!r} is not allowed; allowed: "
                            "a table of dotted parameter names")
    try:
        params = (hafo_params(overrides, preset) if preset in HAFO_PRESETS
                  else valve_params(overrides, preset))
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

    for table, doc, keys in (("device", dev, DEVICE_KEYS), ("assistance", ass, ASSIST_KEYS)):
        for k in doc:
            if k not in keys:
                raise ScenarioError(f"{origin}: unknown key '{table}.{k}' (= {doc[k]!r})"
                                    f"{did_you_mean(k, keys, f'{table}.')}; allowed keys in "
                                    f"[{table}]: " + ", ".join(keys))
    sides = dev.get("sides", ["right"])
    if (not isinstance(sides, list) or not sides or len(set(sides)) != len(sides)
            or any(s not in ("right", "left") for s in sides)):
        raise fail("device.sides", sides, '["right"], ["left"] or ["right", "left"]')
    conds = dev.get("conditions", ["no_device", "transparent", "assist"])
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
    variants_doc = dev.get("variants", {})
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
    profile = None
    if "assist" in conds:
        kind = ass.get("profile", "zhang")
        try:
            if kind == "zhang":
                profile = asst.zhang_profile(ass.get("peak_torque_nm", 40.0),
                                             ass.get("peak_time_pct", 52.9),
                                             ass.get("rise_time_pct", 26.2),
                                             ass.get("fall_time_pct", 9.8))
            elif kind == "spline":
                pts = ass.get("points")
                if not isinstance(pts, list) or any(not isinstance(p, list) or len(p) != 2
                                                    for p in pts):
                    raise fail("assistance.points", pts, "a list of [phase_pct, torque_nm]")
                profile = asst.spline_profile([p[0] for p in pts], [p[1] for p in pts])
            elif kind == "impedance":
                impedance, sweep = _impedance_rows(ass, fail)
            else:
                raise fail("assistance.profile", kind, '"zhang" | "spline" | "impedance"')
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
                        circuit=cc, circuit_spec=spec)


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
    clutched = ass.get("clutched", False)
    if not isinstance(clutched, bool):
        raise fail("assistance.clutched", clutched, "true | false")
    damping = ass.get("damping_nm_s_per_deg", 0.0)
    rest = ass.get("rest_angle_deg", 0.0)

    def single(k):
        if not isinstance(k, (int, float)) or not 0.0 <= k <= 20.0:
            raise fail("assistance.stiffness_nm_per_deg", k, "a number in 0 … 20 N*m/deg")
        if not isinstance(damping, (int, float)) or not 0.0 <= damping <= 5.0:
            raise fail("assistance.damping_nm_s_per_deg", damping, "a number in 0 … 5")
        if not isinstance(rest, (int, float)) or not -40.0 <= rest <= 40.0:
            raise fail("assistance.rest_angle_deg", rest, "a number in -40 … 40 deg")
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
        base = single(ass.get("stiffness_nm_per_deg", 2.5))
    sweep = []
    if "stiffnesses_nm_per_deg" in ass:
        ks = ass["stiffnesses_nm_per_deg"]
        if not isinstance(ks, list) or not ks:
            raise fail("assistance.stiffnesses_nm_per_deg", ks, "a non-empty list of N*m/deg")
        sweep = [(f"assist_k{k:g}", single(k)) for k in ks]
    return base, sweep
