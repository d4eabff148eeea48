"""Regenerate the measured tables of the documentation from the runs that produce them.

Each measured table (or measured sentence) of the documents (docs/results.md,
docs/design_tool.md; README.md links to them) sits between

    <!-- generated:NAME begin -->
    ...
    <!-- generated:NAME end -->

in the one file its block names (``Block.file``; ``--list`` shows them), and is rewritten from
a fresh in-process run of its scenarios, through the functions the ``afo-mj`` CLI itself calls
(``load_scenario`` → ``simulate_walk`` → ``analyse_gait``, ``run_device_scenario``,
``run_bench_scenario``, ``load_compare_items`` → ``run_comparison`` as ``afo-mj compare`` does,
``read_requirements`` → ``compute_design`` → ``build_summary`` as ``afo-mj design`` does);
nothing parses CLI output. Under each table a line states the command that produced it and
the date.

    python tools/readme_tables.py                 # run everything, rewrite every block
    python tools/readme_tables.py --only NAME     # one block (repeatable)
    python tools/readme_tables.py --check         # exit 1 naming the blocks that drifted
    python tools/readme_tables.py --list          # block names, their files, what each runs

Blocks that share runs share them: the graded plantarflexor-weakness table takes its 100 % and
50 % rows from the very runs of ``walk_healthy`` and ``walk_weak_plantarflexors`` that the
scenario table shows (one in-process cache keyed by scenario file and overrides), so the two
tables cannot disagree. ``--cache DIR`` also keeps each run's JSON-ready result on disk, so
that ``--only`` calls in separate processes reuse them (delete DIR to rerun).

**What counts as a change.** A rewrite puts in the fresh text whenever it differs from the
file's (the date line aside: a block regenerated on another day with the same text keeps its
old date). ``--check`` compares *at the printed precision*, so that another machine's float
rounding does not fail it: the words must be identical and every number equal within one unit
of its last printed digit (a value on a rounding boundary may print either way); numbers in
exponent notation below 1e-8 in magnitude (energy-balance errors: round-off) are equal to each
other. A drifted block is listed with the lines that differ. ``tests/test_docs_current.py``
runs ``--check`` as part of the test suite (marked slow), so CI fails when a table drifts.

Each block has a pure formatting function ``format_NAME(results) -> markdown`` working on
plain dicts (SI units in the key names, ``None`` for a missing value, shown as "–"), so the
formatting is tested without running a walk (``tests/test_readme_tables.py``).
"""

from __future__ import annotations

import argparse
import datetime as _dt
import json
import math
import re
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable, Mapping

ROOT = Path(__file__).resolve().parents[1]
MISSING = "–"
TOOL = "tools/readme_tables.py"

# --------------------------------------------------------------------------------------------
# formatting helpers (pure)
# --------------------------------------------------------------------------------------------


def num(x: Any, fmt: str = ".2f", scale: float = 1.0) -> str:
    """``x × scale`` formatted, or "–" for None/NaN; a mean-SD entry (``{"mean": …}``) gives
    its mean. A negative number gets a real minus sign (−), as the documents write them."""
    if isinstance(x, Mapping):
        x = x.get("mean")
    if x is None:
        return MISSING
    try:
        v = float(x) * scale
    except (TypeError, ValueError):
        return MISSING
    if not math.isfinite(v):
        return MISSING
    s = f"{v:{fmt}}"
    if s.startswith("-"):
        s = ("−" + s[1:]) if float(s) != 0.0 else s[1:]
    return s


def table(header: list[str], rows: list[list[str]]) -> str:
    """A GitHub markdown table."""
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(r) + " |" for r in rows]
    return "\n".join(lines)


def pct(fraction: Any) -> str:
    """A strength fraction as "50 %"."""
    if fraction is None:
        return MISSING
    return f"{100 * float(fraction):g} %"


def fall_text(r: Mapping) -> str:
    """"falls in stride N (t = X s)" for a run that fell before an analysable stride."""
    t = r.get("fall_time_s")
    n = r.get("completed_strides")
    where = "" if n is None else f" in stride {int(n) + 1}"
    return f"falls{where}" + ("" if t is None else f" (t = {num(t, '.2f')} s)")


# --------------------------------------------------------------------------------------------
# block formatters (pure: results dict → markdown)
# --------------------------------------------------------------------------------------------

# Winter (2009) normal cadence, as published (not a run): the reference row of the scenario
# table. Speed from Winter's stride 1.51 m at 105.3 steps/min.
WINTER_PUBLISHED = {"peak_ankle_plantarflexor_moment_nm_per_kg": 1.69,
                    "peak_ankle_power_w_per_kg": 3.24,
                    "ankle_push_off_positive_work_j_per_kg": 0.345, "speed_m_s": 1.325}

SCENARIO_ROWS = ("walk_healthy", "walk_weak_plantarflexors", "walk_foot_drop",
                 "walk_spastic_ankle", "walk_child_healthy")


def _walk_label(name: str, r: Mapping) -> str:
    """"`walk_weak_plantarflexors` (50 %)", "`walk_child_healthy` (25 kg, 1.2 m)"."""
    notes = []
    pf, df = r.get("plantarflexor_strength_fraction"), r.get("dorsiflexor_strength_fraction")
    if pf is not None and pf < 1.0:
        notes.append(pct(pf))
    if df is not None and df < 1.0:
        notes.append(pct(df))
    m, h = r.get("body_mass_kg"), r.get("height_m")
    if m is not None and h is not None and (abs(m - 75.0) > 1e-9 or abs(h - 1.75) > 1e-9):
        notes.append(f"{m:g} kg, {h:g} m")
    return f"`{name}`" + (f" ({', '.join(notes)})" if notes else "")


def format_scenarios(results: Mapping[str, Mapping]) -> str:
    """The "What it reproduces" table: one row per scenario of :data:`SCENARIO_ROWS`
    (``results[name]`` = :func:`walk_result`), Winter's published figures on top."""
    header = ["scenario", "angle RMS vs Winter hip / knee / ankle [deg]",
              "peak ankle plantarflexor moment [N·m/kg]", "peak push-off power [W/kg]",
              "push-off work [J/kg]", "push-off peak plantarflexion [deg]",
              "min toe clearance [cm]", "speed [m/s]", "residual force RMS [% BW]"]
    w = WINTER_PUBLISHED
    rows = [["Winter normal (reference)", MISSING,
             num(w["peak_ankle_plantarflexor_moment_nm_per_kg"]),
             num(w["peak_ankle_power_w_per_kg"]),
             num(w["ankle_push_off_positive_work_j_per_kg"], ".3f"), MISSING, MISSING,
             num(w["speed_m_s"], ".3f"), MISSING]]
    healthy = results.get("walk_healthy", {})
    for name in SCENARIO_ROWS:
        r = results.get(name)
        if r is None:
            rows.append([f"`{name}`"] + [MISSING] * 8)
            continue
        label = _walk_label(name, r)
        if r.get("fell"):
            rows.append([label, fall_text(r)] + [""] * 7)
            continue
        rms = " / ".join(num(r.get(f"{j}_angle_rms_error_deg"), ".1f")
                         for j in ("hip", "knee", "ankle"))
        moment = num(r.get("peak_ankle_plantarflexor_moment_nm_per_kg"))
        h = r.get("height_m")
        hm = healthy.get("peak_ankle_plantarflexor_moment_nm_per_kg")
        if name != "walk_healthy" and h is not None and abs(h - 1.75) > 1e-9 and hm is not None:
            moment += f" (healthy × {h:g}/1.75 = {num(hm * h / 1.75)})"
        rows.append([label, rms, moment, num(r.get("peak_ankle_power_w_per_kg")),
                     num(r.get("ankle_push_off_positive_work_j_per_kg"), ".3f"),
                     num(r.get("push_off_peak_plantarflexion_deg"), ".1f"),
                     num(r.get("min_toe_clearance_m"), ".1f", 100.0),
                     num(r.get("speed_m_s")),
                     num(r.get("residual_force_rms_percent_body_weight"), ".1f")])
    return table(header, rows)


