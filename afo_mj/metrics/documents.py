"""Typed result documents of a walk: what ``summary.json`` holds, written from these classes.

* :class:`GaitSummary` -- the gait analysis of one walk
  (:func:`afo_mj.metrics.gait_metrics.analyse_gait`), format ``afo_mj gait summary v1``;
* :class:`FallOutcome` -- what a walk that fell before an analysable stride reports instead;
* :class:`WornCondition` -- one condition of a walk with an orthosis
  (:func:`afo_mj.experiments.device_walk.condition_summary`): gait, the human's and the
  whole ankle's work, the device's figures and its energy per stride and over the run;
* :class:`EnergyLedger` -- a device's energy ledger
  (:meth:`afo_mj.circuits.device.CircuitDevice.ledger`, the ideal source's
  :meth:`~afo_mj.devices.ideal.IdealDevice.ledger`) as one fixed set of keys;
* :class:`WalkSummary` -- the whole ``summary.json`` of ``afo-mj run`` on a walking
  scenario, with or without an orthosis.

Every class is a frozen dataclass with ``to_json()`` and ``from_json()`` (which checks the
format tag, the keys and their kinds: :mod:`afo_mj.metrics.document_base`). The files written
before these classes existed have the same keys and values; ``tests/golden/summary_*.json``
hold such files and the tests compare today's output with them. ``docs/result_documents.md``
is generated from the classes (``tools/result_documents.py``).
"""

from __future__ import annotations

import dataclasses
from typing import ClassVar, Mapping, Sequence

from afo_mj.metrics.document_base import Document, DocumentError, entry

__all__ = ["DocumentError", "StrideStatistic", "GaitReference", "PerLeg", "GaitDefinitions",
           "GaitSummary", "FallOutcome", "HumanAnkleWork", "AnkleJointWork",
           "EndStopContact", "DeviceFigures", "StrideEnergy", "RunEnergy", "WornCondition",
           "EnergyLedger", "HumanResponse", "DeviceWalkPart", "WalkSummary", "BenchSummary",
           "STRIDE_STATISTICS", "SPAN_STATISTICS", "GAIT_FORMAT", "DOCUMENT_CLASSES"]

GAIT_FORMAT = "afo_mj gait summary v1"

#: Every per-cycle scalar of the gait analysis (``{"mean", "sd", "n"}`` over the cycles in
#: ``summary.json``): ``(key, unit, meaning)``; definitions in :mod:`afo_mj.metrics.gait_metrics`.
STRIDE_STATISTICS: tuple[tuple[str, str, str], ...] = (
    ("cycle_time_s", "s", "stride duration T"),
    ("cadence_steps_per_min", "steps/min", "120 / T"),
    ("stride_length_m", "m", "forward pelvis displacement over the cycle"),
    ("speed_m_s", "m/s", "stride length / T"),
    ("stance_fraction", "1", "(toe off - heel strike) / T"),
    ("hip_positive_work_j_per_kg", "J/kg", "hip positive work over the cycle"),
    ("hip_negative_work_j_per_kg", "J/kg", "hip negative work (<= 0)"),
    ("knee_positive_work_j_per_kg", "J/kg", "knee positive work"),
    ("knee_negative_work_j_per_kg", "J/kg", "knee negative work (<= 0)"),
    ("ankle_positive_work_j_per_kg", "J/kg", "ankle (human) positive work"),
    ("ankle_negative_work_j_per_kg", "J/kg", "ankle (human) negative work (<= 0)"),
    ("ankle_push_off_positive_work_j_per_kg", "J/kg", "ankle positive work over 35-70 % "
     "of the cycle (Winter's A2)"),
    ("peak_ankle_power_w_per_kg", "W/kg", "peak ankle power over 35-70 % of the cycle"),
    ("peak_ankle_plantarflexor_moment_nm_per_kg", "N·m/kg", "-min human ankle moment"),
    ("peak_device_plantarflexor_moment_nm_per_kg", "N·m/kg", "-min orthosis moment"),
    ("device_ankle_positive_work_j_per_kg", "J/kg", "orthosis positive work on the ankle"),
    ("device_ankle_negative_work_j_per_kg", "J/kg", "orthosis negative work (<= 0)"),
    ("peak_plantarflexion_40_62_percent_deg", "deg", "-min ankle angle over 40-62 % of the "
     "cycle"),
    ("push_off_peak_plantarflexion_deg", "deg", "the same window ended at toe off"),
    ("peak_plantarflexion_deg", "deg", "-min ankle angle over the cycle"),
    ("swing_peak_dorsiflexion_deg", "deg", "max ankle angle in mid-swing"),
    ("swing_mean_ankle_angle_deg", "deg", "mean ankle angle in mid-swing"),
    ("min_toe_clearance_m", "m", "lowest forefoot sphere height in mid-swing"),
    ("min_heel_clearance_m", "m", "lowest heel sphere height in mid-swing"),
    ("peak_vertical_grf_n_per_kg", "N/kg", "peak vertical ground reaction force"),
    ("residual_force_rms_n", "N", "RMS of the pelvis residual force |F|"),
    ("residual_force_rms_percent_body_weight", "% body weight", "the same in % of m·g"),
    ("residual_moment_rms_nm", "N·m", "RMS of the pelvis residual pitch moment"),
    ("hip_angle_rms_error_deg", "deg", "RMS hip angle error vs the reference"),
    ("hip_angle_within_1sd_fraction", "1", "fraction of the cycle inside reference ± 1 SD "
     "(null: the reference has no SD)"),
    ("hip_moment_rms_error_nm_per_kg", "N·m/kg", "RMS hip moment error vs the reference"),
    ("knee_angle_rms_error_deg", "deg", "RMS knee angle error"),
    ("knee_angle_within_1sd_fraction", "1", "as for the hip"),
    ("knee_moment_rms_error_nm_per_kg", "N·m/kg", "RMS knee moment error"),
    ("ankle_angle_rms_error_deg", "deg", "RMS ankle angle error"),
    ("ankle_angle_within_1sd_fraction", "1", "as for the hip"),
    ("ankle_moment_rms_error_nm_per_kg", "N·m/kg", "RMS ankle moment error"),
)
_STAT_KEYS = tuple(k for k, _, _ in STRIDE_STATISTICS)
#: Statistics that also carry ``over_analysed_span`` (the RMS over the whole analysed span).
SPAN_STATISTICS = ("residual_force_rms_n", "residual_force_rms_percent_body_weight",
                   "residual_moment_rms_nm")


