"""Figures of a device run (the conditions of
:func:`afo_mj.experiments.device_walk.run_device_scenario`).

:func:`plot_device_run` writes into ``out_dir``:

* ``ankle_angle_conditions.png`` -- the worn side's ankle (right unless the device is worn on
  the left only) vs % gait cycle, mean ± 1 SD over the analysed cycles of each condition
  (``no_device`` / ``transparent`` / ``assist``, those present), over the reference band:
  angle (deg, + dorsiflexion), human (muscle) ankle power (W/kg, + generation) and, for the
  device conditions, the orthosis moment (N·m/kg, + plantarflexor, the biomechanics
  convention of ``gait_curves.png``: the negative of the record's sign);
* ``device_torque.png`` -- per device condition, the last (up to) 3 strides of the device
  log against time: commanded, delivered and measured torque (N·m, + plantarflexion),
  actuator chamber pressures (bar, gauge as logged) and motor current (A); dotted
  vertical lines are the worn side's heel strikes;
* ``device_power_flow.png`` -- per device condition, the energy ledger of the whole run (J)
  as a waterfall: what entered the device (electrical energy drawn from the battery,
  mechanical energy the ankle did on the device, energy released from storage), then where
  it went (each named loss, losses each below 0.5 % of the input as one bar, net energy
  stored, energy regenerated into the battery, positive mechanical work done on the ankle);
  what is left at the end is the ledger's residual. The top axis reads the same bars per
  mean analysed stride (J/stride: the summary's ``energy_per_stride`` scaling);

* ``gait_conditions.png`` -- the worn side's hip, knee and ankle (3×3: angle, moment,
  power vs % gait cycle), one mean curve per condition (``no_device``, ``transparent``,
  ``assist``, ``assist_k<K>``, ... those present) over the reference
  mean (± 1 SD band where the reference has one, named with its source; the title says when
  there is none), so walking with and without the device is on one figure. Moments and
  powers are low-pass filtered for the figure only (zero-lag 4th-order Butterworth, 6 Hz,
  :mod:`afo_mj.metrics.kinetics_filter`, stated in the title). Moments and
  powers are the human's (muscles); in the ankle column the whole joint (muscles + device)
  is dashed for the device conditions. A condition that fell is named in the legend;
* ``device_stride_hydraulics.png`` -- per device condition, one mean stride of the worn
  side (heel strike to heel strike, % cycle; mean ± 1 SD over the analysed strides) of the
  device log: commanded vs delivered torque (N·m, + plantarflexion); pressures (bar,
  gauge as logged: the pump ports and cylinder chambers of the HAFO; the pump outlet,
  supply rail and cylinder chambers of the valve circuits); pump (geometric) and cylinder
  (piston) flows (L/min, :func:`afo_mj.metrics.device_signals.device_signals`); motor current
  (A) and speed (rpm) for the HAFO, servo-valve spool position and command (normalised,
  ± 1 = full stroke) for the valve circuits.

The titles of the two figures that compare the wearer's own (muscle) moments and powers across
conditions (``ankle_angle_conditions.png``, ``gait_conditions.png``) say when the run's
summary reports the torque walker's written-in response to the device
(``human_response.rule = "assistance_adaptation"``,
:func:`afo_mj.experiments.device_walk.human_response`): there the change of the human ankle's
work with a device follows from that rule (:func:`human_response_note`).

A condition whose analysis is ``None`` (the walker fell before an analysable cycle) is left
out of every figure (``gait_conditions.png`` names it in its legend); a figure with nothing
to draw (no device condition) is not written.

:data:`FIGURES_BY_KIND` lists the PNGs each kind of run writes next to its ``summary.json``.
"""

from __future__ import annotations

import math
import textwrap
from pathlib import Path

import numpy as np

from afo_mj.metrics.gait_metrics import PERCENT_CYCLE, curve_statistics, reference_band
from afo_mj.metrics.kinetics_filter import filter_note, filtered_kinetic_cycles
from afo_mj.outputs.reference_display import (
    reference_band_note, reference_has_band, reference_label)

__all__ = ["plot_device_run", "gait_conditions_title", "human_response_note", "DEVICE_FIGURES",
           "FIGURES_BY_KIND"]

#: Figures :func:`plot_device_run` writes (in this order) for a run with a device condition.
DEVICE_FIGURES = ("ankle_angle_conditions.png", "gait_conditions.png", "device_torque.png",
                  "device_stride_hydraulics.png", "device_power_flow.png")

