"""The design tool's result as a typed document: what ``design.json`` of ``afo-mj design``
holds (format ``afo_mj design v1``, the tag the file has carried since the tool came in).

:func:`design_summary` builds a :class:`DesignSummary` from what
:func:`afo_mj.design.system_design.compute_design` returns; ``design.json`` is its
``to_json()`` (:func:`afo_mj.outputs.design_report.write_design_report`). The parts with a
fixed shape are typed: the duty cycle (:class:`DutyCycleSummary`), the search
(:class:`DesignSearchSummary`), the best design (:class:`DesignRow`) and the ranked ones
(:class:`RankedDesign`), the written device (:class:`WrittenDevice`), the predicted bench
(:class:`PredictedBench`), the mass check (:class:`MassCheck`), the written scenarios
(:class:`WrittenScenarios`), the walk check (:class:`WalkCheck`), the simulated bench
(:class:`SimulatedBench`, :class:`BenchAgreement`), the design-guideline studies
(:class:`DesignStudies`) and the hose bore trade-off (:class:`HoseBoreTradeoff`). Each part
is built through its ``from_json`` checks (:mod:`afo_mj.metrics.document_base`), so a key the
computation adds or drops is refused by name instead of being written unseen. The
requirements, the assumptions and the per-architecture breakdowns (masses, losses,
efficiencies, margins, whose keys depend on the architecture) stay free-form objects.

Numbers are made plain and non-finite ones null (:func:`jsonable`), as ``design.json`` has
always had them.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any, ClassVar, Mapping, Sequence

import numpy as np

from afo_mj.metrics.document_base import Document, DocumentError, as_document_value, entry

__all__ = ["DESIGN_FORMAT", "DesignSummary", "DutyCycleSummary", "ConstraintPoint",
           "DesignSearchSummary", "DesignRow", "RankedDesign", "WrittenDevice",
           "PredictedBench", "MassItem", "MassCheck", "WrittenScenarios", "WalkWork",
           "WalkCheck", "SimulatedBench", "BenchAgreement", "GuidelineRow", "PowerStudyRow",
           "DesignStudies", "HoseBoreTradeoff", "DESIGN_DOCUMENT_CLASSES", "design_summary",
           "jsonable", "DocumentError"]

DESIGN_FORMAT = "afo_mj design v1"


def jsonable(x: Any) -> Any:
    """``x`` with numpy scalars/arrays as Python numbers/lists and non-finite floats as None."""
    if isinstance(x, dict):
        return {str(k): jsonable(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [jsonable(v) for v in x]
    if isinstance(x, np.ndarray):
        return [jsonable(v) for v in x.tolist()]
    if isinstance(x, (bool, np.bool_)):
        return bool(x)
    if isinstance(x, (int, np.integer)):
        return int(x)
    if isinstance(x, (float, np.floating)):
        v = float(x)
        return v if math.isfinite(v) else None
    return x


# -- the duty cycle and the search -------------------------------------------------------------
@dataclasses.dataclass(frozen=True)
class ConstraintPoint(Document):
    """One torque–velocity point every design must reach."""

    label: str = entry("str", "where the point comes from")
    torque_nm: float = entry("number", "ankle torque", "N·m")
    velocity_deg_s: float = entry("number", "ankle velocity", "deg/s")


@dataclasses.dataclass(frozen=True)
class DutyCycleSummary(Document):
    """The duty cycle the designs are evaluated over
    (:func:`afo_mj.design.design_requirements.duty_cycle`)."""

    note: str = entry("str", "what the duty cycle is")
    stride_time_s: float = entry("number", "stride duration", "s")
    samples: int = entry("int", "samples over the stride")
    positive_work_j_per_stride: float = entry("number", "positive ankle work asked", "J")
    peak_power_w: float = entry("number", "peak ankle power asked", "W")
    constraint_points: Sequence[ConstraintPoint] = entry(
        "list", "the constraint points (the first 12)", list_of=ConstraintPoint, tagged=False)


@dataclasses.dataclass(frozen=True)
class DesignSearchSummary(Document):
    """The design grid searched and the time it took."""

    designs_screened: int = entry("int", "designs in the grid")
    grid_sizes: Mapping = entry("object", "points per grid axis")
    grid: Mapping = entry("object", "the grid's values per axis (SI, named with their unit; "
                          "oil: grade names)")
    search_wall_s: float = entry("number", "wall time of the search", "s")
    total_wall_s: float = entry("number", "wall time of the whole computation (search, "
                                "studies, written device, bench)", "s")


# -- designs -------------------------------------------------------------------------------------
_ARCH = " (keys depend on the architecture)"


@dataclasses.dataclass(frozen=True)
class DesignRow(Document):
    """One design evaluated exactly (:meth:`afo_mj.design.design_search.DesignResult.row`):
    its variables, geometry, masses (one side), motor and battery, the energy per stride,
    efficiencies, heat and temperatures, runtime, peaks and constraint margins."""

    operating_pressure_pa: float = entry("number", "operating pressure", "Pa")
    cylinder_bore_m: float = entry("number", "cylinder bore (two cylinders)", "m")
    pulley_radius_m: float = entry("number", "pulley radius (moment arm)", "m")
    hose_bore_m: float = entry("number", "hose bore (two hoses)", "m")
    pump_displacement_m3_rev: float = entry("number", "pump displacement", "m³/rev")
    oil: str = entry("str", "oil grade")
    motor_rated_power_w: float = entry("number", "motor power class", "W")
    cable_diameter_m: float = entry("number", "cable (rod) diameter", "m")
    cylinder_stroke_m: float = entry("number", "cylinder stroke", "m")
    piston_seal_cross_section_m: float = entry("number", "piston O-ring cross-section", "m")
    torque_per_pressure_m3: float = entry("number", "effective area × arm (A_e r)", "m³")
    relief_cracking_pa: float = entry("number", "relief valve cracking pressure", "Pa")
    total_kg: float = entry("number", "mass, one side", "kg")
    ankle_kg: float = entry("number", "mass worn at the ankle", "kg")
    waist_kg: float = entry("number", "mass worn at the waist", "kg")
    mass_kg: Mapping = entry("object", "mass per part" + _ARCH, "kg")
    torque_constant_nm_a: float = entry("number", "motor torque constant", "N·m/A")
    resistance_ohm: float = entry("number", "motor winding resistance", "Ω")
    current_limit_a: float = entry("number", "driver current limit", "A")
    battery_capacity_ah: float = entry("number", "battery capacity", "Ah")
    battery_resistance_ohm: float = entry("number", "battery internal resistance", "Ω")
    battery_peak_current_a: float = entry("number", "peak battery current", "A")
    losses_j_per_stride: Mapping = entry("object", "loss per stage per stride" + _ARCH, "J")
    chemical_j_per_stride: float = entry("number", "chemical energy drawn per stride", "J")
    positive_work_j_per_stride: float = entry("number", "positive ankle work per stride", "J")
    net_work_j_per_stride: float = entry("number", "net ankle work per stride", "J")
    efficiency: Mapping = entry("object", "efficiency per stage over the stride (null: "
                                "undefined)" + _ARCH, "1")
    system_efficiency: float | None = entry("number?", "positive ankle work / chemical "
                                            "energy (null: undefined)", "1")
    heat_w: float = entry("number", "mean heat", "W")
    heat_to_oil_w: float = entry("number", "mean heat into the oil", "W")
    oil_temperature_k: float = entry("number", "steady oil temperature", "K")
    surface_temperature_k: float = entry("number", "steady pack surface temperature", "K")
    pack_resistance_k_w: float = entry("number", "pack surface to ambient resistance", "K/W")
    runtime_h: float = entry("number", "runtime on one charge", "h")
    heat_capacity_j_k: float = entry("number", "heat capacity of oil and metal", "J/K")
    runtime_strides: float = entry("number", "strides on one charge", "1")
    mean_walking_power_w: float = entry("number", "mean electrical power while walking", "W")
    peak_pump_pressure_pa: float = entry("number", "peak pump pressure over the duty cycle",
                                         "Pa")
    peak_pump_speed_rad_s: float = entry("number", "peak pump speed", "rad/s")
    peak_reynolds: float = entry("number", "peak hose Reynolds number", "1")
    margins: Mapping = entry("object", "relative margin per constraint (null: undefined)", "1")
    feasible: bool = entry("bool", "every constraint met")
    oil_thermal_resistance_k_w: float = entry("number", "oil to ambient resistance written as "
                                              "the simulator's thermal_resistance_k_w", "K/W")
    hydraulic_system_kg: float = entry("number", "motor, pump, manifold, hoses, cylinders and "
                                       "pulley", "kg")
    rated_output_power_w: float = entry("number", "output power the actuator is rated for",
                                        "W")
    hydraulic_power_density_w_kg: float = entry("number", "rated power / hydraulic system "
                                                "mass", "W/kg")
    system_energy_density_wh_kg: float = entry("number", "ankle work over a charge / total "
                                               "mass", "Wh/kg")


@dataclasses.dataclass(frozen=True)
class RankedDesign(Document):
    """One of the ranked feasible designs, in short."""

    total_kg: float = entry("number", "mass, one side", "kg")
    ankle_kg: float = entry("number", "at the ankle", "kg")
    waist_kg: float = entry("number", "at the waist", "kg")
    operating_pressure_pa: float = entry("number", "operating pressure", "Pa")
    cylinder_bore_m: float = entry("number", "cylinder bore", "m")
    pulley_radius_m: float = entry("number", "pulley radius", "m")
    hose_bore_m: float = entry("number", "hose bore", "m")
    pump_displacement_m3_rev: float = entry("number", "pump displacement", "m³/rev")
    oil: str = entry("str", "oil grade")
    motor_rated_power_w: float = entry("number", "motor power class", "W")
    battery_capacity_ah: float = entry("number", "battery capacity", "Ah")
    system_efficiency: float | None = entry("number?", "system efficiency", "1")
    surface_temperature_k: float = entry("number", "steady surface temperature", "K")
    runtime_h: float = entry("number", "runtime", "h")


# -- the written device ----------------------------------------------------------------------------
@dataclasses.dataclass(frozen=True)
class WrittenDevice(Document):
    """The best design as the simulator's device (pump-controlled designs)."""

    preset: str = entry("str", "the preset the parameters override")
    params: Mapping = entry("object", "the preset's parameters written (dotted names, SI)")
    mass_total_kg: float = entry("number", "the simulator's mass budget, one side", "kg")
    mass_at_ankle_kg: float = entry("number", "its part at the ankle", "kg")


