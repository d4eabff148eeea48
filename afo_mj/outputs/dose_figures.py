"""The dose–response figure of :mod:`afo_mj.studies.dose_response`: ``dose_response.png``.

The change of the adapted wearer's net metabolic rate (%, Umberger 2010) against the control
(nothing worn, restart paired with restart) over the dose, as the exoskeleton papers plot a
metabolic change against a device parameter (Collins et al. 2015: against spring
stiffness): the band (min–max over the restarts) shaded, its mean as a line, each restart's
change as a point (hollow: its search had not converged); the change against the matched
control (the control searched on as long, when run) as a dashed line with its range; each
restart's best set walked with the device taken off as a grey triangle; and optionally a
published point with its error bar.
"""

from __future__ import annotations

from pathlib import Path

__all__ = ["plot_dose_response"]


def plot_dose_response(path, result, axis_label: str, reference=None) -> Path:
    """Write the figure (module docstring) for a ``DoseResponseResult`` to ``path``;
    ``reference``: ``(dose, change %, ± %, label)`` of a published point, or None. The
    control is drawn at 0 % where its dose is on the axis."""
    import matplotlib
    matplotlib.use("Agg", force=False)
    from matplotlib.figure import Figure
    fig = Figure(figsize=(6.0, 5.0), layout="constrained")
    ax = fig.add_subplot()
    xs, lo, mean, hi = [], [], [], []
    for lv in result.levels:
        if lv.dose is None:
            continue
        if lv is result.levels[0]:                  # the control on the axis: 0 by definition
            xs.append(lv.dose)
            lo.append(0.0)
            mean.append(0.0)
            hi.append(0.0)
            continue
        if lv.change_pct_mean is None:             # a restart fell: its points only
            continue
        xs.append(lv.dose)
        lo.append(lv.change_pct_min)
        mean.append(lv.change_pct_mean)
        hi.append(lv.change_pct_max)
    order = sorted(range(len(xs)), key=lambda i: xs[i])
    xs, lo, mean, hi = ([v[i] for i in order] for v in (xs, lo, mean, hi))
    ax.fill_between(xs, lo, hi, color="tab:blue", alpha=0.25, lw=0,
                    label="band: min–max over restarts")
    ax.plot(xs, mean, color="tab:blue", lw=1.8, label="mean of restarts")
    first = True
    for lv in result.levels[1:]:
        if lv.dose is None:
            continue
        for r in lv.restarts:
            if r.change_pct is None:
                continue
            ax.plot([lv.dose], [r.change_pct], "o", ms=4,
                    mfc="tab:blue" if r.converged else "white", mec="tab:blue",
                    label=("restart (hollow: search not converged)" if first else None))
            first = False
    matched = [(lv.dose, lv.matched_change_pct_min, lv.matched_change_pct_mean,
                lv.matched_change_pct_max) for lv in result.levels[1:]
               if lv.dose is not None and lv.matched_change_pct_mean is not None]
    if matched:
        if result.levels[0].dose is not None:
            matched.insert(0, (result.levels[0].dose, 0.0, 0.0, 0.0))
        mx, mlo, mmean, mhi = zip(*sorted(matched))
        ax.plot(mx, mmean, "--", color="tab:green", lw=1.5,
                label="against the control searched as long (mean)")
        ax.vlines(mx, mlo, mhi, color="tab:green", lw=3, alpha=0.5)
    off = [(lv.dose, r.device_off_change_pct) for lv in result.levels[1:]
           if lv.dose is not None for r in lv.restarts if r.device_off_change_pct is not None]
    if off:
        ax.plot(*zip(*off), "v", ms=5, mfc="white", mec="0.45",
                label="same wearer, device taken off (at its own speed)")
    fell = [lv.dose for lv in result.levels[1:] if lv.dose is not None
            and any(r.net_metabolic_w_per_kg is None for r in lv.restarts)]
    if fell:
        ax.plot(fell, [0.0] * len(fell), "x", color="tab:red", ms=7,
                label="a restart's best set falls in its scoring walk (level has no band)")
    if reference is not None:
        x, y, e, label = reference
        ax.errorbar([x], [y], yerr=[e], fmt="s", color="tab:red", capsize=3, label=label)
    ax.axhline(0.0, color="0.5", lw=0.8)
    ax.set_xlabel(axis_label)
    ax.set_ylabel("change in net metabolic rate (%)")
    p = result.protocol
    ax.set_title(f"{result.study}: {p['restarts']} restarts × {p['generations']} "
                 "generations per level", fontsize=9)
    fig.legend(*ax.get_legend_handles_labels(), loc="outside lower center", ncols=2,
               fontsize=7)      # under the axes: it hides no point
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=150)
    return path
