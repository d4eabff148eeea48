"""Figures of a parameter study (``afo-mj study DIR``; :mod:`afo_mj.outputs.study_report`).

:func:`plot_study` writes into a directory (matplotlib, Agg backend, no pyplot state):

* ``metric_vs_parameters.png`` -- the ranking metric against each varied parameter, one
  panel each: every successful run as a dot, the mean per level as a line where the
  parameter takes few distinct values (<= :data:`MAX_LEVELS`), and runs without a value
  (failed runs, or successful runs whose metric is missing) as red crosses along the bottom
  of the panel at their parameter value;
* ``heatmap_<p1>__<p2>.png`` -- for each pair of parameters that both have grid levels
  (explicit ``levels``, or any parameter of a ``grid`` design) with at least 2 distinct
  values each in the table: the mean metric over the successful runs of each cell, the
  value written in the cell, cells without a value hatched and the number of failed runs
  of a cell named in it. Pairs without a grid (continuous parameters of random / LHS /
  Sobol' / Saltelli / Morris designs) are skipped;
* ``pareto.png`` -- device studies only, when both Pareto metrics are in the table
  (:func:`afo_mj.studies.study_analysis.pareto_metrics`): the change in human ankle positive
  work vs no device (J/stride, negative = the device took work off the muscles) against the
  electrical energy drawn per stride (J/stride), every successful run in grey and the
  non-dominated runs (both minimised) in red, joined as a staircase;
* ``sensitivity.png`` -- when sensitivity indices were computed: bars of the first-order and
  total Sobol' indices (S1, ST, with their bootstrap confidence intervals) or of Morris's
  mu* (with its confidence interval) and sigma.

File names are sanitised (:func:`safe_name`: dots, colons and anything but letters, digits,
``-`` and ``_`` become ``_``). Axis labels carry units, read from the name's suffix
(:func:`afo_mj.studies.metric_labels.unit_of`, re-exported here: ``_nm`` → N·m,
``_j_per_stride`` → J/stride, ``_deg`` → deg, ...).
"""

from __future__ import annotations

import math
import re
from pathlib import Path
from typing import Any, Sequence

import numpy as np

from afo_mj.studies.metric_labels import _strip_param, label_of, unit_of

__all__ = ["plot_study", "plot_metric_vs_parameters", "plot_heatmaps", "plot_pareto",
           "plot_sensitivity", "safe_name", "unit_of", "label_of", "plot_label", "grid_parameters",
           "MAX_LEVELS", "heatmap_name"]

#: A parameter with at most this many distinct values gets a mean-per-level line.
MAX_LEVELS = 12
#: Cells of a heatmap are annotated with their value up to this many levels per axis.
_ANNOTATE_MAX = 12
_DPI = 110


def safe_name(name: str) -> str:
    """``name`` usable in a file name: dots, colons and anything but letters, digits, ``-``
    and ``_`` become ``_`` (``param:assistance.peak_torque_nm`` →
    ``param_assistance_peak_torque_nm``)."""
    return re.sub(r"[^A-Za-z0-9_-]", "_", str(name))


def heatmap_name(p1: str, p2: str) -> str:
    """The heatmap file of parameters ``p1`` (rows) and ``p2`` (columns), keys without the
    ``param:`` prefix."""
    return f"heatmap_{safe_name(_strip_param(p1))}__{safe_name(_strip_param(p2))}.png"


_FRIENDLY = (("comparison_vs_no_device.", ".human_ankle_positive_work_change_j_per_stride",
              "human ankle positive work change vs no device"),
             ("device_conditions.", ".energy_per_stride.electrical_in_j",
              "electrical energy per stride"))


