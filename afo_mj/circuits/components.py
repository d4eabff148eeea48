"""Circuit components: ports, states, parameters, named losses and stores, as code emitters.

A component declares its **ports** (``hydraulic`` nodes, a motor ``shaft``, the electrical
``bus``, the ``joint`` it drives), keeps its parameters in the library's frozen, validated
dataclasses, and writes its part of the circuit's right-hand side through an emitter
(:class:`afo_mj.circuits.codegen.Emitter`): the flows it sends into each node, the oil volume
it adds to them, torques on shafts and on the joint, the bus power it draws, its own states'
derivatives, and each loss by name. Every equation is a call to one law of
:mod:`afo_mj.hydraulics.laws`; nothing is written twice.

Parameter values never enter the generated code: they are packed into the parameter row, so
one compiled circuit serves every parameter set of its topology (a sweep does not recompile).
Every field of a component's parameters must be read while it emits (the emitter records the
reads) or be listed in ``metadata_fields`` (used outside the simulation: names, masses); a
field that is neither makes building the circuit fail, naming it (issue 18, "no silent
parameter"). An effect the kernel does not simulate is refused when switched on.

Sign conventions: a flow is positive *into* the node named; a joint torque is positive in the
joint's positive direction (dorsiflexion at the ankle); pressures are gauge.
"""

from __future__ import annotations

import dataclasses
import math

from afo_mj.hydraulics.accumulator import GasAccumulatorParams
from afo_mj.hydraulics.battery import BatteryParams
from afo_mj.hydraulics.conduit import HoseParams
from afo_mj.hydraulics.cylinder import CylinderParams
from afo_mj.hydraulics.motor import DriverParams, MotorParams
from afo_mj.hydraulics.params import Parameters, param
from afo_mj.hydraulics.pump import PumpParams
from afo_mj.hydraulics.relief_valve import ReliefValveParams
from afo_mj.hydraulics.seal import OringSeal, cylinder_seal_law_args, seal_law_args

HYDRAULIC, SHAFT, BUS, JOINT = "hydraulic", "shaft", "bus", "joint"


def gated(enabled: bool, value: float) -> float:
    """``value`` when its effect is ``enabled``, else 0. Both are evaluated (read) before the
    call, so a switched-off effect's parameters still count as reaching the circuit: turning
    an effect off is a choice, not a silent parameter."""
    return value if enabled else 0.0


class CircuitError(ValueError):
    """A circuit description that cannot be built (names the component, port, node or
    parameter and what is allowed)."""


class Component:
    """Base of every component: ``name`` (an identifier, unique in its circuit) and
    ``params`` (an instance of ``params_type``)."""

    kind = ""
    ports: dict = {}
    params_type: type = Parameters
    #: parameter fields used outside the simulation (labels, the worn-mass budget)
    metadata_fields: tuple = ()
    #: one-line description for the catalogue
    summary = ""

    def __init__(self, name: str, params=None):
        if not isinstance(name, str) or not name.isidentifier():
            raise CircuitError(f"component name {name!r}: allowed: a Python identifier "
                               "(letters, digits, underscores)")
        self.name = name
        if params is None:
            params = self.params_type()
        if not isinstance(params, self.params_type):
            raise CircuitError(f"component {name!r} ({self.kind}): params must be "
                               f"{self.params_type.__name__}, got {type(params).__name__}")
        self.params = params

    def emit(self, g, p) -> None:  # pragma: no cover - every component overrides it
        """Write this component's equations through emitter ``g``; ``p`` is the recording
        view of ``self.params`` (read parameters through it)."""
        raise NotImplementedError

    def __repr__(self) -> str:
        return f"{type(self).__name__}({self.name!r})"


# ---- electrical --------------------------------------------------------------------------------

@dataclasses.dataclass(frozen=True)
class BatterySourceParams(Parameters):
    """A battery pack feeding the bus, with its state of charge at the start."""

    battery: BatteryParams = BatteryParams()
    initial_soc: float = param(0.5, unit="-", lo=0.0, hi=1.0, doc="state of charge at t = 0")


class Battery(Component):
    """Li-ion pack on the bus (Thevenin model: ``V = V_oc(SOC) − R I``, the OCV a table of
    the parameters, :func:`~afo_mj.hydraulics.laws.table_interp`); the bus voltage is held over
    each step at the last step's current; the pack current follows the bus power
    (:func:`~afo_mj.hydraulics.laws.battery_current_a`). Loss: ``internal`` (``R I²``). Input
    to the ledger: chemical energy ``∫V_oc I dt``.

    Overload: a pack delivers at most its matched-load power ``V_oc²/(4R)`` (at ``I = V_oc/(2R)``,
    the terminal voltage ``V_oc/2``). The loads on the bus see the voltage held from the last
    step, not the pack's terminal equation within the step, so a load can draw more than that
    (a pack whose resistance is large for its load); the current is then capped at
    ``V_oc/(2R)`` and the bus power beyond ``V_oc²/(4R)``, which nothing supplies, is booked
    as the ledger's store ``battery_overload`` (``W_E_OVERLOAD``, negative: energy the model
    made) and the (sub-)steps are counted (``W_OVERLOAD_STEPS``, the ledger's
    ``battery_overload_steps``: a device flag and a console warning). Limiting the loads
    themselves needs the bus voltage solved with the circuit's states, which the held-input
    step does not do."""

    kind = "battery"
    ports = {"bus": BUS}
    params_type = BatterySourceParams
    metadata_fields = ("battery.name", "battery.mass_kg")
    summary = "battery pack: Thevenin cell string with an OCV(SOC) table"

    def emit(self, g, p):
        b = p.battery
        r = g.param(self, "resistance_ohm", b.internal_resistance_ohm)
        ns = g.param(self, "cells_series", b.cells_series)
        cap = g.param(self, "capacity_c", 3600.0 * b.capacity_ah)
        imax = g.param(self, "max_current_a", b.max_current_a)
        soc_tab = g.param_table(self, "ocv_soc", b.ocv_soc)
        v_tab = g.param_table(self, "ocv_cell_v", b.ocv_cell_v)
        g.initial_work("SOC", p.initial_soc)
        g.source_bus(self, "bus")
        loss = g.loss_slot(self, "internal")
        g.begin_line(f"v_oc = {ns} * table_interp(W[W_SOC], {soc_tab}, {v_tab})")
        g.begin_line(f"W[W_U + U_VBUS] = max(v_oc - {r} * W[W_I_BAT], 0.0)")
        g.close_line(f"v_oc = {ns} * table_interp(W[W_SOC], {soc_tab}, {v_tab})")
        g.close_line(f"i_bat = battery_current_a(F[F_PBUS], v_oc, {r})")
        # bus power beyond the matched-load maximum, where the law caps the current
        g.close_line(f"p_overload = F[F_PBUS] - v_oc * v_oc / (4.0 * {r})")
        g.close_line("if p_overload > 0.0:\n    W[W_E_OVERLOAD] -= h * p_overload\n"
                     "    W[W_OVERLOAD_STEPS] += 1.0")
        g.close_line("W[W_I_BAT] = i_bat")
        g.close_line(f"W[W_SOC] -= h * i_bat / {cap}")
        g.close_line("W[W_E_IN] += h * v_oc * i_bat")
        g.close_line("if i_bat > 0.0:\n    W[W_E_IN_DRAWN] += h * v_oc * i_bat")
        g.close_line("W[W_E_ABS_FLOW] += h * abs(v_oc * i_bat)")
        g.close_line(f"{loss} += h * {r} * i_bat * i_bat")
        g.monitor(self, "current_over_rating", f"abs(W[W_I_BAT]) / {imax}", close=True)


