"""Orthosis architectures side by side on one gait: ``afo-mj compare``.

Usage::

    afo-mj compare SCENARIO.toml [SCENARIO.toml ...] --out DIR
                   [--set KEY=VALUE ...] [--strides N]

Each SCENARIO is a walking scenario with a ``[device]`` table (``scenarios/gait_assist_*.toml``).
Only its ``assist`` condition is simulated. A scenario with ``[device.variants]`` gives one row
per variant (the variant's dotted overrides on top of ``device.params``) instead of one row for
its base parameters::

    [device.variants.short_hose]
    "hose.length_m" = 0.5
    [device.variants.long_hose]
    "hose.length_m" = 2.5

Rows are labelled ``"<scenario name>"`` or ``"<scenario name>:<variant>"``. Once per distinct
wearer and gait (walker model, reflex set, body and impairment, reference gait, cadence,
strides, controller, worn side) the walk is also run without a device, as the reference of
every row that wearer walks: the human ankle work (``human_ankle_positive_work_no_device_*``)
and, on the muscle walker (``[walker] model = "muscle"``), the wearer's net metabolic rate
without the device. The no-device walk of a scenario does not depend on its device, so this
is the ``no_device`` condition ``afo-mj run`` of the row's own scenario walks.

Options:

* ``--set KEY=VALUE`` (repeatable): a dotted override applied to every scenario, exactly as for
  ``afo-mj run`` (``--set assistance.peak_torque_nm=30``, ``--set device.params.hose.length_m=2``).
* ``--strides N``: simulate N strides and analyse strides ``[max(2, N - 4), N]`` (stride 1 for
  N = 1); an explicit ``--set gait.strides=...``/``gait.analyse_strides=...`` wins over it.

Output, written into DIR all at once (a failing run leaves DIR as it was, and creates nothing):

* ``comparison.csv``: one row per device (variant); SI units in the column names; a value that
  does not exist for a device (a loss its architecture does not have, a device that fell before
  the analysed strides) is empty.
* ``comparison.json``: the rows (``null`` for missing), the column list, the scenarios compared
  (files, names, variants, overrides) and run information (wall time, versions).
* ``comparison.png``: per row a stacked bar of the electrical energy drawn per stride split into
  each named loss, the change of stored energy, the energy regenerated into the battery and the
  net mechanical work delivered to the ankle, so the efficiency chain and where each device
  loses its energy is visible at a glance; beside it torque-tracking RMSE, peak pressure and
  mass.
* ``comparison.md``: the headline table and the per-stride loss table.

The same two tables are printed on stdout. Exit codes: 0 done; 1 a run could not be simulated or
written (nothing written); 2 an invalid scenario or option (a walking scenario without
``[device]``, a bench scenario, a device without the ``assist`` condition, two rows with the same
label; nothing written).

Columns (per stride = per mean analysed right-leg stride; the ledger is the whole run's, scaled
by mean analysed stride time / run duration, as in ``energy_per_stride`` of ``afo-mj run``):

* ``scenario, variant, label, scenario_file, preset, sides, walker_model, fell,
  fall_time_s``: what the row is (``walker_model``: ``torque`` or ``muscle``; ``fall_time_s``
  empty when the walker did not fall).
* ``torque_tracking_rmse_nm, peak_torque_nm``: commanded against delivered device torque; the
  peak is the largest torque delivered outside end-stop contact (``device.peak_torque_nm`` of
  the run's summary, :mod:`afo_mj.metrics.device_flags`).
* ``tracking_poor``, ``end_stop_contact``: the summary's flags (RMS error above a quarter of the
  commanded peak; pistons at their stroke ends), with ``peak_torque_incl_end_stops_nm`` (the
  whole joint's peak, stops included), ``end_stop_contact_time_s_per_stride`` and
  ``end_stop_impulse_nm_s_per_stride``; each raised flag is also a line under the tables.
* ``newton_unconverged``, ``newton_unconverged_steps``: the circuit solver accepted steps whose
  Newton iteration did not converge: the row's figures are not the model's (a line under the
  tables says so).
* ``battery_overload``, ``battery_overload_steps``: the circuit's bus drew more than its
  battery's matched-load power in some steps (the excess booked as energy no part of the model
  supplied): the row's figures are not a real pack's (a line under the tables says so).
* ``device_positive_work_j_per_stride``, ``device_negative_work_j_per_stride``: the device's
  work on the ankle over the analysed strides (delivered; the negative part is what it absorbs).
* ``ankle_positive_work_j_per_stride``, ``ankle_push_off_positive_work_j_per_stride``: the
  whole joint (muscles + device).
* ``electrical_j_per_stride`` (battery energy drawn), ``electrical_regenerated_j_per_stride``
  (energy returned into the battery), ``electrical_net_j_per_stride`` (drawn − regenerated),
  ``hydraulic_j_per_stride`` (net hydraulic work leaving the pump), ``mechanical_j_per_stride``
  (positive mechanical output of the actuator), ``mechanical_net_j_per_stride`` (net mechanical
  work of the actuator on the ankle: positive output − work absorbed from the ankle),
  ``stored_j_per_stride`` (change of stored energy).
* ``mechanical_role``: ``actuator`` when the device adds net work to the ankle (see below),
  ``brake`` when its net mechanical work is negative (it mostly absorbs, e.g. a back-driven pump
  or a damper), ``near_zero`` otherwise (it neither adds nor takes a meaningful net amount).
* ``efficiency_total``: **net** mechanical work delivered to the ankle / electrical energy drawn
  (``mechanical_net / electrical``; regeneration is not credited, it is its own column). Given
  only for an ``actuator``: ``mechanical_net >= NET_WORK_MIN_J_PER_STRIDE`` and
  ``mechanical_net >= NET_WORK_MIN_FRACTION × mechanical`` (it absorbs back at most half of what
  it puts out). Why net and why not for the others: the energy a device absorbs from the ankle
  and gives back later is not assistance, so positive output over drawn energy flatters a
  device that pushes and brakes in turn, and a brake draws little because the walker powers it;
  its "efficiency" would be a ratio of two small numbers describing no assistance (the
  prototype HAFO, back-driven past its 105 deg/s, shows ~48 % on positive output while taking
  ~60 J/stride from the ankle). Empty otherwise, with the reason in ``not_comparable_reason``.
* ``efficiency_electrical_to_hydraulic`` (net hydraulic work leaving the pump / electrical
  drawn), ``efficiency_hydraulic_to_mechanical`` (net mechanical work / net hydraulic work:
  what the lines, valves, seals and leakage let through): stage efficiencies, empty where a
  stage's net energy flows backwards (the ankle drives it).
* ``loss_<name>_j_per_stride`` for every loss any of the devices reports (the union, in ledger
  order; the names come from the device, none is assumed here).
* ``peak_pressure_mpa, fluid_temperature_rise_k, mass_total_kg, mass_at_ankle_kg``.
* ``battery_runtime_h``: the battery's usable energy / the mean electrical power drawn over
  this walk (regeneration not credited), i.e. hours of walking at this gait with this
  assistance. Given only for an ``actuator``, on the same basis for every row; empty for a
  brake or a near-zero device, whose small draw comes from not assisting (the walker powers
  it), so its long runtime is not comparable with an assisting device's (reason in
  ``not_comparable_reason``).
* ``not_comparable_reason``: empty for an actuator; otherwise why ``efficiency_total``,
  ``battery_runtime_h`` and the ranks are empty, with the net and positive mechanical work.
* ``human_ankle_positive_work_j_per_stride``, ``human_ankle_positive_work_no_device_j_per_
  stride``, ``human_ankle_positive_work_change_j_per_stride`` (muscles alone, with and without
  the device); ``assistance_adaptation``: on the torque walker the fraction of the device
  torque by which its written-in rule lowers the wearer's ankle feedforward, which the human
  work change rests on (empty on the muscle walker, whose reflexes respond; the run's
  ``human_response``); ``speed_m_s``; ``energy_balance_error_rel`` (the ledger residual / energy
  drawn).
* ``efficiency_rank``: one ranking of **all** the rows compared (every scenario and variant
  together) by ``efficiency_total``, 1 = best, each rank given once (ties keep the given
  order); empty for a row without an efficiency (not an actuator).
* ``efficiency_rank_in_scenario``: the same ranking restricted to the rows of one scenario file
  (its variants), 1 = best within that file; empty where ``efficiency_rank`` is.
* The wearer's effort, on the muscle walker only (empty for a torque-walker row, whose walker
  has no muscles): ``net_metabolic_{umberger,bhargava}_w_per_kg`` (the net metabolic rate over
  the analysed strides with the device, Umberger 2010 and Bhargava 2004, as in ``afo-mj
  run``'s ``muscle`` block), ``net_metabolic_{umberger,bhargava}_no_device_w_per_kg`` (the
  same wearer's no-device walk) and ``net_metabolic_{umberger,bhargava}_change_pct`` (100 ×
  (with − without) / without: ``comparison_vs_no_device`` of ``afo-mj run``);
  ``no_device_fall_time_s`` (when the wearer's no-device walk fell, else empty).
* ``rank_metabolic``: the muscle-walker rows ranked by ``net_metabolic_umberger_change_pct``,
  1 = the most negative (the largest saving of the wearer's effort); empty for a row that fell,
  whose wearer's no-device walk fell, or without a change (no analysed stride).
  ``rank_battery_energy``: the muscle-walker rows that did not fall ranked by
  ``electrical_j_per_stride``, 1 = the least battery energy drawn per stride. Both rank every
  such row once (ties keep the given order) and are empty for a torque-walker row; the rows
  stay in ``efficiency_rank`` order. A compare may mix the two walkers: the printed tables
  then say which rows have no effort model, and a line names each row whose metabolic change
  rests on a fall or has no analysed stride.

The per-stride ledger closes: ``electrical_net = mechanical_net + stored + sum(loss_*)`` and
``electrical = that + electrical_regenerated`` (to ``energy_balance_error_rel``), so
``efficiency_total = 1 − (losses + stored + regenerated) / electrical``. The rows are ordered by
``efficiency_rank`` (best first), then the rows without one in the order given; the printed
tables and ``comparison.md`` carry the same caveat for every row that is not an actuator.
"""

