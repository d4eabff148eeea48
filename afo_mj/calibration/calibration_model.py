"""One record replayed through one model: the parameterisation, the replays, the fits.

:class:`CalibrationModel` holds what the calibration method (:mod:`afo_mj.calibration.calibrate`)
evaluates its models on: the record checked against the declared rig, split into a training
and a held-out part, each output channel's scale and noise; the declared parameters (as
factors of the declared values) and the candidate effects' parameters, normalised; the replays
of a structure at such parameters (kept, so that a change of the sensor transforms alone
replays nothing), its training residuals and held-out errors, the bounded robust fit, its
forward-difference Jacobian, the information criteria and the Gauss–Newton identifiability.
"""

from __future__ import annotations

import collections
import contextlib
import dataclasses
import math
from typing import Mapping, Sequence

import numpy as np
from scipy.optimize import least_squares

from afo_mj.calibration import residual_analysis as ra
from afo_mj.calibration.calibration_setup import CalibrationError, CalibrationOptions
from afo_mj.calibration.effect_library import (
    DeclaredParameter, Effect, EffectParameter, ModelSetting, declared_parameters,
    lean_setting)
from afo_mj.calibration.measured_data import MeasuredData
from afo_mj.calibration.record_checks import check_record, declared_charge_pa
from afo_mj.calibration.sampling import check_holds
from afo_mj.calibration.secant_jacobian import SecantJacobian, soft_l1_jacobian_weights
from afo_mj.experiments.bench_replay import HELD_CHANNELS, BenchReplay, ReplayError
from afo_mj.hydraulics.params import ParameterError
from afo_mj.hydraulics.sensor import first_order_lag, sensor_reading

__all__ = ["CalibrationModel", "declared_labels", "model_outputs", "sensor_outputs",
           "DIFF_STEP", "REPLAY_CACHE_SIZE", "FIT_FTOL", "SENSITIVITY_STEP_S",
           "SECANT_REFRESH"]


def declared_labels(replay: BenchReplay, d: DeclaredParameter) -> tuple[str, ...]:
    """The packed labels of declared parameter ``d`` that the replay's circuit has."""
    labels = tuple(lab for lab in d.labels if replay.has(lab))
    if not labels:
        raise CalibrationError(f"declared parameter {d.name}: the circuit "
                               f"{replay.cc.circuit.name!r} packs none of {list(d.labels)}")
    return labels


def model_outputs(replay: BenchReplay, time_s: np.ndarray, inputs: Mapping[str, np.ndarray],
                  setting: ModelSetting, channels: Sequence[str]) -> dict[str, np.ndarray]:
    """Replay with ``setting`` (packed parameters, backlash, temperature drift) and read the
    outputs ``channels`` through its sensor transforms."""
    sim = replay.simulate(time_s, inputs, setting.row, setting.backlash_rad,
                          setting.temperature_rate_k_s)
    return sensor_outputs(time_s, {c: sim[c] for c in channels}, setting.sensors)


def sensor_outputs(time_s: np.ndarray, out: Mapping[str, np.ndarray],
                   sensors: Sequence[tuple]
                   ) -> dict[str, np.ndarray]:
    """The replayed channels ``out`` read through the sensor transforms ``sensors``
    (:attr:`ModelSetting.sensors`, applied in order); ``out`` itself is left as it was."""
    out = dict(out)
    for entry in sensors:
        ch, gain, offset, delay = entry[:4]
        lag = entry[4] if len(entry) > 4 else 0.0
        for c in (list(out) if ch == "*" else [ch]):
            if c in out:
                y = first_order_lag(time_s, out[c], lag) if lag > 0.0 else out[c]
                out[c] = sensor_reading(time_s, y, gain, offset, delay)
    return out