class MotorDriver(Component):
    """Brushless DC motor behind a PWM driver (averaged): ``L di/dt = v − R i − K ω`` with
    ``v`` the controller's command through the driver's current-limit and duty clamps
    (:func:`~afo_mj.hydraulics.laws.driver_voltage_v`); torque ``K i`` on the shaft against
    the friction :func:`~afo_mj.hydraulics.laws.motor_friction_torque_nm`. Bus power
    ``v i + R_on i² + P_q``. Losses: ``driver``, ``copper``, ``friction``. Store: inductance.
    Driven by the circuit's controller (its output is the voltage command)."""

    kind = "motor"
    ports = {"bus": BUS, "shaft": SHAFT}
    metadata_fields = ("motor.mass_kg",)
    summary = "brushless motor with PWM driver (current limit, duty limit)"

    @dataclasses.dataclass(frozen=True)
    class Params(Parameters):
        motor: MotorParams = MotorParams()
        driver: DriverParams = DriverParams()

    params_type = Params
    actuated = True

    def emit(self, g, p):
        m, d = p.motor, p.driver
        R = g.param(self, "R", m.resistance_ohm)
        L = g.param(self, "L", m.inductance_h)
        K = g.param(self, "K", m.torque_constant_nm_a)
        tc = g.param(self, "coulomb_nm", gated(m.friction_enabled, m.coulomb_torque_nm))
        bv = g.param(self, "viscous", gated(m.friction_enabled,
                                                m.viscous_coefficient_nm_s_rad))
        wc = g.param(self, "smoothing_speed", m.smoothing_speed_rad_s)
        wmax = g.param(self, "max_speed", m.max_speed_rad_s)
        ilim = g.param(self, "current_limit", d.current_limit_a)
        lim_on = g.param(self, "limit_on", 1.0 if d.current_limit_enabled else 0.0)
        duty = g.param(self, "max_duty", d.max_duty)
        ron = g.param(self, "r_on", d.on_resistance_ohm)
        pq = g.param(self, "quiescent_w", d.quiescent_power_w)
        g.param(self, "rotor_inertia", m.rotor_inertia_kg_m2)
        i = g.state(self, "current_a", typ=1.0, store=L)
        w = g.speed(self, "shaft")
        v = g.local(self, "v")
        tf = g.local(self, "tf")
        g.line(f"{v} = driver_voltage_v(U[U_CMD], {K} * {w}, {R}, {ilim}, {lim_on}, {duty}, "
               "U[U_VBUS])")
        g.line(f"{tf} = motor_friction_torque_nm({w}, {tc}, {bv}, {wc})")
        g.deriv(i, f"({v} - {R} * {i} - {K} * {w}) / {L}")
        g.torque(self, "shaft", f"{K} * {i} - {tf}")
        g.inertia(self, "shaft", g.param_ref(self, "rotor_inertia"))
        g.bus_power(self, "bus", f"{v} * {i} + {ron} * {i} * {i} + {pq}")
        g.loss(self, "driver", f"{ron} * {i} * {i} + {pq}", oil=False)
        g.loss(self, "copper", f"{R} * {i} * {i}", oil=False)
        g.loss(self, "friction", f"{tf} * {w}", oil=False)
        g.probe(self, "voltage_v", v)
        g.monitor(self, "speed_over_rating", f"abs({w}) / {wmax}")
        # peak winding current as a fraction of the driver's limit (the limit acts on the
        # commanded voltage, so a back-driven motor can exceed it)
        g.monitor(self, "current_over_limit", f"abs({i}) / {ilim}")


class Pump(Component):
    """Fixed-displacement pump on a shaft, from port ``b`` (inlet) to ``a`` (outlet) for a
    positive speed (reversible): flow :func:`~afo_mj.hydraulics.laws.pump_flow_m3_s`, shaft
    torque ``d Δp + T_f`` with :func:`~afo_mj.hydraulics.laws.pump_friction_torque_nm`
    (Wilson / McCandlish–Dorey; ``Δp = p_a − p_b``). Losses: ``volumetric`` (slip flow × Δp),
    ``mechanical`` (friction torque × ω). Probes: ``flow_m3_s``, ``hydraulic_power_w``
    (``Δp Q``, the power the pump gives the oil)."""

    kind = "pump"
    ports = {"shaft": SHAFT, "a": HYDRAULIC, "b": HYDRAULIC}
    params_type = PumpParams
    #: the pump type is a label: its losses are in the coefficients
    metadata_fields = ("kind",)
    summary = "fixed-displacement pump (Wilson slip and friction losses)"

    def emit(self, g, p):
        if p.variable_displacement_enabled:
            raise CircuitError(f"{self.name}.variable_displacement_enabled = True: the "
                               "circuit pump is fixed-displacement (allowed: False)")
        d = g.param(self, "d", p.displacement_m3_rev / (2.0 * math.pi))
        cs = g.param(self, "slip", gated(p.leakage_enabled, p.slip_coefficient))
        cf = g.param(self, "coulomb", gated(p.coulomb_friction_enabled,
                                                p.coulomb_coefficient))
        cv = g.param(self, "viscous", gated(p.viscous_friction_enabled,
                                                p.viscous_coefficient))
        t0 = g.param(self, "drag", p.drag_torque_nm)
        wc = g.param(self, "smoothing_speed", p.smoothing_speed_rad_s)
        wmax = g.param(self, "max_speed", p.max_speed_rad_s)
        gx = g.param(self, "extra_leak", 0.0)
        jr = g.param(self, "rotor_inertia", p.rotor_inertia_kg_m2)
        w = g.speed(self, "shaft")
        pa, pb = g.p(self, "a"), g.p(self, "b")
        dp, q, tf = g.local(self, "dp"), g.local(self, "q"), g.local(self, "tf")
        g.line(f"{dp} = {pa} - {pb}")
        g.line(f"{q} = pump_flow_m3_s({w}, {dp}, {d}, {cs}, {gx}, U[U_MU])")
        g.line(f"{tf} = pump_friction_torque_nm({w}, {dp}, {d}, {cf}, {cv}, {t0}, {wc}, "
               "U[U_MU])")
        g.flow(self, "a", q)
        g.flow(self, "b", f"-{q}")
        g.torque(self, "shaft", f"-({d} * {dp} + {tf})")
        g.inertia(self, "shaft", jr)
        g.loss(self, "volumetric", f"{dp} * ({d} * {w} - {q})")
        g.loss(self, "mechanical", f"{tf} * {w}")
        g.probe(self, "flow_m3_s", q)
        # the hydraulic power delivered at the ports: its integral is the hydraulic energy
        # the pump gave the oil (a device's ``hydraulic_j``, to the Newton tolerance)
        g.probe(self, "hydraulic_power_w", f"{dp} * {q}")
        g.monitor(self, "speed_over_rating", f"abs({w}) / {wmax}")


