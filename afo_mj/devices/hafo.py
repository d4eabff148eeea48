"""The HAFO: untethered pump-controlled hydraulic ankle-foot orthosis (seed ch. 6).

Published figures it must reproduce (Neubauer & Durfee 2016; ``shared/reference/facts.md``):
65 N·m assistance torque, 105 deg/s no-load speed, 3.3 kg in all of which 0.97 kg is worn at
the ankle, design target 90 N·m at 13.8 MPa. The unpublished parameters of :data:`HAFO` are
chosen so that these figures come out of the model (``benchmarks``/bench scenario measure
them); the reasoning, item by item:

* **Pulley and cylinders** — design torque ``τ = p A_e r``: 90 N·m at 13.8 MPa needs
  ``A_e r = 6.52e-6 m³``. An ankle pulley of radius 40 mm (clears the malleoli, keeps cable
  tension below 2.3 kN) and two piston-cable cylinders (antagonistic, one each side of the
  pulley, hydraulically cross-connected so both pull the same way) of 10.4 mm bore with a
  2.0 mm cable give ``A_e = 2 · π/4 (10.4² − 2²) mm² = 163.6 mm²`` and ``A_e r = 6.545e-6 m³``:
  90 N·m at 13.75 MPa. Stroke 45 mm covers ±32° of ankle motion.
* **Pump** — the library's small external gear pump (0.2 cm³/rev, η_v ≈ 0.93, η_m ≈ 0.92 at
  10 MPa): at 105 deg/s the ankle takes 0.72 L/min, 3600 rpm of this pump.
* **Battery** — 6S Li-ion (22.5 V open circuit at the 50 % state of charge the bench figures
  are quoted at), 3 Ah, 0.40 kg.
* **Motor** — a 100 W class brushless motor: torque constant 0.055 N·m/A so that the no-load
  speed at full duty, ``(0.95 · 22.5 V − R i_0)/K ≈ 384 rad/s``, drives the ankle at
  ``384 · d / (A_e r) ≈ 107 deg/s`` before pump slip (≈ 105 deg/s after); 0.6 Ω, 0.1 mH.
* **Current limit** — 6.2 A: at stall the pump needs ``d Δp (1 + C_f)`` + drag for
  ``Δp = 65 N·m / (A_e r) = 9.9 MPa``, ≈ 0.34 N·m, i.e. 6.2 A at K = 0.055. So the 65 N·m
  assistance torque is the driver's current limit, and the 90 N·m design torque is what the
  structure and the relief (cracking at 14.0 MPa) are sized for.
* **Hoses** — 1.1 m each (waist pack to ankle), 3.2 mm bore thermoplastic micro-hose with a
  volumetric wall modulus of 1.5 GPa: Reynolds number ≈ 80 at the rated flow (laminar), 0.3 MPa
  drop per hose at 105 deg/s in 25 °C VG 32.
* **Oil** — ISO VG 32 (low enough viscosity for the cold start of a worn device, high enough for
  pump slip), 0.1 % entrained air after bleeding.
* **Charge** — a 1.5 MPa (gauge) bootstrap reservoir (closed hydrostatic loops run 1–2 MPa
  of charge so that the hose drop at full ankle speed never cavitates a chamber) feeds the
  low-pressure line through a flushing (shuttle) valve, and make-up check valves refill either line
  when the ankle outruns the pump.
* **Masses** — :data:`HAFO_MASSES`, item by item; hose mass is computed (wall 45 g/m + oil).

The device is stepped as a generated circuit (:func:`hafo_circuit`, :mod:`afo_mj.circuits`);
the hand-written kernel it replaced is kept only as the equivalence tests' reference
(``tests/kernel_reference``).
Torque control is through motor voltage (:class:`~afo_mj.circuits.controllers.PumpTorque`);
its gains (``control``, the controller's own
:class:`~afo_mj.circuits.controllers.PumpTorqueGains`) give the isometric torque-step response
of the bench scenario (``scenarios/bench_hafo.toml``).
"""

