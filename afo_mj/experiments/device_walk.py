"""Walking with an orthosis: every condition of a device scenario simulated, analysed and
summarised (the device's work, energy ledger and the wearer's ankle work per stride).

The scenario's ``[device]`` and ``[assistance]`` tables are parsed by
:mod:`afo_mj.scenarios.device_scenario` into a :class:`DeviceConfig`; this module builds the
device for each condition, walks it and writes the per-condition summary block.
"""

from __future__ import annotations

import math

import numpy as np

from afo_mj.hydraulics.params import ParameterError

from afo_mj.metrics.documents import (AnkleJointWork, DeviceFigures, DeviceWalkPart,
                                     EndStopContact, EnergyLedger, HumanAnkleWork,
                                     HumanResponse, RunEnergy, StrideEnergy, WornCondition)
from afo_mj.metrics.gait_metrics import PUSH_OFF_WINDOW
from afo_mj.scenarios.device_scenario import DeviceConfig


def _per_stride(rec, side: int, first: int, last: int):
    """Mask of samples in right-leg strides ``first..last`` (1-based) and their count."""
    hs = rec.events.heel_strikes_s[side]
    last = min(last, len(hs) - 1)
    if last < first:
        return None, 0
    t0, t1 = hs[first - 1], hs[last]
    return (rec.time_s >= t0) & (rec.time_s < t1), last - first + 1


def condition_summary(rec, analysis, device, cfg: DeviceConfig, strides) -> dict:
    """The JSON block of one condition (:func:`worn_condition`'s ``to_block()``)."""
    return worn_condition(rec, analysis, device, cfg, strides).to_block()


def worn_condition(rec, analysis, device, cfg: DeviceConfig, strides) -> WornCondition:
    """The summary of one condition (:class:`~afo_mj.metrics.documents.WornCondition`):
    ``fell`` and ``fall_time_s``, ``gait`` (the analysis, None without an analysable
    stride), ``human`` and ``ankle`` work per analysed stride, and for a worn device
    ``device`` (torque, work, tracking, masses, pressure, the end-stop contact and the
    brake / poor-tracking flags of :mod:`afo_mj.metrics.device_flags`),
    ``energy_per_stride`` and ``energy``. Without a
    complete analysed stride (a fall) the device's figures cover the whole run instead, and
    ``device.window`` says so; per-stride figures are then None."""
    side = 0 if cfg.sides[0] == "right" else 1
    first, last = strides
    mask, n = _per_stride(rec, side, first, last)
    fall = rec.events.fall_time_s
    out = {"fell": fall is not None, "fall_time_s": fall,
           "gait": analysis.document if analysis is not None else None}
    if mask is None:
        out["human"] = HumanAnkleWork(None)
        if device is None or device.log is None or device.log.n == 0:
            return WornCondition(**out)
        return WornCondition(**_device_blocks(out, rec, device, cfg, side,
                                              np.ones(len(rec.time_s), bool), None, []))
    dt = rec.sample_period_s
    w = rec.joint_velocity_rad_s[mask, side, 2]
    p_h = rec.joint_moment_nm[mask, side, 2] * w
    out["human"] = HumanAnkleWork(
        ankle_positive_work_j_per_stride=float(np.sum(np.clip(p_h, 0, None)) * dt / n),
        ankle_negative_work_j_per_stride=float(np.sum(np.clip(p_h, None, 0)) * dt / n))
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
    out["ankle"] = AnkleJointWork(
        push_off_peak_power_w=float(np.mean(peaks)) if peaks else None,
        push_off_positive_work_j_per_stride=float(np.mean(po_work)) if po_work else None,
        positive_work_j_per_stride=float(np.sum(np.clip(p_tot, 0, None)) * dt / n),
        note="whole ankle joint (muscles + device); push-off is "
             f"{PUSH_OFF_WINDOW[0]:.0%}-{PUSH_OFF_WINDOW[1]:.0%} of the stride")
    if device is None:
        return WornCondition(**out)
    return WornCondition(**_device_blocks(out, rec, device, cfg, side, mask, n, hs))


