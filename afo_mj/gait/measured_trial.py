"""Measured gait trials: gait events, every complete cycle per leg, and their mean with SD.

A trial (an OpenSim inverse-kinematics ``.sto``/``.mot``, optionally its inverse-dynamics
``.sto`` and ground-reaction ``.mot``) is a time record that starts and ends anywhere in the
cycle, not one cycle from heel strike. :func:`load_measured_trial` finds the events, cuts every
complete cycle of each leg and gives their mean (and SD) as a
:class:`~afo_mj.gait.reference.ReferenceGait`, so a trial serves wherever a normative table
does (run comparison, metrics, figures).

Events
------
* :func:`events_from_grf` — from each foot's vertical ground reaction force: stance while the
  force exceeds ``on_n`` and until it falls below ``off_n`` (a threshold with hysteresis, so
  noise about one threshold does not chatter; 20–50 N thresholds are usual, e.g. Zeni et al.
  2008 used force-plate onsets as their gold standard), stances and swings shorter than
  ``min_stance_s`` / ``min_swing_s`` merged away. Heel strike = a stance onset, toe off = a
  stance end; an edge at the record's first sample is not an event (the foot was already
  down or up).
* :func:`events_from_markers` — without forces, from marker positions (Zeni, Richards &
  Higginson 2008, *Gait & Posture* 27:710, "coordinate-based"): heel strike at each maximum
  of the heel's forward position relative to the pelvis, toe off at each minimum of the toe's.

Cycles
------
A cycle is heel strike to the next heel strike of the same leg. It is refused (with the
reason in :attr:`MeasuredTrial.refused`) when its duration is off the median by more than
``duration_tolerance`` (a missed or extra event) or when its ends do not meet: an angle at the
end differing from the start by more than ``jump_tolerance_rad`` (a mis-cut record or an event
in the wrong place; gait is periodic, so real cycles close within a few degrees).

When no leg has a complete cycle (a short record), one cycle is *composed* from both legs,
assuming left–right symmetry: the right leg's data from its heel strike to the record's end
give phases ``[0, a)``; the left leg's data supply the rest ``[a, 1)`` at the same phase of
its own cycle (its heel strike half a stride away), the stride time from the two legs'
heel strikes and toe offs. The seam's angle jumps are reported; a seam above the tolerance,
or legs that do not cover the cycle together, refuse the trial with the reason.
"""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path
from typing import Mapping, Sequence

import numpy as np

from afo_mj.gait.reference import (ANGLE_CHANNELS, DEFAULT_OPENSIM_MAPPING, ReferenceGait,
                                   ReferenceGaitError, check_per_kg_magnitude,
                                   read_opensim_storage)

__all__ = ["TrialEvents", "MeasuredTrial", "events_from_grf", "events_from_markers",
           "complete_cycles", "load_measured_trial", "grf_columns"]

SIDES = ("right", "left")
#: how to fix a trial's moment or force beyond a human's per kg (it is divided by this mass)
_PER_MASS_HINT = ("the trial's N*m and N are divided by body_mass_kg = {m:g} kg: give the "
                  "subject's mass (a scenario uses walker.body_mass_kg)")
#: phase points of the cycle averages
N_PHASE = 101


@dataclasses.dataclass(frozen=True)
class TrialEvents:
    """Heel strikes and toe offs per side (s), and how they were found."""

    heel_strikes_s: Mapping[str, np.ndarray]
    toe_offs_s: Mapping[str, np.ndarray]
    method: str