@dataclasses.dataclass(frozen=True)
class PredictedBench(Document):
    """The written device's torque–velocity bench figures from the steady-state laws
    (:func:`afo_mj.design.design_device.predict_bench`)."""

    stall_torque_nm: float = entry("number", "stall torque", "N·m")
    stall_pump_pressure_pa: float = entry("number", "pump pressure at stall", "Pa")
    stall_current_a: float = entry("number", "motor current at stall", "A")
    no_load_speed_deg_s: float = entry("number", "no-load ankle speed", "deg/s")
    no_load_pump_pressure_pa: float = entry("number", "pump pressure at no load", "Pa")
    no_load_motor_speed_rad_s: float = entry("number", "motor speed at no load", "rad/s")
    viscosity_pa_s: float = entry("number", "oil viscosity", "Pa·s")
    soc: float = entry("number", "battery state of charge assumed", "1")
    open_circuit_voltage_v: float = entry("number", "battery open-circuit voltage", "V")


@dataclasses.dataclass(frozen=True)
class MassItem(Document):
    """One part's mass: the design's against the simulator's budget."""

    design_kg: float = entry("number", "the design's", "kg")
    budget_kg: float = entry("number", "the mass budget's", "kg")
    difference_kg: float = entry("number", "design - budget", "kg")


