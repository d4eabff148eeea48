"""Blind calibration of the second independent rig with one effect on (tests/second_rig.py,
its datasheet description scenarios/calibration/second_rig.toml): a softer cable fitted as the
cable, backlash on the simulated load named (issue 41, items 2 and 4).
"""

from __future__ import annotations

import dataclasses
import warnings

import pytest

import second_rig as R
from test_second_rig_blind import P, SCENARIO, _calibrate


@pytest.mark.slow
def test_a_softer_cable_is_fitted_as_the_cable(tmp_path):
    """Issue 41 item 2: the rig's rope replaced by one 5× softer (300 kN/m, the rig's
    ``softer_cable``) while the description keeps the datasheet 1.5 MN/m. The cable's
    compliance is a declared value like any other, so the calibration fits it, named as the
    cable (``cylinder.series_compliance_rad_per_nm``), within its ±30 % tolerance of the truth
    1/(r² k) (it was absent from the fixed declared list, and the oil's bulk modulus was
    lowered instead: −70 % in the user's trial), reported beyond its tolerance; the bulk
    modulus stays within its tolerance and every channel within 2× its floor (measured on
    2026-11-28: 2.66e-3 against 2.72e-3 rad/(N m), bulk modulus −26 %, worst channel
    1.38×)."""
    rep, final = _calibrate(tmp_path, rigid_cable=False, effects={"softer_cable": True})
    truth = 1.0 / (P.pulley_radius_m ** 2 * 3.0e5)
    fit = rep["declared_fit"]
    assert fit["cylinder.series_compliance_rad_per_nm"] == pytest.approx(truth, rel=0.3)
    assert abs(fit["fluid.liquid_bulk_modulus_pa"] / 1.6e9 - 1.0) <= 0.3
    devs = {d["parameter"]: d for d in rep["declared_deviations"]}
    assert devs["cylinder.series_compliance_rad_per_nm"]["relative_change"] > 2.0
    assert "fluid.liquid_bulk_modulus_pa" not in devs
    assert rep["verdict"] == "no_missing_effect" and max(final.values()) <= 2.0, final


@pytest.mark.slow
def test_backlash_on_the_simulated_load_is_named(tmp_path):
    """Rig 2 with 0.02 rad of play at the pulley (its dead-zone cable), 5 s (the figures
    below were measured on 8 s), seed 13: the described rig's backlash candidate, the
    cable's dead band in the circuit
    (``PulleyCylinders.backlash_rad``, the pistons a mass of their own while the cable is
    slack), works on the simulated load. Measured: ``backlash`` named first with
    b = 0.02005 rad, every channel within 2× its noise floor (angle 1.77×, torque 1.03×,
    chambers 1.06×/1.03×, current 1.10×, speed 1.01×). Before the dead band existed:
    structure_wrong, nothing named, the angle 57.9×; with massless pistons (seals at the
    joint's speed while the pistons crossed the gap): angle 2.64×, chambers 2.53×, current
    2.61×."""
    from afo_mj.calibration.calibrate import calibrate_setup, load_calibration_scenario
    from afo_mj.calibration.measured_data import load_measured
    path = R.write_record(tmp_path / "r.csv", 5.0, {"backlash": True}, seed=13)
    setup = load_calibration_scenario(str(SCENARIO))
    # one round: what is asserted is the first effect named and where it leaves the record
    setup = dataclasses.replace(setup, options=dataclasses.replace(setup.options,
                                                                   max_effects=1))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        rep = calibrate_setup(load_measured(path), setup)
    floor = rep["baseline"]["noise_floor"]
    final = {c: rep["error_after"][c] / floor[c] for c in floor}
    assert [s["effect"] for s in rep["effects_selected"]][:1] == ["backlash"]
    play = rep["effects_selected"][0]["parameters"]["backlash.backlash_rad"]
    assert play == pytest.approx(R.EFFECTS["backlash"].default, rel=0.05)
    assert max(final.values()) <= 2.0, final
