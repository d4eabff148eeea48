"""Generated circuits (issue 18): numerics against a tight-tolerance Radau solution of the same
circuit written out by hand (tests/circuit_reference.py), ledger closure, the parameters that
used to be silent, and the description errors."""

from __future__ import annotations

import numpy as np
import pytest
from circuit_reference import nrmse, reference_lab_bench

from afo_mj.circuits.circuit import Circuit
from afo_mj.circuits.codegen import build
from afo_mj.circuits.components import CircuitError
from afo_mj.circuits.device import CircuitDevice
from afo_mj.circuits.library import lab_bench, pump_accumulator, spring_return

STIFF = {"fluid": {"air_fraction": 0.01},
         "components": {"cylinder": {"kind": "pulley_cylinders", "params": {
             "count": 1.0, "pulley_radius_m": 0.04, "cylinder.bore_m": 12e-3,
             "cylinder.rod_diameter_m": 2e-3, "cylinder.stroke_m": 0.016,
             "cylinder.dead_volume_a_m3": 0.4e-6, "cylinder.dead_volume_b_m3": 0.6e-6}}}}


@pytest.mark.slow
def test_lab_bench_matches_radau_on_a_stiff_case_with_end_stops():
    """Sub-cm³ dead volumes, 1 % air at a 0.3 MPa charge, closed check valves, and a drive
    into the end stops (±0.2 rad of pulley travel): NRMSE ≤ 1 % at the 1 ms step."""
    circuit = lab_bench(STIFF)
    n = 1500

    def cmd_fn(t):
        return 10.0 if t < 0.5 else (-10.0 if t < 1.0 else 0.0)

    cmd = np.array([cmd_fn(k * 1e-3) for k in range(n)])
    dev = CircuitDevice(circuit)
    log = dev.run_load(cmd, inertia_kg_m2=0.01, stiffness_nm_rad=20.0, damping_nm_s_rad=0.3)
    ref = reference_lab_bench(circuit, cmd_fn, n * 1e-3, 0.01, 20.0, 0.3)
    # the drive reaches the stops (|θ| > s/(2r)) both ways
    assert ref.y[6].max() > 0.2 and ref.y[6].min() < -0.2
    # the 1 % on the motion, the pump speed and every pressure (measured: angle 0.04 %,
    # shaft 0.46 %, pressures 0.57-0.58 %; the pressures were 3 % off while a step's compression
    # of the aerated oil used the end-of-step compliance, see afo_mj.circuits.stepper)
    for key, row, tol in (("angle_rad", 6, 0.01), ("shaft", 1, 0.01), ("chamber_a", 4, 0.01),
                          ("chamber_b", 5, 0.01), ("line_a", 2, 0.01), ("line_b", 3, 0.01)):
        e = nrmse(log[key], ref.y[row])
        assert e < tol, (key, e)
    led = dev.ledger()
    assert abs(led["balance_error_rel"]) < 1e-9
    assert led["stored_change_j"]["cylinder.end_stops"] != 0.0


@pytest.mark.parametrize("make", [lab_bench, pump_accumulator, spring_return])
def test_new_circuits_close_their_ledger(make):
    circuit = make()
    dev = CircuitDevice(circuit)
    n = 800
    if circuit.controller.kind == "open_loop":
        cmd = 6.0 * np.sin(np.linspace(0, 4 * np.pi, n))
    else:
        cmd = -15.0 * np.sin(np.linspace(0, 2 * np.pi, n)) ** 2   # plantarflexion torque
    log = dev.run_load(cmd, inertia_kg_m2=0.02, stiffness_nm_rad=80.0, damping_nm_s_rad=0.5)
    led = dev.ledger()
    assert led["input_j"] > 0.0
    assert abs(led["balance_error_rel"]) < 1e-9, led
    assert np.all(np.isfinite(log["torque_nm"]))
    assert np.ptp(log["angle_rad"]) > 1e-3          # the circuit moved its load


