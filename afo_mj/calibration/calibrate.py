"""Close the loop with measured data: replay, fit, find the missing effect, report the error.

Method (``afo-mj calibrate``; issue 7):

1. **Replay** the record's inputs through the device model on the bench
   (:class:`afo_mj.experiments.bench_replay.BenchReplay`), starting from the **lean model**: the
   preset with every effect of :mod:`afo_mj.calibration.effect_library` switched off, except the
   effects the user declares.
2. **Fit the declared parameters** (:func:`afo_mj.calibration.effect_library.declared_parameters`)
   on the training part of the record by bounded robust nonlinear least squares
   (``scipy.optimize.least_squares``, trust-region reflective, ``soft_l1`` loss: residuals
   beyond ~3 noise σ count linearly, so a spike or a missing effect does not drag every
   parameter). Residuals are per channel, normalised by the channel's standard deviation, so
   each channel weighs as its NRMSE does. The held-out part is the record's last whole cycles or
   segments (:meth:`afo_mj.calibration.measured_data.MeasuredData.split`); it is never fitted.
   The first ``settle_s`` of the record (the unknown initial state) is left out of every error.
3. **Analyse the residual** (:mod:`afo_mj.calibration.residual_analysis`): per channel NRMSE,
   whiteness (Ljung–Box), noise level, cross-correlation with inputs and states, signature
   correlations, phase average, dominant frequency.
4. **Rank every candidate cheaply**: each effect is switched on at a few probe values and its
   change of the outputs ``Δ`` is projected, together with the declared parameters'
   sensitivities ``J``, onto the residual ``r``. The score is the fraction of ``|r|²`` that
   ``[J, Δ]`` explains beyond ``J`` alone (a linearised score / Lagrange-multiplier test:
   Rao 1948; Engle 1984). Effects whose probe must be scaled negatively to help (e.g. a
   negative leakage) score zero. On a described rig the fraction is also taken with each
   channel in units of its noise σ, and the larger counts (:func:`_score`).
5. **Refit the top candidates** in the full model (declared + effect parameters), each from
   the better of its best probe and the optimum of the ranking's linearisation there
   (:meth:`Calibration.refit_start`), and keep the best one if it pays on all of: the Bayesian
   information criterion falls by more than ``bic_margin`` (Schwarz 1978; AIC is reported too), the
   held-out overall NRMSE falls by at least ``min_error_drop`` (relative; on a described rig,
   or its held-out error in noise units, :meth:`CalibrationModel.error_in_noise_units`), and
   its parameters are identifiable (relative standard error below ``max_relative_se`` and no
   correlation with another parameter above ``max_correlation``, from the Gauss–Newton
   covariance ``s² (JᵀJ)⁻¹``). Repeat greedily until no candidate pays or ``max_effects``
   are in.
6. **Verdict**: ``effect_found`` when at least one effect was added; otherwise
   ``no_missing_effect`` when every held-out residual is white and within ``1.2×`` its noise,
   else ``unexplained_residual`` with where the structure lives (channel, phase, input, lag,
   frequency).

NRMSE of a channel: ``RMS(measured − model)`` on the held-out part over the channel's standard
deviation in the whole record (a fixed scale: a channel that happens to be quiet in the held-out
cycles does not blow up). Overall NRMSE: the root mean square over the fitted output channels.

Code: :class:`Calibration` (here) runs the steps above, one method each (:meth:`Calibration.run`
is their outline); the record's split and scales and the model's replays, residuals and fits
are :class:`~afo_mj.calibration.calibration_model.CalibrationModel`, its base; the options and
the scenario files (a preset, or a rig described as a circuit with its load and sensors) are
read by :mod:`afo_mj.calibration.calibration_setup`. Their public names are importable from
here too.
"""

from __future__ import annotations

import dataclasses
import math
import time
from typing import Mapping, Sequence

import numpy as np

from afo_mj import progress
from afo_mj.calibration import residual_analysis as ra
from afo_mj.calibration.calibration_model import (
    DIFF_STEP, FIT_FTOL, REPLAY_CACHE_SIZE, SENSITIVITY_STEP_S, CalibrationModel, _Model,
    declared_labels, model_outputs, sensor_outputs)
from afo_mj.calibration.calibration_setup import (
    CALIBRATION_KEYS, CALIBRATION_TABLE, LOAD_KEYS, LOAD_TABLE, SENSOR_KEYS, SENSOR_TABLE,
    CalibrationError, CalibrationOptions, CalibrationSetup, load_calibration_scenario,
    load_calibration_setup)
from afo_mj.calibration.effect_library import Effect, described_off, effects_for
from afo_mj.calibration.identifiability import select_parameters
from afo_mj.calibration.measured_data import MeasuredData, MeasuredDataError
from afo_mj.calibration.record_checks import check_signs
from afo_mj.experiments.bench_replay import DEFAULT_MAX_STEP_S, BenchReplay, ReplayError
from afo_mj.hydraulics.params import ParameterError

__all__ = ["CalibrationOptions", "Calibration", "calibrate", "CalibrationError",
           "model_outputs", "sensor_outputs", "CalibrationSetup", "load_calibration_scenario",
           "calibrate_setup", "load_calibration_setup", "declared_labels", "CalibrationModel",
           "LOAD_TABLE", "LOAD_KEYS", "SENSOR_TABLE", "SENSOR_KEYS", "CALIBRATION_TABLE",
           "CALIBRATION_KEYS", "DIFF_STEP", "REPLAY_CACHE_SIZE", "FIT_FTOL"]


@dataclasses.dataclass
class _Residual:
    """A model's held-out errors and outputs and the analysis of its residual (step 3)."""

    err: dict
    out: dict
    whiteness: dict | None = None
    channels: dict | None = None
    baseline: dict | None = None        # the declared fit's: against the noise floor


@dataclasses.dataclass
class _Search:
    """Where the effect search (steps 4–5) stands: the model so far, the effects added (the
    report's ``effects_selected``) and every candidate's scores and refits."""

    model: _Model
    steps: list[dict]
    candidates: dict[str, dict]


@dataclasses.dataclass(frozen=True)
class _Verdict:
    """Step 6: the verdict, where the residual's structure lives, the data-driven
    discrepancy."""

    verdict: str
    where: str | None
    discrepancy: dict | None
    attribution: dict | None = None     # a described rig beyond its noise: what explains it


def _indistinguishable(refits: Sequence[tuple], m: _Model, e: Effect) -> list[str]:
    """The effects of the other paying ``refits`` (``(model, effect, record, ident)``)
    whose held-out error is within :data:`PLAUSIBILITY_SLACK` of the selected ``m``'s
    (effect ``e``): the record does not tell them apart from it (e.g. a leakage across the
    pistons or across the pump)."""
    return [t[1].name for t in refits if t[1] is not e
            and t[0].held_out["overall"] <= (1.0 + PLAUSIBILITY_SLACK) * m.held_out["overall"]]


def _refit_line(rec: dict) -> str:
    """A refit's progress line: its held-out error change, ΔBIC, whether it pays (and why
    not)."""
    line = (f"held-out error {-100 * rec['held_out_drop']:+.0f} %"
            + (f" ({-100 * rec['held_out_drop_noise_units']:+.0f} % in noise units)"
               if "held_out_drop_noise_units" in rec else "")
            + f", ΔBIC {rec['delta_bic']:+.1f}, ")
    if rec.get("plausibility"):
        return (line + ("taken: at the noise floor with every declared value within its "
                        "tolerance" if rec["pays"] else "not taken" + (
                            "" if rec["identifiable"] else " (not identifiable)")
                        + ("" if rec["at_noise"] else " (not at the noise floor)")
                        + (f" ({', '.join(rec['beyond_tolerance'])} beyond tolerance)"
                           if rec["beyond_tolerance"] else "")
                        + (f" (at a bound: {'; '.join(rec['at_bound'])})"
                           if rec.get("at_bound") else "")))
    if rec["pays"]:
        return line + "pays"
    return (line + "does not pay" + ("" if rec["identifiable"] else " (not identifiable)")
            + (f" (at a bound: {'; '.join(rec['at_bound'])})" if rec.get("at_bound") else "")
            + (f" (worse in {', '.join(u.replace('_', ' ') for u in rec['worsened_in'])})"
               if rec.get("worsened_in") else "")
            + (" (a gain on {} does as well: {:.0f} %)".format(
                rec["generic"]["channel"], 100 * rec["generic"]["held_out_drop"])
               if "beats_generic" in rec and not rec["beats_generic"] else ""))


