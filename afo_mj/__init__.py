"""afo_mj: human walking in MuJoCo with a hydraulic ankle-foot orthosis.

Layout (data flows one way): ``afo_mj.hydraulics`` (pure fluid-power physics, no MuJoCo) →
devices assembled from components → the MuJoCo bridge and controllers → scenarios → analysis →
outputs.

Importing the package picks a headless OpenGL backend (:func:`_choose_headless_gl`) before
MuJoCo or dm_control is imported, so that plain ``afo-mj`` calls on a machine without a display
neither warn about GLFW's missing ``DISPLAY`` nor fail to render.
"""

import os as _os
import sys as _sys

__version__ = "0.1.0"

#: Shared libraries that provide each headless backend, tried in this order.
_HEADLESS_GL = (("egl", ("libEGL.so.1", "libEGL.so")),
                ("osmesa", ("libOSMesa.so.8", "libOSMesa.so.6", "libOSMesa.so")))


def _choose_headless_gl(environ=_os.environ, platform: str = _sys.platform) -> str | None:
    """On Linux with neither ``DISPLAY`` nor ``WAYLAND_DISPLAY`` and no ``MUJOCO_GL`` of the
    user's, set ``MUJOCO_GL`` (and ``PYOPENGL_PLATFORM``, unless set) to the first headless
    backend whose library loads: EGL (GPU or Mesa), else OSMesa. A user's ``MUJOCO_GL`` is kept.
    Returns the backend chosen, or ``None`` when nothing was changed."""
    if not platform.startswith("linux") or environ.get("MUJOCO_GL"):
        return None
    if environ.get("DISPLAY") or environ.get("WAYLAND_DISPLAY"):
        return None
    import ctypes
    for backend, libraries in _HEADLESS_GL:
        for lib in libraries:
            try:
                ctypes.CDLL(lib)
            except OSError:
                continue
            environ["MUJOCO_GL"] = backend
            environ.setdefault("PYOPENGL_PLATFORM", backend)
            return backend
    return None


_choose_headless_gl()
