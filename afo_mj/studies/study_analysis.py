"""The analysis of a parameter study: ranking, Pareto front, sensitivity indices (nothing
written; the report's files are :mod:`afo_mj.outputs.study_report`).

Reads a sweep directory of ``afo-mj sweep`` (:mod:`afo_mj.studies.sweep`): ``study.json`` and
``results.parquet`` / ``results.csv`` (one row per run: ``order``, ``run_id``, ``status``,
``exit_code``, ``error``, ``wall_time_s``, ``param:<key>`` inputs and the run's flattened
``summary.json``). :func:`analyse_study` computes what
:func:`afo_mj.outputs.study_report.write_study_report` writes into ``DIR/study/`` (all files
at once, :func:`afo_mj.outputs.result_dir.write_atomically`):

* ``ranking.txt`` -- every run ranked by the metric, with its parameter values; runs without
  a value (failed runs, with their error, and successful runs whose metric is missing) after;
* ``summary.json`` -- the metric and its direction, the best run, the top runs, the Pareto
  front (device studies), the sensitivity indices or why there are none, the failed runs and
  the figures (finite numbers only: NaN is written as null);
* the figures of :func:`afo_mj.outputs.study_figures.plot_study`.

Metrics. Every metric is a column of the results table (a dotted ``summary.json`` path).
:func:`default_metric` picks, for device studies (runs with ``device_conditions.*``), the
change of the human (muscle) ankle positive work per stride of the headline condition vs no
device, ``comparison_vs_no_device.<cond>.human_ankle_positive_work_change_j_per_stride``
(J/stride, smaller = more work taken off the muscles) — on the muscle walker the wearer's net
metabolic rate change ``comparison_vs_no_device.<cond>.net_metabolic_umberger_change_pct``
(%) first — or, without a no-device condition,
``human.ankle_positive_work_j_per_stride``; for walk studies ``ankle_angle_rms_error_deg.mean``
(deg, the ankle angle's RMS error against the reference). The headline condition is the one
``afo-mj run`` writes out (the last of ``device.conditions``), recognised as the condition
whose ``device_conditions.<cond>.human.ankle_positive_work_j_per_stride`` equals the top-level
``human.ankle_positive_work_j_per_stride``.

A study whose runs name their headline condition differently (a sweep of
``assistance.stiffnesses_nm_per_deg = [K]`` runs condition ``assist_k<K>``, one name per run)
gets, for every ``device_conditions.<cond>.*`` and ``comparison_vs_no_device.<cond>.*``
column, a ``<prefix>.headline.*`` column holding each run's own headline condition's value
(:func:`add_headline_columns`), so its runs rank, and form a Pareto front, on one metric.

Pareto front (device studies, :func:`pareto_metrics`), both minimised: x = the wearer's net
metabolic rate change (muscle walker) or else the human ankle positive work change vs no
device (above; more negative is better) and y =
``device_conditions.<cond>.energy_per_stride.electrical_in_j``, the summary's own electrical
energy per stride (J/stride): the whole run's electrical energy drawn from the battery times
the mean analysed stride time over the run duration (start-up strides included in the
ledger), not derived here.

Sensitivity (:func:`sensitivity`): Sobol' first-order and total indices (S1, ST with their
bootstrap confidence intervals; :func:`SALib.analyze.sobol.analyze`, second order not
computed) for a ``saltelli`` design, Morris mu*, mu, sigma (:func:`SALib.analyze.morris.analyze`)
for a ``morris`` design; other designs (grid, random, LHS, Sobol' points) do not support them.
The sweep's ``order`` is the order runs finished in, not the design's, so the design is
regenerated from ``study.json`` (the same SALib sampling with the same seed as
:meth:`afo_mj.studies.study.Study.points`) and each design point is matched to its row by
parameter values. Sobol' indices need every run of the design: if any design point has no
successful run with a finite metric, they are not computed and the report says how many
are missing. Morris trajectories with a missing run are dropped (at least 2 complete
trajectories are needed).
"""

from __future__ import annotations

import difflib
import json
import math
import warnings
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from afo_mj.studies.metric_labels import label_of

__all__ = ["load_results", "ranked_table", "default_metric", "pareto_front", "pareto_metrics",
           "sensitivity", "sensitivity_note", "analyse_study", "metric_columns",
           "check_metric", "headline_condition", "add_headline_columns", "HEADLINE",
           "StudyReportError", "FORMAT",
           "MAXIMISE_HINTS", "REPORT_DIR", "jsonable"]

#: ``summary.json``'s ``"format"``.
FORMAT = "afo_mj study report v1"
#: Where :func:`afo_mj.outputs.study_report.write_study_report` writes, inside the sweep directory.
REPORT_DIR = "study"
#: Metrics whose name contains one of these are ranked largest first by default.
MAXIMISE_HINTS = ("efficiency", "battery_runtime", "within_1sd_fraction", "completed_strides")

