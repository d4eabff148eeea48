"""Candidate effects for calibration: physical terms a model may lack, each switchable.

Every effect is a named, physically parameterised term of a component of the generated
circuits (:mod:`afo_mj.circuits.components`, :mod:`afo_mj.circuits.valves`): the cylinders'
seals, leakage and series cable, the hoses, the oil, the pump, the driver and the servo valve,
each written into the circuit's packed parameter row **by label** (``component.key``,
:attr:`afo_mj.circuits.codegen.CompiledCircuit.param_labels`; every one of them is built into
the circuit whatever its preset value, so varying it never recompiles); the cable transmission
(:mod:`afo_mj.hydraulics.transmission`), the oil's temperature (viscosity, Walther/ASTM D341)
and the sensors (:mod:`afo_mj.hydraulics.sensor`). The calibration
(:mod:`afo_mj.calibration.calibrate`) starts from the **lean model**, the preset with every
effect of this library switched off (:func:`lean_setting`), adds effects one at a time and keeps
those that pay.

Each effect knows how to switch itself on in a :class:`ModelSetting` (:meth:`Effect.apply`):
packed circuit parameters (label → value) for the hydraulic terms, the backlash width and
temperature drift of the replay (:class:`afo_mj.experiments.bench_replay.BenchReplay`), or a
sensor transform applied to the replayed outputs.

=========================  ==============================================================
effect                      term (component: equation; source)
=========================  ==============================================================
stribeck_friction           seal: ``F_S exp(−(v/v_St)²) v/v_St`` (Stribeck peak; Simscape
                            translational friction, facts.md)
pressure_friction           seal: ``c_p |Δp| tanh(v/v_C)`` (seed §2.3, ref. [48])
seal_pressure_friction      seal, per seal: ``f_h (|Δp| + p_a⁺ + p_b⁺) tanh(v/v_C)``: the
                            piston seal against ``|p_a − p_b|``, each cable seal against its
                            own chamber (Parker O-ring handbook ORD 5700)
cable_seal_pressure_friction
                            seal, each cable seal only: ``f_h (p_a⁺ + p_b⁺) tanh(v/v_C)``
                            (Parker ORD 5700; the piston seal as declared)
entrained_air               oil: bulk modulus with air fraction ``a`` (seed eq. 2.5)
hose_wall_compliance        hose: ``C += V_h/(2 K_wall)`` per end (Merritt §2.5)
piston_leakage              cylinder: ``Q = G_l Δp/μ`` across each piston (laminar gap)
pump_leakage                pump: extra ``Q = G_p Δp/μ`` between the ports (worn port plate)
motor_current_limit         driver: voltage clamped to ``Kω ± R I_max`` (current limit)
series_compliance           cable: differential capacitance ``(n A r)²/k`` (transmission)
backlash                    cable: play operator of width ``b`` on the kinematics (an
                            imposed angle); a described circuit: dead band ``±b r/2`` in
                            the cable (Nordin & Gutman 2002 dead-zone model), also on a
                            simulated load
viscosity_drift             oil: ``T = T_0 + Ṫ t`` → ``μ(T)`` (Walther, ASTM D341)
check_valve_cracking        charge check valves: flow only past ``p_crack`` (described
                            circuits; Manring §4.5)
charge_loss                 charge circuit: a drain ``Q = G_d p/μ`` from each pump port to
                            the tank and seat leakage ``Q = G_s Δp/μ`` through each check
                            valve (described circuits; Watton 2009, Merritt §3.2)
motor_friction              motor: ``T_c tanh(ω/ω_c) + b ω`` (described circuits whose motor
                            has no friction declared)
sensor_delay                sensors: every output read ``d`` late
sensor_gain_offset[ch]      sensor of channel ``ch``: ``g y + b`` (only for channels
                            marked uncalibrated)
sensor_lag[ch]              sensor of channel ``ch``: first-order lag ``τ`` (described
                            circuits; Doebelin §3.3)
valve_overlap               servo valve: lap ``x_0`` of the spool (dead band)
spool_lag                   servo valve: first-order spool ``τ ẋ = u − x``
=========================  ==============================================================

Fluid inertance is not in the library: the hoses' inertance needs flow states the lumped hose
does not carry (a known gap; its signature, a line resonance in the pressures, is reported as
``unexplained_residual`` with where it lives).
"""

