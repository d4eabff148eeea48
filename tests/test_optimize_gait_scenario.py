"""``afo-mj optimize-gait --scenario FILE [--condition C]`` (issue 39 item 4): the wearer
re-optimised with a scenario's own device worn.

References, independent of the scenario path: the assistance study's clutched spring
(``--assistance clutched_spring``: the ideal device's command through the walker's
``device_torque`` callback, :mod:`afo_mj.experiments.muscle_assistance`) for the same spring
and body, whose cost must come out bit for bit; the scenario's reflex file read here for the
warm start; the scenario loader itself resolving the printed ``reflex_set`` line.
"""

from __future__ import annotations

import json
import pickle
from pathlib import Path

import numpy as np
import pytest

from afo_mj.cli import main

ROOT = Path(__file__).resolve().parents[1]
SPRING = ROOT / "scenarios" / "gait_muscle_clutched_spring.toml"
HAFO = ROOT / "scenarios" / "gait_muscle_hafo.toml"
TORQUE = ROOT / "scenarios" / "walk_healthy.toml"
# the cheapest search: one generation of four 5 s walks, a step so small that every walk
# is the warm start's (to 1e-9)
TINY = ["--generations", "1", "--popsize", "4", "--duration", "5", "--sigma0", "1e-9",
        "--quiet"]


def test_the_scenarios_device_costs_what_the_assistance_studys_clutched_spring_costs():
    """The scenario's ideal clutched spring (180 N·m/rad, 10 %/62 %, both ankles, no ramp,
    massless) and ``--assistance clutched_spring`` describe the same device on the same
    75 kg, 1.75 m wearer: the objective's cost and everything it measured are equal bit for
    bit, also after the objective has been pickled to a fresh worker (its device rebuilt from
    the file); without the device the cost differs (the device acts)."""
    from afo_mj.experiments.muscle_assistance import Assistance
    from afo_mj.gait.muscle_walk import load_reflex_set
    from afo_mj.human.walker import WalkerParams
    from afo_mj.studies import gait_optimization as go
    kw = dict(duration_s=5.0, settle_s=1.0)
    scen, sc = go.scenario_objective(SPRING, **kw)
    assert scen.scenario.condition == "assist"             # the headline: the last listed
    params = load_reflex_set(sc.reflex_set)
    walker = WalkerParams(body_mass_kg=75.0, height_m=1.75)
    ref = go.GaitObjective(walker=walker, assistance=Assistance(kind="clutched_spring"), **kw)
    cost_ref = go.gait_cost(params, ref)
    go._scenario_and_device.cache_clear()                   # as a worker that never read it
    moved = pickle.loads(pickle.dumps(scen))
    cost_scen = go.gait_cost(params, moved)
    assert cost_ref[0] < 900.0                              # it walked, was scored
    assert cost_scen == cost_ref
    bare = go.gait_cost(params, go.GaitObjective(walker=walker, **kw))
    assert bare[0] != cost_ref[0]
    # the no-device condition of the same scenario is the bare walk
    nodev, _ = go.scenario_objective(SPRING, condition="no_device", **kw)
    assert go.gait_cost(params, nodev) == bare


