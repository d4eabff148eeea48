"""Command-line interface: ``afo-mj``.

* ``afo-mj run SCENARIO.toml --out DIR``: simulate a walking scenario (``scenarios/``),
  analyse the strides it names against its reference gait and write ``summary.json``,
  ``cycles.csv``, ``gait_curves.csv``, ``gait_curves.png`` and ``scenario.toml`` into DIR.
  A walker that falls before a complete stride is an outcome: ``summary.json`` says so with the
  fall time. Exit codes: 0 done (fall or not); 1 the run could not be simulated, analysed or
  written (numerics failure, nothing written); 2 invalid scenario (nothing written).
* ``afo-mj calibrate --scenario S --data D --out DIR``: replay a measured bench record, fit the
  declared parameters, search the effect library for what the model lacks and write
  ``report.json``, ``report.md`` and figures (:mod:`afo_mj.calibration.calibrate`).
* ``afo-mj make-bench-record --kind hafo --effect NAME:PARAM=V --out FILE.csv``: a synthetic
  bench record with undeclared effects (:mod:`afo_mj.calibration.synthetic_records`).
* ``afo-mj sweep STUDY.toml --out DIR [--workers N] [--scheduler ADDRESS|local]``: run a
  parameter study in parallel, resumably (:mod:`afo_mj.studies.sweep`).
* ``afo-mj study DIR [--metric M]``: ranked table, plots, Pareto front and sensitivity indices
  of a sweep; ``afo-mj optimize STUDY.toml --out DIR``: optimise a study's parameters.
* ``afo-mj design REQUIREMENTS.toml --out DIR [--verify]``: size a minimum-weight hydraulic
  orthosis from requirements (:mod:`afo_mj.design.system_design`).
* ``afo-mj build-models``: write the default MJCF models into ``models/mjcf/``.
* ``afo-mj hydraulics-demo``: a loaded pump-controlled cylinder (motor → pump → hoses → piston-cable
  cylinder → load) stepped at 1 ms, with its energy chain and accuracy against a Radau
  reference printed.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np


def _demo(args: argparse.Namespace) -> int:
    from afo_mj.hydraulics.fluid import ATMOSPHERIC_PRESSURE_PA
    from afo_mj.hydraulics.pump_cylinder import STATE_NAMES
    from afo_mj.hydraulics.verification import make_case, run_fixed_step

    case = make_case("loaded")
    case.duration_s = args.duration_s
    t0 = time.perf_counter()
    t, ys, sim = run_fixed_step(case, dt=1e-3, substeps=args.substeps)
    wall = time.perf_counter() - t0
    idx = {n: i for i, n in enumerate(STATE_NAMES)}
    bar = lambda p: (p - ATMOSPHERIC_PRESSURE_PA) / 1e5  # noqa: E731
    cyl = case.circuit.cylinder
    force = cyl.hydraulic_force_n(ys[:, idx["chamber_a_pa"]], ys[:, idx["chamber_b_pa"]])
    eb = sim.energy_balance()
    print("afo_mj hydraulic demo: pump-controlled piston-cable cylinder, 2 kg + 20 kN/m load")
    print(f"  simulated {t[-1]:.2f} s at 1 ms steps ({args.substeps} ROS2 substeps) "
          f"in {wall:.2f} s wall ({wall / (len(t) - 1) * 1e6:.0f} us/step)")
    print(f"  chamber a pressure     {bar(ys[:, idx['chamber_a_pa']]).min():7.1f} .. "
          f"{bar(ys[:, idx['chamber_a_pa']]).max():7.1f} bar (gauge)")
    print(f"  chamber b pressure     {bar(ys[:, idx['chamber_b_pa']]).min():7.1f} .. "
          f"{bar(ys[:, idx['chamber_b_pa']]).max():7.1f} bar (gauge)")
    print(f"  actuator force         {force.min():7.1f} .. {force.max():7.1f} N")
    print(f"  piston position        {ys[:, idx['position_m']].min() * 1e3:7.2f} .. "
          f"{ys[:, idx['position_m']].max() * 1e3:7.2f} mm")
    print(f"  motor speed peak       "
          f"{np.abs(ys[:, idx['speed_rad_s']]).max() * 60 / 2 / np.pi:7.0f} rpm")
    print(f"  oil temperature rise   "
          f"{(ys[-1, idx['fluid_temperature_k']] - ys[0, idx['fluid_temperature_k']]) * 1e3:7.2f}"
          f" mK")
    print("  energy chain (J):")
    print(f"    electrical input     {eb['input_j']:9.4f}")
    for k, v in eb["heat_j"].items():
        print(f"    loss {k:<22s}{v:9.4f}  ({100 * v / eb['input_j']:5.1f} %)")
    print(f"    stored change        {eb['stored_change_j']:9.4f}")
    print(f"    delivered to load    "
          f"{eb['load_out_j'] if 'load_out_j' in eb else eb['output_j']:9.4f}")
    print(f"    balance residual     {eb['residual_j']:9.2e}  "
          f"({100 * eb['relative_residual']:.3f} % of input)")
    summary = {"duration_s": float(t[-1]), "us_per_step": wall / (len(t) - 1) * 1e6,
               "max_force_n": float(force.max()), "energy": {
                   "input_j": float(eb["input_j"]), "output_j": float(eb["output_j"]),
                   "heat_j": {k: float(v) for k, v in eb["heat_j"].items()},
                   "relative_residual": float(eb["relative_residual"])}}
    if args.json:
        print(json.dumps(summary))
    return 0


def _simulate_walk(scenario):
    """The walking simulation (imported lazily: MuJoCo is only needed for ``run``)."""
    from afo_mj.gait.walk import simulate_walk
    return simulate_walk(scenario)


def _fmt(entry, fmt: str = ".2f") -> str:
    """``mean ± sd`` of a summary entry (``{"mean", "sd", "n"}``), '-' when missing."""
    if not isinstance(entry, dict) or entry.get("mean") is None:
        return "-"
    sd = entry.get("sd")
    return f"{entry['mean']:{fmt}}" + ("" if sd is None else f" ± {sd:{fmt}}")


def _run_info_writer(wall_s: float):
    """Writer of ``run_info.json``: what is not a result of the scenario (wall time,
    versions), kept out of ``summary.json`` so that a rerun gives an identical summary."""
    def write(tmp: Path) -> None:
        import platform

        import mujoco
        info = {"wall_time_s": wall_s, "python": platform.python_version(),
                "numpy": np.__version__, "mujoco": mujoco.__version__,
                "platform": platform.platform()}
        (tmp / "run_info.json").write_text(json.dumps(info, indent=2) + "\n", encoding="utf-8")
    return write


def _device_files_writer(results, reference, dsum, name, wall_s):
    """Writer of a device run's figures and ``run_info.json``."""
    def write(tmp: Path) -> None:
        from afo_mj.outputs.device_figures import plot_device_run
        _run_info_writer(wall_s)(tmp)
        if "circuit" in dsum:
            # a circuit's log has its own signal names: the gait figures without the preset
            # devices' hydraulics panels, and the circuit's own torque/pressure figure
            from afo_mj.outputs.circuit_figures import plot_circuit_gait
            plot_device_run(tmp, {c: (r, a, None) for c, (r, a, _d) in results.items()},
                            reference, dsum, name)
            plot_circuit_gait(tmp, results, dsum, name)
        else:
            plot_device_run(tmp, results, reference, dsum, name)
    return write


