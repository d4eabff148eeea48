"""What ``afo-mj`` prints on stdout: the text summaries of runs, benches and calibrations.

Each function takes a finished result (the application layer's run objects or the
summary/report dicts) and returns the lines to print, units stated (deg, N·m, bar, J, W and
so on for the reader; every number comes from the SI result).
"""

from __future__ import annotations

import math
from typing import Mapping

__all__ = ["optimization_lines", "gait_optimization_lines", "fmt_stat", "walk_lines",
           "device_walk_lines", "human_response_line", "device_warnings", "sweep_outcome_counts",
           "sweep_outcome_lines", "bench_lines", "circuit_bench_lines",
           "format_stiffness_summary", "calibration_lines", "schematic_lines", "fmu_lines",
           "sweep_start_lines", "sweep_result_lines", "osim_lines", "adaptation_lines"]


def fmt_stat(entry, fmt: str = ".2f") -> str:
    """``mean ± sd`` of a summary entry (``{"mean", "sd", "n"}``), '-' when missing."""
    if not isinstance(entry, dict) or entry.get("mean") is None:
        return "-"
    sd = entry.get("sd")
    return f"{entry['mean']:{fmt}}" + ("" if sd is None else f" ± {sd:{fmt}}")


_f = fmt_stat


def _body(scenario) -> str:
    """The body that ran (the loaded scenario's, ``--set`` overrides included)."""
    w = scenario.walker
    return f"walker {w.body_mass_kg:g} kg, {w.height_m:g} m"


def walk_lines(scenario, reference, summary: Mapping, wall_time_s: float, out) -> list[str]:
    """A walk's summary: strides, fall, angle errors against the reference, ankle kinetics,
    speed, cadence, toe clearance, residual forces."""
    s = summary
    if s.get("fell") and "n_cycles_used" not in s:
        return [f"afo_mj walk: {scenario.name}: FELL at t = {s['fall_time_s']:.2f} s after "
                f"{s['completed_strides']} complete strides; {s.get('analysis', '')}",
                f"  results: {out}"]
    head = f"afo_mj walk: {scenario.name}, {_body(scenario)}"
    lines = [f"{head} ({scenario.description})" if scenario.description else head,
             f"  simulated {s['duration_s']:.2f} s in {wall_time_s:.1f} s wall; "
             f"{s['completed_strides']} complete right strides; analysed "
             f"{s['n_cycles_used']} cycles (strides {scenario.analyse_strides[0]}-"
             f"{scenario.analyse_strides[1]}, both legs)",
             "  " + ("FELL at t = %.2f s" % s["fall_time_s"] if s["fell"] else "no fall")
             + f"; swing toe contacts {s['swing_toe_contacts']}"]
    ref_name = f"{reference.source} {reference.condition}"
    lines.append(f"  angle RMS error vs {ref_name} [deg]: hip "
                 f"{_f(s['hip_angle_rms_error_deg'])}, knee {_f(s['knee_angle_rms_error_deg'])}"
                 f", ankle {_f(s['ankle_angle_rms_error_deg'])}")
    lines.append(f"  peak ankle plantarflexor moment "
                 f"{_f(s['peak_ankle_plantarflexor_moment_nm_per_kg'])} N*m/kg; peak ankle "
                 f"power {_f(s['peak_ankle_power_w_per_kg'])} W/kg; push-off work "
                 f"{_f(s['ankle_push_off_positive_work_j_per_kg'], '.3f')} J/kg")
    lines.append(f"  speed {_f(s['speed_m_s'])} m/s; cadence "
                 f"{_f(s['cadence_steps_per_min'], '.1f')} steps/min; stride "
                 f"{_f(s['stride_length_m'])} m; min toe clearance "
                 f"{_f(s['min_toe_clearance_m'], '.3f')} m")
    span = s["residual_force_rms_percent_body_weight"].get("over_analysed_span")
    lines.append(f"  residual force RMS {'-' if span is None else f'{span:.2f}'} % body "
                 f"weight; residual moment RMS {_f(s['residual_moment_rms_nm'])} N*m")
    mus = s.get("muscle")
    if mus:
        cot = mus["net_cost_of_transport_umberger_j_per_kg_m"]
        cot_b = mus["net_cost_of_transport_bhargava_j_per_kg_m"]
        lines.append(f"  muscles: net metabolic rate {mus['net_metabolic_umberger_w_per_kg']:.2f} "
                     f"W/kg (Umberger 2010), {mus['net_metabolic_bhargava_w_per_kg']:.2f} "
                     f"(Bhargava 2004); net cost of transport "
                     f"{'-' if cot is None else f'{cot:.2f}'}, "
                     f"{'-' if cot_b is None else f'{cot_b:.2f}'} J/(kg m)")
        if mus["emg_timing_right"]:
            lines.append("  EMG timing agreement with Perry (fraction of the cycle): " + ", ".join(
                f"{k} {v['agreement']:.2f}" for k, v in mus["emg_timing_right"].items()))
    for name, fractions in s.get("band_fraction_vs", {}).items():
        lines.append(f"  fraction of the cycle inside the ±1 SD band of {name}: " + ", ".join(
            f"{ch.split('_')[0]} {_f(v, '.2f')}" for ch, v in fractions.items()))
    lines.append(f"  results: {out}")
    return lines