class Calibration(CalibrationModel):
    """One record, one preset or described rig: the candidate search and the report's numbers
    (the model's replays and fits: :class:`CalibrationModel`)."""

    def __init__(self, data: MeasuredData, preset: str | None = None,
                 options: CalibrationOptions = CalibrationOptions(),
                 replay: BenchReplay | None = None):
        super().__init__(data, preset, options, replay)
        spread = {c: 0.5 * self.scale[c] + abs(float(np.mean(self.meas[c])))
                  for c in self.outputs}
        # a sensor gain/offset only for channels the user marks uncalibrated (issue 20: a
        # per-channel gain must not absorb structure on a channel the user vouches for)
        uncal = options.uncalibrated_channels or ()
        self.library = effects_for(
            self.outputs, spread, self.available,
            is_off=lambda e: described_off(e, self.replay.value), uncalibrated=uncal,
            described=self.described)
        names = [e.name for e in self.library]
        for n in options.declared_effects + options.candidates:
            if n not in names:
                raise ParameterError(f"calibration effect {n!r}; allowed: {', '.join(names)}")
        self.declared_effects = [e for e in self.library if e.name in options.declared_effects]
        pool = [e for e in self.library if e.name not in options.declared_effects]
        if options.candidates:
            pool = [e for e in pool if e.name in options.candidates]
        self.candidates = pool
        self.min_refit_score = (options.min_refit_score if options.min_refit_score is not None
                                else 0.05 if self.described else 1e-4)
        #: the first ranking's sensitivities (declared values at the declared fit, each
        #: candidate's change at its best probe; :meth:`rank`)
        self.rank_columns: dict | None = None
        self.screen_columns: dict = {}
        self.row_weights: np.ndarray | None = None

    # ---------------------------------------------------------------- ranking
    def _declared_jacobian(self, m: _Model, f0: np.ndarray) -> np.ndarray:
        """Forward-difference sensitivities of the training residuals to the declared
        parameters at ``m.x`` (steps ``0.01 · max(|x_j|, 0.1)``); a column the fit's last
        Jacobian took with the same step is reused, not replayed again. The others are taken
        at :attr:`sensitivity_step_s` when one is set (``f0`` is then replayed there too)."""
        cols: list = []
        f0c = None
        for j in range(len(self.declared)):
            x = m.x.copy()
            step = 0.01 * max(abs(x[j]), 0.1)
            if m.raw_jac is not None and m.jac_steps[j] == step:
                cols.append(m.raw_jac[:, j])
                continue
            x[j] += step
            with self.at_sensitivity_step() as coarse:
                if f0c is None:
                    f0c = self.train_residuals(m.effects, m.x) if coarse else f0
                cols.append((self.train_residuals(m.effects, x) - f0c) / step)
        return np.array(cols).T

    def _probes(self, e: Effect) -> list[list[float]]:
        typ = [self._typical(e, p) for p in e.parameters]
        if e.name.startswith("sensor_gain_offset"):
            return [typ]
        probes = []
        for f in (0.3, 1.0, 3.0):
            v = list(typ)
            v[0] = float(np.clip(typ[0] * f, e.parameters[0].lo, e.parameters[0].hi))
            if e.parameters[0].name == "current_limit_a":
                v[0] = float(np.clip(typ[0] * (0.7 + 0.3 * f), e.parameters[0].lo,
                                     e.parameters[0].hi))
            probes.append(v)
        if self.described:
            # a described rig: the shape parameters' other plausible values too
            for j, p in enumerate(e.parameters[1:], start=1):
                for alt in p.probe_values:
                    for base in list(probes[:3]):
                        v = list(base)
                        v[j] = float(np.clip(alt, p.lo, p.hi))
                        probes.append(v)
        return probes

    def rank(self, m: _Model, pool: Sequence[Effect], label: str = "",
             J: np.ndarray | None = None) -> list[dict]:
        """Score every candidate by the linearised projection (module docstring, step 4) at
        the model ``m``, against the declared parameters' sensitivities ``J`` (default: taken
        at ``m.x``); progress (:mod:`afo_mj.progress`) as ``label: ranking N candidate
        effects``. Each score carries where it was taken (``base``: ``m``)."""
        task = progress.reporter().task(f"{label or 'calibration'}: ranking {len(pool)} "
                                        "candidate effects", len(pool), "effects",
                                        fmt=lambda v: f"{v:.0f}")
        f0 = self.train_residuals(m.effects, m.x) if m.fun is None else m.fun
        if J is None:
            J = self._declared_jacobian(m, f0)
        r = -f0
        # a described rig also scores in units of each channel's noise (:func:`_score`)
        w = self.noise_weights() if self.described else None
        base = _ScoreBase(J, r, w)
        first = self.rank_columns is None
        if first:
            # the declared fit's sensitivities and each candidate's change at its best
            # probe: what a declared value beyond its tolerance is compared with
            self.rank_columns = {"declared": {d.name: J[:, j]
                                              for j, d in enumerate(self.declared)},
                                 "effects": {}}
        scores = []
        kd = len(self.declared)
        # each probe's change of the outputs is replayed at the sensitivity step, beside the
        # base there (a difference at one step: the stepper's own error cancels); the probe's
        # residual is that change added to the base's residual at the replay's step
        with self.at_sensitivity_step() as coarse:
            f0c = self.train_residuals(m.effects, m.x) if coarse else f0
        for e in pool:
            best = {"effect": e.name, "score": 0.0, "probe": None, "base": m}
            for probe in self._probes(e):
                xp = [v / p.scale for v, p in zip(probe, e.parameters)]
                x = np.concatenate([m.x, xp])
                try:
                    with self.at_sensitivity_step():
                        f1 = self.train_residuals(m.effects + [e], x) - f0c + f0
                except ParameterError:
                    continue
                xe = None
                if e.name.startswith("sensor_gain_offset"):
                    # two directions: gain (∝ the model output) and offset (constant)
                    k = self.outputs.index(e.channel)
                    n1 = len(self.train_idx)
                    col_g = np.zeros_like(f0)
                    col_o = np.zeros_like(f0)
                    y = (f0[k * n1:(k + 1) * n1] * self.scale[e.channel]
                         + self.meas[e.channel][self.train_idx])
                    col_g[k * n1:(k + 1) * n1] = y / self.scale[e.channel]
                    col_o[k * n1:(k + 1) * n1] = 1.0
                    sc, coef = _score(base, np.column_stack([col_g, col_o]))
                    # the linearised optimum: gain 1 + c_g, offset c_o channel scales
                    xe = [(1.0 + coef[-2]) / e.parameters[0].scale,
                          coef[-1] * self.scale[e.channel] / e.parameters[1].scale]
                else:
                    # a probe that must be applied with the wrong sign scores zero
                    sc, coef = _score(base, (f1 - f0)[:, None],
                                      signed=e.parameters[0].lo >= 0.0)
                    if sc > 0.0:
                        # the linearised optimum: the probe's change scaled by c_Δ
                        xe = [coef[-1] * xp[0]] + xp[1:]
                if first and not e.name.startswith("sensor_gain_offset") and (
                        e.name not in self.rank_columns["effects"] or sc > best["score"]):
                    self.rank_columns["effects"][e.name] = f1 - f0
                if sc > best["score"]:
                    best = {"effect": e.name, "score": float(sc), "probe": probe, "base": m,
                            "probe_cost": self._robust_cost(f1), "linear_start": (
                                None if xe is None else np.concatenate(
                                    [m.x[:kd] + coef[:kd], m.x[kd:], xe]))}
            scores.append(best)
            task.advance()
        scores.sort(key=lambda s: -s["score"])
        top = ", ".join(f"{s['effect']} {s['score']:.3f}" for s in scores[:3] if s["score"] > 0)
        task.close(f"{task.label}: done in {progress.fmt_duration(task.elapsed())}"
                   + (f"; best scores: {top}" if top else "; no candidate explains the residual"))
        return scores

    def refit_start(self, m: _Model, e: Effect, sc: dict) -> tuple[np.ndarray, float]:
        """Where the refit of ``m`` plus candidate ``e`` may start from the ranking ``sc``
        (taken at ``m``): its best probe, or the optimum of the ranking's linearisation there
        (the declared parameters moved by their least-squares step, the effect at the fitted
        multiple of its probe's change), whichever has the lower training cost (one replay
        more; the fit's first). Returns the start and its robust training cost."""
        effects = m.effects + [e]
        x_probe = np.concatenate([m.x, [v / p.scale for v, p in zip(sc["probe"],
                                                                     e.parameters)]])
        probe = (x_probe, float(sc.get("probe_cost", math.inf)))
        if sc.get("linear_start") is None:
            return probe
        x_lin = self._interior(effects, sc["linear_start"])
        try:
            f_lin = self.train_residuals(effects, x_lin)
        except ParameterError:
            return probe
        cost = self._robust_cost(f_lin) if np.all(np.isfinite(f_lin)) else math.inf
        return (x_lin, cost) if cost < probe[1] else probe

    # ---------------------------------------------------------------- identifiability
    def select_declared(self) -> None:
        """A described rig: replay once per declared parameter (1 % steps of its factor),
        select what the record can estimate (:func:`select_parameters`), hold the rest at
        the description's values. Sets :attr:`identifiability_table`."""
        if not self.described or not self.declared:
            return
        k = len(self.declared)
        lo, hi = self._bounds([])
        progress.reporter().stage(f"calibration: identifiability of {k} declared parameters "
                                  f"({k + 1} replays)…")
        with self.at_sensitivity_step():
            J, _ = self.jacobian([], np.ones(k), lo, hi)
        w = self.noise_weights()
        movable = [self.declared_value(d, labels) != 0.0
                   for d, labels in zip(self.declared, self.declared_labels)]
        ident = select_parameters(J, [d.name for d in self.declared], w, movable=movable,
                                  tolerances=[d.tolerance for d in self.declared])
        self.identifiability_table = ident
        #: the screen's sensitivities of every screened declared value (at the described
        #: values) and the whitening: what a deviation is compared with (
        #: :meth:`equivalents`)
        self.screen_columns = {d.name: J[:, j] for j, d in enumerate(self.declared)}
        self.row_weights = w
        self.held_declared = {d.name: self.declared_value(d, labels)
                              for i, (d, labels) in enumerate(zip(self.declared,
                                                                  self.declared_labels))
                              if i not in ident.selected}
        self.declared = tuple(self.declared[i] for i in ident.selected)
        self.declared_labels = [self.declared_labels[i] for i in ident.selected]
        progress.reporter().stage(
            "calibration: fitting " + (", ".join(d.name for d in self.declared) or "nothing")
            + "; held at the description's values: " + (", ".join(self.held_declared)
                                                         or "none"))

    def sensor_lags(self, out: Mapping[str, np.ndarray], max_lag: int = 25) -> dict:
        """Per channel, the time shift of the measured channel against the model's that
        maximises their correlation on the settled record (integer lags up to ``max_lag``
        samples, refined by a parabola through the peak; Bendat & Piersol, *Random Data*,
        §11.1): how far the sensor's clock sits from the model's. Positive: the measurement
        lags. A shift shared by every channel is an acquisition delay (the ``sensor_delay``
        candidate); one channel's alone, that sensor's lag or filter."""
        i0 = int(np.searchsorted(self.t, self.t[0] + self.options.settle_s))
        dt = 1.0 / self.fs_hz
        lags = {}
        for c in self.outputs:
            y = np.asarray(out[c][i0:], dtype=float)
            z = np.asarray(self.meas[c][i0:], dtype=float)
            n = len(y)
            if n <= 4 * max_lag or np.std(y) == 0.0:
                lags[c] = None
                continue
            y = y - y.mean()
            z = z - z.mean()
            ks = np.arange(-max_lag, max_lag + 1)
            r = np.array([np.dot(z[max_lag + k:n - max_lag + k], y[max_lag:n - max_lag])
                          for k in ks])
            j = int(np.argmax(r))
            shift = float(ks[j])
            if 0 < j < len(ks) - 1:
                den = r[j - 1] - 2 * r[j] + r[j + 1]
                if den < 0:
                    shift += 0.5 * (r[j - 1] - r[j + 1]) / den
            lags[c] = shift * dt
        return lags

    def at_bound(self, e: Effect, xe: np.ndarray) -> list[str]:
        """The parameters of effect ``e`` (normalised values ``xe``) that the fit pinned
        within 1 % of the span (of its logarithm, for a positive range over decades) at a
        library bound (a lower bound of 0, an effect's natural "off", does not count): such a
        value is not a physical estimate."""
        out = []
        for p, v in zip(e.parameters, xe):
            val = float(v) * p.scale
            if p.lo > 0.0 and p.hi / p.lo >= 10.0 and val > 0.0:
                # a range over decades: 1 % of its logarithmic span
                span = math.log(p.hi / p.lo)
                near = (math.log(p.hi / val) < 0.01 * span
                        or math.log(val / p.lo) < 0.01 * span)
            else:
                span = p.hi - p.lo
                near = p.hi - val < 0.01 * span or (p.lo != 0.0 and val - p.lo < 0.01 * span)
            if near:
                out.append(f"{p.name} = {val:.3g} {p.unit} at its bound [{p.lo:g}, {p.hi:g}]")
        return out

    def generic_correction(self, m: _Model, n_params: int) -> dict:
        """The best generic discrepancy with ``n_params`` parameters (1: a gain, 2: a gain and
        an offset) on one output channel of model ``m``, fitted on the training part by linear
        least squares: its held-out overall NRMSE drop and channel, and its best drop of the
        held-out error in noise units (:meth:`error_in_noise_units`) and that channel. A
        named effect must do better (issue 20: a per-channel gain must not win by absorbing
        structure), in the units it pays in (:meth:`judge_refit`)."""
        out = self.simulate(m.effects, m.x)
        base = m.held_out["overall"]
        base_noise = self.error_in_noise_units(m.held_out)
        best = {"channel": None, "held_out_drop": 0.0, "parameters": n_params,
                "noise_units_channel": None, "held_out_drop_noise_units": 0.0}
        tr, te = self.train_idx, self.test_idx
        for c in self.outputs:
            y, z = out[c], self.meas[c]
            cols = [y] if n_params <= 1 else [y, np.ones_like(y)]
            A = np.column_stack([col[tr] for col in cols])
            coef, *_ = np.linalg.lstsq(A, z[tr], rcond=None)
            yc = np.column_stack(cols) @ coef
            err = {k: m.held_out[k] for k in self.outputs}
            err[c] = float(np.sqrt(np.mean((yc[te] - z[te]) ** 2)) / self.scale[c])
            overall = float(math.sqrt(np.mean([err[k] ** 2 for k in self.outputs])))
            drop = 1.0 - overall / base
            if drop > best["held_out_drop"]:
                best.update({"channel": c, "held_out_drop": drop})
            drop_noise = 1.0 - self.error_in_noise_units(err) / base_noise
            if drop_noise > best["held_out_drop_noise_units"]:
                best.update({"noise_units_channel": c, "held_out_drop_noise_units": drop_noise})
        return best

    def declared_deviations(self, m: _Model, ident: dict) -> list[dict]:
        """Fitted declared parameters beyond their datasheet tolerance
        (:attr:`DeclaredParameter.tolerance`) by more than 3 standard errors, largest first
        (in tolerances), each with what such a deviation is indistinguishable from: on a
        described rig the effects and other declared values whose sensitivity points the
        same way (:meth:`equivalents`), on a preset the hand-written
        :attr:`DeclaredParameter.above`/``below``."""
        out = []
        for j, (d, labels) in enumerate(zip(self.declared, self.declared_labels)):
            if d.tolerance <= 0.0:
                continue
            f = float(m.x[j])
            sd = float(ident["sd"][j])
            change = f - 1.0
            if not (abs(change) > d.tolerance and abs(change) > 3.0 * sd):
                continue
            datasheet = self.declared_value(d, labels)
            row = {"parameter": d.name, "unit": d.unit, "datasheet": datasheet,
                   "fitted": datasheet * f, "relative_change": change,
                   "relative_sd": sd if math.isfinite(sd) else None,
                   "tolerance": d.tolerance, "in_tolerances": abs(change) / d.tolerance}
            if d.path:
                eq = self.equivalents(d.name, change)
                row["equivalents"] = eq
                row["equivalent_to"] = [
                    f"{q['name']} ({q['type']}{' ' + q['direction'] if q['direction'] else ''}"
                    f", similarity {q['similarity']:.2f})" for q in eq]
            else:
                row["equivalent_to"] = list(d.above if change > 0 else d.below)
            out.append(row)
        out.sort(key=lambda r: -r["in_tolerances"])
        return out

    def equivalents(self, name: str, change: float) -> list[dict]:
        """What declared value ``name`` moved by the relative ``change`` is indistinguishable
        from in this record: every candidate effect (switched on) and every other declared
        value (raised or lowered) whose change of the outputs points the same way as the
        deviation's, by the cosine of their noise-whitened sensitivity columns
        (:func:`afo_mj.calibration.identifiability.similarity`) at least
        :data:`EQUIVALENT_SIMILARITY`, most similar first. The columns are the identifiability
        screen's (declared values, at the described values) and the first ranking's (the
        declared fit's fitted values; each candidate's change at its best probe): no replay
        is run for this."""
        from afo_mj.calibration.identifiability import similarity
        w = self.row_weights
        rank = self.rank_columns or {"declared": {}, "effects": {}}
        # each pair compared at one point: declared values at the described values (the
        # screen's), the deviation and the effects at the declared fit (the ranking's)
        cols = self.screen_columns
        col = cols.get(name)
        if col is None or w is None:
            return []
        sign = 1.0 if change > 0 else -1.0
        out = []
        for other, c in cols.items():
            if other == name:
                continue
            s = similarity(sign * col, c, w)
            if abs(s) >= EQUIVALENT_SIMILARITY:
                out.append({"name": other, "type": "declared value",
                            "direction": "raised" if s > 0 else "lowered",
                            "similarity": abs(s)})
        col = rank["declared"].get(name, col)
        for e in self.library:
            c = rank["effects"].get(e.name)
            if c is None:
                continue
            s = similarity(sign * col, c, w)
            two_sided = e.parameters[0].lo < 0.0
            if s >= EQUIVALENT_SIMILARITY or (two_sided and -s >= EQUIVALENT_SIMILARITY):
                out.append({"name": e.name, "type": "effect", "direction": "",
                            "similarity": abs(s)})
        out.sort(key=lambda q: -q["similarity"])
        return out

    # ---------------------------------------------------------------- the whole method
    def run(self) -> dict:
        """The method (module docstring, steps 1–6) on the record; returns the report
        dictionary (:func:`calibrate`)."""
        t_start = time.perf_counter()
        self.held_declared: dict[str, float] = {}
        replay_step = self.choose_step()                      # before any replay is fitted
        replay_step = self.set_sensitivity_step(replay_step)
        self.select_declared()
        self.drop_fitted_candidates()
        structure = list(self.declared_effects)
        lean_err = self.lean_model()                          # 1. lean model
        declared_fit = self.declared_fit(structure)           # 2. declared fit
        before = self.baseline(declared_fit)                  # 3. its residual
        search = self.search_effects(declared_fit, structure)  # 4.-5. ranking, refits
        after = self.analyse_residuals(before, search.model)  # 3. both residuals
        numerical = self.numerical_check(search.model)        # the replay's own error
        verdict = self.verdict(before, after, bool(search.steps), numerical)  # 6. verdict
        return self.report(t_start, lean_err, declared_fit, before, search, after, verdict,
                           numerical, replay_step)

    def choose_step(self) -> dict:
        """The replay's maximum sub-step, set before the first replay of the method: the
        scenario's ``replay_max_step_s`` when it states one; on a described rig otherwise the
        step the numerical check chooses on the described model
        (:func:`afo_mj.calibration.numerical_check.choose_replay_step`, on the record's first
        ``numerical_check_s``); a preset keeps the replay's. Returns the report's
        ``replay_step``."""
        from afo_mj.calibration.numerical_check import choose_replay_step
        stated = self.options.replay_max_step_s
        if stated is not None:
            self.replay.max_step_s = float(stated)
            return {"source": "scenario", "max_step_s": float(stated), "tried": [],
                    "reason": "[calibration] replay_max_step_s (no choice made)"}
        if not self.described:
            return {"source": "default", "max_step_s": float(self.replay.max_step_s),
                    "tried": [], "reason": "a preset's replay keeps its step (the choice is "
                    "made for a rig described as a circuit)"}
        rep = progress.reporter()
        rep.stage("calibration: choosing the replay's step against Radau on the first "
                  f"{self.options.numerical_check_s:g} s…")
        self.replay.max_step_s = DEFAULT_MAX_STEP_S
        out = choose_replay_step(self, float(self.options.numerical_check_s),
                                 self.options.baseline_noise_multiple, DEFAULT_MAX_STEP_S)
        tried = ", ".join(f"{1e3 * t['max_step_s']:g} ms: {t['max_ratio']:.2f}σ"
                          for t in out["tried"] if t["max_ratio"] is not None)
        rep.stage(f"calibration: replay step {1e3 * out['max_step_s']:g} ms"
                  + (f" (largest replay − Radau difference {tried})" if tried else "")
                  + (f"; {out['reason']}" if out.get("reason") else ""))
        self._replays.clear()
        return out

    def set_sensitivity_step(self, replay_step: dict) -> dict:
        """When the replay's step (chosen or stated) is finer than
        :data:`~afo_mj.calibration.calibration_model.SENSITIVITY_STEP_S`, the sensitivities
        (the identifiability screen, the rankings' probes, a ranking's declared columns not
        reused from a fit) and each fit's first stage are replayed at that step, and only
        the fits' last stage, their held-out errors and the refits' judgement at the
        replay's own (:meth:`CalibrationModel.fit`). Returns ``replay_step`` with
        ``sensitivity_step_s`` (None: the replay's own step throughout)."""
        fine = float(self.replay.max_step_s)
        self.sensitivity_step_s = (SENSITIVITY_STEP_S if self.described
                                   and SENSITIVITY_STEP_S > fine * (1.0 + 1e-9) else None)
        return {**replay_step, "sensitivity_step_s": self.sensitivity_step_s}

    def numerical_check(self, m: _Model) -> dict:
        """The final model ``m`` integrated by Radau beside the replay on the record's first
        ``numerical_check_s`` (:func:`afo_mj.calibration.numerical_check.
        numerical_error_check`): the replay's own numerical error per channel against the
        noise σ and the residual. A check, not a fit."""
        from afo_mj.calibration.numerical_check import numerical_error_check
        w = float(self.options.numerical_check_s)
        if w > 0.0:
            progress.reporter().stage(f"calibration: numerical check of the replay against "
                                      f"Radau on the first {w:g} s…")
        out = numerical_error_check(self, m.effects, m.x, w,
                                    self.options.baseline_noise_multiple)
        if out.get("run"):
            progress.reporter().stage(
                f"calibration: numerical check done in {out['wall_s']:.1f} s; largest "
                f"replay − Radau difference {out['max_ratio']:.2f}× a channel's noise σ")
        return out

    def drop_fitted_candidates(self) -> None:
        """A described rig: an effect writing a fitted declared parameter is that parameter,
        not a candidate (it leaves :attr:`candidates`)."""
        if self.described:
            fitted = {self.replay.resolve(lab) for labels in self.declared_labels
                      for lab in labels}
            self.candidates = [e for e in self.candidates
                               if not {self.replay.resolve(lab) for lab in e.labels} & fitted]

    def lean_model(self) -> dict:
        """Step 1: the lean model (declared parameters at their declared values, no effect)
        replayed on the record; its held-out errors (the report's ``error_preset``). An output
        anti-correlated with it is a flipped sign convention: refused
        (:func:`~afo_mj.calibration.record_checks.check_signs`)."""
        lean_err, lean_out = self.held_out_errors([], np.ones(len(self.declared)))
        settled = np.nonzero(self.t >= self.t[0] + self.options.settle_s)[0]
        flipped = check_signs({c: self.meas[c][settled] for c in self.outputs},
                              {c: lean_out[c][settled] for c in self.outputs},
                              tuple(self.inputs))
        if flipped:
            raise CalibrationError("; ".join(f.message for f in flipped))
        return lean_err

    def declared_fit(self, structure: list[Effect]) -> _Model:
        """Step 2: the declared parameters (and the declared effects ``structure``, from their
        typical values) fitted on the training part."""
        rep = progress.reporter()
        x0 = np.concatenate([np.ones(len(self.declared))] + [
            [self._typical(e, p) / p.scale for p in e.parameters] for e in structure])
        t_fit = time.perf_counter()
        rep.stage(f"calibration: fitting the {len(self.declared)} declared parameters"
                  + (f" and {len(structure)} declared effects" if structure else "") + "…")
        m = self.fit(structure, x0)
        rep.stage(f"calibration: declared fit done in "
                  f"{progress.fmt_duration(time.perf_counter() - t_fit)} "
                  f"({self.evaluations} replays); held-out NRMSE "
                  f"{m.held_out['overall']:.4f}; up to {self.options.max_effects} rounds of "
                  f"{len(self.candidates)} candidate effects follow")
        return m

    def baseline(self, m: _Model) -> _Residual:
        """Step 3 on the declared fit ``m``: its held-out errors against each channel's noise
        floor (``baseline``: a described rig's declared structure must reach
        ``baseline_noise_multiple`` times it), the sensors' time shifts and the residual's
        whiteness."""
        before = _Residual(*self.held_out_errors(m.effects, m.x))
        floor = self.noise_floor()
        mult = self.options.baseline_noise_multiple
        b = {"noise_multiple": mult, "noise_floor": floor,
             "held_out": {c: before.err[c] for c in self.outputs},
             "ratio": {c: before.err[c] / max(floor[c], 1e-12) for c in self.outputs}}
        b["reaches_noise"] = bool(all(v <= mult for v in b["ratio"].values()))
        b["lag_s"] = self.sensor_lags(before.out)
        before.baseline = b
        before.whiteness = self._whiteness(before.out)
        return before

    def search_effects(self, start: _Model, structure: list[Effect]) -> _Search:
        """Steps 4–5: greedy rounds of ranking and refitting from the declared fit ``start``,
        each adding the candidate that pays best, until none pays, the pool is empty or
        ``max_effects`` are in."""
        s = _Search(start, [], {})
        pool = list(self.candidates)
        plausibility = False
        while len(s.model.effects) - len(structure) < self.options.max_effects and pool:
            added = (self.plausibility_round(s, pool) if plausibility
                     else self.search_round(s, pool))
            if added is None:
                if (not plausibility and self.screen_columns
                        and self.beyond_tolerance(s.model) and self.explains(s.model)):
                    # no candidate pays on a model (the declared fit alone, or with the
                    # effects found) that needs a declared value beyond its tolerance: the
                    # plausibility round asks whether an effect explains the record as well
                    # within the datasheet
                    progress.reporter().stage(
                        f"calibration: no candidate pays, but the model holds "
                        f"{', '.join(self.beyond_tolerance(s.model))} beyond its datasheet "
                        "tolerance; the candidates ranked from the described values are "
                        "refitted within it")
                    plausibility = True
                    continue
                break
            pool = [c for c in pool if c.name != added.name]
            if self.at_noise(s.model):
                beyond = self.beyond_tolerance(s.model)
                if not beyond or not self.screen_columns:
                    progress.reporter().stage(
                        f"calibration: every channel within {AT_NOISE_MULTIPLE:g}× its noise "
                        "floor; no candidate can improve beyond the noise, the search ends")
                    break
                # at the noise floor, but only with a declared value beyond its datasheet
                # tolerance: an effect that explains the record as well with every declared
                # value within its tolerance is the more plausible model
                progress.reporter().stage(
                    f"calibration: every channel within {AT_NOISE_MULTIPLE:g}× its noise "
                    f"floor, but with {', '.join(beyond)} beyond its datasheet tolerance; "
                    "the candidates ranked from the described values are refitted")
                plausibility = True
        for name, entry in s.candidates.items():
            entry["best_score"] = max(entry["scores"]) if entry["scores"] else 0.0
            entry["selected"] = any(st["effect"] == name for st in s.steps)
        return s

    def search_round(self, s: _Search, pool: list[Effect]) -> Effect | None:
        """One round: rank ``pool`` on the residual of ``s.model`` (step 4) and, when
        ``s.model`` holds a declared value beyond its datasheet tolerance, also from the
        described values (:meth:`described_ranking`); refit the top ``refit_top`` whose
        better score exceeds ``min_refit_score`` (step 5), each from its start of lowest
        training cost (:meth:`refit_candidate`), and add the paying one with the lowest
        held-out error to ``s``; returns it, or ``None`` when none pays."""
        opts = self.options
        rep = progress.reporter()
        rnd_no = len(s.steps) + 1
        rnd = f"calibration round {rnd_no}/{opts.max_effects}"
        rankings = [self.rank(s.model, pool, rnd)]
        described = self.described_ranking(s.model, pool, rnd)
        if described is not None:
            rankings.append(described)
        info_cur = self.information(s.model)
        per_effect: dict[str, list[dict]] = {}
        for ranking in rankings:
            for sc in ranking:
                per_effect.setdefault(sc["effect"], []).append(sc)
        combined = []
        for name, scs in per_effect.items():
            entry = s.candidates.setdefault(name, {"scores": []})
            score = max(q["score"] for q in scs)
            entry["scores"].append(round(score, 6))
            if len(scs) > 1:
                entry.setdefault("scores_by_start", []).append(
                    {"round": rnd_no, "declared_fit": round(scs[0]["score"], 6),
                     "described_values": round(scs[1]["score"], 6)})
            combined.append((score, name, scs))
        combined.sort(key=lambda t: -t[0])
        top = [t for t in combined if t[0] > self.min_refit_score][:opts.refit_top]
        refits = rep.task(f"{rnd}: refitting the top {len(top)} candidates", len(top),
                          "refits", fmt=lambda v: f"{v:.0f}")
        tried = []
        for k, (score, name, scs) in enumerate(top):
            e = next(c for c in pool if c.name == name)
            got = self.refit_candidate(s, e, score, scs, rnd_no, info_cur)
            if got is not None:
                tried.append(got)
                rep.stage(f"{rnd}: {e.name}: " + _refit_line(got[2]))
            refits.advance()
            if got is not None and got[2]["pays"] and self.at_noise(got[0]) and not (
                    k + 1 < len(top) and top[k + 1][0] >= (1.0 - PLAUSIBILITY_SLACK) * score):
                # what is left is noise: a lower-ranked candidate cannot do better beyond it
                # (one that scored within the slack of it is refitted still: the two may
                # explain the record alike, and are then listed as indistinguishable)
                break
        refits.close()
        paying = [t for t in tried if t[2]["pays"]]
        if not paying:
            rep.stage(f"{rnd}: no candidate pays; the search ends")
            return None
        m, e, rec, ident = min(paying, key=lambda t: t[0].held_out["overall"])
        rep.stage(f"{rnd}: selected {e.name}")
        step = self.selected_step(s.model, m, e, rec, ident)
        # the others that paid within the plausibility slack of it: the record does not
        # tell them apart (as in the plausibility round)
        step["indistinguishable_from"] = _indistinguishable(paying, m, e)
        s.steps.append(step)
        s.model = m
        return e

    def plausibility_round(self, s: _Search, pool: list[Effect]) -> Effect | None:
        """A round after the search stopped on a model ``s.model`` that holds a declared
        value beyond its datasheet tolerance (:meth:`search_effects`): it reached the noise
        floor, or no candidate paid.

        A fit that needs a declared value beyond its tolerance is less plausible than one
        that explains the record as well with every declared value within it: the datasheet
        is evidence too. So the pool is ranked from the described values
        (:meth:`described_ranking`: the values beyond their tolerance left out of the
        projection) and its top ``refit_top`` above ``min_refit_score`` are refitted from
        there, each with every declared value bounded to its datasheet tolerance
        (:meth:`CalibrationModel.fit` ``within_tolerance``: an effect and a declared value
        that act alike, such as a piston leakage and the pump's slip, could otherwise trade
        places again along their common valley). A refit is taken when it explains the record
        as well (at the noise floor, :meth:`at_noise`, or a held-out error within
        :data:`PLAUSIBILITY_SLACK` of the model it replaces), holds every declared value within
        its tolerance, and its new parameters are identifiable (a declared value pinned at its
        tolerance held in the covariance) and not pinned at a library bound
        (:meth:`judge_refit` with ``plausibility``; the held-out drop and ΔBIC of the other
        rounds do not apply: the model it replaces fits as well already, and is judged less
        plausible, not worse fitting). Of those
        taken, the lowest held-out error is added, the others within the slack of it listed as
        indistinguishable from it (``indistinguishable_from``). Returns
        the effect added, or ``None``."""
        rep = progress.reporter()
        rnd_no = len(s.steps) + 1
        rnd = f"calibration round {rnd_no}/{self.options.max_effects} (plausibility)"
        ranking = self.described_ranking(s.model, pool, rnd)
        if ranking is None:
            return None
        info_cur = self.information(s.model)
        top = []
        for sc in ranking:
            entry = s.candidates.setdefault(sc["effect"], {"scores": []})
            entry["scores"].append(round(sc["score"], 6))
            entry.setdefault("scores_by_start", []).append(
                {"round": rnd_no, "described_values": round(sc["score"], 6),
                 "plausibility_round": True})
            if sc["score"] > self.min_refit_score and len(top) < self.options.refit_top:
                top.append(sc)
        taken = []
        for sc in top:
            e = next(c for c in pool if c.name == sc["effect"])
            got = self.refit_candidate(s, e, sc["score"], [sc], rnd_no, info_cur,
                                       plausibility=True)
            if got is None:
                continue
            rep.stage(f"{rnd}: {e.name}: " + _refit_line(got[2]))
            if got[2]["pays"]:
                taken.append(got)
        if not taken:
            rep.stage(f"{rnd}: no candidate explains the record as well with every declared "
                      "value within its tolerance; the search ends")
            return None
        m, e, rec, ident = min(taken, key=lambda t: t[0].held_out["overall"])
        rep.stage(f"{rnd}: selected {e.name}")
        step = self.selected_step(s.model, m, e, rec, ident)
        step["selected_by"] = (
            "plausibility: the model before it explained the record only with "
            + ", ".join(rec["replaced_beyond_tolerance"]) + " beyond its datasheet "
            "tolerance; with this effect it explains it as well (every channel within "
            f"{AT_NOISE_MULTIPLE:g}× its noise floor, or a held-out error within "
            f"{100 * PLAUSIBILITY_SLACK:g} % of it) with every declared value within its "
            "tolerance")
        # the others taken explain it as well: within the slack of the one selected, the
        # record does not tell them apart (e.g. a leakage across the pistons or the pump)
        step["indistinguishable_from"] = _indistinguishable(taken, m, e)
        s.steps.append(step)
        s.model = m
        return e

    def at_noise(self, m: _Model) -> bool:
        """Whether every channel's held-out NRMSE of ``m`` is within
        :data:`AT_NOISE_MULTIPLE` times its noise floor (a described rig; a preset's search
        goes on as before)."""
        return self._within_floor(m, AT_NOISE_MULTIPLE)

    def _within_floor(self, m: _Model, multiple: float) -> bool:
        """Whether every channel's held-out NRMSE of ``m`` is within ``multiple`` times its
        noise floor (a described rig with held-out errors; else False)."""
        if not self.described or m.held_out is None:
            return False
        floor = self.noise_floor()
        return all(m.held_out[c] <= multiple * floor[c] for c in self.outputs)

    def explains(self, m: _Model) -> bool:
        """Whether ``m`` explains the record: every channel's held-out NRMSE within
        ``baseline_noise_multiple`` times its noise floor (what :func:`explains_record`
        asks of a model before its declared values beyond tolerance name anything).

        Only such a model goes to a :meth:`plausibility_round` when no candidate pays:
        one that still misses the record (rig 2's brushes dropping 0.3 V: the angle 66× its
        floor with the bulk modulus at 2.7×) holds its declared values where the fit bent
        them toward what it lacks, and an effect that misses the record "as well" within
        the datasheet is the same bending, not a more plausible explanation (there, a
        current limit of 8.9 A with the held-out error 0.9 % worse and ΔBIC +1406)."""
        return self._within_floor(m, self.options.baseline_noise_multiple)

    def beyond_tolerance(self, m: _Model) -> list[str]:
        """The declared values ``m`` holds beyond their datasheet tolerance (factor ``f``
        with ``|f − 1| >`` tolerance)."""
        return [d.name for d, f in zip(self.declared, m.x)
                if d.tolerance > 0.0 and abs(float(f) - 1.0) > d.tolerance]

    def described_point(self, m: _Model) -> _Model:
        """``m``'s structure with every fitted declared value back at the description's value
        (factor 1) and its effects at ``m``'s values (not fitted: no residuals kept)."""
        kd = len(self.declared)
        return _Model(list(m.effects), np.concatenate([np.ones(kd), m.x[kd:]]))

    def described_ranking(self, m: _Model, pool: Sequence[Effect], rnd: str
                          ) -> list[dict] | None:
        """The ranking from the described values (:meth:`described_point`), or ``None``.

        A fit of the declared values can absorb much of a missing effect's signature: a
        common-mode pressure bled to the drain is mimicked, badly, by a lower charge pressure,
        a softer oil and more air, each driven beyond its tolerance. Ranked at that fit, the
        effect's linearised change explains little more than the moved values already do (on
        rig 2's charge-loss record of 20 s: 0.0056, every pressure 20× its floor), although the
        effect with the values back where described explains the record. A declared value
        beyond its tolerance is the sign of this, and only then (a described rig, whose
        identifiability screen gave the declared values' sensitivities at the described
        values) the candidates are ranked again from the described values: the residual of
        the description with the effects found so far, projected with the screen's columns
        (at the described values, without the effects: a linearisation, not a replay per
        value). The values the fit drove beyond their tolerance are left out of that
        projection (their columns zero, their start the described value): they are what the
        effect may have been absorbed into, and kept in they absorb it again (with them, the
        charge loss above scored 0.016 from the described values). One replay per probe, as
        the first ranking."""
        beyond = set(self.beyond_tolerance(m))
        if not (self.described and self.screen_columns) or not beyond:
            return None
        J0 = np.column_stack([np.zeros_like(self.screen_columns[d.name]) if d.name in beyond
                              else self.screen_columns[d.name] for d in self.declared])
        return self.rank(self.described_point(m), pool, f"{rnd} (from the described values)",
                         J=J0)

    def refit_candidate(self, s: _Search, e: Effect, score: float, scs: Sequence[dict],
                        rnd_no: int, info_cur: dict, plausibility: bool = False
                        ) -> tuple | None:
        """Refit ``s.model`` plus candidate ``e``. Its starts are those of the rankings
        ``scs`` where it scored above ``min_refit_score`` (:meth:`refit_start`: at the
        current fit, at the described values); the start of lowest training cost is fitted
        first; when that refit does not pay, the next start is fitted and the lower-cost fit
        judged (the fit's cost decides). Returns ``(model, effect, record, ident)``, or
        ``None`` when every refit failed."""
        rep = progress.reporter()
        starts = []
        for q in scs:
            if q["probe"] is None or q["score"] <= self.min_refit_score:
                continue
            x0, cost = self.refit_start(q["base"], e, q)
            where = ("declared fit" if q["base"] is s.model else "described values")
            starts.append((cost, where, x0))
        starts.sort(key=lambda t: t[0])
        best = None
        for cost, where, x0 in starts:
            try:
                m = self.fit(s.model.effects + [e], x0, within_tolerance=plausibility)
            except (CalibrationError, ReplayError) as exc:
                s.candidates[e.name]["refit_error"] = str(exc)
                rep.stage(f"calibration round {rnd_no}: {e.name}: refit from the {where} "
                          f"failed ({exc})")
                continue
            if best is not None and m.cost >= best[0].cost:
                continue
            rec, ident = self.judge_refit(s.model, m, e, score, rnd_no, info_cur,
                                          plausibility)
            rec["start"] = where
            best = (m, e, rec, ident)
            if rec["pays"]:
                break
        if best is not None:
            s.candidates[e.name].setdefault("refits", []).append(best[2])
        return best

    def judge_refit(self, current: _Model, m: _Model, e: Effect, score: float,
                    round_no: int, info_cur: dict, plausibility: bool = False
                    ) -> tuple[dict, dict]:
        """Whether ``m`` (``current`` plus candidate ``e``, refitted) pays (step 5): the BIC
        falls by more than ``bic_margin``, the held-out overall NRMSE by ``min_error_drop``,
        the new parameters are identifiable; on a described rig also none is pinned at a
        library bound and it beats a generic per-channel correction with as many parameters.
        Returns the candidate's report record and ``m``'s identifiability."""
        opts = self.options
        info = self.information(m)
        # a plausibility refit bounds the declared values to their tolerance: one pinned at
        # that bound is held, not free, in the covariance (a leakage beside a pump slip held
        # at +100 %: the remainder is the leakage's, however alike the two act)
        held = [k for k, d in enumerate(self.declared)
                if plausibility and d.tolerance > 0.0
                and abs(float(m.x[k]) - 1.0) >= d.tolerance * (1.0 - 1e-3)]
        ident = self.identifiability(m, held)
        k0 = len(current.x)
        rel = ident["relative_se"][k0:]
        corr = ident["correlation"]
        # in a plausibility refit the trade between the effect and a declared value is bounded
        # by that value's tolerance (the datasheet decides it, not the record): only the
        # correlations with the other effects' parameters count; the marginal standard error
        # (relative_se), which carries the declared values' correlation, still must be small
        kd = len(self.declared)
        others = range(kd if plausibility else 0, len(m.x))
        max_corr = float(max((abs(corr[i, j]) for i in range(k0, len(m.x))
                              for j in others if j != i), default=0.0))
        max_corr_declared = float(max((abs(corr[i, j]) for i in range(k0, len(m.x))
                                       for j in range(kd)), default=0.0))
        drop = 1.0 - m.held_out["overall"] / current.held_out["overall"]
        identifiable = bool(np.all(rel < opts.max_relative_se)
                            and max_corr < opts.max_correlation
                            and not ident["rank_deficient"])
        d_bic = info["bic"] - info_cur["bic"]
        pays = bool(d_bic < -opts.bic_margin and drop >= opts.min_error_drop and identifiable)
        earned = {}
        if self.described:
            # a described rig: the effect must also be physically plausible (no parameter
            # pinned at a library bound) and beat a generic per-channel correction with as
            # many parameters. Its held-out drop counts in either of two units: the overall
            # NRMSE (each channel weighed by its signal's spread) or the error in noise units
            # (each by its noise: :meth:`error_in_noise_units`), each against the generic
            # correction's drop in the same units. In NRMSE units an effect that shows only
            # on a channel far more precise than the others cannot reach min_error_drop
            # however well it explains it (rig 2's viscosity drift: the angle from 4.1× its
            # floor to 1.0× and every other channel at its floor is a 5.6 % NRMSE drop); in
            # noise units a model at the noise floor is ~1, so a record whose channels are
            # all within ~1.1× their floor (a clean one) leaves no 10 % to gain
            drop_noise = 1.0 - (self.error_in_noise_units(m.held_out)
                                / self.error_in_noise_units(current.held_out))
            generic = self.generic_correction(current, len(e.parameters))
            units = {"nrmse": drop >= opts.min_error_drop
                     and drop > generic["held_out_drop"],
                     "noise_units": drop_noise >= opts.min_error_drop
                     and drop_noise > generic["held_out_drop_noise_units"]}
            earned = {"at_bound": self.at_bound(e, m.x[k0:]), "generic": generic,
                      "held_out_drop_noise_units": drop_noise,
                      "beats_generic": bool(drop > generic["held_out_drop"] or units[
                          "noise_units"]),
                      "pays_in": [u for u, ok in units.items() if ok]}
            # a refit that pays in one unit by trading the channels against each other
            # (the fit weighs them by their spread, not their noise) and so worsens the
            # other unit beyond min_error_drop does not: rig 1's leakage + delay record
            # took a 1.9 ms lag on the motor current (NRMSE −15.6 %) that left the error in
            # noise units 24.8 % worse, before the delay that explains both
            earned["worsened_in"] = [u for u, d in (("nrmse", drop),
                                                    ("noise_units", drop_noise))
                                     if d <= -opts.min_error_drop]
            pays = bool(d_bic < -opts.bic_margin and identifiable and any(units.values())
                        and not earned["at_bound"] and not earned["worsened_in"])
        if plausibility:
            # after the search stopped on a model with a declared value beyond its tolerance
            # (:meth:`plausibility_round`): taken when it explains the record as well (at the
            # noise floor, or a held-out error within PLAUSIBILITY_SLACK of the model it
            # replaces) with every declared value within its tolerance, identifiable (the
            # declared values pinned at their tolerance held) and at no library bound
            beyond = self.beyond_tolerance(m)
            as_good = bool(self.at_noise(m) or m.held_out["overall"]
                           <= (1.0 + PLAUSIBILITY_SLACK) * current.held_out["overall"])
            earned.update({"plausibility": True, "at_noise": self.at_noise(m),
                           "as_good": as_good, "beyond_tolerance": beyond,
                           "held_at_tolerance": [self.declared[k].name for k in held],
                           "replaced_beyond_tolerance": self.beyond_tolerance(current)})
            pays = bool(identifiable and not earned.get("at_bound") and as_good
                        and not beyond)
        rec = {"round": round_no, "score": score, **earned,
               "delta_bic": d_bic, "delta_aic": info["aic"] - info_cur["aic"],
               "held_out_overall": m.held_out["overall"], "held_out_drop": drop,
               "relative_se": [float(v) for v in rel], "max_correlation": max_corr,
               "max_correlation_with_declared": max_corr_declared,
               "identifiable": identifiable, "pays": pays,
               "parameters": {k: v for k, v in self.physical(m.effects, m.x).items()
                              if k.startswith(e.name + ".")}}
        return rec, ident

    def selected_step(self, current: _Model, m: _Model, e: Effect, rec: dict,
                      ident: dict) -> dict:
        """The report's entry (``effects_selected``) of effect ``e`` added to ``current``,
        giving ``m``."""
        k0 = len(current.x)
        return {"effect": e.name, "component": e.component,
                "equation": e.equation, "reference": e.reference,
                "parameters": rec["parameters"],
                "uncertainties": {f"{e.name}.{p.name}": float(ident["sd"][k0 + j] * p.scale)
                                  for j, p in enumerate(e.parameters)},
                "held_out_before": current.held_out["overall"],
                "held_out_after": m.held_out["overall"],
                "held_out_drop": rec["held_out_drop"],
                **({"held_out_drop_noise_units": rec["held_out_drop_noise_units"],
                    "pays_in": rec["pays_in"]} if "pays_in" in rec else {}),
                "delta_bic": rec["delta_bic"], "delta_aic": rec["delta_aic"]}

    def analyse_residuals(self, before: _Residual, m: _Model) -> _Residual:
        """Step 3 on the final model ``m``: its held-out errors and residual whiteness; then
        each channel's held-out residual analysed (:func:`afo_mj.calibration.residual_analysis.
        analyse_channel`) for the declared fit (``before``) and for ``m``."""
        after = _Residual(*self.held_out_errors(m.effects, m.x))
        after.whiteness = self._whiteness(after.out)
        before.channels = self._channel_summaries(before.out)
        after.channels = self._channel_summaries(after.out)
        return after

    def verdict(self, before: _Residual, after: _Residual, found: bool,
                numerical: Mapping | None = None) -> _Verdict:
        """Step 6: ``effect_found`` when an effect was added (``found``); on a described rig
        whose declared fit misses its noise multiple, ``structure_wrong`` (and where, in the
        baseline) unless every channel beyond the multiple is accounted for
        (:meth:`attribution`: the replay's numerical error, a named drift, transient or
        resonance, or the data-driven discrepancy), then ``unexplained_residual``;
        ``unexplained_residual`` when the declared fit's residual is structured (not on a
        described rig that reaches its noise multiple); else ``no_missing_effect``. With
        where the final residual's structure lives (the numerical check's part included)
        and, when no physical effect explains it, the data-driven discrepancy."""
        baseline = before.baseline
        structured_after = [c for c, s in after.channels.items() if s["structured"]]
        structured_before = [c for c, s in before.channels.items() if s["structured"]]
        if found:
            verdict = "effect_found"
        elif self.described and not baseline["reaches_noise"]:
            verdict = "structure_wrong"
        elif structured_before and not (self.described and baseline["reaches_noise"]):
            verdict = "unexplained_residual"
        else:
            verdict = "no_missing_effect"
        if self.described and not baseline["reaches_noise"]:
            where_base = ra.locate_structure(before.channels) if structured_before else None
            baseline["structure_wrong_where"] = where_base
        where = ra.locate_structure(after.channels) if structured_after else None
        discrepancy = None
        if verdict in ("unexplained_residual", "structure_wrong") or (
                self.described and not found and structured_after):
            discrepancy = self.data_driven_discrepancy(after.out)
        attribution = None
        if verdict == "structure_wrong":
            attribution = self.attribution(before, after, numerical, discrepancy)
            if not attribution["unexplained"]:
                verdict = "unexplained_residual"
                where = where or ra.locate_structure(after.channels)
        unexplained = verdict in ("unexplained_residual", "structure_wrong") or (
            verdict == "effect_found" and bool(structured_after))
        from afo_mj.calibration.numerical_check import numerical_where
        num_where = numerical_where(numerical)
        if unexplained and num_where:
            where = f"{where}; {num_where}" if where else num_where
        return _Verdict(verdict, where if unexplained else None, discrepancy, attribution)

    def attribution(self, before: _Residual, after: _Residual, numerical: Mapping | None,
                    discrepancy: Mapping | None) -> dict:
        """What accounts for each channel a described rig's declared fit leaves beyond its
        noise multiple (no effect was named): ``numerical_error`` (the replay's residual
        misses the multiple on the check's window and Radau's reaches it), the "where"
        findings on that channel (:func:`afo_mj.calibration.residual_analysis.
        where_findings`: a slow drift, a common-mode or differential drift, a transient after
        input steps, a resonance, a broadband excess in the top of the band: a vibration
        faster than the record resolves), ``data_driven_discrepancy`` (found, and its held-out RMS
        within the multiple of the noise). ``unexplained``: the channels nothing accounts
        for; only these make the verdict ``structure_wrong``."""
        base = before.baseline
        mult = float(base["noise_multiple"])
        findings = ra.where_findings(after.channels)
        num = set((numerical or {}).get("explains_excess") or [])
        rows = {}
        for c, r in base["ratio"].items():
            if r <= mult:
                continue
            by = ["numerical_error"] if c in num else []
            by += sorted({f["kind"] for f in findings if c in f["channels"]})
            d = (discrepancy or {}).get(c)
            if (isinstance(d, Mapping) and d.get("found")
                    and d["held_out_rms_after"] <= mult * self.noise[c]):
                by.append("data_driven_discrepancy")
            rows[c] = {"baseline_ratio": float(r), "explained_by": by}
        return {"noise_multiple": mult, "channels": rows,
                "unexplained": [c for c, v in rows.items() if not v["explained_by"]]}

    def final_parameters(self, m: _Model) -> tuple[dict, dict, list[dict]]:
        """The final model's parameters in SI, their standard deviations (``None`` where
        inestimable, never inf/NaN) and the declared parameters beyond their tolerance."""
        ident = self.identifiability(m)
        params = self.physical(m.effects, m.x)
        sd_phys = {}
        k = 0
        for d, labels in zip(self.declared, self.declared_labels):
            sd_phys[d.name] = float(ident["sd"][k] * self.declared_value(d, labels))
            k += 1
        for e in m.effects:
            for p in e.parameters:
                sd_phys[f"{e.name}.{p.name}"] = float(ident["sd"][k] * p.scale)
                k += 1
        deviations = self.declared_deviations(m, ident)
        sd_phys = {k: (v if math.isfinite(v) else None) for k, v in sd_phys.items()}
        return params, sd_phys, deviations

    def report(self, t_start: float, lean_err: dict, declared_fit: _Model, before: _Residual,
               search: _Search, after: _Residual, verdict: _Verdict,
               numerical: dict | None = None, replay_step: dict | None = None) -> dict:
        """The report dictionary (:mod:`afo_mj.outputs.calibration_report` writes it)."""
        params, sd_phys, deviations = self.final_parameters(search.model)
        explains_record(deviations, after.err, before.baseline)
        for st in search.steps:
            st["uncertainties"] = {k: (v if math.isfinite(v) else None)
                                   for k, v in st["uncertainties"].items()}
        return {
            "described": self.described, "command_channel": self.command,
            "preset": self.replay.preset,
            "outputs": list(self.outputs), "skipped_outputs": self.skipped_outputs,
            "inputs": list(self.inputs), "split_by": self.split_by,
            "train_window_s": list(self.train_window), "held_out_window_s":
            list(self.test_window), "settle_s": self.options.settle_s,
            "noise_sigma": dict(self.noise),
            "record_flags": list(self.record_flags),
            "input_hold": self.input_hold, "hold_warnings": list(self.hold_warnings),
            "declared_effects": [e.name for e in self.declared_effects],
            "error_preset": lean_err,
            "error_before": before.err, "error_after": after.err,
            "error_drop": 1.0 - after.err["overall"] / before.err["overall"],
            "declared_fit": self.physical(declared_fit.effects, declared_fit.x),
            "declared_held": dict(self.held_declared),
            "declared_deviations": deviations,
            "declared_set": (None if self.described_set is None else {
                "values": self.described_set.table,
                "excluded": dict(self.described_set.excluded)}),
            "identifiability": (None if self.identifiability_table is None
                                else self.identifiability_table.as_dict()),
            "baseline": before.baseline,
            "effects_selected": search.steps,
            "parameters": params, "parameter_sd": sd_phys,
            "candidates": search.candidates,
            "residual_whiteness_before": before.whiteness,
            "residual_whiteness_after": after.whiteness,
            "channels_before": before.channels, "channels_after": after.channels,
            "verdict": verdict.verdict,
            "unexplained_where": verdict.where,
            "replay_step": replay_step,
            "numerical_error": numerical,
            "residual_attribution": verdict.attribution,
            "data_driven_discrepancy": verdict.discrepancy,
            "evaluations": self.evaluations,
            "evaluations_at_sensitivity_step": self.coarse_evaluations,
            "wall_time_s": time.perf_counter() - t_start,
            "_series": {"time_s": self.t, "measured": self.meas, "before": before.out,
                        "after": after.out, "i_cut": self.i_cut},
        }

    # ---------------------------------------------------------------- residual analysis
    def data_driven_discrepancy(self, out: Mapping[str, np.ndarray]) -> dict:
        """When no physical effect explains the residual: per channel, a sparse regression
        of the final model's residual on terms of the model's outputs and the inputs
        (:func:`afo_mj.calibration.discrepancy.discrepancy_report`), fitted on the training
        part and chosen on the held-out part; labelled a data-driven discrepancy, never a
        physical effect. Only channels whose held-out residual exceeds their noise get
        terms."""
        from afo_mj.calibration.discrepancy import discrepancy_report
        settled = np.arange(len(self.t))[self.t >= self.t[0] + self.options.settle_s]
        idx = settled
        pos = {k: i for i, k in enumerate(idx)}
        train = np.array([pos[k] for k in self.train_idx if k in pos])
        test = np.array([pos[k] for k in self.test_idx if k in pos])
        signals = {c: v[idx] for c, v in self.inputs.items()}
        for c in self.outputs:
            if c not in signals:
                signals[c] = np.asarray(out[c])[idx]
        angle = signals.get("ankle_angle_rad")
        if angle is not None:
            signals["ankle_velocity_rad_s"] = np.gradient(angle, self.t[idx])
        residuals = {c: (self.meas[c] - out[c])[idx] for c in self.outputs}
        try:
            rep = discrepancy_report(residuals, signals, self.t[idx], train, test,
                                     {c: self.noise[c] for c in self.outputs})
        except ValueError as exc:
            return {"error": str(exc)}
        for r in rep.values():
            r["terms"] = [dataclasses.asdict(t) for t in r.get("terms", [])]
        return rep

    def _whiteness(self, out: Mapping[str, np.ndarray]) -> dict:
        idx = self.test_idx
        return {c: ra.whiteness(self.meas[c][idx] - out[c][idx], self.noise[c], self.fs_hz)
                for c in self.outputs}

    def _channel_summaries(self, out: Mapping[str, np.ndarray]) -> dict:
        idx = self.test_idx
        t = self.t[idx]
        ins = {c: v[idx] for c, v in self.inputs.items()}
        angle = self.inputs.get("ankle_angle_rad", self.meas.get("ankle_angle_rad"))
        if angle is None:
            angle = out.get("ankle_angle_rad", np.zeros_like(self.t))
        ins["ankle_velocity_rad_s"] = np.gradient(angle, self.t)[idx]
        states = {c: out[c][idx] for c in self.outputs}
        cycles = []
        try:
            cycles = [(a, b) for a, b in self.data.cycles_s() if a >= t[0] - 1e-9
                      and b <= t[-1] + 2 * self.data.sample_period_s]
        except MeasuredDataError:
            cycles = []
        sig = _signatures(t, ins, states)
        summaries = {c: ra.analyse_channel(c, t, self.meas[c][idx], out[c][idx], ins, states,
                                           sig, self.noise[c], cycles or None)
                     for c in self.outputs}
        for a, b in ra.line_pairs(self.outputs):
            summaries[a]["line_pair_high_band"] = ra.line_pair_high_band(
                self.meas[a][idx] - out[a][idx], self.meas[b][idx] - out[b][idx], self.fs_hz,
                self.noise[a], self.noise[b], sig["velocity"])
        return summaries