from __future__ import annotations

import dataclasses
import json
import math
import re
from pathlib import Path

# the classification is the device summary's (afo_mj.metrics.device_flags), re-exported here
from afo_mj.metrics.device_flags import (NET_WORK_MIN_FRACTION, NET_WORK_MIN_J_PER_STRIDE,
                                         mechanical_role)
from afo_mj.scenarios.walk_scenario import strides_overrides  # re-exported: compare --strides

__all__ = ["CompareError", "CompareItem", "Comparison", "FIXED_COLUMNS", "load_compare_items",
           "strides_overrides", "run_comparison", "comparison_row", "order_rows",
           "rank_effort", "metabolic_rankable", "battery_rankable", "METABOLIC_COLUMNS",
           "loss_columns", "all_columns", "mechanical_role", "NET_WORK_MIN_J_PER_STRIDE",
           "NET_WORK_MIN_FRACTION"]


class CompareError(ValueError):
    """An invalid compare request (names the file, the key, the value and what is allowed)."""


@dataclasses.dataclass(frozen=True)
class CompareItem:
    """One row to simulate: a scenario (file) and one of its variants (or its base)."""

    index: int                 # position of the scenario on the command line
    path: str
    scenario: object           # WalkScenario
    reference: object
    cfg: object                # DeviceConfig with params of the variant, conditions ("assist",)
    variant: str               # "" for the base parameters

    @property
    def label(self) -> str:
        return f"{self.scenario.name}:{self.variant}" if self.variant else self.scenario.name


