"""A second independent ankle bench rig, written from a different textbook than the first.

The first independent rig (``tests/independent_rig.py``) follows Merritt and Manring. This one
is written from Jelali & Kroll, *Hydraulic Servo-systems: Modelling, Identification and
Control* (Springer, 2003; below "J&K"), and Watton, *Fundamentals of Fluid Power Control*
(Cambridge, 2009; below "Watton"), with the seal friction in the per-seal form of the
Parker O-ring handbook. Its modelling choices differ from the first rig's on purpose:

* each hose is two lumped laminar segments (volumes ¼, ½, ¼ of the line at its three nodes,
  the lumped-segment line of J&K's transmission-line chapter) instead of one;
* the liquid's tangent bulk modulus rises with pressure (``B_l = B_0 + m p``, Watton's
  fluid-properties chapter) and the entrained air compresses isothermally (Boyle);
* the piston (with its share of the cable) is a mass on a compliant cable in series with the
  oil, always (the clean rig's cable is a steel rope of finite stiffness, declared);
* every seal's friction grows with its own sealed pressure (piston seal: ``|p_a − p_b|``,
  each cable seal: its chamber against the atmosphere);
* the transmission may have a dead band (backlash, dead-zone model);
* the charge circuit has check valves with cracking pressure *and* seat leakage, and the
  pump has a case drain (external leakage), which the charge circuit makes up (both zero
  on the clean bench: zero-leak poppet seats, an internally drained pump; ``charge_loss``
  switches them on: afo_mj's circuit description has neither, and even 5e-16 m³/(s·Pa)
  of each bleeds the loop's common-mode pressure back to the charge pressure within ~10 s,
  a 0.3–0.7 MPa difference from the described model on a 6 s record);
* viscosity falls exponentially with temperature (Reynolds' law, Watton), not Walther;
* the motor command is a digital voltage updated at 200 Hz and held (zero-order) between
  updates, logged at 1 kHz;
* the sensors differ: chamber pressure transducers (not pump-port ones) with 12-bit ADC
  quantisation, a 14-bit absolute angle encoder, a current shunt with 12-bit ADC, a speed
  signal and a torque cell with their own noise levels.

It shares no code with afo_mj: it imports nothing from the package, writes the measured-data
v1 record (CSV + TOML sidecar, ``docs/measured_data.md``) itself, and integrates with scipy's
stiff solver (``solve_ivp(method="Radau")``), one solve per command hold interval.

Conventions (afo_mj's, ``docs/circuits.md``): angle, velocity and torque positive in
dorsiflexion; positive motor voltage turns the pump forward, from port B to port A; a higher
``p_a`` pushes the piston to larger ``x`` (chamber A grows), which pulls the cable and turns
the ankle in plantarflexion: ``x = −r θ`` for an unstretched cable. Pressures are gauge [Pa].

Switchable effects: :data:`EFFECTS` (all off unless named in ``effects={"name": value}``;
``True`` takes the default).
"""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path
from typing import Callable, Mapping

import numpy as np
from scipy.integrate import solve_ivp

#: atmospheric pressure [Pa] (absolute = gauge + this)
P_ATM = 101325.0
#: the record's sample rate [Hz]
SAMPLE_RATE_HZ = 1000.0
#: the controller's update period of the voltage command [s] (200 Hz, held in between)
COMMAND_UPDATE_S = 5.0e-3


# ----------------------------------------------------------------------------- parameters


