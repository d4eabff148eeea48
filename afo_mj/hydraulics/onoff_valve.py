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

from .orifice import (DEFAULT_DISCHARGE_COEFFICIENT, DEFAULT_TRANSITION_PRESSURE_PA)
from .params import Parameters, effect, param

__all__ = ["OnOffValveParams", "pwm_command"]


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