from __future__ import annotations

import dataclasses

import numpy as np

from afo_mj.circuits.controllers import PumpTorqueGains
from afo_mj.circuits.device import CircuitDevice
from afo_mj.circuits.device_spec import DeviceSpec, LedgerGroups, MassItem
from afo_mj.hydraulics.battery import BatteryParams
from afo_mj.hydraulics.conduit import HoseParams
from afo_mj.hydraulics.cylinder import CylinderParams
from afo_mj.hydraulics.fluid import ATMOSPHERIC_PRESSURE_PA, ISO_VG32, Fluid, FluidParams
from afo_mj.hydraulics.motor import DriverParams, MotorParams
from afo_mj.hydraulics.params import ParameterError, Parameters, param, replace_named
from afo_mj.hydraulics.pump import GEAR_PUMP_SMALL, PumpParams
from afo_mj.hydraulics.relief_valve import ReliefValveParams
from afo_mj.hydraulics.seal import OringSealParams

__all__ = ["PumpAnkleParams", "HafoMassItem", "HAFO", "HAFO_MASSES",
           "HafoDevice", "mass_budget", "hafo_params",
           "HAFO_GAIT", "PRESETS", "hafo_spec", "HAFO_LOG_NAMES", "HAFO_LEDGER",
           "HAFO_OUTPUTS"]


