"""Progress of long phases on stderr: a stage line when a phase starts and, for a phase with a
known amount of work, throttled updates with the elapsed time and an estimate of the time left.

Never on stdout (stdout carries the results tables). Silent unless a command line installs an
active reporter (``afo-mj`` does, unless ``--quiet``): library calls, tests and benchmarks stay
quiet. Standard library only, so every layer may import it.

* :func:`reporter` the reporter of the current context (a silent one by default);
  :func:`using` installs one for a ``with`` block (a :class:`contextvars.ContextVar`: a thread
  started inside keeps the default, silent).
* :meth:`Reporter.stage` one line: ``[afo-mj] simulating 10 strides…``.
* :meth:`Reporter.task` a phase of ``total`` units: :meth:`Task.update` (absolute) or
  :meth:`Task.advance` report progress; on a terminal at most one in-place (``\\r``) update per
  ``tty_interval_s`` (1 s); elsewhere plain lines, at most one per ``plain_interval_s`` (5 s)
  and only when a new 25 % step is reached, so a log gets ≤ 4 lines per phase.
* The time left is ``(total − done) / rate`` with the rate measured from the first update on
  (the work before it, which may include a first-run compilation, does not count), or from
  the phase's start while there is only one update.
* :func:`compile_stage` compiles a numba function for given arguments before a loop uses it,
  saying whether it was compiled (first run) or loaded from numba's cache.
"""

from __future__ import annotations

import contextlib
import contextvars
import math
import os
import sys
import time
from typing import Callable, Iterator

__all__ = ["Reporter", "Task", "reporter", "using", "fmt_duration", "compile_stage"]

PREFIX = "[afo-mj] "


def fmt_duration(s: float) -> str:
    """``0.4 s``, ``17 s``, ``2 min 05 s``, ``1 h 02 min``."""
    if not math.isfinite(s):
        return "?"
    if s < 9.95:
        return f"{max(s, 0.0):.1f} s"
    s = int(round(s))
    if s < 60:
        return f"{s} s"
    if s < 3600:
        return f"{s // 60} min {s % 60:02d} s"
    return f"{s // 3600} h {s % 3600 // 60:02d} min"


class Reporter:
    """Writes progress to ``stream`` (default: ``sys.stderr`` at the time of writing, so a
    redirected stderr is honoured); ``quiet`` writes nothing. ``clock`` and ``tty`` are for
    tests (a fake clock; forcing in-place updates on or off)."""

    def __init__(self, stream=None, quiet: bool = False,
                 clock: Callable[[], float] = time.monotonic, tty: bool | None = None,
                 tty_interval_s: float = 1.0, plain_interval_s: float = 5.0):
        self._stream = stream
        self.quiet = quiet
        self.clock = clock
        self._tty = tty
        self.tty_interval_s = tty_interval_s
        self.plain_interval_s = plain_interval_s
        self._open_line = False          # an in-place line is on screen, unterminated

    @property
    def stream(self):
        return self._stream if self._stream is not None else sys.stderr

    @property
    def tty(self) -> bool:
        if self._tty is not None:
            return self._tty
        try:
            return bool(self.stream.isatty())
        except (AttributeError, ValueError):
            return False

    @property
    def active(self) -> bool:
        return not self.quiet

    def _write(self, text: str, in_place: bool = False) -> None:
        if self.quiet:
            return
        s = self.stream
        try:
            if in_place:
                s.write("\r" + text + "\x1b[K")
                self._open_line = True
            else:
                if self._open_line:
                    s.write("\n")
                    self._open_line = False
                s.write(text + "\n")
            s.flush()
        except (OSError, ValueError):    # a closed or broken stderr never stops a run
            pass

    def stage(self, message: str) -> None:
        """One line saying what starts now."""
        self._write(PREFIX + message)

    def task(self, label: str, total: float | None, unit: str = "",
             fmt: Callable[[float], str] | None = None) -> "Task":
        """A phase of ``total`` units of work (None: unknown): its stage line now, updates
        from :meth:`Task.update`, and a closing line from :meth:`Task.close`."""
        return Task(self, label, total, unit, fmt)


