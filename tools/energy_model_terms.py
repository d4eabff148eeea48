"""The two muscle energy models side by side on one walk (issue 42 item 4): each model's
metabolic rate split into its terms (:func:`afo_mj.human.metabolics.umberger2010_terms_w`,
:func:`afo_mj.human.metabolics.bhargava2004_terms_w`) over the last 5 s of a 10 s walk of the
shipped ``1.25`` reflex set, the net cost of transport and per stride, what the 1 % excitation
floor alone costs, and the Umberger / Bhargava ratio; beside them Weyand et al.'s measured
net cost per stride and OpenSim Moco's 2D walking example's published cost (Bhargava's
model on another walker, :func:`moco_2d`).

The walk's record has each muscle's excitation, activation, CE velocity and tendon force per
1 ms step; the CE length is the law's start length plus the summed steps ``v h`` (the law's
``v = (l_CE − l_CE,old)/h``: the same length to rounding), and the CE's active and fibre
forces are recomputed from them as the law does (:func:`afo_mj.gait.reflex_law._muscle_outputs`).
The terms' sum is checked against the recorded rates.

Run::

    .venv/bin/python tools/energy_model_terms.py           # print the tables
    .venv/bin/python tools/energy_model_terms.py --write   # rewrite docs/muscle_walker.md's block
    .venv/bin/python tools/energy_model_terms.py --check   # exit 1 naming a difference

``--check`` compares with the block of docs/muscle_walker.md between
``<!-- energy-terms:begin -->`` and ``<!-- energy-terms:end -->`` at the printed precision
(``tools/readme_tables.py``'s rule: identical words, numbers within a unit of their last digit).
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "tools"))

from doc_block import mode_parser, write_or_check  # noqa: E402
from afo_mj.gait import reflex_law as rl  # noqa: E402
from afo_mj.gait.muscle_walk import (MuscleWalkStepper, load_reflex_set,  # noqa: E402
                                     run_muscle_walk)
from afo_mj.human import metabolics as me  # noqa: E402
from afo_mj.human import muscle as mu  # noqa: E402

SET_PATH = ROOT / "afo_mj" / "data" / "reflex_params_1.25.json"
DOC = ROOT / "docs" / "muscle_walker.md"
BEGIN, END = "<!-- energy-terms:begin -->", "<!-- energy-terms:end -->"
DURATION_S = 10.0
#: adults' net metabolic energy per stride at their economical walking speeds (J/kg;
#: Weyand et al. 2010, J Exp Biol 213:3972: 2.74 ± 0.12)
WEYAND_J_PER_KG = 2.74
#: OpenSim Moco's 2D walking example with Bhargava et al.'s model (``example2DWalkingMetabolics``,
#: opensim-core; a tracking problem of half a gait cycle, 18 DeGroote-Fregly muscles, the
#: smoothed Bhargava 2004 model). Its one published figure: A. Falisse in opensim-org/
#: opensim-moco pull request #532 (2020-02-06): the metabolic objective term 0.16 at weight
#: 0.1, i.e. the cost of transport the example prints (10 × the term) 1.6 J/(kg m), gross:
#: the model's ``total_metabolic_rate`` includes the basal rate (1.2 W/kg by default)
MOCO_2D_GROSS_COT_J_PER_KG_M = 1.6
MOCO_BASAL_W_PER_KG = 1.2
#: the example's half gait cycle: pelvis_tx 0 -> 0.62347006 m over 0.47008941 s
#: (``referenceCoordinates.sto``, the tracked reference; the problem's final time)
MOCO_2D_HALF_CYCLE_M = 0.62347006
MOCO_2D_HALF_CYCLE_S = 0.47008941
WINDOW_S = 5.0
#: the excitation floor (Geyer & Herr's pre-activation, :data:`afo_mj.human.muscle.PREACTIVATION`)
FLOOR = mu.PREACTIVATION
#: the terms grouped for the side-by-side comparison: (label, Umberger terms, Bhargava terms)
GROUPS = (("activation + maintenance heat", ("activation_maintenance",),
           ("activation", "maintenance")),
          ("shortening / lengthening heat", ("shortening", "lengthening", "nonnegative_raise"),
           ("shortening",)),
          ("CE work (negative work in Umberger)", ("work_positive", "work_negative"),
           ("work",)),
          ("1 W/kg heat floor", ("heat_floor",), ("heat_floor",)))
TERM_LABELS = {"activation_maintenance": "activation + maintenance heat",
               "shortening": "shortening heat", "lengthening": "lengthening heat",
               "nonnegative_raise": "heat raised to keep the total ≥ 0",
               "heat_floor": "1 W/kg heat floor", "work_positive": "positive CE work",
               "work_negative": "negative CE work", "activation": "activation heat",
               "maintenance": "maintenance heat", "work": "CE work (shortening only)"}


def _vec(fn, *args):
    """A compiled scalar function of :mod:`afo_mj.human.muscle` over broadcast arrays."""
    b = np.broadcast_arrays(*(np.asarray(x, dtype=float) for x in args))
    out = np.empty(b[0].shape)
    flat = [x.ravel() for x in b]
    o = out.ravel()
    for i in range(o.size):
        o[i] = fn(*(x[i] for x in flat))
    return out


def muscle_states(walk, T: np.ndarray, lce0_m: np.ndarray, u=None, a=None) -> dict:
    """Per step and muscle ``(n, 2, 7)`` the models' inputs on ``walk``: the CE length
    ``lce0_m + Σ v h``, ``l_CE/l_opt``, the velocity (m/s and l_opt/s), ``f_L``, the active
    force ``a F_max f_L f_V`` and the fibre force (plus the parallel element), as the law
    computes them; ``u``, ``a`` (default the walk's) replace the excitation and activation
    (the floor's cost: ``u = a = 0.01`` at the walk's lengths and velocities)."""
    h = walk.record.sample_period_s
    v = walk.ce_velocity_m_s
    lce = lce0_m + np.cumsum(v * h, axis=0)
    u = walk.excitation if u is None else np.broadcast_to(u, v.shape)
    a = walk.activation if a is None else np.broadcast_to(a, v.shape)
    fmax, vmax, lopt = T[:, rl.T_FMAX], T[:, rl.T_VMAX], T[:, rl.T_LOPT]
    fl = _vec(mu.ce_force_length, lce, lopt)
    fv = _vec(mu.ce_force_velocity, v / lopt, vmax)
    f_act = a * fmax * fl * fv
    f_fib = f_act + _vec(mu.pe_force_n, lce, lopt, fmax)
    return {"u": u, "a": a, "l_ce_m": lce, "l_norm": lce / lopt, "v_m_s": v,
            "v_lopt_s": v / lopt, "f_length": fl, "f_active_n": f_act, "f_fiber_n": f_fib,
            "v_max": np.broadcast_to(vmax, v.shape), "l_opt_m": np.broadcast_to(lopt, v.shape),
            "mass_kg": np.broadcast_to(T[:, rl.T_MASS], v.shape),
            "slow_twitch": np.broadcast_to(T[:, rl.T_SLOW], v.shape)}


def model_terms(st: dict, negative_work: bool = True) -> tuple[dict, dict]:
    """``(Umberger terms, Bhargava terms)``, each ``{name: (n, 2, 7) W}``, from
    :func:`muscle_states`; ``negative_work=False``: Umberger's published 2010 form
    (:func:`afo_mj.human.metabolics.umberger2010_terms_w`)."""
    um = me.umberger2010_terms_w(st["u"], st["a"], st["l_norm"], st["v_lopt_s"],
                                 st["f_active_n"], st["f_length"], st["v_max"], st["l_opt_m"],
                                 st["mass_kg"], st["slow_twitch"], negative_work)
    bh = me.bhargava2004_terms_w(st["u"], st["l_norm"], st["v_m_s"], st["f_fiber_n"],
                                 st["f_active_n"], st["mass_kg"], st["slow_twitch"])
    return um, bh


def walk_with_lengths(params, duration_s: float):
    """``(walk, T, lce0)``: the muscle walk of ``params`` (:func:`run_muscle_walk`), its
    muscle table and the CE lengths it starts from (the law's initial state)."""
    stepper = MuscleWalkStepper(None, params, duration_s=duration_s)
    T = stepper.controller._T.copy()
    lce0 = stepper._X[rl.X_LCE:rl.X_LCE + 14].reshape(2, 7).copy()
    return run_muscle_walk(None, params, duration_s), T, lce0


def analyse(params=None, duration_s: float = DURATION_S, window_s: float = WINDOW_S) -> dict:
    """The figures of the tables: per model each term's mean rate over the last ``window_s``
    (W per kg of body mass), the net rate, COT (J/(kg m)), energy per stride (J/kg), the
    floor's cost, and the largest relative mismatch of the terms' sum to the recorded rates."""
    params = load_reflex_set(SET_PATH) if params is None else params
    walk, T, lce0 = walk_with_lengths(params, duration_s)
    r = walk.record
    if r.events.fall_time_s is not None:
        raise RuntimeError(f"the walk fell at {r.events.fall_time_s} s")
    t_end = float(r.time_s[-1])
    t0 = t_end - window_s
    sel = r.time_s > t0
    mass = r.body_mass_kg
    st = muscle_states(walk, T, lce0)
    um, bh = model_terms(st)
    fl_um, fl_bh = model_terms(muscle_states(walk, T, lce0, FLOOR, FLOOR))
    mism = 0.0
    for terms, rec in ((um, walk.metabolic_umberger_w), (bh, walk.metabolic_bhargava_w)):
        tot = sum(terms.values())
        scale = sum(np.abs(x) for x in terms.values())
        mism = max(mism, float(np.max(np.abs(tot - rec) / scale)))
    dist = float(r.pelvis_position_m[sel][-1, 0] - r.pelvis_position_m[sel][0, 0])
    dur = float(sel.sum() * r.sample_period_s)
    speed = dist / dur
    hs = np.asarray(r.events.heel_strikes_s[0])
    hs = hs[(hs > t0) & (hs <= t_end)]
    stride_s = float(np.diff(hs).mean())

    def per_kg(x):
        return float(x.sum(axis=(1, 2))[sel].mean() / mass)

    out = {"speed_m_s": speed, "stride_s": stride_s, "stride_m": speed * stride_s,
           "terms_sum_mismatch": mism, "window_s": (t0, t_end)}
    pub = sum(per_kg(x) for x in model_terms(st, negative_work=False)[0].values())
    out["umberger_published"] = {"net_w_per_kg": pub, "cot_j_per_kg_m": pub / speed,
                                 "stride_j_per_kg": pub * stride_s}
    for name, terms, floor in (("umberger", um, fl_um), ("bhargava", bh, fl_bh)):
        rates = {k: per_kg(x) for k, x in terms.items()}
        net = sum(rates.values())
        floor_rate = sum(per_kg(x) for x in floor.values())
        out[name] = {"terms_w_per_kg": rates, "net_w_per_kg": net,
                     "cot_j_per_kg_m": net / speed,
                     "stride_j_per_kg": net * stride_s,
                     "walk_cot_j_per_kg_m": walk.cost_of_transport(t0, t_end, name),
                     "floor_w_per_kg": floor_rate, "floor_cot_j_per_kg_m": floor_rate / speed}
    return out


def moco_2d() -> dict:
    """Moco's 2D walking example's net cost from its published gross figure
    (:data:`MOCO_2D_GROSS_COT_J_PER_KG_M`): speed = the half cycle's distance over its time,
    net COT = gross − basal / speed (J/(kg m)), net rate = net COT × speed (W/kg), per stride
    = net COT × two half cycles' distance (J/kg; the problem is left-right symmetric)."""
    speed = MOCO_2D_HALF_CYCLE_M / MOCO_2D_HALF_CYCLE_S
    cot = MOCO_2D_GROSS_COT_J_PER_KG_M - MOCO_BASAL_W_PER_KG / speed
    return {"speed_m_s": speed, "cot_j_per_kg_m": cot, "net_w_per_kg": cot * speed,
            "stride_j_per_kg": cot * 2.0 * MOCO_2D_HALF_CYCLE_M}


def format_tables(res: dict) -> str:
    """The block's markdown (two tables and a summary line) from :func:`analyse`."""
    lines = ["| model | term | mean rate W/kg | share of net |", "|---|---|---|---|"]
    for name, label in (("umberger", "Umberger 2010"), ("bhargava", "Bhargava 2004")):
        m = res[name]
        for k, x in m["terms_w_per_kg"].items():
            lines.append(f"| {label} | {TERM_LABELS[k]} | {x:.3f} | "
                         f"{100 * x / m['net_w_per_kg']:.1f} % |")
        lines.append(f"| {label} | **net (all muscles)** | **{m['net_w_per_kg']:.3f}** | "
                     f"100 % |")
    u, b = res["umberger"], res["bhargava"]
    diff = u["net_w_per_kg"] - b["net_w_per_kg"]
    lines += ["", "| term group | Umberger W/kg | Bhargava W/kg | difference W/kg | "
              "share of the difference |", "|---|---|---|---|---|"]
    for label, ku, kb in GROUPS:
        xu = sum(u["terms_w_per_kg"][k] for k in ku)
        xb = sum(b["terms_w_per_kg"][k] for k in kb)
        lines.append(f"| {label} | {xu:.3f} | {xb:.3f} | {xu - xb:.3f} | "
                     f"{100 * (xu - xb) / diff:.1f} % |")
    lines.append(f"| net | {u['net_w_per_kg']:.3f} | {b['net_w_per_kg']:.3f} | {diff:.3f} | "
                 f"100 % |")
    lines.append(f"| net COT J/(kg m) | {u['cot_j_per_kg_m']:.2f} | {b['cot_j_per_kg_m']:.2f} "
                 f"| | |")
    lines.append(f"| net energy per stride J/kg | {u['stride_j_per_kg']:.2f} | "
                 f"{b['stride_j_per_kg']:.2f} | | |")
    lines.append(f"| all 14 muscles at u = a = 0.01, W/kg | {u['floor_w_per_kg']:.3f} | "
                 f"{b['floor_w_per_kg']:.3f} | {u['floor_w_per_kg'] - b['floor_w_per_kg']:.3f}"
                 f" | {100 * (u['floor_w_per_kg'] - b['floor_w_per_kg']) / diff:.1f} % |")
    lines.append(f"| the same as COT J/(kg m) | {u['floor_cot_j_per_kg_m']:.2f} | "
                 f"{b['floor_cot_j_per_kg_m']:.2f} | | |")
    lines += ["", "| model, form | net W/kg | net COT J/(kg m) | net J/kg per stride | "
              "against Weyand et al. 2010 (2.74 ± 0.12 J/kg per stride) |",
              "|---|---|---|---|---|"]
    for label, m in (("Umberger 2010 as the walker records it (negative work, lengthening "
                      "4 α_ST, total ≥ 0: OpenSim's probe defaults, Uchida et al. 2016)", u),
                     ("Umberger 2010 as published (no negative work, lengthening 0.3 α_ST)",
                      res["umberger_published"]),
                     ("Bhargava 2004", b)):
        lines.append(f"| {label} | {m['net_w_per_kg']:.3f} | {m['cot_j_per_kg_m']:.2f} | "
                     f"{m['stride_j_per_kg']:.2f} | "
                     f"{m['stride_j_per_kg'] / WEYAND_J_PER_KG:.2f} × |")
    moco = moco_2d()
    lines.append(f"| Moco's 2D walking example, Bhargava 2004 smoothed (Falisse, opensim-moco "
                 f"PR #532: gross {MOCO_2D_GROSS_COT_J_PER_KG_M:g} J/(kg m) less the "
                 f"{MOCO_BASAL_W_PER_KG:g} W/kg basal rate at {moco['speed_m_s']:.2f} m/s) | "
                 f"{moco['net_w_per_kg']:.3f} | {moco['cot_j_per_kg_m']:.2f} | "
                 f"{moco['stride_j_per_kg']:.2f} | "
                 f"{moco['stride_j_per_kg'] / WEYAND_J_PER_KG:.2f} × |")
    t0, t1 = res["window_s"]
    lines += ["", f"Umberger / Bhargava: {u['net_w_per_kg'] / b['net_w_per_kg']:.2f} "
              f"(net rates); walk {t0:.1f}–{t1:.1f} s of the `1.25` set at "
              f"{res['speed_m_s']:.2f} m/s, stride {res['stride_s']:.2f} s "
              f"({res['stride_m']:.2f} m); per kg of body mass. "
              f"`tools/energy_model_terms.py`"]
    return "\n".join(lines)


def main(argv=None) -> int:
    args = mode_parser(__doc__.split("\n\n")[0]).parse_args(argv)
    res = analyse()
    if res["terms_sum_mismatch"] > 1e-9:
        print(f"the terms' sum differs from the recorded rates by "
              f"{res['terms_sum_mismatch']:.2e} (relative)", file=sys.stderr)
        return 1
    body = format_tables(res)
    if not (args.check or args.write):
        print(body)
        return 0
    return write_or_check(DOC, BEGIN, END, body, "energy-terms", args.write)


if __name__ == "__main__":
    raise SystemExit(main())
