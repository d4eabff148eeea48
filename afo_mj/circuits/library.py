"""Circuit descriptions shipped with afo_mj (each a plain description a user can copy).

* :func:`lab_bench` — the lab ankle bench: one double-acting piston-cable cylinder on the ankle
  pulley, driven by a reversible pump, charge check valves from a low-pressure reservoir into
  either line, cross-port relief; the foot is a simulated inertia on a torsional spring and
  damper.
* :func:`pump_accumulator` — a pump-controlled pair of cylinders (the HAFO's actuator) with a
  gas accumulator on the pump's line a.
* :func:`spring_return` — a single-acting cylinder with spring return on an ankle lever,
  pump-driven from a vented tank: a plantarflexion-only assist.
* :func:`pump_accumulator_gait`, :func:`spring_return_gait` — the same sized for walking
  (:data:`GAIT_DRIVE`).
"""

from __future__ import annotations

from afo_mj.circuits.circuit import Circuit


def _drive(motor=None, battery=True):
    comps = {"motor": {"kind": "motor", "params": motor or {
        "motor.resistance_ohm": 0.6, "motor.inductance_h": 1e-4,
        "motor.torque_constant_nm_a": 0.055, "motor.rotor_inertia_kg_m2": 5e-7,
        "motor.coulomb_torque_nm": 0.004, "motor.viscous_coefficient_nm_s_rad": 2e-6,
        "driver.current_limit_a": 6.2}},
        "pump": {"kind": "pump"}}
    nodes = {"shaft": ["motor.shaft", "pump.shaft"]}
    if battery:
        comps["battery"] = {"kind": "battery", "params": {
            "battery.capacity_ah": 3.0, "battery.internal_resistance_ohm": 0.10}}
        nodes["bus"] = ["battery.bus", "motor.bus"]
    else:
        nodes["bus"] = ["motor.bus"]
    return comps, nodes


def lab_bench(overrides: dict | None = None) -> Circuit:
    """The lab ankle bench (issue 18 item 8a). Pump line a → hose → cylinder chamber a
    (plantarflexion), line b likewise; check valves from the 0.3 MPa charge reservoir into
    each pump line; a relief valve each way across the pump."""
    comps, nodes = _drive(battery=False)
    comps.update({
        "port_a": {"kind": "volume"}, "port_b": {"kind": "volume"},
        "hose_a": {"kind": "hose", "params": {"length_m": 0.5, "bore_m": 3.2e-3,
                                              "wall_bulk_modulus_pa": 1.5e9}},
        "hose_b": {"kind": "hose", "params": {"length_m": 0.5, "bore_m": 3.2e-3,
                                              "wall_bulk_modulus_pa": 1.5e9}},
        "charge": {"kind": "reservoir", "params": {"pressure_pa": 0.3e6}},
        "check_a": {"kind": "check_valve"}, "check_b": {"kind": "check_valve"},
        "relief_ab": {"kind": "relief_valve", "params": {"cracking_dp_pa": 10e6,
                                                         "max_area_m2": 1e-6}},
        "relief_ba": {"kind": "relief_valve", "params": {"cracking_dp_pa": 10e6,
                                                         "max_area_m2": 1e-6}},
        "cylinder": {"kind": "pulley_cylinders", "params": {
            "count": 1.0, "pulley_radius_m": 0.04, "cylinder.bore_m": 12e-3,
            "cylinder.rod_diameter_m": 2e-3, "cylinder.stroke_m": 0.06,
            "cylinder.dead_volume_a_m3": 0.4e-6, "cylinder.dead_volume_b_m3": 0.6e-6}},
    })
    nodes.update({
        "line_a": ["pump.a", "port_a.port", "hose_a.a", "check_a.b", "relief_ab.a",
                   "relief_ba.b"],
        "line_b": ["pump.b", "port_b.port", "hose_b.a", "check_b.b", "relief_ab.b",
                   "relief_ba.a"],
        "tank": ["charge.port", "check_a.a", "check_b.a"],
        "chamber_a": ["hose_a.b", "cylinder.a"],
        "chamber_b": ["hose_b.b", "cylinder.b"],
        "ankle": ["cylinder.joint"],
    })
    spec = {"name": "lab_bench", "components": comps, "nodes": nodes,
            "controller": {"kind": "open_loop"},
            "options": {"initial_pressure_pa": 0.3e6, "supply_voltage_v": 24.0}}
    return Circuit.from_dict(_merge(spec, overrides))