@dataclasses.dataclass(frozen=True)
class Rig2Params:
    """Nominal ("datasheet") values of the second bench (SI units).

    Motor: a 24 V graphite-brush DC motor of the 40 mm class (R 0.299 Ω, L 0.082 mH,
    k 30.2 mN·m/A, rotor 142 g·cm²). Pump: a 0.3 cm³/rev reversible gear pump, volumetric
    efficiency 92 % at 10 MPa and 3000 rpm with ISO VG 46 at 40 °C (slip conductance
    ``C = 0.08 · D n / 10 MPa``). Lines: 0.6 m of 4 mm bore. Cylinder: 16 mm bore, 3 mm
    cable, 50 mm stroke, 1.5 cm³ dead volume each side, 80 g piston + cable share, on a 35 mm
    pulley; a 3 mm steel rope of 0.3 m free length (``k = E_eff A_metal / L``, 1.5 MN/m).
    Seals: piston seal 12 N, each cable seal 4 N, 50 N·s/m each. Charge: 0.8 MPa, check
    valves crack at 30 kPa. Bench load: 0.04 kg·m², 150 N·m/rad, 1.5 N·m·s/rad."""

    # motor
    resistance_ohm: float = 0.299
    inductance_h: float = 8.2e-5
    motor_k: float = 0.0302                 # N·m/A = V·s/rad
    rotor_inertia_kg_m2: float = 1.42e-5    # rotor + pump gears
    motor_coulomb_nm: float = 4.0e-3
    motor_viscous_nm_s: float = 1.5e-5
    motor_friction_speed_rad_s: float = 2.0
    # pump
    displacement_m3_rev: float = 0.3e-6
    slip_m3_s_pa: float = 0.08 * 0.3e-6 * 50.0 / 10.0e6     # 1.2e-13
    drain_m3_s_pa: float = 0.0              # case drain per port (internally drained pump)
    port_volume_m3: float = 1.0e-6
    # lines
    line_length_m: float = 0.6
    line_bore_m: float = 4.0e-3
    # oil: ISO VG 46 at 40 °C
    oil_density_kg_m3: float = 854.8         # at 40 °C (870 at 15 °C, 7e-4/K expansion)
    viscosity_40c_m2_s: float = 46.0e-6
    viscosity_100c_m2_s: float = 6.8e-6
    temperature_k: float = 313.15
    liquid_bulk_modulus_pa: float = 1.6e9
    bulk_modulus_slope: float = 5.8          # dB_l/dp (tangent modulus rises with pressure)
    air_fraction: float = 0.002              # free air volume / liquid volume at 1 atm
    # cylinder + cable + pulley
    bore_m: float = 16.0e-3
    cable_m: float = 3.0e-3
    stroke_m: float = 0.050
    dead_volume_m3: float = 1.5e-6
    piston_mass_kg: float = 0.08
    pulley_radius_m: float = 0.035
    cable_stiffness_n_m: float = 1.5e6
    cable_damping_ratio: float = 0.05
    # seals (per seal)
    piston_seal_n: float = 12.0
    cable_seal_n: float = 4.0
    seal_viscous_n_s_m: float = 50.0
    seal_smoothing_m_s: float = 5.0e-4
    # foot + bench load
    foot_inertia_kg_m2: float = 0.04
    load_stiffness_nm_rad: float = 150.0
    load_damping_nm_s_rad: float = 1.5
    # charge circuit
    charge_pressure_pa: float = 0.8e6
    check_cracking_pa: float = 3.0e4
    check_conductance_m3_s_pa: float = 5.0e-10
    check_corner_pa: float = 2.0e3
    check_seat_leak_m3_s_pa: float = 0.0    # zero-leak poppet seats
    # sensors
    encoder_bits: int = 14
    pressure_noise_pa: float = 1.5e4
    pressure_adc_full_scale_pa: float = 10.0e6
    current_noise_a: float = 0.04
    current_adc_full_scale_a: float = 40.0    # ±20 A
    adc_bits: int = 12
    speed_noise_rad_s: float = 0.8
    torque_noise_nm: float = 0.2

    def __post_init__(self):
        for f in dataclasses.fields(self):
            v = getattr(self, f.name)
            ok = v >= 0.0 if f.name in _MAY_BE_ZERO else v > 0.0
            if not (isinstance(v, (int, float)) and math.isfinite(v) and ok):
                raise ValueError(f"Rig2Params.{f.name} = {v!r}; allowed: a finite number "
                                 f"{'>= 0' if f.name in _MAY_BE_ZERO else '> 0'}")
        if self.cable_m >= self.bore_m:
            raise ValueError(f"Rig2Params.cable_m = {self.cable_m!r}; allowed: < bore_m")

    @property
    def area_m2(self) -> float:
        """Annular piston area of a piston-cable cylinder, ``A = π (D² − d²)/4``."""
        return math.pi / 4.0 * (self.bore_m ** 2 - self.cable_m ** 2)

    @property
    def displacement_m3_rad(self) -> float:
        return self.displacement_m3_rev / (2.0 * math.pi)

    @property
    def line_volume_m3(self) -> float:
        return math.pi / 4.0 * self.line_bore_m ** 2 * self.line_length_m

    @property
    def viscosity_pa_s(self) -> float:
        """Dynamic viscosity at the nominal temperature (40 °C), ``μ = ρ ν``."""
        return self.oil_density_kg_m3 * self.viscosity_40c_m2_s

    @property
    def encoder_lsb_rad(self) -> float:
        return 2.0 * math.pi / 2 ** self.encoder_bits


_MAY_BE_ZERO = {"drain_m3_s_pa", "slip_m3_s_pa", "check_seat_leak_m3_s_pa", "air_fraction",
                "bulk_modulus_slope",
                "motor_coulomb_nm", "motor_viscous_nm_s", "piston_seal_n", "cable_seal_n",
                "seal_viscous_n_s_m", "load_damping_nm_s_rad", "cable_damping_ratio",
                "check_cracking_pa", "load_stiffness_nm_rad", "inductance_h"}


@dataclasses.dataclass(frozen=True)
class Effect:
    """A switchable effect: its parameter, unit, default and what it does."""

    name: str
    parameter: str
    unit: str
    default: float
    description: str