def device_walk_lines(scenario, config, results: Mapping, device_summary: Mapping,
                      wall_time_s: float, out) -> list[str]:
    """A walk with an orthosis: on the torque walker a line saying that the wearer's response
    to the device is written in (:func:`human_response_line`), then one line per condition
    (gait, human ankle work, the device's torque, work, tracking and energy), then the
    foot-drop and push-off figures."""
    lines = [f"afo_mj walk with {config.preset} on {', '.join(config.sides)}: {scenario.name}, "
             f"{_body(scenario)} ({wall_time_s:.1f} s wall)"]
    lines += human_response_line(device_summary.get("human_response"))
    for c, v in device_summary["device_conditions"].items():
        g = v["gait"]
        line = f"  {c:12s}: "
        if g is None:
            fall = results[c][0].events.fall_time_s
            line += "no analysable stride" + ("" if fall is None
                                              else f" (fell at t = {fall:.2f} s)")
        else:
            line += (f"ankle RMS {_f(g['ankle_angle_rms_error_deg'])} deg, speed "
                     f"{_f(g['speed_m_s'])} m/s, human ankle +work "
                     f"{_num(v['human']['ankle_positive_work_j_per_stride'], '.1f')} "
                     "J/stride")
            if v.get("fell"):
                line += f"; FELL at t = {v['fall_time_s']:.3f} s"
        if "device" in v:
            d, e = v["device"], v["energy"]
            if d.get("positive_work_j_per_stride") is None:
                work = "whole run, no complete stride"
            else:
                work = (f"+work {d['positive_work_j_per_stride']:.1f} / -work "
                        f"{d['negative_work_j_per_stride']:.1f} J/stride")
            line += (f"; device peak {_num(d['peak_torque_nm'], '.1f')} N*m"
                     + (" outside end-stop contact" if d.get("end_stop_contact") else "")
                     + f", {work}, tracking RMSE "
                     f"{d['torque_tracking_rmse_nm']:.1f} N*m, battery drawn "
                     f"{e['electrical_in_j']:.0f} J, regen {e['electrical_regenerated_j']:.0f} J, "
                     f"balance error {100 * e['balance_error_rel']:.2f} %")
        lines.append(line)
        lines += [f"  {'':12s}  {w}" for w in metabolic_lines(
            v.get("muscle"), device_summary.get("comparison_vs_no_device", {}).get(c))]
        if "device" in v:
            lines += [f"  {'':12s}  {w}" for w in device_warnings(v["device"])]
        if g is None:
            continue
        # the foot-drop and push-off figures (gait: both legs pooled; push-off power: the
        # whole ankle joint, muscles + device, of the first worn side's leg)
        po = v.get("ankle", {}).get("push_off_peak_power_w")
        toe = g.get("min_toe_clearance_m")
        if isinstance(toe, dict) and toe.get("mean") is not None:     # printed in mm
            toe = {**toe, "mean": 1e3 * toe["mean"],
                   "sd": None if toe.get("sd") is None else 1e3 * toe["sd"]}
        line = (f"  {'':12s}  swing ankle {_f(g.get('swing_mean_ankle_angle_deg'), '.1f')}"
                f" deg (mean over mid-swing), swing peak dorsiflexion "
                f"{_f(g.get('swing_peak_dorsiflexion_deg'), '.1f')} deg, min toe "
                f"clearance {_f(toe, '.1f')} mm, "
                f"push-off peak power {'-' if po is None else f'{po:.1f}'} W")
        eps = v.get("energy_per_stride")
        if eps is not None:
            line += (f", device electrical {_num(eps['electrical_in_j'], '.1f')} J/stride "
                     f"({config.sides[0]} side)")
        lines.append(line)
    lines.append(f"  results: {out}")
    return lines


def _num(x, fmt: str) -> str:
    """``x`` formatted, '-' for None or NaN."""
    return "-" if x is None or (isinstance(x, float) and math.isnan(x)) else f"{x:{fmt}}"


def human_response_line(block: Mapping | None) -> list[str]:
    """One line when a device run's ``human_response`` block
    (:func:`afo_mj.experiments.device_walk.human_response`) names the torque walker's
    written-in rule, with its value as the block gives it; none otherwise (the muscle
    walker's reflexes respond by themselves)."""
    if not block or block.get("rule") != "assistance_adaptation":
        return []
    a = block.get("assistance_adaptation")
    return [f"  human response: written-in (torque walker, assistance_adaptation = {a}: the "
            f"wearer's ankle feedforward is lowered by {a} x the device torque, so changes "
            "of human ankle work with the device follow from it); for the wearer's own "
            'response use walker.model = "muscle"']


def metabolic_lines(muscle: Mapping | None, change: Mapping | None) -> list[str]:
    """The wearer's effort in one condition of a device walk on the muscle walker: net
    metabolic rate by both models and its change against the no-device condition (none on
    the torque walker, which has no effort model)."""
    if not muscle:
        return []
    line = (f"wearer's net metabolic rate {muscle['net_metabolic_umberger_w_per_kg']:.2f} W/kg "
            f"(Umberger 2010), {muscle['net_metabolic_bhargava_w_per_kg']:.2f} W/kg "
            "(Bhargava 2004)")
    pct = (change or {}).get("net_metabolic_umberger_change_pct")
    if pct is not None:
        line += (f"; vs no device {pct:+.1f} % (Umberger), "
                 f"{change['net_metabolic_bhargava_change_pct']:+.1f} % (Bhargava)")
    elif (change or {}).get("net_metabolic_change_note"):
        line += f"; change vs no device {change['net_metabolic_change_note']}"
    return [line]


def device_warnings(d: Mapping) -> list[str]:
    """The lines that say what a device did besides following its command (the flags of
    :mod:`afo_mj.metrics.device_flags` in a condition's ``device`` block): end-stop contact,
    braking, poor tracking, unconverged solver steps, battery overload; none for a device that
    did none of these."""
    out = []
    es = d.get("end_stop") or {}
    if d.get("end_stop_contact"):
        per = es.get("contact_time_s_per_stride")
        when = (f"{1e3 * per:.0f} ms per stride ({100 * es['contact_fraction']:.1f} % of the "
                f"time, {es['contacts_per_stride']:.1f} contacts per stride, impulse "
                f"{es['impulse_nm_s_per_stride']:.2f} N*m*s per stride)" if per is not None
                else f"{1e3 * es['contact_time_s']:.0f} ms over the run")
        out.append(f"WARNING END-STOP CONTACT: the pistons hit their stroke ends for {when}; "
                   f"the stops carried up to {es['peak_torque_nm']:.1f} N*m (whole-joint "
                   f"peak {_num(d.get('peak_torque_incl_end_stops_nm'), '.1f')} N*m); the "
                   f"device peak above is outside stop contact")
    if d.get("brake"):
        out.append(f"WARNING BRAKE: the device takes net work out of the ankle "
                   f"({_num(d.get('net_work_j_per_stride'), '.1f')} J/stride): it is "
                   f"back-driven or damping, not assisting")
    if d.get("tracking_poor"):
        out.append(f"WARNING TRACKING: RMS torque error {d['torque_tracking_rmse_nm']:.1f} N*m "
                   f"against a commanded peak of {d['commanded_peak_torque_nm']:.1f} N*m: the "
                   f"device did not deliver the assistance its controller asked for")
    return (out + solver_warnings(d.get("newton_unconverged_steps"))
            + battery_warnings(d.get("battery_overload_steps")))


