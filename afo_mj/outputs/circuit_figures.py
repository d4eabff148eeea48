"""Figures of a circuit description (issue 18) worn while walking and on the bench.

* :func:`plot_circuit_gait` — ``circuit_torque.png``: per worn condition, commanded and
  delivered ankle torque over the last strides, every pressure node of the circuit, and the
  motor current (the circuit's generic log: states and probes by name).
* :func:`plot_circuit_bench` — one PNG per bench protocol from
  :func:`afo_mj.experiments.bench_load.run_load_bench`'s series.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

_DPI = 110


def _figure(figsize):
    import matplotlib
    matplotlib.use("Agg", force=False)
    from matplotlib.figure import Figure
    return Figure(figsize=figsize, layout="constrained")


def plot_circuit_gait(out_dir, results: dict, summary: dict, title: str) -> list[Path]:
    """``results``: condition → (record, analysis, device); the CircuitDevice ones drawn."""
    out = Path(out_dir)
    devs = {c: v for c, v in results.items() if v[2] is not None and v[2].log is not None
            and v[2].log.n > 1}
    if not devs:
        return []
    n = len(devs)
    fig = _figure((max(6.5, 5.8 * n), 9.5))
    axes = np.asarray(fig.subplots(3, n, squeeze=False))
    for j, (cond, (rec, _a, dev)) in enumerate(devs.items()):
        L = dev.log.arrays()
        t = L["time_s"][:, 0]
        m = t >= max(float(t[-1]) - 3.0, float(t[0]))
        tt = t[m]
        cmd, dlv = L["commanded_torque_nm"][m, 0], L["delivered_torque_nm"][m, 0]
        ax = axes[0, j]
        ax.plot(tt, -cmd, "k--", lw=1.3, label="commanded")
        ax.plot(tt, -dlv, color="C3", lw=1.5, label="delivered")
        rmse = math.sqrt(float(np.mean((cmd - dlv) ** 2))) if tt.size else math.nan
        ax.set_title(f"{cond}: last 3 s (tracking RMSE {rmse:.1f} N·m)")
        ax.set_ylabel("ankle torque [N·m] (+ plantarflexion)")
        cc = dev.cc
        for name, kind in zip(cc.state_names, cc.state_kinds):
            if kind == "pressure":
                axes[1, j].plot(tt, L[name][m, 0] / 1e5, lw=1.1, label=name)
        axes[1, j].set_ylabel("node pressure [bar]")
        for name in cc.state_names:
            if name.endswith(".current_a"):
                axes[2, j].plot(tt, L[name][m, 0], lw=1.1, label=name)
        axes[2, j].set_ylabel("current [A]")
        axes[2, j].set_xlabel("time [s]")
        for ax in axes[:, j]:
            ax.grid(True, color="0.92", lw=0.5)
            ax.legend(fontsize="small", loc="best")
    fig.suptitle(f"{title}\ncircuit {summary.get('circuit', {}).get('name', '')}: torque "
                 "tracking, node pressures, motor current")
    p = out / "circuit_torque.png"
    fig.savefig(p, dpi=_DPI)
    return [p]


def plot_circuit_bench(series: dict, out_dir, title: str) -> list[Path]:
    """One figure per protocol: every series entry is ``{"x": ..., "y": {label: array},
    "xlabel", "ylabel", "log_x"}`` (time or frequency on x)."""
    out = Path(out_dir)
    written = []
    for proto, panels in series.items():
        fig = _figure((7.5, 3.2 * len(panels)))
        axes = np.atleast_1d(fig.subplots(len(panels), 1, squeeze=False)[:, 0])
        for ax, panel in zip(axes, panels):
            for label, y in panel["y"].items():
                ax.plot(panel["x"], y, lw=1.2, label=label, marker="o" if panel.get("markers")
                        else None, ms=3)
            if panel.get("log_x"):
                ax.set_xscale("log")
            ax.set_xlabel(panel.get("xlabel", ""))
            ax.set_ylabel(panel.get("ylabel", ""))
            ax.grid(True, color="0.92", lw=0.5)
            if len(panel["y"]) > 1:
                ax.legend(fontsize="small", loc="best")
        fig.suptitle(f"{title}: {proto}")
        p = out / f"bench_{proto}.png"
        fig.savefig(p, dpi=_DPI)
        written.append(p)
    return written
