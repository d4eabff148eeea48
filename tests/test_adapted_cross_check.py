"""tools/adapted_cross_check.py: the shipped adapted wearers walked with and without their
device (issue 42: each effect split into the search's share and the device's share)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


@pytest.mark.slow
def test_docs_cross_check_table_is_current():
    """``tools/adapted_cross_check.py --check`` against docs/muscle_walker.md's block."""
    p = subprocess.run([sys.executable, str(ROOT / "tools" / "adapted_cross_check.py"),
                        "--check"], capture_output=True, text=True, cwd=ROOT)
    assert p.returncode == 0, p.stdout + p.stderr
