"""The energy models' terms (issue 42 item 4): ``umberger2010_terms_w`` and
``bhargava2004_terms_w`` (afo_mj.human.metabolics) sum to the compiled rate functions on a
grid of states (shortening, lengthening, the 1 % excitation floor, full activation, beyond
l_opt) and to the rates a walk recorded; the floor's cost (tools/energy_model_terms.py) is
positive and below the walk's net rate; the docs' table is current (slow)."""

from __future__ import annotations

import itertools
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from afo_mj.human import metabolics as me

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tools"))


def _grid():
    """(u, a, l_norm, v_lopt_s, f_length, f_max, v_max, l_opt, mass, f_ST) states."""
    us = (0.0, 0.01, 0.05, 0.3, 1.0)               # 0: below the law's floor (heat floor)
    as_ = (0.0, 0.01, 0.2, 1.0)
    ls = (0.6, 1.0, 1.2, 1.6)
    vs = (-11.0, -3.0, -0.2, 0.0, 0.4, 2.5)
    for u, a, ln, v, fst in itertools.product(us, as_, ls, vs, (0.5, 0.75)):
        fl = float(np.exp(-((ln - 1.0) / 0.4) ** 2 * 3))
        yield u, a, ln, v, fl, 3000.0, 12.0, 0.05, 0.7, fst


def test_terms_sum_to_the_rates_on_a_grid_of_states():
    """Each state's terms sum to the scalar rate within 1e-12 of the terms' magnitude, the
    clamps (non-negative total, 1 W/kg floor) are met somewhere on the grid and never
    negative, and the term names are the declared ones."""
    rows = np.array(list(_grid()))
    u, a, ln, v, fl, fmax, vmax, lopt, m, fst = rows.T
    fv = np.where(v <= 0, (vmax + v) / (vmax - 4.0 * v), 1.5 - 0.5 * (vmax - v) / (vmax + 30 * v))
    f_act = a * fmax * fl * fv
    f_fib = f_act + 0.1 * fmax * np.maximum(ln - 1.0, 0.0) ** 2
    um = me.umberger2010_terms_w(u, a, ln, v, f_act, fl, vmax, lopt, m, fst)
    bh = me.bhargava2004_terms_w(u, ln, v * lopt, f_fib, f_act, m, fst)
    assert tuple(um) == me.UMBERGER_TERMS and tuple(bh) == me.BHARGAVA_TERMS
    for i in range(len(rows)):
        ru = me.umberger2010_rate_w(u[i], a[i], ln[i], v[i], f_act[i], fl[i], vmax[i],
                                    lopt[i], m[i], fst[i])[0]
        rb = me.bhargava2004_rate_w(u[i], ln[i], v[i] * lopt[i], f_fib[i], f_act[i], m[i],
                                    fst[i])[0]
        for terms, ref in ((um, ru), (bh, rb)):
            tot = sum(x[i] for x in terms.values())
            scale = max(sum(abs(x[i]) for x in terms.values()), abs(ref))
            assert abs(tot - ref) <= 1e-12 * scale, (rows[i], tot, ref)
    for key in ("nonnegative_raise", "heat_floor"):
        assert (um[key] >= 0).all() and (um[key] > 0).any(), key
    assert (bh["heat_floor"] >= 0).all() and (bh["heat_floor"] > 0).any()
    assert (um["work_negative"] < 0).any() and (um["lengthening"] > 0).any()
    assert (bh["work"] >= 0).all()