def events_from_grf(time_s, vertical_n: Mapping[str, Sequence[float]], on_n: float = 50.0,
                    off_n: float = 20.0, min_stance_s: float = 0.2,
                    min_swing_s: float = 0.15) -> TrialEvents:
    """Events from each side's vertical ground reaction force (N; module docstring).

    Example: a force that rises through 50 N at 0.10 s and falls through 20 N at 0.72 s gives
    a heel strike at 0.10 s and a toe off at 0.72 s (each crossing interpolated linearly
    between the samples on either side)."""
    t = np.asarray(time_s, float)
    if not 0.0 <= off_n < on_n:
        raise ReferenceGaitError(f"events_from_grf: off_n = {off_n!r}, on_n = {on_n!r}; "
                                 "allowed: 0 <= off_n < on_n (N)")
    hs, to = {}, {}
    for side, f in vertical_n.items():
        f = np.asarray(f, float)
        if f.shape != t.shape or not np.all(np.isfinite(f)):
            raise ReferenceGaitError(f"events_from_grf: {side} force has shape {f.shape} or "
                                     f"non-finite values; allowed: finite, as long as time "
                                     f"({t.shape})")
        stance = np.zeros(len(f), bool)
        on = f[0] > on_n
        for k in range(len(f)):
            if on and f[k] < off_n:
                on = False
            elif not on and f[k] > on_n:
                on = True
            stance[k] = on
        stance = _merge_short(t, stance, min_stance_s, min_swing_s)
        edges = np.flatnonzero(np.diff(stance.astype(int)))
        # each event at the threshold's crossing, interpolated between the two samples
        hs[side] = np.array([_crossing(t, f, k, on_n) for k in edges if stance[k + 1]])
        to[side] = np.array([_crossing(t, f, k, off_n) for k in edges if not stance[k + 1]])
    return TrialEvents(hs, to, f"vertical GRF threshold {on_n:g} N on / {off_n:g} N off")


def _crossing(t, f, k, level):
    """The time ``f`` crosses ``level`` between samples ``k`` and ``k + 1`` (linear), or the
    later sample when it does not cross there (an edge a merge moved)."""
    d = f[k + 1] - f[k]
    if d != 0.0 and min(f[k], f[k + 1]) <= level <= max(f[k], f[k + 1]):
        return float(t[k] + (level - f[k]) / d * (t[k + 1] - t[k]))
    return float(t[k + 1])


def _merge_short(t, stance, min_stance_s, min_swing_s):
    """Remove stances shorter than ``min_stance_s`` and swings shorter than ``min_swing_s``
    (interior runs only: the record's first and last runs are partial)."""
    s = stance.copy()
    for want, shortest in ((True, min_stance_s), (False, min_swing_s)):
        k = 0
        n = len(s)
        while k < n:
            j = k
            while j < n and s[j] == s[k]:
                j += 1
            if s[k] == want and k > 0 and j < n and t[j - 1] - t[k] < shortest:
                s[k:j] = not want
            k = j
    return s


def events_from_markers(time_s, heel_forward_m: Mapping[str, Sequence[float]],
                        toe_forward_m: Mapping[str, Sequence[float]],
                        pelvis_forward_m: Sequence[float],
                        min_interval_s: float = 0.5) -> TrialEvents:
    """Events from marker positions along the walking direction (Zeni et al. 2008): heel
    strike at each local maximum of ``heel − pelvis``, toe off at each local minimum of
    ``toe − pelvis``; extrema closer than ``min_interval_s`` keep the larger."""
    t = np.asarray(time_s, float)
    pel = np.asarray(pelvis_forward_m, float)
    hs, to = {}, {}
    for side in heel_forward_m:
        rel_h = np.asarray(heel_forward_m[side], float) - pel
        rel_t = np.asarray(toe_forward_m[side], float) - pel
        hs[side] = t[_extrema(rel_h, t, min_interval_s)]
        to[side] = t[_extrema(-rel_t, t, min_interval_s)]
    return TrialEvents(hs, to, "marker positions relative to the pelvis (Zeni et al. 2008)")


def _extrema(x, t, min_interval_s):
    """Indices of interior local maxima of ``x``, thinned to one per ``min_interval_s``."""
    k = np.flatnonzero((x[1:-1] > x[:-2]) & (x[1:-1] >= x[2:])) + 1
    keep: list[int] = []
    for i in k:
        if keep and t[i] - t[keep[-1]] < min_interval_s:
            if x[i] > x[keep[-1]]:
                keep[-1] = i
            continue
        keep.append(i)
    return np.array(keep, int)