#: The effects a test can switch on one at a time (all off by default).
EFFECTS: Mapping[str, Effect] = {e.name: e for e in (
    Effect("internal_leakage", "conductance_m3_s_pa", "m³/(s·Pa)", 3.0e-13,
           "laminar leakage across the piston at 40 °C, Q = G (p_a − p_b) μ_40/μ"),
    Effect("sensor_delay", "delay_s", "s", 2.0e-3,
           "every measured output read this late (acquisition latency)"),
    Effect("stribeck", "breakaway_ratio", "1", 3.0,
           "each seal's breakaway force = this × its Coulomb force, falling off "
           "exponentially over 3 mm/s (Tustin's form)"),
    Effect("entrained_air", "air_fraction", "1", 0.02,
           "free air volume / liquid volume at 1 atm (replaces the nominal 0.002)"),
    Effect("viscosity_drift", "temperature_rate_k_s", "K/s", 0.4,
           "the oil warms at this rate from 40 °C (μ = μ_40 exp(−λ (T − T_40)))"),
    Effect("current_limit", "limit_a", "A", 4.0,
           "the driver's chopper holds |i| near this (50 V/A on the excess current)"),
    Effect("softer_cable", "stiffness_n_m", "N/m", 3.0e5,
           "cable stiffness (replaces the nominal 1.5 MN/m: a synthetic rope)"),
    Effect("backlash", "play_rad", "rad", 0.02,
           "total play at the pulley (dead band of the cable transmission)"),
    Effect("seal_pressure_friction", "n_per_pa", "N/Pa", 3.0e-6,
           "each seal's friction grows by this times its sealed pressure"),
    Effect("charge_loss", "drain_m3_s_pa", "m³/(s·Pa)", 2.0e-13,
           "worn pump case drain (per port, to the case at 0 gauge) and leaking check-valve "
           "seats (a quarter of it), the loss made up by the charge circuit"),
    Effect("pressure_port_resonance", "natural_frequency_hz", "Hz", 120.0,
           "each chamber's transducer sits at the end of a drilled port: the oil in the "
           "passage rings on the transducer's dead volume (a Helmholtz resonator, damping "
           "ratio PORT_DAMPING_RATIO), so the transducer reads the chamber pressure through "
           "a second-order system (not an afo_mj library effect)"),
    Effect("brush_drop", "voltage_v", "V", 0.3,
           "the motor's brushes drop this voltage (both together) against the current, "
           "linear in the current up to BRUSH_LINEAR_CURRENT_A and about constant beyond "
           "(the contact drop of a brushed motor; not an afo_mj library effect)"),
)}

#: damping ratio of the pressure transducers' port resonance (laminar passage; Watton's
#: transducer-mounting discussion: lightly damped, 0.05–0.3)
PORT_DAMPING_RATIO = 0.12

#: current below which the brushes' contact drop is about linear (the contact film conducts
#: ohmically at low current density; beyond, the drop is about constant)
BRUSH_LINEAR_CURRENT_A = 0.1

STRIBECK_SPEED_M_S = 3.0e-3
CURRENT_LOOP_GAIN_V_A = 50.0


def resolve_effects(effects: Mapping[str, object] | None) -> dict[str, float]:
    """``{name: value}`` of the effects switched on (``True`` → the default, ``False`` or
    ``None`` → off). An unknown name or a value that is not a finite number > 0 raises
    ``ValueError`` naming it and what is allowed."""
    out = {}
    for name, v in (effects or {}).items():
        if name not in EFFECTS:
            raise ValueError(f"effect {name!r} unknown; allowed: {', '.join(EFFECTS)}")
        if v is None or v is False:
            continue
        val = EFFECTS[name].default if v is True else float(v)
        if not (math.isfinite(val) and val > 0.0):
            raise ValueError(f"effect {name} = {v!r}; allowed: a finite number > 0 "
                             f"({EFFECTS[name].unit}), True or False")
        out[name] = val
    return out


# ----------------------------------------------------------------------------- equations


def viscosity_lambda_per_k(p: Rig2Params) -> float:
    """Temperature coefficient ``λ`` of Reynolds' exponential viscosity law
    ``μ(T) = μ_0 exp(−λ (T − T_0))`` (Watton, fluid-properties chapter), fitted through the
    oil's two datasheet points (40 °C and 100 °C): ``λ = ln(ν_40/ν_100) / 60 K``."""
    return math.log(p.viscosity_40c_m2_s / p.viscosity_100c_m2_s) / 60.0


def effective_bulk_modulus(p_gauge: float, b0: float, slope: float, air: float) -> float:
    """Tangent bulk modulus of oil carrying free air [Pa].

    Liquid: ``B_l = B_0 + m p`` (the tangent modulus rises about linearly with pressure;
    Watton, fluid-properties chapter; m ≈ 5–6 for mineral oils). Air: isothermal (Boyle),
    ``V_g = α V_l p_0/p`` with ``p`` absolute. Liquid and gas compress in series:
    ``1/B_e = (V_l/B_l + V_g/p) / (V_l + V_g)`` (J&K, the oil–air mixture's compressibility),
    i.e. ``B_e = (1 + g) / (1/B_l + g/p)`` with ``g = α p_0/p``."""
    p_abs = max(p_gauge + P_ATM, 1.0e3)
    b_l = b0 + slope * max(p_gauge, 0.0)
    if air <= 0.0:
        return b_l
    g = air * P_ATM / p_abs
    return (1.0 + g) / (1.0 / b_l + g / p_abs)


def poiseuille_resistance(mu: float, length: float, bore: float) -> float:
    """Laminar (Hagen–Poiseuille) resistance of a circular line, ``R = 128 μ l / (π d⁴)``
    [Pa·s/m³] (Watton, the pipe-flow chapter)."""
    return 128.0 * mu * length / (math.pi * bore ** 4)


def smooth_sign(v: float, eps: float) -> float:
    """``v / √(v² + ε²)``: an algebraic smooth signum (friction regularised over ``ε``)."""
    return v / math.sqrt(v * v + eps * eps)


def soft_ramp(x: float, corner: float) -> float:
    """``max(x, 0)`` with a quadratic corner (C¹): 0 for ``x ≤ 0``, ``x²/(2c)`` up to ``c``,
    ``x − c/2`` beyond: a check valve's opening per unit conductance past its cracking
    pressure (closed exactly below it; its seat leakage is a separate term)."""
    if x <= 0.0:
        return 0.0
    if x < corner:
        return x * x / (2.0 * corner)
    return x - 0.5 * corner


