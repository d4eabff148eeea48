"""Figures of a device run (the conditions of :func:`afo_mj.scenarios.device_scenario.run_device_scenario`).

:func:`plot_device_run` writes into ``out_dir``:

* ``ankle_angle_conditions.png`` -- the worn side's ankle (right unless the device is worn on
  the left only) vs % gait cycle, mean ± 1 SD over the analysed cycles of each condition
  (``no_device`` / ``transparent`` / ``assist``, those present), over the reference band:
  angle (deg, + dorsiflexion), human (muscle) ankle power (W/kg, + generation) and, for the
  device conditions, the orthosis moment (N·m/kg, + plantarflexor, the biomechanics
  convention of ``gait_curves.png``: the negative of the record's sign);
* ``device_torque.png`` -- per device condition, the last (up to) 3 strides of the device
  log against time: commanded, delivered and measured torque (N·m, + plantarflexion),
  actuator chamber pressures (bar, absolute as logged) and motor current (A); dotted
  vertical lines are the worn side's heel strikes;
* ``device_power_flow.png`` -- per device condition, the energy ledger of the whole run (J)
  as a waterfall: what entered the device (electrical energy drawn from the battery,
  mechanical energy the ankle did on the device, energy released from storage), then where
  it went (each named loss, net energy stored, energy regenerated into the battery, positive
  mechanical work done on the ankle); what is left at the end is the ledger's residual.

A condition whose analysis is ``None`` (the walker fell before an analysable cycle) is left
out of every figure; a figure with nothing to draw (no device condition) is not written.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from afo_mj.analysis.gait_metrics import PERCENT_CYCLE, curve_statistics, reference_band

__all__ = ["plot_device_run", "DEVICE_FIGURES"]

DEVICE_FIGURES = ("ankle_angle_conditions.png", "device_torque.png", "device_power_flow.png")

_COLOURS = {"no_device": "C0", "transparent": "C1", "assist": "C2"}
_LABELS = {"no_device": "no device", "transparent": "transparent (worn, 0 N·m)",
           "assist": "assist"}
_DPI = 110
_N_STRIDES_SHOWN = 3


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


def _band(ax, x, mean, sd, scale, colour, label, alpha=0.22, ls="-", lw=1.8):
    ax.plot(x, scale * mean, color=colour, lw=lw, ls=ls, label=label)
    if sd is not None:
        lo, hi = scale * (mean - sd), scale * (mean + sd)
        ax.fill_between(x, np.minimum(lo, hi), np.maximum(lo, hi), color=colour, alpha=alpha,
                        lw=0)


# ------------------------------------------------------------------------------------------
# 1. ankle curves per condition
# ------------------------------------------------------------------------------------------

def _plot_conditions(path: Path, conds: dict, reference, side: int, title: str) -> None:
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
            cycles = [c for c in analysis.cycles if c.side == side]
            if not cycles or ch not in cycles[0].curves:
                continue
            mean, sd = curve_statistics(cycles, ch)
            _band(ax, PERCENT_CYCLE, mean, sd, scale, _colour(cond, i),
                  f"{_LABELS.get(cond, cond)}: n = {len(cycles)}, mean ± 1 SD")
        ax.axhline(0.0, color="0.7", lw=0.6)
        ax.set_ylabel(ylabel)
        ax.set_xlim(0, 100)
        ax.grid(True, color="0.92", lw=0.5)
        if ax.get_legend_handles_labels()[0]:
            ax.legend(fontsize="small", loc="best")
    axes[-1].set_xlabel(f"{leg} gait cycle [%] (heel strike to heel strike)")
    fig.suptitle(f"{title}\n{leg} ankle by condition: simulation mean ± 1 SD over the analysed "
                 "cycles;\nreference mean dashed (± 1 SD grey where the reference has one)")
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
        rmse = math.sqrt(float(np.mean((L["commanded_torque_nm"][m, 0]
                                        - L["delivered_torque_nm"][m, 0]) ** 2))) if tt.size else math.nan
        ax.set_title(f"{_LABELS.get(cond, cond)}: last {max(len(hs) - 1, 0)} strides "
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

def _flow_items(energy: dict) -> tuple[list[tuple[str, float, str]], float]:
    """(label, signed amount J, colour) in waterfall order (+ into the device, − out of it),
    and the ledger residual."""
    drawn = float(energy.get("electrical_in_j") or 0.0)
    regen = float(energy.get("electrical_regenerated_j") or 0.0)
    mech_net = float(energy.get("mechanical_out_j") or 0.0)
    mech_pos = float(energy.get("mechanical_positive_out_j") or 0.0)
    mech_absorbed = max(mech_pos - mech_net, 0.0)      # negative work of the ankle on the device
    losses = {k: float(v) for k, v in (energy.get("losses_j") or {}).items()}
    stored = float(sum((energy.get("stored_change_j") or {}).values()))
    items = [("electrical drawn from battery", drawn, "C2"),
             ("mechanical in (ankle back-drives device)", mech_absorbed, "C9")]
    if stored < 0:
        items.append(("released from storage (net)", -stored, "0.6"))
    for k, v in sorted(losses.items(), key=lambda kv: -abs(kv[1])):
        items.append((f"loss: {k.replace('_', ' ')}", -v, "C3"))
    if stored >= 0:
        items.append(("stored (oil, rotor, L, reservoir; net)", -stored, "0.6"))
    items.append(("regenerated into battery", -regen, "C0"))
    items.append(("mechanical positive out (to ankle)", -mech_pos, "C4"))
    residual = sum(v for _, v, _ in items)
    return items, residual


def _plot_power_flow(path: Path, energies: dict, title: str, note: str) -> None:
    n = len(energies)
    rows = max(len(_flow_items(e)[0]) for e in energies.values())
    fig = _figure((max(7.5, 6.4 * n), 1.2 + 0.42 * (rows + 2)))
    axes = np.asarray(fig.subplots(1, n, sharey=True, squeeze=False))[0]
    for j, (cond, energy) in enumerate(energies.items()):
        ax = axes[j]
        items, residual = _flow_items(energy)
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
        ax.set_title(f"{_LABELS.get(cond, cond)}: {top:.0f} J in{sub}", fontsize="medium")
        ax.set_xlabel("energy, whole run [J] (cumulative: bars right = into device, "
                      "left = out of it)", fontsize="small")
    fig.suptitle(f"{title}\ndevice energy flow, whole run ({note}); % of all energy in")
    fig.savefig(path, dpi=_DPI)


# ------------------------------------------------------------------------------------------

def plot_device_run(out_dir, results: dict, reference, summary: dict,
                    title: str) -> list[Path]:
    """Write the device-run figures (see the module docstring) into ``out_dir`` (created if
    missing) and return the paths written.

    ``results``: ``{condition: (record, analysis or None, device or None)}`` and ``summary``
    (with ``"device_conditions"`` and ``"device_sides"``) as returned by
    :func:`afo_mj.scenarios.device_scenario.run_device_scenario`; ``reference``: the reference
    gait the run was compared with; ``title``: the first line of every figure's title.
    """
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    side = _worn_side(summary)
    conds = {c: v for c, v in results.items() if v[1] is not None}
    written: list[Path] = []
    if not conds:
        return written

    p = out / "ankle_angle_conditions.png"
    _plot_conditions(p, conds, reference, side, title)
    written.append(p)

    devs = {c: v for c, v in conds.items() if v[2] is not None and v[2].log.n > 1}
    if devs:
        p = out / "device_torque.png"
        _plot_torque(p, devs, side, title)
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
        p = out / "device_power_flow.png"
        _plot_power_flow(p, energies, title, note)
        written.append(p)
    return written
