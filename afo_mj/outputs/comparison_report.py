"""Files and printed tables of ``afo-mj compare`` (see :mod:`afo_mj.experiments.device_comparison`).

:func:`write_comparison` writes ``comparison.csv``, ``comparison.json``, ``comparison.png`` and
``comparison.md`` into a result directory at once (:func:`afo_mj.outputs.result_dir.
write_atomically`); :func:`format_tables` gives the text printed on stdout.
"""

from __future__ import annotations

import csv
import json
import math
from pathlib import Path

from afo_mj.outputs.console import battery_warnings, solver_warnings

__all__ = ["write_comparison", "format_tables", "headline_table", "loss_table", "plot_comparison",
           "caveats", "effort_caveats", "EFFORT"]

#: (column, header with unit, format) of the headline tables: the energy chain, then the device
#: and the walker
CHAIN = (
    ("label", "device", "s"),
    ("preset", "preset", "s"),
    ("efficiency_total", "eff net [%]", "pct"),
    ("efficiency_electrical_to_hydraulic", "el->hyd [%]", "pct"),
    ("efficiency_hydraulic_to_mechanical", "hyd->mech [%]", "pct"),
    ("electrical_j_per_stride", "electrical [J/stride]", ".2f"),
    ("hydraulic_j_per_stride", "hydraulic [J/stride]", ".2f"),
    ("mechanical_j_per_stride", "mech + [J/stride]", ".2f"),
    ("device_positive_work_j_per_stride", "delivered + [J/stride]", ".2f"),
    ("energy_balance_error_rel", "balance err [%]", "pct3"),
    ("mechanical_net_j_per_stride", "mech net [J/stride]", ".2f"),
    ("mechanical_role", "role", "s"),
    ("efficiency_rank", "rank (all rows)", "d"),
    ("efficiency_rank_in_scenario", "rank in scenario", "d"),
)
DEVICE = (
    ("label", "device", "s"),
    ("torque_tracking_rmse_nm", "tracking RMSE [N*m]", ".2f"),
    ("peak_pressure_mpa", "peak p [MPa]", ".2f"),
    ("fluid_temperature_rise_k", "dT oil [K]", ".3f"),
    ("mass_total_kg", "mass [kg]", ".2f"),
    ("mass_at_ankle_kg", "at ankle [kg]", ".2f"),
    ("battery_runtime_h", "battery (actuators) [h]", ".2f"),
    ("human_ankle_positive_work_j_per_stride", "human ankle + [J/stride]", ".2f"),
    ("human_ankle_positive_work_no_device_j_per_stride", "no device [J/stride]", ".2f"),
    ("speed_m_s", "speed [m/s]", ".3f"),
)
#: the wearer's effort beside the battery energy (printed when a row is on the muscle walker)
EFFORT = (
    ("label", "device", "s"),
    ("walker_model", "walker", "s"),
    ("electrical_j_per_stride", "electrical [J/stride]", ".2f"),
    ("net_metabolic_umberger_w_per_kg", "net metabolic [W/kg]", ".3f"),
    ("net_metabolic_umberger_no_device_w_per_kg", "no device [W/kg]", ".3f"),
    ("net_metabolic_umberger_change_pct", "change Umberger [%]", "+.2f"),
    ("net_metabolic_bhargava_change_pct", "change Bhargava [%]", "+.2f"),
    ("rank_metabolic", "rank metabolic", "d"),
    ("rank_battery_energy", "rank battery energy", "d"),
)
HEADLINE = CHAIN + DEVICE[1:]


def _finite(v) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)


def _cell(v, fmt: str) -> str:
    if fmt == "s":
        return "" if v is None else str(v)
    if not _finite(v):
        return "-"
    if fmt == "pct":
        return f"{100 * v:.1f}"
    if fmt == "pct3":
        return f"{100 * v:.3f}"
    if fmt == "d":
        return f"{int(v)}"
    return f"{v:{fmt}}"


