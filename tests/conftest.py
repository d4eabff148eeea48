"""Suite-wide settings.

Two workers by default (pytest-xdist, in the ``test`` extra): the suite's modules share their
expensive module-scoped fixtures (a device walk, a bench run, the calibration cases), so whole
files go to one worker (``--dist loadfile``). The default applies only when no ``-n`` is given
and xdist is loaded: ``-n 0`` or ``-p no:xdist`` run serially in this process, ``-n 4`` uses
four workers (also whole files), ``--dist load`` spreads single tests, and ``--pdb`` (which
xdist refuses) stays serial.
"""

from __future__ import annotations

import pytest

#: the suite's default: the two cores of the reference machine (README, CI)
DEFAULT_WORKERS = 2


@pytest.hookimpl(tryfirst=True)
def pytest_cmdline_main(config):
    if not config.pluginmanager.has_plugin("xdist") or hasattr(config, "workerinput"):
        return
    opt = config.option
    if getattr(opt, "numprocesses", None) is None and not getattr(opt, "tx", None):
        if (getattr(opt, "usepdb", False) or getattr(opt, "collectonly", False)
                or getattr(opt, "looponfail", False)):
            return
        opt.numprocesses = DEFAULT_WORKERS
    # whole files per worker unless a --dist is named (-n N alone would mean "load")
    if opt.numprocesses and getattr(opt, "dist", "no") == "no" and not getattr(opt, "distload",
                                                                                 False):
        opt.dist = "loadfile"