def test_cli_scenario_run_writes_the_set_warm_started_from_the_scenarios_wearer(tmp_path,
                                                                                 capsys):
    """A one-generation run with the scenario (two worker processes, each rebuilding the
    device) writes reflex_params.json recording the scenario and condition; the search starts
    at the scenario's walker.reflex_set (``--start`` replaces it); the last line printed is
    the ``reflex_set = "..."`` line that, put in the scenario, walks it with the new set;
    run again, the finished search changes nothing."""
    from afo_mj.gait import reflex_law as rl
    from afo_mj.gait.muscle_walk import load_reflex_set
    from afo_mj.scenarios.walk_scenario import load_scenario
    out = tmp_path / "spring"
    assert main(["optimize-gait", "--scenario", str(SPRING), "--out", str(out),
                 "--workers", "2", *TINY]) == 0
    text = capsys.readouterr().out
    doc = json.loads((out / "reflex_params.json").read_text())
    assert doc["format"] == "afo_mj reflex parameters v1"
    assert doc["scenario"]["path"] == str(SPRING) and doc["scenario"]["condition"] == "assist"
    assert doc["assistance"] is None
    # the workers' walks walked (5 s leave fewer than 3 scored strides: 900; a worker that
    # failed would give 3000, a fall over 900 with its time)
    assert doc["cost"] == 900.0 and "fell_s" not in doc["quality"]
    assert doc["quality"]["distance_m"] > 4.0
    start = load_reflex_set(load_scenario(SPRING).reflex_set)
    got = np.array([doc["parameters"][n] for n in rl.PARAM_NAMES])
    np.testing.assert_allclose(got, start, rtol=1e-7, atol=0.0)
    # the printed line, put in the scenario (a copy beside it), names the written file
    line = text.strip().splitlines()[-1]
    assert line.startswith("reflex_set = ")
    copy = SPRING.with_name(f".{tmp_path.name}_copy.toml")
    try:
        copy.write_text(SPRING.read_text().replace('reflex_set = "adapted/clutched_spring"',
                                                   line))
        assert load_scenario(copy).reflex_set.resolve() == (out / "reflex_params.json")
    finally:
        copy.unlink(missing_ok=True)
    # resumed with nothing left to do: the same record
    assert main(["optimize-gait", "--scenario", str(SPRING), "--out", str(out),
                 "--workers", "2", *TINY]) == 0
    capsys.readouterr()
    again = json.loads((out / "reflex_params.json").read_text())
    assert again["parameters"] == doc["parameters"] and again["cost"] == doc["cost"]
    # another condition is another objective: refused in that folder, nothing changed
    assert main(["optimize-gait", "--scenario", str(SPRING), "--condition", "no_device",
                 "--out", str(out), "--workers", "1", *TINY]) == 2
    assert "another objective" in capsys.readouterr().err
    # --start replaces the scenario's set as the warm start
    other = ROOT / "afo_mj" / "data" / "reflex_params_1.25.json"
    out2 = tmp_path / "started"
    assert main(["optimize-gait", "--scenario", str(SPRING), "--start", str(other),
                 "--out", str(out2), "--workers", "1", *TINY]) == 0
    capsys.readouterr()
    doc2 = json.loads((out2 / "reflex_params.json").read_text())
    got2 = np.array([doc2["parameters"][n] for n in rl.PARAM_NAMES])
    np.testing.assert_allclose(got2, load_reflex_set(other), rtol=1e-7, atol=0.0)


@pytest.mark.parametrize("args, words", [
    (["--scenario", str(TORQUE)],
     ["walker.model = 'torque'", "allowed: 'muscle'", 'walker.model = "muscle"']),
    (["--scenario", str(HAFO), "--assistance", "zhang"],
     ["--assistance = 'zhang' with --scenario"]),
    (["--scenario", str(HAFO), "--assistance", "none"],
     ["--assistance = 'none' with --scenario"]),
    (["--scenario", str(HAFO), "--body-mass-kg", "60"],
     ["--body-mass-kg = 60.0 with --scenario", "--set"]),
    (["--scenario", str(HAFO), "--condition", "stiff"],
     ["--condition = 'stiff'", "'no_device', 'transparent', 'assist'"]),
    (["--condition", "assist"], ["--condition = 'assist' without --scenario"]),
    (["--set", "walker.body_mass_kg=60"], ["--set", "without --scenario"]),
    (["--scenario", str(ROOT / "scenarios" / "no_such.toml")],
     ["--scenario", "no_such.toml", "cannot read"]),
])
def test_refusals_exit_2_name_the_option_and_write_nothing(tmp_path, capsys, args, words):
    out = tmp_path / "o"
    assert main(["optimize-gait", "--out", str(out), *args, *TINY]) == 2
    err = capsys.readouterr().err
    for w in words:
        assert w in err
    assert not out.exists()
