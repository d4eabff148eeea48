"""``afo-mj hydraulics-demo`` on the library's lab bench circuit (the generated stepper; its
accuracy against a hand-written Radau reference is tests/test_circuit_accuracy.py), its energy
chain, its input checks, and named parameters of a composite device."""

import math

import numpy as np
import pytest

from afo_mj.app.hydraulics_demo import DEMO_LOAD, hydraulics_demo
from afo_mj.circuits.device import CircuitDevice
from afo_mj.circuits.library import lab_bench
from afo_mj.devices.hafo import HAFO
from afo_mj.hydraulics import ParameterError, effect_switches, flatten, replace_named


@pytest.fixture(scope="module")
def demo():
    return hydraulics_demo(0.6)


def test_energy_chain_closes_and_names_the_chain_losses(demo):
    """Electrical input = load output + named losses + stored change, to round-off; the chain's
    main losses are present and none is negative."""
    e = demo["energy"]
    assert e["input_j"] > 0.5
    total = e["output_j"] + sum(e["heat_j"].values()) + e["stored_change_j"]
    assert total == pytest.approx(e["input_j"], rel=1e-8)
    assert abs(e["relative_residual"]) < 1e-8
    assert all(v >= -1e-12 for v in e["heat_j"].values())
    for name in ("motor.copper", "pump.mechanical", "hose_a.line", "cylinder.seal_friction"):
        assert e["heat_j"][name] > 1e-3 * e["input_j"], name


def test_energy_balance_detects_a_missing_loss(demo):
    """The balance is not tautological: leaving one named loss out of the sum breaks it."""
    e = demo["energy"]
    without = (e["output_j"] + e["stored_change_j"]
               + sum(v for k, v in e["heat_j"].items() if k != "hose_a.line"))
    assert abs(e["input_j"] - without) / e["input_j"] > 1e-2


def test_demo_motion_against_the_load_equation(demo):
    """The foot's angle stays where the cylinder's torque range can hold the load spring:
    ``|θ| ≤ max|τ| / k`` (the static bound of ``J θ̈ = τ − k θ − c θ̇`` for a 3 Hz drive
    well below the foot's 16 Hz natural frequency, with a 20 % allowance for its dynamics),
    and the chambers stay above the vapour floor and below the relief setting."""
    r = demo["ranges"]
    k, j = DEMO_LOAD["stiffness_nm_rad"], DEMO_LOAD["inertia_kg_m2"]
    assert math.sqrt(k / j) / 2 / math.pi > 5 * 3.0
    bound = demo["max_torque_nm"] / k
    assert max(abs(r["angle_rad"][0]), abs(r["angle_rad"][1])) <= 1.2 * bound
    assert max(abs(r["angle_rad"][0]), abs(r["angle_rad"][1])) > 0.5 * bound
    for key in ("chamber_a_gauge_pa", "chamber_b_gauge_pa"):
        assert -0.1e6 < r[key][0] < r[key][1] < 10e6


def test_substeps_converge(demo):
    """Four stepper steps per 1 ms sample change the pressure and torque ranges by < 2 %."""
    fine = hydraulics_demo(0.6, substeps=4)
    for key in ("chamber_a_gauge_pa", "chamber_b_gauge_pa", "torque_nm"):
        for a, b in zip(demo["ranges"][key], fine["ranges"][key]):
            assert a == pytest.approx(b, rel=0.02, abs=2e3 if "pa" in key else 0.02), key


@pytest.mark.parametrize("kwargs, match", [
    ({"duration_s": 0.0}, "duration_s"), ({"duration_s": float("nan")}, "duration_s"),
    ({"duration_s": 0.1, "substeps": 0}, "substeps"),
    ({"duration_s": 0.1, "substeps": 1.5}, "substeps")])
def test_bad_input_is_refused(kwargs, match):
    with pytest.raises(ValueError, match=match):
        hydraulics_demo(**kwargs)


def test_nan_command_is_reported():
    """A non-finite motor voltage stops the run with an error naming the step."""
    dev = CircuitDevice(lab_bench(), open_loop=True, torque_fn=lambda t, a, v: 0.0)
    cmd = np.full(20, 5.0)
    cmd[7] = float("nan")
    with pytest.raises(FloatingPointError, match="non-finite state at step"):
        dev.run_load(cmd, inertia_kg_m2=0.01)


def test_parameters_addressable_by_name_and_effects_switchable():
    p = HAFO
    names = flatten(p)
    assert names["cylinder.bore_m"] == pytest.approx(p.cylinder.bore_m)
    assert "cylinder.piston_seal.stribeck_enabled" in effect_switches(p)
    q = replace_named(p, {"cylinder.bore_m": 0.016, "pump.leakage_enabled": False,
                          "cylinder.piston_seal.coulomb_scale": 2.0})
    assert q.cylinder.bore_m == 0.016 and q.pump.leakage_enabled is False
    assert q.cylinder.piston_seal.coulomb_scale == 2.0 and p.cylinder.bore_m != 0.016
    with pytest.raises(ParameterError, match="bore_m"):
        replace_named(p, {"cylinder.bore_m": -1.0})
    with pytest.raises(ParameterError, match="no parameter 'pmup'"):
        replace_named(p, {"pmup.leakage_enabled": False})
    with pytest.raises(ParameterError, match="True or False"):
        replace_named(p, {"pump.leakage_enabled": 1})