def headline_table(rows, spec=HEADLINE) -> tuple[list[str], list[list[str]]]:
    """Header and cells of a headline table (one row per device)."""
    return ([h for _, h, _ in spec], [[_cell(r.get(c), f) for c, _, f in spec] for r in rows])


def loss_table(rows, columns) -> tuple[list[str], list[list[str]]]:
    """Where the energy drawn per stride goes (J/stride): one line per loss (and the stored
    change, regeneration, net mechanical output, and their total), one column per device."""
    lines = [("electrical_j_per_stride", "electrical drawn")]
    lines += [(c, c[len("loss_"):-len("_j_per_stride")]) for c in columns
              if c.startswith("loss_")]
    lines += [("stored_j_per_stride", "stored (change)"),
              ("electrical_regenerated_j_per_stride", "regenerated to battery"),
              ("mechanical_net_j_per_stride", "mechanical out (net)"),
              ("mechanical_j_per_stride", "mechanical out (positive)")]
    header = ["J/stride"] + [r["label"] for r in rows]
    body = [[name] + [_cell(r.get(c), ".3f") for r in rows] for c, name in lines]
    return header, body


def _text(header, body) -> str:
    w = [max(len(str(x)) for x in col) for col in zip(header, *body)]
    fmt = lambda cells: "  ".join(  # noqa: E731
        (c.ljust(n) if i == 0 else c.rjust(n)) for i, (c, n) in enumerate(zip(cells, w)))
    return "\n".join([fmt(header), "  ".join("-" * n for n in w)] + [fmt(b) for b in body])


def _markdown(header, body) -> str:
    esc = lambda s: str(s).replace("|", "\\|")  # noqa: E731
    lines = ["| " + " | ".join(esc(h) for h in header) + " |",
             "|" + "|".join("---" if i == 0 else "---:" for i in range(len(header))) + "|"]
    lines += ["| " + " | ".join(esc(c) for c in b) + " |" for b in body]
    return "\n".join(lines)


#: How efficiency, battery runtime and ranks are defined (printed and in ``comparison.md``).
DEFINITIONS = (
    "eff net = net mechanical work delivered to the ankle / electrical energy drawn (absorbed "
    "work is subtracted, regeneration not credited); battery = usable battery energy / mean "
    "drawn power of this walk; both only for an actuator (net work >= {min_j:g} J/stride and "
    ">= {frac:.0%} of its positive output); rank (all rows) = one ranking of every row "
    "compared by eff net, rank in scenario = within one scenario file; '-' = not given.")


#: How the effort table's figures and ranks are defined (when a row is on the muscle walker).
EFFORT_DEFINITIONS = (
    "net metabolic = the wearer's net metabolic rate over the analysed strides (Umberger 2010; "
    "change also by Bhargava 2004), no device = the same wearer (walker model, reflex set, "
    "body, impairment, gait) walking without a device, change = (with - without) / without; "
    "rank metabolic = the muscle-walker rows by that change, most negative first; rank battery "
    "energy = the muscle-walker rows by the electrical energy drawn per stride, least first; "
    "a row that fell (or whose no-device walk fell, for rank metabolic) is not ranked.")


def _definitions(rows=()) -> str:
    from afo_mj.experiments.device_comparison import (NET_WORK_MIN_FRACTION,
                                                   NET_WORK_MIN_J_PER_STRIDE)
    text = DEFINITIONS.format(min_j=NET_WORK_MIN_J_PER_STRIDE, frac=NET_WORK_MIN_FRACTION)
    return text + ("\n" + EFFORT_DEFINITIONS if _any_muscle(rows) else "")


def _any_muscle(rows) -> bool:
    return any(r.get("walker_model") == "muscle" for r in rows)