def solver_warnings(newton_unconverged_steps) -> list[str]:
    """The line that says a circuit's solver accepted (sub-)steps whose Newton iteration did
    not converge (the ledger's ``newton_unconverged_steps``); none when there were none."""
    n = int(newton_unconverged_steps or 0)
    if n <= 0:
        return []
    return [f"WARNING SOLVER: {n} circuit (sub-)step(s) accepted with their Newton iteration "
            f"unconverged at the smallest sub-step: the figures and the energy ledger of "
            f"this run are not the model's (a parameter outside what the solver handles?)"]


def battery_warnings(battery_overload_steps) -> list[str]:
    """The line that says a circuit's bus drew more than its battery's matched-load power
    ``V_oc²/(4R)`` (the ledger's ``battery_overload_steps``); none when it never did."""
    n = int(battery_overload_steps or 0)
    if n <= 0:
        return []
    return [f"WARNING BATTERY: {n} circuit (sub-)step(s) drew more bus power than the "
            f"battery's matched-load power V_oc^2/(4R), the most the pack can deliver: the "
            f"excess is booked as the ledger's store battery_overload (energy no part of the "
            f"model supplied); this run's figures are not a real pack's (internal resistance "
            f"too high for the load?)"]


#: Row columns (flattened summary paths) a sweep counts as outcomes to look at, with labels.
SWEEP_OUTCOMES = (("fell", "fell"), ("device.end_stop_contact", "end-stop contact"),
                  ("device.brake", "brake"), ("device.tracking_poor", "poor torque tracking"),
                  ("device.newton_unconverged", "unconverged solver steps"),
                  ("device.battery_overload", "battery past its matched-load power"))


def sweep_outcome_counts(rows) -> dict:
    """``{label: [run_id, ...]}`` of the finished rows whose outcome flag is true (falls,
    end-stop contact, braking, poor tracking, unconverged solver steps, battery overload):
    results, not failures, that a reader of a study must not miss."""
    out = {}
    for key, label in SWEEP_OUTCOMES:
        ids = [r["run_id"] for r in rows if r.get("status") == "ok" and r.get(key) is True]
        if ids:
            out[label] = ids
    return out


def sweep_outcome_lines(rows) -> list[str]:
    """One line per outcome flag that some runs raised: how many and which (first five)."""
    return [f"  {len(ids)} run(s) with {label}: {', '.join(ids[:5])}"
            + (" ..." if len(ids) > 5 else "")
            for label, ids in sweep_outcome_counts(rows).items()]


def bench_lines(bench, summary: Mapping, wall_time_s: float, out) -> list[str]:
    """A bench run: on the stand, the figures of its protocols (against the published ones
    where the device has them) and the stiffness sweeps' table; on the simulated load, each
    protocol's headline figure (:func:`circuit_bench_lines`). Deprecated scenario forms read
    are noted first."""
    notes = [f"  note: {n}" for n in summary.get("notes", ())]
    if summary.get("rig") == "load":
        lines = circuit_bench_lines(bench, summary, wall_time_s, out)
        return lines[:1] + notes + lines[1:]
    lines = [f"afo_mj bench: {bench.name}, preset {bench.preset} on the stand "
             f"({wall_time_s:.1f} s wall)"] + notes
    b, pub = summary["bench"], summary.get("published") or {}
    rows = (("stall_torque_nm", "N*m", ".1f", pub.get("stall_torque_nm")),
            ("no_load_speed_deg_s", "deg/s", ".1f", pub.get("no_load_speed_deg_s")),
            ("rise_time_s", "s (40 N*m isometric step, 10-90 %)", ".4f", None),
            ("overshoot_pct", "%", ".1f", None),
            ("bandwidth_hz", "Hz (isometric torque, open loop, -3 dB)", ".2f", None),
            ("velocity_bandwidth_hz", "Hz (ankle velocity, open loop, -3 dB)", ".1f", None),
            ("position_rise_time_s", "s (closed-loop position step)", ".3f", None))
    for key, unit, fmt, ref in rows:
        if key in b:
            extra = f" (published {ref:g})" if ref is not None else ""
            lines.append(f"  {key:32s} {b[key]:{fmt}} {unit}{extra}")
    if "stiffness" in summary:
        lines += format_stiffness_summary(summary)
    d, e = summary["device"], summary["energy"]
    mass = ("masses not modelled" if d.get("mass_total_kg") is None else
            f"mass {d['mass_total_kg']:.2f} kg in all, {d['mass_at_ankle_kg']:.2f} kg at the "
            "ankle")
    lines.append(f"  {mass}; worst energy balance error "
                 f"{100 * e['balance_error_rel']:.2e} %")
    lines += [f"  {w}" for w in solver_warnings(e.get("newton_unconverged_steps"))
              + battery_warnings(e.get("battery_overload_steps"))]
    lines.append(f"  results: {out}")
    return lines


