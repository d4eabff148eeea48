"""Controllers of the valve-controlled circuits (seed ch. 4, 5, 7): a torque loop on the valve(s)
and a speed (or rail-pressure) loop on the supply motor, in one controller per circuit.

The torque loop and the supply loop are those of the hand-written valve kernel they replaced
(``tests/kernel_reference/valve_kernel.py``, the equivalence tests' reference). Besides the motor
voltage (the value the controller returns, ``U_CMD``) they set the valves' actuated inputs
(:meth:`afo_mj.circuits.codegen.Emitter.input_slot`): the servo valve's spool command, or the
on/off valves' PWM on-fractions and switching rates.

* :class:`ServoValveTorque` (``servo_valve_torque``) — servo valve + supply.
* :class:`DigitalValveTorque` (``digital_valve_torque``) — PWM switching (unloading) valve
  and release valve + constant-speed supply.
"""

from __future__ import annotations

import dataclasses

from afo_mj.circuits.components import CircuitError
from afo_mj.circuits.controllers import Controller
from afo_mj.hydraulics.params import Parameters, effect, param


@dataclasses.dataclass(frozen=True)
class SupplyControlParams(Parameters):
    """Motor speed loop of a valve circuit's supply, and the optional rail-pressure loop that
    sets its speed (supply mode ``pressure_control``)."""

    speed_set_rad_s: float = param(500.0, unit="rad/s", lo=0.0, hi=3000.0,
                                   doc="set speed (constant-speed supply); the top speed of "
                                       "a pressure-controlled one")
    speed_gain_v_s_per_rad: float = param(0.02, unit="V s/rad", lo=0.0, hi=10.0,
                                          doc="k_ω: voltage per speed error")
    speed_integral_gain_v_per_rad: float = param(0.5, unit="V/rad", lo=0.0, hi=1e3,
                                                 doc="k_ωi: voltage per ∫ speed error")
    speed_integral_limit_rad: float = param(50.0, unit="rad", lo=0.0, hi=1e6,
                                            doc="anti-windup clamp on ∫ speed error")
    pressure_control_enabled: bool = effect(
        False, doc="motor speed from a PI loop on the rail pressure (False: the set speed)")
    follows_demand_enabled: bool = effect(
        True, doc="rail set point = tank + load pressure + margin (False: pressure_set_pa)")
    pressure_set_pa: float = param(14.1e6, unit="Pa", lo=0.0, hi=40e6,
                                   doc="fixed rail set point (gauge)")
    pressure_margin_pa: float = param(1.5e6, unit="Pa", lo=0.0, hi=20e6,
                                      doc="rail above the load pressure (following)")
    pressure_min_pa: float = param(2.0e6, unit="Pa", lo=0.0, hi=20e6,
                                   doc="lowest rail set point (following)")
    pressure_gain_rad_s_per_pa: float = param(1e-4, unit="rad/s/Pa", lo=0.0, hi=1.0,
                                              doc="speed per rail pressure error")
    pressure_integral_gain_rad_per_pa: float = param(1e-3, unit="rad/(Pa s)", lo=0.0,
                                                     hi=10.0, doc="speed per ∫ rail error")
    pressure_integral_limit_pa_s: float = param(2e5, unit="Pa s", lo=0.0, hi=1e9,
                                                doc="anti-windup clamp on ∫ rail error")


@dataclasses.dataclass(frozen=True)
class ValveTorqueParams(Parameters):
    """Gains of a valve circuit's torque loop and its supply's loops."""

    valve_gain_per_pa: float = param(2e-8, unit="1/Pa", lo=0.0, hi=1e-4,
                                     doc="k_v: valve command per unit pressure error")
    valve_integral_gain_per_pa_s: float = param(1e-6, unit="1/(Pa s)", lo=0.0, hi=1.0,
                                                doc="k_vi: valve command per ∫ pressure error")
    valve_integral_limit_pa_s: float = param(2e5, unit="Pa s", lo=0.0, hi=1e9,
                                             doc="anti-windup clamp on ∫ pressure error")
    max_torque_nm: float = param(70.0, unit="N m", lo=1.0, hi=500.0,
                                 doc="commanded torque saturation")
    feedforward_density_kg_m3: float = param(870.0, unit="kg/m^3", lo=500.0, hi=2000.0,
                                             doc="oil density the flow feedforward assumes")
    supply: SupplyControlParams = SupplyControlParams()


