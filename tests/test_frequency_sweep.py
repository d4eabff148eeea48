"""Frequency-response sweeps resolve a resonance (issue 19 item 10c): at least 30
frequencies, refined about the peak, and a known second-order peak located within a few %."""

from __future__ import annotations

import math

import numpy as np
import pytest

from afo_mj.experiments.frequency_sweep import (
    MIN_SWEEP_POINTS, adaptive_log_sweep, refinement_bracket, resonance_peak)


def _second_order_gain(f_hz: float, fn_hz: float, zeta: float) -> float:
    """|H(j2πf)| of H(s) = ωn² / (s² + 2ζωn s + ωn²)."""
    r = f_hz / fn_hz
    return 1.0 / math.sqrt((1.0 - r * r) ** 2 + (2.0 * zeta * r) ** 2)


@pytest.mark.parametrize("fn_hz, zeta", [(129.0, 0.15), (37.0, 0.08), (5.3, 0.3)])
def test_adaptive_sweep_locates_a_second_order_peak(fn_hz, zeta):
    calls = []

    def measure(f):
        calls.append(f)
        return {"gain": _second_order_gain(f, fn_hz, zeta)}

    freqs, results, feature = adaptive_log_sweep(measure, 1.0, 400.0)
    assert freqs.size >= MIN_SWEEP_POINTS >= 30
    assert len(calls) == freqs.size and np.all(np.diff(freqs) > 0)
    assert feature == "peak"
    f_true = fn_hz * math.sqrt(1.0 - 2.0 * zeta ** 2)       # the magnitude's maximum
    f_peak, peak_db, inside = resonance_peak(freqs, [r["gain"] for r in results])
    assert inside
    assert f_peak == pytest.approx(f_true, rel=0.03)
    peak_true_db = 20 * math.log10(1.0 / (2 * zeta * math.sqrt(1 - zeta ** 2))
                                   / _second_order_gain(1.0, fn_hz, zeta))
    assert peak_db == pytest.approx(peak_true_db, abs=0.5)
    # denser near the peak: more points within ±25 % of it than the coarse grid alone gives
    near = np.sum(np.abs(np.log(freqs / f_true)) < math.log(1.25))
    coarse = np.geomspace(1.0, 400.0, 20)
    assert near >= np.sum(np.abs(np.log(coarse / f_true)) < math.log(1.25)) + 8


def test_low_pass_sweep_is_refined_at_the_bandwidth():
    """No resonance (first-order low-pass, corner 2.4 Hz): the extra points go to the −3 dB
    crossing, where the bandwidth is read, and no interior peak is claimed."""
    fc = 2.4
    freqs, results, feature = adaptive_log_sweep(
        lambda f: 1.0 / math.sqrt(1.0 + (f / fc) ** 2), 0.2, 30.0)
    assert freqs.size >= 30 and feature == "bandwidth"
    lo, hi, _ = refinement_bracket(np.geomspace(0.2, 30.0, 20),
                                   [1.0 / math.sqrt(1.0 + (f / fc) ** 2)
                                    for f in np.geomspace(0.2, 30.0, 20)])
    assert lo < fc < hi
    assert np.sum((freqs > lo) & (freqs < hi)) == 12
    _, _, inside = resonance_peak(freqs, results)
    assert not inside


@pytest.mark.slow
def test_hafo_bench_default_sweep_resolves_the_foot_on_oil_resonance():
    """The HAFO bench's velocity sweep (the Bode figure's data): ≥ 30 frequencies, the
    resonance inside the range with points on both flanks within ±10 % of it."""
    from afo_mj.devices.registry import device_spec
    from afo_mj.experiments.bench_stand import frequency_response
    s, series = frequency_response(device_spec("hafo"), kind="velocity")
    f = series["frequency_response_velocity"]["freq_hz"]
    assert s["n_frequencies"] == f.size >= 30
    assert s["refined"] == "peak" and s["resonance_inside_range"]
    f0 = s["resonance_hz"]
    assert 50.0 < f0 < 300.0
    assert np.sum((f > f0) & (f < 1.1 * f0)) >= 2 and np.sum((f < f0) & (f > f0 / 1.1)) >= 2
