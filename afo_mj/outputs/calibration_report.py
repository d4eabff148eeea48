"""Files of ``afo-mj calibrate``: the report of :func:`afo_mj.calibration.calibrate.calibrate`.

:func:`write_calibration_report` writes into a result directory, all at once
(:func:`afo_mj.outputs.result_dir.write_atomically`: a failure leaves no half-written file and
nothing replaced):

* ``report.json`` -- the report dictionary without its ``"_series"``, numpy scalars and arrays
  as plain numbers and lists (:func:`to_jsonable`), written from its document
  (:func:`calibration_document`, :class:`afo_mj.calibration.report_document.CalibrationReport`),
  plus ``"format"`` (:data:`FORMAT`),
  ``"data"`` (the record's path) and ``"command"`` (the command line). A NaN or infinity
  anywhere in the report is refused (ValueError naming its key path); JSON never holds NaN.
* ``report.md`` -- for an engineer: the verdict in plain words, the held-out NRMSE per channel
  (preset, declared fit, after the selected effects), each selected effect (equation, fitted
  parameters ± 1 SD in SI, the held-out drop and ΔBIC/ΔAIC it bought), the fitted parameters,
  the candidate table (sorted by best ranking score), the residual whiteness before/after
  (Ljung–Box p, excess over the sensor noise), the windows and noise σ, and the figures.
* ``fit_before_after.png`` -- per output channel, measured vs the model before (declared fit)
  and after (with the selected effects), the last :data:`CONTEXT_S` s of training and the
  held-out part (shaded);
* ``residual_before_after.png`` -- per channel, ``measured − model`` on the held-out part,
  before and after, with ±2σ of the sensor noise;
* ``residual_spectrum.png`` -- per channel, the Welch PSD of the held-out residual before and
  after (:func:`afo_mj.calibration.residual_analysis.residual_spectrum`), log–log axes, with the
  one-sided PSD ``2σ²/fs`` of white sensor noise for reference.

The figures need the report's ``"_series"`` (what :func:`calibrate` returns); a report read back
from ``report.json`` has none, and is written without figures (``report.md`` says so).
Figures draw at most :data:`MAX_PLOT_POINTS` points per line (stride decimation), so each draws
in well under a second whatever the record's length. Pressures are drawn in MPa, every other
channel in its SI unit (:data:`afo_mj.calibration.measured_data.CHANNELS`).
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping
from pathlib import Path

import numpy as np

from afo_mj.calibration.report_document import REPORT_FORMAT, CalibrationReport
from afo_mj.outputs.result_dir import write_atomically

__all__ = ["write_calibration_report", "calibration_document", "to_jsonable",
           "render_markdown", "verdict_sentence", "FORMAT", "FIGURES", "CONTEXT_S",
           "MAX_PLOT_POINTS"]

#: ``report.json``'s ``"format"`` (:class:`~afo_mj.calibration.report_document.CalibrationReport`).
FORMAT = REPORT_FORMAT
#: The PNGs written when the report carries its ``"_series"``.
FIGURES = ("fit_before_after.png", "residual_before_after.png", "residual_spectrum.png")
#: Seconds of training shown before the held-out part in ``fit_before_after.png``.
CONTEXT_S = 4.0
#: Most points drawn per line (longer series are decimated by a stride).
MAX_PLOT_POINTS = 4000
_DPI = 110
#: "structured" threshold of :mod:`afo_mj.calibration.residual_analysis` (for the verdict text).
_EXCESS = 1.2

_UNIT_PRETTY = {"m^3": "m³", "m^2": "m²", "rad/(N m)": "rad/(N·m)", "N m/A": "N·m/A",
                "ohm": "Ω", "-": "1", "N m": "N·m"}
#: parameter-name suffix → SI unit, for names the effect library does not know
_SUFFIX_UNITS = (("_rad_per_nm", "rad/(N·m)"), ("_nm_a", "N·m/A"), ("_1_pa", "1/Pa"),
                 ("_m_s", "m/s"), ("_k_s", "K/s"), ("_rad_s", "rad/s"), ("_m3", "m³"),
                 ("_m2", "m²"), ("_pa", "Pa"), ("_nm", "N·m"), ("_ohm", "Ω"), ("_rad", "rad"),
                 ("_n", "N"), ("_a", "A"), ("_s", "s"), ("_m", "m"), ("_k", "K"), ("_v", "V"))


# --------------------------------------------------------------------------- JSON

def _key_path(path: str, key) -> str:
    k = str(key)
    if k.isidentifier():
        return f"{path}.{k}" if path else k
    return f"{path}[{k!r}]"


def to_jsonable(obj, path: str = ""):
    """``obj`` as plain JSON types: numpy scalars → float/int/bool, arrays and tuples → lists,
    mappings → dicts with str keys, paths → str.

    Raises ValueError naming the key path (e.g. ``error_after.overall`` or
    ``effects_selected[0].delta_bic``) for a NaN or infinite number, and for an object JSON
    cannot hold."""
    where = path or "<report>"
    if obj is None or isinstance(obj, (str, bool)):
        return obj
    if isinstance(obj, np.bool_):
        return bool(obj)
    if isinstance(obj, (int, np.integer)):
        return int(obj)
    if isinstance(obj, (float, np.floating)):
        f = float(obj)
        if not math.isfinite(f):
            raise ValueError(f"calibration report: {where} = {f!r}; allowed: a finite number "
                             "(NaN and infinity are not written into report.json)")
        return f
    if isinstance(obj, Path):
        return str(obj)
    if isinstance(obj, Mapping):
        out = {}
        for k, v in obj.items():
            if not isinstance(k, (str, int, np.integer)) or isinstance(k, bool):
                raise ValueError(f"calibration report: {where} has a key {k!r} of type "
                                 f"{type(k).__name__}; allowed: str keys")
            out[str(k)] = to_jsonable(v, _key_path(path, k))
        return out
    if isinstance(obj, np.ndarray):
        if obj.dtype.kind in "fc" and obj.size and not np.all(np.isfinite(obj)):
            flat = np.flatnonzero(~np.isfinite(obj))
            raise ValueError(f"calibration report: {where} holds a non-finite value "
                             f"(at flat index {int(flat[0])}, {flat.size} in all); allowed: "
                             "finite numbers")
        return [to_jsonable(v, f"{where}[{i}]") for i, v in enumerate(obj.tolist())]
    if isinstance(obj, (list, tuple)):
        return [to_jsonable(v, f"{where}[{i}]") for i, v in enumerate(obj)]
    raise ValueError(f"calibration report: {where} is a {type(obj).__name__}; allowed: "
                     "numbers, str, bool, None, lists and dicts of them")


# --------------------------------------------------------------------------- formatting

def _f(v, fmt: str = ".4g") -> str:
    if v is None or isinstance(v, bool) or not isinstance(v, (int, float)):
        return "—" if v is None else str(v)
    return f"{v:{fmt}}"


def _pct(v, digits: int = 2) -> str:
    return "—" if v is None else f"{100.0 * v:.{digits}f}"


def _signed_pct(change) -> str:
    """A relative change as ``−59 %`` / ``+3 %`` (unicode minus)."""
    if change is None:
        return "—"
    p = 100.0 * change
    if abs(p) < 0.5:
        return "±0 %"
    return f"{'+' if p > 0 else '−'}{abs(p):.0f} %"


def _md_table(header: list[str], rows: list[list[str]], align_left: int = 1) -> str:
    esc = lambda s: str(s).replace("|", "\\|").replace("\n", " ")  # noqa: E731
    lines = ["| " + " | ".join(esc(h) for h in header) + " |",
             "|" + "|".join("---" if i < align_left else "---:"
                            for i in range(len(header))) + "|"]
    lines += ["| " + " | ".join(esc(c) for c in r) + " |" for r in rows]
    return "\n".join(lines)


def _channel_unit(ch: str) -> str:
    try:
        from afo_mj.calibration.measured_data import CHANNELS
        u = CHANNELS[ch].unit if ch in CHANNELS else ""
    except Exception:          # the report must render even if the channel table moved
        u = ""
    return u or _suffix_unit(ch)


def _suffix_unit(name: str) -> str:
    for suf, unit in _SUFFIX_UNITS:
        if name.endswith(suf):
            return unit
    return "1"


def _parameter_units(report: Mapping) -> dict[str, str]:
    """Parameter name (``declared`` or ``effect.parameter``) → SI unit, from the effect
    library where it knows the device's command; other names by their suffix
    (:func:`_suffix_unit`)."""
    units: dict[str, str] = {}
    try:
        from afo_mj.calibration.effect_library import declared_parameters, effects_for
        described = bool(report.get("described"))
        outputs = list(report.get("outputs") or [])
        if described:
            # a described rig's declared set: every value of its description, with its unit
            for row in (report.get("declared_set") or {}).get("values", []):
                units[row["name"]] = _UNIT_PRETTY.get(row["unit"], row["unit"])
        else:
            for d in declared_parameters(report.get("command_channel")):
                units[d.name] = _UNIT_PRETTY.get(d.unit, d.unit)
        for e in effects_for(outputs, described=described):
            for p in e.parameters:
                units[f"{e.name}.{p.name}"] = _UNIT_PRETTY.get(p.unit, p.unit)
    except Exception:          # unknown command, or a hand-made report: fall back to names
        pass
    return units


def _replay_kind(report: Mapping) -> str:
    """What was replayed, in words: a described circuit, or a preset and its command."""
    if report.get("described"):
        return "described circuit"
    return f"preset, {report.get('command_channel', '?')} command"


def _unit_of(name: str, units: Mapping[str, str]) -> str:
    if name in units:
        return units[name]
    return _suffix_unit(name.rsplit(".", 1)[-1])


def _overall(err) -> float | None:
    if isinstance(err, Mapping):
        v = err.get("overall")
        return float(v) if isinstance(v, (int, float)) and not isinstance(v, bool) else None
    return None


def verdict_sentence(report: Mapping) -> str:
    """The verdict of a (JSON-able) report in plain words: the first paragraph of
    ``report.md``."""
    verdict = report.get("verdict")
    before, after = _overall(report.get("error_before")), _overall(report.get("error_after"))
    drop = report.get("error_drop")
    where = report.get("unexplained_where")
    if verdict == "effect_found":
        effects = list(report.get("effects_selected") or [])
        names = ", ".join(f"{e.get('effect')} ({e.get('component')})" for e in effects) \
            or "(none listed)"
        head = "Effect found" if len(effects) <= 1 else "Effects found"
        change = _signed_pct(-drop) if isinstance(drop, (int, float)) else "—"
        s = (f"**{head}: {names}**, held-out NRMSE {_f(before, '.4f')} → "
             f"{_f(after, '.4f')} ({change}).")
        if where:
            s += (f"\n\nSome structure remains in the residual after the selected effects: "
                  f"{where}.")
        return s
    devs = report.get("declared_deviations") or []
    if verdict == "no_missing_effect" and devs:
        d = devs[0]
        eq = " or ".join(d.get("equivalent_to") or []) or "a wrong datasheet value"
        return ("**No missing effect, but a declared value is off:** the described rig "
                f"explains the record to the noise level once `{d['parameter']}` moves "
                f"{_signed_pct(d.get('relative_change'))} from its datasheet value (tolerance "
                f"±{100 * d['tolerance']:.0f} %): {eq}. "
                f"{len(devs) - 1} more beyond tolerance." if len(devs) > 1 else
                "**No missing effect, but a declared value is off:** the described rig "
                f"explains the record to the noise level once `{d['parameter']}` moves "
                f"{_signed_pct(d.get('relative_change'))} from its datasheet value (tolerance "
                f"±{100 * d['tolerance']:.0f} %): {eq}.")
    if verdict == "no_missing_effect":
        return ("**No missing effect:** the declared model, with its parameters fitted, "
                "explains the record to the noise level: every held-out residual is white "
                f"and within {_EXCESS:g}× its sensor noise (held-out NRMSE "
                f"{_f(before, '.4f')}). No candidate effect was added.")
    if verdict == "structure_wrong":
        base = report.get("baseline") or {}
        ratio = base.get("ratio") or {}
        worst = ", ".join(f"`{c}` {v:.2g}×" for c, v in sorted(ratio.items(),
                                                                key=lambda kv: -kv[1])
                          if v > base.get("noise_multiple", 2.0))
        s = ("**The declared structure is wrong:** with the identifiable parameters fitted, "
             f"the described rig does not reach {base.get('noise_multiple', 2.0):g}× the "
             f"noise floor on {worst or 'some channels'} (held-out NRMSE over σ/SD), and no "
             "candidate effect of the library explains the difference. Check the "
             "description (components, connections, sensors, signs) before reading any "
             "parameter.")
        s += f"\n\nWhere the structure lives: {where or 'not located'}."
        s += _attribution_sentence(report)
        return s
    if verdict == "unexplained_residual":
        s = ("**Unexplained residual:** the held-out residual of the declared model is "
             "structured (not white and larger than the sensor noise), but no candidate "
             "effect of the library explains it: none lowered BIC, the held-out error and "
             "stayed identifiable all at once. The model misses something the library does "
             f"not contain (held-out NRMSE {_f(before, '.4f')}).")
        s += f"\n\nWhere the structure lives: {where or 'not located'}."
        s += _attribution_sentence(report)
        return s
    return f"**Verdict: {verdict!r}** (unknown verdict)."


_EXPLAINED = {"numerical_error": "the replay's numerical error",
              "data_driven_discrepancy": "the data-driven discrepancy",
              "common_mode_drift": "a common-mode drift", "differential_drift":
              "a differential drift", "drift": "a slow drift",
              "step_transient": "a transient after input steps", "resonance": "a resonance"}


def _attribution_sentence(report: Mapping) -> str:
    """What accounts for each channel a described rig leaves beyond its noise multiple
    (the report's ``residual_attribution``); empty without one."""
    att = report.get("residual_attribution")
    if not isinstance(att, Mapping) or not att.get("channels"):
        return ""
    parts = []
    for c, v in att["channels"].items():
        by = [_EXPLAINED.get(k, k) for k in v.get("explained_by") or []]
        parts.append(f"`{c}` {v.get('baseline_ratio', float('nan')):.2f}× its floor: "
                     + (", ".join(by) if by else "**nothing accounts for it**"))
    return (f"\n\nBeyond {att.get('noise_multiple', 2.0):g}× the noise floor, and what "
            "accounts for it: " + "; ".join(parts) + ". `structure_wrong` is kept for a "
            "channel nothing accounts for.")


def _step_section(step: Mapping | None) -> list[str]:
    """The report's "Replay step" section (``replay_step``): the step the replay ran at and,
    when the numerical check chose it, the replay − Radau error at each step tried."""
    if not step:
        return []
    L = ["## Replay step\n"]
    h = step.get("max_step_s")
    if step.get("source") != "numerical_check":
        L.append(f"The replay ran in sub-steps of at most {_f(1e3 * h, '.4g')} ms: "
                 f"{step.get('reason', step.get('source', '—'))}.\n")
        return L
    t0, t1 = step.get("window_s", [0.0, 0.0])
    L.append(f"Chosen before any fit: the described model integrated by Radau on "
             f"{t0:.3g}–{t1:.3g} s beside the replay, whose step was halved from "
             f"{_f(1e3 * step['start_s'], '.4g')} ms while a channel's replay − Radau RMS "
             f"exceeded {step['target_ratio']:g} of its noise σ (floor "
             f"{_f(1e3 * step['floor_s'], '.4g')} ms). Chosen: **{_f(1e3 * h, '.4g')} ms**"
             + ("" if step.get("reached") else
                " (the target was not reached" + (": a halving stopped cutting the error)"
                                                   if step.get("stalled") else
                                                   " at the floor)"))
             + ".\n")
    tried = step.get("tried") or []
    if tried:
        chans = list(tried[0]["ratios"])
        rows = [[f"{_f(1e3 * s['max_step_s'], '.4g')}", str(s["substeps"])]
                + [_f(s["ratios"].get(c), ".2f") for c in chans] for s in tried]
        L.append(_md_table(["step [ms]", "sub-steps per sample"]
                           + [f"`{c}` / σ" for c in chans], rows) + "\n")
    return L


def _numerical_section(num: Mapping | None) -> list[str]:
    """The report's "Numerical error of the replay" section (``numerical_error``)."""
    if num is None:
        return []
    L = ["## Numerical error of the replay (against Radau)\n"]
    if not num.get("run"):
        L.append(f"Not checked: {num.get('reason', '—')}.\n")
        return L
    t0, t1 = num["window_s"]
    L.append(f"The final model integrated by `solve_ivp(Radau)` at rtol {num['rtol']:g} on "
             f"the record's inputs, {t0:.3g}–{t1:.3g} s (scored from {num['scored_from_s']:.3g}"
             f" s), beside the replay the calibration fits with: their difference is the "
             f"replay's own numerical error, a check, not a fit ({num['rhs_evaluations']} "
             f"right-hand-side evaluations, {num['wall_s']:.1f} s).\n")
    rows = []
    for c, v in num["channels"].items():
        unit = _channel_unit(c)
        share = v.get("share")
        rows.append([f"`{c}`", f"{_f(v['noise_sigma'])} {unit}".strip(),
                     f"{_f(v['rms_difference'])} {unit}".strip(), _f(v.get("ratio"), ".2f"),
                     "—" if share is None else f"{100 * share:.0f}",
                     _f(v.get("residual_ratio_replay"), ".2f"),
                     _f(v.get("residual_ratio_reference"), ".2f"),
                     "yes" if v.get("explains_excess") else ""])
    L.append(_md_table(["channel", "noise σ", "replay − Radau RMS", "/ σ",
                        "share of residual [%]", "residual / σ (replay)",
                        "residual / σ (Radau)", "explains the excess"], rows) + "\n")
    if num.get("not_compared"):
        L.append("Not compared: " + "; ".join(f"`{c}` ({r})" for c, r in
                                              num["not_compared"].items()) + ".\n")
    if num.get("below_floor_samples"):
        L.append(f"The Radau run has {num['below_floor_samples']} samples with a pressure "
                 "below the vapour floor, which the replay's stepper raises to it: the two "
                 "differ there by construction.\n")
    return L


def _best_refit(entry: Mapping) -> Mapping | None:
    refits = list(entry.get("refits") or [])
    if not refits:
        return None
    paying = [r for r in refits if r.get("pays")]
    return paying[-1] if paying else refits[-1]


def render_markdown(report: Mapping, figures: tuple[str, ...] = FIGURES) -> str:
    """``report.md`` of a JSON-able report (:func:`to_jsonable` of the calibration's report,
    with ``format``/``data``/``command``); ``figures``: the PNGs written next to it."""
    units = _parameter_units(report)
    outputs = list(report.get("outputs") or [])
    L: list[str] = []
    L.append(f"# Calibration report: {report.get('preset', '?')} "
             f"({_replay_kind(report)} bench replay)\n")
    L.append(verdict_sentence(report) + "\n")
    meta = []
    if report.get("data") is not None:
        meta.append(f"Record: `{report['data']}`")
    if report.get("command"):
        meta.append(f"Command: `{report['command']}`")
    if meta:
        L.append("  \n".join(meta) + "\n")

    # ---- what the record checks flagged (afo_mj.calibration.record_checks)
    if report.get("record_flags"):
        L.append("## Record checks\n")
        L.append("The record does not fit the declared rig everywhere; read the verdict with "
                 "this in mind:\n")
        L += [f"- {m}" for m in report["record_flags"]]
        L.append("")

    # ---- baseline against the noise floor, identifiability (a described rig)
    base = report.get("baseline")
    if base:
        L.append("## Baseline against the noise floor\n")
        L.append(f"Held-out NRMSE of each channel next to its noise floor σ/SD: the baseline "
                 f"(the declared model with its identifiable parameters fitted, before any "
                 f"effect) must reach {base.get('noise_multiple', 2.0):g}× the floor; final: "
                 f"with the effects selected.\n")
        ea = report.get("error_after") or {}
        rows = []
        for c in base.get("ratio", {}):
            fl = base["noise_floor"].get(c)
            a = ea.get(c)
            lag = (base.get("lag_s") or {}).get(c)
            rows.append([f"`{c}`", _pct(fl), _pct(base["held_out"].get(c)),
                         f"{base['ratio'].get(c, float('nan')):.2f}", _pct(a),
                         f"{a / fl:.2f}" if isinstance(a, (int, float)) and fl else "—",
                         "—" if lag is None else f"{1e3 * lag:+.2f}"])
        L.append(_md_table(["channel", "noise floor [%]", "baseline [%]", "baseline / floor",
                            "final [%]", "final / floor", "sensor lag [ms]"], rows) + "\n")
        L.append("Sensor lag: the shift of the measured channel against the baseline model "
                 "that best aligns them (positive: the measurement lags).\n")
        L.append("Reaches the noise: **" + ("yes" if base.get("reaches_noise") else "no")
                 + "**.\n")
    L += _step_section(report.get("replay_step"))
    L += _numerical_section(report.get("numerical_error"))
    ident = report.get("identifiability")
    if ident:
        L.append("## Identifiability\n")
        L.append("Which declared parameters this record can estimate: sensitivities to a "
                 "relative change of each datasheet value, whitened by the sensor noise; "
                 "pivoted QR order and ratio |R_kk|/|R_00|; predicted relative standard "
                 "error (Cramér–Rao). Held parameters stay at the description's values.\n")
        held = report.get("declared_held") or {}
        rows = []
        for r in ident.get("parameters", []):
            se = r.get("predicted_relative_se")
            rows.append([f"`{r['name']}`", _f(r.get("sensitivity"), ".3g"),
                         "—" if r.get("pivot_rank") is None else str(r["pivot_rank"]),
                         _f(r.get("pivot_ratio"), ".2g"),
                         "—" if se is None else _f(se, ".2g"),
                         "fitted" if r.get("fitted") else
                         f"held at {_f(held.get(r['name']), '.4g')}: {r.get('reason')}"])
        L.append(_md_table(["parameter", "sensitivity", "pivot", "ratio", "rel. SE",
                            "decision"], rows) + "\n")
        sv = ident.get("singular_values") or []
        if sv:
            L.append("Whitened singular values: " + ", ".join(_f(v, ".3g") for v in sv)
                     + ".\n")
    dset = report.get("declared_set")
    if dset:
        excl = dset.get("excluded") or {}
        tol = {r["name"]: r for r in dset.get("values", [])}
        L.append("### The declared set\n")
        L.append(f"Every numeric value of the description is a declared value "
                 f"({len(tol)}); each carries a datasheet tolerance by kind of quantity, "
                 "or the one stated in `[calibration.tolerances]`. Screened above: "
                 f"{len(tol) - len(excl)}. Not screened ({len(excl)}):\n")
        rows = [[f"`{n}`", _f(tol.get(n, {}).get("value"), ".4g"),
                 tol.get(n, {}).get("kind", "—"), why] for n, why in excl.items()]
        if rows:
            L.append(_md_table(["value", "described", "kind", "why not fitted"], rows) + "\n")
        stated = [r for r in tol.values() if r.get("tolerance_source", "").startswith("[")]
        if stated:
            L.append("Tolerances stated by the user: " + ", ".join(
                f"`{r['name']}` ±{100 * r['tolerance']:.3g} %" for r in stated) + ".\n")

    # ---- declared parameters beyond their datasheet tolerance
    devs = report.get("declared_deviations")
    if devs:
        L.append("## Declared parameters beyond their datasheet tolerance\n")
        missing = [d for d in devs if d.get("explains_record") is False]
        if missing:
            worst = missing[0].get("final_worst_ratio")
            L.append("A fitted datasheet value outside its tolerance (by more than 3 standard "
                     "errors) in a model that still misses the record "
                     + (f"(worst channel {worst:.3g}× its noise floor) "
                        if isinstance(worst, (int, float)) else "")
                     + "names nothing: the fit bent these values toward what the model "
                     "lacks. Read them as part of the unexplained residual, not as wrong "
                     "datasheet values nor as the effects listed beside them.\n")
        else:
            L.append("A fitted datasheet value outside its tolerance (by more than 3 "
                     "standard errors) is either a wrong datasheet value or an effect that "
                     "acts exactly like it; the record cannot separate the two.\n")
        rows = [[f"`{d['parameter']}`", _f(d.get("datasheet")), _f(d.get("fitted")),
                 _signed_pct(d.get("relative_change")), f"±{100 * d['tolerance']:.0f} %",
                 ", ".join(d.get("equivalent_to") or []) or "—"] for d in devs]
        L.append(_md_table(["parameter", "datasheet", "fitted", "change", "tolerance",
                            "indistinguishable from"], rows) + "\n")

    # ---- data-driven discrepancy (afo_mj.calibration.discrepancy)
    disc = report.get("data_driven_discrepancy")
    if disc:
        L.append("## Data-driven discrepancy (not a physical effect)\n")
        L.append("No effect of the library explains the residual. A sparse regression of each "
                 "channel's residual on terms of the model's outputs and the inputs, or a "
                 "second-order reading of the channel's model output (ω_n, ζ), fitted on "
                 "the training part and chosen on the held-out part, describes what is "
                 "missing; it is a correlation in the data, not a named mechanism.\n")
        rows = []
        for ch, r in disc.items():
            if not isinstance(r, Mapping):
                continue
            rows.append([f"`{ch}`", (r.get("expression") or "—") if r.get("found") else
                         "within the noise" if r.get("within_noise") else
                         "no sparse term predicts the held-out residual",
                         _pct(r.get("held_out_gain")) if r.get("found") else "—"])
        if rows:
            L.append(_md_table(["channel", "discrepancy", "held-out gain [%]"], rows) + "\n")

    # ---- held-out error
    L.append("## Held-out error\n")
    L.append("NRMSE = RMS(measured − model) on the held-out part / SD of the channel over the "
             "whole record, in %. *Preset*: the preset's values, no effect; *declared fit*: "
             "the declared parameters fitted on the training part (before); *after*: with the "
             "selected effects.\n")
    eb, ea, ep = (report.get(k) or {} for k in ("error_before", "error_after", "error_preset"))
    rows = []
    for ch in outputs + ["overall"]:
        b, a = eb.get(ch), ea.get(ch)
        change = (a / b - 1.0) if isinstance(a, (int, float)) and isinstance(b, (int, float)) \
            and b > 0 else None
        rows.append([f"**{ch}**" if ch == "overall" else f"`{ch}`",
                     _pct(ep.get(ch)), _pct(b), _pct(a), _signed_pct(change)])
    L.append(_md_table(["channel", "preset [%]", "declared fit [%]", "after [%]", "change"],
                       rows) + "\n")
    if report.get("skipped_outputs"):
        L.append("Output channels of the record the replay does not produce (not fitted): "
                 + ", ".join(f"`{c}`" for c in report["skipped_outputs"]) + ".\n")

    # ---- effects selected
    L.append("## Effects selected\n")
    effects = list(report.get("effects_selected") or [])
    if not effects:
        L.append("None: no candidate paid for itself (BIC, held-out error and "
                 "identifiability together).\n")
    for i, e in enumerate(effects, 1):
        L.append(f"### {i}. `{e.get('effect')}` ({e.get('component')})\n")
        L.append(f"Equation: `{e.get('equation')}`  \nReference: {e.get('reference')}\n")
        sd = e.get("uncertainties") or {}
        prow = [[f"`{k}`", _f(v), _f(sd.get(k), ".2g"), _unit_of(k, units)]
                for k, v in (e.get("parameters") or {}).items()]
        L.append(_md_table(["parameter", "value", "± 1 SD", "unit"], prow) + "\n")
        drop = e.get("held_out_drop")
        L.append(f"Held-out NRMSE (overall) {_pct(e.get('held_out_before'))} % → "
                 f"{_pct(e.get('held_out_after'))} % "
                 f"({_signed_pct(-drop) if isinstance(drop, (int, float)) else '—'})"
                 + (f"; in units of each channel's noise "
                    f"{_signed_pct(-e['held_out_drop_noise_units'])}"
                    if isinstance(e.get("held_out_drop_noise_units"), (int, float)) else "")
                 + (f" (pays in: {', '.join(e['pays_in'])})" if e.get("pays_in") else "")
                 + f"; ΔBIC {_f(e.get('delta_bic'), '.1f')}, "
                 f"ΔAIC {_f(e.get('delta_aic'), '.1f')} "
                 "(negative: the effect pays for its parameters).\n")

    # ---- fitted parameters
    L.append("## Fitted parameters\n")
    declared_fit = report.get("declared_fit") or {}
    params = report.get("parameters") or {}
    psd = report.get("parameter_sd") or {}
    names = list(declared_fit) + [k for k in params if k not in declared_fit]
    prow = [[f"`{k}`", _f(declared_fit.get(k)), _f(params.get(k)), _f(psd.get(k), ".2g"),
             _unit_of(k, units)] for k in names]
    L.append("*Declared fit*: the declared model fitted alone; *final*: fitted together with "
             "the selected effects, ± 1 SD from the Gauss–Newton covariance. SI units.\n")
    L.append(_md_table(["parameter", "declared fit", "final", "± 1 SD", "unit"], prow) + "\n")
    if report.get("declared_effects"):
        L.append("Effects declared by the user (in the model from the start): "
                 + ", ".join(f"`{n}`" for n in report["declared_effects"]) + ".\n")

    # ---- candidates
    L.append("## Candidates\n")
    L.append("Score: the fraction of the training residual's |r|² the effect's linearised "
             "change explains beyond the declared parameters (best over the rounds). The top "
             "candidates were refitted in the full model; an effect *pays* when ΔBIC falls "
             "enough, the held-out error drops enough (on a described rig: the overall NRMSE "
             "or the error in units of each channel's noise; the score is the larger of the "
             "two units' too) and its parameters are identifiable.\n")
    cands = report.get("candidates") or {}
    order = sorted(cands.items(), key=lambda kv: -float(kv[1].get("best_score") or 0.0))
    crow = []
    for name, c in order:
        r = _best_refit(c)
        err = c.get("refit_error")
        crow.append([f"`{name}`", _f(c.get("best_score"), ".3g"),
                     _signed_pct(-r["held_out_drop"]) if r and isinstance(
                         r.get("held_out_drop"), (int, float)) else "—",
                     _f(r.get("delta_bic"), ".1f") if r else "—",
                     ("yes" if r.get("identifiable") else "no") if r else "—",
                     ("yes" if r.get("pays") else "no") if r else
                     ("refit failed" if err else "not refitted"),
                     "**yes**" if c.get("selected") else ""])
    if crow:
        L.append(_md_table(["effect", "best score", "refit held-out change", "ΔBIC",
                            "identifiable", "pays", "selected"], crow) + "\n")
    else:
        L.append("No candidate was ranked.\n")
    for name, c in order:
        r = _best_refit(c)
        if not r or "beats_generic" not in r:
            continue
        g = r.get("generic") or {}
        why = []
        if r.get("at_bound"):
            why.append("fitted at a library bound: " + "; ".join(r["at_bound"]))
        if not r.get("beats_generic"):
            why.append(f"a generic gain on `{g.get('channel')}` with as many parameters cuts "
                       f"the held-out error as much ({_signed_pct(-g.get('held_out_drop', 0))})")
        if why:
            L.append(f"- `{name}` does not earn its name: " + "; ".join(why) + ".")
            L.append("")
    errs = [(n, c["refit_error"]) for n, c in order if c.get("refit_error")]
    for n, msg in errs:
        L.append(f"- refit of `{n}` failed: {msg}")
    if errs:
        L.append("")

    # ---- whiteness
    L.append("## Residual whiteness (held-out part)\n")
    L.append("Ljung–Box p-value of the (block-averaged) residual: white when p > 0.01; excess "
             "= RMS(residual)/sensor-noise σ (≈ 1 when the residual is only noise). "
             f"Structured: not white and excess > {_EXCESS:g}.\n")
    wb = report.get("residual_whiteness_before") or {}
    wa = report.get("residual_whiteness_after") or {}
    cb = report.get("channels_before") or {}
    ca = report.get("channels_after") or {}
    wrow = []
    for ch in outputs or list(wb):
        b, a = wb.get(ch) or {}, wa.get(ch) or {}

        def st(summ):
            s = summ.get(ch) or {}
            return "—" if "structured" not in s else ("yes" if s["structured"] else "no")
        wrow.append([f"`{ch}`", _f(b.get("p_value"), ".3g"), _f(b.get("excess_ratio"), ".2f"),
                     st(cb), _f(a.get("p_value"), ".3g"), _f(a.get("excess_ratio"), ".2f"),
                     st(ca)])
    L.append(_md_table(["channel", "p before", "excess before", "structured before",
                        "p after", "excess after", "structured after"], wrow) + "\n")

    # ---- windows, noise
    L.append("## Windows and noise\n")
    tw, hw = report.get("train_window_s") or [None, None], \
        report.get("held_out_window_s") or [None, None]
    L.append(f"- training: {_f(tw[0], '.3f')} … {_f(tw[1], '.3f')} s (after "
             f"{_f(report.get('settle_s'), '.3g')} s of settling, left out of every error)")
    L.append(f"- held out: {_f(hw[0], '.3f')} … {_f(hw[1], '.3f')} s (split by "
             f"{report.get('split_by', '?')}; never fitted)")
    L.append("- inputs: " + ", ".join(f"`{c}`" for c in report.get("inputs") or []))
    L.append(f"- model evaluations: {report.get('evaluations', '—')}, wall time "
             f"{_f(report.get('wall_time_s'), '.1f')} s")
    L.append("")
    noise = report.get("noise_sigma") or {}
    L.append(_md_table(["channel", "noise σ", "unit"],
                       [[f"`{c}`", _f(v), _channel_unit(c)] for c, v in noise.items()]) + "\n")

    # ---- figures
    L.append("## Figures\n")
    if figures:
        cap = {"fit_before_after.png": "Measured vs model before and after (held-out part "
                                       "shaded)",
               "residual_before_after.png": "Held-out residual before and after, ±2σ noise",
               "residual_spectrum.png": "Welch PSD of the held-out residual before and after"}
        for f in figures:
            L.append(f"![{cap.get(f, f)}]({f})\n")
    else:
        L.append("None: the report carries no time series (`_series`).\n")
    return "\n".join(L).rstrip() + "\n"


# --------------------------------------------------------------------------- figures

def _figure(figsize):
    import matplotlib
    matplotlib.use("Agg", force=False)
    from matplotlib.figure import Figure
    return Figure(figsize=figsize, layout="constrained")


def _display(ch: str) -> tuple[float, str]:
    """Scale and unit a channel is drawn in (pressures in MPa, the rest in SI)."""
    unit = _channel_unit(ch)
    if unit == "Pa":
        return 1e-6, "MPa"
    return 1.0, unit


def _stride(n: int) -> int:
    return max(1, -(-n // MAX_PLOT_POINTS))


def _series(report: Mapping) -> dict | None:
    """The validated ``_series`` (finite 1-D arrays of one length), or None without one."""
    s = report.get("_series")
    if s is None:
        return None
    if not isinstance(s, Mapping):
        raise ValueError(f"calibration report: _series is a {type(s).__name__}; allowed: the "
                         "dict calibrate returns")
    t = np.asarray(s.get("time_s"), dtype=float)
    if t.ndim != 1 or t.size < 16 or not np.all(np.isfinite(t)) or not np.all(np.diff(t) > 0):
        raise ValueError("calibration report: _series.time_s must be a strictly increasing, "
                         "finite 1-D array of at least 16 samples")
    i_cut = s.get("i_cut")
    if isinstance(i_cut, bool) or not isinstance(i_cut, (int, np.integer)) \
            or not 0 < int(i_cut) <= t.size - 8:
        raise ValueError(f"calibration report: _series.i_cut = {i_cut!r}; allowed: an integer "
                         f"1 … {t.size - 8} (first held-out sample, ≥ 8 held-out samples)")
    out = {"time_s": t, "i_cut": int(i_cut)}
    outputs = list(report.get("outputs") or s.get("measured", {}).keys())
    for part in ("measured", "before", "after"):
        group = s.get(part)
        if not isinstance(group, Mapping):
            raise ValueError(f"calibration report: _series.{part} is missing; allowed: a dict "
                             "channel → array")
        out[part] = {}
        for ch in outputs:
            if ch not in group:
                raise ValueError(f"calibration report: _series.{part} has no channel {ch!r}")
            a = np.asarray(group[ch], dtype=float)
            if a.shape != t.shape:
                raise ValueError(f"calibration report: _series.{part}[{ch!r}] has shape "
                                 f"{a.shape}; allowed: {t.shape} (as time_s)")
            if not np.all(np.isfinite(a)):
                raise ValueError(f"calibration report: _series.{part}[{ch!r}] holds a "
                                 "non-finite value; allowed: finite numbers")
            out[part][ch] = a
    out["outputs"] = outputs
    return out


_STYLE = {"measured": dict(color="0.25", lw=0.8, label="measured"),
          "before": dict(color="C3", lw=1.0, label="model before (declared fit)"),
          "after": dict(color="C0", lw=1.0, label="model after (with selected effects)")}


def _plot_fit(path: Path, s: dict, report: Mapping) -> None:
    t, k = s["time_s"], s["i_cut"]
    t_cut = t[k]
    i0 = int(np.searchsorted(t, t_cut - CONTEXT_S))
    sl = slice(i0, None, _stride(t.size - i0))
    chans = s["outputs"]
    fig = _figure((10.0, 1.0 + 2.1 * len(chans)))
    axes = np.atleast_1d(fig.subplots(len(chans), 1, sharex=True, squeeze=False)[:, 0])
    for ax, ch in zip(axes, chans):
        scale, unit = _display(ch)
        for part in ("measured", "before", "after"):
            ax.plot(t[sl], scale * s[part][ch][sl], **_STYLE[part])
        ax.axvspan(t_cut, t[-1], color="C2", alpha=0.07, lw=0)
        ax.axvline(t_cut, color="C2", lw=1.0, ls="--")
        ax.set_ylabel(f"{ch}\n[{unit}]", fontsize="small")
        ax.grid(True, color="0.92", lw=0.5)
    axes[0].legend(fontsize="small", loc="upper left", ncols=3)
    axes[-1].set_xlabel("time [s] (shaded: held-out part, never fitted)")
    axes[-1].set_xlim(t[i0], t[-1])
    fig.suptitle(f"Calibration of {report.get('preset', '?')}: measured vs model, last "
                 f"{min(CONTEXT_S, t_cut - t[i0]):.1f} s of training and the held-out part")
    fig.savefig(path, dpi=_DPI)


def _plot_residuals(path: Path, s: dict, report: Mapping) -> None:
    t, k = s["time_s"], s["i_cut"]
    sl = slice(k, None, _stride(t.size - k))
    chans = s["outputs"]
    noise = report.get("noise_sigma") or {}
    fig = _figure((10.0, 1.0 + 2.1 * len(chans)))
    axes = np.atleast_1d(fig.subplots(len(chans), 1, sharex=True, squeeze=False)[:, 0])
    for ax, ch in zip(axes, chans):
        scale, unit = _display(ch)
        y = s["measured"][ch]
        for part in ("before", "after"):
            st = dict(_STYLE[part])
            st["label"] = f"residual {part}"
            ax.plot(t[sl], scale * (y - s[part][ch])[sl], **st)
        sig = noise.get(ch)
        if isinstance(sig, (int, float, np.floating)) and np.isfinite(sig) and sig > 0:
            for sgn in (1.0, -1.0):
                ax.axhline(sgn * 2.0 * scale * float(sig), color="0.4", lw=0.8, ls="--",
                           label="±2σ sensor noise" if sgn > 0 else None)
        ax.axhline(0.0, color="0.7", lw=0.5)
        ax.set_ylabel(f"{ch}\nmeasured − model [{unit}]", fontsize="small")
        ax.grid(True, color="0.92", lw=0.5)
    axes[0].legend(fontsize="small", loc="upper left", ncols=3)
    axes[-1].set_xlabel("time [s] (held-out part)")
    axes[-1].set_xlim(t[k], t[-1])
    fig.suptitle("Held-out residual before and after the selected effects")
    fig.savefig(path, dpi=_DPI)


def _plot_spectrum(path: Path, s: dict, report: Mapping) -> None:
    from afo_mj.calibration.residual_analysis import residual_spectrum
    t, k = s["time_s"], s["i_cut"]
    fs = 1.0 / float(np.median(np.diff(t)))
    chans = s["outputs"]
    noise = report.get("noise_sigma") or {}
    fig = _figure((10.0, 1.0 + 2.1 * len(chans)))
    axes = np.atleast_1d(fig.subplots(len(chans), 1, sharex=True, squeeze=False)[:, 0])
    for ax, ch in zip(axes, chans):
        scale, unit = _display(ch)
        y = s["measured"][ch][k:]
        for part in ("before", "after"):
            f, p = residual_spectrum(y - s[part][ch][k:], fs)
            p = p * scale ** 2
            keep = (f > 0) & (p > 0)
            st = dict(_STYLE[part])
            st["label"] = f"residual {part}"
            if np.any(keep):
                ax.loglog(f[keep], p[keep], **st)
        sig = noise.get(ch)
        if isinstance(sig, (int, float, np.floating)) and np.isfinite(sig) and sig > 0:
            ax.axhline(2.0 * (scale * float(sig)) ** 2 / fs, color="0.4", lw=0.8, ls="--",
                       label="white sensor noise 2σ²/fs")
        ax.set_yscale("log")
        ax.set_ylabel(f"{ch}\nPSD [{unit}²/Hz]", fontsize="small")
        ax.grid(True, color="0.92", lw=0.5, which="both")
    axes[0].legend(fontsize="small", loc="upper right", ncols=3)
    axes[-1].set_xlabel("frequency [Hz] (Welch, Hann, 50 % overlap; held-out part)")
    df = fs / min(1024, t.size - k)               # Welch bin width
    axes[-1].set_xlim(df, fs / 2.0)
    fig.suptitle("Spectrum of the held-out residual before and after")
    fig.savefig(path, dpi=_DPI)


_PLOTTERS = {"fit_before_after.png": _plot_fit,
             "residual_before_after.png": _plot_residuals,
             "residual_spectrum.png": _plot_spectrum}


# --------------------------------------------------------------------------- writer

def calibration_document(report: Mapping, data_path=None,
                         command: str | None = None) -> CalibrationReport:
    """The :class:`~afo_mj.calibration.report_document.CalibrationReport` (what
    ``report.json`` holds) of a :func:`afo_mj.calibration.calibrate.calibrate` report: its
    ``"_series"`` left out, numbers made plain (:func:`to_jsonable`: ValueError naming the
    key path for a NaN or infinity), a malformed headline refused
    (:class:`~afo_mj.calibration.report_document.DocumentError`, a ValueError)."""
    if not isinstance(report, Mapping):
        raise ValueError(f"report is a {type(report).__name__}; allowed: the dict calibrate "
                         "returns")
    body = to_jsonable({k: v for k, v in report.items() if k != "_series"})
    return CalibrationReport.from_report(body, data_path, command)


def write_calibration_report(report: dict, out_dir, data_path=None,
                             command: str | None = None) -> dict[str, Path]:
    """Write ``report.json``, ``report.md`` and the figures (:data:`FIGURES`, when the report
    carries ``"_series"``) of a :func:`afo_mj.calibration.calibrate.calibrate` report into
    ``out_dir``, all at once (module docstring). Returns file name → path.

    Raises ValueError (naming the key path) for a NaN/infinite number in the report or a
    malformed ``_series``; then nothing is written."""
    if not isinstance(report, Mapping):
        raise ValueError(f"report is a {type(report).__name__}; allowed: the dict calibrate "
                         "returns")
    if command is not None and not isinstance(command, str):
        raise ValueError(f"command = {command!r}; allowed: a str or None")
    doc = calibration_document(report, data_path, command).to_json()
    text = json.dumps(doc, indent=2, allow_nan=False, ensure_ascii=False) + "\n"
    series = _series(report)
    figures = FIGURES if series is not None else ()
    md = render_markdown(doc, figures)

    def writer(tmp: Path) -> None:
        (tmp / "report.json").write_text(text, encoding="utf-8")
        (tmp / "report.md").write_text(md, encoding="utf-8")
        for name in figures:
            _PLOTTERS[name](tmp / name, series, doc)

    out = write_atomically(out_dir, writer)
    names = ("report.json", "report.md") + figures
    return {n: out / n for n in names}