WEAKNESS_FRACTIONS = (1.0, 0.7, 0.6, 0.5, 0.45, 0.4, 0.35)


def format_plantarflexor_weakness(results: Mapping[float, Mapping]) -> str:
    """Graded plantarflexor weakness: ``results[fraction]`` = :func:`walk_result`."""
    header = ["plantarflexor strength", "push-off work [J/kg]",
              "push-off peak plantarflexion [deg]", "speed [m/s]",
              "peak ankle plantarflexor moment [N·m/kg]", "ankle angle RMS vs Winter [deg]"]
    rows = []
    for f in sorted(results, reverse=True):
        r = results[f]
        label = pct(f) + {1.0: " (`walk_healthy`)", 0.5: " (`walk_weak_plantarflexors`)"
                          }.get(float(f), "")
        if r is None:
            rows.append([label] + [MISSING] * 5)
        elif r.get("fell"):
            rows.append([label, fall_text(r)] + [""] * 4)
        else:
            rows.append([label, num(r.get("ankle_push_off_positive_work_j_per_kg"), ".3f"),
                         num(r.get("push_off_peak_plantarflexion_deg"), ".1f"),
                         num(r.get("speed_m_s")),
                         num(r.get("peak_ankle_plantarflexor_moment_nm_per_kg")),
                         num(r.get("ankle_angle_rms_error_deg"), ".1f")])
    return table(header, rows)


IDEAL_ASSIST_PEAKS_NM = {"walk_healthy": (20.0, 40.0, 60.0),
                         "walk_weak_plantarflexors": (20.0, 40.0)}
WORN_MASSES = {"0.97 kg at the right ankle": (("shank_cuff_r", 0.50), ("foot_plate_r", 0.47)),
               "HAFO-like 3.3 kg (2.33 kg at the waist)": (("waist", 2.33),
                                                           ("shank_cuff_r", 0.50),
                                                           ("foot_plate_r", 0.47))}


def format_ideal_assist(results: Mapping) -> str:
    """An ideal push-off assist and carried device mass: ``results["assist"][scenario]
    [peak_nm]`` (0 = the unassisted run) and ``results["worn"][label]`` = :func:`walk_result`
    of ``walk_healthy`` / ``walk_weak_plantarflexors``."""
    header = ["walker, condition", "human push-off work [J/kg]",
              "push-off peak plantarflexion [deg]", "speed [m/s]",
              "angle RMS vs Winter hip / knee / ankle [deg]"]
    names = {"walk_healthy": "healthy", "walk_weak_plantarflexors": "weak (50 %)"}

    def row(label, r):
        if r is None:
            return [label] + [MISSING] * 4
        if r.get("fell"):
            return [label, fall_text(r), "", "", ""]
        return [label, num(r.get("ankle_push_off_positive_work_j_per_kg"), ".3f"),
                num(r.get("push_off_peak_plantarflexion_deg"), ".1f"), num(r.get("speed_m_s")),
                " / ".join(num(r.get(f"{j}_angle_rms_error_deg"), ".1f")
                           for j in ("hip", "knee", "ankle"))]
    rows = []
    for name, by_peak in (results.get("assist") or {}).items():
        for peak in sorted(by_peak, key=float):
            cond = "no device" if float(peak) == 0 else f"ideal assist {float(peak):g} N·m"
            rows.append(row(f"{names.get(name, name)}, {cond}", by_peak[peak]))
    for label, r in (results.get("worn") or {}).items():
        rows.append(row(f"healthy, carrying {label}", r))
    return table(header, rows)


BAND_CHANNELS = (("knee_angle_rad", "knee"), ("ankle_angle_rad", "ankle"),
                 ("thigh_angle_rad", "thigh from vertical"), ("hip_angle_rad", "hip"))


def format_schwartz_bands(results: Mapping[str, Mapping]) -> str:
    """Fraction of the cycle inside Schwartz et al. (2008) ±1 SD: ``results`` maps a column
    label (e.g. "`walk_schwartz_free` vs Free") to ``{channel: fraction}``."""
    cols = list(results)
    rows = [[label] + [num((results[c] or {}).get(ch), ".2f") for c in cols]
            for ch, label in BAND_CHANNELS]
    return table(["channel"] + cols, rows)


# what the prototype's publication gives beyond the bench summary's "published" entries
HAFO_PUBLISHED_TEXT = {"mass": "3.3 / 0.97 kg", "step": "not quantified", "bandwidth": "—",
                       "velocity_bandwidth": "—", "position": '"slow"', "balance": ""}


def format_hafo_bench(results: Mapping[str, Mapping]) -> str:
    """The HAFO presets on the test stand: ``results["hafo"]``, ``results["hafo_gait"]`` =
    bench summaries (``bench``: stall torque N·m, no-load speed deg/s, rise time s,
    overshoot %, bandwidths Hz, position rise time s; ``device`` masses; ``energy``
    balance; ``published``)."""
    def b(preset):
        return ((results.get(preset) or {}).get("bench")) or {}

    def d(preset):
        return ((results.get(preset) or {}).get("device")) or {}
    pub = (results.get("hafo") or {}).get("published") or {}

    def col(preset):
        x, m = b(preset), d(preset)
        stall = f"{num(x.get('stall_torque_nm'), '.1f')} N·m"
        if preset == "hafo":
            stall += " (current limit)"
        return [stall, f"{num(x.get('no_load_speed_deg_s'), '.1f')} deg/s",
                f"{num(m.get('mass_total_kg'), '.2f')} / "
                f"{num(m.get('mass_at_ankle_kg'), '.2f')} kg",
                f"{num(x.get('rise_time_s'), '.1f', 1e3)} ms, "
                f"{num(x.get('overshoot_pct'), '.1f')} %"
                .replace(", 0.0 %", ", 0 %"),
                f"{num(x.get('bandwidth_hz'), '.1f')} Hz",
                f"{num(x.get('velocity_bandwidth_hz'), '.0f')} Hz",
                f"{num(x.get('position_rise_time_s'), '.3f')} s",
                num((results.get(preset) or {}).get("energy", {}).get("balance_error_rel"), ".1e")]
    published = [f"{num(pub.get('stall_torque_nm'), 'g')} N·m",
                 f"{num(pub.get('no_load_speed_deg_s'), 'g')} deg/s",
                 HAFO_PUBLISHED_TEXT["mass"], HAFO_PUBLISHED_TEXT["step"],
                 HAFO_PUBLISHED_TEXT["bandwidth"], HAFO_PUBLISHED_TEXT["velocity_bandwidth"],
                 HAFO_PUBLISHED_TEXT["position"], HAFO_PUBLISHED_TEXT["balance"]]
    labels = ["stall torque", "no-load speed", "mass, total / at the ankle",
              "40 N·m isometric step: rise time, overshoot", "open-loop isometric-torque bandwidth",
              "open-loop velocity bandwidth", "closed-loop position step (15°) rise",
              "worst energy-balance error of any bench run"]
    rows = [[lbl, a, p, g]
            for lbl, a, p, g in zip(labels, col("hafo"), published, col("hafo_gait"))]
    return table(["figure", "`hafo` model", "published", "`hafo_gait`"], rows)


def format_stiffness_bench(results: Mapping) -> str:
    """The PHAFO on the stiffness rig: ``results["stiffness"]`` = the bench summary's
    per-stiffness entries (``commanded_nm_per_deg``, ``emulated_nm_per_deg``,
    ``hysteresis_energy_j``, ``peak_torque_nm``, ``peak_supply_pressure_pa``,
    ``energy_balance_error_rel``)."""
    header = ["commanded N·m/deg", "emulated N·m/deg", "hysteresis loop J/cycle",
              "peak torque N·m", "rail MPa", "energy balance"]
    rows = [[num(v.get("commanded_nm_per_deg"), ".1f"), num(v.get("emulated_nm_per_deg"), ".3f"),
             num(v.get("hysteresis_energy_j"), ".2f"), num(v.get("peak_torque_nm"), ".1f"),
             num(v.get("peak_supply_pressure_pa"), ".2f", 1e-6),
             num(v.get("energy_balance_error_rel"), ".0e")]
            for v in results.get("stiffness", {}).values()]
    return table(header, rows)


