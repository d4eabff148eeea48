"""Opening a recording in rerun's viewer: ``afo-mj view``.

:func:`viewer_command` checks the file and builds the viewer command (the native viewer, or
``rerun --serve-web`` for rerun's web viewer, which works without a display);
:func:`headless_problem` says why a window cannot open here and how else to see the file.
"""

from __future__ import annotations

import os
import shlex
import shutil
import socket
import sys
from pathlib import Path

from afo_mj.app.errors import InvalidInput

__all__ = ["viewer_command", "headless_problem"]


def viewer_command(rrd_path, web: bool = False) -> list[str]:
    """The command that opens ``rrd_path`` (InvalidInput unless it is an existing .rrd)."""
    p = Path(rrd_path)
    if p.suffix != ".rrd" or not p.is_file():
        raise InvalidInput(f"{str(p)!r} is not an existing .rrd file (write one with "
                           f"`afo-mj run SCENARIO --out DIR --rrd FILE.rrd`)")
    exe = shutil.which("rerun") or str(Path(sys.executable).with_name("rerun"))
    return [exe, "--serve-web", str(p)] if web else [exe, str(p)]


def headless_problem(rrd_path) -> str | None:
    """None where a viewer window can open (a display, or not Linux); otherwise the message
    with the two ways to see the file: rerun's web viewer (with the ssh port forwarding for
    a remote machine) or copying the file to a machine with a display."""
    if not sys.platform.startswith("linux") or os.environ.get("DISPLAY") \
            or os.environ.get("WAYLAND_DISPLAY"):
        return None
    p = Path(rrd_path)
    host = socket.gethostname()
    q = shlex.quote(str(p.resolve()))
    return (f"no display here (DISPLAY and WAYLAND_DISPLAY are unset), so the rerun viewer "
            f"cannot open a window. Either\n"
            f"  serve rerun's web viewer and open it in a browser:\n"
            f"    afo-mj view {q} --web      (runs `rerun --serve-web FILE`)\n"
            f"    then open http://localhost:9090 (from another machine, forward the web and "
            f"data ports first: ssh -L 9090:localhost:9090 -L 9876:localhost:9876 {host})\n"
            f"  or copy the recording to a machine with a display and open it there:\n"
            f"    scp {host}:{q} . && rerun {shlex.quote(p.name)}")
