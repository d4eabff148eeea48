"""The data behind the gait figures (issue 19 item 10a, 10b), not their pixels: the reference
band drawn is the reference's mean ± 1 SD, a figure whose reference has no SD claims no band,
and the displayed moments/powers are low-pass filtered so that an impact spike does not set
the axes. Synthetic Winter records (tests/gait_fixtures.py), no simulation."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from afo_mj.metrics.gait_metrics import PERCENT_CYCLE, analyse_gait
from afo_mj.metrics.kinetics_filter import (
    KINETICS_CUTOFF_HZ, KINETICS_FILTER_ORDER, filtered_kinetic_cycles, lowpass_zero_lag)
from afo_mj.gait.reference import load_normative
from afo_mj.outputs.device_figures import gait_conditions_title
from afo_mj.outputs.gait_report import gait_curve_panels

from gait_fixtures import WINTER_CYCLE_TIME_S, synthetic_record

T = WINTER_CYCLE_TIME_S


@pytest.fixture(scope="module")
def record():
    return synthetic_record(n_cycles=5)


def _analysis(rec, ref):
    return analyse_gait(rec, ref, strides=(2, 4))


def test_schwartz_band_is_the_reference_mean_plus_minus_sd(record):
    ref = load_normative("schwartz2008", "Free")
    a = _analysis(record, ref)
    data = gait_curve_panels(a.cycles, ref, record)
    assert data["band"]
    for ch, scale in (("knee_angle_rad", math.degrees(1.0)),
                      ("ankle_moment_nm_per_kg", -1.0), ("hip_power_w_per_kg", 1.0)):
        mean, sd = ref.band(ch, PERCENT_CYCLE / 100.0)
        r = data["panels"][ch]["reference"]
        assert r is not None and r.has_band, ch
        np.testing.assert_allclose(r.mean, scale * mean)
        np.testing.assert_allclose(r.lower, np.minimum(scale * (mean - sd), scale * (mean + sd)))
        np.testing.assert_allclose(r.upper, np.maximum(scale * (mean - sd), scale * (mean + sd)))
        assert np.all(r.upper - r.lower > 0)
    title = " ".join(data["notes"])
    assert "± 1 SD" in title and "schwartz2008" in title


def test_winter_has_no_sd_and_no_title_claims_a_band(record):
    ref = load_normative("winter", "normal")
    assert not ref.sd_splines                     # the shipped table has no SD column
    a = _analysis(record, ref)
    data = gait_curve_panels(a.cycles, ref, record)
    assert not data["band"]
    assert all(p["reference"] is None or not p["reference"].has_band
               for p in data["panels"].values())
    note = " ".join(data["notes"])
    assert "no band" in note and "± 1 SD" not in note
    # gait_conditions.png (device runs): no band claimed for Winter, named for Schwartz
    t = gait_conditions_title("run", "right", ref, has_band=False)
    assert "band" not in t.replace("no band", "") and "± 1 SD" not in t
    t = gait_conditions_title("run", "right", load_normative("schwartz2008", "Free"), True)
    assert "± 1 SD" in t


def test_filter_is_zero_lag_fourth_order_minus_3db_at_the_cutoff():
    dt = 0.004
    t = np.arange(0, 20.0, dt)
    for f, expected in ((KINETICS_CUTOFF_HZ, 1 / math.sqrt(2)), (1.0, 1.0)):
        y = lowpass_zero_lag(np.sin(2 * np.pi * f * t), dt)
        mid = slice(t.size // 4, 3 * t.size // 4)
        assert np.max(np.abs(y[mid])) == pytest.approx(expected, abs=0.01), f
        # zero lag: the filtered sine peaks where the input does
        lag = np.argmax(np.correlate(y[mid], np.sin(2 * np.pi * f * t[mid]), "same")) - (
            y[mid].size // 2)
        assert abs(lag) <= 1
    assert KINETICS_FILTER_ORDER == 4
    # 4th order: 24 dB per octave far above the cutoff (two 2nd-order passes)
    y = lowpass_zero_lag(np.sin(2 * np.pi * 48.0 * t), dt)
    assert np.max(np.abs(y[t.size // 4: 3 * t.size // 4])) < 10 ** (-60 / 20)


def test_impact_spike_does_not_set_the_displayed_knee_power(record):
    """A 12 ms knee-moment impulse at foot flat (8 % of each cycle), as a stiff simulated
    contact gives: the unfiltered power reaches −5 W/kg, the displayed (filtered) power stays
    within a physiological bound (Winter's knee power in loading response ≈ −0.8 W/kg; bound
    −1.5 W/kg), while the un-spiked rest of the curve is barely changed."""
    rec = dataclasses.replace(record, joint_moment_nm=record.joint_moment_nm.copy())
    ref = load_normative("winter", "normal")
    t = rec.time_s
    m = rec.body_mass_kg
    for side, hs in enumerate(rec.events.heel_strikes_s):
        for h in hs:
            w = (t >= h + 0.08 * T) & (t < h + 0.08 * T + 0.012)
            vel = rec.joint_velocity_rad_s[w, side, 1]
            # a moment whose power is −5 W/kg over the impulse
            rec.joint_moment_nm[w, side, 1] = -5.0 * m / np.where(
                np.abs(vel) > 0.3, vel, np.sign(vel) * 0.3 + (vel == 0) * 0.3)
    a = _analysis(rec, ref)
    raw = gait_curve_panels(a.cycles, ref, None)["panels"]["knee_power_w_per_kg"]
    shown = gait_curve_panels(a.cycles, ref, rec)["panels"]["knee_power_w_per_kg"]
    assert shown["filtered"] and not raw["filtered"]
    assert raw["simulation_mean"].min() < -3.0
    assert shown["simulation_mean"].min() > -1.5
    # away from the impulse the display follows the curve (cycle 30..100 %)
    clean = gait_curve_panels(_analysis(record, ref).cycles, ref, record)["panels"]
    far = PERCENT_CYCLE > 30
    diff = shown["simulation_mean"][far] - clean["knee_power_w_per_kg"]["simulation_mean"][far]
    assert np.max(np.abs(diff)) < 0.05
    # metrics are not filtered: the summary's negative knee work still holds the impulse
    assert a.summary["knee_negative_work_j_per_kg"]["mean"] < \
        _analysis(record, ref).summary["knee_negative_work_j_per_kg"]["mean"] - 0.03


def test_filtered_cycles_keep_angles_and_scalars(record):
    ref = load_normative("winter", "normal")
    a = _analysis(record, ref)
    f = filtered_kinetic_cycles(record, a.cycles)
    for c0, c1 in zip(a.cycles, f):
        assert c0.scalars == c1.scalars
        np.testing.assert_array_equal(c0.curves["knee_angle_rad"], c1.curves["knee_angle_rad"])
        assert not np.array_equal(c0.curves["knee_power_w_per_kg"],
                                  c1.curves["knee_power_w_per_kg"])