def _chain(*writers):
    """One results-directory writer that calls ``writers`` (None entries skipped) in turn."""
    def write(tmp: Path) -> None:
        for w in writers:
            if w is not None:
                w(tmp)
    return write


def _recording_writer(scenario, runs, reference):
    """Writer of ``recording.rrd`` into the results directory when the scenario's
    ``[output] record`` is true (else None)."""
    if not getattr(scenario, "record", False):
        return None

    def write(tmp: Path) -> None:
        from afo_mj.outputs.gait_report import ReportError
        from afo_mj.outputs.recording import RecordingError
        try:
            _write_rrd(tmp / "recording.rrd", scenario, runs, reference)
        except RecordingError as exc:
            raise ReportError(f"recording.rrd: {exc}") from None
    return write


def _write_rrd(path, scenario, runs, reference) -> dict:
    from afo_mj.outputs.recording import write_recording
    return write_recording(path, runs, reference, title=scenario.name,
                           signal_rate_hz=getattr(scenario, "record_signal_rate_hz", 500.0),
                           transform_rate_hz=getattr(scenario, "record_transform_rate_hz", 50.0))


def _rrd_option(args, scenario, runs, reference) -> int:
    """``--rrd FILE``: the recording written beside the results (0, or 1 on failure)."""
    if not getattr(args, "rrd", None):
        return 0
    from afo_mj.outputs.recording import RecordingError
    try:
        info = _write_rrd(args.rrd, scenario, runs, reference)
    except (RecordingError, OSError) as exc:
        print(f"afo-mj: recording not written: {exc}", file=sys.stderr)
        return 1
    print(f"  recording: {info['path']} ({len(info['entities'])} entities; open with "
          f"`afo-mj view {info['path']}`)")
    return 0


def _run(args: argparse.Namespace) -> int:
    from afo_mj.metrics.gait_metrics import GaitAnalysisError, analyse_gait
    from afo_mj.outputs.gait_report import ReportError, write_run_outputs
    from afo_mj.scenarios.walk_scenario import ScenarioError, load_scenario

    from afo_mj.outputs.result_dir import ResultDirError, check_result_dir
    from afo_mj.scenarios.bench_scenario import is_bench_document
    from afo_mj.scenarios.device_scenario import device_config
    from afo_mj.scenarios.walk_scenario import strides_overrides
    try:
        text = Path(args.scenario).read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError):
        text = ""          # load_scenario reports it
    try:
        check_result_dir(args.out)
    except ResultDirError as exc:
        print(f"afo-mj run: {exc}; nothing written", file=sys.stderr)
        return 2
    if args.strides is not None and args.strides < 1:
        print(f"afo-mj run: --strides = {args.strides} is not allowed; allowed: an integer "
              f">= 1", file=sys.stderr)
        return 2
    if is_bench_document(text):
        if args.strides is not None:
            print(f"afo-mj run: --strides: {args.scenario} is a bench scenario (no strides); "
                  f"allowed: --strides on walking scenarios only", file=sys.stderr)
            return 2
        return _run_bench(args)
    overrides = ((strides_overrides(args.strides) if args.strides is not None else [])
                 + list(args.set or ()))
    try:
        scenario = load_scenario(args.scenario, overrides=overrides)
        reference = scenario.load_reference()
        dev_cfg = device_config(scenario)
    except ScenarioError as exc:
        print(f"afo-mj run: invalid scenario: {exc}", file=sys.stderr)
        return 2
    for note in scenario.notes:
        print(f"afo-mj run: note: {note}", file=sys.stderr)
    if dev_cfg is not None:
        return _run_device(args, scenario, reference, dev_cfg)
    from afo_mj.gait.walk import WalkNumericsError
    t0 = time.perf_counter()
    try:
        record = _simulate_walk(scenario)
    except WalkNumericsError as exc:
        print(f"afo-mj run: {scenario.name}: {exc}; nothing written", file=sys.stderr)
        return 1
    wall = time.perf_counter() - t0
    from afo_mj.outputs.recording import RecordedRun
    runs = [RecordedRun("walk", record)]
    try:
        analysis = analyse_gait(record, reference, scenario.analyse_strides)
    except GaitAnalysisError as exc:
        if record.events.fall_time_s is None:
            print(f"afo-mj run: {scenario.name}: {exc}", file=sys.stderr)
            return 1
        # A fall before any analysable stride is the run's outcome: report it.
        ev = record.events
        summary = {"scenario": scenario.as_dict(), "fell": True,
                   "fall_time_s": ev.fall_time_s,
                   "completed_strides": max(len(ev.heel_strikes_s[0]) - 1, 0),
                   "swing_toe_contacts": len(ev.swing_toe_contacts),
                   "duration_s": float(record.time_s[-1]) if len(record.time_s) else 0.0,
                   "analysis": str(exc)}
        out = write_run_outputs(args.out, summary, [], reference, record, scenario.text,
                                extra_files=_chain(_run_info_writer(wall), _recording_writer(
                                    scenario, runs, reference)))
        print(f"afo_mj walk: {scenario.name}: FELL at t = {ev.fall_time_s:.2f} s after "
              f"{summary['completed_strides']} complete strides; {exc}")
        print(f"  results: {out}")
        return _rrd_option(args, scenario, runs, reference)
    try:
        summary = {"scenario": scenario.as_dict(), **analysis.summary}
        if scenario.band_references:
            from afo_mj.metrics.gait_metrics import band_fraction
            from afo_mj.gait.reference import load_normative
            summary["band_fraction_vs"] = {
                f"{src}:{cond}": band_fraction(analysis.cycles, load_normative(src, cond))
                for src, cond in scenario.band_references}
        out = write_run_outputs(args.out, summary, analysis.cycles, reference, record,
                                scenario.text, extra_files=_chain(
                                    _run_info_writer(wall),
                                    _recording_writer(scenario, runs, reference)))
    except (GaitAnalysisError, ReportError) as exc:
        print(f"afo-mj run: {scenario.name}: {exc}", file=sys.stderr)
        return 1
    s = summary
    print(f"afo_mj walk: {scenario.name} ({scenario.description})" if scenario.description
          else f"afo_mj walk: {scenario.name}")
    print(f"  simulated {s['duration_s']:.2f} s in {wall:.1f} s wall; "
          f"{s['completed_strides']} complete right strides; analysed "
          f"{s['n_cycles_used']} cycles (strides {scenario.analyse_strides[0]}-"
          f"{scenario.analyse_strides[1]}, both legs)")
    print("  " + ("FELL at t = %.2f s" % s["fall_time_s"] if s["fell"] else "no fall")
          + f"; swing toe contacts {s['swing_toe_contacts']}")
    ref_name = f"{reference.source} {reference.condition}"
    print(f"  angle RMS error vs {ref_name} [deg]: hip {_fmt(s['hip_angle_rms_error_deg'])}, "
          f"knee {_fmt(s['knee_angle_rms_error_deg'])}, "
          f"ankle {_fmt(s['ankle_angle_rms_error_deg'])}")
    print(f"  peak ankle plantarflexor moment "
          f"{_fmt(s['peak_ankle_plantarflexor_moment_nm_per_kg'])} "
          f"N*m/kg; peak ankle power {_fmt(s['peak_ankle_power_w_per_kg'])} W/kg; "
          f"push-off work {_fmt(s['ankle_push_off_positive_work_j_per_kg'], '.3f')} J/kg")
    print(f"  speed {_fmt(s['speed_m_s'])} m/s; cadence {_fmt(s['cadence_steps_per_min'], '.1f')} "
          f"steps/min; stride {_fmt(s['stride_length_m'])} m; min toe clearance "
          f"{_fmt(s['min_toe_clearance_m'], '.3f')} m")
    rf = s["residual_force_rms_percent_body_weight"]
    span = rf.get("over_analysed_span")
    print(f"  residual force RMS {'-' if span is None else f'{span:.2f}'} % body weight; "
          f"residual moment RMS {_fmt(s['residual_moment_rms_nm'])} N*m")
    for name, fractions in s.get("band_fraction_vs", {}).items():
        print(f"  fraction of the cycle inside the ±1 SD band of {name}: " + ", ".join(
            f"{ch.split('_')[0]} {_fmt(v, '.2f')}" for ch, v in fractions.items()))
    print(f"  results: {out}")
    return _rrd_option(args, scenario, runs, reference)