#: relative forward-difference step of the fits' Jacobians (on the normalised parameters)
DIFF_STEP = 1e-2
#: replays kept by :meth:`CalibrationModel.simulate` (the least recently used is dropped): enough
#: for a Jacobian's columns and the point they start from
REPLAY_CACHE_SIZE = 16
#: the fits stop when a step lowers the cost by less than this fraction of it: with the
#: ~2·10⁴ training residuals of a 6 s record that is < 0.02 in the BIC (bic_margin 10) and
#: < 0.1 noise χ² units; scipy's default 1e-8 spent about a fifth of the replays on such steps
FIT_FTOL = 1e-6
#: the replay step of the sensitivities (the identifiability screen, the candidate rankings'
#: probes) and of each fit's first stage when the replay's own step is finer, s: the presets'
#: 0.5 ms. A sensitivity is a difference of two replays at one step, so the stepper's own error,
#: nearly the same in both, largely cancels; a fit started there is finished at the replay's step
#: (:meth:`CalibrationModel.fit`), so no fitted value keeps the coarse step's bias
SENSITIVITY_STEP_S = 5e-4
#: finite-difference columns retaken per iteration of a fit between secant (Broyden) updates
#: of its Jacobian (:class:`afo_mj.calibration.secant_jacobian.SecantJacobian`); a full
#: Jacobian is taken at the start, after a rejected step and at the end
SECANT_REFRESH = 2


@dataclasses.dataclass
class _Model:
    """A model structure (declared parameters + effects, in order) and its fitted values."""

    effects: list[Effect]
    x: np.ndarray                       # normalised: declared factors, then effect values/scale
    cost: float = math.inf             # ½ Σ ρ(r²) on the training part
    sse: float = math.inf               # Σ r² on the training part
    held_out: dict | None = None        # channel → NRMSE, "overall"
    jac: np.ndarray | None = None
    nfev: int = 0
    fun: np.ndarray | None = None       # training residuals at x
    raw_jac: np.ndarray | None = None   # their forward-difference Jacobian at x (no loss)
    jac_steps: np.ndarray | None = None  # ... and its steps
    cov: np.ndarray | None = None

    def n_params(self) -> int:
        return len(self.x)


class _Resolving:
    """The labels a described circuit's replay answers to (by role, :meth:`BenchReplay.has`)."""

    def __init__(self, replay: BenchReplay):
        self.replay = replay

    def __contains__(self, label) -> bool:
        return self.replay.has(label)