def effort_caveats(rows) -> list[str]:
    """Lines about the wearer's effort: in a compare mixing the walkers, which rows have no
    effort model (the torque walker's); per muscle-walker row whose metabolic change rests on a
    fall (its walk or its wearer's no-device walk) or on no analysed stride, what it rests on
    and that it is not ranked."""
    if not _any_muscle(rows):
        return []
    out = []
    torque = [r["label"] for r in rows if r.get("walker_model") != "muscle"]
    if torque:
        out.append("NO EFFORT MODEL: " + ", ".join(torque) + ": on the torque-driven walker, "
                   "which has no muscles and so no metabolic rate; rank metabolic and rank "
                   "battery energy rank the muscle-walker rows only")
    for r in rows:
        if r.get("walker_model") != "muscle":
            continue
        why = []
        if r.get("fell"):
            why.append(f"the walker fell at {r['fall_time_s']:.2f} s wearing it")
        if _finite(r.get("no_device_fall_time_s")):
            why.append(f"the same wearer's no-device walk fell at "
                       f"{r['no_device_fall_time_s']:.2f} s")
        if not _finite(r.get("net_metabolic_umberger_w_per_kg")):
            why.append("the walk with the device has no analysed stride (no metabolic rate)")
        if not _finite(r.get("net_metabolic_umberger_no_device_w_per_kg")):
            why.append("the no-device walk has no analysed stride (no metabolic rate)")
        if why:
            change = r.get("net_metabolic_umberger_change_pct")
            shown = (f"its metabolic change ({change:+.2f} %) rests on that and is not ranked"
                     if _finite(change) else "it has no metabolic change and is not ranked")
            fell = r.get("fell") or _finite(r.get("no_device_fall_time_s"))
            head = "METABOLIC CHANGE ON A FALL" if fell else "NO ANALYSED STRIDE"
            out.append(f"{head}: {r['label']}: " + "; ".join(why)
                       + f": {shown}")
    return out


def caveats(rows) -> list[str]:
    """One line per row that is not an actuator: why its efficiency, battery runtime and ranks
    are not given (``not_comparable_reason``); one per row whose pistons hit their end stops
    or whose torque tracking was poor (:mod:`afo_mj.metrics.device_flags`), whose circuit
    solver accepted unconverged steps, or whose bus drew more than its battery's matched-load
    power."""
    out = [f"NOT COMPARABLE: {r['label']}: {r['not_comparable_reason']}" for r in rows
           if r.get("not_comparable_reason")]
    for r in rows:
        if r.get("end_stop_contact"):
            out.append(f"END-STOP CONTACT: {r['label']}: the pistons hit their stroke ends "
                       f"({1e3 * r['end_stop_contact_time_s_per_stride']:.0f} ms per stride, "
                       f"impulse {r['end_stop_impulse_nm_s_per_stride']:.2f} N*m*s per stride; "
                       f"whole-joint peak {r['peak_torque_incl_end_stops_nm']:.1f} N*m, "
                       f"{r['peak_torque_nm']:.1f} N*m outside contact)")
        if r.get("tracking_poor"):
            out.append(f"POOR TRACKING: {r['label']}: RMS torque error "
                       f"{r['torque_tracking_rmse_nm']:.1f} N*m: it did not deliver the "
                       "assistance asked for")
        out += [f"{w.split(':', 1)[0]}: {r['label']}:{w.split(':', 1)[1]}"
                for w in solver_warnings(r.get("newton_unconverged_steps"))
                + battery_warnings(r.get("battery_overload_steps"))]
    return out + effort_caveats(rows)


def format_tables(comp) -> str:
    """The tables as printed on stdout (the energy chain, the device and walker, and, when a
    row is on the muscle walker, the wearer's effort beside the battery energy), with the
    definitions and the caveats (:func:`caveats`, :func:`effort_caveats`)."""
    h2, b2 = loss_table(comp.rows, comp.columns)
    notes = caveats(comp.rows)
    effort = (("\n\nthe wearer's effort (muscle walker) and the battery energy:\n"
               + _text(*headline_table(comp.rows, EFFORT))) if _any_muscle(comp.rows) else "")
    return ("energy chain (per mean analysed stride):\n"
            + _text(*headline_table(comp.rows, CHAIN))
            + "\n\ndevice and walker:\n" + _text(*headline_table(comp.rows, DEVICE))
            + effort + "\n\n" + _definitions(comp.rows)
            + ("\n" + "\n".join(notes) if notes else "")
            + "\n\nwhere the electrical energy goes, per stride [J]:\n" + _text(h2, b2))


