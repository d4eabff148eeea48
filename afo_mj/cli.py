"""Command-line interface ``afo-mj``: parses arguments, calls the application layer
(:mod:`afo_mj.app`) and prints its results; ``afo-mj --help`` lists the commands.

Exit codes: 0 done (a fall, an infeasible design's report or a verdict are outcomes); 1 the
run could not be simulated, analysed or written (nothing written), or every sweep run failed;
2 invalid input (nothing written); 130 interrupted (one line on stderr; run, render, compare
write nothing; a sweep or optimisation keeps its finished runs: run it again to resume).
"""

from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import Callable

import numpy as np

from afo_mj.outputs import console


def _err(command: str, message: str) -> None:
    print(f"afo-mj {command}: {message}", file=sys.stderr)


def _print(lines) -> None:
    print("\n".join(lines))


def _demo(args) -> int:
    from afo_mj.app.hydraulics_demo import hydraulics_demo
    try:
        d = hydraulics_demo(args.duration_s, args.substeps)
    except ValueError as exc:
        _err("hydraulics-demo", str(exc).replace("duration_s", "--duration-s")
             .replace("substeps", "--substeps"))
        return 2
    _print(console.hydraulics_demo_lines(d))
    if args.json:
        keys = ("input_j", "output_j", "heat_j", "relative_residual")
        print(json.dumps({k: d[k] for k in ("duration_s", "us_per_step", "max_torque_nm")}
                         | {"energy": {k: d["energy"][k] for k in keys}}))
    return 0


def _run(args) -> int:
    from afo_mj.app.run import BenchRun, DeviceWalkRun, run_recorded
    res, info = run_recorded(args.scenario, args.rrd, args.set or (), args.strides,
                             out_dir=args.out, on_note=lambda n: _err("run", f"note: {n}"))
    if isinstance(res, BenchRun):
        _print(console.bench_lines(res.bench, res.summary, res.wall_time_s, res.out_dir))
    elif isinstance(res, DeviceWalkRun):
        _print(console.device_walk_lines(res.scenario, res.config, res.results,
                                         res.device_summary.to_block(), res.wall_time_s,
                                         res.out_dir))
    else:
        _print(console.walk_lines(res.scenario, res.reference, res.summary.to_json(),
                                  res.wall_time_s, res.out_dir))
    if args.rrd and info is None:
        _err("run", "--rrd is not written for a circuit bench (no time-domain recording of "
             "its protocols yet)")
    elif info is not None:
        print(f"  recording: {info['path']} ({len(info['entities'])} entities; open with "
              f"`afo-mj view {info['path']}`)")
    return 0


def _compare(args) -> int:
    from afo_mj import progress
    from afo_mj.app.compare import compare
    from afo_mj.outputs.comparison_report import format_tables
    rep = progress.reporter()
    res = compare(args.scenarios, args.out, args.set or (), args.strides, rrd_path=args.rrd,
                  on_note=lambda n: _err("compare", f"note: {n}"),
                  on_stage=lambda m: rep.stage(f"compare: {m}"))
    comp = res.comparison
    print(f"afo_mj compare: {len(comp.rows)} devices, assist condition, per mean analysed "
          f"stride ({comp.wall_time_s:.1f} s wall)")
    print(format_tables(comp))
    print(f"  results: {res.out_dir}")
    if res.recording:
        print(f"  recording: {res.recording['path']} ({len(comp.rows)} devices side by side; "
              f"open with `afo-mj view {res.recording['path']}`)")
    return 0


def _view(args) -> int:
    """The rerun viewer on the file (``--web``: over HTTP); no display, no ``--web``: exit 2."""
    from afo_mj.app.viewer import headless_problem, run_viewer, viewer_command
    cmd = viewer_command(args.rrd, web=args.web)
    if args.print_command:
        print(" ".join(cmd))
        return 0
    why = None if args.web else headless_problem(args.rrd)
    if why:
        _err("view", why)
        return 2
    if not Path(cmd[0]).exists():
        _err("view", "the rerun viewer executable is missing (pip install rerun-sdk)")
        return 1
    return run_viewer(cmd)        # the viewer (and rerun's server) dies with afo-mj


