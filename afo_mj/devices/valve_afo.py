"""Valve-controlled, digital-valve and stiffness-emulating ankle orthoses (seed ch. 4, 5, 7).

The same worn architecture as the HAFO (:mod:`afo_mj.devices.hafo`: power supply at the waist,
two hoses, two antagonistic piston-cable cylinders on a 40 mm ankle pulley, the same oil,
battery and driver), with the pump-controlled circuit replaced by a **valve-controlled** one
(:func:`valve_circuit`, a generated circuit): a unidirectional pump, a check valve, a rail
with a gas accumulator, an unloading valve and a relief valve, and a 4/3 servo valve that
meters the cylinders' flow by throttling. The seed's variants for intermittent duty are
presets and ``supply_mode`` values:

==========================  =================================================================
``valve_no_accumulator``    constant-speed fixed pump, surplus flow over the relief valve
``valve_accumulator``       the same with a 50 cm³ gas accumulator on the rail
``valve`` (``unloading``)   accumulator + unloading valve: pump unloaded to tank when charged
``valve_pressure_control``  motor speed follows the load: rail = load pressure + 1.5 MPa
``valve_variable``          pressure-compensated variable-displacement pump, constant speed
``digital``                 PWM on/off valve unloads the pump; a release valve vents port A
``phafo``                   stiffness emulator: 14.1 MPa rail held by proportional
                            flow-rate (motor-speed) control, servo valve, impedance control
==========================  =================================================================

Why these numbers (one side; none is a published part, each is reasoned):

* **Pump and motor** — 0.4 cm³/rev gear pump (the library's small gear pump scaled) at a set
  speed of 500 rad/s (4800 rpm): 1.9 L/min, 30 % over the walker's peak push-off demand
  ``A_e r θ̇ ≈ 6.5e-6 m³ × 3.8 rad/s ≈ 1.5 L/min``. At an 11 MPa rail it needs 0.70 N·m, so a
  faster-wound motor than the HAFO's (K = 0.035 N·m/A, 0.12 Ω: about 22 A, back-EMF 17.5 V on
  the 22.5 V pack) with a 25 A driver limit.
* **Rail** — 40 N·m of assistance needs 6.1 MPa across the pistons (``A_e r = 6.545e-6 m³``);
  the servo valve needs about 1–2 MPa across its two lands at the push-off flow, so the rail
  works at 9.5–11 MPa: unloading valve cut-in 9.6 / cut-out 11.1 MPa abs, relief cracking
  at 11.5 MPa above the tank.
* **Accumulator** — 50 cm³ diaphragm type precharged to 6 MPa abs: between cut-in and
  cut-out it holds ``50 (1 − (6/11.1)^(1/1.4)) − 50 (1 − (6/9.6)^(1/1.4)) ≈ 3.6 cm³``, more
  than the ≈ 2.3 cm³ one push-off takes (``A_e r`` × 20°). 0.35 kg.
* **Servo valve** — a miniature proportional/servo valve, 4 L/min at 7 MPa, 200 Hz spool
  (first-order, τ = 0.8 ms), 0.05 L/min centre leakage at 21 MPa, 0.5 W coil.
* **Tank** — a 0.5 MPa bootstrap reservoir (the pump's inlet and the make-up valves'
  source; the pistons then sit at equal pressure with no torque).
* **Digital** — two 2 mm² on/off valves of 2 ms switching time, 2 W holding and 0.05 J per
  switch (:mod:`afo_mj.hydraulics.onoff_valve` defaults), PWM at 50 Hz (20 periods per
  second at the 1 ms walker step; the on-fraction over each step is exact, so the duty is not
  quantised). No accumulator: the pump's flow is metered in time instead.
* **PHAFO** — the group's pediatric device: 14.1 MPa rail, up to 62 N·m, emulated springs of
  1–4.6 N·m/deg, 1.5 kg worn (facts.md). Pulley 32 mm with the HAFO's cylinders
  (``A_e r = 5.24e-6 m³``: 62 N·m at 11.8 MPa, so 2.3 MPa is left across the valve); the power
  supply is tethered (a clinic tool), so nothing is worn at the waist; its 48 V bus (a 12S
  pack in the model) drives the HAFO's 0.055 N·m/A motor, which holds the 14.1 MPa rail
  against the pump's and the servo valve's leakage at about 17 A (≈ 105 W at idle, measured
  by the stiffness bench).
"""

from __future__ import annotations

import dataclasses
import math


from afo_mj.circuits import components as _cc
from afo_mj.circuits import valve_controllers as _vc
from afo_mj.circuits import valves as _cv
from afo_mj.circuits.circuit import Circuit, CircuitOptions, ThermalParams
from afo_mj.circuits.components import CircuitError
from afo_mj.circuits.device import CircuitDevice
from afo_mj.circuits.device_spec import DeviceSpec, LedgerGroups
from afo_mj.devices.hafo import (HAFO_GAIT, HAFO_LEDGER, HafoMassItem, PumpAnkleParams,
                                 _hose_mass_kg, check_sides)