def test_published_umberger_2010_form_by_hand():
    """``negative_work=False``: Umberger's published 2010 form. A lengthening muscle (v = 0.4
    l_opt/s at l_opt, u = a = 0.3) by hand: heat ``S A^0.6 (128 f_FT + 25) + S A 0.3 α_ST v``
    (α_ST = 250/v_max), no work, against ``4 α_ST`` and the negative work in the default; a
    shortening muscle is the same in both."""
    S, A, vmax, v, fst, m, lopt, fa = 1.5, 0.3, 12.0, 0.4, 0.5, 0.7, 0.05, 900.0
    am = S * A ** 0.6 * (128 * (1 - fst) + 25)
    a_st = 250.0 / vmax
    pub = me.umberger2010_terms_w(A, A, 1.0, v, fa, 1.0, vmax, lopt, m, fst,
                                  negative_work=False)
    total = sum(float(x) for x in pub.values())
    assert total == pytest.approx((am + S * A * 0.3 * a_st * v) * m, rel=1e-12)
    assert float(pub["work_negative"]) == 0.0 and float(pub["nonnegative_raise"]) == 0.0
    dflt = me.umberger2010_terms_w(A, A, 1.0, v, fa, 1.0, vmax, lopt, m, fst)
    w_neg = -fa * v * lopt / m
    raw = am + S * A * 4.0 * a_st * v + w_neg
    assert sum(float(x) for x in dflt.values()) == pytest.approx(max(raw, 0.0) * m + max(
        1.0 - (am + S * A * 4.0 * a_st * v - min(raw, 0.0)), 0.0) * m, rel=1e-12)
    short = [me.umberger2010_terms_w(A, A, 1.0, -2.0, fa, 1.0, vmax, lopt, m, fst,
                                     negative_work=nw) for nw in (True, False)]
    assert sum(short[0].values()) == pytest.approx(sum(short[1].values()), rel=1e-15)


def test_terms_sum_to_a_walks_recorded_rates_and_the_floor_costs_less_than_the_walk():
    """A 4 s walk of the shipped 1.25 set: the terms from the record (CE length summed from
    its velocities) sum to the recorded Umberger and Bhargava rates within 1e-9 of the terms'
    magnitude; the 1 % excitation floor's cost is positive and below each model's net rate,
    and the net rates give the walk's own cost of transport."""
    import energy_model_terms as emt
    res = emt.analyse(duration_s=4.0, window_s=2.0)
    assert res["terms_sum_mismatch"] <= 1e-9
    for name in ("umberger", "bhargava"):
        r = res[name]
        assert 0.0 < r["floor_w_per_kg"] < r["net_w_per_kg"], (name, r)
        assert r["cot_j_per_kg_m"] == pytest.approx(r["walk_cot_j_per_kg_m"], rel=1e-9)
        assert r["net_w_per_kg"] == pytest.approx(sum(r["terms_w_per_kg"].values()),
                                                  rel=1e-12)


def test_moco_2d_row_is_the_published_gross_figure_net_of_the_basal_rate():
    """Moco's 2D walking example (opensim-moco PR #532: the metabolic term 0.16 at weight 0.1,
    gross of the 1.2 W/kg basal rate) on its reference's half cycle, 0.62347006 m in
    0.47008941 s: worked by hand, speed 1.32628 m/s, net COT 1.6 − 1.2/1.32628 = 0.69521
    J/(kg m), net 0.92205 W/kg, per stride 0.69521 × 1.24694 m = 0.86689 J/kg; the docs'
    row says so."""
    import energy_model_terms as emt
    m = emt.moco_2d()
    assert m["speed_m_s"] == pytest.approx(1.32628, abs=1e-5)
    assert m["cot_j_per_kg_m"] == pytest.approx(0.69521, abs=1e-5)
    assert m["net_w_per_kg"] == pytest.approx(0.92205, abs=1e-5)
    assert m["stride_j_per_kg"] == pytest.approx(0.86689, abs=1e-5)
    doc = (ROOT / "docs" / "muscle_walker.md").read_text(encoding="utf-8")
    assert "| 0.922 | 0.70 | 0.87 | 0.32 × |" in doc


@pytest.mark.slow
def test_docs_energy_table_is_current():
    """``tools/energy_model_terms.py --check`` against docs/muscle_walker.md's block."""
    p = subprocess.run([sys.executable, str(ROOT / "tools" / "energy_model_terms.py"),
                        "--check"], capture_output=True, text=True, cwd=ROOT)
    assert p.returncode == 0, p.stdout + p.stderr
