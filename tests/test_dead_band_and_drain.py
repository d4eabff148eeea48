"""Optional circuit terms against analytic references: the cable's dead band
(``PulleyCylinders.backlash_rad``, the dead-zone model of Nordin & Gutman, Automatica 38
(2002) 1633, with the pistons as a mass of their own: a piston crossing the gap under a
constant pressure difference against Coulomb friction is uniformly accelerated), a drain
to the tank and a check valve's seat leakage (laminar, Merritt §3.2), and that
a description without them generates the code it generated before.
"""

from __future__ import annotations

import numpy as np

R_PULLEY = 0.04
PLAY_RAD = 0.02


def _sealed_pulley_with_play():
    """One piston-cable cylinder on a 40 mm pulley between two rigid 2 cm³ volumes (no pump,
    no seal friction, no stops, no leakage), air-free oil at 5 MPa, a rigid cable with a
    play of 0.02 rad at the pulley."""
    from afo_mj.circuits.circuit import Circuit, CircuitOptions
    from afo_mj.circuits.codegen import build
    from afo_mj.circuits.components import PulleyCylinders, Volume, VolumeParams
    from afo_mj.circuits.controllers import OpenLoop
    from afo_mj.hydraulics.cylinder import CylinderParams
    from afo_mj.hydraulics.fluid import FluidParams

    cyl = CylinderParams(internal_leakage_enabled=False, end_stops_enabled=False,
                         seal_friction_enabled=False)
    comp = PulleyCylinders("cylinders", PulleyCylinders.Params(
        cylinder=cyl, count=1.0, pulley_radius_m=R_PULLEY, backlash_rad=PLAY_RAD))
    comps = [comp, Volume("vol_a", VolumeParams(volume_m3=2e-6)),
             Volume("vol_b", VolumeParams(volume_m3=2e-6))]
    nodes = {"chamber_a": ["cylinders.a", "vol_a.port"],
             "chamber_b": ["cylinders.b", "vol_b.port"], "ankle": ["cylinders.joint"]}
    fluid = FluidParams(entrained_air_enabled=False)
    cc = build(Circuit("dead_band_check", comps, nodes, OpenLoop(), fluid=fluid,
                       options=CircuitOptions(initial_pressure_pa=5e6)))
    return cc, comp, cyl, float(fluid.liquid_bulk_modulus_pa)


def test_dead_band_carries_no_torque_inside_the_gap_and_the_oil_spring_outside():
    """The joint turned slowly from the middle of the gap (θ̇ constant, 1 ms steps) with the
    chambers sealed. The dead-zone model, ``F = k dz(δ)``: while ``|r θ| < β = b r/2`` the
    pistons stay where they are (no seal friction, equal pressures: nothing moves them) and
    the slack cable carries nothing (the chambers keep their 5 MPa, no joint torque); past
    the edge the pistons follow the pulley less the play, ``x − x_0 = −(r θ − β)``, and the
    linear chambers give ``Δp = A S (r θ − β)``, ``S = 1/C_a + 1/C_b``, the torque
    ``τ = −r A Δp``. The pistons' travel (probe) is the kinematic one plus the play taken
    up."""
    from afo_mj.circuits.device import CircuitDevice

    cc, comp, cyl, b = _sealed_pulley_with_play()
    h, n_steps = 1e-3, 1000
    theta_end = 0.5 * PLAY_RAD + 0.0015           # 1.5 mrad beyond the half play
    th = np.linspace(0.0, theta_end, n_steps + 1)
    thd = np.full(n_steps + 1, theta_end / (n_steps * h))
    dev = CircuitDevice(cc, timestep_s=h)
    log = dev.run_imposed(np.zeros(n_steps), th, thd)
    theta = th[1:]
    tau = log["torque_nm"]
    dp = log["chamber_a"] - log["chamber_b"]
    area = comp.torque_per_pa() / R_PULLEY
    beta = 0.5 * PLAY_RAD * R_PULLEY
    inside = R_PULLEY * theta < 0.8 * beta
    outside = R_PULLEY * theta > beta + 0.2 * (R_PULLEY * theta_end - beta)
    assert inside.sum() > 500 and outside.sum() > 100
    # inside: no transmitted force (the rounded edge leaves the slack cable below 1 mN here)
    assert np.max(np.abs(tau[inside])) < R_PULLEY * 1e-3
    assert np.max(np.abs(dp[inside])) < 1e-3 / area
    # outside: the oil spring on the travel past the edge
    x = 0.5 * cyl.stroke_m - (R_PULLEY * theta - beta)
    ca = (2e-6 + cyl.dead_volume_a_m3 + area * x) / b
    cb = (2e-6 + cyl.dead_volume_b_m3 + area * (cyl.stroke_m - x)) / b
    dp_ref = area * (1.0 / ca + 1.0 / cb) * (R_PULLEY * theta - beta)
    assert dp_ref[outside].max() > 5e5                        # a stiff spring past the edge
    np.testing.assert_allclose(dp[outside], dp_ref[outside], rtol=5e-3,
                               atol=2e-3 * dp_ref[outside].max())
    np.testing.assert_allclose(tau[outside], -R_PULLEY * area * dp[outside], rtol=1e-9)
    xp = log["cylinders.piston_position_m"]
    np.testing.assert_allclose(xp[outside], x[outside], atol=1e-7)
    np.testing.assert_allclose(xp[inside], 0.5 * cyl.stroke_m, atol=1e-7)
    led = dev.ledger()
    assert abs(led["balance_error_rel"]) < 1e-6, led


