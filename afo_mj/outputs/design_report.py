"""Outputs of the design tool (``afo-mj design``): JSON, Markdown, CSV tables, figures and the
best design as scenarios that ``afo-mj run`` accepts.

Everything is written into one directory at once (:func:`afo_mj.outputs.result_dir.
write_atomically`): a failure leaves the directory as it was.

Files (``DIR``):

* ``design.json`` — the :class:`~afo_mj.design.design_document.DesignSummary`
  (:func:`build_summary`, format ``afo_mj design v1``): requirements, duty cycle, verdict (or the
  infeasibility explanation and the binding constraint), the best design with its mass
  breakdown (ankle / waist), efficiencies per stage, losses per stride, heat, temperatures,
  runtime, the predicted bench figures and the mass check against the simulator's mass budget,
  the ranked designs, the studies, the assumptions; ``walk_check``: the device's quasi-static
  work on the ankle over the written walk's gait
  (:func:`afo_mj.design.system_design.walk_work_check`) and ``warnings`` (a device that
  brakes that walk; also at the top of ``design.md``, in the description of
  ``design_walk.toml`` and on stderr); no NaN (``null`` instead);
* ``design.md`` — the same for reading;
* ``designs.csv`` — the ranked feasible designs, one row each;
* ``design_bench.toml`` — the best design on the torque–velocity bench
  (``afo-mj run DIR/design_bench.toml --out X``); ``design_walk.toml`` — walking with it
  (based on ``scenarios/gait_assist_hafo.toml``); pump-controlled designs only; the documents
  are built by :mod:`afo_mj.design.design_scenarios` (re-exported here);
* ``study_pressure.csv/.png``, ``study_oil.csv/.png``, ``study_power.csv/.png`` — the
  design-guideline studies; ``hose_bore_tradeoff.csv/.png`` — the hose bore trade-off of the
  best design;
* ``requirements.toml`` — the requirements as read.
"""

from __future__ import annotations

import csv
import dataclasses
import json
from pathlib import Path

import numpy as np

from afo_mj.design.design_document import (DESIGN_FORMAT, DesignSummary, design_summary,
                                           jsonable)
from afo_mj.design.design_requirements import toml_dumps
from afo_mj.design.design_scenarios import bench_scenario, walk_scenario
from afo_mj.outputs.result_dir import write_atomically

__all__ = ["build_summary", "summary_text", "write_design_report", "bench_scenario",
           "walk_scenario", "jsonable", "DesignSummary"]

FORMAT = DESIGN_FORMAT

#: The :class:`~afo_mj.design.design_document.DesignSummary` of a design computation
#: (``design.json``: its ``to_json()``, the files written added by
#: :func:`write_design_report`).
build_summary = design_summary


def summary_text(s: dict, out_dir) -> str:
    """What ``afo-mj design`` prints."""
    req = s["requirements"]
    lines = [f"afo-mj design: {req['name']} ({s['architecture']}-controlled), "
             f"{s['search']['designs_screened']} designs screened in "
             f"{s['search']['search_wall_s']:.2f} s"]
    if not s["feasible"]:
        lines.append(f"  {s['explanation']}")
        lines.append(f"  binding: {', '.join(s['binding_constraints']) or '-'}")
        lines.append(f"  results: {out_dir}")
        return "\n".join(lines)
    b = s["best"]
    lines += [
        f"  best: {b['total_kg']:.3f} kg ({b['ankle_kg']:.3f} kg at the ankle, "
        f"{b['waist_kg']:.3f} kg at the waist)",
        f"  {b['operating_pressure_pa'] / 1e6:.1f} MPa, bore {b['cylinder_bore_m'] * 1e3:.1f} mm"
        f" × 2, pulley {b['pulley_radius_m'] * 1e3:.1f} mm, hose {b['hose_bore_m'] * 1e3:.2f} mm"
        f", pump {b['pump_displacement_m3_rev'] * 1e6:.3f} cm³/rev, {b['oil']}, motor "
        f"{b['motor_rated_power_w']:.0f} W class, battery {b['battery_capacity_ah']:.2f} Ah",
        f"  system efficiency {b['system_efficiency'] * 100:.1f} %, heat {b['heat_w']:.1f} W, "
        f"surface {b['surface_temperature_k'] - 273.15:.1f} °C, runtime {b['runtime_h']:.2f} h",
    ]
    if "predicted_bench" in s:
        pb = s["predicted_bench"]
        lines.append(f"  predicted bench: stall {pb['stall_torque_nm']:.1f} N*m, no-load "
                     f"{pb['no_load_speed_deg_s']:.1f} deg/s; mass budget of the written "
                     f"preset {s['mass_check']['budget_total_kg']:.3f} kg "
                     f"({s['mass_check']['total_rel_difference'] * 100:+.1f} %)")
    if "simulated_bench" in s:
        sb, ag = s["simulated_bench"], s["bench_agreement"]
        lines.append(f"  simulated bench: stall {sb['stall_torque_nm']:.1f} N*m "
                     f"({ag['stall_torque_rel'] * 100:+.2f} %), no-load "
                     f"{sb['no_load_speed_deg_s']:.1f} deg/s "
                     f"({ag['no_load_speed_rel'] * 100:+.2f} %)")
    if "scenarios" in s and "bench" in s["scenarios"]:
        lines.append(f"  run it: afo-mj run {Path(out_dir) / 'design_bench.toml'} --out OUT")
    lines.append(f"  results: {out_dir}")
    return "\n".join(lines)