@dataclasses.dataclass(frozen=True)
class StrideStatistic(Document):
    """Mean, sample SD (ddof 1) and count over the finite values of the analysed cycles
    (unit: the metric's)."""

    mean: float | None = entry("number?", "mean (null when n = 0)")
    sd: float | None = entry("number?", "sample standard deviation (null when n < 2)")
    n: int = entry("int", "number of cycles with a finite value")
    over_analysed_span: float | None = entry(
        "number?", "residual metrics only: the RMS over the whole analysed span",
        omit_none=True, default=None)
    #: A residual metric's statistic always has ``over_analysed_span`` (null when NaN).
    spanned: bool = False

    def _body(self) -> dict:
        out = {"mean": self.mean, "sd": self.sd, "n": self.n}
        if self.spanned:
            out["over_analysed_span"] = self.over_analysed_span
        return out

    @classmethod
    def _from_body(cls, data, where):
        spanned = "over_analysed_span" in data
        cls._check_keys(data, where)
        d = super()._from_body(data, where)
        return dataclasses.replace(d, spanned=spanned)


@dataclasses.dataclass(frozen=True)
class GaitReference(Document):
    """The reference gait the walk is compared with."""

    source: str | None = entry("str?", "reference source (e.g. winter, schwartz2008)")
    condition: str | None = entry("str?", "the source's condition (e.g. normal, Free)")
    cycle_time_s: float | None = entry("number?", "the reference's stride time", "s")
    speed_m_s: float | None = entry("number?", "the reference's walking speed", "m/s")


@dataclasses.dataclass(frozen=True)
class PerLeg(Document):
    """One count per leg."""

    right: int = entry("int", "right leg")
    left: int = entry("int", "left leg")


@dataclasses.dataclass(frozen=True)
class GaitDefinitions(Document):
    """The analysis windows and conventions the numbers follow."""

    push_off_window_percent_cycle: tuple = entry("list", "push-off work and peak power "
                                                 "window", "% cycle")
    push_off_angle_window_percent_cycle: tuple = entry("list", "push-off plantarflexion "
                                                       "window", "% cycle")
    mid_swing_window_percent_swing: tuple = entry("list", "mid-swing clearance window",
                                                  "% swing")
    statistics: str = entry("str", "how the statistics are taken")
    signs: str = entry("str", "sign conventions")


