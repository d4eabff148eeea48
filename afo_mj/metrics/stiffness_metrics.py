"""Stiffness and hysteresis of an ankle orthosis from a slow torque–angle sweep (numpy only).

A stiffness rig rotates the ankle (or the orthosis on a dummy leg) slowly back and forth
through dorsiflexion and plantarflexion and records the angle and the orthosis torque. This
module reduces such a record to the figures clinical AFO testing reports.

Signs and units
---------------
``angle_rad``: ankle angle [rad], + dorsiflexion (project convention). ``torque_nm``: the torque
the orthosis exerts on the ankle [N·m], + in the direction of increasing angle (the project's
moment convention, as :class:`afo_mj.human.test_stand.AnkleTestStand` records
``device_torque_nm``). A spring-like orthosis resists the motion: ``τ = −K (θ − θ0)`` with
``K > 0``; this module reports that ``K``. (A rig's *applied* torque is the negative of this;
pass ``-applied`` to use it.)

Definitions
-----------
* Stiffness ``K`` [N·m/rad, and N·m/deg]: minus the least-squares slope of torque on angle,
  ``τ ≈ a + s θ``, ``K = −s``, over the whole loop (every sample of the whole cycles used, or of
  all samples when there is no whole cycle), optionally only over samples with the angle
  inside ``angle_window_rad``. This is the "linear fit of the AFO resistive torque and angular
  deflection" of clinical AFO rigs (Bregman et al. 2009, *Gait Posture* 30:144–149, BRUCE;
  Shuman & Russell Esposito 2021, *J. Biomech. Eng.* 144:011004, EMPIRE; compared in
  *J. NeuroEng. Rehabil.* 20:23 (2023), "Comparison of five different methodologies for
  evaluating ankle–foot orthosis stiffness"). ``r_squared`` is that fit's coefficient of
  determination (1 when the torque is constant and exactly fitted).
* Rest angle ``θ0`` [rad]: where the fitted line crosses zero torque, ``θ0 = −a/s`` (the
  "neutral angle" of Bregman et al. 2009); NaN when ``K`` = 0.
* Branch stiffnesses: the same fit on the dorsiflexing samples (angle increasing) and on the
  plantarflexing samples (angle decreasing), the direction taken from ``velocity_rad_s`` when
  given, else from the sample-to-sample change of the angle.
* Loop area, per cycle: ``W_d = −∮ τ dθ`` [J] over one whole cycle (closed polygon, trapezoidal
  rule): the work the ankle does on the orthosis and does not get back, positive for a
  dissipating orthosis. ``hysteresis_energy_j`` is its mean over the cycles used.
* Loss factor ``η = W_d / (2π W_s)`` with ``W_s = ½ K A²``, ``A`` half the peak-to-peak angle of
  the cycle: the loss factor of linear viscoelasticity (Lazan, *Damping of Materials and
  Members in Structural Mechanics*, 1968; Nashif, Jones & Henderson, *Vibration Damping*, 1985,
  §2.2). For ``τ = −Kθ − Bθ̇`` under ``θ = A sin ωt``: ``W_d = π B ω A²``, ``η = B ω / K``.
* Hysteresis fraction ``W_d / W_load``: the loop area over the work done on the orthosis while
  it is loaded, ``W_load = −∫ τ dθ`` over the samples moving away from the rest angle
  (``(θ − θ0) dθ > 0``), i.e. 1 − the energy returned on unloading / the energy put in (the
  "energy return" of prosthetic-foot testing read the other way round, cf. Hafner et al. 2002,
  *Clin. Biomech.* 17:325–344). 0 for a spring; 1 when nothing comes back on unloading; above
  1 when the ankle must still push the orthosis back on unloading (damper-dominated: for
  ``τ = −Kθ − Bθ̇`` under ``θ = A sin ωt`` it is ``πBω / (K + πBω/2)``, above 1 for
  ``η > 2/π``). With ``K <= 0`` the rest angle is NaN, ``W_load`` is taken about the mean
  angle, and the loss factor is NaN.

Cycles
------
The angle's turning points are found with a hysteresis threshold of a quarter of the whole
angle range (so noise does not create extra extrema); a cycle runs from one turning point to
the second next one (max → min → max or min → max → min). Samples before the first turning
point and after the last whole cycle are left out of the loop figures. With two or more whole
cycles the first is dropped as a start-up transient; ``n_cycles`` is the number used. Without
a whole cycle (a one-way sweep) the stiffness uses every sample and the loop figures are NaN.

Example
-------
>>> import numpy as np
>>> t = np.linspace(0.0, 3.0, 3001)
>>> theta = 0.2 * np.sin(2 * np.pi * t)
>>> r = sweep_stiffness(theta, -30.0 * theta - 2.0 * np.gradient(theta, t))
>>> round(r.stiffness_nm_per_rad, 3), r.n_cycles
(30.0, 1)
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

__all__ = ["SweepStiffness", "StiffnessSweepError", "sweep_stiffness", "turning_points",
           "MIN_SAMPLES"]

#: Fewest samples a sweep must have.
MIN_SAMPLES = 10
#: Turning-point threshold as a fraction of the whole angle range.
TURNING_THRESHOLD_FRACTION = 0.25
#: Angle ranges below this [rad] are "no motion".
MIN_ANGLE_RANGE_RAD = 1e-6


class StiffnessSweepError(ValueError):
    """A torque–angle record that cannot be reduced (too short, NaN, no motion, bad window)."""


@dataclasses.dataclass(frozen=True)
class SweepStiffness:
    """Figures of one torque–angle sweep (definitions in the module docstring)."""

    stiffness_nm_per_rad: float
    stiffness_nm_per_deg: float
    rest_angle_rad: float
    r_squared: float
    dorsiflexing_stiffness_nm_per_rad: float
    plantarflexing_stiffness_nm_per_rad: float
    hysteresis_energy_j: float
    loss_factor: float
    hysteresis_fraction: float
    max_torque_nm: float
    angle_amplitude_rad: float
    n_cycles: int
    n_samples_fitted: int

    def as_dict(self) -> dict:
        """The figures as a plain dict (JSON-ready)."""
        return dataclasses.asdict(self)


def _series(name: str, x) -> np.ndarray:
    a = np.asarray(x, dtype=float)
    if a.ndim != 1:
        raise StiffnessSweepError(f"{name} must be one-dimensional; got shape {a.shape}")
    bad = np.flatnonzero(~np.isfinite(a))
    if bad.size:
        raise StiffnessSweepError(f"{name} has {bad.size} non-finite value(s) (NaN or inf), "
                                  f"first at index {bad[0]} (= {a[bad[0]]}); allowed: finite "
                                  f"numbers only")
    return a


def turning_points(angle_rad, threshold_rad: float | None = None) -> np.ndarray:
    """Indices of the angle's turning points (alternating maxima and minima), each a reversal
    of at least ``threshold_rad`` (default a quarter of the whole range): the classic
    peak–valley detector with hysteresis, so noise smaller than the threshold makes no extra
    extrema. The last running extreme is included only if the angle came back from it by the
    threshold."""
    a = np.asarray(angle_rad, dtype=float)
    if threshold_rad is None:
        threshold_rad = TURNING_THRESHOLD_FRACTION * float(np.ptp(a))
    if not threshold_rad > 0:
        return np.zeros(0, dtype=int)
    out: list[int] = []
    direction = 0                    # +1 rising (tracking a max), -1 falling (tracking a min)
    i_max = i_min = 0
    for i in range(1, a.size):
        v = a[i]
        if v > a[i_max]:
            i_max = i
        if v < a[i_min]:
            i_min = i
        if direction >= 0 and a[i_max] - v >= threshold_rad and (direction > 0 or i_max > i_min):
            out.append(i_max)
            direction, i_min = -1, i
        elif direction <= 0 and v - a[i_min] >= threshold_rad and (direction < 0 or i_min > i_max):
            out.append(i_min)
            direction, i_max = 1, i
    return np.asarray(out, dtype=int)


def _fit(theta: np.ndarray, tau: np.ndarray) -> tuple[float, float, float]:
    """Least squares ``tau ≈ a + s theta``: (slope s, intercept a, r²)."""
    tm, fm = theta.mean(), tau.mean()
    dt, df = theta - tm, tau - fm
    sxx = float(dt @ dt)
    if sxx <= 0.0:
        return math.nan, math.nan, math.nan
    s = float(dt @ df) / sxx
    a = float(fm - s * tm)
    ss_tot = float(df @ df)
    ss_res = float(((df - s * dt) ** 2).sum())
    r2 = 1.0 - ss_res / ss_tot if ss_tot > 0.0 else 1.0
    return s, a, r2


def _loop_work(theta: np.ndarray, tau: np.ndarray) -> float:
    """∮ τ dθ over the closed polygon through the samples (trapezoidal rule)."""
    th = np.append(theta, theta[0])
    ta = np.append(tau, tau[0])
    return float((0.5 * (ta[1:] + ta[:-1]) * np.diff(th)).sum())


def _loading_work(theta: np.ndarray, tau: np.ndarray, theta0: float) -> float:
    """−∫ τ dθ over the segments moving away from ``theta0`` (segments that cross it are split
    there, with the torque interpolated linearly)."""
    total = 0.0
    for k in range(theta.size - 1):
        t0, t1, f0, f1 = theta[k], theta[k + 1], tau[k], tau[k + 1]
        if t1 == t0:
            continue
        if (t0 - theta0) * (t1 - theta0) < 0.0:           # crosses the rest angle: split
            fc = f0 + (f1 - f0) * (theta0 - t0) / (t1 - t0)
            # only the part after the crossing moves away from theta0
            total += -0.5 * (fc + f1) * (t1 - theta0)
        elif (0.5 * (t0 + t1) - theta0) * (t1 - t0) > 0.0:
            total += -0.5 * (f0 + f1) * (t1 - t0)
    return total


def sweep_stiffness(angle_rad, torque_nm, velocity_rad_s=None,
                    angle_window_rad: tuple[float, float] | None = None) -> SweepStiffness:
    """Stiffness, rest angle, branch stiffnesses, loop area, loss factor and hysteresis
    fraction of a torque–angle sweep (definitions, signs and cycle handling in the module
    docstring).

    ``angle_rad``, ``torque_nm`` and the optional ``velocity_rad_s`` (only its sign is used, to
    split the branches) are equal-length 1-D sequences in time order; ``angle_window_rad =
    (lo, hi)`` restricts the stiffness fits (not the loop figures) to ``lo <= θ <= hi``.
    Raises :class:`StiffnessSweepError` for fewer than :data:`MIN_SAMPLES` samples, unequal
    lengths, non-finite values, an angle that does not move, or a bad window.
    """
    theta = _series("angle_rad", angle_rad)
    tau = _series("torque_nm", torque_nm)
    if theta.size != tau.size:
        raise StiffnessSweepError(f"angle_rad and torque_nm have different lengths "
                                  f"({theta.size} and {tau.size}); allowed: equal lengths")
    if theta.size < MIN_SAMPLES:
        raise StiffnessSweepError(f"angle_rad has {theta.size} samples; allowed: at least "
                                  f"{MIN_SAMPLES}")
    span = float(np.ptp(theta))
    if span < MIN_ANGLE_RANGE_RAD:
        raise StiffnessSweepError(f"angle_rad does not move (range {span:.3g} rad); allowed: a "
                                  f"sweep with a range of at least {MIN_ANGLE_RANGE_RAD:g} rad")
    if velocity_rad_s is None:
        direction = np.sign(np.gradient(theta))
    else:
        vel = _series("velocity_rad_s", velocity_rad_s)
        if vel.size != theta.size:
            raise StiffnessSweepError(f"velocity_rad_s has {vel.size} samples, angle_rad "
                                      f"{theta.size}; allowed: equal lengths")
        direction = np.sign(vel)

    # whole cycles between every second turning point; drop the first of two or more
    tp = turning_points(theta)
    cycles = [(int(tp[k]), int(tp[k + 2])) for k in range(0, tp.size - 2, 2)]
    if len(cycles) >= 2:
        cycles = cycles[1:]
    if cycles:
        used = np.concatenate([np.arange(i0, i1) for i0, i1 in cycles])
    else:
        used = np.arange(theta.size)

    fit_mask = np.zeros(theta.size, dtype=bool)
    fit_mask[used] = True
    if angle_window_rad is not None:
        try:
            lo, hi = (float(v) for v in angle_window_rad)
        except (TypeError, ValueError):
            raise StiffnessSweepError(f"angle_window_rad = {angle_window_rad!r} is not a pair "
                                      f"of numbers; allowed: (lo, hi) in rad, lo < hi") from None
        if not (math.isfinite(lo) and math.isfinite(hi) and lo < hi):
            raise StiffnessSweepError(f"angle_window_rad = {angle_window_rad!r}; allowed: "
                                      f"finite (lo, hi) in rad with lo < hi")
        fit_mask &= (theta >= lo) & (theta <= hi)
        inside = theta[fit_mask]
        if inside.size < MIN_SAMPLES or np.ptp(inside) < MIN_ANGLE_RANGE_RAD:
            raise StiffnessSweepError(
                f"angle_window_rad = {angle_window_rad!r} holds {inside.size} samples spanning "
                f"{(np.ptp(inside) if inside.size else 0.0):.3g} rad of the sweep "
                f"(angle {theta.min():.4g}..{theta.max():.4g} rad); allowed: a window with at "
                f"least {MIN_SAMPLES} samples and some motion")

    s, a, r2 = _fit(theta[fit_mask], tau[fit_mask])
    k = -s
    theta0 = float(-a / s) if s != 0.0 else math.nan

    def branch(sign: float) -> float:
        m = fit_mask & (direction == sign)
        if m.sum() < 3:
            return math.nan
        bs, _, _ = _fit(theta[m], tau[m])
        return -bs

    if cycles:
        w_d, w_load, amp = [], [], []
        ref0 = theta0 if math.isfinite(theta0) else float(theta[used].mean())
        for i0, i1 in cycles:
            th, ta = theta[i0:i1 + 1], tau[i0:i1 + 1]
            w_d.append(-_loop_work(th, ta))
            w_load.append(_loading_work(th, ta, ref0))
            amp.append(0.5 * float(np.ptp(th)))
        hyst = float(np.mean(w_d))
        amplitude = float(np.mean(amp))
        w_s = 0.5 * k * amplitude ** 2
        loss = hyst / (2.0 * math.pi * w_s) if w_s > 0.0 else math.nan
        load = float(np.mean(w_load))
        frac = hyst / load if load > 0.0 else math.nan
    else:
        hyst = loss = frac = math.nan
        amplitude = 0.5 * span

    return SweepStiffness(
        stiffness_nm_per_rad=k, stiffness_nm_per_deg=k * math.pi / 180.0,
        rest_angle_rad=theta0, r_squared=r2,
        dorsiflexing_stiffness_nm_per_rad=branch(1.0),
        plantarflexing_stiffness_nm_per_rad=branch(-1.0),
        hysteresis_energy_j=hyst, loss_factor=loss, hysteresis_fraction=frac,
        max_torque_nm=float(np.abs(tau[used]).max()), angle_amplitude_rad=amplitude,
        n_cycles=len(cycles), n_samples_fitted=int(fit_mask.sum()))