_FIXED = ("order", "run_id", "status", "exit_code", "error", "wall_time_s")
_CHANGE = "human_ankle_positive_work_change_j_per_stride"
#: on the muscle walker the wearer's effort: net metabolic rate change vs no device (%)
_METABOLIC = "net_metabolic_umberger_change_pct"
_CMP = "comparison_vs_no_device."
_DC = "device_conditions."
_HUMAN = "human.ankle_positive_work_j_per_stride"
_EPS = "energy_per_stride.electrical_in_j"
_WALK_METRICS = ("ankle_angle_rms_error_deg.mean", "gait.ankle_angle_rms_error_deg.mean")
_PRINT_TOP = 10
#: the condition name of the per-run headline columns (:func:`add_headline_columns`)
HEADLINE = "headline"


class StudyReportError(ValueError):
    """A sweep directory that cannot be reported on (missing study.json or results)."""


# --------------------------------------------------------------------------- loading

def load_results(out_dir) -> tuple[dict, pd.DataFrame]:
    """``(study, rows)`` of a sweep directory: ``study.json`` as a dict and the results table
    as a DataFrame in run order. Reads ``results.parquet`` or ``results.csv`` (the newer when
    both are there), or the per-run ``rows/*.json`` when there is no table yet.
    Raises :class:`StudyReportError` when the directory holds no sweep."""
    d = Path(out_dir)
    meta = d / "study.json"
    if not meta.is_file():
        raise StudyReportError(f"{d}: no study.json (not a sweep directory of afo-mj sweep)")
    try:
        study = json.loads(meta.read_text(encoding="utf-8"))
    except (OSError, ValueError) as exc:
        raise StudyReportError(f"{meta}: unreadable ({exc})") from None
    tables = [p for p in (d / "results.parquet", d / "results.csv") if p.is_file()]
    if tables:
        path = max(tables, key=lambda p: p.stat().st_mtime)
        try:
            if path.suffix == ".parquet":
                df = pd.read_parquet(path)
            else:
                df = pd.read_csv(path, dtype={"run_id": str, "status": str, "error": str},
                                 keep_default_na=True)
                for c in ("run_id", "status", "error"):
                    if c in df.columns:
                        df[c] = df[c].astype(object).where(df[c].notna(), "").astype(str)
        except Exception as exc:                    # noqa: BLE001 - any reader error
            raise StudyReportError(f"{path}: unreadable results table ({exc})") from None
    else:
        from afo_mj.studies.sweep import read_rows
        rows = read_rows(d)
        if not rows:
            raise StudyReportError(f"{d}: no results.parquet, results.csv or rows/ "
                                   "(has the sweep run?)")
        df = pd.DataFrame(rows)
    if "status" not in df.columns:
        df["status"] = "ok"
    df["status"] = df["status"].fillna("failed").astype(str)
    if "order" in df.columns:
        df = df.sort_values("order", kind="stable")
    return study, add_headline_columns(df.reset_index(drop=True))


def _ok(df: pd.DataFrame) -> np.ndarray:
    return (df["status"].astype(str) == "ok").to_numpy()


def _values(df: pd.DataFrame, col: str) -> np.ndarray:
    """A column as floats (booleans as 0/1, text as NaN)."""
    s = df[col]
    if s.dtype == bool:
        return s.to_numpy(float)
    if s.dtype == object:
        s = s.map(lambda v: {"True": 1.0, "False": 0.0}.get(v, v) if isinstance(v, str) else v)
    return pd.to_numeric(s, errors="coerce").to_numpy(float)


def metric_columns(df: pd.DataFrame) -> list[str]:
    """The metric columns: everything but the fixed columns and the ``param:`` inputs."""
    return [c for c in df.columns if c not in _FIXED and not str(c).startswith("param:")]


def _param_columns(study: dict, df: pd.DataFrame) -> list[str]:
    cols = ["param:" + p["key"] for p in study.get("parameters", [])
            if "param:" + p["key"] in df.columns]
    return cols + [c for c in df.columns if str(c).startswith("param:") and c not in cols]


def check_metric(df: pd.DataFrame, metric: str) -> str:
    """``metric`` if it is a numeric metric column; ValueError naming it and the closest
    metric names otherwise."""
    names = metric_columns(df)
    if metric not in df.columns or metric not in names:
        close = difflib.get_close_matches(metric, names, n=6, cutoff=0.5)
        leaf = str(metric).split(".")[-1]
        close += [n for n in names if leaf and leaf in n and n not in close][:6 - len(close)]
        hint = (f"close names: {', '.join(close)}" if close else
                f"no close name among the {len(names)} metric columns"
                + (f" (e.g. {', '.join(names[:5])})" if names else ""))
        raise ValueError(f"unknown metric {metric!r}; {hint}")
    present = df[metric].notna().to_numpy()
    if np.any(present) and not np.any(present & ~np.isnan(_values(df, metric))):
        raise ValueError(f"metric {metric!r} is not numeric (values such as "
                         f"{df[metric].dropna().iloc[0]!r})")
    return metric