@dataclasses.dataclass
class Comparison:
    rows: list
    columns: list
    scenarios: list
    wall_time_s: float = math.nan


#: the columns every row has, in table order (losses are inserted after ``efficiency_*``)
HEAD_COLUMNS = (
    "scenario", "variant", "label", "scenario_file", "preset", "sides", "walker_model", "fell",
    "fall_time_s", "torque_tracking_rmse_nm", "tracking_poor", "peak_torque_nm",
    "peak_torque_incl_end_stops_nm", "end_stop_contact", "end_stop_contact_time_s_per_stride",
    "end_stop_impulse_nm_s_per_stride", "newton_unconverged", "newton_unconverged_steps",
    "battery_overload", "battery_overload_steps",
    "device_positive_work_j_per_stride",
    "device_negative_work_j_per_stride",
    "ankle_positive_work_j_per_stride", "ankle_push_off_positive_work_j_per_stride",
    "electrical_j_per_stride", "electrical_regenerated_j_per_stride",
    "electrical_net_j_per_stride", "hydraulic_j_per_stride", "mechanical_j_per_stride",
    "mechanical_net_j_per_stride", "stored_j_per_stride", "mechanical_role",
    "efficiency_total", "efficiency_electrical_to_hydraulic",
    "efficiency_hydraulic_to_mechanical")
