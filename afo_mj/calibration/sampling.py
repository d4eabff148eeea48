"""How a record's input was produced between its samples: declared, detected from the data, checked.

A bench record samples its inputs, but the replay must know what the input did *between* the
samples (issue 41, item 1). Two cases matter:

* ``"zero_order"``: a **digital command** (a DAC output, a PWM driver's duty, a controller's
  torque reference) changes only when the controller updates it and is held in between. Logged
  at the update rate or faster it shows runs of exactly equal consecutive samples with steps
  between them; replayed with linear interpolation, each step is smeared over a sample interval
  and the fast states it drives (the motor current, with an electrical time constant of a
  fraction of a millisecond) lag and undershoot.
* ``"linear"``: a **sampled continuous signal** (an analog voltage, a measured quantity): it
  moved smoothly between the samples, which linear interpolation approximates to second order.

The declaration comes from the record's sidecar (``[hold]``,
:data:`afo_mj.calibration.measured_data.HOLD_VALUES`) or the calibration scenario
(``[calibration.hold]``, which overrides the sidecar); undeclared, the replay keeps its default
(:attr:`afo_mj.experiments.bench_replay.BenchReplay.default_hold`). :func:`detect_hold` looks at
the data; :func:`check_holds` compares, and a contradiction is reported as a warning naming the
channel, the hold used, where it came from and the evidence. A declaration is always honoured
(the user may know better than a statistic, e.g. a slowly moving digital command whose every
step is one DAC count), never silently replaced.
"""

from __future__ import annotations

import dataclasses
from typing import Mapping

import numpy as np

__all__ = ["HoldEvidence", "detect_hold", "check_holds"]

#: fraction of exactly repeated consecutive samples above which the input is held
REPEAT_FRACTION = 0.5
#: a step is "one quantum" when it is within this factor of the smallest step
QUANTUM_FACTOR = 1.5
#: the smallest step counts as a converter quantum when it is at most this fraction of the span
QUANTUM_SPAN = 0.02
#: fraction of the steps that must be one quantum for "quantised continuous signal"
QUANTUM_STEPS = 0.9
#: a difference is a jump when it exceeds this many robust standard deviations of the
#: differences (noisy records)
JUMP_SIGMA = 6.0
#: fraction of the energy of the differences (Σ Δx²) the jumps must carry, and fraction of
#: the jumps that must be isolated (neither neighbour a jump), for a noisy record to count as held
JUMP_VARIATION = 0.5
JUMP_ISOLATED = 0.8


@dataclasses.dataclass(frozen=True)
class HoldEvidence:
    """What :func:`detect_hold` found in one sampled input.

    ``verdict``: ``"zero_order"``, ``"linear"`` or ``"undecided"`` (constant, or too short);
    ``repeat_fraction``: fraction of consecutive samples exactly equal (0…1);
    ``median_run_samples``: median length of the runs of equal samples (of the spacing between
    jumps, for a noisy record), 1 for a signal that never repeats; ``jump_fraction``: fraction
    of the energy of the differences (Σ Δx²) carried by isolated jumps (0…1); ``quantum``:
    the smallest nonzero step (the converter's resolution where the signal is quantised; 0 if
    none); ``reason``: the criterion that decided, in words."""

    verdict: str
    repeat_fraction: float
    median_run_samples: float
    jump_fraction: float
    quantum: float
    reason: str

    def as_dict(self) -> dict:
        return dataclasses.asdict(self)

    def summary(self) -> str:
        """The evidence in one phrase (for warnings)."""
        return (f"{100 * self.repeat_fraction:.0f} % of consecutive samples repeat exactly, "
                f"median run {self.median_run_samples:.3g} samples, isolated jumps carry "
                f"{100 * self.jump_fraction:.0f} % of the energy of the differences: {self.reason}")


def _runs(same: np.ndarray) -> np.ndarray:
    """Lengths (in samples) of the runs of equal samples, given ``same[k]``: sample k+1
    equals sample k."""
    change = np.flatnonzero(~same)
    edges = np.concatenate(([-1], change, [len(same)]))
    return np.diff(edges)


