"""Opening a recording in rerun's viewer: ``afo-mj view``.

:func:`viewer_command` checks the file and builds the viewer command (the native viewer, or
``rerun --serve-web`` for rerun's web viewer, which works without a display);
:func:`headless_problem` says why a window cannot open here and how else to see the file.
"""

from __future__ import annotations

import os
import shlex
import shutil
import signal
import socket
import subprocess
import sys
from pathlib import Path

from afo_mj.app.errors import InvalidInput

__all__ = ["viewer_command", "headless_problem", "run_viewer"]

#: how long the viewer gets to exit after SIGTERM before it is killed (s)
VIEWER_STOP_GRACE_S = 3.0
_STOP_SIGNALS = tuple(s for s in (signal.SIGINT, signal.SIGTERM, getattr(signal, "SIGHUP", None))
                      if s is not None)


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


def run_viewer(cmd: list[str]) -> int:
    """Run the viewer ``cmd`` until it exits; its exit code. The viewer dies with this
    process: it runs in its own process group (``rerun`` is a Python wrapper that starts the
    native viewer or web server as its own child), and SIGINT, SIGTERM or SIGHUP here stops
    the whole group (SIGTERM, then SIGKILL after :data:`VIEWER_STOP_GRACE_S`) and returns
    128 + the signal's number (130 for Ctrl-C). Without this, a signal ended only this
    process and left ``rerun --serve-web`` serving, at full CPU, with no parent."""
    posix = os.name == "posix"
    proc = subprocess.Popen(cmd, start_new_session=posix)
    got: dict[str, int] = {}

    def stop(signum, frame):
        got.setdefault("signal", signum)
        raise KeyboardInterrupt

    in_main = _is_main_thread()
    old = {s: signal.getsignal(s) for s in _STOP_SIGNALS} if in_main else {}
    try:
        for s in old:
            signal.signal(s, stop)
        return proc.wait()
    except KeyboardInterrupt:
        got.setdefault("signal", signal.SIGINT)
        return 128 + int(got["signal"])
    finally:
        try:
            for s in old:                         # a second signal during the stop: ignored
                signal.signal(s, signal.SIG_IGN)
            _stop_group(proc, posix)
        finally:
            for s, h in old.items():
                signal.signal(s, h)


def _stop_group(proc: subprocess.Popen, posix: bool) -> None:
    """Stop the viewer and everything it started (its process group), if still running."""
    def send(sig):
        try:
            if posix:
                os.killpg(proc.pid, sig)
            else:
                proc.send_signal(sig)
        except (ProcessLookupError, PermissionError):
            pass
    if proc.poll() is None:
        send(signal.SIGTERM)
        try:
            proc.wait(timeout=VIEWER_STOP_GRACE_S)
        except subprocess.TimeoutExpired:
            send(signal.SIGKILL if posix else signal.SIGTERM)
            proc.wait()
    if posix:                  # the wrapper gone, its children (the server) may be left
        send(signal.SIGTERM)


def _is_main_thread() -> bool:
    import threading
    return threading.current_thread() is threading.main_thread()
