"""``design.offscreen``: the off-screen VTK window is chosen before any render window exists."""

from __future__ import annotations

import subprocess
import sys

from hapticopt.design import offscreen


def test_prefers_egl_then_osmesa_then_vtk_default():
    assert offscreen.choose_window(lambda lib: "libEGL.so.1") == "vtkEGLRenderWindow"
    assert offscreen.choose_window(lambda lib: "libOSMesa.so.8" if lib == "OSMesa" else None) == \
        "vtkOSOpenGLRenderWindow"
    assert offscreen.choose_window(lambda lib: None) is None


def test_configure_keeps_a_users_choice():
    env = {offscreen.ENV: "vtkXOpenGLRenderWindow"}
    assert offscreen.configure(env) == "vtkXOpenGLRenderWindow"
    assert env == {offscreen.ENV: "vtkXOpenGLRenderWindow"}


def test_configure_sets_the_variable_vtk_reads():
    env: dict[str, str] = {}
    window = offscreen.configure(env)
    assert env.get(offscreen.ENV) == window
    assert offscreen.configure(env) == window  # idempotent


def test_render_emits_no_vtk_line_without_a_display(tmp_path):
    """A pyvista picture after ``configure`` writes nothing on stdout or stderr (no X probe)."""
    code = (
        "from hapticopt.design import offscreen; w = offscreen.configure()\n"
        "import pyvista as pv\n"
        "pl = pv.Plotter(off_screen=True, window_size=(64, 64)); pl.add_mesh(pv.Sphere())\n"
        f"pl.screenshot({str(tmp_path / 's.png')!r}); pl.close()\n"
        "print(w)\n"
    )
    env = {k: v for k, v in __import__("os").environ.items() if k not in ("DISPLAY", offscreen.ENV)}
    res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, timeout=120)
    assert res.returncode == 0, res.stderr
    assert res.stderr == ""
    assert res.stdout.strip() in {w for w, _ in offscreen.OFFSCREEN_WINDOWS} | {"None"}
    assert (tmp_path / "s.png").stat().st_size > 0
