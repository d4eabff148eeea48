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

The replay's step
-----------------
The stepper is backward Euler (first order): its error halves with its step. Left in the
replay, that error is fitted: every described value is a declared parameter, so the fit moves
physical values to absorb numerics. Backward Euler lengthens a fast pole's time constant by
about half a step; the fit takes it back by lowering the value that sets it (the clean 20 s
records, seed 10: at 0.5 ms the second rig's motor inductance came out −32 % against its
±30 % tolerance, its L/R being 0.27 ms; at 0.125 ms, where every channel's error was below
σ/2, the lab rig's came out −32 %, L/R 0.17 ms; at 0.0625 ms −15 %).

So before any fit a described rig's replay step is chosen by this check
(:func:`choose_replay_step`): the described model on the first ``numerical_check_s``, Radau
once (the reference does not depend on the replay's step, so each step tried costs one short
replay), the replay from 0.5 ms halved while any channel's error exceeds :data:`STEP_RATIO`
(σ/4) of its noise, down to :data:`STEP_FLOOR_S`. Measured on those records with the check's
2 s window, the largest ratio (the motor current's) at 0.5, 0.25, 0.125 ms: lab rig 1.58,
0.82, 0.42 σ; second rig 1.49, 0.76, 0.38 σ; at 0.0625 ms 0.21 and 0.19 σ: both choose
0.0625 ms (Radau 2.0–2.1 s, each replay of the window 0.01–0.03 s).
"""

from __future__ import annotations

import math
import time
from typing import Mapping

import numpy as np

from afo_mj.calibration.calibration_model import sensor_outputs
from afo_mj.experiments.bench_replay import ReplayError
from afo_mj.experiments.replay_reference import reference_replay

__all__ = ["numerical_error_check", "numerical_where", "choose_replay_step", "CHECK_RTOL",
           "NOTABLE_RATIO", "STEP_RATIO", "STEP_FLOOR_S", "STALL_FACTOR"]

#: relative tolerance of the Radau check in a calibration
CHECK_RTOL = 1e-7
#: numerical error (RMS over σ) above which a channel's is named in the "where"
NOTABLE_RATIO = 0.5
_MIN_SAMPLES = 20
#: the step choice halves the replay's step while a channel's numerical error exceeds this
#: fraction of its noise σ: half of :data:`NOTABLE_RATIO`, because at σ/2 the fit still
#: absorbed the stepper's error into a physical value (module docstring, *The replay's step*)
STEP_RATIO = 0.25
#: the finest maximum sub-step the choice of the replay's step tries, s (1/16 ms)
STEP_FLOOR_S = 6.25e-5
#: a halving of the step that leaves the largest ratio above this fraction of the coarser
#: step's has stalled (first order: a halving halves the error)
STALL_FACTOR = 0.8


def _window(model, window_s: float):
    """``(n, keep)``: the check window's first ``n`` samples and the indices scored (after
    ``settle_s``), or the reason (a string) it cannot run."""
    if window_s <= 0.0:
        return "calibration.numerical_check_s = 0 (not asked for)"
    t = model.t
    n = int(min(np.searchsorted(t, t[0] + window_s, side="right"), model.i_end))
    keep = np.flatnonzero(t[:n] >= t[0] + model.options.settle_s)
    if keep.size < _MIN_SAMPLES:
        return (f"the window of {window_s:g} s leaves {keep.size} samples after settle_s = "
                f"{model.options.settle_s:g} s; allowed: at least {_MIN_SAMPLES} (raise "
                "calibration.numerical_check_s)")
    return n, keep


def _reference(model, setting, n: int):
    """The Radau reference of ``setting`` over the first ``n`` samples."""
    inputs = {c: v[:n] for c, v in model.inputs.items()}
    return reference_replay(model.replay, model.t[:n], inputs, setting.row,
                            setting.backlash_rad, setting.temperature_rate_k_s,
                            rtol=CHECK_RTOL)


def _compare(model, setting, n: int, keep: np.ndarray, ref, multiple: float) -> dict:
    """The replay of ``setting`` at the replay's present step beside the Radau reference
    ``ref``: the check's figures (module docstring) without the reference's cost."""
    t = model.t
    inputs = {c: v[:n] for c, v in model.inputs.items()}
    sim = model.replay.simulate(t[:n], inputs, setting.row, setting.backlash_rad,
                                setting.temperature_rate_k_s)
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
    ratios = [v["ratio"] for v in channels.values() if v["ratio"] is not None]
    return {"channels": channels, "max_ratio": max(ratios) if ratios else None,
            "explains_excess": [c for c, v in channels.items() if v["explains_excess"]]}


def numerical_error_check(model, effects, x: np.ndarray, window_s: float,
                          multiple: float) -> dict:
    """The check (module docstring) of the structure ``effects`` at normalised parameters
    ``x`` of ``model`` (a :class:`~afo_mj.calibration.calibration_model.CalibrationModel`)
    on the record's first ``window_s`` seconds; ``multiple`` is the noise multiple the
    baseline must reach. Returns ``{"run": True, "window_s": [t0, t1], "rtol",
    "wall_s", "rhs_evaluations", "below_floor_samples", "channels": {…}, "not_compared",
    "max_ratio", "explains_excess": [channels], "max_step_s"}``, or ``{"run": False,
    "reason"}`` when it cannot run (a window of 0 s, one shorter than the settling time, a
    torque reference, a failed integration)."""
    win = _window(model, window_s)
    if isinstance(win, str):
        return {"run": False, "reason": win}
    n, keep = win
    setting = model.setting(effects, x)
    try:
        ref = _reference(model, setting, n)
        cmp = _compare(model, setting, n, keep, ref, multiple)
    except ReplayError as exc:
        return {"run": False, "reason": str(exc)}
    t = model.t
    not_compared = dict(ref.not_compared)
    for c in model.outputs:
        if c not in cmp["channels"] and c not in not_compared:
            not_compared[c] = "not an output of the replay"
    return {"run": True, "window_s": [float(t[0]), float(t[n - 1])],
            "scored_from_s": float(t[keep[0]]), "rtol": ref.rtol, "wall_s": ref.wall_s,
            "rhs_evaluations": ref.rhs_evaluations,
            "below_floor_samples": ref.below_floor_samples, "channels": cmp["channels"],
            "not_compared": {c: r for c, r in not_compared.items() if c in model.outputs},
            "max_ratio": cmp["max_ratio"], "explains_excess": cmp["explains_excess"],
            "max_step_s": float(model.replay.max_step_s)}


def choose_replay_step(model, window_s: float, multiple: float,
                       start_s: float | None = None, floor_s: float = STEP_FLOOR_S,
                       target_ratio: float = STEP_RATIO) -> dict:
    """The replay's maximum sub-step, chosen by the check before any fit (module docstring,
    *The replay's step*). The described model (no effect, every declared value at its
    described value) is integrated once by Radau on the record's first ``window_s`` seconds;
    the replay at ``start_s`` (default: its present
    :attr:`~afo_mj.experiments.bench_replay.BenchReplay.max_step_s`) is set beside it, and the
    step halved while a channel's error exceeds ``target_ratio`` (:data:`STEP_RATIO`) of its
    noise σ, down to ``floor_s``. A halving that leaves the largest ratio above
    :data:`STALL_FACTOR` of the coarser step's has stalled (what remains is not the step's
    error: a vapour-floor clip, a held value's lag): the halving stops and the coarser step
    is kept.

    Sets the replay's ``max_step_s`` to the step chosen. Returns ``{"source":
    "numerical_check", "max_step_s", "start_s", "floor_s", "target_ratio", "window_s",
    "reached", "stalled", "tried": [{"max_step_s", "substeps", "max_ratio", "ratios",
    "above", "cpu_s"}], "reference_wall_s", "rhs_evaluations"}``; when the check cannot
    run, ``"source": "default"``, the start step and the ``"reason"``."""
    replay = model.replay
    start = float(replay.max_step_s if start_s is None else start_s)
    replay.max_step_s = start
    out = {"source": "numerical_check", "max_step_s": start, "start_s": start,
           "floor_s": float(floor_s), "target_ratio": float(target_ratio), "tried": [],
           "reached": False, "stalled": False}
    win = _window(model, window_s)
    if isinstance(win, str):
        return {**out, "source": "default", "reason": f"not chosen: {win}"}
    n, keep = win
    out["window_s"] = [float(model.t[0]), float(model.t[n - 1])]
    setting = model.setting([], np.ones(len(model.declared)))
    dt = float(np.median(np.diff(model.t[:n])))
    try:
        ref = _reference(model, setting, n)
    except ReplayError as exc:
        return {**out, "source": "default", "reason": f"not chosen: {exc}"}
    out["reference_wall_s"] = ref.wall_s
    out["rhs_evaluations"] = ref.rhs_evaluations
    h = start
    chosen = start
    while True:
        replay.max_step_s = h
        c0 = time.process_time()
        try:
            cmp = _compare(model, setting, n, keep, ref, multiple)
        except ReplayError as exc:
            out["reason"] = f"the replay at {h:g} s failed: {exc}"
            break
        ratios = {c: v["ratio"] for c, v in cmp["channels"].items()}
        worst = cmp["max_ratio"]
        out["tried"].append({
            "max_step_s": h, "substeps": max(1, int(math.ceil(dt / h - 1e-9))),
            "max_ratio": worst, "ratios": ratios,
            "above": [c for c, r in ratios.items() if r is None or r > target_ratio],
            "cpu_s": time.process_time() - c0})
        prev = out["tried"][-2]["max_ratio"] if len(out["tried"]) > 1 else None
        if (prev is not None and worst is not None
                and worst > STALL_FACTOR * prev):
            out["stalled"] = True
            break
        chosen = h
        if worst is None or worst <= target_ratio:
            out["reached"] = True
            break
        if 0.5 * h < floor_s * (1.0 - 1e-9):
            break
        h *= 0.5
    replay.max_step_s = chosen
    out["max_step_s"] = chosen
    return out


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