def _maximise(metric: str) -> bool:
    return any(h in metric for h in MAXIMISE_HINTS)


# --------------------------------------------------------------------------- metrics

def _conditions(df: pd.DataFrame, suffix: str, prefix: str = _DC) -> list[str]:
    """Condition names ``c`` of the columns ``<prefix><c>.<suffix>`` (names may hold dots)."""
    out = []
    for c in df.columns:
        c = str(c)
        if c.startswith(prefix) and c.endswith("." + suffix):
            name = c[len(prefix):-len(suffix) - 1]
            if name:
                out.append(name)
    return out


def headline_condition(df: pd.DataFrame) -> str | None:
    """The condition ``afo-mj run`` wrote out at the top level of the summaries (None for a
    walk study): the device condition whose human ankle work equals the top-level one in the
    successful runs; ``assist`` (or the last condition) when that cannot be told."""
    conds = _conditions(df, "human.ankle_positive_work_j_per_stride")
    if not conds:
        return None
    ok = _ok(df)
    if _HUMAN in df.columns and np.any(ok):
        top = _values(df, _HUMAN)[ok]
        score = {}
        for c in conds:
            v = _values(df, f"{_DC}{c}.human.ankle_positive_work_j_per_stride")[ok]
            both = np.isfinite(top) & np.isfinite(v)
            score[c] = int(np.sum(both & np.isclose(top, v, rtol=1e-12, atol=0.0)))
        best = max(score.values())
        if best > 0:
            tied = [c for c in conds if score[c] == best]
            return "assist" if "assist" in tied else tied[-1]
    non_base = [c for c in conds if c != "no_device"]
    if "assist" in non_base:
        return "assist"
    return (non_base or conds)[-1]


def _row_headlines(df: pd.DataFrame, conds: list[str]) -> list[str | None]:
    """Each run's headline condition: of the conditions with a value in its row, the one
    whose human ankle work equals the top-level one (``assist`` among ties), else the last
    one that is not ``no_device``; None for a row without any (a failed run)."""
    work = {c: _values(df, f"{_DC}{c}.human.ankle_positive_work_j_per_stride") for c in conds}
    present = {c: np.zeros(len(df), bool) for c in conds}
    for col in df.columns:
        col = str(col)
        c = _condition_of(col, _DC, conds)
        if c is not None:
            present[c] |= np.isfinite(_values(df, col))
    top = _values(df, _HUMAN) if _HUMAN in df.columns else np.full(len(df), np.nan)
    out: list[str | None] = []
    for i in range(len(df)):
        have = [c for c in conds if present[c][i]]
        same = [c for c in have if np.isfinite(top[i]) and np.isfinite(work[c][i])
                and np.isclose(top[i], work[c][i], rtol=1e-12, atol=0.0)]
        rest = [c for c in have if c != "no_device"]
        out.append(("assist" if "assist" in same else same[-1]) if same
                   else rest[-1] if rest else None)
    return out


def _condition_of(col: str, prefix: str, conds: list[str]) -> str | None:
    """The condition of column ``<prefix><cond>.<rest>`` (the longest of ``conds`` that
    fits: names such as ``assist_k2.5`` hold dots), or None."""
    if not col.startswith(prefix):
        return None
    fits = [c for c in conds if col.startswith(f"{prefix}{c}.")]
    return max(fits, key=len) if fits else None


def add_headline_columns(df: pd.DataFrame) -> pd.DataFrame:
    """``df`` with ``device_conditions.headline.*`` and ``comparison_vs_no_device.headline.*``
    columns (each run's value of its own headline condition) when the successful runs'
    headline conditions differ (module docstring); ``df`` unchanged otherwise."""
    conds = [c for c in _conditions(df, "human.ankle_positive_work_j_per_stride")
             if c != HEADLINE]
    if len(conds) < 2 or any(str(c).startswith((f"{_DC}{HEADLINE}.", f"{_CMP}{HEADLINE}."))
                             for c in df.columns):
        return df
    heads = _row_headlines(df, conds)
    ok = _ok(df)
    if len({h for h, good in zip(heads, ok) if good and h is not None}) < 2:
        return df
    new: dict[str, np.ndarray] = {}
    for prefix in (_DC, _CMP):
        for col in df.columns:
            col = str(col)
            c = _condition_of(col, prefix, conds)
            if c is None:
                continue
            name = f"{prefix}{HEADLINE}.{col[len(prefix) + len(c) + 1:]}"
            if name not in new:
                new[name] = np.full(len(df), np.nan)
            rows = np.array([h == c for h in heads])
            new[name][rows] = _values(df, col)[rows]
    return pd.concat([df, pd.DataFrame(new, index=df.index)], axis=1)


