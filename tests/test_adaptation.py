"""The adaptation protocol (afo_mj.studies.adaptation, ``afo-mj adapt``): convergence on
synthetic histories, the spread and the paired change against hand-computed values, the
refusals, and one tiny real run through the command (resumed once)."""

from __future__ import annotations

import json

import pytest

from afo_mj.app.errors import InvalidInput
from afo_mj.studies import adaptation as ad


def _history(bests):
    return [{"generation": i + 1, "best": b} for i, b in enumerate(bests)]


def test_a_plateau_converges_and_a_falling_cost_does_not():
    plateau = _history([6.0, 5.5, 5.3, 5.2] + [5.1] * 6 + [5.095])
    ok, why, change = ad.search_converged(plateau, window=5, tol=0.01)
    # the best after generation 6 (5.1) against the last (5.095)
    assert ok and change == pytest.approx(0.005) and "<= 0.01" in why
    falling = _history([6.0 - 0.02 * i for i in range(11)])
    ok, why, change = ad.search_converged(falling, window=5, tol=0.01)
    assert not ok and change == pytest.approx(0.10) and "> 0.01" in why
    # one plateau shorter than the window is no evidence
    ok, why, change = ad.search_converged(_history([5.0] * 5), window=5, tol=0.01)
    assert not ok and change is None and "needs 6" in why


def test_spread_and_paired_changes_by_hand():
    spread, pct = ad.rate_spread([5.00, 5.05, 4.98])
    assert spread == pytest.approx(0.07)
    assert pct == pytest.approx(100 * 0.07 / (15.03 / 3))          # 1.3972 %
    assert ad.rate_spread([5.0, None]) == (None, None)
    ch = ad.paired_changes([5.0, 5.1], [4.8, 4.9], best_control=1, best_condition=0)
    # 4.8/5.0 - 1 = -4 %; 4.9/5.1 - 1 = -3.9216 %
    assert ch["paired"] == pytest.approx([-4.0, -3.92157], abs=1e-5)
    assert ch["paired_mean"] == pytest.approx(-3.96078, abs=1e-5)
    assert ch["paired_spread"] == pytest.approx(0.07843, abs=1e-5)
    assert ch["best"] == pytest.approx(100 * (4.8 / 5.1 - 1))      # -5.882 %
    # every pairing: 4.8/5.1 (-5.88 %) … 4.9/5.0 (-2 %)
    assert ch["all_pairs_range"] == pytest.approx([100 * (4.8 / 5.1 - 1), -2.0])
    fell = ad.paired_changes([5.0, 5.1], [4.8, None], 0, 0)
    assert fell["paired"][1] is None and fell["paired_mean"] is None
    assert fell["paired_spread"] is None and fell["all_pairs_range"] is None


def test_group_estimates_by_hand():
    """Six restarts in two groups of three: each group's wearer is its lowest-cost restart,
    the spreads and the changes against the control group by group as worked by hand."""
    ctl = ad.group_estimates([5.0, 4.9, 5.2, 5.1, 5.3, 4.95],
                             [4.5, 4.4, 4.6, 4.45, 4.7, 4.42], 2)
    assert ctl["size"] == 3 and ctl["restarts"] == [[0, 1, 2], [3, 4, 5]]
    assert ctl["best_restart"] == [1, 5] and ctl["best_rate"] == [4.4, 4.42]
    assert ctl["best_spread_pct"] == pytest.approx(100 * 0.02 / 4.41)          # 0.4535 %
    assert ctl["mean_rate"] == pytest.approx([4.5, 13.57 / 3])
    assert ctl["mean_spread_pct"] == pytest.approx(0.51718, abs=1e-5)
    assert "change_pct_best" not in ctl
    dev = ad.group_estimates([5.0, 5.1, 4.8, 4.7, 5.0, 5.2],
                             [4.3, 4.2, 4.35, 4.25, 4.5, 4.3], 2, ctl)
    assert dev["best_restart"] == [2, 3]
    # 4.35 / 4.4 - 1 = -1.13636 %; 4.25 / 4.42 - 1 = -3.84615 %
    assert dev["change_pct_best"] == pytest.approx([-1.13636, -3.84615], abs=1e-5)
    assert dev["change_pct_best_mean"] == pytest.approx(-2.49126, abs=1e-5)
    assert dev["change_pct_best_spread"] == pytest.approx(2.70979, abs=1e-5)
    # group means 4.28333 / 4.5 - 1 = -4.81481 %; 4.35 / 4.52333 - 1 = -3.83198 %
    assert dev["change_pct_mean"] == pytest.approx([-4.81481, -3.83198], abs=1e-5)
    assert dev["change_pct_mean_spread"] == pytest.approx(0.98283, abs=1e-5)
    fell = ad.group_estimates([5.0, 4.9, 5.2, 5.1], [4.5, None, 4.6, 4.45], 2)
    assert fell["best_rate"] == [None, 4.45] and fell["best_spread_pct"] is None
    assert fell["mean_rate"][0] is None and fell["mean_spread_pct"] is None
    with pytest.raises(ValueError, match="a divisor"):
        ad.group_estimates([5.0, 4.9, 5.2], [4.5, 4.4, 4.6], 2)


