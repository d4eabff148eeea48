"""Run one scenario file: a walk, a walk with an orthosis (every condition) or a bench.

:func:`run_scenario` is what ``afo-mj run`` does and what a sweep runs for each point: it
loads and checks the scenario (and the results directory, before anything is simulated),
simulates, analyses, composes the ``summary.json`` document and, when ``out_dir`` is given,
writes the results directory atomically (:func:`run_recorded`: with a ``--rrd`` recording,
which may lie inside it, in the same atomic write). It returns a :class:`WalkRun`, a
:class:`DeviceWalkRun` or a :class:`BenchRun`; bad input raises
:class:`~afo_mj.app.errors.InvalidInput`, a run that cannot be simulated, analysed or written
raises :class:`~afo_mj.app.errors.RunFailed` (nothing written in either case).

A walker that falls is an outcome, not a failure, with or without a device and whenever it
falls: the run is written and the summary says so (``fell``, ``fall_time_s``,
``completed_strides``; a device run also per condition in ``device_conditions``).

Example::

    from afo_mj.app.run import run_scenario
    res = run_scenario("scenarios/walk_healthy.toml", overrides=["gait.strides=4"])
    print(res.summary.gait.mean("speed_m_s"))   # nothing written: out_dir not given

``summary`` is a :class:`~afo_mj.metrics.documents.WalkSummary`; ``summary.json`` is its
``to_json()``.
"""

from __future__ import annotations

import dataclasses
import json
import platform
import time
from pathlib import Path
from typing import TYPE_CHECKING, Any, Callable, Sequence

import numpy as np

from afo_mj.app.errors import InvalidInput, RunFailed
from afo_mj.metrics.documents import DeviceWalkPart, FallOutcome, WalkSummary

if TYPE_CHECKING:
    from afo_mj.metrics.gait_metrics import GaitAnalysis

__all__ = ["WalkRun", "DeviceWalkRun", "BenchRun", "run_scenario", "run_bench", "record_run",
           "run_recorded", "check_rrd_path", "run_info", "write_rrd"]


@dataclasses.dataclass(frozen=True)
class WalkRun:
    """A walk without an orthosis: the scenario, its reference gait, the simulated record,
    the analysis (None when the walker fell before an analysable stride) and the summary
    (what ``summary.json`` holds: its ``to_json()``)."""

    scenario: Any
    reference: Any
    record: Any
    analysis: GaitAnalysis | None
    summary: WalkSummary
    wall_time_s: float
    out_dir: Path | None = None

    @property
    def fell(self) -> bool:
        return self.summary.fell

    def recorded_runs(self) -> list:
        from afo_mj.outputs.recording import RecordedRun
        return [RecordedRun("walk", self.record)]


@dataclasses.dataclass(frozen=True)
class DeviceWalkRun:
    """A walk with an orthosis: every condition ``{name: (record, analysis, device)}``, the
    device part of the summary (per condition) and the summary (the headline condition's
    walk, the last one, with the device part; ``summary.json`` is its ``to_json()``)."""

    scenario: Any
    reference: Any
    config: Any
    results: dict
    device_summary: DeviceWalkPart
    summary: WalkSummary
    wall_time_s: float
    out_dir: Path | None = None

    @property
    def headline(self) -> str:
        return self.config.conditions[-1]

    @property
    def fell(self) -> bool:
        """The headline condition's walker fell (an outcome: the summary says when)."""
        return self.summary.fell

    def recorded_runs(self) -> list:
        from afo_mj.outputs.recording import RecordedRun
        return [RecordedRun(c, r, d) for c, (r, _a, d) in self.results.items()]


@dataclasses.dataclass(frozen=True)
class BenchRun:
    """A bench scenario: the protocols' summary and their time series."""

    bench: Any
    summary: dict
    series: dict
    wall_time_s: float
    out_dir: Path | None = None
    #: the summary as its typed document (:class:`afo_mj.metrics.documents.BenchSummary`):
    #: ``summary.json`` is its ``to_json()``
    document: Any = None


def run_info(wall_s: float) -> dict:
    """What is not a result of the scenario (wall time, versions): ``run_info.json``, kept
    out of ``summary.json`` so that a rerun gives an identical summary."""
    import mujoco
    return {"wall_time_s": wall_s, "python": platform.python_version(),
            "numpy": np.__version__, "mujoco": mujoco.__version__,
            "platform": platform.platform()}