class Task:
    """One phase with a known amount of work (see :class:`Reporter`)."""

    def __init__(self, rep: Reporter, label: str, total: float | None, unit: str = "",
                 fmt: Callable[[float], str] | None = None):
        self.rep, self.label, self.total, self.unit = rep, label, total, unit
        self.fmt = fmt or (lambda v: f"{v:g}")
        self.t0 = rep.clock()
        self.done = 0.0
        self._first: tuple[float, float] | None = None   # (time, done) at the first update
        self._last_print = self.t0
        self._step = 0                                    # 25 % steps already printed
        self.closed = False
        rep.stage(label + "…")

    # -- the estimate --------------------------------------------------------------------
    def elapsed(self, now: float | None = None) -> float:
        return (self.rep.clock() if now is None else now) - self.t0

    def time_left(self, now: float | None = None) -> float:
        """Seconds left at the rate measured so far (nan when unknown)."""
        now = self.rep.clock() if now is None else now
        if not self.total or self.done <= 0:
            return math.nan
        if self._first is not None and self.done > self._first[1] and now > self._first[0]:
            rate = (self.done - self._first[1]) / (now - self._first[0])
        elif now > self.t0:
            rate = self.done / (now - self.t0)
        else:
            return math.nan
        return max(self.total - self.done, 0.0) / rate if rate > 0 else math.nan

    def line(self, now: float | None = None) -> str:
        now = self.rep.clock() if now is None else now
        unit = f" {self.unit}" if self.unit else ""
        if self.total:
            frac = min(self.done / self.total, 1.0)
            head = f"{self.label}: {self.fmt(self.done)}/{self.fmt(self.total)}{unit} ({frac:.0%})"
        else:
            head = f"{self.label}: {self.fmt(self.done)}{unit}"
        left = self.time_left(now)
        tail = f", {fmt_duration(self.elapsed(now))} elapsed"
        if math.isfinite(left):
            tail += f", ~{fmt_duration(left)} left"
        return head + tail

    # -- reporting -----------------------------------------------------------------------
    def update(self, done: float) -> None:
        """Progress to ``done`` units (absolute); prints only when the throttle allows."""
        rep = self.rep
        self.done = done
        if rep.quiet or self.closed:
            return
        now = rep.clock()
        if self._first is None:
            self._first = (now, done)
        since = now - self._last_print
        if rep.tty:
            if since < rep.tty_interval_s:
                return
            rep._write(PREFIX + self.line(now), in_place=True)
            self._last_print = now
            return
        if not self.total:
            if since >= 6 * rep.plain_interval_s:
                rep._write(PREFIX + self.line(now))
                self._last_print = now
            return
        step = int(4 * min(done / self.total, 1.0) + 1e-9)
        if step > self._step and step < 4 and since >= rep.plain_interval_s:
            self._step = step
            rep._write(PREFIX + self.line(now))
            self._last_print = now

    def advance(self, n: float = 1.0) -> None:
        self.update(self.done + n)

    def close(self, message: str | None = None) -> None:
        """The closing line: ``label: done in 12 s`` (or ``message``), always printed."""
        if self.closed:
            return
        self.closed = True
        el = fmt_duration(self.elapsed())
        self.rep._write(PREFIX + (message if message is not None
                                  else f"{self.label}: done in {el}"))

    def abort(self) -> None:
        """The phase ends with an error: end an in-place line (no closing line)."""
        if not self.closed:
            self.closed = True
            if self.rep._open_line:
                self.rep._write(PREFIX + f"{self.label}: stopped after "
                                         f"{fmt_duration(self.elapsed())}")

    def __enter__(self) -> "Task":
        return self

    def __exit__(self, exc_type, exc, tb) -> None:
        if exc_type is None:
            self.close()
        else:
            self.abort()


_SILENT = Reporter(quiet=True)
_current: contextvars.ContextVar[Reporter] = contextvars.ContextVar("afo_mj_progress",
                                                                    default=_SILENT)


def reporter() -> Reporter:
    """The reporter of the current context (silent unless one was installed)."""
    return _current.get()


@contextlib.contextmanager
def using(rep: Reporter) -> Iterator[Reporter]:
    """Install ``rep`` for the ``with`` block."""
    token = _current.set(rep)
    try:
        yield rep
    finally:
        _current.reset(token)


def _numba_cache_file(dispatcher) -> str | None:
    """The index file of a numba dispatcher's on-disk cache (None when unknown)."""
    try:
        return dispatcher._cache._cache_file._index_path
    except AttributeError:
        return None


def compile_stage(dispatcher, args: tuple, what: str, first_run_s: str) -> None:
    """Compile ``dispatcher`` (a ``numba.njit(cache=True)`` function) for ``args`` now, unless
    this process has it already: with a stage line when it is compiled for the first time
    (``first_run_s``: the typical time, e.g. ``"~10 s"``) and a line with the time taken; a
    load from numba's on-disk cache is silent unless it takes longer than a second."""
    try:
        # the types the call will dispatch on (so that the call finds this compilation)
        sig = tuple(dispatcher.typeof_pyval(a) for a in args)
        if sig in dispatcher.overloads:
            return
    except Exception:                           # noqa: BLE001 - never stop a run for this
        return                                  # the first call compiles it, unannounced
    rep = reporter()
    index = _numba_cache_file(dispatcher)
    cached = index is not None and os.path.exists(index)
    if not cached:
        rep.stage(f"compiling {what} (first run only, {first_run_s})…")
    t0 = time.perf_counter()
    dispatcher.compile(sig)
    dt = time.perf_counter() - t0
    hits = sum(dispatcher.stats.cache_hits.values()) if hasattr(dispatcher, "stats") else 0
    if not cached or not hits:
        rep.stage(f"compiled {what} in {fmt_duration(dt)} (cached for later runs)")
    elif dt > 1.0:
        rep.stage(f"loaded {what} from the compile cache in {fmt_duration(dt)}")