def seal_force(v: float, sealed_pa: float, f0: float, prm: Rig2Params,
               fx: Mapping[str, float]) -> float:
    """Friction of one seal [N], opposing the sliding velocity ``v``.

    Per-seal form of the Parker O-ring handbook (ORD 5700, "Friction"): a compression part
    ``F_C`` plus a hydraulic part ``F_H = f_h p`` that grows with the pressure the seal holds
    against its other side (switched on by ``seal_pressure_friction``: ``f_h`` in N/Pa);
    a breakaway peak decaying exponentially with speed (Tustin's form, Armstrong-Hélouvry,
    Dupont & Canudas de Wit, Automatica 30 (1994), §2.1) when ``stribeck`` is on; viscous
    ``b v``. ``F = [(F_C + f_h p_s) (1 + (k_s − 1) e^{−|v|/v_s})] sgn_ε(v) + b v``."""
    fc = f0
    if "seal_pressure_friction" in fx:
        fc += fx["seal_pressure_friction"] * max(sealed_pa, 0.0)
    if "stribeck" in fx:
        fc *= 1.0 + (fx["stribeck"] - 1.0) * math.exp(-abs(v) / STRIBECK_SPEED_M_S)
    return fc * smooth_sign(v, prm.seal_smoothing_m_s) + prm.seal_viscous_n_s_m * v


def brush_drop(i: float, drop_v: float) -> float:
    """Voltage lost across the brush–commutator contacts of a brushed DC motor [V], both
    brushes together, against the armature current ``i``.

    The classical DC-machine model takes the brush drop as a constant voltage opposing the
    current, independent of its size (Chapman, *Electric Machinery Fundamentals*, the DC
    motor chapter: about 2 V for the carbon brushes of industrial machines; copper-graphite
    brushes of a low-voltage motor drop a few tenths of a volt). At low current the contact
    film conducts about ohmically, so the drop rises linearly up to a current and is constant
    beyond (the brush model of the Modelica Standard Library,
    ``Modelica.Electrical.Machines.Losses.DCMachines.Brush``); written here with the
    algebraic smooth sign, ``V_b i/√(i² + I_lin²)``, ``I_lin`` =
    :data:`BRUSH_LINEAR_CURRENT_A`. The armature equation becomes
    ``L di/dt = V − R i − V_b(i) − k ω``."""
    return drop_v * smooth_sign(i, BRUSH_LINEAR_CURRENT_A)


def dead_zone(d: float, half_play: float, eps: float) -> tuple[float, float]:
    """Dead-zone model of a compliant transmission with play (Nordin & Gutman, "Controlling
    mechanical systems with backlash — a survey", Automatica 38 (2002), eq. 2): the spring
    acts on ``d − β sgn(d)`` outside ``|d| ≤ β`` and carries nothing inside. Smoothed over
    ``eps`` (hyperbolic corners); returns the stretch and its slope (0 … 1)."""
    if half_play <= 0.0:
        return d, 1.0
    a, b = d - half_play, -d - half_play
    sa, sb = math.sqrt(a * a + eps * eps), math.sqrt(b * b + eps * eps)
    return 0.5 * (a + sa) - 0.5 * (b + sb), 0.5 * (1.0 + a / sa) + 0.5 * (1.0 + b / sb)


# ----------------------------------------------------------------------------- the rig


STATES = ("i", "omega_m", "phi_m", "p_1a", "p_ma", "p_a", "p_1b", "p_mb", "p_b",
          "x_p", "v_p", "theta", "omega_f")


