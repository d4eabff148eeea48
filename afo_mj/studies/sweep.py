"""Run a study's points in parallel, locally or on a Dask cluster, with results kept run by run.

Each point is one run of the base scenario with the point's ``--set`` overrides, executed in a
worker process by the ``runner`` the caller gives (the application layer's
:func:`afo_mj.app.sweep_point.run_point`: the same code as ``afo-mj run``, in-process and
without figures), so a sweep's row holds exactly the metrics a single run writes to
``summary.json``. A row is: ``run_id``, ``status`` (``ok``/``failed``), ``exit_code``,
``error`` (the run's last error line, empty when it succeeded), ``wall_time_s``, the inputs as
``param:<dotted key>`` columns and every scalar of ``summary.json`` flattened to dotted names
(``{"mean", "sd", "n"}`` statistics as ``key.mean``, ``key.sd``, ``key.n``; the scenario echo
and the definitions are left out).

Storage (``DIR``): ``study.json`` (the study as run), ``rows/<run_id>.json`` (one file per
finished run, written atomically: the record of truth; a row lost to the infrastructure, a
worker process that died or a lost Dask task, is marked ``retry`` and run again on resume), and
``results.parquet`` (or
``results.csv``), the table of all rows, rewritten atomically as runs finish and at the end.
A sweep that is interrupted (SIGINT/SIGTERM, a crash, a lost cluster) resumes when it is run
again with the same study and ``DIR``: runs whose row exists are not recomputed, runs in flight
when it stopped are run again, and no row is duplicated (a row's file name is its run id). A
run that raises or exits non-zero is recorded with its error and does not stop the sweep.

Executors: local worker processes (:func:`afo_mj.experiments.batch.run_unordered`: forked
where the platform allows, so workers start with the parent's compiled code) by default; a
Dask ``distributed`` cluster when a scheduler address is given, or ``"local"`` for a
:class:`distributed.LocalCluster` of ``workers`` single-threaded processes on this machine
(Dask's own scheduler does the placement, retries of lost workers and transfers; we only
submit runs and collect rows).
"""

from __future__ import annotations

import json
import math
import os
import re
import signal
import sys
import time
from pathlib import Path
from typing import Any, Callable, Iterable, Sequence

from afo_mj.studies.study import Study, StudyError

__all__ = ["flatten_summary", "check_study_keys", "Sweep", "SweepInterrupted",
           "read_rows", "write_table", "PARAM_PREFIX", "connect_scheduler",
           "SCHEDULER_CONNECT_TIMEOUT_S"]

PARAM_PREFIX = "param:"
#: how long a sweep waits to reach a Dask scheduler before refusing it (s)
SCHEDULER_CONNECT_TIMEOUT_S = 5.0
_SKIP_TOP = ("scenario", "definitions", "format")


class SweepInterrupted(RuntimeError):
    """The sweep stopped on a signal; finished rows are kept (run it again to resume)."""


def flatten_summary(summary: dict) -> dict[str, Any]:
    """Every scalar of a ``summary.json`` under its dotted path (numbers as float, booleans
    as bool, ``None`` as NaN); strings and lists are left out."""
    out: dict[str, Any] = {}

    def walk(d, prefix):
        for k, v in d.items():
            if not prefix and k in _SKIP_TOP:
                continue
            key = f"{prefix}{k}"
            if isinstance(v, dict):
                walk(v, key + ".")
            elif isinstance(v, bool):
                out[key] = v
            elif isinstance(v, (int, float)):
                out[key] = float(v)
            elif v is None:
                out[key] = math.nan
    walk(summary, "")
    return out


def _load_with(scenario_path: Path, overrides: Sequence[str]):
    """Parse the base scenario with ``overrides`` as ``afo-mj run --set`` would (walk or bench
    scenario, and the device it names), without running anything."""
    from afo_mj.scenarios.bench_scenario import is_bench_document, load_bench_scenario
    from afo_mj.scenarios.device_scenario import device_config
    from afo_mj.scenarios.walk_scenario import load_scenario

    if is_bench_document(scenario_path.read_text(encoding="utf-8")):
        return load_bench_scenario(scenario_path, overrides=overrides)
    scenario = load_scenario(scenario_path, overrides=overrides)
    device_config(scenario)
    return scenario