#: The PNGs each kind of run writes next to its ``summary.json`` (``afo-mj run``; ``compare``
#: for ``afo-mj compare``). Walking runs write ``gait_curves.png``
#: (:mod:`afo_mj.outputs.gait_report`); device walks add :data:`DEVICE_FIGURES`; the benches
#: write :func:`afo_mj.outputs.bench_figures.plot_bench`'s and
#: :func:`afo_mj.outputs.bench_figures.plot_stiffness_bench`'s figures. A sample of each
#: is in ``docs/figures/`` (README there).
FIGURES_BY_KIND = {
    "walk": ("gait_curves.png",),
    "device_hafo": ("gait_curves.png",) + DEVICE_FIGURES,
    "device_valve": ("gait_curves.png",) + DEVICE_FIGURES,
    "device_stiffness_emulation": ("gait_curves.png",) + DEVICE_FIGURES,
    "bench_hafo": ("hafo_torque_velocity.png", "hafo_isometric_steps.png", "hafo_bode.png",
                   "hafo_position_step.png"),
    "bench_stiffness": ("stiffness_loops.png", "stiffness_timeseries.png"),
    "compare": ("comparison.png",),
}

_COLOURS = {"no_device": "C0", "transparent": "C1", "assist": "C2"}
_LABELS = {"no_device": "no device", "transparent": "transparent (worn, 0 N·m)",
           "assist": "assist"}
_DPI = 110
_N_STRIDES_SHOWN = 3
#: losses below this fraction of the energy in are drawn as one bar in the energy flow
_SMALL_LOSS = 0.005


def _figure(figsize):
    import matplotlib
    matplotlib.use("Agg", force=False)
    from matplotlib.figure import Figure
    return Figure(figsize=figsize, layout="constrained")


def _worn_side(summary: dict) -> int:
    sides = summary.get("device_sides") or ["right"]
    return 0 if "right" in sides else 1


def _colour(cond: str, i: int) -> str:
    return _COLOURS.get(cond, f"C{3 + i}")


def _colour_map(conds) -> dict:
    """One colour per condition, the same in every figure (fixed for the named conditions,
    C3, C4, ... in run order for the others, e.g. the stiffness sweep's ``assist_k<K>``)."""
    out, i = {}, 0
    for c in conds:
        if c in _COLOURS:
            out[c] = _COLOURS[c]
        else:
            out[c] = f"C{3 + i}"
            i += 1
    return out


def _label(cond: str) -> str:
    """Legend name of a condition (``assist_k2.5`` → ``assist, K = 2.5 N·m/deg``)."""
    if cond in _LABELS:
        return _LABELS[cond]
    if cond.startswith("assist_k"):
        return f"assist, K = {cond.removeprefix('assist_k')} N·m/deg"
    return cond


def _device_column(summary: dict, side: int) -> int:
    """Column of the device log (one per worn side, in ``device_sides`` order) of walker
    side ``side`` (0 right, 1 left)."""
    sides = list(summary.get("device_sides") or ["right"])
    leg = ("right", "left")[side]
    return sides.index(leg) if leg in sides else 0


def _band(ax, x, mean, sd, scale, colour, label, alpha=0.22, ls="-", lw=1.8):
    ax.plot(x, scale * mean, color=colour, lw=lw, ls=ls, label=label)
    if sd is not None:
        lo, hi = scale * (mean - sd), scale * (mean + sd)
        ax.fill_between(x, np.minimum(lo, hi), np.maximum(lo, hi), color=colour, alpha=alpha,
                        lw=0)


# ------------------------------------------------------------------------------------------
# 1. ankle curves per condition
# ------------------------------------------------------------------------------------------

def human_response_note(summary: dict) -> str:
    """What a figure comparing the wearer's work across conditions must say of the walker:
    ``" (torque walker: feedforward lowered by <a> × device torque)"`` when the summary's
    ``human_response`` names the written-in rule ``assistance_adaptation`` (its value as the
    summary gives it), ``""`` otherwise (the muscle walker, or a summary without the block)."""
    hr = summary.get("human_response") if isinstance(summary, dict) else None
    if not isinstance(hr, dict) or hr.get("rule") != "assistance_adaptation":
        return ""
    return (f" (torque walker: feedforward lowered by {hr.get('assistance_adaptation')} × "
            "device torque)")