def circuit_bench_lines(bench, summary: Mapping, wall_time_s: float, out) -> list[str]:
    """A circuit bench: each protocol's headline figure and the energy ledgers."""
    b = summary["bench"]
    lines = [f"afo_mj bench: {bench.name}, circuit {summary['circuit']['name']} (controller "
             f"{summary['circuit']['controller']}; {wall_time_s:.1f} s wall)"]
    rows = (("torque_velocity", "stall_torque_nm", "N*m", ".1f"),
            ("torque_velocity", "no_load_speed_deg_s", "deg/s", ".1f"),
            ("isometric_steps", "rise_time_s", "s (largest step, 10-90 %)", ".4f"),
            ("isometric_steps", "overshoot_pct", "%", ".1f"),
            ("frequency_response", "resonance_hz", "Hz (open-loop velocity/voltage peak)",
             ".1f"),
            ("frequency_response", "resonance_peak_db", "dB above the lowest frequency", ".1f"),
            ("position_step", "rise_time_s", "s (closed-loop position step)", ".3f"),
            ("position_step", "overshoot_pct", "% (position step)", ".1f"),
            ("stiffness", "worst_error_rel", "(worst emulated stiffness error)", ".3f"),
            ("tracking", "rmse_nm", "N*m (torque profile on a moving load)", ".2f"))
    for proto, key, unit, fmt in rows:
        v = b.get(proto, {}).get(key)
        if isinstance(v, (int, float)):
            lines.append(f"  {proto + '.' + key:40s} {v:{fmt}} {unit}")
    e = summary["energy"]
    lines.append(f"  worst energy balance error {e['balance_error_rel']:.2e} over "
                 f"{len(summary['ledger'])} runs ("
                 f"{'closed' if e['ledger_closed'] else 'NOT closed'} within "
                 f"{e['tolerance']:g})")
    lines += [f"  {w}" for w in solver_warnings(e.get("newton_unconverged_steps"))
              + battery_warnings(e.get("battery_overload_steps"))]
    lines.append(f"  results: {out}")
    return lines


def format_stiffness_summary(summary: Mapping) -> list[str]:
    """Printed lines of a stiffness-bench summary (units stated; N·m/deg and deg for the
    clinical reader)."""
    sw = summary["sweep"]
    lines = [f"  sweep ±{math.degrees(sw['amplitude_rad']):.3g} deg at {sw['frequency_hz']:g} Hz, "
             f"{sw['cycles']} cycles (first dropped), stand foot {sw['body_mass_kg']:g} kg / "
             f"{sw['height_m']:g} m, step {sw['timestep_s'] * 1e3:g} ms",
             f"  {'commanded':>10s} {'emulated':>9s} {'error':>6s} {'r^2':>6s} "
             f"{'loop area':>9s} {'hyst.':>6s} {'peak torque':>11s} {'(K A)':>7s} "
             f"{'load/chamber/rail':>17s} {'electrical':>10s} {'mean':>5s} {'balance':>8s}",
             f"  {'[N*m/deg]':>10s} {'[N*m/deg]':>9s} {'[%]':>6s} {'[-]':>6s} "
             f"{'[J/cycle]':>9s} {'[-]':>6s} {'[N*m]':>11s} {'[N*m]':>7s} "
             f"{'[MPa]':>17s} {'[J]':>10s} {'[W]':>5s} {'err [%]':>8s}"]
    for v in summary["stiffness"].values():
        pr = "/".join("-" if v.get(k) is None else f"{v[k] / 1e6:.2f}"
                      for k in ("peak_load_pressure_pa", "peak_chamber_pressure_pa",
                                "peak_supply_pressure_pa"))
        lines.append(
            f"  {v['commanded_nm_per_deg']:10.3g} {v['emulated_nm_per_deg']:9.4g} "
            f"{100 * v['error_rel']:+6.2f} {v['r_squared']:6.4f} "
            f"{v['hysteresis_energy_j']:9.3f} {v['hysteresis_fraction']:6.3f} "
            f"{v['peak_torque_nm']:11.2f} {v['commanded_peak_torque_nm']:7.2f} {pr:>17s} "
            f"{v['electrical_in_j']:10.0f} {v['mean_electrical_power_w']:5.0f} "
            f"{100 * v['energy_balance_error_rel']:8.1e}")
    acc = summary["acceptance"]
    lines.append(f"  acceptance (every emulated stiffness within "
                 f"{100 * acc['tolerance_rel']:g} % of its command): "
                 f"{'PASSED' if acc['passed'] else 'FAILED'}, worst "
                 f"{100 * acc['worst_error_rel']:.2f} %")
    return lines


def calibration_lines(report: Mapping, out) -> list[str]:
    """A calibration's verdict, the effects it added (with their held-out error drop) and
    the overall held-out NRMSE before and after."""
    eb, ea = report["error_before"]["overall"], report["error_after"]["overall"]
    lines = [f"verdict: {report['verdict']}"]
    for s in report["effects_selected"]:
        pars = ", ".join(f"{k.split('.', 1)[1]} = {v:.4g}" for k, v in s["parameters"].items())
        lines.append(f"  + {s['effect']} ({s['component']}): {pars}; held-out NRMSE "
                     f"{s['held_out_before']:.4f} -> {s['held_out_after']:.4f} "
                     f"({-100 * s['held_out_drop']:+.0f} %"
                     + (f"; {-100 * s['held_out_drop_noise_units']:+.0f} % in noise units"
                        if "held_out_drop_noise_units" in s else "") + ")")
    if report.get("unexplained_where"):
        lines.append(f"  unexplained: {report['unexplained_where']}")
    lines.append(f"held-out NRMSE (overall): before {eb:.4f}, after {ea:.4f} "
                 f"({-100 * report['error_drop']:+.0f} %); {report['evaluations']} replays in "
                 f"{report['wall_time_s']:.1f} s")
    lines.append(f"wrote {out}/report.json, report.md and figures")
    return lines