@dataclasses.dataclass(frozen=True)
class GaitSummary(Document):
    """The gait analysis of one walk over its analysed strides. In JSON the statistics
    (:data:`STRIDE_STATISTICS`) are top-level keys between ``duration_s`` and
    ``definitions``, each ``{"mean", "sd", "n"}`` (``over_analysed_span`` too for the
    residuals) or null (a ``*_within_1sd_fraction`` against a reference without SD)."""

    FORMAT: ClassVar[str] = GAIT_FORMAT
    TITLE: ClassVar[str] = "gait summary (one walk's analysis)"

    reference: GaitReference | None = entry(GaitReference, "the reference gait (null: none)",
                                            tagged=False, nullable=True)
    body_mass_kg: float = entry("number", "walker's body mass", "kg")
    height_m: float = entry("number", "walker's height", "m")
    strides_requested: tuple | None = entry("list?", "[first, last] analysed strides per leg "
                                            "(1-based, inclusive; null: all)")
    n_cycles_used: int = entry("int", "cycles analysed, both legs pooled")
    n_cycles_per_leg: PerLeg = entry(PerLeg, "cycles analysed per leg", tagged=False)
    completed_strides: int = entry("int", "complete right-leg cycles before the end or fall")
    completed_strides_per_leg: PerLeg = entry(PerLeg, "complete cycles per leg", tagged=False)
    fall_time_s: float | None = entry("number?", "time of the fall (null: no fall)", "s")
    fell: bool = entry("bool", "the walker fell")
    swing_toe_contacts: int = entry("int", "toe contacts during swing, whole run")
    swing_toe_contacts_per_leg: PerLeg = entry(PerLeg, "the same per leg", tagged=False)
    analysed_span_s: tuple = entry("list", "[start, end] of the analysed cycles", "s")
    swing_toe_contacts_in_analysed_span: int = entry("int", "swing toe contacts in that span")
    duration_s: float = entry("number", "simulated duration", "s")
    statistics: Mapping[str, StrideStatistic | None] = dataclasses.field(default_factory=dict)
    definitions: GaitDefinitions | None = entry(GaitDefinitions, "windows and conventions",
                                                tagged=False, default=None)

    def _body(self) -> dict:
        out = {}
        for k, v in super()._body().items():
            if k == "definitions":
                for name in _STAT_KEYS:
                    st = self.statistics.get(name)
                    out[name] = None if st is None else st._body()
            out[k] = v
        return out

    @classmethod
    def _from_body(cls, data, where):
        data = dict(data)
        stats = {}
        for name in _STAT_KEYS:
            if name not in data:
                raise DocumentError(f"{where}: missing statistic {name!r}; required: every "
                                    "key of afo_mj.metrics.documents.STRIDE_STATISTICS")
            v = data.pop(name)
            if v is not None:
                st = StrideStatistic._from_body(v, f"{where}.{name}")
                if st.spanned != (name in SPAN_STATISTICS):
                    raise DocumentError(f"{where}.{name}: over_analysed_span "
                                        f"{'missing' if not st.spanned else 'not allowed'}; "
                                        f"it belongs to {', '.join(SPAN_STATISTICS)} only")
                v = st
            stats[name] = v
        doc = super()._from_body(data, where)
        return dataclasses.replace(doc, statistics=stats)

    def mean(self, name: str) -> float | None:
        """The mean of statistic ``name`` (None when it has none)."""
        if name not in self.statistics:
            raise KeyError(f"{name!r} is no gait statistic; allowed: {', '.join(_STAT_KEYS)}")
        st = self.statistics[name]
        return None if st is None else st.mean


@dataclasses.dataclass(frozen=True)
class FallOutcome(Document):
    """A walk that fell before an analysable stride: the fall is its result."""

    fell: bool = entry("bool", "always true")
    fall_time_s: float = entry("number", "time of the fall", "s")
    completed_strides: int = entry("int", "complete right-leg cycles before the fall")
    swing_toe_contacts: int = entry("int", "toe contacts during swing")
    duration_s: float = entry("number", "simulated duration", "s")
    analysis: str = entry("str", "why there is no gait analysis")


@dataclasses.dataclass(frozen=True)
class HumanAnkleWork(Document):
    """The wearer's (muscles') ankle work per analysed stride of the worn leg."""

    ankle_positive_work_j_per_stride: float | None = entry(
        "number?", "positive work (null: no complete analysed stride)", "J")
    ankle_negative_work_j_per_stride: float | None = entry(
        "number?", "negative work (<= 0)", "J", omit_none=True, default=None)