def _plot_conditions(path: Path, conds: dict, reference, side: int, title: str,
                     colours: dict | None = None) -> None:
    colours = colours or {}
    leg = ("right", "left")[side]
    fig = _figure((8.5, 10.5))
    axes = fig.subplots(3, 1, sharex=True)
    ref_name = (f"{getattr(reference, 'source', 'reference')} "
                f"{getattr(reference, 'condition', '')}").strip()
    panels = (("ankle_angle_rad", math.degrees(1.0),
               f"{leg} ankle angle [deg]\n(+ dorsiflexion)", False),
              ("ankle_power_w_per_kg", 1.0,
               f"{leg} ankle power, human [W/kg]\n(muscles only; + generation)", False),
              ("ankle_device_moment_nm_per_kg", -1.0,
               "orthosis moment [N·m/kg]\n(+ plantarflexor)", True))
    for ax, (ch, scale, ylabel, device_only) in zip(axes, panels):
        band = None if device_only else reference_band(reference, ch)
        if band is not None:
            rmean, rsd = band
            _band(ax, PERCENT_CYCLE, rmean, rsd, scale, "0.35",
                  f"{ref_name} mean" + (" ± 1 SD" if rsd is not None else ""),
                  alpha=0.2, ls="--", lw=1.2)
        for i, (cond, (rec, analysis, dev)) in enumerate(conds.items()):
            if device_only and dev is None:
                continue
            source = (analysis.cycles if ch in ("ankle_angle_rad",)
                      else filtered_kinetic_cycles(rec, analysis.cycles))
            cycles = [c for c in source if c.side == side]
            if not cycles or ch not in cycles[0].curves:
                continue
            mean, sd = curve_statistics(cycles, ch)
            _band(ax, PERCENT_CYCLE, mean, sd, scale, colours.get(cond, _colour(cond, i)),
                  f"{_label(cond)}: n = {len(cycles)}, mean ± 1 SD")
        ax.axhline(0.0, color="0.7", lw=0.6)
        ax.set_ylabel(ylabel)
        ax.set_xlim(0, 100)
        ax.grid(True, color="0.92", lw=0.5)
        if ax.get_legend_handles_labels()[0]:
            ax.legend(fontsize="small", loc="best")
    axes[-1].set_xlabel(f"{leg} gait cycle [%] (heel strike to heel strike)")
    has_band = reference_has_band(reference, ("ankle_angle_rad", "ankle_power_w_per_kg"))
    note = ("" if reference is None
            else "\n" + textwrap.fill(reference_band_note(reference, has_band), 100))
    fig.suptitle(f"{title}\n{leg} ankle by condition: simulation mean ± 1 SD over the analysed "
                 f"cycles{note}\n" + textwrap.fill(filter_note(), 100))
    fig.savefig(path, dpi=_DPI)


# ------------------------------------------------------------------------------------------
# 1b. hip, knee, ankle per condition (with and without the device on one figure)
# ------------------------------------------------------------------------------------------

def gait_conditions_title(title: str, leg: str, reference, has_band: bool) -> str:
    """The title of ``gait_conditions.png``: what is drawn, what the reference band is (or
    that there is none: :func:`afo_mj.outputs.reference_display.reference_band_note`) and the
    display filter of the moments and powers."""
    ref = "" if reference is None else "; " + reference_band_note(reference, has_band)
    return (f"{title}\n{leg} hip, knee and ankle by condition (with and without the device): "
            f"simulation mean per condition{ref}\n"
            "moments in the biomechanics convention (the negative of the record's sign); "
            "heel strike to heel strike\n" + textwrap.fill(filter_note(), 110))


