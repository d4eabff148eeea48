"""The calibration report as a typed document: what ``report.json`` of ``afo-mj calibrate``
holds (format ``afo_mj calibration report v1``).

:meth:`CalibrationReport.from_report` builds it from the JSON-able form of the dict
:func:`afo_mj.calibration.calibrate.calibrate` returns (its ``"_series"`` left out, numbers made
plain: :func:`afo_mj.outputs.calibration_report.to_jsonable`), with the record's path and the
command line; ``to_json()`` is ``report.json``. The headline (verdict, errors, selected effects,
parameters) is typed; every other key of the calibration's report is kept, in its order, in
``details`` (the calibration's own report grows keys as the method grows: they pass through
without a change here). :meth:`CalibrationReport.from_json` reads a ``report.json`` back,
checking the format tag and the headline keys and their kinds.
"""

from __future__ import annotations

import dataclasses
from typing import ClassVar, Mapping

from afo_mj.metrics.document_base import Document, DocumentError, as_document_value, entry

__all__ = ["CalibrationReport", "REPORT_FORMAT", "DocumentError"]

REPORT_FORMAT = "afo_mj calibration report v1"

_DETAILS_DOC = ("every other key of the calibration's report, in its order (written at the top "
                "level of report.json): described, command_channel, skipped_outputs, inputs, "
                "split_by, train_window_s, held_out_window_s (s), settle_s (s), noise_sigma "
                "(channel units), record_flags, input_hold, hold_warnings, declared_effects, "
                "error_preset, declared_fit, declared_held, declared_deviations, "
                "identifiability, baseline, parameter_sd (parameter units), candidates, "
                "residual_whiteness_before/after, channels_before/after, unexplained_where, "
                "replay_step (the replay's maximum sub-step, s, and how it was set: chosen "
                "by the numerical check before any fit, each step tried with each channel's "
                "replay − Radau RMS over its noise σ; or stated in the scenario), "
                "numerical_error (the replay against Radau on the record's first seconds, per "
                "channel against the noise), residual_attribution (what accounts for each "
                "channel beyond the noise multiple), data_driven_discrepancy, evaluations, "
                "wall_time_s (s); see docs/calibration.md")


@dataclasses.dataclass(frozen=True)
class CalibrationReport(Document):
    """``report.json`` of a calibration against a measured bench record."""

    FORMAT: ClassVar[str] = REPORT_FORMAT
    TITLE: ClassVar[str] = "calibration report (report.json of afo-mj calibrate)"

    data: str | None = entry("str?", "the measured record's path (null: not given)")
    command: str | None = entry("str?", "the command line that made the report")
    preset: str | None = entry("str?", "the calibrated preset or described circuit's name")
    outputs: tuple = entry("list", "the measured channels fitted")
    error_before: Mapping = entry("object", "held-out NRMSE per channel and overall, "
                                  "declared parameters fitted", "1")
    error_after: Mapping = entry("object", "the same with the selected effects", "1")
    error_drop: float | None = entry("number?", "1 - after/before (overall)", "1")
    effects_selected: tuple = entry("list", "the effects added, in order, each with its "
                                    "equation, parameters and held-out errors")
    parameters: Mapping = entry("object", "the fitted physical parameters (SI, named with "
                                "their unit)")
    verdict: str = entry("str", "effect_found, no_missing_effect, unexplained_residual or "
                         "structure_wrong")
    details: Mapping = entry("object", _DETAILS_DOC, default=None)
    #: The report's keys in their order (how ``to_json`` lays them out).
    order: tuple = ()

    _HEAD: ClassVar[tuple[str, ...]] = ("data", "command")

    def to_json(self) -> dict:
        typed = {k: v for k, v in super()._body().items() if k != "details"}
        out = {"format": self.FORMAT}
        for k in self._HEAD:
            out[k] = typed[k]
        for k in self.order:
            if k in out:
                continue
            out[k] = typed[k] if k in typed else as_json(self.details[k])
        for k, v in typed.items():           # typed keys the order does not name
            out.setdefault(k, v)
        for k, v in (self.details or {}).items():
            out.setdefault(k, as_json(v))
        return out

    def _body(self) -> dict:
        out = self.to_json()
        out.pop("format")
        return out

    @classmethod
    def _from_body(cls, data: Mapping, where: str):
        if not isinstance(data, Mapping):
            raise DocumentError(f"{where}: a {type(data).__name__}; allowed: a JSON object")
        names = [f.name for f in cls._fields() if f.name != "details"]
        missing = [k for k in names if k not in data]
        if missing:
            raise DocumentError(f"{where}: missing key(s) {', '.join(map(repr, missing))}; "
                                f"required: {', '.join(names)}")
        kw = {f.name: cls._value_from(data[f.name], f.metadata, f"{where}.{f.name}")
              for f in cls._fields() if f.name != "details"}
        details = {k: as_document_value(v) for k, v in data.items() if k not in names}
        return cls(**kw, details=details, order=tuple(k for k in data if k != "format"))

    @classmethod
    def from_report(cls, report: Mapping, data_path=None,
                    command: str | None = None) -> "CalibrationReport":
        """The document of a calibration's JSON-able report (no ``"_series"``, plain
        numbers), with the record's path ``data_path`` and the ``command`` line. The
        report's own ``format``/``data``/``command`` keys, if it has any, give way to
        these (as ``report.json`` has always been written)."""
        if "_series" in report:
            raise DocumentError("calibration report: '_series' is not part of report.json; "
                                "allowed: the report without it")
        body = {"data": None if data_path is None else str(data_path), "command": command}
        body.update({k: v for k, v in report.items() if k not in ("format", *body)})
        return cls._from_body(body, "calibration report")


def as_json(v):
    """A stored free-form value as JSON (tuples back to lists)."""
    return Document._value_json(v, {"map_of": None, "kind": "object"})
