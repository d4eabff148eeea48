"""Result files of a walking run, written atomically.

:func:`write_run_outputs` writes into ``out_dir``:

* ``summary.json`` -- the summary of :func:`afo_mj.metrics.gait_metrics.summarize` (strict
  JSON: NaN/inf become ``null``; a non-finite joint-angle RMS error is a numerics failure and
  raises :class:`ReportError` instead);
* ``cycles.csv`` -- one row per analysed cycle per leg: leg, stride, start/end/toe-off times
  and every per-cycle scalar, units in the column names;
* ``gait_curves.csv`` -- mean and SD over cycles of every resampled channel, and the
  reference mean/SD, on 0..100 % of the cycle;
* ``gait_curves.png`` -- 3×3 figure: joint angle, moment and power vs % cycle for hip, knee
  and ankle; simulation mean ± 1 SD shaded, reference mean (with its ±1 SD band where it has
  one, named with its source in the title and legend; Winter's table has no SD: dashed line
  only, and the title says no band is drawn:
  :mod:`afo_mj.outputs.reference_display`). Moments are drawn in the biomechanics convention,
  extensor/plantarflexor positive (the negative of the record's sign). With the run's record
  the moments and powers are low-pass filtered for the figure only (zero-lag 4th-order
  Butterworth, 6 Hz, :mod:`afo_mj.metrics.kinetics_filter`; stated in the title);
  ``summary.json`` and ``gait_curves.csv`` stay unfiltered;
* ``scenario.toml`` -- the scenario text, when given.

Everything is first written into a temporary sibling directory, then each file is moved into
``out_dir`` with :func:`os.replace`; a failure before that leaves ``out_dir`` untouched (and
not created). Files in ``out_dir`` other than these are left alone.
"""

from __future__ import annotations

import csv
import json
import math
import textwrap
from pathlib import Path
from typing import Any, Sequence

import numpy as np

from afo_mj.outputs.result_dir import ResultDirError, write_atomically
from afo_mj.metrics.gait_metrics import (
    CURVE_CHANNELS, JOINTS, PERCENT_CYCLE, GaitCycle, reference_band, curve_statistics)
from afo_mj.metrics.kinetics_filter import (
    KINETIC_CHANNELS, KINETICS_CUTOFF_HZ, filter_note, filtered_kinetic_cycles)
from afo_mj.outputs.reference_display import (
    reference_band_note, reference_curve, reference_label)

__all__ = ["ReportError", "write_run_outputs", "gait_curve_panels", "OUTPUT_FILES",
           "json_ready"]

OUTPUT_FILES = ("summary.json", "cycles.csv", "gait_curves.csv", "gait_curves.png",
                "scenario.toml")

#: Summary keys whose mean must be finite: a NaN there means the simulation's numbers broke.
KEY_METRICS = tuple(f"{j}_angle_rms_error_deg" for j in JOINTS)


class ReportError(ValueError):
    """The results cannot be written as they are (non-finite key metric, bad input)."""