# loss names of the ledger → the words the tables use; the rest are summed as "other"
POWER_COLUMNS = (("motor_copper", "motor copper"), ("pump_volumetric", "pump leakage"),
                 ("servo_valve_throttling", "servo valve"), ("driver", "driver"),
                 ("pump_mechanical", "pump mech."))


def format_phafo_power(results: Mapping) -> str:
    """Mean electrical power of the PHAFO holding its rail on the stiffness rig, and where it
    goes, per commanded stiffness (W: each loss's energy over the sweep's duration, which is
    ``electrical_in_j / mean_electrical_power_w``)."""
    header = (["commanded N·m/deg", "electrical W"] + [f"{lbl} W" for _, lbl in POWER_COLUMNS]
              + ["other W"])
    rows = []
    for v in results.get("stiffness", {}).values():
        p, e = v.get("mean_electrical_power_w"), v.get("electrical_in_j")
        losses = v.get("losses_j") or {}
        scale = (p / e) if p is not None and e else None
        row = [num(v.get("commanded_nm_per_deg"), ".1f"), num(p, ".0f")]
        for key, _ in POWER_COLUMNS:
            row.append(num(None if scale is None else losses.get(key), ".0f",
                           1.0 if scale is None else scale))
        other = sum(x for k, x in losses.items() if k not in dict(POWER_COLUMNS))
        row.append(num(None if scale is None or not losses else other, ".0f",
                       1.0 if scale is None else scale))
        rows.append(row)
    return table(header, rows)


def _condition_label(cond: str) -> str:
    if cond == "no_device":
        return "no device"
    m = re.fullmatch(r"assist_k(.+)", cond)
    return f"{m.group(1)} N·m/deg" if m else cond


def format_foot_drop(results: Mapping[str, Mapping]) -> str:
    """The child with foot drop and the PHAFO on both ankles: ``results[condition]`` with
    ``swing_mean_ankle_angle_deg``, ``min_toe_clearance_m``, ``push_off_peak_power_w``,
    ``speed_m_s``, ``electrical_in_j_per_stride`` (right side), or a fall. Rows: no device,
    then the stiffnesses ascending."""
    header = ["condition", "mid-swing ankle deg", "min toe clearance mm",
              "push-off peak power W", "speed m/s", "device electrical J/stride (right side)"]

    def key(c):
        m = re.fullmatch(r"assist_k(.+)", c)
        return (0, 0.0) if c == "no_device" else (1, float(m.group(1)) if m else math.inf)
    rows = []
    for cond in sorted(results, key=key):
        r = results[cond]
        if r.get("fell"):
            rows.append([_condition_label(cond), fall_text(r), "", "", "", ""])
            continue
        elec = r.get("electrical_in_j_per_stride")
        rows.append([_condition_label(cond), num(r.get("swing_mean_ankle_angle_deg"), ".1f"),
                     num(r.get("min_toe_clearance_m"), ".1f", 1e3),
                     num(r.get("push_off_peak_power_w"), ".1f"), num(r.get("speed_m_s")),
                     num(elec, ".0f")])
    return table(header, rows)


HAFO_GAIT_ROWS = (("healthy", "no_device", "healthy, no device"),
                  ("healthy", "transparent", "healthy, `hafo_gait` transparent"),
                  ("healthy", "assist", "healthy, `hafo_gait` assist (Zhang, 40 N·m)"),
                  ("prototype", "transparent", "healthy, `hafo` (prototype) transparent"),
                  ("weak", "no_device", "weak plantarflexors (× 0.5), no device"),
                  ("weak", "assist", "weak, `hafo_gait` assist"))
LOSS_WORDS = {"motor_copper": "motor copper", "pump_mechanical": "pump mechanical",
              "line": "line", "pump_volumetric": "pump volumetric", "driver": "driver",
              "battery_internal": "battery", "seal_friction": "seal friction",
              "motor_friction": "motor friction"}


def format_hafo_gait(results: Mapping[str, Mapping]) -> str:
    """The HAFO in gait: ``results[run][condition]`` (runs ``healthy``, ``prototype``,
    ``weak``: :func:`device_walk_result` of the three gait scenarios), then a sentence on
    the assisted healthy run's efficiency and losses."""
    header = ["scenario, condition", "speed m/s", "human ankle +work J/stride",
              "device +/− work J/stride", "push-off work (whole ankle) J/stride",
              "electrical in / balance error"]
    rows = []

    def get(run, cond):
        return (results.get(run) or {}).get(cond)
    h0, w0, wa = get("healthy", "no_device"), get("weak", "no_device"), get("weak", "assist")
    for run, cond, label in HAFO_GAIT_ROWS:
        r = get(run, cond)
        if r is None:
            rows.append([label] + [MISSING] * 5)
            continue
        if r.get("fell"):
            rows.append([label, fall_text(r)] + [""] * 4)
            continue
        po = num(r.get("push_off_work_j_per_stride"), ".1f")
        if (run, cond) == ("weak", "assist") and None not in (h0, w0):
            a, b, c = (x.get("push_off_work_j_per_stride") for x in (wa, w0, h0))
            if None not in (a, b, c) and c != b:
                po += f" ({num(100 * (a - b) / (c - b), '.0f')} % of the deficit restored)"
        if cond == "no_device":
            dev = elec = MISSING
        else:
            dev = (f"{num(r.get('device_positive_work_j_per_stride'), '.1f')} / "
                   f"{num(r.get('device_negative_work_j_per_stride'), '.1f')}")
            regen = r.get("electrical_regenerated_j")
            elec = (f"{num(r.get('electrical_in_j'), '.0f')} J"
                    + (f" ({num(regen, '.0f')} J regenerated)" if regen and regen >= 1.0 else "")
                    + f" / {num(r.get('balance_error_rel'), '.0e')}")
        rows.append([label, num(r.get("speed_m_s")),
                     num(r.get("human_ankle_positive_work_j_per_stride"), ".1f"), dev, po, elec])
    out = table(header, rows)
    ha = get("healthy", "assist")
    if ha is not None and not ha.get("fell"):
        losses = sorted(((v, k) for k, v in (ha.get("losses_j") or {}).items()
                         if k in LOSS_WORDS), reverse=True)
        out += ("\n\nThe assisted healthy run: total efficiency (positive ankle work / "
                f"electrical) {num(ha.get('efficiency_total'), '.2f')}. Its losses over the run: "
                + ", ".join(f"{LOSS_WORDS[k]} {num(v, '.0f')} J" for v, k in losses)
                + f". Battery runtime at this gait is {num(ha.get('battery_runtime_h'), '.1f')} h;"
                f" peak pressure {num(ha.get('peak_pressure_mpa'), '.1f')} MPa; oil temperature "
                f"rise {num(ha.get('fluid_temperature_rise_k'), '.1f')} K.")
    return out


# comparison row labels (scenario name, or "name:variant") → the words the table uses
COMPARISON_LABELS = {
    "gait_assist_hafo": "HAFO (`hafo_gait`, pump-controlled)",
    "gait_assist_valve:pressure_control": "valve, pressure control",
    "gait_assist_valve:variable_displacement": "valve, variable displacement",
    "gait_assist_valve:unloading": "valve, accumulator + unloading (`valve`)",
    "gait_assist_valve:accumulator": "valve, accumulator, no unloading",
    "gait_assist_valve:no_accumulator": "valve, no accumulator",
    "gait_assist_digital": "digital (PWM unloading + release)"}
# ledger loss names → short words; any other name is shown with spaces for underscores
COMPARISON_LOSS_WORDS = {"motor_copper": "motor copper", "pump_mechanical": "pump mech.",
                         "pump_volumetric": "pump vol.", "servo_valve_throttling":
                         "servo throttling", "battery_internal": "battery"}


def sig(x: Any, scale: float = 1.0) -> str:
    """About two significant figures: "171", "16", "8.8", "0.52" (or "–")."""
    if x is None or (isinstance(x, float) and not math.isfinite(x)):
        return MISSING
    v = abs(float(x) * scale)
    return num(x, ".0f" if v >= 9.95 else ".1f" if v >= 0.995 else ".2f", scale)