class CalibrationModel:
    """One record, one model: the record's split, scales and noise, the declared parameters,
    and the replays, residuals and fits of a structure (declared parameters + effects) at
    normalised parameters. :class:`afo_mj.calibration.calibrate.Calibration` searches with it."""

    def __init__(self, data: MeasuredData, preset: str | None = None,
                 options: CalibrationOptions = CalibrationOptions(),
                 replay: BenchReplay | None = None):
        self.data = data
        self.options = options
        preset = preset or data.source.get("preset")
        if not preset:
            raise CalibrationError("the record's sidecar names no source.preset and none was "
                                   "given (--preset)")
        self.replay = replay or BenchReplay(preset)
        #: the model is the user's own description (its declared model is as described, its
        #: switched-off effects the candidates), not a preset's lean model
        self.described = self.replay.described
        #: the device's preferred command channel (a preset's open-loop command)
        self.command = self.replay.commands[0]
        try:
            input_names = self.replay.check_inputs(data.channels)
        except ReplayError as exc:
            raise CalibrationError(str(exc)) from None
        self.outputs = [c for c in data.outputs if c in self.replay.outputs]
        skipped = [c for c in data.outputs if c not in self.replay.outputs]
        if not self.outputs:
            raise CalibrationError(f"none of the record's outputs {list(data.outputs)} is "
                                   f"produced by the {self.replay.preset!r} bench replay "
                                   f"(allowed: "
                                   f"{', '.join(self.replay.outputs)})")
        self.skipped_outputs = skipped
        findings = check_record(data.channels, self.replay.params, data.noise,
                                tuple(data.inputs),
                                charge_pa=declared_charge_pa(getattr(self.replay.cc,
                                                                     "circuit", None)),
                                sample_period_s=data.sample_period_s)
        refused = [f.message for f in findings if f.severity == "refuse"]
        if refused:
            raise CalibrationError("; ".join(refused))
        #: what the record checks flagged (the report's ``record_flags``)
        self.record_flags = [f.message for f in findings if f.severity == "flag"]
        self.t = np.asarray(data.time_s, dtype=float)
        self.inputs = {c: np.asarray(data.channels[c], dtype=float) for c in input_names}
        self._declare_holds(data, options)
        if "fluid_temperature_k" in data.inputs:
            self.inputs["fluid_temperature_k"] = np.asarray(
                data.channels["fluid_temperature_k"], dtype=float)
        self.meas = {c: np.asarray(data.channels[c], dtype=float) for c in self.outputs}
        self.fs_hz = 1.0 / data.sample_period_s
        # split: train before test, whole cycles/segments
        by = options.split_by
        if by == "auto":
            by = ("cycles" if ("cycle_starts_s" in data.segments or "period_s" in data.segments)
                  else "segments" if "boundaries_s" in data.segments else "tail")
        self.split_by = by
        train, test = data.split(options.held_out_fraction, by=by)
        self.i_cut = int(np.searchsorted(self.t, test.time_s[0] - 1e-9))
        self.i_end = len(self.t)
        t_settle = self.t[0] + options.settle_s
        self.train_idx = np.nonzero((self.t >= t_settle) & (np.arange(len(self.t))
                                                            < self.i_cut))[0]
        self.test_idx = np.arange(self.i_cut, self.i_end)
        if len(self.train_idx) < 50 or len(self.test_idx) < 50:
            raise CalibrationError(f"train {len(self.train_idx)} / held-out "
                                   f"{len(self.test_idx)} samples; at least 50 each needed "
                                   "(a longer record or another held_out_fraction)")
        self.train_window = (float(self.t[self.train_idx[0]]), float(self.t[self.i_cut]))
        self.test_window = (float(self.t[self.i_cut]), float(self.t[-1]))
        self.scale = {}
        for c in self.outputs:
            s = float(np.std(self.meas[c]))
            if not s > 1e-12 * max(1.0, abs(float(np.mean(self.meas[c])))):
                raise CalibrationError(f"output channel {c} is constant in the record; it "
                                       "cannot be fitted (drop it from outputs)")
            self.scale[c] = s
        self.noise = {}
        for c in self.outputs:
            sig = data.noise.get(c)
            self.noise[c] = float(sig) if sig else ra.noise_sigma_estimate(self.meas[c])
        self.context = {}
        self.available = (set(self.replay.param_labels) if not self.described
                          else _Resolving(self.replay))
        #: a described rig's declared set: every numeric value of its description
        #: (:mod:`afo_mj.calibration.declared_set`); None for a preset
        self.described_set = None
        if self.described:
            from afo_mj.calibration.declared_set import described_parameters
            self.described_set = described_parameters(
                self.replay, dict(options.tolerances), options.fixed)
            self.declared = self.described_set.parameters
            self.declared_labels = [d.labels for d in self.declared]
        else:
            if options.tolerances or options.fixed:
                key = "tolerances" if options.tolerances else "fixed"
                raise CalibrationError(
                    f"calibration.{key}: per-value tolerances and fixed values apply to a rig "
                    "described as a circuit ([circuit]); a preset's declared set is fixed "
                    f"(allowed: no calibration.{key} with a preset)")
            self.declared = declared_parameters(self.command)
            #: per declared parameter, the packed labels this circuit has (scaled together)
            self.declared_labels = [declared_labels(self.replay, d) for d in self.declared]
        #: the identifiability analysis of a described rig (None for the presets)
        self.identifiability_table = None
        noise_norm = [self.noise[c] / self.scale[c] for c in self.outputs]
        self.f_scale = 3.0 * float(np.median(noise_norm))
        self.evaluations = 0
        #: replays run at :attr:`sensitivity_step_s` (counted in :attr:`evaluations` too)
        self.coarse_evaluations = 0
        #: the step of the sensitivities and of the fits' first stage (None: the replay's own
        #: step throughout; set by the choice of the replay's step when it is finer)
        self.sensitivity_step_s: float | None = None
        self._replays: collections.OrderedDict = collections.OrderedDict()
        #: the fits' step corrections ``J_f − J_c`` by column (:meth:`fit`): (declared name
        #: or effect.parameter, fine step, coarse step) → column, taken once per calibration
        self._step_corrections: dict[tuple, np.ndarray] = {}
        self.log: list[str] = []

    # ---------------------------------------------------------------- model evaluation
    def _typical(self, e: Effect, p: EffectParameter) -> float:
        if p.name == "current_limit_a" and "motor_current_a" in self.meas:
            i_max = float(np.max(np.abs(self.meas["motor_current_a"])))
            return float(np.clip(0.8 * i_max, p.lo, p.hi))
        return p.typical

    def _bounds(self, effects: Sequence[Effect], within_tolerance: bool = False
                ) -> tuple[np.ndarray, np.ndarray]:
        lo = [d.lo_factor for d in self.declared]
        hi = [d.hi_factor for d in self.declared]
        if within_tolerance:
            lo = [max(v, 1.0 - d.tolerance) if d.tolerance > 0.0 else v
                  for v, d in zip(lo, self.declared)]
            hi = [min(v, 1.0 + d.tolerance) if d.tolerance > 0.0 else v
                  for v, d in zip(hi, self.declared)]
        for e in effects:
            for p in e.parameters:
                lo.append(p.lo / p.scale)
                hi.append(p.hi / p.scale)
        return np.array(lo), np.array(hi)

    def setting(self, effects: Sequence[Effect], x: np.ndarray) -> ModelSetting:
        """The :class:`ModelSetting` of a structure at normalised parameters ``x``."""
        s = lean_setting(self.available, self.described)
        if self.described_set is not None:
            # the description's values moved by their factors, the row as building the
            # circuit would pack it (a bore moves the area, seal friction and drag-out)
            try:
                s.row.update(self.described_set.row(
                    {d.path: d.value * float(f) for d, f in zip(self.declared, x)}))
            except ParameterError as exc:
                # a value outside its field's range (a fit's step): no replay of it
                raise ReplayError(str(exc)) from None
        else:
            for labels, f in zip(self.declared_labels, x):
                for lab in labels:
                    s.row[lab] = self.replay.value(lab) * float(f)
        k = len(self.declared)
        for e in effects:
            vals = [float(x[k + j] * p.scale) for j, p in enumerate(e.parameters)]
            e.apply(s, vals, self.context)
            k += len(e.parameters)
        return s

    def physical(self, effects: Sequence[Effect], x: np.ndarray) -> dict[str, float]:
        """Parameter name → value in SI of a structure at ``x``."""
        out = {}
        for d, labels, f in zip(self.declared, self.declared_labels, x):
            out[d.name] = self.declared_value(d, labels) * float(f)
        k = len(self.declared)
        for e in effects:
            for p in e.parameters:
                out[f"{e.name}.{p.name}"] = float(x[k] * p.scale)
                k += 1
        return out

    def declared_value(self, d: DeclaredParameter, labels: Sequence[str]) -> float:
        """The described (datasheet) value of declared parameter ``d``: a described rig's
        field value, else the preset's packed value of its first label."""
        return float(d.value) if d.path else self.replay.value(labels[0])

    def simulate(self, effects: Sequence[Effect], x: np.ndarray, n: int | None = None
                 ) -> dict[str, np.ndarray]:
        """The model's outputs over the first ``n`` samples (all by default).

        The circuit is replayed only when its packed parameters, backlash or temperature
        drift differ from those of the last :data:`REPLAY_CACHE_SIZE` replays: a change of
        the sensor effects alone (delay, gain, offset: a Jacobian column, a ranking probe)
        re-reads a kept replay through the new sensor transforms. :attr:`evaluations`
        counts the replays run."""
        n = self.i_end if n is None else n
        setting = self.setting(effects, x)
        key = (n, float(self.replay.max_step_s), tuple(sorted(setting.row.items())),
               setting.backlash_rad, setting.temperature_rate_k_s)
        raw = self._replays.get(key)
        if raw is None:
            self.evaluations += 1
            if self.sensitivity_step_s is not None and self.replay.max_step_s == \
                    self.sensitivity_step_s:
                self.coarse_evaluations += 1
            inputs = {c: v[:n] for c, v in self.inputs.items()}
            sim = self.replay.simulate(self.t[:n], inputs, setting.row, setting.backlash_rad,
                                       setting.temperature_rate_k_s)
            raw = {c: sim[c] for c in self.outputs}
            self._replays[key] = raw
            while len(self._replays) > REPLAY_CACHE_SIZE:
                self._replays.popitem(last=False)
        else:
            self._replays.move_to_end(key)
        # copies: what the caller does with its outputs never reaches the kept replay
        return {c: np.array(v) for c, v in sensor_outputs(self.t[:n], raw,
                                                           setting.sensors).items()}

    @contextlib.contextmanager
    def at_sensitivity_step(self):
        """Replays inside run at :attr:`sensitivity_step_s` (when one is set; else at the
        replay's own step)."""
        step = self.sensitivity_step_s
        if step is None:
            yield False
            return
        old = self.replay.max_step_s
        self.replay.max_step_s = step
        try:
            yield True
        finally:
            self.replay.max_step_s = old

    def _residual_vector(self, out: Mapping[str, np.ndarray], idx: np.ndarray) -> np.ndarray:
        return np.concatenate([(out[c][idx] - self.meas[c][idx]) / self.scale[c]
                               for c in self.outputs])

    def _declare_holds(self, data: MeasuredData, options: CalibrationOptions) -> None:
        """Hold each replayed command as declared (the scenario's ``[calibration.hold]`` over
        the sidecar's ``[hold]``), else as the replay's default; check each against its data
        (:func:`afo_mj.calibration.sampling.check_holds`): a contradiction is a record flag
        (the declaration is kept). Sets :attr:`input_hold` and :attr:`hold_warnings`."""
        sources = {c: "declared in the record's sidecar [hold]" for c in data.hold}
        declared = dict(data.hold)
        for c, h in options.hold:
            declared[c] = h
            sources[c] = "declared in the scenario's [calibration.hold]"
        replayed = {c: h for c, h in declared.items() if c in self.inputs}
        self.replay.set_hold(replayed, key="hold")
        default = ("the replay's default for a described circuit" if self.described
                   else "the replay's default for a preset")
        used = {c: self.replay.hold_of(c) for c in self.inputs if c in HELD_CHANNELS}
        self.input_hold, self.hold_warnings = check_holds(
            self.inputs, used, {c: sources.get(c, default) for c in used})
        self.record_flags.extend(self.hold_warnings)

    def train_residuals(self, effects, x) -> np.ndarray:
        try:
            out = self.simulate(effects, x, self.i_cut)
        except ReplayError:
            # a parameter set the kernel cannot integrate: a large, finite residual steers
            # the trust region away from it (never NaN)
            return np.full(len(self.train_idx) * len(self.outputs), 1e3)
        return self._residual_vector(out, self.train_idx)

    def held_out_errors(self, effects, x) -> tuple[dict, dict[str, np.ndarray]]:
        out = self.simulate(effects, x)
        idx = self.test_idx
        err = {c: float(np.sqrt(np.mean((out[c][idx] - self.meas[c][idx]) ** 2))
                        / self.scale[c]) for c in self.outputs}
        err["overall"] = float(math.sqrt(np.mean([err[c] ** 2 for c in self.outputs])))
        return err, out

    # ---------------------------------------------------------------- fitting
    def fit(self, effects: Sequence[Effect], x0: np.ndarray, max_nfev: int | None = None,
            within_tolerance: bool = False) -> _Model:
        """The bounded robust least-squares fit of ``effects`` (declared factors, then the
        effects' normalised values) on the training part from ``x0``, its residuals at the
        replay's step.

        With a :attr:`sensitivity_step_s` coarser than the replay's step, the fit's
        Jacobians are taken there (each replay ~7× cheaper) and corrected by the difference
        between the two steps' Jacobians taken once, at the start: ``J(x) ≈ J_c(x) + (J_f(x₀)
        − J_c(x₀))``. The stepper's error changes little with the parameters, so what the
        correction leaves is second order in ``x − x₀``; the residuals, the cost and the
        fit's end are the replay's own step's. The correction's columns are kept by
        parameter (:meth:`step_correction`): a parameter's column is replayed at the fine
        step once per calibration, at the first fit that holds it, so a fit costs a replay
        per parameter at the coarse step per full Jacobian and a fine replay per parameter
        new to the calibration.

        Between full Jacobians (the first, one after each rejected step, and one at the
        end, which is what the covariance and the rankings read), the Jacobian is carried
        by secant updates with :data:`SECANT_REFRESH` columns retaken per step
        (:class:`~afo_mj.calibration.secant_jacobian.SecantJacobian`): a step costs about
        three replays, not one per parameter.

        ``within_tolerance``: each declared value with a datasheet tolerance is bounded to
        it (factor ``1 ± tolerance``, inside its fit range): the fit of the record with the
        datasheet held."""
        lo, hi = self._bounds(effects, within_tolerance)
        x0 = np.clip(np.asarray(x0, dtype=float), lo, hi)
        # keep the start strictly inside (trf needs an interior point)
        span = hi - lo
        x0 = np.clip(x0, lo + 1e-9 * span, hi - 1e-9 * span)
        two_steps = (self.sensitivity_step_s is not None
                     and self.sensitivity_step_s > self.replay.max_step_s)
        keys = self.column_keys(effects)
        steps = np.full(x0.size, np.nan)
        correction: list[np.ndarray] = []

        def columns(x, cols):
            if not two_steps:
                J, h = self.jacobian(effects, x, lo, hi, columns=list(cols))
            else:
                with self.at_sensitivity_step():
                    J, h = self.jacobian(effects, x, lo, hi, columns=list(cols))
                if not correction:
                    correction.append(self.step_correction(effects, keys, x, lo, hi, J))
                J = J + correction[0]
            steps[list(cols)] = h[list(cols)]
            return J

        sj = SecantJacobian(lambda x: self.train_residuals(effects, x), columns, x0.size,
                            refresh=SECANT_REFRESH)
        res = least_squares(sj.residuals, x0, jac=sj.jacobian,
                            bounds=(lo, hi), method="trf", loss="soft_l1",
                            f_scale=self.f_scale, x_scale=1.0, ftol=FIT_FTOL,
                            max_nfev=max_nfev or self.options.max_nfev)
        r = res.fun
        if not np.all(np.isfinite(r)):
            raise CalibrationError("non-finite residual in the fit")
        # the covariance, the rankings and the screens read the Jacobian at the end: a
        # finite-difference one, not the secant estimate the last steps were taken with
        if sj.J is None or not np.array_equal(sj.x, res.x) or not sj.fresh.all():
            sj.full(res.x)
        raw = sj.J
        m = _Model(list(effects), res.x, cost=float(res.cost), sse=float(r @ r),
                   jac=soft_l1_jacobian_weights(r, self.f_scale)[:, None] * raw,
                   nfev=int(res.nfev), fun=np.array(r), raw_jac=raw, jac_steps=steps.copy())
        m.held_out, _ = self.held_out_errors(effects, res.x)
        return m

    def column_keys(self, effects: Sequence[Effect]) -> list[str]:
        """A name per parameter of a structure, in the order of its ``x``: each declared
        value's name, then ``effect.parameter``."""
        return ([d.name for d in self.declared]
                + [f"{e.name}.{p.name}" for e in effects for p in e.parameters])

    def step_correction(self, effects: Sequence[Effect], keys: Sequence[str], x: np.ndarray,
                        lo: np.ndarray, hi: np.ndarray, jc: np.ndarray) -> np.ndarray:
        """The columns of ``J_f − J_c`` (:meth:`fit`) at ``x``, ``jc`` the coarse
        Jacobian there: a column kept from an earlier fit of this calibration is reused
        (the stepper's error varies little with the parameters, so its sensitivity is taken
        as one per parameter: the same second-order approximation as holding it over one
        fit's path), the others are replayed at the fine step and kept."""
        steps = (float(self.replay.max_step_s), float(self.sensitivity_step_s))
        missing = [j for j, k in enumerate(keys) if (k, *steps) not in self._step_corrections]
        if missing:
            jf, _ = self.jacobian(effects, x, lo, hi, columns=missing)
            for j in missing:
                self._step_corrections[(keys[j], *steps)] = jf[:, j] - jc[:, j]
        return np.column_stack([self._step_corrections[(k, *steps)] for k in keys])

    def jacobian(self, effects: Sequence[Effect], x: np.ndarray, lo: np.ndarray,
                 hi: np.ndarray, columns: Sequence[int] | None = None
                 ) -> tuple[np.ndarray, np.ndarray]:
        """``(J, steps)``: the forward-difference Jacobian of :meth:`train_residuals` at
        ``x`` and the step of each column, with the steps of
        ``scipy.optimize.least_squares(diff_step=DIFF_STEP)`` (``2-point``): ``DIFF_STEP
        · |x_j|`` (``√ε · max(1, |x_j|)`` where that is no step), taken backwards where the
        forward step would leave the bounds ``[lo, hi]``. The residuals at ``x`` and a
        column whose parameter only changes the sensor transforms come from kept replays
        (:meth:`simulate`). ``columns``: only these columns are taken (the others NaN)."""
        x = np.asarray(x, dtype=float)
        f0 = self.train_residuals(effects, x)
        sign = np.where(x >= 0.0, 1.0, -1.0)
        h = DIFF_STEP * sign * np.abs(x)
        dx = (x + h) - x
        h = np.where(dx == 0.0, np.sqrt(np.finfo(float).eps) * sign
                     * np.maximum(1.0, np.abs(x)), h)
        # one-sided steps kept inside the bounds (scipy's _adjust_scheme_to_bounds)
        lower, upper = x - lo, hi - x
        xh = x + h
        violated = (xh < lo) | (xh > hi)
        fitting = np.abs(h) <= np.maximum(lower, upper)
        h = np.where(violated & fitting, -h, h)
        h = np.where(~fitting & (upper >= lower), upper, h)
        h = np.where(~fitting & (upper < lower), -lower, h)
        J = np.full((f0.size, x.size), np.nan)
        for j in (range(x.size) if columns is None else columns):
            x1 = x.copy()
            x1[j] = x[j] + h[j]
            J[:, j] = (self.train_residuals(effects, x1) - f0) / (x1[j] - x[j])
        return J, h

    def information(self, m: _Model) -> dict[str, float]:
        """Gaussian AIC/BIC on the training residuals (normalised), ``m`` residuals,
        ``p`` parameters: ``AIC = m ln(SSE/m) + 2p``, ``BIC = m ln(SSE/m) + p ln m``."""
        n = len(self.train_idx) * len(self.outputs)
        p = m.n_params()
        ll = n * math.log(max(m.sse, 1e-300) / n)
        return {"aic": ll + 2 * p, "bic": ll + p * math.log(n)}

    def identifiability(self, m: _Model, held: Sequence[int] = ()) -> dict:
        """Relative standard errors and correlations of the parameters, from the Gauss–Newton
        covariance ``s² (JᵀJ)⁻¹`` with ``s² = SSE/(m − p)`` (normalised parameters).

        ``held``: indices of parameters pinned at an active bound of the fit (a declared value
        at its datasheet tolerance in a fit bounded to it): not free at the optimum, so the
        covariance is that of the free parameters with these held (their columns left out of
        ``J``; Bates & Watts, *Nonlinear Regression Analysis*, 1988, §3.6 on parameters at
        bounds); a held parameter reads standard error 0 and correlation 0."""
        J = np.asarray(m.jac)
        n, p = J.shape
        free = np.array([k for k in range(p) if k not in set(held)], dtype=int)
        jtj = J.T @ J
        s2 = m.sse / max(n - len(free), 1)
        try:
            cov = np.zeros((p, p))
            cov[np.ix_(free, free)] = s2 * np.linalg.pinv(jtj[np.ix_(free, free)], rcond=1e-12)
        except np.linalg.LinAlgError:
            cov = np.full((p, p), np.inf)
        sd = np.sqrt(np.maximum(np.diag(cov), 0.0))
        with np.errstate(invalid="ignore", divide="ignore"):
            corr = cov / np.outer(sd, sd)
        corr = np.nan_to_num(corr, nan=1.0)
        if len(free) < p:
            corr[[k for k in range(p) if k not in set(free)], :] = 0.0
            corr[:, [k for k in range(p) if k not in set(free)]] = 0.0
            np.fill_diagonal(corr, 1.0)
        rel = sd / np.maximum(np.abs(m.x), 1e-12)
        m.cov = cov
        return {"sd": sd, "relative_se": rel, "correlation": corr, "held": list(held),
                "rank_deficient": bool(np.linalg.matrix_rank(jtj[np.ix_(free, free)])
                                       < len(free))}

    def _robust_cost(self, f: np.ndarray) -> float:
        """The fits' objective at residuals ``f``: ``½ Σ ρ(f²)`` with the ``soft_l1`` loss
        at ``f_scale`` (what ``least_squares`` reports as ``cost``)."""
        c = self.f_scale
        return float(c * c * np.sum(np.sqrt(1.0 + (f / c) ** 2) - 1.0))

    def _interior(self, effects: Sequence[Effect], x: np.ndarray) -> np.ndarray:
        """``x`` clipped strictly inside the fit's bounds (the start :meth:`fit` takes)."""
        lo, hi = self._bounds(effects)
        span = hi - lo
        return np.clip(np.clip(np.asarray(x, dtype=float), lo, hi), lo + 1e-9 * span,
                       hi - 1e-9 * span)

    # ---------------------------------------------------------------- noise
    def noise_floor(self) -> dict[str, float]:
        """Per channel, the NRMSE a perfect model would show: the sensor noise σ over the
        channel's SD (the NRMSE scale)."""
        return {c: self.noise[c] / self.scale[c] for c in self.outputs}

    def error_in_noise_units(self, err: Mapping[str, float]) -> float:
        """A model's held-out error measured against the noise: ``√(mean_c (e_c/f_c)²)``, the
        root mean square over the output channels of each channel's held-out NRMSE ``e_c``
        over its noise floor ``f_c`` (:meth:`noise_floor`). It is the held-out RMS residual
        of each channel in units of its own noise σ, averaged in the mean square: the
        Gaussian log-likelihood's view of the held-out part, in which every channel weighs
        by its noise, not by its signal's spread (as the overall NRMSE does). A perfect model
        scores about 1 whatever the channels' spreads."""
        floor = self.noise_floor()
        return float(math.sqrt(np.mean([(err[c] / floor[c]) ** 2 for c in self.outputs])))

    def noise_weights(self) -> np.ndarray:
        """Per training residual row (:meth:`train_residuals`, channel by channel), the
        weight ``1/f_c`` that turns its NRMSE units into units of the channel's noise σ (the
        whitening of the identifiability screen)."""
        floor = self.noise_floor()
        n1 = len(self.train_idx)
        return np.concatenate([np.full(n1, 1.0 / max(floor[c], 1e-12)) for c in self.outputs])
