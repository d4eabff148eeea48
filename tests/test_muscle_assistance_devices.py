"""The muscle walker's device condition wears any circuit preset (issue 40 item 2): a valve
preset, built as ``afo-mj run`` builds an ``assist`` condition, walks and acts (its command
the Zhang profile worked out here, its delivered torque the record's, its ledger closed,
its masses what the worn-mass condition carries); the HAFO condition is the device the
former path built (HafoDevice of the preset directly) bit for bit; an unknown or non-circuit
preset is refused by name."""

from __future__ import annotations

from importlib.resources import files

import numpy as np
import pytest

from afo_mj.control import assistance as asst
from afo_mj.devices.hafo import HafoDevice, hafo_params
from afo_mj.devices.valve_afo import VALVE_PRESETS
from afo_mj.experiments import muscle_assistance as ma
from afo_mj.gait.muscle_walk import run_muscle_walk
from afo_mj.human.walker import WalkerParams
from afo_mj.studies.gait_optimization import load_reflex_set

# the reflex set re-optimised with the HAFO worn: it walks under a worn ankle device
ADAPTED = files("afo_mj") / "data" / "adapted" / "hafo.json"


@pytest.fixture(scope="module")
def params():
    return load_reflex_set(ADAPTED)


def _zhang_by_hand(phase, peak):
    """Zhang et al. 2017, published timing, written out: zero outside 26.7 … 62.7 % of the
    stride, flat-ended cubic rise to ``peak`` at 52.9 % and fall; plantarflexion (−)."""
    x = 100.0 * np.asarray(phase, float)
    u = np.where(x <= 52.9, (x - 26.7) / 26.2, (62.7 - x) / 9.8)
    out = -peak * u * u * (3.0 - 2.0 * u)
    return np.where((x < 26.7) | (x > 62.7), 0.0, out)


def test_a_valve_preset_condition_walks_and_acts(params):
    a = ma.Assistance("hafo", hafo_preset="valve", hafo_peak_torque_nm=40.0)
    assert a.label == "valve AFO (valve, 40 N·m)"
    walk, dev = ma.assistance_walk(a, params=params, duration_s=2.5)
    r = walk.record
    assert dev.spec.name == "valve" and dev.spec.open_loop_switch is not None
    assert dev.params == VALVE_PRESETS["valve"] and dev.sides == ("right",)
    assert r.events.fall_time_s is None
    log = dev.log.arrays()
    cmd = log["commanded_torque_nm"][:, 0]
    # its command is the Zhang profile of 40 N·m on its own phase estimate, once it has one
    on = cmd != 0.0
    assert on.sum() > 100 and cmd.min() == pytest.approx(-40.0, abs=0.5)
    # (a 1001-point table interpolated linearly: within h²/8·max|τ″| ≈ 0.003 N·m of the curve)
    np.testing.assert_allclose(cmd[on], _zhang_by_hand(log["phase"][on, 0], 40.0), atol=0.01)
    # it delivers a plantarflexion torque while its command peaks, and the record holds it
    dlv = log["delivered_torque_nm"][:, 0]
    peak = dlv[cmd < -30.0]
    assert peak.min() < -25.0 and peak.mean() < -10.0
    n = min(len(r.time_s), len(dlv))
    np.testing.assert_array_equal(r.device_moment_nm[:n, 0], dlv[:n])
    assert np.all(r.device_moment_nm[:, 1] == 0.0)
    led = dev.ledger(0)
    assert abs(led["balance_error_rel"]) < 1e-9 and led["input_drawn_j"] > 0.0
    # the worn-mass condition of the same preset carries the same masses and no torque: the
    # walks part once the valve AFO acts
    mass, none = ma.assistance_walk(ma.Assistance("worn_mass", hafo_preset="valve"),
                                    params=params, duration_s=2.5)
    assert none is None and np.all(mass.record.device_moment_nm == 0.0)
    same = run_muscle_walk(WalkerParams(), params, 2.5, worn_masses=tuple(dev.worn_masses()))
    np.testing.assert_array_equal(mass.record.qpos, same.record.qpos)
    assert not np.array_equal(mass.record.qpos, r.qpos)


def test_the_hafo_condition_is_the_hafo_built_directly(params):
    """The former path: HafoDevice of the preset's parameters with the Zhang profile."""
    a = ma.Assistance("hafo", hafo_preset="hafo_gait", hafo_peak_torque_nm=35.0)
    walk, dev = ma.assistance_walk(a, params=params, duration_s=1.5)
    ref_dev = HafoDevice(hafo_params(preset="hafo_gait"), sides=("right",),
                         profile=asst.zhang_profile(35.0, *ma.ZHANG_TIMING_PCT),
                         timestep_s=1e-3, max_steps=1504)
    ref = run_muscle_walk(WalkerParams(), params, 1.5, worn_masses=tuple(ref_dev.worn_masses()),
                          device=ref_dev)
    assert dev.spec.name == "hafo_gait" and dev.params == ref_dev.params
    np.testing.assert_array_equal(walk.record.qpos, ref.record.qpos)
    np.testing.assert_array_equal(dev.W, ref_dev.W)
    assert ma.hafo_device is ma.assistance_device


def test_a_preset_that_is_no_circuit_preset_is_refused():
    with pytest.raises(ValueError, match=r"assistance.hafo_preset = 'ideal'; allowed: hafo, "
                                         r"hafo_gait, valve, .*phafo"):
        ma.Assistance("hafo", hafo_preset="ideal")
    with pytest.raises(ValueError, match=r"assistance.hafo_preset = 'vlave'"):
        ma.Assistance("zhang", hafo_preset="vlave")
