"""Brushless DC motor with its driver (PWM inverter with current limit).

Motor (standard DC-equivalent model of a trapezoidal BLDC motor, e.g. Krishnan, *Permanent
Magnet Synchronous and Brushless DC Motor Drives*, 2010, ch. 9; maxon catalogue conventions):

    L di/dt = v − R i − K ω
    J dω/dt = K i − T_f(ω) − T_load,    T_f = T_c tanh(ω/ω_c) + b ω

with one constant ``K`` for torque (N m/A) and back-EMF (V s/rad), equal in SI for an ideal
machine, which makes the electromechanical conversion lossless: ``v i = R i² + L i di/dt
+ (T_f + J dω/dt + T_load) ω``.

Driver: a PWM inverter fed from the bus. It applies the commanded voltage, clipped to
``± max_duty · V_bus``, and limits the winding current by clipping the voltage to the band that
gives at most ``± I_max`` at steady state, ``K ω ± R I_max`` (a voltage-clamp current limiter);
both clamps have 0.05 V rounded corners (the law :func:`~afo_mj.hydraulics.laws.
driver_voltage_v`, exact to ``r²/(4|v − v_limit|)`` away from them).
Its losses are conduction ``R_on i²`` and a quiescent power, so the bus supplies
``P_bus = v i + R_on i² + P_q`` (negative when regenerating).
"""

from __future__ import annotations

import dataclasses

import numpy as np

from . import laws
from .params import Parameters, effect, param
from .power import PowerFlow


@dataclasses.dataclass(frozen=True)
class MotorParams(Parameters):
    """A brushless DC motor (phase-to-phase values)."""

    resistance_ohm: float = param(0.4, unit="ohm", lo=0.0, hi=100.0, lo_open=True)
    inductance_h: float = param(0.1e-3, unit="H", lo=1e-7, hi=1.0)
    torque_constant_nm_a: float = param(0.025, unit="N m/A", lo=0.0, hi=10.0, lo_open=True,
                                        doc="K: torque per ampere = back-EMF per rad/s")
    rotor_inertia_kg_m2: float = param(1.2e-5, unit="kg m^2", lo=0.0, hi=10.0, lo_open=True)
    coulomb_torque_nm: float = param(0.005, unit="N m", lo=0.0, hi=10.0)
    viscous_coefficient_nm_s_rad: float = param(1e-6, unit="N m s/rad", lo=0.0, hi=1.0)
    smoothing_speed_rad_s: float = param(1.0, unit="rad/s", lo=1e-6, hi=1e3)
    max_speed_rad_s: float = param(1700.0, unit="rad/s", lo=0.0, hi=1e5, lo_open=True)
    mass_kg: float = param(0.25, unit="kg", lo=0.0, hi=100.0)
    friction_enabled: bool = effect(True, doc="bearing/brush-free Coulomb + viscous friction")


@dataclasses.dataclass(frozen=True)
class DriverParams(Parameters):
    """PWM motor driver."""

    current_limit_a: float = param(15.0, unit="A", lo=0.0, hi=1000.0, lo_open=True)
    max_duty: float = param(0.95, unit="-", lo=0.0, hi=1.0, lo_open=True)
    on_resistance_ohm: float = param(0.02, unit="ohm", lo=0.0, hi=10.0,
                                     doc="conduction resistance of the bridge")
    quiescent_power_w: float = param(0.3, unit="W", lo=0.0, hi=100.0)
    current_limit_enabled: bool = effect(True, doc="voltage clamp at the current limit")


class BrushlessMotor:
    """Electrical and mechanical equations of a :class:`MotorParams` motor and its driver."""

    def __init__(self, motor: MotorParams, driver: DriverParams = DriverParams()):
        self.params = motor
        self.driver = driver

    def applied_voltage_v(self, command_v, speed_rad_s, bus_voltage_v):
        """Voltage the driver applies: command clipped to the current-limit band
        ``K ω ± R I_max`` and the duty range ``± d V_bus``, both with 0.05 V rounded corners
        (:func:`~afo_mj.hydraulics.laws.driver_voltage_v`)."""
        d, m = self.driver, self.params
        return laws.driver_voltage_v(np.asarray(command_v, dtype=float),
                                     m.torque_constant_nm_a * np.asarray(speed_rad_s, dtype=float),
                                     m.resistance_ohm, d.current_limit_a,
                                     float(d.current_limit_enabled), d.max_duty,
                                     np.asarray(bus_voltage_v, dtype=float))

    def friction_torque_nm(self, speed_rad_s):
        """``T_f = T_c tanh(ω/ω_c) + b ω`` (:func:`~afo_mj.hydraulics.laws.
        motor_friction_torque_nm`), 0 with friction disabled."""
        m = self.params
        w = np.asarray(speed_rad_s, dtype=float)
        if not m.friction_enabled:
            return np.zeros_like(w)
        return laws.motor_friction_torque_nm(w, m.coulomb_torque_nm,
                                             m.viscous_coefficient_nm_s_rad,
                                             m.smoothing_speed_rad_s)

    def current_rate_a_s(self, voltage_v, current_a, speed_rad_s):
        """``di/dt = (v − R i − K ω) / L``."""
        m = self.params
        return (voltage_v - m.resistance_ohm * current_a
                - m.torque_constant_nm_a * speed_rad_s) / m.inductance_h

    def electromagnetic_torque_nm(self, current_a):
        return self.params.torque_constant_nm_a * np.asarray(current_a, dtype=float)

    def bus_power_w(self, voltage_v, current_a):
        """Power drawn from the bus: ``v i + R_on i² + P_q``."""
        i = np.asarray(current_a, dtype=float)
        return voltage_v * i + self.driver.on_resistance_ohm * i * i + self.driver.quiescent_power_w

    def power(self, voltage_v, current_a, speed_rad_s, current_rate_a_s) -> PowerFlow:
        """Motor alone: ``in = v i``; ``out = (K i − T_f) ω`` (to the shaft, inertia torque
        included in ``out`` of the rotor balance); ``heat = R i² + T_f ω``;
        ``stored = L i di/dt``."""
        m = self.params
        i = np.asarray(current_a, dtype=float)
        w = np.asarray(speed_rad_s, dtype=float)
        tf = self.friction_torque_nm(w)
        return PowerFlow(voltage_v * i, (m.torque_constant_nm_a * i - tf) * w,
                         m.resistance_ohm * i * i + tf * w,
                         m.inductance_h * i * current_rate_a_s)

    def driver_power(self, voltage_v, current_a) -> PowerFlow:
        """Driver: ``in = P_bus``, ``out = v i``, ``heat = R_on i² + P_q``."""
        i = np.asarray(current_a, dtype=float)
        heat = self.driver.on_resistance_ohm * i * i + self.driver.quiescent_power_w
        return PowerFlow(voltage_v * i + heat, voltage_v * i, heat, 0.0)