from afo_mj.hydraulics.accumulator import GasAccumulatorParams
from afo_mj.hydraulics.onoff_valve import OnOffValveParams
from afo_mj.hydraulics.orifice import OrificeParams
from afo_mj.hydraulics.params import ParameterError, effect, param, replace_named
from afo_mj.hydraulics.pump import GEAR_PUMP_SMALL
from afo_mj.hydraulics.servo_valve import ServoValveParams
from afo_mj.hydraulics.unloading_valve import UnloadingValveParams

__all__ = ["CONTROL_SET_BY_PRESET", "VALVE_CONTROL_ALIASES", "ValveAnkleParams",
           "VALVE_PRESETS", "valve_params", "valve_mass_budget", "ValveAfoDevice", "CIRCUITS",
           "SERVO_LOSS_TABLE", "DIGITAL_LOSS_TABLE", "SUPPLY_MODES", "valve_circuit",
           "valve_initial_state"]

CIRCUITS = ("servo", "digital")
SUPPLY_MODES = ("constant_speed", "unloading", "pressure_control", "variable_displacement")


#: The controller parameters (:class:`~afo_mj.circuits.valve_controllers.ValveTorqueParams`)
#: that a valve preset sets from its own fields, by dotted name: the torque saturation, the
#: oil density of the flow feedforward, the supply's set speed, its pressure loop (on with
#: ``supply_mode = "pressure_control"``) and the rail set points. ``valve_control`` keeps
#: them at their defaults (:meth:`ValveAnkleParams.check`), so each has one name.
CONTROL_SET_BY_PRESET = {
    "max_torque_nm": "max_torque_nm",
    "feedforward_density_kg_m3": "fluid.density_kg_m3",
    "supply.speed_set_rad_s": "motor_speed_rad_s",
    "supply.pressure_control_enabled": "supply_mode",
    "supply.follows_demand_enabled": "supply_pressure_follows_demand",
    "supply.pressure_set_pa": "supply_pressure_set_pa",
    "supply.pressure_margin_pa": "supply_pressure_margin_pa",
    "supply.pressure_min_pa": "supply_pressure_min_pa",
}

#: The valve presets' former flat names of the supply's loop gains (``ValveControlParams``,
#: before its fields became :class:`~afo_mj.circuits.valve_controllers.ValveTorqueParams`'s):
#: still accepted by :func:`valve_params`, as the names they stand for.
VALVE_CONTROL_ALIASES = {
    "valve_control.speed_gain_v_s_per_rad": "valve_control.supply.speed_gain_v_s_per_rad",
    "valve_control.speed_integral_gain_v_per_rad":
        "valve_control.supply.speed_integral_gain_v_per_rad",
    "valve_control.speed_integral_limit_rad": "valve_control.supply.speed_integral_limit_rad",
    "valve_control.supply_gain_rad_s_per_pa": "valve_control.supply.pressure_gain_rad_s_per_pa",
    "valve_control.supply_integral_gain_rad_per_pa":
        "valve_control.supply.pressure_integral_gain_rad_per_pa",
    "valve_control.supply_integral_limit_pa_s":
        "valve_control.supply.pressure_integral_limit_pa_s",
}


def _dotted(obj, name: str):
    for part in name.split("."):
        obj = getattr(obj, part)
    return obj


