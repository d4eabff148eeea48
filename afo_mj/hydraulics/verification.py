"""Verification runs: the fixed-step circuit against a tight-tolerance Radau reference.

Used by the tests and by ``benchmarks/hydraulics_step.py``. Each case is a loaded
pump-controlled cylinder driven by a motor-voltage profile held over each step (zero-order
hold, as a controller's output is); the reference integrates exactly the same held input with
``scipy.integrate.solve_ivp(method="Radau", rtol=1e-8)`` interval by interval.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
from scipy.integrate import solve_ivp

from .params import replace_named
from .pump_cylinder import (CircuitSimulator, LoadParams, PumpCylinderCircuit,
                            PumpCylinderParams, STATE_NAMES)

CASES = ("loaded", "small_volume_air", "end_stop")


@dataclasses.dataclass
class Case:
    name: str
    circuit: PumpCylinderCircuit
    y0: np.ndarray
    duration_s: float
    command: callable  # t -> (motor_command_v, external_force_n)


def make_case(name: str = "loaded") -> Case:
    """Build one verification case.

    * ``loaded``: 2 kg + 20 kN/m spring load, 1 m hoses, sinusoidal motor voltage (3 Hz).
    * ``small_volume_air``: sub-cm³ chambers (0.05 cm³ dead volume, 0.2 m × 2 mm hoses), 1 %
      entrained air, circuit charged to only 0.3 MPa abs: air-dominated, very stiff/soft switching.
    * ``end_stop``: the piston is driven into its end stop and held there.
    """
    base = PumpCylinderParams(load=LoadParams(mass_kg=2.0, stiffness_n_m=2.0e4,
                                              rest_position_m=0.015, damping_n_s_m=50.0))
    amp, freq, init_p = 8.0, 3.0, 2.0e6
    if name == "loaded":
        params = base
    elif name == "small_volume_air":
        params = replace_named(base, {
            "fluid.air_fraction": 0.01,
            "cylinder.dead_volume_a_m3": 0.05e-6, "cylinder.dead_volume_b_m3": 0.05e-6,
            "cylinder.bore_m": 8e-3, "cylinder.rod_diameter_m": 1.5e-3,
            "hose_a.length_m": 0.2, "hose_a.bore_m": 2e-3,
            "hose_b.length_m": 0.2, "hose_b.bore_m": 2e-3,
            "pump_port_volume_m3": 0.05e-6, "load.stiffness_n_m": 5.0e3})
        amp, init_p = 4.0, 0.3e6
    elif name == "end_stop":
        params = replace_named(base, {"load.stiffness_n_m": 0.0, "load.damping_n_s_m": 200.0})
        amp, freq = 10.0, 1.5
    else:
        raise ValueError(f"case = {name!r}; allowed: {', '.join(CASES)}")
    circuit = PumpCylinderCircuit(params)
    y0 = circuit.initial_state(pressure_pa=init_p)

    def command(t: float):
        return (amp * math.sin(2 * math.pi * freq * t), 0.0)

    return Case(name, circuit, y0, 0.6 if name != "end_stop" else 0.5, command)


def run_fixed_step(case: Case, dt: float = 1e-3, substeps: int = 4):
    """Fixed-step run; returns ``(t, Y, simulator)``, Y of shape (n_steps + 1, n_states)."""
    sim = CircuitSimulator(case.circuit, case.y0, substeps=substeps)
    n = int(round(case.duration_s / dt))
    ys = np.empty((n + 1, case.y0.size))
    ys[0] = sim.y
    for k in range(n):
        ys[k + 1] = sim.step(dt, case.command(k * dt))
    return np.arange(n + 1) * dt, ys, sim


def run_reference(case: Case, dt: float = 1e-3, rtol: float = 1e-8):
    """Radau reference with the same held input, restarted at every hold interval."""
    c = case.circuit

    n = int(round(case.duration_s / dt))
    ys = np.empty((n + 1, case.y0.size))
    ys[0] = case.y0
    y = case.y0.copy()
    atol = 1e-9 * c.scale
    for k in range(n):
        u = case.command(k * dt)

        def f(t, yy, u=u):
            if yy.ndim == 1:
                return c.evaluate(t, yy[:, None], u)[0][:, 0]
            return c.evaluate(t, yy, u)[0]

        sol = solve_ivp(f, (k * dt, (k + 1) * dt), y, method="Radau", rtol=rtol, atol=atol,
                        vectorized=True)
        if sol.status != 0:
            raise RuntimeError(f"Radau reference failed at t = {k * dt}: {sol.message}")
        y = sol.y[:, -1]
        ys[k + 1] = y
    return np.arange(n + 1) * dt, ys


def nrmse(sim: np.ndarray, ref: np.ndarray) -> float:
    """Root-mean-square error normalised by the reference's range (max − min)."""
    span = float(np.max(ref) - np.min(ref))
    return float(np.sqrt(np.mean((sim - ref) ** 2)) / span) if span > 0 else 0.0


def compare(case_name: str = "loaded", dt: float = 1e-3, substeps: int = 4,
            duration_s: float | None = None) -> dict:
    """NRMSE of the fixed-step run vs Radau on pressures and actuator force."""
    case = make_case(case_name)
    if duration_s is not None:
        case.duration_s = duration_s
    t, ys, sim = run_fixed_step(case, dt, substeps)
    _, yr = run_reference(case, dt)
    cyl = case.circuit.cylinder
    idx = {n: i for i, n in enumerate(STATE_NAMES)}
    out = {}
    for name in ("pump_a_pa", "pump_b_pa", "chamber_a_pa", "chamber_b_pa"):
        out[name] = nrmse(ys[:, idx[name]], yr[:, idx[name]])
    force = lambda y: cyl.hydraulic_force_n(y[:, idx["chamber_a_pa"]],  # noqa: E731
                                            y[:, idx["chamber_b_pa"]])
    out["actuator_force_n"] = nrmse(force(ys), force(yr))
    out["position_m"] = nrmse(ys[:, idx["position_m"]], yr[:, idx["position_m"]])
    out["worst"] = max(out.values())
    out["max_position_m"] = float(np.max(yr[:, idx["position_m"]]))
    out["substeps_per_step"] = sim.stepper.substeps_taken / (len(t) - 1)
    return out


