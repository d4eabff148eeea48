"""``afo-mj compare`` on the muscle walker (issue 39, item 3): device scenarios worn by the
muscle-driven walker are ranked side by side by the change of the wearer's net metabolic rate
against the same wearer walking without a device, and by the battery energy drawn per stride.

The reference is independent of compare's path: ``afo-mj run`` of each row's own scenario
(its ``no_device`` and ``assist`` conditions), whose summary holds the wearer's metabolic
rates and ``comparison_vs_no_device``; the ranks and caveats of synthetic rows are checked
against orderings worked out by hand.
"""

from __future__ import annotations

import csv
import json
import math
import types
from pathlib import Path

import pytest

from afo_mj.experiments import device_comparison as dc
from afo_mj.outputs import comparison_report as cr
from cli_helpers import csv_number, run_cli

SCEN = Path(__file__).resolve().parents[1] / "scenarios"
HAFO = SCEN / "gait_muscle_hafo.toml"
SPRING = SCEN / "gait_spring_return.toml"
TORQUE_HAFO = SCEN / "gait_assist_hafo.toml"
SHORT = ["--strides", "5", "--set", "gait.analyse_strides=[3, 5]"]
MUSCLE = ["--set", "walker.model=muscle", "--set", "walker.reflex_set=adapted/hafo"]
EFFORT_COLUMNS = ("walker_model", "net_metabolic_umberger_w_per_kg",
                  "net_metabolic_umberger_change_pct", "net_metabolic_bhargava_change_pct",
                  "rank_metabolic", "rank_battery_energy")




def _csv(out: Path) -> dict:
    with (out / "comparison.csv").open(encoding="utf-8") as f:
        return {r["label"]: r for r in csv.DictReader(f)}


@pytest.fixture(scope="module")
def compared(tmp_path_factory):
    out = tmp_path_factory.mktemp("cmp_muscle") / "cmp"
    rc, stdout, stderr = run_cli(["compare", str(HAFO), str(SPRING), "--out", str(out),
                                *MUSCLE, *SHORT])
    assert rc == 0, stderr
    return out, _csv(out), stdout


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    """``afo-mj run`` of each scenario, no device and assist, the same wearer and strides."""
    tmp = tmp_path_factory.mktemp("run_muscle")
    out = {}
    for name, path in (("gait_muscle_hafo", HAFO), ("gait_spring_return", SPRING)):
        d = tmp / name
        rc, _, err = run_cli(["run", str(path), "--out", str(d), *MUSCLE, *SHORT, "--set",
                            'device.conditions=["no_device", "assist"]'])
        assert rc == 0, err
        out[name] = json.loads((d / "summary.json").read_text(encoding="utf-8"))
    return out


@pytest.mark.slow
def test_rows_carry_the_wearers_effort_as_afo_mj_run_reports_it(compared, runs):
    out, rows, _ = compared
    assert set(rows) == {"gait_muscle_hafo", "gait_spring_return"}
    doc = json.loads((out / "comparison.json").read_text(encoding="utf-8"))
    for c in EFFORT_COLUMNS:
        assert c in doc["columns"]
    for label, r in rows.items():
        s = runs[label]
        conds = s["device_conditions"]
        assert r["walker_model"] == "muscle" and s["scenario"]["walker_model"] == "muscle"
        assert r["fell"] == "false" and not conds["assist"]["fell"]
        with_dev = conds["assist"]["muscle"]
        without = conds["no_device"]["muscle"]
        for model in ("umberger", "bhargava"):
            rate, base = csv_number(r[f"net_metabolic_{model}_w_per_kg"]), \
                csv_number(r[f"net_metabolic_{model}_no_device_w_per_kg"])
            # the row's own figures: with the device, and this wearer without one
            assert rate == pytest.approx(with_dev[f"net_metabolic_{model}_w_per_kg"],
                                         rel=1e-12)
            assert base == pytest.approx(without[f"net_metabolic_{model}_w_per_kg"],
                                         rel=1e-12)
            change = csv_number(r[f"net_metabolic_{model}_change_pct"])
            assert change == pytest.approx(100.0 * (rate - base) / base, rel=1e-12)
            assert change == pytest.approx(
                s["comparison_vs_no_device"]["assist"][f"net_metabolic_{model}_change_pct"],
                rel=1e-9)
        # the battery energy is the run's assist energy per stride
        assert csv_number(r["electrical_j_per_stride"]) == pytest.approx(
            conds["assist"]["energy_per_stride"]["electrical_in_j"], rel=1e-12)
        assert csv_number(r["human_ankle_positive_work_no_device_j_per_stride"]) == pytest.approx(
            conds["no_device"]["human"]["ankle_positive_work_j_per_stride"], rel=1e-12)
        assert r["no_device_fall_time_s"] == ""