class Hose(Component):
    """A hose between nodes ``a`` and ``b``: flow from the pressure drop through the inverse
    Darcy–Weisbach law :func:`~afo_mj.hydraulics.laws.hose_flow_m3_s` (laminar, Blasius or
    Haaland turbulent, smooth transition; laminar only when ``turbulence_enabled`` is off);
    half its oil volume and wall compliance lumped at each end (Merritt §2.5). Loss:
    ``line``. Fluid inertance needs a flow state this lumped element has not: refused."""

    kind = "hose"
    ports = {"a": HYDRAULIC, "b": HYDRAULIC}
    params_type = HoseParams
    summary = "hose: laminar/turbulent loss, volume and wall compliance at its ends"

    def emit(self, g, p):
        if p.inertance_enabled:
            raise CircuitError(f"{self.name}.inertance_enabled = True: the lumped hose has no "
                               "flow state for the fluid column's inertia (allowed: False)")
        length = g.param(self, "length", p.length_m)
        bore = g.param(self, "bore", p.bore_m)
        rough = g.param(self, "relative_roughness", p.roughness_m / p.bore_m)
        turb = g.param(self, "turbulent", 1.0 if p.turbulence_enabled else 0.0)
        half = g.param(self, "half_volume", 0.5 * p.volume_m3)
        kinv = g.param(self, "wall_inv", gated(p.wall_compliance_enabled,
                                                  1.0 / p.wall_bulk_modulus_pa))
        pa, pb = g.p(self, "a"), g.p(self, "b")
        q = g.local(self, "q")
        g.line(f"{q} = hose_flow_m3_s({pa} - {pb}, {length}, {bore}, U[U_MU], U[U_RHO], "
               f"{rough}, {turb})")
        g.flow(self, "a", f"-{q}")
        g.flow(self, "b", q)
        g.volume(self, "a", half, wall_volume=half, wall_inv=kinv)
        g.volume(self, "b", half, wall_volume=half, wall_inv=kinv)
        g.loss(self, "line", f"({pa} - {pb}) * {q}")
        g.probe(self, "flow_m3_s", q)


class ReliefValve(Component):
    """Direct-acting relief valve from ``a`` (inlet) to ``b``: opening
    :func:`~afo_mj.hydraulics.laws.relief_valve_area_m2`, flow through the regularised
    orifice :func:`~afo_mj.hydraulics.laws.orifice_flow_m3_s`; seated for a reverse drop
    (seat leakage area only). Loss: ``throttling``."""

    kind = "relief_valve"
    ports = {"a": HYDRAULIC, "b": HYDRAULIC}
    params_type = ReliefValveParams
    summary = "relief valve: poppet opening from cracking to full, orifice flow"

    def emit(self, g, p):
        crack = g.param(self, "cracking", p.cracking_dp_pa)
        over = g.param(self, "override", p.override_dp_pa)
        amax = g.param(self, "max_area", p.max_area_m2)
        aleak = g.param(self, "leak_area", gated(p.leakage_enabled, p.leakage_area_m2))
        cd = g.param(self, "cd", p.discharge_coefficient)
        pcr = g.param(self, "p_cr", p.transition_pressure_pa)
        g.param(self, "opening_smoothing", p.opening_smoothing)
        pa, pb = g.p(self, "a"), g.p(self, "b")
        dp, q = g.local(self, "dp"), g.local(self, "q")
        g.line(f"{dp} = {pa} - {pb}")
        g.line(f"{q} = orifice_flow_m3_s({dp}, relief_valve_area_m2({dp}, {crack}, {over}, "
               f"{amax}, {aleak}) if {dp} > 0.0 else {aleak}, {cd}, U[U_RHO], {pcr})")
        g.flow(self, "a", f"-{q}")
        g.flow(self, "b", q)
        g.loss(self, "throttling", f"{dp} * {q}")
        g.probe(self, "flow_m3_s", q)


@dataclasses.dataclass(frozen=True)
class CheckValveParams(Parameters):
    """A conductance-type check valve (charge/make-up valve of a closed circuit)."""

    conductance_m3_s_pa: float = param(1e-9, unit="m^3/(s Pa)", lo=0.0, hi=1e-6, lo_open=True,
                                       doc="open conductance G")
    cracking_pa: float = param(0.0, unit="Pa", lo=0.0, hi=1e7, doc="cracking pressure drop")
    band_pa: float = param(2e4, unit="Pa", lo=1.0, hi=1e6,
                           doc="width of the C¹ opening corner")
    seat_leakage_m3: float = param(0.0, unit="m^3", lo=0.0, hi=1e-10,
                                   doc="laminar conductance G_s of a worn seat: Q = G_s Δp/μ "
                                       "both ways, open or shut (0: a tight seat; built only "
                                       "when not 0)")


class CheckValve(Component):
    """Check valve from ``a`` to ``b``: ``Q = G ramp(Δp − p_crack)``
    (:func:`~afo_mj.hydraulics.laws.check_valve_flow_m3_s`). A worn or dirty seat leaks both
    ways whether the valve is open or shut: ``Q_s = G_s Δp/μ`` through the seat's gap
    (:func:`~afo_mj.hydraulics.laws.laminar_gap_flow_m3_s`, laminar clearance flow, Merritt,
    *Hydraulic Control Systems*, 1967, §3.2; a make-up valve's seat leakage in a closed
    loop, Watton, *Fundamentals of Fluid Power Control*, 2009, the closed-circuit
    chapter), built when ``seat_leakage_m3`` is not 0 (or for a calibration,
    :meth:`~afo_mj.circuits.circuit.Circuit.with_optional_terms`). Loss: ``throttling``."""

    kind = "check_valve"
    ports = {"a": HYDRAULIC, "b": HYDRAULIC}
    params_type = CheckValveParams
    summary = "check valve: conductance with a cracking pressure (and seat leakage)"

    def emit(self, g, p):
        gc = g.param(self, "conductance", p.conductance_m3_s_pa)
        crack = g.param(self, "cracking", p.cracking_pa)
        band = g.param(self, "band", p.band_pa)
        pa, pb = g.p(self, "a"), g.p(self, "b")
        q = g.local(self, "q")
        if g.optional(p.seat_leakage_m3):
            gs = g.param(self, "seat_leak", p.seat_leakage_m3)
            g.line(f"{q} = check_valve_flow_m3_s({pa} - {pb}, {gc}, {crack}, {band}) + "
                   f"laminar_gap_flow_m3_s({pa} - {pb}, {gs}, U[U_MU])")
        else:
            g.line(f"{q} = check_valve_flow_m3_s({pa} - {pb}, {gc}, {crack}, {band})")
        g.flow(self, "a", f"-{q}")
        g.flow(self, "b", q)
        g.loss(self, "throttling", f"({pa} - {pb}) * {q}")
        g.probe(self, "flow_m3_s", q)