def _loss_name(column: str) -> str:
    name = re.sub(r"^loss_|_j_per_stride$", "", column)
    return COMPARISON_LOSS_WORDS.get(name, name.replace("_", " "))


def format_comparison(results: Mapping) -> str:
    """``afo-mj compare`` of the three gait-assist scenarios: ``results["rows"]`` = the
    comparison's rows in their ranked order (columns of
    :mod:`afo_mj.experiments.device_comparison`, ``loss_names`` = a row's loss columns),
    one table row each. A row without an efficiency (not an actuator) shows "–" with a
    numbered note under the table giving its ``not_comparable_reason``."""
    header = ["device", "net efficiency (net ankle work / electrical)", "electrical J/stride",
              "delivered +work J/stride", "tracking RMSE N·m", "largest losses J/stride",
              "oil ΔT K", "battery h", "rank"]
    rows, notes = [], []
    for r in results.get("rows") or []:
        label = r.get("label") or ""
        name = COMPARISON_LABELS.get(label, f"`{label}`")
        if r.get("fell"):
            rows.append([name, fall_text(r)] + [""] * 7)
            continue
        eff = r.get("efficiency_total")
        if eff is None:
            notes.append(f"[{len(notes) + 1}] {name}"
                         + (f" ({r['mechanical_role']})" if r.get("mechanical_role") else "")
                         + f": {r.get('not_comparable_reason') or 'no efficiency'}.")
            eff_text = f"{MISSING} [{len(notes)}]"
        else:
            eff_text = f"{sig(eff, 100.0)} %"
        cols = r.get("loss_names") or [k for k in r if k.startswith("loss_")]
        losses = sorted(((r.get(c), i, c) for i, c in enumerate(cols)
                         if r.get(c) is not None), key=lambda t: (-t[0], t[1]))[:3]
        rank = r.get("efficiency_rank")
        rows.append([name, eff_text, num(r.get("electrical_j_per_stride"), ".0f"),
                     num(r.get("device_positive_work_j_per_stride"), ".1f"),
                     num(r.get("torque_tracking_rmse_nm"), ".1f"),
                     ", ".join(f"{_loss_name(c)} {sig(v)}" for v, _, c in losses) or MISSING,
                     num(r.get("fluid_temperature_rise_k"), ".1f"),
                     sig(r.get("battery_runtime_h")),
                     MISSING if rank is None else str(int(rank))])
    out = table(header, rows)
    if notes:
        out += "\n\n" + "<br>\n".join(notes)
    return out


def _signed_pct(rel: Any, fmt: str = ".1f") -> str:
    """A relative difference as "+0.07 %" / "−1.1 %" (or "–")."""
    if rel is None:
        return MISSING
    s = num(rel, fmt, 100.0)
    return s if s.startswith("−") or s == MISSING else "+" + s
    # (a value that rounds to zero prints "+0.0 %")


#: the mass budget's parts worn at the ankle (as ``design.md`` books them)
DESIGN_ANKLE_PARTS = ("cylinders", "shank_cuff_struts", "pulley_bearings", "foot_plate")
# what the prototype's publication gives (docs/design_tool.md compares the design with it)
HAFO_PROTOTYPE_KG, HAFO_PROTOTYPE_STALL_NM = 3.3, 65.0


def format_design_hafo(s: Mapping) -> str:
    """``afo-mj design scenarios/design/hafo_requirements.toml --verify``: ``s`` = what
    ``design.json`` holds (``best``, ``predicted_bench``, ``simulated_bench``,
    ``bench_agreement``, ``mass_check``, ``walk_check``). The prediction against the simulated
    bench and the mass budget, then the design in one paragraph and its walk check."""
    pb, sb = s.get("predicted_bench") or {}, s.get("simulated_bench") or {}
    ag, mc = s.get("bench_agreement") or {}, s.get("mass_check") or {}
    b = s.get("best") or {}
    items = sorted(((v.get("difference_kg"), k, v) for k, v in (mc.get("items") or {}).items()
                    if k in DESIGN_ANKLE_PARTS and v.get("difference_kg") is not None
                    and abs(v["difference_kg"]) >= 0.003), key=lambda t: -abs(t[0]))
    why = ", ".join(f"{k.replace('_', ' ')} {num(v.get('design_kg'), '.3f')} vs "
                    f"{num(v.get('budget_kg'), '.3f')}" for _, k, v in items)
    rows = [["stall torque", f"{num(pb.get('stall_torque_nm'), '.2f')} N·m",
             f"{num(sb.get('stall_torque_nm'), '.2f')} N·m "
             f"({_signed_pct(ag.get('stall_torque_rel'), '.2f')} %)"],
            ["no-load speed", f"{num(pb.get('no_load_speed_deg_s'), '.1f')} deg/s",
             f"{num(sb.get('no_load_speed_deg_s'), '.1f')} deg/s "
             f"({_signed_pct(ag.get('no_load_speed_rel'), '.2f')} %)"],
            ["mass, one side", f"{num(mc.get('design_total_kg'), '.3f')} kg",
             f"{num(mc.get('budget_total_kg'), '.3f')} kg, mass budget of the written parameters "
             f"({_signed_pct(mc.get('total_rel_difference'))} %)"],
            ["mass at the ankle", f"{num(mc.get('design_ankle_kg'), '.3f')} kg",
             f"{num(mc.get('budget_ankle_kg'), '.3f')} kg "
             f"({_signed_pct(mc.get('ankle_rel_difference'))} %"
             + (f": {why} kg" if why else "") + ")"]]
    out = table(["figure", "design's prediction",
                 "simulator (torque–velocity bench; mass budget)"], rows)
    eff = b.get("efficiency") or {}
    mass = b.get("mass_kg") or {}
    total = b.get("total_kg")
    lighter = None if total is None else HAFO_PROTOTYPE_KG - total
    out += (
        f"\n\nThe design: 2 × {num(b.get('cylinder_bore_m'), '.1f', 1e3)} mm cylinders on a "
        f"{num(b.get('pulley_radius_m'), '.0f', 1e3)} mm pulley (`A_e r` = "
        f"{num(b.get('torque_per_pressure_m3'), '.2e')} m³), "
        f"{num(b.get('hose_bore_m'), '.2f', 1e3)} mm hoses, a "
        f"{num(b.get('pump_displacement_m3_rev'), '.3f', 1e6)} cm³/rev pump (peak speed "
        f"{num(b.get('peak_pump_speed_rad_s'), '.0f')} rad/s), "
        f"{str(b.get('oil') or MISSING).replace('ISO_VG', 'ISO VG ')}, a "
        f"{num(b.get('motor_rated_power_w'), '.0f')} W class motor "
        f"({num(mass.get('motor'), '.0f', 1e3)} g), a 6S "
        f"{num(b.get('battery_capacity_ah'), '.2f')} Ah pack "
        f"({num(mass.get('battery'), '.2f')} kg); system efficiency "
        f"{num(b.get('system_efficiency'), '.0f', 100.0)} % over the stride (pump "
        f"{num(eff.get('pump'), '.0f', 100.0)} %, motor {num(eff.get('motor'), '.0f', 100.0)} %, "
        f"lines {num(eff.get('lines'), '.0f', 100.0)} %, cylinders "
        f"{num(eff.get('cylinders'), '.0f', 100.0)} %), {num(b.get('heat_w'), '.1f')} W of heat, "
        f"pack surface {celsius(b.get('surface_temperature_k'))} °C. "
        f"The published prototype weighs {HAFO_PROTOTYPE_KG:g} kg and stalls at "
        f"{HAFO_PROTOTYPE_STALL_NM:g} N·m; this design carries the "
        f"{num((s.get('requirements') or {}).get('peak_torque_nm'), 'g')} N·m target for "
        f"{num(lighter, '.1f')} kg less.")
    wc = s.get("walk_check") or {}
    conds = wc.get("conditions") or {}
    if conds:
        out += (
            f"\n\nWalk check of the written `design_walk.toml` (quasi-static, "
            f"{wc.get('gait', MISSING)} gait): no-load speed "
            f"{num(wc.get('no_load_speed_deg_s'), '.1f')} deg/s against the gait's peak "
            f"plantarflexion velocity {num(wc.get('peak_plantarflexion_velocity_deg_s'), '.1f')}"
            f" deg/s; the ankle back-drives the pump for "
            f"{num(wc.get('back_driven_fraction_of_stride'), '.0f', 100.0)} % of the stride; net "
            "device work " + ", ".join(
                f"{num((v or {}).get('net_work_j_per_stride'), '.1f')} J/stride {c}"
                for c, v in conds.items()) + ".")
    return out


