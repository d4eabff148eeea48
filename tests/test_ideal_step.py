"""The ideal device's compiled step (afo_mj.devices.ideal_step) against values worked out by
hand, stepped both ways it is stepped: from Python (IdealDevice.begin_step/end_step, the
kernels called as numba functions) and through its C entry points (the addresses a compiled
walk loop calls, called here with ctypes).

The foot switch in every case: stance from t = 0 (a heel strike with no stride before it),
swing at 0.7 s, stance again at 1.0 s (a 1.0 s stride measured: from then on the phase is
t − 1.0 s), and nothing else; the phase is −1 until 1.0 s."""

from __future__ import annotations

import ctypes
import math

import numpy as np
import pytest

from afo_mj.control import assistance as asst
from afo_mj.devices.ideal import ClutchedSpring, IdealDevice

H = 1e-3
_P = ctypes.POINTER(ctypes.c_double)
_PI = ctypes.POINTER(ctypes.c_int64)
_BEGIN = ctypes.CFUNCTYPE(None, ctypes.c_double, _P, _P, _P, _P, _PI)
_END = ctypes.CFUNCTYPE(ctypes.c_int64, _P, _P, _PI, _P, ctypes.c_int64, ctypes.c_int64,
                        ctypes.c_int64, ctypes.c_int64, ctypes.c_double)


class _Native:
    """Steps a device through its C entry points as a compiled loop does."""

    def __init__(self, dev):
        self.dev, self.nc = dev, dev.native_coupling()
        self.begin = _BEGIN(self.nc.begin_address)
        self.end = _END(self.nc.end_address)
        self.io = np.zeros(6)
        self.k = 0

    @staticmethod
    def _p(a, kind=_P):
        return a.ctypes.data_as(kind)

    def begin_step(self, t, angle2, velocity2, stance2):
        io = self.io
        io[0:2], io[2:4], io[4:6] = angle2, velocity2, stance2
        self.begin(t, self._p(io[0:2]), self._p(io[2:4]), self._p(io[4:6]),
                   self._p(self.nc.buffer), self._p(self.nc.meta, _PI))
        self.t = t
        return self.nc.force2, self.nc.damping2

    def end_step(self, velocity2):
        self.io[2:4] = velocity2
        log = self.nc.log
        code = self.end(self._p(self.io[2:4]), self._p(self.nc.buffer),
                        self._p(self.nc.meta, _PI), self._p(log), *log.shape, self.k,
                        self.t + H)
        assert code == (2 if self.k < log.shape[0] else 1)
        self.k += 1
        self.dev.native_finished(1, self.t)
        return self.nc.delivered2


def _stepper(dev, path):
    return dev if path == "python" else _Native(dev)


def _walk_switch(stepper, side=0):
    """The foot switch of the module docstring up to the second heel strike (angle 0)."""
    for t in (0.0, 0.7, 1.0):
        st = np.zeros(2)
        st[side] = 1.0 if t != 0.7 else 0.0
        stepper.begin_step(t, np.zeros(2), np.zeros(2), st)
        stepper.end_step(np.zeros(2))


@pytest.mark.parametrize("path", ["python", "native"])
@pytest.mark.parametrize("ratchet", [False, True])
def test_clutched_spring_is_minus_k_times_the_stretch_after_engagement(path, ratchet):
    """K = 200 N·m/rad, engaged at 10 %, released past 60 %. Engages at the first step in
    stance with phase ≥ 0.10 (t = 1.2 s, θ = 0.03 rad: slack); then τ = −K (θ − θ_e) for
    θ > θ_e, 0 below; with the ratchet, θ = 0.01 at 1.4 s moves θ_e down to 0.01. Past the
    release (65 %) and in swing: 0."""
    K = 200.0
    dev = IdealDevice(sides=("right",), spring=ClutchedSpring(K, 0.10, 0.60, ratchet),
                      max_steps=100)
    s = _stepper(dev, path)
    _walk_switch(s)
    te = 0.01 if ratchet else 0.03
    steps = [  # t, θ, torque by hand
        (1.05, 0.02, 0.0),                       # phase 0.05: not yet engaged
        (1.2, 0.03, 0.0),                        # engages, slack
        (1.3, 0.08, -K * (0.08 - 0.03)),         # -10 N·m
        (1.4, 0.01, 0.0),                        # below θ_e (the ratchet follows it)
        (1.5, 0.06, -K * (0.06 - te)),           # -6 (plain) / -10 N·m (ratchet)
        (1.65, 0.09, 0.0),                       # past the release
    ]
    for t, th, want in steps:
        f, d = s.begin_step(t, np.array([th, 0.0]), np.array([0.5, 0.0]),
                            np.array([1.0, 0.0]))
        assert f[0] == pytest.approx(want, abs=1e-12) and f[1] == 0.0 and d[0] == 0.0
        assert s.end_step(np.array([0.5, 0.0]))[0] == f[0]
    L = dev.log.arrays()
    assert L["engaged_angle_rad"][6, 0] == pytest.approx(te)      # the step at 1.5 s
    assert L["clutch_engaged"][:, 0].tolist() == [0, 0, 0, 0, 1, 1, 1, 1, 0]
    assert L["phase"][5, 0] == pytest.approx(0.3)
    assert L["time_s"][5, 0] == pytest.approx(1.3 + H)
    assert L["ankle_angle_rad"][5, 0] == pytest.approx(0.08 + H * 0.5)
    # the ledger: the spring absorbs τ·q̇·h each engaged step (q̇ = +0.5 rad/s)
    absorbed = sum(-w for _t, _th, w in steps) * 0.5 * H
    led = dev.ledger(0)
    assert led["electrical_regenerated_j"] == pytest.approx(absorbed, rel=1e-12)
    assert led["electrical_drawn_j"] == 0.0
    assert led["peak_torque_nm"] == pytest.approx(10.0)
    assert dev.steps == 9 and dev.log.n == 9


