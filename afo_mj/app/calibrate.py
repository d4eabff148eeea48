"""Calibrate the model against a measured bench record: ``afo-mj calibrate``.

:func:`calibrate_record` reads the calibration setup (the preset, its declared parameters and
the options: :func:`afo_mj.calibration.calibrate.load_calibration_setup`) and the measured
record (:func:`afo_mj.calibration.measured_data.load_measured`, which warns about suspect
units), replays and fits (:func:`afo_mj.calibration.calibrate.calibrate`) and writes the
report with its figures. Bad input raises :class:`~afo_mj.app.errors.InvalidInput`, a
calibration that cannot run :class:`~afo_mj.app.errors.RunFailed` (nothing written).
"""

from __future__ import annotations

import dataclasses
import warnings
from pathlib import Path
from typing import Callable

from afo_mj.app.errors import InvalidInput, RunFailed
from afo_mj.calibration.report_document import CalibrationReport

__all__ = ["CalibrationRun", "calibrate_record"]


@dataclasses.dataclass(frozen=True)
class CalibrationRun:
    """The calibration report (:class:`~afo_mj.calibration.report_document.CalibrationReport`:
    ``report.json`` is its ``to_json()``) and where it was written."""

    report: CalibrationReport
    out_dir: Path | None


def calibrate_record(scenario_path, data_path, out_dir=None, command: str | None = None,
                     on_warning: Callable[[str], None] | None = None,
                     on_stage: Callable[[str], None] | None = None) -> CalibrationRun:
    """Calibrate the preset of ``scenario_path`` against the record ``data_path``; with
    ``out_dir``, write ``report.json``, ``report.md`` and the figures (``command``: the
    command line echoed in the report)."""
    from afo_mj.calibration.calibrate import (CalibrationError, calibrate_setup,
                                              load_calibration_scenario)
    from afo_mj.calibration.measured_data import MeasuredDataError, load_measured
    from afo_mj.experiments.bench_replay import ReplayError
    from afo_mj.hydraulics.params import ParameterError
    from afo_mj.outputs.calibration_report import write_calibration_report
    from afo_mj.outputs.result_dir import ResultDirError, check_result_dir, write_atomically

    if out_dir is not None:
        try:
            check_result_dir(out_dir)
        except ResultDirError as exc:
            raise InvalidInput(f"{exc}; nothing written") from None
    try:
        setup = load_calibration_scenario(scenario_path)
        preset = setup.preset or (setup.circuit.name if setup.circuit is not None else None)
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            data = load_measured(data_path)
        if on_warning is not None:
            for w in caught:
                on_warning(str(w.message))
            if (setup.circuit is None and data.source.get("preset")
                    and data.source["preset"] != preset):
                on_warning(f"the record says source.preset = {data.source['preset']!r}; "
                           f"calibrating {preset!r} (from --scenario)")
    except (ParameterError, MeasuredDataError, OSError) as exc:
        raise InvalidInput(str(exc)) from None
    try:
        report = calibrate_setup(data, setup)
    except (CalibrationError, ParameterError) as exc:
        raise InvalidInput(str(exc)) from None
    except (ReplayError, FloatingPointError) as exc:
        raise RunFailed(f"{exc}; nothing written") from None
    if on_warning is not None:
        for flag in report.get("record_flags") or ():
            on_warning(flag)
    from afo_mj.outputs.calibration_report import calibration_document
    try:
        doc = calibration_document(report, data_path, command)
    except ValueError as exc:
        raise RunFailed(f"{exc}; nothing written") from None
    if out_dir is None:
        return CalibrationRun(doc, None)
    if on_stage is not None:
        on_stage(f"writing the report and figures to {out_dir}…")
    try:
        out = write_atomically(out_dir, lambda d: write_calibration_report(
            report, d, data_path=data_path, command=command))
    except (ResultDirError, ValueError, OSError) as exc:
        raise RunFailed(f"{exc}; nothing written") from None
    return CalibrationRun(doc, out)