def _run_info_writer(wall_s: float) -> Callable[[Path], None]:
    def write(tmp: Path) -> None:
        text = json.dumps(run_info(wall_s), indent=2) + "\n"
        (tmp / "run_info.json").write_text(text, encoding="utf-8")
    return write


def _chain(*writers) -> Callable[[Path], None]:
    """One results-directory writer that calls ``writers`` (None entries skipped) in turn."""
    def write(tmp: Path) -> None:
        for w in writers:
            if w is not None:
                w(tmp)
    return write


def _recording_writer(scenario, runs, reference):
    """Writer of ``recording.rrd`` when the scenario's ``[output] record`` is true."""
    if not getattr(scenario, "record", False):
        return None

    def write(tmp: Path) -> None:
        from afo_mj.outputs.gait_report import ReportError
        from afo_mj.outputs.recording import RecordingError
        try:
            write_rrd(tmp / "recording.rrd", scenario, runs, reference)
        except RecordingError as exc:
            raise ReportError(f"recording.rrd: {exc}") from None
    return write


def _opensim_writer(scenario, runs):
    """Writer of ``opensim/<run>_{ik,id,grf}`` files, ``<run>_grf.xml`` and the model
    ``<run>.osim`` (:mod:`afo_mj.outputs.opensim_export`)
    for every run (a walk, or each condition of a device walk) when the scenario's
    ``[output] opensim`` is true."""
    if not getattr(scenario, "opensim", False):
        return None

    def write(tmp: Path) -> None:
        from afo_mj.outputs.gait_report import ReportError
        from afo_mj.outputs.opensim_export import write_opensim
        try:
            for run in runs:
                write_opensim(run.record, tmp / "opensim", run.name)
        except ValueError as exc:
            raise ReportError(f"opensim files: {exc}") from None
    return write


def write_rrd(path, scenario, runs, reference) -> dict:
    """The rerun recording of ``runs`` (:class:`~afo_mj.outputs.recording.RecordedRun`) at
    the scenario's recording rates; returns the writer's info (``path``, ``entities``)."""
    from afo_mj.outputs.recording import write_recording
    return write_recording(path, runs, reference, title=scenario.name,
                           signal_rate_hz=getattr(scenario, "record_signal_rate_hz", 500.0),
                           transform_rate_hz=getattr(scenario, "record_transform_rate_hz", 50.0))


def _read_text(path) -> str:
    try:
        return Path(path).read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError):
        return ""          # the loader reports it


def run_scenario(path, overrides: Sequence[str] = (), strides: int | None = None,
                 out_dir=None, figures: bool = True,
                 on_note: Callable[[str], None] | None = None, *, recording=None
                 ) -> WalkRun | DeviceWalkRun | BenchRun:
    """Load, check, run and (with ``out_dir``) write the scenario file ``path``.

    ``overrides``: ``--set`` style ``"dotted.key=value"`` strings; ``strides``: the number
    of strides to simulate (the analysed window follows, ``run --strides``); ``figures``:
    False writes the numbers only; ``on_note``: called with each note the scenario carries
    (e.g. a substituted reference) before the simulation starts; ``recording``: a
    :class:`~afo_mj.outputs.recording.RecordingTarget` written with the results (see
    :func:`run_recorded`, which checks it and commits it).
    """
    from afo_mj.outputs.result_dir import ResultDirError, check_result_dir
    from afo_mj.scenarios.bench_scenario import is_bench_document
    from afo_mj.scenarios.device_scenario import device_config
    from afo_mj.scenarios.walk_scenario import ScenarioError, load_scenario, strides_overrides

    if out_dir is not None:
        try:
            check_result_dir(out_dir)
        except ResultDirError as exc:
            raise InvalidInput(f"{exc}; nothing written") from None
    if strides is not None and (isinstance(strides, bool) or not isinstance(strides, int)
                                or strides < 1):
        raise InvalidInput(f"--strides = {strides!r} is not allowed; allowed: an integer >= 1")
    if is_bench_document(_read_text(path)):
        if strides is not None:
            raise InvalidInput(f"--strides: {path} is a bench scenario (no strides); allowed: "
                               f"--strides on walking scenarios only")
        return run_bench(path, overrides, out_dir, figures, recording=recording)
    ov = (strides_overrides(strides) if strides is not None else []) + list(overrides)
    try:
        scenario = load_scenario(path, overrides=ov)
        reference = scenario.load_reference()
        cfg = device_config(scenario)
    except ScenarioError as exc:
        raise InvalidInput(f"invalid scenario: {exc}") from None
    for note in scenario.notes:
        if on_note is not None:
            on_note(note)
    if cfg is not None:
        return _run_device(scenario, reference, cfg, out_dir, figures, recording)
    return _run_walk(scenario, reference, out_dir, figures, recording)