def _has_finite_ok(df: pd.DataFrame, col: str) -> bool:
    return col in df.columns and bool(np.any(np.isfinite(_values(df, col)[_ok(df)])))


def metric_spread(values) -> dict:
    """``n``, ``mean``, ``sd`` (sample, ``n − 1``; None below two values), ``min`` and ``max``
    of the finite ``values``: how far the runs of a study spread on its metric, which is what
    an effect has to exceed (e.g. the spread between seeds of one adapted wearer)."""
    x = np.asarray(values, dtype=float)
    x = x[np.isfinite(x)]
    n = int(x.size)
    if n == 0:
        return {"n": 0, "mean": None, "sd": None, "min": None, "max": None}
    return {"n": n, "mean": float(np.mean(x)),
            "sd": float(np.std(x, ddof=1)) if n >= 2 else None,
            "min": float(np.min(x)), "max": float(np.max(x))}


def default_metric(df: pd.DataFrame) -> str:
    """A sensible ranking metric (smaller is better). Device studies: on the muscle walker the
    wearer's net metabolic rate change vs no device of the headline condition (%, Umberger
    2010: the field ranks assistance by it), else that condition's human ankle positive work
    change vs no device (J/stride), else the human ankle positive work per stride; walk
    studies: the ankle angle RMS error (deg). Raises ValueError when the table has none of
    them with a value."""
    head = headline_condition(df)
    tried = []
    if head is not None:
        tried += [f"{_CMP}{head}.{_METABOLIC}", f"{_CMP}{head}.{_CHANGE}", _HUMAN,
                  f"{_DC}{head}.human.ankle_positive_work_j_per_stride"]
    tried += list(_WALK_METRICS)
    for m in tried:
        if _has_finite_ok(df, m):
            return m
    raise ValueError("no default metric: none of " + ", ".join(tried) + " has a value in a "
                     "successful run; name one (--metric)")


def pareto_metrics(df: pd.DataFrame) -> tuple[str, str] | None:
    """The Pareto axes of a device study, both minimised: (the wearer's net metabolic rate
    change vs no device, % (muscle walker), or else the human ankle positive work change vs
    no device, J/stride; electrical energy drawn per stride, J/stride) of the headline
    condition; None when the table does not have both (walk study, no ``no_device``)."""
    head = headline_condition(df)
    if head is None:
        return None
    y = f"{_DC}{head}.{_EPS}"
    for x in (f"{_CMP}{head}.{_METABOLIC}", f"{_CMP}{head}.{_CHANGE}"):
        if x in df.columns and y in df.columns and _has_finite_ok(df, x):
            return x, y
    return None


def pareto_front(df: pd.DataFrame, x_metric: str, y_metric: str) -> pd.DataFrame:
    """The non-dominated successful runs (rows of ``df``), both metrics minimised, sorted by
    ``x_metric``. A run is dominated when another is no worse in both and better in one;
    runs with equal values are all kept. Runs without both values are left out."""
    check_metric(df, x_metric)
    check_metric(df, y_metric)
    x, y = _values(df, x_metric), _values(df, y_metric)
    idx = np.flatnonzero(_ok(df) & np.isfinite(x) & np.isfinite(y))
    order = idx[np.lexsort((y[idx], x[idx]))]
    keep = []
    best_y, last = math.inf, None
    for i in order:
        if y[i] < best_y:
            keep.append(i)
            best_y, last = y[i], (x[i], y[i])
        elif last is not None and x[i] == last[0] and y[i] == last[1]:
            keep.append(i)                             # an exact duplicate of a front run
    return df.iloc[keep]


# --------------------------------------------------------------------------- ranking

def _fmt(v, width: int | None = None) -> str:
    if v is None:
        s = ""
    elif isinstance(v, (bool, np.bool_)):
        s = str(bool(v))
    elif isinstance(v, (int, float, np.integer, np.floating)):
        f = float(v)
        s = "nan" if math.isnan(f) else f"{f:.6g}"
    else:
        s = str(v)
    return s


def _table(header: list[str], rows: list[list[str]]) -> list[str]:
    w = [max(len(h), *(len(r[i]) for r in rows)) if rows else len(h)
         for i, h in enumerate(header)]
    line = lambda cells: "  ".join(c.rjust(w[i]) if i != 1 else c.ljust(w[i])  # noqa: E731
                                   for i, c in enumerate(cells)).rstrip()
    return [line(header), line(["-" * x for x in w])] + [line(r) for r in rows]