def _run_device(args, scenario, reference, cfg) -> int:
    """A walking scenario with an orthosis: every condition, the headline one written out."""
    import numpy as np

    from afo_mj.gait.walk import WalkNumericsError
    from afo_mj.outputs.gait_report import ReportError, write_run_outputs
    from afo_mj.experiments.device_walk import run_device_scenario
    t0 = time.perf_counter()
    try:
        dsum, results = run_device_scenario(scenario, reference, cfg)
    except (WalkNumericsError, FloatingPointError) as exc:
        print(f"afo-mj run: {scenario.name}: {exc}; nothing written", file=sys.stderr)
        return 1
    wall = time.perf_counter() - t0
    head = cfg.conditions[-1]
    rec, analysis, dev = results[head]
    block = dsum["device_conditions"][head]
    if analysis is None:
        print(f"afo-mj run: {scenario.name}: condition {head!r} has no analysable stride "
              f"(fell at {rec.events.fall_time_s}); nothing written", file=sys.stderr)
        return 1
    summary = {"scenario": {**scenario.as_dict(), "device": dict(scenario.device),
                            "assistance": dict(scenario.assistance)},
               **analysis.summary, "condition": head,
               "gait": analysis.summary, "human": block["human"], **dsum}
    if "device" in block:
        summary["device"] = block["device"]
        summary["energy"] = block["energy"]
    extra = {}
    if dev is not None and dev.log is not None:
        L = dev.log.arrays()
        cols = [k for k in L]
        data = np.column_stack([L[k][:, 0] for k in cols])
        extra["device_timeseries.csv"] = (",".join(cols), data)
    from afo_mj.outputs.recording import RecordedRun
    runs = [RecordedRun(c, r, d) for c, (r, _a, d) in results.items()]
    try:
        out = write_run_outputs(args.out, summary, analysis.cycles, reference, rec,
                                scenario.text, extra_tables=extra,
                                extra_files=_chain(
                                    _device_files_writer(results, reference, dsum,
                                                         scenario.name, wall),
                                    _recording_writer(scenario, runs, reference)))
    except ReportError as exc:
        print(f"afo-mj run: {scenario.name}: {exc}", file=sys.stderr)
        return 1
    print(f"afo_mj walk with {cfg.preset} on {', '.join(cfg.sides)}: {scenario.name} "
          f"({wall:.1f} s wall)")
    for c, v in dsum["device_conditions"].items():
        g = v["gait"]
        line = f"  {c:12s}: "
        if g is None:
            fall = results[c][0].events.fall_time_s
            line += "no analysable stride" + ("" if fall is None
                                              else f" (fell at t = {fall:.2f} s)")
        else:
            line += (f"ankle RMS {_fmt(g['ankle_angle_rms_error_deg'])} deg, speed "
                     f"{_fmt(g['speed_m_s'])} m/s, human ankle +work "
                     f"{v['human']['ankle_positive_work_j_per_stride']:.1f} J/stride")
        if "device" in v:
            d, e = v["device"], v["energy"]
            line += (f"; device peak {d['peak_torque_nm']:.1f} N*m, +work "
                     f"{d['positive_work_j_per_stride']:.1f} / -work "
                     f"{d['negative_work_j_per_stride']:.1f} J/stride, tracking RMSE "
                     f"{d['torque_tracking_rmse_nm']:.1f} N*m, battery drawn "
                     f"{e['electrical_in_j']:.0f} J, regen {e['electrical_regenerated_j']:.0f} J, "
                     f"balance error {100 * e['balance_error_rel']:.2f} %")
        print(line)
        if g is not None:
            # the foot-drop and push-off figures (gait: both legs pooled; push-off power:
            # the whole ankle joint, muscles + device, of the first worn side's leg)
            po = v.get("ankle", {}).get("push_off_peak_power_w")
            toe = g.get("min_toe_clearance_m")
            if isinstance(toe, dict) and toe.get("mean") is not None:     # printed in mm
                toe = {**toe, "mean": 1e3 * toe["mean"],
                       "sd": None if toe.get("sd") is None else 1e3 * toe["sd"]}
            line = (f"  {'':12s}  swing ankle {_fmt(g.get('swing_mean_ankle_angle_deg'), '.1f')}"
                    f" deg (mean over mid-swing), swing peak dorsiflexion "
                    f"{_fmt(g.get('swing_peak_dorsiflexion_deg'), '.1f')} deg, min toe "
                    f"clearance {_fmt(toe, '.1f')} mm, "
                    f"push-off peak power {'-' if po is None else f'{po:.1f}'} W")
            eps = v.get("energy_per_stride")
            if eps is not None:
                line += (f", device electrical {eps['electrical_in_j']:.1f} J/stride "
                         f"({cfg.sides[0]} side)")
            print(line)
    print(f"  results: {out}")
    return _rrd_option(args, scenario, runs, reference)


