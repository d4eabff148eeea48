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

from afo_mj.analysis.gait_metrics import PUSH_OFF_WINDOW
from afo_mj.control import assistance as asst
from afo_mj.hydraulics.params import ParameterError
from afo_mj.scenarios.walk_scenario import ScenarioError

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

    for k in dev:
        if k not in DEVICE_KEYS:
            raise fail(f"device.{k}", dev[k], "keys " + ", ".join(DEVICE_KEYS))
    for k in ass:
        if k not in ASSIST_KEYS:
            raise fail(f"assistance.{k}", ass[k], "keys " + ", ".join(ASSIST_KEYS))
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


def _per_stride(rec, side: int, first: int, last: int):
    """Mask of samples in right-leg strides ``first..last`` (1-based) and their count."""
    hs = rec.events.heel_strikes_s[side]
    last = min(last, len(hs) - 1)
    if last < first:
        return None, 0
    t0, t1 = hs[first - 1], hs[last]
    return (rec.time_s >= t0) & (rec.time_s < t1), last - first + 1


def condition_summary(rec, analysis, device, cfg: DeviceConfig, strides) -> dict:
    """The issue-4 summary block of one condition (gait, human, device, energy)."""
    side = 0 if cfg.sides[0] == "right" else 1
    first, last = strides
    mask, n = _per_stride(rec, side, first, last)
    out = {"gait": analysis.summary if analysis is not None else None}
    if mask is None:
        out["human"] = {"ankle_positive_work_j_per_stride": None}
        return out
    dt = rec.sample_period_s
    w = rec.joint_velocity_rad_s[mask, side, 2]
    p_h = rec.joint_moment_nm[mask, side, 2] * w
    out["human"] = {"ankle_positive_work_j_per_stride": float(np.sum(np.clip(p_h, 0, None))
                                                               * dt / n),
                    "ankle_negative_work_j_per_stride": float(np.sum(np.clip(p_h, None, 0))
                                                              * dt / n)}
    # the whole joint (muscles + device): push-off restoration is judged on it
    p_tot = (rec.joint_moment_nm[mask, side, 2] + rec.device_moment_nm[mask, side]) * w
    t_m = rec.time_s[mask]
    hs = [h for h in rec.events.heel_strikes_s[side] if t_m[0] - 1e-9 <= h <= t_m[-1] + dt]
    peaks, po_work = [], []
    for a, b in zip(hs[:-1], hs[1:]):
        sel = (t_m >= a) & (t_m < b)
        if not np.any(sel):
            continue
        ph = (t_m[sel] - a) / (b - a)
        win = (ph >= PUSH_OFF_WINDOW[0]) & (ph <= PUSH_OFF_WINDOW[1])
        pw = p_tot[sel][win]
        if pw.size:
            peaks.append(float(np.max(pw)))
            po_work.append(float(np.sum(np.clip(pw, 0, None)) * dt))
    out["ankle"] = {
        "push_off_peak_power_w": float(np.mean(peaks)) if peaks else None,
        "push_off_positive_work_j_per_stride": float(np.mean(po_work)) if po_work else None,
        "positive_work_j_per_stride": float(np.sum(np.clip(p_tot, 0, None)) * dt / n),
        "note": "whole ankle joint (muscles + device); push-off is "
                f"{PUSH_OFF_WINDOW[0]:.0%}-{PUSH_OFF_WINDOW[1]:.0%} of the stride",
    }
    if device is None:
        return out
    L = device.log.arrays()
    k = 0
    n_log = min(len(L["time_s"]), len(rec.time_s))
    m = mask[:n_log]
    cmd = L["commanded_torque_nm"][:n_log, k][m]
    dlv = L["delivered_torque_nm"][:n_log, k][m]
    p_d = rec.device_moment_nm[mask, side] * w
    led = device_ledger(device, cfg, L, k)
    drawn = led["electrical_drawn_j"]
    mech_pos = float(np.sum(np.clip(L["mechanical_power_w"][:, k], 0, None)) * dt)
    duration = float(rec.time_s[-1] - rec.time_s[0]) if len(rec.time_s) > 1 else 0.0
    mean_power = drawn / duration if duration > 0 else math.nan
    energy_wh = led["battery_energy_wh"]
    runtime_h = (energy_wh / mean_power) if mean_power > 0 and energy_wh else None
    out["device"] = {
        "peak_torque_nm": float(np.max(np.abs(dlv))),
        "torque_tracking_rmse_nm": float(np.sqrt(np.mean((cmd - dlv) ** 2))),
        "positive_work_j_per_stride": float(np.sum(np.clip(p_d, 0, None)) * dt / n),
        "negative_work_j_per_stride": float(np.sum(np.clip(p_d, None, 0)) * dt / n),
        "mass_total_kg": getattr(device, "mass_total_kg", None),
        "mass_at_ankle_kg": getattr(device, "mass_at_ankle_kg", None),
        "peak_pressure_mpa": led["peak_pressure_pa"] / 1e6,
        "fluid_temperature_rise_k": led["temperature_rise_k"],
        "battery_runtime_h": runtime_h,
        "coupling_torque_error_rms_nm": led["coupling_torque_error_rms_nm"],
        "newton_unconverged_steps": led["newton_unconverged_steps"],
    }
    # per-stride figures: the whole-run ledger scaled by (mean analysed stride time / run time)
    stride_s = float(np.mean(np.diff(hs[:]))) if len(hs) > 1 else math.nan
    scale = stride_s / duration if duration > 0 and math.isfinite(stride_s) else math.nan
    out["energy_per_stride"] = {
        "stride_time_s": stride_s,
        "electrical_in_j": drawn * scale,
        "hydraulic_j": None if led["hydraulic_j"] is None else led["hydraulic_j"] * scale,
        "mechanical_positive_out_j": mech_pos * scale,
        "losses_j": {k: v * scale for k, v in led["losses_j"].items()},
        "note": "whole-run ledger (start-up strides included) times mean analysed stride "
                "time / run duration",
    }
    out["energy"] = {
        "run_duration_s": duration,
        "electrical_in_j": drawn,
        "electrical_regenerated_j": led["electrical_regenerated_j"],
        "hydraulic_j": led["hydraulic_j"],
        "mechanical_out_j": led["mechanical_out_j"],
        "mechanical_positive_out_j": mech_pos,
        "losses_j": led["losses_j"],
        "stored_change_j": led["stored_change_j"],
        "efficiency_total": mech_pos / drawn if drawn > 0 else None,
        "balance_error_rel": led["balance_error_rel"],
        "note": "whole run; electrical_in_j is the battery's chemical energy drawn, "
                "regeneration (ankle back-driving the pump) counted apart",
    }
    if cfg.circuit is not None:
        out["energy"]["input_j"] = led["input_j"]
        out["energy"]["note"] = ("whole run; electrical_in_j is the energy drawn from the "
                                 "circuit's source (battery chemical energy, or the ideal "
                                 "bench supply), electrical_regenerated_j what went back; "
                                 "losses and stores per component instance")
        out["device"]["note"] = ("circuit description: worn masses are not modelled "
                                 "(mass_total_kg null); hydraulic_j is not a ledger term")
    return out