TAIL_COLUMNS = (
    "peak_pressure_mpa", "fluid_temperature_rise_k", "mass_total_kg", "mass_at_ankle_kg",
    "battery_runtime_h", "not_comparable_reason", "human_ankle_positive_work_j_per_stride",
    "human_ankle_positive_work_no_device_j_per_stride",
    "human_ankle_positive_work_change_j_per_stride", "assistance_adaptation", "speed_m_s",
    "energy_balance_error_rel",
    "efficiency_rank", "efficiency_rank_in_scenario",
    "net_metabolic_umberger_w_per_kg", "net_metabolic_umberger_no_device_w_per_kg",
    "net_metabolic_umberger_change_pct", "net_metabolic_bhargava_w_per_kg",
    "net_metabolic_bhargava_no_device_w_per_kg", "net_metabolic_bhargava_change_pct",
    "no_device_fall_time_s", "rank_metabolic", "rank_battery_energy")
#: the columns of the wearer's effort, given only on the muscle walker (None on the torque one)
METABOLIC_COLUMNS = ("net_metabolic_umberger_w_per_kg",
                     "net_metabolic_umberger_no_device_w_per_kg",
                     "net_metabolic_umberger_change_pct", "net_metabolic_bhargava_w_per_kg",
                     "net_metabolic_bhargava_no_device_w_per_kg",
                     "net_metabolic_bhargava_change_pct")
FIXED_COLUMNS = HEAD_COLUMNS + TAIL_COLUMNS



def loss_column(name: str) -> str:
    """``loss_<name>_j_per_stride`` for a ledger loss name (anything but ``[a-z0-9_]`` → ``_``)."""
    return "loss_" + re.sub(r"[^a-z0-9_]", "_", str(name).lower()) + "_j_per_stride"