#: a described rig's model whose held-out NRMSE is within this multiple of every channel's
#: noise floor leaves only noise (the threshold of the verdict's "within 1.2× its noise"):
#: the round's remaining refits and later rounds are skipped
AT_NOISE_MULTIPLE = 1.2
#: a plausibility refit (every declared value within its tolerance) explains the record "as
#: well" as the model it replaces when its held-out overall NRMSE is at most this much larger
#: (or every channel is within AT_NOISE_MULTIPLE of its floor)
PLAUSIBILITY_SLACK = 0.02


#: a declared value's deviation and another change of the outputs are indistinguishable when
#: the cosine of their noise-whitened columns is at least this: the other explains at least
#: 90 % (0.95²) of the deviation's signature, and the rest is what separates them
EQUIVALENT_SIMILARITY = 0.95


def explains_record(deviations: list[dict], error_after: Mapping[str, float],
                    baseline: Mapping) -> list[dict]:
    """Mark each declared value beyond its tolerance (``deviations``, the report's
    ``declared_deviations``) with whether the model holding it explains the record:
    ``explains_record`` is True when every channel's final held-out NRMSE
    (``error_after``) is within the noise multiple of its noise floor (``baseline``'s
    ``noise_multiple`` and ``noise_floor``), with ``final_worst_ratio`` the worst channel's
    NRMSE over its floor.

    A deviation of a model that explains the record is a finding: a wrong datasheet value,
    or an effect that acts exactly like it. A deviation of a model that still misses the
    record (on rig 2's brushes dropping 0.3 V, the bulk modulus at 2.7× and the winding
    resistance at +24 % with the residual 66× the angle's floor) is the fit bending a value
    toward something the model lacks, and names nothing. Returns ``deviations``, changed in
    place."""
    floor = baseline.get("noise_floor") or {}
    mult = float(baseline.get("noise_multiple", 2.0))
    ratios = [float(error_after[c]) / max(float(f), 1e-12) for c, f in floor.items()
              if c in error_after]
    worst = max(ratios) if ratios else float("nan")
    for d in deviations:
        d["explains_record"] = bool(ratios) and worst <= mult
        d["final_worst_ratio"] = worst if math.isfinite(worst) else None
    return deviations


