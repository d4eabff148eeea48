"""How much of a calibration's residual is the replay's own numerical error.

The final model (declared parameters fitted, effects selected) is replayed twice on the first
``numerical_check_s`` of the record: by the replay the calibration fits with (the circuits'
stepper, :meth:`afo_mj.experiments.bench_replay.BenchReplay.simulate`) and by Radau at a tight
tolerance (:func:`afo_mj.experiments.replay_reference.reference_replay`), both read through the
model's sensor transforms. The difference is the stepper's error; it is set per channel
against the channel's noise σ and against the residual there. A check, not a fit: nothing is
adjusted.

Per channel, over the window's samples after ``settle_s``:

* ``rms_difference``, ``max_difference``: replay − Radau (channel units);
* ``ratio``: ``rms_difference/σ``, the numerical error in noise units;
* ``residual_ratio_replay``, ``residual_ratio_reference``: RMS(measured − model)/σ with the
  replay's and with Radau's outputs;
* ``share``: ``rms_difference / RMS(measured − replay)``, the numerical error's size against
  the residual (by the triangle inequality the residual without it is at least
  ``(1 − share)`` of it);
* ``explains_excess``: the replay's residual misses ``multiple``·σ there and Radau's reaches
  it (the stepper, not the rig, puts the channel above the noise multiple);
* ``notable``: ``ratio`` > :data:`NOTABLE_RATIO` (half the noise).

The Radau check's own tolerance (``rtol`` = :data:`CHECK_RTOL`): on the lab rig, the
pressures at rtol 1e-6 and 1e-7 differed by 0.09 Pa RMS over a 4 MPa span, at 1e-7 and 1e-8
by 0.001 Pa (a 1 s lab-rig run measured with this change), far below any sensor's noise.
"""

from __future__ import annotations

import math
from typing import Mapping

import numpy as np

from afo_mj.calibration.calibration_model import sensor_outputs
from afo_mj.experiments.bench_replay import ReplayError
from afo_mj.experiments.replay_reference import reference_replay

__all__ = ["numerical_error_check", "numerical_where", "CHECK_RTOL", "NOTABLE_RATIO"]

#: relative tolerance of the Radau check in a calibration
CHECK_RTOL = 1e-7
#: numerical error (RMS over σ) above which a channel's is named in the "where"
NOTABLE_RATIO = 0.5
_MIN_SAMPLES = 20


def numerical_error_check(model, effects, x: np.ndarray, window_s: float,
                          multiple: float) -> dict:
    """The check (module docstring) of the structure ``effects`` at normalised parameters
    ``x`` of ``model`` (a :class:`~afo_mj.calibration.calibration_model.CalibrationModel`)
    on the record's first ``window_s`` seconds; ``multiple`` is the noise multiple the
    baseline must reach. Returns ``{"run": True, "window_s": [t0, t1], "rtol",
    "wall_s", "rhs_evaluations", "below_floor_samples", "channels": {…}, "not_compared",
    "max_ratio", "explains_excess": [channels]}``, or ``{"run": False, "reason"}`` when it
    cannot run (a window of 0 s, one shorter than the settling time, a torque reference, a
    failed integration)."""
    if window_s <= 0.0:
        return {"run": False, "reason": "calibration.numerical_check_s = 0 (not asked for)"}
    t = model.t
    n = int(min(np.searchsorted(t, t[0] + window_s, side="right"), model.i_end))
    keep = np.flatnonzero(t[:n] >= t[0] + model.options.settle_s)
    if keep.size < _MIN_SAMPLES:
        return {"run": False, "reason": f"the window of {window_s:g} s leaves {keep.size} "
                f"samples after settle_s = {model.options.settle_s:g} s; allowed: at least "
                f"{_MIN_SAMPLES} (raise calibration.numerical_check_s)"}
    setting = model.setting(effects, x)
    inputs = {c: v[:n] for c, v in model.inputs.items()}
    try:
        ref = reference_replay(model.replay, t[:n], inputs, setting.row,
                               setting.backlash_rad, setting.temperature_rate_k_s,
                               rtol=CHECK_RTOL)
        sim = model.replay.simulate(t[:n], inputs, setting.row, setting.backlash_rad,
                                    setting.temperature_rate_k_s)
    except ReplayError as exc:
        return {"run": False, "reason": str(exc)}
    compared = [c for c in model.outputs if c in ref.outputs]
    rep = sensor_outputs(t[:n], {c: sim[c] for c in compared}, setting.sensors)
    rad = sensor_outputs(t[:n], {c: ref.outputs[c] for c in compared}, setting.sensors)
    channels = {}
    for c in compared:
        sigma = float(model.noise[c])
        z = model.meas[c][:n][keep]
        d = rep[c][keep] - rad[c][keep]
        rms_d = float(np.sqrt(np.mean(d ** 2)))
        res_rep = float(np.sqrt(np.mean((z - rep[c][keep]) ** 2)))
        res_ref = float(np.sqrt(np.mean((z - rad[c][keep]) ** 2)))
        ratio = rms_d / sigma if sigma > 0 else math.inf
        channels[c] = {
            "noise_sigma": sigma, "rms_difference": rms_d,
            "max_difference": float(np.max(np.abs(d))),
            "ratio": ratio if math.isfinite(ratio) else None,
            "residual_ratio_replay": res_rep / sigma if sigma > 0 else None,
            "residual_ratio_reference": res_ref / sigma if sigma > 0 else None,
            "share": rms_d / res_rep if res_rep > 0 else None,
            "explains_excess": bool(sigma > 0 and res_rep > multiple * sigma
                                    >= res_ref),
            "notable": bool(not math.isfinite(ratio) or ratio > NOTABLE_RATIO)}
    not_compared = dict(ref.not_compared)
    for c in model.outputs:
        if c not in compared and c not in not_compared:
            not_compared[c] = "not an output of the replay"
    ratios = [v["ratio"] for v in channels.values() if v["ratio"] is not None]
    return {"run": True, "window_s": [float(t[0]), float(t[n - 1])],
            "scored_from_s": float(t[keep[0]]), "rtol": ref.rtol, "wall_s": ref.wall_s,
            "rhs_evaluations": ref.rhs_evaluations,
            "below_floor_samples": ref.below_floor_samples, "channels": channels,
            "not_compared": {c: r for c, r in not_compared.items() if c in model.outputs},
            "max_ratio": max(ratios) if ratios else None,
            "explains_excess": [c for c, v in channels.items() if v["explains_excess"]]}


def numerical_where(check: Mapping | None) -> str | None:
    """The check's part of the "where": the channels whose numerical error exceeds
    :data:`NOTABLE_RATIO` of the noise, largest first, each with its size against σ and
    against the residual; None when none does or the check did not run."""
    if not check or not check.get("run"):
        return None
    rows = sorted(((c, v) for c, v in check["channels"].items() if v["notable"]),
                  key=lambda cv: -(cv[1]["ratio"] or math.inf))
    if not rows:
        return None
    t0, t1 = check["window_s"]
    parts = []
    for c, v in rows:
        share = v.get("share")
        s = (f"{c} {v['ratio']:.2f}× the noise σ"
             + (f" ({100 * share:.0f} % of the residual's RMS)" if share is not None else ""))
        if v["explains_excess"]:
            s += ", which alone puts the channel above its noise multiple"
        parts.append(s)
    return (f"the replay's own numerical error (replay − Radau at rtol {check['rtol']:g}, "
            f"{t1 - t0:.3g} s from the record's start): " + "; ".join(parts))