@dataclasses.dataclass(frozen=True)
class ValveAnkleParams(PumpAnkleParams):
    """One side of a valve-controlled (servo or digital) ankle orthosis.

    Inherits the worn parts of the HAFO (fluid, motor, driver, pump, hoses, cylinders, relief,
    battery, thermal); ``reservoir_pressure_pa`` is the tank; the flushing fields are unused.
    """

    circuit: str = "servo"
    supply_mode: str = "unloading"
    accumulator_enabled: bool = effect(True, doc="gas accumulator on the supply rail")
    accumulator: GasAccumulatorParams = GasAccumulatorParams(
        gas_volume_m3=50e-6, precharge_pressure_pa=6.0e6, max_pressure_pa=12.0e6)
    accumulator_mass_kg: float = param(0.35, unit="kg", lo=0.0, hi=10.0)
    accumulator_blend_pa: float = param(0.2e6, unit="Pa", lo=1e3, hi=5e6,
                                        doc="band over which the gas spring engages at the "
                                            "precharge pressure")
    unloading: UnloadingValveParams = UnloadingValveParams(
        cut_out_pressure_pa=11.1e6, cut_in_pressure_pa=9.6e6, switching_band_pa=0.3e6,
        time_constant_s=2e-3)
    servo_valve: ServoValveParams = ServoValveParams(leakage_flow_m3_s=0.05 / 60e3)
    servo_coil_power_w: float = param(0.5, unit="W", lo=0.0, hi=100.0,
                                      doc="servo valve torque-motor power")
    switching_valve: OnOffValveParams = OnOffValveParams()
    release_valve_area_m2: float = param(2.0e-6, unit="m^2", lo=1e-9, hi=1e-4,
                                         doc="digital circuit: release valve's open area "
                                             "(an on/off valve of switching_valve's timing)")
    pwm_frequency_hz: float = param(50.0, unit="Hz", lo=1.0, hi=2000.0,
                                    doc="PWM frequency of the digital circuit's on/off valves")
    check_valve_conductance_m3_s_pa: float = param(1e-9, unit="m^3/(s Pa)", lo=1e-14, hi=1e-6,
                                                   doc="pump check valve, open")
    check_valve_cracking_pa: float = param(0.05e6, unit="Pa", lo=0.0, hi=5e6)
    manifold_volume_m3: float = param(2e-6, unit="m^3", lo=1e-8, hi=1e-3,
                                      doc="oil in the supply manifold (rail) besides the "
                                          "accumulator")
    motor_speed_rad_s: float = param(500.0, unit="rad/s", lo=0.0, hi=3000.0,
                                     doc="set speed of a constant-speed supply; the top speed "
                                         "of a pressure-controlled one")
    supply_pressure_follows_demand: bool = effect(
        True, doc="pressure_control: rail = load pressure + margin (False: fixed "
                  "supply_pressure_set_pa, a regulated rail)")
    supply_pressure_set_pa: float = param(14.1e6, unit="Pa", lo=0.0, hi=40e6,
                                          doc="fixed rail set point (gauge)")
    supply_pressure_margin_pa: float = param(1.5e6, unit="Pa", lo=0.0, hi=20e6,
                                             doc="rail above the load pressure (following)")
    supply_pressure_min_pa: float = param(2.0e6, unit="Pa", lo=0.0, hi=20e6,
                                          doc="lowest rail set point (following)")
    compensator_pressure_pa: float = param(11.0e6, unit="Pa", lo=0.0, hi=40e6,
                                           doc="variable pump: rail at which displacement "
                                               "reaches its minimum (gauge)")
    compensator_band_pa: float = param(1.0e6, unit="Pa", lo=1e4, hi=20e6,
                                       doc="variable pump: pressure band of full stroke")
    min_displacement_fraction: float = param(0.03, unit="-", lo=0.0, hi=1.0,
                                             doc="variable pump: smallest displacement")
    initial_supply_pressure_pa: float = param(9.0e6, unit="Pa", lo=0.0, hi=40e6,
                                              doc="rail at t = 0 (gauge; a charged "
                                                  "accumulator), the other nodes at the tank")
    max_torque_nm: float = param(70.0, unit="N m", lo=1.0, hi=500.0,
                                 doc="commanded torque saturation")
    valve_block_mass_kg: float = param(0.35, unit="kg", lo=0.0, hi=10.0,
                                       doc="manifold with servo (or on/off) valves, check, "
                                           "unloading and relief valves")
    power_supply_worn: bool = effect(True, doc="battery, motor, pump and valves worn at the "
                                               "waist (False: a tethered bench supply)")
    #: the gains of the valve circuit's controller (the torque loop, the supply's speed and
    #: rail-pressure loops); its set points are the preset's own fields
    #: (:data:`CONTROL_SET_BY_PRESET`) and stay at their defaults here
    valve_control: _vc.ValveTorqueParams = _vc.ValveTorqueParams()

    def check(self) -> None:
        super().check()
        default = _vc.ValveTorqueParams()
        for name, field in CONTROL_SET_BY_PRESET.items():
            value = _dotted(self.valve_control, name)
            if value != _dotted(default, name):
                raise ParameterError(f"{type(self).__name__}.valve_control.{name} = {value!r}: "
                                     f"set by the preset's {field}; allowed: the default "
                                     f"{_dotted(default, name)!r} (set {field} instead)")
        if self.circuit not in CIRCUITS:
            self.fail("circuit", f"allowed: {', '.join(CIRCUITS)}")
        if self.supply_mode not in SUPPLY_MODES:
            self.fail("supply_mode", f"allowed: {', '.join(SUPPLY_MODES)}")
        if self.circuit == "digital" and self.supply_mode != "constant_speed":
            self.fail("supply_mode", "the digital circuit meters a constant-speed pump's flow "
                      "by PWM: allowed: constant_speed")
        if self.supply_mode == "unloading" and not self.accumulator_enabled:
            self.fail("supply_mode", "an unloading valve needs the accumulator "
                      "(accumulator_enabled = True)")
        if self.pwm_frequency_hz * self.switching_valve.switching_time_s > 0.25:
            self.fail("pwm_frequency_hz", "the valve's switching time must be under a quarter "
                      f"of the PWM period (switching_time_s = "
                      f"{self.switching_valve.switching_time_s})")

    # -- derived --------------------------------------------------------------------------
    @property
    def servo_full_area_m2(self) -> float:
        """Servo edge area per unit of normalised spool opening, ``w x_max`` (m²): an edge
        opened by ``x − lap`` (fractions of the stroke) has ``w x_max (x − lap)``."""
        return self.servo_valve.area_gradient_m * self.servo_valve.spool_max_m

    @property
    def nominal_pump_flow_m3_s(self) -> float:
        return self.pump.displacement_m3_rev / (2 * math.pi) * self.motor_speed_rad_s