def _plot_gait_conditions(path: Path, results: dict, reference, side: int, title: str,
                          colours: dict) -> None:
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch

    from afo_mj.metrics.gait_metrics import JOINTS
    leg = ("right", "left")[side]
    fig = _figure((13.0, 10.0))
    axes = fig.subplots(3, 3, sharex=True)
    ref_name = (f"{getattr(reference, 'source', 'reference')} "
                f"{getattr(reference, 'condition', '')}").strip()
    rows = (("angle_rad", math.degrees(1.0), "angle [deg]\n(+ flexion / dorsiflexion)"),
            ("moment_nm_per_kg", -1.0, "moment, human [N·m/kg]\n(+ extensor / plantarflexor)"),
            ("power_w_per_kg", 1.0, "power, human [W/kg]\n(+ generation)"))
    device_total = {"moment_nm_per_kg": "ankle_device_moment_nm_per_kg",
                    "power_w_per_kg": "ankle_device_power_w_per_kg"}
    handles = [Line2D([], [], color="0.35", ls="--", lw=1.2)]
    labels = [f"{ref_name} mean"]
    has_band = reference_has_band(reference, [f"{j}_{k}" for j in JOINTS for k in (
        "angle_rad", "moment_nm_per_kg", "power_w_per_kg")])
    if reference is not None:
        labels[0] = reference_label(reference, False) if not has_band else f"{ref_name} mean"
    if has_band:
        handles.append(Patch(color="0.5", alpha=0.25))
        labels.append(reference_label(reference, True))
    shown = {cond: filtered_kinetic_cycles(rec, analysis.cycles)
             for cond, (rec, analysis, dev) in results.items() if analysis is not None}
    any_total = False
    for cond, (rec, analysis, dev) in results.items():
        col = colours.get(cond, "C7")
        if analysis is None:
            fall = getattr(rec.events, "fall_time_s", None)
            handles.append(Line2D([], [], color=col, lw=0, marker="x", ms=7, mew=2))
            labels.append(f"{_label(cond)}: no analysable stride"
                          + ("" if fall is None else f" (fell at t = {fall:.2f} s)"))
            continue
        cycles = [c for c in analysis.cycles if c.side == side]
        handles.append(Line2D([], [], color=col, lw=1.8))
        labels.append(f"{_label(cond)}: mean of {len(cycles)} {leg} cycles")
    for r, (kind, scale, ylabel) in enumerate(rows):
        for c, joint in enumerate(JOINTS):
            ax = axes[r, c]
            ch = f"{joint}_{kind}"
            band = reference_band(reference, ch)
            if band is not None:
                rmean, rsd = band
                ax.plot(PERCENT_CYCLE, scale * rmean, color="0.35", lw=1.2, ls="--")
                if rsd is not None:
                    a, b = scale * (rmean - rsd), scale * (rmean + rsd)
                    ax.fill_between(PERCENT_CYCLE, np.minimum(a, b), np.maximum(a, b),
                                    color="0.5", alpha=0.25, lw=0)
            for cond, (rec, analysis, dev) in results.items():
                if analysis is None:
                    continue
                cycles = [cy for cy in (shown[cond] if kind != "angle_rad" else analysis.cycles)
                          if cy.side == side]
                if not cycles or ch not in cycles[0].curves:
                    continue
                col = colours.get(cond, "C7")
                mean, _ = curve_statistics(cycles, ch)
                ax.plot(PERCENT_CYCLE, scale * mean, color=col, lw=1.6)
                dch = device_total.get(kind)
                if joint == "ankle" and dch and dev is not None and dch in cycles[0].curves:
                    dmean, _ = curve_statistics(cycles, dch)
                    ax.plot(PERCENT_CYCLE, scale * (mean + dmean), color=col, lw=1.1,
                            ls=(0, (4, 2)))
                    any_total = True
            ax.axhline(0.0, color="0.7", lw=0.6)
            ax.set_xlim(0, 100)
            ax.grid(True, color="0.92", lw=0.5)
            ax.set_axisbelow(True)
            if r == 0:
                ax.set_title(f"{leg} {joint}")
            if c == 0:
                ax.set_ylabel(ylabel)
            if r == 2:
                ax.set_xlabel(f"{leg} gait cycle [%]")
    if any_total:
        handles.append(Line2D([], [], color="0.2", lw=1.1, ls=(0, (4, 2))))
        labels.append("ankle: whole joint, human + device (device conditions)")
    fig.legend(handles, labels, loc="outside lower center", ncol=2, fontsize="small",
               frameon=False)
    fig.suptitle(gait_conditions_title(title, leg, reference, has_band))
    fig.savefig(path, dpi=_DPI)


# ------------------------------------------------------------------------------------------
# 2b. one mean stride of the device: torque, pressures, flows, valve / motor
# ------------------------------------------------------------------------------------------

_L_MIN = 6.0e4          # m³/s → L/min
_RPM = 60.0 / (2.0 * math.pi)


def _stride_stack(t: np.ndarray, y: np.ndarray, windows) -> np.ndarray:
    """``y(t)`` resampled on the 101-point % cycle grid of each (t0, t1) window: (n, 101)."""
    return np.stack([np.interp(t0 + PERCENT_CYCLE / 100.0 * (t1 - t0), t, y)
                     for t0, t1 in windows])


