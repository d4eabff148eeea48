"""Compare orthosis architectures on one gait: ``afo-mj compare``.

:func:`compare` loads the device scenarios (and their variants), runs each one's assist
condition and the shared no-device baseline (:mod:`afo_mj.experiments.device_comparison`),
writes the comparison directory and, with ``rrd_path``, a rerun recording of every device side
by side (the two written together or not at all; ``--out`` and ``--rrd`` are checked before
anything runs). Bad input raises :class:`~afo_mj.app.errors.InvalidInput`, a failed run or
recording :class:`~afo_mj.app.errors.RunFailed` (nothing written).
"""

from __future__ import annotations

import dataclasses
import platform
import re
from pathlib import Path
from typing import Any, Callable, Sequence

import numpy as np

from afo_mj.app.errors import InvalidInput, RunFailed

__all__ = ["ComparisonRun", "compare"]


@dataclasses.dataclass(frozen=True)
class ComparisonRun:
    """The comparison (:class:`afo_mj.experiments.device_comparison.Comparison`), where it was
    written, and the recording's info (``path``, ``entities``; None without ``rrd_path``)."""

    comparison: Any
    out_dir: Path
    recording: dict | None = None


def compare(scenario_paths: Sequence[str], out_dir, overrides: Sequence[str] = (),
            strides: int | None = None, rrd_path=None,
            on_note: Callable[[str], None] | None = None,
            on_stage: Callable[[str], None] | None = None) -> ComparisonRun:
    """Run and write the comparison of ``scenario_paths`` (see the module docstring)."""
    import mujoco

    from afo_mj.experiments.device_comparison import (CompareError, load_compare_items,
                                                      run_comparison)
    from afo_mj.gait.walk import WalkNumericsError
    from afo_mj.outputs.comparison_report import write_comparison
    from afo_mj.outputs.result_dir import ResultDirError, check_result_dir
    from afo_mj.scenarios.walk_scenario import ScenarioError

    try:
        check_result_dir(out_dir)
    except ResultDirError as exc:
        raise InvalidInput(f"{exc}; nothing written") from None
    if rrd_path:
        from afo_mj.app.run import check_rrd_path
        check_rrd_path(rrd_path, out_dir)
    try:
        items = load_compare_items(scenario_paths, overrides=overrides, strides=strides)
    except (ScenarioError, CompareError) as exc:
        raise InvalidInput(f"invalid scenario: {exc}; nothing written") from None
    for note in dict.fromkeys(n for it in items for n in it.scenario.notes):
        if on_note is not None:
            on_note(note)
    kept: list | None = [] if rrd_path else None
    try:
        comp = run_comparison(items, progress=on_stage, keep_runs=kept)
    except (WalkNumericsError, FloatingPointError) as exc:
        raise RunFailed(f"{exc}; nothing written") from None
    info = {"argv": {"scenarios": list(scenario_paths), "set": list(overrides),
                     "strides": strides},
            "python": platform.python_version(), "numpy": np.__version__,
            "mujoco": mujoco.__version__, "platform": platform.platform()}
    if not rrd_path:
        try:
            out = write_comparison(out_dir, comp, info)
        except (ResultDirError, OSError, ValueError) as exc:
            raise RunFailed(f"{exc}; nothing written") from None
        return ComparisonRun(comp, out)
    from afo_mj.outputs.recording import (RecordedRun, RecordingError, write_recording,
                                          write_results_with_recording)
    runs = [RecordedRun(re.sub(r"[^A-Za-z0-9_]+", "_", label).strip("_") or f"run{i}",
                        rec, dev) for i, (label, rec, dev) in enumerate(kept)]

    def record(file: Path) -> dict:
        try:
            return write_recording(file, runs, items[0].reference, title="afo_mj compare")
        except (RecordingError, OSError) as exc:
            raise RunFailed(f"recording not written: {exc}; nothing written") from None

    try:
        rec_info = write_results_with_recording(
            out_dir, rrd_path, lambda stage: write_comparison(stage, comp, info), record)
    except (ResultDirError, OSError, ValueError) as exc:
        raise RunFailed(f"{exc}; nothing written") from None
    return ComparisonRun(comp, Path(out_dir), recording=rec_info)