@dataclasses.dataclass(frozen=True)
class AnkleJointWork(Document):
    """The whole ankle joint (muscles + device) per analysed stride."""

    push_off_peak_power_w: float | None = entry("number?", "mean of the push-off peak power",
                                                "W")
    push_off_positive_work_j_per_stride: float | None = entry(
        "number?", "positive work in the push-off window", "J")
    positive_work_j_per_stride: float | None = entry("number?", "positive work over the stride",
                                                     "J")
    note: str = entry("str", "what the block covers")


@dataclasses.dataclass(frozen=True)
class EndStopContact(Document):
    """The device's end stops over the analysed strides
    (:func:`afo_mj.metrics.device_flags.end_stop_contact`)."""

    contact_time_s: float | None = entry("number?", "time in contact, whole window", "s")
    contact_time_s_per_stride: float | None = entry("number?", "per stride", "s")
    contact_fraction: float | None = entry("number?", "fraction of samples in contact", "1")
    contacts_per_stride: float | None = entry("number?", "contact onsets per stride", "1")
    impulse_nm_s_per_stride: float | None = entry("number?", "∫|τ_stop| dt per stride",
                                                  "N·m·s")
    peak_torque_nm: float | None = entry("number?", "the stops' largest |torque|", "N·m")


@dataclasses.dataclass(frozen=True)
class DeviceFigures(Document):
    """A worn device's torque, work, masses, hydraulics and flags
    (:func:`afo_mj.experiments.device_walk.condition_summary`)."""

    window: str = entry("str", "the samples the figures cover")
    peak_torque_nm: float | None = entry("number?", "peak |delivered torque| (outside "
                                         "end-stop contact where the device has stops)", "N·m")
    torque_tracking_rmse_nm: float | None = entry("number?", "RMS commanded - delivered", "N·m")
    commanded_peak_torque_nm: float | None = entry("number?", "peak |commanded torque|", "N·m")
    positive_work_j_per_stride: float | None = entry("number?", "device positive work on the "
                                                     "ankle", "J")
    negative_work_j_per_stride: float | None = entry("number?", "negative work (<= 0)", "J")
    net_work_j_per_stride: float | None = entry("number?", "net work", "J")
    mechanical_role: str = entry("str", "actuator, brake, near_zero or empty (unknown)")
    mass_total_kg: float | None = entry("number?", "worn mass (null: not modelled)", "kg")
    mass_at_ankle_kg: float | None = entry("number?", "mass carried at the ankle", "kg")
    peak_pressure_mpa: float | None = entry("number?", "peak hydraulic pressure", "MPa")
    fluid_temperature_rise_k: float | None = entry("number?", "oil temperature rise", "K")
    battery_runtime_h: float | None = entry("number?", "battery energy / mean power drawn",
                                            "h")
    coupling_torque_error_rms_nm: float | None = entry("number?", "RMS coupling torque error",
                                                       "N·m")
    newton_unconverged_steps: int = entry("int", "steps accepted with Newton unconverged")
    battery_overload_steps: int = entry("int", "steps beyond the battery's matched load")
    peak_torque_incl_end_stops_nm: float | None = entry(
        "number?", "peak |delivered torque| with the stops' share", "N·m", omit_none=True,
        default=None)
    end_stop: EndStopContact | None = entry(EndStopContact, "end-stop contact (devices with "
                                            "stops)", omit_none=True, tagged=False,
                                            default=None)
    end_stop_contact: bool = entry("bool", "flag: the stops carried torque", default=False)
    brake: bool = entry("bool", "flag: mechanical_role is brake", default=False)
    tracking_poor: bool = entry("bool", "flag: poor torque tracking", default=False)
    newton_unconverged: bool = entry("bool", "flag: newton_unconverged_steps > 0",
                                     default=False)
    battery_overload: bool = entry("bool", "flag: battery_overload_steps > 0", default=False)
    flags: tuple = entry("list", "names of the flags set", default=())
    note: str | None = entry("str?", "what the figures leave out", omit_none=True,
                             default=None)


@dataclasses.dataclass(frozen=True)
class StrideEnergy(Document):
    """The energy ledger per analysed stride (whole-run ledger × mean stride time / run
    duration)."""

    stride_time_s: float | None = entry("number?", "mean analysed stride time", "s")
    electrical_in_j: float | None = entry("number?", "energy drawn from the source", "J")
    hydraulic_j: float | None = entry("number?", "hydraulic energy delivered (null: not a "
                                      "ledger term)", "J")
    mechanical_positive_out_j: float | None = entry("number?", "positive mechanical output",
                                                    "J")
    losses_j: Mapping = entry("object", "loss per name (J; null where not finite)", "J")
    note: str = entry("str", "how the figures are scaled")