@dataclasses.dataclass(frozen=True)
class PumpAnkleParams(Parameters):
    """One side of a pump-controlled ankle orthosis, component by component."""

    fluid: FluidParams = ISO_VG32.replace(air_fraction=0.001)
    motor: MotorParams = MotorParams(resistance_ohm=0.6, inductance_h=0.1e-3,
                                     torque_constant_nm_a=0.055, rotor_inertia_kg_m2=5e-7,
                                     coulomb_torque_nm=0.004, viscous_coefficient_nm_s_rad=2e-6,
                                     max_speed_rad_s=1700.0, mass_kg=0.14)
    driver: DriverParams = DriverParams(current_limit_a=6.2, max_duty=0.95,
                                        on_resistance_ohm=0.02, quiescent_power_w=0.3)
    pump: PumpParams = GEAR_PUMP_SMALL
    pump_mass_kg: float = param(0.25, unit="kg", lo=0.01, hi=5.0,
                                doc="pump with its motor coupling (mass budget)")
    hose: HoseParams = HoseParams(length_m=1.1, bore_m=3.2e-3, wall_bulk_modulus_pa=1.5e9)
    cylinder: CylinderParams = CylinderParams(
        kind="piston_cable", bore_m=10.4e-3, rod_diameter_m=2.0e-3, stroke_m=0.045,
        dead_volume_a_m3=0.3e-6, dead_volume_b_m3=0.3e-6, piston_mass_kg=0.02,
        radial_clearance_m=5e-6, land_length_m=5e-3,
        piston_seal=OringSealParams(cross_section_m=1.78e-3),
        rod_seal=OringSealParams(cross_section_m=1.0e-3))
    cylinders: float = param(2.0, unit="-", lo=1.0, hi=4.0, doc="cylinders on the pulley")
    pulley_radius_m: float = param(0.040, unit="m", lo=0.005, hi=0.2, doc="ankle pulley radius r")
    relief: ReliefValveParams = ReliefValveParams(cracking_dp_pa=14.0e6, override_dp_pa=1.0e6,
                                                  max_area_m2=1.0e-6, leakage_area_m2=1e-11)
    flushing_conductance_m3_s_pa: float = param(5e-12, unit="m^3/(s Pa)", lo=1e-15, hi=1e-6,
                                                doc="flushing valve conductance (open)")
    makeup_conductance_m3_s_pa: float = param(1e-9, unit="m^3/(s Pa)", lo=1e-15, hi=1e-6,
                                              doc="make-up check valve conductance (open)")
    makeup_band_pa: float = param(2e4, unit="Pa", lo=1e2, hi=1e6,
                                  doc="opening corner width of the make-up check valves")
    reservoir_pressure_pa: float = param(1.5e6, unit="Pa", lo=0.0, hi=5e6,
                                         doc="charge reservoir gauge pressure")
    flushing_band_pa: float = param(0.05e6, unit="Pa", lo=1e3, hi=1e6,
                                    doc="line pressure difference over which the shuttle shifts")
    pump_port_volume_m3: float = param(0.3e-6, unit="m^3", lo=1e-9, hi=1e-3,
                                       doc="oil volume in each pump port and manifold")
    battery: BatteryParams = BatteryParams(name="6S 3 Ah Li-ion NMC", capacity_ah=3.0,
                                           cells_series=6.0, internal_resistance_ohm=0.10,
                                           max_current_a=20.0, mass_kg=0.40)
    initial_soc: float = param(0.5, unit="-", lo=0.0, hi=1.0, doc="battery state of charge at t=0")
    heat_capacity_j_k: float = param(240.0, unit="J/K", lo=1.0, hi=1e6,
                                     doc="oil (≈35 cm³) plus manifold/pump metal")
    thermal_resistance_k_w: float = param(3.0, unit="K/W", lo=0.01, hi=1e3,
                                          doc="oil to ambient through pack and hoses")
    ambient_temperature_k: float = param(298.15, unit="K", lo=230.0, hi=330.0)
    #: the torque loop's gains (:class:`~afo_mj.circuits.controllers.PumpTorque`); its
    #: ``spring_feedforward`` is for a spring-return cylinder and stays 0 here
    control: PumpTorqueGains = PumpTorqueGains()

    def check(self) -> None:
        if self.cylinder.kind != "piston_cable":
            self.fail("cylinder", "the ankle actuator uses piston_cable cylinders")
        if self.control.spring_feedforward != 0.0:
            raise ParameterError(f"{type(self).__name__}.control.spring_feedforward = "
                                 f"{self.control.spring_feedforward!r}: the piston-cable "
                                 "cylinders have no return spring; allowed: 0")
        if self.reservoir_pressure_pa >= self.relief.cracking_dp_pa:
            self.fail("reservoir_pressure_pa", "must be below relief.cracking_dp_pa")

    # -- derived figures ---------------------------------------------------------------------
    @property
    def effective_area_m2(self) -> float:
        return self.cylinders * self.cylinder.area_a_m2

    @property
    def torque_per_pressure_m3(self) -> float:
        """``A_e r``: ankle torque per pascal of line pressure difference."""
        return self.effective_area_m2 * self.pulley_radius_m

    @property
    def hose_volume_m3(self) -> float:
        return self.hose.volume_m3

    @property
    def oil_volume_m3(self) -> float:
        cyl = self.cylinders * (self.cylinder.dead_volume_a_m3 + self.cylinder.dead_volume_b_m3
                                + self.cylinder.area_a_m2 * self.cylinder.stroke_m)
        return 2 * self.hose_volume_m3 + cyl + 2 * self.pump_port_volume_m3

    def hydraulic_stiffness_nm_per_rad(self, pressure_pa: float = 1e6) -> float:
        """Ankle stiffness of the oil with the pump held, ``(A_e r)² (1/C_a + 1/C_b)`` at
        mid-stroke (Merritt §5.3; ``C`` = chamber + hose + port volume / B + hose wall)."""
        fl = Fluid(self.fluid)
        b = float(fl.bulk_modulus_pa(pressure_pa + ATMOSPHERIC_PRESSURE_PA))
        v_ch = (self.cylinder.dead_volume_a_m3
                + self.effective_area_m2 * self.cylinder.stroke_m / 2)
        c_line = ((v_ch + self.hose_volume_m3 + self.pump_port_volume_m3) / b
                  + self.hose_volume_m3 / self.hose.wall_bulk_modulus_pa)
        return self.torque_per_pressure_m3 ** 2 * 2.0 / c_line


HAFO_ACTUATOR = PumpAnkleParams()