def test_free_load_coasts_through_the_gap():
    """A free inertia (1 kg m², no spring, no damper) thrown at 0.5 rad/s from the middle of
    the gap:
    inside the dead band nothing holds it (it coasts at its speed: ``θ = θ̇_0 t``), at the
    edge the sealed oil throws it back (no friction: an elastic bounce), and it recrosses
    the whole gap at the same speed the other way (``b/θ̇_0`` = 40 ms)."""
    from afo_mj.circuits.device import CircuitDevice, JointLoad

    cc, _, _, _ = _sealed_pulley_with_play()
    h, n = 1e-3, 120
    w0 = 0.5
    dev = CircuitDevice(cc, timestep_s=h / 4)
    zeros = np.zeros(n + 1)
    log = dev.run_imposed(np.zeros(n), zeros, zeros, substeps=4,
                          load=JointLoad(1.0, initial_velocity_rad_s=w0))
    t = (np.arange(n) + 1) * h
    theta, w = log["angle_rad"], log["velocity_rad_s"]
    first = t < 0.8 * (0.5 * PLAY_RAD) / w0                   # before the edge
    np.testing.assert_allclose(w[first], w0, rtol=1e-3)
    np.testing.assert_allclose(theta[first], w0 * t[first], rtol=2e-3)
    back = (theta < 0.4 * PLAY_RAD) & (theta > -0.4 * PLAY_RAD) & (w < 0.0)
    assert back.sum() > 20                       # it came back through the gap
    # coasting again: a constant speed (the backward-Euler bounce at the edge dissipates
    # some of the energy, so less than w0), the gap crossed at that speed
    w_back = float(np.mean(w[back]))
    np.testing.assert_allclose(w[back], w_back, rtol=1e-3)
    assert -w0 < w_back < -0.5 * w0
    np.testing.assert_allclose(np.diff(theta[back]), w_back * h, rtol=2e-3)