@dataclasses.dataclass(frozen=True)
class DrainParams(Parameters):
    """An external leak to the tank (a pump's case drain, a leaking fitting)."""

    conductance_m3: float = param(1e-15, unit="m^3", lo=0.0, hi=1e-10,
                                  doc="laminar conductance G_d: Q = G_d p/μ to the tank at "
                                      "0 gauge")


class Drain(Component):
    """A laminar leak from its node to the tank at atmospheric pressure (0 gauge):
    ``Q = G_d p/μ`` (:func:`~afo_mj.hydraulics.laws.laminar_gap_flow_m3_s`; the external
    leakage of a pump to its case drain, Watton, *Fundamentals of Fluid Power Control*,
    2009, the pump chapter; Merritt, *Hydraulic Control Systems*, 1967, §3.2 for the
    laminar gap). In a closed loop with a charge circuit the oil it loses is made up by the
    check valves: the loop's common-mode pressure bleeds back to the charge pressure. Loss:
    ``drain`` (``p Q``: the oil leaves at 0 gauge, its pressure energy throttled)."""

    kind = "drain"
    ports = {"port": HYDRAULIC}
    params_type = DrainParams
    summary = "drain: laminar leak to the tank at 0 gauge (a pump's case drain)"

    def emit(self, g, p):
        gd = g.param(self, "conductance", p.conductance_m3)
        pp = g.p(self, "port")
        q = g.local(self, "q")
        g.line(f"{q} = laminar_gap_flow_m3_s({pp}, {gd}, U[U_MU])")
        g.flow(self, "port", f"-{q}")
        g.loss(self, "drain", f"{pp} * {q}")
        g.probe(self, "flow_m3_s", q)


@dataclasses.dataclass(frozen=True)
class FlushingValveParams(Parameters):
    """A flushing (shuttle) valve: the charge supply into the lower of two lines."""

    conductance_m3_s_pa: float = param(5e-12, unit="m^3/(s Pa)", lo=1e-15, hi=1e-6,
                                       doc="open conductance G")
    shift_band_pa: float = param(0.05e6, unit="Pa", lo=1e3, hi=1e6,
                                 doc="line pressure difference over which the spool shifts")


class FlushingValve(Component):
    """Flushing (shuttle) valve of a closed loop: connects the charge supply ``s`` to
    whichever of the lines ``a``, ``b`` is at the lower pressure
    (:func:`~afo_mj.hydraulics.laws.shuttle_valve_flow_m3_s`, one spool:
    :func:`~afo_mj.hydraulics.laws.shuttle_valve_share`), so the loop is replenished and
    its low side never cavitates. Loss: ``throttling``."""

    kind = "flushing_valve"
    ports = {"a": HYDRAULIC, "b": HYDRAULIC, "s": HYDRAULIC}
    params_type = FlushingValveParams
    summary = "flushing (shuttle) valve: charge supply into the lower line"

    def emit(self, g, p):
        gc = g.param(self, "conductance", p.conductance_m3_s_pa)
        band = g.param(self, "band", p.shift_band_pa)
        pa, pb, ps = g.p(self, "a"), g.p(self, "b"), g.p(self, "s")
        qa, qb, sa = g.local(self, "qa"), g.local(self, "qb"), g.local(self, "sa")
        # one spool: b's share is what a's leaves (one tanh per evaluation, not two)
        g.line(f"{sa} = shuttle_valve_share({pa}, {pb}, {band})")
        g.line(f"{qa} = shuttle_valve_flow_m3_s({sa}, {pa}, {ps}, {gc})")
        g.line(f"{qb} = shuttle_valve_flow_m3_s(1.0 - {sa}, {pb}, {ps}, {gc})")
        g.flow(self, "a", qa)
        g.flow(self, "b", qb)
        g.flow(self, "s", f"-({qa} + {qb})")
        g.loss(self, "throttling", f"({ps} - {pa}) * {qa} + ({ps} - {pb}) * {qb}")
        g.probe(self, "flow_m3_s", f"{qa} + {qb}")


@dataclasses.dataclass(frozen=True)
class ReservoirParams(Parameters):
    """A reservoir held at a constant gauge pressure (a charge reservoir, or a vented tank
    at 0)."""

    pressure_pa: float = param(0.0, unit="Pa", lo=0.0, hi=5e6, doc="gauge pressure")


class Reservoir(Component):
    """A constant-pressure node (boundary): its node has no pressure state. The ledger books
    the energy the circuit puts into it, ``∫ p_r Q_in dt`` (negative when it feeds the
    circuit)."""

    kind = "reservoir"
    ports = {"port": HYDRAULIC}
    params_type = ReservoirParams
    summary = "reservoir at constant pressure (boundary node)"

    def emit(self, g, p):
        g.fix_pressure(self, "port", g.param(self, "pressure", p.pressure_pa))


@dataclasses.dataclass(frozen=True)
class VolumeParams(Parameters):
    """Oil volume of a manifold, port or block at a node."""

    volume_m3: float = param(0.3e-6, unit="m^3", lo=0.0, hi=1e-2, lo_open=True)


class Volume(Component):
    """A rigid oil volume at a node (pump ports, manifold): capacitance ``V/B(p)``."""

    kind = "volume"
    ports = {"port": HYDRAULIC}
    params_type = VolumeParams
    summary = "rigid oil volume (manifold, port)"

    def emit(self, g, p):
        g.volume(self, "port", g.param(self, "volume", p.volume_m3))