def celsius(kelvin: Any) -> str:
    """A temperature in K shown in °C, one decimal."""
    return MISSING if kelvin is None else num(float(kelvin) - 273.15, ".1f")


def _mpa(pa: Any) -> str:
    return num(pa, ".1f", 1e-6)


def format_design_guidelines(s: Mapping) -> str:
    """The design-guideline studies and the hose-bore trade-off of the HAFO requirements
    (``s`` = ``design.json``: ``studies`` with ``pressure``, ``oil`` and ``power`` rows,
    ``hose_bore_tradeoff``)."""
    st = s.get("studies") or {}
    pr = [r for r in st.get("pressure") or [] if r.get("total_kg") is not None]
    header = ["operating pressure MPa"] + [_mpa(r.get("operating_pressure_pa")) for r in pr]
    rows = [["total mass kg"] + [num(r.get("total_kg"), ".3f") for r in pr],
            ["system efficiency %"] + [num(r.get("system_efficiency"), ".1f", 100.0)
                                       for r in pr],
            ["hydraulic power density W/kg"] + [num(r.get("hydraulic_power_density_w_kg"),
                                                    ".0f") for r in pr],
            ["system energy density Wh/kg"] + [num(r.get("system_energy_density_wh_kg"), ".2f")
                                               for r in pr]]
    out = table(header, rows)
    if len(pr) >= 2:
        a, z = pr[0], pr[-1]
        out += (f"\n\nFrom {_mpa(a.get('operating_pressure_pa'))} to "
                f"{_mpa(z.get('operating_pressure_pa'))} MPa the lightest design goes from "
                f"{num(a.get('total_kg'), '.3f')} to {num(z.get('total_kg'), '.3f')} kg "
                f"({_signed_pct((z['total_kg'] - a['total_kg']) / a['total_kg'], '.0f')} %) and "
                f"its system efficiency from {num(a.get('system_efficiency'), '.1f', 100.0)} to "
                f"{num(z.get('system_efficiency'), '.1f', 100.0)} %.")
    oil = st.get("oil") or []
    if oil:
        out += ("\n\nPer oil grade (lightest over the pressure sweep): " + ", ".join(
            f"{str(r.get('oil')).replace('ISO_VG', 'VG ')} {num(r.get('total_kg'), '.3f')} kg"
            for r in oil) + ".")
    power = st.get("power") or []
    if power:
        def pw(r):
            head = f"{num(r.get('rated_output_power_w'), '.0f')} W"
            if not r.get("feasible"):
                return head + " infeasible (" + ", ".join(
                    str(x).replace("_", " ") for x in r.get("binding") or ["–"]) + ")"
            return (f"{head} {num(r.get('total_kg'), '.2f')} kg "
                    f"({num(r.get('hydraulic_power_density_w_kg'), '.0f')} W/kg)")
        out += ("\n\nPer rated output power (the corner speed × "
                + " … ".join(num(r.get("power_factor"), "g")
                             for r in power[::max(len(power) - 1, 1)])
                + "): " + ", ".join(pw(r) for r in power) + ".")
    h = s.get("hose_bore_tradeoff") or {}
    if h.get("optimum_hose_bore_m") is not None:
        bores = h.get("hose_bore_m") or []
        rng = (f"{num(bores[0], '.1f', 1e3)}–{num(bores[-1], '.0f', 1e3)} mm"
               if bores else MISSING)
        inside = h.get("interior_optimum") and h.get("feasible_interior_optimum")
        out += (f"\n\nHose bore trade-off: with the motor held the total mass is lowest at "
                f"{num(h.get('optimum_hose_bore_m'), '.2f', 1e3)} mm; with each bore's lightest"
                f" feasible motor, at {num(h.get('feasible_optimum_hose_bore_m'), '.2f', 1e3)} mm"
                f" ({'both inside' if inside else 'not both inside'} {rng}).")
    return out


ARCHITECTURE_LABELS = {"pump": "pump-controlled",
                       "digital": "digital (PWM unloading, constant-speed pump)",
                       "valve": "valve (servo, rail following the load + 1.5 MPa)"}
#: ledger loss names of a design row → words; the pump's two losses are shown as one
DESIGN_LOSS_WORDS = {"motor_copper": "motor copper", "pump": "pump",
                     "servo_throttling": "servo throttling", "switching_valves":
                     "switching valves", "valve_coils": "coils", "motor_friction":
                     "motor friction", "pump_mechanical": "pump mechanical"}


def _design_losses(losses: Mapping[str, float], n: int = 3) -> str:
    """The ``n`` largest losses per stride; the pump's mechanical and volumetric losses are
    one ("pump") unless the circuit's pump runs at constant speed (its mechanical loss then
    stands alone, as the digital circuit's does)."""
    merged = dict(losses)
    if "pump_volumetric" in merged and "switching_valves" not in merged:
        merged["pump"] = merged.pop("pump_volumetric") + merged.pop("pump_mechanical", 0.0)
    top = sorted(merged.items(), key=lambda kv: -kv[1])[:n]
    return ", ".join(f"{DESIGN_LOSS_WORDS.get(k, k.replace('_', ' '))} {num(v, '.1f')}"
                     for k, v in top)


def format_design_architectures(results: Mapping) -> str:
    """The three circuits sized for one light duty (``results["light"][arch]`` = a design
    row or ``None``), the HAFO duty's verdict for the valve circuits
    (``results["hafo"][arch]`` = ``{"feasible", "explanation"}``) and, for comparison, the
    net efficiencies the simulator measures in gait (``results["simulated"]`` = the
    comparison's rows)."""
    rows = []
    for arch in ("pump", "digital", "valve"):
        r = (results.get("light") or {}).get(arch)
        if not r:
            rows.append([ARCHITECTURE_LABELS[arch], "infeasible", MISSING, MISSING])
            continue
        rows.append([ARCHITECTURE_LABELS[arch], num(r.get("total_kg"), ".2f"),
                     f"{num(r.get('system_efficiency'), '.0f', 100.0)} %",
                     _design_losses(r.get("losses_j_per_stride") or {}, 4)])
    out = table(["circuit", "mass kg", "system efficiency", "largest losses J/stride"], rows)
    light = results.get("light") or {}
    order = sorted((a for a in light if light[a]),
                   key=lambda a: -light[a].get("system_efficiency", 0.0))
    sim = {r.get("label"): r for r in (results.get("simulated") or {}).get("rows") or []}
    picks = (("pump", "gait_assist_hafo"), ("valve", "gait_assist_valve:pressure_control"),
             ("digital", "gait_assist_digital"))
    sim_eff = {a: (sim.get(lbl) or {}).get("efficiency_total") for a, lbl in picks}
    sim_order = sorted((a for a in sim_eff if sim_eff[a] is not None), key=lambda a: -sim_eff[a])
    out += ("\n\nDesign model's order of system efficiency: " + " > ".join(order)
            + ". In gait the simulator measures net efficiency (net ankle work / electrical, "
            "`afo-mj compare` of `scenarios/gait_assist_{hafo,valve,digital}.toml`): "
            + ", ".join(f"{a} {sig(sim_eff[a], 100.0)} %" for a in sim_order)
            + (" (the same order)." if sim_order == order
               else f" (another order: {' > '.join(sim_order)})."))
    hafo = results.get("hafo") or {}
    bad = [(a, v) for a, v in hafo.items() if v and not v.get("feasible")]
    if bad:
        out += ("\n\nAt the HAFO requirements: " + "; ".join(
            f"{a}: {v.get('explanation')}" for a, v in bad) + ".")
    return out