def _projected(A: np.ndarray, r: np.ndarray) -> float:
    """``|P_A r|²``: the part of ``|r|²`` the columns of ``A`` explain (least squares)."""
    coef, *_ = np.linalg.lstsq(A, r, rcond=None)
    fit = A @ coef
    return float(fit @ fit)


@dataclasses.dataclass
class _ScoreBase:
    """What a ranking scores every probe against: the declared parameters' sensitivities
    ``J``, the training residual ``r`` to explain (NRMSE units, channel by channel) and,
    on a described rig, the row weights ``w`` that put each channel in units of its noise
    σ (:meth:`CalibrationModel.noise_weights`; ``None``: NRMSE units only). What ``J``
    explains, in each unit, is taken once."""

    J: np.ndarray
    r: np.ndarray
    w: np.ndarray | None = None

    def __post_init__(self):
        #: (row weights or None, J, r) in each unit, what J explains there and |r|²
        self.units = [(None, self.J, self.r)]
        if self.w is not None:
            self.units.append((self.w, self.J * self.w[:, None], self.r * self.w))
        self.explained = [_projected(J, r) for _, J, r in self.units]
        self.total = [max(float(r @ r), 1e-300) for _, _, r in self.units]


def _score(base: _ScoreBase, cols: np.ndarray, signed: bool = False
           ) -> tuple[float, np.ndarray]:
    """The linearised score of a candidate whose change of the training residual is
    ``cols`` (one column per direction): the fraction of ``|r|²`` that ``[J, cols]``
    explains beyond ``J`` alone (a Lagrange-multiplier test: Rao 1948; Engle 1984), and the
    least-squares coefficients of ``[J, cols]``. ``signed``: the last column must enter with
    a positive coefficient, else the score is 0 (a leakage cannot be negative).

    In NRMSE units each channel weighs by its signal's spread; with noise weights
    (:class:`_ScoreBase`) the fraction is also taken in units of each channel's noise σ,
    and the larger of the two is the score, with its coefficients. An effect that shows only
    on a precise channel (rig 2's 14-bit encoder, its floor a tenth of the others': a slow
    viscosity drift moves only the angle, through the pump's slip) explains a large part of
    the residual beyond the noise but at most that channel's small share of it in NRMSE units
    (0.041 against the refit gate of 0.05 there; in noise units its share is the angle's
    excess over its noise, most of the residual)."""
    best, best_coef = 0.0, None
    for (w, J, r), done, total in zip(base.units, base.explained, base.total):
        A = np.column_stack([J, cols if w is None else cols * w[:, None]])
        coef, *_ = np.linalg.lstsq(A, r, rcond=None)
        if best_coef is None:
            best_coef = coef
        if signed and not coef[-1] > 0.0:
            continue
        sc = max(_projected(A, r) - done, 0.0) / total
        if sc > best:
            best, best_coef = sc, coef
    return best, best_coef


