"""Synthetic gait records with known answers, for tests of the analysis and the CLI.

:func:`synthetic_record` builds a :class:`~afo_mj.gait.record.GaitRecord` whose joint angles
and moments are exactly Winter's normal-cadence gait: right leg from heel strikes at 0, T, 2T,
...; left leg shifted by half a cycle; toe off at 62 % of every cycle; pelvis moving forward at
1.325 m/s; constant residual force and moment; foot clearance in swing known in closed form.

The Winter data come from the raw shared file ``/work/shared/data/winter_normal_cadence.csv``
when present (independent of the package's derived table), else from the shipped table via
:func:`afo_mj.gait.reference.load_normative`.
"""

from __future__ import annotations

import csv
import math
from pathlib import Path

import numpy as np
from scipy.interpolate import CubicSpline

from afo_mj.gait.record import GaitEvents, GaitRecord

WINTER_CSV = Path("/work/shared/data/winter_normal_cadence.csv")
WINTER_CYCLE_TIME_S = 1.1396
WINTER_SPEED_M_S = 1.325
TOE_OFF_FRACTION = 0.62
RESIDUAL_FORCE_N = (3.0, 4.0)    # |F| = 5 N
RESIDUAL_MOMENT_NM = 2.0
TOE_CLEARANCE = (0.01, 0.04)     # ball height in swing = a + b sin(pi s), s = swing fraction
HEEL_CLEARANCE = (0.02, 0.05)


def mid_swing_min(a: float, b: float, window=(0.10, 0.90)) -> float:
    """Minimum of a + b sin(pi s) over the mid-swing window."""
    return a + b * math.sin(math.pi * window[0])


class WinterSplines:
    """Periodic splines of Winter's angles (rad) and moments (N*m/kg, our sign) vs phase."""

    def __init__(self) -> None:
        if WINTER_CSV.exists():
            self.source = "raw"
            rows = []
            with WINTER_CSV.open(encoding="utf-8-sig") as f:
                for row in csv.reader(f):
                    try:
                        rows.append([float(row[1])] + [float(x) for x in row[4:12]])
                    except (ValueError, IndexError):
                        continue
            d = np.asarray(rows)
            keep = d[:, 0] < 99.5            # 0..98 %, close the period with the 0 % sample
            ph = np.r_[d[keep, 0] / 100.0, 1.0]
            col = lambda i: np.r_[d[keep, i], d[0, i]]  # noqa: E731
            deg = math.pi / 180.0
            self.angles = [CubicSpline(ph, col(i) * deg, bc_type="periodic") for i in (1, 2, 3)]
            # Winter moments are extensor/plantarflexor positive: negate to our convention
            self.moments = [CubicSpline(ph, -col(i), bc_type="periodic") for i in (6, 7, 8)]
            self.grf = [CubicSpline(ph, col(i), bc_type="periodic") for i in (4, 5)]
        else:
            from afo_mj.gait.reference import load_normative
            self.source = "shipped"
            ref = load_normative("winter", "normal")
            j = ("hip", "knee", "ankle")
            self.angles = [ref.splines[f"{n}_angle_rad"] for n in j]
            self.moments = [ref.splines[f"{n}_moment_nm_per_kg"] for n in j]
            self.grf = [ref.splines["grf_x_n_per_kg"], ref.splines["grf_z_n_per_kg"]]