def complete_cycles(time_s, angles: Mapping[str, Sequence[float]], heel_strikes_s,
                    jump_tolerance_rad: float = math.radians(5.0),
                    duration_tolerance: float = 0.25) -> tuple[list, list]:
    """``(cycles, refused)``: each complete cycle ``(t0, t1)`` between successive heel
    strikes whose angles close within ``jump_tolerance_rad`` and whose duration is within
    ``duration_tolerance`` of the median; the refused ones as ``(t0, t1, reason)``."""
    t = np.asarray(time_s, float)
    hs = np.asarray(heel_strikes_s, float)
    pairs = [(a, b) for a, b in zip(hs[:-1], hs[1:]) if t[0] <= a and b <= t[-1]]
    cycles, refused = [], []
    if not pairs:
        return cycles, refused
    med = float(np.median([b - a for a, b in pairs]))
    for a, b in pairs:
        if abs((b - a) - med) > duration_tolerance * med:
            refused.append((a, b, f"lasts {b - a:.3f} s against the median {med:.3f} s (a "
                                  f"missed or extra event)"))
            continue
        jumps = {ch: float(np.interp(b, t, v) - np.interp(a, t, v)) for ch, v in angles.items()}
        worst = max(jumps, key=lambda c: abs(jumps[c]))
        if abs(jumps[worst]) > jump_tolerance_rad:
            refused.append((a, b, f"its ends do not meet: {worst} jumps "
                                  f"{math.degrees(jumps[worst]):+.1f} deg (tolerance "
                                  f"{math.degrees(jump_tolerance_rad):.1f} deg)"))
            continue
        cycles.append((a, b))
    return cycles, refused


@dataclasses.dataclass(frozen=True)
class MeasuredTrial:
    """A measured trial cut into cycles (module docstring): ``events``; per side the kept
    ``cycles`` ``(t0, t1)`` and the ``refused`` ones with reasons; ``reference``, the mean
    cycle with its SD over the kept cycles of both legs (or the composed cycle);
    ``composed`` (the seam's phase and angle jumps, rad) when no leg had a complete cycle;
    ``notes`` what was detected and assumed (units, knee sign, event method)."""

    events: TrialEvents
    cycles: Mapping[str, list]
    refused: Mapping[str, list]
    reference: ReferenceGait
    composed: Mapping | None
    notes: tuple[str, ...]

    @property
    def n_cycles(self) -> int:
        return sum(len(v) for v in self.cycles.values())


def grf_columns(labels: Sequence[str]) -> dict[str, str]:
    """The vertical-force column of each side in a ground-reaction ``.mot``'s labels: a
    ``…force…vy`` label whose name says the side (``r``/``right``/``R_`` or
    ``l``/``left``/``L_``, or OpenSim's example convention ``ground_force_vy`` (right) and
    ``1_ground_force_vy`` (left)). Raises when a side cannot be told."""
    out: dict[str, str] = {}
    vy = [lab for lab in labels if "force" in lab.lower() and lab.lower().endswith("vy")]
    for lab in vy:
        low = lab.lower()
        tokens = set(low.replace("/", "_").split("_"))
        side = ("right" if tokens & {"r", "right"} else "left" if tokens & {"l", "left"}
                else None)
        if side is None and low == "ground_force_vy":
            side = "right"
        elif side is None and low == "1_ground_force_vy":
            side = "left"
        if side is not None and side not in out:
            out[side] = lab
    if set(out) != set(SIDES):
        raise ReferenceGaitError(f"ground reaction columns: found {out} among {vy}; allowed: "
                                 "one vertical force (…force_vy) per side named r/right/l/left, "
                                 "or ground_force_vy and 1_ground_force_vy; pass grf_columns=")
    return out


