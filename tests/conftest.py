"""Suite-wide settings.

Two workers by default (pytest-xdist, in the ``test`` extra): the suite's modules share their
expensive module-scoped fixtures (a device walk, a bench run, the calibration cases), so whole
files go to one worker (``--dist loadfile``). The default applies only when no ``-n`` is given
and xdist is loaded: ``-n 0`` or ``-p no:xdist`` run serially in this process, ``-n 4`` uses
four workers (also whole files), ``--dist load`` spreads single tests, and ``--pdb`` (which
xdist refuses) stays serial.

Files are handed out in collection order, so the heaviest go first (:data:`HEAVY_FILES`,
longest-processing-time-first scheduling): a worker that draws a long blind calibration late
would otherwise run alone at the end while the other idles.
"""

from __future__ import annotations

import pytest

#: the suite's default: the two cores of the reference machine (README, CI)
DEFAULT_WORKERS = 2

#: the suite's heaviest files with their time in seconds (measured on 2026-11-29 with
#: ``--durations``, one process beside another job: only their order matters), run first; the
#: other files follow in their usual order. A stale figure costs balance, never a test.
HEAVY_FILES = {
    "test_rig_calibration.py": 137.0,
    "test_rig_calibration_pair.py": 134.0,
    "test_second_rig_blind.py": 121.0,
    "test_calibration.py": 101.0,       # its two-process pool of synthetic-record cases
    "test_second_rig_effects.py": 75.0,     # one round on the backlash record (2026-11-29)
    "test_hold_variants.py": 25.0,          # the wrong-hold replay without a search
    "test_valve_gait.py": 29.0,
    "test_figures.py": 17.0,
    "test_sweep.py": 15.0,
    "test_properties_circuits.py": 13.0,
    "test_independent_rig.py": 12.0,
    "test_human_response.py": 12.0,
    "test_walk_env.py": 11.0,
}


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
        # keep the collection's order of files (heaviest first, below), not xdist's default of
        # most tests first, which put the few-test blind calibrations last
        opt.loadscopereorder = False


def pytest_collection_modifyitems(session, config, items):
    """The heaviest files first (:data:`HEAVY_FILES`), each file's tests kept together and in
    their order; the sort is stable, so the rest keep theirs."""
    items.sort(key=lambda it: -HEAVY_FILES.get(it.path.name, 0.0))