def plot_label(name: str, width: int = 48) -> str:
    """A figure label: :func:`label_of`, the Pareto metrics in words (the condition in
    brackets), long names wrapped at their dots."""
    n = _strip_param(name)
    for pre, suf, words in _FRIENDLY:
        if n.startswith(pre) and n.endswith(suf) and len(n) > len(pre) + len(suf):
            cond = n[len(pre):-len(suf)]
            u = unit_of(n)
            return _wrap(f"{words} [{cond}] ({u})" if u else f"{words} [{cond}]", width)
    return _wrap(label_of(name), width)


def _wrap(text: str, width: int) -> str:
    if len(text) <= width:
        return text
    lines, cur = [], ""
    for part in re.split(r"(?<=[.\s])", text):
        if cur and len(cur) + len(part) > width:
            lines.append(cur)
            cur = ""
        cur += part
    if cur:
        lines.append(cur)
    return "\n".join(x.strip() for x in lines)


# --------------------------------------------------------------------------- helpers

def _figure(figsize):
    import matplotlib
    matplotlib.use("Agg", force=False)
    from matplotlib.figure import Figure
    return Figure(figsize=figsize, layout="constrained")


def _save(fig, path: Path) -> None:
    fig.savefig(path, dpi=_DPI)


def _numeric(values) -> np.ndarray:
    """Values as floats (booleans as 0/1, anything else not a number as NaN)."""
    out = np.full(len(values), np.nan)
    for i, v in enumerate(values):
        if isinstance(v, (bool, np.bool_)):
            out[i] = float(v)
        elif isinstance(v, (int, float, np.integer, np.floating)) and v is not None:
            out[i] = float(v)
    return out


def _is_numeric_param(values) -> bool:
    vals = [v for v in values if v is not None and not (isinstance(v, float) and math.isnan(v))]
    return bool(vals) and all(isinstance(v, (int, float, np.integer, np.floating))
                              and not isinstance(v, (bool, np.bool_)) for v in vals)


def _level_order(values, study_levels: Sequence = ()) -> list:
    """Distinct values (NaN/None left out; numbers within 1e-9 relative are one value): the
    study's level order where given, numbers sorted, anything else in order of appearance."""
    vals = [v for v in values
            if v is not None and not (isinstance(v, (float, np.floating)) and math.isnan(v))]
    if _is_numeric_param(vals):
        u = np.unique(np.asarray(vals, float))
        seen: list = []
        for x in u:
            if not seen or not math.isclose(x, seen[-1], rel_tol=1e-9, abs_tol=1e-12):
                seen.append(float(x))
    else:
        seen = list({str(v): v for v in vals}.values())
    if study_levels:
        ordered = [s for lv in study_levels for s in seen if _same(s, lv)]
        return ordered + [s for s in seen if not any(_same(s, o) for o in ordered)]
    return seen


def _same(a, b) -> bool:
    if _is_numeric_param([a]) and _is_numeric_param([b]):
        return math.isclose(float(a), float(b), rel_tol=1e-9, abs_tol=1e-12)
    return str(a) == str(b)


def _fmt(v) -> str:
    if isinstance(v, (float, np.floating)):
        return f"{float(v):.4g}"
    return str(v)


def grid_parameters(study: dict, df) -> list[tuple[str, list]]:
    """Parameters with grid levels, as (``param:<key>`` column, distinct values in level
    order): those with explicit ``levels`` and every parameter of a ``grid`` design, having
    at least 2 distinct values in the table."""
    kind = (study.get("design") or {}).get("kind", "grid")
    out = []
    for p in study.get("parameters", []):
        col = "param:" + p["key"]
        if col not in df.columns:
            continue
        levels = list(p.get("levels") or [])
        if not levels and kind != "grid":
            continue
        vals = _level_order(list(df[col]), levels)
        if len(vals) >= 2:
            out.append((col, vals))
    return out


def _param_columns(study: dict, df) -> list[str]:
    cols = ["param:" + p["key"] for p in study.get("parameters", [])
            if "param:" + p["key"] in df.columns]
    return cols + [c for c in df.columns if str(c).startswith("param:") and c not in cols]