def _did_you_mean(key: str, message: str) -> str:
    """A suggestion for the whole dotted ``key`` with its misspelt part replaced by the
    closest of the names the scenario's error lists as allowed/known (the scenario's own
    suggestion names only that part), or '' when there is none or the message has it."""
    from afo_mj.scenarios.walk_scenario import did_you_mean

    m = re.search(r"(?:allowed|known)[^:]*:(.*)$", message, flags=re.S)
    names = sorted(set(re.findall(r"[A-Za-z_][A-Za-z0-9_]*", m.group(1)))) if m else []
    parts = key.split(".")
    for i, part in enumerate(parts):
        if part in names:
            continue
        hint = did_you_mean(part, names, prefix="".join(p + "." for p in parts[:i]),
                            suffix="".join("." + p for p in parts[i + 1:]))
        return hint if hint and hint.strip() not in message else ""
    return ""


def check_study_keys(study: Study, points: Sequence[dict] | None = None) -> None:
    """Check, before any run, that the study's fixed ``set`` overrides and every parameter key
    (with its value at the first point) are accepted by the base scenario, exactly as
    ``afo-mj run --set`` parses them. Raises :class:`StudyError` naming the key, the
    scenario's reason and a difflib "did you mean"; a misspelt key would otherwise fail every
    run of the sweep."""
    from afo_mj.scenarios.walk_scenario import ScenarioError

    origin = str(study.source_path) if study.source_path else study.name
    fixed = list(study.fixed)
    try:
        _load_with(study.scenario_path, fixed)
    except (ScenarioError, ValueError, OSError) as exc:
        bad = next((f for f in fixed if f.partition("=")[0].strip() in str(exc)), None)
        key = bad.partition("=")[0].strip() if bad else ""
        raise StudyError(f"{origin}: set = {bad or fixed!r} is not accepted by the scenario "
                         f"{study.scenario_path}: {exc}{_did_you_mean(key, str(exc))}; "
                         f"nothing was run") from None
    points = list(study.points() if points is None else points)
    first = points[0] if points else {}
    for p in study.parameters:
        value = first.get(p.key, p.levels[0] if p.levels else p.lo)
        override = study.overrides({p.key: value})[len(fixed):]
        try:
            _load_with(study.scenario_path, fixed + override)
        except (ScenarioError, ValueError, OSError) as exc:
            raise StudyError(f"{origin}: parameter key = {p.key!r} (first value {value!r}) is "
                             f"not accepted by the scenario {study.scenario_path}: {exc}"
                             f"{_did_you_mean(p.key, str(exc))}; nothing was run") from None


def _write_json_atomic(path: Path, obj) -> None:
    tmp = path.with_name(f".{path.name}.tmp-{os.getpid()}")
    tmp.write_text(json.dumps(obj, default=_json_default, allow_nan=True), encoding="utf-8")
    os.replace(tmp, path)


def _json_default(o):
    try:
        return float(o)
    except (TypeError, ValueError):
        return str(o)


def read_rows(out_dir) -> list[dict]:
    """The finished rows of a sweep directory (``rows/*.json``), ordered by run order."""
    rows = []
    rdir = Path(out_dir) / "rows"
    if not rdir.is_dir():
        return rows
    for p in rdir.glob("*.json"):
        try:
            rows.append(json.loads(p.read_text(encoding="utf-8")))
        except (OSError, ValueError):
            continue                                  # a torn file: the run is redone
    rows.sort(key=lambda r: r.get("order", 0))
    return rows