class GasAccumulator(Component):
    """Gas-charged accumulator at a node: the capacitance
    :func:`~afo_mj.hydraulics.laws.gas_accumulator_capacitance_m3_pa` (polytropic gas above
    the precharge) plus its port volume. Its stored energy is the node's ``∫p dV``. The
    working-pressure rating is monitored."""

    kind = "gas_accumulator"
    ports = {"port": HYDRAULIC}
    params_type = GasAccumulatorParams
    summary = "gas accumulator (polytropic), capacitance at its node"

    def emit(self, g, p):
        v0 = g.param(self, "gas_volume", p.gas_volume_m3)
        p0 = g.param(self, "precharge_abs", p.precharge_pressure_pa)
        n = g.param(self, "polytropic_index", p.polytropic_index)
        pmax = g.param(self, "max_pressure_abs", p.max_pressure_pa)
        g.param(self, "stop_bulk_modulus", p.stop_bulk_modulus_pa)
        band = g.param(self, "band", 0.02 * p.precharge_pressure_pa)
        g.volume(self, "port", g.param(self, "port_volume", p.port_volume_m3))
        pp = g.p(self, "port")
        g.capacitance(self, "port", f"gas_accumulator_capacitance_m3_pa({pp} + P_ATM, {v0}, "
                      f"{p0}, {n}, {band})")
        g.monitor(self, "pressure_over_rating", f"({pp} + P_ATM) / {pmax}")


#: the stiffness at the pistons taken for a rigid cable (``series_compliance_rad_per_nm = 0``)
#: in :class:`PulleyCylinders`' massive-piston model (built with a backlash): 1e10 N/m, a
#: stretch of 0.3 µm under 3 kN, against the 1e6-1e7 N/m of a steel rope of a few mm
RIGID_CABLE_STIFFNESS_N_M = 1.0e10
#: the most cable force over which :class:`PulleyCylinders`' dead band takes its edge: the
#: edge is rounded over β/20 of travel (a progressive take-up of the slack), or over F_r/k
#: where that is less, since inside the gap the rounding leaves the slack cable a force
#: ``k r²/(4 d)`` at a distance d from the edge (r the rounding's travel): a few newtons
#: for a steel rope, kilonewtons for a rigid cable without this bound; with it, at most
#: ``F_r²/(4 k d)``
PLAY_EDGE_FORCE_N = 50.0