def _run_walk(scenario, reference, out_dir, figures: bool, recording=None) -> WalkRun:
    from afo_mj.gait.muscle_scenario import MuscleScenarioError
    from afo_mj.gait.walkers import walk_scenario
    from afo_mj.gait.walk import WalkNumericsError
    from afo_mj.metrics.gait_metrics import GaitAnalysisError, analyse_gait
    from afo_mj.outputs.gait_report import ReportError, write_run_outputs
    from afo_mj.outputs.recording import RecordedRun

    t0 = time.perf_counter()
    try:
        # the scenario's own walker (walker.model, one registry: walkers.WALKER_MODELS)
        record, muscle_walk = walk_scenario(scenario, reference=reference)
    except MuscleScenarioError as exc:
        raise InvalidInput(str(exc)) from None
    except (WalkNumericsError, FloatingPointError) as exc:
        raise RunFailed(f"{scenario.name}: {exc}; nothing written") from None
    wall = time.perf_counter() - t0
    runs = [RecordedRun("walk", record, extra_signals=_muscle_signals(muscle_walk))]
    rrd = _rrd_writer(recording, lambda f: write_rrd(f, scenario, runs, reference))
    try:
        analysis = analyse_gait(record, reference, scenario.analyse_strides)
    except GaitAnalysisError as exc:
        if record.events.fall_time_s is None:
            raise RunFailed(f"{scenario.name}: {exc}") from None
        # a fall before any analysable stride is the run's outcome: report it
        ev = record.events
        summary = WalkSummary(scenario=scenario.as_dict(), gait=None, fall=FallOutcome(
            fell=True, fall_time_s=ev.fall_time_s,
            completed_strides=max(len(ev.heel_strikes_s[0]) - 1, 0),
            swing_toe_contacts=len(ev.swing_toe_contacts),
            duration_s=float(record.time_s[-1]) if len(record.time_s) else 0.0,
            analysis=str(exc)))
        out = None
        if out_dir is not None:
            try:
                out = write_run_outputs(out_dir, summary.to_json(), [], reference, record,
                                        scenario.text,
                                        extra_files=_chain(_run_info_writer(wall),
                                                           _recording_writer(scenario, runs,
                                                                             reference),
                                                           _opensim_writer(scenario, runs),
                                                           rrd),
                                        figures=figures)
            except ReportError as exc2:
                raise RunFailed(f"{scenario.name}: {exc2}") from None
        return WalkRun(scenario, reference, record, None, summary, wall, out)
    muscle = muscle_files = None
    if muscle_walk is not None:
        muscle, muscle_files = _muscle_outputs(muscle_walk, analysis, figures)
    try:
        bands = None
        if scenario.band_references:
            from afo_mj.gait.reference import load_normative
            from afo_mj.metrics.gait_metrics import band_fraction
            bands = {
                f"{src}:{cond}": band_fraction(analysis.cycles, load_normative(src, cond))
                for src, cond in scenario.band_references}
        summary = WalkSummary(scenario=scenario.as_dict(), gait=analysis.document,
                              muscle=muscle, band_fraction_vs=bands)
        out = None
        if out_dir is not None:
            out = write_run_outputs(out_dir, summary.to_json(), analysis.cycles, reference, record,
                                    scenario.text, extra_files=_chain(
                                        _run_info_writer(wall),
                                        _recording_writer(scenario, runs, reference),
                                        _opensim_writer(scenario, runs), muscle_files,
                                        rrd),
                                    figures=figures)
    except (GaitAnalysisError, ReportError) as exc:
        raise RunFailed(f"{scenario.name}: {exc}") from None
    return WalkRun(scenario, reference, record, analysis, summary, wall, out)


def _muscle_signals(walk) -> dict:
    """A muscle walk's signals for its recording (none for the torque walker)."""
    if walk is None:
        return {}
    from afo_mj.metrics.muscle_metrics import muscle_signals
    return muscle_signals(walk)