def write_table(rows: Sequence[dict], path: Path, fmt: str) -> Path:
    """All rows as one table (Parquet via pyarrow, or CSV), written atomically. Columns: the
    fixed ones first, then the parameters, then the metrics in sorted order."""
    fixed = ["order", "run_id", "status", "exit_code", "error", "wall_time_s", "retry"]
    keys = set()
    for r in rows:
        keys.update(r)
    params = sorted(k for k in keys if k.startswith(PARAM_PREFIX))
    metrics = sorted(k for k in keys if k not in fixed and k not in params)
    cols = [k for k in fixed if k in keys] + params + metrics
    tmp = path.with_name(f".{path.name}.tmp-{os.getpid()}")
    if fmt == "parquet":
        import pyarrow as pa
        import pyarrow.parquet as pq
        data = {}
        for c in cols:
            vals = [r.get(c) for r in rows]
            if all(v is None or isinstance(v, bool) for v in vals):
                data[c] = pa.array(vals, type=pa.bool_())
            elif all(v is None or (isinstance(v, (int, float)) and not isinstance(v, bool))
                     for v in vals):
                data[c] = pa.array([None if v is None else float(v) for v in vals],
                                   type=pa.float64())
            else:
                data[c] = pa.array([None if v is None else str(v) for v in vals],
                                   type=pa.string())
        pq.write_table(pa.table(data), tmp)
    else:
        import csv
        with open(tmp, "w", newline="", encoding="utf-8") as fh:
            w = csv.writer(fh)
            w.writerow(cols)
            for r in rows:
                w.writerow(["" if r.get(c) is None else r.get(c) for c in cols])
    os.replace(tmp, path)
    return path


class _Progress:
    """A one-line progress report on stderr: runs done, failures, elapsed and time left."""

    def __init__(self, total: int, already: int, stream=None, enabled: bool = True):
        self.total, self.done, self.failed = total, already, 0
        self.started = time.perf_counter()
        self.new = 0
        self.stream = stream or sys.stderr
        self.enabled = enabled
        self.tty = hasattr(self.stream, "isatty") and self.stream.isatty()
        self._last = 0.0

    def update(self, failed: bool) -> None:
        self.done += 1
        self.new += 1
        self.failed += int(failed)
        self.show()

    def show(self, final: bool = False) -> None:
        if not self.enabled:
            return
        now = time.perf_counter()
        if not (final or self.tty or now - self._last > 5.0 or self.done == self.total):
            return
        self._last = now
        el = now - self.started
        left = (self.total - self.done) * el / self.new if self.new else float("nan")
        width = 30
        fill = int(width * self.done / max(self.total, 1))
        msg = (f"[{'#' * fill}{'-' * (width - fill)}] {self.done}/{self.total} runs, "
               f"{self.failed} failed, {_hms(el)} elapsed"
               + (f", ~{_hms(left)} left" if math.isfinite(left) and self.done < self.total
                  else ""))
        end = "\n" if (final or not self.tty) else ""
        print(("\r" if self.tty else "") + msg, end=end, file=self.stream, flush=True)


def _hms(s: float) -> str:
    s = int(round(s))
    return (f"{s // 3600}:{s % 3600 // 60:02d}:{s % 60:02d}" if s >= 3600
            else f"{s // 60}:{s % 60:02d}")