class PulleyCylinders(Component):
    """``count`` piston-cable cylinders whose cable loops over a joint pulley of radius
    ``r`` (the HAFO's antagonistic pair; one such cylinder is the lab bench's double-acting
    piston-cable cylinder): piston position from the a-end ``x = s/2 − r θ`` (dorsiflexion
    drives into chamber a), chamber volumes ``V_a = V_a0 + A x``, ``V_b = V_b0 + A (s − x)``
    (each side's own dead volume), joint torque ``τ = −r n (A (p_a − p_b) − F_seal − F_stop)``
    with ``F_stop`` the end stops (:func:`~afo_mj.hydraulics.laws.end_stop_force_n`) and
    ``F_seal`` one piston seal and two cable seals per cylinder
    (:func:`~afo_mj.hydraulics.laws.seal_friction_n`, all sliding at the piston speed);
    internal leakage across the piston (laminar gap, Merritt §3.2); piston-seal drag-out film
    (Müller & Nau) carried from the chamber the piston enters. With
    ``cylinder.seal_pressure_per_chamber`` each cable seal's pressure friction grows with its
    own chamber's pressure against the ambient
    (:func:`~afo_mj.hydraulics.laws.chamber_seal_pressure_friction_n`, Parker ORD 5700) and
    only the piston seal's with ``|p_a − p_b|``. Losses: ``seal_friction``,
    ``leakage``. Store: ``end_stops`` (the work done on them; the joint angle is held over a
    step, so stores that depend on it are booked as the work done on them).

    Series cable: a compliance ``1/k`` between pulley and pistons (massless pistons), stretched
    by the cable force ``F_c = n A Δp − F_seal + F_stop``
    (:func:`~afo_mj.hydraulics.laws.cable_stretch_m`): the pistons sit at
    ``x = s/2 − r θ + δ``, ``δ = r² (1/k) F_c``, and sweep ``n A δ̇`` besides the kinematic
    flow. Its hydraulic part ``r² (1/k) n A Δp`` joins the chambers by the differential
    capacitance :func:`~afo_mj.hydraulics.laws.series_spring_capacitance_m3_pa` (their
    continuity solved together, :func:`~afo_mj.hydraulics.laws.coupled_node_rate_pa_s`); its
    part ``G = F_stop − F_seal``, which moves with the joint's velocity (friction) and angle
    (stops) as well as the pressures, enters as the backward-Euler difference quotient
    ``r² (1/k) (G − G_n)/h`` over the step (``G_n`` held from the last step's end,
    :meth:`~afo_mj.circuits.codegen.Emitter.held`). The seals and stops are evaluated at the
    kinematic speed ``−r θ̇``; their loss and work are booked at the pistons' own speed
    ``−r θ̇ + δ̇`` and the cable's store ``series_spring`` at ``F_c δ̇`` (its energy
    ``½ r² (1/k) F_c²``), which closes the ledger exactly (the oil's work on the pistons
    ``n A Δp (ẋ_kin + δ̇) = F_c ẋ_kin + F_c δ̇ + F_seal (ẋ_kin + δ̇) − F_stop (ẋ_kin + δ̇)``).
    A rigid cable (``1/k = 0``) adds nothing.

    Backlash (``backlash_rad`` = b, built when not 0, or with the circuit's optional
    terms): a dead band of total width b at the pulley, i.e. ``±β`` with ``β = b r/2`` of
    cable travel, in series with the cable spring: the dead-zone model of a compliant
    transmission with play (Nordin & Gutman, "Controlling mechanical systems with backlash —
    a survey", *Automatica* 38 (2002) 1633, eq. 2: ``F = k dz(δ)``, ``dz(δ) = δ − β sgn δ``
    outside ``|δ| ≤ β``, 0 inside; written ``dz(δ) = δ − clip(δ, −β, β)`` with the clip's
    corners rounded (:func:`~afo_mj.hydraulics.laws.soft_clip`) over ``min(β/20, F_r/k)``,
    :data:`PLAY_EDGE_FORCE_N` = ``F_r``; an exact linear spring at ``b = 0``). Inside the gap
    the cable carries nothing, so the pistons are no longer tied to the joint: they move
    under the oil, their seals and their own inertia, and the model above (massless pistons
    on the cable) gives way to the pistons as a mass with two states of their own, the
    cable's travel ``δ = x − x_kin`` (``x_kin = s/2 − r θ``) and the pistons' speed ``v``:

    * ``δ̇ = v + r θ̇``;
    * ``n m v̇ = n A (p_a − p_b) − F_seal(v) + F_stop(x, v) − F_c``, Newton's second law of
      the pistons (with their cable share, ``cylinder.piston_mass_kg`` per cylinder): the
      force balance of a hydraulic piston on its load (Merritt, *Hydraulic Control Systems*,
      1967, the chapter on hydraulic power elements; Jelali & Kroll, *Hydraulic
      Servo-systems*, 2003, the cylinder's mechanical model), with the seals and the stops
      at the pistons' own speed and position ``x = x_kin + δ``;
    * ``F_c = k dz(δ)``, ``k = 1/(r² (1/k_θ))`` the cable's stiffness at the pistons
      (``series_compliance_rad_per_nm`` = ``1/k_θ``; a rigid cable, ``1/k_θ = 0``, is
      :data:`RIGID_CABLE_STIFFNESS_N_M`, stiff enough that its stretch stays far below any
      angle sensor's step); the joint torque is the cable's pull ``τ = −r F_c``;
    * the chambers see the pistons' own speed, ``Q_a = −n A v``, and their volumes the
      pistons' position.

    The ledger: the oil's work on the pistons ``n A Δp v`` is the seals' loss ``F_seal v``,
    the stops' store ``−F_stop v``, the pistons' kinetic energy ``½ n m v²`` (the store of
    the state ``v``), the cable's store ``series_spring`` ``F_c δ̇`` and the joint's work
    ``F_c (−r θ̇) = τ θ̇``: it closes exactly at every step. The probe ``end_stop_torque_nm``
    is then the stops' force referred to the joint, ``−r F_stop`` (the force reaches the
    joint through the cable). With no play (``b = 0``, the optional term built at 0) this is
    the massive-piston version of the cable above: the same statics, plus the pistons'
    inertia on the cable spring.

    Cable-seal (external) drag-out is refused:
    the film returns on the in-stroke and the circuit has no ambient node for it. Probes:
    ``piston_position_m`` (kinematic plus the stretch), ``hydraulic_torque_nm`` and
    ``end_stop_torque_nm`` (the stops' share of the joint torque, ``−r F_stop``; 0 off the
    stops)."""

    kind = "pulley_cylinders"
    ports = {"a": HYDRAULIC, "b": HYDRAULIC, "joint": JOINT}
    metadata_fields = ("cylinder.piston_mass_kg",)
    summary = "piston-cable cylinders on a joint pulley (antagonistic pair or one double-acting)"

    @dataclasses.dataclass(frozen=True)
    class Params(Parameters):
        cylinder: CylinderParams = CylinderParams()
        count: float = param(1.0, unit="-", lo=1.0, hi=4.0, doc="cylinders on the pulley")
        pulley_radius_m: float = param(0.04, unit="m", lo=0.005, hi=0.2)
        series_compliance_rad_per_nm: float = param(
            0.0, unit="rad/(N m)", lo=0.0, hi=1.0,
            doc="1/k of the cable between pulley and pistons (0: rigid); always built, so "
                "that a fit can vary it without recompiling")
        backlash_rad: float = param(
            0.0, unit="rad", lo=0.0, hi=0.5,
            doc="total play of the cable on the pulley, as an angle of the joint (a dead "
                "band in the transmission; 0: none, not built)")

    params_type = Params

    def torque_per_pa(self) -> float:
        """``n A r``: joint torque per pascal of ``p_a − p_b``."""
        return self.params.count * self.params.cylinder.area_a_m2 * self.params.pulley_radius_m

    def emit(self, g, p):
        cy = p.cylinder
        if cy.kind != "piston_cable":
            raise CircuitError(f"{self.name}.cylinder.kind = {cy.kind!r}: a pulley drive "
                               "needs piston_cable cylinders (allowed: 'piston_cable')")
        if cy.rod_seal.leakage_enabled:
            raise CircuitError(f"{self.name}.cylinder.rod_seal.leakage_enabled = True: "
                               "external cable-seal drag-out is not simulated (allowed: False)")
        n = g.param(self, "count", p.count)
        r = g.param(self, "pulley_radius", p.pulley_radius_m)
        area = g.param(self, "area", cy.area_a_m2)
        stroke = g.param(self, "stroke", cy.stroke_m)
        va0 = g.param(self, "dead_a", cy.dead_volume_a_m3)
        vb0 = g.param(self, "dead_b", cy.dead_volume_b_m3)
        gl = g.param(self, "leak_g", gated(cy.internal_leakage_enabled,
                                           cy.leakage_conductance_m3))
        k_stop, c_stop = cy.end_stop_stiffness_n_m, cy.end_stop_damping_n_s_m
        ks = g.param(self, "stop_k", gated(cy.end_stops_enabled, k_stop))
        cs = g.param(self, "stop_c", gated(cy.end_stops_enabled, c_stop))
        seal, cp_own = _seal_params(g, self, cy, rods=2)
        ps = cy.piston_seal
        drag_on = g.param(self, "dragout_on", 1.0 if ps.leakage_enabled else 0.0)
        ps_seal = OringSeal(ps, cy.bore_m)
        w_grad = g.param(self, "dragout_w", ps_seal.peak_contact_pressure_pa
                         / ps_seal.contact_half_width_m)
        dbore = g.param(self, "bore", cy.bore_m)
        v_c = g.param_ref(self, "seal_v_c")
        pa, pb = g.p(self, "a"), g.p(self, "b")
        th, thd = "th", "thd"
        x, xd, f_s, f_e, q_l, q_d, f_g, xs = (g.local(self, k) for k in
                                              ("x", "xd", "fseal", "fstop", "qleak", "qdrag",
                                               "fg", "xs"))
        comp_s = g.param(self, "series_compliance", p.series_compliance_rad_per_nm)
        if g.optional(p.backlash_rad):
            self._emit_piston_mass(g, p, n, r, area, stroke, va0, vb0, gl, ks, cs, seal, cp_own,
                                   drag_on, w_grad, dbore, v_c, comp_s)
            return
        # series cable: its hydraulic stretch as the chambers' differential capacitance, the
        # rest (stops less seal friction) as a difference quotient over the step (docstring)
        c_s = g.local(self, "cs")
        g.line(f"{c_s} = series_spring_capacitance_m3_pa({n} * {area} * {r}, {comp_s})")
        g.couple(self, "a", "b", c_s)
        g.line(f"{x} = 0.5 * {stroke} - {r} * {th}")
        g.line(f"{xd} = -{r} * {thd}")
        g.line(f"{f_s} = {n} * (seal_friction_n({xd}, {pa} - {pb}, {seal}) + "
               f"chamber_seal_pressure_friction_n({xd}, {pa}, {pb}, {cp_own}, {v_c}))")
        g.line(f"{f_e} = {n} * end_stop_force_n({x}, {xd}, {stroke}, {ks}, {cs})")
        g.line(f"{f_g} = {f_e} - {f_s}")
        g_n = g.held(self, "cable_force_other_n", f_g)
        g.line(f"{xs} = (cable_stretch_m({r}, {comp_s}, {f_g}) - cable_stretch_m({r}, {comp_s}, "
               f"{g_n})) * U[U_INV_H]")
        g.line(f"{q_l} = {n} * laminar_gap_flow_m3_s({pa} - {pb}, {gl}, U[U_MU])")
        g.line(f"{q_d} = {n} * seal_dragout_flow_m3_s({xd}, U[U_MU], {dbore}, {w_grad}) "
               f"if {drag_on} != 0.0 else 0.0")
        # chamber a grows as x grows: its net inflow from the piston is −n A ẋ
        g.flow(self, "a", f"-{n} * {area} * ({xd} + {xs}) - {q_l} + {q_d}")
        g.flow(self, "b", f"{n} * {area} * ({xd} + {xs}) + {q_l} - {q_d}")
        g.volume(self, "a", f"{n} * max({va0} + {area} * {x}, 0.5 * {va0})")
        g.volume(self, "b", f"{n} * max({vb0} + {area} * ({stroke} - {x}), 0.5 * {vb0})")
        # force on the pistons towards +x: n A (p_a − p_b) − F_seal + F_stop; τ = F dx/dθ
        g.joint_torque(self, f"-{r} * ({n} * {area} * ({pa} - {pb}) - {f_s} + {f_e})")
        # the pistons' speed, the cable's stretch rate included: the hydraulic part
        # c_s Δṗ/(n A) and the rest xs
        vp = f"({xd} + {c_s} * (d{pa} - d{pb}) / ({n} * {area}) + {xs})"
        g.loss(self, "seal_friction", f"{f_s} * {vp}")
        g.loss(self, "leakage", f"({pa} - {pb}) * {q_l} + ({pb} - {pa}) * {q_d}")
        g.store_rate(self, "end_stops", f"-{f_e} * {vp}")
        # the cable's energy ½ r²(1/k) F_c², booked as F_c δ̇ (δ̇ = vp − ẋ_kin)
        g.store_rate(self, "series_spring", f"({n} * {area} * ({pa} - {pb}) + {f_g}) * "
                     f"({c_s} * (d{pa} - d{pb}) / ({n} * {area}) + {xs})")
        # the pistons' travel: kinematic plus the cable's stretch under its whole force
        g.probe(self, "piston_position_m", f"{x} + cable_stretch_m({r}, {comp_s}, {n} * "
                f"{area} * ({pa} - {pb}) + {f_g})")
        g.probe(self, "hydraulic_torque_nm", f"-{r} * {n} * {area} * ({pa} - {pb})")
        # the end stops' share of the joint torque (0 unless a piston is past a stroke end):
        # what the run's summary reports as stop contact, apart from the torque delivered
        g.probe(self, "end_stop_torque_nm", f"-{r} * {f_e}")

    def _emit_piston_mass(self, g, p, n, r, area, stroke, va0, vb0, gl, ks, cs, seal, cp_own,
                          drag_on, w_grad, dbore, v_c, comp_s):
        """The pistons as a mass on the cable's dead-zone spring (built with a play; class
        docstring, "Backlash"). States: the cable's travel ``δ`` (piston position less the
        kinematic one) and the pistons' speed ``v``."""
        pa, pb = g.p(self, "a"), g.p(self, "b")
        b_rad = g.param(self, "backlash", p.backlash_rad)
        mass = g.param(self, "piston_mass", p.cylinder.piston_mass_kg)
        k_rigid = g.param(self, "rigid_cable_k", RIGID_CABLE_STIFFNESS_N_M)
        f_round = g.param(self, "play_edge_force", PLAY_EDGE_FORCE_N)
        # the pistons' speed keeps their kinetic energy ½ n m v² (store n m)
        dl = g.state(self, "cable_travel_m", typ=1e-4)
        v = g.state(self, "piston_speed_m_s", typ=1e-2, store=f"{n} * {mass}")
        x, f_s, f_e, f_c, k_c, half, q_l, q_d = (
            g.local(self, k) for k in ("x", "fseal", "fstop", "fcable", "kcable", "half_play",
                                       "qleak", "qdrag"))
        g.line(f"{x} = 0.5 * {stroke} - {r} * th + {dl}")
        # seals and stops act on the pistons, at their own position and speed
        g.line(f"{f_s} = {n} * (seal_friction_n({v}, {pa} - {pb}, {seal}) + "
               f"chamber_seal_pressure_friction_n({v}, {pa}, {pb}, {cp_own}, {v_c}))")
        g.line(f"{f_e} = {n} * end_stop_force_n({x}, {v}, {stroke}, {ks}, {cs})")
        # the cable's stiffness at the piston k = 1/(r² (1/k_θ)); a rigid cable: k_rigid
        g.line(f"{k_c} = 1.0 / max({r} * {r} * {comp_s}, 1.0 / {k_rigid})")
        g.line(f"{half} = 0.5 * {b_rad} * {r}")
        # dead-zone spring F = k (δ − clip(δ, −β, β)), the clip's corners rounded over
        # min(β/20, F_r/k) (docstring)
        g.line(f"{f_c} = {k_c} * ({dl} - soft_clip({dl}, -{half}, {half}, "
               f"min(0.05 * {half}, {f_round} / {k_c})))")
        g.deriv(dl, f"{v} + {r} * thd")
        g.deriv(v, f"({n} * {area} * ({pa} - {pb}) - {f_s} + {f_e} - {f_c}) / ({n} * {mass})")
        g.line(f"{q_l} = {n} * laminar_gap_flow_m3_s({pa} - {pb}, {gl}, U[U_MU])")
        g.line(f"{q_d} = {n} * seal_dragout_flow_m3_s({v}, U[U_MU], {dbore}, {w_grad}) "
               f"if {drag_on} != 0.0 else 0.0")
        g.flow(self, "a", f"-{n} * {area} * {v} - {q_l} + {q_d}")
        g.flow(self, "b", f"{n} * {area} * {v} + {q_l} - {q_d}")
        g.volume(self, "a", f"{n} * max({va0} + {area} * {x}, 0.5 * {va0})")
        g.volume(self, "b", f"{n} * max({vb0} + {area} * ({stroke} - {x}), 0.5 * {vb0})")
        # the cable pulls the pulley: τ = −r F_c
        g.joint_torque(self, f"-{r} * {f_c}")
        g.loss(self, "seal_friction", f"{f_s} * {v}")
        g.loss(self, "leakage", f"({pa} - {pb}) * {q_l} + ({pb} - {pa}) * {q_d}")
        g.store_rate(self, "end_stops", f"-{f_e} * {v}")
        # the cable's energy ∫F_c dδ, booked as F_c δ̇
        g.store_rate(self, "series_spring", f"{f_c} * ({v} + {r} * thd)")
        g.probe(self, "piston_position_m", x)
        g.probe(self, "hydraulic_torque_nm", f"-{r} * {n} * {area} * ({pa} - {pb})")
        g.probe(self, "end_stop_torque_nm", f"-{r} * {f_e}")