@dataclasses.dataclass(frozen=True)
class RunEnergy(Document):
    """The device's energy over the whole run (its ledger, :class:`EnergyLedger`)."""

    run_duration_s: float | None = entry("number?", "run duration", "s")
    electrical_in_j: float | None = entry("number?", "energy drawn from the source", "J")
    electrical_regenerated_j: float | None = entry("number?", "energy returned to the source", "J")
    hydraulic_j: float | None = entry("number?", "hydraulic energy the pump delivered", "J")
    mechanical_out_j: float | None = entry("number?", "net mechanical work on the ankle", "J")
    mechanical_positive_out_j: float | None = entry("number?", "positive mechanical work", "J")
    losses_j: Mapping = entry("object", "loss per name", "J")
    stored_change_j: Mapping = entry("object", "change of each store", "J")
    efficiency_total: float | None = entry("number?", "mechanical positive out / drawn", "1")
    balance_error_rel: float | None = entry("number?", "ledger residual / energy throughput", "1")
    note: str = entry("str", "what the figures cover")
    input_j: float | None = entry("number?", "net input (circuit descriptions)", "J",
                                  omit_none=True, default=None)


@dataclasses.dataclass(frozen=True)
class WornCondition(Document):
    """One condition of a walk with an orthosis (``no_device``, ``transparent``, ``assist``
    or a stiffness condition). In ``summary.json`` it is embedded untagged in
    ``device_conditions``; on its own it carries its format tag."""

    FORMAT: ClassVar[str] = "afo_mj worn condition v1"
    TITLE: ClassVar[str] = "worn condition (one device condition of a walk)"

    fell: bool = entry("bool", "the walker fell")
    fall_time_s: float | None = entry("number?", "time of the fall (null: none)", "s")
    gait: GaitSummary | None = entry(GaitSummary, "gait analysis (null: no analysable "
                                     "stride)", nullable=True)
    human: HumanAnkleWork = entry(HumanAnkleWork, "the wearer's ankle work", tagged=False)
    ankle: AnkleJointWork | None = entry(AnkleJointWork, "the whole ankle joint (absent "
                                         "without a complete stride)", omit_none=True,
                                         tagged=False, default=None)
    device: DeviceFigures | None = entry(DeviceFigures, "the device (absent without one)",
                                         omit_none=True, tagged=False, default=None)
    energy_per_stride: StrideEnergy | None = entry(StrideEnergy, "energy per stride",
                                                   omit_none=True, tagged=False, default=None)
    energy: RunEnergy | None = entry(RunEnergy, "energy over the run", omit_none=True,
                                     tagged=False, default=None)
    muscle: Mapping | None = entry("object?", "muscle walker only: net metabolic rate and cost "
                                   "of transport (Umberger 2010, Bhargava 2004) and per "
                                   "muscle (afo_mj.metrics.muscle_metrics.muscle_summary); "
                                   "null without analysed strides", default=None)
    #: Whether the ``muscle`` key is present (a muscle walker's condition) even when null.
    has_muscle: bool = False

    def _body(self) -> dict:
        out = super()._body()
        if not self.has_muscle:
            out.pop("muscle")
        return out

    @classmethod
    def _from_body(cls, data, where):
        doc = super()._from_body(data, where) if "muscle" in data else \
            super()._from_body({**data, "muscle": None}, where)
        return dataclasses.replace(doc, has_muscle="muscle" in data)

    def with_muscle(self, block: Mapping | None) -> "WornCondition":
        """This condition with the muscle walker's ``muscle`` block (None: not analysed)."""
        return dataclasses.replace(self, muscle=block, has_muscle=True)


_LEDGER_DOC = "(null: the device does not report it)"