@dataclasses.dataclass(frozen=True)
class MassCheck(Document):
    """The design's mass against the simulator's mass budget of the written parameters
    (:func:`afo_mj.design.design_device.mass_check`)."""

    design_total_kg: float = entry("number", "the design's total", "kg")
    budget_total_kg: float = entry("number", "the budget's total", "kg")
    total_rel_difference: float = entry("number", "budget / design - 1", "1")
    design_ankle_kg: float = entry("number", "the design's mass at the ankle", "kg")
    budget_ankle_kg: float = entry("number", "the budget's", "kg")
    ankle_rel_difference: float = entry("number", "budget / design - 1", "1")
    items: Mapping[str, MassItem] = entry("object", "per part", map_of=MassItem, tagged=False)


@dataclasses.dataclass(frozen=True)
class WrittenScenarios(Document):
    """The scenarios written: ``bench``, ``walk`` and ``run`` (pump-controlled designs), or a
    ``note`` saying why none is (other architectures)."""

    bench: str | None = entry("str", "the bench scenario's file name", omit_none=True,
                              default=None)
    walk: str | None = entry("str", "the walking scenario's file name", omit_none=True,
                             default=None)
    run: str | None = entry("str", "how to run the bench", omit_none=True, default=None)
    note: str | None = entry("str", "why no scenario is written", omit_none=True,
                             default=None)

    def __post_init__(self):
        files = (self.bench, self.walk, self.run)
        if not ((self.note is None and None not in files)
                or (self.note is not None and files == (None, None, None))):
            raise DocumentError("WrittenScenarios: either bench, walk and run, or note alone")


