"""Assistance on the muscle-driven walker: what a device does to the wearer's metabolic cost.

No rule of the wearer's response is written in: the device's torque, its worn masses and (for
a worn circuit) its hydraulic dynamics act on the skeleton, and the reflex controller and muscles
(:mod:`afo_mj.gait.muscle_walk`) respond. A condition is an :class:`Assistance`:

* ``none`` — the walker alone;
* ``worn_mass`` — the worn masses of the ``hafo`` condition's device
  (:meth:`afo_mj.devices.hafo.HafoDevice.worn_masses`, 3.58 kg of which 0.97 kg at the ankle
  for ``hafo_gait``) and no torque;
* ``zhang`` — an ideal ankle torque following the profile of Zhang et al. (2017, *Science*
  356:1280; :func:`afo_mj.control.assistance.zhang_profile`, published timing: peak at
  52.9 %, rise 26.2 %, fall 9.8 % of the stride) against the gait phase estimated from each
  foot's stance (:func:`afo_mj.control.assistance.phase_update`), only while that foot is in
  stance, massless;
* ``clutched_spring`` — an ideal, massless clutched spring in parallel with the calf, as in
  Collins, Wiggin & Sawicki (2015, *Nature* 522:212): the clutch engages once per stance,
  at ``spring_engage_phase`` of the stride (foot flat), with the spring slack at the ankle
  angle of that moment; it then resists dorsiflexion past that angle with
  ``spring_nm_per_rad`` and returns the energy in push-off, and opens at toe off or at
  ``spring_release_phase``, free in swing (both ideal conditions are the command of
  :class:`afo_mj.devices.ideal.IdealDevice`, which scenarios wear as ``preset = "ideal"``);
* ``hafo`` — a circuit device worn on the right ankle, its pump or valves, hoses, cylinders
  and controller stepped with MuJoCo, commanding the Zhang profile of
  ``hafo_peak_torque_nm``; its ledger (every loss) comes with the result. The device is the
  preset ``hafo_preset``: the HAFO ``hafo_gait`` by default, or any HAFO or valve preset
  (:func:`afo_mj.devices.registry.preset_names`),
  built as ``afo-mj run`` builds a scenario's ``assist`` condition with ``[device] preset =
  hafo_preset, sides = ["right"]`` (:func:`afo_mj.experiments.device_walk.preset_config`,
  :func:`~afo_mj.experiments.device_walk.make_device`). The kind and field names keep the
  HAFO's (stored reflex sets name them).

The wearer is reported with the controller it walked with before (*naive*: the same reflex
set) or re-optimised with the device worn (*adapted*: a warm-started CMA-ES run of
:func:`afo_mj.studies.gait_optimization.optimize_gait` with this condition in its
objective). :func:`assistance_summary` gives the metabolic rate (Umberger 2010 and Bhargava
2004, net of the 1.2 W/kg basal rate), speed, stride, the human's and the device's ankle work
per stride and the push-off power.
"""

from __future__ import annotations

import dataclasses
import math
import re

import numpy as np

from afo_mj.control import assistance as asst
from afo_mj.devices.ideal import ClutchedSpring, IdealDevice
from afo_mj.devices.registry import device_entry, preset_names
from afo_mj.experiments.device_walk import make_device, preset_config
from afo_mj.gait.muscle_walk import MuscleWalk, run_muscle_walk
from afo_mj.human.metabolics import basal_rate_w
from afo_mj.human.walker import WalkerParams

__all__ = ["KINDS", "DEVICE_PRESETS", "Assistance", "ideal_device", "assistance_device",
           "assistance_walk", "assistance_summary", "assistance_comparison", "battery_use"]

#: the conditions :class:`Assistance` knows
KINDS = ("none", "worn_mass", "zhang", "clutched_spring", "hafo")
#: Zhang et al. (2017) published timing (% of stride): peak, rise, fall
ZHANG_TIMING_PCT = (52.9, 26.2, 9.8)
SIDE_INDEX = {"right": 0, "left": 1}
#: the presets the ``hafo`` condition can wear: every registered preset device
#: (:func:`afo_mj.devices.registry.preset_names`)
DEVICE_PRESETS = preset_names()