def detect_hold(signal, *, repeat_threshold: float = REPEAT_FRACTION) -> HoldEvidence:
    """Decide from the data whether a sampled input looks zero-order held or continuous.

    Criteria, in order, with their reasoning:

    1. **Constant** (no sample differs from the first, up to 1e-9 of the span): the hold
       makes no difference; ``"undecided"``.
    2. **Exact repeats** (the fraction of zero first differences ≥ ``repeat_threshold``, 0.5):
       a continuous quantity sampled by a converter repeats exactly only when it moves by less
       than one converter quantum per sample, and then every step between runs is one quantum.
       So: if at least 90 % of the steps are within 1.5× the smallest step and that step is at
       most 2 % of the span (a converter of ≥ 6 bits over the signal's range), the repeats are
       quantisation of a slowly varying continuous signal: ``"linear"``. Otherwise the steps
       are larger than the resolution and varied: the signal was held between updates (a
       digital command logged faster than, or at, its update rate): ``"zero_order"``.
    3. **No exact repeats** (sensor noise on the logged command, or a continuous signal):
       a held command with noise has first differences that are noise (robust σ from the
       median absolute deviation) except for single isolated jumps at the updates, which
       carry most of the signal's variation; a band-limited continuous signal's differences
       follow its slope, which changes over several samples, so large differences come in
       neighbouring groups (a smooth transition), not isolated. Jumps are differences beyond
       6 robust σ; if they carry ≥ 50 % of the energy of the differences (Σ Δx², which the
       noise adds to as n σ² and a held command's updates as the sum of their squared steps,
       so a few large steps dominate) and ≥ 80 % of them are isolated (neither neighbour a
       jump): ``"zero_order"``, else ``"linear"``.

    Limits: a digital command that moves by exactly one count per update is, from its samples
    alone, the same as a quantised continuous signal (criterion 2 says ``"linear"``); steps
    smaller than ~8× the noise per update interval are not found under noise (criterion 3
    says ``"linear"``). A declaration overrides the verdict (:func:`check_holds` only warns).
    """
    x = np.asarray(signal, dtype=float).ravel()
    if x.size < 3 or not np.all(np.isfinite(x)):
        return HoldEvidence("undecided", 0.0, 1.0, 0.0, 0.0,
                            "fewer than 3 finite samples")
    d = np.diff(x)
    span = float(np.ptp(x))
    tol = 1e-9 * span
    if span == 0.0:
        return HoldEvidence("undecided", 1.0, float(x.size), 0.0, 0.0,
                            "constant: the hold makes no difference")
    ad = np.abs(d)
    same = ad <= tol
    repeat = float(np.mean(same))
    steps = ad[~same]
    quantum = float(np.min(steps))
    runs = _runs(same)
    med_run = float(np.median(runs))
    if repeat >= repeat_threshold:
        one_quantum = float(np.mean(steps <= QUANTUM_FACTOR * quantum))
        if one_quantum >= QUANTUM_STEPS and quantum <= QUANTUM_SPAN * span:
            return HoldEvidence("linear", repeat, med_run, 0.0, quantum,
                                f"{100 * one_quantum:.0f} % of the steps are one quantum "
                                f"({quantum:.3g}, {100 * quantum / span:.2g} % of the span): a "
                                f"quantised, slowly varying continuous signal")
        return HoldEvidence("zero_order", repeat, med_run, 1.0, quantum,
                            "runs of equal samples with steps larger than the resolution "
                            "between them: a command held between updates")
    sigma = 1.4826 * float(np.median(np.abs(d - np.median(d))))
    big = ad > JUMP_SIGMA * max(sigma, tol)
    energy = float(np.sum(d * d))
    jump_var = float(np.sum(d[big] ** 2)) / energy if energy > 0.0 else 0.0
    idx = np.flatnonzero(big)
    if idx.size:
        nb = np.zeros_like(big)
        nb[1:] |= big[:-1]
        nb[:-1] |= big[1:]
        isolated = float(np.mean(~nb[idx]))
    else:
        isolated = 0.0
    if idx.size >= 2 and jump_var >= JUMP_VARIATION and isolated >= JUMP_ISOLATED:
        spacing = float(np.median(np.diff(idx)))
        return HoldEvidence("zero_order", repeat, spacing, jump_var * isolated, quantum,
                            f"isolated jumps beyond {JUMP_SIGMA:g} σ of the sample-to-sample "
                            f"noise carry most of the variation: a held command with noise")
    return HoldEvidence("linear", repeat, med_run, jump_var * isolated, quantum,
                        "few exact repeats and no isolated jumps: a sampled continuous "
                        "signal")


def check_holds(channels: Mapping[str, np.ndarray], used: Mapping[str, str],
                sources: Mapping[str, str]) -> tuple[dict[str, dict], list[str]]:
    """Check the hold each input is replayed with against its data.

    ``channels``: input channel → samples; ``used``: channel → the hold the replay uses;
    ``sources``: channel → where that hold came from (a declaration's place, or the replay's
    default). Returns ``(report, warnings)``: per channel the hold used, its source and the
    :class:`HoldEvidence` (as a dict), and one warning per channel whose data contradict the
    hold used (the verdict is a hold and differs), naming the channel, the hold, its source
    and the evidence. The hold used is never changed here."""
    report, warns = {}, []
    for ch, hold in used.items():
        ev = detect_hold(channels[ch])
        src = sources.get(ch, "the replay's default")
        report[ch] = {"hold": hold, "source": src, "detected": ev.verdict,
                      "evidence": ev.as_dict()}
        if ev.verdict in ("zero_order", "linear") and ev.verdict != hold:
            kept = ("the declaration is kept" if "default" not in src else
                    f"declare hold {ch} = \"{ev.verdict}\" (the sidecar's [hold] or the "
                    f"scenario's [calibration.hold]) if the data are right")
            warns.append(f"input {ch} is replayed with hold = \"{hold}\" ({src}) but its data "
                         f"look {ev.verdict}: {ev.summary()}; {kept}")
    return report, warns