def test_protocol_and_command_refusals(tmp_path):
    with pytest.raises(ValueError, match=r"restarts = 0; allowed: an integer 1"):
        ad.AdaptationProtocol(restarts=0)
    with pytest.raises(ValueError, match="settle_s"):
        ad.AdaptationProtocol(search_walk_s=3.5)
    with pytest.raises(ValueError, match=r"groups = 4 with restarts = 9; allowed: a divisor "
                                         r"of restarts \(1, 3, 9\)"):
        ad.AdaptationProtocol(restarts=9, groups=4)
    from afo_mj.app.adaptation import adapt
    with pytest.raises(InvalidInput, match=r"--restarts = 0; allowed"):
        adapt(["clutched_spring"], tmp_path / "a", restarts=0)
    with pytest.raises(InvalidInput, match=r"--groups = 2 with restarts = 3; allowed"):
        adapt(["clutched_spring"], tmp_path / "a", groups=2)
    from afo_mj.studies.hil_tuning import HilProtocol
    with pytest.raises(ValueError, match=r"adaptation.groups = 3; allowed: 1"):
        HilProtocol(adaptation=ad.AdaptationProtocol(groups=3))
    with pytest.raises(InvalidInput, match=r"condition 'spring'; allowed: none, worn_mass"):
        adapt(["spring"], tmp_path / "b")
    with pytest.raises(InvalidInput, match="repeat"):
        adapt(["zhang", "zhang"], tmp_path / "c")
    with pytest.raises(InvalidInput, match="one scenario file alone"):
        adapt(["none", "scenarios/gait_assist_hafo.toml"], tmp_path / "d")
    with pytest.raises(InvalidInput, match="--start"):
        adapt(["none"], tmp_path / "e", start=str(tmp_path / "missing.json"))
    assert not any((tmp_path / n).exists() for n in "abcde")


def test_a_folder_of_other_settings_is_refused(tmp_path):
    conds = ad.assistance_conditions(["clutched_spring"], ad.AdaptationProtocol())
    assert [c.name for c in conds] == ["none", "clutched_spring"]      # the control first
    (tmp_path / "adaptation_protocol.json").write_text(json.dumps({"popsize": 8}))
    from afo_mj.app.adaptation import DEFAULT_START
    with pytest.raises(ValueError, match="popsize = 8; given 16"):
        ad.adapt_conditions(tmp_path, conds, DEFAULT_START, ad.AdaptationProtocol())