def ranked_table(df: pd.DataFrame, metric: str, ascending: bool = True,
                 top: int | None = 20) -> str:
    """A plain-text table of the best runs by ``metric`` (smallest first when
    ``ascending``; ``top`` rows, None for all) with their parameter values, then the
    successful runs without a value and the failed runs (with their error)."""
    check_metric(df, metric)
    pcols = [c for c in df.columns if str(c).startswith("param:")]
    v = _values(df, metric)
    ok = _ok(df)
    ranked = np.flatnonzero(ok & np.isfinite(v))
    key = v[ranked] if ascending else -v[ranked]
    ranked = ranked[np.argsort(key, kind="stable")]
    shown = ranked if top is None else ranked[:top]
    header = ["#", "run_id"] + [label_of(c) for c in pcols] + [label_of(metric)]
    rows = [[str(k + 1), str(df["run_id"].iloc[i]) if "run_id" in df.columns else str(i)]
            + [_fmt(df[c].iloc[i]) for c in pcols] + [_fmt(v[i])]
            for k, i in enumerate(shown)]
    out = [f"Runs ranked by {metric} ({'smallest' if ascending else 'largest'} first): "
           f"{len(shown)} of {len(ranked)} runs with a value shown"]
    out += _table(header, rows) if rows else ["  (no run has a value)"]
    novalue = np.flatnonzero(ok & ~np.isfinite(v))
    failed = np.flatnonzero(~ok)
    for title, sel, with_err in (("Successful runs without a value of the metric", novalue,
                                  False), ("Failed runs", failed, True)):
        if not len(sel):
            continue
        lim = sel if top is None else sel[:top]
        out += ["", f"{title} ({len(sel)}" + (f", {len(lim)} shown" if len(lim) < len(sel)
                                              else "") + "):"]
        hdr = ["-", "run_id"] + [label_of(c) for c in pcols] + (["error"] if with_err else [])
        body = []
        for i in lim:
            row = ["-", str(df["run_id"].iloc[i]) if "run_id" in df.columns else str(i)]
            row += [_fmt(df[c].iloc[i]) for c in pcols]
            if with_err:
                err = str(df["error"].iloc[i]) if "error" in df.columns else ""
                err = "" if err == "nan" else err
                row.append((err[:77] + "...") if len(err) > 80 else err)
            body.append(row)
        out += _table(hdr, body)
    return "\n".join(out) + "\n"


# --------------------------------------------------------------------------- sensitivity

def _study_object(study: dict):
    from afo_mj.studies.study import Study, StudyParameter
    params = tuple(StudyParameter(p["key"], tuple(p.get("levels") or ()), p.get("lo"),
                                  p.get("hi"), int(p.get("points", 3)),
                                  p.get("scale", "linear"), bool(p.get("integer", False)))
                   for p in study["parameters"])
    des = study.get("design") or {}
    return Study(name=study.get("name", "study"), description="",
                 scenario_path=Path(study.get("scenario", ".")), fixed=tuple(study.get("set", [])),
                 parameters=params, design=des.get("kind", "grid"),
                 samples=int(des.get("samples", 16)), seed=int(des.get("seed", 0)),
                 output_format="parquet", optimize={})


def _problem(study: dict) -> dict:
    prob = study.get("salib_problem")
    if prob:
        return {"num_vars": int(prob["num_vars"]), "names": list(prob["names"]),
                "bounds": [list(map(float, b)) for b in prob["bounds"]]}
    return _study_object(study).salib_problem()


def _design(study: dict) -> tuple[np.ndarray, list[dict]]:
    """The design's SALib sample matrix and its points (as the sweep ran them)."""
    st = _study_object(study)
    prob = _problem(study)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        if st.design == "saltelli":
            from SALib.sample import sobol as salib_sobol
            X = salib_sobol.sample(prob, st.samples, calc_second_order=False, seed=st.seed)
        else:
            from SALib.sample import morris as salib_morris
            X = salib_morris.sample(prob, st.samples, num_levels=4, seed=st.seed)
        points = st.points()
    return np.asarray(X, float), points


def _match(df: pd.DataFrame, keys: list[str], points: list[dict]) -> np.ndarray:
    """Row index of ``df`` for each design point (-1 when none): the successful row with
    the same parameter values (exactly, or within 1e-9 relative), else a failed one."""
    cols = ["param:" + k for k in keys]
    if any(c not in df.columns for c in cols):
        return np.full(len(points), -1)
    T = np.column_stack([_values(df, c) for c in cols])
    ok = _ok(df)
    exact: dict[tuple, int] = {}
    for i in np.argsort(~ok, kind="stable"):          # successful rows first
        exact.setdefault(tuple(T[i]), int(i))
    out = np.full(len(points), -1)
    for n, p in enumerate(points):
        t = tuple(float(p[k]) for k in keys)
        i = exact.get(t)
        if i is None:
            close = np.flatnonzero(np.all(np.isclose(T, np.array(t), rtol=1e-9, atol=1e-12),
                                          axis=1))
            if len(close):
                i = int(close[np.argmax(ok[close])])
        out[n] = -1 if i is None else i
    return out