def _markdown_report(comp) -> str:
    h2, b2 = loss_table(comp.rows, comp.columns)
    names = ", ".join(f"`{s['file']}`" for s in comp.scenarios)
    notes = caveats(comp.rows)
    return (f"# Device comparison\n\nScenarios: {names}; the `assist` condition, per mean "
            "analysed stride. Full table: `comparison.csv`.\n\n"
            + _definitions(comp.rows).replace("\n", "\n\n") + "\n\n"
            + "".join(f"> **{n}**\n>\n" for n in notes) + ("\n" if notes else "")
            + "## Energy chain\n\n"
            + _markdown(*headline_table(comp.rows, CHAIN))
            + "\n\n## Device and walker\n\n" + _markdown(*headline_table(comp.rows, DEVICE))
            + (("\n\n## The wearer's effort (muscle walker) and the battery energy\n\n"
                + _markdown(*headline_table(comp.rows, EFFORT))) if _any_muscle(comp.rows)
               else "")
            + "\n\n## Where the electrical energy goes (J/stride)\n\n" + _markdown(h2, b2)
            + "\n\nelectrical drawn = losses + stored change + regenerated + net mechanical "
              "output (to the energy balance error).\n")


def _csv_value(v):
    if v is None or (isinstance(v, float) and not math.isfinite(v)):
        return ""
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, float):
        return repr(v)
    return v