@dataclasses.dataclass(frozen=True)
class WalkWork(Document):
    """The device's quasi-static work on the ankle over one stride."""

    positive_work_j_per_stride: float = entry("number", "positive work", "J")
    negative_work_j_per_stride: float = entry("number", "negative work (<= 0)", "J")
    net_work_j_per_stride: float = entry("number", "net work", "J")


@dataclasses.dataclass(frozen=True)
class WalkCheck(Document):
    """The written walk checked without simulating it
    (:func:`afo_mj.design.design_device.walk_work_check`): a device that does net negative
    work on the ankle brakes the walker."""

    model: str = entry("str", "the quasi-static model")
    gait: str = entry("str", "the walk's gait (source/condition)")
    cycle_time_s: float = entry("number", "its stride time", "s")
    samples: int = entry("int", "samples over the stride")
    stall_torque_nm: float = entry("number", "the device's stall torque", "N·m")
    no_load_speed_deg_s: float = entry("number", "its no-load speed", "deg/s")
    peak_plantarflexion_velocity_deg_s: float = entry(
        "number", "the gait's peak plantarflexion velocity", "deg/s")
    back_driven_fraction_of_stride: float = entry("number", "fraction of the stride the ankle "
                                                  "back-drives the pump", "1")
    conditions: Mapping[str, WalkWork] = entry("object", "the work per condition "
                                               "(transparent, assist)", map_of=WalkWork,
                                               tagged=False)
    brakes: bool = entry("bool", "net negative work in some condition")
    warning: str | None = entry("str?", "the warning (null: none)")


@dataclasses.dataclass(frozen=True)
class SimulatedBench(Document):
    """The written device on the simulator's torque–velocity bench (``--verify``)."""

    stall_torque_nm: float = entry("number", "stall torque", "N·m")
    no_load_speed_deg_s: float = entry("number", "no-load speed", "deg/s")
    energy_error_max: float = entry("number", "largest relative energy balance error", "1")


@dataclasses.dataclass(frozen=True)
class BenchAgreement(Document):
    """The simulated bench against the predicted one."""

    stall_torque_rel: float = entry("number", "simulated / predicted stall torque - 1", "1")
    no_load_speed_rel: float = entry("number", "simulated / predicted no-load speed - 1", "1")


# -- studies -----------------------------------------------------------------------------------
@dataclasses.dataclass(frozen=True)
class GuidelineRow(Document):
    """The lightest feasible design at one point of a design-guideline study
    (:func:`afo_mj.design.design_studies.guideline_studies`)."""

    operating_pressure_pa: float = entry("number", "operating pressure", "Pa")
    oil: str = entry("str", "oil grade")
    rated_output_power_w: float = entry("number", "rated output power", "W")
    total_kg: float = entry("number", "mass, one side", "kg")
    ankle_kg: float = entry("number", "at the ankle", "kg")
    waist_kg: float = entry("number", "at the waist", "kg")
    system_efficiency: float | None = entry("number?", "system efficiency", "1")
    pump_efficiency: float | None = entry("number?", "pump efficiency", "1")
    motor_efficiency: float | None = entry("number?", "motor efficiency", "1")
    lines_efficiency: float | None = entry("number?", "lines efficiency", "1")
    cylinders_efficiency: float | None = entry("number?", "cylinders efficiency", "1")
    hydraulic_power_density_w_kg: float = entry("number", "hydraulic power density", "W/kg")
    system_energy_density_wh_kg: float = entry("number", "system energy density", "Wh/kg")
    cylinder_bore_m: float = entry("number", "cylinder bore", "m")
    pulley_radius_m: float = entry("number", "pulley radius", "m")
    hose_bore_m: float = entry("number", "hose bore", "m")
    pump_displacement_m3_rev: float = entry("number", "pump displacement", "m³/rev")
    motor_rated_power_w: float = entry("number", "motor power class", "W")
    surface_temperature_k: float = entry("number", "steady surface temperature", "K")
    runtime_h: float = entry("number", "runtime", "h")