def _ok(df) -> np.ndarray:
    return (df["status"].astype(str) == "ok").to_numpy() if "status" in df.columns \
        else np.ones(len(df), bool)


def _metric_values(df, metric) -> np.ndarray:
    if metric is None or metric not in df.columns:
        return np.full(len(df), np.nan)
    return _numeric(list(df[metric]))


# --------------------------------------------------------------------------- figures

def plot_metric_vs_parameters(path, study: dict, df, metric: str) -> Path | None:
    """``metric_vs_parameters.png``: the metric against each parameter (one panel each);
    None (nothing written) when the table has no parameter column."""
    cols = _param_columns(study, df)
    if not cols:
        return None
    path = Path(path)
    y = _metric_values(df, metric)
    ok = _ok(df)
    good = ok & np.isfinite(y)
    bad = ~good
    n = len(cols)
    ncol = min(n, 3)
    nrow = math.ceil(n / ncol)
    fig = _figure((4.2 * ncol, 3.4 * nrow))
    axes = np.atleast_1d(fig.subplots(nrow, ncol, squeeze=False)).ravel()
    levels_by_key = {"param:" + p["key"]: list(p.get("levels") or [])
                     for p in study.get("parameters", [])}
    for ax, col in zip(axes, cols):
        raw = list(df[col])
        if _is_numeric_param(raw):
            x = _numeric(raw)
            ticks = None
        else:
            order = _level_order(raw, levels_by_key.get(col, ()))
            x = np.array([next((i for i, o in enumerate(order) if _same(v, o)), np.nan)
                          for v in raw], float)
            ticks = order
        ax.plot(x[good], y[good], "o", ms=5, alpha=0.7, color="tab:blue",
                label="run", zorder=3)
        levels = _level_order([v for v, g in zip(raw, good) if g])
        if 1 < len(levels) <= MAX_LEVELS:
            xs, ms = [], []
            for lv in levels:
                sel = good & np.array([_same(v, lv) for v in raw])
                xs.append(float(np.mean(x[sel])))
                ms.append(float(np.mean(y[sel])))
            ax.plot(xs, ms, "-", color="tab:orange", lw=1.5, label="mean per level", zorder=2)
        if np.any(bad):
            ax.plot(x[bad], np.full(int(np.sum(bad)), 0.04), "x", color="tab:red", ms=8,
                    mew=2, transform=ax.get_xaxis_transform(), clip_on=False,
                    label=f"failed / no value ({int(np.sum(bad))})", zorder=4)
        if ticks is not None:
            ax.set_xticks(range(len(ticks)), [_fmt(t) for t in ticks])
        ax.set_xlabel(plot_label(col))
        ax.set_ylabel(plot_label(metric, 36) if metric else "metric", fontsize=8)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7, loc="best")
    for ax in axes[n:]:
        ax.set_visible(False)
    fig.suptitle(_wrap(f"{study.get('name', 'study')}: {plot_label(metric, 1000)}: "
                       f"{int(np.sum(good))} runs with a value, {int(np.sum(bad))} without",
                       40 * ncol), fontsize=9)
    _save(fig, path)
    return path