def _leg_mapping(side: str) -> dict[str, str]:
    """The default OpenSim angle columns of one leg (``_r`` → ``_l`` for the left)."""
    suffix = "_r" if side == "right" else "_l"
    return {ch: DEFAULT_OPENSIM_MAPPING[ch].replace("_r", suffix) for ch in ANGLE_CHANNELS}


def _column(labels, data, name, origin):
    """Column ``name`` of a trial file; a NaN or infinite value in it is refused, naming the
    file, the column, the data row and its time (every value a trial uses must be finite:
    a gap would otherwise pass into the cycles' means, or silently drop out between them)."""
    from afo_mj.gait.reference import _find_label
    i = _find_label(labels, name)
    if i is None:
        raise ReferenceGaitError(f"{origin}: column {name!r} not found; labels: {labels}")
    col = data[:, i]
    bad = np.flatnonzero(~np.isfinite(col))
    if bad.size:
        k = int(bad[0])
        ti = _find_label(labels, "time")
        at = ("" if ti is None or ti == i or not np.isfinite(data[k, ti])
              else f" (time {data[k, ti]:g} s)")
        raise ReferenceGaitError(
            f"{origin}: column {name!r} has the non-finite value {float(col[k])!r} at data row "
            f"{k + 1}{at}{f' and {bad.size - 1} more rows' if bad.size > 1 else ''}; allowed: "
            "finite numbers in every column the trial uses (fill or cut the gap before "
            "loading)")
    return col