_VALVE_MOTOR = HAFO_GAIT.motor.replace(torque_constant_nm_a=0.035, resistance_ohm=0.12,
                                       inductance_h=0.04e-3)
_VALVE_BASE = ValveAnkleParams(
    **{f.name: getattr(HAFO_GAIT, f.name) for f in dataclasses.fields(PumpAnkleParams)}
).replace(
    pump=GEAR_PUMP_SMALL.replace(displacement_m3_rev=0.4e-6,
                                 rotor_inertia_kg_m2=2.0 * GEAR_PUMP_SMALL.rotor_inertia_kg_m2),
    pump_mass_kg=0.30, motor=_VALVE_MOTOR,
    driver=HAFO_GAIT.driver.replace(current_limit_a=25.0),
    relief=HAFO_GAIT.relief.replace(cracking_dp_pa=11.5e6, override_dp_pa=1.0e6,
                                    max_area_m2=2.0e-6),
    reservoir_pressure_pa=0.5e6)

#: The valve-controlled presets (variants of the supply), the digital one and the PHAFO.
VALVE_PRESETS = {
    "valve": _VALVE_BASE,
    "valve_no_accumulator": _VALVE_BASE.replace(supply_mode="constant_speed",
                                                accumulator_enabled=False,
                                                initial_supply_pressure_pa=0.5e6),
    "valve_accumulator": _VALVE_BASE.replace(supply_mode="constant_speed"),
    "valve_pressure_control": _VALVE_BASE.replace(
        supply_mode="pressure_control", supply_pressure_min_pa=4.0e6,
        accumulator=_VALVE_BASE.accumulator.replace(gas_volume_m3=4e-6,
                                                    precharge_pressure_pa=1.5e6),
        accumulator_mass_kg=0.10, initial_supply_pressure_pa=4.0e6),
    "valve_variable": _VALVE_BASE.replace(supply_mode="variable_displacement",
                                          accumulator_enabled=False,
                                          pump_mass_kg=0.40),
    "digital": _VALVE_BASE.replace(
        circuit="digital", supply_mode="constant_speed", accumulator_enabled=False,
        initial_supply_pressure_pa=0.5e6, servo_coil_power_w=0.0,
        valve_control=_vc.ValveTorqueParams(valve_gain_per_pa=8e-8,
                                            valve_integral_gain_per_pa_s=5e-7)),
    "phafo": _VALVE_BASE.replace(
        supply_mode="pressure_control", supply_pressure_follows_demand=False,
        supply_pressure_set_pa=14.1e6, pulley_radius_m=0.032, max_torque_nm=62.0,
        accumulator=_VALVE_BASE.accumulator.replace(precharge_pressure_pa=8.0e6,
                                                    max_pressure_pa=16.0e6),
        relief=_VALVE_BASE.relief.replace(cracking_dp_pa=15.5e6),
        unloading=UnloadingValveParams(cut_out_pressure_pa=15.2e6, cut_in_pressure_pa=14.0e6),
        initial_supply_pressure_pa=14.0e6, power_supply_worn=False,
        motor=HAFO_GAIT.motor, battery=HAFO_GAIT.battery.replace(
            name="tethered 48 V bench supply (modelled as a 12S pack)", cells_series=12.0),
        motor_speed_rad_s=560.0),
}


def valve_params(overrides: dict | None = None, preset: str = "valve") -> ValveAnkleParams:
    """A preset (:data:`VALVE_PRESETS`) with dotted-name overrides, validated (the former
    names of :data:`VALVE_CONTROL_ALIASES` are read as the names they stand for)."""
    if preset not in VALVE_PRESETS:
        raise ParameterError(f"device.preset = {preset!r}; allowed: {', '.join(VALVE_PRESETS)}")
    base = VALVE_PRESETS[preset]
    if not overrides:
        return base
    named = {}
    for key, value in overrides.items():
        name = VALVE_CONTROL_ALIASES.get(key, key)
        if name in named:
            raise ParameterError(f"device.params: {key!r} and {name!r} name one parameter; "
                                 "allowed: one of them")
        named[name] = value
    return replace_named(base, named)