def _run_bench(args) -> int:
    """A bench scenario: the device on the ankle test stand."""
    import json

    from afo_mj.outputs.gait_report import json_ready
    from afo_mj.outputs.result_dir import ResultDirError, write_atomically
    from afo_mj.experiments.bench_run import run_bench_scenario
    from afo_mj.scenarios.bench_scenario import load_bench_scenario
    from afo_mj.experiments.hafo_bench import BenchError, plot_bench
    from afo_mj.scenarios.walk_scenario import ScenarioError
    try:
        bs = load_bench_scenario(args.scenario, overrides=args.set or ())
    except ScenarioError as exc:
        print(f"afo-mj run: invalid scenario: {exc}", file=sys.stderr)
        return 2
    t0 = time.perf_counter()
    from afo_mj.experiments.circuit_bench import CircuitBenchError
    try:
        summary, series = run_bench_scenario(bs)
    except (BenchError, CircuitBenchError, FloatingPointError) as exc:
        print(f"afo-mj run: {bs.name}: {exc}; nothing written", file=sys.stderr)
        return 1
    wall = time.perf_counter() - t0

    def writer(tmp: Path) -> None:
        _run_info_writer(wall)(tmp)
        text = json.dumps(json_ready(summary), indent=2, allow_nan=False)
        (tmp / "summary.json").write_text(text + "\n", encoding="utf-8")
        (tmp / "scenario.toml").write_text(bs.text, encoding="utf-8")
        if bs.bench_kind == "stiffness":
            from afo_mj.experiments.stiffness_bench import plot_stiffness_bench
            plot_stiffness_bench(series, tmp)
        elif bs.bench_kind == "circuit":
            from afo_mj.outputs.circuit_figures import plot_circuit_bench
            plot_circuit_bench(series, tmp, bs.name)
        else:
            plot_bench(series, tmp)

    try:
        out = write_atomically(args.out, writer)
    except ResultDirError as exc:
        print(f"afo-mj run: {bs.name}: {exc}", file=sys.stderr)
        return 1
    if bs.bench_kind == "circuit":
        return _print_circuit_bench(args, bs, summary, out, wall)
    rc = _bench_rrd_option(args, bs, series)
    print(f"afo_mj bench: {bs.name}, preset {bs.preset} ({wall:.1f} s wall)")
    if bs.bench_kind == "stiffness":
        from afo_mj.experiments.stiffness_bench import format_stiffness_summary
        for line in format_stiffness_summary(summary):
            print(line)
        print(f"  mass {summary['device']['mass_total_kg']:.2f} kg worn; worst energy balance "
              f"error {100 * summary['energy']['balance_error_rel']:.2e} %")
        print(f"  results: {out}")
        return rc
    b = summary["bench"]
    pub = summary["published"]

    def show(key, unit, fmt=".3g", ref=None):
        if key in b:
            extra = f" (published {ref:g})" if ref is not None else ""
            print(f"  {key:32s} {b[key]:{fmt}} {unit}{extra}")
    show("stall_torque_nm", "N*m", ".1f", pub.get("stall_torque_nm"))
    show("no_load_speed_deg_s", "deg/s", ".1f", pub.get("no_load_speed_deg_s"))
    show("rise_time_s", "s (40 N*m isometric step, 10-90 %)", ".4f")
    show("overshoot_pct", "%", ".1f")
    show("bandwidth_hz", "Hz (isometric torque, open loop, -3 dB)", ".2f")
    show("velocity_bandwidth_hz", "Hz (ankle velocity, open loop, -3 dB)", ".1f")
    show("position_rise_time_s", "s (closed-loop position step)", ".3f")
    print(f"  mass {summary['device']['mass_total_kg']:.2f} kg in all, "
          f"{summary['device']['mass_at_ankle_kg']:.2f} kg at the ankle; worst energy "
          f"balance error {100 * summary['energy']['balance_error_rel']:.3f} %")
    print(f"  results: {out}")
    return rc


def _print_circuit_bench(args, bs, summary, out, wall) -> int:
    b = summary["bench"]
    print(f"afo_mj bench: {bs.name}, circuit {summary['circuit']['name']} (controller "
          f"{summary['circuit']['controller']}; {wall:.1f} s wall)")
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
            print(f"  {proto + '.' + key:40s} {v:{fmt}} {unit}")
    e = summary["energy"]
    print(f"  worst energy balance error {e['balance_error_rel']:.2e} over "
          f"{len(summary['ledger'])} runs ({'closed' if e['ledger_closed'] else 'NOT closed'}"
          f" within {e['tolerance']:g})")
    print(f"  results: {out}")
    if getattr(args, "rrd", None):
        print("afo-mj: --rrd is not written for a circuit bench (no time-domain recording "
              "of its protocols yet)", file=sys.stderr)
    return 0


def _bench_rrd_option(args, bs, series) -> int:
    """``--rrd FILE`` for a bench run: its time-domain experiments, one after another."""
    if not getattr(args, "rrd", None):
        return 0
    from afo_mj.outputs.recording import RecordingError, write_bench_recording
    try:
        info = write_bench_recording(args.rrd, series, title=bs.name)
    except (RecordingError, OSError) as exc:
        print(f"afo-mj: recording not written: {exc}", file=sys.stderr)
        return 1
    print(f"  recording: {info['path']} ({len(info['entities'])} entities; open with "
          f"`afo-mj view {info['path']}`)")
    return 0