def hydraulics_demo_lines(d: Mapping) -> list[str]:
    """The hydraulics demo's ranges (bar gauge, N·m, mm, deg, rpm, mK) and energy chain (J)."""
    r, e = d["ranges"], d["energy"]
    lines = ["afo_mj hydraulic demo: the lab bench circuit (pump-controlled piston-cable "
             "cylinder, 40 mm pulley) on a simulated foot, 8 V 3 Hz open-loop motor voltage",
             f"  simulated {d['duration_s']:.2f} s in 1 ms samples ({d['substeps']} stepper "
             f"step(s) each) in {d['wall_time_s']:.2f} s wall ({d['us_per_step']:.0f} "
             "us/sample)"]
    for key, label in (("chamber_a_gauge_pa", "chamber a pressure"),
                       ("chamber_b_gauge_pa", "chamber b pressure")):
        lo, hi = r[key]
        lines.append(f"  {label:22s} {lo / 1e5:7.1f} .. {hi / 1e5:7.1f} bar (gauge)")
    lines.append(f"  {'actuator torque':22s} {r['torque_nm'][0]:7.2f} .. "
                 f"{r['torque_nm'][1]:7.2f} N·m")
    lines.append(f"  {'piston position':22s} {r['position_m'][0] * 1e3:7.2f} .. "
                 f"{r['position_m'][1] * 1e3:7.2f} mm")
    lines.append(f"  {'joint angle':22s} {math.degrees(r['angle_rad'][0]):7.2f} .. "
                 f"{math.degrees(r['angle_rad'][1]):7.2f} deg")
    lines.append(f"  {'motor speed peak':22s} "
                 f"{d['motor_speed_peak_rad_s'] * 60 / 2 / math.pi:7.0f} rpm")
    lines.append(f"  {'oil temperature rise':22s} {d['oil_temperature_rise_k'] * 1e3:7.2f} mK")
    lines.append("  energy chain (J):")
    lines.append(f"    electrical input     {e['input_j']:9.4f}")
    share = (lambda v: f"  ({100 * v / e['input_j']:5.1f} %)") if e["input_j"] > 0 else \
        (lambda v: "")
    for k, v in e["heat_j"].items():
        lines.append(f"    loss {k:<22s}{v:9.4f}{share(v)}")
    lines.append(f"    stored change        {e['stored_change_j']:9.4f}")
    lines.append(f"    delivered to load    {e['load_out_j']:9.4f}")
    lines.append(f"    balance residual     {e['residual_j']:9.2e}  "
                 f"({100 * e['relative_residual']:.2e} % of the energy throughput)")
    return lines


def optimization_lines(res: Mapping, out) -> list[str]:
    """``afo-mj optimize``: the best point, its metric and constraints, and a JSON line."""
    import json
    metric = res["config"]["metric"] if isinstance(res.get("config"), dict) else ""
    lines = [f"afo-mj optimize: {res['study_name']}: {res['n_runs']} runs ({res['state']}); "
             f"best {metric} = {res['best_metric']} "
             f"({'feasible' if res['best_feasible'] else 'INFEASIBLE'})"]
    lines += [f"  {k} = {v}" for k, v in (res.get("best_point") or {}).items()]
    lines += [f"  constraint {k} = {v}" for k, v in (res.get("constraint_values") or {}).items()]
    lines.append(f"  {res.get('message', '')}; {out}/optimization.json")
    lines.append(json.dumps({k: res.get(k) for k in (
        "best_point", "best_metric", "best_feasible", "constraint_values", "n_runs", "state",
        "message")}, default=str))
    return lines


def _pct(v, fmt: str = "+.2f") -> str:
    return "-" if v is None else f"{v:{fmt}} %"


def _group_lines(g, control: str) -> list[str]:
    """``afo-mj adapt --groups``: a condition's group wearers (best of each group) and group
    means with their spreads, and its changes against the control group by group."""
    if not g:
        return []

    def rates(xs):
        return ", ".join("falls" if x is None else f"{x:.3f}" for x in xs)

    def spread(x):
        return "-" if x is None else f"{x:.2f} %"
    lines = [f"    best of {g['size']} in {len(g['restarts'])} groups (restarts "
             + ", ".join(str(i) for i in g["best_restart"]) + f"): {rates(g['best_rate'])} "
             f"W/kg, spread {spread(g['best_spread_pct'])}; group means "
             f"{rates(g['mean_rate'])} W/kg, spread {spread(g['mean_spread_pct'])}"]
    if "change_pct_best" in g:
        sp = g["change_pct_best_spread"]
        lines.append(f"    vs {control} by group, best of {g['size']}: "
                     + ", ".join(_pct(x) for x in g["change_pct_best"])
                     + f" (mean {_pct(g['change_pct_best_mean'])}, spread "
                     + ("-" if sp is None else f"{sp:.2f} points") + ")")
    return lines


def adaptation_lines(res, out) -> list[str]:
    """``afo-mj adapt``: per condition every restart's net metabolic rate (W/kg, Umberger
    2010) and convergence, the spread, the wearer and its change against the control (paired
    by restart and best against best), then a JSON line."""
    import json
    p = res.protocol
    lines = [f"afo-mj adapt: {len(res.conditions)} conditions x {p['restarts']} restarts, "
             f"CMA-ES popsize {p['popsize']}, sigma0 {p['sigma0']:g}, up to "
             f"{p['generations']} generations; {res.walks} walks"
             + ("" if res.cpu_s is None else f", {res.cpu_s:.0f} s CPU"),
             f"  start {res.start}; converged: window {p['window']} generations, best cost "
             f"change <= {p['cost_tol']:g}, spread <= {p['spread_target_pct']:g} %"]
    for c in res.conditions:
        lines.append(f"  {c.label}: wearer restart {c.best_restart}, "
                     + ("falls" if c.net_metabolic_w_per_kg is None
                        else f"{c.net_metabolic_w_per_kg:.3f} W/kg")
                     + ("" if c.spread_pct is None else
                        f"; spread {c.spread_w_per_kg:.3f} W/kg = {c.spread_pct:.2f} %")
                     + f"; {'converged' if c.converged else 'NOT converged'} ({c.reason})")
        for r in c.restarts:
            rate = ("falls" if r.net_metabolic_w_per_kg is None
                    else f"{r.net_metabolic_w_per_kg:.3f} W/kg")
            lines.append(f"    restart {r.restart} (seed {r.seed}): {rate}, cost "
                         f"{r.search_cost:.3f} after {r.generations} generations; "
                         f"{r.convergence}")
        if c.change_pct_paired is not None:
            rng = c.change_pct_all_pairs_range
            lines.append(f"    vs {res.control}: paired "
                         + ", ".join(_pct(x) for x in c.change_pct_paired)
                         + f" (mean {_pct(c.change_pct_paired_mean)}, spread "
                         + ("-" if c.change_pct_paired_spread is None
                            else f"{c.change_pct_paired_spread:.2f} points")
                         + f"); best vs best {_pct(c.change_pct_best)}"
                         + ("" if rng is None else f" (every pairing {rng[0]:+.2f} … "
                            f"{rng[1]:+.2f} %)"))
        lines += _group_lines(c.groups, res.control)
    lines.append(f"  {out}/adaptation.json "
                 + ("(every condition converged)" if res.converged else
                    "(not converged: run again with more --generations to continue)"))
    lines.append(json.dumps({c.name: {"net_metabolic_w_per_kg": c.net_metabolic_w_per_kg,
                                      "spread_pct": c.spread_pct, "converged": c.converged,
                                      "change_pct_best": c.change_pct_best,
                                      "change_pct_paired": c.change_pct_paired,
                                      **({} if not c.groups else {
                                          "best_of_group_spread_pct":
                                              c.groups["best_spread_pct"],
                                          "change_pct_by_group":
                                              c.groups.get("change_pct_best")})}
                             for c in res.conditions}))
    return lines


