"""``afo-mj dose-response``: a dose–response study file (:mod:`afo_mj.studies.
dose_response`) run by continuation of the adapted wearer, resumable (run again with the same
``--out`` to continue), its figure written next to ``dose_response.json``.

Raises :class:`~afo_mj.app.errors.InvalidInput` (exit 2, nothing written) for a study file
that is missing or invalid (its message names the key), a start that is not a reflex set, or
a folder holding another study.
"""

from __future__ import annotations

from pathlib import Path

from afo_mj.app.errors import InvalidInput

__all__ = ["dose_response", "REFERENCES"]

#: published points drawn on a variable's figure: (dose, change %, ± %, label)
REFERENCES = {
    # Collins, Wiggin & Sawicki 2015 (Nature 522:212): the medium spring's reduction
    "spring_nm_per_rad": (180.0, -7.2, 2.6, "Collins et al. 2015, medium spring"),
}


def dose_response(study, out, workers: int | None = None, progress=None):
    """Run (or continue) the study file ``study`` into ``out``; returns the
    :class:`~afo_mj.studies.dose_response.DoseResponseResult` (also in
    ``out/dose_response.json``) and writes ``out/dose_response.png``."""
    from afo_mj import progress as _progress
    from afo_mj.outputs.dose_figures import plot_dose_response
    from afo_mj.studies import dose_response as dr
    if workers is not None and (isinstance(workers, bool) or workers < 1):
        raise InvalidInput(f"--workers = {workers!r}; allowed: an integer >= 1")
    if not Path(study).is_file():
        raise InvalidInput(f"study {study}: no such file")
    try:
        s = dr.load_dose_study(study)
    except ValueError as exc:
        raise InvalidInput(str(exc)) from None
    try:
        dr.load_reflex_set(s.start)
    except (OSError, ValueError, KeyError) as exc:
        raise InvalidInput(f"{study}: dose_response.start {s.start}: {exc}") from None
    stage = progress or _progress.reporter().stage
    try:
        res = dr.run_dose_response(out, s, workers=workers,
                                   progress=lambda m: stage(f"dose-response: {m}"))
    except ValueError as exc:
        raise InvalidInput(str(exc)) from None
    plot_dose_response(Path(out) / "dose_response.png", res,
                       dr.DOSE_VARIABLES[s.variable][2], REFERENCES.get(s.variable))
    return res