def test_compiled_code_is_shared_by_parameter_sets():
    a = build(lab_bench())
    b = build(lab_bench({"components": {"hose_a": {"kind": "hose", "params": {
        "length_m": 2.0}}}}))
    assert a.source_path == b.source_path
    assert not np.array_equal(a.P, b.P)


def test_a_changed_law_gives_a_new_compiled_module():
    """numba's disk cache does not see a change in a function called from another file, so
    the generated text (whose hash names the cached module) carries the hash of the law,
    phase, impedance and buffer-view modules it calls: here recomputed from the files
    themselves."""
    import hashlib
    from pathlib import Path
    import afo_mj.circuits.buffer_views as v_mod
    import afo_mj.control.assistance as a_mod
    import afo_mj.control.impedance as i_mod
    import afo_mj.hydraulics.laws as l_mod
    from afo_mj.circuits.codegen import generate
    h = hashlib.sha256()
    for mod in (l_mod, a_mod, i_mod, v_mod):
        h.update(Path(mod.__file__).read_bytes())
    text, _, _ = generate(lab_bench())
    assert h.hexdigest()[:20] in text.splitlines()[1]


def _run(circuit, n=600):
    dev = CircuitDevice(circuit)
    cmd = np.full(n, 8.0)
    return dev.run_load(cmd, inertia_kg_m2=0.01, stiffness_nm_rad=60.0, damping_nm_s_rad=0.5)


def test_formerly_silent_parameters_change_results():
    base = _run(lab_bench())
    cyl = {"kind": "pulley_cylinders", "params": {
        "count": 1.0, "pulley_radius_m": 0.04, "cylinder.bore_m": 12e-3,
        "cylinder.rod_diameter_m": 2e-3, "cylinder.stroke_m": 0.06,
        "cylinder.dead_volume_a_m3": 0.4e-6, "cylinder.dead_volume_b_m3": 3e-6}}
    dead_b = _run(lab_bench({"components": {"cylinder": cyl}}))
    assert not np.allclose(dead_b["chamber_b"], base["chamber_b"], rtol=1e-6)
    stops = dict(cyl)
    stops["params"] = dict(cyl["params"], **{"cylinder.dead_volume_b_m3": 0.6e-6,
                                             "cylinder.stroke_m": 0.02,
                                             "cylinder.end_stops_enabled": False})
    with_stops = dict(stops)
    with_stops["params"] = dict(stops["params"], **{"cylinder.end_stops_enabled": True})
    a = _run(lab_bench({"components": {"cylinder": stops}}))
    b = _run(lab_bench({"components": {"cylinder": with_stops}}))
    assert np.max(np.abs(a["angle_rad"])) > 0.25 + 0.05      # past the stop without them
    assert np.max(np.abs(b["angle_rad"])) < 0.25 + 0.01      # held at s/(2r) with them
    # turbulent hoses: a thin long hose at high flow goes past Re 2000
    hose = {"kind": "hose", "params": {"length_m": 3.0, "bore_m": 1.5e-3,
                                       "turbulence_enabled": False}}
    lam = build(lab_bench({"components": {"hose_a": hose}}))
    turb = build(lab_bench({"components": {"hose_a": dict(hose, params=dict(
        hose["params"], turbulence_enabled=True))}}))
    i = lam.param_labels.index("hose_a.turbulent")
    assert lam.P[i] == 0.0 and turb.P[i] == 1.0