_FEASIBLE_ONLY = " (feasible rows only)"


@dataclasses.dataclass(frozen=True)
class PowerStudyRow(Document):
    """One output power of the power study: the requirements' torque or speed scaled by
    ``power_factor``; the lightest feasible design's figures (as :class:`GuidelineRow`), or
    the binding constraints when none is feasible."""

    power_factor: float = entry("number", "scale on the requirements' power", "1")
    rated_output_power_w: float = entry("number", "rated output power", "W")
    feasible: bool = entry("bool", "a design meets the scaled requirements")
    binding: Sequence | None = entry("list", "the binding constraints (infeasible rows only)",
                                     omit_none=True, default=None)
    operating_pressure_pa: float | None = entry("number", "operating pressure" +
                                                _FEASIBLE_ONLY, "Pa", omit_none=True,
                                                default=None)
    oil: str | None = entry("str", "oil grade" + _FEASIBLE_ONLY, omit_none=True, default=None)
    total_kg: float | None = entry("number", "mass, one side" + _FEASIBLE_ONLY, "kg",
                                   omit_none=True, default=None)
    ankle_kg: float | None = entry("number", "at the ankle" + _FEASIBLE_ONLY, "kg",
                                   omit_none=True, default=None)
    waist_kg: float | None = entry("number", "at the waist" + _FEASIBLE_ONLY, "kg",
                                   omit_none=True, default=None)
    system_efficiency: float | None = entry("number?", "system efficiency" + _FEASIBLE_ONLY,
                                            "1", omit_none=True, default=None)
    pump_efficiency: float | None = entry("number?", "pump efficiency" + _FEASIBLE_ONLY, "1",
                                          omit_none=True, default=None)
    motor_efficiency: float | None = entry("number?", "motor efficiency" + _FEASIBLE_ONLY,
                                           "1", omit_none=True, default=None)
    lines_efficiency: float | None = entry("number?", "lines efficiency" + _FEASIBLE_ONLY,
                                           "1", omit_none=True, default=None)
    cylinders_efficiency: float | None = entry("number?", "cylinders efficiency" +
                                               _FEASIBLE_ONLY, "1", omit_none=True,
                                               default=None)
    hydraulic_power_density_w_kg: float | None = entry(
        "number", "hydraulic power density" + _FEASIBLE_ONLY, "W/kg", omit_none=True,
        default=None)
    system_energy_density_wh_kg: float | None = entry(
        "number", "system energy density" + _FEASIBLE_ONLY, "Wh/kg", omit_none=True,
        default=None)
    cylinder_bore_m: float | None = entry("number", "cylinder bore" + _FEASIBLE_ONLY, "m",
                                          omit_none=True, default=None)
    pulley_radius_m: float | None = entry("number", "pulley radius" + _FEASIBLE_ONLY, "m",
                                          omit_none=True, default=None)
    hose_bore_m: float | None = entry("number", "hose bore" + _FEASIBLE_ONLY, "m",
                                      omit_none=True, default=None)
    pump_displacement_m3_rev: float | None = entry(
        "number", "pump displacement" + _FEASIBLE_ONLY, "m³/rev", omit_none=True,
        default=None)
    motor_rated_power_w: float | None = entry("number", "motor power class" + _FEASIBLE_ONLY,
                                              "W", omit_none=True, default=None)
    surface_temperature_k: float | None = entry(
        "number", "steady surface temperature" + _FEASIBLE_ONLY, "K", omit_none=True,
        default=None)
    runtime_h: float | None = entry("number", "runtime" + _FEASIBLE_ONLY, "h", omit_none=True,
                                    default=None)

    @classmethod
    def _from_body(cls, data, where):
        data = dict(data)
        feasible = data.get("feasible")
        design = [f.name for f in GuidelineRow._fields() if f.name != "rated_output_power_w"]
        if feasible is True:
            if "binding" in data:
                raise DocumentError(f"{where}: key 'binding' not allowed in a feasible row")
            required = ["power_factor", "rated_output_power_w", "feasible", *design]
        else:
            extra = [k for k in design if k in data]
            if extra:
                raise DocumentError(f"{where}: key(s) {', '.join(map(repr, extra))} not "
                                    "allowed in an infeasible row; allowed: power_factor, "
                                    "rated_output_power_w, feasible, binding")
            required = ["power_factor", "rated_output_power_w", "feasible", "binding"]
        cls._check_keys(data, where, required=required)
        return super()._from_body(data, where)

    def _body(self) -> dict:
        out = super()._body()
        if self.feasible:           # a feasible row's efficiencies are there even when null
            for k in ("system_efficiency", "pump_efficiency", "motor_efficiency",
                      "lines_efficiency", "cylinders_efficiency"):
                out.setdefault(k, None)
            order = [f.name for f in self._fields()]
            out = {k: out[k] for k in order if k in out}
        return out