def valve_mass_budget(p: ValveAnkleParams) -> tuple[HafoMassItem, ...]:
    """Parts, masses and where they are worn (one side). The ankle parts are the HAFO's; the
    PHAFO's are its published 1.5 kg worn; a tethered supply is not worn (site ``off_body``)."""
    supply_site = "waist" if p.power_supply_worn else "off_body"
    if p.power_supply_worn:
        ankle = (
            HafoMassItem("cylinders", 0.26, "shank_cuff", "two piston-cable cylinders"),
            HafoMassItem("shank_cuff_struts", 0.31, "shank_cuff", "cuff, uprights, guides"),
            HafoMassItem("pulley_bearings", 0.12, "ankle_axis", "pulley, axle, bearings"),
            HafoMassItem("foot_plate", 0.28, "foot_plate", "carbon foot plate and stirrup"))
    else:
        ankle = (
            HafoMassItem("cylinders", 0.30, "shank_cuff", "two piston-cable cylinders"),
            HafoMassItem("shank_cuff_struts", 0.55, "shank_cuff",
                         "cuff, uprights, guides, sensors"),
            HafoMassItem("pulley_bearings", 0.25, "ankle_axis", "pulley, axle, bearings"),
            HafoMassItem("foot_plate", 0.40, "foot_plate", "foot plate and shoe insert"))
    items = list(ankle) + [
        HafoMassItem("battery", p.battery.mass_kg, supply_site, p.battery.name),
        HafoMassItem("motor", p.motor.mass_kg, supply_site, "brushless motor"),
        HafoMassItem("pump", p.pump_mass_kg, supply_site,
                     f"{p.pump.displacement_m3_rev * 1e6:.2g} cm³/rev pump"),
        HafoMassItem("valve_block", p.valve_block_mass_kg, supply_site,
                     ("servo" if p.circuit == "servo" else "two on/off")
                     + " valve(s), check, unloading and relief valves, reservoir"),
        HafoMassItem("electronics", 0.35, supply_site, "motor and valve drivers, sensors"),
        HafoMassItem("enclosure_belt", 0.58, supply_site, "housing and waist belt"),
        HafoMassItem("hoses", _hose_mass_kg(p), supply_site, "two hoses with oil")]
    if p.accumulator_enabled:
        items.append(HafoMassItem("accumulator", p.accumulator_mass_kg, supply_site,
                                  f"{p.accumulator.gas_volume_m3 * 1e6:.0f} cm³ gas "
                                  "accumulator"))
    return tuple(items)