#: a part of the mass budget (the circuits' :class:`~afo_mj.circuits.device_spec.MassItem`)
HafoMassItem = MassItem


def _hose_mass_kg(p: PumpAnkleParams, wall_kg_m: float = 0.045) -> float:
    oil = p.fluid.density_kg_m3 * p.hose_volume_m3
    return 2 * (wall_kg_m * p.hose.length_m + oil)


def mass_budget(p: PumpAnkleParams = HAFO_ACTUATOR) -> tuple[HafoMassItem, ...]:
    """The HAFO's parts with their masses and where they are worn (one side)."""
    return (
        # ankle: 0.97 kg
        HafoMassItem("cylinders", 0.26, "shank_cuff", "two 10.4 mm piston-cable cylinders, "
                     "aluminium bodies, with oil"),
        HafoMassItem("shank_cuff_struts", 0.31, "shank_cuff", "cuff, uprights, cable guides"),
        HafoMassItem("pulley_bearings", 0.12, "ankle_axis", "40 mm pulley, axle, bearings"),
        HafoMassItem("foot_plate", 0.28, "foot_plate", "carbon foot plate and stirrup"),
        # waist: power supply
        HafoMassItem("battery", p.battery.mass_kg, "waist", p.battery.name),
        HafoMassItem("motor", p.motor.mass_kg, "waist", "100 W class brushless motor"),
        HafoMassItem("pump", p.pump_mass_kg, "waist",
                     f"{p.pump.displacement_m3_rev * 1e6:.2g} cm³/rev gear pump"),
        HafoMassItem("manifold_reservoir_valves", 0.50, "waist",
                     "manifold, charge reservoir, relief and flushing valves"),
        HafoMassItem("electronics", 0.35, "waist", "motor driver, controller, sensors"),
        HafoMassItem("enclosure_belt", 0.58, "waist", "housing and waist belt"),
        HafoMassItem("hoses", _hose_mass_kg(p), "waist",
                     "two hoses (45 g/m wall + oil), lumped with the pack"),
    )


HAFO_MASSES = mass_budget()
HAFO = HAFO_ACTUATOR

#: The HAFO architecture sized for normal walking (preset ``hafo_gait``). The published
#: prototype's 105 deg/s no-load speed is about half the 216 deg/s peak plantarflexion
#: velocity of a 75 kg walker (``facts.md``), and back-driving it past that speed turns the
#: motor into a generator whose EMF exceeds the bus: the pump then brakes the ankle at up to
#: the relief pressure (the gait scenarios measure ≈ 60 J/stride of braking in transparent
#: mode). This variant keeps every other choice of :data:`HAFO` and changes only what sets
#: the speed:
#:
#: * pump 0.6 cm³/rev (three times the displacement, same gear-pump loss coefficients):
#:   no-load ankle speed ≈ 3 × 105 ≈ 315 deg/s, above the walker's push-off velocity;
#:   0.35 kg instead of 0.25 kg;
#: * driver current limit 18.6 A (three times 6.2 A) so the stall torque stays 65 N·m at the
#:   same pressure; a 200 W class motor of the same torque constant (same no-load speed per
#:   volt) with a third of the winding resistance (0.2 Ω) so its copper loss at the limit
#:   (69 W) matches the prototype motor's at its own; rotor 1.2e-6 kg m², 0.30 kg;
#: * battery rated for 30 A (high-power 18650 cells, same 6S 3 Ah, same mass);
#: * hoses 4.2 mm bore: three times the flow through the 3.2 mm hoses would cost nine times
#:   the laminar line loss; ``3^¼ · 3.2 mm ≈ 4.2 mm`` keeps the pressure drop per hose at
#:   full speed where the prototype's is (Reynolds number ≈ 180, still laminar);
#: * pressure-loop gains divided by 3 (the loop gain is pump flow per pressure error).
#:
#: Mass: 3.58 kg in all, 0.97 kg at the ankle (unchanged: the ankle parts are the same).
HAFO_GAIT = HAFO_ACTUATOR.replace(
    pump=GEAR_PUMP_SMALL.replace(displacement_m3_rev=0.6e-6,
                                 rotor_inertia_kg_m2=3.0 * GEAR_PUMP_SMALL.rotor_inertia_kg_m2),
    pump_mass_kg=0.35,
    motor=HAFO_ACTUATOR.motor.replace(resistance_ohm=0.2, inductance_h=0.05e-3,
                                      rotor_inertia_kg_m2=1.2e-6, mass_kg=0.30),
    driver=HAFO_ACTUATOR.driver.replace(current_limit_a=18.6),
    battery=HAFO_ACTUATOR.battery.replace(max_current_a=30.0),
    hose=HAFO_ACTUATOR.hose.replace(bore_m=4.2e-3),
    control=PumpTorqueGains(pressure_gain_rad_s_per_pa=0.4e-5,
                            pressure_integral_gain_rad_per_pa=4e-4 / 3.0))