def pump_accumulator(overrides: dict | None = None) -> Circuit:
    """Pump-controlled HAFO actuator (two piston-cable cylinders on a 40 mm pulley) with a
    10 cm³ gas accumulator precharged to 1 MPa abs on pump line a (issue 18 item 8b);
    battery-powered, torque-controlled."""
    comps, nodes = _drive()
    comps.update({
        "port_a": {"kind": "volume"}, "port_b": {"kind": "volume"},
        "accumulator": {"kind": "gas_accumulator", "params": {
            "gas_volume_m3": 10e-6, "precharge_pressure_pa": 1.0e6, "max_pressure_pa": 16e6,
            "port_volume_m3": 0.2e-6}},
        "hose_a": {"kind": "hose", "params": {"length_m": 1.1, "bore_m": 3.2e-3,
                                              "wall_bulk_modulus_pa": 1.5e9}},
        "hose_b": {"kind": "hose", "params": {"length_m": 1.1, "bore_m": 3.2e-3,
                                              "wall_bulk_modulus_pa": 1.5e9}},
        "charge": {"kind": "reservoir", "params": {"pressure_pa": 1.5e6}},
        "check_a": {"kind": "check_valve"}, "check_b": {"kind": "check_valve"},
        "relief_ab": {"kind": "relief_valve", "params": {"cracking_dp_pa": 14e6,
                                                         "max_area_m2": 1e-6}},
        "relief_ba": {"kind": "relief_valve", "params": {"cracking_dp_pa": 14e6,
                                                         "max_area_m2": 1e-6}},
        "cylinders": {"kind": "pulley_cylinders", "params": {
            "count": 2.0, "pulley_radius_m": 0.04, "cylinder.bore_m": 10.4e-3,
            "cylinder.rod_diameter_m": 2e-3, "cylinder.stroke_m": 0.045,
            "cylinder.dead_volume_a_m3": 0.3e-6, "cylinder.dead_volume_b_m3": 0.3e-6}},
    })
    nodes.update({
        "line_a": ["pump.a", "port_a.port", "accumulator.port", "hose_a.a", "check_a.b",
                   "relief_ab.a", "relief_ba.b"],
        "line_b": ["pump.b", "port_b.port", "hose_b.a", "check_b.b", "relief_ab.b",
                   "relief_ba.a"],
        "tank": ["charge.port", "check_a.a", "check_b.a"],
        "chamber_a": ["hose_a.b", "cylinders.a"],
        "chamber_b": ["hose_b.b", "cylinders.b"],
        "ankle": ["cylinders.joint"],
    })
    spec = {"name": "pump_accumulator", "components": comps, "nodes": nodes,
            "controller": {"kind": "pump_torque", "motor": "motor", "pump": "pump",
                           "actuator": "cylinders"},
            "options": {"initial_pressure_pa": 1.5e6}}
    return Circuit.from_dict(_merge(spec, overrides))


def spring_return(overrides: dict | None = None) -> Circuit:
    """Single-acting cylinder with spring return on a 50 mm ankle lever (issue 18 item 8c):
    the pump draws from a vented tank through a check valve and pushes into the cylinder;
    reversing the pump drains it back; relief to tank."""
    comps, nodes = _drive()
    comps.update({
        "port_p": {"kind": "volume"}, "port_s": {"kind": "volume"},
        "hose": {"kind": "hose", "params": {"length_m": 1.0, "bore_m": 3.2e-3,
                                            "wall_bulk_modulus_pa": 1.5e9}},
        "tank": {"kind": "reservoir", "params": {"pressure_pa": 0.0}},
        "makeup": {"kind": "check_valve"},
        "relief": {"kind": "relief_valve", "params": {"cracking_dp_pa": 12e6,
                                                      "max_area_m2": 1e-6}},
        "cylinder": {"kind": "spring_return_cylinder"},
    })
    nodes.update({
        "line": ["pump.a", "port_p.port", "hose.a", "relief.a", "makeup.b"],
        "suction": ["pump.b", "port_s.port"],
        "vent": ["tank.port", "relief.b", "makeup.a"],
        "chamber": ["hose.b", "cylinder.a"],
        "ankle": ["cylinder.joint"],
    })
    # the suction port draws from the tank, and takes the oil back when the pump reverses,
    # through a short open suction line (a check valve there dead-heads the reversed pump:
    # the chamber could not be drained and the suction port pumped up to 22 MPa in gait)
    comps["inlet"] = {"kind": "hose", "params": {"length_m": 0.1, "bore_m": 4e-3,
                                                 "wall_bulk_modulus_pa": 1.5e9}}
    nodes["vent"].append("inlet.a")
    nodes["suction"].append("inlet.b")
    spec = {"name": "spring_return", "components": comps, "nodes": nodes,
            "controller": {"kind": "pump_torque", "motor": "motor", "pump": "pump",
                           "actuator": "cylinder"}}
    return Circuit.from_dict(_merge(spec, overrides))


