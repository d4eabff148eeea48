"""Fast 2/2 on/off (switching) valve for pulse-width-modulated digital hydraulics.

A high-frequency switching valve meters flow by time instead of by throttling: it is either
closed or fully open, and a PWM command with duty cycle ``D`` at frequency ``f`` delivers on
average ``D`` times the open flow (seed ch. 5, the digital switching valve; Linjama,
"Digital fluid power – state of the art", SICFP 2011). Losses are the throttling while the
valve travels between its ends (worst at half open at full pressure drop), the pressure drop of
the open valve, and the actuator's electrical power (holding current plus energy per switch).

Position ``x ∈ [0, 1]`` (0 closed, 1 fully open), rate-limited travel (our model: the coil
force saturates, so the armature travels at about constant speed; close to the end it settles
exponentially so the rate is continuous in ``x``):

    dx/dt = clip((x_cmd − x) / τ_s, −1/T_sw, 1/T_sw),   x_cmd = clip(u, 0, 1)

with ``T_sw`` the switching time (full stroke at the limited rate) and ``τ_s ≪ T_sw`` the
end-approach time constant. A full opening starting at rest takes ``T_sw − τ_s`` at constant
rate, then an exponential tail of time constant ``τ_s``; the flow it misses relative to an ideal
instant valve (at constant Δp, ``Q ∝ x``) is ``Q_open · (T_sw/2 + τ_s²/(2 T_sw))``; a full closing
passes the same extra volume, so while both transitions complete within each PWM phase the
period-average flow is ``D · Q_open`` (the closing lag returns what the opening lag missed);
what the transitions cost is throttling heat, not mean flow.

Flow from ``in`` to ``out``: ``A = A_leak + (A_max − A_leak) clip(x, 0, 1)`` through the
regularised orifice law (:func:`~afo_mj.hydraulics.orifice.orifice_flow_m3_s`); all of ``Δp Q`` is
heat.

Actuator (electrical) power: ``P_el = P_hold · clip(u, 0, 1) + E_sw · n_sw`` with ``n_sw`` the
switching events per second (a PWM at ``f`` switches ``2 f`` times per second).

Example: default valve (2 mm², ``T_sw`` = 2 ms, 0.05 J per switch, 2 W holding) at 50 Hz and
``D = 0.4``: mean actuator power ``2·0.4 + 0.05·100 = 5.8 W``; at Δp = 10 MPa it delivers on
average about ``0.4 · 1.84e-4 = 7.4e-5 m³/s`` (4.4 L/min) of VG 46.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from . import laws
from .orifice import (DEFAULT_DISCHARGE_COEFFICIENT, DEFAULT_TRANSITION_PRESSURE_PA,
                      orifice_flow_m3_s, throttle_power)
from .params import Parameters, effect, param
from .power import PowerFlow

__all__ = ["OnOffValveParams", "OnOffValve", "pwm_command"]


def pwm_command(t_s, duty_cycle, frequency_hz):
    """PWM on/off command: 1.0 during the first ``D`` fraction of each period, else 0.0.

    ``u(t) = 1 if frac(t f) < D else 0`` (vectorised over ``t_s``, ``duty_cycle``).

    Example: ``pwm_command([0.0, 0.004, 0.006, 0.011], 0.5, 100.0)`` → ``[1., 1., 0., 1.]``
    (phases 0, 0.4, 0.6, 0.1).
    """
    phase = np.mod(np.asarray(t_s, dtype=float) * frequency_hz, 1.0)
    return (phase < np.asarray(duty_cycle, dtype=float)).astype(float)


@dataclasses.dataclass(frozen=True)
class OnOffValveParams(Parameters):
    """A fast-switching 2/2 on/off valve (normally closed)."""

    max_area_m2: float = param(2.0e-6, unit="m^2", lo=0.0, hi=1e-2, lo_open=True,
                               doc="flow area fully open")
    discharge_coefficient: float = param(DEFAULT_DISCHARGE_COEFFICIENT, unit="-", lo=0.0,
                                         hi=1.0, lo_open=True, doc="C_d")
    transition_pressure_pa: float = param(DEFAULT_TRANSITION_PRESSURE_PA, unit="Pa", lo=0.0,
                                          hi=1e6, lo_open=True,
                                          doc="p_cr of the regularised orifice law")
    switching_time_s: float = param(2.0e-3, unit="s", lo=0.0, hi=1.0, lo_open=True,
                                    doc="T_sw: closed to fully open at the limited rate")
    approach_time_constant_s: float = param(0.1e-3, unit="s", lo=0.0, hi=1.0, lo_open=True,
                                            doc="τ_s: exponential settling near the end "
                                                "(must be < switching_time_s)")
    leakage_area_m2: float = param(1.0e-11, unit="m^2", lo=0.0, hi=1e-2,
                                   doc="leakage area when closed (must be < max_area_m2)")
    switching_energy_j: float = param(0.05, unit="J", lo=0.0, hi=100.0,
                                      doc="actuator electrical energy per switching event")
    holding_power_w: float = param(2.0, unit="W", lo=0.0, hi=1e3,
                                   doc="coil power while commanded on")
    leakage_enabled: bool = effect(True, doc="leakage through leakage_area_m2 when closed")

    def check(self) -> None:
        if self.leakage_area_m2 >= self.max_area_m2:
            self.fail("leakage_area_m2", f"must be below max_area_m2 = {self.max_area_m2}")
        if self.approach_time_constant_s >= self.switching_time_s:
            self.fail("approach_time_constant_s",
                      f"must be below switching_time_s = {self.switching_time_s}")


class OnOffValve:
    """Position dynamics, flow, hydraulic and actuator power of one :class:`OnOffValveParams`."""

    def __init__(self, params: OnOffValveParams = OnOffValveParams()):
        self.params = params
        self._leak_area = params.leakage_area_m2 if params.leakage_enabled else 0.0

    def position_rate(self, x, command_on):
        """``dx/dt = clip((clip(u, 0, 1) − x)/τ_s, −1/T_sw, 1/T_sw)`` (1/s): the law
        :func:`~afo_mj.hydraulics.laws.onoff_valve_rate_1_s` with sharp corners."""
        p = self.params
        return laws.onoff_valve_rate_1_s(np.asarray(x, dtype=float),
                                         np.asarray(command_on, dtype=float),
                                         p.approach_time_constant_s, p.switching_time_s, 0.0)

    def area_m2(self, x):
        """Flow area ``A_leak + (A_max − A_leak) clip(x, 0, 1)``
        (:func:`~afo_mj.hydraulics.laws.valve_opening_area_m2`)."""
        return laws.valve_opening_area_m2(np.asarray(x, dtype=float), self.params.max_area_m2,
                                          self._leak_area)

    def flow_m3_s(self, x, p_in_pa, p_out_pa, density_kg_m3):
        """Flow from ``in`` to ``out`` at valve position ``x``."""
        p = self.params
        dp = np.asarray(p_in_pa, dtype=float) - p_out_pa
        return orifice_flow_m3_s(dp, self.area_m2(x), p.discharge_coefficient, density_kg_m3,
                                 p.transition_pressure_pa)

    def power(self, x, p_in_pa, p_out_pa, density_kg_m3) -> PowerFlow:
        """Hydraulic throttling power (:func:`~afo_mj.hydraulics.orifice.throttle_power`)."""
        return throttle_power(p_in_pa, p_out_pa,
                              self.flow_m3_s(x, p_in_pa, p_out_pa, density_kg_m3))

    def actuator_power_w(self, command_on, switching_rate_hz):
        """Electrical power of the actuator: ``P_hold clip(u, 0, 1) + E_sw n_sw`` (W), with
        ``switching_rate_hz`` the switching events per second (2 f for a PWM at f)."""
        p = self.params
        return (p.holding_power_w * np.clip(np.asarray(command_on, dtype=float), 0.0, 1.0)
                + p.switching_energy_j * np.asarray(switching_rate_hz, dtype=float))

    def pwm_actuator_power_w(self, duty_cycle, frequency_hz):
        """Period-average actuator power of a PWM: ``P_hold D + 2 f E_sw`` (W); a duty of 0 or
        1 does not switch."""
        d = np.clip(np.asarray(duty_cycle, dtype=float), 0.0, 1.0)
        switching = np.where((d > 0.0) & (d < 1.0), 2.0 * np.asarray(frequency_hz, dtype=float),
                             0.0)
        return self.actuator_power_w(d, switching)

    def transition_heat_j(self, dp_pa, density_kg_m3):
        """Throttling heat of one complete linear-ramp transition at constant ``Δp`` (J),
        neglecting leakage, ``τ_s`` and the regularisation: the area ramps linearly over
        ``T_sw`` so the heat is half that of the open valve over the same time,
        ``½ Δp Q_open T_sw`` (our arithmetic)."""
        p = self.params
        dp = np.asarray(dp_pa, dtype=float)
        q_open = orifice_flow_m3_s(dp, p.max_area_m2, p.discharge_coefficient, density_kg_m3,
                                   p.transition_pressure_pa)
        return 0.5 * dp * q_open * p.switching_time_s