def json_ready(x: Any) -> Any:
    """NaN/inf → None, numpy scalars/arrays → Python, recursively."""
    if isinstance(x, dict):
        return {str(k): json_ready(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [json_ready(v) for v in x]
    if isinstance(x, np.ndarray):
        return json_ready(x.tolist())
    if isinstance(x, (float, np.floating)):
        return float(x) if math.isfinite(x) else None
    if isinstance(x, (np.integer,)):
        return int(x)
    if isinstance(x, np.bool_):
        return bool(x)
    return x


def _check_key_metrics(summary: dict) -> None:
    for key in KEY_METRICS:
        if key not in summary:
            continue
        entry = summary[key]
        mean = entry.get("mean") if isinstance(entry, dict) else entry
        if mean is None or not math.isfinite(float(mean)):
            raise ReportError(f"summary[{key!r}] mean = {mean!r}: a joint-angle RMS error that "
                              f"is not a finite number means the simulation's numerics failed; "
                              f"no results written")


def _write_summary(path: Path, summary: dict) -> None:
    text = json.dumps(json_ready(summary), indent=2, allow_nan=False)
    path.write_text(text + "\n", encoding="utf-8")


def _write_cycles(path: Path, cycles: Sequence[GaitCycle]) -> None:
    keys = list(cycles[0].scalars) if cycles else []
    with path.open("w", newline="", encoding="utf-8") as f:
        w = csv.writer(f)
        w.writerow(["leg", "stride", "start_s", "end_s", "toe_off_s", *keys])
        for c in cycles:
            w.writerow([c.leg, c.stride, f"{c.start_s:.6f}", f"{c.end_s:.6f}",
                        "" if c.toe_off_s is None else f"{c.toe_off_s:.6f}",
                        *("" if not math.isfinite(c.scalars[k]) else f"{c.scalars[k]:.8g}"
                          for k in keys)])


def _write_curves(path: Path, cycles: Sequence[GaitCycle], reference) -> None:
    cols: list[tuple[str, np.ndarray | None]] = [("percent_cycle", PERCENT_CYCLE)]
    for ch in CURVE_CHANNELS:
        mean, sd = curve_statistics(cycles, ch)
        cols += [(f"{ch}_mean", mean), (f"{ch}_sd", sd)]
        band = reference_band(reference, ch)
        if band is not None:
            cols += [(f"reference_{ch}_mean", band[0]), (f"reference_{ch}_sd", band[1])]
    with path.open("w", newline="", encoding="utf-8") as f:
        w = csv.writer(f)
        w.writerow([n for n, _ in cols])
        for i in range(PERCENT_CYCLE.size):
            w.writerow(["" if v is None or not math.isfinite(v[i]) else f"{v[i]:.8g}"
                        for _, v in cols])


_ROWS = (("angle_rad", math.degrees(1.0), "angle [deg]\n(+ flexion / dorsiflexion)"),
         ("moment_nm_per_kg", -1.0,
          "moment [N·m/kg]\n(+ extensor / plantarflexor,\n= −moment of the record)"),
         ("power_w_per_kg", 1.0, "power [W/kg]\n(+ generation)"))


def gait_curve_panels(cycles: Sequence[GaitCycle], reference, record=None,
                      cutoff_hz: float = KINETICS_CUTOFF_HZ) -> dict:
    """The data ``gait_curves.png`` draws, as drawn (scaled, degrees, biomechanics signs).

    Returns ``{"panels": {channel: {"simulation_mean", "simulation_lower",
    "simulation_upper", "reference": ReferenceCurve | None, "filtered": bool}}, "band":
    whether any reference band is drawn, "filtered": whether moments/powers were low-pass
    filtered (with ``record``; see :mod:`afo_mj.metrics.kinetics_filter`), "notes": the
    caption lines (what the reference and its band are, the filter)}``.
    """
    shown = filtered_kinetic_cycles(record, cycles, cutoff_hz) if record is not None else cycles
    panels = {}
    for kind, scale, _ in _ROWS:
        for joint in JOINTS:
            ch = f"{joint}_{kind}"
            filt = record is not None and ch in KINETIC_CHANNELS
            mean, sd = curve_statistics(shown if filt else cycles, ch)
            lo = hi = None
            if sd is not None:
                a, b = scale * (mean - sd), scale * (mean + sd)
                lo, hi = np.minimum(a, b), np.maximum(a, b)
            panels[ch] = {"simulation_mean": scale * mean, "simulation_lower": lo,
                          "simulation_upper": hi,
                          "reference": reference_curve(reference, ch, scale),
                          "filtered": filt}
    band = any(p["reference"] is not None and p["reference"].has_band for p in panels.values())
    notes = [] if reference is None else [reference_band_note(reference, band)]
    notes.append(filter_note(cutoff_hz) if record is not None
                 else "moments and powers unfiltered (no record given)")
    return {"panels": panels, "band": band, "filtered": record is not None, "notes": notes}


def _plot(path: Path, cycles: Sequence[GaitCycle], reference, title: str,
          record=None) -> None:
    import matplotlib
    matplotlib.use("Agg", force=False)
    from matplotlib.figure import Figure

    data = gait_curve_panels(cycles, reference, record)
    fig = Figure(figsize=(12, 9.4), layout="constrained")
    axes = fig.subplots(3, 3, sharex=True)
    for r, (kind, scale, ylabel) in enumerate(_ROWS):
        for c, joint in enumerate(JOINTS):
            ax = axes[r, c]
            p = data["panels"][f"{joint}_{kind}"]
            ax.plot(PERCENT_CYCLE, p["simulation_mean"], color="C0", lw=1.8,
                    label=f"simulation (n = {len(cycles)})")
            if p["simulation_lower"] is not None:
                ax.fill_between(PERCENT_CYCLE, p["simulation_lower"], p["simulation_upper"],
                                color="C0", alpha=0.25, lw=0, label="simulation ±1 SD")
            ref = p["reference"]
            if ref is not None:
                ax.plot(PERCENT_CYCLE, ref.mean, color="k", lw=1.2, ls="--",
                        label="reference mean")
                if ref.has_band:
                    ax.fill_between(PERCENT_CYCLE, ref.lower, ref.upper, color="0.5",
                                    alpha=0.25, lw=0, label="reference ± 1 SD")
            ax.axhline(0.0, color="0.7", lw=0.6)
            if r == 0:
                ax.set_title(joint)
            if c == 0:
                ax.set_ylabel(ylabel + ("\nfiltered, see title" if p["filtered"] else ""))
            if r == 2:
                ax.set_xlabel("gait cycle [%] (heel strike to heel strike)")
            ax.set_xlim(0, 100)
    axes[0, 0].legend(fontsize="small", loc="best")
    lines = [title]
    if reference is not None:
        lines.append(reference_label(reference, data["band"]))
    lines += data["notes"]
    fig.suptitle("\n".join(textwrap.fill(x, 130) for x in lines), fontsize="medium")
    fig.savefig(path, dpi=110)


def write_run_outputs(out_dir, summary: dict, cycles: Sequence[GaitCycle], reference,
                      record=None, scenario_text: str | None = None,
                      title: str | None = None, extra_tables: dict | None = None,
                      extra_files=None, figures: bool = True) -> Path:
    """Write the run's result files into ``out_dir`` atomically (see the module docstring).

    ``cycles``: the analysed cycles (:func:`afo_mj.metrics.gait_metrics.extract_cycles` or
    ``analyse_gait(...).cycles``); ``reference``: the reference gait the run was compared
    with; ``record``: the run's :class:`~afo_mj.gait.record.GaitRecord` (only its body size
    is used, for the figure title); ``extra_tables``: ``{file name: (CSV header, 2-D array)}``;
    ``extra_files``: a callable that writes more files (figures, run information) into the
    directory it is given; ``figures``: False leaves out ``gait_curves.png`` (sweeps and
    tests that read only the numbers).
    Returns the output directory path.
    A run that fell before any analysable cycle (``summary["fell"]`` true, no cycles) writes
    its outcome: ``summary.json`` (and ``scenario.toml``) only.
    Raises :class:`ReportError` (nothing written) for a non-finite key metric, or for no
    cycles without a fall.
    """
    out = Path(out_dir)
    if not cycles and not summary.get("fell"):
        raise ReportError("write_run_outputs: no cycles to write; nothing written")
    if cycles:
        _check_key_metrics(summary)
    if title is None:
        name = (summary.get("scenario", {}).get("name")
                if isinstance(summary.get("scenario"), dict) else None)
        title = f"{name or 'walk'}: {len(cycles)} cycles"
        if record is not None:
            title += f", {record.body_mass_kg:g} kg, {record.height_m:g} m"

    def writer(tmp: Path) -> None:
        _write_summary(tmp / "summary.json", summary)
        if cycles:
            _write_cycles(tmp / "cycles.csv", cycles)
            _write_curves(tmp / "gait_curves.csv", cycles, reference)
            if figures:
                _plot(tmp / "gait_curves.png", cycles, reference, title, record)
        if scenario_text is not None:
            (tmp / "scenario.toml").write_text(scenario_text, encoding="utf-8")
        for fname, (header, data) in (extra_tables or {}).items():
            # extra time series (e.g. the device's), SI units named in the header
            if not np.all(np.isfinite(data)):
                raise ReportError(f"{fname}: non-finite values; nothing written")
            np.savetxt(tmp / fname, data, delimiter=",", header=header, comments="",
                       fmt="%.9g")
        if extra_files is not None:
            extra_files(tmp)

    from afo_mj import progress
    rep = progress.reporter()
    t0 = rep.clock()
    rep.stage(f"writing the results{' and figures' if figures else ''} to {out}…")
    try:
        written = write_atomically(out, writer)
    except ResultDirError as exc:
        raise ReportError(str(exc)) from None
    rep.stage(f"results written in {progress.fmt_duration(rep.clock() - t0)}")
    return written