@dataclasses.dataclass(frozen=True)
class Assistance:
    """One assistance condition (module docstring). ``sides``: the assisted ankles of the
    ideal conditions (the ``hafo`` condition's device is worn on the right); ``hafo_preset``:
    that device's preset (:data:`DEVICE_PRESETS`, HAFO or valve); ``ramp_strides``: the ideal
    torque's linear ramp-on over the first strides the phase estimator has measured.

    Defaults: Zhang peak 0.5 N·m/kg (a moderate torque chosen here, about a third of the
    1.6 N·m/kg biological ankle moment peak); spring 180 N·m/rad engaged at 10 % of the
    stride (foot flat) and released by 62 % or at toe off (Collins et al. 2015 found the
    metabolic minimum at their medium spring of about this stiffness); HAFO peak 40 N·m
    (``scenarios/gait_assist_hafo.toml``).
    """

    kind: str = "none"
    sides: tuple = ("right", "left")
    zhang_peak_nm_per_kg: float = 0.5
    spring_nm_per_rad: float = 180.0
    spring_engage_phase: float = 0.10
    spring_release_phase: float = 0.62
    #: the engaged clutch takes up slack (:class:`afo_mj.devices.ideal.ClutchedSpring`)
    spring_ratchet: bool = False
    hafo_peak_torque_nm: float = 40.0
    hafo_preset: str = "hafo_gait"
    #: ideal conditions: the torque rises linearly over this many strides of the phase
    #: estimator (as devices ramp assistance on), 0 = at once
    ramp_strides: int = 0
    #: the Zhang profile's timing ``(peak, rise, fall)`` in % of the stride, of the ``zhang``
    #: torque and of the ``hafo`` command (:func:`afo_mj.control.assistance.zhang_profile`);
    #: default the published generic timing :data:`ZHANG_TIMING_PCT`. Left out of the repr
    #: at that default, so that the optimiser's state key (:func:`afo_mj.studies.
    #: gait_optimization.optimize_gait`) of the searches saved before it stays the same
    zhang_timing_pct: tuple = ZHANG_TIMING_PCT

    def __repr__(self) -> str:
        shown = [f for f in dataclasses.fields(self)
                 if f.repr and not (f.name == "zhang_timing_pct"
                                    and self.zhang_timing_pct == ZHANG_TIMING_PCT)]
        return (f"{type(self).__qualname__}("
                + ", ".join(f"{f.name}={getattr(self, f.name)!r}" for f in shown) + ")")

    def __post_init__(self):
        if self.kind not in KINDS:
            raise ValueError(f"assistance.kind = {self.kind!r}; allowed: {', '.join(KINDS)}")
        sides = tuple(self.sides)
        if not sides or len(set(sides)) != len(sides) or any(s not in SIDE_INDEX
                                                             for s in sides):
            raise ValueError(f"assistance.sides = {list(self.sides)!r}; allowed: a non-empty "
                             "subset of ['right', 'left']")
        object.__setattr__(self, "sides", sides)
        if self.hafo_preset not in DEVICE_PRESETS:
            raise ValueError(f"assistance.hafo_preset = {self.hafo_preset!r}; allowed: "
                             f"{', '.join(DEVICE_PRESETS)}")
        if not isinstance(self.spring_ratchet, bool):
            raise ValueError(f"assistance.spring_ratchet = {self.spring_ratchet!r}; allowed: "
                             "True, False")
        if isinstance(self.ramp_strides, bool) or not isinstance(self.ramp_strides, int) \
                or not 0 <= self.ramp_strides <= 100:
            raise ValueError(f"assistance.ramp_strides = {self.ramp_strides!r}; allowed: an "
                             "integer 0 … 100")
        timing = self.zhang_timing_pct
        if isinstance(timing, (str, bytes)) or not hasattr(timing, "__len__") \
                or len(timing) != 3 or any(isinstance(v, bool) or not isinstance(v, (int, float))
                                           or not math.isfinite(v) for v in timing):
            raise ValueError(f"assistance.zhang_timing_pct = {timing!r}; allowed: three "
                             "finite numbers (peak, rise, fall), % of the stride")
        timing = tuple(float(v) for v in timing)
        object.__setattr__(self, "zhang_timing_pct", timing)
        try:
            asst.zhang_profile(1.0, *timing, n=3)
        except asst.ParameterError as exc:
            raise ValueError(f"assistance.zhang_timing_pct = {list(timing)!r}: {exc}") from None
        for name, lo, hi in (("zhang_peak_nm_per_kg", 0.0, 3.0),
                             ("spring_nm_per_rad", 0.0, 2000.0),
                             ("spring_engage_phase", 0.0, 0.5),
                             ("spring_release_phase", 0.3, 1.0),
                             ("hafo_peak_torque_nm", 0.0, 80.0)):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not lo <= v <= hi:
                raise ValueError(f"assistance.{name} = {v!r}; allowed: {lo:g} … {hi:g}")

    @property
    def label(self) -> str:
        """A short name for tables."""
        timing = ("" if self.zhang_timing_pct == ZHANG_TIMING_PCT else
                  ", peak {:.1f} %, rise {:.1f} %, fall {:.1f} %".format(*self.zhang_timing_pct))
        if self.kind == "zhang":
            return f"zhang {self.zhang_peak_nm_per_kg:g} N·m/kg{timing}"
        if self.kind == "clutched_spring":
            return (f"clutched spring {self.spring_nm_per_rad:g} N·m/rad"
                    + (", ratchet" if self.spring_ratchet else ""))
        if self.kind == "hafo":
            name = device_entry(self.hafo_preset).label
            return f"{name} ({self.hafo_preset}, {self.hafo_peak_torque_nm:g} N·m{timing})"
        return self.kind