def _device_blocks(out: dict, rec, device, cfg: DeviceConfig, side: int, mask, n, hs) -> dict:
    """``out`` with the ``device``, ``energy_per_stride`` and ``energy`` blocks of
    :func:`worn_condition` (documents) over the samples ``mask`` spanning ``n`` strides (``n`` None:
    the whole run, no complete stride; per-stride figures None)."""
    from afo_mj.metrics.device_flags import (device_flags, end_stop_contact, end_stop_torque,
                                             mechanical_role, tracking_flag)
    dt = rec.sample_period_s
    L = device.log.arrays()
    k = 0
    n_log = min(len(L["time_s"]), len(rec.time_s))
    m = mask[:n_log]
    cmd = L["commanded_torque_nm"][:n_log, k][m]
    dlv = L["delivered_torque_nm"][:n_log, k][m]
    w = rec.joint_velocity_rad_s[mask, side, 2]
    p_d = rec.device_moment_nm[mask, side] * w
    per = (lambda x: x / n) if n else (lambda x: None)
    led = device_ledger(device, cfg, L, k)
    drawn = led.electrical_drawn_j
    mech_pos = float(np.sum(np.clip(L["mechanical_power_w"][:, k], 0, None)) * dt)
    duration = float(rec.time_s[-1] - rec.time_s[0]) if len(rec.time_s) > 1 else 0.0
    mean_power = drawn / duration if duration > 0 else math.nan
    energy_wh = led.battery_energy_wh
    runtime_h = (energy_wh / mean_power) if mean_power > 0 and energy_wh else None
    pos_w = float(np.sum(np.clip(p_d, 0, None)) * dt)
    neg_w = float(np.sum(np.clip(p_d, None, 0)) * dt)
    stop = end_stop_torque(L)
    contact = None
    peak = float(np.max(np.abs(dlv))) if dlv.size else 0.0
    if stop is not None:
        contact = end_stop_contact(stop[:n_log, k][m], dlv, dt, n or 1)
        if not n:
            for key in ("contact_time_s_per_stride", "contacts_per_stride",
                        "impulse_nm_s_per_stride"):
                contact[key] = None
        free = contact.pop("delivered_peak_outside_contact_nm")
        peak_all, peak = peak, (None if math.isnan(free) else free)
    rmse = float(np.sqrt(np.mean((cmd - dlv) ** 2))) if cmd.size else math.nan
    cmd_peak = float(np.max(np.abs(cmd))) if cmd.size else 0.0
    role, _reason = mechanical_role(per(pos_w + neg_w) if n else math.nan,
                                    per(pos_w) if n else math.nan)
    flags = device_flags(contact, role, tracking_flag(rmse, cmd_peak),
                         led.newton_unconverged_steps, led.battery_overload_steps)
    flags["flags"] = tuple(flags["flags"])
    device_note = None
    if cfg.circuit is not None:
        device_note = ("circuit description: worn masses are not modelled "
                       "(mass_total_kg null); hydraulic_j is not a ledger term")
    out["device"] = DeviceFigures(
        window=(f"the analysed strides of the {cfg.sides[0]} leg" if n else
                "whole run (no complete analysed stride): per-stride figures are None"),
        peak_torque_nm=peak,
        torque_tracking_rmse_nm=rmse,
        commanded_peak_torque_nm=cmd_peak,
        positive_work_j_per_stride=per(pos_w),
        negative_work_j_per_stride=per(neg_w),
        net_work_j_per_stride=per(pos_w + neg_w),
        mechanical_role=role,
        mass_total_kg=getattr(device, "mass_total_kg", None),
        mass_at_ankle_kg=getattr(device, "mass_at_ankle_kg", None),
        peak_pressure_mpa=led.peak_pressure_pa / 1e6,
        fluid_temperature_rise_k=led.temperature_rise_k,
        battery_runtime_h=runtime_h,
        coupling_torque_error_rms_nm=led.coupling_torque_error_rms_nm,
        newton_unconverged_steps=led.newton_unconverged_steps,
        battery_overload_steps=led.battery_overload_steps,
        peak_torque_incl_end_stops_nm=peak_all if contact is not None else None,
        end_stop=EndStopContact(**contact) if contact is not None else None,
        note=device_note, **flags)
    # per-stride figures: the whole-run ledger scaled by (mean analysed stride time / run time)
    stride_s = float(np.mean(np.diff(hs[:]))) if len(hs) > 1 else math.nan
    scale = stride_s / duration if duration > 0 and math.isfinite(stride_s) else math.nan
    out["energy_per_stride"] = StrideEnergy(
        stride_time_s=stride_s,
        electrical_in_j=drawn * scale,
        hydraulic_j=None if led.hydraulic_j is None else led.hydraulic_j * scale,
        mechanical_positive_out_j=mech_pos * scale,
        losses_j={k: v * scale for k, v in led.losses_j.items()},
        note="whole-run ledger (start-up strides included) times mean analysed stride "
             "time / run duration")
    energy_note = ("whole run; electrical_in_j is the battery's chemical energy drawn, "
                   "regeneration (ankle back-driving the pump) counted apart")
    if cfg.circuit is not None:
        energy_note = ("whole run; electrical_in_j is the energy drawn from the "
                       "circuit's source (battery chemical energy, or the ideal "
                       "bench supply), electrical_regenerated_j what went back; "
                       "losses and stores per component instance")
    out["energy"] = RunEnergy(
        run_duration_s=duration,
        electrical_in_j=drawn,
        electrical_regenerated_j=led.electrical_regenerated_j,
        hydraulic_j=led.hydraulic_j,
        mechanical_out_j=led.mechanical_out_j,
        mechanical_positive_out_j=mech_pos,
        losses_j=dict(led.losses_j),
        stored_change_j=dict(led.stored_change_j),
        efficiency_total=mech_pos / drawn if drawn > 0 else None,
        balance_error_rel=led.balance_error_rel,
        note=energy_note,
        input_j=led.input_j if cfg.circuit is not None else None)
    return out