def _compare(args) -> int:
    """``afo-mj compare``: orthosis architectures side by side on one gait (usage:
    :mod:`afo_mj.experiments.device_comparison`)."""
    import platform

    from afo_mj.experiments.device_comparison import (CompareError, load_compare_items,
                                                   run_comparison)
    from afo_mj.gait.walk import WalkNumericsError
    from afo_mj.outputs.comparison_report import format_tables, write_comparison
    from afo_mj.outputs.result_dir import ResultDirError, check_result_dir
    from afo_mj.scenarios.walk_scenario import ScenarioError
    try:
        check_result_dir(args.out)
    except ResultDirError as exc:
        print(f"afo-mj compare: {exc}; nothing written", file=sys.stderr)
        return 2
    try:
        items = load_compare_items(args.scenarios, overrides=args.set or (),
                                   strides=args.strides)
    except (ScenarioError, CompareError) as exc:
        print(f"afo-mj compare: invalid scenario: {exc}; nothing written", file=sys.stderr)
        return 2
    for note in dict.fromkeys(n for it in items for n in it.scenario.notes):
        print(f"afo-mj compare: note: {note}", file=sys.stderr)
    kept: list | None = [] if args.rrd else None
    try:
        from afo_mj import progress
        rep = progress.reporter()
        comp = run_comparison(items, progress=lambda m: rep.stage(f"compare: {m}"),
                              keep_runs=kept)
    except (WalkNumericsError, FloatingPointError) as exc:
        print(f"afo-mj compare: {exc}; nothing written", file=sys.stderr)
        return 1
    import mujoco
    info = {"argv": {"scenarios": list(args.scenarios), "set": list(args.set or ()),
                     "strides": args.strides},
            "python": platform.python_version(), "numpy": np.__version__,
            "mujoco": mujoco.__version__, "platform": platform.platform()}
    try:
        out = write_comparison(args.out, comp, info)
    except (ResultDirError, OSError, ValueError) as exc:
        print(f"afo-mj compare: {exc}; nothing written", file=sys.stderr)
        return 1
    print(f"afo_mj compare: {len(comp.rows)} devices, assist condition, per mean analysed "
          f"stride ({comp.wall_time_s:.1f} s wall)")
    print(format_tables(comp))
    print(f"  results: {out}")
    if kept:
        import re

        from afo_mj.outputs.recording import RecordedRun, RecordingError, write_recording
        runs = [RecordedRun(re.sub(r"[^A-Za-z0-9_]+", "_", label).strip("_") or f"run{i}",
                               rec, dev) for i, (label, rec, dev) in enumerate(kept)]
        try:
            info = write_recording(args.rrd, runs, items[0].reference,
                                   title="afo_mj compare")
        except (RecordingError, OSError) as exc:
            print(f"afo-mj compare: recording not written: {exc}", file=sys.stderr)
            return 1
        print(f"  recording: {info['path']} ({len(runs)} devices side by side; open with "
              f"`afo-mj view {info['path']}`)")
    return 0


def _view(args) -> int:
    """``afo-mj view FILE.rrd``: the rerun viewer (installed with rerun-sdk) on the file; with
    ``--web`` rerun's web viewer served over HTTP (works without a display). Without a display
    and without ``--web``: exit 2 with the ways to see the file."""
    import os
    import shlex
    import shutil
    import socket
    import subprocess
    p = Path(args.rrd)
    if p.suffix != ".rrd" or not p.is_file():
        print(f"afo-mj view: {str(p)!r} is not an existing .rrd file (write one with "
              f"`afo-mj run SCENARIO --out DIR --rrd FILE.rrd`)", file=sys.stderr)
        return 2
    exe = shutil.which("rerun") or str(Path(sys.executable).with_name("rerun"))
    web = getattr(args, "web", False)
    cmd = [exe, "--serve-web", str(p)] if web else [exe, str(p)]
    if args.print_command:
        print(" ".join(cmd))
        return 0
    headless = (sys.platform.startswith("linux") and not os.environ.get("DISPLAY")
                and not os.environ.get("WAYLAND_DISPLAY"))
    if headless and not web:
        host = socket.gethostname()
        q = shlex.quote(str(p.resolve()))
        print(f"afo-mj view: no display here (DISPLAY and WAYLAND_DISPLAY are unset), so the "
              f"rerun viewer cannot open a window. Either\n"
              f"  serve rerun's web viewer and open it in a browser:\n"
              f"    afo-mj view {q} --web      (runs `rerun --serve-web FILE`)\n"
              f"    then open http://localhost:9090 (from another machine, forward the web "
              f"and data ports first: ssh -L 9090:localhost:9090 -L 9876:localhost:9876 "
              f"{host})\n"
              f"  or copy the recording to a machine with a display and open it there:\n"
              f"    scp {host}:{q} . && rerun {shlex.quote(p.name)}", file=sys.stderr)
        return 2
    if not Path(exe).exists():
        print("afo-mj view: the rerun viewer executable is missing (pip install "
              "rerun-sdk)", file=sys.stderr)
        return 1
    return subprocess.call(cmd)


def _render(args) -> int:
    """``afo-mj render SCENARIO --mp4 FILE``."""
    from afo_mj.app.render import render as render_scenario
    from afo_mj.outputs.video import RenderError
    from afo_mj.scenarios.walk_scenario import ScenarioError
    try:
        info = render_scenario(args.scenario, args.mp4, overrides=args.set or (),
                               condition=args.condition, fps=args.fps, width=args.width,
                               height=args.height, max_seconds=args.max_seconds)
    except (RenderError, ScenarioError) as exc:
        print(f"afo-mj render: {exc}; nothing written", file=sys.stderr)
        return 2
    print(f"afo_mj render: {info['path']}: {info['frames']} frames at {info['fps']} fps, "
          f"{info['width']}x{info['height']}, {info['duration_s']:.2f} s simulated "
          f"(condition {info['condition']})")
    return 0


def _build_models(args: argparse.Namespace) -> int:
    from afo_mj.human import test_stand, walker
    for path in (walker.write_default_xml(), test_stand.write_default_xml()):
        print(f"wrote {path}")
    return 0