@dataclasses.dataclass(frozen=True)
class DigitalValveTorqueParams(ValveTorqueParams):
    """:class:`ValveTorqueParams` and the PWM frequency of the on/off valves."""

    pwm_frequency_hz: float = param(50.0, unit="Hz", lo=1.0, hi=2000.0,
                                    doc="PWM frequency of the on/off valves")


def _refs(ctrl, circuit, keys):
    out = {}
    for key in keys:
        if key not in ctrl.refs:
            raise CircuitError(f"controller {ctrl.kind}: missing {key!r} (the name of the "
                               f"circuit's {key} component); allowed keys: {', '.join(keys)}")
        out[key] = circuit.component(ctrl.refs[key], f"controller.{key}")
    extra = sorted(set(ctrl.refs) - set(keys))
    if extra:
        raise CircuitError(f"controller {ctrl.kind}: unknown key {extra[0]!r}; allowed: "
                           f"{', '.join(keys)}")
    act = out["actuator"]
    if not hasattr(act, "torque_per_pa"):
        raise CircuitError(f"controller.actuator = {act.name!r} ({act.kind}) drives no joint")
    pump = out["pump"]
    if pump.kind not in ("pump", "variable_pump"):
        raise CircuitError(f"controller.pump = {pump.name!r} ({pump.kind}); allowed: a "
                           "'pump' or 'variable_pump'")
    return out


class _ValveTorqueBase(Controller):
    """Shared parts: the pressure-error loop and the supply's speed loop. The packed switch
    ``controller.valve_command_on`` (0 by default) makes the command the valve command ``u``
    itself, open loop (a bench replay of a measured valve command), with no torque demand
    reaching the supply loop."""

    def _torque_loop(self, g, p, circuit, act):
        own = circuit.controller_owner
        ktp = g.param(own, "torque_per_pa", act.torque_per_pa())
        tmax = g.param(own, "max_torque", p.max_torque_nm)
        kv = g.param(own, "k_v", p.valve_gain_per_pa)
        kvi = g.param(own, "k_vi", p.valve_integral_gain_per_pa_s)
        lim = g.param(own, "valve_int_limit", p.valve_integral_limit_pa_s)
        rho = g.param(own, "ff_density", p.feedforward_density_kg_m3)
        integ = g.ctrl_slot("pressure_integral")
        # open-loop bench replay: the command is the valve command itself (no torque demand)
        self.open_loop = g.param(own, "valve_command_on", 0.0)
        pa = g.p(act, "a")
        pb = g.p(act, "b") if "b" in act.ports else "0.0"
        for line in (f"tau_cmd = 0.0 if {self.open_loop} != 0.0 else "
                     f"min(max(cmd, -{tmax}), {tmax})",
                     f"dp_meas = {pa} - {pb}",
                     f"W[W_TAU_MEAS] = -{ktp} * dp_meas",
                     f"dp_des = -tau_cmd / {ktp}",
                     "err = dp_des - dp_meas",
                     f"integ = min(max({integ} + err * h, -{lim}), {lim})",
                     f"{integ} = integ",
                     f"q_ff = -{ktp} * thd"):
            g.ctrl_line(line)
        return kv, kvi, rho

    def _supply_loop(self, g, s, circuit, motor, pump, rail, tank, wset=None):
        """Motor voltage ``v = K ω_s + R d_eff (p_out − p_in)/K + k_ω e_ω + k_ωi ∫e_ω`` with
        ``ω_s`` the set speed or (pressure control) ``|Q_ff|/d + k_p e_p + k_i ∫e_p`` clipped
        to ``[0, ω_set]``, ``e_p`` the rail error against ``p_t + |Δp_d| + margin`` (at
        least the minimum) or the fixed set point. Emits the ``return``."""
        own = circuit.controller_owner
        if wset is None:
            wset = g.param(own, "speed_set", s.speed_set_rad_s)
        kw = g.param(own, "k_w", s.speed_gain_v_s_per_rad)
        kwi = g.param(own, "k_wi", s.speed_integral_gain_v_per_rad)
        wlim = g.param(own, "speed_int_limit", s.speed_integral_limit_rad)
        pc_on = g.param(own, "pressure_control_on", 1.0 if s.pressure_control_enabled else 0.0)
        follow = g.param(own, "follows_demand_on", 1.0 if s.follows_demand_enabled else 0.0)
        pset = g.param(own, "pressure_set", s.pressure_set_pa)
        margin = g.param(own, "pressure_margin", s.pressure_margin_pa)
        pmin = g.param(own, "pressure_min", s.pressure_min_pa)
        kpp = g.param(own, "k_pp", s.pressure_gain_rad_s_per_pa)
        kpi = g.param(own, "k_pi", s.pressure_integral_gain_rad_per_pa)
        plim = g.param(own, "pressure_int_limit", s.pressure_integral_limit_pa_s)
        pint = g.ctrl_slot("rail_integral")
        wint = g.ctrl_slot("speed_integral")
        d = g.param_ref(pump, "d")
        R, K = g.param_ref(motor, "R"), g.param_ref(motor, "K")
        w = g.speed(pump, "shaft")
        p_out, p_in = g.p(pump, "a"), g.p(pump, "b")
        if pump.kind == "variable_pump":
            eps = (f"compensator_displacement_fraction({g.p(pump, 'sense')}, "
                   f"{g.param_ref(pump, 'compensator')}, {g.param_ref(pump, 'compensator_band')}, "
                   f"{g.param_ref(pump, 'min_fraction')})")
        else:
            eps = "1.0"
        for line in (
                f"w_set = {wset}",
                f"if {pc_on} != 0.0:\n"
                f"    if {follow} != 0.0:\n"
                f"        p_d = max({tank} + abs(dp_des) + {margin}, {pmin})\n"
                f"    else:\n"
                f"        p_d = {pset}\n"
                f"    e_p = p_d - {rail}\n"
                f"    pint = min(max({pint} + e_p * h, -{plim}), {plim})\n"
                f"    {pint} = pint\n"
                f"    w_set = min(max(abs(q_ff) / {d} + {kpp} * e_p + {kpi} * pint, 0.0), "
                f"{wset})",
                f"e_w = w_set - {w}",
                f"wint = min(max({wint} + e_w * h, -{wlim}), {wlim})",
                f"{wint} = wint",
                f"i_ff = {eps} * {d} * ({p_out} - {p_in}) / {K}",
                f"return {K} * w_set + {R} * i_ff + {kw} * e_w + {kwi} * wint"):
            g.ctrl_line(line)


