"""Figures of the bench experiments: on the stand (torque-velocity, isometric steps,
frequency response, position step; the stiffness sweeps' torque-angle loops and time series),
drawn from the ``series`` :func:`afo_mj.experiments.bench_stand.run_stand` returns; on the
simulated load: :mod:`afo_mj.outputs.circuit_figures`.
"""

from __future__ import annotations

import math
import warnings
from pathlib import Path
from typing import Mapping

import numpy as np

from afo_mj.experiments.frequency_sweep import resonance_peak
from afo_mj.experiments.bench_stand import STROKE_LIMIT_RAD
from afo_mj.scenarios.bench_protocols import BenchError, StiffnessBenchError

__all__ = ["plot_bench", "plot_stiffness_bench", "plot_bench_series"]

_DEG = math.pi / 180.0


def plot_bench_series(rig: str, series: Mapping, out_dir, name: str,
                      published: Mapping | None = None) -> list:
    """The figures of a bench run on ``rig`` (``stand``: :func:`plot_bench` for the
    protocols with time series, :func:`plot_stiffness_bench` for the stiffness sweeps;
    ``load``: :func:`afo_mj.outputs.circuit_figures.plot_circuit_bench`) into ``out_dir``;
    ``published``: figures to mark on the torque–velocity plot. Returns the paths written."""
    if rig == "load":
        from afo_mj.outputs.circuit_figures import plot_circuit_bench
        return plot_circuit_bench(series, out_dir, name)
    paths = []
    if any(k != "stiffness_sweeps" for k in series):
        paths += plot_bench(series, out_dir, published)
    if "stiffness_sweeps" in series:
        paths += plot_stiffness_bench(series, out_dir)
    return paths


# -- the HAFO bench ----------------------------------------------------------------------
def plot_bench(series: Mapping[str, Mapping[str, np.ndarray]], out_dir,
               published: Mapping | None = None) -> list[Path]:
    """Write the stand's figures present in ``series`` as PNGs into ``out_dir``; returns
    paths (the file names keep the HAFO bench's, where they were first drawn).

    ``hafo_torque_velocity.png`` (curve, with the ``published`` stall torque and no-load speed
    when given: the HAFO prototype's 65 N·m / 105 deg/s), ``hafo_isometric_steps.png``,
    ``hafo_bode.png`` (magnitude re low frequency and phase, torque and velocity),
    ``hafo_position_step.png``.
    """
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    if not isinstance(series, Mapping):
        raise BenchError(f"series = {type(series).__name__}; allowed: the series dict of "
                         "run_bench")
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    paths = []

    def save(fig, name):
        p = out / name
        fig.tight_layout()
        fig.savefig(p, dpi=120)
        plt.close(fig)
        paths.append(p)

    if "torque_velocity" in series:
        tv = series["torque_velocity"]
        fig, ax = plt.subplots(figsize=(6, 4.2))
        ax.plot(tv["plantarflexion_speed_deg_s"], tv["assist_torque_nm"], "o-", label="model")
        if published:
            ax.plot([0.0], [published["stall_torque_nm"]], "r*", ms=13,
                    label=f"published {published['stall_torque_nm']:g} N·m stall")
            ax.plot([published["no_load_speed_deg_s"]], [0.0], "rs", ms=9,
                    label=f"published {published['no_load_speed_deg_s']:g} deg/s no load")
        if "no_load" in series:
            nl = series["no_load"]
            t = nl["time_s"]
            sel = (t >= 0.15) & (nl["angle_deg"] >= -math.degrees(STROKE_LIMIT_RAD))
            if np.any(sel):
                ax.plot([-float(np.mean(nl["velocity_deg_s"][sel]))], [0.0], "kx", ms=10,
                        mew=2, label="model no load (free foot)")
        ax.axhline(0, color="0.6", lw=0.8)
        ax.set_xlabel("plantarflexion speed [deg/s]")
        ax.set_ylabel("plantarflexion torque [N·m]")
        ax.set_title("Torque–velocity at full motor voltage")
        ax.legend(fontsize=8)
        ax.grid(alpha=0.3)
        save(fig, "hafo_torque_velocity.png")

    steps = sorted((k for k in series if k.startswith("isometric_step_")),
                   key=lambda k: float(k.removeprefix("isometric_step_").removesuffix("nm")))
    if steps:
        fig, ax = plt.subplots(figsize=(6, 4.2))
        for k in steps:
            s = series[k]
            lab = k.removeprefix("isometric_step_").replace("nm", " N·m")
            line, = ax.plot(s["time_s"], -s["torque_nm"], label=lab)
            ax.plot(s["time_s"], -s["command_nm"], "--", color=line.get_color(), lw=0.8)
        ax.set_xlabel("time [s]")
        ax.set_ylabel("plantarflexion torque [N·m]")
        ax.set_title("Isometric torque steps (dashed: command)")
        ax.legend(fontsize=8)
        ax.grid(alpha=0.3)
        save(fig, "hafo_isometric_steps.png")

    fr = [k for k in ("frequency_response_torque", "frequency_response_velocity") if k in series]
    if fr:
        fig, (a1, a2) = plt.subplots(2, 1, figsize=(6, 6), sharex=True)
        for k in fr:
            s = series[k]
            lab = {"torque": "isometric torque (foot locked)",
                   "velocity": "ankle velocity (free foot)"}.get(
                       k.removeprefix("frequency_response_"), k)
            lab += f", {len(s['freq_hz'])} frequencies"
            line, = a1.semilogx(s["freq_hz"], s["gain_db"], "o-", ms=3, label=lab)
            a2.semilogx(s["freq_hz"], s["phase_deg"], "o-", ms=3, label=lab)
            f_pk, db_pk, inside = resonance_peak(s["freq_hz"], s["gain"])
            if inside:
                a1.plot([f_pk], [db_pk], "v", color=line.get_color(), ms=7,
                        label=f"peak {f_pk:.0f} Hz, {db_pk:+.1f} dB")
        a1.axhline(-3.0, color="0.5", ls=":", lw=1, label="−3 dB (bandwidth)")
        a1.set_ylabel("gain re low frequency [dB]")
        a1.set_title("Open-loop response to motor voltage")
        a1.legend(fontsize=8)
        a2.set_ylabel("phase [deg]")
        a2.set_xlabel("frequency [Hz]")
        for a in (a1, a2):
            a.grid(alpha=0.3, which="both")
        save(fig, "hafo_bode.png")

    if "position_step" in series:
        s = series["position_step"]
        fig, (a1, a2) = plt.subplots(2, 1, figsize=(6, 5.5), sharex=True)
        a1.plot(s["time_s"], s["angle_deg"], label="ankle angle")
        a1.plot(s["time_s"], s["reference_deg"], "--", label="reference")
        a1.set_ylabel("ankle angle [deg]\n(+ dorsiflexion)")
        a1.legend(fontsize=8)
        a2.plot(s["time_s"], s["torque_nm"], label="delivered")
        a2.plot(s["time_s"], s["command_nm"], "--", lw=0.8, label="commanded")
        a2.set_ylabel("device torque [N·m]\n(+ dorsiflexing)")
        a2.set_xlabel("time [s]")
        a2.legend(fontsize=8)
        a1.set_title("Closed-loop position step (PD + gravity compensation, torque mode)")
        for a in (a1, a2):
            a.grid(alpha=0.3)
        save(fig, "hafo_position_step.png")
    if not paths:
        warnings.warn("plot_bench: series holds none of the bench tests; nothing drawn",
                      RuntimeWarning, stacklevel=2)
    return paths


