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

from .params import Parameters, effect, param


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