def hil_tuning_lines(res, out, json_line: bool = True) -> list[str]:
    """``tools/hil_tuning.py``: every arm's restarts (net metabolic rate, W/kg, Umberger 2010;
    the tuned profiles; for the HAFO the battery energy per stride and mean electrical
    power), the changes (tuned vs generic paired by restart, both vs the control) beside
    Zhang et al.'s figure, then (``json_line``) a JSON line."""
    import json
    p = res.protocol["adaptation"]
    b = res.protocol["bounds"]

    def rate(v):
        return "falls" if v is None else f"{v:.3f} W/kg"

    def change(name, ch):
        rng = ch.get("all_pairs_range")
        return (f"  {name}: paired " + ", ".join(_pct(x) for x in ch["paired"])
                + f" (mean {_pct(ch['paired_mean'])}, spread "
                + ("-" if ch["paired_spread"] is None else f"{ch['paired_spread']:.2f} points")
                + f"); best vs best {_pct(ch['best'])}"
                + ("" if rng is None else f" (every pairing {rng[0]:+.2f} … {rng[1]:+.2f} %)"))

    bat = res.battery

    def battery(j, w):
        return "" if j is None else f", battery {j:.2f} J/stride ({w:.2f} W)"

    lines = [("" if res.device is None else f"{res.device}, battery weight {bat['weight']:g}: ")
             + f"hil tuning: 3 arms x {p['restarts']} restarts, CMA-ES popsize {p['popsize']}, "
             f"{p['generations']} generations, sigma0 {p['sigma0']:g} (reflexes), "
             f"{res.protocol['profile_sigma']:g} of each bound (profile); {res.walks} walks"
             + ("" if res.cpu_s is None else f", {res.cpu_s:.0f} s CPU"),
             "  bounds: peak " + "–".join(f"{v:g}" for v in b["peak_nm_per_kg"])
             + " N·m/kg, peak time " + "–".join(f"{v:g}" for v in b["peak_time_pct"])
             + " %, rise " + "–".join(f"{v:g}" for v in b["rise_time_pct"])
             + " %, fall " + "–".join(f"{v:g}" for v in b["fall_time_pct"]) + " % of stride",
             f"  objective: {res.objective}"]
    for name, arm in (("control", res.control), ("generic", res.generic)):
        lines.append(f"  {name} ({arm.label}): wearer restart {arm.best_restart}, "
                     f"{rate(arm.net_metabolic_w_per_kg)}"
                     + ("" if arm.spread_pct is None else f"; spread {arm.spread_pct:.2f} %"))
        for r in arm.restarts:
            gb = ("" if bat is None or name != "generic" else
                  battery(bat["generic_j_per_stride"][r.restart],
                          bat["generic_power_w"][r.restart]))
            lines.append(f"    restart {r.restart} (seed {r.seed}): "
                         f"{rate(r.net_metabolic_w_per_kg)}{gb}, cost {r.search_cost:.3f} "
                         f"after {r.generations} generations; {r.convergence}")
    lines.append(f"  tuned: wearer restart {res.tuned_best_restart}, "
                 f"{rate(res.tuned_net_metabolic_w_per_kg)}"
                 + ("" if res.tuned_spread_pct is None
                    else f"; spread {res.tuned_spread_pct:.2f} %"))
    for r in res.tuned:
        lines.append(f"    restart {r.restart} (seed {r.seed}): peak {r.peak_nm_per_kg:.3f} "
                     f"N·m/kg at {r.peak_time_pct:.1f} %, rise {r.rise_time_pct:.1f} %, fall "
                     f"{r.fall_time_pct:.1f} %; {rate(r.net_metabolic_w_per_kg)}"
                     f"{battery(r.battery_j_per_stride, r.electrical_power_w)}, cost "
                     f"{r.search_cost:.3f}"
                     + ("" if r.wearer_cost is None else
                        f" (wearer's {r.wearer_cost:.3f})")
                     + f" after {r.generations} generations; {r.convergence}")
    lines.append("  change of the net metabolic rate:")
    lines.append(change("tuned vs generic", res.tuned_vs_generic))
    lines.append(change("tuned vs control", res.tuned_vs_control))
    lines.append(change("generic vs control", res.generic_vs_control))
    pub = res.published
    lines.append(f"  published: tuned {pub['tuned_change_pct']:+.1f} ± "
                 f"{pub['tuned_change_sd_pct']:.1f} % ({pub['source']})")
    if bat is not None:
        lines.append(f"  battery per stride: generic {_num(bat['generic_best_j_per_stride'])} "
                     f"J (spread {_num(bat['generic_spread_j_per_stride'])}), tuned "
                     f"{_num(bat['tuned_best_j_per_stride'])} J (spread "
                     f"{_num(bat['tuned_spread_j_per_stride'])}); mean electrical power "
                     f"generic {_num(bat['generic_best_power_w'])} W, tuned "
                     f"{_num(bat['tuned_best_power_w'])} W")
    lines.append(f"  {out}/" + ("hil_tuning.json" if bat is None
                                else f"hil_tuning_hafo_w{bat['weight']:g}.json"))
    if not json_line:
        return lines
    lines.append(json.dumps({"tuned_vs_generic": res.tuned_vs_generic,
                             "tuned_vs_control": res.tuned_vs_control,
                             "generic_vs_control": res.generic_vs_control,
                             "tuned_profiles": [{k: getattr(r, k) for k in (
                                 "peak_nm_per_kg", "peak_time_pct", "rise_time_pct",
                                 "fall_time_pct")} for r in res.tuned]}))