def _muscle_outputs(walk, analysis, figures: bool = True):
    """The summary's ``muscle`` block over the analysed strides and a writer of
    ``muscles_cycle.csv`` (:func:`afo_mj.metrics.muscle_metrics.muscle_cycle_table`) and,
    with ``figures``, ``muscles_cycle.png`` (:mod:`afo_mj.outputs.muscle_figures`)."""
    from afo_mj.metrics.muscle_metrics import muscle_cycle_table, muscle_summary
    from afo_mj.metrics.muscle_timing import PERRY_ON_PCT
    t0, t1 = analysis.summary["analysed_span_s"]
    block = muscle_summary(walk, t0, t1)
    hs = [h for h in walk.record.events.heel_strikes_s[0] if t0 - 1e-9 <= h <= t1 + 1e-9]
    header, rows = muscle_cycle_table(walk, hs)

    def write(tmp: Path) -> None:
        np.savetxt(tmp / "muscles_cycle.csv", rows, delimiter=",", header=",".join(header),
                   comments="", fmt="%.6g")
        if figures:
            from afo_mj.outputs.muscle_figures import plot_muscle_cycle
            plot_muscle_cycle(tmp / "muscles_cycle.png", header, rows, list(walk.muscles),
                              PERRY_ON_PCT, f"muscle walk: net metabolic rate "
                              f"{block['net_metabolic_umberger_w_per_kg']:.2f} W/kg (Umberger "
                              f"2010), {block['net_metabolic_bhargava_w_per_kg']:.2f} "
                              "(Bhargava 2004)")
    return block, write


def _device_files_writer(results, reference, dsum, name, wall_s, figures: bool):
    """Writer of a device run's figures (when ``figures``) and ``run_info.json``."""
    def write(tmp: Path) -> None:
        _run_info_writer(wall_s)(tmp)
        if not figures:
            return
        from afo_mj.outputs.device_figures import plot_device_run
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


def _schematic_writer(cfg):
    """Writer of ``circuit.svg``: the worn circuit's schematic (:mod:`afo_mj.outputs.schematic`),
    for every device that is a circuit (the ideal source is none: nothing written)."""
    def write(tmp: Path) -> None:
        spec = cfg.device_spec()
        if spec is None:
            return
        from afo_mj.outputs.schematic import schematic_svg
        (tmp / "circuit.svg").write_text(schematic_svg(spec.circuit, title=spec.name),
                                         encoding="utf-8")
    return write