def ideal_device(a: Assistance, body_mass_kg: float, timestep_s: float = 1e-3,
                 max_steps: int = 0) -> IdealDevice:
    """The device of a ``zhang`` or ``clutched_spring`` condition: an
    :class:`~afo_mj.devices.ideal.IdealDevice` (massless; gait phase estimated from stance as
    a device would estimate it) on ``a.sides`` commanding the Zhang profile of
    ``a.zhang_peak_nm_per_kg`` × ``body_mass_kg`` or the clutched spring, with ``a``'s ramp;
    it delivers exactly what it commands, stepped in the muscle walk's compiled loop."""
    if a.kind not in ("zhang", "clutched_spring"):
        raise ValueError(f"ideal_device: assistance.kind = {a.kind!r}; allowed: 'zhang', "
                         "'clutched_spring'")
    spring = (ClutchedSpring(a.spring_nm_per_rad, a.spring_engage_phase,
                             a.spring_release_phase, a.spring_ratchet)
              if a.kind == "clutched_spring" else None)
    profile = (asst.zhang_profile(a.zhang_peak_nm_per_kg * body_mass_kg, *a.zhang_timing_pct)
               if a.kind == "zhang" else None)
    return IdealDevice(sides=a.sides, profile=profile, spring=spring,
                       ramp_strides=a.ramp_strides, timestep_s=timestep_s,
                       max_steps=max_steps)


def assistance_device(a: Assistance, timestep_s: float, max_steps: int = 0):
    """The device of a ``hafo`` condition (module docstring): the preset ``a.hafo_preset`` on
    the right ankle commanding the Zhang profile of ``a.hafo_peak_torque_nm``, built as
    ``afo-mj run`` builds an ``assist`` condition (a log of ``max_steps`` steps)."""
    cfg = preset_config(a.hafo_preset, ("right",),
                        asst.zhang_profile(a.hafo_peak_torque_nm, *a.zhang_timing_pct),
                        key="assistance.hafo_preset")
    return make_device(cfg, "assist", timestep_s, max_steps)


#: the former name of :func:`assistance_device` (the HAFO was its only device)
hafo_device = assistance_device


def assistance_walk(assistance: Assistance, walker: WalkerParams | None = None,
                    params: np.ndarray | None = None, duration_s: float = 12.0,
                    max_force_scale: dict | None = None, worn_masses=()):
    """Walk the muscle walker under one condition (with ``worn_masses`` besides the
    device's). Returns ``(walk, device)`` (the :class:`~afo_mj.gait.muscle_walk.MuscleWalk`
    and the ``hafo`` condition's device, or None). The ideal conditions wear
    :func:`ideal_device` (no log kept; not returned: an ideal source has no losses to report)."""
    w = walker or WalkerParams()
    a = assistance
    extra = tuple(worn_masses)
    if a.kind == "none":
        return run_muscle_walk(w, params, duration_s, worn_masses=extra,
                               max_force_scale=max_force_scale), None
    if a.kind in ("zhang", "clutched_spring"):
        return run_muscle_walk(w, params, duration_s, worn_masses=extra,
                               max_force_scale=max_force_scale,
                               device=ideal_device(a, w.body_mass_kg, w.timestep_s)), None
    dev = assistance_device(a, w.timestep_s, int(duration_s / w.timestep_s) + 4)
    worn = tuple(dev.worn_masses()) + extra
    if a.kind == "worn_mass":
        return run_muscle_walk(w, params, duration_s, worn_masses=worn,
                               max_force_scale=max_force_scale), None
    walk = run_muscle_walk(w, params, duration_s, worn_masses=worn, device=dev,
                           max_force_scale=max_force_scale)
    return walk, dev