# --------------------------------------------------------------------------------------------
# runs (through the functions the CLI calls)
# --------------------------------------------------------------------------------------------

WALK_KEYS = ("hip_angle_rms_error_deg", "knee_angle_rms_error_deg", "ankle_angle_rms_error_deg",
             "peak_ankle_plantarflexor_moment_nm_per_kg", "peak_ankle_power_w_per_kg",
             "ankle_push_off_positive_work_j_per_kg", "push_off_peak_plantarflexion_deg",
             "min_toe_clearance_m", "speed_m_s", "swing_mean_ankle_angle_deg",
             "cadence_steps_per_min")

_MEMO: dict[str, Any] = {}
CACHE_DIR: Path | None = None


def _mean(entry: Any) -> float | None:
    if isinstance(entry, Mapping):
        entry = entry.get("mean")
    return None if entry is None else float(entry)


def _memo(key: str, fn: Callable[[], Any]) -> Any:
    """In-process memo of a run's JSON-ready result, and on disk under ``--cache DIR``."""
    if key in _MEMO:
        return _MEMO[key]
    path = None
    if CACHE_DIR is not None:
        path = CACHE_DIR / (re.sub(r"[^A-Za-z0-9_.=-]+", "_", key) + ".json")
        if path.exists():
            _MEMO[key] = json.loads(path.read_text(encoding="utf-8"))
            return _MEMO[key]
    print(f"[readme_tables] running {key} ...", file=sys.stderr, flush=True)
    t0 = _dt.datetime.now()
    out = fn()
    print(f"[readme_tables]   done in {(_dt.datetime.now() - t0).total_seconds():.0f} s",
          file=sys.stderr, flush=True)
    _MEMO[key] = out
    if path is not None:
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(json.dumps(out, indent=1, allow_nan=False), encoding="utf-8")
    return out


def _gait_result(summary: Mapping | None, events) -> dict:
    out: dict[str, Any] = {k: None for k in WALK_KEYS}
    if summary is not None:
        for k in WALK_KEYS:
            out[k] = _mean(summary.get(k))
        rf = summary.get("residual_force_rms_percent_body_weight") or {}
        out["residual_force_rms_percent_body_weight"] = rf.get("over_analysed_span")
    out["fell"] = events.fall_time_s is not None
    out["fall_time_s"] = events.fall_time_s
    out["completed_strides"] = max(len(events.heel_strikes_s[0]) - 1, 0)
    return out


class PushOffAssist:
    """An ideal orthosis (an ``AnkleDevice`` as in README's *From Python*; the one of
    ``tests/test_walk.py``): a half-sine plantarflexion torque over 35–62 % of each stance
    leg's phase, peak ``peak_nm``."""

    def __init__(self, peak_nm: float):
        self.peak_nm = peak_nm

    def torque_nm(self, t_s, angle_rad, velocity_rad_s, phase, stance):
        import numpy as np
        out = np.zeros(2)
        for s in (0, 1):
            if stance[s] and 0.35 < phase[s] < 0.62:
                out[s] = -self.peak_nm * np.sin(np.pi * (phase[s] - 0.35) / 0.27)
        return out


def walk_result(scenario_path: str, overrides: tuple[str, ...] = (), *,
                assist_peak_nm: float | None = None,
                worn: tuple[tuple[str, float], ...] = ()) -> dict:
    """One walk as ``afo-mj run`` does it (``load_scenario`` → ``simulate_walk`` →
    ``analyse_gait``, band fractions as the CLI adds them): the means of the table's
    metrics, the fall, body size and strength fractions. ``assist_peak_nm``: wear the ideal
    :class:`PushOffAssist`; ``worn``: carry ``(site, kg)`` masses (``simulate_walk``'s
    ``device`` and ``worn_masses``, as in README's *From Python*)."""
    def run():
        from afo_mj.metrics.gait_metrics import GaitAnalysisError, analyse_gait, band_fraction
        from afo_mj.gait.reference import load_normative
        from afo_mj.gait.walk import simulate_walk
        from afo_mj.scenarios.walk_scenario import load_scenario
        from afo_mj.human.walker import WornMass
        sc = load_scenario(ROOT / scenario_path, overrides=list(overrides))
        reference = sc.load_reference()
        record = simulate_walk(
            sc, device=None if assist_peak_nm is None else PushOffAssist(assist_peak_nm),
            worn_masses=[WornMass(site, kg, f"part{i}") for i, (site, kg) in enumerate(worn)])
        try:
            analysis = analyse_gait(record, reference, sc.analyse_strides)
        except GaitAnalysisError:
            if record.events.fall_time_s is None:
                raise
            analysis = None
        out = _gait_result(None if analysis is None else analysis.summary, record.events)
        out.update(name=sc.name, body_mass_kg=sc.walker.body_mass_kg,
                   height_m=sc.walker.height_m,
                   plantarflexor_strength_fraction=sc.walker.plantarflexor_strength_fraction,
                   dorsiflexor_strength_fraction=sc.walker.dorsiflexor_strength_fraction)
        if analysis is not None and sc.band_references:
            out["band_fraction_vs"] = {
                f"{src}:{cond}": {ch: _mean(v) for ch, v in band_fraction(
                    analysis.cycles, load_normative(src, cond)).items()}
                for src, cond in sc.band_references}
        return out
    key = "walk:" + scenario_path + "".join(" --set " + o for o in overrides)
    if assist_peak_nm is not None:
        key += f" assist={assist_peak_nm:g}"
    if worn:
        key += " worn=" + ",".join(f"{site}:{kg:g}" for site, kg in worn)
    return _memo(key, run)


def bench_result(scenario_path: str) -> dict:
    """A bench scenario as ``afo-mj run`` runs it (``load_bench_scenario`` →
    ``run_bench_scenario``): its JSON-ready summary."""
    def run():
        from afo_mj.outputs.gait_report import json_ready
        from afo_mj.experiments.bench_run import run_bench_scenario
        from afo_mj.scenarios.bench_scenario import load_bench_scenario
        summary, _series = run_bench_scenario(load_bench_scenario(ROOT / scenario_path))
        return json_ready(summary)
    return _memo("bench:" + scenario_path, run)


def device_walk_result(scenario_path: str) -> dict:
    """A device scenario as ``afo-mj run`` runs it (``run_device_scenario``): per condition
    the gait means, the whole-ankle push-off power and the electrical energy per stride of
    the first worn side."""
    def run():
        from afo_mj.experiments.device_walk import run_device_scenario
        from afo_mj.scenarios.device_scenario import device_config
        from afo_mj.scenarios.walk_scenario import load_scenario
        sc = load_scenario(ROOT / scenario_path)
        reference = sc.load_reference()
        dsum, results = run_device_scenario(sc, reference, device_config(sc))
        out = {}
        for cond, v in dsum["device_conditions"].items():
            rec = results[cond][0]
            r = _gait_result(v.get("gait"), rec.events)
            r["push_off_peak_power_w"] = (v.get("ankle") or {}).get("push_off_peak_power_w")
            eps = v.get("energy_per_stride")
            r["electrical_in_j_per_stride"] = None if eps is None else eps["electrical_in_j"]
            r["human_ankle_positive_work_j_per_stride"] = (
                v["human"].get("ankle_positive_work_j_per_stride"))
            r["push_off_work_j_per_stride"] = (
                (v.get("ankle") or {}).get("push_off_positive_work_j_per_stride"))
            if "device" in v:
                d, e = v["device"], v["energy"]
                r.update(device_positive_work_j_per_stride=d["positive_work_j_per_stride"],
                         device_negative_work_j_per_stride=d["negative_work_j_per_stride"],
                         peak_pressure_mpa=d.get("peak_pressure_mpa"),
                         fluid_temperature_rise_k=d.get("fluid_temperature_rise_k"),
                         battery_runtime_h=d.get("battery_runtime_h"),
                         electrical_in_j=e.get("electrical_in_j"),
                         electrical_regenerated_j=e.get("electrical_regenerated_j"),
                         efficiency_total=e.get("efficiency_total"),
                         balance_error_rel=e.get("balance_error_rel"),
                         losses_j=dict(e.get("losses_j") or {}))
            out[cond] = r
        return out
    return _memo("device:" + scenario_path, run)


