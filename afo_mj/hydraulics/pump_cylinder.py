"""Pump-controlled cylinder circuit: motor → bidirectional pump → two hoses → cylinder → load.

The reference closed circuit of the library (the seed's pump-controlled architecture, ch. 4 and
the HAFO of ch. 6, without the ankle): a PWM driver and brushless motor turn a bidirectional
pump whose ports feed chambers a and b of a cylinder through one hose each. The cylinder drives a
lumped load (mass, spring, damper, external force). There is no throttling valve.

States (SI, pressures absolute)::

    current_a, speed_rad_s, pump_a_pa, pump_b_pa, chamber_a_pa, chamber_b_pa,
    position_m, velocity_m_s, fluid_temperature_k

Node continuity (Merritt 1967 §2.5): ``C(p) dp/dt = Σ Q_in − dV/dt`` with the node capacitance
``C = V/B(p) + V_hose/(2 K_wall)`` (half of each hose's volume and wall compliance lumped at each
end; ``B(p)`` from seed eq. 2.5 and the cavitation rule of :mod:`.fluid`). Hose flow from the
quasi-steady loss law of :mod:`.conduit` (inverted by fixed-point iteration). Temperature:
``C_th dT/dt = Σ heat into the oil − (T − T_amb)/R_th`` (motor and driver heat go to ambient).

Energy ledger (gauge pressures): electrical bus input = load output + Σ named heat
+ Δ(stored: inductance, rotating and moving masses, end stops, oil compression).
"""

from __future__ import annotations

import dataclasses
import numpy as np

from . import laws
from .conduit import Hose, HoseParams
from .cylinder import Cylinder, CylinderParams
from .fluid import ATMOSPHERIC_PRESSURE_PA, Fluid, FluidParams, ISO_VG46
from .integrator import Ros2, SimulationError
from .motor import BrushlessMotor, DriverParams, MotorParams
from .params import Parameters, param
from .pump import GEAR_PUMP_SMALL, Pump, PumpParams

STATE_NAMES = ("current_a", "speed_rad_s", "pump_a_pa", "pump_b_pa", "chamber_a_pa",
               "chamber_b_pa", "position_m", "velocity_m_s", "fluid_temperature_k")
(I_CUR, I_W, I_PPA, I_PPB, I_PCA, I_PCB, I_X, I_V, I_T) = range(len(STATE_NAMES))

#: Named heat flows of the ledger (W), in the order of the chain.
HEAT_NAMES = ("driver", "motor_copper", "motor_friction", "pump_leakage_friction", "hose_a",
              "hose_b", "cylinder_seal_friction", "cylinder_leakage", "end_stop_damping")


@dataclasses.dataclass(frozen=True)
class LoadParams(Parameters):
    """Lumped load on the piston: mass, spring to ``rest_position_m``, damper."""

    mass_kg: float = param(2.0, unit="kg", lo=0.0, hi=1e4, doc="load mass moved with the piston")
    stiffness_n_m: float = param(0.0, unit="N/m", lo=0.0, hi=1e9)
    rest_position_m: float = param(0.015, unit="m", lo=-10.0, hi=10.0)
    damping_n_s_m: float = param(0.0, unit="N s/m", lo=0.0, hi=1e7)


@dataclasses.dataclass(frozen=True)
class PumpCylinderParams(Parameters):
    """Everything in the pump-controlled cylinder circuit."""

    fluid: FluidParams = ISO_VG46
    motor: MotorParams = dataclasses.field(default_factory=MotorParams)
    driver: DriverParams = dataclasses.field(default_factory=DriverParams)
    pump: PumpParams = GEAR_PUMP_SMALL
    hose_a: HoseParams = dataclasses.field(default_factory=HoseParams)
    hose_b: HoseParams = dataclasses.field(default_factory=HoseParams)
    cylinder: CylinderParams = dataclasses.field(default_factory=CylinderParams)
    load: LoadParams = dataclasses.field(default_factory=LoadParams)
    bus_voltage_v: float = param(24.0, unit="V", lo=0.0, hi=1000.0, lo_open=True)
    pump_port_volume_m3: float = param(0.3e-6, unit="m^3", lo=0.0, hi=1e-2, lo_open=True,
                                       doc="oil volume in each pump port and manifold")
    fluid_heat_capacity_j_k: float = param(60.0, unit="J/K", lo=1e-3, hi=1e7,
                                           doc="oil plus wetted metal thermal capacity")
    fluid_thermal_resistance_k_w: float = param(2.0, unit="K/W", lo=1e-4, hi=1e4,
                                                doc="oil to ambient thermal resistance")
    ambient_temperature_k: float = param(298.15, unit="K", lo=200.0, hi=400.0)


