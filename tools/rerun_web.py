"""Rerun's web viewer in headless Chromium: serve a recording, open it, time the load, take a
screenshot. Used by ``benchmarks/recording.py`` and ``tools/recording_screenshot.py``.

Nothing here downloads anything: the web viewer is the one bundled in ``rerun-sdk`` (its
``rerun --serve-web FILE``, what ``afo-mj view FILE --web`` runs), the browser is the system's
Chromium (Debian: ``apt-get install chromium``), driven through the Chrome DevTools Protocol
over a pipe (``--remote-debugging-pipe``: NUL-terminated JSON messages on file descriptors 3
and 4), so no websocket or browser-automation package is needed.

Load time, as measured here: from the page's navigation until the viewer's own state (the
web handle's ``viewer_state()``: the ``GetStateResponse`` of rerun's viewer-control API,
protobuf) says that nothing is loading any more *and* that the recording's ``time`` timeline
reaches the last time logged. That is when every chunk of the file has been ingested by the
viewer's store: the plots are complete. The encoded state is read with a small generic
protobuf reader (field numbers only): a loading source is the only part of the state holding
the word ``Loading`` (its status line), and the timeline's end is a varint equal to the last
logged time in nanoseconds. A screenshot is taken at that moment too, so the measure can be
checked by eye.
"""

from __future__ import annotations

import base64
import contextlib
import json
import os
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import time
import urllib.parse
import urllib.request
from pathlib import Path

__all__ = ["chromium_path", "serve", "Browser", "open_and_time", "BrowserMissing"]


class BrowserMissing(RuntimeError):
    """No Chromium on this machine (``apt-get install -y chromium``)."""


def chromium_path() -> str:
    for name in ("chromium", "chromium-browser", "google-chrome", "chrome"):
        p = shutil.which(name)
        if p:
            return p
    raise BrowserMissing("no Chromium found (Debian: apt-get install -y chromium)")


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _rerun_exe() -> str:
    exe = Path(sys.executable).with_name("rerun")
    return str(exe) if exe.exists() else (shutil.which("rerun") or "rerun")


@contextlib.contextmanager
def serve_file(rrd_path):
    """The file over plain HTTP (with the CORS header the viewer's fetch needs), on a free
    port, from a thread; yields its URL."""
    import functools
    import http.server
    import threading
    p = Path(rrd_path).resolve()

    class Handler(http.server.SimpleHTTPRequestHandler):
        def end_headers(self):
            self.send_header("Access-Control-Allow-Origin", "*")
            super().end_headers()

        def log_message(self, *a):
            pass
    httpd = http.server.ThreadingHTTPServer(
        ("127.0.0.1", 0), functools.partial(Handler, directory=str(p.parent)))
    th = threading.Thread(target=httpd.serve_forever, daemon=True)
    th.start()
    try:
        yield f"http://127.0.0.1:{httpd.server_address[1]}/{urllib.parse.quote(p.name)}"
    finally:
        httpd.shutdown()
        httpd.server_close()


@contextlib.contextmanager
def serve(rrd_path=None, timeout_s: float = 60.0):
    """``rerun --serve-web FILE`` on free ports, in its own process group (stopped on exit);
    yields the viewer's URL (the web viewer with the file's gRPC proxy as its data source)."""
    web, grpc = _free_port(), _free_port()
    cmd = [_rerun_exe(), "--serve-web", "--web-viewer-port", str(web), "--port", str(grpc),
           "--bind", "127.0.0.1"] + ([str(rrd_path)] if rrd_path else [])
    log = tempfile.TemporaryFile()
    proc = subprocess.Popen(cmd, stdout=log, stderr=subprocess.STDOUT, start_new_session=True,
                            env={**os.environ, "RERUN_ANALYTICS": "0"})
    try:
        t0 = time.monotonic()
        while True:
            try:
                urllib.request.urlopen(f"http://127.0.0.1:{web}/", timeout=2).read(16)
                break
            except OSError:
                if proc.poll() is not None or time.monotonic() - t0 > timeout_s:
                    log.seek(0)
                    raise RuntimeError(f"rerun --serve-web did not start: "
                                       f"{log.read().decode(errors='replace')[-2000:]}")
                time.sleep(0.2)
        src = urllib.parse.quote(f"rerun+http://127.0.0.1:{grpc}/proxy", safe="")
        yield f"http://127.0.0.1:{web}/?url={src}&renderer=webgl"
    finally:
        with contextlib.suppress(ProcessLookupError):
            os.killpg(proc.pid, signal.SIGTERM)
        try:
            proc.wait(timeout=5)
        except subprocess.TimeoutExpired:
            with contextlib.suppress(ProcessLookupError):
                os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()
        log.close()