@dataclasses.dataclass(frozen=True)
class EnergyLedger(Document):
    """A device's energy ledger over a run, J unless named otherwise: every key a circuit
    device, a device with ledger groups or the ideal source reports, null where the device
    does not report it; the balance ``input_j = mechanical_out_j + Σ losses_j +
    Σ stored_change_j + residual_j``."""

    FORMAT: ClassVar[str] = "afo_mj energy ledger v1"
    TITLE: ClassVar[str] = "energy ledger (a device's)"

    input_j: float = entry("number", "net energy in from the source (drawn - regenerated)",
                           "J")
    input_drawn_j: float = entry("number", "energy drawn from the source", "J")
    mechanical_out_j: float = entry("number", "net mechanical work on the joint", "J")
    losses_j: Mapping = entry("object", "dissipated energy per loss name", "J")
    stored_change_j: Mapping = entry("object", "change of each store", "J")
    residual_j: float = entry("number", "balance residual", "J")
    balance_error_rel: float = entry("number", "residual / energy throughput", "1")
    energy_throughput_j: float = entry("number", "energy throughput (the residual's scale)",
                                       "J")
    heat_to_oil_j: float = entry("number", "heat into the oil", "J")
    peak_pressure_pa: float = entry("number", "peak pressure", "Pa")
    monitors: Mapping = entry("object", "each monitor's value (component-defined units)")
    state_peaks: Mapping = entry("object", "each state's peak over the run (state units)")
    probe_integrals: Mapping = entry("object", "each probe's time integral (a flow probe: m³)")
    newton_iterations: int = entry("int", "Newton iterations")
    jacobian_builds: int = entry("int", "Jacobian builds")
    newton_unconverged_steps: int = entry("int", "steps accepted with Newton unconverged")
    substepped_steps: int = entry("int", "sub-stepped steps")
    pressure_floor_steps: int = entry("int", "steps with a pressure clipped at the vapour "
                                      "floor")
    battery_overload_steps: int = entry("int", "steps beyond the battery's matched load")
    coupling_torque_error_rms_nm: float = entry("number", "RMS coupling torque error", "N·m")
    electrical_in_j: float | None = entry("number?", "electrical input " + _LEDGER_DOC, "J")
    electrical_drawn_j: float | None = entry("number?", "electrical energy drawn " +
                                             _LEDGER_DOC, "J")
    electrical_regenerated_j: float | None = entry("number?", "electrical energy returned " +
                                                   _LEDGER_DOC, "J")
    hydraulic_j: float | None = entry("number?", "hydraulic energy the pump delivered " +
                                      _LEDGER_DOC, "J")
    peak_current_a: float | None = entry("number?", "peak motor current " + _LEDGER_DOC, "A")
    temperature_rise_k: float | None = entry("number?", "oil temperature rise " + _LEDGER_DOC,
                                             "K")
    soc: float | None = entry("number?", "battery state of charge at the end " + _LEDGER_DOC,
                              "1")
    substeps: int | None = entry("int?", "sub-steps taken " + _LEDGER_DOC)
    mechanical_positive_out_j: float | None = entry("number?", "positive mechanical work " +
                                                    _LEDGER_DOC, "J")
    mechanical_negative_out_j: float | None = entry("number?", "negative mechanical work " +
                                                    _LEDGER_DOC, "J")
    peak_torque_nm: float | None = entry("number?", "peak |torque| " + _LEDGER_DOC, "N·m")
    battery_energy_wh: float | None = entry("number?", "battery energy " + _LEDGER_DOC, "Wh")
    source: str | None = entry("str?", "what the source is (the ideal device) " + _LEDGER_DOC)
    extras: Mapping = entry("object", "the device spec's own named ledger figures "
                            "(ledger_extras)")

    @classmethod
    def from_ledger(cls, ledger: Mapping, extra_keys=()) -> "EnergyLedger":
        """The document of a device's ledger dict (``device.ledger(k)``): keys it does not
        report become None; ``extra_keys`` (the spec's ``ledger_extras``) go to ``extras``;
        any other key raises :class:`DocumentError` naming it."""
        names = [f.name for f in cls._fields() if f.name != "extras"]
        unknown = [k for k in ledger if k not in names and k not in extra_keys]
        if unknown:
            raise DocumentError(f"energy ledger: unknown key(s) {', '.join(map(repr, unknown))}"
                                f"; allowed: {', '.join(names)} and the spec's ledger_extras "
                                f"({', '.join(extra_keys) or 'none'})")
        body = {k: ledger.get(k) for k in names}
        body["extras"] = {k: ledger[k] for k in extra_keys if k in ledger}
        return cls._from_body(body, "energy ledger")


@dataclasses.dataclass(frozen=True)
class HumanResponse(Document):
    """How the simulated wearer answers a worn device
    (:func:`afo_mj.experiments.device_walk.human_response`)."""

    walker_model: str = entry("str", "the walker model")
    rule: str | None = entry("str?", "the written-in rule (null: the walker's own response)")
    assistance_adaptation: float | None = entry("number?", "the torque walker's feedforward "
                                                "reduction per device torque", "1")
    note: str = entry("str", "what it means")