# -- tables and figures -------------------------------------------------------------------------
def _write_csv(path: Path, rows: list[dict]) -> None:
    if not rows:
        path.write_text("", encoding="utf-8")
        return
    keys = list(dict.fromkeys(k for r in rows for k in r))
    with path.open("w", newline="", encoding="utf-8") as fh:
        w = csv.DictWriter(fh, fieldnames=keys)
        w.writeheader()
        for r in rows:
            w.writerow({k: ("" if r.get(k) is None else r.get(k)) for k in keys})


def _flat(row: dict, prefix: str = "") -> dict:
    out = {}
    for k, v in row.items():
        if isinstance(v, dict):
            out.update(_flat(v, f"{prefix}{k}."))
        else:
            out[prefix + k] = v
    return out


def _plot_study(path: Path, rows: list[dict], xkey: str, xlabel: str, title: str,
                xscale: float = 1.0, categorical: bool = False, logx: bool = False) -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    rows = [r for r in rows if r.get("total_kg") is not None]
    fig, ax = plt.subplots(1, 3, figsize=(13, 3.8))
    if not rows:
        for a_ in ax:
            a_.text(0.5, 0.5, "no feasible design", ha="center", va="center")
        fig.savefig(path, dpi=110)
        plt.close(fig)
        return
    x = (np.arange(len(rows)) if categorical
         else np.array([r[xkey] for r in rows], dtype=float) * xscale)
    def col(k):
        return np.array([np.nan if r.get(k) is None else r[k] for r in rows], dtype=float)
    ax[0].plot(x, col("total_kg"), "o-", label="total")
    ax[0].plot(x, col("waist_kg"), "s--", label="at the waist")
    ax[0].plot(x, col("ankle_kg"), "^--", label="at the ankle")
    ax[0].set_ylabel("mass, one side [kg]")
    ax[0].legend(fontsize=8)
    for k, lab in (("system_efficiency", "system"), ("pump_efficiency", "pump"),
                   ("motor_efficiency", "motor"), ("lines_efficiency", "lines"),
                   ("cylinders_efficiency", "cylinders")):
        ax[1].plot(x, col(k) * 100.0, "o-", label=lab)
    ax[1].set_ylabel("efficiency over the stride [%]")
    ax[1].legend(fontsize=8)
    ax[2].plot(x, col("hydraulic_power_density_w_kg"), "o-", color="C3")
    ax[2].set_ylabel("hydraulic power density [W/kg]", color="C3")
    a2 = ax[2].twinx()
    a2.plot(x, col("system_energy_density_wh_kg"), "s--", color="C4")
    a2.set_ylabel("system energy density [Wh/kg]", color="C4")
    for a_ in ax:
        a_.set_xlabel(xlabel)
        a_.grid(alpha=0.3)
        if categorical:
            a_.set_xticks(x)
            a_.set_xticklabels([str(r[xkey]) for r in rows], fontsize=8)
        if logx:
            a_.set_xscale("log")
    fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def _plot_hose(path: Path, hose: dict) -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    x = np.asarray(hose["hose_bore_m"]) * 1e3
    fig, ax = plt.subplots(1, 2, figsize=(10, 3.8))
    ax[0].plot(x, hose["total_kg"], "o-", label="motor held, battery re-sized")
    feas = np.asarray(hose["feasible"], dtype=bool)
    ax[0].plot(x[~feas], np.asarray(hose["total_kg"])[~feas], "rx",
               label="motor held: a constraint fails")
    re_ = np.asarray(hose["total_reoptimised_kg"], dtype=float)
    ok = np.isfinite(re_)
    ax[0].plot(x[ok], re_[ok], "s--", color="C2", ms=4, label="lightest feasible motor")
    k = int(np.argmin(np.where(ok, re_, np.inf))) if np.any(ok) else int(np.argmin(
        hose["total_kg"]))
    ax[0].axvline(x[k], color="k", lw=0.8, ls=":")
    ax[0].set_ylabel("mass, one side [kg]")
    ax[0].legend(fontsize=8)
    ax[1].plot(x, hose["hoses_kg"], "o-", label="hoses with oil [kg]")
    ax[1].plot(x, hose["battery_kg"], "s-", label="battery [kg]")
    ax1 = ax[1].twinx()
    ax1.semilogy(x, hose["line_loss_j_per_stride"], "^--", color="C3")
    ax1.set_ylabel("line loss [J/stride]", color="C3")
    ax[1].legend(fontsize=8)
    for a_ in ax:
        a_.set_xlabel("hose bore [mm]")
        a_.grid(alpha=0.3)
    fig.suptitle("hose bore trade-off of the best design: hose and oil mass against the "
                 "battery that pays for the viscous line loss", fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


# -- markdown -----------------------------------------------------------------------------------
def _md(s: dict) -> str:
    req = s["requirements"]
    L = [f"# Design: {req['name']}", "", req.get("description") or "", "",
         f"Architecture: **{s['architecture']}-controlled**. Duty cycle: "
         f"{s['duty_cycle']['note']}. Search: {s['search']['designs_screened']} designs "
         f"screened in {s['search']['search_wall_s']:.2f} s.", ""]
    if not s["feasible"]:
        L += ["## Infeasible", "", s["explanation"], "",
              f"Binding: {', '.join(s['binding_constraints']) or '-'}", "",
              "Designs ruled out per constraint:", ""]
        L += [f"* {k}: {v}" for k, v in s["designs_ruled_out_by_constraint"].items()]
        return "\n".join(L) + "\n"
    b = s["best"]
    for w in s.get("warnings") or []:
        L += ["## WARNING", "", f"**{w}**", ""]
    wc = s.get("walk_check")
    if wc:
        works = "; ".join(f"{k}: {v['positive_work_j_per_stride']:.1f} / "
                          f"{v['negative_work_j_per_stride']:.1f} / "
                          f"{v['net_work_j_per_stride']:.1f}"
                          for k, v in wc["conditions"].items())
        L += [f"Written walk check (`design_walk.toml`, {wc['gait']} gait, {wc['model']}): "
              f"device work on the ankle +/−/net J/stride {works}; no-load speed "
              f"{wc['no_load_speed_deg_s']:.1f} deg/s against the gait's peak plantarflexion "
              f"velocity {wc['peak_plantarflexion_velocity_deg_s']:.1f} deg/s.", ""]
    L += ["## Best design", "", "| variable | value |", "|---|---|",
          f"| operating pressure | {b['operating_pressure_pa'] / 1e6:.2f} MPa "
          f"(relief cracks at {b['relief_cracking_pa'] / 1e6:.2f} MPa) |",
          f"| cylinders | 2 × bore {b['cylinder_bore_m'] * 1e3:.1f} mm, cable "
          f"{b['cable_diameter_m'] * 1e3:.2f} mm, stroke {b['cylinder_stroke_m'] * 1e3:.1f} mm |",
          f"| pulley radius | {b['pulley_radius_m'] * 1e3:.1f} mm (A_e r = "
          f"{b['torque_per_pressure_m3']:.3e} m³) |",
          f"| hoses | 2 × {b['hose_bore_m'] * 1e3:.2f} mm bore |",
          f"| pump | {b['pump_displacement_m3_rev'] * 1e6:.3f} cm³/rev |",
          f"| oil | {b['oil']} |",
          f"| motor | {b['motor_rated_power_w']:.0f} W class, K = "
          f"{b['torque_constant_nm_a'] * 1e3:.1f} mN·m/A, R = {b['resistance_ohm']:.3f} Ω, "
          f"current limit {b['current_limit_a']:.2f} A |",
          f"| battery | {req['cells_series']}S {b['battery_capacity_ah']:.2f} Ah "
          f"{req['battery_chemistry']} |", "",
          "### Mass (one side)", "", "| part | kg | worn at |", "|---|---|---|"]
    ankle = {"cylinders", "shank_cuff_struts", "pulley_bearings", "foot_plate"}
    for k, v in b["mass_kg"].items():
        L.append(f"| {k} | {v:.3f} | {'ankle' if k in ankle else 'waist'} |")
    L += [f"| **total** | **{b['total_kg']:.3f}** | ankle {b['ankle_kg']:.3f}, waist "
          f"{b['waist_kg']:.3f} |", "",
          "### Efficiency over the stride", "",
          "| stage | efficiency |", "|---|---|"]
    for k, v in b["efficiency"].items():
        L.append(f"| {k} | {'-' if v is None else f'{v * 100:.1f} %'} |")
    se = b["system_efficiency"]
    L += [f"| **system** (positive ankle work / chemical energy) | "
          f"**{'-' if se is None else f'{se * 100:.1f} %'}** |", "",
          "Losses per stride (J): " + ", ".join(f"{k} {v:.2f}" for k, v in
                                                b["losses_j_per_stride"].items()), "",
          f"Heat {b['heat_w']:.2f} W mean ({b['heat_to_oil_w']:.2f} W into the oil); steady "
          f"oil and pack surface {b['surface_temperature_k']:.1f} K "
          f"({b['surface_temperature_k'] - 273.15:.1f} °C, limit "
          f"{req['max_surface_temperature_k'] - 273.15:.1f} °C) through "
          f"{b['pack_resistance_k_w']:.2f} K/W. Runtime {b['runtime_h']:.2f} h "
          f"({b['runtime_strides']:.0f} strides); mean walking power "
          f"{b['mean_walking_power_w']:.1f} W.", "",
          f"Hydraulic power density {b['hydraulic_power_density_w_kg']:.0f} W/kg (rated "
          f"{b['rated_output_power_w']:.0f} W over {b['hydraulic_system_kg']:.3f} kg of motor, "
          f"pump, manifold, hoses, cylinders and pulley); system energy density "
          f"{b['system_energy_density_wh_kg']:.2f} Wh/kg.", ""]
    if "predicted_bench" in s:
        pb, mc = s["predicted_bench"], s["mass_check"]
        L += ["### As the simulator's device", "",
              f"Written as `design_bench.toml` (`afo-mj run DIR/design_bench.toml --out OUT`) "
              f"and `design_walk.toml`, `[device] preset = \"hafo\"` with "
              f"{len(s['device']['params'])} overrides.", "",
              "| figure | predicted | simulated |", "|---|---|---|"]
        sb = s.get("simulated_bench") or {}
        st = f"{sb['stall_torque_nm']:.2f}" if sb else "(run with --verify)"
        sp = f"{sb['no_load_speed_deg_s']:.2f}" if sb else ""
        L += [f"| stall torque [N·m] | {pb['stall_torque_nm']:.2f} | {st} |",
              f"| no-load speed [deg/s] | {pb['no_load_speed_deg_s']:.2f} | {sp} |",
              f"| mass, total [kg] | {mc['design_total_kg']:.3f} | {mc['budget_total_kg']:.3f} "
              f"(mass budget, {mc['total_rel_difference'] * 100:+.1f} %) |",
              f"| mass at the ankle [kg] | {mc['design_ankle_kg']:.3f} | "
              f"{mc['budget_ankle_kg']:.3f} ({mc['ankle_rel_difference'] * 100:+.1f} %) |", ""]
    L += ["## Ranked designs", "",
          "| # | kg | ankle kg | MPa | bore mm | arm mm | hose mm | pump cm³ | oil | motor W | "
          "η | surface °C | h |", "|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for k, r in enumerate(s["ranked"][:10]):
        eta = "-" if r["system_efficiency"] is None else f"{r['system_efficiency'] * 100:.1f}"
        L.append(f"| {k + 1} | {r['total_kg']:.3f} | {r['ankle_kg']:.3f} | "
                 f"{r['operating_pressure_pa'] / 1e6:.1f} | {r['cylinder_bore_m'] * 1e3:.1f} | "
                 f"{r['pulley_radius_m'] * 1e3:.1f} | {r['hose_bore_m'] * 1e3:.2f} | "
                 f"{r['pump_displacement_m3_rev'] * 1e6:.3f} | {r['oil']} | "
                 f"{r['motor_rated_power_w']:.0f} | {eta} | "
                 f"{r['surface_temperature_k'] - 273.15:.1f} | {r['runtime_h']:.2f} |")
    st = s.get("studies")
    if st:
        L += ["", "## Design guidelines", "",
              "Lightest feasible design per operating pressure (`study_pressure.csv/.png`):", "",
              "| MPa | kg | system η | pump η | lines η | W/kg | Wh/kg |",
              "|---|---|---|---|---|---|---|"]
        for r in st["pressure"]:
            L.append(f"| {r['operating_pressure_pa'] / 1e6:.1f} | {r['total_kg']:.3f} | "
                     f"{_pct(r['system_efficiency'])} | {_pct(r['pump_efficiency'])} | "
                     f"{_pct(r['lines_efficiency'])} | "
                     f"{r['hydraulic_power_density_w_kg']:.0f} | "
                     f"{r['system_energy_density_wh_kg']:.2f} |")
        L += ["", "Per oil grade (`study_oil.csv/.png`): " + "; ".join(
            f"{r['oil']} {r['total_kg']:.3f} kg, η {_pct(r['system_efficiency'])}"
            for r in st["oil"]), "",
            "Per output power (`study_power.csv/.png`): " + "; ".join(
                f"{r['rated_output_power_w']:.0f} W → "
                + (f"{r['total_kg']:.3f} kg, {r['hydraulic_power_density_w_kg']:.0f} W/kg"
                   if r.get("feasible") else f"infeasible ({', '.join(r.get('binding', []))})")
                for r in st["power"])]
    hb = s.get("hose_bore_tradeoff")
    if hb:
        fo = hb.get("feasible_optimum_hose_bore_m")
        L += ["", f"Hose bore trade-off (`hose_bore_tradeoff.csv/.png`): with the motor held, "
                  f"lightest at {hb['optimum_hose_bore_m'] * 1e3:.2f} mm "
                  f"({'inside' if hb['interior_optimum'] else 'at an end of'} the range); "
                  f"with each bore's lightest feasible motor, at "
                  + (f"{fo * 1e3:.2f} mm." if fo else "no feasible bore.")]
    return "\n".join(L) + "\n"


def _pct(v) -> str:
    return "-" if v is None else f"{v * 100:.1f} %"


def write_design_report(out_dir, result, summary: DesignSummary, written: dict | None,
                        study: dict | None, hose: dict | None, top: int = 10,
                        requirements_text: str | None = None) -> DesignSummary:
    """Write every file of the module docstring into ``out_dir`` at once; returns the
    document written as ``design.json`` (``summary`` with the files written).
    ``requirements_text``: the requirements as read (with any ``--set`` applied)."""
    req = result.requirements
    done: list[DesignSummary] = []

    def writer(tmp: Path) -> None:
        files = ["design.json", "design.md"]
        text = requirements_text
        if text is None and req.source_path is not None:
            try:
                text = Path(req.source_path).read_text(encoding="utf-8")
            except OSError:
                text = None
        if text is not None:
            (tmp / "requirements.toml").write_text(text, encoding="utf-8")
            files.append("requirements.toml")
        if result.feasible:
            rows = [_flat(result.row(k)) for k in range(min(len(result.order), max(top, 50)))]
            _write_csv(tmp / "designs.csv", rows)
            files.append("designs.csv")
        if written is not None:
            ov = written["overrides"]
            (tmp / "design_bench.toml").write_text(toml_dumps(bench_scenario(req, ov)),
                                                   encoding="utf-8")
            (tmp / "design_walk.toml").write_text(toml_dumps(walk_scenario(
                req, ov, written["predicted_bench"]["stall_torque_nm"],
                (written.get("walk_check") or {}).get("warning"))), encoding="utf-8")
            files += ["design_bench.toml", "design_walk.toml"]
        if study is not None:
            for key, xkey, xl, kw in (
                    ("pressure", "operating_pressure_pa", "operating pressure [MPa]",
                     {"xscale": 1e-6}),
                    ("oil", "oil", "oil grade", {"categorical": True}),
                    ("power", "rated_output_power_w", "rated output power [W]",
                     {"logx": True})):
                _write_csv(tmp / f"study_{key}.csv", study[key])
                _plot_study(tmp / f"study_{key}.png", study[key], xkey, xl,
                            f"{req.name}: lightest feasible design per {xl.split(' [')[0]}",
                            **kw)
                files += [f"study_{key}.csv", f"study_{key}.png"]
        if hose is not None:
            n = len(hose["hose_bore_m"])
            _write_csv(tmp / "hose_bore_tradeoff.csv",
                       [{k: jsonable(np.asarray(v)[i]) for k, v in hose.items()}
                        for i in range(n)])
            _plot_hose(tmp / "hose_bore_tradeoff.png", hose)
            files += ["hose_bore_tradeoff.csv", "hose_bore_tradeoff.png"]
        doc = dataclasses.replace(summary, files=tuple(files))
        data = doc.to_json()
        (tmp / "design.json").write_text(json.dumps(data, indent=1, allow_nan=False),
                                         encoding="utf-8")
        (tmp / "design.md").write_text(_md(data), encoding="utf-8")
        done.append(doc)

    write_atomically(out_dir, writer)
    return done[-1]