class Browser:
    """Headless Chromium driven over ``--remote-debugging-pipe``: one page, commands by
    :meth:`call` (a CDP method and its params; returns the result)."""

    def __init__(self, width: int = 1600, height: int = 1000):
        self._profile = tempfile.mkdtemp(prefix="afo_mj_chromium_")
        to_r, to_w = os.pipe()          # we write commands → Chromium reads fd 3
        from_r, from_w = os.pipe()      # Chromium writes fd 4 → we read
        args = [chromium_path(), "--headless=new", "--remote-debugging-pipe", "--no-sandbox",
                "--no-first-run", "--no-default-browser-check", "--disable-extensions",
                "--disable-background-networking", "--disable-component-update",
                "--use-angle=swiftshader", "--enable-unsafe-swiftshader",
                "--ignore-gpu-blocklist", f"--window-size={width},{height}",
                f"--user-data-dir={self._profile}", "about:blank"]

        def child_fds():
            os.dup2(to_r, 3)
            os.dup2(from_w, 4)
        self._proc = subprocess.Popen(args, pass_fds=(3, 4), preexec_fn=child_fds,
                                      stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                                      start_new_session=True)
        os.close(to_r)
        os.close(from_w)
        self._w = os.fdopen(to_w, "wb", buffering=0)
        self._r = os.fdopen(from_r, "rb", buffering=0)
        self._buf = b""
        self._id = 0
        self.events: list[dict] = []
        targets = self.call("Target.getTargets")["targetInfos"]
        page = next(t for t in targets if t["type"] == "page")
        self._session = self.call("Target.attachToTarget", targetId=page["targetId"],
                                  flatten=True)["sessionId"]
        self.call("Emulation.setDeviceMetricsOverride", session=True, width=width,
                  height=height, deviceScaleFactor=1, mobile=False)
        self.call("Page.enable", session=True)

    def _read_message(self) -> dict:
        while b"\0" not in self._buf:
            chunk = self._r.read(1 << 20)
            if not chunk:
                raise RuntimeError("Chromium closed the DevTools pipe")
            self._buf += chunk
        msg, self._buf = self._buf.split(b"\0", 1)
        return json.loads(msg)

    def call(self, method: str, session: bool = False, **params):
        self._id += 1
        msg = {"id": self._id, "method": method, "params": params}
        if session:
            msg["sessionId"] = self._session
        self._w.write(json.dumps(msg).encode() + b"\0")
        while True:
            m = self._read_message()
            if m.get("id") == self._id:
                if "error" in m:
                    raise RuntimeError(f"{method}: {m['error']}")
                return m.get("result", {})
            self.events.append(m)

    def evaluate(self, expression: str):
        r = self.call("Runtime.evaluate", session=True, expression=expression,
                      returnByValue=True, awaitPromise=True)
        if "exceptionDetails" in r:
            raise RuntimeError(f"{expression!r}: {r['exceptionDetails']}")
        return r["result"].get("value")

    def screenshot(self, path) -> None:
        data = self.call("Page.captureScreenshot", session=True, format="png")["data"]
        Path(path).write_bytes(base64.b64decode(data))

    def close(self) -> None:
        with contextlib.suppress(Exception):
            self._w.write(json.dumps({"id": self._id + 1, "method": "Browser.close"}).encode()
                          + b"\0")
        try:
            self._proc.wait(timeout=5)
        except subprocess.TimeoutExpired:
            with contextlib.suppress(ProcessLookupError):
                os.killpg(self._proc.pid, signal.SIGKILL)
            self._proc.wait()
        for f in (self._w, self._r):
            with contextlib.suppress(Exception):
                f.close()
        shutil.rmtree(self._profile, ignore_errors=True)

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


# -- the viewer's state: a generic protobuf reader ----------------------------------------------
def _varint(b: bytes, i: int) -> tuple[int, int]:
    v = shift = 0
    while True:
        x = b[i]
        i += 1
        v |= (x & 0x7F) << shift
        shift += 7
        if not x & 0x80:
            return v, i


def _pb_fields(b: bytes):
    """(field number, wire type, value) of one protobuf message; raises on malformed input."""
    i = 0
    while i < len(b):
        key, i = _varint(b, i)
        num, wt = key >> 3, key & 7
        if wt == 0:
            v, i = _varint(b, i)
        elif wt == 1:
            v, i = b[i:i + 8], i + 8
        elif wt == 2:
            n, i = _varint(b, i)
            v, i = b[i:i + n], i + n
        elif wt == 5:
            v, i = b[i:i + 4], i + 4
        else:
            raise ValueError("not a protobuf message")
        if i > len(b) or num == 0:
            raise ValueError("not a protobuf message")
        yield num, wt, v