def _calibrate(args) -> int:
    """``afo-mj calibrate``: exit 0 done (whatever the verdict), 1 the calibration failed
    (nothing written), 2 bad input (nothing written)."""
    import warnings

    from afo_mj.calibration.calibrate import (
        CalibrationError, calibrate, load_calibration_setup)
    from afo_mj.calibration.measured_data import MeasuredDataError, load_measured
    from afo_mj.hydraulics.params import ParameterError
    from afo_mj.outputs.calibration_report import write_calibration_report
    from afo_mj.outputs.result_dir import ResultDirError, check_result_dir, write_atomically
    from afo_mj.experiments.bench_replay import ReplayError

    try:
        check_result_dir(args.out)
    except ResultDirError as exc:
        print(f"afo-mj calibrate: {exc}; nothing written", file=sys.stderr)
        return 2
    try:
        preset, overrides, options = load_calibration_setup(args.scenario)
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            data = load_measured(args.data)
        for w in caught:
            print(f"warning: {w.message}", file=sys.stderr)
        if data.source.get("preset") and data.source["preset"] != preset:
            print(f"warning: the record says source.preset = {data.source['preset']!r}; "
                  f"calibrating {preset!r} (from --scenario)", file=sys.stderr)
    except (ParameterError, MeasuredDataError, OSError) as exc:
        print(f"afo-mj calibrate: {exc}", file=sys.stderr)
        return 2
    try:
        report = calibrate(data, preset, options, overrides)
    except (CalibrationError, ParameterError) as exc:
        print(f"afo-mj calibrate: {exc}", file=sys.stderr)
        return 2
    except (ReplayError, FloatingPointError) as exc:
        print(f"afo-mj calibrate: {exc}; nothing written", file=sys.stderr)
        return 1
    command = "afo-mj " + " ".join(sys.argv[1:]) if sys.argv[1:2] == ["calibrate"] else None
    from afo_mj import progress
    progress.reporter().stage(f"writing the report and figures to {args.out}…")
    try:
        write_atomically(args.out, lambda d: write_calibration_report(
            report, d, data_path=args.data, command=command))
    except (ResultDirError, ValueError, OSError) as exc:
        print(f"afo-mj calibrate: {exc}; nothing written", file=sys.stderr)
        return 1
    eb, ea = report["error_before"]["overall"], report["error_after"]["overall"]
    print(f"verdict: {report['verdict']}")
    for s in report["effects_selected"]:
        pars = ", ".join(f"{k.split('.', 1)[1]} = {v:.4g}" for k, v in s["parameters"].items())
        print(f"  + {s['effect']} ({s['component']}): {pars}; held-out NRMSE "
              f"{s['held_out_before']:.4f} -> {s['held_out_after']:.4f} "
              f"({-100 * s['held_out_drop']:+.0f} %)")
    if report.get("unexplained_where"):
        print(f"  unexplained: {report['unexplained_where']}")
    print(f"held-out NRMSE (overall): before {eb:.4f}, after {ea:.4f} "
          f"({-100 * report['error_drop']:+.0f} %); {report['evaluations']} replays in "
          f"{report['wall_time_s']:.1f} s")
    print(f"wrote {args.out}/report.json, report.md and figures")
    print(json.dumps({"verdict": report["verdict"],
                      "effects": [s["effect"] for s in report["effects_selected"]],
                      "error_before": eb, "error_after": ea}))
    return 0


def _make_bench_record(args) -> int:
    """``afo-mj make-bench-record``: a synthetic bench record with undeclared effects."""
    import warnings

    from afo_mj.calibration.measured_data import MeasuredDataError
    from afo_mj.calibration.synthetic_records import generate_record
    from afo_mj.hydraulics.params import ParameterError

    def pairs(items, what):
        out = {}
        for it in items or []:
            k, sep, v = it.partition("=")
            if not sep:
                raise ParameterError(f"{what} {it!r}; allowed: NAME=VALUE")
            try:
                out[k.strip()] = float(v)
            except ValueError:
                raise ParameterError(f"{what} {it!r}: {v!r} is not a number") from None
        return out

    try:
        if args.preset is not None:
            from afo_mj.experiments.bench_replay import kind_of_preset
            kind_of_preset(args.preset, key="--preset")
        effects = {}
        for spec in args.effect or []:
            name, _, rest = spec.partition(":")
            effects[name.strip()] = pairs([p for p in rest.split(",") if p], "--effect")
        mismatch = pairs(args.mismatch, "--mismatch")
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            data = generate_record(args.out, args.kind, effects, mismatch,
                                   noise_scale=args.noise_scale, duration_s=args.duration_s,
                                   fs_hz=args.fs_hz, seed=args.seed, preset=args.preset,
                                   torque_sensor_resonance_hz=args.resonance_hz)
    except (ParameterError, MeasuredDataError, OSError) as exc:
        print(f"afo-mj make-bench-record: {exc}", file=sys.stderr)
        return 2
    print(f"wrote {args.out} ({data.n_samples} samples) and its sidecar: "
          f"{data.source['description']}")
    return 0


def _sweep(args) -> int:
    """``afo-mj sweep``: exit 0 all runs done (failed runs recorded and reported), 1 every run
    failed, 2 invalid study (a key the scenario does not accept: checked before any run),
    130 interrupted (finished runs kept: run again to resume)."""
    from afo_mj.studies.study import StudyError, load_study
    from afo_mj.studies.sweep import Sweep, SweepInterrupted, check_study_keys

    try:
        study = load_study(args.study)
        points = study.points()
        check_study_keys(study, points)
    except StudyError as exc:
        print(f"afo-mj sweep: invalid study: {exc}", file=sys.stderr)
        return 2
    if args.workers is not None and args.workers < 1:
        print(f"afo-mj sweep: --workers = {args.workers}; allowed: >= 1", file=sys.stderr)
        return 2
    sw = Sweep(study, args.out, workers=args.workers, scheduler=args.scheduler,
               fmt=args.format, keep_runs=args.keep_runs, progress=not args.quiet)
    where = (f"Dask scheduler {args.scheduler}" if args.scheduler and args.scheduler != "local"
             else f"a local Dask cluster of {sw.workers} workers" if args.scheduler
             else f"{sw.workers} local worker process(es)")
    print(f"afo-mj sweep: {study.name}: {len(points)} runs ({study.design} design over "
          f"{', '.join(p.key for p in study.parameters)}) on {where}")
    t0 = time.perf_counter()
    try:
        rows = sw.run(points)
    except SweepInterrupted as exc:
        print(f"afo-mj sweep: {exc}", file=sys.stderr)
        return 130
    except ValueError as exc:
        print(f"afo-mj sweep: {exc}", file=sys.stderr)
        return 2
    failed = [r for r in rows if r["status"] != "ok"]
    print(f"  {len(rows)} runs, {len(failed)} failed, {time.perf_counter() - t0:.1f} s wall; "
          f"table: {sw.table_path}")
    for r in failed[:5]:
        print(f"  failed {r['run_id']}: {r['error']}")
    print(json.dumps({"runs": len(rows), "failed": len(failed), "table": str(sw.table_path)}))
    if rows and len(failed) == len(rows):
        print(f"afo-mj sweep: every run failed ({len(rows)} of {len(rows)}), e.g. "
              f"{failed[0]['error']}; see {sw.table_path}", file=sys.stderr)
        return 1
    if failed:
        print(f"afo-mj sweep: {len(failed)} of {len(rows)} runs failed (recorded in "
              f"{sw.table_path})", file=sys.stderr)
    return 0