def _jsonable(x):
    if isinstance(x, dict):
        return {str(k): _jsonable(v) for k, v in x.items()}
    if isinstance(x, (list, tuple, np.ndarray)):
        return [_jsonable(v) for v in x]
    if isinstance(x, (bool, np.bool_)):
        return bool(x)
    if isinstance(x, (int, np.integer)):
        return int(x)
    if isinstance(x, (float, np.floating)):
        f = float(x)
        return f if math.isfinite(f) else None
    if x is None or isinstance(x, str):
        return x
    return str(x)


#: public name of :func:`_jsonable` (finite plain-Python numbers; NaN as None)
jsonable = _jsonable


def sensitivity(study_dict: dict, df: pd.DataFrame, metric: str) -> dict | None:
    """Sensitivity indices of ``metric``: Sobol' S1/ST (``saltelli`` design) or Morris
    mu*/sigma (``morris`` design); None for any other design (they do not support them).

    Returns ``{"method": "sobol"|"morris", "metric", "design", "n_design_points",
    "n_runs", "indices": [{"parameter", ...}]}`` with, per parameter, ``S1``, ``S1_conf``,
    ``ST``, ``ST_conf`` (95 % bootstrap half-widths) or ``mu``, ``mu_star``,
    ``mu_star_conf``, ``sigma`` (elementary effects over the full parameter range, metric
    units), plus ``n_trajectories`` / ``dropped_trajectories`` for Morris. When they cannot
    be computed (failed or missing runs for Sobol', fewer than 2 complete trajectories for
    Morris, a table that does not match the design) ``indices`` is absent and ``skipped``
    says why."""
    check_metric(df, metric)
    kind = (study_dict.get("design") or {}).get("kind", "grid")
    if kind not in ("saltelli", "morris"):
        return None
    method = "sobol" if kind == "saltelli" else "morris"
    base = {"method": method, "metric": metric, "design": kind}
    try:
        X, points = _design(study_dict)
    except Exception as exc:                        # noqa: BLE001 - reported, not raised
        return {**base, "skipped": f"the {kind} design could not be regenerated from "
                f"study.json ({type(exc).__name__}: {exc})"}
    keys = [p["key"] for p in study_dict["parameters"]]
    prob = _problem(study_dict)
    rows = _match(df, keys, points)
    v = _values(df, metric)
    ok = _ok(df)
    M = len(points)
    missing = int(np.sum(rows < 0))
    failed = int(np.sum((rows >= 0) & ~ok[np.maximum(rows, 0)]))
    Y = np.where(rows >= 0, v[np.maximum(rows, 0)], np.nan)
    Y[(rows >= 0) & ~ok[np.maximum(rows, 0)]] = np.nan
    novalue = int(np.sum(np.isnan(Y))) - missing - failed
    have = np.isfinite(Y)
    base.update(n_design_points=M, n_runs=int(np.sum(have)))
    if missing == M:
        return {**base, "skipped": f"none of the {M} design points is in the table (the "
                "table's parameter values do not match the design regenerated from "
                "study.json: another SALib version, or another study?)"}
    gaps = (f"{missing} not run, {failed} failed, {novalue} without a value of {metric}")
    if method == "sobol":
        if not np.all(have):
            return {**base, "skipped": f"{M - int(np.sum(have))} of the {M} runs of the "
                    f"Saltelli design have no value ({gaps}); Sobol' indices need every "
                    "run, so they were not computed (rerun the sweep to fill the gaps)"}
        from SALib.analyze import sobol as salib_sobol
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            si = salib_sobol.analyze(prob, Y, calc_second_order=False, seed=0)
        base["indices"] = [{"parameter": k, "S1": si["S1"][j], "S1_conf": si["S1_conf"][j],
                            "ST": si["ST"][j], "ST_conf": si["ST_conf"][j]}
                           for j, k in enumerate(keys)]
        return _jsonable(base)
    D = len(keys)
    T = M // (D + 1)
    complete = [t for t in range(T) if np.all(have[t * (D + 1):(t + 1) * (D + 1)])]
    base.update(n_trajectories=len(complete), dropped_trajectories=T - len(complete))
    if len(complete) < 2:
        return {**base, "skipped": f"{len(complete)} of the {T} Morris trajectories are "
                f"complete ({gaps}); at least 2 are needed"}
    sel = np.concatenate([np.arange(t * (D + 1), (t + 1) * (D + 1)) for t in complete])
    from SALib.analyze import morris as salib_morris
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        si = salib_morris.analyze(prob, X[sel], Y[sel], num_levels=4, seed=0)
    base["n_runs"] = int(len(sel))
    base["indices"] = [{"parameter": k, "mu": si["mu"][j], "mu_star": si["mu_star"][j],
                        "mu_star_conf": si["mu_star_conf"][j], "sigma": si["sigma"][j]}
                       for j, k in enumerate(keys)]
    return _jsonable(base)