def _pb_varints(b: bytes, depth: int = 0) -> set[int]:
    """Every varint in a message and, recursively, in its length-delimited fields that parse
    as messages."""
    out: set[int] = set()
    try:
        fields = list(_pb_fields(b))
    except (ValueError, IndexError):
        return out
    for _num, wt, v in fields:
        if wt == 0:
            out.add(v)
        elif wt == 2 and depth < 8:
            out |= _pb_varints(v, depth + 1)
    return out


#: the timeline of the end marker (:func:`with_end_marker`)
MARKER_TIMELINE = "zz_loaded_marker"


def with_end_marker(rrd_path, out_path) -> Path:
    """A copy of the recording with one more chunk at its end, on a timeline of its own
    (:data:`MARKER_TIMELINE`, same recording id): rrd streams concatenate, and the viewer
    ingests a stream in order, so the viewer's state lists that timeline only once every
    chunk before it is in its store."""
    import rerun as rr
    rrd_path, out_path = Path(rrd_path), Path(out_path)
    (entry,) = rr.chunk.RrdReader(str(rrd_path)).recordings()
    marker = out_path.with_name(out_path.name + ".marker.rrd")
    stream = rr.RecordingStream(entry.application_id, recording_id=entry.recording_id)
    stream.save(str(marker))
    stream.set_time(MARKER_TIMELINE, sequence=1)
    stream.log("loaded_marker", rr.TextLog("end of the recording"))
    stream.flush()
    stream.disconnect()
    out_path.write_bytes(rrd_path.read_bytes() + marker.read_bytes())
    marker.unlink()
    return out_path


def _pb_first(b: bytes, num: int):
    for n, _wt, v in _pb_fields(b):
        if n == num:
            return v
    return None


def current_time_s(state: bytes | None) -> float | None:
    """The time cursor of the active recording in an encoded viewer state [s], or None.
    (``GetStateResponse``: field 3 the recordings; in one, field 3 the cursor: its timeline
    (1), kind (2) and time (3: field 1, nanoseconds on a duration timeline).)"""
    if not state:
        return None
    try:
        for n, wt, rec in _pb_fields(state):
            if n != 3 or wt != 2:
                continue
            cur = _pb_first(rec, 3)
            if cur is None:
                continue
            at = _pb_first(cur, 3)
            if at is None:
                continue
            ns = _pb_first(at, 1)
            return 0.0 if ns is None else ns / 1e9
    except (ValueError, IndexError):
        return None
    return None


def viewer_state(browser: Browser) -> bytes | None:
    """The encoded viewer state, or None before the viewer has started."""
    v = browser.evaluate("window._handle ? Array.from(window._handle.viewer_state()) : null")
    return None if v is None else bytes(v)


def open_and_time(url: str, screenshot=None, timeout_s: float = 600.0,
                  poll_s: float = 0.1, width: int = 1600, height: int = 1000) -> dict:
    """Open ``url`` in headless Chromium and time the load (see the module's docstring):
    ``{"started_s": the viewer running, "loaded_s": every chunk ingested, "timed_out", ...}``,
    seconds from the navigation, and the page's main-thread CPU time by then (``script_cpu_s``:
JavaScript and WebAssembly; ``task_cpu_s``: every task, drawing included) from Chromium's
``Performance.getMetrics``. ``screenshot``: a PNG path written once loaded."""
    with Browser(width, height) as b:
        b.call("Performance.enable", session=True)
        t0 = time.monotonic()
        b.call("Page.navigate", session=True, url=url)
        started = loaded = None
        while time.monotonic() - t0 < timeout_s:
            state = viewer_state(b)
            now = time.monotonic() - t0
            if state is not None and started is None:
                started = now
            if state is not None and MARKER_TIMELINE.encode() in state:
                loaded = now
                break
            time.sleep(poll_s)
        # the page's own CPU time (main thread: script, incl. the viewer's WebAssembly, and
        # every task), less blurred by other load on the machine than the wall-clock time
        m = {x["name"]: x["value"] for x in
             b.call("Performance.getMetrics", session=True)["metrics"]}
        if screenshot is not None:
            time.sleep(1.0)                 # a frame or two drawn with everything in
            b.screenshot(screenshot)
        return {"started_s": started, "loaded_s": loaded, "timed_out": loaded is None,
                "script_cpu_s": m.get("ScriptDuration"), "task_cpu_s": m.get("TaskDuration")}