#: Device presets by scenario name.
PRESETS = {"hafo": HAFO, "hafo_gait": HAFO_GAIT}


def hafo_params(overrides: dict | None = None, preset: str = "hafo") -> PumpAnkleParams:
    """A preset (:data:`PRESETS`) with dotted-name overrides (``{"hose.length_m": 2.2}``),
    validated."""
    if preset not in PRESETS:
        raise ParameterError(f"device.preset = {preset!r}; allowed: {', '.join(PRESETS)}")
    base = PRESETS[preset]
    return replace_named(base, overrides or {}) if overrides else base


def hafo_circuit(p: PumpAnkleParams = HAFO_ACTUATOR, mode: str = "torque",
                 initial_pressure_pa: float | None = None, name: str = "hafo"):
    """The pump-controlled ankle actuator of ``p`` as a circuit description
    (:mod:`afo_mj.circuits`): battery → motor + driver → reversible pump → two hoses → the
    pulley cylinders; cross-port relief valves, a flushing valve from the charge reservoir
    into the lower line, a make-up check valve into each line; the HAFO torque loop
    (``mode="voltage"``: the command is the motor voltage). Every field of ``p`` reaches the
    circuit or is a mass-budget figure (``pump_mass_kg``)."""
    from afo_mj.circuits.circuit import Circuit, CircuitOptions, ThermalParams
    from afo_mj.circuits.components import (
        Battery, BatterySourceParams, CheckValve, CheckValveParams, FlushingValve,
        FlushingValveParams, Hose, MotorDriver, PulleyCylinders, Pump, ReliefValve,
        Reservoir, ReservoirParams, Volume, VolumeParams)
    from afo_mj.circuits.controllers import OpenLoop, PumpTorque
    if mode not in ("torque", "voltage"):
        raise ParameterError(f"device.mode = {mode!r}; allowed: torque, voltage")
    port = VolumeParams(volume_m3=p.pump_port_volume_m3)
    makeup = CheckValveParams(conductance_m3_s_pa=p.makeup_conductance_m3_s_pa,
                              cracking_pa=0.0, band_pa=p.makeup_band_pa)
    comps = [
        Battery("battery", BatterySourceParams(battery=p.battery, initial_soc=p.initial_soc)),
        MotorDriver("motor", MotorDriver.Params(motor=p.motor, driver=p.driver)),
        Pump("pump", p.pump),
        Volume("port_a", port), Volume("port_b", port),
        Hose("hose_a", p.hose), Hose("hose_b", p.hose),
        ReliefValve("relief_ab", p.relief), ReliefValve("relief_ba", p.relief),
        Reservoir("charge", ReservoirParams(pressure_pa=p.reservoir_pressure_pa)),
        FlushingValve("flushing", FlushingValveParams(
            conductance_m3_s_pa=p.flushing_conductance_m3_s_pa,
            shift_band_pa=p.flushing_band_pa)),
        CheckValve("makeup_a", makeup), CheckValve("makeup_b", makeup),
        PulleyCylinders("cylinders", PulleyCylinders.Params(
            cylinder=p.cylinder, count=p.cylinders, pulley_radius_m=p.pulley_radius_m)),
    ]
    nodes = {
        "bus": ["battery.bus", "motor.bus"],
        "shaft": ["motor.shaft", "pump.shaft"],
        "line_a": ["pump.a", "port_a.port", "hose_a.a", "relief_ab.a", "relief_ba.b",
                   "flushing.a", "makeup_a.b"],
        "line_b": ["pump.b", "port_b.port", "hose_b.a", "relief_ab.b", "relief_ba.a",
                   "flushing.b", "makeup_b.b"],
        "tank": ["charge.port", "flushing.s", "makeup_a.a", "makeup_b.a"],
        "chamber_a": ["hose_a.b", "cylinders.a"],
        "chamber_b": ["hose_b.b", "cylinders.b"],
        "ankle": ["cylinders.joint"],
    }
    controller = (OpenLoop() if mode == "voltage" else PumpTorque(
        p.control, motor="motor", pump="pump", actuator="cylinders"))
    p0 = p.reservoir_pressure_pa if initial_pressure_pa is None else initial_pressure_pa
    return Circuit(name, comps, nodes, controller, fluid=p.fluid,
                   thermal=ThermalParams(heat_capacity_j_k=p.heat_capacity_j_k,
                                         thermal_resistance_k_w=p.thermal_resistance_k_w,
                                         ambient_temperature_k=p.ambient_temperature_k),
                   options=CircuitOptions(initial_pressure_pa=p0))