COMPARISON_SCENARIOS = ("scenarios/gait_assist_hafo.toml", "scenarios/gait_assist_valve.toml",
                        "scenarios/gait_assist_digital.toml")


def comparison_result(scenario_paths: tuple[str, ...]) -> dict:
    """A comparison as ``afo-mj compare`` runs it (``load_compare_items`` →
    ``run_comparison``, as :func:`afo_mj.app.compare.compare` calls them, without writing a
    directory): ``{"rows": [...]}``, the rows in their ranked order with every column of the
    comparison (``None`` for NaN), ``scenario_file`` as given."""
    def run():
        from afo_mj.experiments.device_comparison import load_compare_items, run_comparison
        items = load_compare_items([str(ROOT / p) for p in scenario_paths])
        comp = run_comparison(items)
        given = {str(ROOT / p): p for p in scenario_paths}
        rows = []
        for r in comp.rows:
            row = {}
            for k, v in r.items():
                if k.startswith("_"):
                    continue
                if isinstance(v, float) and not math.isfinite(v):
                    v = None
                row[k] = v
            row["scenario_file"] = given.get(row.get("scenario_file"), row.get("scenario_file"))
            row["loss_names"] = [c for c in r.get("_loss_names") or []]
            rows.append(row)
        return {"rows": rows, "columns": list(comp.columns)}
    return _memo("compare:" + " ".join(scenario_paths), run)


DESIGN_HAFO = "scenarios/design/hafo_requirements.toml"
DESIGN_LIGHT = "scenarios/design/valve_requirements.toml"


def design_result(requirements_path: str, *, studies: bool = True,
                  verify: bool = True) -> dict:
    """``afo-mj design REQUIREMENTS [--verify]`` as the CLI runs it (``read_requirements`` →
    ``compute_design`` → ``build_summary``), nothing written: what ``design.json`` holds,
    less the search grid, the ranked designs and the wall times."""
    def run():
        from afo_mj.design.system_design import compute_design, read_requirements
        from afo_mj.outputs.design_report import build_summary
        req, _text = read_requirements(ROOT / requirements_path)
        d = compute_design(req, studies=studies, verify=verify)
        out = build_summary(d["result"], d["written"], d["study"], d["hose"], d["bench"],
                            d["wall_s"]).to_json()
        for k in ("search", "ranked", "assumptions", "device"):
            out.pop(k, None)
        return out
    return _memo(f"design:{requirements_path}:studies={studies}:verify={verify}", run)


def design_search_result(requirements_path: str, architecture: str) -> dict:
    """The design search alone (``size_system``, as ``afo-mj design`` runs it first) of a
    requirements file with ``requirement.architecture`` set: feasibility, explanation, the
    best design's row."""
    def run():
        from afo_mj.design.system_design import read_requirements, size_system
        from afo_mj.outputs.design_report import jsonable
        req, _text = read_requirements(
            ROOT / requirements_path, [f'requirement.architecture="{architecture}"'])
        res = size_system(req)
        return jsonable({"feasible": res.feasible, "explanation": res.explanation,
                         "best": res.row(0) if res.feasible else None})
    return _memo(f"design_search:{requirements_path}:{architecture}", run)


def collect_design_hafo() -> dict:
    return design_result(DESIGN_HAFO)


def collect_design_architectures() -> dict:
    light = {a: design_search_result(DESIGN_LIGHT, a)["best"] for a in ("pump", "digital", "valve")}
    hafo = {a: {k: v for k, v in design_search_result(DESIGN_HAFO, a).items() if k != "best"}
            for a in ("valve", "digital")}
    return {"light": light, "hafo": hafo, "simulated": comparison_result(COMPARISON_SCENARIOS)}


def collect_scenarios() -> dict:
    return {name: walk_result(f"scenarios/{name}.toml") for name in SCENARIO_ROWS}


def collect_plantarflexor_weakness() -> dict:
    out = {}
    for f in WEAKNESS_FRACTIONS:
        if f == 1.0:
            out[f] = walk_result("scenarios/walk_healthy.toml")
        elif f == 0.5:
            out[f] = walk_result("scenarios/walk_weak_plantarflexors.toml")
        else:
            out[f] = walk_result("scenarios/walk_weak_plantarflexors.toml",
                                 (f"impairment.plantarflexor_strength_fraction={f:g}",))
    return out


def collect_ideal_assist() -> dict:
    assist = {}
    for name, peaks in IDEAL_ASSIST_PEAKS_NM.items():
        path = f"scenarios/{name}.toml"
        assist[name] = {0.0: walk_result(path)}
        assist[name].update({p: walk_result(path, assist_peak_nm=p) for p in peaks})
    worn = {label: walk_result("scenarios/walk_healthy.toml", worn=w)
            for label, w in WORN_MASSES.items()}
    return {"assist": assist, "worn": worn}


def collect_schwartz_bands() -> dict:
    out = {}
    for name, cond in (("walk_schwartz_free", "Free"), ("walk_schwartz_fast", "Fast")):
        r = walk_result(f"scenarios/{name}.toml")
        out[f"`{name}` vs {cond}"] = (r.get("band_fraction_vs") or {}).get(f"schwartz2008:{cond}")
    return out


def collect_hafo_bench() -> dict:
    return {"hafo": bench_result("scenarios/bench_hafo.toml"),
            "hafo_gait": bench_result("scenarios/bench_hafo_gait.toml")}


def collect_stiffness_bench() -> dict:
    return bench_result("scenarios/stiffness_bench.toml")


def collect_foot_drop() -> dict:
    return device_walk_result("scenarios/gait_stiffness_emulation.toml")


def collect_comparison() -> dict:
    return comparison_result(COMPARISON_SCENARIOS)


def collect_hafo_gait() -> dict:
    return {"healthy": device_walk_result("scenarios/gait_assist_hafo.toml"),
            "prototype": device_walk_result("scenarios/gait_assist_hafo_prototype.toml"),
            "weak": device_walk_result("scenarios/gait_weak_plantarflexors_hafo.toml")}


# --------------------------------------------------------------------------------------------
# blocks
# --------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Block:
    name: str
    collect: Callable[[], Any]      # runs the scenarios → JSON-ready results
    format: Callable[[Any], str]    # pure
    runs: str                       # what it runs, for the stamp line and --list
    file: str = "docs/results.md"   # the file holding its markers, relative to the root