@pytest.mark.slow
def test_tiny_protocol_run_through_the_command_and_resumed(tmp_path, capsys):
    """2 restarts x 2 generations x 4 walks of 5 s, the control and the clutched spring; the
    rates reported are those of the best sets walked again here by the assistance module, and
    a second run with one generation more continues every search."""
    from afo_mj.cli import main
    from afo_mj.experiments.muscle_assistance import (Assistance, assistance_summary,
                                                      assistance_walk)
    from afo_mj.studies.gait_optimization import load_reflex_set
    out = tmp_path / "adapt"
    argv = ["adapt", "clutched_spring", "--out", str(out), "--restarts", "2", "--popsize", "4",
            "--search-walk-s", "5", "--score-walk-s", "5", "--workers", "1", "--window", "1",
            "--groups", "2", "--quiet"]
    assert main(argv + ["--generations", "2"]) == 0
    res = ad.AdaptationResult.from_json(json.loads((out / "adaptation.json").read_text()))
    assert [c.name for c in res.conditions] == ["none", "clutched_spring"]
    assert res.walks == 2 * 2 * 2 * 4
    rates = {}
    for c in res.conditions:
        for r in c.restarts:
            walk, dev = assistance_walk(Assistance(c.name), None,
                                        load_reflex_set(out / c.name / f"restart{r.restart}"
                                                        / "reflex_params.json"), 5.0)
            s = assistance_summary(walk, 3.0, dev)
            want = None if s["fell_s"] is not None else s.get("net_metabolic_w_per_kg")
            assert r.net_metabolic_w_per_kg == (None if want is None
                                                else pytest.approx(want, rel=1e-12))
            rates[c.name, r.restart] = want
    spring = res.condition("clutched_spring")
    for i, x in enumerate(spring.change_pct_paired):
        c0, c1 = rates["none", i], rates["clutched_spring", i]
        assert x == (None if c0 is None or c1 is None else pytest.approx(100 * (c1 / c0 - 1)))
    # groups of one restart: each group's wearer is its restart, changed as paired
    assert list(spring.groups["best_rate"]) == [rates["clutched_spring", 0],
                                                rates["clutched_spring", 1]]
    assert list(spring.groups["change_pct_best"]) == list(spring.change_pct_paired)
    assert "change_pct_best" not in res.condition("none").groups
    printed = capsys.readouterr().out
    assert "afo-mj adapt: 2 conditions x 2 restarts" in printed
    assert "best of 1 in 2 groups" in printed and "vs none by group, best of 1" in printed
    assert main(argv + ["--generations", "3"]) == 0
    res2 = ad.AdaptationResult.from_json(json.loads((out / "adaptation.json").read_text()))
    assert res2.walks == 2 * 2 * 3 * 4
    assert all(r.generations == 3 for c in res2.conditions for r in c.restarts)
    assert all(r.cpu_s is not None and r.cpu_s > 0 for c in res2.conditions
               for r in c.restarts)
    # another step on the same folder is refused before any walk
    assert main(argv + ["--generations", "3", "--sigma0", "0.1"]) == 2


def test_a_scenario_s_conditions_with_the_control_first():
    from pathlib import Path
    root = Path(__file__).resolve().parents[1]
    conds, start = ad.scenario_conditions(root / "scenarios" / "gait_muscle_clutched_spring.toml",
                                          ad.AdaptationProtocol(search_walk_s=8.0))
    assert [c.name for c in conds] == ["no_device", "assist"]
    assert [c.objective.scenario.condition for c in conds] == ["no_device", "assist"]
    assert all(c.objective.duration_s == 8.0 and c.objective.tracking_weight == 0.25
               for c in conds)
    assert start.endswith("clutched_spring.json")
    with pytest.raises(InvalidInput, match="walker.model"):
        from afo_mj.app.adaptation import adapt
        adapt([str(root / "scenarios" / "gait_assist_hafo.toml")], "unused")


def _square(x):
    if x < 0:
        raise ArithmeticError(f"negative {x}")
    return x * x


def test_generations_walk_on_a_dask_client():
    """evaluate_batch's Dask branch: results in input order, a task's error kept with its
    item (an in-process cluster: no worker processes to start)."""
    from distributed import Client

    from afo_mj.studies.gait_optimization import evaluate_batch
    with Client(processes=False, n_workers=1, threads_per_worker=2,
                dashboard_address=None) as client:
        res = evaluate_batch(_square, [3, -1, 2], client=client)
    assert [r.value for r in res] == [9, None, 4]
    assert isinstance(res[1].error, ArithmeticError) and not res[1].ok


def test_a_folder_with_other_settings_is_refused_by_name(tmp_path):
    """The one refusal the adaptation, dose-response and HIL studies share: a saved setting
    that differs is named with both values; a key the saved file lacks is refused unless
    the caller allows it (a folder written before that setting existed)."""
    from afo_mj.studies.adaptation import refuse_other_settings
    with pytest.raises(ValueError, match=r"holds a study with popsize = 8; given 16; allowed"):
        refuse_other_settings(tmp_path, {"popsize": 8, "seed": 1}, {"seed": 1, "popsize": 16},
                              "a study")
    with pytest.raises(ValueError, match=r"with groups = None; given 2"):
        refuse_other_settings(tmp_path, {"seed": 1}, {"seed": 1, "groups": 2}, "searches")
    refuse_other_settings(tmp_path, {"seed": 1}, {"seed": 1, "groups": 2}, "searches",
                          absent_ok=True)
    refuse_other_settings(tmp_path, {"seed": 1, "x": 2}, {"seed": 1}, "searches")