def load_measured_trial(coords_path, grf_path=None, *, events: TrialEvents | None = None,
                        grf_columns_by_side: Mapping[str, str] | None = None,
                        in_degrees: bool | None = None, knee_flexion_sign="auto",
                        jump_tolerance_rad: float = math.radians(5.0),
                        on_n: float = 50.0, off_n: float = 20.0,
                        speed_m_s: float | None = None, id_path=None,
                        body_mass_kg: float | None = None) -> MeasuredTrial:
    """Cut a measured trial into cycles (module docstring).

    ``coords_path``: OpenSim coordinates (``hip_flexion_r/l``, ``knee_angle_r/l``,
    ``ankle_angle_r/l``; units from the header's ``inDegrees`` unless ``in_degrees``; knee
    sign as :func:`~afo_mj.gait.reference.load_opensim_storage` decides it). Events from
    ``grf_path`` (a ground-reaction ``.mot``, or a CSV with a ``time`` column and the same
    column names; :func:`grf_columns`) or given as ``events``.
    With ``id_path`` (OpenSim inverse dynamics, ``<coordinate>_moment`` in N·m, the knee's
    with the same sign rule) and ``body_mass_kg``, the cycles' joint moments per kg come too;
    with ``grf_path`` and ``body_mass_kg`` each foot's ground reaction force per kg (forward
    ``…vx``, vertical ``…vy``). Raises :class:`~afo_mj.gait.reference.ReferenceGaitError`
    naming the file when the trial holds no usable cycle and none can be composed."""
    origin = str(coords_path)
    header, labels, data = read_opensim_storage(coords_path)
    notes = []
    if in_degrees is None:
        flag = header.get("inDegrees")
        if flag is None or flag.lower() not in ("yes", "no"):
            raise ReferenceGaitError(f"{origin}: header key 'inDegrees' is {flag!r}; allowed "
                                     "yes/no, or pass in_degrees=True/False")
        in_degrees = flag.lower() == "yes"
        notes.append(f"angles in {'degrees' if in_degrees else 'radians'} (header inDegrees = "
                     f"{flag})")
    else:
        notes.append(f"angles in {'degrees' if in_degrees else 'radians'} (given)")
    f = math.pi / 180.0 if in_degrees else 1.0
    t = _column(labels, data, "time", origin)
    legs = {side: {ch: f * _column(labels, data, col, origin)
                   for ch, col in _leg_mapping(side).items()} for side in SIDES}
    if knee_flexion_sign == "auto":
        k = legs["right"]["knee_angle_rad"]
        knee_flexion_sign = 1 if k[np.argmax(np.abs(k))] > 0 else -1
        notes.append(f"knee flexion sign {knee_flexion_sign:+d} (auto: "
                     f"{'Rajagopal2015' if knee_flexion_sign > 0 else 'gait2392'} convention)")
    for side in SIDES:
        legs[side]["knee_angle_rad"] = legs[side]["knee_angle_rad"] * knee_flexion_sign
    extra = {side: {} for side in SIDES}        # moments and forces per kg, not closure-checked
    if (id_path is not None or grf_path is not None) and body_mass_kg is not None:
        if not (math.isfinite(body_mass_kg) and body_mass_kg > 0):
            raise ReferenceGaitError(f"{origin}: body_mass_kg = {body_mass_kg!r}; allowed: > 0")
    if id_path is not None:
        if body_mass_kg is None:
            raise ReferenceGaitError(f"{id_path}: moments need body_mass_kg (N·m → N·m/kg)")
        _, ilabels, idata = read_opensim_storage(id_path)
        it = _column(ilabels, idata, "time", str(id_path))
        for side in SIDES:
            for ch, col in _leg_mapping(side).items():
                m = _column(ilabels, idata, col + "_moment", str(id_path))
                sign = knee_flexion_sign if ch == "knee_angle_rad" else 1
                mch = ch.replace("angle_rad", "moment_nm_per_kg")
                check_per_kg_magnitude(mch, m / body_mass_kg, col + "_moment", str(id_path),
                                       _PER_MASS_HINT.format(m=body_mass_kg))
                extra[side][mch] = np.interp(t, it, sign * m / body_mass_kg)
        notes.append(f"moments from {Path(id_path).name} per {body_mass_kg:g} kg")
    if events is None:
        if grf_path is None:
            raise ReferenceGaitError(f"{origin}: no events: pass grf_path (a ground-reaction "
                                     ".mot) or events (events_from_grf / events_from_markers)")
        if Path(grf_path).suffix.lower() == ".csv":
            from afo_mj.gait.reference import read_delimited
            glabels, gdata = read_delimited(Path(grf_path), None, str(grf_path))
        else:
            _, glabels, gdata = read_opensim_storage(grf_path)
        cols = dict(grf_columns_by_side) if grf_columns_by_side else grf_columns(glabels)
        gt = _column(glabels, gdata, "time", str(grf_path))
        forces = {side: np.interp(t, gt, _column(glabels, gdata, cols[side], str(grf_path)))
                  for side in SIDES}
        events = events_from_grf(t, forces, on_n, off_n)
        notes.append(f"events from {Path(grf_path).name}: {events.method}, columns {cols}")
        if body_mass_kg is not None:
            for side in SIDES:
                fx = cols[side][:-1] + "x"                   # …force…vy → …force…vx
                extra[side]["grf_x_n_per_kg"] = np.interp(
                    t, gt, _column(glabels, gdata, fx, str(grf_path))) / body_mass_kg
                extra[side]["grf_z_n_per_kg"] = forces[side] / body_mass_kg
                for ch, col in (("grf_x_n_per_kg", fx), ("grf_z_n_per_kg", cols[side])):
                    check_per_kg_magnitude(ch, extra[side][ch], col, str(grf_path),
                                           _PER_MASS_HINT.format(m=body_mass_kg))
    else:
        notes.append(f"events given: {events.method}")
    cycles, refused = {}, {}
    for side in SIDES:
        cycles[side], refused[side] = complete_cycles(
            t, legs[side], events.heel_strikes_s.get(side, []), jump_tolerance_rad)
    phase = np.linspace(0.0, 1.0, N_PHASE)
    composed = None
    if any(cycles.values()):
        samples = []
        for side in SIDES:
            for a, b in cycles[side]:
                samples.append({ch: np.interp(a + phase * (b - a), t, v)
                                for ch, v in {**legs[side], **extra[side]}.items()})
        chans = list(samples[0])
        mean = {ch: np.mean([s[ch] for s in samples], axis=0) for ch in chans}
        sd = ({ch: np.std([s[ch] for s in samples], axis=0, ddof=1) for ch in chans}
              if len(samples) > 1 else None)
        period = float(np.mean([b - a for side in SIDES for a, b in cycles[side]]))
    else:
        mean, period, composed = _compose(t, legs, events, jump_tolerance_rad, origin,
                                          refused)
        sd = None
        notes.append(f"no complete cycle in either leg: one cycle composed from both legs "
                     f"(seam at {100 * composed['seam_phase']:.0f} % of the cycle, largest "
                     f"jump {math.degrees(composed['largest_jump_rad']):.1f} deg)")
    ref = ReferenceGait.from_samples(
        phase, mean, sd=sd, cycle_time_s=period, speed_m_s=speed_m_s, source="trial",
        condition=Path(coords_path).stem,
        metadata={"file": origin, "knee_flexion_sign": knee_flexion_sign,
                  "cycles": {s: [list(c) for c in cycles[s]] for s in SIDES},
                  "notes": notes}, origin=origin)
    return MeasuredTrial(events, cycles, refused, ref, composed, tuple(notes))