BLOCKS: dict[str, Block] = {b.name: b for b in (
    Block("scenarios", collect_scenarios, format_scenarios,
          "scenarios/walk_{healthy,weak_plantarflexors,foot_drop,spastic_ankle,child_healthy}"
          ".toml, strides 4–10 of 10, both legs"),
    Block("plantarflexor_weakness", collect_plantarflexor_weakness,
          format_plantarflexor_weakness,
          "scenarios/walk_weak_plantarflexors.toml with impairment.plantarflexor_strength_"
          "fraction = 0.7 / 0.6 / 0.45 / 0.4 / 0.35; 100 % and 50 % are the scenario table's "
          "walk_healthy and walk_weak_plantarflexors runs"),
    Block("ideal_assist", collect_ideal_assist, format_ideal_assist,
          "scenarios/walk_healthy.toml and walk_weak_plantarflexors.toml with an ideal "
          "half-sine push-off torque over 35–62 % of stance (simulate_walk's device) or "
          "carried masses (worn_masses); the no-device rows are "
          "the scenario table's runs"),
    Block("schwartz_bands", collect_schwartz_bands, format_schwartz_bands,
          "scenarios/walk_schwartz_free.toml, walk_schwartz_fast.toml"),
    Block("hafo_bench", collect_hafo_bench, format_hafo_bench,
          "scenarios/bench_hafo.toml, bench_hafo_gait.toml, each preset stepping its "
          "generated circuit"),
    Block("hafo_gait", collect_hafo_gait, format_hafo_gait,
          "scenarios/gait_assist_hafo.toml, gait_assist_hafo_prototype.toml, "
          "gait_weak_plantarflexors_hafo.toml, right ankle, strides 4–10"),
    Block("comparison", collect_comparison, format_comparison,
          "scenarios/gait_assist_{hafo,valve,digital}.toml through run_comparison as afo-mj "
          "compare does (assist condition, every variant, one no-device reference), right "
          "ankle, strides 4–10"),
    Block("stiffness_bench", collect_stiffness_bench, format_stiffness_bench,
          "scenarios/stiffness_bench.toml"),
    Block("phafo_power", collect_stiffness_bench, format_phafo_power,
          "scenarios/stiffness_bench.toml, the same run as stiffness_bench"),
    Block("foot_drop", collect_foot_drop, format_foot_drop,
          "scenarios/gait_stiffness_emulation.toml"),
    Block("design_hafo", collect_design_hafo, format_design_hafo,
          f"afo-mj design {DESIGN_HAFO} --verify (read_requirements → compute_design → "
          "build_summary, as the command does)", "docs/design_tool.md"),
    Block("design_guidelines", collect_design_hafo, format_design_guidelines,
          f"afo-mj design {DESIGN_HAFO}, the same run as design_hafo (its studies and hose "
          "bore trade-off)", "docs/design_tool.md"),
    Block("design_architectures", collect_design_architectures, format_design_architectures,
          f"the design search of {DESIGN_LIGHT} and {DESIGN_HAFO} with requirement."
          "architecture = pump / digital / valve; the simulated efficiencies are the "
          "comparison block's run", "docs/design_tool.md"),
)}


def collect(name: str) -> Any:
    """Run block ``name``'s scenarios (tests monkeypatch this)."""
    return BLOCKS[name].collect()


STAMP_RE = re.compile(r"^(<sub>Generated by `.*?`) on \d{4}-\d{2}-\d{2}(.*)$", re.M)


def render(name: str, results: Any, date: str) -> str:
    b = BLOCKS[name]
    return (b.format(results).rstrip("\n") + "\n\n"
            f"<sub>Generated by `python {TOOL} --only {name}` on {date}; runs {b.runs}.</sub>")


def markers(name: str) -> tuple[str, str]:
    return f"<!-- generated:{name} begin -->", f"<!-- generated:{name} end -->"


def block_span(text: str, name: str) -> tuple[int, int]:
    """Start and end offsets of the block's body (between its markers); ValueError unless
    each marker occurs exactly once, begin before end."""
    begin, end = markers(name)
    if text.count(begin) != 1 or text.count(end) != 1:
        raise ValueError(f"block {name!r}: expected each of {begin!r} and {end!r} exactly once")
    i, j = text.index(begin) + len(begin), text.index(end)
    if j < i:
        raise ValueError(f"block {name!r}: end marker before begin marker")
    return i, j


def _undated(s: str) -> str:
    return STAMP_RE.sub(r"\1 on DATE\2", s).strip()


# a number as the formatters print it: optional sign (ASCII or real minus), digits, decimals,
# exponent; not part of a word or a name ("ISO_VG32", "assist_k4.6", "reflex_params_1.25")
NUMBER_RE = re.compile(r"(?<![\w.])[−-]?\d+(?:\.\d+)?(?:e[+-]?\d+)?(?![\w])")
#: numbers in exponent notation at or below this magnitude are round-off (energy-balance
#: errors): equal to each other whatever their digits
ROUNDOFF = 1e-8


def _value_and_unit(token: str) -> tuple[float, float, bool]:
    """The printed number, one unit of its last printed digit, whether it has an exponent."""
    t = token.replace("−", "-")
    mant, _, exp = t.partition("e")
    decimals = len(mant.partition(".")[2])
    unit = 10.0 ** (-decimals) * (10.0 ** int(exp) if exp else 1.0)
    return float(t), unit, bool(exp)


def same_number(a: str, b: str) -> bool:
    """Two printed numbers equal at the printed precision (module docstring)."""
    if a == b:
        return True
    va, ua, ea = _value_and_unit(a)
    vb, ub, eb = _value_and_unit(b)
    if (ea or eb) and abs(va) <= ROUNDOFF and abs(vb) <= ROUNDOFF:
        return True
    return abs(va - vb) <= max(ua, ub) * (1.0 + 1e-9)


def same_at_printed_precision(old: str, new: str) -> bool:
    """``old`` and ``new`` (block texts) alike but for numbers within a unit of their last
    printed digit (and round-off figures): the words between the numbers must be identical."""
    a, b = _undated(old), _undated(new)
    if a == b:
        return True
    na, nb = NUMBER_RE.findall(a), NUMBER_RE.findall(b)
    if NUMBER_RE.split(a) != NUMBER_RE.split(b) or len(na) != len(nb):
        return False
    return all(same_number(x, y) for x, y in zip(na, nb))


def drift_lines(old: str, new: str) -> list[str]:
    """The lines of two block texts that differ beyond the printed precision, as "- old" /
    "+ new" pairs (a whole unified diff when the line structure changed)."""
    a, b = _undated(old).splitlines(), _undated(new).splitlines()
    if len(a) != len(b):
        import difflib
        return [ln for ln in difflib.unified_diff(a, b, "file", "fresh run", lineterm="")]
    out = []
    for x, y in zip(a, b):
        if not same_at_printed_precision(x, y):
            out += ["- " + x, "+ " + y]
    return out


def replace_block(text: str, name: str, body: str) -> tuple[str, bool]:
    """``text`` with block ``name``'s body replaced; whether its (undated) text changed. An
    unchanged block keeps its old date."""
    i, j = block_span(text, name)
    old = text[i:j]
    if _undated(old) == _undated(body):
        return text, False
    return text[:i] + "\n" + body.strip() + "\n" + text[j:], True


def main(argv: list[str] | None = None) -> int:
    global CACHE_DIR
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--only", action="append", choices=sorted(BLOCKS), metavar="NAME",
                    help="regenerate this block only (repeatable); names: --list")
    ap.add_argument("--check", action="store_true",
                    help="write nothing; exit 1 naming the blocks that differ from a fresh run "
                         "beyond the printed precision, with the lines that differ")
    ap.add_argument("--list", action="store_true",
                    help="list the blocks, the file holding each and what each runs")
    ap.add_argument("--root", type=Path, default=ROOT,
                    help="directory the blocks' files are relative to (default: the repository)")
    ap.add_argument("--cache", type=Path, default=None,
                    help="keep each run's result as JSON here and reuse it")
    args = ap.parse_args(argv)
    if args.list:
        for b in BLOCKS.values():
            print(f"{b.name:24s} {b.file}: {b.runs}")
        return 0
    CACHE_DIR = args.cache
    names = args.only or list(BLOCKS)
    date = _dt.date.today().isoformat()
    texts: dict[Path, str] = {}
    for name in names:
        path = args.root / BLOCKS[name].file
        if path not in texts:
            texts[path] = path.read_text(encoding="utf-8")
        block_span(texts[path], name)          # fail on missing markers before any run
    changed, drifted = [], []
    for name in names:
        path = args.root / BLOCKS[name].file
        body = render(name, collect(name), date)
        i, j = block_span(texts[path], name)
        if not same_at_printed_precision(texts[path][i:j], body):
            drifted.append((name, drift_lines(texts[path][i:j], body)))
        texts[path], did = replace_block(texts[path], name, body)
        if did:
            changed.append(name)
        if not args.check and did:             # write as we go: a later block may fail
            path.write_text(texts[path], encoding="utf-8")
            print(f"[readme_tables] {name}: rewritten in {path}", file=sys.stderr)
    if args.check:
        for name, lines in drifted:
            print(f"{name}: would change ({BLOCKS[name].file})")
            for ln in lines:
                print("    " + ln)
        if drifted:
            print(f"regenerate: python {TOOL} --only " + " --only ".join(n for n, _ in drifted))
        return 1 if drifted else 0
    if not changed:
        print("[readme_tables] no block changed", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
