"""Body-size presets: values against the CDC 2000 growth-chart files, scenario precedence, the
error for an unknown name, the 0.5 ms step for small walkers, and the child foot-drop walk.

The reference numbers below were typed from the CDC data files ``statage.csv`` and
``wtage.csv`` (https://www.cdc.gov/growthcharts/percentile_data_files.htm), column P50, at full
precision; the module stores them rounded to 0.01 cm / 0.01 kg.
"""

from __future__ import annotations

import dataclasses
import os
from pathlib import Path

os.environ.setdefault("MUJOCO_GL", "egl")

import pytest  # noqa: E402

from afo_mj.human.body_presets import (BODY_PRESETS, DEFAULT_TIMESTEP_S,  # noqa: E402
                                       body_preset, default_timestep_s)
from afo_mj.human.walker import WalkerParams  # noqa: E402
from afo_mj.hydraulics.params import ParameterError  # noqa: E402
from afo_mj.scenarios.walk_scenario import (ScenarioError, load_scenario,  # noqa: E402
                                            parse_scenario)

SCENARIOS = Path(__file__).resolve().parents[1] / "scenarios"

# CDC 2000, P50: (Agemos, Sex 1 = boys / 2 = girls) -> stature [cm], weight [kg]
CDC_STATURE_CM = {
    (72.5, 1): 115.6608862, (72.5, 2): 115.0054978,
    (96.5, 1): 128.1237104, (96.5, 2): 127.8262759,
    (120.5, 1): 138.8234114, (120.5, 2): 138.2111552,
    (144.5, 1): 149.3088178, (144.5, 2): 151.4865636,
    (48.5, 1): 102.5104735, (168.5, 2): 160.4776996,
    (240.0, 1): 176.8492322, (240.0, 2): 163.338251,
}
CDC_WEIGHT_KG = {
    (72.5, 1): 20.77769565, (72.5, 2): 20.33635961,
    (96.5, 1): 25.75256528, (96.5, 2): 25.7570168,
    (120.5, 1): 32.08799062, (120.5, 2): 33.06392318,
    (144.5, 1): 40.67443658, (144.5, 2): 41.82797963,
    (48.5, 1): 16.31676727, (168.5, 2): 49.49075409,
    (240.0, 1): 70.59761453, (240.0, 2): 58.21897289,
}
CM_TOL_M = 0.006e-2      # the table is rounded to 0.01 cm
KG_TOL = 0.006


@pytest.mark.parametrize("age", [6, 8, 10, 12])
def test_child_presets_are_the_cdc_medians(age):
    agemos = 12 * age + 0.5
    boy, girl = body_preset(f"child_{age}y_boy"), body_preset(f"child_{age}y_girl")
    both = body_preset(f"child_{age}y")
    assert boy.height_m == pytest.approx(CDC_STATURE_CM[(agemos, 1)] / 100, abs=CM_TOL_M)
    assert girl.height_m == pytest.approx(CDC_STATURE_CM[(agemos, 2)] / 100, abs=CM_TOL_M)
    assert boy.body_mass_kg == pytest.approx(CDC_WEIGHT_KG[(agemos, 1)], abs=KG_TOL)
    assert girl.body_mass_kg == pytest.approx(CDC_WEIGHT_KG[(agemos, 2)], abs=KG_TOL)
    # the sex-neutral child is the mean of the two medians
    h = (CDC_STATURE_CM[(agemos, 1)] + CDC_STATURE_CM[(agemos, 2)]) / 200
    m = (CDC_WEIGHT_KG[(agemos, 1)] + CDC_WEIGHT_KG[(agemos, 2)]) / 2
    assert both.height_m == pytest.approx(h, abs=CM_TOL_M)
    assert both.body_mass_kg == pytest.approx(m, abs=KG_TOL)
    assert (boy.sex, girl.sex, both.age_years) == ("male", "female", age)


def test_range_ends_and_adults():
    assert body_preset("child_4y_boy").height_m == pytest.approx(1.025104735, abs=CM_TOL_M)
    assert body_preset("child_4y_boy").body_mass_kg == pytest.approx(16.31676727, abs=KG_TOL)
    assert body_preset("child_14y_girl").height_m == pytest.approx(1.604776996, abs=CM_TOL_M)
    assert body_preset("child_14y_girl").body_mass_kg == pytest.approx(49.49075409, abs=KG_TOL)
    assert body_preset("adult_male").height_m == pytest.approx(1.768492322, abs=CM_TOL_M)
    assert body_preset("adult_male").body_mass_kg == pytest.approx(70.59761453, abs=KG_TOL)
    assert body_preset("adult_female").height_m == pytest.approx(1.63338251, abs=CM_TOL_M)
    assert body_preset("adult_female").body_mass_kg == pytest.approx(58.21897289, abs=KG_TOL)
    names = set(BODY_PRESETS)
    assert {f"child_{a}y" for a in range(4, 15)} <= names
    # children grow: stature rises with age; every preset is a valid walker
    heights = [body_preset(f"child_{a}y").height_m for a in range(4, 15)]
    assert heights == sorted(heights)
    for p in BODY_PRESETS.values():
        WalkerParams(body_mass_kg=p.body_mass_kg, height_m=p.height_m)