def plot_heatmaps(out_dir, study: dict, df, metric: str) -> list[Path]:
    """``heatmap_<p1>__<p2>.png`` for each pair of grid parameters (mean metric per cell)."""
    out_dir = Path(out_dir)
    grid = grid_parameters(study, df)
    y = _metric_values(df, metric)
    ok = _ok(df)
    good = ok & np.isfinite(y)
    written = []
    for i in range(len(grid)):
        for j in range(i + 1, len(grid)):
            (c1, l1), (c2, l2) = grid[i], grid[j]
            v1, v2 = list(df[c1]), list(df[c2])
            idx1 = np.array([next((k for k, lv in enumerate(l1) if _same(v, lv)), -1)
                             for v in v1])
            idx2 = np.array([next((k for k, lv in enumerate(l2) if _same(v, lv)), -1)
                             for v in v2])
            mean = np.full((len(l1), len(l2)), np.nan)
            nfail = np.zeros((len(l1), len(l2)), int)
            for a in range(len(l1)):
                for b in range(len(l2)):
                    cell = (idx1 == a) & (idx2 == b)
                    if np.any(cell & good):
                        mean[a, b] = float(np.mean(y[cell & good]))
                    nfail[a, b] = int(np.sum(cell & ~good))
            fig = _figure((min(2.7 + 0.9 * max(len(l2), 3), 16.0),
                           min(2.0 + 0.6 * max(len(l1), 3), 12.0)))
            ax = fig.add_subplot()
            finite = np.isfinite(mean)
            lo = hi = 0.0
            ax.set_facecolor("#dddddd")
            if np.any(finite):
                im = ax.imshow(np.ma.masked_invalid(mean), origin="lower", aspect="auto",
                               cmap="viridis")
                cb = fig.colorbar(im, ax=ax)
                cb.set_label("mean " + plot_label(metric, 36), fontsize=8)
                lo, hi = float(np.nanmin(mean)), float(np.nanmax(mean))
            else:
                ax.imshow(np.zeros_like(mean), origin="lower", aspect="auto", cmap="Greys",
                          vmin=0, vmax=1)
            for a in range(len(l1)):
                for b in range(len(l2)):
                    if not finite[a, b]:
                        ax.add_patch(_hatch(b, a))
                    if len(l1) <= _ANNOTATE_MAX and len(l2) <= _ANNOTATE_MAX:
                        txt = f"{mean[a, b]:.3g}" if finite[a, b] else "no value"
                        if nfail[a, b]:
                            txt += f"\n{nfail[a, b]} failed"
                        dark = (finite[a, b] and hi > lo
                                and (mean[a, b] - lo) / (hi - lo) < 0.55)
                        ax.text(b, a, txt, ha="center", va="center", fontsize=7,
                                color="white" if dark else "black")
            ax.set_xticks(range(len(l2)), [_fmt(v) for v in l2])
            ax.set_yticks(range(len(l1)), [_fmt(v) for v in l1])
            ax.set_xlabel(plot_label(c2))
            ax.set_ylabel(plot_label(c1))
            ax.set_title(_wrap(f"mean {plot_label(metric, 1000)} per cell", 60), fontsize=8)
            p = out_dir / heatmap_name(c1, c2)
            _save(fig, p)
            written.append(p)
    return written


def _hatch(x, y):
    from matplotlib.patches import Rectangle
    return Rectangle((x - 0.5, y - 0.5), 1, 1, fill=False, hatch="//", edgecolor="0.5", lw=0)


def plot_pareto(path, df, x_metric: str, y_metric: str, front) -> Path:
    """``pareto.png``: ``y_metric`` against ``x_metric`` for every successful run, the
    non-dominated ``front`` (a DataFrame of rows of ``df``) highlighted."""
    path = Path(path)
    x = _metric_values(df, x_metric)
    y = _metric_values(df, y_metric)
    good = _ok(df) & np.isfinite(x) & np.isfinite(y)
    fig = _figure((6.4, 4.8))
    ax = fig.add_subplot()
    ax.plot(x[good], y[good], "o", color="0.6", ms=5, label=f"run ({int(np.sum(good))})")
    fx = _numeric(list(front[x_metric])) if len(front) else np.array([])
    fy = _numeric(list(front[y_metric])) if len(front) else np.array([])
    if len(fx):
        o = np.argsort(fx, kind="stable")
        ax.step(fx[o], fy[o], where="post", color="tab:red", lw=1.2, alpha=0.7)
        ax.plot(fx[o], fy[o], "o", color="tab:red", ms=7,
                label=f"Pareto front ({len(fx)})")
        pcols = [c for c in front.columns if str(c).startswith("param:")]
        if len(fx) <= 8 and pcols:
            for k in o:
                r = front.iloc[int(k)]
                ax.annotate(", ".join(_fmt(r[c]) for c in pcols), (fx[k], fy[k]),
                            textcoords="offset points", xytext=(5, 4), fontsize=7)
    nbad = int(len(df) - np.sum(good))
    ax.set_xlabel(plot_label(x_metric, 60)
                  + "\n(negative: less human ankle work than without the device)", fontsize=8)
    ax.set_ylabel(plot_label(y_metric, 40), fontsize=8)
    ax.set_title("both minimised" + (f"; {nbad} runs without both values not shown"
                                     if nbad else ""), fontsize=9)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    _save(fig, path)
    return path


