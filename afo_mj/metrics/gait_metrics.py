"""Gait metrics of a simulated walk, per gait cycle and as mean ± SD over strides.

Cycles
------
A gait cycle (stride) of one leg runs from a heel strike of that leg to its next heel strike
(``record.events.heel_strikes_s[side]``). Strides are numbered from 1 per leg in the order of
the heel strikes; a selection ``strides=(4, 10)`` (1-based, inclusive) takes cycles 4..10 of
each leg, i.e. skips the first three start-up strides. Only complete cycles are used: both heel
strikes inside the record and, if the walker fell, before the fall. Both legs' selected cycles
are pooled for mean ± SD. Each cycle's signals are resampled linearly in time onto 0..100 % of
the cycle (101 points). The leg's first toe off inside the cycle gives the stance fraction and
starts the swing phase.

Definitions (SI, per kg body mass where named so)
-------------------------------------------------
Sign conventions are those of :mod:`afo_mj.gait.record`: angles positive in hip flexion, knee
flexion, ankle dorsiflexion; moments positive in the same direction, so joint power =
moment × angular velocity and a plantarflexor (push-off) moment is negative.

* Joint power, positive and negative joint work follow Winter (2009), *Biomechanics and Motor
  Control of Human Movement*, 4th ed., ch. 6: P = M·ω; positive work = ∫ max(P, 0) dt, negative
  work = ∫ min(P, 0) dt (≤ 0) over the cycle in time, from the record's samples (not the
  resampled curve), per kg body mass.
* Ankle push-off work (Winter's A2 burst): ∫ max(P_ankle, 0) dt over 35–70 % of the cycle.
  Peak ankle power: max P_ankle over the same 35–70 % window.
* Peak ankle plantarflexor moment: −min(M_ankle) over the cycle (human moment only; the
  orthosis torque is reported separately as ``device_*``).
* Push-off peak plantarflexion: −min(ankle angle) over 40–62 % of the cycle (terminal stance
  and pre-swing up to a normal toe off); peak plantarflexion: −min(ankle angle) over the whole
  cycle (Winter's −19.8° lies at 66 %, just after toe off).
* Swing peak dorsiflexion: max(ankle angle) from toe off to the next heel strike.
* Minimum toe (heel) clearance: min of ``contact_height_m[:, side, 1]`` (``[..., 0]``) in
  mid-swing, the window from toe off + 10 % to toe off + 90 % of the swing duration (the first
  and last 10 % of swing, where the foot leaves and approaches the floor, are excluded). The
  ball sphere is the model's lowest forefoot point (no toes).
* Cadence 120 / T (steps/min, two steps per stride of duration T); stride length = forward
  pelvis displacement over the cycle; speed = stride length / T; stance fraction =
  (toe off − heel strike) / T.
* Deviation from a reference gait at the same percent of the cycle: RMS angle error (deg) over
  the 101 points; fraction of the 101 points inside the reference mean ± 1 SD (None where the
  reference has no SD, e.g. Winter).
* Residual pelvis force |F| = hypot(F_x, F_z) and pitch moment: RMS over each cycle, and over
  the whole analysed time span (first selected heel strike to last selected cycle end); force
  also in % body weight (m·g, g = 9.81 m/s²).
* Peak vertical GRF of the leg per kg over the cycle.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any, Iterable, Mapping, Sequence

import numpy as np

from afo_mj.gait.record import GaitRecord
from afo_mj.metrics.documents import GaitSummary

__all__ = [
    "GaitAnalysisError", "GaitCycle", "GaitAnalysis", "analyse_gait", "summarize",
    "extract_cycles", "find_cycles", "band_fraction", "reference_band", "curve_statistics",
    "scalar_statistics",
    "CURVE_CHANNELS", "PERCENT_CYCLE", "JOINTS", "LEGS", "GRAVITY_M_S2",
    "PUSH_OFF_WINDOW", "PUSH_OFF_ANGLE_WINDOW", "MID_SWING_WINDOW",
]

GRAVITY_M_S2 = 9.81
JOINTS = ("hip", "knee", "ankle")
LEGS = ("right", "left")
N_POINTS = 101
PERCENT_CYCLE = np.linspace(0.0, 100.0, N_POINTS)
"""The 0..100 % grid every cycle is resampled onto."""
_PHASE = PERCENT_CYCLE / 100.0

PUSH_OFF_WINDOW = (0.35, 0.70)
"""Fraction of the cycle for ankle push-off work and peak ankle power (Winter's A2 burst)."""
PUSH_OFF_ANGLE_WINDOW = (0.40, 0.62)
"""Fraction of the cycle for the push-off peak plantarflexion angle. Push-off is stance: the
window ends at toe off when the foot leaves earlier (after toe off the unloaded foot moves
freely and is not pushing off); ``peak_plantarflexion_40_62_percent_deg`` is the whole window."""
MID_SWING_WINDOW = (0.10, 0.90)
"""Fraction of the swing duration (from toe off) searched for minimum foot clearance and swing
peak dorsiflexion (the ends are left out: the last touch of toe off and the floor's push on the
foot as heel strike begins are not swing)."""

ANGLE_CHANNELS = tuple(f"{j}_angle_rad" for j in JOINTS)
MOMENT_CHANNELS = tuple(f"{j}_moment_nm_per_kg" for j in JOINTS)
POWER_CHANNELS = tuple(f"{j}_power_w_per_kg" for j in JOINTS)
CURVE_CHANNELS = (ANGLE_CHANNELS + MOMENT_CHANNELS + POWER_CHANNELS
                  + ("grf_x_n_per_kg", "grf_z_n_per_kg", "ankle_device_moment_nm_per_kg",
                     "ankle_device_power_w_per_kg", "toe_height_m", "heel_height_m"))
"""Channels resampled per cycle (names as in :mod:`afo_mj.gait.reference` where shared)."""


class GaitAnalysisError(ValueError):
    """The record cannot be analysed (no complete cycle, non-finite key metric, ...)."""


@dataclasses.dataclass(frozen=True)
class GaitCycle:
    """One gait cycle of one leg: resampled curves (101 points) and scalar metrics.

    ``side`` 0 = right, 1 = left; ``stride`` 1-based per leg; ``toe_off_s`` None if the leg
    never left the floor in this cycle (then stance and swing metrics are NaN).
    """

    side: int
    stride: int
    start_s: float
    end_s: float
    toe_off_s: float | None
    curves: Mapping[str, np.ndarray]
    scalars: Mapping[str, float]

    @property
    def leg(self) -> str:
        return LEGS[self.side]

    @property
    def duration_s(self) -> float:
        return self.end_s - self.start_s


@dataclasses.dataclass(frozen=True)
class GaitAnalysis:
    """What :func:`analyse_gait` returns: the typed summary ``document``
    (:class:`~afo_mj.metrics.documents.GaitSummary`) and its JSON-ready ``summary`` (its
    ``to_json()``), the selected ``cycles`` and mean/SD ``curves`` per channel
    (``{channel: (mean, sd)}`` on :data:`PERCENT_CYCLE`)."""

    summary: dict[str, Any]
    cycles: list[GaitCycle]
    curves: dict[str, tuple[np.ndarray, np.ndarray | None]]
    document: GaitSummary


# ------------------------------------------------------------------------------------------
# cycle detection
# ------------------------------------------------------------------------------------------

def _complete_cycles(record: GaitRecord, side: int) -> list[tuple[int, float, float]]:
    """(stride, start, end) of every complete cycle of ``side`` (before a fall, in the record)."""
    hs = sorted(float(t) for t in record.events.heel_strikes_s[side])
    if record.time_s.size == 0:
        return []
    t_first, t_last = float(record.time_s[0]), float(record.time_s[-1])
    tol = 0.5 * record.sample_period_s
    fall = record.events.fall_time_s
    out = []
    for k in range(len(hs) - 1):
        t0, t1 = hs[k], hs[k + 1]
        if t1 <= t0 or t0 < t_first - tol or t1 > t_last + tol:
            continue
        if fall is not None and t1 > fall:
            continue
        out.append((k + 1, t0, t1))
    return out


def _check_strides(strides: tuple[int, int] | None) -> tuple[int, int] | None:
    if strides is None:
        return None
    try:
        a, b = (int(s) for s in strides)
    except (TypeError, ValueError):
        raise GaitAnalysisError(f"strides = {strides!r}; allowed: (first, last), 1-based "
                                f"inclusive integers, or None for all") from None
    if a < 1 or b < a:
        raise GaitAnalysisError(f"strides = {strides!r}; allowed: 1 <= first <= last")
    return a, b


def find_cycles(record: GaitRecord, strides: tuple[int, int] | None = (4, 10)
                ) -> list[tuple[int, int, float, float, float | None]]:
    """Selected complete cycles as (side, stride, start_s, end_s, toe_off_s or None).

    ``strides`` = (first, last), 1-based inclusive per leg, or None for every complete cycle.
    Fewer cycles than requested: those that exist are returned (possibly none).
    """
    sel = _check_strides(strides)
    out = []
    for side in (0, 1):
        toe_offs = np.sort(np.asarray(record.events.toe_offs_s[side], dtype=float))
        for stride, t0, t1 in _complete_cycles(record, side):
            if sel is not None and not (sel[0] <= stride <= sel[1]):
                continue
            inside = toe_offs[(toe_offs > t0) & (toe_offs < t1)]
            out.append((side, stride, t0, t1, float(inside[0]) if inside.size else None))
    return out


# ------------------------------------------------------------------------------------------
# per-cycle metrics
# ------------------------------------------------------------------------------------------

def _window(t: np.ndarray, y: np.ndarray, ta: float, tb: float) -> tuple[np.ndarray, np.ndarray]:
    """Samples of ``y(t)`` on [ta, tb], with the end points linearly interpolated."""
    inside = (t > ta) & (t < tb)
    tt = np.concatenate(([ta], t[inside], [tb]))
    yy = np.concatenate(([np.interp(ta, t, y)], y[inside], [np.interp(tb, t, y)]))
    return tt, yy


def _trapezoid(y: np.ndarray, t: np.ndarray) -> float:
    return float(np.sum(0.5 * (y[1:] + y[:-1]) * np.diff(t))) if t.size > 1 else 0.0


def _work(t: np.ndarray, p: np.ndarray, ta: float, tb: float) -> tuple[float, float]:
    """(positive, negative) work of power ``p`` over [ta, tb] (Winter 2009: ∫max(P,0),
    ∫min(P,0))."""
    tt, pp = _window(t, p, ta, tb)
    return _trapezoid(np.maximum(pp, 0.0), tt), _trapezoid(np.minimum(pp, 0.0), tt)


def _rms(x: np.ndarray) -> float:
    return float(np.sqrt(np.mean(np.square(x)))) if x.size else math.nan


def reference_band(reference, channel: str) -> tuple[np.ndarray, np.ndarray | None] | None:
    """Reference (mean, sd) of ``channel`` on the 101-point grid, or None if it lacks it.

    Powers absent from the reference are computed with its ``powers_w_per_kg`` (Winter)."""
    if reference is None:
        return None
    has = getattr(reference, "has", None)
    if has is None or has(channel):
        try:
            mean, sd = reference.band(channel, _PHASE)
            return np.asarray(mean, dtype=float), (None if sd is None
                                                   else np.asarray(sd, dtype=float))
        except (KeyError, ValueError):
            pass
    if channel in POWER_CHANNELS and hasattr(reference, "powers_w_per_kg"):
        try:
            return np.asarray(reference.powers_w_per_kg(_PHASE)[..., POWER_CHANNELS.index(channel)],
                              dtype=float), None
        except (KeyError, ValueError):
            return None
    return None


def _cycle(record: GaitRecord, side: int, stride: int, t0: float, t1: float,
           toe_off: float | None, refs: Mapping[str, tuple[np.ndarray, np.ndarray | None]]
           ) -> GaitCycle:
    t = record.time_s
    m = record.body_mass_kg
    T = t1 - t0
    tg = t0 + _PHASE * T
    interp = lambda y: np.interp(tg, t, y)  # noqa: E731
    power = record.joint_power_w[:, side, :]
    ankle_vel = record.joint_velocity_rad_s[:, side, 2]
    device_power = record.device_moment_nm[:, side] * ankle_vel
    curves: dict[str, np.ndarray] = {}
    for j, name in enumerate(JOINTS):
        curves[f"{name}_angle_rad"] = interp(record.joint_angle_rad[:, side, j])
        curves[f"{name}_moment_nm_per_kg"] = interp(record.joint_moment_nm[:, side, j]) / m
        curves[f"{name}_power_w_per_kg"] = interp(power[:, j]) / m
    # the thigh's angle from vertical (hip flexion − trunk/pelvis forward tilt), comparable
    # with gait data whose pelvis tilts (Schwartz 2008: hip − pelvic tilt)
    curves["pelvis_tilt_rad"] = interp(record.pelvis_tilt_rad)
    curves["thigh_angle_rad"] = interp(record.joint_angle_rad[:, side, 0] - record.pelvis_tilt_rad)
    curves["grf_x_n_per_kg"] = interp(record.grf_n[:, side, 0]) / m
    curves["grf_z_n_per_kg"] = interp(record.grf_n[:, side, 1]) / m
    curves["ankle_device_moment_nm_per_kg"] = interp(record.device_moment_nm[:, side]) / m
    curves["ankle_device_power_w_per_kg"] = interp(device_power) / m
    curves["heel_height_m"] = interp(record.contact_height_m[:, side, 0])
    curves["toe_height_m"] = interp(record.contact_height_m[:, side, 1])

    s: dict[str, float] = {}
    s["cycle_time_s"] = T
    s["cadence_steps_per_min"] = 120.0 / T
    x0, x1 = np.interp([t0, t1], t, record.pelvis_position_m[:, 0])
    s["stride_length_m"] = float(x1 - x0)
    s["speed_m_s"] = float(x1 - x0) / T
    s["stance_fraction"] = (toe_off - t0) / T if toe_off is not None else math.nan

    for j, name in enumerate(JOINTS):
        pos, neg = _work(t, power[:, j], t0, t1)
        s[f"{name}_positive_work_j_per_kg"] = pos / m
        s[f"{name}_negative_work_j_per_kg"] = neg / m
    pa, pb = t0 + PUSH_OFF_WINDOW[0] * T, t0 + PUSH_OFF_WINDOW[1] * T
    s["ankle_push_off_positive_work_j_per_kg"] = _work(t, power[:, 2], pa, pb)[0] / m
    s["peak_ankle_power_w_per_kg"] = float(np.max(_window(t, power[:, 2], pa, pb)[1])) / m
    _, ankle_m = _window(t, record.joint_moment_nm[:, side, 2], t0, t1)
    s["peak_ankle_plantarflexor_moment_nm_per_kg"] = -float(np.min(ankle_m)) / m
    _, dev_m = _window(t, record.device_moment_nm[:, side], t0, t1)
    s["peak_device_plantarflexor_moment_nm_per_kg"] = -float(np.min(dev_m)) / m
    dpos, dneg = _work(t, device_power, t0, t1)
    s["device_ankle_positive_work_j_per_kg"] = dpos / m
    s["device_ankle_negative_work_j_per_kg"] = dneg / m

    ankle = record.joint_angle_rad[:, side, 2]
    _, a_all = _window(t, ankle, t0, t1)
    wa, wb = t0 + PUSH_OFF_ANGLE_WINDOW[0] * T, t0 + PUSH_OFF_ANGLE_WINDOW[1] * T
    _, a_po = _window(t, ankle, wa, wb)
    s["peak_plantarflexion_40_62_percent_deg"] = -math.degrees(float(np.min(a_po)))
    if toe_off is not None and toe_off > wa:
        _, a_po = _window(t, ankle, wa, min(wb, toe_off))
    s["push_off_peak_plantarflexion_deg"] = -math.degrees(float(np.min(a_po)))
    s["peak_plantarflexion_deg"] = -math.degrees(float(np.min(a_all)))
    if toe_off is not None:
        ts = t1 - toe_off
        wa, wb = toe_off + MID_SWING_WINDOW[0] * ts, toe_off + MID_SWING_WINDOW[1] * ts
        _, a_sw = _window(t, ankle, wa, wb)
        s["swing_peak_dorsiflexion_deg"] = math.degrees(float(np.max(a_sw)))
        # the foot drop signature: the ankle hangs plantarflexed through swing
        s["swing_mean_ankle_angle_deg"] = math.degrees(float(np.mean(a_sw)))
        s["min_toe_clearance_m"] = float(np.min(
            _window(t, record.contact_height_m[:, side, 1], wa, wb)[1]))
        s["min_heel_clearance_m"] = float(np.min(
            _window(t, record.contact_height_m[:, side, 0], wa, wb)[1]))
    else:
        for k in ("swing_peak_dorsiflexion_deg", "swing_mean_ankle_angle_deg",
                  "min_toe_clearance_m", "min_heel_clearance_m"):
            s[k] = math.nan
    _, fz = _window(t, record.grf_n[:, side, 1], t0, t1)
    s["peak_vertical_grf_n_per_kg"] = float(np.max(fz)) / m

    mask = (t >= t0) & (t <= t1)
    f = np.hypot(record.residual_force_n[mask, 0], record.residual_force_n[mask, 1])
    s["residual_force_rms_n"] = _rms(f)
    s["residual_force_rms_percent_body_weight"] = 100.0 * _rms(f) / (m * GRAVITY_M_S2)
    s["residual_moment_rms_nm"] = _rms(record.residual_moment_nm[mask])

    for j, name in enumerate(JOINTS):
        ach = f"{name}_angle_rad"
        ref = refs.get(ach)
        if ref is None:
            s[f"{name}_angle_rms_error_deg"] = math.nan
            s[f"{name}_angle_within_1sd_fraction"] = math.nan
        else:
            mean, sd = ref
            s[f"{name}_angle_rms_error_deg"] = math.degrees(_rms(curves[ach] - mean))
            s[f"{name}_angle_within_1sd_fraction"] = (
                math.nan if sd is None else float(np.mean(np.abs(curves[ach] - mean) <= sd)))
        mref = refs.get(f"{name}_moment_nm_per_kg")
        s[f"{name}_moment_rms_error_nm_per_kg"] = (
            math.nan if mref is None else _rms(curves[f"{name}_moment_nm_per_kg"] - mref[0]))
    return GaitCycle(side=side, stride=stride, start_s=t0, end_s=t1, toe_off_s=toe_off,
                     curves=curves, scalars=s)


def _reference_bands(reference) -> dict[str, tuple[np.ndarray, np.ndarray | None]]:
    out = {}
    for ch in CURVE_CHANNELS:
        band = reference_band(reference, ch)
        if band is not None:
            out[ch] = band
    return out


def _no_cycle_message(record: GaitRecord, strides: tuple[int, int] | None) -> str:
    ev = record.events
    n_complete = [len(_complete_cycles(record, s)) for s in (0, 1)]
    t_end = float(record.time_s[-1]) if record.time_s.size else 0.0
    why = (f"the walker fell at t = {ev.fall_time_s:.3f} s" if ev.fall_time_s is not None
           else f"the record ends at t = {t_end:.3f} s")
    want = "any stride" if strides is None else f"strides {strides[0]}-{strides[1]}"
    return (f"no complete gait cycle to analyse for {want}: {why}; complete cycles "
            f"right {n_complete[0]}, left {n_complete[1]} (heel strikes right "
            f"{len(ev.heel_strikes_s[0])}, left {len(ev.heel_strikes_s[1])})")


def extract_cycles(record: GaitRecord, reference=None,
                   strides: tuple[int, int] | None = (4, 10)) -> list[GaitCycle]:
    """The selected cycles of both legs with curves and scalars (see the module docstring).

    ``reference`` (a :class:`~afo_mj.gait.reference.ReferenceGait` or None) adds the angle
    RMS errors, band fractions and moment RMS errors (NaN without it).
    Raises :class:`GaitAnalysisError` when no cycle is selected.
    """
    sel = _check_strides(strides)
    found = find_cycles(record, sel)
    if not found:
        raise GaitAnalysisError(_no_cycle_message(record, sel))
    refs = _reference_bands(reference)
    return [_cycle(record, *c, refs=refs) for c in found]


# ------------------------------------------------------------------------------------------
# statistics over cycles
# ------------------------------------------------------------------------------------------

def scalar_statistics(values: Iterable[float]) -> dict[str, float | int | None]:
    """``{"mean", "sd", "n"}`` over the finite values (sample SD, ddof = 1; None if n < 2;
    mean None if n = 0)."""
    v = np.asarray([x for x in values if x is not None], dtype=float)
    v = v[np.isfinite(v)]
    n = int(v.size)
    return {"mean": float(np.mean(v)) if n else None,
            "sd": float(np.std(v, ddof=1)) if n >= 2 else None, "n": n}


def curve_statistics(cycles: Sequence[GaitCycle], channel: str
                     ) -> tuple[np.ndarray, np.ndarray | None]:
    """Mean and SD (ddof = 1; None for a single cycle) of ``channel`` over ``cycles``."""
    if not cycles:
        raise GaitAnalysisError("curve_statistics: no cycles")
    a = np.stack([c.curves[channel] for c in cycles])
    return a.mean(axis=0), (a.std(axis=0, ddof=1) if len(cycles) >= 2 else None)


def band_fraction(cycles: Sequence[GaitCycle], reference,
                  channels: Sequence[str] = ANGLE_CHANNELS + ("thigh_angle_rad",)
                  ) -> dict[str, dict | None]:
    """Fraction of each cycle's 101 points inside the reference mean ± 1 SD, per channel.

    Returns ``{channel: {"mean", "sd", "n"}}`` over cycles, or ``None`` for a channel the
    reference lacks or gives without SD (Winter). Works with any reference with SD bands, e.g.
    ``load_normative("schwartz2008", "Free")`` (angles only). ``thigh_angle_rad`` compares the
    walker's thigh-from-vertical with the reference's hip angle less its pelvic tilt: the
    like-for-like hip comparison for a walker whose pelvis stays level.
    """
    out: dict[str, dict | None] = {}
    for ch in channels:
        band = reference_band(reference, ch)
        if band is None or band[1] is None:
            out[ch] = None
            continue
        mean, sd = band
        out[ch] = scalar_statistics(float(np.mean(np.abs(c.curves[ch] - mean) <= sd))
                                    for c in cycles)
    return out


# ------------------------------------------------------------------------------------------
# summary
# ------------------------------------------------------------------------------------------

def _clean(x: Any) -> Any:
    """NaN/inf → None, numpy scalars → Python, recursively (JSON-ready)."""
    if isinstance(x, dict):
        return {k: _clean(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_clean(v) for v in x]
    if isinstance(x, (np.floating, float)):
        return float(x) if math.isfinite(x) else None
    if isinstance(x, np.integer):
        return int(x)
    return x


def analyse_gait(record: GaitRecord, reference,
                 strides: tuple[int, int] | None = (4, 10)) -> GaitAnalysis:
    """Cycles, mean/SD curves and the JSON-ready summary (see :func:`summarize`)."""
    sel = _check_strides(strides)
    cycles = extract_cycles(record, reference, sel)
    summary: dict[str, Any] = {"format": "afo_mj gait summary v1"}
    summary["reference"] = {
        "source": getattr(reference, "source", None),
        "condition": getattr(reference, "condition", None),
        "cycle_time_s": getattr(reference, "cycle_time_s", None),
        "speed_m_s": getattr(reference, "speed_m_s", None)} if reference is not None else None
    summary["body_mass_kg"] = record.body_mass_kg
    summary["height_m"] = record.height_m
    summary["strides_requested"] = None if sel is None else list(sel)
    summary["n_cycles_used"] = len(cycles)
    summary["n_cycles_per_leg"] = {leg: sum(c.side == s for c in cycles)
                                   for s, leg in enumerate(LEGS)}
    completed = {leg: len(_complete_cycles(record, s)) for s, leg in enumerate(LEGS)}
    summary["completed_strides"] = completed["right"]
    summary["completed_strides_per_leg"] = completed
    ev = record.events
    summary["fall_time_s"] = ev.fall_time_s
    summary["fell"] = ev.fall_time_s is not None
    summary["swing_toe_contacts"] = len(ev.swing_toe_contacts)
    summary["swing_toe_contacts_per_leg"] = {
        leg: sum(1 for _, sd in ev.swing_toe_contacts if sd == s) for s, leg in enumerate(LEGS)}
    span = (min(c.start_s for c in cycles), max(c.end_s for c in cycles))
    summary["analysed_span_s"] = list(span)
    summary["swing_toe_contacts_in_analysed_span"] = sum(
        1 for t, _ in ev.swing_toe_contacts if span[0] <= t <= span[1])
    summary["duration_s"] = (float(record.time_s[-1] - record.time_s[0]) if record.time_s.size
                             else 0.0)

    for key in cycles[0].scalars:
        summary[key] = scalar_statistics(c.scalars[key] for c in cycles)
    # band fractions: None where the reference has no SD
    for j in JOINTS:
        key = f"{j}_angle_within_1sd_fraction"
        if summary[key]["n"] == 0:
            summary[key] = None
    # residuals over the whole analysed span as well
    t = record.time_s
    mask = (t >= span[0]) & (t <= span[1])
    f = np.hypot(record.residual_force_n[mask, 0], record.residual_force_n[mask, 1])
    bw = record.body_mass_kg * GRAVITY_M_S2
    summary["residual_force_rms_n"]["over_analysed_span"] = _rms(f)
    summary["residual_force_rms_percent_body_weight"]["over_analysed_span"] = 100 * _rms(f) / bw
    summary["residual_moment_rms_nm"]["over_analysed_span"] = _rms(record.residual_moment_nm[mask])
    summary["definitions"] = {
        "push_off_window_percent_cycle": [100 * w for w in PUSH_OFF_WINDOW],
        "push_off_angle_window_percent_cycle": [100 * w for w in PUSH_OFF_ANGLE_WINDOW],
        "mid_swing_window_percent_swing": [100 * w for w in MID_SWING_WINDOW],
        "statistics": "mean and sample SD (ddof 1) over the pooled selected cycles of both legs",
        "signs": "angles + flexion/dorsiflexion; moments + in the angle direction (plantarflexor "
                 "moment negative); negative work <= 0",
    }
    if reference is not None:
        for j in JOINTS:
            st = summary[f"{j}_angle_rms_error_deg"]
            if st["n"] < len(cycles):
                raise GaitAnalysisError(
                    f"{j}_angle_rms_error_deg is not finite in {len(cycles) - st['n']} of "
                    f"{len(cycles)} cycles: the simulation's joint angles contain NaN/inf "
                    f"(numerics failure)")
    curves = {ch: curve_statistics(cycles, ch) for ch in CURVE_CHANNELS}
    # the document checks the keys and their kinds; the summary dict is written from it
    doc = GaitSummary.from_json(_clean(summary))
    return GaitAnalysis(summary=doc.to_json(), cycles=cycles, curves=curves, document=doc)


def summarize(record: GaitRecord, reference, strides: tuple[int, int] | None = (4, 10)
              ) -> dict[str, Any]:
    """JSON-ready summary of a run: every per-cycle scalar as ``{"mean", "sd", "n"}`` over the
    pooled selected cycles of both legs, keys carrying units (``ankle_angle_rms_error_deg``,
    ``peak_ankle_plantarflexor_moment_nm_per_kg``, ``speed_m_s``,
    ``residual_force_rms_percent_body_weight`` (+ ``over_analysed_span``), ...), plus
    ``fall_time_s`` (None without a fall), ``swing_toe_contacts``, ``n_cycles_used``,
    ``completed_strides`` (complete right-leg cycles before the end or the fall).

    ``strides``: (first, last) 1-based inclusive per leg, or None for all; fewer cycles than
    requested are used as they are (see ``n``). Raises :class:`GaitAnalysisError` when no
    cycle can be analysed (the message says why, e.g. the fall time). NaN metrics become None.
    """
    return analyse_gait(record, reference, strides).summary