def _run_device(scenario, reference, cfg, out_dir, figures: bool,
                recording=None) -> DeviceWalkRun:
    """A walking scenario with an orthosis: every condition, the headline one written out."""
    from afo_mj.experiments.device_walk import run_device_conditions
    from afo_mj.gait.muscle_scenario import MuscleScenarioError
    from afo_mj.gait.walk import WalkNumericsError
    from afo_mj.outputs.gait_report import ReportError, write_run_outputs
    from afo_mj.outputs.recording import RecordedRun

    t0 = time.perf_counter()
    walks = {}                      # each condition's muscle walk (muscle walker only)
    try:
        part, results = run_device_conditions(scenario, reference, cfg, muscle_walks=walks)
    except MuscleScenarioError as exc:
        raise InvalidInput(str(exc)) from None
    except (WalkNumericsError, FloatingPointError) as exc:
        raise RunFailed(f"{scenario.name}: {exc}; nothing written") from None
    wall = time.perf_counter() - t0
    head = cfg.conditions[-1]
    rec, analysis, dev = results[head]
    dsum = part.to_block()              # the figures read the conditions as JSON
    dsum.pop("condition")
    scen = {**scenario.as_dict(), "device": dict(scenario.device),
            "assistance": dict(scenario.assistance)}
    if analysis is None:
        ev = rec.events
        if ev.fall_time_s is None:
            raise RunFailed(f"{scenario.name}: condition {head!r} has no analysable stride "
                            f"(strides {scenario.analyse_strides[0]}-"
                            f"{scenario.analyse_strides[1]} not completed); nothing written")
        # a fall before an analysable stride is the run's outcome, as for a plain walk
        fall = FallOutcome(
            fell=True, fall_time_s=ev.fall_time_s,
            completed_strides=max(len(ev.heel_strikes_s[0]) - 1, 0),
            swing_toe_contacts=len(ev.swing_toe_contacts),
            duration_s=float(rec.time_s[-1]) if len(rec.time_s) else 0.0,
            analysis=f"the walker fell at t = {ev.fall_time_s:.3f} s, before the "
                     f"analysed strides {scenario.analyse_strides[0]}-"
                     f"{scenario.analyse_strides[1]} were complete")
        gait, cycles = None, []
    else:
        fall, gait, cycles = None, analysis.document, analysis.cycles
    muscle = muscle_files = None
    if head in walks and analysis is not None:
        # the wearer's effort in the headline condition: the muscle block and its files
        muscle, muscle_files = _muscle_outputs(walks[head], analysis, figures)
    summary = WalkSummary(scenario=scen, gait=gait, fall=fall, device=part, muscle=muscle)
    out = None
    if out_dir is not None:
        extra = {}
        if dev is not None and dev.log is not None:
            L = dev.log.arrays()
            cols = list(L)
            extra["device_timeseries.csv"] = (",".join(cols),
                                              np.column_stack([L[k][:, 0] for k in cols]))
        runs = [RecordedRun(c, r, d, extra_signals=_muscle_signals(walks.get(c)))
                for c, (r, _a, d) in results.items()]
        try:
            out = write_run_outputs(out_dir, summary.to_json(), cycles, reference, rec,
                                    scenario.text, extra_tables=extra,
                                    extra_files=_chain(
                                        _device_files_writer(results, reference, dsum,
                                                             scenario.name, wall, figures),
                                        muscle_files, _schematic_writer(cfg),
                                        _recording_writer(scenario, runs, reference),
                                        _opensim_writer(scenario, runs),
                                        _rrd_writer(recording, lambda f: write_rrd(
                                            f, scenario, runs, reference))),
                                    figures=figures)
        except ReportError as exc:
            raise RunFailed(f"{scenario.name}: {exc}") from None
    return DeviceWalkRun(scenario, reference, cfg, results, part, summary, wall, out)


def run_bench(path, overrides: Sequence[str] = (), out_dir=None,
              figures: bool = True, *, recording=None) -> BenchRun:
    """Run the bench scenario ``path``: its protocols on its device, on the ankle test stand
    or a simulated load; with ``out_dir``, write ``summary.json``,
    ``scenario.toml``, ``run_info.json`` and (``figures``) the bench figures. A walking
    scenario raises :class:`~afo_mj.app.errors.InvalidInput` (run it with
    :func:`run_scenario`)."""
    from afo_mj.experiments.bench_run import run_bench_scenario
    from afo_mj.outputs.gait_report import json_ready
    from afo_mj.outputs.result_dir import ResultDirError, write_atomically
    from afo_mj.scenarios.bench_protocols import BenchError
    from afo_mj.scenarios.bench_scenario import load_bench_scenario
    from afo_mj.scenarios.walk_scenario import ScenarioError

    from afo_mj.scenarios.bench_scenario import is_bench_document
    if not is_bench_document(_read_text(path)):
        raise InvalidInput(f"{path} is not a bench scenario (no [bench] table); allowed: a "
                           f"bench scenario such as scenarios/bench_hafo.toml")
    if out_dir is not None:
        from afo_mj.outputs.result_dir import check_result_dir
        try:
            check_result_dir(out_dir)
        except ResultDirError as exc:
            raise InvalidInput(f"{exc}; nothing written") from None
    try:
        bs = load_bench_scenario(path, overrides=overrides)
    except ScenarioError as exc:
        raise InvalidInput(f"invalid scenario: {exc}") from None
    t0 = time.perf_counter()
    try:
        summary, series = run_bench_scenario(bs)
    except (BenchError, FloatingPointError) as exc:
        raise RunFailed(f"{bs.name}: {exc}; nothing written") from None
    wall = time.perf_counter() - t0
    from afo_mj.metrics.documents import BenchSummary
    document = BenchSummary.from_json(json_ready(summary))
    if out_dir is None:
        return BenchRun(bs, summary, series, wall, document=document)

    def writer(tmp: Path) -> None:
        _run_info_writer(wall)(tmp)
        text = json.dumps(document.to_json(), indent=2, allow_nan=False)
        (tmp / "summary.json").write_text(text + "\n", encoding="utf-8")
        (tmp / "scenario.toml").write_text(bs.text, encoding="utf-8")
        if not figures:
            return
        from afo_mj.outputs.bench_figures import plot_bench_series
        plot_bench_series(bs.rig, series, tmp, bs.name, summary.get("published"))

    from afo_mj.outputs.recording import write_bench_recording
    rrd = _rrd_writer(recording, lambda f: None if bs.rig == "load" else
                      write_bench_recording(f, series, title=bs.name))
    try:
        out = write_atomically(out_dir, _chain(writer, rrd))
    except (ResultDirError, ValueError) as exc:
        raise RunFailed(f"{bs.name}: {exc}") from None
    return BenchRun(bs, summary, series, wall, out, document)


