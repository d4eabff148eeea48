"""Errors of the application layer, each carrying the command line's exit status."""

from __future__ import annotations

__all__ = ["AppError", "InvalidInput", "RunFailed"]


class AppError(Exception):
    """A workflow that stopped; ``exit_code`` is what ``afo-mj`` exits with. Nothing was
    written when it is raised."""

    exit_code = 1


class InvalidInput(AppError):
    """The input (scenario, study, data file, option, results directory) is not allowed; the
    message names the key, the value and what is allowed."""

    exit_code = 2


class RunFailed(AppError):
    """The input was valid but the run could not be simulated, analysed or written."""

    exit_code = 1
