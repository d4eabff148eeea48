"""Offscreen MP4 video of a walk, with the ankle torque drawn over it (``afo-mj render``).

What is rendered: the walker of a :class:`~afo_mj.gait.record.GaitRecord` replayed from its
generalised positions (``record.qpos``, one row per sample, on the compiled model
``record.model_xml``), at ``fps`` frames per second of *simulated* time (real-time playback:
frame ``k`` shows the sample nearest ``time_s[0] + k / fps``). Rendering is offscreen through
MuJoCo's :class:`mujoco.Renderer` (``MUJOCO_GL=egl`` unless the caller chose another backend
before MuJoCo was imported); frames are encoded one at a time with PyAV (H.264 ``libx264``,
``yuv420p``; MPEG-4 part 2 if the FFmpeg build has no H.264 encoder), so memory stays flat
whatever the length of the walk.

Camera: a free camera looking at the sagittal (x-z) plane from the walker's right side
(azimuth 90 deg: the camera looks along +y, the lateral axis, so the walker walks left to
right with its right leg nearest), 6 deg above horizontal, at a distance of 1.85 x stature. It
follows the pelvis forward position (x, moving average over 1 s so the gait's speed
fluctuations do not shake the picture) at a fixed height. For legibility only (the record's
kinematics are untouched): the far (left) leg is drawn a shade darker than the near (right)
one, the feet's 1 cm visual capsules are thickened to 2.2 cm, device-attachment sites are
hidden, a light gradient sky is added and the floor checker is drawn in 0.5 m squares.

Overlay:

* at each ankle that wears the orthosis, a disc in the sagittal plane centred on the ankle
  axis whose radius grows with the orthosis torque |tau| (a faint ring marks full scale:
  ``max(40 N·m, peak |tau| of the run)``) and whose colour gives its direction (orange =
  plantarflexion, blue = dorsiflexion), and an arrow along the disc's top edge showing which
  way the torque turns the foot (forward = clockwise in this view = plantarflexion, length
  proportional to |tau|);
* a strip along the bottom of the frame (22 % of its height, on a darkened panel): the last
  2 s of the orthosis torque (orange) and of the human (muscle) net ankle moment (light blue)
  of the first worn ankle (right ankle without a device), N·m, plotted with **+ =
  plantarflexion** upward (the biomechanics convention of ``gait_curves.png``; the record's
  own sign is + dorsiflexion), a grey zero line, the y-range printed at the left, and a thin
  bar along the strip's top edge showing how far through the video the frame is. The y-range
  is fixed for the whole video (both signals over the whole run, 10 % margin). The legend and
  the scenario / condition label are drawn once with matplotlib (frames at least 240 px wide).

Functions: :func:`render_record` (a record to an MP4), :func:`render_frames` (a few frames in
memory), :func:`check_render_options`. This module only renders and writes: loading and
simulating a scenario is :func:`afo_mj.app.render.render` (what ``afo-mj render`` calls).
The MP4 is written atomically (a temporary file in the target directory, then
:func:`os.replace`): a failed render leaves no partial file. Bad arguments raise
:class:`RenderError` (a :class:`ValueError`) naming the key, the value and what is allowed.
"""

from __future__ import annotations

import math
import os
import tempfile
from pathlib import Path
from typing import Callable, Sequence

import numpy as np

__all__ = ["RenderError", "render_record", "render_frames", "check_render_options",
           "choose_gl", "FPS_RANGE", "SIZE_RANGE"]

FPS_RANGE = (1, 240)
SIZE_RANGE = (16, 3840)
STRIP_FRACTION = 0.22          # bottom strip height / frame height
STRIP_WINDOW_S = 2.0           # time shown in the strip
TORQUE_FULL_SCALE_NM = 40.0    # disc full scale, at least
CAMERA_DISTANCE_PER_STATURE = 1.85
CAMERA_ELEVATION_DEG = -6.0
CAMERA_SMOOTHING_S = 1.0

