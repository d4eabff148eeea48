"""Typed result documents (afo_mj.metrics.documents): summary.json written from them equals,
byte for byte, what the code wrote before they existed (tests/golden/summary_*.json, made by
`afo-mj run <scenario> --strides 2` on the commit before the documents came in; the runs are
deterministic, so floats are compared exactly), and from_json refuses a malformed document
naming the key."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from afo_mj.app.run import DeviceWalkRun, WalkRun, run_scenario
from afo_mj.metrics.documents import (DocumentError, EnergyLedger, GaitSummary, WalkSummary,
                                      WornCondition)

ROOT = Path(__file__).resolve().parents[1]
GOLDEN = ROOT / "tests" / "golden"
CASES = {"walk_healthy": WalkRun, "gait_assist_hafo": DeviceWalkRun,
         "gait_pump_accumulator": DeviceWalkRun}


def _golden(name: str) -> str:
    return (GOLDEN / f"summary_{name}_strides2.json").read_text(encoding="utf-8")


@pytest.mark.parametrize("name", list(CASES))
def test_summary_json_equals_the_golden_file(name, tmp_path, monkeypatch):
    out = tmp_path / "out"
    monkeypatch.chdir(ROOT)             # the summary names the scenario file as given
    res = run_scenario(f"scenarios/{name}.toml", strides=2, out_dir=out, figures=False)
    assert isinstance(res, CASES[name]) and isinstance(res.summary, WalkSummary)
    text = (out / "summary.json").read_text(encoding="utf-8")
    want = _golden(name)
    assert json.loads(text) == json.loads(want)      # key for key, floats exactly
    assert text == want                              # and in the same order and layout
    # the typed fields say what the file says
    data = json.loads(want)
    assert res.summary.gait.mean("speed_m_s") == data["speed_m_s"]["mean"]
    if res.summary.device is not None:
        head = res.summary.device.headline
        assert head.device.peak_torque_nm == data["device"]["peak_torque_nm"]
        assert head.energy.electrical_in_j == data["energy"]["electrical_in_j"]


@pytest.mark.parametrize("name", list(CASES))
def test_golden_files_round_trip_through_the_documents(name):
    data = json.loads(_golden(name))
    doc = WalkSummary.from_json(data)
    assert doc.to_json() == data
    assert json.dumps(doc.to_json(), indent=2) + "\n" == _golden(name)
    gait = GaitSummary.from_json(doc.gait.to_json())
    assert gait == doc.gait
    if doc.device is not None:
        for c, cond in doc.device.device_conditions.items():
            assert data["device_conditions"][c] == cond.to_block()
            again = WornCondition.from_json(cond.to_json())
            assert again.to_json()["format"] == "afo_mj worn condition v1"
            assert again.to_block() == data["device_conditions"][c]


def test_from_json_names_the_bad_key():
    data = json.loads(_golden("gait_assist_hafo"))
    bad = dict(data, format="afo_mj gait summary v0")
    with pytest.raises(DocumentError, match=r"format = 'afo_mj gait summary v0'; allowed"):
        WalkSummary.from_json(bad)
    bad = {k: v for k, v in data.items() if k != "duration_s"}
    with pytest.raises(DocumentError, match="missing key.*'duration_s'"):
        WalkSummary.from_json(bad)
    bad = dict(data, stride_speed=1.0)
    with pytest.raises(DocumentError, match="unknown key.*'stride_speed'"):
        WalkSummary.from_json(bad)
    bad = json.loads(json.dumps(data))
    bad["device_conditions"]["assist"]["device"]["newton_unconverged_steps"] = "none"
    with pytest.raises(DocumentError, match=r"device_conditions.assist.device."
                                            r"newton_unconverged_steps = 'none'"):
        WalkSummary.from_json(bad)
    bad = json.loads(json.dumps(data))
    bad["energy"]["electrical_in_j"] += 1.0           # the headline differs from its block
    with pytest.raises(DocumentError, match=r"energy differs from device_conditions"):
        WalkSummary.from_json(bad)
    with pytest.raises(DocumentError, match="residual_moment_rms_nm: over_analysed_span"):
        g = json.loads(json.dumps(data["gait"]))
        del g["residual_moment_rms_nm"]["over_analysed_span"]
        GaitSummary.from_json(g)


def test_energy_ledger_document_of_a_circuit_device_balances():
    """A described circuit's ledger as a document: every key kept, the keys it does not
    report None, and the balance input = out + losses + stores + residual holds on the
    document's own numbers (a relation the ledger is built to keep)."""
    import numpy as np
    from afo_mj.circuits.device import CircuitDevice
    from afo_mj.circuits.library import pump_accumulator
    dev = CircuitDevice(pump_accumulator())
    cmd = -15.0 * np.sin(np.linspace(0, 2 * np.pi, 400)) ** 2    # plantarflexion torque
    dev.run_load(cmd, inertia_kg_m2=0.02, stiffness_nm_rad=80.0, damping_nm_s_rad=0.5)
    led = dev.ledger(0)
    assert led["input_j"] > 0.0
    doc = EnergyLedger.from_ledger(led, tuple(dev.spec.ledger_extras))
    assert EnergyLedger.from_json(doc.to_json()) == doc
    assert doc.input_j == led["input_j"] and doc.losses_j == led["losses_j"]
    assert doc.source is None and doc.battery_energy_wh is None
    total = (doc.mechanical_out_j + sum(doc.losses_j.values())
             + sum(doc.stored_change_j.values()) + doc.residual_j)
    assert total == pytest.approx(doc.input_j, rel=1e-12, abs=1e-15)
    with pytest.raises(DocumentError, match="unknown key.*'extra_figure'"):
        EnergyLedger.from_ledger({**led, "extra_figure": 1.0})


