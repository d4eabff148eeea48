"""A run's result directory, written all at once or not at all.

:func:`write_atomically` lets a writer fill a temporary sibling directory, then moves each
file into place with :func:`os.replace` (the whole directory at once when it did not exist).
A writer that raises leaves ``out_dir`` untouched (and not created); files already in
``out_dir`` that the writer does not produce are left alone.
"""

from __future__ import annotations

import os
import shutil
import tempfile
from pathlib import Path
from typing import Callable

__all__ = ["ResultDirError", "write_atomically"]


class ResultDirError(ValueError):
    """The output path cannot take a result directory."""


def write_atomically(out_dir, writer: Callable[[Path], None]) -> Path:
    """Call ``writer(tmp_dir)`` and move what it wrote into ``out_dir``; returns the path."""
    out = Path(out_dir)
    if out.exists() and not out.is_dir():
        raise ResultDirError(f"{out} exists and is not a directory; nothing written")
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{out.name}.tmp-", dir=out.parent))
    umask = os.umask(0o022)
    os.umask(umask)
    os.chmod(tmp, 0o777 & ~umask)         # mkdtemp makes 0700; the result is an ordinary dir
    try:
        writer(tmp)
        if not out.exists():
            os.replace(tmp, out)          # the whole directory appears at once
            return out
        for f in sorted(tmp.iterdir()):
            os.replace(f, out / f.name)
    finally:
        if tmp.exists():
            shutil.rmtree(tmp, ignore_errors=True)
    return out