def _seal_params(g, comp, cy, rods: int) -> tuple[str, str]:
    """Pack one piston seal + ``rods`` rod/cable seals of a cylinder (all sliding at the piston
    speed) as the argument list of :func:`~afo_mj.hydraulics.laws.seal_friction_n`
    (:func:`~afo_mj.hydraulics.seal.cylinder_seal_law_args`), and, for a two-rod
    (piston-cable) cylinder, the packed reference of each cable seal's own pressure
    coefficient (:func:`~afo_mj.hydraulics.laws.chamber_seal_pressure_friction_n`; 0 unless
    ``seal_pressure_per_chamber``; ``""`` for one rod). With ``seal_pressure_per_chamber``
    the |Δp| coefficient is the piston seal's alone; a single-acting cylinder's rod seal then
    seals the vented side and adds none."""
    on = cy.seal_friction_enabled
    own = bool(cy.seal_pressure_per_chamber)
    # the viscous and pressure coefficients reach the seal model through their switches
    # (0 while an effect is off): read here so that switching one off is not "unused"
    for seal in (cy.piston_seal, cy.rod_seal):
        _ = (seal.pressure_coefficient_m2, seal.viscous_coefficient_n_s_m)
    piston = seal_law_args(cy.piston_seal, cy.bore_m)
    rod = seal_law_args(cy.rod_seal, max(cy.rod_diameter_m, 1e-6))
    # per chamber: the cable seals' pressure coefficient leaves the |Δp| sum
    fc, st, v_st, v_c, fv, cp = cylinder_seal_law_args(
        piston, rod[:5] + (0.0,) if own else rod, rods)
    args = ", ".join((g.param(comp, "seal_fc", gated(on, float(fc))),
                      g.param(comp, "seal_stribeck", gated(on, float(st))),
                      g.param(comp, "seal_v_st", v_st), g.param(comp, "seal_v_c", v_c),
                      g.param(comp, "seal_fv", gated(on, fv)),
                      g.param(comp, "seal_cp", gated(on, cp))))
    cp_own = ""
    if rods == 2:
        cp_own = g.param(comp, "seal_cp_chamber", gated(on and own, rod[5]))
    return args, cp_own


