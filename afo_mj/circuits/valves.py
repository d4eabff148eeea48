"""Valve components of the circuits: metering valves, switching valves, supply valves and pumps
that the valve-controlled and digital-valve ankle actuators use (seed ch. 4, 5, 7; they replaced
a hand-written kernel, kept as the tests' reference in ``tests/kernel_reference``).

* :class:`ServoValve` (``servo_valve``) — 4/3 proportional/servo valve: first-order spool,
  four metering edges with lap and centre leakage, a coil on the bus.
* :class:`OnOffValve` (``onoff_valve``) — fast 2/2 on/off valve with rate-limited travel,
  driven by the on-fraction of a PWM signal; holding power and switching energy on the bus.
* :class:`UnloadingValve` (``unloading_valve``) — pilot-operated unloading valve with snap
  action (dumps a pump to tank while the pilot line, the supply rail, is charged).
* :class:`VariablePump` (``variable_pump``) — pressure-compensated variable-displacement pump.
* :class:`FixedOrifice` (``orifice``) — a fixed restriction (an always-open valve edge).
* :class:`SupplyAccumulator` (``supply_accumulator``) — gas accumulator on a supply rail with
  the pressure band over which its gas engages as a parameter, its port volume the rail's
  oil.

A valve command (spool position, PWM on-fraction, switching rate) is an actuated input that
the circuit's controller sets each step (:meth:`afo_mj.circuits.codegen.Emitter.input`); the
valve-circuit controllers are in :mod:`afo_mj.circuits.valve_controllers`. Every equation is a
law of :mod:`afo_mj.hydraulics.laws`. Sign conventions as in
:mod:`afo_mj.circuits.components` (flows positive into the node named).
"""

from __future__ import annotations

import dataclasses
import math

from afo_mj.circuits.components import BUS, HYDRAULIC, SHAFT, CircuitError, Component
from afo_mj.hydraulics.accumulator import GasAccumulatorParams
from afo_mj.hydraulics.onoff_valve import OnOffValveParams
from afo_mj.hydraulics.orifice import OrificeParams
from afo_mj.hydraulics.params import Parameters, param
from afo_mj.hydraulics.pump import PumpParams
from afo_mj.hydraulics.servo_valve import ServoValveParams
from afo_mj.hydraulics.unloading_valve import UnloadingValveParams


def _emit_orifice_flow(g, comp, key, dp, area, cd, pcr) -> str:
    """Emit ``q = orifice_flow_m3_s(dp, area, …)`` into local ``key``; returns its name."""
    q = g.local(comp, key)
    g.line(f"{q} = orifice_flow_m3_s({dp}, {area}, {cd}, U[U_RHO], {pcr})")
    return q


# ---- 4/3 servo valve ----------------------------------------------------------------------------

@dataclasses.dataclass(frozen=True)
class ServoValveComponentParams(Parameters):
    """A 4/3 servo valve (:class:`~afo_mj.hydraulics.servo_valve.ServoValveParams`: rating,
    spool, lap, leakage) and the power its torque motor draws."""

    valve: ServoValveParams = ServoValveParams()
    coil_power_w: float = param(0.5, unit="W", lo=0.0, hi=100.0,
                                doc="torque-motor (coil) power drawn from the bus")


