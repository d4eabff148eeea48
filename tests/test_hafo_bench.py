"""The HAFO on the stand rig (seed ch. 6 tests on the ankle test stand,
:mod:`afo_mj.experiments.bench_stand`) and the response metrics it uses.

The metric functions are checked against exact analytic responses; the bench against the
published prototype figures (65 N·m, 105 deg/s) and the expected direction of parameter
changes. The whole bench runs once (module fixture) and is reused.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from afo_mj.metrics.response_metrics import bandwidth_hz, sine_response, step_metrics
from afo_mj.devices.hafo import hafo_params, hafo_spec
from afo_mj.devices.registry import device_spec
from afo_mj.experiments import bench_stand as hb

HAFO = device_spec("hafo")


# -- response metrics against analytic responses --------------------------------------------------
def test_step_metrics_first_order_exact():
    tau, ts, dt = 0.05, 0.1, 1e-5
    t = np.arange(0.0, ts + 20 * tau, dt)
    y = np.where(t >= ts, 1.0 - np.exp(-(t - ts) / tau), 0.0)
    m = step_metrics(t, y, 1.0, ts)
    assert m["rise_time_s"] == pytest.approx(math.log(9.0) * tau, rel=1e-3)   # 2.197 τ
    assert m["settling_time_s"] == pytest.approx(math.log(50.0) * tau, rel=1e-3)  # 2 %: 3.91 τ
    assert m["overshoot_pct"] < 1e-4
    assert abs(m["steady_state_error"]) < 1e-6


@pytest.mark.parametrize("zeta", [0.2, 0.5, 0.7])
def test_step_metrics_second_order_overshoot(zeta):
    wn, ts, dt = 30.0, 0.05, 1e-5
    t = np.arange(0.0, ts + 40.0 / (zeta * wn), dt)
    s = np.clip(t - ts, 0.0, None)
    wd = wn * math.sqrt(1 - zeta ** 2)
    unit = 1 - np.exp(-zeta * wn * s) / math.sqrt(1 - zeta ** 2) * np.sin(wd * s + math.acos(zeta))
    expected = 100 * math.exp(-zeta * math.pi / math.sqrt(1 - zeta ** 2))
    m = step_metrics(t, unit, 1.0, ts)
    assert m["overshoot_pct"] == pytest.approx(expected, abs=0.02)
    assert m["peak_time_s"] == pytest.approx(math.pi / wd, abs=2 * dt)
    # a downward step of −40 (torque sign) gives the same normalised metrics
    m2 = step_metrics(t, -40.0 * unit, -40.0, ts)
    assert m2["overshoot_pct"] == pytest.approx(m["overshoot_pct"], rel=1e-9)
    assert m2["rise_time_s"] == pytest.approx(m["rise_time_s"], rel=1e-9)


def test_sine_fit_first_order_minus_3db_at_corner():
    tau = 0.02
    fc = 1 / (2 * math.pi * tau)
    freqs = fc * np.logspace(-2, 1, 31)
    gains, phases = [], []
    for f in freqs:
        w = 2 * math.pi * f
        t = np.arange(0.0, 8 * tau + 3 / f, min(1e-4, 1 / (200 * f)))
        u = np.sin(w * t)
        # exact response of τ ẏ + y = u from rest
        wt = w * tau
        y = (np.sin(w * t) - wt * np.cos(w * t) + wt * np.exp(-t / tau)) / (1 + wt ** 2)
        r = sine_response(t, u, y, f, settle_cycles=(8 * tau) * f)
        gains.append(r["gain_db"])
        phases.append(r["phase_deg"])
        assert r["gain"] == pytest.approx(1 / math.sqrt(1 + (w * tau) ** 2), rel=1e-3)
        assert r["phase_deg"] == pytest.approx(-math.degrees(math.atan(w * tau)), abs=0.1)
    bw = bandwidth_hz(freqs, gains)
    assert bw == pytest.approx(fc, rel=0.01)


def test_metric_input_checks():
    t = np.linspace(0, 1, 11)
    with pytest.raises(ValueError, match="empty"):
        step_metrics([], [], 1.0, 0.0)
    with pytest.raises(ValueError, match="non-finite"):
        step_metrics(t, np.r_[np.zeros(5), np.nan, np.ones(5)], 1.0, 0.2)
    with pytest.raises(ValueError, match="lengths must match"):
        step_metrics(t, np.ones(10), 1.0, 0.2)
    with pytest.raises(ValueError, match="t_step"):
        step_metrics(t, np.ones(11), 1.0, 5.0)
    with pytest.raises(ValueError, match="freq_hz"):
        sine_response(t, t, t, -1.0)
    with pytest.raises(ValueError, match="no whole cycle"):
        sine_response(t, t, t, 0.5, settle_cycles=1)
    with pytest.raises(ValueError, match="lengths must match"):
        bandwidth_hz([1, 2, 3], [0, -1])
    with pytest.raises(ValueError, match="non-finite"):
        bandwidth_hz([1, 2, 3], [0, float("nan"), -5])
    bw, note = bandwidth_hz([1, 10, 100], [0.0, -1.0, -2.0], return_note=True)
    assert math.isnan(bw) and "never fell 3 dB" in note
    with pytest.warns(RuntimeWarning, match="bandwidth above the measured range"):
        assert math.isnan(bandwidth_hz([1, 10], [0.0, -1.0]))


# -- the bench -----------------------------------------------------------------------------
@pytest.fixture(scope="module")
def bench():
    return hb.run_stand(HAFO)


@pytest.mark.slow
def test_torque_velocity_reproduces_published_figures(bench):
    s, series = bench
    assert s["stall_torque_nm"] == pytest.approx(65.0, rel=0.10)
    assert s["no_load_speed_deg_s"] == pytest.approx(105.0, rel=0.10)
    assert s["no_load_speed_from_curve_deg_s"] == pytest.approx(105.0, rel=0.10)
    tv = series["torque_velocity"]
    # assistance torque falls with plantarflexion speed (a motor's torque–speed line)
    assert np.all(np.diff(tv["assist_torque_nm"]) < 0.5)
    assert tv["assist_torque_nm"][0] == pytest.approx(s["stall_torque_nm"], rel=0.05)


@pytest.mark.slow
def test_isometric_40nm_step(bench):
    s, series = bench
    m = s["isometric_steps"]["40"]
    assert m["rise_time_s"] < 0.2
    assert abs(m["steady_state_error"]) < 0.05 * 40.0
    assert m["settling_time_s"] < 0.4
    tail = series["isometric_step_40nm"]["torque_nm"][-200:]
    assert np.all(np.abs(tail + 40.0) < 0.05 * 40.0)
    assert s["rise_time_s"] == m["rise_time_s"]
    for level, mm in s["isometric_steps"].items():
        assert abs(mm["steady_state_error_rel"]) < 0.05, level


@pytest.mark.slow
def test_bench_summary_and_energy_balance(bench):
    s, series = bench
    for key in ("stall_torque_nm", "no_load_speed_deg_s", "bandwidth_hz", "velocity_bandwidth_hz",
                "rise_time_s", "position_rise_time_s", "position_overshoot_pct",
                "position_steady_state_error_deg", "energy_error_max"):
        assert np.isfinite(s[key]), key
    assert s["velocity_bandwidth_hz"] > s["bandwidth_hz"] > 0
    assert len(s["energy_errors"]) > 20
    worst = max(s["energy_errors"], key=s["energy_errors"].get)
    assert s["energy_error_max"] < 0.005, (worst, s["energy_errors"][worst])
    # the position step reaches its reference
    assert abs(s["position_steady_state_error_deg"]) < 1.0


_BW_FREQS = (0.2, 0.5, 1.0, 1.5, 2.0, 3.0, 5.0, 8.0)


def _torque_bandwidth(overrides):
    s, _ = hb.frequency_response(hafo_spec(hafo_params(overrides)), "torque", _BW_FREQS)
    assert s["energy_error_max"] < 0.005
    return s["bandwidth_hz"]


def test_hose_length_and_entrained_air_lower_torque_bandwidth():
    base = _torque_bandwidth({})
    long_hose = _torque_bandwidth({"hose.length_m": 2.2})
    airy = _torque_bandwidth({"fluid.air_fraction": 0.01})
    assert np.isfinite(base) and np.isfinite(long_hose) and np.isfinite(airy)
    assert long_hose < 0.95 * base, (base, long_hose)
    assert airy < 0.95 * base, (base, airy)


def test_bench_argument_checks():
    with pytest.raises(hb.BenchError, match="protocols = .*allowed"):
        hb.run_stand(HAFO, ("torque_velocity", "bogus"))
    with pytest.raises(hb.BenchError, match="kind = 'position'"):
        hb.frequency_response(HAFO, kind="position")
    with pytest.raises(hb.BenchError, match=r"levels_nm\[1\] = -5"):
        hb.isometric_steps(HAFO, levels_nm=(20, -5))
    with pytest.raises(hb.BenchError, match=r"velocities_deg_s\[0\] = 30"):
        hb.torque_velocity(HAFO, velocities_deg_s=(30,))
    with pytest.raises(hb.BenchError, match="step_rad = 0"):
        hb.position_step(HAFO, step_rad=0.0)
    with pytest.raises(hb.BenchError, match="spec = dict"):
        hb.run_stand({"hose.length_m": 2.2})


@pytest.mark.slow
def test_plot_bench_writes_pngs(bench, tmp_path):
    _, series = bench
    from afo_mj.outputs.bench_figures import plot_bench
    paths = plot_bench(series, tmp_path)
    names = sorted(p.name for p in paths)
    assert names == ["hafo_bode.png", "hafo_isometric_steps.png", "hafo_position_step.png",
                     "hafo_torque_velocity.png"]
    for p in paths:
        assert p.stat().st_size > 10_000
        assert p.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
