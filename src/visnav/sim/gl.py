"""Headless OpenGL for MuJoCo rendering: backend choice and a shared render context.

:func:`select_gl_backend` prefers EGL, falls back to OSMesa and raises
:class:`RenderingUnavailableError` naming the missing library and its Debian
package (``libegl1`` / ``libosmesa6``) when neither is installed. It sets
``MUJOCO_GL`` / ``PYOPENGL_PLATFORM`` only when called (never at import).
visnav creates its GL contexts itself (``mujoco.egl`` / ``mujoco.osmesa``), so
the choice works even when ``mujoco`` was imported before the variables were set.
"""

from __future__ import annotations

import ctypes.util
import os
from typing import Any

import mujoco

from visnav.sim.errors import RenderingUnavailableError

__all__ = ["RenderContext", "RenderingUnavailableError", "select_gl_backend"]

_BACKENDS = {
    "egl": ("EGL", "libegl1"),
    "osmesa": ("OSMesa", "libosmesa6"),
}


def select_gl_backend() -> str:
    """Choose the headless OpenGL backend; call before creating the first renderer.

    Honours ``MUJOCO_GL`` if it is ``egl`` or ``osmesa``; otherwise uses EGL when
    ``libEGL`` is installed, else OSMesa. Sets ``MUJOCO_GL`` and
    ``PYOPENGL_PLATFORM`` to the choice when they are unset or empty. Environment
    variables are only touched when this function is called, never at import.

    Returns:
        ``"egl"`` or ``"osmesa"``.

    Raises:
        RenderingUnavailableError: the requested or every backend's library is
            missing; the message names the library and the Debian package.
    """
    requested = os.environ.get("MUJOCO_GL", "").strip().lower()
    candidates = [requested] if requested in _BACKENDS else ["egl", "osmesa"]
    missing: list[str] = []
    for backend in candidates:
        library, package = _BACKENDS[backend]
        if ctypes.util.find_library(library) is None:
            missing.append(f"lib{library} (Debian package {package})")
            continue
        for name in ("MUJOCO_GL", "PYOPENGL_PLATFORM"):
            if not os.environ.get(name, "").strip():
                os.environ[name] = backend
        return backend
    hint = "apt-get install libegl1 (EGL; GPU or Mesa) or libosmesa6 (software OSMesa)"
    if requested in _BACKENDS:
        msg = (
            f"MUJOCO_GL={requested} but {missing[0]} is not installed. Fix: {hint}, or unset "
            "MUJOCO_GL to let visnav choose"
        )
    else:
        msg = f"no headless OpenGL: {' and '.join(missing)} are not installed. Fix: {hint}"
    raise RenderingUnavailableError(msg)


def _gl_context(backend: str, width: int, height: int) -> Any:
    platform = os.environ.get("PYOPENGL_PLATFORM", "").strip() or backend
    if platform != backend:
        msg = (
            f"PYOPENGL_PLATFORM={platform} conflicts with the {backend} backend. Fix: unset "
            f"PYOPENGL_PLATFORM or set it to {backend} before starting Python"
        )
        raise RenderingUnavailableError(msg)
    try:
        if backend == "egl":
            from mujoco.egl import GLContext  # noqa: PLC0415 - needs the env set first
        else:
            from mujoco.osmesa import GLContext  # noqa: PLC0415
        return GLContext(width, height)
    except Exception as exc:
        library, package = _BACKENDS[backend]
        other = "osmesa" if backend == "egl" else "egl"
        msg = (
            f"creating a {backend} OpenGL context failed ({type(exc).__name__}: {exc}). Fix: "
            f"check that lib{library} (Debian package {package}) works, or start Python with "
            f"MUJOCO_GL={other} (needs {_BACKENDS[other][1]})"
        )
        raise RenderingUnavailableError(msg) from exc


class RenderContext:
    """An offscreen OpenGL context and MuJoCo render context for one compiled model.

    Several :class:`CameraSensor` objects of the same model can share one
    context (textures and meshes are uploaded once); its framebuffer must be at
    least as large as their render canvases.

    Args:
        model: the compiled model; its offscreen buffer size
            (``vis.global_.offwidth/offheight``) is raised to the maximum if needed.
        max_width: largest canvas width to render.
        max_height: largest canvas height to render.
    """

    def __init__(self, model: mujoco.MjModel, *, max_width: int, max_height: int) -> None:
        self.backend = select_gl_backend()
        model.vis.global_.offwidth = max(int(model.vis.global_.offwidth), int(max_width))
        model.vis.global_.offheight = max(int(model.vis.global_.offheight), int(max_height))
        self.max_width = int(model.vis.global_.offwidth)
        self.max_height = int(model.vis.global_.offheight)
        self.model = model
        self._gl: Any = _gl_context(self.backend, self.max_width, self.max_height)
        self._gl.make_current()
        self.mjr = mujoco.MjrContext(model, mujoco.mjtFontScale.mjFONTSCALE_50.value)
        mujoco.mjr_setBuffer(mujoco.mjtFramebuffer.mjFB_OFFSCREEN.value, self.mjr)
        self.mjr.readDepthMap = mujoco.mjtDepthMap.mjDEPTH_ZEROFAR

    def make_current(self) -> None:
        """Make this context current on the calling thread."""
        if self._gl is None:
            msg = "the render context is closed. Fix: create a new RenderContext"
            raise RenderingUnavailableError(msg)
        self._gl.make_current()

    def close(self) -> None:
        """Free the GL resources (idempotent)."""
        if self._gl is not None:
            self._gl.make_current()
            self.mjr.free()
            self._gl.free()
            self._gl = None

    def __enter__(self) -> RenderContext:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