def test_unknown_preset_raises_naming_value_and_allowed():
    with pytest.raises(ParameterError, match=r"'child_99y'.*allowed: .*child_8y"):
        body_preset("child_99y")


def test_scenario_preset_sets_mass_and_height():
    sc = parse_scenario('[walker]\nbody_preset = "child_10y"\n', origin="x.toml")
    assert sc.walker.height_m == pytest.approx((138.8234114 + 138.2111552) / 200, abs=CM_TOL_M)
    assert sc.walker.body_mass_kg == pytest.approx((32.08799062 + 33.06392318) / 2, abs=KG_TOL)


def test_explicit_mass_and_height_override_the_preset():
    sc = parse_scenario('[walker]\nbody_preset = "child_8y"\nheight_m = 1.31\n', origin="x")
    assert sc.walker.height_m == 1.31
    assert sc.walker.body_mass_kg == pytest.approx((25.75256528 + 25.7570168) / 2, abs=KG_TOL)
    sc = parse_scenario('[walker]\nbody_preset = "child_8y"\nbody_mass_kg = 30.0\n', origin="x")
    assert sc.walker.body_mass_kg == 30.0
    assert sc.walker.height_m == pytest.approx((128.1237104 + 127.8262759) / 200, abs=CM_TOL_M)
    # --set overrides the file's preset like any other key
    sc = parse_scenario('[walker]\nbody_preset = "child_8y"\n', origin="x",
                        overrides=["walker.body_preset=adult_female"])
    assert sc.walker.height_m == pytest.approx(1.63338251, abs=CM_TOL_M)


@pytest.mark.parametrize("value, problem", [('"child_99y"', "is not a known body preset"),
                                            ("8", "has the wrong type")])
def test_bad_preset_is_a_scenario_error(value, problem):
    with pytest.raises(ScenarioError) as info:
        parse_scenario(f"[walker]\nbody_preset = {value}\n", origin="bad.toml")
    msg = str(info.value)
    assert msg.startswith("bad.toml: walker.body_preset = ")
    assert problem in msg
    assert "allowed: one of " in msg and "child_8y" in msg and "adult_male" in msg


def test_small_walkers_default_to_half_millisecond():
    # WalkerParams.timestep_s: below about 1.3 m the walker needs 0.5 ms
    assert default_timestep_s(1.2) == 5e-4 and default_timestep_s(1.75) == 1e-3
    assert DEFAULT_TIMESTEP_S == WalkerParams().timestep_s
    step = lambda text: parse_scenario(text, origin="x").walker.timestep_s  # noqa: E731
    assert step('[walker]\nbody_preset = "child_8y"\n') == 5e-4         # 1.280 m
    assert step('[walker]\nbody_preset = "child_10y"\n') == 1e-3        # 1.385 m
    assert step('[walker]\nheight_m = 1.1\nbody_mass_kg = 20.0\n') == 5e-4
    assert step('[walker]\nbody_preset = "child_8y"\nheight_m = 1.5\n') == 1e-3
    assert step('[walker]\nbody_preset = "child_6y"\ntimestep_s = 0.002\n') == 0.002
    assert step("") == 1e-3


def test_child_foot_drop_scenario_file():
    sc = load_scenario(SCENARIOS / "walk_child_foot_drop.toml")
    assert sc.walker.dorsiflexor_strength_fraction == 0.02
    assert sc.walker.height_m == pytest.approx((128.1237104 + 127.8262759) / 200, abs=CM_TOL_M)
    assert sc.walker.timestep_s == 5e-4
    assert sc.device == {}


def test_child_with_foot_drop_walks_with_a_hanging_foot():
    """Dorsiflexors at 2 %: the 8-year-old still walks ten strides, but the swinging foot hangs
    (more plantarflexed through swing) and clears the floor less than the same child healthy."""
    from afo_mj.metrics.gait_metrics import analyse_gait
    from afo_mj.gait.walk import simulate_walk

    sc = load_scenario(SCENARIOS / "walk_child_foot_drop.toml")
    healthy = dataclasses.replace(sc, walker=sc.walker.replace(dorsiflexor_strength_fraction=1.0))
    out = {}
    for key, s in (("drop", sc), ("healthy", healthy)):
        rec = simulate_walk(s)
        assert rec.events.fall_time_s is None, key
        out[key] = analyse_gait(rec, s.load_reference(), s.analyse_strides).summary
    d, h = out["drop"], out["healthy"]
    assert d["completed_strides"] >= 10
    mean = lambda s, k: s[k]["mean"]  # noqa: E731
    assert mean(d, "swing_mean_ankle_angle_deg") < mean(h, "swing_mean_ankle_angle_deg") - 5.0
    assert mean(d, "min_toe_clearance_m") < mean(h, "min_toe_clearance_m") - 0.005