class PumpCylinderCircuit:
    """Right-hand side, power flows and stored energy of :class:`PumpCylinderParams`.

    Inputs ``u = (motor_command_v, external_force_n)``.
    """

    state_names = STATE_NAMES

    def __init__(self, params: PumpCylinderParams = PumpCylinderParams()):
        self.params = params
        self.fluid = Fluid(params.fluid)
        self.motor = BrushlessMotor(params.motor, params.driver)
        self.pump = Pump(params.pump)
        self.hose_a = Hose(params.hose_a)
        self.hose_b = Hose(params.hose_b)
        self.cylinder = Cylinder(params.cylinder)
        self.inertia_kg_m2 = params.motor.rotor_inertia_kg_m2 + params.pump.rotor_inertia_kg_m2
        self.moving_mass_kg = params.cylinder.piston_mass_kg + params.load.mass_kg
        self.scale = np.array([1.0, 10.0, 1e6, 1e6, 1e6, 1e6,
                               params.cylinder.stroke_m, 0.01, 1.0])
        # Error control: the winding current settles in L/R (~0.1-1 ms) after each held-voltage
        # change; that transient is not worth subdividing for (the L-stable step lands on its
        # quasi-steady value), so its error is weighed against the current limit.
        self.error_scale = self.scale.copy()
        self.error_scale[I_CUR] = 100.0 * params.driver.current_limit_a

    # -- initial state -----------------------------------------------------------------------
    def initial_state(self, pressure_pa: float = 1e6, position_m: float | None = None,
                      temperature_k: float | None = None) -> np.ndarray:
        """Circuit at rest with every node at ``pressure_pa`` (absolute)."""
        x0 = self.params.cylinder.stroke_m / 2 if position_m is None else position_m
        t0 = self.params.ambient_temperature_k if temperature_k is None else temperature_k
        return np.array([0.0, 0.0, pressure_pa, pressure_pa, pressure_pa, pressure_pa,
                         x0, 0.0, t0])

    # -- physics -----------------------------------------------------------------------------
    def _hose_flow(self, hose: Hose, dp, rho, nu):
        """Invert the loss law ``Δp = R_lam Q φ(Re)`` for ``Q``
        (:func:`~afo_mj.hydraulics.laws.hose_flow_m3_s`, through :meth:`Hose.flow_m3_s`)."""
        return hose.flow_m3_s(dp, rho, nu)

    def evaluate(self, t: float, y: np.ndarray, u) -> tuple[np.ndarray, dict]:
        """``(dy/dt, flows)`` for a batch of states ``y`` of shape (n, k)."""
        p = self.params
        command_v, f_ext = u
        cur, w, ppa, ppb, pca, pcb, x, v, temp = y
        nu = self.fluid.kinematic_viscosity_m2_s(temp)
        rho = self.fluid.density_kg_m3(ATMOSPHERIC_PRESSURE_PA, temp)
        mu = rho * nu

        # motor and driver
        volt = self.motor.applied_voltage_v(command_v, w, p.bus_voltage_v)
        di = self.motor.current_rate_a_s(volt, cur, w)
        t_motor_f = self.motor.friction_torque_nm(w)
        # pump
        dp_pump = ppa - ppb
        q_pump = self.pump.flow_m3_s(w, dp_pump, mu)
        t_pump = self.pump.shaft_torque_nm(w, dp_pump, mu)
        dw = (self.motor.electromagnetic_torque_nm(cur) - t_motor_f - t_pump) / self.inertia_kg_m2
        # hoses (a: pump a → chamber a, b: pump b → chamber b)
        q_ha = self._hose_flow(self.hose_a, ppa - pca, rho, nu)
        q_hb = self._hose_flow(self.hose_b, ppb - pcb, rho, nu)
        # cylinder
        cyl = self.cylinder
        va, vb = cyl.chamber_volumes_m3(x)
        q_leak = cyl.internal_leakage_m3_s(pca, pcb, mu)
        f_h = cyl.hydraulic_force_n(pca, pcb)
        f_fr = cyl.friction_force_n(v, pca, pcb)
        f_stop = cyl.end_stop_force_n(x, v)
        ld = p.load
        f_load = -ld.stiffness_n_m * (x - ld.rest_position_m) - ld.damping_n_s_m * v + f_ext
        dv = (f_h - f_fr + f_stop + f_load) / self.moving_mass_kg
        # node continuity
        b_oil = self.fluid.bulk_modulus_pa
        ha, hb = self.hose_a, self.hose_b
        vpa = p.pump_port_volume_m3 + ha.volume_m3 / 2
        vpb = p.pump_port_volume_m3 + hb.volume_m3 / 2
        vca = va + ha.volume_m3 / 2
        vcb = vb + hb.volume_m3 / 2
        # each node holds half of each hose's wall (laws.node_capacitance_m3_pa)
        cap = laws.node_capacitance_m3_pa
        c_pa = cap(vpa, b_oil(ppa), ha.volume_m3 / 2, ha.wall_compliance_inv_pa)
        c_pb = cap(vpb, b_oil(ppb), hb.volume_m3 / 2, hb.wall_compliance_inv_pa)
        c_ca = cap(vca, b_oil(pca), ha.volume_m3 / 2, ha.wall_compliance_inv_pa)
        c_cb = cap(vcb, b_oil(pcb), hb.volume_m3 / 2, hb.wall_compliance_inv_pa)
        net_pa = q_pump - q_ha
        net_pb = -q_pump - q_hb
        net_ca = q_ha - q_leak - cyl.area_a_m2 * v
        net_cb = q_hb + q_leak + cyl.area_b_m2 * v
        # heat into the oil and temperature
        heat = {
            "driver": self.motor.driver.on_resistance_ohm * cur * cur
            + self.motor.driver.quiescent_power_w,
            "motor_copper": p.motor.resistance_ohm * cur * cur,
            "motor_friction": t_motor_f * w,
            "pump_leakage_friction": self.pump.friction_torque_nm(w, dp_pump, mu) * w
            + dp_pump * self.pump.leakage_m3_s(dp_pump, mu),
            "hose_a": (ppa - pca) * q_ha,
            "hose_b": (ppb - pcb) * q_hb,
            "cylinder_seal_friction": f_fr * v,
            "cylinder_leakage": (pca - pcb) * q_leak,
            "end_stop_damping": -(f_stop - self._stop_elastic(x)) * v,
        }
        heat_to_oil = (heat["pump_leakage_friction"] + heat["hose_a"] + heat["hose_b"]
                       + heat["cylinder_seal_friction"] + heat["cylinder_leakage"])
        dtemp = laws.lumped_temperature_rate_k_s(temp, heat_to_oil, p.ambient_temperature_k,
                                                 p.fluid_thermal_resistance_k_w,
                                                 p.fluid_heat_capacity_j_k)
        dy = np.stack([di, dw, net_pa / c_pa, net_pb / c_pb, net_ca / c_ca, net_cb / c_cb,
                       v, dv, dtemp])
        g = lambda pr: pr - ATMOSPHERIC_PRESSURE_PA  # noqa: E731  gauge
        flows = {
            "voltage_v": volt,
            "electrical_in_w": self.motor.bus_power_w(volt, cur),
            "load_out_w": -f_load * v,
            "oil_compression_w": g(ppa) * net_pa + g(ppb) * net_pb + g(pca) * net_ca
            + g(pcb) * net_cb,
            "heat": heat,
            "pump_flow_m3_s": q_pump,
            "hydraulic_force_n": f_h,
            "friction_force_n": f_fr,
        }
        return dy, flows

    def _stop_elastic(self, x):
        """The spring part of the end-stop force (the law without its damper)."""
        cyl = self.cylinder
        if not cyl.params.end_stops_enabled:
            return 0.0
        return laws.end_stop_force_n(x, 0.0, cyl.params.stroke_m,
                                     cyl.params.end_stop_stiffness_n_m, 0.0)

    def stored_energy_j(self, y: np.ndarray) -> dict:
        """Energy held in state functions: inductance, rotating and moving masses, end stops."""
        cur, w, _, _, _, _, x, v, _ = y
        return {
            "inductance": 0.5 * self.params.motor.inductance_h * cur ** 2,
            "rotation": 0.5 * self.inertia_kg_m2 * w ** 2,
            "translation": 0.5 * self.moving_mass_kg * v ** 2,
            "end_stops": float(self.cylinder.end_stop_energy_j(x)),
        }