def plot_comparison(comp, path: Path) -> None:
    """``comparison.png``: energy split per device (left), tracking / pressure / mass (right)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

    rows = comp.rows
    n = len(rows)
    labels = [r["label"] for r in rows]
    loss_cols = [c for c in comp.columns if c.startswith("loss_")]
    segs = [(c, c[len("loss_"):-len("_j_per_stride")]) for c in loss_cols]
    segs += [("stored_j_per_stride", "stored (change)"),
             ("electrical_regenerated_j_per_stride", "regenerated"),
             ("mechanical_net_j_per_stride", "mechanical out (net; < 0: absorbed from the ankle)")]
    cmap = plt.get_cmap("tab20")
    colors = {c: cmap(i % 20) for i, (c, _) in enumerate(segs[:-3])}
    colors["stored_j_per_stride"] = "0.75"
    colors["electrical_regenerated_j_per_stride"] = "0.45"
    colors["mechanical_net_j_per_stride"] = "#1a7f37"

    fig = plt.figure(figsize=(16, 2.2 + 0.55 * n + 0.12 * len(segs)))
    gs = fig.add_gridspec(1, 4, width_ratios=[3.4, 1, 1, 1], wspace=0.08)
    ax = fig.add_subplot(gs[0])
    y = np.arange(n)[::-1]
    pos = np.zeros(n)
    neg = np.zeros(n)
    for c, name in segs:
        v = np.array([r.get(c) if _finite(r.get(c)) else 0.0 for r in rows], dtype=float)
        if not np.any(v != 0):
            continue
        left = np.where(v >= 0, pos, neg)
        hatch = "//" if c == "mechanical_net_j_per_stride" else None
        ax.barh(y, v, left=left, color=colors[c], edgecolor="white", linewidth=0.5,
                hatch=hatch, label=name, height=0.62)
        pos += np.clip(v, 0, None)
        neg += np.clip(v, None, 0)
    elec = np.array([r.get("electrical_j_per_stride") if _finite(r.get("electrical_j_per_stride"))
                     else np.nan for r in rows], dtype=float)
    ax.scatter(elec, y, marker="|", s=400, color="k", zorder=5, label="electrical drawn")
    for yi, r, e, right in zip(y, rows, elec, pos):
        eff = r.get("efficiency_total")
        if np.isfinite(e):
            tail = (f"\n eff net {100 * eff:.1f} %" if _finite(eff)
                    else f"\n efficiency not comparable ({r.get('mechanical_role') or 'unknown'})")
            ax.text(right, yi, f" {e:.1f} J drawn" + tail, va="center", ha="left", fontsize=8)
    lo, hi = float(neg.min()), float(np.nanmax(np.append(pos, elec)))
    ax.set_xlim(min(lo * 1.05, 0.0), hi * 1.3 + 1e-9)
    ax.set_yticks(y)
    ax.set_yticklabels(labels)
    ax.axvline(0, color="k", lw=0.6)
    ax.set_xlabel("energy per stride [J] (electrical drawn = losses + stored + regenerated "
                  "+ net mechanical)")
    ax.set_title("Where the electrical energy goes (assist, per analysed stride)")
    ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.18), ncol=5, fontsize=7,
              frameon=False)
    ax.set_ylim(-0.7, n - 0.2)
    for i, (col, title, unit, extra) in enumerate((
            ("torque_tracking_rmse_nm", "torque tracking RMSE", "N*m", None),
            ("peak_pressure_mpa", "peak pressure", "MPa", None),
            ("mass_total_kg", "mass", "kg", "mass_at_ankle_kg"))):
        a = fig.add_subplot(gs[i + 1], sharey=ax)
        v = np.array([r.get(col) if _finite(r.get(col)) else np.nan for r in rows], float)
        a.barh(y, v, color="#4c72b0", height=0.62, label="total" if extra else None)
        if extra:
            e = np.array([r.get(extra) if _finite(r.get(extra)) else np.nan for r in rows],
                         float)
            a.barh(y, e, color="#dd8452", height=0.62, label="at the ankle")
            a.legend(fontsize=7, loc="lower right")
        for yi, vi in zip(y, v):
            if np.isfinite(vi):
                a.text(vi, yi, f" {vi:.2f}", va="center", fontsize=7)
        a.set_title(title, fontsize=10)
        a.set_xlabel(unit)
        a.tick_params(labelleft=False)
        finite = v[np.isfinite(v)]
        if finite.size:
            a.set_xlim(0, 1.3 * max(float(finite.max()), 1e-9))
    fig.savefig(path, dpi=110, bbox_inches="tight")
    plt.close(fig)


def write_comparison(out_dir, comp, run_info: dict | None = None) -> Path:
    """Write the four files into ``out_dir`` at once; returns the directory."""
    from afo_mj.outputs.gait_report import json_ready
    from afo_mj.outputs.result_dir import write_atomically

    def writer(tmp: Path) -> None:
        with (tmp / "comparison.csv").open("w", newline="", encoding="utf-8") as f:
            w = csv.writer(f)
            w.writerow(comp.columns)
            for r in comp.rows:
                w.writerow([_csv_value(r.get(c)) for c in comp.columns])
        doc = {"columns": comp.columns,
               "rows": [{c: r.get(c) for c in comp.columns} for r in comp.rows],
               "scenarios": comp.scenarios,
               "run_info": {"wall_time_s": comp.wall_time_s, **(run_info or {})},
               "note": "assist condition only; per stride = whole-run ledger scaled to the "
                       "mean analysed stride; " + _definitions(comp.rows).replace("\n", " ")
                       + " null = not applicable to that device (see not_comparable_reason)"}
        text = json.dumps(json_ready(doc), indent=2, allow_nan=False)
        (tmp / "comparison.json").write_text(text + "\n", encoding="utf-8")
        (tmp / "comparison.md").write_text(_markdown_report(comp), encoding="utf-8")
        plot_comparison(comp, tmp / "comparison.png")

    return write_atomically(out_dir, writer)
