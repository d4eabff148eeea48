"""The torque walker's tracking controller as a human controller (issue 40 item 5): walked by
the plain ControllerWalk's Python loop it is the torque walk's compiled loop (walk_loop) bit
for bit — without a device and with a coupled HAFO, whose torque the wearer answers through
``answer_device`` in one and in compiled code in the other — events, scuffs and the
controller's own gait phase included."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from afo_mj.gait.controller import ControllerSetup, HumanController
from afo_mj.gait.controller_walk import ControllerWalk
from afo_mj.gait.walk import Walk, run_walk
from afo_mj.gait.tracking_controller import TrackingController
from afo_mj.scenarios.walk_scenario import load_scenario

ROOT = Path(__file__).resolve().parents[1]
STRIDES = 2


@pytest.fixture(scope="module")
def scenario():
    sc = load_scenario(ROOT / "scenarios" / "walk_healthy.toml")
    ref = sc.load_reference()
    return sc, ref, sc.cycle_time_s(ref)


def _plain(scenario, device=None, worn=()):
    sc, ref, T = scenario
    ctl = TrackingController(sc.controller_params(),
                             ControllerSetup(sc.walker, ref, T, STRIDES))
    assert isinstance(ctl, HumanController) and ctl.compiled(None) is None
    w = ControllerWalk(ctl, (STRIDES + 1.5) * T + 1.0, STRIDES, worn, device)
    assert not w.compiled                       # stepped in Python, step by step
    return w.run()


def _same(got, want):
    for name in want.array_fields():
        np.testing.assert_array_equal(getattr(got, name), getattr(want, name), err_msg=name)
    assert got.signals == {} and want.signals == {}
    assert got.events == want.events


def test_plain_controller_walk_is_the_compiled_torque_walk(scenario):
    sc, ref, T = scenario
    want = run_walk(sc.walker, ref, T, STRIDES, sc.controller_params(), loop="compiled")
    got = _plain(scenario)
    _same(got, want)
    # the controller's phase estimate (reset at heel strike), not the one from the events
    assert got.gait_phase[0, 1] == pytest.approx(0.5, abs=0.01)
    assert len(want.events.heel_strikes_s[0]) == STRIDES + 1


def test_plain_controller_walk_with_the_hafo_is_the_compiled_torque_walk(scenario):
    from afo_mj.control.assistance import zhang_profile
    from afo_mj.devices.hafo import HafoDevice, hafo_params
    sc, ref, T = scenario

    def dev():
        return HafoDevice(hafo_params(preset="hafo_gait"), sides=("right",),
                          profile=zhang_profile(40.0, 52.9, 26.2, 9.8), max_steps=5000)
    d1, d2 = dev(), dev()
    w = Walk(sc.walker, ref, T, STRIDES, sc.controller_params(), d2.worn_masses(), d2,
             loop="compiled")
    assert w.compiled
    want = w.run()
    got = _plain(scenario, d1, d1.worn_masses())
    _same(got, want)
    assert np.abs(want.device_moment_nm[:, 0]).max() > 10.0     # the device did push
    assert d1.ledger(0)["input_j"] == d2.ledger(0)["input_j"]
