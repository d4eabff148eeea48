"""Blind calibration of the second independent rig's clean records (tests/second_rig.py,
its datasheet description scenarios/calibration/second_rig.toml): ``no_missing_effect`` with
every channel within 2× its noise floor, with the rig's compliant cable and with a rigid one.
The rig's physics against analytic references: tests/test_second_rig.py; its effects:
tests/test_second_rig_effects.py.
"""

from __future__ import annotations

import dataclasses
import warnings
from pathlib import Path

import pytest

import second_rig as R

ROOT = Path(__file__).resolve().parents[1]
SCENARIO = ROOT / "scenarios" / "calibration" / "second_rig.toml"
P = R.Rig2Params()

CAL_DURATION_S = 6.0


def _calibrate(tmp_path, rigid_cable: bool, effects=None):
    from afo_mj.calibration.calibrate import calibrate_setup, load_calibration_scenario
    from afo_mj.calibration.measured_data import load_measured
    prm = dataclasses.replace(P, cable_stiffness_n_m=1.5e9) if rigid_cable else P
    path = R.write_record(tmp_path / "r.csv", CAL_DURATION_S, effects=effects, seed=5,
                          params=prm)
    scn = SCENARIO
    if rigid_cable:
        scn = tmp_path / "rigid.toml"
        text = SCENARIO.read_text(encoding="utf-8")
        assert "series_compliance_rad_per_nm = 5.442e-4" in text
        scn.write_text(text.replace("series_compliance_rad_per_nm = 5.442e-4",
                                    "series_compliance_rad_per_nm = 0.0"), encoding="utf-8")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        rep = calibrate_setup(load_measured(path), load_calibration_scenario(str(scn)))
    floor = rep["baseline"]["noise_floor"]
    final = {c: rep["error_after"][c] / floor[c] for c in floor}
    print(rep["verdict"], {c: round(v, 2) for c, v in final.items()})
    return rep, final


@pytest.mark.slow
def test_clean_record_reaches_the_noise_floor(tmp_path):
    """The clean record of the rig as built (a steel rope of 1.5 MN/m, declared): what it
    should give, ``no_missing_effect`` with every channel within 2× its noise floor. The
    rig's 20 N of seal friction stretches the rope (0.76 mrad at the ankle at each
    reversal); the described series compliance stretches with the cable's force, the seal
    friction included (measured: worst channel 1.26×, the angle 1.23×; before, with the
    hydraulic torque only, structure_wrong and the angle at 2.29×)."""
    rep, final = _calibrate(tmp_path, rigid_cable=False)
    assert rep["verdict"] == "no_missing_effect" and rep["effects_selected"] == []
    assert max(final.values()) <= 2.0, final
    # nothing named: no declared value beyond its tolerance (at the replay's 0.5 ms the fit
    # moved the motor inductance -32 % to absorb the stepper's error; the step is now chosen
    # by the numerical check before the fit, issue 41)
    assert rep["declared_deviations"] == [], rep["declared_deviations"]
    assert rep["replay_step"]["source"] == "numerical_check" and rep["replay_step"]["reached"]


@pytest.mark.slow
def test_clean_record_with_a_rigid_cable_reaches_the_noise_floor(tmp_path):
    """The same bench with a rigid cable (k = 1.5 GN/m, described with no series compliance):
    ``no_missing_effect``, nothing named, every channel within 2× its noise floor, and the
    fitted seal Coulomb force within 5 % of the rig's 20 N (12 + 2 × 4 N)."""
    rep, final = _calibrate(tmp_path, rigid_cable=True)
    assert rep["hold_warnings"] == [] and rep["record_flags"] == []
    assert rep["verdict"] == "no_missing_effect" and rep["effects_selected"] == []
    assert rep["declared_deviations"] == [], rep["declared_deviations"]
    assert max(final.values()) <= 2.0, final
    # the seals' total Coulomb force, packed from the fitted described values (each seal's
    # O-ring figures) as the circuit packs it
    from afo_mj.calibration.calibrate import load_calibration_scenario
    from afo_mj.calibration.declared_set import described_parameters
    scn = tmp_path / "rigid.toml"
    ds = described_parameters(load_calibration_scenario(str(scn)).replay())
    fitted = {k: v for k, v in rep["declared_fit"].items() if k.startswith("cylinder.")}
    fc = ds.row(fitted).get("cylinder.seal_fc", ds._base["cylinder.seal_fc"])
    assert fc == pytest.approx(20.0, rel=0.05)
