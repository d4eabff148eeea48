"""Low-level controllers a circuit description can name (the ``controller`` of a circuit).

A controller turns the per-step command (a torque, a voltage) and the circuit's measured
states into the actuated component's input (the motor's voltage command ``U_CMD``). Like the
components, it writes code through the emitter and keeps its gains in a validated dataclass.
"""

from __future__ import annotations

import dataclasses

from afo_mj.circuits.components import CircuitError
from afo_mj.hydraulics.params import Parameters, param


class Controller:
    """Base: ``kind``, ``params``; :meth:`emit` writes the body of ``controller(y, th, thd,
    cmd, h, P, W)`` (which returns the actuated input)."""

    kind = ""
    params_type: type = Parameters
    summary = ""

    def __init__(self, params=None, **refs):
        self.params = self.params_type() if params is None else params
        if not isinstance(self.params, self.params_type):
            raise CircuitError(f"controller {self.kind!r}: params must be "
                               f"{self.params_type.__name__}")
        self.refs = refs

    def emit(self, g, p, circuit) -> None:  # pragma: no cover
        raise NotImplementedError


@dataclasses.dataclass(frozen=True)
class NoParams(Parameters):
    """No parameters."""


class OpenLoop(Controller):
    """The command is the actuated input itself (motor voltage, V): open-loop bench tests."""

    kind = "open_loop"
    params_type = NoParams
    summary = "command passed through (motor voltage)"

    def emit(self, g, p, circuit):
        g.ctrl_line("W[W_TAU_MEAS] = 0.0")
        g.ctrl_line("return cmd")


@dataclasses.dataclass(frozen=True)
class PumpTorqueGains(Parameters):
    """Gains of the pump-controlled torque loop (the HAFO's law)."""

    pressure_gain_rad_s_per_pa: float = param(1.2e-5, unit="rad/s/Pa", lo=0.0, hi=1e-2,
                                              doc="k_p: pump speed per unit pressure error")
    pressure_integral_gain_rad_per_pa: float = param(4e-4, unit="rad/(Pa s)", lo=0.0, hi=1.0,
                                                     doc="k_i: pump speed per ∫ pressure error")
    integral_limit_pa_s: float = param(1e5, unit="Pa s", lo=0.0, hi=1e9,
                                       doc="anti-windup clamp on ∫ pressure error")
    speed_gain_v_s_per_rad: float = param(0.02, unit="V s/rad", lo=0.0, hi=10.0,
                                          doc="k_ω: motor voltage per unit speed error")
    spring_feedforward: float = param(0.0, unit="-", lo=0.0, hi=1.0,
                                      doc="k_s: fraction of a spring-return actuator's "
                                          "spring force added to the pressure demand (0: the "
                                          "HAFO's law; 1: the spring's torque compensated, "
                                          "so zero command is transparent)")


class PumpTorque(Controller):
    """Torque control of a pump-controlled circuit through motor voltage (seed ch. 6; the
    HAFO's controller). Pressure transducers on the actuator's nodes give the hydraulic
    torque ``τ_m = −k_τ (p_a − p_b)`` (``k_τ`` the actuator's torque per pascal). The pump
    speed demand is the flow feedforward that holds the pressures while the joint moves plus a
    PI law on the pressure error; the voltage adds the current feedforward for the pump torque
    and a proportional speed loop on the motor's Hall speed::

        ω_d = −k_τ θ̇ / d + k_p e + k_i ∫e dt,   e = Δp_d − (p_a − p_b)
        Δp_d = −τ_cmd/k_τ + k_s (F_0 + k x(θ)) / A
        v   = R d Δp_d / K + K ω_d + k_ω (ω_d − ω)

    The spring term (``spring_feedforward`` k_s, default 0) is for a spring-return cylinder
    (:class:`~afo_mj.circuits.components.SpringReturnCylinder`): the pressure that holds its
    return spring, ``(F_0 + k (x_0 − r θ)) / A``, so that the delivered torque, not only the
    hydraulic one, follows the command.

    References: ``motor``, ``pump``, ``actuator`` (component names); the actuator's ports
    ``a``/``b`` are the measured nodes (``b`` may be absent: single-acting, gauge)."""

    kind = "pump_torque"
    params_type = PumpTorqueGains
    summary = "pump-controlled torque loop (pressure PI + flow feedforward, HAFO)"

    def emit(self, g, p, circuit):
        for key in ("motor", "pump", "actuator"):
            if key not in self.refs:
                raise CircuitError(f"controller pump_torque: missing {key!r} (the name of "
                                   f"the circuit's {key} component)")
        motor = circuit.component(self.refs["motor"], "controller.motor")
        pump = circuit.component(self.refs["pump"], "controller.pump")
        act = circuit.component(self.refs["actuator"], "controller.actuator")
        if not hasattr(act, "torque_per_pa"):
            raise CircuitError(f"controller.actuator = {act.name!r} ({act.kind}) drives no "
                               "joint")
        ktp = g.param(circuit.controller_owner, "torque_per_pa", act.torque_per_pa())
        kp = g.param(circuit.controller_owner, "k_p", p.pressure_gain_rad_s_per_pa)
        ki = g.param(circuit.controller_owner, "k_i", p.pressure_integral_gain_rad_per_pa)
        lim = g.param(circuit.controller_owner, "int_limit", p.integral_limit_pa_s)
        kw = g.param(circuit.controller_owner, "k_w", p.speed_gain_v_s_per_rad)
        d = g.param_ref(pump, "d")
        R, K = g.param_ref(motor, "R"), g.param_ref(motor, "K")
        integ = g.ctrl_slot("pressure_integral")
        ks = g.param(circuit.controller_owner, "spring_ff", p.spring_feedforward)
        spring = "0.0"
        if act.kind == "spring_return_cylinder":
            spring = (f"{ks} * ({g.param_ref(act, 'spring_f0')} + {g.param_ref(act, 'spring_k')}"
                      f" * ({g.param_ref(act, 'x0')} - {g.param_ref(act, 'arm')} * th)) / "
                      f"{g.param_ref(act, 'area')}")
        elif p.spring_feedforward != 0.0:
            raise CircuitError(f"controller.params.spring_feedforward = "
                               f"{p.spring_feedforward!r}: actuator {act.name!r} ({act.kind}) "
                               "has no return spring (allowed: 0, or a "
                               "spring_return_cylinder actuator)")
        pa = g.p(act, "a")
        pb = g.p(act, "b") if "b" in act.ports else "0.0"
        w = g.speed(pump, "shaft")
        for line in (f"dp_meas = {pa} - {pb}",
                     f"W[W_TAU_MEAS] = -{ktp} * dp_meas",
                     f"dp_des = -cmd / {ktp} + {spring}",
                     "err = dp_des - dp_meas",
                     f"integ = min(max({integ} + err * h, -{lim}), {lim})",
                     f"{integ} = integ",
                     f"w_des = -{ktp} * thd / {d} + {kp} * err + {ki} * integ",
                     f"return {R} * {d} * dp_des / {K} + {K} * w_des + {kw} * (w_des - {w})"):
            g.ctrl_line(line)