def load_compare_items(paths, overrides=(), strides: int | None = None) -> list[CompareItem]:
    """Validate every scenario and expand its variants; raises ScenarioError / CompareError
    before anything is simulated."""
    from afo_mj.scenarios.bench_scenario import is_bench_document
    from afo_mj.scenarios.device_scenario import device_config
    from afo_mj.scenarios.walk_scenario import load_scenario

    if strides is not None and (isinstance(strides, bool) or not isinstance(strides, int)
                                or strides < 1):
        raise CompareError(f"--strides = {strides!r} is not allowed; allowed: an integer >= 1")
    ov = (strides_overrides(strides) if strides is not None else []) + list(overrides or ())
    if not paths:
        raise CompareError("no scenario given; allowed: one or more walking scenario files "
                           "with a [device] table")
    items: list[CompareItem] = []
    seen: dict[str, str] = {}
    for i, path in enumerate(paths):
        try:
            text = Path(path).read_text(encoding="utf-8")
        except (OSError, UnicodeDecodeError):
            text = ""          # load_scenario reports it
        if is_bench_document(text):
            raise CompareError(f"{path}: is a bench scenario ([bench] table) and cannot be "
                               "compared on a gait; allowed: a walking scenario with a "
                               "[device] table")
        scenario = load_scenario(path, overrides=ov)
        cfg = device_config(scenario)
        if cfg is None:
            raise CompareError(f"{path}: device = (none): the walking scenario has no [device] "
                               "table; allowed: a walking scenario with a [device] table, e.g. "
                               "scenarios/gait_assist_hafo.toml")
        # the assist condition's command: a torque profile, impedance rows or (the ideal
        # device) a clutched spring
        commanded = (cfg.profile is not None or cfg.impedance is not None
                     or cfg.spring is not None)
        if "assist" not in cfg.conditions or not commanded:
            raise CompareError(f"{path}: device.conditions = {list(cfg.conditions)!r} is not "
                               "allowed for compare; allowed: a list including 'assist' "
                               "(compare runs the assist condition)")
        reference = scenario.load_reference()
        variants = dict(cfg.variants) or {"": cfg.params}
        for vname, vparams in variants.items():
            item = CompareItem(i, str(path), scenario, reference,
                               dataclasses.replace(cfg, params=vparams, conditions=("assist",)),
                               vname)
            if item.label in seen:
                raise CompareError(f"{path}: row label = {item.label!r} is also the label of a "
                                   f"row of {seen[item.label]}; allowed: distinct scenario "
                                   "names (or variant names)")
            seen[item.label] = str(path)
            items.append(item)
    return items


def _num(x):
    """A float, NaN for None/missing."""
    if x is None:
        return math.nan
    try:
        return float(x)
    except (TypeError, ValueError):
        return math.nan


def _ratio(a, b):
    """``a / b`` for a stage efficiency: NaN unless both are finite, ``b > 0`` and ``a >= 0``
    (a negative net output means the energy flows backwards through that stage: the ankle
    drives the device, and the stage has no efficiency)."""
    a, b = _num(a), _num(b)
    return a / b if math.isfinite(a) and math.isfinite(b) and b > 0 and a >= 0 else math.nan


def _mean(entry):
    return _num(entry.get("mean")) if isinstance(entry, dict) else _num(entry)


