"""Issue 38 item 5: small input checks a new user hit (each test fails on the code before
its fix)."""

from __future__ import annotations

import pytest

from afo_mj.scenarios.walk_scenario import ScenarioError, parse_scenario

_DEVICE = """
name = "t"
[device]
preset = "hafo"
conditions = ["assist"]
"""


def _device_error(extra: str) -> str:
    from afo_mj.scenarios.device_scenario import device_config
    sc = parse_scenario(_DEVICE + extra, origin="t.toml")
    with pytest.raises(ScenarioError) as info:
        device_config(sc)
    return str(info.value)


def test_misspelt_assistance_key_suggests_the_key():
    msg = _device_error("[assistance]\npeak_torque_n = 30.0\n")
    assert "assistance.peak_torque_n" in msg
    assert "did you mean 'assistance.peak_torque_nm'?" in msg


def test_misspelt_device_key_suggests_the_key():
    sc_text = _DEVICE.replace('conditions = ["assist"]', 'conditons = ["assist"]')
    from afo_mj.scenarios.device_scenario import device_config
    with pytest.raises(ScenarioError) as info:
        device_config(parse_scenario(sc_text, origin="t.toml"))
    assert "did you mean 'device.conditions'?" in str(info.value)


def test_one_stride_says_the_start_up_stride_is_analysed():
    from afo_mj.scenarios.walk_scenario import strides_overrides
    sc = parse_scenario('name = "t"\n[gait]\nstrides = 10\nanalyse_strides = [4, 10]\n',
                        origin="t.toml", overrides=strides_overrides(1))
    assert sc.analyse_strides == (1, 1)
    assert any("start-up stride" in n and "gait.analyse_strides" in n for n in sc.notes)
    sc = parse_scenario('name = "t"\n[gait]\nstrides = 1\n', origin="t.toml")
    assert sc.analyse_strides == (1, 1)
    assert any("start-up stride" in n for n in sc.notes)


def test_windows_past_the_start_up_stride_carry_no_start_up_note():
    from afo_mj.scenarios.walk_scenario import strides_overrides
    for ov in ([], strides_overrides(2), strides_overrides(6)):
        sc = parse_scenario('name = "t"\n', origin="t.toml", overrides=ov)
        assert sc.analyse_strides[0] >= 2
        assert not any("start-up" in n for n in sc.notes)


def test_a_body_outside_the_human_range_is_noted():
    sc = parse_scenario('name = "t"\n', origin="t.toml",
                        overrides=["walker.body_mass_kg=10", "walker.height_m=2.2"])
    bmi = 10.0 / 2.2 ** 2                     # 2.07 kg/m², far below any human's
    note = [n for n in sc.notes if "body mass index" in n]
    assert len(note) == 1
    assert f"{bmi:.1f} kg/m^2" in note[0] and "10 kg" in note[0] and "2.2 m" in note[0]
    sc = parse_scenario('name = "t"\n', origin="t.toml",
                        overrides=["walker.body_mass_kg=200", "walker.height_m=1.2"])
    assert any("body mass index" in n for n in sc.notes)     # 139 kg/m²


@pytest.mark.parametrize("walker", ['body_preset = "child_4y"', 'body_preset = "adult_female"',
                                    "body_mass_kg = 75.0\nheight_m = 1.75",
                                    "body_mass_kg = 120.0\nheight_m = 1.8"])
def test_human_bodies_carry_no_body_size_note(walker):
    sc = parse_scenario(f'name = "t"\n[walker]\n{walker}\n', origin="t.toml")
    assert not any("body mass index" in n for n in sc.notes)