def test_piston_crosses_the_gap_uniformly_accelerated():
    """The joint held at 0, the chambers on two reservoirs (1.2 and 1.0 MPa), the piston at
    rest in the middle of a 0.1 rad play (β = 2 mm of travel on the 40 mm pulley), its seals
    pure Coulomb friction ``F_C`` (no breakaway peak, no viscous or pressure part). While the
    cable is slack the piston is a mass under a constant net force: ``m ẍ = A Δp − F_C``, so
    ``v = a t`` and ``δ = a t²/2`` with ``a = (A Δp − F_C)/m`` until ``δ = β``
    (uniformly accelerated motion; backward Euler's ``δ`` is ahead by ``a h t/2``), the
    joint feels nothing meanwhile, the seals turn ``F_C δ`` into heat and the oil's work
    ``A Δp δ`` is that plus the kinetic energy ``½ m v²``. Then the cable takes the piston:
    at rest against the edge it passes the whole ``A Δp`` to the pulley, ``τ = −r A Δp``."""
    from afo_mj.circuits.circuit import Circuit
    from afo_mj.circuits.codegen import build
    from afo_mj.circuits.components import PulleyCylinders, Reservoir, ReservoirParams
    from afo_mj.circuits.controllers import OpenLoop
    from afo_mj.circuits.device import CircuitDevice
    from afo_mj.hydraulics.cylinder import CylinderParams
    from afo_mj.hydraulics.seal import OringSealParams, cylinder_seal_law_args, seal_law_args

    play, mass, p_a, p_b = 0.1, 0.08, 1.2e6, 1.0e6
    seal = dict(stribeck_enabled=False, viscous_enabled=False, breakaway_velocity_m_s=1e-4)
    cyl = CylinderParams(bore_m=16e-3, rod_diameter_m=3e-3, stroke_m=0.05,
                         piston_mass_kg=mass, internal_leakage_enabled=False,
                         end_stops_enabled=False,
                         piston_seal=OringSealParams(**seal),
                         rod_seal=OringSealParams(cross_section_m=1e-3, **seal))
    comp = PulleyCylinders("cyl", PulleyCylinders.Params(
        cylinder=cyl, pulley_radius_m=R_PULLEY, backlash_rad=play))
    comps = [comp, Reservoir("res_a", ReservoirParams(pressure_pa=p_a)),
             Reservoir("res_b", ReservoirParams(pressure_pa=p_b))]
    nodes = {"a": ["cyl.a", "res_a.port"], "b": ["cyl.b", "res_b.port"],
             "ankle": ["cyl.joint"]}
    cc = build(Circuit("gap_crossing", comps, nodes, OpenLoop()))
    # the seals' Coulomb level: one piston seal and two cable seals (the model's input)
    f_c = cylinder_seal_law_args(seal_law_args(cyl.piston_seal, cyl.bore_m),
                                 seal_law_args(cyl.rod_seal, cyl.rod_diameter_m), 2)[0]
    area = cyl.area_a_m2
    acc = (area * (p_a - p_b) - f_c) / mass
    beta = 0.5 * play * R_PULLEY
    t_cross = np.sqrt(2.0 * beta / acc)
    assert f_c > 3.0 and 1e-3 < t_cross < 1e-2
    h, n = 1e-5, int(2.0 * t_cross / 1e-5)
    dev = CircuitDevice(cc, timestep_s=h)
    zeros = np.zeros(n + 1)
    log = dev.run_imposed(np.zeros(n), zeros, zeros)
    t = (np.arange(n) + 1) * h
    delta = log["cyl.piston_position_m"] - 0.5 * cyl.stroke_m
    v = log["cyl.piston_speed_m_s"]
    slack = delta < 0.9 * beta
    assert 0.8 * t_cross < t[slack][-1] < t_cross
    np.testing.assert_allclose(v[slack], acc * t[slack], rtol=2e-3, atol=1e-3 * acc * h)
    np.testing.assert_allclose(delta[slack], 0.5 * acc * t[slack] ** 2,
                               rtol=0, atol=acc * h * t_cross)
    assert np.max(np.abs(log["torque_nm"][slack])) < 1e-3 * R_PULLEY * area * (p_a - p_b)
    # the energy of the crossing, at its last slack sample
    k = int(np.flatnonzero(slack)[-1])
    dev2 = CircuitDevice(cc, timestep_s=h)
    dev2.run_imposed(np.zeros(k + 1), zeros[:k + 2], zeros[:k + 2])
    led = dev2.ledger()
    d_k = delta[k]
    assert abs(led["losses_j"]["cyl.seal_friction"] - f_c * d_k) < 2e-3 * f_c * d_k
    oil = area * (p_a - p_b) * d_k
    kinetic = led["stored_change_j"]["state.cyl.piston_speed_m_s"]
    assert abs(kinetic - 0.5 * mass * v[k] ** 2) < 2e-2 * 0.5 * mass * v[k] ** 2
    assert abs(led["residual_j"]) < 1e-9 * oil, led
    # taken up: at rest on the edge, the cable passes the whole pressure force
    end = t > 1.7 * t_cross
    np.testing.assert_allclose(log["torque_nm"][end], -R_PULLEY * area * (p_a - p_b),
                               rtol=1e-3)
    np.testing.assert_allclose(v[end], 0.0, atol=1e-3 * acc * t_cross)
    assert abs(dev.ledger()["residual_j"]) < 1e-9 * area * (p_a - p_b) * beta