@dataclasses.dataclass(frozen=True)
class SpringReturnParams(Parameters):
    """A single-acting cylinder on a lever at the joint, retracted by a spring."""

    cylinder: CylinderParams = CylinderParams(kind="single_acting", bore_m=14e-3,
                                              rod_diameter_m=5e-3, stroke_m=0.04,
                                              dead_volume_a_m3=0.3e-6, dead_volume_b_m3=0.3e-6)
    moment_arm_m: float = param(0.05, unit="m", lo=0.005, hi=0.3,
                                doc="lever arm r: piston travel per radian of plantarflexion")
    spring_rate_n_m: float = param(2000.0, unit="N/m", lo=0.0, hi=1e7,
                                   doc="return spring rate")
    spring_preload_n: float = param(20.0, unit="N", lo=0.0, hi=1e5,
                                    doc="return spring force at x = 0")
    neutral_position_m: float = param(0.01, unit="m", lo=0.0, hi=1.0,
                                      doc="piston position at joint angle 0")


class SpringReturnCylinder(Component):
    """Single-acting cylinder on a lever (plantarflexion-only assist), retracted by a spring:
    piston ``x = x_0 − r θ`` (plantarflexion extends it), chamber ``V = V_0 + A x``, force on
    the piston ``A p − (F_0 + k x) − F_seal + F_stop`` (rod side vented: one piston seal, one
    rod seal), joint torque ``τ = −r F``. Loss: ``seal_friction``. Stores: ``spring`` and
    ``end_stops``, booked as the work done on them. Probes: ``piston_position_m`` and
    ``end_stop_torque_nm`` (the stops' share of the joint torque, ``−r F_stop``)."""

    kind = "spring_return_cylinder"
    ports = {"a": HYDRAULIC, "joint": JOINT}
    params_type = SpringReturnParams

    def torque_per_pa(self) -> float:
        """``A r``: joint torque per pascal of chamber pressure."""
        return self.params.cylinder.area_a_m2 * self.params.moment_arm_m

    metadata_fields = ("cylinder.piston_mass_kg", "cylinder.dead_volume_b_m3",
                       "cylinder.radial_clearance_m", "cylinder.land_length_m",
                       "cylinder.internal_leakage_enabled")
    summary = "single-acting cylinder with spring return on a joint lever (new in issue 18)"

    def emit(self, g, p):
        cy = p.cylinder
        if cy.kind != "single_acting":
            raise CircuitError(f"{self.name}.cylinder.kind = {cy.kind!r}: allowed: "
                               "'single_acting'")
        if cy.rod_seal.leakage_enabled or cy.piston_seal.leakage_enabled:
            raise CircuitError(f"{self.name}: seal drag-out leakage of a single-acting "
                               "cylinder goes to the vented side, not simulated (allowed: "
                               "leakage_enabled = False)")
        r = g.param(self, "arm", p.moment_arm_m)
        area = g.param(self, "area", cy.area_a_m2)
        stroke = g.param(self, "stroke", cy.stroke_m)
        v0 = g.param(self, "dead_a", cy.dead_volume_a_m3)
        k = g.param(self, "spring_k", p.spring_rate_n_m)
        f0 = g.param(self, "spring_f0", p.spring_preload_n)
        x0 = g.param(self, "x0", p.neutral_position_m)
        k_stop, c_stop = cy.end_stop_stiffness_n_m, cy.end_stop_damping_n_s_m
        ks = g.param(self, "stop_k", gated(cy.end_stops_enabled, k_stop))
        cs = g.param(self, "stop_c", gated(cy.end_stops_enabled, c_stop))
        seal, _ = _seal_params(g, self, cy, rods=1)
        pa = g.p(self, "a")
        x, xd, f_s, f_e = (g.local(self, n) for n in ("x", "xd", "fseal", "fstop"))
        g.line(f"{x} = {x0} - {r} * th")
        g.line(f"{xd} = -{r} * thd")
        g.line(f"{f_s} = seal_friction_n({xd}, {pa}, {seal})")
        g.line(f"{f_e} = end_stop_force_n({x}, {xd}, {stroke}, {ks}, {cs})")
        g.flow(self, "a", f"-{area} * {xd}")
        g.volume(self, "a", f"max({v0} + {area} * {x}, 0.5 * {v0})")
        g.joint_torque(self, f"-{r} * ({area} * {pa} - ({f0} + {k} * {x}) - {f_s} + {f_e})")
        g.loss(self, "seal_friction", f"{f_s} * {xd}")
        g.store_rate(self, "spring", f"({f0} + {k} * {x}) * {xd}")
        g.store_rate(self, "end_stops", f"-{f_e} * {xd}")
        g.probe(self, "piston_position_m", x)
        g.probe(self, "end_stop_torque_nm", f"-{r} * {f_e}")