class Rig2:
    """The bench's ODE for one parameter set, effect set and voltage command.

    ``chambers_shut``: valves between the lines and the cylinder ports are closed (the
    chambers hold their oil; for the resonance check). ``motor_locked``: the motor shaft is
    held (ω = 0)."""

    def __init__(self, params: Rig2Params | None = None, effects=None,
                 voltage: Callable[[float], float] | None = None, *,
                 chambers_shut: bool = False, motor_locked: bool = False):
        self.p = p = params or Rig2Params()
        self.fx = fx = resolve_effects(effects)
        self.voltage = voltage or (lambda t: 0.0)
        self.chambers_shut = chambers_shut
        self.motor_locked = motor_locked
        self._held_v: float | None = None
        self.ix = {n: k for k, n in enumerate(STATES)}
        self.A = p.area_m2
        self.D = p.displacement_m3_rad
        self.lam = viscosity_lambda_per_k(p)
        self.air = fx.get("entrained_air", p.air_fraction)
        self.k_c = fx.get("softer_cable", p.cable_stiffness_n_m)
        self.c_c = 2.0 * p.cable_damping_ratio * math.sqrt(self.k_c * p.piston_mass_kg)
        self.half_play_m = 0.5 * fx.get("backlash", 0.0) * p.pulley_radius_m
        self.G_pist40 = fx.get("internal_leakage", 0.0)
        self.drain = p.drain_m3_s_pa + fx.get("charge_loss", 0.0)
        self.seat = p.check_seat_leak_m3_s_pa + 0.25 * fx.get("charge_loss", 0.0)
        vl = p.line_volume_m3
        self.V_1 = p.port_volume_m3 + vl / 4.0
        self.V_m = vl / 2.0
        self.V_ch0 = p.dead_volume_m3 + vl / 4.0

    # ------------------------------------------------------------------ helpers
    def temperature_k(self, t: float) -> float:
        return self.p.temperature_k + self.fx.get("viscosity_drift", 0.0) * t

    def viscosity_ratio(self, t: float) -> float:
        """``μ(T)/μ_40`` (Reynolds' exponential law)."""
        return math.exp(-self.lam * (self.temperature_k(t) - self.p.temperature_k))

    def capacitance(self, p_gauge: float, volume: float) -> float:
        """Hydraulic capacitance ``V / B_e(p)`` [m³/Pa] of a node (the pressure build-up
        equation ``(V/B_e) dp/dt = Σ Q − dV/dt``, J&K's and Watton's continuity equation)."""
        p = self.p
        return volume / effective_bulk_modulus(p_gauge, p.liquid_bulk_modulus_pa,
                                               p.bulk_modulus_slope, self.air)

    def initial_state(self, **override) -> np.ndarray:
        """At rest, every line at the charge pressure less the check valves' cracking."""
        y = np.zeros(len(STATES))
        p0 = self.p.charge_pressure_pa - self.p.check_cracking_pa
        for n in ("p_1a", "p_ma", "p_a", "p_1b", "p_mb", "p_b"):
            y[self.ix[n]] = p0
        for k, v in override.items():
            y[self.ix[k]] = v
        return y

    def atol(self) -> np.ndarray:
        scale = {"i": 1e-6, "omega_m": 1e-5, "phi_m": 1e-7, "x_p": 1e-10, "v_p": 1e-8,
                 "theta": 1e-9, "omega_f": 1e-8}
        return np.array([scale.get(n, 1e-1) for n in STATES])

    # ------------------------------------------------------------------ algebraic part
    def algebraic(self, t: float, y: np.ndarray) -> dict:
        """Every flow, force and torque at (t, y)."""
        p, fx = self.p, self.fx
        i, w = y[0], y[1]
        p1a, pma, pa, p1b, pmb, pb = y[3], y[4], y[5], y[6], y[7], y[8]
        x, vp, th, wf = y[9], y[10], y[11], y[12]
        v_cmd = self.voltage(t) if self._held_v is None else self._held_v
        # driver: the command, less a chopper's correction on the current beyond its limit
        v_mot = v_cmd
        lim = fx.get("current_limit")
        if lim is not None and abs(i) > lim:
            v_mot = v_cmd - CURRENT_LOOP_GAIN_V_A * (abs(i) - lim) * math.copysign(1.0, i)
        # the brushes' contact drop, inside the motor (off: none, the clean bench's motor is
        # taken at its datasheet terminal resistance)
        v_brush = brush_drop(i, fx["brush_drop"]) if "brush_drop" in fx else 0.0
        mu_r = self.viscosity_ratio(t)
        # motor friction (Coulomb, regularised, + viscous)
        t_fric = p.motor_coulomb_nm * smooth_sign(w, p.motor_friction_speed_rad_s) \
            + p.motor_viscous_nm_s * w
        # pump (J&K's and Watton's ideal pump with laminar slip): Q = D ω − C_s Δp, T = D Δp;
        # slip and drain conductances scale as 1/μ
        dp_pump = p1a - p1b
        q_slip = p.slip_m3_s_pa / mu_r * dp_pump
        q_drain_a = self.drain / mu_r * p1a
        q_drain_b = self.drain / mu_r * p1b
        # charge check valves: open past the cracking pressure, seat leakage both ways
        pc = p.charge_pressure_pa
        q_ca = (p.check_conductance_m3_s_pa * soft_ramp(pc - p1a - p.check_cracking_pa,
                                                        p.check_corner_pa)
                + self.seat * (pc - p1a))
        q_cb = (p.check_conductance_m3_s_pa * soft_ramp(pc - p1b - p.check_cracking_pa,
                                                        p.check_corner_pa)
                + self.seat * (pc - p1b))
        # lines: two laminar segments each (R/2 apiece)
        r_half = 0.5 * poiseuille_resistance(p.viscosity_pa_s * mu_r, p.line_length_m,
                                             p.line_bore_m)
        q1a, q1b = (p1a - pma) / r_half, (p1b - pmb) / r_half
        if self.chambers_shut:
            q2a = q2b = 0.0
        else:
            q2a, q2b = (pma - pa) / r_half, (pmb - pb) / r_half
        # piston: internal leakage across it, per-seal friction
        q_pist = self.G_pist40 / mu_r * (pa - pb)
        f_seal = (seal_force(vp, abs(pa - pb), p.piston_seal_n, p, fx)
                  + seal_force(vp, pa, p.cable_seal_n, p, fx)
                  + seal_force(vp, pb, p.cable_seal_n, p, fx))
        # cable between piston and pulley, with play: stretch δ = x + r θ
        r = p.pulley_radius_m
        d, dd = x + r * th, vp + r * wf
        st, slope = dead_zone(d, self.half_play_m, 2.0e-5)
        f_cable = self.k_c * st + self.c_c * slope * dd
        tau = -r * f_cable
        return dict(v_cmd=v_cmd, v_mot=v_mot, v_brush=v_brush, i=i, w=w, t_fric=t_fric,
                    dp_pump=dp_pump, q_slip=q_slip, q_drain_a=q_drain_a, q_drain_b=q_drain_b,
                    q_ca=q_ca, q_cb=q_cb, q1a=q1a, q1b=q1b, q2a=q2a, q2b=q2b, q_pist=q_pist,
                    f_seal=f_seal, f_cable=f_cable, tau=tau, x=x, vp=vp, theta=th, wf=wf,
                    p1a=p1a, pma=pma, pa=pa, p1b=p1b, pmb=pmb, pb=pb)

    # ------------------------------------------------------------------ derivatives
    def rhs(self, t: float, y: np.ndarray) -> np.ndarray:
        """``dy/dt``. Motor (J&K's and Watton's DC-motor drive): ``L di/dt = V − R i − V_b(i)
        − k ω`` (``V_b``: :func:`brush_drop`, 0 unless ``brush_drop`` is on),
        ``J ω̇ = k i − T_f − D Δp``. Continuity at each of the six line nodes. Piston:
        ``m ẍ = A (p_a − p_b) − F_seal − F_cable``. Foot: ``J θ̈ = τ − k_L θ − c_L θ̇``."""
        p, a = self.p, self.algebraic(t, y)
        dy = np.zeros_like(y)
        A, s, D = self.A, p.stroke_m, self.D
        if p.inductance_h > 0:
            dy[0] = (a["v_mot"] - p.resistance_ohm * a["i"] - a["v_brush"]
                     - p.motor_k * a["w"]) / p.inductance_h
        if not self.motor_locked:
            dy[1] = (p.motor_k * a["i"] - a["t_fric"] - D * a["dp_pump"]) / p.rotor_inertia_kg_m2
            dy[2] = a["w"]
        qp = D * a["w"]
        dy[3] = (qp - a["q_slip"] - a["q_drain_a"] + a["q_ca"] - a["q1a"]) / \
            self.capacitance(a["p1a"], self.V_1)
        dy[6] = (-qp + a["q_slip"] - a["q_drain_b"] + a["q_cb"] - a["q1b"]) / \
            self.capacitance(a["p1b"], self.V_1)
        dy[4] = (a["q1a"] - a["q2a"]) / self.capacitance(a["pma"], self.V_m)
        dy[7] = (a["q1b"] - a["q2b"]) / self.capacitance(a["pmb"], self.V_m)
        va = self.V_ch0 + A * (s / 2.0 + a["x"])
        vb = self.V_ch0 + A * (s / 2.0 - a["x"])
        dy[5] = (a["q2a"] - a["q_pist"] - A * a["vp"]) / self.capacitance(a["pa"], va)
        dy[8] = (a["q2b"] + a["q_pist"] + A * a["vp"]) / self.capacitance(a["pb"], vb)
        dy[9] = a["vp"]
        dy[10] = (A * (a["pa"] - a["pb"]) - a["f_seal"] - a["f_cable"]) / p.piston_mass_kg
        dy[11] = a["wf"]
        dy[12] = (a["tau"] - p.load_stiffness_nm_rad * a["theta"]
                  - p.load_damping_nm_s_rad * a["wf"]) / p.foot_inertia_kg_m2
        return dy

    # ------------------------------------------------------------------ integration
    def simulate(self, duration_s: float, *, hold_period_s: float | None = COMMAND_UPDATE_S,
                 y0=None, rtol: float = 1e-6, sample_rate_hz: float = SAMPLE_RATE_HZ,
                 method: str = "Radau"):
        """Integrate over ``[0, duration_s]``; returns ``(t, Y)`` at ``sample_rate_hz``.

        ``hold_period_s``: the command is updated at ``k · hold_period_s`` and held until the
        next update (zero-order hold, Franklin, Powell & Workman, *Digital Control of Dynamic
        Systems*, §4.3); each hold interval is its own solve (the right-hand side is smooth
        inside it). ``None``: the voltage is read continuously (one solve)."""
        if not (duration_s > 0 and math.isfinite(duration_s)):
            raise ValueError(f"duration_s = {duration_s!r}; allowed: a finite number > 0")
        if hold_period_s is not None and not hold_period_s > 0:
            raise ValueError(f"hold_period_s = {hold_period_s!r}; allowed: > 0 or None")
        y = self.initial_state() if y0 is None else np.asarray(y0, dtype=float).copy()
        n = int(round(duration_s * sample_rate_hz)) + 1
        t = np.arange(n) / sample_rate_hz
        Y = np.empty((len(y), n))
        Y[:, 0] = y
        atol = self.atol()
        if hold_period_s is None:
            sol = solve_ivp(self.rhs, (0.0, t[-1]), y, method=method, t_eval=t, rtol=rtol,
                            atol=atol, max_step=2e-3)
            if not sol.success:
                raise RuntimeError(f"second rig: solver failed: {sol.message}")
            return sol.t, sol.y
        n_seg = int(math.ceil(t[-1] / hold_period_s - 1e-9))
        try:
            for k in range(n_seg):
                t0, t1 = k * hold_period_s, min((k + 1) * hold_period_s, t[-1])
                self._held_v = float(self.voltage(t0))
                inside = np.flatnonzero((t > t0 + 1e-12) & (t <= t1 + 1e-12))
                sol = solve_ivp(self.rhs, (t0, t1), y, method=method, rtol=rtol, atol=atol,
                                max_step=hold_period_s, dense_output=inside.size > 0)
                if not sol.success:
                    raise RuntimeError(f"second rig: solver failed at t = {t0:g} s: "
                                       f"{sol.message}")
                y = sol.y[:, -1]
                if inside.size:
                    Y[:, inside] = sol.sol(np.minimum(t[inside], t1))
        finally:
            self._held_v = None
        if not np.all(np.isfinite(Y)):
            raise RuntimeError("second rig: the solution holds NaN or inf")
        return t, Y