@dataclasses.dataclass(frozen=True)
class DesignStudies(Document):
    """The design-guideline studies: the lightest feasible design per operating pressure,
    per oil grade and per output power (``study_*.csv``)."""

    pressure: Sequence[GuidelineRow] = entry("list", "per operating pressure",
                                             list_of=GuidelineRow, tagged=False)
    oil: Sequence[GuidelineRow] = entry("list", "per oil grade", list_of=GuidelineRow,
                                        tagged=False)
    power: Sequence[PowerStudyRow] = entry("list", "per output power",
                                           list_of=PowerStudyRow, tagged=False)


@dataclasses.dataclass(frozen=True)
class HoseBoreTradeoff(Document):
    """The best design with its hose bore varied
    (:func:`afo_mj.design.design_studies.hose_bore_study`): per bore, with the motor held
    (the battery re-sized) and with each bore's lightest feasible motor; then the
    optima."""

    hose_bore_m: Sequence = entry("list", "the hose bores", "m")
    total_kg: Sequence = entry("list", "mass, one side, motor held", "kg")
    battery_kg: Sequence = entry("list", "battery mass", "kg")
    hoses_kg: Sequence = entry("list", "hoses with oil", "kg")
    line_loss_j_per_stride: Sequence = entry("list", "viscous line loss per stride", "J")
    system_efficiency: Sequence = entry("list", "system efficiency (null: undefined)", "1")
    feasible: Sequence = entry("list", "every constraint met, motor held")
    surface_temperature_k: Sequence = entry("list", "steady surface temperature", "K")
    peak_reynolds: Sequence = entry("list", "peak hose Reynolds number", "1")
    total_reoptimised_kg: Sequence = entry("list", "mass with the lightest feasible motor "
                                           "(null: none feasible)", "kg")
    motor_reoptimised_w: Sequence = entry("list", "that motor's power class", "W")
    optimum_hose_bore_m: float = entry("number", "lightest bore, motor held", "m")
    interior_optimum: bool = entry("bool", "that bore is inside the range")
    feasible_optimum_hose_bore_m: float | None = entry(
        "number?", "lightest bore with a feasible motor (null: none)", "m")
    feasible_interior_optimum: bool = entry("bool", "that bore is inside the range")