class ServoValve(Component):
    """4/3 proportional/servo valve between a supply ``p``, a tank ``t`` and the lines ``a``,
    ``b`` (seed ch. 4; library model :mod:`afo_mj.hydraulics.servo_valve`).

    Spool ``x`` (fraction of full stroke) lags the controller's command ``u`` (input
    ``command``) at the valve's bandwidth, first order:
    ``ẋ = (clip(u, −1, 1) − x)/τ``, ``τ = 1/(2π f_n)``
    (:func:`~afo_mj.hydraulics.laws.spool_lag_rate_1_s`; the library's second-order spool
    and its damping ratio are not simulated). Edge areas
    (:func:`~afo_mj.hydraulics.laws.spool_edge_area_m2`, Merritt 1967 §3.4–3.6):
    ``A_PA = A_BT = A_f ramp(x − o) + A_leak``, ``A_AT = A_PB = A_f ramp(−x − o) + A_leak``
    with ``A_f = w x_max`` (area gradient from the rated flow), ``o`` the lap as a fraction of
    the stroke, the corner rounded over ``± opening_smoothing_m``, and ``A_leak`` the centre
    leakage area from the maker's leakage figure. Each edge is a regularised orifice
    (:func:`~afo_mj.hydraulics.laws.orifice_flow_m3_s`): ``P→A``, ``A→T``, ``P→B``, ``B→T``.

    Ports: ``p``, ``t``, ``a``, ``b`` (hydraulic), ``bus`` (the coil). Losses: ``throttling``
    (``Σ Δp_e Q_e`` over the four edges), ``coil`` (electrical, not oil heat). Probe:
    ``spool``. Input: ``command``."""

    kind = "servo_valve"
    ports = {"p": HYDRAULIC, "t": HYDRAULIC, "a": HYDRAULIC, "b": HYDRAULIC, "bus": BUS}
    params_type = ServoValveComponentParams
    #: the first-order spool has no damping ratio (that of the library's second-order model)
    metadata_fields = ("valve.damping_ratio",)
    summary = "4/3 servo valve: first-order spool, four metering edges, lap, leakage, coil"

    def emit(self, g, p):
        v = p.valve
        # the rating, leakage figure and lap size the edges (ServoValveParams' derived figures,
        # whose fields the read-recording view counts as used)
        xmax = v.spool_max_m
        af = g.param(self, "full_area", v.area_gradient_m * xmax)
        lap = g.param(self, "lap", v.effective_overlap_m / xmax)
        rnd = g.param(self, "rounding", v.opening_smoothing_m / xmax)
        aleak = g.param(self, "leak_area", v.leakage_area_m2)
        tau = g.param(self, "tau", 1.0 / (2.0 * math.pi * v.natural_frequency_hz))
        cd = g.param(self, "cd", v.discharge_coefficient)
        pcr = g.param(self, "p_cr", v.transition_pressure_pa)
        coil = g.param(self, "coil_power", p.coil_power_w)
        x = g.state(self, "spool", typ=1e-2)
        u = g.input(self, "command")
        pp, pt, pa, pb = (g.p(self, k) for k in ("p", "t", "a", "b"))
        a_pos, a_neg = g.local(self, "a_pos"), g.local(self, "a_neg")
        g.line(f"{a_pos} = spool_edge_area_m2({x}, 1.0, {lap}, {af}, {rnd}, {aleak})")
        g.line(f"{a_neg} = spool_edge_area_m2(-{x}, 1.0, {lap}, {af}, {rnd}, {aleak})")
        q_pa = _emit_orifice_flow(g, self, "q_pa", f"{pp} - {pa}", a_pos, cd, pcr)
        q_at = _emit_orifice_flow(g, self, "q_at", f"{pa} - {pt}", a_neg, cd, pcr)
        q_pb = _emit_orifice_flow(g, self, "q_pb", f"{pp} - {pb}", a_neg, cd, pcr)
        q_bt = _emit_orifice_flow(g, self, "q_bt", f"{pb} - {pt}", a_pos, cd, pcr)
        g.deriv(x, f"spool_lag_rate_1_s({x}, {u}, {tau})")
        g.flow(self, "p", f"-({q_pa} + {q_pb})")
        g.flow(self, "a", f"{q_pa} - {q_at}")
        g.flow(self, "b", f"{q_pb} - {q_bt}")
        g.flow(self, "t", f"{q_at} + {q_bt}")
        g.loss(self, "throttling", f"({pp} - {pa}) * {q_pa} + ({pa} - {pt}) * {q_at} + "
               f"({pp} - {pb}) * {q_pb} + ({pb} - {pt}) * {q_bt}")
        g.bus_power(self, "bus", coil)
        g.loss(self, "coil", coil, oil=False)
        g.probe(self, "spool", x)


# ---- on/off valve -------------------------------------------------------------------------------

@dataclasses.dataclass(frozen=True)
class OnOffComponentParams(Parameters):
    """A fast on/off valve (:class:`~afo_mj.hydraulics.onoff_valve.OnOffValveParams`) and
    whether its coil holds it shut (normally open) or open (normally closed)."""

    valve: OnOffValveParams = OnOffValveParams()
    normally_open: bool = False