def sensitivity_note(study_dict: dict, result: dict | None) -> str:
    """One paragraph on the sensitivity indices: the indices, why they were skipped, or why
    the design does not support them."""
    kind = (study_dict.get("design") or {}).get("kind", "grid")
    if result is None:
        return (f"Sensitivity indices: not computed: a {kind} design does not support them "
                "(Sobol' indices need a Saltelli design, elementary effects a Morris design; "
                'set design.kind = "saltelli" or "morris" in the study to get them).')
    if "indices" not in result:
        name = "Sobol' indices" if result["method"] == "sobol" else "Morris elementary effects"
        return f"Sensitivity ({name}): not computed: {result['skipped']}."
    lines = []
    if result["method"] == "sobol":
        lines.append(f"Sobol' indices of {result['metric']} ({result['n_runs']} runs; "
                     "± 95 % bootstrap):")
        hdr = ["parameter", "S1", "±", "ST", "±"]
        body = [[r["parameter"], _fmt(r["S1"]), _fmt(r["S1_conf"]), _fmt(r["ST"]),
                 _fmt(r["ST_conf"])] for r in result["indices"]]
    else:
        lines.append(f"Morris elementary effects of {label_of(result['metric'])} over the full "
                     f"range of each parameter ({result['n_trajectories']} trajectories"
                     + (f", {result['dropped_trajectories']} incomplete dropped"
                        if result.get("dropped_trajectories") else "") + "):")
        hdr = ["parameter", "mu*", "±", "mu", "sigma"]
        body = [[r["parameter"], _fmt(r["mu_star"]), _fmt(r["mu_star_conf"]), _fmt(r["mu"]),
                 _fmt(r["sigma"])] for r in result["indices"]]
    # the parameter column left-aligned
    w = [max(len(h), *(len(b[i]) for b in body)) for i, h in enumerate(hdr)]
    for cells in [hdr] + body:
        lines.append("  " + "  ".join(c.ljust(w[i]) if i == 0 else c.rjust(w[i])
                                      for i, c in enumerate(cells)).rstrip())
    return "\n".join(lines)


# --------------------------------------------------------------------------- report

def _run_record(df: pd.DataFrame, i: int, pcols: list[str], extra: dict | None = None) -> dict:
    r = {"run_id": str(df["run_id"].iloc[i]) if "run_id" in df.columns else str(i),
         "parameters": {c[len("param:"):]: _jsonable(_plain(df[c].iloc[i])) for c in pcols}}
    if extra:
        r.update(extra)
    return r


def _plain(v):
    return v.item() if isinstance(v, np.generic) else v