class ServoValveTorque(_ValveTorqueBase):
    """Torque control of a servo-valve circuit (seed ch. 4; the PHAFO's inner loop, ch. 7).

    Transducers on the actuator's chambers give ``Δp``; the demand ``Δp_d = −τ_cmd/k_τ``
    (``τ_cmd`` clipped to ``±max_torque_nm``, ``k_τ`` the actuator's torque per pascal). Spool
    command ``u = clip(u_ff + k_v e + k_vi ∫e, −1, 1)``, ``e = Δp_d − Δp`` (anti-windup clamp),
    with the flow feedforward ``u_ff = Q_ff/(C_d A_f √(2 Δp_e/ρ))``, ``Q_ff = −k_τ θ̇`` the flow
    that keeps the chamber pressures while the joint moves and ``Δp_e = max((p_s − p_t)/2,
    0.2 MPa)`` the drop across each of the two lands in series. The supply motor: see
    :meth:`_supply_loop`. References: ``motor``, ``pump``, ``valve`` (a ``servo_valve``),
    ``actuator``."""

    kind = "servo_valve_torque"
    params_type = ValveTorqueParams
    summary = "servo-valve torque loop + supply speed / rail-pressure loop"

    def emit(self, g, p, circuit):
        r = _refs(self, circuit, ("motor", "pump", "valve", "actuator"))
        valve = r["valve"]
        if valve.kind != "servo_valve":
            raise CircuitError(f"controller.valve = {valve.name!r} ({valve.kind}); allowed: "
                               "a 'servo_valve'")
        kv, kvi, rho = self._torque_loop(g, p, circuit, r["actuator"])
        ps, pt = g.p(valve, "p"), g.p(valve, "t")
        cd, af = g.param_ref(valve, "cd"), g.param_ref(valve, "full_area")
        cmd = g.input_slot(valve, "command")
        for line in (f"dpe = max(0.5 * ({ps} - {pt}), 2e5)",
                     f"u_ff = q_ff / ({cd} * {af} * math.sqrt(2.0 * dpe / {rho}))",
                     f"u = cmd if {self.open_loop} != 0.0 else "
                     f"u_ff + {kv} * err + {kvi} * integ",
                     f"{cmd} = min(max(u, -1.0), 1.0)",
                     f"{g.ctrl_slot('valve_command')} = {cmd}"):
            g.ctrl_line(line)
        self._supply_loop(g, p.supply, circuit, r["motor"], r["pump"], ps, pt)


def _check_digital_refs(r) -> None:
    for key in ("switching", "release"):
        comp = r[key]
        if comp.kind != "onoff_valve":
            raise CircuitError(f"controller.{key} = {comp.name!r} ({comp.kind}); "
                               "allowed: an 'onoff_valve'")