def _plot_stride_hydraulics(path: Path, devs: dict, summary: dict, side: int, title: str,
                            colours: dict, left_out=()) -> None:
    from afo_mj.metrics.device_signals import device_signals
    leg = ("right", "left")[side]
    k = _device_column(summary, side)
    n = len(devs)
    fig = _figure((max(7.0, 5.6 * n), 12.0))
    axes = np.asarray(fig.subplots(4, n, sharex=True, squeeze=False))
    valve_any = False
    for j, (cond, (rec, analysis, dev)) in enumerate(devs.items()):
        L = dev.log.arrays()
        t = L["time_s"][:, k]
        windows = [(c.start_s, c.end_s) for c in analysis.cycles
                   if c.side == side and c.end_s <= t[-1] + 1e-9]
        col = colours.get(cond, "C2")
        if not windows:
            for r in range(4):
                axes[r, j].text(0.5, 0.5, "no analysed stride inside the device log",
                                ha="center", va="center", transform=axes[r, j].transAxes)
            continue
        sig = device_signals(dev)
        valve = "pump_pa" in L
        valve_any |= valve

        def draw(ax, y, scale, colour, label, ls="-", lw=1.5):
            st = scale * _stride_stack(t, y[:, k], windows)
            _band(ax, PERCENT_CYCLE, st.mean(axis=0),
                  st.std(axis=0, ddof=1) if len(windows) > 1 else None, 1.0, colour, label,
                  alpha=0.18, ls=ls, lw=lw)

        ax = axes[0, j]
        draw(ax, L["commanded_torque_nm"], -1.0, "k", "commanded", ls="--", lw=1.3)
        draw(ax, L["delivered_torque_nm"], -1.0, col, "delivered")
        ax.set_title(f"{_label(cond)}: mean of {len(windows)} {leg} strides (± 1 SD)")
        ax = axes[1, j]
        if valve:
            pres = (("pump_pa", "pump outlet", "C1"), ("supply_pa", "supply rail", "C0"),
                    ("chamber_a_pa", "chamber A", "C4"), ("chamber_b_pa", "chamber B", "C5"))
        else:
            pres = (("pressure_a_pa", "pump port A", "C1"), ("pressure_b_pa", "pump port B", "C0"),
                    ("chamber_a_pa", "chamber A", "C4"), ("chamber_b_pa", "chamber B", "C5"))
        for name, lab, c2 in pres:
            if name in L:
                draw(ax, L[name], 1e-5, c2, lab, lw=1.2,
                     ls="-" if name.startswith("chamber") else (0, (3, 1.5)))
        ax = axes[2, j]
        if "pump_flow_m3_s" in sig:
            draw(ax, sig["pump_flow_m3_s"].values, _L_MIN, "C1",
                 "pump, geometric D ω / 2π" + (" (full stroke)" if valve else ""), lw=1.3)
        if "cylinder_flow_m3_s" in sig:
            draw(ax, sig["cylinder_flow_m3_s"].values, _L_MIN, "C9",
                 "cylinder (piston) A r dθ/dt, + dorsiflexion", lw=1.3)
        ax = axes[3, j]
        if valve:
            draw(ax, L["valve_command"], 1.0, "k", "servo valve command", ls="--", lw=1.2)
            draw(ax, L["valve_position"], 1.0, "C3", "servo valve spool position", lw=1.4)
            if ("unloading_valve_position" in L
                    and np.ptp(L["unloading_valve_position"][:, k]) > 0.01):
                draw(ax, L["unloading_valve_position"], 1.0, "C8",
                     "unloading valve position (0 closed .. 1 open)", lw=1.0)
            peak = max(float(np.max(np.abs(L[f][:, k]))) for f in
                       ("valve_command", "valve_position", "unloading_valve_position") if f in L)
            lim = min(1.05, max(0.1, 1.2 * peak))
            ax.set_ylim(-lim, lim)
        else:
            draw(ax, L["motor_current_a"], 1.0, "C2", "motor current [A] (left axis)", lw=1.3)
            ax2 = ax.twinx()
            draw(ax2, L["motor_speed_rad_s"], _RPM, "C6", "motor speed [rpm] (right axis)",
                 lw=1.1)
            ax2.set_ylabel("motor speed [rpm]")
            h1, l1 = ax.get_legend_handles_labels()
            h2, l2 = ax2.get_legend_handles_labels()
            ax.legend(h1 + h2, l1 + l2, fontsize="small", loc="upper left")
        for r in range(4):
            a = axes[r, j]
            a.axhline(0.0, color="0.7", lw=0.6)
            a.set_xlim(0, 100)
            a.grid(True, color="0.92", lw=0.5)
            a.set_axisbelow(True)
            if r < 3 or valve:
                a.legend(fontsize="small", loc="best")
        axes[3, j].set_xlabel(f"{leg} gait cycle [%] (heel strike to heel strike)")
        axes[3, j].set_ylabel("spool position / command\n[normalised, ± 1 = full stroke]"
                              if valve else "motor current [A]")
    axes[0, 0].set_ylabel("ankle torque [N·m]\n(+ plantarflexion)")
    axes[1, 0].set_ylabel("pressure [bar] (gauge)")
    axes[2, 0].set_ylabel("flow [L/min]")
    note = ("" if not left_out else "\nnot shown (no analysable stride): "
            + ", ".join(_label(c) for c in left_out))
    fig.suptitle(f"{title}\ndevice over one mean stride ({leg} ankle): torque tracking, "
                 "pressures, flows and " + ("valve" if valve_any else "motor") + note)
    fig.savefig(path, dpi=_DPI)


