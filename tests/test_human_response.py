"""A device run says how its simulated wearer answers the device (issue 39 item 5).

The torque walker lowers its ankle feedforward by ``controller.assistance_adaptation`` × the
device torque, a written-in rule: its summary carries a ``human_response`` block naming the
rule and the value used, the console prints one line about it, and the figures comparing the
wearer's moments and powers across conditions say so in their titles. The muscle walker has
no such rule (``rule: None``, no console line, no title note). Adding the block changes no
result: the default run's numbers equal those with the default value given explicitly.
"""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import pytest
from matplotlib.figure import Figure

from afo_mj import cli
from afo_mj.gait.walk import ControllerParams

ROOT = Path(__file__).resolve().parents[1]
TORQUE = ROOT / "scenarios" / "gait_assist_hafo.toml"
MUSCLE = ROOT / "scenarios" / "gait_muscle_hafo.toml"
SHORT_TORQUE = ["--strides", "5", "--set", "gait.analyse_strides=[3, 5]"]
SHORT_MUSCLE = ["--strides", "4", "--set", "gait.analyse_strides=[2,4]"]
#: the figures whose curves are the wearer's own (muscle) moments and powers by condition
HUMAN_FIGURES = ("ankle_angle_conditions.png", "gait_conditions.png")


def _run(tmp_path: Path, name: str, scenario: Path, args, capsys, monkeypatch) -> dict:
    """Run through the CLI; returns the summary, stdout and each figure's suptitle."""
    titles: dict[str, str] = {}
    pending: list[str] = []
    orig_suptitle, orig_savefig = Figure.suptitle, Figure.savefig

    def suptitle(self, t, *a, **kw):
        pending.append(str(t))
        return orig_suptitle(self, t, *a, **kw)

    def savefig(self, fname, *a, **kw):
        titles[Path(str(fname)).name] = pending[-1] if pending else ""
        pending.clear()
        return orig_savefig(self, fname, *a, **kw)

    monkeypatch.setattr(Figure, "suptitle", suptitle)
    monkeypatch.setattr(Figure, "savefig", savefig)
    out = tmp_path / name
    capsys.readouterr()
    assert cli.main(["run", str(scenario), "--out", str(out), "--quiet", *args]) == 0
    stdout = capsys.readouterr().out
    monkeypatch.undo()
    summary = json.loads((out / "summary.json").read_text())
    return {"summary": summary, "stdout": stdout, "titles": titles}


def _default_adaptation() -> float:
    return next(f.default for f in dataclasses.fields(ControllerParams)
                if f.name == "assistance_adaptation")


@pytest.mark.slow
def test_torque_walker_names_its_written_in_rule(tmp_path, capsys, monkeypatch):
    r = _run(tmp_path, "half", TORQUE,
             [*SHORT_TORQUE, "--set", "controller.assistance_adaptation=0.5"], capsys,
             monkeypatch)
    s = r["summary"]
    hr = s["human_response"]
    assert hr["walker_model"] == "torque"
    assert hr["rule"] == "assistance_adaptation"
    assert hr["assistance_adaptation"] == 0.5           # the value the run was given
    assert s["scenario"]["controller_effective"]["assistance_adaptation"] == 0.5
    assert "written-in rule" in hr["note"]
    # console: one line right under the header, naming the value and the muscle walker
    lines = r["stdout"].splitlines()
    assert lines[0].startswith("afo_mj walk with hafo_gait")
    assert lines[1].startswith("  human response: written-in (torque walker, "
                               "assistance_adaptation = 0.5")
    assert 'walker.model = "muscle"' in lines[1]
    assert sum("human response" in ln for ln in lines) == 1
    # figures of the wearer's work across conditions say it; the device-only ones need not
    note = "(torque walker: feedforward lowered by 0.5 × device torque)"
    for name in HUMAN_FIGURES:
        assert note in r["titles"][name], name
    assert note not in r["titles"]["device_torque.png"]


def test_muscle_walker_has_no_rule(tmp_path, capsys, monkeypatch):
    r = _run(tmp_path, "muscle", MUSCLE, SHORT_MUSCLE, capsys, monkeypatch)
    hr = r["summary"]["human_response"]
    assert hr["walker_model"] == "muscle"
    assert hr["rule"] is None
    assert hr["assistance_adaptation"] is None
    assert "reflexes respond" in hr["note"]
    assert "human response" not in r["stdout"]
    for name in HUMAN_FIGURES:
        assert "feedforward lowered" not in r["titles"][name], name


@pytest.mark.slow
def test_default_results_unchanged(tmp_path, capsys, monkeypatch):
    """The default run names the default value, and every number equals (bitwise: the JSON
    text of each number) that of the run with the default given explicitly."""
    a = _default_adaptation()
    base = _run(tmp_path, "default", TORQUE, SHORT_TORQUE, capsys, monkeypatch)["summary"]
    expl = _run(tmp_path, "explicit", TORQUE,
                [*SHORT_TORQUE, "--set", f"controller.assistance_adaptation={a!r}"], capsys,
                monkeypatch)["summary"]
    assert base["human_response"]["assistance_adaptation"] == a == 1.0
    assert expl["human_response"] == base["human_response"]
    for key in ("gait", "human", "device", "energy", "device_conditions",
                "comparison_vs_no_device"):
        assert json.dumps(base[key], sort_keys=True) == json.dumps(expl[key], sort_keys=True), key
    assert base["scenario"]["controller_effective"] == expl["scenario"]["controller_effective"]


@pytest.mark.parametrize("block, expected", [
    ({"walker_model": "torque", "rule": "assistance_adaptation", "assistance_adaptation": 0.25},
     " (torque walker: feedforward lowered by 0.25 × device torque)"),
    ({"walker_model": "muscle", "rule": None, "assistance_adaptation": None}, ""),
    (None, ""),
])
def test_title_note_read_from_summary(block, expected):
    from afo_mj.outputs.console import human_response_line
    from afo_mj.outputs.device_figures import human_response_note
    summary = {} if block is None else {"human_response": block}
    assert human_response_note(summary) == expected
    lines = human_response_line(block)
    assert len(lines) == (1 if expected else 0)
    if expected:
        assert "assistance_adaptation = 0.25" in lines[0]