def _signatures(t, inputs, states) -> dict[str, np.ndarray]:
    """Candidate signatures of the issue: sign of velocity, velocity, low pressure, Δp across
    the piston, time (drift) and the time derivative of each output (a time shift)."""
    v = inputs["ankle_velocity_rad_s"]
    sig = {"sign_velocity": np.tanh(v / (0.05 * (np.std(v) + 1e-12))), "velocity": v,
           "time": t - t[0]}
    if "chamber_a_pa" in states and "chamber_b_pa" in states:
        dp = states["chamber_a_pa"] - states["chamber_b_pa"]
    elif "pressure_a_pa" in states and "pressure_b_pa" in states:
        dp = states["pressure_a_pa"] - states["pressure_b_pa"]
    else:
        dp = None
    if dp is not None:
        sig["delta_p"] = dp
        sig["abs_delta_p_sign_velocity"] = np.abs(dp) * sig["sign_velocity"]
    press = [states[c] for c in states if c.endswith("_pa")]
    if press:
        p_min = np.min(np.vstack(press), axis=0)
        sig["low_pressure"] = 1.0 / (1.0 + np.maximum(p_min, 0.0) / 1e6)
    for c, y in states.items():
        sig[f"d_{c}_dt"] = np.gradient(y, t)
    return sig


def calibrate(data: MeasuredData, preset: str | None = None,
              options: CalibrationOptions = CalibrationOptions(),
              overrides: Mapping[str, object] | None = None) -> dict:
    """Run the whole method on a record; returns the report dictionary (see
    :mod:`afo_mj.outputs.calibration_report` for what is written from it). ``preset``
    defaults to the record's ``source.preset``; ``overrides`` are dotted device parameters."""
    preset = preset or data.source.get("preset")
    replay = BenchReplay(preset, overrides) if preset else None
    return Calibration(data, preset, options, replay=replay).run()


def calibrate_setup(data: MeasuredData, setup: CalibrationSetup) -> dict:
    """Run the whole method on a record with what a scenario declares
    (:func:`load_calibration_scenario`); returns the report dictionary."""
    preset = setup.preset or data.source.get("preset") if setup.circuit is None else None
    if setup.circuit is None and not preset:
        raise CalibrationError("the record's sidecar names no source.preset and none was "
                               "given (--preset)")
    replay = (setup.replay() if setup.circuit is not None
              else BenchReplay(preset, setup.overrides))
    return Calibration(data, preset or setup.circuit.name, setup.options, replay=replay).run()
