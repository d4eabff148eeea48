"""Many walks at once (afo_mj.experiments.batch, issue 21): a parallel batch returns, in input
order, exactly what each walk gives when run alone in this process (bit for bit), failed
items are reported per item, and bad input is refused naming the argument."""

from __future__ import annotations

import dataclasses
import json
import pickle
from pathlib import Path
from types import MappingProxyType

import numpy as np
import pytest

from afo_mj.experiments import batch
from afo_mj.gait.walk import simulate_walk
from afo_mj.metrics.gait_metrics import analyse_gait
from afo_mj.scenarios.walk_scenario import load_scenario

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def scenarios():
    base = load_scenario(ROOT / "scenarios" / "walk_healthy.toml",
                         ["gait.strides=3", "gait.analyse_strides=[2, 3]"])
    return [dataclasses.replace(base, controller=MappingProxyType(
        dict(base.controller, ankle_kp_nm_per_rad=kp))) for kp in (260.0, 300.0, 340.0)]


def test_walk_scenario_pickles(scenarios):
    s = scenarios[0]
    back = pickle.loads(pickle.dumps(s))
    assert back == s and isinstance(back.controller, MappingProxyType)
    assert back.controller_params() == s.controller_params()


def test_parallel_records_equal_serial_in_order(scenarios):
    got = batch.walk_batch(scenarios, workers=2)
    for s, rec in zip(scenarios, got):
        alone = simulate_walk(s)
        assert np.array_equal(rec.qpos, alone.qpos)
        assert np.array_equal(rec.joint_moment_nm, alone.joint_moment_nm)
        assert rec.events == alone.events
    # different parameters give different walks (the order is the input's)
    assert not np.array_equal(got[0].qpos, got[2].qpos)


def test_summaries_equal_the_analysis_in_process(scenarios):
    got = batch.walk_batch(scenarios[:2], workers=2, result="summary")
    for s, summary in zip(scenarios, got):
        ref = analyse_gait(simulate_walk(s), s.load_reference(), s.analyse_strides).summary
        assert json.dumps(summary, sort_keys=True) == json.dumps(ref, sort_keys=True)


def _fail_on_two(x):
    if x == 2:
        raise ValueError("item two is bad")
    return x * x


def test_errors_are_reported_per_item():
    res = batch.run_batch(_fail_on_two, [1, 2, 3], workers=2)
    assert [r.ok for r in res] == [True, False, True]
    assert res[0].value == 1 and res[2].value == 9
    assert isinstance(res[1].error, ValueError) and "item two" in str(res[1].error)
    # in-process (one worker) the same
    res1 = batch.run_batch(_fail_on_two, [1, 2, 3], workers=1)
    assert [r.ok for r in res1] == [True, False, True]


def test_a_failed_walk_names_its_index(scenarios):
    bad = dataclasses.replace(scenarios[0], reference="nonexistent")
    with pytest.raises(RuntimeError, match="walk 1"):
        batch.walk_batch([scenarios[0], bad], workers=2)
    out = batch.walk_batch([scenarios[0], bad], workers=2, raise_errors=False)
    assert hasattr(out[0], "qpos") and not out[1].ok


@pytest.mark.parametrize("workers", [0, -1, 1.5, True, "2"])
def test_bad_workers_names_the_argument(workers):
    with pytest.raises(ValueError, match="workers"):
        batch.run_batch(_fail_on_two, [1], workers=workers)


def test_bad_input_names_the_argument(scenarios):
    with pytest.raises(ValueError, match=r"scenarios\[1\]"):
        batch.walk_batch([scenarios[0], "walk_healthy.toml"])
    with pytest.raises(ValueError, match="result = 'curves'"):
        batch.walk_batch(scenarios, result="curves")