class OnOffValve(Component):
    """Fast 2/2 on/off valve from ``a`` to ``b`` switched by PWM (seed ch. 5; library model
    :mod:`afo_mj.hydraulics.onoff_valve`).

    Opening ``x`` (0 shut … 1 open) travels towards the commanded opening ``u`` (input
    ``command``: the fraction of the step the PWM signal asks for the valve open, so the duty
    is exact at any step length) at the rate limit of its switching time, approaching the end
    exponentially (:func:`~afo_mj.hydraulics.laws.onoff_valve_rate_1_s`, corners rounded over
    5 % of the limit); area :func:`~afo_mj.hydraulics.laws.valve_opening_area_m2` (the seat
    leakage when shut), flow the regularised orifice. While it travels the valve throttles:
    the switching loss is in ``throttling``.

    Coil power on the bus: ``P_hold e + E_sw n_sw`` with ``e`` the energised fraction
    (``1 − u`` for a normally-open valve, ``u`` for a normally-closed one) and ``n_sw`` the
    switchings per second (input ``switch_rate``). Ports: ``a``, ``b``, ``bus``. Losses:
    ``throttling``, ``coil`` (electrical). Probe: ``position``."""

    kind = "onoff_valve"
    ports = {"a": HYDRAULIC, "b": HYDRAULIC, "bus": BUS}
    params_type = OnOffComponentParams
    summary = "on/off valve: rate-limited travel, PWM on-fraction input, coil power"

    def emit(self, g, p):
        v = p.valve
        amax = g.param(self, "max_area", v.max_area_m2)
        aleak = g.param(self, "leak_area", v.leakage_area_m2 if v.leakage_enabled else 0.0)
        cd = g.param(self, "cd", v.discharge_coefficient)
        pcr = g.param(self, "p_cr", v.transition_pressure_pa)
        tsw = g.param(self, "switching_time", v.switching_time_s)
        taus = g.param(self, "approach_tau", v.approach_time_constant_s)
        esw = g.param(self, "switching_energy", v.switching_energy_j)
        hold = g.param(self, "holding_power", v.holding_power_w)
        no = g.param(self, "normally_open", 1.0 if p.normally_open else 0.0)
        x = g.state(self, "position", typ=1e-2)
        u = g.input(self, "command")
        nsw = g.input(self, "switch_rate")
        pa, pb = g.p(self, "a"), g.p(self, "b")
        area = g.local(self, "area")
        g.line(f"{area} = valve_opening_area_m2({x}, {amax}, {aleak})")
        q = _emit_orifice_flow(g, self, "q", f"{pa} - {pb}", area, cd, pcr)
        g.deriv(x, f"onoff_valve_rate_1_s({x}, {u}, {taus}, {tsw}, 0.05)")
        g.flow(self, "a", f"-{q}")
        g.flow(self, "b", q)
        coil = f"{hold} * ({no} + (1.0 - 2.0 * {no}) * {u}) + {esw} * {nsw}"
        g.loss(self, "throttling", f"({pa} - {pb}) * {q}")
        g.bus_power(self, "bus", coil)
        g.loss(self, "coil", coil, oil=False)
        g.probe(self, "position", x)


# ---- unloading valve ----------------------------------------------------------------------------

class UnloadingValve(Component):
    """Pilot-operated unloading valve from ``a`` (the pump line) to ``b`` (tank), piloted by
    the pressure at ``pilot`` (the supply rail behind the pump's check valve; a pilot line
    passes no flow). Library model :mod:`afo_mj.hydraulics.unloading_valve`; seed ch. 4.

    Opening ``x``: :func:`~afo_mj.hydraulics.laws.unloading_valve_snap_rate_1_s` with the
    pilot's absolute pressure: opens above cut-out, shuts below cut-in (hysteresis) and, in
    between, snaps to the end it is nearer (a valve that has cracked open goes on opening).
    Area :func:`~afo_mj.hydraulics.laws.valve_opening_area_m2`, regularised orifice flow.
    Ports: ``a``, ``b``, ``pilot``. Loss: ``throttling``. Probe: ``position``."""

    kind = "unloading_valve"
    ports = {"a": HYDRAULIC, "b": HYDRAULIC, "pilot": HYDRAULIC}
    params_type = UnloadingValveParams
    summary = "pilot-operated unloading valve with hysteresis and snap action"

    def emit(self, g, p):
        cut_out = g.param(self, "cut_out_abs", p.cut_out_pressure_pa)
        cut_in = g.param(self, "cut_in_abs", p.cut_in_pressure_pa)
        band = g.param(self, "band", p.switching_band_pa)
        tau = g.param(self, "tau", p.time_constant_s)
        hyst = g.param(self, "hysteresis_on", 1.0 if p.hysteresis_enabled else 0.0)
        amax = g.param(self, "max_area", p.max_area_m2)
        aleak = g.param(self, "leak_area", p.leakage_area_m2 if p.leakage_enabled else 0.0)
        cd = g.param(self, "cd", p.discharge_coefficient)
        pcr = g.param(self, "p_cr", p.transition_pressure_pa)
        x = g.state(self, "position", typ=1e-2)
        pa, pb, pil = g.p(self, "a"), g.p(self, "b"), g.p(self, "pilot")
        area = g.local(self, "area")
        g.line(f"{area} = valve_opening_area_m2({x}, {amax}, {aleak})")
        q = _emit_orifice_flow(g, self, "q", f"{pa} - {pb}", area, cd, pcr)
        g.deriv(x, f"unloading_valve_snap_rate_1_s({x}, {pil} + P_ATM, {cut_out}, {cut_in}, "
                   f"{band}, {tau}, {hyst})")
        g.flow(self, "a", f"-{q}")
        g.flow(self, "b", q)
        g.loss(self, "throttling", f"({pa} - {pb}) * {q}")
        g.probe(self, "position", x)