def _render(args) -> int:
    """``afo-mj render SCENARIO --mp4 FILE``."""
    from afo_mj.app.render import render
    from afo_mj.outputs.video import RenderError
    try:
        info = render(args.scenario, args.mp4, overrides=args.set or (),
                      condition=args.condition, fps=args.fps, width=args.width,
                      height=args.height, max_seconds=args.max_seconds)
    except RenderError as exc:                  # bad input included (InvalidRender)
        _err("render", f"{exc}; nothing written")
        return 2
    print(f"afo_mj render: {info['path']}: {info['frames']} frames at {info['fps']} fps, "
          f"{info['width']}x{info['height']}, {info['duration_s']:.2f} s simulated "
          f"(condition {info['condition']})")
    return 0


def _build_models(args) -> int:
    from afo_mj.human import test_stand, walker
    _print(f"wrote {p}" for p in (walker.write_default_xml(), test_stand.write_default_xml()))
    return 0


def _calibrate(args) -> int:
    from afo_mj import progress
    from afo_mj.app.calibrate import calibrate_record
    command = "afo-mj " + " ".join(sys.argv[1:]) if sys.argv[1:2] == ["calibrate"] else None
    res = calibrate_record(args.scenario, args.data, args.out, command=command,
                           on_warning=lambda w: print(f"warning: {w}", file=sys.stderr),
                           on_stage=progress.reporter().stage)
    r = res.report
    _print(console.calibration_lines(r.to_json(), args.out))
    print(json.dumps({"verdict": r.verdict,
                      "effects": [s["effect"] for s in r.effects_selected],
                      "error_before": r.error_before["overall"],
                      "error_after": r.error_after["overall"]}))
    return 0


def _make_bench_record(args) -> int:
    from afo_mj.app.bench_record import make_bench_record, parse_effects, parse_pairs
    data = make_bench_record(args.out, args.kind, parse_effects(args.effect),
                             parse_pairs(args.mismatch, "--mismatch"),
                             preset=args.preset, noise_scale=args.noise_scale,
                             duration_s=args.duration_s, fs_hz=args.fs_hz, seed=args.seed,
                             resonance_hz=args.resonance_hz)
    print(f"wrote {args.out} ({data.n_samples} samples) and its sidecar: "
          f"{data.source['description']}")
    return 0


def _sweep(args) -> int:
    """Exit 0 done (failures recorded), 1 every run failed, 2 invalid study, 130 interrupted."""
    from afo_mj.app.study_runs import run_sweep

    def start(study, points, sw):
        _print(console.sweep_start_lines(study, points, sw.workers, args.scheduler))
    res = run_sweep(args.study, args.out, args.workers, args.scheduler, args.format,
                    args.keep_runs, progress=not args.quiet, on_start=start)
    rows, failed, table = res.rows, res.failed, res.table_path
    # falls, end-stop contact, braking, poor tracking: outcomes, each said
    _print(console.sweep_result_lines(rows, failed, res.wall_time_s, table))
    if rows and len(failed) == len(rows):
        _err("sweep", f"every run failed ({len(rows)} of {len(rows)}), e.g. "
             f"{failed[0]['error']}; see {table}")
        return 1
    if failed:
        _err("sweep", f"{len(failed)} of {len(rows)} runs failed (recorded in {table})")
    return 0


def _study(args) -> int:
    from afo_mj.outputs.study_report import write_study_report
    try:
        rep = write_study_report(args.dir, metric=args.metric)
    except (ValueError, OSError) as exc:
        _err("study", str(exc))
        return 2
    print(rep.get("text", ""))
    return 0


def _optimize(args) -> int:
    """Exit 0 done, 2 invalid study, 130 interrupted (runs and ``optimization.json`` kept)."""
    from afo_mj.app.study_runs import run_optimization
    res = run_optimization(args.study, args.out, args.workers, args.scheduler,
                           progress=not args.quiet)
    _print(console.optimization_lines(res, args.out))
    return 0


def _given(fn, args, skip=()) -> dict:
    """The parsed options that are keyword parameters of ``fn`` (but ``out`` and ``skip``)."""
    names = set(__import__("inspect").signature(fn).parameters) - {"out", *skip}
    return {k: v for k, v in vars(args).items() if k in names}


