"""The grammar of ``afo-mj``: every command, its arguments, defaults and help text (argparse).

:func:`build_parser` is used by :func:`afo_mj.cli.main`, which gives the handler of each
command (a function ``args -> exit code``) by the command's name as typed
(``hydraulics-demo``, ``run``, ...): its table :data:`afo_mj.cli.COMMANDS`.
"""

from __future__ import annotations

import argparse
from typing import Callable, Mapping

__all__ = ["build_parser", "package_version"]


def package_version() -> str:
    """The installed package's version (the source tree's when not installed)."""
    from importlib.metadata import PackageNotFoundError, version
    try:
        return version("afo_mj")
    except PackageNotFoundError:
        from afo_mj import __version__
        return __version__


def build_parser(handlers: Mapping[str, Callable], version: str) -> argparse.ArgumentParser:
    """The ``afo-mj`` parser; ``handlers``: command function by the command's name as typed
    (``hydraulics-demo``, ``run``, ``make-bench-record``, ...), set as each sub-command's
    ``func``; ``version``: what ``--version`` prints."""
    parser = argparse.ArgumentParser(
        prog="afo-mj", description="Simulate human walking in MuJoCo with a hydraulic ankle "
        "orthosis: walks, device benches, comparisons, calibration, studies and design.")
    parser.add_argument("--version", action="version", version=f"afo-mj {version}")
    sub = parser.add_subparsers(dest="command", required=True)
    demo = sub.add_parser("hydraulics-demo",
                          help="run the lab bench circuit on a simulated foot headless and "
                          "print its ranges and energy chain")
    demo.add_argument("--duration-s", type=float, default=1.0, dest="duration_s")
    demo.add_argument("--substeps", type=int, default=1,
                      help="circuit stepper steps per 1 ms sample (default 1)")
    demo.add_argument("--json", action="store_true", help="also print a JSON summary line")
    demo.set_defaults(func=handlers["hydraulics-demo"])
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
    run.set_defaults(func=handlers["run"])
    view = sub.add_parser("view", help="open a recording (.rrd) in the rerun viewer")
    view.add_argument("rrd", metavar="FILE.rrd", help="a recording written by --rrd")
    view.add_argument("--print-command", action="store_true",
                      help="print the viewer command instead of starting it")
    view.add_argument("--web", action="store_true",
                      help="serve rerun's web viewer over HTTP (http://localhost:9090) instead "
                           "of opening a window; works on a machine without a display")
    view.set_defaults(func=handlers["view"])
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
    render.set_defaults(func=handlers["render"])
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
    cmp_.set_defaults(func=handlers["compare"])
    cal = sub.add_parser("calibrate", help="replay a measured bench record, fit the model, "
                         "find the effect it lacks and report the error before and after")
    cal.add_argument("--scenario", required=True,
                     help="a device preset name (hafo, valve, ...) or a TOML file with "
                          "[device] preset/params and an optional [calibration] table")
    cal.add_argument("--data", required=True, help="measured record (CSV or Parquet with its "
                     "TOML sidecar; docs/measured_data.md)")
    cal.add_argument("--out", required=True, help="output directory (report.json, report.md, "
                     "PNGs)")
    cal.set_defaults(func=handlers["calibrate"])
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
    mk.set_defaults(func=handlers["make-bench-record"])
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
    sw.set_defaults(func=handlers["sweep"])
    st = sub.add_parser("study", help="rank, plot and analyse (Sobol'/Morris) a sweep's results")
    st.add_argument("dir", help="a sweep directory (afo-mj sweep --out DIR)")
    st.add_argument("--metric", default=None, help="metric to rank by (a results column); "
                    "default: human ankle positive work change (device studies) or ankle "
                    "angle RMS error")
    st.set_defaults(func=handlers["study"])
    op = sub.add_parser("optimize", help="optimise a study's parameters (e.g. the Zhang "
                        "assistance profile) for a metric under constraints, in parallel")
    op.add_argument("study", help="study file with an [optimize] table")
    op.add_argument("--out", required=True, help="directory for the runs and optimization.json")
    op.add_argument("--workers", type=int, default=None, help="worker processes")
    op.add_argument("--scheduler", default=None, metavar="ADDRESS",
                    help="Dask scheduler address, or 'local'")
    op.add_argument("--quiet", action="store_true", help="no progress bar")
    op.set_defaults(func=handlers["optimize"])
    og = sub.add_parser("optimize-gait", help="optimise the muscle-reflex walker's controller "
                        "(CMA-ES) for steady walking at a speed with little effort; resumable")
    og.add_argument("--out", required=True, help="directory for reflex_params.json and the "
                    "optimiser's state (run again to continue)")
    og.add_argument("--speed", dest="speed_m_s", type=float, default=1.25,
                    help="target speed, m/s")
    og.add_argument("--generations", type=int, default=60, help="CMA-ES generations in all")
    og.add_argument("--duration", dest="duration_s", type=float, default=12.0,
                    help="seconds each evaluation walks (the first 3 not scored)")
    og.add_argument("--sigma0", type=float, default=0.2,
                    help="CMA-ES initial step on the log of each parameter (default 0.2)")
    og.add_argument("--tracking-weight", type=float, default=1.0,
                    help="weight of the mean angle RMS against Winter, per degree")
    og.add_argument("--tracking-max-weight", type=float, default=0.0,
                    help="weight of the worst joint's angle RMS, per degree")
    og.add_argument("--effort-weight", type=float, default=1.0,
                    help="weight of the net cost of transport (Umberger), per J/(kg m)")
    og.add_argument("--emg-weight", type=float, default=0.0,
                    help="weight of the soleus and tibialis anterior EMG timing term")
    og.add_argument("--popsize", type=int, default=16, help="walks per generation")
    og.add_argument("--seed", type=int, default=1, help="CMA-ES seed (same seed, same result)")
    og.add_argument("--start", default=None, help="reflex_params.json to start from")
    og.add_argument("--workers", type=int, default=None, help="worker processes")
    og.add_argument("--body-mass-kg", type=float, default=None,
                    help="walker body mass, kg (default 75)")
    og.add_argument("--height-m", type=float, default=None,
                    help="walker stature, m (default 1.75)")
    og.add_argument("--assistance", default=None,
                    choices=("none", "worn_mass", "zhang", "clutched_spring", "hafo"),
                    help="device worn while optimising (the adapted wearer; default none)")
    og.add_argument("--ramp-strides", type=int, default=None,
                    help="the ideal torque (zhang) ramps on over this many strides (default 0)")
    og.add_argument("--plantarflexor-strength", type=float, default=None,
                    help="soleus and gastrocnemius maximum force as a fraction (weakness; "
                         "default 1)")
    og.add_argument("--scenario", default=None, metavar="FILE",
                    help="wear this muscle-walker scenario's device instead of --assistance: "
                         "its body, impairment and device; its walker.reflex_set is the warm "
                         "start unless --start is given")
    og.add_argument("--condition", default=None,
                    help="the scenario's condition worn (default its last listed, e.g. assist)")
    og.add_argument("--set", dest="overrides", action="append", metavar="KEY=VALUE",
                    help="override a --scenario key, e.g. device.params.mass_kg=0.5 "
                         "(repeatable)")
    og.add_argument("--robust", action="store_true",
                    help="also walk with body mass -15 %% and +15 %%, 1 kg at the right ankle "
                         "and the HAFO's worn masses (each fall penalised)")
    og.add_argument("--quiet", action="store_true", help="no progress on stderr")
    og.set_defaults(func=handlers["optimize-gait"])
    ad = sub.add_parser("adapt", help="adapt the muscle walker's wearer to each condition by "
                        "several CMA-ES restarts from one converged control; reports each "
                        "rate's restart-to-restart spread and the paired change against the "
                        "control; resumable")
    ad.add_argument("conditions", nargs="+", metavar="SCENARIO_OR_KINDS",
                    help="assistance kinds (none, worn_mass, zhang, clutched_spring, hafo; "
                         "none, the control, added first) or one muscle-walker scenario file "
                         "(its conditions, no_device first)")
    ad.add_argument("--out", required=True, help="directory of the searches and "
                    "adaptation.json (run again to continue)")
    ad.add_argument("--restarts", type=int, default=3, help="independent searches per "
                    "condition (CMA-ES seeds seed, seed+1, ...)")
    ad.add_argument("--generations", type=int, default=100, help="CMA-ES generations per "
                    "search in all")
    ad.add_argument("--popsize", type=int, default=16, help="walks per generation")
    ad.add_argument("--sigma0", type=float, default=0.04, help="CMA-ES initial step on the "
                    "log of each parameter (small: the start is converged)")
    ad.add_argument("--seed", type=int, default=1, help="first restart's CMA-ES seed")
    ad.add_argument("--window", type=int, default=10, help="convergence window, generations")
    ad.add_argument("--cost-tol", type=float, default=0.01, help="largest fall of the best "
                    "cost over the window of a converged search (objective units)")
    ad.add_argument("--spread-target-pct", type=float, default=1.0, help="largest restarts' "
                    "spread of a converged condition, %% of its rate")
    ad.add_argument("--search-walk-s", type=float, default=16.0, help="seconds each search "
                    "walk lasts (the first 3 not scored)")
    ad.add_argument("--score-walk-s", type=float, default=20.0, help="seconds of the walk "
                    "that scores each restart's best set")
    ad.add_argument("--groups", type=int, default=1, help="split the restarts into this many "
                    "groups (a divisor of --restarts): each group's best restart is a "
                    "replicate of the best-of-(restarts/groups) wearer, whose spread is then "
                    "the one checked against --spread-target-pct")
    ad.add_argument("--start", default=None, help="reflex_params.json every search starts "
                    "from (default: the shipped control, or the scenario's reflex_set)")
    ad.add_argument("--workers", type=int, default=None, help="worker processes")
    ad.add_argument("--dask", default=None, metavar="ADDRESS", help="walk on this Dask "
                    "scheduler (tcp://host:8786), or 'local' for a local Dask cluster")
    ad.add_argument("--set", dest="overrides", action="append", metavar="KEY=VALUE",
                    help="override a key of the scenario file (repeatable)")
    ad.add_argument("--quiet", action="store_true", help="no progress on stderr")
    ad.set_defaults(func=handlers["adapt"])
    dr = sub.add_parser("dose-response", help="a dose-response study file (scenarios/studies/"
                        "dose_*.toml): the wearer adapted at each dose by continuation from "
                        "the previous one, the net metabolic change against the control with "
                        "its band over restarts, and its figure; resumable")
    dr.add_argument("study", help="the study file ([dose_response] table)")
    dr.add_argument("--out", required=True, help="directory of the searches, "
                    "dose_response.json and dose_response.png (run again to continue)")
    dr.add_argument("--workers", type=int, default=None, help="worker processes")
    dr.add_argument("--quiet", action="store_true", help="no progress on stderr")
    dr.set_defaults(func=handlers["dose-response"])
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
    de.set_defaults(func=handlers["design"])
    sch = sub.add_parser("schematic", help="draw a circuit as an ISO 1219-1-style schematic "
                         "(SVG; PNG where cairosvg is installed)")
    sch.add_argument("scenario", help="a scenario file with [circuit] or [device], a device "
                     "preset (hafo, valve, digital, phafo, ...) or a library circuit "
                     "(lab_bench, pump_accumulator, spring_return, ...)")
    sch.add_argument("--out", required=True, metavar="FILE.svg",
                     help="the drawing to write (.svg, or .png)")
    sch.add_argument("--set", action="append", metavar="KEY=VALUE",
                     help="override a scenario value by its dotted key, as for run; with a "
                          "preset name: device.params.NAME=VALUE (repeatable)")
    sch.set_defaults(func=handlers["schematic"])
    fmu = sub.add_parser("export-fmu", help="write a scenario's circuit as an FMI 2.0 "
                         "co-simulation FMU (inputs: command, joint angle and velocity)")
    fmu.add_argument("scenario", help="a scenario file with a [circuit] or a [device] preset "
                     "(e.g. scenarios/gait_lab_bench.toml), or a preset name (hafo, valve, ...)")
    fmu.add_argument("--out", required=True, metavar="FILE.fmu", help="the FMU to write")
    fmu.add_argument("--set", action="append", metavar="KEY=VALUE",
                     help="override a scenario value by its dotted key, as for run "
                          "(repeatable)")
    fmu.add_argument("--timestep-s", type=float, default=5e-4, dest="timestep_s",
                     help="longest internal step, s: each communication step is split into "
                          "equal sub-steps no longer than this (default 0.0005)")
    fmu.add_argument("--step-size-s", type=float, default=1e-3, dest="step_size_s",
                     help="the default experiment's communication step, s (default 0.001)")
    fmu.set_defaults(func=handlers["export-fmu"])
    osm = sub.add_parser("export-osim", help="write a walking scenario's walker as OpenSim "
                         "models (<run>.osim per run, for OpenSim's tools on the run's "
                         "[output] opensim files)")
    osm.add_argument("scenario", help="a walking scenario file, e.g. scenarios/walk_healthy.toml "
                     "(a device scenario gives one model per condition, with its worn masses)")
    osm.add_argument("--out", required=True, metavar="DIR", help="output directory")
    osm.add_argument("--set", action="append", metavar="KEY=VALUE",
                     help="override a scenario value by its dotted key, as for run "
                          "(repeatable)")
    osm.set_defaults(func=handlers["export-osim"])
    build = sub.add_parser("build-models", help="write the default MJCF models to models/mjcf/")
    build.set_defaults(func=handlers["build-models"])
    for p in sub.choices.values():
        if "--quiet" not in p._option_string_actions:
            p.add_argument("--quiet", action="store_true",
                           help="no progress on stderr (stage lines, time left); errors "
                                "and warnings still go there")
    return parser
