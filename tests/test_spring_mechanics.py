"""Issue 42 item 3: where a clutched spring's energy goes (afo_mj.experiments.spring_mechanics)
and the ratchet clutch (afo_mj.devices.ideal.ClutchedSpring.ratchet).

References: the spring's stored energy ``τ²/(2k)`` (a linear spring's energy from its force
alone) against the integrated power; Geyer & Herr's series-elastic law
(:func:`afo_mj.human.muscle.se_force_n`) evaluated on the reconstructed tendon length against
the recorded tendon force; the ratchet's torque against ``k (θ − min θ)`` by hand.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from afo_mj.devices.ideal import ClutchedSpring, IdealDevice
from afo_mj.experiments import spring_mechanics as sm
from afo_mj.experiments.muscle_assistance import Assistance, assistance_walk
from afo_mj.gait import reflex_law as rl
from afo_mj.gait.muscle_walk import load_reflex_set, muscle_table_scaled
from afo_mj.gait.reference import load_normative
from afo_mj.human import muscle as mu

ROOT = Path(__file__).resolve().parents[1]
SET = ROOT / "afo_mj" / "data" / "adapted" / "clutched_spring.json"
K = 180.0


@pytest.fixture(scope="module")
def walks():
    p = load_reflex_set(SET)
    out = {}
    for name, a in (("none", Assistance("none")),
                    ("spring", Assistance("clutched_spring", spring_nm_per_rad=K)),
                    ("ratchet", Assistance("clutched_spring", spring_nm_per_rad=K,
                                           spring_engage_phase=0.02, spring_ratchet=True))):
        out[name] = assistance_walk(a, params=p, duration_s=9.0)[0]
    return out


def test_spring_work_matches_its_stored_energy(walks):
    """Absorbed work per stride (∫ τ θ̇ < 0) against the rises of the stored energy τ²/(2k)
    (a linear spring's energy from its force alone), summed over the strides; the returned
    work against its falls."""
    w = walks["spring"]
    s = sm.spring_stride_energy(w, settle_s=3.0)
    hs = sm.scored_strides(w, 3.0)
    tau, t = w.record.device_moment_nm[:, 0], w.record.time_s
    sel = (t > hs[0]) & (t <= hs[-1])
    e = tau[sel] ** 2 / (2 * K)
    de = np.diff(np.concatenate([[tau[np.argmax(sel) - 1] ** 2 / (2 * K)], e]))
    n = len(hs) - 1
    assert s.absorbed_j < -0.5
    assert -s.absorbed_j == pytest.approx(de.clip(0).sum() / n, rel=0.03)
    assert s.returned_j == pytest.approx(-de.clip(None, 0).sum() / n, rel=0.06)
    assert s.peak_moment_nm == pytest.approx(float(np.sqrt(2 * K * e.max())), rel=1e-9)
    none = sm.spring_stride_energy(walks["none"], settle_s=3.0)
    assert none.absorbed_j == 0.0 and none.returned_j == 0.0


def test_tendon_force_and_length_agree_with_the_se_law(walks):
    """The recorded soleus force is Geyer & Herr's SE force of ``l_MTU(q_{k−1}) − l_CE`` (the
    module's alignment), to rounding; with the record's own sample ``k`` it is not."""
    w = walks["spring"]
    r = w.record
    T = muscle_table_scaled(r.sample_period_s, height_m=float(r.height_m))
    m = rl.MUSCLES.index("soleus")
    lm = sm.mtu_lengths_m(w, "soleus")
    f = w.force_n[:, 0, m]
    lce = np.cumsum(w.ce_velocity_m_s[:, 0, m]) * r.sample_period_s
    k0 = 3000 + int(np.argmax(f[3000:4000]))
    eps = np.sqrt(f[k0] / T[m, rl.T_FMAX]) * mu.EPS_REF
    off = lm[k0 - 1] - T[m, rl.T_LSLACK] * (1 + eps) - lce[k0]   # the unknown start length
    ks = np.arange(3000, len(f) - 1)

    def misfit(shift):
        lse = lm[ks - shift] - (lce[ks] + off)
        fse = np.array([mu.se_force_n(x, T[m, rl.T_LSLACK], T[m, rl.T_FMAX]) for x in lse])
        return float(np.abs(fse - f[ks]).max())

    assert misfit(1) < 1e-6 * f.max()
    assert misfit(0) > 10.0                   # a one-step misalignment is visible
    for name in ("soleus", "gastrocnemius"):
        ms = sm.muscle_stride_work(w, (name,), 3.0)[name]
        # a pure spring: its net work over whole strides is its stored energy's change only
        assert abs(ms.tendon_net_j) < 0.01 * ms.tendon_positive_j
        assert ms.fibre_positive_j > 0 > ms.fibre_negative_j


def test_ratchet_stretches_from_the_lowest_angle():
    """Engaged at 2 % of the stride, the ratchet's slack angle follows the ankle down, so the
    torque is k (θ − min θ) past the minimum; without it, k (θ − θ at engagement)⁺."""
    ang = [0.05, 0.0, -0.10, -0.15, -0.05, 0.10]
    out = {}
    for ratchet in (False, True):
        d = IdealDevice(sides=("right",), spring=ClutchedSpring(K, 0.02, 0.62, ratchet))
        stance, t = np.array([False, False]), 0.0
        for k in range(3):   # three 1 s strides give the phase estimator a stride time
            for on in (True, False):
                stance[0] = on
                d.begin_step(t, np.zeros(2), np.zeros(2), stance)
                d.end_step(np.zeros(2))
                t += 0.5
        stance[0] = True
        taus = []
        for i, th in enumerate(ang):
            f, _ = d.begin_step(t + 0.03 + 0.05 * i, np.array([th, 0.0]), np.zeros(2), stance)
            taus.append(float(f[0]))
            d.end_step(np.zeros(2))
        out[ratchet] = taus
    # the first stance step is the heel strike (phase 0): the clutch engages at the second
    engaged = ang[1]
    assert out[False] == pytest.approx([0.0] + [-K * max(th - engaged, 0.0) for th in ang[1:]],
                                       abs=1e-12)
    lows = np.minimum.accumulate(ang[1:])
    assert out[True] == pytest.approx([0.0] + [-K * (th - lo) for th, lo in zip(ang[1:], lows)],
                                      abs=1e-12)
    assert out[True][-1] == pytest.approx(-K * 0.25) and out[False][-1] == pytest.approx(-K * 0.1)


def test_ratchet_catches_more_of_the_stance(walks):
    """On the walker, the ratchet engaged at 2 % stretches the spring from the stance
    minimum: it stores and returns more than the clutch locked at 10 %."""
    fixed = sm.spring_stride_energy(walks["spring"], 3.0)
    rat = sm.spring_stride_energy(walks["ratchet"], 3.0)
    assert rat.returned_j > 2.0 * fixed.returned_j
    st = sm.ankle_stance_profile(walks["none"], 0.02, 3.0)
    assert st.lowest_rad < st.angle_at_engage_rad < st.peak_rad


def test_reference_stance_profile_is_winters():
    """Winter's ankle: lowest −4.6° near 6 %, peak 9.6° near 44 % of the stride (the
    normative table, read independently here)."""
    st = sm.reference_stance_profile(load_normative(), 0.02)
    assert np.degrees(st.lowest_rad) == pytest.approx(-4.6, abs=0.1)
    assert np.degrees(st.peak_rad) == pytest.approx(9.6, abs=0.1)
    assert st.peak_phase == pytest.approx(0.44, abs=0.01)


def test_scenario_ratchet_key():
    from afo_mj.scenarios.device_scenario import ASSISTANCE
    assert ASSISTANCE["ratchet"].kind == "bool"
    with pytest.raises(ValueError, match="spring_ratchet"):
        Assistance("clutched_spring", spring_ratchet=1)


def test_too_short_a_walk_is_refused(walks):
    with pytest.raises(ValueError, match="whole right strides"):
        sm.scored_strides(walks["none"], settle_s=8.5)


@pytest.mark.slow
def test_docs_spring_table_is_current():
    """``tools/spring_mechanics.py --check`` against docs/muscle_walker.md's block."""
    p = subprocess.run([sys.executable, str(ROOT / "tools" / "spring_mechanics.py"), "--check"],
                       capture_output=True, text=True, cwd=ROOT)
    assert p.returncode == 0, p.stdout + p.stderr