@dataclasses.dataclass(frozen=True)
class DeviceWalkPart(Document):
    """What a walk with an orthosis adds to ``summary.json``: every condition and the
    device. The headline condition (the last) is also given at the top level: its ``human``,
    ``device`` and ``energy`` blocks (derived from ``device_conditions``, not stored twice)."""

    condition: str = entry("str", "the headline condition (the last one run)")
    device_conditions: Mapping[str, WornCondition] = entry(
        "object", "each condition's block", map_of=WornCondition, tagged=False)
    device_preset: str | None = entry("str?", "the device preset (null: a described circuit)")
    device_sides: tuple = entry("list", "worn sides (right/left)")
    human_response: HumanResponse = entry(HumanResponse, "the wearer's answer to the device",
                                          tagged=False)
    circuit: Mapping | None = entry("object?", "a described circuit: name, controller and "
                                    "its description", omit_none=True, default=None)
    comparison_vs_no_device: Mapping | None = entry(
        "object?", "per condition: the change of the human ankle positive work (J/stride) "
        "and, on the muscle walker, of the net metabolic rate (W/kg and %)", omit_none=True,
        default=None)

    @property
    def headline(self) -> WornCondition:
        return self.device_conditions[self.condition]


@dataclasses.dataclass(frozen=True)
class WalkSummary(Document):
    """``summary.json`` of a walking run (``afo-mj run``), with or without an orthosis. Its
    format tag is the gait summary's (``afo_mj gait summary v1``): the walk's gait analysis
    is its body, at the top level. Layout: ``scenario``; the gait analysis'
    (:class:`GaitSummary`) keys, or a fall's (:class:`FallOutcome`); with an orthosis
    ``condition``, ``gait`` (the same analysis again, or the fall), ``human`` (the headline
    condition's), ``device_conditions``, ``device_preset``, ``device_sides``,
    ``human_response``, ``circuit`` and ``comparison_vs_no_device`` when present, the
    headline's ``device`` and ``energy``; then ``muscle`` (muscle walker) and
    ``band_fraction_vs`` (extra references)."""

    FORMAT: ClassVar[str] = GAIT_FORMAT
    TITLE: ClassVar[str] = "walk summary (summary.json of afo-mj run)"

    scenario: Mapping = entry("object", "the scenario as run (its tables, overrides applied)")
    gait: GaitSummary | None = entry(GaitSummary, "the gait analysis (null: the walker fell "
                                     "before an analysable stride)", nullable=True)
    fall: FallOutcome | None = entry(FallOutcome, "the fall, when there is no gait analysis",
                                     omit_none=True, tagged=False, default=None)
    device: DeviceWalkPart | None = entry(DeviceWalkPart, "a walk with an orthosis",
                                          omit_none=True, tagged=False, default=None)
    muscle: Mapping | None = entry("object?", "muscle walker: the (headline) walk's muscle "
                                   "block", omit_none=True, default=None)
    band_fraction_vs: Mapping | None = entry(
        "object?", "fraction of each cycle inside other references' ± 1 SD bands "
        "({'source:condition': {channel: statistic or null}})", omit_none=True, default=None)

    def __post_init__(self):
        if (self.gait is None) == (self.fall is None):
            raise DocumentError("WalkSummary: exactly one of gait and fall is given")

    @property
    def fell(self) -> bool:
        return self.fall is not None or bool(self.gait.fell)

    def to_json(self) -> dict:
        """The ``summary.json`` dict: ``scenario`` first, then the format tag (as written
        since the tag came in with the gait analysis' keys)."""
        body = self._body()
        return {"scenario": body.pop("scenario"), "format": self.FORMAT, **body}

    def _body(self) -> dict:
        out = {"scenario": _json_value(self.scenario)}
        out.update(self.gait._body() if self.gait is not None else self.fall._body())
        if self.device is not None:
            d, head = self.device, self.device.headline
            out["condition"] = d.condition
            out["gait"] = self.gait.to_json() if self.gait is not None else self.fall._body()
            out["human"] = head.human._body()
            part = d._body()
            part.pop("condition")
            out.update(part)
            if head.device is not None:
                out["device"] = head.device._body()
                out["energy"] = head.energy._body()
        if self.muscle is not None:
            out["muscle"] = _json_value(self.muscle)
        if self.band_fraction_vs is not None:
            out["band_fraction_vs"] = _json_value(self.band_fraction_vs)
        return out

    @classmethod
    def _from_body(cls, data, where):
        data = dict(data)
        if "scenario" not in data:
            raise DocumentError(f"{where}: missing key 'scenario'")
        scenario = Document._value_from(data.pop("scenario"), {"kind": "object",
                                                               "map_of": None,
                                                               "omit_none": False},
                                        f"{where}.scenario")
        muscle = data.pop("muscle", None)
        bands = data.pop("band_fraction_vs", None)
        device = None
        if "device_conditions" in data:
            part_keys = [f.name for f in DeviceWalkPart._fields()]
            part = {k: data.pop(k) for k in part_keys if k in data}
            device = DeviceWalkPart._from_body(part, f"{where}(device part)")
            head = device.headline
            nested = data.pop("gait", "<absent>")
            human = data.pop("human", "<absent>")
            if human != head.human._body():
                raise DocumentError(f"{where}.human differs from device_conditions"
                                    f"[{device.condition!r}].human")
            for key in ("device", "energy"):
                blk = getattr(head, key)
                got = data.pop(key, None)
                want = None if blk is None else blk._body()
                if got != want:
                    raise DocumentError(f"{where}.{key} differs from device_conditions"
                                        f"[{device.condition!r}].{key}")
        else:
            nested = None
        gait = fall = None
        if "analysis" in data:
            fall = FallOutcome._from_body(data, where)
            if device is not None and nested != fall._body():
                raise DocumentError(f"{where}.gait differs from the fall at the top level")
        else:
            gait = GaitSummary._from_body(data, where)
            if device is not None and nested != gait.to_json():
                raise DocumentError(f"{where}.gait differs from the analysis at the top level")
        obj = {"kind": "object?", "map_of": None, "omit_none": True}
        return cls(scenario=scenario, gait=gait, fall=fall, device=device,
                   muscle=Document._value_from(muscle, obj, f"{where}.muscle"),
                   band_fraction_vs=Document._value_from(bands, obj,
                                                         f"{where}.band_fraction_vs"))


