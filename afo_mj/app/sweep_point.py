"""One point of a parameter study, run in-process: what a sweep's worker executes.

:func:`run_point` runs the study's base scenario with the point's ``--set`` overrides through
:func:`afo_mj.app.run.run_scenario` (the code ``afo-mj run`` uses), without figures, and turns
the summary into one row of the study's table (:mod:`afo_mj.studies.sweep`). It is a
module-level function so that local worker processes and Dask workers can unpickle it.
"""

from __future__ import annotations

import os
import time
import traceback
from pathlib import Path
from typing import Any, Sequence

from afo_mj.metrics.document_base import Document

__all__ = ["run_point"]


def run_point(scenario_path: str, overrides: Sequence[str], run_id: str,
              point: dict[str, Any], keep_dir: str | None = None) -> dict[str, Any]:
    """Run one point; returns its row: ``run_id``, ``status`` (``ok``/``failed``),
    ``exit_code`` (what ``afo-mj run`` would exit with), ``error`` (empty when it
    succeeded), ``wall_time_s``, ``param:<key>`` inputs and the flattened summary. With
    ``keep_dir`` the run's results directory (numbers, no figures) is kept as
    ``keep_dir/<run_id>``. Never raises for a failing run (the error is in the row)."""
    os.environ.setdefault("MUJOCO_GL", "egl")
    from afo_mj import progress
    from afo_mj.app.errors import AppError
    from afo_mj.app.run import run_scenario
    from afo_mj.outputs.gait_report import json_ready
    from afo_mj.studies.sweep import PARAM_PREFIX, flatten_summary

    t0 = time.perf_counter()
    row: dict[str, Any] = {"run_id": run_id}
    for k, v in point.items():
        row[PARAM_PREFIX + k] = v
    out = None
    if keep_dir:
        out = Path(keep_dir) / run_id
        if out.exists():                        # a run in flight when a sweep stopped
            import shutil
            shutil.rmtree(out)
    summary = None
    try:
        with progress.using(progress.Reporter(quiet=True)):
            res = run_scenario(scenario_path, overrides=list(overrides), out_dir=out,
                               figures=False)
        doc = res.summary           # a walk's WalkSummary document, a bench's dict
        summary = json_ready(doc.to_json() if isinstance(doc, Document) else doc)
        code, error = 0, ""
    except AppError as exc:
        code, error = exc.exit_code, str(exc)
    except Exception as exc:                    # noqa: BLE001 - recorded, not raised
        code = -1
        error = f"{type(exc).__name__}: {exc}"
        tb = traceback.format_exc(limit=3).strip().splitlines()
        error += " | " + tb[-2].strip() if len(tb) >= 2 else ""
    row["exit_code"] = code
    if summary is not None:
        row.update(flatten_summary(summary))
        row["status"] = "ok"
    else:
        row["status"] = "failed"
    row["error"] = error
    row["wall_time_s"] = time.perf_counter() - t0
    return row
