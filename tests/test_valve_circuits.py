"""The valve presets as generated circuits (issue 18) against the old hand-written valve kernel.

Each preset runs in both on the same imposed ankle motion (θ̇ = 1.41 rad/s peak at 1.5 Hz,
θ_{n+1} = θ_n + h θ̇_{n+1}) with the same plantarflexion torque command (0 → −25 N·m → 0
over 0.4 s) through the coupled-device protocol (``begin_step``/``end_step``), and the
pressures, the end-of-step torque, the motor and the ledger totals are compared.

Exact equality is not expected; the new stepper and components differ on purpose:

1. the joint angle in ``rhs`` is the end-of-step angle ``θ_n + h θ̇_{n+1}`` (the old kernel
   held ``θ_n``): chamber volumes and so the pressures move by ~``A r θ̇ h`` a step;
2. the soft clips are true smooth min/max (:func:`~afo_mj.hydraulics.laws.soft_clip`); the
   old one overshot its limits by half its corner radius: the driver's voltage clamp by
   0.025 V, the on/off valves' travel rate by 2.5 %, the compensator's full stroke by 1 %;
3. the relief valve passes its seat leakage backwards too (the old one nothing);
4. the servo valve's edges use the library's centred corner
   (:func:`~afo_mj.hydraulics.laws.spool_edge_area_m2`, ± 1 % of the stroke), the old
   kernel a one-sided cubic over 2 %: the areas differ for openings under 2 %, where the
   valve sits while it holds a torque;
5. the cylinders count each cylinder's dead volume and piston leakage (the old kernel one
   cylinder's for the pair): +0.3 cm³ in each chamber node (≈ 4 % of its oil);
6. the orifices use the oil density at the oil's temperature (the old kernel the reference
   density: 0.7 % apart at 25 °C, 0.35 % in every orifice flow);
7. the servo supplies other than ``unloading`` have no unloading valve (the old kernel kept a
   shut one leaking ≈ 1e-8 m³/s to tank);
8. the step conserves oil (each node's compliance is its mean over the step,
   :func:`~afo_mj.hydraulics.laws.oil_mean_compliance_per_pa`; the old kernel the tangent one
   at the step's end): the pressures reach a threshold a step earlier or later, so a
   snap-action valve (the unloading valve's cut-out, the digital valves' switching) can
   switch 1 ms apart, and the pump outlet jumps by its whole span in that step.

The differences these make were measured (``python -m pytest tests/test_valve_circuits.py
-s`` prints them) and the tolerances below sit just above them; a regression in a component
or the assembly shows as a jump past them. The generated ledgers close to 1e-9.
"""

from __future__ import annotations

import numpy as np
import pytest

from afo_mj.circuits.codegen import build
from afo_mj.circuits.components import CircuitError
from afo_mj.circuits.device import CircuitDevice
from afo_mj.devices.valve_afo import VALVE_PRESETS, valve_circuit, valve_initial_state
from kernel_reference import valve_kernel as va
from kernel_reference.kernel_devices import ValveKernelDevice

H = 1e-3
N = 400
#: circuit state label → old kernel state index
STATES = {"chamber_a": va.Y_PCA, "chamber_b": va.Y_PCB, "port_a": va.Y_PVA,
          "port_b": va.Y_PVB, "rail": va.Y_PS, "pump_out": va.Y_PP, "shaft": va.Y_W,
          "motor.current_a": va.Y_I}


def _motion(n):
    t = np.arange(n + 1) * H
    v = 0.15 * 2 * np.pi * 1.5 * np.cos(2 * np.pi * 1.5 * t)
    th = np.zeros(n + 1)
    for k in range(n):
        th[k + 1] = th[k] + H * v[k + 1]
    return th, v


def _torque(t, th, thd):
    return -25.0 * np.sin(np.pi * t / 0.4) ** 2