def assistance_summary(walk: MuscleWalk, settle_s: float = 3.0, device=None) -> dict:
    """What a condition did, over the whole strides of the right leg after ``settle_s``:
    ``fell`` (time or None), ``strides``, ``speed_m_s``, ``stride_s``, net metabolic rate
    (W/kg, Umberger 2010 and Bhargava 2004, basal 1.2 W/kg left out) and net cost of
    transport (J/(kg m), Umberger), per stride on the right ankle the muscles' positive and
    net work and the device's net work (J; + into the body), the peak of the right ankle
    power of muscles plus device averaged over the strides (W/kg, 101 phase points), and
    with a worn device its ledger (input, mechanical output, every loss). Rates are means over the
    scored strides; the cost of transport is given by both metabolic models."""
    r = walk.record
    out = {"fell_s": r.events.fall_time_s, "duration_s": float(r.time_s[-1])}
    hs = np.asarray(r.events.heel_strikes_s[0], float)
    hs = hs[hs > settle_s]
    out["strides"] = max(len(hs) - 1, 0)
    if len(hs) < 3:
        return out
    t0, t1 = float(hs[0]), float(hs[-1])
    sel = (r.time_s > t0) & (r.time_s <= t1)
    dt = r.sample_period_s
    m = r.body_mass_kg
    dist = float(r.pelvis_position_m[sel][-1, 0] - r.pelvis_position_m[sel][0, 0])
    n_str = len(hs) - 1
    basal = basal_rate_w(m)
    rates = {}
    for model in ("umberger", "bhargava"):
        rate = walk.metabolic_rate_w(model)[sel] - basal
        rates[model] = float(rate.mean()) / m
    v_ank = r.joint_velocity_rad_s[sel, 0, 2]
    p_musc = r.joint_moment_nm[sel, 0, 2] * v_ank
    p_dev = r.device_moment_nm[sel, 0] * v_ank
    # the push-off peak of the stride-averaged power (as gait analysis reports it): the
    # per-sample maximum caught contact transients of a single step
    t_sel = r.time_s[sel]
    ph = np.linspace(0.0, 1.0, 101)
    mean_power = np.zeros_like(ph)
    for a, b in zip(hs[:-1], hs[1:]):
        mean_power += np.interp(a + ph * (b - a), t_sel, p_musc + p_dev) / n_str
    out.update({
        "speed_m_s": dist / (t1 - t0), "stride_s": (t1 - t0) / n_str,
        "net_metabolic_w_per_kg": rates["umberger"],
        "net_metabolic_bhargava_w_per_kg": rates["bhargava"],
        "net_cost_of_transport_j_per_kg_m": rates["umberger"] * (t1 - t0) / dist
        if dist > 0 else math.inf,
        "net_cost_of_transport_bhargava_j_per_kg_m": rates["bhargava"] * (t1 - t0) / dist
        if dist > 0 else math.inf,
        "ankle_muscle_positive_work_j_per_stride": float(np.clip(p_musc, 0, None).sum() * dt
                                                         / n_str),
        "ankle_muscle_net_work_j_per_stride": float(p_musc.sum() * dt / n_str),
        "ankle_device_net_work_j_per_stride": float(p_dev.sum() * dt / n_str),
        "ankle_peak_power_w_per_kg": float(mean_power.max() / m),
    })
    if device is not None:
        led = device.ledger(0)
        out["device_ledger"] = {"input_j": led["input_j"],
                                "mechanical_out_j": led["mechanical_out_j"],
                                "losses_j": led["losses_j"],
                                "balance_error_rel": led["balance_error_rel"]}
    return out