from __future__ import annotations

import dataclasses
from typing import Callable, Collection, Sequence

import numpy as np

from afo_mj.hydraulics.params import ParameterError

__all__ = ["EffectParameter", "Effect", "ModelSetting", "DeclaredParameter", "effects_for",
           "lean_setting", "declared_parameters", "EFFECT_NAMES", "effect_by_name",
           "described_off"]


@dataclasses.dataclass(frozen=True)
class EffectParameter:
    """One parameter of an effect (or a declared parameter): SI unit, bounds for the fit and a
    typical value (the fit's start and the ranking's probe)."""

    name: str
    unit: str
    lo: float
    hi: float
    typical: float
    doc: str = ""
    #: values the ranking also probes for a shape parameter (a described rig's ranking)
    probe_values: tuple[float, ...] = ()

    def __post_init__(self):
        if not (np.isfinite(self.lo) and np.isfinite(self.hi) and self.lo < self.hi):
            raise ParameterError(f"{self.name}: bounds [{self.lo!r}, {self.hi!r}]; allowed: "
                                 "finite with lo < hi")
        if not self.lo <= self.typical <= self.hi:
            raise ParameterError(f"{self.name}: typical = {self.typical!r}; allowed: within "
                                 f"[{self.lo!r}, {self.hi!r}]")

    @property
    def scale(self) -> float:
        """The magnitude the fit normalises by."""
        return max(abs(self.typical), abs(self.hi - self.lo) * 1e-3, 1e-300)


@dataclasses.dataclass
class ModelSetting:
    """What one replay runs with: packed circuit parameters by label, replay options and
    sensor transforms (``(channel or "*", gain, offset, delay_s)``, applied in order)."""

    row: dict[str, float] = dataclasses.field(default_factory=dict)
    backlash_rad: float = 0.0
    temperature_rate_k_s: float = 0.0
    sensors: list[tuple[str, float, float, float]] = dataclasses.field(default_factory=list)

    def copy(self) -> "ModelSetting":
        return ModelSetting(dict(self.row), self.backlash_rad, self.temperature_rate_k_s,
                            list(self.sensors))


@dataclasses.dataclass(frozen=True)
class Effect:
    """A candidate effect: name, the component it belongs to, its equation and source, its
    parameters and how to switch it on (``setter(setting, values, context)``); ``labels``:
    the packed circuit parameters it writes (an effect whose circuit lacks one is not
    offered)."""

    name: str
    component: str
    equation: str
    reference: str
    parameters: tuple[EffectParameter, ...]
    setter: Callable[[ModelSetting, Sequence[float], dict], None]
    #: offered only for a described rig (an effect of the description's own parts that the
    #: presets' lean model keeps on: check-valve cracking, motor friction)
    described_only: bool = False
    signature: str = ""
    channel: str = ""
    labels: tuple[str, ...] = ()

    def apply(self, setting: ModelSetting, values: Sequence[float], context: dict) -> None:
        if len(values) != len(self.parameters):
            raise ParameterError(f"effect {self.name}: {len(values)} values for parameters "
                                 f"{[p.name for p in self.parameters]}")
        self.setter(setting, values, context)


@dataclasses.dataclass(frozen=True)
class DeclaredParameter:
    """A parameter of the declared model the calibration always fits: packed circuit
    parameters (``labels``: those the circuit has are all set to the same factor times their
    preset values; the first present is the one reported), bounded to
    ``[lo_factor, hi_factor]`` times the preset's value.

    ``tolerance``: how far (relative) a real part may sit from its datasheet value (0: not
    checked); ``above``/``below``: the effects a fitted value beyond the tolerance on that side
    is indistinguishable from (a worn pump's extra slip *is* a larger slip coefficient; check
    valves that crack late *are* a lower charge pressure), which the report names as what the
    deviation may be."""

    name: str
    unit: str
    labels: tuple[str, ...]
    lo_factor: float
    hi_factor: float
    doc: str = ""
    tolerance: float = 0.0
    above: tuple[str, ...] = ()
    below: tuple[str, ...] = ()
    #: a described rig's value (:mod:`afo_mj.calibration.declared_set`): its place in the
    #: description (the fit sets it there and the row follows), described value, kind
    path: str = ""
    value: float | None = None
    kind: str = ""