def _run_both(params, n=N):
    th, v = _motion(n)
    old = ValveKernelDevice(params, torque_fn=_torque, timestep_s=H)
    new = CircuitDevice(valve_circuit(params), timestep_s=H, torque_fn=_torque)
    for label, value in valve_initial_state(params).items():
        new.Y[:, new.cc.index(label)] = value
    log = {k: np.zeros((n, 2)) for k in list(STATES) + ["tau", "tau_end"]}
    stance = np.zeros(2)
    for k in range(n):
        a2, v2, vn = (np.array([x, 0.0]) for x in (th[k], v[k], v[k + 1]))
        old.begin_step(k * H, a2, v2, stance)
        new.begin_step(k * H, a2, v2, stance)
        log["tau"][k] = old.end_step(vn)[0], new.end_step(vn)[0]
        log["tau_end"][k] = old.W[0, va.W_TAU_END], new.W[0, new.k.W_TAU_END]
        for label, i in STATES.items():
            log[label][k] = old.Y[0, i], new.Y[0, new.cc.index(label)]
    return old, new, log


def _nrmse(pair, upto=None):
    """RMS of new − old over the old signal's span."""
    old, new = pair[:upto, 0], pair[:upto, 1]
    return float(np.sqrt(np.mean((new - old) ** 2)) / max(np.ptp(old), 1e-30))


def _switches(x, frac=0.2):
    """Steps where ``x`` jumps by more than ``frac`` of its span in one step."""
    return np.flatnonzero(np.abs(np.diff(x)) > frac * max(np.ptp(x), 1e-30)) + 1


def _nrmse_between_switches(pair, window=4):
    """``_nrmse`` with ``window`` steps either side of every snap (a jump of a fifth of the
    span in one step, in either signal) left out, after checking that both signals snap at
    the same instants to within one step (item 8)."""
    so, sn = _switches(pair[:, 0]), _switches(pair[:, 1])
    assert len(so) == len(sn) and np.all(np.abs(so - sn) <= 1), (so, sn)
    keep = np.ones(pair.shape[0], bool)
    for k in np.concatenate([so, sn]):
        keep[max(k - window, 0):k + window + 1] = False
    return _nrmse(pair[keep])


#: per preset: NRMSE bounds (end-of-step torque, chamber and port pressures, rail, pump
#: outlet, motor speed), and the relative bounds on the input and mechanical energies.
#: Measured 2026-11-27 (servo presets: torque 0.5–0.8 %, chambers ≤ 0.33 %, input energy
#: ≤ 0.13 %, mechanical ≤ 0.85 %; see the module docstring for why they differ at all).
SERVO = dict(tau_end=0.01, chambers=0.005, rail=0.01, pump_out=0.01, shaft=0.012,
             input=2.5e-3, mech=0.012)
TOLERANCES = {
    "valve_accumulator": SERVO,
    "valve_pressure_control": SERVO,
    "valve_variable": SERVO,
    "phafo": SERVO,
    # the constant-speed pump without accumulator blows its whole surplus over the relief
    # valve: the motor speed barely moves (16 rad/s span), so its NRMSE is over a tiny span
    "valve_no_accumulator": dict(SERVO, shaft=0.08),
    # the motor's slow-down after the unloading valve's cut-out starts a step apart (item 8):
    # measured 3.7 % (0.8 % before item 8), and the input energy 0.25 %
    "valve": dict(SERVO, shaft=0.045, input=3.5e-3),
}
#: presets with an unloading valve (a snap-action cut-out)
UNLOADING = ("valve",)
FAST = ("valve",)


def _check_servo(name):
    params = VALVE_PRESETS[name]
    old, new, log = _run_both(params)
    tol = TOLERANCES[name]
    got = {"tau_end": _nrmse(log["tau_end"]),
           "chambers": max(_nrmse(log[k]) for k in ("chamber_a", "chamber_b", "port_a",
                                                   "port_b")),
           "rail": _nrmse(log["rail"]),
           # the unloading valve's cut-out can fall a step apart (item 8): its pump outlet is
           # compared between the snaps (measured for ``valve``, cut-out at step 183 vs 184:
           # 4.6 % over the whole run, 0.01 % between)
           "pump_out": (_nrmse_between_switches(log["pump_out"]) if name in UNLOADING
                        else _nrmse(log["pump_out"])),
           "shaft": _nrmse(log["shaft"])}
    lo, ln = old.ledger(), new.ledger()
    got["input"] = abs(ln["input_j"] / lo["electrical_in_j"] - 1.0)
    got["mech"] = abs(ln["mechanical_out_j"] / lo["mechanical_out_j"] - 1.0)
    print(name, {k: f"{v:.2e}" for k, v in got.items()},
          f"balance {ln['balance_error_rel']:.1e}")
    for key, bound in tol.items():
        assert got[key] < bound, (name, key, got[key], bound)
    assert abs(ln["balance_error_rel"]) <= 1e-9, ln
    # the same losses in the same places: throttling in the servo valve, the pump's and the
    # motor's losses (within the bounds of the input energy's)
    pairs = (("servo.throttling", "servo_valve_throttling"),
             ("motor.copper", "motor_copper"), ("pump.mechanical", "pump_mechanical"))
    for new_key, old_key in pairs:
        a, b = ln["losses_j"][new_key], lo["losses_j"][old_key]
        assert a == pytest.approx(b, rel=0.02, abs=0.01), (new_key, a, b)
    assert ln["losses_j"]["servo.coil"] == pytest.approx(lo["losses_j"]["valve_actuators"],
                                                         rel=1e-9)