def _json_value(v):
    return Document._value_json(v, {"map_of": None, "kind": "object"})


#: The documents ``docs/result_documents.md`` describes, with their embedded blocks.
@dataclasses.dataclass(frozen=True)
class BenchSummary(Document):
    """``summary.json`` of a bench scenario (``afo-mj run`` of a ``[bench]`` file,
    :func:`afo_mj.experiments.bench_run.run_bench_scenario`): the protocols run on the ankle
    test stand (``rig = "stand"``) or on a simulated load (``"load"``), their figures, the
    device, and the energy balance. The protocols' own figures are free-form objects named
    by protocol (documented in ``scenarios/README.md``, bench scenarios)."""

    FORMAT: ClassVar[str] = "afo_mj bench summary v2"
    TITLE: ClassVar[str] = "bench summary (summary.json of a bench scenario)"

    scenario: Mapping = entry("object", "the bench scenario as run")
    rig: str = entry("str", '"stand" (the MuJoCo ankle test stand) or "load" (a simulated '
                     "joint load)")
    protocols: Sequence = entry("list", "the protocols run, in order")
    notes: Sequence = entry("list", "notes on the scenario (deprecated keys read, ...)")
    bench: Mapping = entry("object", "stand: the scalar figures (bench.*); load: per protocol")
    bench_detail: Mapping | None = entry("object?", "stand: per-level and per-run detail",
                                         omit_none=True, default=None)
    device: Mapping = entry("object", "the device: its name, controller and masses (kg)",
                            default=None)
    circuit: Mapping | None = entry("object?", "load: the circuit's name and controller",
                                    omit_none=True, default=None)
    ledger: Mapping | None = entry("object?", "load: the energy ledger of each run (J)",
                                   omit_none=True, default=None)
    published: Mapping | None = entry("object?", "stand: the published figures the device is "
                                      "compared with (its spec's)", omit_none=True,
                                      default=None)
    stiffness: Mapping | None = entry("object?", "stand, stiffness protocol: per commanded "
                                      "stiffness k<K>", omit_none=True, default=None)
    sweep: Mapping | None = entry("object?", "stand, stiffness protocol: the sweep",
                                  omit_none=True, default=None)
    acceptance: Mapping | None = entry("object?", "stand, stiffness protocol: its acceptance",
                                       omit_none=True, default=None)
    energy: Mapping = entry("object", "the energy balance: the worst relative residual of any "
                            "run (balance_error_rel), with its note", default=None)

    def __post_init__(self):
        if self.rig not in ("stand", "load"):
            raise DocumentError(f"BenchSummary: rig = {self.rig!r}; allowed: stand, load")


DOCUMENT_CLASSES = (WalkSummary, BenchSummary, GaitSummary, StrideStatistic, GaitReference, PerLeg,
                    GaitDefinitions, FallOutcome, DeviceWalkPart, HumanResponse,
                    WornCondition, HumanAnkleWork, AnkleJointWork, DeviceFigures,
                    EndStopContact, StrideEnergy, RunEnergy, EnergyLedger)