def plot_sensitivity(path, sens: dict, metric: str | None = None) -> Path | None:
    """``sensitivity.png``: S1/ST bars (Sobol') or mu*/sigma bars (Morris) per parameter;
    None when ``sens`` holds no indices."""
    if not sens or not sens.get("indices"):
        return None
    path = Path(path)
    rows = sens["indices"]
    names = [r["parameter"] for r in rows]
    pos = np.arange(len(names))
    w = 0.38
    fig = _figure((1.8 + 1.3 * len(names), 4.4))
    ax = fig.add_subplot()

    def arr(k):
        return np.array([np.nan if r.get(k) is None else float(r[k]) for r in rows])

    metric = metric or sens.get("metric", "")
    if sens.get("method") == "sobol":
        ax.bar(pos - w / 2, arr("S1"), w, yerr=np.nan_to_num(arr("S1_conf")), capsize=3,
               label="first order S1", color="tab:blue")
        ax.bar(pos + w / 2, arr("ST"), w, yerr=np.nan_to_num(arr("ST_conf")), capsize=3,
               label="total ST", color="tab:orange")
        ax.set_ylabel("Sobol' index (1, fraction of the variance)")
        ax.axhline(0, color="k", lw=0.6)
        title = f"Sobol' indices of {metric} ({sens.get('n_runs', '?')} runs)"
    else:
        u = unit_of(metric)
        ax.bar(pos - w / 2, arr("mu_star"), w, yerr=np.nan_to_num(arr("mu_star_conf")),
               capsize=3, label="μ* (mean |elementary effect|)", color="tab:blue")
        ax.bar(pos + w / 2, arr("sigma"), w, label="σ (sd of the effects)", color="tab:orange")
        ax.set_ylabel(f"elementary effect ({u + ', ' if u else ''}"
                      "change over the full parameter range)", fontsize=8)
        title = (f"Morris screening of {metric} ({sens.get('n_trajectories', '?')} "
                 "trajectories)")
    ax.set_xticks(pos, [plot_label(n, 28) for n in names], rotation=20, ha="right", fontsize=8)
    ax.set_title(_wrap(title, 70), fontsize=9)
    ax.grid(alpha=0.3, axis="y")
    ax.legend(fontsize=8)
    _save(fig, path)
    return path


def plot_study(out_dir, study: dict, df, metric: str | None, *,
               pareto_axes: tuple[str, str] | None = None, front=None,
               sensitivity: dict | None = None) -> list[str]:
    """All the figures of a study into ``out_dir``; returns the file names written."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    written: list[Any] = []
    if metric is not None:
        written.append(plot_metric_vs_parameters(out_dir / "metric_vs_parameters.png", study,
                                                 df, metric))
        written += plot_heatmaps(out_dir, study, df, metric)
    if pareto_axes is not None and front is not None:
        written.append(plot_pareto(out_dir / "pareto.png", df, pareto_axes[0],
                                   pareto_axes[1], front))
    if sensitivity:
        written.append(plot_sensitivity(out_dir / "sensitivity.png", sensitivity))
    return [Path(p).name for p in written if p is not None]