def device_ledger(device, cfg: DeviceConfig, L: dict, k: int = 0) -> EnergyLedger:
    """The ledger terms the summary reads: the device's own ledger, with, for a device whose
    spec names no ledger groups (a description: the generic ledger of
    :meth:`afo_mj.circuits.device.CircuitDevice.ledger`), the generic keys mapped (drawn =
    ``input_drawn_j``, regenerated = ``input_drawn_j − input_j``, the oil temperature rise
    from the device log), and the battery energy from the circuit's battery component
    (None without one). A device that is no circuit reports its own (the ideal source).
    Returned as the :class:`~afo_mj.metrics.documents.EnergyLedger` document."""
    led = dict(device.ledger(k))
    spec = getattr(device, "spec", None)
    if spec is None:
        return EnergyLedger.from_ledger(led)
    circuit = device.cc.circuit
    if spec.ledger is None:
        temp = L["oil_temperature_k"][:, k]
        led["electrical_drawn_j"] = led["input_drawn_j"]
        led["electrical_regenerated_j"] = led["input_drawn_j"] - led["input_j"]
        led["hydraulic_j"] = None
        led["temperature_rise_k"] = (float(temp[-1] - circuit.thermal.ambient_temperature_k)
                                     if temp.size else 0.0)
    bats = [c for c in circuit.components if c.kind == "battery"]
    wh = None
    if bats:
        wh = bats[0].params.battery.energy_wh
    led["battery_energy_wh"] = wh
    return EnergyLedger.from_ledger(led, tuple(spec.ledger_extras))


def preset_config(preset: str, sides, profile: np.ndarray | None = None,
                  key: str = "device.preset") -> DeviceConfig:
    """The device of a scenario's ``[device] preset = <preset>, sides = <sides>`` (no
    ``params`` overrides) with ``profile`` (torque vs stride phase, N·m) as its ``assist``
    condition, for a tool that wears a registered device without a scenario file (the
    environment's ``mode="hafo"``, the muscle walker's assistance conditions); build it with
    :func:`make_device`. ``preset``: a registered circuit device
    (:mod:`afo_mj.devices.registry`; the ideal device is no circuit); ``key`` names the
    option in the error."""
    from afo_mj.devices.registry import device_entry
    from afo_mj.scenarios.device_scenario import device_params
    try:
        device_entry(preset, key)
    except ParameterError as exc:
        raise ValueError(str(exc)) from None
    preset, params, _ = device_params({"preset": preset}, key)
    return DeviceConfig(preset, params, tuple(sides),
                        ("assist",) if profile is not None else ("transparent",), profile)