# ---------------------------------------------------------------------------- the effects
def _row(*labels):
    """A setter writing the effect's parameters, in order, into the packed ``labels`` (a
    label that is a tuple receives the same value in each of its entries)."""
    def set_(s: ModelSetting, v, ctx):
        for lab, x in zip(labels, v):
            for one in (lab if isinstance(lab, tuple) else (lab,)):
                s.row[one] = float(x)
    return set_


def _flat(*labels) -> tuple[str, ...]:
    return tuple(x for lab in labels for x in (lab if isinstance(lab, tuple) else (lab,)))


def _set_current_limit(s, v, ctx):
    s.row["motor.limit_on"] = 1.0
    s.row["motor.current_limit"] = float(v[0])


def _set_backlash(s, v, ctx):
    s.backlash_rad = float(v[0])


def _set_drift(s, v, ctx):
    s.temperature_rate_k_s = float(v[0])


def _set_delay(s, v, ctx):
    s.sensors.append(("*", 1.0, 0.0, float(v[0])))


def _set_gain_offset(channel):
    def set_(s, v, ctx):
        s.sensors.append((channel, float(v[0]), float(v[1]), 0.0))
    return set_


#: the packed circuit parameters the effects write (``component.key`` of
#: :func:`afo_mj.devices.hafo.hafo_circuit` / :func:`afo_mj.devices.valve_afo.valve_circuit`)
_STRIBECK = ("cylinders.seal_stribeck", "cylinders.seal_v_st")
_CP = "cylinders.seal_cp"
_CP_CHAMBER = "cylinders.seal_cp_chamber"
_AIR = "fluid.air_fraction"
_WALL = ("hose_a.wall_inv", "hose_b.wall_inv")
_LEAK = "cylinders.leak_g"
_PUMP_LEAK = "pump.extra_leak"
_CURRENT_LIMIT = ("motor.limit_on", "motor.current_limit")
_SERIES = "cylinders.series_compliance"
_LAP = "servo.lap"
_CHECK_CRACK = ("check_a.cracking", "check_b.cracking")
_MOTOR_FRICTION = ("motor.coulomb_nm", "motor.viscous")
_SPOOL_TAU = "servo.tau"
_PLAY = "cylinders.backlash"
_DRAIN = ("drain_a.conductance", "drain_b.conductance")
_SEAT = ("check_a.seat_leak", "check_b.seat_leak")