# ------------------------------------------------------------------------------------------
# 2. device torque, pressures, current vs time
# ------------------------------------------------------------------------------------------

def _window(rec, t: np.ndarray, side: int):
    """Mask of the last (up to) 3 complete strides of ``side`` in the log time ``t``."""
    hs = sorted(float(h) for h in rec.events.heel_strikes_s[side] if h <= t[-1])
    if len(hs) >= 2:
        k = min(_N_STRIDES_SHOWN, len(hs) - 1)
        t0, t1 = hs[-1 - k], hs[-1]
    else:
        t1 = float(t[-1])
        t0 = max(float(t[0]), t1 - 3.0)
    return (t >= t0) & (t <= t1), [h for h in hs if t0 <= h <= t1]


def _plot_torque(path: Path, devs: dict, side: int, title: str) -> None:
    n = len(devs)
    fig = _figure((max(6.5, 5.8 * n), 9.5))
    axes = np.asarray(fig.subplots(3, n, sharey="row", squeeze=False))
    for j, (cond, (rec, analysis, dev)) in enumerate(devs.items()):
        L = dev.log.arrays()
        t = L["time_s"][:, 0]
        m, hs = _window(rec, t, side)
        tt = t[m]
        ax = axes[0, j]
        ax.plot(tt, -L["commanded_torque_nm"][m, 0], color="k", lw=1.4, ls="--",
                label="commanded")
        ax.plot(tt, -L["delivered_torque_nm"][m, 0], color="C3", lw=1.6, label="delivered")
        ax.plot(tt, -L["measured_torque_nm"][m, 0], color="C0", lw=0.9, alpha=0.7,
                label="measured (sensor)")
        rmse = (math.sqrt(float(np.mean((L["commanded_torque_nm"][m, 0]
                                         - L["delivered_torque_nm"][m, 0]) ** 2)))
                if tt.size else math.nan)
        ax.set_title(f"{_label(cond)}: last {max(len(hs) - 1, 0)} strides "
                     f"(tracking RMSE {rmse:.1f} N·m)")
        ax = axes[1, j]
        ax.plot(tt, L["chamber_a_pa"][m, 0] / 1e5, color="C4", lw=1.3, label="chamber A")
        ax.plot(tt, L["chamber_b_pa"][m, 0] / 1e5, color="C5", lw=1.3, label="chamber B")
        ax = axes[2, j]
        ax.plot(tt, L["motor_current_a"][m, 0], color="C2", lw=1.2, label="motor current")
        for r in range(3):
            ax = axes[r, j]
            for h in hs:
                ax.axvline(h, color="0.6", lw=0.7, ls=":")
            ax.set_axisbelow(True)
            ax.grid(True, color="0.92", lw=0.5)
            if tt.size:
                ax.set_xlim(tt[0], tt[-1])
            if j == 0:                    # the same signals in every column
                ax.legend(fontsize="small", loc="best")
        axes[0, j].axhline(0.0, color="0.7", lw=0.6)
        axes[2, j].axhline(0.0, color="0.7", lw=0.6)
        axes[2, j].set_xlabel("time [s] (dotted: heel strikes)")
    axes[0, 0].set_ylabel("ankle torque [N·m]\n(+ plantarflexion)")
    axes[1, 0].set_ylabel("chamber pressure [bar]")
    axes[2, 0].set_ylabel("motor current [A]")
    fig.suptitle(f"{title}\ndevice torque tracking, actuator pressures and motor current "
                 f"({('right', 'left')[side]} ankle)")
    fig.savefig(path, dpi=_DPI)


# ------------------------------------------------------------------------------------------
# 3. energy flow (waterfall of the whole-run ledger)
# ------------------------------------------------------------------------------------------

def _energy_in(energy: dict) -> float:
    """Energy into the device over the run (J): drawn, back-driven in, released from storage."""
    drawn = float(energy.get("electrical_in_j") or 0.0)
    mech_net = float(energy.get("mechanical_out_j") or 0.0)
    mech_pos = float(energy.get("mechanical_positive_out_j") or 0.0)
    stored = float(sum((energy.get("stored_change_j") or {}).values()))
    return drawn + max(mech_pos - mech_net, 0.0) + max(-stored, 0.0)


