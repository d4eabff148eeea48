"""Impedance emulation (:mod:`afo_mj.control.impedance`): the commanded torque against the
spring/damper formulas written out here, the row choice by phase, the clutch, bad rows; and a
circuit device that emulates a spring on the test stand (its delivered torque against −K θ)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from afo_mj.control.impedance import impedance_table, impedance_torque
from afo_mj.hydraulics.params import ParameterError

ROWS = [(0.3, 100.0, 2.0, 0.05, 0), (0.6, 250.0, 0.0, -0.1, 1), (1.0, 40.0, 1.0, 0.0, 0)]


def _by_hand(phase, theta, theta_dot):
    """The emulated element written out per row (row 0 before the phase is known)."""
    if phase < 0.3:
        return -100.0 * (theta - 0.05) - 2.0 * theta_dot
    if phase < 0.6:
        return -250.0 * (theta + 0.1) if theta > -0.1 else 0.0
    return -40.0 * theta - 1.0 * theta_dot


@pytest.mark.parametrize("phase", [-1.0, 0.0, 0.29, 0.3, 0.45, 0.59, 0.6, 0.99, 1.0, 1.2])
@pytest.mark.parametrize("theta,theta_dot", [(0.2, 1.5), (-0.3, -2.0), (-0.05, 0.4)])
def test_torque_is_the_row_of_the_phase(phase, theta, theta_dot):
    table = impedance_table(ROWS)
    assert impedance_torque(table, phase, theta, theta_dot) == pytest.approx(
        _by_hand(phase, theta, theta_dot), rel=1e-14, abs=1e-14)


def test_table_layout():
    t = impedance_table(ROWS)
    assert t[0] == 3 and t.shape == (16,)
    np.testing.assert_array_equal(t[1:6], ROWS[0])


@pytest.mark.parametrize("rows,match", [
    ([], "at least one row"),
    ([(1.0, 10.0, 0.0, 0.0)], "5 numbers"),
    ([(0.5, 10.0, 0.0, 0.0, 0), (0.4, 10.0, 0.0, 0.0, 0)], "increasing"),
    ([(1.0, -1.0, 0.0, 0.0, 0)], "≥ 0"),
    ([(1.0, 10.0, 0.0, 0.0, 2)], "clutched"),
    ([(1.0, math.nan, 0.0, 0.0, 0)], "finite"),
    ("abc", "rows of 5 numbers"),
])
def test_bad_rows_are_named(rows, match):
    with pytest.raises(ParameterError, match=match):
        impedance_table(rows)


def test_hafo_emulates_a_spring_on_the_stand():
    """Any torque-controlled circuit takes impedance rows: the HAFO (pump-controlled) on the
    stand with a slow imposed ±0.15 rad sinusoid emulates 60 N·m/rad; the delivered torque
    follows −K θ to within the device's own tracking error (seal friction, pressure loop)."""
    from afo_mj.devices.hafo import HAFO_GAIT, HafoDevice
    from afo_mj.human.test_stand import AnkleTestStand, ImposedTrajectory, StandLoad
    k = 60.0
    dev = HafoDevice(HAFO_GAIT, impedance=[(1.0, k, 0.0, 0.0, 0)], max_steps=2100)
    stand = AnkleTestStand(load=StandLoad(kind="imposed",
                                          trajectory=ImposedTrajectory.sinusoid(0.15, 0.5)))
    rec = stand.run_device(dev, 2.0)
    theta, tau = rec.angle_rad[500:], rec.device_torque_nm[500:]
    fit = np.polyfit(theta, tau, 1)
    assert fit[0] == pytest.approx(-k, rel=0.05), fit
    assert np.sqrt(np.mean((tau + k * theta) ** 2)) < 0.1 * k * 0.15
    with pytest.raises(Exception, match="both profile and impedance"):
        HafoDevice(HAFO_GAIT, impedance=ROWS, profile=np.zeros(11))


def test_scenarios_give_impedance_to_any_torque_controlled_device(tmp_path):
    """``profile = "impedance"`` on the pump-controlled HAFO builds a HAFO device emulating the
    rows; on a [circuit] with the open-loop controller it is refused, naming the key."""
    from afo_mj.devices.hafo import HAFO_GAIT
    from afo_mj.experiments.device_walk import make_device
    from afo_mj.scenarios.device_scenario import device_config
    from afo_mj.scenarios.walk_scenario import ScenarioError, load_scenario
    path = tmp_path / "imp.toml"
    path.write_text('[device]\npreset = "hafo_gait"\n[assistance]\nprofile = "impedance"\n'
                    'stiffness_nm_per_deg = 2.0\n')
    cfg = device_config(load_scenario(path))
    dev = make_device(cfg, "assist", 1e-3, 0)
    assert dev.spec.name == "hafo_gait" and dev.params == HAFO_GAIT and not dev.transparent
    table = dev.profile
    assert impedance_torque(table, 0.5, 0.1, 0.0) == pytest.approx(-2.0 * 180 / math.pi * 0.1)
    assert make_device(cfg, "transparent", 1e-3, 0).transparent
    path.write_text('[circuit]\nlibrary = "lab_bench"\n[assistance]\nprofile = "impedance"\n'
                    'stiffness_nm_per_deg = 2.0\n')
    with pytest.raises(ScenarioError, match="open_loop"):
        device_config(load_scenario(path))
