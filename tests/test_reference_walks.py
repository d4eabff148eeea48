"""Every documented reference/condition on the adult default scenario either walks 4 strides
without falling or is refused at load with its documented reason (issue 19, item 2)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from afo_mj.gait.walk import run_walk
from afo_mj.scenarios.walk_scenario import (REFERENCES, UNWALKABLE, ScenarioError,
                                            load_scenario)

ROOT = Path(__file__).resolve().parents[1]
ADULT = ROOT / "scenarios" / "walk_healthy.toml"
CASES = [(src, cond) for src, conds in REFERENCES.items() for cond in conds]


def _overrides(src, cond, strides=4):
    return [f"gait.reference={src}", f"gait.condition={cond}", f"gait.strides={strides}"]


@pytest.mark.parametrize("src,cond", CASES, ids=[f"{s}:{c}" for s, c in CASES])
def test_every_documented_reference_walks_or_is_refused(src, cond):
    if (src, cond) in UNWALKABLE:
        with pytest.raises(ScenarioError) as exc:
            load_scenario(ADULT, _overrides(src, cond))
        msg = str(exc.value)
        assert f"gait.condition = {cond!r}" in msg and repr(src) in msg
        assert UNWALKABLE[(src, cond)] in msg
        return
    s = load_scenario(ADULT, _overrides(src, cond))
    ref = s.load_reference()
    rec = run_walk(s.walker, ref, s.cycle_time_s(ref), s.strides, s.controller_params())
    assert rec.events.fall_time_s is None, f"{src}:{cond} fell at {rec.events.fall_time_s} s"
    assert len(rec.events.heel_strikes_s[0]) >= 5      # the start + 4 complete right strides


def test_unwalkable_message_names_reference_condition_reason_and_what_to_set():
    with pytest.raises(ScenarioError) as exc:
        load_scenario(ADULT, _overrides("schwartz2008", "Fast"))
    msg = str(exc.value)
    assert msg.startswith(str(ADULT))
    assert "gait.reference = 'schwartz2008', gait.condition = 'Fast' cannot be walked" in msg
    assert "falls" in msg                                           # why
    assert 'gait.reference = "winter"' in msg                       # what to set instead
    assert "gait.cadence_steps_per_min = 120" in msg                # Fast's own cadence
    assert 'gait.band_references = ["schwartz2008:Fast"]' in msg
    # bands of an unwalkable condition stay usable
    s = load_scenario(ADULT, ["gait.band_references=['schwartz2008:VeryFast']"])
    assert s.band_references == (("schwartz2008", "VeryFast"),)


def test_unwalkable_reference_exits_2_and_simulates_nothing(tmp_path):
    out = tmp_path / "r"
    p = subprocess.run([sys.executable, "-m", "afo_mj.cli", "run", str(ADULT), "--out", str(out),
                        "--set", "gait.reference=schwartz2008", "--set",
                        "gait.condition=VeryFast"], capture_output=True, text=True, cwd=ROOT)
    assert p.returncode == 2, p.stderr
    assert "cannot be walked" in p.stderr and not out.exists()


def test_schwartz_start_speed_is_derived_and_winter_keeps_the_default():
    s = load_scenario(ADULT, _overrides("schwartz2008", "VerySlow"))
    assert 0.55 < s.controller_params().initial_speed_m_s < 0.7       # its own, slow start
    s = load_scenario(ADULT, _overrides("schwartz2008", "VerySlow")
                      + ["controller.initial_speed_m_s=0.9"])
    assert s.controller_params().initial_speed_m_s == 0.9             # the user's wins
    w = load_scenario(ADULT)
    assert w.controller_params().initial_speed_m_s == 1.0
    assert abs(w.start_speed_m_s() - 1.0) < 0.002     # the rule reproduces Winter's default
