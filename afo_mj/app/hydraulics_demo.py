"""The hydraulics demo: the library's lab bench (:func:`afo_mj.circuits.library.lab_bench`:
motor → reversible pump → two hoses → piston-cable cylinder on a 40 mm pulley, charge checks
and cross-port reliefs) driving a simulated foot — an inertia on a torsional spring and damper
(:class:`afo_mj.circuits.device.JointLoad`) — with a sinusoidal motor voltage, stepped by the
generated circuit stepper; its ranges and its energy chain by component."""

from __future__ import annotations

import math
import time

import numpy as np

__all__ = ["hydraulics_demo", "DEMO_LOAD", "DEMO_VOLTAGE_AMPLITUDE_V", "DEMO_FREQUENCY_HZ"]

#: the foot the demo drives: 2 kg at the 40 mm pulley radius (J = m r²), on a 20 kN/m spring
#: and a 50 N·s/m damper seen at the piston (k r², c r²): 3.2e-3 kg·m², 32 N·m/rad,
#: 0.08 N·m·s/rad
DEMO_LOAD = {"inertia_kg_m2": 2.0 * 0.04 ** 2, "stiffness_nm_rad": 2.0e4 * 0.04 ** 2,
             "damping_nm_s_rad": 50.0 * 0.04 ** 2}
#: the open-loop motor voltage, ``8 V · sin(2π 3 Hz t)``, held over each 1 ms sample
DEMO_VOLTAGE_AMPLITUDE_V = 8.0
DEMO_FREQUENCY_HZ = 3.0
SAMPLE_S = 1e-3


def hydraulics_demo(duration_s: float = 1.0, substeps: int = 1) -> dict:
    """Run the demo; returns the figures ``afo-mj hydraulics-demo`` prints (SI units):
    ``duration_s``, ``us_per_step`` (per 1 ms sample), ``wall_time_s``, ``substeps`` (stepper
    steps per sample), ``ranges`` (name → (min, max): chamber gauge pressures, the cylinder's
    hydraulic torque on the joint, piston position, joint angle), ``motor_speed_peak_rad_s``,
    ``oil_temperature_rise_k``, ``max_torque_nm`` and ``energy`` (``input_j``, ``output_j``
    = ``load_out_j`` the mechanical energy into the joint, ``heat_j`` by component loss,
    ``stored_change_j``, ``residual_j``, ``relative_residual`` = residual / the energy
    throughput of the run, :meth:`~afo_mj.circuits.device.CircuitDevice.component_ledger`)."""
    from afo_mj.circuits.device import CircuitDevice, JointLoad
    from afo_mj.circuits.library import lab_bench

    if not (isinstance(duration_s, (int, float)) and math.isfinite(duration_s)
            and duration_s >= SAMPLE_S):
        raise ValueError(f"duration_s = {duration_s!r}; allowed: a finite number >= {SAMPLE_S}")
    if int(substeps) != substeps or substeps < 1:
        raise ValueError(f"substeps = {substeps!r}; allowed: an integer >= 1")
    sub = int(substeps)
    n = int(round(duration_s / SAMPLE_S))
    t = np.arange(n) * SAMPLE_S
    volts = DEMO_VOLTAGE_AMPLITUDE_V * np.sin(2 * math.pi * DEMO_FREQUENCY_HZ * t)
    # open loop: the command is the motor voltage; torque_fn is only the protocol's marker
    dev = CircuitDevice(lab_bench(), timestep_s=SAMPLE_S / sub, open_loop=True,
                        torque_fn=lambda _t, _a, _v: 0.0)
    load = JointLoad(**DEMO_LOAD)
    t0 = time.perf_counter()
    log = dev.run_imposed(volts, np.zeros(n), np.zeros(n), substeps=sub, load=load)
    wall = time.perf_counter() - t0
    led = dev.component_ledger()
    torque = log["cylinder.hydraulic_torque_nm"]

    def span(x):
        return float(np.min(x)), float(np.max(x))

    stored = float(sum(led["stored_change_j"].values()))
    e_in = led["input_j"]
    return {"duration_s": float(log["time_s"][-1]), "us_per_step": wall / n * 1e6,
            "wall_time_s": wall, "substeps": sub,
            "ranges": {"chamber_a_gauge_pa": span(log["chamber_a"]),
                       "chamber_b_gauge_pa": span(log["chamber_b"]),
                       "torque_nm": span(torque),
                       "position_m": span(log["cylinder.piston_position_m"]),
                       "angle_rad": span(log["angle_rad"])},
            "motor_speed_peak_rad_s": float(np.max(np.abs(log["shaft"]))),
            "oil_temperature_rise_k": float(log["oil_temperature_k"][-1]
                                            - dev.cc.circuit.thermal.ambient_temperature_k),
            "max_torque_nm": float(np.max(np.abs(torque))),
            "energy": {"input_j": e_in, "output_j": led["mechanical_out_j"],
                       "load_out_j": led["mechanical_out_j"],
                       "heat_j": dict(led["losses_j"]),
                       "stored_change_j": stored, "residual_j": led["residual_j"],
                       "relative_residual": led["balance_error_rel"]}}
