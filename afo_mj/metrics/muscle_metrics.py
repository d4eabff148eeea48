"""What a muscle-driven walk did, muscle by muscle: metabolic rates, activations and EMG timing.

Works on a :class:`afo_mj.gait.muscle_walk.MuscleWalk` (its per-step, per-side, per-muscle
arrays and its gait record). Over a window of whole right strides:

* per muscle (both legs' mean): mean metabolic rate by Umberger (2010) and by Bhargava et al.
  (2004) (:mod:`afo_mj.human.metabolics`), mean and peak activation, peak tendon force;
* whole body: net metabolic rate (the muscles' sum, W/kg; the basal 1.2 W/kg left out) and
  the net cost of transport (J/(kg m)) by both models;
* the right leg's soleus, gastrocnemius and tibialis anterior on/off timing against Perry &
  Burnfield's EMG (:mod:`afo_mj.metrics.muscle_timing`);
* :func:`muscle_cycle_table`: the right leg's excitation, activation, force and metabolic
  rate per muscle over the cycle (mean of the strides, 100 points), for a CSV.
"""

from __future__ import annotations

import numpy as np

from afo_mj.metrics.muscle_timing import PERRY_ON_PCT, cycle_average, timing_agreement

__all__ = ["muscle_summary", "muscle_cycle_table", "muscle_signals"]


def _window(walk, first_hs_s: float, last_hs_s: float):
    r = walk.record
    sel = (r.time_s > first_hs_s) & (r.time_s <= last_hs_s)
    if sel.sum() < 2:
        raise ValueError(f"muscle summary: the window {first_hs_s} … {last_hs_s} s holds no "
                         "samples")
    return sel


def muscle_summary(walk, first_hs_s: float, last_hs_s: float) -> dict:
    """The muscle block of a run summary over ``[first_hs_s, last_hs_s]`` (two right heel
    strikes; module docstring)."""
    r = walk.record
    sel = _window(walk, first_hs_s, last_hs_s)
    m = r.body_mass_kg
    dist = float(r.pelvis_position_m[sel][-1, 0] - r.pelvis_position_m[sel][0, 0])
    span = last_hs_s - first_hs_s
    out = {"window_s": [first_hs_s, last_hs_s], "muscles": {}}
    for model, arr in (("umberger", walk.metabolic_umberger_w),
                       ("bhargava", walk.metabolic_bhargava_w)):
        rate = float(arr[sel].sum(axis=(1, 2)).mean()) / m
        out[f"net_metabolic_{model}_w_per_kg"] = rate
        out[f"net_cost_of_transport_{model}_j_per_kg_m"] = (rate * span / dist if dist > 0
                                                            else None)
    for i, name in enumerate(walk.muscles):
        out["muscles"][name] = {
            "metabolic_umberger_w": float(walk.metabolic_umberger_w[sel, :, i].mean()),
            "metabolic_bhargava_w": float(walk.metabolic_bhargava_w[sel, :, i].mean()),
            "mean_activation": float(walk.activation[sel, :, i].mean()),
            "peak_activation": float(walk.activation[sel, :, i].max()),
            "peak_force_n": float(walk.force_n[sel, :, i].max())}
    hs = [h for h in r.events.heel_strikes_s[0] if first_hs_s - 1e-9 <= h <= last_hs_s + 1e-9]
    timing = {}
    if len(hs) >= 2:
        for name, ref in PERRY_ON_PCT.items():
            avg = cycle_average(walk.excitation[:, 0, walk.muscles.index(name)], r.time_s, hs)
            t = timing_agreement(avg, ref)
            timing[name] = {"agreement": t["agreement"], "on_pct": t["on_pct"],
                            "perry_on_pct": list(ref)}
    out["emg_timing_right"] = timing
    return out


def muscle_cycle_table(walk, heel_strikes_s, n: int = 100) -> tuple[list[str], np.ndarray]:
    """``(header, rows)``: phase (%) then, per muscle of the right leg, the stride-mean
    excitation, activation, tendon force (N), fibre power (W, ``F × (−v_CE)``: + while the
    fibres shorten, the force being the tendon's, which the CE carries in series) and Umberger
    metabolic rate (W) on ``n`` points."""
    r = walk.record
    cols, header = [100.0 * np.arange(n) / n], ["phase_pct"]
    power = -walk.force_n * walk.ce_velocity_m_s
    for i, name in enumerate(walk.muscles):
        for label, arr in (("excitation", walk.excitation), ("activation", walk.activation),
                           ("force_n", walk.force_n), ("power_w", power),
                           ("metabolic_w", walk.metabolic_umberger_w)):
            cols.append(cycle_average(arr[:, 0, i], r.time_s, heel_strikes_s, n))
            header.append(f"{name}.{label}")
    return header, np.column_stack(cols)


def muscle_signals(walk) -> dict:
    """Per-sample signals of a muscle walk for a recording: ``{path: (values, unit, label)}``
    with each side's and muscle's activation, tendon force and Umberger metabolic rate, and
    the whole body's net metabolic rate by both models (W/kg)."""
    from afo_mj.human.metabolics import basal_rate_w
    m = walk.record.body_mass_kg
    out = {}
    for s, side in enumerate(("right", "left")):
        for i, name in enumerate(walk.muscles):
            out[f"muscle_activation/{name}/{side}"] = (walk.activation[:, s, i], "1",
                                                       f"{name} activation {side}")
            out[f"muscle_force_n/{name}/{side}"] = (walk.force_n[:, s, i], "N",
                                                    f"{name} force {side}")
            out[f"muscle_metabolic_w/{name}/{side}"] = (walk.metabolic_umberger_w[:, s, i],
                                                        "W", f"{name} metabolic {side}")
    basal = basal_rate_w(m)
    for model in ("umberger", "bhargava"):
        out[f"metabolic_w_per_kg/{model}"] = ((walk.metabolic_rate_w(model) - basal) / m,
                                              "W/kg", f"net metabolic rate ({model})")
    return out