def _emit_pwm(g, own, r, f_hz) -> None:
    """The on/off valves' inputs from the metering command ``u`` (a local of the controller,
    in [−1, 1]): ``u ≥ 0`` the switching valve shut for the fraction ``u`` of each PWM period
    and the release valve shut; ``u < 0`` the switching valve open and the release valve open
    for ``−u`` of each period. Each valve's input is the PWM signal's on-fraction over the step
    (:func:`~afo_mj.hydraulics.laws.pwm_on_fraction`, the controller keeps the clock) and its
    switching rate, ``2 f`` while it is modulated."""
    sw, rel = r["switching"], r["release"]
    f = g.param(own, "pwm_frequency", f_hz)
    clock = g.ctrl_slot("time")
    s_cmd, s_rate = g.input_slot(sw, "command"), g.input_slot(sw, "switch_rate")
    r_cmd, r_rate = g.input_slot(rel, "command"), g.input_slot(rel, "switch_rate")
    for line in (
            f"t = {clock}",
            f"{clock} = t + h",
            "if u >= 0.0:\n    duty_s = 1.0 - u\n    duty_r = 0.0\n"
            "else:\n    duty_s = 1.0\n    duty_r = -u",
            f"{s_cmd} = pwm_on_fraction(t, h, duty_s, {f})",
            f"{r_cmd} = pwm_on_fraction(t, h, duty_r, {f})",
            f"{s_rate} = 2.0 * {f} if (duty_s > 0.0 and duty_s < 1.0) else 0.0",
            f"{r_rate} = 2.0 * {f} if (duty_r > 0.0 and duty_r < 1.0) else 0.0"):
        g.ctrl_line(line)


class DigitalValveTorque(_ValveTorqueBase):
    """Torque control of the digital circuit (seed ch. 5): the pump runs at its set speed; a
    normally-open on/off valve (``switching``) unloads it to tank, and while that valve is
    shut the pump's flow passes into line A; a normally-closed one (``release``) vents line A.

    ``u = clip(u_ff + k_v e + k_vi ∫e, −1, 1)`` as in :class:`ServoValveTorque` with the
    feedforward ``Q_ff/(d ω_set)`` for a flow into A, ``Q_ff/(C_d A_r √(2 max(p_A − p_t,
    0.2 MPa)/ρ))`` out of it; ``u`` meters the valves by PWM (:func:`_emit_pwm`).
    References: ``motor``, ``pump``, ``switching``, ``release`` (``onoff_valve``),
    ``actuator``."""

    kind = "digital_valve_torque"
    params_type = DigitalValveTorqueParams
    summary = "digital (PWM on/off valve) torque loop + constant-speed supply"

    def emit(self, g, p, circuit):
        r = _refs(self, circuit, ("motor", "pump", "switching", "release", "actuator"))
        _check_digital_refs(r)
        if p.supply.pressure_control_enabled:
            raise CircuitError("controller.supply.pressure_control_enabled = True: the "
                               "digital circuit meters a constant-speed pump (allowed: False)")
        kv, kvi, rho = self._torque_loop(g, p, circuit, r["actuator"])
        own = circuit.controller_owner
        d = g.param_ref(r["pump"], "d")
        wset = g.param(own, "speed_set", p.supply.speed_set_rad_s)
        rel = r["release"]
        pca = g.p(r["actuator"], "a")
        pt = g.p(rel, "b")
        rcd, ramax = g.param_ref(rel, "cd"), g.param_ref(rel, "max_area")
        for line in (
                "if q_ff > 0.0:\n"
                f"    u_ff = q_ff / ({d} * {wset})\n"
                "else:\n"
                f"    u_ff = q_ff / max({rcd} * {ramax} * math.sqrt(2.0 * max({pca} - {pt}, "
                f"2e5) / {rho}), 1e-12)",
                f"u = cmd if {self.open_loop} != 0.0 else u_ff + {kv} * err + {kvi} * integ",
                "u = min(max(u, -1.0), 1.0)",
                f"{g.ctrl_slot('valve_command')} = u"):
            g.ctrl_line(line)
        _emit_pwm(g, own, r, p.pwm_frequency_hz)
        rail = g.p(r["pump"], "a")
        self._supply_loop(g, p.supply, circuit, r["motor"], r["pump"], rail, pt, wset)


CONTROLLERS = (ServoValveTorque, DigitalValveTorque)

__all__ = ["SupplyControlParams", "ValveTorqueParams", "DigitalValveTorqueParams",
           "ServoValveTorque", "DigitalValveTorque", "CONTROLLERS"]