def _optimize_gait(args) -> int:
    """Exit 0 done (resumable: run again to continue), 2 invalid options."""
    from afo_mj.app.gait_optimization import optimize_reflex_gait
    doc = optimize_reflex_gait(args.out, **_given(optimize_reflex_gait, args))
    _print(console.gait_optimization_lines(doc, args.out))
    return 0


def _adapt(args) -> int:
    """Exit 0 done (resumable: run again to continue), 2 invalid options."""
    from afo_mj.app.adaptation import adapt
    _print(console.adaptation_lines(adapt(out=args.out, **_given(adapt, args)), args.out))
    return 0


def _dose_response(args) -> int:
    """Exit 0 done (resumable: run again to continue), 2 invalid study or options."""
    from afo_mj.app.dose_response import dose_response as dr
    _print(console.dose_response_lines(dr(out=args.out, **_given(dr, args)), args.out))
    return 0


def _design(args) -> int:
    """Exit 0 a feasible design written, 1 infeasible (the binding constraint printed and
    written), 2 invalid requirements (nothing written)."""
    from afo_mj.app.design import design
    from afo_mj.design.design_requirements import DesignError
    if args.top < 1:
        _err("design", f"--top = {args.top}; allowed: >= 1")
        return 2
    try:
        out = design(args.requirements, args.out, overrides=args.set or (),
                     studies=not args.no_studies, verify=args.verify, top=args.top)
    except DesignError as exc:
        _err("design", str(exc))
        return 2
    print(out.text)
    for w in out.warnings:
        _err("design", f"WARNING: {w}")
    return 0 if out.feasible else 1


def _schematic(args) -> int:
    """Exit 0 written, 2 invalid input (nothing written)."""
    from afo_mj.app.schematic import write_circuit_schematic
    _print(console.schematic_lines(write_circuit_schematic(args.scenario, args.out, args.set)))
    return 0


def _export_fmu(args) -> int:
    """Exit 0 written, 1 the library could not be built, 2 invalid scenario or option."""
    from afo_mj.app.fmu import export_fmu
    _print(console.fmu_lines(export_fmu(args.scenario, args.out, args.set or (),
                                        timestep_s=args.timestep_s,
                                        step_size_s=args.step_size_s)))
    return 0


def _export_osim(args) -> int:
    """Exit 0 written, 1 a file could not be written, 2 invalid scenario (nothing written)."""
    from afo_mj.app.osim import export_osim
    _print(console.osim_lines(export_osim(args.scenario, args.out, args.set or ())))
    return 0


_ATOMIC = ("hydraulics-demo", "run", "render", "compare")    # write all at once or nothing

# every command as typed -> its handler (args -> exit code); build_parser declares the same
COMMANDS: dict[str, Callable[..., int]] = {
    "hydraulics-demo": _demo, "run": _run, "view": _view, "render": _render,
    "compare": _compare, "calibrate": _calibrate, "make-bench-record": _make_bench_record,
    "sweep": _sweep, "study": _study, "optimize": _optimize, "optimize-gait": _optimize_gait,
    "adapt": _adapt, "dose-response": _dose_response, "design": _design, "schematic": _schematic,
    "export-fmu": _export_fmu, "export-osim": _export_osim, "build-models": _build_models}


def main(argv: list[str] | None = None) -> int:
    from afo_mj.cli_args import build_parser, package_version
    args = build_parser(COMMANDS, package_version()).parse_args(argv)
    from afo_mj import progress
    from afo_mj.app.errors import AppError
    # progress (stage lines, time left) on stderr only: stdout carries the results
    rep = progress.Reporter(quiet=bool(getattr(args, "quiet", False)))
    # (messages show numbers as 1.5, not np.float64(1.5))
    with np.printoptions(legacy="1.25"), progress.using(rep):
        try:
            return args.func(args)
        except AppError as exc:
            _err(args.command, str(exc))
            return exc.exit_code
        except KeyboardInterrupt:         # Ctrl-C: one line, no traceback
            what = "; nothing written" if args.command in _ATOMIC else ""
            _err(args.command, f"interrupted (SIGINT){what}")
            return 130


if __name__ == "__main__":
    sys.exit(main())
