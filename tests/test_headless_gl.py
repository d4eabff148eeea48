"""Headless OpenGL backend (issue 19 item 9): a plain ``afo-mj`` call on a machine without a
display picks EGL (or OSMesa) itself, before MuJoCo/dm_control is imported, and keeps a user's
own ``MUJOCO_GL``."""

from __future__ import annotations

import ctypes
import os
import subprocess
import sys
from pathlib import Path

import pytest

import afo_mj

ROOT = Path(__file__).resolve().parents[1]
_DISPLAY_VARS = ("DISPLAY", "WAYLAND_DISPLAY", "MUJOCO_GL", "PYOPENGL_PLATFORM")


def _loads(lib: str) -> bool:
    try:
        ctypes.CDLL(lib)
        return True
    except OSError:
        return False


def _headless_env(**extra) -> dict:
    env = {k: v for k, v in os.environ.items() if k not in _DISPLAY_VARS}
    env["PYTHONPATH"] = os.pathsep.join([str(ROOT)] + [p for p in [os.environ.get(
        "PYTHONPATH")] if p])
    env.update(extra)
    return env


def _python(code: str, env: dict) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-c", code], env=env, capture_output=True,
                          text=True, timeout=120, cwd=ROOT)


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="DISPLAY is X11/Linux")
def test_headless_import_picks_a_backend_without_glfw_warning():
    if not any(_loads(lib) for lib in ("libEGL.so.1", "libOSMesa.so.8", "libOSMesa.so.6")):
        pytest.skip("neither libEGL nor libOSMesa on this machine")
    # the walk imports dm_control.mujoco, which tries GLFW (and warns) when MUJOCO_GL is unset
    p = _python("import os, afo_mj.cli, dm_control.mujoco; print(os.environ.get('MUJOCO_GL'),"
                " os.environ.get('PYOPENGL_PLATFORM'))", _headless_env())
    assert p.returncode == 0, p.stderr
    assert "GLFW" not in p.stderr and "DISPLAY" not in p.stderr, p.stderr
    backend = p.stdout.split()
    assert backend[0] in ("egl", "osmesa") and backend[1] == backend[0]


def test_a_users_backend_is_kept():
    p = _python("import os, afo_mj; print(os.environ['MUJOCO_GL'], "
                "os.environ.get('PYOPENGL_PLATFORM'))", _headless_env(MUJOCO_GL="osmesa"))
    assert p.returncode == 0, p.stderr
    assert p.stdout.split() == ["osmesa", "None"]


@pytest.mark.parametrize("environ, platform, expect", [
    ({"DISPLAY": ":0"}, "linux", None),
    ({"WAYLAND_DISPLAY": "wayland-0"}, "linux", None),
    ({"MUJOCO_GL": "glfw"}, "linux", None),
    ({}, "darwin", None),
])
def test_no_change_with_a_display_or_a_choice(environ, platform, expect):
    env = dict(environ)
    assert afo_mj._choose_headless_gl(env, platform) is expect
    assert env == environ
