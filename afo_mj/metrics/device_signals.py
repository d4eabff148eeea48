"""Device signals derived from an orthosis run's log: flows, the power at each stage of the
chain and the running efficiency, in SI units, per worn side.

The devices log states and a few outputs (their generated circuits' log under the names of
:data:`~afo_mj.devices.hafo.HAFO_LOG_NAMES` and
:data:`~afo_mj.devices.valve_afo.VALVE_LOG_NAMES`); what follows from them
and the device's parameters is computed here, after the run, so the hot loop stays lean.

Stages of the power chain (HAFO, Neubauer ch. 2; the valve circuit the same up to the pump):

* electrical, at the battery terminals: ``P_el = V_bus · I_bat``;
* hydraulic, at the pump outlet: ``P_hyd = Δp_pump · Q_pump`` with the geometric pump flow
  ``Q_pump = D ω / 2π`` (displacement ``D`` per revolution, shaft speed ``ω``; for the
  variable-displacement pump this is the full-stroke flow, an upper bound, since the
  compensator's displacement fraction is not logged) and ``Δp_pump`` = port A − port B for the
  pump-controlled (closed) circuit, outlet − reservoir for the open valve circuit;
* mechanical, at the ankle: ``P_mech = τ_device · θ̇`` (positive when the device drives the
  joint);
* the running efficiency ``η(t) = ∫ max(P_mech, 0) dt / ∫ max(P_el, 0) dt`` (positive ankle
  work per electrical energy drawn so far; the whole-run figure of the summary's ledger).

The piston (load) flow is ``Q_cyl = A_e r θ̇``: effective piston area of the cylinders on the
pulley times the cable speed (piston-cable cylinders, seed §2.4).
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

__all__ = ["DeviceSignal", "device_signals"]


@dataclasses.dataclass(frozen=True)
class DeviceSignal:
    """One derived signal: ``values`` (n, sides) in ``unit``."""

    values: np.ndarray
    unit: str
    doc: str


def _cumulative(power_w: np.ndarray, t_s: np.ndarray) -> np.ndarray:
    """Right-point running integral of ``power_w`` over ``t_s`` (column-wise)."""
    dt = np.diff(t_s, prepend=t_s[0] if len(t_s) else 0.0)
    return np.cumsum(power_w * dt[:, None], axis=0)


def device_signals(device) -> dict[str, DeviceSignal]:
    """Derived signals of a finished :class:`~afo_mj.devices.hafo.HafoDevice` (or valve
    device) run, from its log and parameters. Returns an empty dict when the device kept no
    log.

    Example: ``device_signals(dev)["pump_flow_m3_s"].values[:, 0]`` is the right side's
    geometric pump flow [m³/s] at each logged step.
    """
    log = getattr(device, "log", None)
    if log is None or log.n == 0:
        return {}
    L = log.arrays()
    p = device.params
    t = L["time_s"][:, 0]
    omega = L["motor_speed_rad_s"]
    disp = p.pump.displacement_m3_rev
    q_pump = disp * omega / (2.0 * math.pi)
    if "pump_pa" in L:                                   # open circuit: outlet to reservoir
        dp_pump = L["pump_pa"] - p.reservoir_pressure_pa
        circuit = "outlet − reservoir"
    else:                                                # closed circuit: port A − port B
        dp_pump = L["pressure_a_pa"] - L["pressure_b_pa"]
        circuit = "port A − port B"
    q_cyl = p.effective_area_m2 * p.pulley_radius_m * L["ankle_velocity_rad_s"]
    p_el = L["bus_voltage_v"] * L["battery_current_a"]
    p_hyd = dp_pump * q_pump
    p_mech = L["mechanical_power_w"]
    e_in = _cumulative(np.maximum(p_el, 0.0), t)
    e_out = _cumulative(np.maximum(p_mech, 0.0), t)
    with np.errstate(invalid="ignore", divide="ignore"):
        eta = np.where(e_in > 1e-9, e_out / np.where(e_in > 1e-9, e_in, 1.0), 0.0)
    return {
        "pump_flow_m3_s": DeviceSignal(q_pump, "m^3/s", "geometric pump flow D ω / 2π"),
        "cylinder_flow_m3_s": DeviceSignal(q_cyl, "m^3/s",
                                           "piston flow A_e r θ̇ (+ = dorsiflexion)"),
        "electrical_power_w": DeviceSignal(p_el, "W", "battery terminal power V_bus I_bat"),
        "hydraulic_power_w": DeviceSignal(p_hyd, "W",
                                          f"pump hydraulic power Δp Q_pump, Δp = {circuit}"),
        "mechanical_power_w": DeviceSignal(p_mech, "W", "ankle power τ_device θ̇"),
        "running_efficiency": DeviceSignal(eta, "1",
                                           "∫ max(P_mech, 0) dt / ∫ max(P_el, 0) dt so far"),
    }