def analyse_study(out_dir, metric: str | None = None,
                  ascending: bool | None = None) -> dict:
    """Everything the report of the sweep in ``out_dir`` holds, nothing written (the files:
    :func:`afo_mj.outputs.study_report.write_study_report`): the runs ranked by ``metric``
    (:func:`default_metric` when None; smallest first unless ``ascending`` is False, or None
    and the name contains one of :data:`MAXIMISE_HINTS`), the best and top runs, the Pareto
    front (device studies), the sensitivity indices, the failed runs.

    Returns ``{"study": study.json dict, "table": the results DataFrame, "metric": str |
    None (None: no successful run), "ascending": bool, "ranking": the full ranking text
    (``ranking.txt``), "sections": [paragraphs of the report to print], "summary": the
    summary.json dict (without ``figures``, not yet JSON-cleaned), "pareto_axes": (x, y) |
    None, "front": DataFrame | None, "sensitivity": dict | None}``. Raises
    :class:`StudyReportError` (a ValueError) for a directory without a sweep, ValueError for
    an unknown metric (naming close ones)."""
    out_dir = Path(out_dir)
    study, df = load_results(out_dir)
    ok = _ok(df)
    if metric is not None:
        check_metric(df, metric)
    else:
        try:
            metric = default_metric(df)
        except ValueError:
            if np.any(ok):
                raise
            metric = None                              # every run failed: list them
    if ascending is None:
        ascending = not (metric is not None and _maximise(metric))
    pcols = _param_columns(study, df)
    kind = (study.get("design") or {}).get("kind", "?")
    head = [f"Study {study.get('name', '?')}: {kind} design over "
            f"{', '.join(p['key'] for p in study.get('parameters', []))}; {len(df)} runs, "
            f"{int(np.sum(ok))} ok, {int(np.sum(~ok))} failed"]
    summary: dict[str, Any] = {"format": FORMAT, "study": study.get("name"), "design": kind,
                               "runs": len(df), "ok": int(np.sum(ok)),
                               "failed": int(np.sum(~ok)), "metric": metric,
                               "ascending": ascending}
    sections = list(head)
    if metric is None:
        ranking = ("No successful run: nothing to rank.\n"
                   + _failed_list(df, pcols))
        sections += ["", ranking.rstrip()]
        summary.update(best=None, top=[], pareto=None, sensitivity=None,
                       sensitivity_note="no successful run")
        sens, front, axes = None, None, None
    else:
        ranking = ranked_table(df, metric, ascending, top=None)
        sections += ["", ranked_table(df, metric, ascending, top=_PRINT_TOP).rstrip()]
        v = _values(df, metric)
        ranked = np.flatnonzero(ok & np.isfinite(v))
        ranked = ranked[np.argsort(v[ranked] if ascending else -v[ranked], kind="stable")]
        summary["metric_label"] = label_of(metric)
        summary["top"] = [_run_record(df, int(i), pcols, {"value": _jsonable(v[i])})
                          for i in ranked[:20]]
        summary["best"] = summary["top"][0] if summary["top"] else None
        summary["spread"] = metric_spread(v[ranked])
        if summary["best"]:
            b = summary["best"]
            sections += ["", f"Best run: {b['run_id']}: {metric} = {_fmt(b['value'])} at "
                         + ", ".join(f"{k} = {_fmt(x)}" for k, x in b["parameters"].items())]
        sp = summary["spread"]
        if sp["n"] >= 2:
            # the spread the best run stands out from (e.g. between seeds of one wearer)
            sections.append(f"Over the {sp['n']} runs with a value: mean {_fmt(sp['mean'])}, "
                            f"SD {_fmt(sp['sd'])}, range {_fmt(sp['min'])} … "
                            f"{_fmt(sp['max'])} ({label_of(metric)})")
        axes = pareto_metrics(df)
        front = None
        if axes is not None:
            front = pareto_front(df, *axes)
        if axes is not None and not len(front):
            summary["pareto"] = None
            sections += ["", f"Pareto front: no successful run has both {axes[0]} and "
                         f"{axes[1]}"]
            axes = front = None
        elif axes is not None:
            xs, ys = _values(front, axes[0]), _values(front, axes[1])
            summary["pareto"] = {
                "x_metric": axes[0], "y_metric": axes[1], "minimised": [True, True],
                "runs": [_run_record(front, k, pcols, {"x": _jsonable(xs[k]),
                                                       "y": _jsonable(ys[k])})
                         for k in range(len(front))]}
            lines = [f"Pareto front ({len(front)} runs; both minimised): {label_of(axes[0])} "
                     f"vs {label_of(axes[1])}"]
            for k in range(len(front)):
                r = summary["pareto"]["runs"][k]
                lines.append(f"  {r['run_id']}: x = {_fmt(xs[k])}, y = {_fmt(ys[k])}  ("
                             + ", ".join(f"{p} = {_fmt(x)}" for p, x in
                                         r["parameters"].items()) + ")")
            sections += [""] + lines
        elif "pareto" not in summary:
            summary["pareto"] = None
        sens = sensitivity(study, df, metric)
        summary["sensitivity"] = sens
        summary["sensitivity_note"] = sensitivity_note(study, sens)
        sections += ["", summary["sensitivity_note"]]
    summary["failed_runs"] = [_run_record(df, int(i), pcols,
                                          {"error": str(df["error"].iloc[i])
                                           if "error" in df.columns else ""})
                              for i in np.flatnonzero(~ok)]
    return {"study": study, "table": df, "metric": metric, "ascending": ascending,
            "ranking": ranking, "sections": sections, "summary": summary,
            "pareto_axes": axes, "front": front, "sensitivity": sens}


def _failed_list(df: pd.DataFrame, pcols: list[str]) -> str:
    lines = [f"Failed runs ({int(np.sum(~_ok(df)))}):"]
    for i in np.flatnonzero(~_ok(df)):
        err = str(df["error"].iloc[i]) if "error" in df.columns else ""
        lines.append(f"  {df['run_id'].iloc[i] if 'run_id' in df.columns else i}: "
                     + ", ".join(f"{c[len('param:'):]} = {_fmt(df[c].iloc[i])}" for c in pcols)
                     + (f": {err}" if err else ""))
    return "\n".join(lines) + "\n"