# ---- pressure-compensated pump ----------------------------------------------------------------

@dataclasses.dataclass(frozen=True)
class VariablePumpParams(Parameters):
    """A pump whose displacement a pressure compensator sets from a sensed pressure."""

    pump: PumpParams = PumpParams()
    compensator_pressure_pa: float = param(11.0e6, unit="Pa", lo=0.0, hi=40e6,
                                           doc="sensed gauge pressure at which the "
                                               "displacement reaches its minimum")
    compensator_band_pa: float = param(1.0e6, unit="Pa", lo=1e4, hi=20e6,
                                       doc="pressure band from full to minimum stroke")
    min_displacement_fraction: float = param(0.03, unit="-", lo=0.0, hi=1.0,
                                             doc="smallest displacement fraction ε_min")


class VariablePump(Component):
    """Pressure-compensated variable-displacement pump on a shaft, from ``b`` (inlet) to ``a``
    (outlet), its compensator sensing the pressure at ``sense`` (the supply rail; a pilot
    line, no flow). Displacement fraction
    :func:`~afo_mj.hydraulics.laws.compensator_displacement_fraction` (quasi-static);
    flow :func:`~afo_mj.hydraulics.laws.pump_flow_m3_s` at ``ε ω`` (``ε d ω`` less the slip
    of the full displacement, Wilson); torque ``ε d Δp + T_f`` with the Coulomb and drag part
    of :func:`~afo_mj.hydraulics.laws.pump_friction_torque_nm` at ``ε d`` and its viscous part
    at the full ``d`` (the rotating group churns whatever the stroke). Losses:
    ``volumetric``, ``mechanical``. Probes: ``flow_m3_s``, ``hydraulic_power_w`` (``Δp Q``),
    ``displacement_fraction``. The
    component is variable-displacement whatever the library's switch says."""

    kind = "variable_pump"
    ports = {"shaft": SHAFT, "a": HYDRAULIC, "b": HYDRAULIC, "sense": HYDRAULIC}
    params_type = VariablePumpParams
    metadata_fields = ("pump.kind", "pump.variable_displacement_enabled")
    summary = "pressure-compensated variable-displacement pump (Wilson losses)"

    def emit(self, g, p):
        pu = p.pump
        d = g.param(self, "d", pu.displacement_m3_rev / (2.0 * math.pi))
        cs = g.param(self, "slip", pu.slip_coefficient if pu.leakage_enabled else 0.0)
        cf = g.param(self, "coulomb", pu.coulomb_coefficient if pu.coulomb_friction_enabled
                     else 0.0)
        cv = g.param(self, "viscous", pu.viscous_coefficient if pu.viscous_friction_enabled
                     else 0.0)
        t0 = g.param(self, "drag", pu.drag_torque_nm)
        wc = g.param(self, "smoothing_speed", pu.smoothing_speed_rad_s)
        wmax = g.param(self, "max_speed", pu.max_speed_rad_s)
        gx = g.param(self, "extra_leak", 0.0)
        jr = g.param(self, "rotor_inertia", pu.rotor_inertia_kg_m2)
        pc = g.param(self, "compensator", p.compensator_pressure_pa)
        band = g.param(self, "compensator_band", p.compensator_band_pa)
        emin = g.param(self, "min_fraction", p.min_displacement_fraction)
        w = g.speed(self, "shaft")
        pa, pb, ps = g.p(self, "a"), g.p(self, "b"), g.p(self, "sense")
        eps, dp, q, tf = (g.local(self, k) for k in ("eps", "dp", "q", "tf"))
        g.line(f"{eps} = compensator_displacement_fraction({ps}, {pc}, {band}, {emin})")
        g.line(f"{dp} = {pa} - {pb}")
        g.line(f"{q} = pump_flow_m3_s({eps} * {w}, {dp}, {d}, {cs}, {gx}, U[U_MU])")
        g.line(f"{tf} = pump_friction_torque_nm({w}, {dp}, {eps} * {d}, {cf}, 0.0, {t0}, {wc}, "
               f"U[U_MU]) + pump_friction_torque_nm({w}, 0.0, {d}, 0.0, {cv}, 0.0, {wc}, "
               "U[U_MU])")
        g.flow(self, "a", q)
        g.flow(self, "b", f"-{q}")
        g.torque(self, "shaft", f"-({eps} * {d} * {dp} + {tf})")
        g.inertia(self, "shaft", jr)
        g.loss(self, "volumetric", f"{dp} * ({eps} * {d} * {w} - {q})")
        g.loss(self, "mechanical", f"{tf} * {w}")
        g.probe(self, "flow_m3_s", q)
        g.probe(self, "hydraulic_power_w", f"{dp} * {q}")
        g.probe(self, "displacement_fraction", eps)
        g.monitor(self, "speed_over_rating", f"abs({w}) / {wmax}")


