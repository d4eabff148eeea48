"""Screenshots of a recording in rerun's web viewer (headless Chromium), at chosen moments of
its playback: to see, without a display, what `afo-mj view FILE --web` shows (the walkers
framed by the camera that follows them, the orthosis, the plots).

The recording opens playing (its blueprint), so the page is screenshot when the viewer's time
cursor first passes each requested time. Needs Chromium (Debian: apt-get install -y chromium);
nothing is downloaded.

Run: ``.venv/bin/python tools/recording_screenshot.py FILE.rrd OUT_PREFIX [T1 T2 ...]``
(times in seconds of the recording; default 1 6 11) → OUT_PREFIX_<t>s.png; the last line is a
JSON object with the files and the times at which they were taken.
"""

from __future__ import annotations

import json
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

import rerun_web as web  # noqa: E402


def screenshots(rrd, prefix, times_s=(1.0, 6.0, 11.0), timeout_s: float = 300.0,
                width: int = 1600, height: int = 1000) -> list[dict]:
    """PNG screenshots of ``rrd`` playing in the web viewer, one when the cursor first passes
    each of ``times_s``; returns ``[{"file", "requested_s", "cursor_s"}]``."""
    todo = sorted(float(t) for t in times_s)
    out = []
    with web.serve(rrd) as url, web.Browser(width, height) as b:
        b.call("Page.navigate", session=True, url=url)
        t0 = time.monotonic()
        while todo and time.monotonic() - t0 < timeout_s:
            cur = web.current_time_s(web.viewer_state(b))
            if cur is not None and cur >= todo[0]:
                f = Path(f"{prefix}_{todo[0]:g}s.png")
                b.screenshot(f)
                out.append({"file": str(f), "requested_s": todo.pop(0), "cursor_s": cur})
            time.sleep(0.05)
    if todo:
        raise SystemExit(f"the viewer's cursor did not reach {todo} s within {timeout_s:g} s")
    return out


if __name__ == "__main__":
    if len(sys.argv) < 3:
        raise SystemExit(__doc__)
    shots = screenshots(sys.argv[1], sys.argv[2], [float(x) for x in sys.argv[3:]] or
                        (1.0, 6.0, 11.0))
    print(json.dumps({"screenshots": shots}))