def valve_circuit(params: ValveAnkleParams) -> Circuit:
    """The circuit description of one side of a valve orthosis (issue 18): the components and
    nodes of the servo or digital circuit (those of the hand-written kernel it replaced,
    ``tests/kernel_reference/valve_kernel.py``).

    Nodes: ``bus``, ``shaft``, ``pump_out`` (pump outlet, relief, unloading or switching
    valve, check valve), ``rail`` (behind the check valve: manifold or accumulator, servo
    valve's P or the digital circuit's open P→A edge; the unloading valve's pilot and the
    compensator's sense line), ``tank`` (the pressurised reservoir), ``port_a``/``port_b``
    (valve ports with their make-up check valves), ``chamber_a``/``chamber_b``, ``ankle``.

    Which fields reach which component: the shared parts (fluid, motor, driver, pump, hoses,
    cylinders, relief, make-up valves, port volumes, battery, thermal) as in the HAFO; the
    servo circuit's ``servo_valve`` and ``servo_coil_power_w``; the digital circuit's
    ``switching_valve``, ``release_valve_area_m2`` and ``pwm_frequency_hz``, its open port
    edges sized as the servo valve at full opening; the check valve, ``manifold_volume_m3``
    (the accumulator's port volume when there is one), the accumulator and
    ``accumulator_blend_pa``; ``unloading`` with the unloading supply, the compensator fields
    with the variable-displacement one, the rail set points with pressure control;
    ``valve_control`` (the controller's own gains) in the controller, with its set points
    (:data:`CONTROL_SET_BY_PRESET`) from ``motor_speed_rad_s``, ``max_torque_nm``, the supply
    mode and rail set points and the oil's density.
    Fields of a supply or circuit not chosen describe no component (the old kernel packed
    them and kept, e.g., a shut unloading valve leaking in every servo supply). Not in the
    circuit at all: the HAFO's flushing valve and its control gains (the valve circuits have
    neither), the masses, and ``initial_supply_pressure_pa`` (an initial state:
    :func:`valve_initial_state`).

    The servo valve's metering edges are rounded over ± 1 % of the stroke at least (the old
    kernel rounded each over 2 % whatever ``opening_smoothing_m`` says: a sharp edge stalls
    the step's Newton iteration at null)."""
    p = params
    if not isinstance(p, ValveAnkleParams):
        raise CircuitError(f"valve_circuit(params = {type(p).__name__}); allowed: "
                           "ValveAnkleParams")
    digital = p.circuit == "digital"
    sv = p.servo_valve
    comps = [
        _cc.Battery("battery", _cc.BatterySourceParams(battery=p.battery,
                                                       initial_soc=p.initial_soc)),
        _cc.MotorDriver("motor", _cc.MotorDriver.Params(motor=p.motor, driver=p.driver)),
        _cc.Volume("pump_port", _cc.VolumeParams(volume_m3=p.pump_port_volume_m3)),
        _cc.ReliefValve("relief", p.relief),
        _cc.Reservoir("tank", _cc.ReservoirParams(pressure_pa=p.reservoir_pressure_pa)),
        _cc.CheckValve("check", _cc.CheckValveParams(
            conductance_m3_s_pa=p.check_valve_conductance_m3_s_pa,
            cracking_pa=p.check_valve_cracking_pa, band_pa=2e4)),
        _cc.Volume("port_a", _cc.VolumeParams(volume_m3=p.pump_port_volume_m3)),
        _cc.Volume("port_b", _cc.VolumeParams(volume_m3=p.pump_port_volume_m3)),
        _cc.Hose("hose_a", p.hose), _cc.Hose("hose_b", p.hose),
        _cc.PulleyCylinders("cylinders", _cc.PulleyCylinders.Params(
            cylinder=p.cylinder, count=p.cylinders, pulley_radius_m=p.pulley_radius_m)),
    ]
    for side in ("a", "b"):
        comps.append(_cc.CheckValve(f"makeup_{side}", _cc.CheckValveParams(
            conductance_m3_s_pa=p.makeup_conductance_m3_s_pa, cracking_pa=0.0,
            band_pa=p.makeup_band_pa)))
    pump = p.pump.replace(variable_displacement_enabled=False)
    if p.supply_mode == "variable_displacement":
        comps.append(_cv.VariablePump("pump", _cv.VariablePumpParams(
            pump=pump, compensator_pressure_pa=p.compensator_pressure_pa,
            compensator_band_pa=p.compensator_band_pa,
            min_displacement_fraction=p.min_displacement_fraction)))
    else:
        comps.append(_cc.Pump("pump", pump))
    if p.accumulator_enabled:
        comps.append(_cv.SupplyAccumulator("accumulator", _cv.SupplyAccumulatorParams(
            accumulator=p.accumulator.replace(port_volume_m3=p.manifold_volume_m3),
            engage_band_pa=p.accumulator_blend_pa)))
        rail_store = "accumulator.port"
    else:
        comps.append(_cc.Volume("manifold", _cc.VolumeParams(volume_m3=p.manifold_volume_m3)))
        rail_store = "manifold.port"
    nodes = {
        "bus": ["battery.bus", "motor.bus"],
        "shaft": ["motor.shaft", "pump.shaft"],
        "pump_out": ["pump.a", "pump_port.port", "relief.a", "check.a"],
        "tank": ["tank.port", "pump.b", "relief.b", "makeup_a.a", "makeup_b.a"],
        "rail": ["check.b", rail_store],
        "port_a": ["port_a.port", "hose_a.a", "makeup_a.b"],
        "port_b": ["port_b.port", "hose_b.a", "makeup_b.b"],
        "chamber_a": ["hose_a.b", "cylinders.a"],
        "chamber_b": ["hose_b.b", "cylinders.b"],
        "ankle": ["cylinders.joint"],
    }
    if p.supply_mode == "variable_displacement":
        nodes["rail"].append("pump.sense")
    if p.supply_mode == "unloading":
        comps.append(_cv.UnloadingValve("unloading", p.unloading))
        nodes["pump_out"].append("unloading.a")
        nodes["tank"].append("unloading.b")
        nodes["rail"].append("unloading.pilot")
    # the controller: the preset's gains with the set points its own fields give
    loop = replace_named(p.valve_control, {
        name: (p.supply_mode == "pressure_control" if field == "supply_mode"
               else _dotted(p, field)) for name, field in CONTROL_SET_BY_PRESET.items()})
    if digital:
        if p.servo_coil_power_w != 0.0:
            raise CircuitError(f"servo_coil_power_w = {p.servo_coil_power_w!r} with circuit = "
                               "'digital': the digital circuit has no servo valve (allowed: 0)")
        edge = OrificeParams(area_m2=p.servo_full_area_m2,
                             discharge_coefficient=sv.discharge_coefficient,
                             transition_pressure_pa=sv.transition_pressure_pa)
        comps += [
            _cv.FixedOrifice("edge_pa", edge), _cv.FixedOrifice("edge_bt", edge),
            _cv.OnOffValve("switching", _cv.OnOffComponentParams(
                valve=p.switching_valve, normally_open=True)),
            _cv.OnOffValve("release", _cv.OnOffComponentParams(
                valve=p.switching_valve.replace(max_area_m2=p.release_valve_area_m2),
                normally_open=False))]
        nodes["bus"] += ["switching.bus", "release.bus"]
        nodes["pump_out"].append("switching.a")
        nodes["tank"] += ["switching.b", "release.b", "edge_bt.b"]
        nodes["rail"].append("edge_pa.a")
        nodes["port_a"] += ["edge_pa.b", "release.a"]
        nodes["port_b"].append("edge_bt.a")
        controller = _vc.DigitalValveTorque(
            _vc.DigitalValveTorqueParams(pwm_frequency_hz=p.pwm_frequency_hz, **{
                f.name: getattr(loop, f.name) for f in dataclasses.fields(loop)}),
            motor="motor", pump="pump", switching="switching", release="release",
            actuator="cylinders")
    else:
        smoothing = max(sv.opening_smoothing_m, 0.01 * sv.spool_max_m)
        comps.append(_cv.ServoValve("servo", _cv.ServoValveComponentParams(
            valve=sv.replace(opening_smoothing_m=smoothing),
            coil_power_w=p.servo_coil_power_w)))
        nodes["bus"].append("servo.bus")
        nodes["tank"].append("servo.t")
        nodes["rail"].append("servo.p")
        nodes["port_a"].append("servo.a")
        nodes["port_b"].append("servo.b")
        controller = _vc.ServoValveTorque(loop, motor="motor", pump="pump", valve="servo",
                                          actuator="cylinders")
    return Circuit(
        f"valve_{p.circuit}_{p.supply_mode}", comps, nodes, controller, fluid=p.fluid,
        thermal=ThermalParams(heat_capacity_j_k=p.heat_capacity_j_k,
                              thermal_resistance_k_w=p.thermal_resistance_k_w,
                              ambient_temperature_k=p.ambient_temperature_k),
        options=CircuitOptions(initial_pressure_pa=p.reservoir_pressure_pa))