class Sweep:
    """A study's runs into ``out_dir``: ``workers`` local processes, or a Dask scheduler
    (``scheduler``: an address such as ``tcp://host:8786``, or ``"local"``)."""

    def __init__(self, study: Study, out_dir, workers: int | None = None,
                 scheduler: str | None = None, fmt: str | None = None,
                 keep_runs: bool = False, progress: bool = True,
                 runner: Callable[..., dict] | None = None):
        if runner is None:
            raise ValueError("Sweep: runner is None; allowed: a picklable callable "
                             "(scenario_path, overrides, run_id, point, keep_dir) -> row, "
                             "e.g. afo_mj.app.sweep_point.run_point")
        self.runner = runner
        self.study = study
        self.out_dir = Path(out_dir)
        self.workers = max(1, int(workers or os.cpu_count() or 1))
        self.scheduler = scheduler
        self.fmt = fmt or study.output_format
        if self.fmt not in ("parquet", "csv"):
            raise ValueError(f"format = {self.fmt!r}; allowed: parquet, csv")
        self.keep_runs = keep_runs
        self.progress = progress
        self._keys_checked = False

    @property
    def table_path(self) -> Path:
        return self.out_dir / f"results.{self.fmt}"

    def _prepare(self) -> None:
        (self.out_dir / "rows").mkdir(parents=True, exist_ok=True)
        if self.keep_runs:
            (self.out_dir / "runs").mkdir(exist_ok=True)
        meta = self.out_dir / "study.json"
        info = self.study.as_dict()
        if meta.is_file():
            old = json.loads(meta.read_text(encoding="utf-8"))
            if old.get("scenario") != info["scenario"] or old.get("set") != info["set"]:
                raise ValueError(f"{self.out_dir} holds a sweep of another study "
                                 f"({old.get('name')!r}: scenario {old.get('scenario')}); "
                                 "use another --out")
        _write_json_atomic(meta, info)

    def run(self, points: Sequence[dict] | None = None) -> list[dict]:
        """Run every point that has no row yet; returns all rows of these points (in point
        order). Raises :class:`SweepInterrupted` on SIGINT/SIGTERM after saving the table,
        and :class:`StudyError` before any run (nothing written) when a key is not accepted by
        the base scenario (:func:`check_study_keys`, on the first call) or when the Dask
        scheduler cannot be reached (ValueError naming its address)."""
        points = list(self.study.points() if points is None else points)
        if not self._keys_checked:          # once per sweep (the optimiser calls run often)
            check_study_keys(self.study, points)
            self._keys_checked = True
        client = self._connect()            # before anything is written: refused, nothing
        try:
            return self._run(points, client)
        finally:
            if client is not None:
                client.close()

    def _connect(self):
        return connect_scheduler(self.scheduler)

    def _run(self, points, client) -> list[dict]:
        self._prepare()
        ids = [self.study.run_id(p) for p in points]
        # rows of runs lost to the infrastructure (a worker that died, a lost Dask task) are
        # not results: they are run again
        have = {r["run_id"]: r for r in read_rows(self.out_dir) if not r.get("retry")}
        order0 = 1 + max((r.get("order", 0) for r in have.values()), default=0)
        todo = []
        seen = set()
        for i, (rid, p) in enumerate(zip(ids, points)):
            if rid in have or rid in seen:
                continue
            seen.add(rid)
            todo.append((i, rid, p))
        prog = _Progress(len(set(ids)), len(set(ids)) - len(todo), enabled=self.progress)
        stop = {"signal": None}

        def handler(signum, frame):
            stop["signal"] = signum
            raise KeyboardInterrupt

        old = {s: signal.getsignal(s) for s in (signal.SIGINT, signal.SIGTERM)}
        in_main = _is_main_thread()
        if in_main:
            for s in old:
                signal.signal(s, handler)
        new_rows = {}
        last_write = time.perf_counter()
        try:
            for k, row in self._execute(todo, client):
                row["order"] = order0 + k
                _write_json_atomic(self.out_dir / "rows" / f"{row['run_id']}.json", row)
                new_rows[row["run_id"]] = row
                prog.update(row["status"] != "ok")
                if time.perf_counter() - last_write > 2.0:
                    write_table(read_rows(self.out_dir), self.table_path, self.fmt)
                    last_write = time.perf_counter()
        except KeyboardInterrupt:
            write_table(read_rows(self.out_dir), self.table_path, self.fmt)
            prog.show(final=True)
            done = len(read_rows(self.out_dir))
            raise SweepInterrupted(
                "interrupted "
                f"({signal.Signals(stop['signal']).name if stop['signal'] else 'SIGINT'})"
                f": {done} runs saved in {self.out_dir}; run the same command again to resume")
        finally:
            if in_main:
                for s, h in old.items():
                    signal.signal(s, h)
        rows = read_rows(self.out_dir)
        write_table(rows, self.table_path, self.fmt)
        prog.show(final=True)
        by_id = {r["run_id"]: r for r in rows}
        return [by_id[i] for i in ids if i in by_id]

    # -- executors -------------------------------------------------------------------------
    def _args(self, rid, p):
        keep = str(self.out_dir / "runs") if self.keep_runs else None
        return (str(self.study.scenario_path), self.study.overrides(p), rid, p, keep)

    def _execute(self, todo, client=None) -> Iterable[tuple[int, dict]]:
        if not todo:
            return
        if self.scheduler:
            yield from self._execute_dask(todo, client)
        elif self.workers == 1:
            for k, (i, rid, p) in enumerate(todo):
                yield k, self.runner(*self._args(rid, p))
        else:
            yield from self._execute_local(todo)

    def _execute_local(self, todo):
        from afo_mj.experiments.batch import call_packed, run_unordered
        packed = [(self.runner,) + self._args(rid, p) for _, rid, p in todo]
        for k, (j, res) in enumerate(run_unordered(call_packed, packed, self.workers)):
            i, rid, p = todo[j]
            if res.ok:
                yield k, res.value
            else:                                    # a worker that died
                exc = res.error
                yield k, _failed_row(rid, p, f"worker failed: {type(exc).__name__}: {exc}")

    def _execute_dask(self, todo, client=None):
        """Runs on the Dask ``client`` (the caller's, left open) or on a local cluster
        started here (``scheduler = "local"``, closed here)."""
        from distributed import Client, LocalCluster, as_completed

        cluster = own = None
        if client is None:
            cluster = LocalCluster(n_workers=self.workers, threads_per_worker=1,
                                   processes=True, dashboard_address=None)
            client = own = Client(cluster)
        try:
            futs = {}
            for i, rid, p in todo:
                f = client.submit(self.runner, *self._args(rid, p), key=f"afo-run-{rid}",
                                  pure=False)
                futs[f] = (i, rid, p)
            for k, fut in enumerate(as_completed(list(futs))):
                i, rid, p = futs[fut]
                try:
                    row = fut.result()
                except Exception as exc:
                    row = _failed_row(rid, p, f"dask task failed: {type(exc).__name__}: {exc}")
                yield k, row
        finally:
            if own is not None:
                own.close()
            if cluster is not None:
                cluster.close()


