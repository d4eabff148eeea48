"""Stiffness bench: a stiffness-emulating orthosis (the PHAFO) on a clinical stiffness rig.

Clinical AFO stiffness rigs rotate the ankle slowly through dorsiflexion and plantarflexion and
record the orthosis torque against the angle (Bregman et al. 2009, *Gait Posture* 30:144,
BRUCE; Shuman & Russell Esposito 2021, EMPIRE). This bench does the same on the ankle test
stand (:class:`~afo_mj.human.test_stand.AnkleTestStand`, ``imposed`` load: a position-
controlled drive) with a valve-circuit orthosis (:class:`~afo_mj.devices.valve_afo.
ValveAfoDevice`) emulating a linear spring (and optional damper) about a rest angle:

    τ_cmd = −K (θ − θ0) − B θ̇                 (+ dorsiflexion, the device's impedance mode)

For each commanded stiffness ``K`` a fresh stand and device run the sweep
``θ(t) = A sin(2π f t)`` for ``cycles`` periods (the foot starts at neutral moving into
dorsiflexion; the rail starts charged at its initial pressure). The record (angle, delivered
torque) is reduced by :func:`afo_mj.metrics.stiffness_metrics.sweep_stiffness` (least-squares
slope over whole cycles, the first cycle dropped as start-up), and the device's ledger gives
the pressures and energies.

Figures per commanded stiffness (``summary["stiffness"]["k<K>"]``, K in N·m/deg as written in
the scenario, e.g. ``k2.5``), SI unless the name says otherwise:

* ``commanded_nm_per_rad`` / ``commanded_nm_per_deg``; ``emulated_nm_per_rad`` /
  ``emulated_nm_per_deg`` (the fitted slope, restoring positive) and ``error_rel``
  = emulated / commanded − 1;
* ``r_squared``, ``rest_angle_rad`` (zero-torque crossing of the fit), branch stiffnesses
  ``dorsiflexing_nm_per_rad`` / ``plantarflexing_nm_per_rad``;
* ``hysteresis_energy_j`` (loop area per cycle, J), ``hysteresis_fraction`` (loop area / work
  put in while loading), ``loss_factor``;
* ``peak_torque_nm`` (largest |τ| over the analysed cycles) and, for comparison,
  ``commanded_peak_torque_nm`` = K A (+ B 2π f A for a damper: the spring's peak at the
  amplitude, an upper bound of the sum);
* ``torque_tracking_rmse_nm`` (commanded vs delivered over the whole run);
* ``peak_pressure_pa`` (highest node of the circuit, the rail included, gauge),
  ``peak_chamber_pressure_pa`` (highest cylinder chamber, gauge), ``peak_load_pressure_pa``
  (largest |chamber A − chamber B|: the pressure that makes the torque, ``|τ| / (A_e r)``),
  ``peak_supply_pressure_pa`` (the rail);
* ``electrical_in_j`` (battery energy drawn over the run), ``electrical_per_cycle_j``,
  ``mean_electrical_power_w``, ``mechanical_out_j`` (work the device did on the ankle; < 0:
  the rig did work on it), ``energy_balance_error_rel`` (ledger residual / energy drawn) and
  ``energy_error`` (residual / max(|electrical in|, |mechanical out|), as the HAFO bench).

``summary["acceptance"]``: every emulated stiffness within ``tolerance_rel`` (10 %, the
issue's acceptance figure) of its command.

Default sweep: ±12° at 0.25 Hz (15 deg/s peak, 12 s per stiffness for 3 cycles): slow enough
for a quasi-static rig, the amplitude the stiffest 4.6 N·m/deg spring can reach below the
PHAFO's 62 N·m (4.6 × 12 = 55.2 N·m).
"""

from __future__ import annotations

import math

import numpy as np

from afo_mj.metrics.stiffness_metrics import sweep_stiffness
from afo_mj.experiments.hafo_bench import energy_error
from afo_mj.scenarios.bench_protocols import (StiffnessBenchError, StiffnessSweepConfig,
                                              stiffness_label, sweep_config)

__all__ = ["StiffnessBenchError", "StiffnessSweepConfig", "ACCEPTANCE_TOLERANCE_REL",
           "sweep_config", "run_stiffness_sweep", "run_stiffness_bench", "stiffness_label"]

#: The issue's acceptance figure: emulated stiffness within 10 % of the command.
ACCEPTANCE_TOLERANCE_REL = 0.10
_DEG = math.pi / 180.0


