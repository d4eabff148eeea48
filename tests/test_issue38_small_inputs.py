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
