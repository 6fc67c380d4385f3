"""Off-screen rendering set up before VTK makes its first render window.

VTK ≥ 9.4 picks its OpenGL window class at run time. Without a choice it first tries the X11
window (``vtkXOpenGLRenderWindow``); on a machine without a display that probe fails and VTK
logs ``bad X server connection. DISPLAY=`` (with ANSI colour codes, on stderr, even for
``Plotter(off_screen=True)``) before it falls back to EGL. Our pictures are always off screen,
so we name the off-screen window class instead (VTK's documented run-time setting
``VTK_DEFAULT_OPENGL_WINDOW``): the X probe never runs and the warning is never emitted.

Choice: EGL when ``libEGL`` is installed (the vtk wheels have EGL support built in), else
OSMesa when ``libOSMesa`` is, else VTK's own default. A value the user already set in the
environment is kept. The variable is read when a render window is created, so calling
:func:`configure` any time before the first ``pyvista.Plotter`` is enough; it is set in
``os.environ`` so that the worker processes the CLI spawns inherit it.
"""

from __future__ import annotations

import ctypes.util
import os

#: VTK's run-time window selection (docs.vtk.org, "Runtime settings", OpenGL)
ENV = "VTK_DEFAULT_OPENGL_WINDOW"
#: off-screen window classes in order of preference, with the shared library each needs
OFFSCREEN_WINDOWS = (("vtkEGLRenderWindow", "EGL"), ("vtkOSOpenGLRenderWindow", "OSMesa"))


def choose_window(find_library=ctypes.util.find_library) -> str | None:
    """The off-screen window class whose library is installed, or None (VTK's default then)."""
    for window, library in OFFSCREEN_WINDOWS:
        if find_library(library):
            return window
    return None


def configure(environ: dict[str, str] | None = None) -> str | None:
    """Select the off-screen render window for this process and its children; returns the class.

    Idempotent; keeps a value already present in ``environ`` (default ``os.environ``).
    """
    env = os.environ if environ is None else environ
    if env.get(ENV):
        return env[ENV]
    window = choose_window()
    if window is not None:
        env[ENV] = window
    return window