def _num(v, fmt: str = ".2f") -> str:
    return "-" if v is None else f"{v:{fmt}}"


def hil_front_lines(results, out) -> list[str]:
    """``tools/hil_tuning.py --device hafo``: each battery weight's arms
    (:func:`hil_tuning_lines`), then the front: per weight the wearer's net metabolic rate
    (W/kg), its change against the generic HAFO profile and the control (paired mean with its
    spread in points), the battery energy per stride (J) and mean electrical power (W) with
    the restarts' spread, and a JSON line of the front."""
    import json
    lines = []
    for res in results:
        lines += hil_tuning_lines(res, out, json_line=False)
    g = results[0]
    b0 = g.battery
    lines.append("  front (wearer = lowest search cost; paired mean and spread over restarts):")
    lines.append(f"    generic HAFO: {_num(g.generic.net_metabolic_w_per_kg, '.3f')} W/kg, "
                 f"vs control {_pct(g.generic_vs_control['paired_mean'])} (spread "
                 f"{_num(g.generic_vs_control['paired_spread'])} points); battery "
                 f"{_num(b0['generic_best_j_per_stride'])} J/stride (spread "
                 f"{_num(b0['generic_spread_j_per_stride'])}), "
                 f"{_num(b0['generic_best_power_w'])} W")
    front = []
    for res in results:
        b, tg, tc = res.battery, res.tuned_vs_generic, res.tuned_vs_control
        lines.append(f"    w = {b['weight']:g}: {_num(res.tuned_net_metabolic_w_per_kg, '.3f')} "
                     f"W/kg (spread {_pct(res.tuned_spread_pct, '.2f')}), vs generic "
                     f"{_pct(tg['paired_mean'])} (spread {_num(tg['paired_spread'])} points), "
                     f"vs control {_pct(tc['paired_mean'])} (spread "
                     f"{_num(tc['paired_spread'])} points); battery "
                     f"{_num(b['tuned_best_j_per_stride'])} J/stride (spread "
                     f"{_num(b['tuned_spread_j_per_stride'])}), {_num(b['tuned_best_power_w'])} W")
        front.append({"battery_weight": b["weight"],
                      "net_metabolic_w_per_kg": res.tuned_net_metabolic_w_per_kg,
                      "rate_spread_pct": res.tuned_spread_pct,
                      "vs_generic_pct": tg, "vs_control_pct": tc,
                      "battery_j_per_stride": b["tuned_j_per_stride"],
                      "electrical_power_w": b["tuned_power_w"],
                      "profiles": [{k: getattr(r, k) for k in (
                          "peak_nm_per_kg", "peak_time_pct", "rise_time_pct",
                          "fall_time_pct")} for r in res.tuned]})
    lines.append(json.dumps({"device": "hafo", "generic": {
        "net_metabolic_w_per_kg": g.generic.net_metabolic_w_per_kg,
        "vs_control_pct": g.generic_vs_control,
        "battery_j_per_stride": b0["generic_j_per_stride"],
        "electrical_power_w": b0["generic_power_w"]}, "front": front}))
    return lines


def dose_response_lines(res, out) -> list[str]:
    """``afo-mj dose-response``: per level every restart's net metabolic rate (W/kg,
    Umberger 2010), its paired change against the control and convergence, the band of the
    changes, whether the response is monotone within the bands, then a JSON line."""
    import json
    p = res.protocol
    lines = [f"afo-mj dose-response {res.study}: {res.variable} ({res.unit or '-'}), "
             f"{len(res.levels)} rungs x {p['restarts']} restarts by continuation, "
             f"{p['generations']} generations each; {res.walks} walks"
             + ("" if res.cpu_s is None else f", {res.cpu_s:.0f} s CPU")
             + ("" if res.complete else " (INCOMPLETE: run again to continue)")]
    for lv in res.levels:
        dose = "control" if lv.dose is None else f"{lv.dose:g}"
        band = ("" if lv.change_pct_mean is None else
                f"; change {_pct(lv.change_pct_mean)} ({lv.change_pct_min:+.2f} … "
                f"{lv.change_pct_max:+.2f} %)")
        if lv.matched_change_pct_mean is not None:
            band += (f"; vs the matched control {_pct(lv.matched_change_pct_mean)} "
                     f"({lv.matched_change_pct_min:+.2f} … {lv.matched_change_pct_max:+.2f} %)")
        lines.append(f"  {dose}: {lv.label}" + band + f"; {lv.searches_converged} of "
                     f"{len(lv.restarts)} searches converged"
                     + ("" if lv.spread_pct is None else f", spread {lv.spread_pct:.2f} %"))
        for r in lv.restarts:
            rate = ("falls" if r.net_metabolic_w_per_kg is None
                    else f"{r.net_metabolic_w_per_kg:.3f} W/kg")
            lines.append(f"    restart {r.restart}: {rate}"
                         + ("" if r.change_pct is None else f" ({_pct(r.change_pct)})")
                         + ("" if r.matched_change_pct is None else
                            f", vs matched control {r.matched_control_w_per_kg:.3f} W/kg: "
                            f"{_pct(r.matched_change_pct)}")
                         + ("" if r.device_off_fell_s is None and r.device_off_w_per_kg is None
                            else "; device off: " + (
                                f"falls at {r.device_off_fell_s:.1f} s"
                                if r.device_off_w_per_kg is None else
                                f"{r.device_off_w_per_kg:.3f} W/kg "
                                f"({_pct(r.device_off_change_pct)}) at "
                                f"{r.device_off_speed_m_s:.2f} m/s"))
                         + f", cost {r.search_cost:.3f} after {r.generations} generations; "
                         f"{r.convergence}")
    mono = {True: "yes", False: "NO", None: "-"}
    lines.append(f"  monotone (non-increasing) within the bands: "
                 f"{mono[res.monotone_within_bands]}; means falling at every step: "
                 f"{mono[res.monotone_means]}"
                 + (f" (left out, a restart fell: {', '.join(res.monotone_left_out)})"
                    if res.monotone_left_out else "")
                 + "; each restart's chain non-increasing: "
                 + ", ".join(mono[x] for x in res.monotone_per_restart)
                 + f"; against the matched control, within the bands: "
                 f"{mono[res.monotone_matched_within_bands]}")
    lines.append(f"  {out}/dose_response.json, {out}/dose_response.png")
    lines.append(json.dumps({"dose": [lv.dose for lv in res.levels],
                             "change_pct_mean": [lv.change_pct_mean for lv in res.levels],
                             "change_pct_min": [lv.change_pct_min for lv in res.levels],
                             "change_pct_max": [lv.change_pct_max for lv in res.levels],
                             "monotone_within_bands": res.monotone_within_bands}))
    return lines