def _loss_layout(energies) -> tuple[list[str], set]:
    """The loss rows shared by every condition's waterfall (the same rows in every panel, so
    that they can share the y axis): loss names by decreasing total share, and those below
    :data:`_SMALL_LOSS` of the energy in for every condition (drawn as one bar, if two or
    more)."""
    share: dict[str, float] = {}
    small: set | None = None
    for e in energies:
        tot = max(_energy_in(e), 1e-12)
        losses = {k: float(v) for k, v in (e.get("losses_j") or {}).items()}
        for k, v in losses.items():
            share[k] = share.get(k, 0.0) + abs(v) / tot
        sm = {k for k, v in losses.items() if abs(v) < _SMALL_LOSS * tot}
        small = sm if small is None else small & sm
    small = small or set()
    if len(small) < 2:
        small = set()
    return sorted(share, key=lambda k: -share[k]), small


def _flow_items(energy: dict, order=None, small=frozenset()
                ) -> tuple[list[tuple[str, float, str]], float]:
    """(label, signed amount J, colour) in waterfall order (+ into the device, − out of it),
    and the ledger residual: electrical in, mechanical in, the losses (in ``order``; those in
    ``small`` as one bar), net storage, regeneration, positive mechanical work on the ankle."""
    drawn = float(energy.get("electrical_in_j") or 0.0)
    regen = float(energy.get("electrical_regenerated_j") or 0.0)
    mech_net = float(energy.get("mechanical_out_j") or 0.0)
    mech_pos = float(energy.get("mechanical_positive_out_j") or 0.0)
    mech_absorbed = max(mech_pos - mech_net, 0.0)      # negative work of the ankle on the device
    losses = {k: float(v) for k, v in (energy.get("losses_j") or {}).items()}
    stored = float(sum((energy.get("stored_change_j") or {}).values()))
    if order is None:
        order = sorted(losses, key=lambda k: -abs(losses[k]))
    items = [("electrical drawn from battery", drawn, "C2"),
             ("mechanical in (ankle back-drives device)", mech_absorbed, "C9")]
    for k in order:
        if k not in small:
            items.append((f"loss: {k.replace('_', ' ')}", -losses.get(k, 0.0), "C3"))
    if small:
        items.append((f"loss: {len(small)} others, each < {_SMALL_LOSS:.1%} of the input\n("
                      + ", ".join(k.replace('_', ' ') for k in sorted(small)) + ")",
                      -sum(losses.get(k, 0.0) for k in small), "#e8a0a0"))
    items.append(("net stored (oil, rotor, L, reservoir;\nbar left) or released (right)",
                  -stored, "0.6"))
    items.append(("regenerated into battery", -regen, "C0"))
    items.append(("mechanical positive out (to ankle)", -mech_pos, "C4"))
    residual = sum(v for _, v, _ in items)
    return items, residual


