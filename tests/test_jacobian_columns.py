"""The stepper's partial re-evaluation of Jacobian columns (``rhs_columns``) against full
evaluations of the right-hand side (``rhs_step``) at the perturbed points, on every shipped
circuit kind: the two must agree bit for bit."""

from __future__ import annotations

import numpy as np
import pytest

from afo_mj.circuits import library
from afo_mj.circuits.device import CircuitDevice
from afo_mj.circuits.jacobian_columns import ColumnCodeError, column_function
from afo_mj.devices.hafo import HafoDevice
from afo_mj.devices.valve_afo import VALVE_PRESETS, valve_circuit, valve_initial_state

CIRCUITS = ["hafo", "lab_bench", "pump_accumulator", "spring_return", "valve",
            "valve_pressure_control", "valve_variable", "digital", "phafo"]


def _device(name: str) -> CircuitDevice:
    if name == "hafo":
        return HafoDevice(timestep_s=1e-3)
    if name in VALVE_PRESETS:
        p = VALVE_PRESETS[name]
        return CircuitDevice(valve_circuit(p), initial_state=valve_initial_state(p))
    return CircuitDevice(getattr(library, name)())


def _points(dev: CircuitDevice, rng, n: int):
    """``n`` states around the device's initial one (pressures 0.2–6 MPa, speeds and
    currents of either sign), each with an old state 1 % away and a joint motion."""
    k = dev.k
    kinds = dev.cc.state_kinds
    for _ in range(n):
        y = np.array(dev.Y[0], dtype=float)
        for j, kind in enumerate(kinds):
            if kind == "pressure":
                y[j] = rng.uniform(0.2e6, 6e6)
            else:
                y[j] += rng.normal() * k.Y_TYP[j]
        yo = y * (1.0 + 0.01 * rng.normal(size=y.shape))
        yield y, yo, rng.uniform(-0.3, 0.3), rng.uniform(-3.0, 3.0)


@pytest.mark.parametrize("name", CIRCUITS)
def test_columns_equal_full_evaluations_bit_for_bit(name):
    """Each state's column, the joint motion's column and the base point from
    ``rhs_columns`` are exactly what ``rhs_step`` gives at the same points."""
    dev = _device(name)
    k = dev.k
    n = k.N_Y
    P = np.array(dev.P[0])
    W = np.array(dev.W[0])
    k.begin_extra(dev.Y[0], P, W)                   # viscosity, density, bus voltage
    U = W[k.W_U:k.W_U + k.N_U]
    rng = np.random.default_rng(7)
    width = dev.S.shape[2]
    for y, yo, th, thd in _points(dev, rng, 12):
        U[k.U_CMD] = rng.uniform(-5.0, 5.0)
        D = 1e-7 * np.maximum(np.abs(y), k.Y_TYP)
        dy, F = np.zeros(n), np.zeros(width)
        C, T = np.zeros((n, n + 1)), np.zeros(n + 1)
        th2, thd2 = th + 1e-3 * (thd + 0.1), thd + 0.1
        k.rhs_columns(y, yo, th, thd, th2, thd2, U, P, dy, F, D, C, T, 1.0, 1.0)
        ref, Fr = np.zeros(n), np.zeros(width)
        k.rhs_step(y, yo, th, thd, U, P, ref, Fr)
        assert np.array_equal(dy, ref) and F[k.F_TAU] == Fr[k.F_TAU]
        for j in range(n):
            yp = y.copy()
            yp[j] = y[j] + D[j]
            k.rhs_step(yp, yo, th, thd, U, P, ref, Fr)
            assert np.array_equal(C[j, :n], ref), (name, dev.cc.state_names[j])
            assert C[j, n] == Fr[k.F_TAU], (name, dev.cc.state_names[j])
        k.rhs_step(y, yo, th2, thd2, U, P, ref, Fr)
        assert np.array_equal(T[:n], ref) and T[n] == Fr[k.F_TAU], name


def test_a_column_re_evaluates_only_what_its_state_reaches():
    """The HAFO's motor-current column touches the shaft and the winding only: no oil
    compliance, hose or valve is evaluated again (that is the saving)."""
    src = open(HafoDevice(timestep_s=1e-3).k.__file__).read()
    body = src[src.index("def rhs_columns("):]
    body = body[:body.index("\n\n")]
    i = HafoDevice(timestep_s=1e-3).cc.state_names.index("motor.current_a")
    block = body[body.index(f"yq{i} = "):]
    block = block[:block.index(f"C[{i}, ")]
    assert "oil_mean_compliance_per_pa" not in block and "hose_flow" not in block
    assert "dy0_c" in block                         # the shaft's torque balance is


def test_column_code_refuses_what_it_cannot_split():
    with pytest.raises(ColumnCodeError, match="assigned twice"):
        column_function(["a = y[0]", "a = y[1]", "dy[0] = a"], 1, "")
    with pytest.raises(ColumnCodeError, match="single assignment"):
        column_function(["if y[0] > 0:\n    dy[0] = 1.0"], 1, "")