_SIDES = ("right", "left")
_ORANGE = np.array([245, 130, 30], np.uint8)
_BLUE = np.array([120, 190, 255], np.uint8)
_GREY = np.array([150, 150, 150], np.uint8)
_PLANTAR_RGBA = (0.96, 0.45, 0.08, 0.65)
_DORSI_RGBA = (0.15, 0.45, 1.0, 0.65)


class RenderError(ValueError):
    """A render request that cannot be carried out; the message names the key and value."""


#: MUJOCO_GL as the user set it (None: unset, so this module chooses EGL)
_USER_GL = os.environ.get("MUJOCO_GL")
os.environ.setdefault("MUJOCO_GL", "egl")


def _mujoco():
    """Import MuJoCo, choosing the EGL offscreen backend unless one was chosen already."""
    os.environ.setdefault("MUJOCO_GL", "egl")
    import mujoco
    return mujoco


def _make_renderer(mj, model, height: int, width: int):
    """``mujoco.Renderer``. Without a display, when MuJoCo was imported before MUJOCO_GL was
    set (it then picks GLFW, which needs one) and the user chose no backend, MuJoCo's EGL
    context is used instead."""
    if _USER_GL is None and not os.environ.get("DISPLAY"):
        try:
            from mujoco.egl import GLContext as EglContext
            from mujoco.rendering.classic import gl_context
            if getattr(gl_context, "GLContext", None) is not EglContext:
                gl_context.GLContext = EglContext
        except Exception:  # noqa: BLE001 -- leave MuJoCo's own choice
            pass
    try:
        return mj.Renderer(model, height, width)
    except Exception as exc:  # noqa: BLE001 -- GL/EGL failures come in many types
        first = exc
    raise RenderError(
        f"no offscreen OpenGL context could be created (MUJOCO_GL="
        f"{_USER_GL if _USER_GL is not None else 'egl (default)'}; {type(first).__name__}: "
        f"{first}); allowed: MUJOCO_GL=egl (GPU or Mesa EGL) or MUJOCO_GL=osmesa, set before "
        "MuJoCo is imported") from None


# --------------------------------------------------------------------------- validation

def _check_int(key: str, value, lo: int, hi: int, even: bool = False) -> int:
    ok = isinstance(value, (int, np.integer)) and not isinstance(value, bool)
    if not ok and isinstance(value, float) and value.is_integer():
        value, ok = int(value), True
    if not ok or not lo <= value <= hi:
        raise RenderError(f"{key} = {value!r} is not allowed; allowed: an integer "
                          f"{lo}..{hi}" + (", even" if even else ""))
    if even and value % 2:
        raise RenderError(f"{key} = {value!r} is not allowed; allowed: an even integer "
                          f"{lo}..{hi} (the video is yuv420p)")
    return int(value)


def _check_max_seconds(max_seconds) -> float | None:
    if max_seconds is None:
        return None
    try:
        v = float(max_seconds)
    except (TypeError, ValueError):
        v = float("nan")
    if not (math.isfinite(v) and v > 0):
        raise RenderError(f"max_seconds = {max_seconds!r} is not allowed; allowed: a number "
                          "of seconds > 0, or None for the whole walk")
    return v


def check_render_options(fps, width, height, max_seconds) -> None:
    """Raise :class:`RenderError` unless :func:`render_record` accepts these options (what
    :func:`afo_mj.app.render.render` checks before simulating)."""
    _check_int("fps", fps, *FPS_RANGE)
    _check_int("width", width, *SIZE_RANGE, even=True)
    _check_int("height", height, *SIZE_RANGE, even=True)
    _check_max_seconds(max_seconds)


def choose_gl() -> None:
    """Choose the offscreen GL backend (EGL unless the user chose one) and import MuJoCo; call
    before anything else imports MuJoCo."""
    _mujoco()


def _check_record(record) -> None:
    if getattr(record, "qpos", None) is None or getattr(record, "model_xml", None) is None:
        raise RenderError("record.qpos / record.model_xml = None is not allowed; allowed: a "
                          "GaitRecord from run_walk, which keeps the positions and the model")
    if len(record.time_s) < 1 or len(record.qpos) != len(record.time_s):
        raise RenderError(f"record.qpos has {len(record.qpos)} rows for "
                          f"{len(record.time_s)} samples; allowed: one row per sample (>= 1)")