# -- the stiffness rig -------------------------------------------------------------------
def plot_stiffness_bench(series: Mapping, out_dir) -> list[Path]:
    """Write the stiffness-rig figures into ``out_dir``; returns the paths written:

    * ``stiffness_loops.png``: torque vs angle loops per commanded stiffness (solid) with the
      commanded spring lines τ = −K (θ − θ0) (dashed);
    * ``stiffness_timeseries.png`` (when the series carries the device log, as
      :func:`~afo_mj.experiments.bench_stand.stiffness_sweeps`' does): one column per
      commanded stiffness against time:
      commanded vs delivered torque (N·m, + dorsiflexing) with the imposed ankle angle (deg,
      right axis); pressures (bar, gauge: supply rail, pump outlet, cylinder chambers A
      and B); servo-valve spool position and command (normalised, ± 1 = full stroke). Shaded:
      the first cycle, dropped from the stiffness fit as start-up.
    """
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    sweeps = series.get("stiffness_sweeps") if isinstance(series, Mapping) else None
    if not sweeps:
        raise StiffnessBenchError("series has no 'stiffness_sweeps'; allowed: the series of "
                                  "stiffness_sweeps")
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    fig, ax = plt.subplots(figsize=(6.4, 4.8))
    for lab, s in sweeps.items():
        th = np.degrees(s["angle_rad"])
        line, = ax.plot(th, s["torque_nm"], lw=1.0,
                        label=f"{lab.removeprefix('k')} N·m/deg emulated")
        k_deg = s["stiffness_nm_per_rad"] * _DEG
        x = np.array([th.min(), th.max()])
        ax.plot(x, -k_deg * (x - math.degrees(s["rest_angle_rad"])), "--", color="k",
                lw=0.8, zorder=3, label=f"{k_deg:g} N·m/deg commanded")
    ax.axhline(0, color="0.6", lw=0.6)
    ax.axvline(0, color="0.6", lw=0.6)
    ax.set_xlabel("ankle angle [deg] (+ dorsiflexion)")
    ax.set_ylabel("orthosis torque on the ankle [N·m] (+ dorsiflexing)")
    ax.set_title("Stiffness emulation on the stiffness rig: torque vs angle")
    ax.legend(fontsize=7, ncol=2)
    ax.grid(alpha=0.3)
    fig.tight_layout()
    p = out / "stiffness_loops.png"
    fig.savefig(p, dpi=120)
    plt.close(fig)
    paths = [p]
    if all("log_time_s" in s for s in sweeps.values()):
        p = out / "stiffness_timeseries.png"
        _plot_stiffness_timeseries(sweeps, p)
        paths.append(p)
    return paths