def _common_effects() -> list[Effect]:
    P = EffectParameter
    return [
        Effect("stribeck_friction", "seal",
               "F_S exp(-(v/v_St)^2) v/v_St added to the seal friction of each cylinder",
               "Stribeck breakaway peak; Simscape translational friction (facts.md)",
               (P("stribeck_force_n", "N", 0.0, 500.0, 30.0, "Stribeck gain F_S per cylinder"),
                P("stribeck_velocity_m_s", "m/s", 1e-3, 0.1, 0.01, "v_St",
                  probe_values=(0.002, 0.03))),
               _row(*_STRIBECK), signature="torque residual odd in piston speed, peaked at "
                                           "low speed (velocity reversals)",
               labels=_flat(*_STRIBECK)),
        Effect("pressure_friction", "seal",
               "c_p |Δp| tanh(v/v_C) per cylinder",
               "seed §2.3 (pressure-energised seals, ref. [48]); afo_mj.hydraulics.seal",
               (P("pressure_coefficient_m2", "m^2", 0.0, 5e-5, 2e-6,
                  "friction force per Pa across the piston"),),
               _row(_CP), signature="torque residual ∝ |Δp|·sign(v)", labels=(_CP,)),
        Effect("seal_pressure_friction", "seal",
               "f_h (|Δp| + p_a⁺ + p_b⁺) tanh(v/v_C) per cylinder: the piston seal against "
               "|p_a − p_b|, each cable seal against its own chamber's gauge pressure",
               "Parker O-ring handbook ORD 5700, friction F = F_C + F_H per seal; "
               "afo_mj.hydraulics.laws.chamber_seal_pressure_friction_n",
               (P("seal_pressure_coefficient_m2", "m^2", 0.0, 5e-5, 2e-6,
                  "friction force per Pa of each seal's own sealed pressure"),),
               _row((_CP, _CP_CHAMBER)),
               signature="torque residual ∝ (|Δp| + p_a + p_b)·sign(v): grows with the "
                         "common-mode pressure too", labels=(_CP, _CP_CHAMBER)),
        Effect("cable_seal_pressure_friction", "seal",
               "f_h (p_a⁺ + p_b⁺) tanh(v/v_C) per cylinder: each cable (rod) seal against its "
               "own chamber's gauge pressure, the piston seal's friction as declared",
               "Parker O-ring handbook ORD 5700, friction F = F_C + F_H per seal (a piston "
               "seal of low or balanced friction, the cable seals loaded by their chambers); "
               "afo_mj.hydraulics.laws.chamber_seal_pressure_friction_n",
               (P("cable_seal_pressure_coefficient_m2", "m^2", 0.0, 5e-5, 2e-6,
                  "friction force per Pa of each cable seal's own chamber pressure"),),
               _row(_CP_CHAMBER),
               signature="torque residual ∝ (p_a + p_b)·sign(v): the common-mode pressure "
                         "only", labels=(_CP_CHAMBER,)),
        Effect("entrained_air", "oil",
               "B_eff(p) of seed eq. 2.5 with air fraction a at atmospheric pressure",
               "seed eq. 2.5 (entrained air)",
               (P("air_fraction", "-", 0.0, 0.1, 0.005, "free air volume fraction at 1 atm"),),
               _row(_AIR), signature="pressure lag growing at low pressure", labels=(_AIR,)),
        Effect("hose_wall_compliance", "hose",
               "C += V_h/(2 K_wall) at each hose end",
               "Merritt, Hydraulic Control Systems (1967) §2.5",
               (P("wall_compliance_1_pa", "1/Pa", 0.0, 1e-7, 1e-9,
                  "1/K_wall of the hose wall"),),
               _row(_WALL), signature="pressure lag independent of pressure",
               labels=_flat(_WALL)),
        Effect("piston_leakage", "cylinder",
               "Q = G_l Δp/μ across the piston (laminar gap)",
               "Merritt §3 (annular clearance flow); afo_mj.hydraulics.cylinder",
               (P("leakage_conductance_m3", "m^3", 0.0, 1e-12, 2e-15, "G_l per cylinder"),),
               _row(_LEAK), signature="chamber Δp decays under load; residual ∝ ∫Δp",
               labels=(_LEAK,)),
        Effect("pump_leakage", "pump",
               "Q = G_p Δp/μ between the pump ports (in addition to the slip coefficient)",
               "Wilson slip flow, McCandlish & Dorey (1984); afo_mj.hydraulics.pump",
               (P("extra_leakage_conductance_m3", "m^3", 0.0, 1e-12, 2e-15, "G_p"),),
               _row(_PUMP_LEAK), signature="speed/pressure residual ∝ Δp_pump",
               labels=(_PUMP_LEAK,)),
        Effect("motor_current_limit", "driver",
               "v clamped to K ω ± R I_max (the driver's current limit)",
               "afo_mj.hydraulics.motor (driver)",
               (P("current_limit_a", "A", 0.3, 40.0, 5.0, "I_max"),),
               _set_current_limit, signature="current residual where |i| is large: a flat "
                                             "top", labels=_CURRENT_LIMIT),
        Effect("series_compliance", "transmission",
               "differential chamber capacitance (n A r)²/k (cable stiffness k)",
               "afo_mj.hydraulics.laws.series_spring_capacitance_m3_pa, "
               "coupled_node_rate_pa_s",
               (P("compliance_rad_per_nm", "rad/(N m)", 0.0, 1e-2, 2e-4, "1/k"),),
               _row(_SERIES), signature="torque/pressure lag ∝ dτ/dt", labels=(_SERIES,)),
        Effect("backlash", "transmission",
               "play operator of total width b on the ankle angle the cylinders see",
               "Tao & Kokotović (1996) ch. 3; afo_mj.hydraulics.transmission.play_operator",
               (P("backlash_rad", "rad", 0.0, 0.2, 0.01, "b"),),
               _set_backlash, signature="residual at velocity reversals ∝ sign(θ̇)"),
        Effect("viscosity_drift", "oil",
               "T = T_0 + Ṫ (t − t_0) sets μ(T) (Walther, ASTM D341)",
               "ASTM D341; afo_mj.hydraulics.fluid",
               (P("temperature_rate_k_s", "K/s", -2.0, 2.0, 0.2, "Ṫ"),),
               _set_drift, signature="residual growing with time (leakage/line loss drift)"),
        Effect("check_valve_cracking", "check valve",
               "flow G (p_c − p_crack − p)₊: the charge check valves open only past p_crack",
               "afo_mj.hydraulics.laws (check valve with cracking pressure; Manring §4.5)",
               (P("cracking_pa", "Pa", 0.0, 3e5, 3e4, "cracking pressure p_crack"),),
               _row(_CHECK_CRACK), described_only=True,
               signature="the low line sags below the charge pressure before the check "
                         "valve feeds it", labels=_flat(_CHECK_CRACK)),
        Effect("charge_loss", "charge circuit",
               "Q = G_d p/μ from each pump port to the tank (case drain) and Q = G_s Δp/μ "
               "through each check valve's seat, both ways; the charge circuit makes up "
               "what is lost",
               "Watton, Fundamentals of Fluid Power Control (2009), pump external leakage "
               "and the closed circuit's make-up; Merritt (1967) §3.2 (laminar leakage); "
               "afo_mj.circuits.components.Drain, CheckValve",
               (P("drain_conductance_m3", "m^3", 0.0, 1e-13, 2e-15,
                  "G_d per pump port (Q = G_d p/μ)"),
                P("seat_leakage_m3", "m^3", 0.0, 1e-13, 5e-16,
                  "G_s per check valve (Q = G_s Δp/μ)")),
               _row(_DRAIN, _SEAT), described_only=True,
               signature="the loop's common-mode pressure drifts back to the charge "
                         "pressure (oil lost to the drain, made up by the check valves)",
               labels=_flat(_DRAIN, _SEAT)),
        Effect("motor_friction", "motor",
               "T_f = T_c tanh(ω/ω_c) + b ω on the motor shaft (bearing, brush, seal drag)",
               "afo_mj.hydraulics.laws.motor_friction_torque_nm (Armstrong-Hélouvry 1994)",
               (P("coulomb_torque_nm", "N m", 0.0, 0.1, 5e-3, "T_c"),
                P("viscous_nm_s_rad", "N m s/rad", 0.0, 1e-3, 1e-5, "b")),
               _row(*_MOTOR_FRICTION), described_only=True,
               signature="current residual ∝ sign(ω) and ω", labels=_flat(*_MOTOR_FRICTION)),
        Effect("sensor_delay", "sensors",
               "every output read late: y_meas(t) = y(t − d)",
               "afo_mj.hydraulics.sensor (acquisition latency, filter group delay)",
               (P("delay_s", "s", 0.0, 0.05, 0.003, "d"),),
               _set_delay, signature="residual ∝ −d·dy/dt"),
    ]