def _plot_power_flow(path: Path, energies: dict, title: str, note: str,
                     per_stride: dict | None = None) -> None:
    n = len(energies)
    order, small = _loss_layout(energies.values())
    rows = max(len(_flow_items(e, order, small)[0]) for e in energies.values())
    fig = _figure((max(7.5, 6.4 * n), 1.2 + 0.42 * (rows + 2)))
    axes = np.asarray(fig.subplots(1, n, sharey=True, squeeze=False))[0]
    for j, (cond, energy) in enumerate(energies.items()):
        ax = axes[j]
        items, residual = _flow_items(energy, order, small)
        level = 0.0
        top = max(sum(v for _, v, _ in items if v > 0), 1e-12)
        labels = []
        for i, (label, v, colour) in enumerate(items):
            start = level
            level += v
            ax.barh(i, v, left=start, color=colour, height=0.7,
                    edgecolor="k" if v > 0 else "none", lw=0.5)
            if i + 1 < len(items):
                ax.plot([level, level], [i + 0.35, i + 0.65], color="0.5", lw=0.6)
            x_text = max(start, level)
            ax.text(x_text + 0.01 * top, i, f"{abs(v):.1f} J ({abs(v) / top:.0%})",
                    va="center", ha="left", fontsize="small")
            labels.append(label)
        i_total = len(items)
        ax.barh(i_total, level, color="k", height=0.35)
        ax.text(max(level, 0.0) + 0.01 * top, i_total,
                f"residual {residual:+.2g} J", va="center", ha="left", fontsize="small")
        labels.append("ledger residual (in − out)")
        ax.set_yticks(range(len(labels)))
        ax.set_yticklabels(labels)
        ax.set_ylim(len(labels) - 0.4, -0.6)
        ax.set_xlim(0.0, 1.28 * top)
        ax.axvline(0.0, color="0.5", lw=0.6)
        ax.set_axisbelow(True)
        ax.grid(True, axis="x", color="0.92", lw=0.5)
        eff = energy.get("efficiency_total")
        sub = f", mech. positive out / drawn = {eff:.0%}" if isinstance(eff, (int, float)) else ""
        ax.set_title(f"{_label(cond)}: {top:.0f} J in{sub}", fontsize="medium")
        ax.set_xlabel("energy, whole run [J]\n(cumulative: bars right = into the device, "
                      "left = out of it)", fontsize="small")
        eps = (per_stride or {}).get(cond)
        drawn = float(energy.get("electrical_in_j") or 0.0)
        if isinstance(eps, dict) and drawn > 0 and isinstance(eps.get("electrical_in_j"),
                                                              (int, float)):
            f = float(eps["electrical_in_j"]) / drawn      # per mean analysed stride
            if math.isfinite(f) and f > 0:
                sec = ax.secondary_xaxis("top", functions=(lambda x, f=f: x * f,
                                                           lambda x, f=f: x / f))
                sec.set_xlabel(f"per mean stride ({eps.get('stride_time_s', math.nan):.2f} s) "
                               "[J/stride]", fontsize="small")
                sec.tick_params(labelsize="small")
    fig.suptitle(f"{title}\ndevice energy flow, whole run ({note}); % of all energy in")
    fig.savefig(path, dpi=_DPI)


# ------------------------------------------------------------------------------------------

#: the log fields the torque and hydraulics figures need (those of the HAFO and valve presets)
PRESET_LOG_FIELDS = ("commanded_torque_nm", "delivered_torque_nm", "measured_torque_nm",
                     "chamber_a_pa", "chamber_b_pa")


def plot_device_run(out_dir, results: dict, reference, summary: dict,
                    title: str) -> list[Path]:
    """Write the device-run figures (see the module docstring) into ``out_dir`` (created if
    missing) and return the paths written.

    ``results``: ``{condition: (record, analysis or None, device or None)}`` and ``summary``
    (with ``"device_conditions"`` and ``"device_sides"``) as returned by
    :func:`afo_mj.experiments.device_walk.run_device_scenario`; ``reference``: the reference
    gait the run was compared with; ``title``: the first line of every figure's title.
    """
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    side = _worn_side(summary)
    colours = _colour_map(results)
    conds = {c: v for c, v in results.items() if v[1] is not None}
    written: list[Path] = []
    if not conds:
        return written

    # the figures of the wearer's own moments and powers name a written-in response
    human_title = title + human_response_note(summary)
    p = out / "ankle_angle_conditions.png"
    _plot_conditions(p, conds, reference, side, human_title, colours)
    written.append(p)

    if any(v[2] is not None for v in results.values()):
        p = out / "gait_conditions.png"
        _plot_gait_conditions(p, results, reference, side, human_title, colours)
        written.append(p)

    # the torque and hydraulics figures read the preset devices' signal names; a device that
    # logs others (the ideal device, a described circuit) has the gait figures only
    devs = {c: v for c, v in conds.items() if v[2] is not None and v[2].log.n > 1
            and all(f in v[2].log.FIELDS for f in PRESET_LOG_FIELDS)}
    if devs:
        p = out / "device_torque.png"
        _plot_torque(p, devs, side, title)
        written.append(p)
        p = out / "device_stride_hydraulics.png"
        fell = [c for c, v in results.items() if v[1] is None and v[2] is not None]
        _plot_stride_hydraulics(p, devs, summary, side, title, colours, fell)
        written.append(p)

    dc = summary.get("device_conditions") or {}
    energies = {c: dc[c]["energy"] for c in devs if isinstance(dc.get(c), dict)
                and isinstance(dc[c].get("energy"), dict)}
    if energies:
        rec = next(iter(devs.values()))[0]
        dur = float(rec.time_s[-1] - rec.time_s[0]) if len(rec.time_s) > 1 else 0.0
        n_hs = len(rec.events.heel_strikes_s[side])
        note = (f"{dur:.1f} s, {max(n_hs - 1, 0)} {('right', 'left')[side]} strides "
                "incl. the start")
        per_stride = {c: dc[c].get("energy_per_stride") for c in energies}
        p = out / "device_power_flow.png"
        _plot_power_flow(p, energies, title, note, per_stride)
        written.append(p)
    return written