# -- the whole file ------------------------------------------------------------------------------
@dataclasses.dataclass(frozen=True)
class DesignSummary(Document):
    """``design.json`` of ``afo-mj design``: the requirements, the duty cycle, the verdict
    (or the infeasibility explanation and the binding constraints), the search, the
    assumptions; for a feasible design the best design, the ranked ones and the hose bore
    trade-off; for a pump-controlled one the written device, its predicted bench figures,
    mass check, scenarios and walk check (with any warning); with ``--verify`` the simulated
    bench; with the studies the design guidelines; last the files written."""

    FORMAT: ClassVar[str] = DESIGN_FORMAT
    TITLE: ClassVar[str] = "design summary (design.json of afo-mj design)"

    requirements: Mapping = entry("object", "the requirements as read (their keys, SI; the "
                                  "source file as file)")
    duty_cycle: DutyCycleSummary = entry(DutyCycleSummary, "the duty cycle", tagged=False)
    architecture: str = entry("str", "pump, valve or digital")
    feasible: bool = entry("bool", "a design meets every requirement")
    explanation: str | None = entry("str?", "why none does (null: feasible)")
    binding_constraints: Sequence = entry("list", "the constraints that rule out the last "
                                          "designs (empty: feasible)")
    designs_ruled_out_by_constraint: Mapping = entry("object", "designs ruled out per "
                                                     "constraint")
    constraints: Mapping = entry("object", "what each constraint checks")
    search: DesignSearchSummary = entry(DesignSearchSummary, "the search", tagged=False)
    assumptions: Mapping = entry("object", "the sizing assumptions "
                                 "(afo_mj.design.design_models.DesignAssumptions, SI)")
    best: DesignRow | None = entry(DesignRow, "the lightest feasible design", omit_none=True,
                                   tagged=False, default=None)
    ranked: Sequence[RankedDesign] | None = entry(
        "list", "the ranked feasible designs (at most 20), lightest first",
        list_of=RankedDesign, tagged=False, omit_none=True, default=None)
    feasible_designs_evaluated_exactly: int | None = entry(
        "int", "feasible designs among those evaluated exactly", omit_none=True,
        default=None)
    device: WrittenDevice | None = entry(WrittenDevice, "the written device (pump-controlled)",
                                         omit_none=True, tagged=False, default=None)
    predicted_bench: PredictedBench | None = entry(PredictedBench, "its predicted bench "
                                                   "figures", omit_none=True, tagged=False,
                                                   default=None)
    mass_check: MassCheck | None = entry(MassCheck, "its mass against the simulator's "
                                         "budget", omit_none=True, tagged=False, default=None)
    scenarios: WrittenScenarios | None = entry(WrittenScenarios, "the scenarios written "
                                               "(feasible designs)", omit_none=True,
                                               tagged=False, default=None)
    walk_check: WalkCheck | None = entry(WalkCheck, "the written walk checked",
                                         omit_none=True, tagged=False, default=None)
    warnings: Sequence | None = entry("list", "warnings (a device that brakes the written "
                                      "walk)", omit_none=True, default=None)
    simulated_bench: SimulatedBench | None = entry(SimulatedBench, "the simulated bench "
                                                   "(--verify)", omit_none=True, tagged=False,
                                                   default=None)
    bench_agreement: BenchAgreement | None = entry(BenchAgreement, "simulated against "
                                                   "predicted (--verify)", omit_none=True,
                                                   tagged=False, default=None)
    studies: DesignStudies | None = entry(DesignStudies, "the design guidelines (unless "
                                          "--no-studies)", omit_none=True, tagged=False,
                                          default=None)
    hose_bore_tradeoff: HoseBoreTradeoff | None = entry(
        HoseBoreTradeoff, "the best design's hose bore trade-off", omit_none=True,
        tagged=False, default=None)
    files: Sequence | None = entry("list", "the files written into the directory",
                                   omit_none=True, default=None)

    def __post_init__(self):
        if self.feasible and (self.best is None or self.ranked is None):
            raise DocumentError("DesignSummary: a feasible design has best and ranked")
        if not self.feasible and (self.best is not None or self.explanation is None):
            raise DocumentError("DesignSummary: an infeasible design has an explanation and "
                                "no best design")
        if (self.simulated_bench is None) != (self.bench_agreement is None):
            raise DocumentError("DesignSummary: simulated_bench and bench_agreement come "
                                "together")

    @property
    def warning_list(self) -> list[str]:
        """The warnings (empty when none)."""
        return list(self.warnings or ())


def _part(cls, value: Mapping, name: str):
    """``value`` (made JSON-able) as document part ``cls``, through its key and kind checks."""
    return cls._from_body(jsonable(value), f"DesignSummary.{name}")