def valve_initial_state(params: ValveAnkleParams) -> dict:
    """Initial values of the :func:`valve_circuit` states that do not start at the tank
    pressure or at rest (state label → value), as :class:`ValveAfoDevice` starts the old
    kernel: the rail charged to ``initial_supply_pressure_pa`` (at least the tank's), the
    motor at its set speed unless a pressure loop sets it."""
    out = {"rail": max(params.initial_supply_pressure_pa, params.reservoir_pressure_pa)}
    if params.supply_mode != "pressure_control":
        out["shaft"] = params.motor_speed_rad_s
    return out


#: ledger losses of the servo circuit: each named loss the sum of these component losses
SERVO_LOSS_TABLE = {
    "battery_internal": ("battery.internal",), "driver": ("motor.driver",),
    "motor_copper": ("motor.copper",), "motor_friction": ("motor.friction",),
    "pump_volumetric": ("pump.volumetric",), "pump_mechanical": ("pump.mechanical",),
    "unloading": ("unloading.throttling",), "check_valve": ("check.throttling",),
    "relief": ("relief.throttling",), "servo_valve_throttling": ("servo.throttling",),
    "makeup_valves": ("makeup_a.throttling", "makeup_b.throttling"),
    "line": ("hose_a.line", "hose_b.line"), "seal_friction": ("cylinders.seal_friction",),
    "leakage": ("cylinders.leakage",), "valve_actuators": ("servo.coil",)}
#: the digital circuit's (its unloading valve is the PWM switching valve; the metering is
#: done by the release valve and the open port edges)
DIGITAL_LOSS_TABLE = {
    "battery_internal": ("battery.internal",), "driver": ("motor.driver",),
    "motor_copper": ("motor.copper",), "motor_friction": ("motor.friction",),
    "pump_volumetric": ("pump.volumetric",), "pump_mechanical": ("pump.mechanical",),
    "switching_valve": ("switching.throttling",), "check_valve": ("check.throttling",),
    "relief": ("relief.throttling",),
    "release_valve_and_ports": ("release.throttling", "edge_pa.throttling",
                                "edge_bt.throttling"),
    "makeup_valves": ("makeup_a.throttling", "makeup_b.throttling"),
    "line": ("hose_a.line", "hose_b.line"), "seal_friction": ("cylinders.seal_friction",),
    "leakage": ("cylinders.leakage",), "valve_actuators": ("switching.coil", "release.coil")}


#: the valve circuits' names for the log columns
VALVE_LOG_NAMES = {"actuated_input": "motor_command_v", "motor.current_a": "motor_current_a",
                   "shaft": "motor_speed_rad_s", "pump_out": "pump_pa", "rail": "supply_pa",
                   "port_a": "port_a_pa", "port_b": "port_b_pa",
                   "chamber_a": "chamber_a_pa", "chamber_b": "chamber_b_pa",
                   "servo.spool": "valve_position",
                   "unloading.position": "unloading_valve_position",
                   # the digital circuit: the PWM switching valve unloads the pump, the
                   # release valve meters the flow out of line A
                   "switching.position": "unloading_valve_position",
                   "release.position": "valve_position",
                   "controller.valve_command": "valve_command"}