SIDE_NAMES = ("right", "left")

#: the HAFO's names for the log columns the gait, recording and signal code read
HAFO_LOG_NAMES = {"actuated_input": "motor_command_v", "motor.current_a": "motor_current_a",
                  "shaft": "motor_speed_rad_s", "line_a": "pressure_a_pa",
                  "line_b": "pressure_b_pa", "chamber_a": "chamber_a_pa",
                  "chamber_b": "chamber_b_pa"}
#: the HAFO's ledger: named losses (chain order) and stores, each a sum of component entries
HAFO_LEDGER = LedgerGroups(
    losses={
        "battery_internal": ("battery.internal",), "driver": ("motor.driver",),
        "motor_copper": ("motor.copper",), "motor_friction": ("motor.friction",),
        "pump_volumetric": ("pump.volumetric",), "pump_mechanical": ("pump.mechanical",),
        "line": ("hose_a.line", "hose_b.line"),
        "charge_valves": ("flushing.throttling", "makeup_a.throttling",
                          "makeup_b.throttling"),
        "relief": ("relief_ab.throttling", "relief_ba.throttling"),
        "seal_friction": ("cylinders.seal_friction",), "leakage": ("cylinders.leakage",)},
    stores={
        "inductance": ("state.motor.current_a",), "rotor": ("rotor.shaft",),
        "oil": ("oil.line_a", "oil.line_b", "oil.chamber_a", "oil.chamber_b"),
        # the reservoir gives energy when it feeds the lines: its store falls
        "reservoir": ("reservoir.tank",), "end_stops": ("cylinders.end_stops",),
        # the cable between pulley and pistons (zero with the rigid cable)
        "series_spring": ("cylinders.series_spring",),
        # the void opened where a pressure was clipped at the vapour floor (zero without)
        "cavitation": ("cavitation",),
        # the bus energy beyond the battery's matched-load power (zero without; negative)
        "battery_overload": ("battery_overload",)},
    # the parts upstream of the pump's ports: the hydraulic energy the pump delivered is the
    # input less their losses and the change of their stores (energy balance of that part)
    upstream_losses=("battery_internal", "driver", "motor_copper", "motor_friction",
                     "pump_volumetric", "pump_mechanical"),
    upstream_stores=("inductance", "rotor", "battery_overload"))
