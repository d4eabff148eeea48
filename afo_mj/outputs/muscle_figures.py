"""The muscle figure of a muscle-driven walk: ``muscles_cycle.png``.

From the stride-mean table of :func:`afo_mj.metrics.muscle_metrics.muscle_cycle_table` (right
leg, % gait cycle from heel strike): per muscle one row with its excitation and activation
(0–1) and, as grey bars under the curves, the on-intervals of normal walking EMG where
:data:`afo_mj.metrics.muscle_timing.PERRY_ON_PCT` has them (Perry & Burnfield 2010); a
second column with the muscle's fibre power (W, + shortening: ``F × (−v_CE)``) and its
Umberger metabolic rate (W). The title carries the whole walk's net metabolic rate.
"""

from __future__ import annotations

from pathlib import Path

__all__ = ["plot_muscle_cycle"]


def plot_muscle_cycle(path, header, rows, muscles, perry=None, title: str = "") -> Path:
    """Write ``muscles_cycle.png`` (module docstring) from the table ``(header, rows)``."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    col = {h: i for i, h in enumerate(header)}
    ph = rows[:, col["phase_pct"]]
    n = len(muscles)
    fig, axes = plt.subplots(n, 2, figsize=(10, 1.6 * n + 0.8), sharex=True, squeeze=False)
    for i, name in enumerate(muscles):
        ax, ax2 = axes[i]
        for a, b in (perry or {}).get(name, ()):
            for lo, hi in ((a, min(b, 100.0)), (0.0, b - 100.0) if b > 100.0 else (0, 0)):
                if hi > lo:
                    ax.axvspan(lo, hi, ymax=0.12, color="0.6", lw=0)
        ax.plot(ph, rows[:, col[f"{name}.excitation"]], lw=1, color="tab:orange",
                label="excitation")
        ax.plot(ph, rows[:, col[f"{name}.activation"]], lw=1.6, color="tab:blue",
                label="activation")
        ax.set_ylim(0, 1.05)
        ax.set_ylabel(name.replace("_", " "), fontsize=8)
        ax2.plot(ph, rows[:, col[f"{name}.power_w"]], lw=1.2, color="tab:green",
                 label="fibre power (W, + shortening)")
        ax2.plot(ph, rows[:, col[f"{name}.metabolic_w"]], lw=1.2, color="tab:red",
                 label="metabolic rate (W, Umberger)")
        ax2.axhline(0, color="0.8", lw=0.6)
    axes[0, 0].legend(fontsize=7, loc="upper right")
    axes[0, 1].legend(fontsize=7, loc="upper right")
    axes[0, 0].set_title("right leg, mean stride (grey: EMG on, Perry & Burnfield 2010)",
                         fontsize=9)
    for ax in axes[-1]:
        ax.set_xlabel("% gait cycle (right heel strike)")
        ax.set_xlim(0, 100)
    fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    out = Path(path)
    fig.savefig(out, dpi=110)
    plt.close(fig)
    return out
