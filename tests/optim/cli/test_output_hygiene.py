"""Issue 21 item 2: no command prints a VTK line or an ANSI escape when its output is a pipe.

The commands run as a user runs them (a new process, stdout and stderr piped, no DISPLAY and no
VTK window chosen in the environment), including every one that draws with VTK: export --render,
and optimise (its evaluator pictures and the export's render)."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from hapticopt.design import offscreen

DATA = Path(__file__).parents[1] / "data"


def run_cli(*args: str, cwd: Path) -> subprocess.CompletedProcess:
    env = {k: v for k, v in os.environ.items() if k not in ("DISPLAY", "WAYLAND_DISPLAY", offscreen.ENV)}
    return subprocess.run([sys.executable, "-m", "hapticopt.optim.cli", *args], capture_output=True, text=True,
                          env=env, cwd=cwd, timeout=600)


def assert_clean(res: subprocess.CompletedProcess) -> None:
    assert res.returncode == 0, res.stderr
    for stream in (res.stdout, res.stderr):
        for line in stream.splitlines():
            assert "vtk" not in line.lower(), line
            assert "\x1b" not in line, repr(line)


@pytest.mark.parametrize("args", [
    ("presets",), ("problems",), ("metrics",), ("evaluate", "--preset", "prrr-paper"),
    ("verify", "--preset", "handle-paper"),
])
def test_quick_commands(args, tmp_path):
    assert_clean(run_cli(*args, cwd=tmp_path))


def test_commands_that_render(tmp_path):
    res = run_cli("export", "--preset", "prrr-paper", "--render", "--out", str(tmp_path / "export"), cwd=tmp_path)
    assert_clean(res)
    assert (tmp_path / "export" / "prrr-paper.png").stat().st_size > 0
    res = run_cli("optimise", str(DATA / "beta-isotropic.toml"), "--out", str(tmp_path / "run"), "--scheduler",
                  "inline", "--max-evals", "12", "--no-verify", cwd=tmp_path)
    assert_clean(res)
    assert (tmp_path / "run" / "beta-isotropic-optimum.png").stat().st_size > 0  # the export's render
    assert list((tmp_path / "run" / "plots").glob("*.png"))  # the evaluators' pictures