def test_battery_ocv_table_is_a_parameter():
    c1 = pump_accumulator()
    flat = (3.7,) * 12
    c2 = pump_accumulator({"components": {"battery": {"kind": "battery", "params": {
        "battery.ocv_cell_v": flat}}}})
    d1, d2 = CircuitDevice(c1), CircuitDevice(c2)
    cmd = np.full(300, -20.0)
    l1 = d1.run_load(cmd, inertia_kg_m2=0.02, stiffness_nm_rad=80.0)
    d2.run_load(cmd, inertia_kg_m2=0.02, stiffness_nm_rad=80.0)
    assert d1.ledger()["input_j"] != pytest.approx(d2.ledger()["input_j"], rel=1e-6)
    k = d1.k
    soc_pts = (0.0, 0.05, 0.10, 0.20, 0.30, 0.40, 0.50, 0.60, 0.70, 0.80, 0.90, 1.0)
    v_pts = (3.00, 3.45, 3.55, 3.62, 3.66, 3.70, 3.75, 3.81, 3.88, 3.96, 4.06, 4.20)
    v_oc = 6 * float(np.interp(d1.W[0, k.W_SOC], soc_pts, v_pts))
    # the bus voltage held for the next step: V_oc(SOC) − R I of the last step
    d1.k.begin_extra(d1.Y[0], d1.P[0], d1.W[0])
    assert d1.W[0, k.W_U + k.U_VBUS] == pytest.approx(v_oc - 0.10 * d1.W[0, k.W_I_BAT],
                                                       rel=1e-9)
    d2.k.begin_extra(d2.Y[0], d2.P[0], d2.W[0])
    assert d2.W[0, k.W_U + k.U_VBUS] < 6 * 3.7 + 1e-9
    assert np.isfinite(l1["torque_nm"]).all()


def test_seal_leakage_simulated_or_refused():
    cyl = {"kind": "pulley_cylinders", "params": {
        "cylinder.rod_seal.leakage_enabled": True}}
    with pytest.raises(CircuitError, match="rod_seal.leakage_enabled"):
        build(lab_bench({"components": {"cylinder": cyl}}))
    cyl = {"kind": "pulley_cylinders", "params": {
        "count": 1.0, "cylinder.stroke_m": 0.06,
        "cylinder.piston_seal.leakage_enabled": True}}
    cc = build(lab_bench({"components": {"cylinder": cyl}}))
    assert cc.P[cc.param_labels.index("cylinder.dragout_on")] == 1.0


# ---- description errors ----------------------------------------------------------------------

def _spec():
    return {"name": "t", "components": {
        "supply": {"kind": "reservoir", "params": {"pressure_pa": 1e6}},
        "hose": {"kind": "hose"},
        "cyl": {"kind": "spring_return_cylinder"}},
        "nodes": {"p": ["supply.port", "hose.a"], "c": ["hose.b", "cyl.a"],
                  "ankle": ["cyl.joint"]}}


def test_a_minimal_description_builds():
    dev = CircuitDevice(Circuit.from_dict(_spec()))
    dev.run_load(np.zeros(50), inertia_kg_m2=0.01, stiffness_nm_rad=10.0)
    assert abs(dev.ledger()["balance_error_rel"]) < 1e-9


@pytest.mark.parametrize("mutate, match", [
    (lambda s: s["nodes"].pop("c"), "not connected"),
    (lambda s: s["nodes"]["p"].append("nosuch.a"), "unknown component 'nosuch'"),
    (lambda s: s["nodes"]["p"].append("cyl.x"), "has no port 'x'"),
    (lambda s: s["components"].update(bad={"kind": "warp_drive"}), "warp_drive"),
    (lambda s: s["components"]["hose"].update(params={"colour": 3}), "colour"),
    (lambda s: s["nodes"].update(j2=["hose.a"]), "connected twice"),
    (lambda s: s["nodes"].update(p=["supply.port", "hose.a", "cyl.joint"]), "domains"),
])
def test_description_errors_name_the_problem(mutate, match):
    spec = _spec()
    mutate(spec)
    with pytest.raises(CircuitError, match=match):
        build(Circuit.from_dict(spec))


def test_node_without_capacitance_is_refused():
    spec = _spec()
    spec["components"]["cv"] = {"kind": "check_valve"}
    spec["components"]["cv2"] = {"kind": "check_valve"}
    spec["nodes"]["mid"] = ["cv.b", "cv2.a"]
    spec["nodes"]["p"] += ["cv.a"]
    spec["nodes"]["c"] += ["cv2.b"]
    with pytest.raises(CircuitError, match="node 'mid' has no capacitance"):
        build(Circuit.from_dict(spec))