def record_run(res: WalkRun | DeviceWalkRun | BenchRun, path) -> dict | None:
    """Write the rerun recording of a finished run to ``path`` (``--rrd``): a walk's body
    and signals (every condition of a device walk), or a bench's time-domain experiments one
    after another. Returns the writer's info (``path``, ``entities``), or None for a bench on
    the simulated load (no time-domain recording of its protocols yet). Raises
    :class:`~afo_mj.app.errors.RunFailed` when the file cannot be written."""
    from afo_mj.outputs.recording import RecordingError, write_bench_recording
    try:
        if isinstance(res, BenchRun):
            if res.bench.rig == "load":
                return None
            return write_bench_recording(path, res.series, title=res.bench.name)
        return write_rrd(path, res.scenario, res.recorded_runs(), res.reference)
    except (RecordingError, OSError) as exc:
        raise RunFailed(f"recording not written: {exc}") from None


def check_rrd_path(rrd_path, out_dir=None) -> Path:
    """Raise :class:`~afo_mj.app.errors.InvalidInput` unless ``rrd_path`` can take the
    ``--rrd`` recording (see :func:`afo_mj.outputs.recording.check_recording_path`); called
    before anything is simulated."""
    from afo_mj.outputs.recording import RecordingError, check_recording_path
    try:
        return check_recording_path(rrd_path, out_dir)
    except RecordingError as exc:
        raise InvalidInput(f"{exc}; nothing written") from None


def run_recorded(path, rrd_path, overrides: Sequence[str] = (), strides: int | None = None,
                 out_dir=None, figures: bool = True,
                 on_note: Callable[[str], None] | None = None):
    """:func:`run_scenario` and its rerun recording at ``rrd_path`` (``afo-mj run --rrd``);
    returns ``(run, recording info or None)`` (None: no ``rrd_path``, or a circuit bench, see
    :func:`record_run`).

    ``--out`` and ``--rrd`` are checked before anything is simulated. With ``out_dir`` the
    recording is written as part of the results directory's atomic write
    (:class:`afo_mj.outputs.recording.RecordingTarget`): a recording that fails leaves no
    results, an interrupted run leaves nothing, and a recording inside ``out_dir`` is listed
    in the directory's manifest, so the same command can run again.
    """
    from afo_mj.outputs.recording import RecordingTarget
    from afo_mj.outputs.result_dir import ResultDirError, check_result_dir
    if not rrd_path:
        return run_scenario(path, overrides, strides, out_dir, figures, on_note), None
    if out_dir is not None:
        try:
            check_result_dir(out_dir)
        except ResultDirError as exc:
            raise InvalidInput(f"{exc}; nothing written") from None
    check_rrd_path(rrd_path, out_dir)
    if out_dir is None:
        res = run_scenario(path, overrides, strides, None, figures, on_note)
        return res, record_run(res, rrd_path)       # the recording is written atomically
    target = RecordingTarget(rrd_path, out_dir)
    try:
        res = run_scenario(path, overrides, strides, out_dir, figures, on_note,
                           recording=target)
        try:
            info = target.commit()
        except OSError as exc:
            raise RunFailed(f"recording not written: {exc} (the results are in "
                            f"{res.out_dir})") from None
    except BaseException:
        target.discard()
        raise
    return res, info


def _rrd_writer(target, record):
    """The ``--rrd`` recording as a results-directory writer (None without ``target``):
    ``record(file)`` writes it; a failure raises RunFailed (the results are not written)."""
    if target is None:
        return None

    def rec(file: Path):
        from afo_mj.outputs.recording import RecordingError
        try:
            return record(file)
        except (RecordingError, OSError) as exc:
            raise RunFailed(f"recording not written: {exc}; nothing written") from None
    return target.writer(rec)