def comparison_row(item: CompareItem, block: dict, record=None,
                   human_no_device: float | None = None, no_device: dict | None = None,
                   human_response: dict | None = None) -> dict:
    """One table row from a condition block of
    :func:`afo_mj.experiments.device_walk.condition_summary` (``device``, ``energy``,
    ``energy_per_stride``, ``human``, ``ankle``, ``gait``, and ``muscle`` on the muscle
    walker); nothing device-specific assumed: the losses are whatever
    ``energy_per_stride.losses_j`` names. ``no_device`` is the no-device block of the same
    wearer (its ``human`` work is the reference unless ``human_no_device`` is given, its
    ``muscle`` block the reference of the metabolic change); ``human_response`` the run's
    block of that name (:func:`afo_mj.experiments.device_walk.human_response`)."""
    dev = block.get("device") or {}
    en = block.get("energy") or {}
    eps = block.get("energy_per_stride") or {}
    hum = block.get("human") or {}
    ank = block.get("ankle") or {}
    gait = block.get("gait") or {}
    fall = None
    if record is not None:
        fall = getattr(getattr(record, "events", None), "fall_time_s", None)
    row = {"scenario": item.scenario.name, "variant": item.variant, "label": item.label,
           "scenario_file": item.path, "preset": item.cfg.preset,
           "sides": "+".join(item.cfg.sides),
           "walker_model": getattr(item.scenario, "walker_model", "torque"),
           "fell": fall is not None,
           "fall_time_s": _num(fall)}
    # scale of the whole-run ledger to one mean analysed stride (as energy_per_stride does)
    duration = _num(en.get("run_duration_s"))
    scale = _ratio(eps.get("stride_time_s"), duration)
    elec = _num(eps.get("electrical_in_j"))
    regen = _num(en.get("electrical_regenerated_j")) * scale
    stored_d = en.get("stored_change_j")
    stored = (sum(_num(v) for v in stored_d.values()) if isinstance(stored_d, dict)
              else _num(stored_d)) * scale
    hyd = _num(eps.get("hydraulic_j"))
    mech = _num(eps.get("mechanical_positive_out_j"))
    mech_net = _num(en.get("mechanical_out_j")) * scale
    role, reason = mechanical_role(mech_net, mech)
    actuator = role == "actuator"
    row.update({
        "torque_tracking_rmse_nm": _num(dev.get("torque_tracking_rmse_nm")),
        "tracking_poor": bool(dev.get("tracking_poor")),
        "peak_torque_nm": _num(dev.get("peak_torque_nm")),
        "peak_torque_incl_end_stops_nm": _num(dev.get("peak_torque_incl_end_stops_nm",
                                                      dev.get("peak_torque_nm"))),
        "end_stop_contact": bool(dev.get("end_stop_contact")),
        "end_stop_contact_time_s_per_stride":
            _num((dev.get("end_stop") or {}).get("contact_time_s_per_stride")),
        "end_stop_impulse_nm_s_per_stride":
            _num((dev.get("end_stop") or {}).get("impulse_nm_s_per_stride")),
        "newton_unconverged": bool(dev.get("newton_unconverged")),
        "newton_unconverged_steps": int(dev.get("newton_unconverged_steps") or 0),
        "battery_overload": bool(dev.get("battery_overload")),
        "battery_overload_steps": int(dev.get("battery_overload_steps") or 0),
        "device_positive_work_j_per_stride": _num(dev.get("positive_work_j_per_stride")),
        "device_negative_work_j_per_stride": _num(dev.get("negative_work_j_per_stride")),
        "ankle_positive_work_j_per_stride": _num(ank.get("positive_work_j_per_stride")),
        "ankle_push_off_positive_work_j_per_stride":
            _num(ank.get("push_off_positive_work_j_per_stride")),
        "electrical_j_per_stride": elec,
        "electrical_regenerated_j_per_stride": regen,
        "electrical_net_j_per_stride": elec - regen,
        "hydraulic_j_per_stride": hyd,
        "mechanical_j_per_stride": mech,
        "mechanical_net_j_per_stride": mech_net,
        "stored_j_per_stride": stored,
        "mechanical_role": role,
        # net work delivered / energy drawn, for an actuator only (module docstring)
        "efficiency_total": _ratio(mech_net, elec) if actuator else math.nan,
        "efficiency_electrical_to_hydraulic": _ratio(hyd, elec),
        # net through the stage: the ankle's negative work flows back through the lines,
        # so positive mechanical output over net hydraulic work could exceed 1
        "efficiency_hydraulic_to_mechanical": _ratio(mech_net, hyd),
    })
    for name, v in (eps.get("losses_j") or {}).items():
        row[loss_column(name)] = _num(v)
    human = _num(hum.get("ankle_positive_work_j_per_stride"))
    if human_no_device is None and no_device is not None:
        human_no_device = (no_device.get("human") or {}).get("ankle_positive_work_j_per_stride")
    ref = _num(human_no_device)
    row.update({
        "peak_pressure_mpa": _num(dev.get("peak_pressure_mpa")),
        "fluid_temperature_rise_k": _num(dev.get("fluid_temperature_rise_k")),
        "mass_total_kg": _num(dev.get("mass_total_kg")),
        "mass_at_ankle_kg": _num(dev.get("mass_at_ankle_kg")),
        # same basis for every row (usable energy / mean drawn power); actuators only
        "battery_runtime_h": _num(dev.get("battery_runtime_h")) if actuator else math.nan,
        "not_comparable_reason": reason,
        "human_ankle_positive_work_j_per_stride": human,
        "human_ankle_positive_work_no_device_j_per_stride": ref,
        "human_ankle_positive_work_change_j_per_stride": human - ref,
        # the torque walker's written-in response (None on the muscle walker: no rule)
        "assistance_adaptation": (human_response or {}).get("assistance_adaptation"),
        "speed_m_s": _mean(gait.get("speed_m_s")),
        "energy_balance_error_rel": _num(en.get("balance_error_rel")),
    })
    row.update(_metabolic_columns(row["walker_model"], block, no_device))
    # loss names in the order the devices list them (the ledger's chain order)
    row["_loss_names"] = [loss_column(n) for n in (eps.get("losses_j") or {})]
    return row