def _plot_stiffness_timeseries(sweeps: Mapping, path: Path) -> None:
    """``stiffness_timeseries.png`` (see :func:`plot_stiffness_bench`)."""
    import matplotlib
    matplotlib.use("Agg", force=False)
    from matplotlib.figure import Figure

    n = len(sweeps)
    fig = Figure(figsize=(max(7.0, 5.2 * n), 9.0), layout="constrained")
    axes = np.asarray(fig.subplots(3, n, sharex="col", sharey="row", squeeze=False))
    for j, (lab, s) in enumerate(sweeps.items()):
        t = np.asarray(s["log_time_s"])
        k_deg = s["stiffness_nm_per_rad"] * _DEG
        ax = axes[0, j]
        ax.plot(t, s["commanded_torque_nm"], "--", color="k", lw=1.1, label="commanded")
        ax.plot(t, s["log_delivered_torque_nm"], color="C3", lw=1.4, label="delivered")
        ax.set_title(f"commanded spring {k_deg:g} N·m/deg")
        axr = ax.twinx()
        axr.plot(s["time_s"], np.degrees(s["angle_rad"]), color="C0", lw=0.9, alpha=0.6,
                 label="ankle angle (imposed; right axis)")
        axr.set_ylim(-1.6 * np.degrees(np.max(np.abs(s["angle_rad"]))),
                     1.6 * np.degrees(np.max(np.abs(s["angle_rad"]))))
        if j == n - 1:
            axr.set_ylabel("ankle angle [deg] (+ dorsiflexion)", color="C0")
        else:
            axr.tick_params(labelright=False)
        if j == 0:
            h1, l1 = ax.get_legend_handles_labels()
            h2, l2 = axr.get_legend_handles_labels()
            handles, labels = h1 + h2, ["torque commanded", "torque delivered"] + l2
        ax = axes[1, j]
        for name, lbl, col, ls in (("supply_pa", "supply rail", "C0", "--"),
                                   ("pump_pa", "pump outlet", "C1", ":"),
                                   ("chamber_a_pa", "chamber A", "C4", "-"),
                                   ("chamber_b_pa", "chamber B", "C5", "-")):
            if name not in s:          # a signal this device does not log
                continue
            x = np.asarray(s[name])
            ax.plot(t if x.size == t.size else s["time_s"], x / 1e5, ls, color=col, lw=1.2,
                    label=lbl)
        if j == 0:
            h, lb = ax.get_legend_handles_labels()
            handles, labels = handles + h, labels + [f"{x} pressure" for x in lb]
        ax = axes[2, j]
        if "valve_command" in s:
            ax.plot(t, s["valve_command"], "--", color="0.3", lw=1.0, label="valve command")
        if "valve_position" in s:
            ax.plot(t, s["valve_position"], color="C2", lw=1.2, label="valve spool position")
        if j == 0:
            h, lb = ax.get_legend_handles_labels()
            handles, labels = handles + h, labels + lb
        ax.set_xlabel("time [s]")
        # the first cycle: start-up, dropped from the fit (zero crossings of the imposed
        # sinusoid: the cycle is the time to the second upward crossing)
        th = np.asarray(s["angle_rad"])
        ts = np.asarray(s["time_s"])
        up = np.nonzero((th[:-1] <= 0.0) & (th[1:] > 0.0))[0]
        if up.size >= 2:
            for a in axes[:, j]:
                a.axvspan(ts[0], ts[up[1]], color="0.9", lw=0, zorder=0)
        for a in axes[:, j]:
            a.axhline(0.0, color="0.7", lw=0.6)
            a.grid(True, color="0.92", lw=0.5)
            a.set_axisbelow(True)
            a.set_xlim(float(t[0]), float(t[-1]))
    fig.legend(handles, labels, loc="outside lower center", ncol=5, fontsize="small",
               frameon=False)
    axes[0, 0].set_ylabel("orthosis torque [N·m]\n(+ dorsiflexing)")
    axes[1, 0].set_ylabel("pressure [bar] (gauge)")
    axes[2, 0].set_ylabel("servo valve\n[normalised, ± 1 = full stroke]")
    fig.suptitle("Stiffness emulation on the stiffness rig against time: torque tracking, "
                 "circuit pressures, servo valve\n(shaded: the first cycle, dropped from the "
                 "fit as start-up)")
    fig.savefig(path, dpi=110)