def make_device(cfg: DeviceConfig, condition: str, timestep_s: float, max_steps: int,
                torque_fn=None):
    """The orthosis of ``cfg`` for one condition: a registered device or a described
    circuit (:meth:`DeviceConfig.device_spec`, stepped by
    :class:`~afo_mj.circuits.device.CircuitDevice`) or the ideal source, with the assistance
    profile or the impedance rows (any torque-controlled device emulates them) when the
    condition is ``assist`` or a stiffness condition. ``torque_fn(t, angle, velocity)``,
    when given, is the command instead (the circuit's controller input; asked once per worn
    side in ``cfg.sides`` order each step): the environment's action
    (:mod:`afo_mj.experiments.walk_env`)."""
    active = condition == "assist" or condition in cfg.impedance_conditions
    imp = cfg.impedance_conditions.get(condition, cfg.impedance) if active else None
    prof = cfg.profile if active and cfg.impedance is None else None
    kw = dict(sides=cfg.sides, profile=prof, impedance=imp, timestep_s=timestep_s,
              max_steps=max_steps)
    spec = cfg.device_spec()
    if torque_fn is not None:
        if spec is None:
            raise ValueError(f"device.preset = {cfg.preset!r} takes no torque command: it is "
                             "no circuit (it delivers its profile exactly); allowed: a circuit "
                             "device (a registered device or a [circuit])")
        kw.update(profile=None, impedance=None, torque_fn=torque_fn)
    if spec is None:   # exactly its command (afo_mj.devices.ideal)
        from afo_mj.devices.ideal import IdealDevice
        return IdealDevice(cfg.params, spring=cfg.spring if active else None,
                           ramp_strides=cfg.ramp_strides, **kw)
    from afo_mj.circuits.device import CircuitDevice
    return CircuitDevice(spec, **kw)


#: What the ``human_response`` block says of each walker model (:func:`human_response`).
HUMAN_RESPONSE_NOTES = {
    "torque": ("the wearer's ankle feedforward is lowered by this fraction of the device "
               "torque (a written-in rule, not a response): human ankle work changes with a "
               "device follow from it"),
    "muscle": "reflexes respond; no written-in rule",
}


def human_response(scenario) -> dict:
    """How the simulated wearer answers a worn device, for a device run's summary.

    The torque walker has no answer of its own: it lowers its ankle feedforward by
    ``controller.assistance_adaptation`` × the device's torque
    (:mod:`afo_mj.gait.tracking_controller`), so any change of the human ankle's work with a
    device rests on that rule. The block is
    ``{"walker_model": "torque", "rule": "assistance_adaptation", "assistance_adaptation":
    <the scenario's value>, "note": ...}``. The muscle walker's reflexes respond to the
    device by themselves: ``{"walker_model": "muscle", "rule": None, "assistance_adaptation":
    None, "note": ...}``."""
    model = getattr(scenario, "walker_model", "torque")
    if model == "torque":
        return {"walker_model": "torque", "rule": "assistance_adaptation",
                "assistance_adaptation": float(scenario.controller_params()
                                               .assistance_adaptation),
                "note": HUMAN_RESPONSE_NOTES["torque"]}
    if model == "muscle":
        return {"walker_model": "muscle", "rule": None, "assistance_adaptation": None,
                "note": HUMAN_RESPONSE_NOTES["muscle"]}
    from afo_mj.gait.controller import controller_class, controller_names
    if model in controller_names():
        return {"walker_model": model, "rule": None, "assistance_adaptation": None,
                "note": controller_class(model).device_response_note}
    raise ValueError(f"walker.model = {model!r}; allowed: "
                     f"{', '.join(map(repr, HUMAN_RESPONSE_NOTES))}")


def run_device_scenario(scenario, reference, cfg: DeviceConfig, muscle_walks=None):
    """Run every condition; returns ``(summary, per-condition (record, analysis, device))``,
    the summary as a JSON-able dict (:func:`run_device_conditions`' document without its
    headline ``condition``)."""
    part, results = run_device_conditions(scenario, reference, cfg, muscle_walks)
    summary = part.to_block()
    summary.pop("condition")
    return summary, results