@dataclasses.dataclass
class Ledger:
    """Energies (J) accumulated by the trapezoidal rule of the power flows at step ends."""

    electrical_in_j: float = 0.0
    load_out_j: float = 0.0
    oil_compression_j: float = 0.0
    heat_j: dict = dataclasses.field(default_factory=lambda: {k: 0.0 for k in HEAT_NAMES})

    def add(self, dt: float, a: dict, b: dict) -> None:
        self.electrical_in_j += 0.5 * dt * float(a["electrical_in_w"][0] + b["electrical_in_w"][0])
        self.load_out_j += 0.5 * dt * float(a["load_out_w"][0] + b["load_out_w"][0])
        self.oil_compression_j += 0.5 * dt * float(a["oil_compression_w"][0]
                                                   + b["oil_compression_w"][0])
        for k in HEAT_NAMES:
            self.heat_j[k] += 0.5 * dt * float(np.asarray(a["heat"][k])[0]
                                               + np.asarray(b["heat"][k])[0])

    @property
    def heat_total_j(self) -> float:
        return sum(self.heat_j.values())


class CircuitSimulator:
    """Advance a circuit by fixed steps with :class:`~.integrator.Ros2`, keeping a ledger.

    ``substeps`` splits each step (e.g. one 1 ms MuJoCo step) into equal ROS2 steps; inputs are
    held constant over the step (zero-order hold, as a controller's output is). The default 4
    resolves the motor's electrical transient (L/R ≈ 0.25 ms) that follows each held-voltage
    change; with 1 the pressures stay stable but lose accuracy at reversals (measured in
    ``benchmarks/hydraulics_step.py``). Each substep is further subdivided only where the
    error estimate asks (end-stop impacts).
    """

    def __init__(self, circuit: PumpCylinderCircuit, y0: np.ndarray, substeps: int = 4):
        if substeps < 1:
            raise ValueError(f"substeps = {substeps!r}; allowed: integer >= 1")
        self.circuit = circuit
        self.y = np.array(y0, dtype=float)
        self.t = 0.0
        self.substeps = int(substeps)
        self.stepper = Ros2(circuit.evaluate, circuit.scale, names=list(circuit.state_names),
                            error_scale=circuit.error_scale)
        self.ledger = Ledger()
        self.stored0 = circuit.stored_energy_j(self.y)
        self.pressure_clamps = 0
        self._marks: list = []
        self._pressure_rows = [i for i, n in enumerate(circuit.state_names) if n.endswith("_pa")]

    def step(self, dt: float, u) -> np.ndarray:
        """Advance by ``dt`` with inputs ``u`` held (ROS2 with error-controlled subdivision).

        The ledger integrates the power flows by the trapezoidal rule over every accepted
        substep, with both ends evaluated under the same held input.
        """
        h = dt / self.substeps
        for _ in range(self.substeps):
            self._marks.clear()
            y = self.stepper.advance(self.t, self.y, h, u, self._record)
            clamped, n = self.circuit.fluid.clamp_pressure(y[self._pressure_rows])
            if n:
                y[self._pressure_rows] = clamped
                self.pressure_clamps += n
            _, end_flows = self.circuit.evaluate(self.t + h, y[:, None], u)
            self._marks.append((0.0, end_flows))
            for (hh, fa), (_, fb) in zip(self._marks[:-1], self._marks[1:]):
                self.ledger.add(hh, fa, fb)
            self.y = y
            self.t += h
        return self.y

    def _record(self, h: float, flows: dict) -> None:
        self._marks.append((h, flows))

    def energy_balance(self) -> dict:
        """``input − (output + heat + Δstored)`` and its parts (J)."""
        led = self.ledger
        s1 = self.circuit.stored_energy_j(self.y)
        d_stored = sum(s1.values()) - sum(self.stored0.values()) + led.oil_compression_j
        residual = led.electrical_in_j - led.load_out_j - led.heat_total_j - d_stored
        return {"input_j": led.electrical_in_j, "output_j": led.load_out_j,
                "heat_j": dict(led.heat_j), "heat_total_j": led.heat_total_j,
                "stored_change_j": d_stored, "residual_j": residual,
                "relative_residual": residual / abs(led.electrical_in_j)}


__all__ = ["PumpCylinderParams", "PumpCylinderCircuit", "LoadParams", "CircuitSimulator",
           "Ledger", "SimulationError", "STATE_NAMES", "HEAT_NAMES"]