def run_stiffness_sweep(params, stiffness_nm_per_rad: float,
                        cfg: StiffnessSweepConfig) -> tuple[dict, dict]:
    """One commanded stiffness on the stand: ``(figures, series)`` (module docstring)."""
    from afo_mj.devices.valve_afo import ValveAfoDevice, ValveAnkleParams
    from afo_mj.human.test_stand import AnkleTestStand, ImposedTrajectory, StandLoad
    if not isinstance(params, ValveAnkleParams):
        raise StiffnessBenchError(f"params = {type(params).__name__}; allowed: ValveAnkleParams "
                                  "(a valve-circuit preset such as phafo: impedance emulation)")
    k = float(stiffness_nm_per_rad)
    traj = ImposedTrajectory.sinusoid(cfg.amplitude_rad, cfg.frequency_hz)
    stand = AnkleTestStand(body_mass_kg=cfg.body_mass_kg, height_m=cfg.height_m,
                           load=StandLoad(kind="imposed", trajectory=traj),
                           timestep_s=cfg.timestep_s)
    n = int(round(cfg.duration_s / cfg.timestep_s))
    dev = ValveAfoDevice(params, impedance=[(1e9, k, cfg.damping_nm_s_per_rad,
                                             cfg.rest_angle_rad, 0.0)],
                         timestep_s=cfg.timestep_s, max_steps=n)
    rec = stand.run_device(dev, cfg.duration_s)
    log = {name: v[:, 0] for name, v in dev.log.arrays().items()}
    led = dev.ledger()
    theta, tau = rec.angle_rad, rec.device_torque_nm
    sw = sweep_stiffness(theta, tau, rec.velocity_rad_s)
    w = 2 * math.pi * cfg.frequency_hz
    cmd, dlv = log["commanded_torque_nm"], log["delivered_torque_nm"]
    drawn = led["electrical_drawn_j"]
    fig = {
        "commanded_nm_per_rad": k,
        "commanded_nm_per_deg": k * _DEG,
        "emulated_nm_per_rad": sw.stiffness_nm_per_rad,
        "emulated_nm_per_deg": sw.stiffness_nm_per_deg,
        "error_rel": sw.stiffness_nm_per_rad / k - 1.0,
        "r_squared": sw.r_squared,
        "rest_angle_rad": sw.rest_angle_rad,
        "dorsiflexing_nm_per_rad": sw.dorsiflexing_stiffness_nm_per_rad,
        "plantarflexing_nm_per_rad": sw.plantarflexing_stiffness_nm_per_rad,
        "hysteresis_energy_j": sw.hysteresis_energy_j,
        "hysteresis_fraction": sw.hysteresis_fraction,
        "loss_factor": sw.loss_factor,
        "cycles_analysed": sw.n_cycles,
        "angle_amplitude_rad": sw.angle_amplitude_rad,
        "peak_torque_nm": sw.max_torque_nm,
        "commanded_peak_torque_nm": k * cfg.amplitude_rad
        + cfg.damping_nm_s_per_rad * w * cfg.amplitude_rad,
        "torque_tracking_rmse_nm": float(np.sqrt(np.mean((cmd - dlv) ** 2))),
        "peak_pressure_pa": led["peak_pressure_pa"],
        "peak_chamber_pressure_pa": float(max(log["chamber_a_pa"].max(),
                                              log["chamber_b_pa"].max())),
        "peak_load_pressure_pa": float(np.max(np.abs(log["chamber_a_pa"]
                                                     - log["chamber_b_pa"]))),
        "peak_supply_pressure_pa": led["peak_supply_pressure_pa"],
        "electrical_in_j": drawn,
        "electrical_per_cycle_j": drawn / cfg.cycles,
        "mean_electrical_power_w": drawn / cfg.duration_s,
        "mechanical_out_j": led["mechanical_out_j"],
        "losses_j": led["losses_j"],
        "energy_balance_error_rel": led["balance_error_rel"],
        "energy_error": energy_error(led),
        "newton_unconverged_steps": led["newton_unconverged_steps"],
        "battery_overload_steps": led["battery_overload_steps"],
    }
    series = {"time_s": rec.time_s, "angle_rad": theta, "torque_nm": tau,
              "commanded_torque_nm": cmd, "supply_pa": log["supply_pa"],
              "stiffness_nm_per_rad": k, "rest_angle_rad": cfg.rest_angle_rad,
              # the device log (its own time base) for stiffness_timeseries.png
              "log_time_s": log["time_s"], "log_delivered_torque_nm": dlv,
              "pump_pa": log["pump_pa"], "chamber_a_pa": log["chamber_a_pa"],
              "chamber_b_pa": log["chamber_b_pa"], "valve_position": log["valve_position"],
              "valve_command": log["valve_command"]}
    return fig, series


def run_stiffness_bench(params, cfg: StiffnessSweepConfig,
                        tolerance_rel: float = ACCEPTANCE_TOLERANCE_REL) -> tuple[dict, dict]:
    """Every commanded stiffness of ``cfg``; returns ``(summary, series)``: summary keys
    ``stiffness`` (per ``k<K>``, module docstring), ``sweep`` (the rig settings, SI),
    ``acceptance`` and ``energy_error_max``; series ``stiffness_sweeps`` → ``k<K>`` → arrays."""
    per, series = {}, {}
    for k in cfg.stiffnesses_nm_per_rad:
        lab = stiffness_label(k)
        per[lab], series[lab] = run_stiffness_sweep(params, k, cfg)
    worst = max(abs(v["error_rel"]) for v in per.values())
    summary = {
        "stiffness": per,
        "sweep": {"amplitude_rad": cfg.amplitude_rad, "frequency_hz": cfg.frequency_hz,
                  "cycles": cfg.cycles, "duration_s": cfg.duration_s,
                  "damping_nm_s_per_rad": cfg.damping_nm_s_per_rad,
                  "rest_angle_rad": cfg.rest_angle_rad, "timestep_s": cfg.timestep_s,
                  "body_mass_kg": cfg.body_mass_kg, "height_m": cfg.height_m,
                  "imposed": "theta(t) = amplitude sin(2 pi f t) from neutral; first cycle "
                             "dropped as start-up"},
        "acceptance": {"tolerance_rel": tolerance_rel, "worst_error_rel": worst,
                       "passed": bool(worst <= tolerance_rel),
                       "criterion": "|emulated / commanded stiffness - 1| <= tolerance_rel "
                                    "for every commanded stiffness"},
        "energy_error_max": max(v["energy_error"] for v in per.values()),
    }
    return summary, {"stiffness_sweeps": series}