# ---- fixed orifice ----------------------------------------------------------------------------

class FixedOrifice(Component):
    """A fixed restriction from ``a`` to ``b`` (an always-open valve edge, a restrictor):
    :func:`~afo_mj.hydraulics.laws.orifice_flow_m3_s` (Merritt 1967 §3.3). Loss:
    ``throttling``."""

    kind = "orifice"
    ports = {"a": HYDRAULIC, "b": HYDRAULIC}
    params_type = OrificeParams
    summary = "fixed orifice (restrictor, open valve edge)"

    def emit(self, g, p):
        area = g.param(self, "area", p.area_m2)
        cd = g.param(self, "cd", p.discharge_coefficient)
        pcr = g.param(self, "p_cr", p.transition_pressure_pa)
        pa, pb = g.p(self, "a"), g.p(self, "b")
        q = _emit_orifice_flow(g, self, "q", f"{pa} - {pb}", area, cd, pcr)
        g.flow(self, "a", f"-{q}")
        g.flow(self, "b", q)
        g.loss(self, "throttling", f"({pa} - {pb}) * {q}")
        g.probe(self, "flow_m3_s", q)


# ---- supply accumulator -----------------------------------------------------------------------

@dataclasses.dataclass(frozen=True)
class SupplyAccumulatorParams(Parameters):
    """A gas accumulator on a supply rail; ``accumulator.port_volume_m3`` is the rail's oil
    (manifold) volume."""

    accumulator: GasAccumulatorParams = GasAccumulatorParams()
    engage_band_pa: float = param(0.2e6, unit="Pa", lo=1e3, hi=5e6,
                                  doc="band above the precharge over which the gas engages")


class SupplyAccumulator(Component):
    """Gas accumulator on a supply rail: the capacitance
    :func:`~afo_mj.hydraulics.laws.gas_accumulator_capacitance_m3_pa` (polytropic gas above
    the precharge, engaged over ``engage_band_pa``) plus its port (manifold) oil volume. Its
    stored energy is the node's ``∫p dV``; the working-pressure rating is monitored. (The
    library's :class:`~afo_mj.circuits.components.GasAccumulator` with the band a parameter;
    the liquid stop behind a bottomed bladder is not simulated.)"""

    kind = "supply_accumulator"
    ports = {"port": HYDRAULIC}
    params_type = SupplyAccumulatorParams
    metadata_fields = ("accumulator.stop_bulk_modulus_pa",)
    summary = "gas accumulator with its engage band, on a supply rail"

    def emit(self, g, p):
        a = p.accumulator
        v0 = g.param(self, "gas_volume", a.gas_volume_m3)
        p0 = g.param(self, "precharge_abs", a.precharge_pressure_pa)
        n = g.param(self, "polytropic_index", a.polytropic_index)
        pmax = g.param(self, "max_pressure_abs", a.max_pressure_pa)
        band = g.param(self, "band", p.engage_band_pa)
        g.volume(self, "port", g.param(self, "port_volume", a.port_volume_m3))
        pp = g.p(self, "port")
        g.capacitance(self, "port", f"gas_accumulator_capacitance_m3_pa({pp} + P_ATM, {v0}, "
                      f"{p0}, {n}, {band})")
        g.monitor(self, "pressure_over_rating", f"({pp} + P_ATM) / {pmax}")


COMPONENTS = (ServoValve, OnOffValve, UnloadingValve, VariablePump, FixedOrifice,
              SupplyAccumulator)

__all__ = [c.__name__ for c in COMPONENTS] + [
    "ServoValveComponentParams", "OnOffComponentParams", "VariablePumpParams",
    "SupplyAccumulatorParams", "CircuitError"]