def _phase(t: np.ndarray, hs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Phase in [0,1) and d phase/dt from heel strike times (extrapolated outside)."""
    k = np.clip(np.searchsorted(hs, t, side="right") - 1, 0, len(hs) - 2)
    period = hs[k + 1] - hs[k]
    ph = (t - hs[k]) / period
    return np.mod(ph, 1.0), 1.0 / period


def synthetic_record(n_cycles: int = 12, body_mass_kg: float = 75.0, height_m: float = 1.75,
                     sample_period_s: float = 0.004, jitter: float = 0.0, seed: int = 0,
                     ankle_offset_rad: float = 0.0, fall_time_s: float | None = None,
                     splines: WinterSplines | None = None) -> GaitRecord:
    """A record of ``n_cycles`` right-leg cycles of Winter's gait (see the module docstring).

    ``jitter``: cycle durations T·(1 + U(−jitter, jitter)); ``ankle_offset_rad`` is added to
    both ankle angles; ``fall_time_s`` truncates the record there and sets the fall event.
    """
    w = splines or WinterSplines()
    rng = np.random.default_rng(seed)
    T = WINTER_CYCLE_TIME_S
    durations = (T * (1.0 + rng.uniform(-jitter, jitter, n_cycles)) if jitter
                 else np.full(n_cycles, T))
    hs_r = np.r_[0.0, np.cumsum(durations)]
    hs_l = hs_r[:-1] + 0.5 * durations            # left heel strike half a cycle later
    t_end = hs_r[-1] + 0.3 * T                      # a bit of the next cycle
    if fall_time_s is not None:
        t_end = min(t_end, fall_time_s)
    n = int(round(t_end / sample_period_s)) + 1
    rec = GaitRecord.allocate(n, body_mass_kg, height_m, sample_period_s)
    t = np.arange(n) * sample_period_s
    rec.time_s[:] = t
    m = body_mass_kg
    hs_l_ext = np.r_[hs_l[0] - durations[0], hs_l, hs_l[-1] + durations[-1]]
    hs_r_ext = np.r_[hs_r, hs_r[-1] + durations[-1]]
    toe_offs = ([], [])
    for side, hs in ((0, hs_r_ext), (1, hs_l_ext)):
        ph, dph = _phase(t, hs)
        for j in range(3):
            rec.joint_angle_rad[:, side, j] = w.angles[j](ph)
            rec.joint_velocity_rad_s[:, side, j] = w.angles[j](ph, 1) * dph
            rec.joint_moment_nm[:, side, j] = w.moments[j](ph) * m
        rec.joint_angle_rad[:, side, 2] += ankle_offset_rad
        rec.grf_n[:, side, 0] = w.grf[0](ph) * m
        rec.grf_n[:, side, 1] = w.grf[1](ph) * m
        swing = ph >= TOE_OFF_FRACTION
        s = np.where(swing, (ph - TOE_OFF_FRACTION) / (1 - TOE_OFF_FRACTION), 0.0)
        rec.contact_height_m[:, side, 1] = np.where(
            swing, TOE_CLEARANCE[0] + TOE_CLEARANCE[1] * np.sin(np.pi * s), 0.0)
        rec.contact_height_m[:, side, 0] = np.where(
            swing, HEEL_CLEARANCE[0] + HEEL_CLEARANCE[1] * np.sin(np.pi * s), 0.0)
        rec.contact_force_n[:, side, 0] = np.where(swing, 0.0, rec.grf_n[:, side, 1])
        rec.gait_phase[:, side] = ph
        for a, b in zip(hs[:-1], hs[1:]):
            to = a + TOE_OFF_FRACTION * (b - a)
            if 0 <= to <= t[-1]:
                toe_offs[side].append(float(to))
    rec.pelvis_position_m[:, 0] = WINTER_SPEED_M_S * t
    rec.pelvis_position_m[:, 1] = 0.92
    rec.pelvis_velocity_m_s[:, 0] = WINTER_SPEED_M_S
    rec.residual_force_n[:, 0] = RESIDUAL_FORCE_N[0]
    rec.residual_force_n[:, 1] = RESIDUAL_FORCE_N[1]
    rec.residual_moment_nm[:] = RESIDUAL_MOMENT_NM
    rec.events = GaitEvents(
        heel_strikes_s=([float(x) for x in hs_r if x <= t[-1]],
                        [float(x) for x in hs_l if x <= t[-1]]),
        toe_offs_s=(sorted(toe_offs[0]), sorted(toe_offs[1])),
        fall_time_s=fall_time_s,
        swing_toe_contacts=[(0.5, 0), (3.3, 1)])
    return rec