def test_calibration_report_golden_round_trips_byte_for_byte():
    """report.json of a real calibration (a 3 s synthetic hafo record, seed 1, made on the
    commit before the document; its "data" path shortened to rec.csv) read into the document
    and written again gives the same text; the headline is typed."""
    from afo_mj.calibration.report_document import CalibrationReport
    text = (GOLDEN / "report_hafo_synthetic_3s.json").read_text(encoding="utf-8")
    data = json.loads(text)
    doc = CalibrationReport.from_json(data)
    assert json.dumps(doc.to_json(), indent=2, allow_nan=False, ensure_ascii=False) + "\n" \
        == text
    assert doc.verdict == data["verdict"] and doc.preset == "hafo"
    assert doc.error_before["overall"] == data["error_before"]["overall"]
    assert doc.details["wall_time_s"] == data["wall_time_s"]
    with pytest.raises(DocumentError, match="format = 'afo_mj calibration report v2'"):
        CalibrationReport.from_json(dict(data, format="afo_mj calibration report v2"))
    with pytest.raises(DocumentError, match="missing key.*'verdict'"):
        CalibrationReport.from_json({k: v for k, v in data.items() if k != "verdict"})
    with pytest.raises(DocumentError, match=r"error_drop = 'big'; allowed: number"):
        CalibrationReport.from_json(dict(data, error_drop="big"))


def test_calibration_report_file_is_written_from_the_document(tmp_path):
    """write_calibration_report's report.json is CalibrationReport.from_report(...).to_json():
    a report whose verdict is no string is refused naming the key, nothing written."""
    from test_calibration_report import make_report

    from afo_mj.outputs.calibration_report import write_calibration_report
    rep = make_report(with_series=False)
    files = write_calibration_report(rep, tmp_path / "ok", data_path="rec.csv", command="c")
    data = json.loads(files["report.json"].read_text(encoding="utf-8"))
    assert list(data)[:3] == ["format", "data", "command"] and data["data"] == "rec.csv"
    with pytest.raises(DocumentError, match=r"calibration report.verdict = 3"):
        write_calibration_report(dict(rep, verdict=3), tmp_path / "bad")
    assert not (tmp_path / "bad").exists()


@pytest.mark.parametrize("scenario, overrides", [
    ("bench_hafo.toml", ['bench.protocols=["isometric_steps"]']),
    ("bench_lab_bench.toml", ['bench.protocols=["torque_velocity"]']),
])
def test_bench_summary_is_written_from_its_document(tmp_path, scenario, overrides):
    """Issue 40 item 4: a bench's summary.json is its BenchSummary document, equal key for key
    and value for value to the summary the bench run assembled (the load rig's keys come in
    the document's order: device after bench), read back by from_json to the same JSON; a
    summary with a key the document does not declare is refused naming it."""
    import json

    from afo_mj.app.run import run_scenario
    from afo_mj.metrics.documents import BenchSummary, DocumentError
    from afo_mj.outputs.gait_report import json_ready
    root = Path(__file__).resolve().parents[1] / "scenarios"
    res = run_scenario(root / scenario, overrides=overrides, out_dir=tmp_path / "b",
                       figures=False)
    written = json.loads((tmp_path / "b" / "summary.json").read_text(encoding="utf-8"))
    assert written == json.loads(json.dumps(json_ready(res.summary)))
    assert written["format"] == BenchSummary.FORMAT == res.document.FORMAT
    assert BenchSummary.from_json(written).to_json() == written
    with pytest.raises(DocumentError, match="unknown key.*'bogus'"):
        BenchSummary.from_json({**written, "bogus": 1})