def _study(args) -> int:
    """``afo-mj study DIR``: ranked table, plots and sensitivity indices of a sweep."""
    from afo_mj.outputs.study_report import write_study_report

    try:
        rep = write_study_report(args.dir, metric=args.metric)
    except (ValueError, OSError) as exc:
        print(f"afo-mj study: {exc}", file=sys.stderr)
        return 2
    print(rep.get("text", ""))
    return 0


def _optimize(args) -> int:
    """``afo-mj optimize STUDY.toml``: exit 0 done, 2 invalid study, 130 interrupted (the
    runs and ``optimization.json`` are kept: run again to resume)."""
    from afo_mj.studies.optimize import optimize_study
    from afo_mj.studies.study import StudyError, load_study
    from afo_mj.studies.sweep import SweepInterrupted

    if args.workers is not None and args.workers < 1:
        print(f"afo-mj optimize: --workers = {args.workers}; allowed: >= 1", file=sys.stderr)
        return 2
    try:
        study = load_study(args.study)
        res = optimize_study(study, args.out, workers=args.workers, scheduler=args.scheduler,
                             progress=not args.quiet)
    except StudyError as exc:
        print(f"afo-mj optimize: invalid study: {exc}", file=sys.stderr)
        return 2
    except SweepInterrupted as exc:
        print(f"afo-mj optimize: {exc}", file=sys.stderr)
        return 130
    except ValueError as exc:
        print(f"afo-mj optimize: {exc}", file=sys.stderr)
        return 2
    print(f"afo-mj optimize: {study.name}: {res['n_runs']} runs ({res['state']}); best "
          f"{res['config']['metric'] if isinstance(res.get('config'), dict) else ''} = "
          f"{res['best_metric']} ({'feasible' if res['best_feasible'] else 'INFEASIBLE'})")
    for k, v in (res.get("best_point") or {}).items():
        print(f"  {k} = {v}")
    for k, v in (res.get("constraint_values") or {}).items():
        print(f"  constraint {k} = {v}")
    print(f"  {res.get('message', '')}; {args.out}/optimization.json")
    print(json.dumps({k: res.get(k) for k in ("best_point", "best_metric", "best_feasible",
                                              "constraint_values", "n_runs", "state",
                                              "message")}, default=str))
    return 0


def _design(args) -> int:
    """``afo-mj design``: exit 0 a feasible design written, 1 infeasible (the binding
    constraint printed and written), 2 invalid requirements (nothing written)."""
    from afo_mj.app.design import design as run_design
    from afo_mj.design.design_requirements import DesignError

    if args.top < 1:
        print(f"afo-mj design: --top = {args.top}; allowed: >= 1", file=sys.stderr)
        return 2
    try:
        out = run_design(args.requirements, args.out, overrides=args.set or (),
                         studies=not args.no_studies, verify=args.verify, top=args.top)
    except DesignError as exc:
        print(f"afo-mj design: {exc}", file=sys.stderr)
        return 2
    print(out["text"])
    for w in out.get("warnings") or []:
        print(f"afo-mj design: WARNING: {w}", file=sys.stderr)
    return 0 if out["feasible"] else 1