def device_ledger(device, cfg: DeviceConfig, L: dict, k: int = 0) -> dict:
    """The ledger terms the summary reads, for a preset device (its own ledger) or a circuit
    (:meth:`afo_mj.circuits.device.CircuitDevice.ledger`, generic keys mapped: drawn =
    ``input_drawn_j``, regenerated = ``input_drawn_j − input_j``, the oil temperature rise
    from the device log, the battery energy from the circuit's battery component)."""
    led = dict(device.ledger(k))
    if cfg.circuit is None:
        from afo_mj.hydraulics.battery import Battery
        led["battery_energy_wh"] = Battery(cfg.params.battery).energy_wh
        return led
    temp = L["oil_temperature_k"][:, k]
    led["electrical_drawn_j"] = led["input_drawn_j"]
    led["electrical_regenerated_j"] = led["input_drawn_j"] - led["input_j"]
    led["hydraulic_j"] = None
    led["temperature_rise_k"] = (float(temp[-1] - cfg.circuit.circuit.thermal
                                       .ambient_temperature_k) if temp.size else 0.0)
    bats = [c for c in cfg.circuit.circuit.components if c.kind == "battery"]
    wh = None
    if bats:
        from afo_mj.hydraulics.battery import Battery
        wh = Battery(bats[0].params.battery).energy_wh
    led["battery_energy_wh"] = wh
    return led