# ----------------------------------------------------------------------------- command


def voltage_command(duration_s: float = 20.0, amplitude_v: float = 4.0,
                    update_s: float = COMMAND_UPDATE_S, seed: int = 2024
                    ) -> Callable[[float], float]:
    """The controller's voltage command, computed at each update ``k · update_s`` and held.

    First 40 %: steps to pseudo-random levels in ``[−A, A]`` (a fixed sequence, ``seed``),
    0.4 s each, the first after 0.1 s at rest. Then a multisine of 12 components from 0.4 to
    10 Hz with Schroeder phases (Pintelon & Schoukens, *System Identification: A Frequency
    Domain Approach*, 2nd ed. 2012, §4.2: low crest factor), scaled to a peak of A."""
    if not update_s > 0:
        raise ValueError(f"update_s = {update_s!r}; allowed: > 0")
    rng = np.random.default_rng(seed)
    t_steps = 0.4 * duration_s
    n_lv = int(math.ceil(t_steps / 0.4)) + 1
    levels = amplitude_v * rng.uniform(-1.0, 1.0, n_lv)
    levels[-1] = 0.0
    f = np.geomspace(0.4, 10.0, 12)
    k = np.arange(1, len(f) + 1)
    ph = -np.pi * k * (k - 1) / len(f)
    tt = np.arange(0.0, 2.0 / f[0], 1e-3)
    peak = np.max(np.abs(np.sin(2 * np.pi * f[:, None] * tt[None, :] + ph[:, None]).sum(0)))
    gain = amplitude_v / peak

    def raw(t: float) -> float:
        if t < 0.1:
            return 0.0
        if t < t_steps:
            return float(levels[min(int((t - 0.1) // 0.4), n_lv - 1)])
        tc = t - t_steps
        env = min(tc / 0.2, 1.0)
        return float(env * gain * np.sum(np.sin(2 * np.pi * f * tc + ph)))

    def u(t: float) -> float:
        return raw(math.floor(t / update_s + 1e-9) * update_s)

    return u


# ----------------------------------------------------------------------------- sensors


#: recorded channels (afo_mj measured-data v1 names) and their units
CHANNEL_UNITS = {"motor_voltage_v": "V", "ankle_angle_rad": "rad", "ankle_torque_nm": "N·m",
                 "chamber_a_pa": "Pa", "chamber_b_pa": "Pa", "motor_current_a": "A",
                 "motor_speed_rad_s": "rad/s"}
OUTPUTS = tuple(k for k in CHANNEL_UNITS if k != "motor_voltage_v")


def true_channels(rig: Rig2, t: np.ndarray, Y: np.ndarray) -> dict[str, np.ndarray]:
    """Noise-free, undelayed sensor quantities at the samples. The torque cell sits between
    pulley and foot: it reads the cable's torque on the pulley."""
    ix = rig.ix
    out = {"ankle_angle_rad": Y[ix["theta"]].copy(), "chamber_a_pa": Y[ix["p_a"]].copy(),
           "chamber_b_pa": Y[ix["p_b"]].copy(), "motor_current_a": Y[ix["i"]].copy(),
           "motor_speed_rad_s": Y[ix["omega_m"]].copy()}
    out["ankle_torque_nm"] = np.array([rig.algebraic(float(tj), Y[:, j])["tau"]
                                       for j, tj in enumerate(t)])
    v = rig.voltage
    out["motor_voltage_v"] = np.array([v(float(tj)) for tj in t])
    return out


def quantum(params: Rig2Params) -> dict[str, float]:
    """Converter step of each quantised channel: the 14-bit absolute encoder, the 12-bit
    ADCs of the pressure transducers (0 … full scale) and the current shunt (±half)."""
    return {"ankle_angle_rad": params.encoder_lsb_rad,
            "chamber_a_pa": params.pressure_adc_full_scale_pa / 2 ** params.adc_bits,
            "chamber_b_pa": params.pressure_adc_full_scale_pa / 2 ** params.adc_bits,
            "motor_current_a": params.current_adc_full_scale_a / 2 ** params.adc_bits}


def noise_sigmas(params: Rig2Params) -> dict[str, float]:
    """Each output's noise σ: the sensor's white noise and its quantisation (``q/√12``,
    Widrow & Kollár, *Quantization Noise*, 2008, ch. 4) added in quadrature."""
    white = {"ankle_angle_rad": 0.0, "ankle_torque_nm": params.torque_noise_nm,
             "chamber_a_pa": params.pressure_noise_pa, "chamber_b_pa": params.pressure_noise_pa,
             "motor_current_a": params.current_noise_a,
             "motor_speed_rad_s": params.speed_noise_rad_s}
    q = quantum(params)
    return {ch: math.sqrt(s ** 2 + q.get(ch, 0.0) ** 2 / 12.0) for ch, s in white.items()}


def port_reading(t: np.ndarray, p: np.ndarray, natural_frequency_hz: float,
                 damping_ratio: float = PORT_DAMPING_RATIO) -> np.ndarray:
    """What a transducer at the end of a drilled port reads of the chamber pressure ``p``:
    the port's oil (inertance ``I``) rings on the transducer's dead volume (capacitance
    ``C``), ``p_s'' + 2ζω_n p_s' + ω_n² p_s = ω_n² p`` with ``ω_n = 1/√(IC)`` (a Helmholtz
    resonator; Watton, transducer mounting; Doebelin, *Measurement Systems*, second-order
    instruments). Integrated exactly for a chamber pressure linear between the samples
    (``scipy.signal.lsim``), starting at rest at ``p[0]``."""
    from scipy.signal import lsim
    w = 2.0 * math.pi * natural_frequency_hz
    sys = ([w * w], [1.0, 2.0 * damping_ratio * w, w * w])
    _, y, _ = lsim(sys, p - p[0], t, interp=True)
    return np.asarray(y) + p[0]


def measure(rig: Rig2, t: np.ndarray, Y: np.ndarray, seed: int) -> dict[str, np.ndarray]:
    """What the data logger stores: the chamber pressures read through their ports
    (``pressure_port_resonance``), each output delayed (``sensor_delay``), its white noise
    added (seeded), then quantised by its converter (round to the step); the pressure ADCs
    clip at 0 and full scale, the current ADC at ±half its span. The command is logged as
    sent."""
    true = true_channels(rig, t, Y)
    if "pressure_port_resonance" in rig.fx:
        for ch in ("chamber_a_pa", "chamber_b_pa"):
            true[ch] = port_reading(t, true[ch], rig.fx["pressure_port_resonance"])
    rng = np.random.default_rng(seed)
    delay = rig.fx.get("sensor_delay", 0.0)
    p = rig.p
    white = {"ankle_angle_rad": 0.0, "ankle_torque_nm": p.torque_noise_nm,
             "chamber_a_pa": p.pressure_noise_pa, "chamber_b_pa": p.pressure_noise_pa,
             "motor_current_a": p.current_noise_a, "motor_speed_rad_s": p.speed_noise_rad_s}
    q = quantum(p)
    out = {"time_s": t.copy(), "motor_voltage_v": true["motor_voltage_v"]}
    for ch in OUTPUTS:
        x = true[ch]
        if delay > 0:
            x = np.interp(t - delay, t, x, left=x[0])
        if white[ch] > 0:
            x = x + rng.normal(0.0, white[ch], len(t))
        if ch in q:
            x = np.round(x / q[ch]) * q[ch]
        if ch.startswith("chamber_"):
            x = np.clip(x, 0.0, p.pressure_adc_full_scale_pa)
        elif ch == "motor_current_a":
            x = np.clip(x, -p.current_adc_full_scale_a / 2, p.current_adc_full_scale_a / 2)
        out[ch] = x
    return out


# ----------------------------------------------------------------------------- records


def simulate_record(duration_s: float, effects=None, seed: int = 0, *,
                    params: Rig2Params | None = None, amplitude_v: float = 4.0,
                    rtol: float = 1e-6):
    """Simulate the bench driven by :func:`voltage_command` and measure it; returns
    ``(rig, channels)``."""
    rig = Rig2(params, effects, voltage_command(duration_s, amplitude_v))
    t, Y = rig.simulate(duration_s, rtol=rtol)
    return rig, measure(rig, t, Y, seed)


def _toml_value(v) -> str:
    if isinstance(v, str):
        return '"' + v.replace("\\", "\\\\").replace('"', '\\"') + '"'
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    return repr(float(v))


def write_record(path, duration_s: float = 20.0, effects=None, seed: int = 0, *,
                 params: Rig2Params | None = None, amplitude_v: float = 4.0,
                 rtol: float = 1e-6) -> Path:
    """Simulate the bench and write the record in the afo_mj measured-data v1 format
    (``docs/measured_data.md``): ``path`` (CSV, ``time_s`` first) and its sidecar (same stem,
    ``.toml``) with ``[source]``, ``[noise]`` and ``[hold] motor_voltage_v = "zero_order"``.
    Written here, not with afo_mj's writer; returns ``path``."""
    path = Path(path)
    if path.suffix != ".csv":
        raise ValueError(f"path = {str(path)!r}; allowed: a .csv file")
    rig, ch = simulate_record(duration_s, effects, seed, params=params,
                              amplitude_v=amplitude_v, rtol=rtol)
    cols = ["time_s", "motor_voltage_v", *OUTPUTS]
    data = np.column_stack([ch[c] for c in cols])
    with open(path, "w", encoding="utf-8", newline="") as f:
        f.write(",".join(cols) + "\n")
        for row in data.tolist():
            f.write(",".join(repr(v) for v in row) + "\n")
    on = ", ".join(f"{k}={v:g}" for k, v in rig.fx.items()) or "none"
    desc = (f"second independent ankle bench (tests/second_rig.py: Jelali & Kroll / Watton "
            f"equations, scipy Radau rtol={rtol:g}), not afo_mj's model; {duration_s:g} s, "
            f"seed {seed}; voltage command updated every {COMMAND_UPDATE_S * 1e3:g} ms and "
            f"held; effects on: {on}")
    lines = ['format = "afo_mj measured data v1"',
             f"inputs = {_toml_value(['motor_voltage_v'])}",
             f"outputs = {_toml_value(list(OUTPUTS))}", "",
             "[source]", f"preset = {_toml_value('second_rig')}",
             f"description = {_toml_value(desc)}",
             f"origin = {_toml_value('afo_mj tests/second_rig.py')}", "", "[noise]"]
    lines += [f"{c} = {s!r}" for c, s in noise_sigmas(rig.p).items()]
    lines += ["", "[hold]", 'motor_voltage_v = "zero_order"', ""]
    path.with_suffix(".toml").write_text("\n".join(lines), encoding="utf-8")
    return path