def _circuit_backlash() -> Effect:
    """The backlash of a described circuit: the cable's dead band inside the circuit
    (:class:`afo_mj.circuits.components.PulleyCylinders`, ``backlash_rad``), so it acts on a
    simulated load as on an imposed angle."""
    return Effect("backlash", "transmission",
                  "dead band of total width b in the cable at the pulley, in series with the "
                  "cable spring: F = k dz(δ), no force inside |δ| ≤ b r/2",
                  "Nordin & Gutman, Automatica 38 (2002) 1633, eq. 2 (dead-zone model); "
                  "afo_mj.circuits.components.PulleyCylinders",
                  (EffectParameter("backlash_rad", "rad", 0.0, 0.2, 0.01, "b",
                                   probe_values=(0.003, 0.03)),),
                  _row(_PLAY), described_only=True,
                  signature="no torque while the joint crosses the gap after each force "
                            "reversal: angle and torque residuals at reversals",
                  labels=(_PLAY,))


def _gain_offset_effect(channel: str, spread: float) -> Effect:
    P = EffectParameter
    return Effect(f"sensor_gain_offset[{channel}]", "sensors",
                  f"{channel}: y_meas = g y + b", "afo_mj.hydraulics.sensor (span and zero)",
                  (P("gain", "-", 0.5, 2.0, 1.0, "g"),
                   P("offset", _unit(channel), -spread, spread, 0.0, "b")),
                  _set_gain_offset(channel), signature=f"{channel} residual ∝ y and constant",
                  channel=channel)