def gait_optimization_lines(doc: Mapping, out) -> list[str]:
    """``afo-mj optimize-gait``: the best reflex set's cost and gait, and a JSON line."""
    import json
    q = doc.get("quality") or {}
    opt = doc["optimizer"]
    lines = [f"afo-mj optimize-gait: CMA-ES, {opt['generations']} generations, "
             f"{opt['evaluations']} walks; best cost {doc['cost']:.2f}"]
    if "speed_m_s" in q:
        rms = q["angle_rms_deg"]
        lines.append(f"  speed {q['speed_m_s']:.2f} m/s (target "
                     f"{doc['objective']['target_speed_m_s']}), stride {q['stride_s']:.2f} s, "
                     f"angle RMS vs Winter [deg] hip {rms['hip']:.1f}, knee {rms['knee']:.1f}, "
                     f"ankle {rms['ankle']:.1f}")
        lines.append(f"  net cost of transport {q['net_cost_of_transport_j_per_kg_m']:.2f} "
                     "J/(kg m) (Umberger 2010)")
    elif q:
        lines.append(f"  no steady walk yet: {q}")
    lines.append(f"  {out}/reflex_params.json")
    lines.append(json.dumps({"cost": doc["cost"], "quality": q}, default=str))
    lines.extend(reflex_set_lines(doc, out))
    return lines


def reflex_set_lines(doc: Mapping, out) -> list[str]:
    """The line that makes a muscle scenario walk with the optimised set: ``reflex_set =
    "<path>"`` for its ``[walker]`` table, the path relative to the scenario's folder (where
    scenarios resolve it) for an optimisation of a scenario, else absolute."""
    import json
    import os
    from pathlib import Path
    target = Path(out).resolve() / "reflex_params.json"
    sc = doc.get("scenario")
    if sc:
        folder = Path(sc["path"]).parent
        try:
            path = Path(os.path.relpath(target, folder)).as_posix()
        except ValueError:      # another drive (Windows): no relative path
            path = target.as_posix()
        head = f"  to walk {Path(sc['path']).name} with this wearer, put in its [walker]:"
    else:
        path = target.as_posix()
        head = "  to walk a muscle scenario with this set, put in its [walker]:"
    return [head, f"reflex_set = {json.dumps(path)}"]


def schematic_lines(info: Mapping) -> list[str]:
    """What ``afo-mj schematic`` wrote."""
    return [f"afo_mj schematic: {info['path']}: circuit {info['circuit']!r}, "
            f"{info['components']} components, {info['nodes']} nodes"]


def fmu_lines(info: Mapping) -> list[str]:
    """What ``afo-mj export-fmu`` wrote, and what the importing host needs."""
    kinds: dict = {}
    for v in info["variables"]:
        kinds[v["causality"]] = kinds.get(v["causality"], 0) + 1
    return [f"afo_mj export-fmu: {info['path']}: FMI 2.0 co-simulation FMU of {info['origin']} "
            f"({kinds.get('input', 0)} inputs, {kinds.get('output', 0)} outputs, "
            f"{kinds.get('parameter', 0)} parameters; kernel {info['kernel']})",
            "  the importing host needs Linux x86-64, this Python "
            f"({info['libpython'] or 'a Python host: this build has no shared libpython'}) "
            "and afo_mj importable in it (README: FMU export)"]


def sweep_start_lines(study, points, workers: int, scheduler) -> list[str]:
    """What ``afo-mj sweep`` is about to run, and where."""
    where = (f"Dask scheduler {scheduler}" if scheduler not in (None, "local")
             else f"a local Dask cluster of {workers} workers" if scheduler
             else f"{workers} local worker process(es)")
    return [f"afo-mj sweep: {study.name}: {len(points)} runs ({study.design} design over "
            f"{', '.join(p.key for p in study.parameters)}) on {where}"]


def sweep_result_lines(rows, failed, wall_time_s: float, table) -> list[str]:
    """The sweep's counts, its first failures, its outcomes (falls, end-stop contact,
    braking, poor tracking: each said) and a JSON line of the counts."""
    import json
    out = [f"  {len(rows)} runs, {len(failed)} failed, {wall_time_s:.1f} s wall; "
           f"table: {table}"]
    out += [f"  failed {r['run_id']}: {r['error']}" for r in failed[:5]]
    out += sweep_outcome_lines(rows)
    flagged = {k: len(v) for k, v in sweep_outcome_counts(rows).items()}
    out.append(json.dumps({"runs": len(rows), "failed": len(failed), "outcomes": flagged,
                           "table": str(table)}))
    return out


def osim_lines(models) -> list[str]:
    """What ``afo-mj export-osim`` wrote: one OpenSim model per run."""
    out = []
    for m in models:
        worn = f", {m['worn_mass_kg']:.2f} kg worn" if m["worn_mass_kg"] else ""
        out.append(f"afo_mj export-osim: {m['path']}: OpenSim model of run {m['run']!r} "
                   f"({m['mass_kg']:.2f} kg{worn})")
    return out