#: the output channels of a HAFO bench replay (:mod:`afo_mj.experiments.bench_replay`)
HAFO_OUTPUTS = ("pressure_a_pa", "pressure_b_pa", "chamber_a_pa", "chamber_b_pa",
                "ankle_torque_nm", "motor_current_a", "motor_speed_rad_s",
                "fluid_temperature_k", "battery_current_a", "bus_voltage_v")


#: the HAFO prototype's published bench figures (Neubauer & Durfee 2016; seed ch. 6;
#: ``shared/reference/facts.md``): stall torque and no-load ankle speed (deg/s, as published)
HAFO_PUBLISHED = {"stall_torque_nm": 65.0, "no_load_speed_deg_s": 105.0}


def hafo_spec(params: PumpAnkleParams = HAFO_ACTUATOR, name: str = "hafo",
              initial_pressure_pa: float | None = None) -> DeviceSpec:
    """The pump-controlled orthosis of ``params`` as a device spec: :func:`hafo_circuit` with
    its torque loop (and the motor-voltage variant for open-loop use), the motor voltage as
    the open-loop command, the HAFO's log names, ledger and mass budget."""
    return DeviceSpec(
        name=name, params=params,
        circuit=hafo_circuit(params, "torque", initial_pressure_pa),
        open_loop_circuit=hafo_circuit(params, "voltage", initial_pressure_pa),
        summary="pump-controlled hydraulic AFO (battery, motor, reversible pump, "
                "piston-cable cylinders)",
        open_loop_channel="motor_voltage_v", outputs=HAFO_OUTPUTS, log_names=HAFO_LOG_NAMES,
        ledger=HAFO_LEDGER, current_limit_a=params.driver.current_limit_a,
        masses=mass_budget(params), mass_label="hafo", published=HAFO_PUBLISHED)


class HafoDevice(CircuitDevice):
    """HAFO worn on one or both ankles, stepped with MuJoCo (coupled-device protocol): a
    :class:`~afo_mj.circuits.device.CircuitDevice` of :func:`hafo_spec` (``params``).

    ``begin_step(t, angle, velocity, stance)`` → ``(joint_force, joint_damping)`` per walker
    side (zeros where not worn); MuJoCo steps; ``end_step(velocity_new)`` → delivered torque.
    ``profile`` is a tabulated torque vs stride phase (+dorsiflexion, N·m,
    :mod:`afo_mj.control.assistance`), ``impedance`` rows of an emulated spring/damper
    (:func:`afo_mj.control.impedance.impedance_table`), or neither (transparent: zero
    commanded torque). ``torque_fn(t, angle, velocity) -> N·m`` replaces them (bench tests);
    with ``mode="voltage"`` it returns the motor voltage instead (open-loop bench tests).
    """

    def __init__(self, params: PumpAnkleParams = HAFO_ACTUATOR, sides=("right",),
                 profile: np.ndarray | None = None, timestep_s: float = 1e-3,
                 max_steps: int = 0, mode: str = "torque", torque_fn=None,
                 initial_pressure_pa: float | None = None, min_stride_s: float = 0.4,
                 max_stride_s: float = 3.0, impedance=None):
        if mode not in ("torque", "voltage"):
            raise ParameterError(f"device.mode = {mode!r}; allowed: torque, voltage")
        check_sides(sides)
        self.mode = mode
        super().__init__(hafo_spec(params, initial_pressure_pa=initial_pressure_pa),
                         sides=sides, timestep_s=timestep_s, torque_fn=torque_fn,
                         profile=profile, max_steps=max_steps, min_stride_s=min_stride_s,
                         max_stride_s=max_stride_s, impedance=impedance,
                         open_loop=mode == "voltage")


def check_sides(sides) -> None:
    """Refuse a ``device.sides`` that is not a non-empty subset of :data:`SIDE_NAMES`."""
    bad = [s for s in sides if s not in SIDE_NAMES]
    if bad or not sides or len(set(sides)) != len(sides):
        raise ParameterError(f"device.sides = {list(sides)!r}; allowed: a non-empty subset "
                             "of ['right', 'left']")
