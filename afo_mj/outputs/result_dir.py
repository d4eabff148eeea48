"""A run's result directory, written all at once or not at all, holding only that run's files.

:func:`write_atomically` lets a writer fill a temporary sibling directory, lists what it wrote
in :data:`MANIFEST` and swaps it in for ``out_dir`` at the end (two renames), so the directory
holds this run's files and nothing else: a previous run's files do not linger beside the new
ones. A writer that raises leaves ``out_dir`` untouched (and not created).

``out_dir`` may be a new path, an empty directory, or a previous result directory (one with a
:data:`MANIFEST`, whose listed files are replaced). A directory holding files afo-mj did not
write (not in its manifest, or any file without one) is refused with :class:`ResultDirError`
naming them, and so is a path that is an existing file: :func:`check_result_dir` says so before
any work starts (``afo-mj`` exits 2).
"""

from __future__ import annotations

import json
import os
import shutil
import tempfile
from pathlib import Path
from typing import Callable

__all__ = ["MANIFEST", "ResultDirError", "check_result_dir", "write_atomically"]

MANIFEST = ".afo_mj_files.json"
"""The file, in every result directory, listing the entries afo-mj wrote there."""


class ResultDirError(ValueError):
    """The output path cannot take a result directory."""


def _manifest_entries(out: Path) -> set[str] | None:
    """The entries a previous afo-mj run listed in ``out``'s manifest (None: no manifest)."""
    try:
        doc = json.loads((out / MANIFEST).read_text(encoding="utf-8"))
    except FileNotFoundError:
        return None
    except (OSError, ValueError):
        return None
    files = doc.get("files") if isinstance(doc, dict) else None
    return {str(f) for f in files} if isinstance(files, list) else None


def check_result_dir(out_dir) -> Path:
    """Raise :class:`ResultDirError` unless ``out_dir`` can take a result directory: a new
    path, an empty directory or a previous afo-mj result directory with nothing else in it."""
    out = Path(out_dir)
    if out.exists() and not out.is_dir():
        raise ResultDirError(f"--out {out}: exists and is not a directory; allowed: a new "
                             f"path, an empty directory or a previous afo-mj result directory")
    if out.is_dir():
        names = sorted(p.name for p in out.iterdir())
        ours = _manifest_entries(out)
        foreign = [n for n in names if n != MANIFEST and (ours is None or n not in ours)]
        if foreign:
            shown = ", ".join(foreign[:8]) + (f" and {len(foreign) - 8} more"
                                              if len(foreign) > 8 else "")
            raise ResultDirError(
                f"--out {out}: holds files afo-mj did not write ({shown}); allowed: a new "
                f"path, an empty directory or a previous afo-mj result directory (move "
                f"those files away or choose another --out)")
    return out


def write_atomically(out_dir, writer: Callable[[Path], None]) -> Path:
    """Call ``writer(tmp_dir)`` and swap what it wrote in as ``out_dir``; returns the path."""
    out = check_result_dir(out_dir)
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{out.name}.tmp-", dir=out.parent))
    umask = os.umask(0o022)
    os.umask(umask)
    os.chmod(tmp, 0o777 & ~umask)         # mkdtemp makes 0700; the result is an ordinary dir
    old = None
    try:
        writer(tmp)
        files = sorted(p.name for p in tmp.iterdir() if p.name != MANIFEST)
        (tmp / MANIFEST).write_text(json.dumps({"written_by": "afo-mj", "files": files},
                                               indent=1) + "\n", encoding="utf-8")
        if out.exists():
            check_result_dir(out)         # nothing foreign arrived while the writer ran
            old = Path(tempfile.mkdtemp(prefix=f".{out.name}.old-", dir=out.parent))
            os.replace(out, old)          # onto the empty placeholder directory
            try:
                os.replace(tmp, out)
            except OSError:
                os.replace(old, out)      # put the previous results back
                raise
        else:
            os.replace(tmp, out)          # the whole directory appears at once
    finally:
        for d in (tmp, old):
            if d is not None and d.exists():
                shutil.rmtree(d, ignore_errors=True)
    return out