def battery_use(walk: MuscleWalk, device, settle_s: float = 3.0) -> dict | None:
    """The energy a worn circuit device took from its battery over the strides
    :func:`assistance_summary` scores (the right leg's whole strides after ``settle_s``), or
    None with fewer than three scored heel strikes: ``battery_j`` (J), per stride, as mean
    electrical power (W) and per kg and metre walked (``battery_cost_of_transport_j_per_kg_m``,
    the units of the net metabolic cost of transport).

    The pack is a Thevenin source (:class:`afo_mj.circuits.components.Battery`: terminal
    voltage ``V = V_oc − R I``), so the chemical power it gives up is ``V_oc I = V I + R I²``
    (the ledger's input: net, regeneration counted back). It is summed here over the device
    log's steps in the window, ``Σ h (V_bus I + R I²)``, with the logged bus voltage and
    battery current; the log holds one row per step while the ledger integrates every
    sub-step with the voltage of that instant, so the sum differs from the ledger by a few
    parts per thousand (measured on the shipped HAFO wearer against the ledger's input of a
    walk stopped at the window's last heel strike less that of one stopped at its first:
    −0.3 % over the strides of a 16 s walk, −0.5 % of a 6 s walk).
    ValueError for a device with no battery in its log."""
    params = getattr(getattr(device, "spec", None), "params", None)
    battery = getattr(params, "battery", None)
    log = getattr(device, "log", None)
    if battery is None or log is None or "battery_current_a" not in log.FIELDS:
        name = getattr(getattr(device, "spec", None), "name", type(device).__name__)
        raise ValueError(f"battery_use: device {name!r} has no battery in its log; allowed: a "
                         "circuit device with a battery, walked with its log")
    r = walk.record
    hs = np.asarray(r.events.heel_strikes_s[0], float)
    hs = hs[hs > settle_s]
    if len(hs) < 3:
        return None
    t0, t1 = float(hs[0]), float(hs[-1])
    n = log.n
    t = log.data[:n, log.FIELDS.index("time_s"), 0]
    v = log.data[:n, log.FIELDS.index("bus_voltage_v"), 0]
    i = log.data[:n, log.FIELDS.index("battery_current_a"), 0]
    sel = (t > t0) & (t <= t1)
    e = float(np.sum(device.timestep_s * (v[sel] * i[sel]
                                          + battery.internal_resistance_ohm * i[sel] ** 2)))
    sel_r = (r.time_s > t0) & (r.time_s <= t1)
    dist = float(r.pelvis_position_m[sel_r][-1, 0] - r.pelvis_position_m[sel_r][0, 0])
    n_str = len(hs) - 1
    return {"battery_j": e, "strides": n_str, "battery_j_per_stride": e / n_str,
            "electrical_power_w": e / (t1 - t0),
            "battery_cost_of_transport_j_per_kg_m": e / (r.body_mass_kg * dist)
            if dist > 0 else math.inf}


def assistance_comparison(params: np.ndarray, conditions=None, walker: WalkerParams | None = None,
                          duration_s: float = 20.0, settle_s: float = 3.0,
                          max_force_scale: dict | None = None, workers: int | None = None
                          ) -> list[dict]:
    """Every condition (default: one of each kind) walked by the same reflex set (the naive
    wearer), in parallel; per condition its :func:`assistance_summary` with ``label``, and,
    where both it and the first condition walked, ``metabolic_change_pct``: the change of the
    net metabolic rate (Umberger) against the first condition. A walk that diverges is a row
    with ``diverged`` true, ``fell_s`` its time and the error."""
    from afo_mj.experiments.batch import run_batch
    conds = list(conditions) if conditions is not None else [Assistance(k) for k in KINDS]
    items = [(a, walker, params, duration_s, settle_s, max_force_scale) for a in conds]
    res = run_batch(_compare_one, items, workers)
    rows = []
    for a, r in zip(conds, res):
        if not r.ok:
            raise RuntimeError(f"assistance {a.label}: {r.error}")
        rows.append(dict(r.value, label=a.label, kind=a.kind))
    base = rows[0].get("net_metabolic_w_per_kg")
    for row in rows:
        v = row.get("net_metabolic_w_per_kg")
        if base and v is not None and row["fell_s"] is None and rows[0]["fell_s"] is None:
            row["metabolic_change_pct"] = 100.0 * (v - base) / base
    return rows


def _compare_one(item):
    a, walker, params, duration_s, settle_s, scale = item
    try:
        walk, dev = assistance_walk(a, walker, params, duration_s, max_force_scale=scale)
    except FloatingPointError as exc:
        # a diverged walk is a result of the comparison (reported with its time), not an
        # error that loses the other conditions
        m = re.search(r"t = ([0-9.]+)", str(exc))
        return {"fell_s": float(m.group(1)) if m else 0.0, "diverged": True,
                "error": str(exc), "strides": 0}
    return assistance_summary(walk, settle_s, dev)