def test_two_drives_are_refused():
    with pytest.raises(CircuitError, match="two drives"):
        lab_bench({"components": {"motor2": {"kind": "motor"}},
                   "nodes": {"bus": ["motor.bus", "motor2.bus"],
                             "shaft": ["motor.shaft", "pump.shaft", "motor2.shaft"]}})


def test_lu_factor_and_solve_match_numpy():
    """The stepper's LU factorisation (partial pivoting) and substitution, reused by the
    Newton correction's chord iterations, against numpy's solver on random and permuted
    systems (a zero leading pivot forces every row interchange)."""
    from afo_mj.circuits import stepper
    rng = np.random.default_rng(7)
    for n in range(1, 9):
        for trial in range(20):
            M = rng.normal(size=(n, n))
            if trial == 0 and n > 1:
                M[0, 0] = 0.0
            B = rng.normal(size=(n, 2))
            want = np.linalg.solve(M, B)
            LU, piv, got = M.copy(), np.zeros(n), B.copy()
            stepper.lu_factor(LU, piv, n)
            stepper.lu_solve(LU, piv, got, n, 2)
            np.testing.assert_allclose(got, want, rtol=1e-9, atol=1e-9 * np.abs(want).max())


def _stiff_device_with(monkeypatch, max_age):
    from afo_mj.circuits import stepper
    monkeypatch.setattr(stepper, "JAC_MAX_AGE", max_age)
    return CircuitDevice(build(lab_bench(STIFF)))


@pytest.mark.slow
def test_kept_prediction_matrix_leaves_the_converged_step_and_is_rebuilt(monkeypatch):
    """Issue 21: the prediction matrix kept across steps (a W-method) against the same stepper
    rebuilding it every step (``JAC_MAX_AGE = 1``, the method before). With the motion imposed
    the prediction only seeds Newton, so both give the same backward-Euler steps (within the
    Newton tolerance); with a simulated load it changes only the torque handed over within the
    step, so the motion agrees far inside the 1 % the Radau tests allow (measured: states 5e-11
    of their span imposed; NRMSE 1e-7 to 8e-7 loaded). The reuse must also be real: far
    fewer matrices built than steps (measured 357 of 1500)."""
    n = 1500
    t = np.arange(n + 1) * 1e-3
    th = 0.25 * np.sin(2 * np.pi * 1.5 * t)              # drives into both end stops
    thd = 0.25 * 2 * np.pi * 1.5 * np.cos(2 * np.pi * 1.5 * t)
    cmd = 8.0 * np.sin(2 * np.pi * 0.7 * t[:-1])
    logs, builds = {}, {}
    for age in (1, 10):
        dev = _stiff_device_with(monkeypatch, age)
        imposed = dev.run_imposed(cmd, th, thd)
        builds[age] = dev.ledger()["jacobian_builds"]
        dev2 = _stiff_device_with(monkeypatch, age)
        loaded = dev2.run_load(np.concatenate([cmd, -cmd]), inertia_kg_m2=0.01,
                               stiffness_nm_rad=20.0, damping_nm_s_rad=0.3)
        assert abs(dev2.ledger()["balance_error_rel"]) < 1e-9
        logs[age] = (imposed, loaded)
    assert builds[1] == n
    assert builds[10] < 0.5 * n
    for key in ("shaft", "line_a", "line_b", "chamber_a", "chamber_b"):
        a, b = logs[1][0][key], logs[10][0][key]
        scale = max(np.ptp(a), 1e-9)
        assert np.max(np.abs(a - b)) < 1e-8 * scale, key
    for key in ("angle_rad", "shaft", "chamber_a", "chamber_b"):
        a, b = logs[1][1][key], logs[10][1][key]
        assert nrmse(b, a) < 2e-5, (key, nrmse(b, a))