def _compose(t, legs, events, tol, origin, refused):
    """One cycle from the right leg's partial cycle and the left leg's (module docstring):
    ``(mean channels on the phase grid, stride time, seam report)``."""
    hs = {s: np.asarray(events.heel_strikes_s.get(s, []), float) for s in SIDES}
    if len(hs["right"]) == 0 or len(hs["left"]) == 0:
        raise ReferenceGaitError(
            f"{origin}: no complete cycle in either leg and no heel strike of "
            f"{'the right' if len(hs['right']) == 0 else 'the left'} leg to compose one "
            f"from; refused: {refused}")
    r0 = float(hs["right"][0])
    l0 = float(hs["left"][0])
    # stride time: twice the step time between the two legs' heel strikes (symmetry)
    step = abs(l0 - r0)
    period = 2.0 * step
    if period <= 0:
        raise ReferenceGaitError(f"{origin}: both legs strike at {r0} s; no cycle composable")
    # the right leg covers [0, a) of its cycle; the left leg's cycle phase at time τ is
    # (τ − l0)/T (or from l0 − T if the left strike came first)
    a = min((t[-1] - r0) / period, 1.0)
    phase = np.linspace(0.0, 1.0, N_PHASE)
    out, jumps = {}, {}
    for ch in ANGLE_CHANNELS:
        vals = np.empty(N_PHASE)
        for i, p in enumerate(phase):
            if p < a:
                vals[i] = np.interp(r0 + p * period, t, legs["right"][ch])
            else:
                tau = l0 + p * period
                if tau > t[-1]:
                    tau -= period
                if tau < t[0]:
                    raise ReferenceGaitError(
                        f"{origin}: the legs together do not cover the cycle (the left leg's "
                        f"phase {100 * p:.0f} % lies outside the record {t[0]:g}…{t[-1]:g} s)")
                vals[i] = np.interp(tau, t, legs["left"][ch])
        out[ch] = vals
        k = int(np.searchsorted(phase, a))
        if 0 < k < N_PHASE:
            before = 2 * vals[k - 1] - vals[k - 2] if k >= 2 else vals[k - 1]
            jumps[ch] = float(vals[k] - before)
    worst = max(jumps.values(), key=abs) if jumps else 0.0
    if abs(worst) > tol:
        raise ReferenceGaitError(f"{origin}: no complete cycle in either leg, and the cycle "
                                 f"composed from both legs has a seam jump of "
                                 f"{math.degrees(worst):+.1f} deg at {100 * a:.0f} % (tolerance "
                                 f"{math.degrees(tol):.1f} deg); refused")
    return out, period, {"seam_phase": a, "jumps_rad": jumps, "largest_jump_rad": abs(worst),
                         "stride_time_s": period}