def _set_lag(channel):
    def set_(s, v, ctx):
        s.sensors.append((channel, 1.0, 0.0, 0.0, float(v[0])))
    return set_


def _lag_effect(channel: str) -> Effect:
    return Effect(f"sensor_lag[{channel}]", "sensors",
                  f"{channel}: τ ẏ_m = y − y_m (first-order sensor dynamics)",
                  "Doebelin, Measurement Systems §3.3; afo_mj.hydraulics.sensor.first_order_lag",
                  (EffectParameter("time_constant_s", "s", 1e-4, 0.05, 2e-3, "τ"),),
                  _set_lag(channel), signature=f"{channel} residual ∝ −τ dy/dt, growing "
                                               "with frequency", channel=channel)


def _unit(channel: str) -> str:
    from afo_mj.calibration.measured_data import CHANNELS
    return CHANNELS[channel].unit if channel in CHANNELS else "-"


def _valve_effects() -> list[Effect]:
    P = EffectParameter
    return [
        Effect("valve_overlap", "servo valve",
               "edge area w x_max ramp(|x| − x_0): no flow inside the lap x_0 (dead band)",
               "afo_mj.hydraulics.servo_valve (Merritt §3.4, overlapped spool)",
               (P("overlap", "-", 0.0, 0.4, 0.05, "lap x_0 as a fraction of the stroke"),),
               _row(_LAP),
               signature="flow missing at small commands: residual where |u| < x_0",
               labels=(_LAP,)),
        Effect("spool_lag", "servo valve",
               "τ ẋ = u − x (the spool's first-order lag)",
               "afo_mj.hydraulics.servo_valve (bandwidth f = 1/(2πτ))",
               (P("spool_time_constant_s", "s", 1e-4, 0.1, 0.01, "τ"),),
               _row(_SPOOL_TAU),
               signature="pressure residual ∝ −τ du/dt", labels=(_SPOOL_TAU,)),
    ]


#: names of the library's effects (per-channel sensor effects as ``sensor_gain_offset[ch]``)
EFFECT_NAMES = tuple(e.name for e in _common_effects()) + (
    "sensor_gain_offset", "sensor_lag") + tuple(e.name for e in _valve_effects())

#: the lean model's values of what the effects switch on (the circuits' shared entries)
_LEAN_ROW = {_STRIBECK[0]: 0.0, _CP: 0.0, _CP_CHAMBER: 0.0, _AIR: 0.0, _WALL[0]: 0.0,
             _WALL[1]: 0.0, _LEAK: 0.0, _PUMP_LEAK: 0.0, _CURRENT_LIMIT[0]: 0.0, _SERIES: 0.0}
#: what "switched off" means in a described circuit (the lean values and the effects only a
#: described circuit is offered)
_OFF_VALUES = dict(_LEAN_ROW, **{_CHECK_CRACK[0]: 0.0, _CHECK_CRACK[1]: 0.0,
                                 _MOTOR_FRICTION[0]: 0.0, _MOTOR_FRICTION[1]: 0.0,
                                 _PLAY: 0.0},
                   **{lab: 0.0 for lab in _DRAIN + _SEAT})
#: the servo valve's: critical-centre spool, and a fast one (0.5 ms: 320 Hz)
_LEAN_VALVE = {_LAP: 0.0, _SPOOL_TAU: 5e-4}


def _offered(e: Effect, available, is_off=None) -> bool:
    if available is not None and not all(lab in available for lab in e.labels):
        return False
    return is_off is None or is_off(e)


