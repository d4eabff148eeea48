"""``afo-mj design REQUIREMENTS.toml --out DIR``: size the lightest hydraulic ankle actuation
for a set of requirements and write the results directory.

The computation is :mod:`afo_mj.design.system_design` (:func:`~afo_mj.design.system_design.
read_requirements`, :func:`~afo_mj.design.system_design.compute_design`, nothing written); the
files are :mod:`afo_mj.outputs.design_report`. This module joins the two.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

from afo_mj.app.errors import InvalidInput
from afo_mj.design.design_document import DesignSummary
from afo_mj.design.design_requirements import DesignError

__all__ = ["design", "DesignRun", "InvalidRequirements"]


class InvalidRequirements(InvalidInput, DesignError):
    """Invalid requirements (unreadable file, bad ``--set`` override, a value not allowed):
    exit 2, nothing written. Both an :class:`afo_mj.app.errors.InvalidInput` and a
    :class:`afo_mj.design.design_requirements.DesignError` (what the design tool raised before
    the application layer), so callers catching either keep working."""


@dataclasses.dataclass(frozen=True)
class DesignRun:
    """What :func:`design` returns: the verdict, the document written as ``design.json``
    (its ``to_json()``), what to print, where it was written and the warnings."""

    feasible: bool
    summary: DesignSummary
    text: str
    out_dir: Path
    warnings: tuple[str, ...] = ()


def design(requirements_path, out_dir, overrides=(), studies: bool = True,
           verify: bool = False, top: int = 10) -> DesignRun:
    """Read and validate the requirements (``overrides``: ``key=value`` strings as for
    ``afo-mj run --set``, e.g. ``requirement.runtime_h=3``), search the designs
    (:func:`afo_mj.design.system_design.compute_design`) and write into ``out_dir`` atomically
    (:func:`afo_mj.outputs.design_report.write_design_report`): ``design.json``, ``design.md``,
    ``designs.csv`` (the ranked designs, at least ``top``), the best design as
    ``design_bench.toml`` (torque–velocity bench of ``afo-mj run``) and ``design_walk.toml``
    (walking with it), the study tables ``study_*.csv`` and figures ``study_*.png``
    (``studies``), ``hose_bore_tradeoff.csv/png``. ``verify=True`` also runs the
    torque–velocity bench on the written parameters and reports simulated against predicted
    figures.

    The written walk is checked (quasi-static, no simulation): a device that brakes the walker
    is reported as a warning (``design.json`` ``warnings`` and ``walk_check``, ``design.md``,
    the description of ``design_walk.toml``, and the returned ``warnings``).

    Returns a :class:`DesignRun` (``summary``: the
    :class:`~afo_mj.design.design_document.DesignSummary` written as ``design.json``).
    Raises :class:`InvalidRequirements` (an ``InvalidInput`` and a ``DesignError``) for
    invalid requirements, nothing written. An infeasible requirement is not an error: the
    explanation is written and returned (``feasible`` False)."""
    from afo_mj.design.system_design import compute_design, read_requirements
    from afo_mj.outputs.design_report import build_summary, summary_text, write_design_report

    try:
        req, text = read_requirements(requirements_path, overrides)
    except InvalidRequirements:
        raise
    except DesignError as exc:
        raise InvalidRequirements(str(exc)) from None
    d = compute_design(req, studies=studies, verify=verify)
    result = d["result"]
    summary = build_summary(result, d["written"], d["study"], d["hose"], d["bench"],
                            d["wall_s"])
    doc = write_design_report(out_dir, result, summary, d["written"], d["study"], d["hose"],
                              top=top, requirements_text=text)
    return DesignRun(feasible=doc.feasible, summary=doc,
                     text=summary_text(doc.to_json(), out_dir), out_dir=Path(out_dir),
                     warnings=tuple(doc.warning_list))