def design_summary(result, written: dict | None, study: dict | None, hose: dict | None,
                   bench: dict | None, wall_s: float) -> DesignSummary:
    """The :class:`DesignSummary` of a design computation (the parts
    :func:`afo_mj.design.system_design.compute_design` returns)."""
    from afo_mj.design.design_evaluation import CONSTRAINTS
    req = result.requirements
    duty = result.duty
    kw: dict[str, Any] = {
        "requirements": as_document_value(jsonable(req.as_dict())),
        "duty_cycle": _part(DutyCycleSummary, {
            "note": duty.note, "stride_time_s": duty.stride_time_s,
            "samples": int(duty.torque_nm.size),
            "positive_work_j_per_stride": duty.positive_work_j,
            "peak_power_w": duty.peak_power_w,
            "constraint_points": [
                {"label": lab, "torque_nm": float(t), "velocity_deg_s": math.degrees(float(v))}
                for lab, t, v in zip(duty.constraint_labels[:12],
                                     duty.constraint_torque_nm[:12],
                                     duty.constraint_velocity_rad_s[:12])]}, "duty_cycle"),
        "architecture": req.architecture,
        "feasible": bool(result.feasible),
        "explanation": result.explanation,
        "binding_constraints": as_document_value(jsonable(result.binding)),
        "designs_ruled_out_by_constraint": as_document_value(jsonable(result.counts)),
        "constraints": as_document_value(dict(CONSTRAINTS)),
        "search": _part(DesignSearchSummary, {
            "designs_screened": result.screened,
            "grid_sizes": {k: len(v) for k, v in result.grid.items()},
            "grid": result.grid, "search_wall_s": result.wall_s,
            "total_wall_s": wall_s}, "search"),
        "assumptions": as_document_value(jsonable(dataclasses.asdict(result.assumptions))),
    }
    if result.feasible:
        n = len(result.order)
        kw["best"] = _part(DesignRow, result.row(0), "best")
        keys = [f.name for f in RankedDesign._fields()]
        rows = (result.row(i) for i in range(min(n, 20)))
        kw["ranked"] = tuple(_part(RankedDesign, {k: r[k] for k in keys}, f"ranked[{i}]")
                             for i, r in enumerate(rows))
        kw["feasible_designs_evaluated_exactly"] = n
    if written is not None:
        pb = _part(PredictedBench, written["predicted_bench"], "predicted_bench")
        mc = _part(MassCheck, written["mass_check"], "mass_check")
        kw["device"] = _part(WrittenDevice, {
            "preset": "hafo", "params": written["overrides"],
            "mass_total_kg": mc.budget_total_kg, "mass_at_ankle_kg": mc.budget_ankle_kg},
            "device")
        kw["predicted_bench"] = pb
        kw["mass_check"] = mc
        kw["scenarios"] = WrittenScenarios(bench="design_bench.toml", walk="design_walk.toml",
                                           run="afo-mj run DIR/design_bench.toml --out OUT")
        if written.get("walk_check") is not None:
            wc = _part(WalkCheck, written["walk_check"], "walk_check")
            kw["walk_check"] = wc
            if wc.warning:
                kw["warnings"] = (wc.warning,)
    elif result.feasible:
        kw["scenarios"] = WrittenScenarios(note=written_note(req))
    if bench is not None:
        pb = kw["predicted_bench"]
        kw["simulated_bench"] = _part(SimulatedBench, bench, "simulated_bench")
        kw["bench_agreement"] = _part(BenchAgreement, {
            "stall_torque_rel": bench["stall_torque_nm"] / pb.stall_torque_nm - 1.0,
            "no_load_speed_rel": bench["no_load_speed_deg_s"] / pb.no_load_speed_deg_s - 1.0},
            "bench_agreement")
    if study is not None:
        kw["studies"] = _part(DesignStudies, study, "studies")
    if hose is not None:
        tk = np.asarray(hose["total_kg"])
        k = int(np.argmin(tk))
        tr = np.asarray(hose["total_reoptimised_kg"], dtype=float)
        kr = int(np.argmin(tr))
        block = {k_: np.asarray(v) for k_, v in hose.items()}
        block.update(
            optimum_hose_bore_m=float(hose["hose_bore_m"][k]),
            interior_optimum=bool(0 < k < tk.size - 1),
            feasible_optimum_hose_bore_m=(float(hose["hose_bore_m"][kr])
                                          if np.isfinite(tr[kr]) else None),
            feasible_interior_optimum=bool(np.isfinite(tr[kr]) and 0 < kr < tr.size - 1))
        kw["hose_bore_tradeoff"] = _part(HoseBoreTradeoff, block, "hose_bore_tradeoff")
    return DesignSummary(**kw)


def written_note(req) -> str:
    """Why a design of another architecture than the pump-controlled one writes no scenario."""
    return (f"architecture {req.architecture!r}: designs are reported; the written "
            f"scenarios are for the pump-controlled HAFO kernel only")


#: The design documents ``docs/result_documents.md`` describes, the whole file first.
DESIGN_DOCUMENT_CLASSES = (DesignSummary, DutyCycleSummary, ConstraintPoint,
                           DesignSearchSummary, DesignRow, RankedDesign, WrittenDevice,
                           PredictedBench, MassCheck, MassItem, WrittenScenarios, WalkCheck,
                           WalkWork, SimulatedBench, BenchAgreement, DesignStudies,
                           GuidelineRow, PowerStudyRow, HoseBoreTradeoff)