def _zhang(phase, peak):
    """Zhang et al. 2017 at 52.9 / 26.2 / 9.8 % written out (flat-ended cubics),
    plantarflexion negative."""
    x = 100.0 * phase
    if x < 26.7 or x > 62.7:
        return 0.0
    u = (x - 26.7) / 26.2 if x <= 52.9 else (62.7 - x) / 9.8
    return -peak * u * u * (3.0 - 2.0 * u)


@pytest.mark.parametrize("path", ["python", "native"])
def test_profile_torque_at_known_phases_with_the_ramp_and_the_stance_gate(path):
    """Zhang 40 N·m on the left ankle, ramp over 2 strides: one stride measured, so half the
    profile: at 40 % of the stride −20 × u²(3 − 2u), u = 13.3/26.2; at the peak (52.9 %)
    −20 N·m; nothing in swing at 55 % (where the profile pulls); nothing before a stride is
    measured."""
    dev = IdealDevice(sides=("left",), profile=asst.zhang_profile(40.0, 52.9, 26.2, 9.8),
                      ramp_strides=2)
    s = _stepper(dev, path)
    f, _ = s.begin_step(0.0, np.zeros(2), np.zeros(2), np.array([0.0, 1.0]))
    assert f[1] == 0.0                                   # no stride measured
    s.end_step(np.zeros(2))
    _walk_switch(s, side=1)
    u = 13.3 / 26.2
    for t, on, want in ((1.4, 1.0, -20.0 * u * u * (3 - 2 * u)),
                        (1.5, 1.0, 0.5 * _zhang(0.5, 40.0)), (1.529, 1.0, -20.0),
                        (1.55, 0.0, 0.0)):       # the foot lifted early: none in swing
        f, _ = s.begin_step(t, np.zeros(2), np.zeros(2), np.array([0.0, on]))
        assert f[1] == pytest.approx(want, abs=2e-3) and f[0] == 0.0
        s.end_step(np.zeros(2))
    assert dev.phase2[1] == pytest.approx(0.55)
    assert dev.phase[1, asst.PH_N] == 1.0


@pytest.mark.parametrize("path", ["python", "native"])
def test_impedance_rows_by_hand(path):
    """Rows (phase < 0.5: K 150, B 2, θ0 0.05, clutched; else K 50, B 0.5, θ0 0): before a
    stride is measured the first row, τ = −150 (θ − 0.05) − 2 θ̇ when θ > θ0, 0 at or below;
    at 70 % τ = −50 θ − 0.5 θ̇."""
    dev = IdealDevice(sides=("right", "left"),
                      impedance=[(0.5, 150.0, 2.0, 0.05, 1.0), (1.0, 50.0, 0.5, 0.0, 0.0)])
    s = _stepper(dev, path)
    f, _ = s.begin_step(0.0, np.array([0.1, 0.02]), np.array([0.4, 0.4]), np.ones(2))
    assert f[0] == pytest.approx(-150.0 * 0.05 - 2.0 * 0.4, abs=1e-12)      # -8.3
    assert f[1] == 0.0                                                     # clutch slack
    s.end_step(np.zeros(2))
    _walk_switch(s)
    f, _ = s.begin_step(1.7, np.array([0.1, 0.1]), np.array([-1.0, -1.0]), np.ones(2))
    assert f[0] == pytest.approx(-50.0 * 0.1 + 0.5, abs=1e-12)               # -4.5
    # the left side saw no second heel strike (its stance never fell): first row
    assert f[1] == pytest.approx(-150.0 * 0.05 + 2.0, abs=1e-12)
    assert math.isnan(dev.theta_engaged[0])


def test_a_non_finite_torque_is_refused_not_delivered():
    dev = IdealDevice(sides=("right",), impedance=[(1.0, 10.0, 0.0, 0.0, 0.0)])
    dev.begin_step(0.0, np.array([np.inf, 0.0]), np.zeros(2), np.ones(2))
    with pytest.raises(FloatingPointError, match="non-finite torque"):
        dev.end_step(np.zeros(2))
