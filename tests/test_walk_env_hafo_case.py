"""The environment's mode="hafo" is a case of mode="device" (issue 40 item 2): its device is
the HAFO preset on both ankles, configured as a scenario's ``[device] preset = hafo_preset,
sides = ["right", "left"]`` and built by ``afo-mj run``'s make_device (so it keeps its log,
as a run's device does); its energy term stays the bus power (battery current × bus voltage
summed over the sides, counted when positive), worked here from that log; a preset that is
no HAFO preset is refused by name."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from afo_mj.experiments import walk_env as we
from afo_mj.experiments.device_walk import preset_config

ROOT = Path(__file__).resolve().parents[1]
SC = str(ROOT / "scenarios" / "walk_healthy.toml")
SHORT = ["gait.strides=2", "gait.analyse_strides=[1, 2]"]


def test_hafo_mode_wears_the_preset_as_a_device_scenario_would():
    env = we.AnkleAssistEnv(SC, mode="hafo", hafo_preset="hafo", overrides=SHORT)
    cfg = env.device_config
    ref = preset_config("hafo", ("right", "left"))
    assert (cfg.preset, cfg.sides, cfg.profile) == ("hafo", ("right", "left"), None)
    assert cfg.params == ref.params
    env.reset(seed=0)
    rng = np.random.default_rng(1)
    for _ in range(40):
        a = rng.uniform(-20.0, 10.0, 2)
        speed = env.walk.pelvis_speed_m_s
        obs, r, term, trunc, info = env.step(a)
    d = env.device
    assert d.sides == ("right", "left") and d.params == ref.params
    # its log, as afo-mj run keeps a condition's
    assert d.log.n == d.steps == env.walk.steps == 400
    # the energy term: the last control period's (10 steps) mean bus power, per m g v
    L = d.log.arrays()
    p = np.maximum(np.sum(L["battery_current_a"][-10:] * L["bus_voltage_v"][-10:], axis=1),
                   0.0)
    mg = env.walk.phys.body_mass_kg * 9.81
    assert env.last["energy"] == pytest.approx(p.mean() / (mg * max(speed, 0.3)), rel=1e-12)
    assert env.last["energy"] > 0.0


def test_a_preset_that_is_no_hafo_preset_is_refused():
    with pytest.raises(ValueError, match=r"hafo_preset = 'valve'; allowed: hafo, hafo_gait "
                                         r"\(a valve preset: mode = 'device'"):
        we.AnkleAssistEnv(SC, mode="hafo", hafo_preset="valve", overrides=SHORT)