def _sides_index(device_sides) -> tuple[int, ...]:
    out = []
    for s in device_sides:
        if s in (0, 1):
            out.append(int(s))
        elif s in _SIDES:
            out.append(_SIDES.index(s))
        else:
            raise RenderError(f"device_sides entry {s!r} is not allowed; allowed: "
                              "'right', 'left' (or 0, 1)")
    return tuple(sorted(set(out)))


# --------------------------------------------------------------------------- the renderer

def _smooth(x: np.ndarray, n: int) -> np.ndarray:
    """Centred moving average over ``n`` samples, edges padded with the end values."""
    if n <= 1 or len(x) < 3:
        return x.astype(float)
    n = min(n, len(x))
    pad = np.concatenate([np.full(n // 2, x[0]), x, np.full(n - 1 - n // 2, x[-1])])
    c = np.cumsum(np.concatenate([[0.0], pad]))
    return (c[n:] - c[:-n]) / n


def _text_layer(width: int, height: int, items,
                fontsize_pt: float) -> tuple[np.ndarray, np.ndarray]:
    """RGB and alpha (float, 0..1) of text drawn once with matplotlib's Agg backend.

    ``items``: (x_px, y_px from top, text, rgb 0..1, ha, va)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure
    dpi = 100.0
    fig = Figure(figsize=(width / dpi, height / dpi), dpi=dpi)
    fig.patch.set_alpha(0.0)
    FigureCanvasAgg(fig)
    for x, y, text, rgb, ha, va in items:
        fig.text(x / width, 1.0 - y / height, text, color=rgb, ha=ha, va=va,
                 fontsize=fontsize_pt, family="DejaVu Sans")
    fig.canvas.draw()
    rgba = np.asarray(fig.canvas.buffer_rgba())[:height, :width].astype(np.float32)
    return rgba[..., :3], rgba[..., 3:] / 255.0


def _compile_for_video(mj, xml: str):
    """The record's model with a light sky added (a gradient skybox) and the floor's checker
    rescaled to 0.5 m squares, so that the walker's progress shows against the floor."""
    try:
        spec = mj.MjSpec.from_string(xml)
    except Exception as exc:  # noqa: BLE001 -- any parse error is a bad record
        raise RenderError(f"record.model_xml does not compile ({exc})") from None
    try:
        spec.add_texture(name="video_sky", type=mj.mjtTexture.mjTEXTURE_SKYBOX,
                         builtin=mj.mjtBuiltin.mjBUILTIN_GRADIENT, rgb1=[0.78, 0.87, 0.96],
                         rgb2=[0.98, 0.98, 1.0], width=256, height=1536)
        m = spec.compile()
    except Exception:  # noqa: BLE001 -- cosmetic only: fall back to the model as recorded
        try:
            m = mj.MjModel.from_xml_string(xml)
        except Exception as exc:  # noqa: BLE001
            raise RenderError(f"record.model_xml does not compile ({exc})") from None
    for g in range(m.ngeom):
        mat = m.geom_matid[g]
        if m.geom_type[g] == mj.mjtGeom.mjGEOM_PLANE and mat >= 0 and m.geom_size[g, 0] > 0:
            m.mat_texrepeat[mat] = [m.geom_size[g, 0] * 2 / 0.5, m.geom_size[g, 1] * 2 / 0.5]
            m.mat_texuniform[mat] = 0
    return m


class _WalkRenderer:
    """Model, data, offscreen renderer and precomputed overlay for one record."""

    def __init__(self, record, width: int, height: int, device_sides=None, label: str = ""):
        _check_record(record)
        self.mj = mj = _mujoco()
        self.rec = record
        self.w, self.h = int(width), int(height)
        self.model = m = _compile_for_video(mj, record.model_xml)
        m.vis.global_.offwidth = max(int(m.vis.global_.offwidth), self.w)
        m.vis.global_.offheight = max(int(m.vis.global_.offheight), self.h)
        m.vis.quality.shadowsize = 2048
        for i in range(m.ngeom):       # far (left) leg a shade darker than the near one
            body = m.body(m.geom_bodyid[i]).name
            if body.endswith("_l") and body.split("_")[0] in ("thigh", "shank", "foot"):
                m.geom_rgba[i, :3] *= 0.72
        for i in range(m.ngeom):       # the 1 cm foot capsule is hard to see on video
            if m.body(m.geom_bodyid[i]).name.startswith("foot_") and \
                    m.geom_type[i] == mj.mjtGeom.mjGEOM_CAPSULE:
                m.geom_size[i, 0] = max(m.geom_size[i, 0], 0.022)
        self.opt = mj.MjvOption()
        self.opt.sitegroup[:] = 0      # no device-attachment sites
        self.data = mj.MjData(m)
        self.renderer = _make_renderer(mj, m, self.h, self.w)

        t = np.asarray(record.time_s, float)
        self.t = t
        self.dt = float(record.sample_period_s)
        dev = np.asarray(record.device_moment_nm, float)
        self.sides = (_sides_index(device_sides) if device_sides is not None else
                      tuple(s for s in (0, 1) if np.any(dev[:, s] != 0.0)))
        self.plot_side = self.sides[0] if self.sides else 0
        self.ankle_jnt = [m.joint(f"ankle_{s[0]}").id for s in _SIDES]
        self.ankle_y = [float(self._ankle_y(s)) for s in (0, 1)]
        # plotted signals, + plantarflexion (the negative of the record's sign)
        self.dev_sig = -dev[:, self.plot_side] if self.sides else None
        self.hum_sig = -np.asarray(record.joint_moment_nm, float)[:, self.plot_side, 2]
        peak = float(np.max(np.abs(dev[:, list(self.sides)]))) if self.sides else 0.0
        self.full_scale = max(TORQUE_FULL_SCALE_NM, peak)
        self.dev_nm = dev

        # camera: follows the smoothed pelvis x at a fixed height
        px = np.asarray(record.qpos, float)[:, 0] + float(m.body("pelvis").pos[0])
        self.cam_x = _smooth(px, int(round(CAMERA_SMOOTHING_S / max(self.dt, 1e-9))))
        stature = float(getattr(record, "height_m", 1.75) or 1.75)
        self.cam = mj.MjvCamera()
        self.cam.type = mj.mjtCamera.mjCAMERA_FREE
        self.cam.azimuth = 90.0
        self.cam.elevation = CAMERA_ELEVATION_DEG
        self.cam.distance = CAMERA_DISTANCE_PER_STATURE * stature
        self.cam_z = 0.36 * stature
        self._overlay_setup(label)

    def _ankle_y(self, side: int) -> float:
        mj, m, d = self.mj, self.model, self.data
        d.qpos[:] = self.rec.qpos[0]
        mj.mj_kinematics(m, d)
        return d.xanchor[self.ankle_jnt[side], 1]

    # ---- 2D overlay (numpy) ----
    def _overlay_setup(self, label: str) -> None:
        w, h = self.w, self.h
        hs = max(8, int(round(STRIP_FRACTION * h)))
        self.strip_h = hs
        self.text = w >= 240 and hs >= 40
        fs = float(np.clip(h / 60.0, 6.0, 28.0))          # font size, pt at 100 dpi
        line = int(round(fs * 100 / 72 * 1.45))              # text line height, px
        top = line + 3 if self.text else 3
        self.left = int(round(fs * 100 / 72 * 3.6)) if self.text else 2
        self.plot_top, self.plot_bot = top, hs - 3
        sigs = [self.hum_sig] + ([self.dev_sig] if self.dev_sig is not None else [])
        lo = min(0.0, min(float(np.min(s)) for s in sigs))
        hi = max(0.0, max(float(np.max(s)) for s in sigs))
        span = max(hi - lo, 2.0)
        self.y_lo, self.y_hi = lo - 0.1 * span, hi + 0.1 * span
        self.label_layer = self.strip_layer = None
        if not self.text:
            return
        side = _SIDES[self.plot_side]
        wide = w >= 560
        grey = (0.85, 0.85, 0.85)
        items = [(self.left, 1, "\u2501 orthosis torque" if wide else "\u2501 orthosis",
                  _ORANGE / 255, "left", "top") if self.sides else
                 (self.left, 1, "no orthosis", (0.8, 0.8, 0.8), "left", "top"),
                 (self.left + (0.30 if wide else 0.27) * w, 1,
                  "\u2501 human ankle moment" if wide else "\u2501 human", _BLUE / 255,
                  "left", "top"),
                 (w - 4, 1, f"{side} ankle, N\u00b7m (+ plantarflexion), last "
                  f"{STRIP_WINDOW_S:g} s" if wide else f"{side} ankle N\u00b7m, +PF",
                  grey, "right", "top"),
                 (self.left - 3, self.plot_top, f"{self.y_hi:+.0f}", grey, "right", "top"),
                 (self.left - 3, self.plot_bot, f"{self.y_lo:+.0f}", grey, "right", "bottom")]
        zero_row = float(self._row(0.0))
        if min(zero_row - self.plot_top, self.plot_bot - zero_row) > 1.2 * line:
            items.append((self.left - 3, zero_row, "0", grey, "right", "center"))
        self.strip_layer = _text_layer(w, hs, items, fs)
        if label:
            lh = line + 6
            self.label_layer = _text_layer(w, lh, [(6, 3, label, (0.1, 0.1, 0.1), "left",
                                                    "top")], fs)

    def _row(self, v):
        a = (np.asarray(v, float) - self.y_lo) / (self.y_hi - self.y_lo)
        return self.plot_bot - a * (self.plot_bot - self.plot_top)

    def _draw_strip(self, img: np.ndarray, t: float, progress: float) -> None:
        w, hs = self.w, self.strip_h
        strip = img[self.h - hs:].astype(np.float32)
        strip *= 0.25                                        # darkened panel
        strip += 0.75 * 20.0
        if self.strip_layer is not None:
            rgb, a = self.strip_layer
            strip[:] = strip * (1 - a) + rgb * a
        x0 = self.left
        cols = np.arange(x0, w)
        rows = np.arange(hs)[:, None]
        zero = int(round(float(self._row(0.0))))
        strip[zero, x0:] = _GREY
        strip[0:2, :max(1, int(round(progress * w)))] = (200, 200, 200)
        ts = t - STRIP_WINDOW_S * (1.0 - (cols - x0) / max(1, w - 1 - x0))
        valid = ts >= self.t[0] - 1e-9
        for sig, colour in ((self.hum_sig, _BLUE), (self.dev_sig, _ORANGE)):
            if sig is None:
                continue
            y = self._row(np.interp(ts, self.t, sig))
            yp = np.concatenate([[y[0]], y[:-1]])
            lo = np.minimum(y, yp) - 0.9
            hi = np.maximum(y, yp) + 0.9
            mask = (rows >= lo[None, :]) & (rows <= hi[None, :]) & valid[None, :]
            sub = strip[:, x0:]
            sub[mask] = colour
        img[self.h - hs:] = np.clip(strip, 0, 255).astype(np.uint8)
        if self.label_layer is not None:
            rgb, a = self.label_layer
            lh = rgb.shape[0]
            top = img[:lh].astype(np.float32)
            img[:lh] = (top * (1 - a) + rgb * a).astype(np.uint8)

    # ---- 3D overlay (scene geoms) ----
    def _add_geom(self, gtype, size, pos, mat, rgba):
        mj, scene = self.mj, self.renderer.scene
        if scene.ngeom >= scene.maxgeom:
            return None
        g = scene.geoms[scene.ngeom]
        mj.mjv_initGeom(g, gtype, np.asarray(size, float), np.asarray(pos, float),
                        np.asarray(mat, float).ravel(), np.asarray(rgba, np.float32))
        scene.ngeom += 1
        return g

    def _draw_torque(self, i: int) -> None:
        mj = self.mj
        # cylinder axis (local z) along the lateral y axis: a disc in the sagittal plane
        mat = np.array([[1, 0, 0], [0, 0, -1], [0, 1, 0]], float)
        for s in self.sides:
            tau = float(self.dev_nm[i, s])
            frac = min(1.0, abs(tau) / self.full_scale)
            c = self.data.xanchor[self.ankle_jnt[s]].copy()
            c[1] = self.ankle_y[s] - 0.075                  # on the camera side of the ankle
            r_full = 0.08
            self._add_geom(mj.mjtGeom.mjGEOM_CYLINDER, [r_full, 0.002, 0], c + [0, 0.004, 0],
                           mat, (0.2, 0.2, 0.2, 0.3))
            if frac < 0.01:
                continue
            rgba = _PLANTAR_RGBA if tau < 0 else _DORSI_RGBA
            r = 0.015 + (r_full - 0.015) * frac
            self._add_geom(mj.mjtGeom.mjGEOM_CYLINDER, [r, 0.004, 0], c, mat, rgba)
            # along the top of the disc: forward = clockwise in this view = toes down
            # (plantarflexion), backward = dorsiflexion. MuJoCo draws an arrow geom
            # size[2] / 2 long (shaft to size[2] / 3, head to size[2] / 2) along local z.
            ln = 0.03 + 0.12 * frac
            fwd = tau < 0
            arrow_mat = (np.array([[0, 0, 1], [0, 1, 0], [-1, 0, 0]], float) if fwd else
                         np.array([[0, 0, -1], [0, 1, 0], [1, 0, 0]], float))
            start = c + [-0.5 * ln if fwd else 0.5 * ln, -0.01, r + 0.018]
            self._add_geom(mj.mjtGeom.mjGEOM_ARROW, [0.012, 0.012, 2.0 * ln], start,
                           arrow_mat, rgba[:3] + (1.0,))

    # ---- frames ----
    def sample_index(self, t: float) -> int:
        i = int(round(float(np.interp(t, self.t, np.arange(len(self.t))))))
        return min(max(i, 0), len(self.t) - 1)

    def frame(self, t: float, progress: float = 0.0) -> np.ndarray:
        mj, m, d = self.mj, self.model, self.data
        i = self.sample_index(t)
        d.qpos[:] = self.rec.qpos[i]
        d.qvel[:] = 0.0
        mj.mj_forward(m, d)
        self.cam.lookat[:] = (self.cam_x[i], 0.0, self.cam_z)
        self.renderer.update_scene(d, self.cam, scene_option=self.opt)
        self._draw_torque(i)
        img = np.array(self.renderer.render(), copy=True)
        self._draw_strip(img, float(self.t[i]), progress)
        return img

    def close(self) -> None:
        r = getattr(self, "renderer", None)
        if r is not None:
            try:
                r.close()
            except Exception:  # noqa: BLE001 -- teardown of a GL context is best effort
                pass
            self.renderer = None


def _frame_times(record, fps: int, max_seconds: float | None) -> np.ndarray:
    t0, t1 = float(record.time_s[0]), float(record.time_s[-1])
    if max_seconds is not None:
        t1 = min(t1, t0 + max_seconds)
    n = int(math.floor((t1 - t0) * fps + 1e-9)) + 1
    return t0 + np.arange(n) / fps


def render_frames(record, times_s: Sequence[float], width: int = 640, height: int = 480,
                  device_sides=None, label: str = "") -> np.ndarray:
    """Frames of ``record`` at the simulated times ``times_s`` [s] (nearest sample), as a
    ``(k, height, width, 3)`` uint8 RGB array, with the same camera and overlay as the video.

    ``device_sides``: ankles wearing the orthosis ('right'/'left'); None = those whose
    ``device_moment_nm`` is not identically zero. ``label`` is printed top-left."""
    width = _check_int("width", width, *SIZE_RANGE)
    height = _check_int("height", height, *SIZE_RANGE)
    times = np.atleast_1d(np.asarray(times_s, float))
    if times.ndim != 1 or not np.all(np.isfinite(times)):
        raise RenderError(f"times_s = {times_s!r} is not allowed; allowed: finite times [s]")
    wr = _WalkRenderer(record, width, height, device_sides, label)
    try:
        out = np.empty((len(times), height, width, 3), np.uint8)
        span = max(float(record.time_s[-1] - record.time_s[0]), 1e-9)
        for k, t in enumerate(times):
            out[k] = wr.frame(float(t), (float(t) - float(record.time_s[0])) / span)
        return out
    finally:
        wr.close()


def _open_stream(container, fps: int, width: int, height: int):
    import av
    for codec in ("libx264", "h264", "mpeg4"):
        try:
            av.codec.Codec(codec, "w")
        except Exception:  # noqa: BLE001 -- encoder missing from this FFmpeg build
            continue
        stream = container.add_stream(codec, rate=fps)
        stream.width, stream.height, stream.pix_fmt = width, height, "yuv420p"
        if codec in ("libx264", "h264"):
            stream.options = {"crf": "20", "preset": "medium"}
        else:
            stream.bit_rate = max(1_000_000, width * height * fps // 4)
        return stream, ("h264" if codec != "mpeg4" else "mpeg4")
    raise RenderError("this FFmpeg build (PyAV) has neither an H.264 nor an MPEG-4 encoder")


def render_record(record, mp4_path, fps: int = 30, width: int = 640, height: int = 480,
                  max_seconds: float | None = None,
                  progress: Callable[[int, int], None] | None = None,
                  device_sides=None, label: str = "") -> dict:
    """Render ``record`` to an MP4 at ``mp4_path`` (written atomically) and return
    ``{"frames", "fps", "width", "height", "duration_s", "codec", "path"}``.

    ``fps`` 1..240 frames per second of simulated time; ``width``/``height`` even, 16..3840
    px; ``max_seconds`` renders only the first seconds of the walk; ``progress(done, total)``
    is called after each encoded frame; ``device_sides``/``label`` as in :func:`render_frames`.
    """
    fps = _check_int("fps", fps, *FPS_RANGE)
    width = _check_int("width", width, *SIZE_RANGE, even=True)
    height = _check_int("height", height, *SIZE_RANGE, even=True)
    max_seconds = _check_max_seconds(max_seconds)
    _check_record(record)
    path = Path(mp4_path)
    if path.suffix.lower() != ".mp4":
        raise RenderError(f"mp4 path = {str(path)!r} is not allowed; allowed: a file name "
                          "ending in .mp4")
    if path.is_dir():
        raise RenderError(f"mp4 path = {str(path)!r} is a directory; allowed: a file name")
    times = _frame_times(record, fps, max_seconds)
    import av

    from afo_mj import progress as _progress
    wr = _WalkRenderer(record, width, height, device_sides, label)
    task = _progress.reporter().task(f"rendering {len(times)} frames to {path}",
                                     len(times), "frames", fmt=lambda v: f"{v:.0f}")
    tmp = None
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(prefix=f".{path.stem}.", suffix=".part.mp4",
                                   dir=path.parent)
        os.close(fd)
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(tmp, 0o666 & ~umask)          # mkstemp makes it 0600; keep the usual mode
        with av.open(tmp, "w", format="mp4") as container:
            stream, codec = _open_stream(container, fps, width, height)
            n = len(times)
            for k, t in enumerate(times):
                img = wr.frame(float(t), (k + 1) / n)
                frame = av.VideoFrame.from_ndarray(img, format="rgb24")
                for packet in stream.encode(frame):
                    container.mux(packet)
                if progress is not None:
                    progress(k + 1, n)
                task.update(k + 1)
            for packet in stream.encode():
                container.mux(packet)
        os.replace(tmp, path)
        tmp = None
        task.close()
    finally:
        task.abort()                    # no-op after close: ends an in-place line on error
        wr.close()
        if tmp is not None:
            try:
                os.unlink(tmp)
            except OSError:
                pass
    return {"frames": len(times), "fps": fps, "width": width, "height": height,
            "duration_s": len(times) / fps, "codec": codec, "path": str(path)}