@pytest.mark.slow
def test_ranks_order_the_rows_by_metabolic_change_and_by_battery_energy(compared):
    _, rows, stdout = compared
    rs = list(rows.values())
    by_change = sorted(rs, key=lambda r: csv_number(r["net_metabolic_umberger_change_pct"]))
    assert [int(r["rank_metabolic"]) for r in by_change] == [1, 2]
    by_energy = sorted(rs, key=lambda r: csv_number(r["electrical_j_per_stride"]))
    assert [int(r["rank_battery_energy"]) for r in by_energy] == [1, 2]
    # the existing ranking is kept (neither device is an actuator on this walk: no rank)
    assert all(r["efficiency_rank"] == "" for r in rs)
    # the headline tables show the effort beside the battery energy, with both ranks
    assert "the wearer's effort (muscle walker) and the battery energy:" in stdout
    assert "rank metabolic" in stdout and "rank battery energy" in stdout
    assert "NO EFFORT MODEL" not in stdout and "METABOLIC CHANGE ON A FALL" not in stdout
    md = (compared[0] / "comparison.md").read_text(encoding="utf-8")
    assert "## The wearer's effort (muscle walker) and the battery energy" in md
    effort = stdout.split("the wearer's effort (muscle walker) and the battery energy:")[1]
    for r in rs:
        line = next(x for x in effort.splitlines() if x.startswith(r["label"] + " "))
        assert f"{csv_number(r['net_metabolic_umberger_change_pct']):+.2f}" in line


@pytest.mark.slow
def test_a_compare_mixing_the_walkers_ranks_effort_among_muscle_rows_only(tmp_path, runs):
    out = tmp_path / "mixed"
    rc, stdout, err = run_cli(["compare", str(HAFO), str(TORQUE_HAFO), "--out", str(out),
                             *SHORT])
    assert rc == 0, err
    rows = _csv(out)
    m, t = rows["gait_muscle_hafo"], rows["gait_assist_hafo"]
    assert m["walker_model"] == "muscle" and t["walker_model"] == "torque"
    for c in ("net_metabolic_umberger_w_per_kg", "net_metabolic_umberger_change_pct",
              "net_metabolic_bhargava_change_pct", "rank_metabolic", "rank_battery_energy"):
        assert t[c] == "", c
    assert m["rank_metabolic"] == "1" and m["rank_battery_energy"] == "1"
    # the torque walker's written-in response is named on its row (the default 1.0 of
    # ControllerParams); the muscle walker has none
    from afo_mj.gait.walk import ControllerParams
    assert csv_number(t["assistance_adaptation"]) == ControllerParams().assistance_adaptation
    assert m["assistance_adaptation"] == ""
    # the muscle row's reference is its own wearer's no-device walk (the scenario's own
    # walker, not the torque walker's), as afo-mj run walks it
    ref = runs["gait_muscle_hafo"]["device_conditions"]["no_device"]
    assert csv_number(m["net_metabolic_umberger_no_device_w_per_kg"]) == pytest.approx(
        ref["muscle"]["net_metabolic_umberger_w_per_kg"], rel=1e-12)
    assert csv_number(m["human_ankle_positive_work_no_device_j_per_stride"]) == pytest.approx(
        ref["human"]["ankle_positive_work_j_per_stride"], rel=1e-12)
    assert csv_number(t["human_ankle_positive_work_no_device_j_per_stride"]) != pytest.approx(
        ref["human"]["ankle_positive_work_j_per_stride"], rel=1e-3)
    line = next(x for x in stdout.splitlines() if x.startswith("NO EFFORT MODEL"))
    assert "gait_assist_hafo" in line and "gait_muscle_hafo" not in line
    assert "NO EFFORT MODEL: gait_assist_hafo" in (out / "comparison.md").read_text()


# ---------------------------------------------------------------------------- synthetic rows

def _item(name: str, model: str = "muscle"):
    sc = types.SimpleNamespace(name=name, walker_model=model)
    return dc.CompareItem(0, f"{name}.toml", sc, None,
                          types.SimpleNamespace(preset="p", sides=("right",)), "")


def _block(elec: float, rate: float | None, fell_at: float | None = None):
    """A condition block: ``elec`` J drawn per stride, net metabolic rate ``rate`` W/kg by
    both models (None: no analysed stride, no muscle block)."""
    muscle = (None if rate is None else
              {"net_metabolic_umberger_w_per_kg": rate,
               "net_metabolic_bhargava_w_per_kg": 0.5 * rate})
    return {"fell": fell_at is not None, "fall_time_s": fell_at,
            "device": {}, "energy": {"run_duration_s": 10.0, "mechanical_out_j": 10.0},
            "energy_per_stride": {"stride_time_s": 1.0, "electrical_in_j": elec,
                                  "mechanical_positive_out_j": 1.0, "losses_j": {}},
            "human": {"ankle_positive_work_j_per_stride": 5.0}, "ankle": {}, "gait": None,
            "muscle": muscle}