def _version() -> str:
    """The installed package's version (the source tree's when not installed)."""
    from importlib.metadata import PackageNotFoundError, version
    try:
        return version("afo_mj")
    except PackageNotFoundError:
        from afo_mj import __version__
        return __version__


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="afo-mj", description="Simulate human walking in MuJoCo with a hydraulic ankle "
        "orthosis: walks, device benches, comparisons, calibration, studies and design.")
    parser.add_argument("--version", action="version", version=f"afo-mj {_version()}")
    sub = parser.add_subparsers(dest="command", required=True)
    demo = sub.add_parser("hydraulics-demo",
                          help="run the hydraulic cylinder demo headless and print results")
    demo.add_argument("--duration-s", type=float, default=1.0, dest="duration_s")
    demo.add_argument("--substeps", type=int, default=4)
    demo.add_argument("--json", action="store_true", help="also print a JSON summary line")
    demo.set_defaults(func=_demo)
    run = sub.add_parser("run", help="simulate a walking scenario (TOML) and write its results")
    run.add_argument("scenario", help="scenario file, e.g. scenarios/walk_healthy.toml")
    run.add_argument("--out", required=True, help="output directory: a new path, an empty "
                     "directory or a previous result directory (replaced by this run's files)")
    run.add_argument("--set", action="append", metavar="KEY=VALUE",
                     help="override a scenario value by its dotted key, e.g. gait.strides=4 "
                          "or device.params.hose.length_m=2.2 (repeatable)")
    run.add_argument("--strides", type=int, default=None, metavar="N",
                     help="simulate N strides, analyse [max(2, N-4), N] (as for compare); "
                          "an explicit --set gait.strides/gait.analyse_strides wins")
    run.add_argument("--rrd", metavar="FILE.rrd", default=None,
                     help="also save a rerun recording of the run (3D body, orthosis, every "
                          "signal on one timeline) to FILE.rrd; open it with `afo-mj view`")
    run.set_defaults(func=_run)
    view = sub.add_parser("view", help="open a recording (.rrd) in the rerun viewer")
    view.add_argument("rrd", metavar="FILE.rrd", help="a recording written by --rrd")
    view.add_argument("--print-command", action="store_true",
                      help="print the viewer command instead of starting it")
    view.add_argument("--web", action="store_true",
                      help="serve rerun's web viewer over HTTP (http://localhost:9090) instead "
                           "of opening a window; works on a machine without a display")
    view.set_defaults(func=_view)
    render = sub.add_parser("render", help="render a video of a walking scenario offscreen "
                            "(MuJoCo renderer, MUJOCO_GL=egl), ankle torque shown")
    render.add_argument("scenario", help="walking scenario file (with or without [device])")
    render.add_argument("--mp4", required=True, metavar="FILE.mp4", help="video to write")
    render.add_argument("--set", action="append", metavar="KEY=VALUE",
                        help="override a scenario value, as for run (repeatable)")
    render.add_argument("--condition", default=None,
                        help="device scenarios: the condition to render (default: the last, "
                             "e.g. assist)")
    render.add_argument("--fps", type=int, default=30, help="frames per second (1..240)")
    render.add_argument("--width", type=int, default=640, help="pixels (16..3840)")
    render.add_argument("--height", type=int, default=480, help="pixels (16..3840)")
    render.add_argument("--max-seconds", type=float, default=None, dest="max_seconds",
                        help="render only the first N simulated seconds")
    render.set_defaults(func=_render)
    cmp_ = sub.add_parser("compare", help="compare orthosis architectures (device scenarios "
                          "and their [device.variants]) on one gait")
    cmp_.add_argument("scenarios", nargs="+", metavar="SCENARIO",
                      help="walking scenarios with a [device] table")
    cmp_.add_argument("--out", required=True, help="output directory (created or updated)")
    cmp_.add_argument("--set", action="append", metavar="KEY=VALUE",
                      help="override applied to every scenario, as for run (repeatable)")
    cmp_.add_argument("--strides", type=int, default=None, metavar="N",
                      help="simulate N strides, analyse [max(2, N-4), N]")
    cmp_.add_argument("--rrd", metavar="FILE.rrd", default=None,
                      help="also save a rerun recording with every device's assist run "
                           "walking side by side")
    cmp_.set_defaults(func=_compare)
    cal = sub.add_parser("calibrate", help="replay a measured bench record, fit the model, "
                         "find the effect it lacks and report the error before and after")
    cal.add_argument("--scenario", required=True,
                     help="a device preset name (hafo, valve, ...) or a TOML file with "
                          "[device] preset/params and an optional [calibration] table")
    cal.add_argument("--data", required=True, help="measured record (CSV or Parquet with its "
                     "TOML sidecar; docs/measured_data.md)")
    cal.add_argument("--out", required=True, help="output directory (report.json, report.md, "
                     "PNGs)")
    cal.set_defaults(func=_calibrate)
    mk = sub.add_parser("make-bench-record", help="write a synthetic bench record with "
                        "effects the lean model does not declare (test data for calibrate)")
    mk.add_argument("--kind", choices=("hafo", "valve"), default="hafo")
    mk.add_argument("--preset", default=None, help="device preset (default: hafo / valve)")
    mk.add_argument("--effect", action="append", metavar="NAME[:PARAM=VALUE,...]",
                    help="switch a library effect on, e.g. piston_leakage:"
                         "leakage_conductance_m3=8e-15 (repeatable)")
    mk.add_argument("--mismatch", action="append", metavar="PARAM=FACTOR",
                    help="scale a declared parameter, e.g. seal_coulomb_force_n=1.5")
    mk.add_argument("--resonance-hz", type=float, default=0.0, dest="resonance_hz",
                    help="torque sensor seen through a resonance at this frequency (an "
                         "effect outside the library)")
    mk.add_argument("--duration-s", type=float, default=20.0, dest="duration_s")
    mk.add_argument("--fs-hz", type=float, default=1000.0, dest="fs_hz")
    mk.add_argument("--noise-scale", type=float, default=1.0, dest="noise_scale")
    mk.add_argument("--seed", type=int, default=0)
    mk.add_argument("--out", required=True, metavar="FILE.csv",
                    help="data file (.csv or .parquet); the sidecar goes beside it")
    mk.set_defaults(func=_make_bench_record)
    sw = sub.add_parser("sweep", help="run a parameter study (TOML) in parallel: local "
                        "processes or a Dask cluster; resumable")
    sw.add_argument("study", help="study file, e.g. scenarios/studies/hafo_peak_torque_timing.toml")
    sw.add_argument("--out", required=True, help="sweep directory (rows/, results table); "
                    "running again resumes")
    sw.add_argument("--workers", type=int, default=None,
                    help="worker processes (default: the machine's cores)")
    sw.add_argument("--scheduler", default=None, metavar="ADDRESS",
                    help="a Dask scheduler address (tcp://host:8786), or 'local' for a local "
                         "Dask cluster of --workers processes")
    sw.add_argument("--format", choices=("parquet", "csv"), default=None,
                    help="results table format (default: the study's, parquet)")
    sw.add_argument("--keep-runs", action="store_true", dest="keep_runs",
                    help="keep every run's result directory under DIR/runs/")
    sw.add_argument("--quiet", action="store_true", help="no progress bar")
    sw.set_defaults(func=_sweep)
    st = sub.add_parser("study", help="rank, plot and analyse (Sobol'/Morris) a sweep's results")
    st.add_argument("dir", help="a sweep directory (afo-mj sweep --out DIR)")
    st.add_argument("--metric", default=None, help="metric to rank by (a results column); "
                    "default: human ankle positive work change (device studies) or ankle "
                    "angle RMS error")
    st.set_defaults(func=_study)
    op = sub.add_parser("optimize", help="optimise a study's parameters (e.g. the Zhang "
                        "assistance profile) for a metric under constraints, in parallel")
    op.add_argument("study", help="study file with an [optimize] table")
    op.add_argument("--out", required=True, help="directory for the runs and optimization.json")
    op.add_argument("--workers", type=int, default=None, help="worker processes")
    op.add_argument("--scheduler", default=None, metavar="ADDRESS",
                    help="Dask scheduler address, or 'local'")
    op.add_argument("--quiet", action="store_true", help="no progress bar")
    op.set_defaults(func=_optimize)
    de = sub.add_parser("design", help="size a minimum-weight hydraulic orthosis from "
                        "requirements and write it as scenarios afo-mj run accepts")
    de.add_argument("requirements", help="requirements file, e.g. "
                    "scenarios/design/hafo_requirements.toml")
    de.add_argument("--out", required=True, help="output directory (design.json, design.md, "
                    "designs.csv, design_bench.toml, design_walk.toml, studies)")
    de.add_argument("--set", action="append", metavar="KEY=VALUE",
                    help="override a requirement by its dotted key, e.g. "
                         "requirement.runtime_h=3 (repeatable)")
    de.add_argument("--verify", action="store_true",
                    help="also run the written design on the simulated torque-velocity bench "
                         "and report it against the prediction")
    de.add_argument("--no-studies", action="store_true", dest="no_studies",
                    help="skip the design-guideline studies")
    de.add_argument("--top", type=int, default=10, help="designs to list (default 10)")
    de.set_defaults(func=_design)
    build = sub.add_parser("build-models", help="write the default MJCF models to models/mjcf/")
    build.set_defaults(func=_build_models)
    for p in sub.choices.values():
        if "--quiet" not in p._option_string_actions:
            p.add_argument("--quiet", action="store_true",
                           help="no progress on stderr (stage lines, time left); errors "
                                "and warnings still go there")
    args = parser.parse_args(argv)
    if getattr(args, "duration_s", 1.0) <= 0:
        parser.error(f"--duration-s = {args.duration_s}; allowed: > 0")
    if getattr(args, "substeps", 1) < 1:
        parser.error(f"--substeps = {args.substeps}; allowed: integer >= 1")
    from afo_mj import progress
    # progress (stage lines, time left) on stderr only: stdout carries the results
    rep = progress.Reporter(quiet=bool(getattr(args, "quiet", False)))
    with np.printoptions(legacy="1.25"), progress.using(rep):
        # (messages show numbers as 1.5, not np.float64(1.5))
        return args.func(args)


if __name__ == "__main__":
    sys.exit(main())