def make_device(cfg: DeviceConfig, condition: str, timestep_s: float, max_steps: int):
    """The orthosis of ``cfg`` for one condition: the HAFO (pump-controlled), a valve /
    digital / stiffness-emulating device (:mod:`afo_mj.devices.valve_afo`) or a described
    circuit, with the assistance profile or the impedance rows (any torque-controlled
    device emulates them) when the condition is ``assist`` or a stiffness condition."""
    from afo_mj.devices.hafo import HafoDevice
    from afo_mj.devices.valve_afo import ValveAfoDevice, ValveAnkleParams
    active = condition == "assist" or condition in cfg.impedance_conditions
    imp = cfg.impedance_conditions.get(condition, cfg.impedance) if active else None
    prof = cfg.profile if active and cfg.impedance is None else None
    kw = dict(sides=cfg.sides, profile=prof, impedance=imp, timestep_s=timestep_s,
              max_steps=max_steps)
    if cfg.circuit is not None:
        from afo_mj.circuits.device import CircuitDevice
        return CircuitDevice(cfg.circuit, **kw)
    if isinstance(cfg.params, ValveAnkleParams):
        return ValveAfoDevice(cfg.params, **kw)
    return HafoDevice(cfg.params, **kw)


def run_device_scenario(scenario, reference, cfg: DeviceConfig):
    """Run every condition; returns ``(summary, per-condition (record, analysis, device))``."""
    from afo_mj.analysis.gait_metrics import GaitAnalysisError, analyse_gait
    from afo_mj.gait.walk import run_walk
    T = scenario.cycle_time_s(reference)
    dt = scenario.walker.timestep_s
    results = {}
    n = len(cfg.conditions)
    for i, cond in enumerate(cfg.conditions, 1):
        dev = None
        worn = ()
        if cond != "no_device":
            steps = int(((scenario.strides + 1.5) * T + 1.0) / dt) + 4
            dev = make_device(cfg, cond, dt, steps)
            # a circuit description has no worn-mass layout (its parts' masses are metadata)
            worn = dev.worn_masses() if hasattr(dev, "worn_masses") else ()
        rec = run_walk(scenario.walker, reference, T, scenario.strides,
                       scenario.controller_params(), worn_masses=worn, device=dev,
                       label=f"condition {i}/{n}: {cond}" if n > 1 else cond)
        try:
            analysis = analyse_gait(rec, reference, scenario.analyse_strides)
        except GaitAnalysisError:
            analysis = None
        results[cond] = (rec, analysis, dev)
    conds = {c: condition_summary(r, a, d, cfg, scenario.analyse_strides)
             for c, (r, a, d) in results.items()}
    summary = {"device_conditions": conds, "device_preset": cfg.preset,
               "device_sides": list(cfg.sides)}
    if cfg.circuit is not None:
        summary["circuit"] = {"name": cfg.circuit.circuit.name,
                              "controller": cfg.circuit.circuit.controller.kind,
                              "description": cfg.circuit_spec}
    if "no_device" in conds:
        base = conds["no_device"]["human"]["ankle_positive_work_j_per_stride"]
        summary["comparison_vs_no_device"] = {
            c: {"human_ankle_positive_work_change_j_per_stride":
                (v["human"]["ankle_positive_work_j_per_stride"] - base)
                if base is not None and v["human"]["ankle_positive_work_j_per_stride"]
                is not None else None}
            for c, v in conds.items() if c != "no_device"}
    return summary, results