def _record(fell_at):
    return types.SimpleNamespace(events=types.SimpleNamespace(fall_time_s=fell_at))


def test_effort_ranks_and_caveats_of_falls_and_missing_strides():
    base = _block(0.0, 4.0)                           # the wearer's no-device walk
    base_fell = _block(0.0, 4.0, fell_at=2.5)         # a wearer whose no-device walk fell

    def row(name, elec, rate, fell_at=None, ref=base, model="muscle"):
        return dc.comparison_row(_item(name, model), _block(elec, rate, fell_at),
                                 _record(fell_at), no_device=ref)

    rows = dc.order_rows([
        row("a", 12.0, 3.6),                          # -10 %
        row("b", 9.0, 3.2, fell_at=3.2),              # -20 %, but it fell
        row("c", 11.0, None),                         # no analysed stride
        row("d", 8.0, 3.0, model="torque"),           # no effort model
        row("e", 10.0, 4.2),                          # +5 %
        row("f", 14.0, 3.4, ref=base_fell),           # -15 % against a walk that fell
    ])
    r = {x["label"]: x for x in rows}
    assert r["a"]["net_metabolic_umberger_change_pct"] == pytest.approx(-10.0)
    assert r["a"]["net_metabolic_bhargava_change_pct"] == pytest.approx(-10.0)
    assert r["e"]["net_metabolic_umberger_change_pct"] == pytest.approx(5.0)
    assert r["f"]["net_metabolic_umberger_change_pct"] == pytest.approx(-15.0)
    assert math.isnan(r["c"]["net_metabolic_umberger_change_pct"])
    assert r["d"]["net_metabolic_umberger_change_pct"] is None
    assert r["d"]["net_metabolic_umberger_w_per_kg"] is None
    # metabolic: only a and e qualify (b fell, c has no stride, d is torque, f's reference fell)
    assert {k: v["rank_metabolic"] for k, v in r.items()} == {
        "a": 1, "b": None, "c": None, "d": None, "e": 2, "f": None}
    # battery: the muscle rows that did not fall, least energy first: e 10, c 11, a 12, f 14
    assert {k: v["rank_battery_energy"] for k, v in r.items()} == {
        "a": 3, "b": None, "c": 2, "d": None, "e": 1, "f": 4}
    notes = cr.effort_caveats(rows)
    assert notes[0].startswith("NO EFFORT MODEL: d:")
    text = "\n".join(notes)
    assert "METABOLIC CHANGE ON A FALL: b: the walker fell at 3.20 s" in text
    assert "-20.00 %" in text and "not ranked" in text
    assert "METABOLIC CHANGE ON A FALL: f: the same wearer's no-device walk fell at 2.50 s" in text
    assert "NO ANALYSED STRIDE: c:" in text
    assert not any(n.split(":")[1].strip() in ("a", "e") for n in notes)
    comp = dc.Comparison(rows, dc.all_columns(rows), [{"file": "a.toml"}])
    for doc in (cr.format_tables(comp), cr._markdown_report(comp)):
        assert "NO EFFORT MODEL: d" in doc and "METABOLIC CHANGE ON A FALL: b" in doc


def test_torque_only_compare_has_no_effort_table_or_lines():
    rows = dc.order_rows([dc.comparison_row(_item("t", "torque"), _block(5.0, None))])
    assert rows[0]["rank_metabolic"] is None and rows[0]["rank_battery_energy"] is None
    comp = dc.Comparison(rows, dc.all_columns(rows), [{"file": "t.toml"}])
    text = cr.format_tables(comp)
    assert "wearer's effort" not in text and "NO EFFORT MODEL" not in text
    assert cr.effort_caveats(rows) == []


def test_compare_takes_every_kind_of_assist_command():
    """The assist condition may be commanded by a torque profile or (the ideal device) a
    clutched spring: compare loads both (it refused all but a profile)."""
    from afo_mj.experiments.device_comparison import load_compare_items
    for name in ("gait_muscle_clutched_spring.toml", "gait_muscle_ideal_zhang.toml"):
        path = SCEN / name
        if not path.exists():
            pytest.skip(f"{name} not shipped")
        items = load_compare_items([str(path)], strides=3)
        assert items and all(it.cfg.conditions == ("assist",) for it in items), name