def _metabolic_columns(walker_model: str, block: dict, no_device: dict | None) -> dict:
    """The wearer's net metabolic rate with the device and without it (the same wearer's
    no-device walk) and the change in % of the rate without it, by Umberger (2010) and
    Bhargava (2004); None on the torque walker (no muscles), NaN where a walk has no analysed
    stride; ``no_device_fall_time_s`` (NaN when that walk did not fall)."""
    out = {c: None for c in METABOLIC_COLUMNS}
    out["no_device_fall_time_s"] = math.nan
    if no_device is not None:
        out["no_device_fall_time_s"] = _num(no_device.get("fall_time_s"))
    if walker_model != "muscle":
        return out
    mine = block.get("muscle") or {}
    base = (no_device or {}).get("muscle") or {}
    for model in ("umberger", "bhargava"):
        key = f"net_metabolic_{model}_w_per_kg"
        v, b = _num(mine.get(key)), _num(base.get(key))
        out[key] = v
        out[f"net_metabolic_{model}_no_device_w_per_kg"] = b
        out[f"net_metabolic_{model}_change_pct"] = (100.0 * (v - b) / b
                                                    if math.isfinite(v) and math.isfinite(b)
                                                    and b != 0 else math.nan)
    return out


def loss_columns(rows) -> list[str]:
    """Union of the rows' loss columns, first-seen order (each device's ledger order)."""
    out: list[str] = []
    for r in rows:
        for c in r.get("_loss_names") or [k for k in r if k.startswith("loss_")]:
            if c not in out:
                out.append(c)
    return out


def all_columns(rows) -> list[str]:
    return list(HEAD_COLUMNS) + loss_columns(rows) + list(TAIL_COLUMNS)


def order_rows(rows, group_key=lambda r: r["scenario_file"]) -> list[dict]:
    """All rows ranked together by ``efficiency_total`` (best first), then the rows without one
    in the given order; sets ``efficiency_rank`` (1 = best of all rows compared, each rank once,
    ties in the given order) and ``efficiency_rank_in_scenario`` (1 = best of the rows with the
    same ``group_key``, i.e. of one scenario file); both ``None`` for a row without an
    efficiency."""
    rows = list(rows)
    ranked = sorted((r for r in rows if math.isfinite(_num(r.get("efficiency_total")))),
                    key=lambda r: -_num(r.get("efficiency_total")))   # stable: ties keep order
    unranked = [r for r in rows if not math.isfinite(_num(r.get("efficiency_total")))]
    in_group: dict = {}
    for rank, r in enumerate(ranked, start=1):
        r["efficiency_rank"] = rank
        g = group_key(r)
        in_group[g] = in_group.get(g, 0) + 1
        r["efficiency_rank_in_scenario"] = in_group[g]
    for r in unranked:
        r["efficiency_rank"] = None
        r["efficiency_rank_in_scenario"] = None
    rank_effort(rows)
    return ranked + unranked


def _walked_through(r) -> bool:
    """The row's walk did not fall (a missing ``fell`` counts as no fall)."""
    return not r.get("fell")


def metabolic_rankable(r) -> bool:
    """A muscle-walker row whose metabolic change can be ranked: a finite Umberger change,
    and neither its walk nor its wearer's no-device walk fell."""
    return (r.get("walker_model") == "muscle" and _walked_through(r)
            and math.isfinite(_num(r.get("net_metabolic_umberger_change_pct")))
            and not math.isfinite(_num(r.get("no_device_fall_time_s"))))


def battery_rankable(r) -> bool:
    """A muscle-walker row whose walk did not fall, with a finite energy drawn per stride."""
    return (r.get("walker_model") == "muscle" and _walked_through(r)
            and math.isfinite(_num(r.get("electrical_j_per_stride"))))