def connect_scheduler(address: str | None):
    """A client of the Dask scheduler at ``address`` (None for no address or ``"local"``:
    local processes, or a local cluster started by the sweep); ValueError naming the address
    when it cannot be reached within :data:`SCHEDULER_CONNECT_TIMEOUT_S` (an unreachable
    scheduler is refused at once, before a sweep writes anything)."""
    if not address or address == "local":
        return None
    from distributed import Client
    allowed = ("allowed: the address of a running Dask scheduler (e.g. tcp://host:8786, "
               "printed by `dask scheduler`), 'local' for a Dask cluster on this machine, "
               "or no --scheduler for local worker processes; nothing written")
    try:
        return Client(address, timeout=SCHEDULER_CONNECT_TIMEOUT_S)
    except (OSError, ValueError, TypeError) as exc:
        why = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        raise ValueError(f"--scheduler {address}: cannot reach the Dask scheduler ({why}; "
                         f"waited up to {SCHEDULER_CONNECT_TIMEOUT_S:g} s); {allowed}") from None


def _failed_row(rid, p, error) -> dict:
    row = {"run_id": rid, "exit_code": -1, "status": "failed", "error": error,
           "wall_time_s": math.nan, "retry": True}
    for k, v in p.items():
        row[PARAM_PREFIX + k] = v
    return row


def _is_main_thread() -> bool:
    import threading
    return threading.current_thread() is threading.main_thread()