def _leaky_volume():
    """A 10 cm³ volume of air-free oil at 2 MPa with a drain to the tank, and beside it a
    second volume fed from a 1 MPa reservoir through a check valve that cracks at 5 MPa
    (shut throughout) with a leaking seat."""
    from afo_mj.circuits.circuit import Circuit, CircuitOptions
    from afo_mj.circuits.codegen import build
    from afo_mj.circuits.components import (
        CheckValve, CheckValveParams, Drain, DrainParams, PulleyCylinders, Reservoir,
        ReservoirParams, Volume, VolumeParams)
    from afo_mj.circuits.controllers import OpenLoop
    from afo_mj.hydraulics.cylinder import CylinderParams
    from afo_mj.hydraulics.fluid import FluidParams

    cyl = CylinderParams(internal_leakage_enabled=False, end_stops_enabled=False,
                         seal_friction_enabled=False)
    comps = [PulleyCylinders("cylinders", PulleyCylinders.Params(cylinder=cyl)),
             Volume("vol_a", VolumeParams(volume_m3=1e-5)),
             Volume("vol_b", VolumeParams(volume_m3=1e-5)),
             Drain("drain", DrainParams(conductance_m3=2e-16)),
             Reservoir("charge", ReservoirParams(pressure_pa=1e6)),
             CheckValve("check", CheckValveParams(cracking_pa=5e6, seat_leakage_m3=1e-16))]
    nodes = {"a": ["cylinders.a", "vol_a.port", "drain.port"],
             "b": ["cylinders.b", "vol_b.port", "check.b"], "tank": ["charge.port", "check.a"],
             "ankle": ["cylinders.joint"]}
    fluid = FluidParams(entrained_air_enabled=False)
    return build(Circuit("drain_check", comps, nodes, OpenLoop(), fluid=fluid,
                         options=CircuitOptions(initial_pressure_pa=2e6))), fluid, cyl


def test_drain_and_seat_leakage_relax_their_nodes_exponentially():
    """Laminar leaks from a sealed node: ``C ṗ = −(G/μ)(p − p_∞)`` with ``C = V/B``, so
    ``p − p_∞`` decays as ``exp(−G t/(μ C))``: the drained node towards 0 gauge, the node
    behind the leaking check-valve seat towards the reservoir's 1 MPa (μ at the circuit's
    ambient temperature; the joint held still)."""
    from afo_mj.circuits.device import CircuitDevice
    from afo_mj.hydraulics.fluid import Fluid

    cc, fluid, cyl = _leaky_volume()
    h, n = 1e-3, 2000
    dev = CircuitDevice(cc, timestep_s=h)
    zeros = np.zeros(n + 1)
    log = dev.run_imposed(np.zeros(n), zeros, zeros)
    mu = Fluid(fluid).dynamic_viscosity_pa_s(float(cc.circuit.thermal.ambient_temperature_k))
    t = (np.arange(n) + 1) * h
    area = cyl.area_a_m2
    for node, g, vol, p_inf in (("a", 2e-16, 1e-5 + cyl.dead_volume_a_m3
                                 + area * 0.5 * cyl.stroke_m, 0.0),
                                ("b", 1e-16, 1e-5 + cyl.dead_volume_b_m3
                                 + area * 0.5 * cyl.stroke_m, 1e6)):
        c = vol / float(fluid.liquid_bulk_modulus_pa)
        ref = p_inf + (2e6 - p_inf) * np.exp(-g * t / (mu * c))
        assert ref[-1] < 2e6 - 0.2 * (2e6 - p_inf)               # a fifth of the way or more
        np.testing.assert_allclose(log[node], ref, rtol=0, atol=2e-3 * (2e6 - p_inf))
    # no input and no joint work: what the leaks throttled is what the oil's stores gave
    led = dev.ledger()
    assert abs(led["residual_j"]) < 1e-9 * led["losses_j"]["drain.drain"], led
    assert led["losses_j"]["drain.drain"] > 0.0


def test_optional_terms_leave_a_description_without_them_unchanged():
    """A term whose value is 0 is not built (the generated text is the one without it); a
    circuit built with its optional terms has them, at 0, and a drain at 0 on each pump port
    node that feeds a check valve."""
    from afo_mj.circuits.codegen import generate
    from afo_mj.devices.registry import device_spec

    circ = device_spec("lab_bench").circuit
    text, g, _ = generate(circ)
    assert not any(k in lab for lab in g.P_labels for k in ("backlash", "seat_leak", "drain"))
    opt = circ.with_optional_terms()
    text2, g2, _ = generate(opt)
    labels = dict(zip(g2.P_labels, g2.P))
    assert labels["cylinder.backlash"] == 0.0
    assert labels["check_a.seat_leak"] == 0.0 and labels["check_b.seat_leak"] == 0.0
    drains = [c.name for c in opt.components if c.kind == "drain"]
    assert drains == ["pump_drain_a", "pump_drain_b"]
    assert all(labels[f"{d}.conductance"] == 0.0 for d in drains)
    # the plain description is untouched
    assert not circ.optional_terms and generate(circ)[0] == text