#: the valve circuits' ledger stores
VALVE_STORE_TABLE = {
    "inductance": ("state.motor.current_a",), "rotor": ("rotor.shaft",),
    "oil": ("oil.pump_out", "oil.rail", "oil.port_a", "oil.port_b", "oil.chamber_a",
            "oil.chamber_b"),
    "reservoir": ("reservoir.tank",), "end_stops": ("cylinders.end_stops",),
    "series_spring": ("cylinders.series_spring",),
    # the void opened where a pressure was clipped at the vapour floor (zero without)
    "cavitation": ("cavitation",),
    # the bus energy beyond the battery's matched-load power (zero without; negative)
    "battery_overload": ("battery_overload",)}
#: the valves' coils draw from the bus too: the hydraulic energy the pump delivered is the
#: input less the drive train's losses and the coils' power
VALVE_UPSTREAM_LOSSES = HAFO_LEDGER.upstream_losses + ("valve_actuators",)
#: the output channels of a valve circuit's bench replay
VALVE_OUTPUTS = ("pump_pressure_pa", "supply_pressure_pa", "pressure_a_pa", "pressure_b_pa",
                 "chamber_a_pa", "chamber_b_pa", "valve_position", "ankle_torque_nm",
                 "motor_current_a", "motor_speed_rad_s", "fluid_temperature_k")


def valve_spec(params: ValveAnkleParams = None, name: str = "valve") -> DeviceSpec:
    """The valve orthosis of ``params`` as a device spec: :func:`valve_circuit` started from
    :func:`valve_initial_state`, the valve command as its open-loop command (the controller's
    ``valve_command_on`` switch hands the metering valve to it), the servo or digital
    circuit's ledger, the rail's peak pressure and the pumped volume as extra ledger
    figures, and the mass budget."""
    params = VALVE_PRESETS["valve"] if params is None else params
    if not isinstance(params, ValveAnkleParams):
        raise ParameterError(f"device params = {type(params).__name__}; allowed: "
                             "ValveAnkleParams")
    losses = SERVO_LOSS_TABLE if params.circuit == "servo" else DIGITAL_LOSS_TABLE
    return DeviceSpec(
        name=name, params=params, circuit=valve_circuit(params),
        summary=f"valve-controlled AFO ({params.circuit} circuit, {params.supply_mode} "
                "supply)",
        open_loop_channel="valve_command", open_loop_switch="controller.valve_command_on",
        initial_state=valve_initial_state(params), outputs=VALVE_OUTPUTS,
        log_names=VALVE_LOG_NAMES,
        ledger=LedgerGroups(losses=losses, stores=VALVE_STORE_TABLE,
                            upstream_losses=VALVE_UPSTREAM_LOSSES,
                            upstream_stores=HAFO_LEDGER.upstream_stores),
        ledger_extras={"peak_supply_pressure_pa": ("state_peaks", "rail"),
                       "pump_volume_m3": ("probe_integrals", "pump.flow_m3_s")},
        current_limit_a=params.driver.current_limit_a,
        masses=valve_mass_budget(params), mass_label="valve_afo")


class ValveAfoDevice(CircuitDevice):
    """A :class:`ValveAnkleParams` orthosis worn on one or both ankles: a
    :class:`~afo_mj.circuits.device.CircuitDevice` of :func:`valve_spec` (``params``).

    ``profile``: assistance torque vs stride phase, or ``impedance``: rows of
    :func:`afo_mj.control.impedance.impedance_table` (passive-AFO emulation, clutched spring,
    per-phase impedance), or ``torque_fn(t, θ, θ̇)`` (bench; with ``mode="valve_command"`` it
    returns the valve command ``u ∈ [−1, 1]`` instead, open loop: the controller's
    ``valve_command_on`` switch); none of them: transparent (zero torque commanded).
    """

    def __init__(self, params: ValveAnkleParams = VALVE_PRESETS["valve"], sides=("right",),
                 profile=None, impedance=None, timestep_s: float = 1e-3, max_steps: int = 0,
                 torque_fn=None, min_stride_s: float = 0.4, max_stride_s: float = 3.0,
                 mode: str = "torque"):
        if mode not in ("torque", "valve_command"):
            raise ParameterError(f"device.mode = {mode!r}; allowed: torque, valve_command "
                                 "(torque_fn returns the valve command u in [-1, 1])")
        if mode == "valve_command" and torque_fn is None:
            raise ParameterError("device.mode = 'valve_command' needs a torque_fn giving u")
        if impedance is not None and profile is not None:
            raise ParameterError("device: both profile and impedance given; allowed: one")
        spec = valve_spec(params)
        check_sides(sides)
        self.mode = mode
        super().__init__(spec, sides=sides, timestep_s=timestep_s, torque_fn=torque_fn,
                         profile=profile, max_steps=max_steps, min_stride_s=min_stride_s,
                         max_stride_s=max_stride_s, impedance=impedance,
                         open_loop=mode == "valve_command")
