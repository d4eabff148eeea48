"""Ankle assistance vs gait phase: torque profiles and online gait-phase estimation.

Profiles are tabulated once over the stride (phase 0 = heel strike … 1 = next heel strike of
the same foot) and looked up per step by a compiled linear interpolation. Torques are given as
plantarflexion assistance magnitudes (N·m, ≥ 0) and returned with the ankle sign convention of
the package (+dorsiflexion), i.e. negated.

* :func:`zhang_profile` — the four-parameter profile of Zhang et al., "Human-in-the-loop
  optimization of exoskeleton assistance during walking", *Science* 356:1280 (2017): zero until
  onset ``t_p − t_r``, a cubic rise to the peak torque at ``t_p``, a cubic fall to zero at
  ``t_p + t_f`` (all times in % of stride), zero after. Each piece is the cubic with zero slope
  at both of its knots (the shape of the paper's cubic-spline segments with flat ends).
  Published example (facts.md): peak at 52.9 %, rise 26.2 %, fall 9.8 % of stride.
* :func:`spline_profile` — an n-point profile through user points (phase %, N·m) by a
  shape-preserving monotone cubic (scipy's ``PchipInterpolator``: no overshoot, so a
  non-negative set of points never produces dorsiflexion torque between them), periodic.

Gait phase from foot contact (no oracle timing): :func:`phase_update` keeps, per side, the
time of the last heel strike (rising edge of the foot-switch signal after a minimum swing) and
the mean of the last ``n`` measured stride durations. Phase = time since heel strike / mean
stride, held at 1 until the next heel strike. Until two heel strikes have been seen there is no
stride estimate and the phase is reported as −1 (assistance off), as on a real device.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from afo_mj.hydraulics.params import ParameterError

TABLE_POINTS = 1001


def zhang_profile(peak_torque_nm: float, peak_time_pct: float, rise_time_pct: float,
                  fall_time_pct: float, n: int = TABLE_POINTS) -> np.ndarray:
    """Tabulated Zhang et al. (2017) profile over phase ``linspace(0, 1, n)`` (+dorsiflexion).

    Example: ``zhang_profile(40, 52.9, 26.2, 9.8)`` is 0 before 26.7 %, 20 N·m plantarflexion
    (−20) at 39.8 %, −40 at 52.9 %, 0 from 62.7 % on.
    """
    checks = {"peak_torque_nm": (peak_torque_nm, 0.0, 500.0),
              "peak_time_pct": (peak_time_pct, 0.0, 100.0),
              "rise_time_pct": (rise_time_pct, 0.1, 100.0),
              "fall_time_pct": (fall_time_pct, 0.1, 100.0)}
    for key, (v, lo, hi) in checks.items():
        if not (isinstance(v, (int, float)) and lo <= v <= hi):
            raise ParameterError(f"assistance.{key} = {v!r}; allowed: {lo:g} <= {key} <= {hi:g}")
    if peak_time_pct - rise_time_pct < 0 or peak_time_pct + fall_time_pct > 100:
        raise ParameterError(
            f"assistance: onset peak_time_pct - rise_time_pct = {peak_time_pct - rise_time_pct:g} "
            f"and end peak_time_pct + fall_time_pct = {peak_time_pct + fall_time_pct:g}; "
            "allowed: both within 0 … 100 % of the stride")
    x = np.linspace(0.0, 100.0, n)
    tau = np.zeros(n)
    on, pk, off = peak_time_pct - rise_time_pct, peak_time_pct, peak_time_pct + fall_time_pct
    rise = (x >= on) & (x <= pk)
    u = (x[rise] - on) / rise_time_pct
    tau[rise] = u * u * (3 - 2 * u)
    fall = (x > pk) & (x <= off)
    u = (off - x[fall]) / fall_time_pct
    tau[fall] = u * u * (3 - 2 * u)
    return -peak_torque_nm * tau


def spline_profile(phase_pct, torque_nm, n: int = TABLE_POINTS) -> np.ndarray:
    """Tabulated periodic monotone-cubic profile through ``(phase_pct, torque_nm)`` points
    (plantarflexion magnitudes), returned +dorsiflexion over ``linspace(0, 1, n)``."""
    from scipy.interpolate import PchipInterpolator

    x = np.asarray(phase_pct, dtype=float)
    y = np.asarray(torque_nm, dtype=float)
    if x.ndim != 1 or x.shape != y.shape or len(x) < 2:
        raise ParameterError(f"assistance.points: need >= 2 (phase_pct, torque_nm) pairs; got "
                             f"{len(x)} phases and {len(y)} torques")
    if np.any(np.diff(x) <= 0) or x[0] < 0 or x[-1] >= 100:
        raise ParameterError(f"assistance.points phase_pct = {x.tolist()}; allowed: strictly "
                             "increasing, within 0 <= phase < 100")
    if not np.all(np.isfinite(y)) or np.any(np.abs(y) > 500):
        raise ParameterError(f"assistance.points torque_nm = {y.tolist()}; allowed: finite, "
                             "|torque| <= 500 N·m")
    # periodic: wrap one point each side
    xx = np.concatenate([[x[-1] - 100.0], x, [x[0] + 100.0]])
    yy = np.concatenate([[y[-1]], y, [y[0]]])
    f = PchipInterpolator(xx, yy)
    return -f(np.linspace(0.0, 100.0, n))


@numba.njit(cache=True)
def table_lookup(table, phase):
    """Linear interpolation of a tabulated profile at ``phase`` in [0, 1]; 0 if ``phase < 0``."""
    if phase < 0.0:
        return 0.0
    n = table.shape[0]
    x = phase * (n - 1)
    if x >= n - 1:
        return table[n - 1]
    i = int(x)
    return table[i] + (x - i) * (table[i + 1] - table[i])


# phase-estimator state per side
PH_LAST_HS, PH_STANCE, PH_N, PH_MEAN, PH_PHASE = range(5)
PH_HIST = 5            # start of the stride history ring
N_PH_HIST = 3
N_PH = PH_HIST + N_PH_HIST


def new_phase_state(sides: int) -> np.ndarray:
    st = np.zeros((sides, N_PH))
    st[:, PH_LAST_HS] = -1.0
    st[:, PH_PHASE] = -1.0
    return st


@numba.njit(cache=True)
def phase_update(st, t, stance, min_stride_s, max_stride_s):
    """Update one side's estimator with the foot-switch state and return the phase (or −1).

    A heel strike is a rising edge of ``stance``. Stride durations outside
    ``[min_stride_s, max_stride_s]`` (a stumble, a stop) are not averaged in.
    """
    was = st[PH_STANCE]
    if stance and was == 0.0:
        last = st[PH_LAST_HS]
        if last >= 0.0:
            dur = t - last
            if min_stride_s <= dur <= max_stride_s:
                n = int(st[PH_N])
                st[PH_HIST + n % N_PH_HIST] = dur
                n += 1
                st[PH_N] = n
                m = min(n, N_PH_HIST)
                s = 0.0
                for k in range(m):
                    s += st[PH_HIST + k]
                st[PH_MEAN] = s / m
        st[PH_LAST_HS] = t
    st[PH_STANCE] = 1.0 if stance else 0.0
    if st[PH_N] < 1 or st[PH_LAST_HS] < 0.0:
        st[PH_PHASE] = -1.0
        return -1.0
    ph = (t - st[PH_LAST_HS]) / st[PH_MEAN]
    if ph > 1.0:
        ph = 1.0
    st[PH_PHASE] = ph
    return ph


def phase_error_check(estimated: np.ndarray, oracle: np.ndarray) -> float:
    """RMS circular difference between two phase series in [0, 1] (for tests and reports)."""
    ok = (estimated >= 0) & (oracle >= 0)
    d = np.abs(estimated[ok] - oracle[ok])
    d = np.minimum(d, 1 - d)
    return float(math.sqrt(np.mean(d * d))) if d.size else math.nan