#: What sizes a pump-controlled circuit for walking (as the HAFO's ``hafo_gait`` preset,
#: :data:`afo_mj.devices.hafo.HAFO_GAIT`): with the 0.2 cm³/rev pump the flow feedforward
#: asks 215 pump rad/s per ankle rad/s, so at push-off (≈ 4 rad/s) the motor's EMF passes the
#: 22 V bus and the pump brakes the ankle at the relief pressure (measured on
#: pump_accumulator, 40 N·m Zhang profile: delivered −30 … +99 N·m, tracking RMSE 43.5 N·m).
#: A 0.6 cm³/rev pump (72 rad/s per ankle rad/s), an 18.6 A driver and a 0.2 Ω motor keep the
#: 65 N·m-class stall at the same pressure; 4.2 mm hoses keep the line loss per hose at three
#: times the flow. The pressure loop gains are raised (k_p 4e-5 rad/s/Pa, k_i 1e-3):
#: an accumulator on the line, or a single chamber, is a far larger compliance than the
#: HAFO's closed pair, and the HAFO's gains left a 10 bar error through push-off.
GAIT_DRIVE = {
    "components": {
        "pump": {"kind": "pump", "params": {"displacement_m3_rev": 0.6e-6,
                                            "rotor_inertia_kg_m2": 6e-7}},
        "motor": {"kind": "motor", "params": {
            "motor.resistance_ohm": 0.2, "motor.inductance_h": 0.05e-3,
            "motor.rotor_inertia_kg_m2": 1.2e-6, "driver.current_limit_a": 18.6}},
        "battery": {"kind": "battery", "params": {"battery.max_current_a": 30.0}}},
    "controller": {"params": {"pressure_gain_rad_s_per_pa": 4e-5,
                              "pressure_integral_gain_rad_per_pa": 1e-3}},
}


def pump_accumulator_gait(overrides: dict | None = None) -> Circuit:
    """:func:`pump_accumulator` sized for walking (:data:`GAIT_DRIVE`, 4.2 mm hoses)."""
    hose = {"kind": "hose", "params": {"bore_m": 4.2e-3}}
    gait = _merge(GAIT_DRIVE, {"name": "pump_accumulator_gait",
                               "components": {"hose_a": hose, "hose_b": hose}})
    return pump_accumulator(_merge(gait, overrides))


def spring_return_gait(overrides: dict | None = None) -> Circuit:
    """:func:`spring_return` sized for walking (:data:`GAIT_DRIVE`, a 4.2 mm hose), its piston
    at 16 mm at the neutral ankle so that the 40 mm stroke spans −0.46 … +0.32 rad (the
    10 mm of :func:`spring_return` puts the retracted stop at +0.2 rad, inside the walker's
    dorsiflexion: −270 N·m on the stop in gait), and the return spring compensated by the
    controller (``spring_feedforward = 1``: zero command is transparent)."""
    gait = _merge(GAIT_DRIVE, {
        "name": "spring_return_gait",
        "components": {"hose": {"kind": "hose", "params": {"bore_m": 4.2e-3}},
                       "cylinder": {"kind": "spring_return_cylinder",
                                    "params": {"neutral_position_m": 0.016}}},
        "controller": {"params": {"spring_feedforward": 1.0}}})
    return spring_return(_merge(gait, overrides))


def _merge(spec: dict, overrides: dict | None) -> dict:
    if not overrides:
        return spec
    out = dict(spec)
    for k, v in overrides.items():
        if isinstance(v, dict) and isinstance(out.get(k), dict):
            out[k] = _merge(out[k], v)
        else:
            out[k] = v
    return out


LIBRARY = {"lab_bench": lab_bench, "pump_accumulator": pump_accumulator,
           "spring_return": spring_return, "pump_accumulator_gait": pump_accumulator_gait,
           "spring_return_gait": spring_return_gait}