def run_device_conditions(scenario, reference, cfg: DeviceConfig, muscle_walks=None):
    """Run every condition; returns ``(part, per-condition (record, analysis, device))``,
    ``part`` the :class:`~afo_mj.metrics.documents.DeviceWalkPart` document (headline: the
    last condition).

    The walker is the scenario's (``walker.model``,
    :data:`afo_mj.gait.walkers.WALKER_MODELS`). On the muscle walker
    each condition's block gains ``muscle`` (net metabolic rate and cost of transport by
    Umberger 2010 and Bhargava 2004, per muscle: :func:`afo_mj.metrics.muscle_metrics.
    muscle_summary` over the analysed strides) and ``comparison_vs_no_device`` the change of
    the net metabolic rate; ``muscle_walks`` (a dict), when given, receives each condition's
    :class:`~afo_mj.gait.muscle_walk.MuscleWalk`. The summary's ``human_response``
    (:func:`human_response`) says whether the wearer's answer to the device is a written-in
    rule (torque walker) or their own (muscle walker)."""
    from afo_mj.metrics.gait_metrics import GaitAnalysisError, analyse_gait
    from afo_mj.gait.walkers import walker_model
    entry = walker_model(scenario)
    walk_fn, duration_fn = entry.walk, entry.duration
    dt = scenario.walker.timestep_s
    results, walks = {}, {}
    n = len(cfg.conditions)
    for i, cond in enumerate(cfg.conditions, 1):
        dev = None
        worn = ()
        if cond != "no_device":
            steps = int(duration_fn(scenario, reference) / dt) + 4
            dev = make_device(cfg, cond, dt, steps)
            # a circuit description has no worn-mass layout (its parts' masses are metadata)
            worn = dev.worn_masses() if hasattr(dev, "worn_masses") else ()
        rec, walk = walk_fn(scenario, reference, dev, worn,
                            f"condition {i}/{n}: {cond}" if n > 1 else cond)
        try:
            analysis = analyse_gait(rec, reference, scenario.analyse_strides)
        except GaitAnalysisError:
            analysis = None
        results[cond] = (rec, analysis, dev)
        if walk is not None:
            walks[cond] = walk
            if muscle_walks is not None:
                muscle_walks[cond] = walk
    conds = {c: worn_condition(r, a, d, cfg, scenario.analyse_strides)
             for c, (r, a, d) in results.items()}
    circuit = None
    if cfg.circuit is not None:
        circuit = {"name": cfg.circuit.circuit.name,
                   "controller": cfg.circuit.circuit.controller.kind,
                   "description": cfg.circuit_spec}
    for c, walk in walks.items():
        conds[c] = conds[c].with_muscle(_muscle_block(walk, results[c][1]))
    comparison = None
    if "no_device" in conds:
        nd = conds["no_device"]
        base = nd.human.ankle_positive_work_j_per_stride
        comparison = {
            c: {"human_ankle_positive_work_change_j_per_stride":
                (v.human.ankle_positive_work_j_per_stride - base)
                if base is not None and v.human.ankle_positive_work_j_per_stride
                is not None else None,
                **_metabolic_change(nd.muscle, v.muscle, nd.fall_time_s, v.fall_time_s)}
            for c, v in conds.items() if c != "no_device"}
    part = DeviceWalkPart(condition=cfg.conditions[-1], device_conditions=conds,
                          device_preset=cfg.preset, device_sides=tuple(cfg.sides),
                          human_response=HumanResponse(**human_response(scenario)),
                          circuit=circuit, comparison_vs_no_device=comparison)
    return part, results


def _muscle_block(walk, analysis) -> dict | None:
    """The condition's ``muscle`` block over its analysed strides (None without them)."""
    if analysis is None:
        return None
    from afo_mj.metrics.muscle_metrics import muscle_summary
    t0, t1 = analysis.summary["analysed_span_s"]
    return muscle_summary(walk, t0, t1)


def _metabolic_change(base: dict | None, cond: dict | None, base_fall_s=None,
                      cond_fall_s=None) -> dict:
    """The wearer's net metabolic rate with the device minus without it, W/kg and % of the
    rate without it, by both models (nothing on the torque walker, None where a condition
    has no analysed stride). A walk that fell (with or without the device) gives no change:
    its rate over the strides before the fall is no steady walk's, so the two cannot be set
    against each other; ``net_metabolic_change_note`` says which fell (the fall is the
    result)."""
    if base is None and cond is None:
        return {}
    out = {}
    fell = [f"the walk {w} fell at t = {t:.3f} s" for w, t in
            (("without the device", base_fall_s), ("with the device", cond_fall_s))
            if t is not None]
    for model in ("umberger", "bhargava"):
        key = f"net_metabolic_{model}_w_per_kg"
        b = None if base is None else base.get(key)
        v = None if cond is None else cond.get(key)
        ok = b is not None and v is not None and not fell
        out[f"net_metabolic_{model}_change_w_per_kg"] = (v - b) if ok else None
        out[f"net_metabolic_{model}_change_pct"] = (100.0 * (v - b) / b) if ok and b else None
    if fell:
        out["net_metabolic_change_note"] = "not given: " + "; ".join(fell)
    return out