def rank_effort(rows) -> None:
    """Set ``rank_metabolic`` (1 = the most negative change of the wearer's net metabolic
    rate, Umberger, against the same wearer without a device) and ``rank_battery_energy``
    (1 = the least electrical energy drawn per stride) over the muscle-walker rows
    (:func:`metabolic_rankable`, :func:`battery_rankable`); each rank given once, ties in the
    given order; None for the other rows (a torque-walker row has no effort model)."""
    for col, ok, key in (
            ("rank_metabolic", metabolic_rankable,
             lambda r: _num(r.get("net_metabolic_umberger_change_pct"))),
            ("rank_battery_energy", battery_rankable,
             lambda r: _num(r.get("electrical_j_per_stride")))):
        for r in rows:
            r[col] = None
        for rank, r in enumerate(sorted((r for r in rows if ok(r)), key=key), start=1):
            r[col] = rank


def _walker_gait_key(item: CompareItem) -> str:
    """What makes two no-device walks identical (walker, gait, controller, side)."""
    d = item.scenario.as_dict()
    for k in ("name", "description", "file"):
        d.pop(k, None)
    d["side"] = item.cfg.sides[0]
    return json.dumps(d, sort_keys=True, default=str)


def run_comparison(items, progress=None, human_reference: bool = True,
                   keep_runs: list | None = None) -> Comparison:
    """Simulate every item's assist condition (and the no-device reference once per walker/
    gait); raises what :func:`run_device_scenario` raises (WalkNumericsError,
    FloatingPointError) on a numerics failure. ``keep_runs``, when a list, receives
    ``(label, record, device)`` of every item's assist run (for a recording)."""
    import time

    from afo_mj.experiments.device_walk import run_device_scenario

    t0 = time.perf_counter()
    # the no-device walk of each distinct wearer and gait (the key holds the walker model,
    # reflex set, body and impairment): its human ankle work and, on the muscle walker, its
    # net metabolic rate are the reference of every row worn by that wearer
    no_device_walks: dict[str, dict] = {}
    rows = []
    for item in items:
        ref_block = None
        if human_reference:
            key = _walker_gait_key(item)
            if key not in no_device_walks:
                if progress:
                    progress(f"{item.scenario.name}: no_device (human reference)")
                cfg0 = dataclasses.replace(item.cfg, conditions=("no_device",))
                s0, _ = run_device_scenario(item.scenario, item.reference, cfg0)
                no_device_walks[key] = s0["device_conditions"]["no_device"]
            ref_block = no_device_walks[key]
        if progress:
            progress(f"{item.label}: assist")
        summary, results = run_device_scenario(item.scenario, item.reference, item.cfg)
        rec = results["assist"][0]
        if keep_runs is not None:
            keep_runs.append((item.label, rec, results["assist"][2]))
        rows.append(comparison_row(item, summary["device_conditions"]["assist"], rec,
                                   None if ref_block is not None else math.nan,
                                   no_device=ref_block,
                                   human_response=summary.get("human_response")))
    columns = all_columns(rows)     # loss columns in the order the scenarios were given
    rows = order_rows(rows)
    scenarios = []
    for item in items:
        if scenarios and scenarios[-1]["index"] == item.index:
            if item.variant:
                scenarios[-1]["variants"].append(item.variant)
            continue
        scenarios.append({"index": item.index, "file": item.path, "name": item.scenario.name,
                          "preset": item.cfg.preset, "sides": list(item.cfg.sides),
                          "walker_model": getattr(item.scenario, "walker_model", "torque"),
                          "strides": item.scenario.strides,
                          "analyse_strides": list(item.scenario.analyse_strides),
                          "device": _plain(item.scenario.device),
                          "assistance": _plain(item.scenario.assistance),
                          "variants": [item.variant] if item.variant else []})
    return Comparison(rows, columns, scenarios, time.perf_counter() - t0)


def _plain(m):
    """A mapping (possibly read-only, nested) as plain dicts."""
    if hasattr(m, "items"):
        return {str(k): _plain(v) for k, v in m.items()}
    if isinstance(m, (list, tuple)):
        return [_plain(v) for v in m]
    return m
