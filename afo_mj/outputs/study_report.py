"""The report of a parameter study (``afo-mj study DIR``): ``DIR/study/`` written at once.

The analysis (ranking, Pareto front, sensitivity indices) is
:func:`afo_mj.studies.study_analysis.analyse_study`; this module writes it
(:func:`afo_mj.outputs.result_dir.write_atomically`, a failure leaves ``DIR/study/`` as it
was):

* ``ranking.txt`` -- every run ranked by the metric, with its parameter values; runs without
  a value (failed runs, with their error, and successful runs whose metric is missing) after;
* ``summary.json`` -- the metric and its direction, the best run, the top runs, the Pareto
  front (device studies), the sensitivity indices or why there are none, the failed runs and
  the figures (finite numbers only: NaN is written as null);
* the figures of :func:`afo_mj.outputs.study_figures.plot_study`.
"""

from __future__ import annotations

import json
from pathlib import Path

from afo_mj.outputs.result_dir import write_atomically
from afo_mj.outputs.study_figures import plot_study
from afo_mj.studies.study_analysis import REPORT_DIR, analyse_study, jsonable

__all__ = ["write_study_report"]


def write_study_report(out_dir, metric: str | None = None,
                       ascending: bool | None = None) -> dict:
    """Write ``DIR/study/`` (``ranking.txt``, ``summary.json`` and the figures) for the sweep
    in ``out_dir``, ranked by ``metric`` (:func:`~afo_mj.studies.study_analysis.analyse_study`:
    :func:`~afo_mj.studies.study_analysis.default_metric` when None; smallest first unless
    ``ascending`` is False, or None and the name contains one of
    :data:`~afo_mj.studies.study_analysis.MAXIMISE_HINTS`).

    Returns ``{"dir": Path, "files": [names written], "text": the report to print,
    "summary": the summary.json dict}``. Raises
    :class:`~afo_mj.studies.study_analysis.StudyReportError` (a ValueError) for a directory
    without a sweep, ValueError for an unknown metric (naming close ones); nothing written."""
    out_dir = Path(out_dir)
    a = analyse_study(out_dir, metric, ascending)
    summary = a["summary"]
    sens = a["sensitivity"]
    rdir = out_dir / REPORT_DIR
    written: dict[str, list] = {"figures": []}

    def writer(tmp: Path) -> None:
        (tmp / "ranking.txt").write_text(a["ranking"], encoding="utf-8")
        written["figures"] = plot_study(tmp, a["study"], a["table"], a["metric"],
                                        pareto_axes=a["pareto_axes"], front=a["front"],
                                        sensitivity=sens if sens and "indices" in sens
                                        else None)
        summary["figures"] = list(written["figures"])
        (tmp / "summary.json").write_text(
            json.dumps(jsonable(summary), indent=2, allow_nan=False) + "\n", encoding="utf-8")

    write_atomically(rdir, writer)
    files = ["ranking.txt", "summary.json"] + list(written["figures"])
    sections = a["sections"] + ["", f"Written to {rdir}: {', '.join(files)}"]
    return {"dir": rdir, "files": files, "text": "\n".join(sections) + "\n",
            "summary": jsonable(summary)}
