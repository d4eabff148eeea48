"""Helpers the command-line tests share (imported by name, like gait_fixtures)."""

from __future__ import annotations

import contextlib
import io
import math

from afo_mj import cli


def run_cli(argv) -> tuple[int, str, str]:
    """``afo_mj.cli.main(argv)`` with its stdout and stderr captured: ``(rc, out, err)``."""
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        rc = cli.main(argv)
    return rc, out.getvalue(), err.getvalue()


def csv_number(x: str) -> float:
    """A CSV cell as a number (an empty cell is NaN)."""
    return float(x) if x != "" else math.nan