def effects_for(outputs: Sequence[str],
                output_spread: dict[str, float] | None = None,
                available: Collection[str] | None = None,
                is_off: Callable[[Effect], bool] | None = None,
                uncalibrated: Collection[str] | None = None,
                described: bool = False) -> list[Effect]:
    """The candidate effects for a replay whose record has the output channels ``outputs``
    (one gain/offset effect per output). ``available``: the circuit's packed parameter
    labels; an effect writing a label the circuit has not (the servo valve's lap in the
    digital circuit and in the pump-controlled HAFO) is left out. ``described`` (a described
    rig, :attr:`afo_mj.experiments.bench_replay.BenchReplay.described`): ``is_off(effect)``
    tells whether the description has the effect switched off (an effect the user described
    is part of the declared model, not a candidate), a sensor gain/offset is offered only for
    the channels in ``uncalibrated`` (those the user marks so; every channel when ``None``),
    and a first-order lag per output besides."""
    out = [e for e in _common_effects() + _valve_effects()
           if described or not e.described_only]
    if described:
        # a described circuit's backlash is its cable's dead band (a simulated load has no
        # imposed angle for the play operator)
        out = [_circuit_backlash() if e.name == "backlash" else e for e in out]
    out = [e for e in out if e.labels or not described or e.name in _CIRCUIT_OTHER]
    out = [e for e in out if _offered(e, available, is_off if described else None)]
    spread = output_spread or {}
    for ch in outputs:
        if uncalibrated is not None and ch not in uncalibrated:
            continue
        out.append(_gain_offset_effect(ch, float(spread.get(ch, 1.0))))
    if described:
        out += [_lag_effect(ch) for ch in outputs]
    return out


def effect_by_name(effects: Sequence[Effect], name: str) -> Effect:
    for e in effects:
        if e.name == name:
            return e
    raise ParameterError(f"effect = {name!r}; allowed: {', '.join(e.name for e in effects)}")


def described_off(e: Effect, value: Callable[[str], float]) -> bool:
    """Whether a described circuit has effect ``e`` switched off: each of its labels that the
    lean model sets holds the lean value in the description (``value(label)``)."""
    return all(value(lab) == _OFF_VALUES[lab] for lab in e.labels if lab in _OFF_VALUES)


#: the effects a described circuit's replay offers besides those writing circuit labels
#: (its backlash is the cable's dead band, a circuit label: :func:`_circuit_backlash`)
_CIRCUIT_OTHER = ("viscosity_drift", "sensor_delay")


def lean_setting(available: Collection[str] | None = None,
                 described: bool = False) -> ModelSetting:
    """The lean model: every effect of the library off (the entries of ``available`` labels
    only, when given: a circuit without a servo valve has no lap to close). A described
    circuit is its own declared model: nothing is switched off (its effects that are off
    are the candidates)."""
    if described:
        return ModelSetting(row={})
    row = dict(_LEAN_ROW)
    row.update(_LEAN_VALVE)
    if available is not None:
        row = {k: v for k, v in row.items() if k in available}
    return ModelSetting(row=row)


def declared_parameters(command: str) -> tuple[DeclaredParameter, ...]:
    """A preset's declared parameters, which the calibration fits before looking for
    effects: the oil and seal values and those of the element the open-loop ``command``
    drives (the motor for a motor voltage, the metering valve for a valve command). A
    described rig declares every value of its description instead
    (:mod:`afo_mj.calibration.declared_set`)."""
    D = DeclaredParameter
    common = (D("seal_coulomb_force_n", "N", ("cylinders.seal_fc",), 0.0, 20.0,
                "Coulomb friction of one cylinder's seals"),
              D("liquid_bulk_modulus_pa", "Pa", ("fluid.liquid_bulk_modulus",), 0.3, 2.0,
                "oil bulk modulus"))
    if command == "motor_voltage_v":
        return (D("motor_resistance_ohm", "ohm", ("motor.R",), 0.5, 2.0, "winding resistance"),
                D("torque_constant_nm_a", "N m/A", ("motor.K",), 0.7, 1.4, "motor K")) + common
    if command != "valve_command":
        raise ParameterError(f"command = {command!r}; allowed: motor_voltage_v, "
                             "valve_command (the open-loop command of a preset)")
    # the servo valve's metering area, or the digital circuit's open edges sized like it
    return (D("valve_full_area_m2", "m^2", ("servo.full_area", "edge_pa.area", "edge_bt.area"),
              0.5, 2.0, "servo valve metering area at full stroke"),) + common