@pytest.mark.parametrize("name", [pytest.param(n, marks=() if n in FAST else pytest.mark.slow)
                                  for n in TOLERANCES])
def test_servo_presets_match_the_old_kernel(name):
    _check_servo(name)


@pytest.mark.slow
def test_digital_preset_matches_the_old_kernel():
    """The digital circuit switches its valves by PWM with no accumulator: the torque is a
    50 Hz saw-tooth, and the closed loop's duty decisions make the small differences above
    grow once they change a switching instant. Over the first 150 ms the states agree to
    ~3 %; over the run they drift (measured: chamber NRMSE 9 %, input energy 1.3 %),
    asserted at that level. The torque handed to MuJoCo (the step's
    prediction) differs more than the end-of-step torque at the instants a valve starts to
    move (the linearisation sees the valve's opening differently), so the end-of-step torque
    is compared."""
    old, new, log = _run_both(VALVE_PRESETS["digital"])
    early = {k: _nrmse(log[k], 150) for k in ("tau_end", "chamber_a", "rail", "pump_out")}
    full = {k: _nrmse(log[k]) for k in ("tau_end", "chamber_a", "rail", "pump_out")}
    lo, ln = old.ledger(), new.ledger()
    rel_in = abs(ln["input_j"] / lo["electrical_in_j"] - 1.0)
    print("digital early", early, "full", full, "input", rel_in)
    # measured (2026-11-24, with the oil-conserving step, item 8): early 2.6 % (pump outlet
    # 3.4 %), full 6.7–9.3 %, input energy 1.3 %; before item 8: early 1.7 % (3.2 %),
    # full 5.7–7.4 %, input 3.5 %. The switching instants move by a step (item 8) and the
    # closed loop's later duty decisions follow them.
    for key, value in early.items():
        assert value < (0.04 if key == "pump_out" else 0.03), (key, value)
    for key, value in full.items():
        assert value < 0.105, (key, value)
    assert rel_in < 0.045
    assert abs(ln["balance_error_rel"]) <= 1e-9, ln


def test_valve_circuits_build_for_every_preset_with_their_components():
    kinds = {}
    for name, params in VALVE_PRESETS.items():
        circuit = valve_circuit(params)
        kinds[name] = {c.kind for c in circuit.components}
    assert "unloading_valve" in kinds["valve"]
    assert "unloading_valve" not in kinds["valve_accumulator"]
    assert "supply_accumulator" not in kinds["valve_no_accumulator"]
    assert "variable_pump" in kinds["valve_variable"]
    assert {"onoff_valve", "orifice"} <= kinds["digital"]
    assert "servo_valve" not in kinds["digital"]
    assert all("servo_valve" in kinds[n] for n in kinds if n != "digital")


def test_bad_valve_descriptions_are_refused():
    with pytest.raises(CircuitError, match="servo_coil_power_w"):
        valve_circuit(VALVE_PRESETS["digital"].replace(servo_coil_power_w=0.5))
    # a valve whose command no controller sets
    circuit = valve_circuit(VALVE_PRESETS["valve"])
    from afo_mj.circuits.controllers import OpenLoop
    circuit.controller = OpenLoop()
    with pytest.raises(CircuitError, match="servo.command.*driven by no controller"):
        build(circuit)
