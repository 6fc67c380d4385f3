"""Start-up cost of the ``hapticopt`` command line (optim/cli/__init__.py): importing it, and
``hapticopt --help``, load no heavy third-party package (issue 22 item 5). The packages are those of
``tests/test_layers.py::LAZY`` that a short CLI call should never pay for; each is checked in a
fresh interpreter, because this test process has long imported them."""

from __future__ import annotations

import json
import subprocess
import sys

import pytest

#: must stay out of ``import hapticopt.optim.cli`` and ``hapticopt --help``
HEAVY = ("scipy.optimize", "scipy.integrate", "jax", "mujoco", "pyvista", "gmsh", "build123d", "dask", "nlopt",
         "matplotlib", "manifold3d", "skfem", "pyamg")


def loaded_after(code: str) -> list[str]:
    """The HEAVY packages in ``sys.modules`` after running ``code`` in a fresh interpreter."""
    probe = f"{code}\nimport sys, json\nprint(json.dumps(sorted(m for m in {HEAVY!r} if m in sys.modules)))"
    out = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, timeout=120, check=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


def test_importing_the_cli_loads_no_heavy_package():
    assert loaded_after("import hapticopt.optim.cli") == []


def test_help_loads_no_heavy_package():
    code = ("from typer.testing import CliRunner\nfrom hapticopt.optim.cli import app\n"
            "r = CliRunner().invoke(app, ['--help'])\nassert r.exit_code == 0 and 'optimise' in r.output, r.output")
    assert loaded_after(code) == []


@pytest.mark.parametrize("command", ["optimise", "sweep", "compare", "verify", "export"])
def test_subcommand_help_loads_no_heavy_package(command):
    code = ("from typer.testing import CliRunner\nfrom hapticopt.optim.cli import app\n"
            f"r = CliRunner().invoke(app, [{command!r}, '--help'])\nassert r.exit_code == 0, r.output")
    assert loaded_after(code) == []


def test_the_probe_sees_a_heavy_import():
    """The check can fail: an evaluator module that uses jax shows up."""
    assert "jax" in loaded_after("import hapticopt.analysis.prrr.structure.statics")


@pytest.mark.parametrize("argv, says", [
    (["evaluate", "--preset", "prrr-paper", "--bogus"], "no such option: --bogus (see `hapticopt evaluate --help`)"),
    (["sweep"], "missing argument"),
    (["bogus"], "no such command 'bogus'"),
    (["verify", "--preset", "prrr-paper", "--period-ms", "abc"], "invalid value for '--period-ms'"),
])
def test_a_usage_error_is_one_line_exit_2(argv, says):
    """Issue 37 item 9: click's usage errors (unknown option or command, missing argument, a value of
    the wrong type) are one line on stderr naming the command's help, exit 2, not typer's usage box."""
    from typer.testing import CliRunner

    from hapticopt.optim.cli import app
    r = CliRunner().invoke(app, argv)
    assert r.exit_code == 2
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: ") and says in lines[0], r.stderr
    assert "Usage:" not in r.output and "╭" not in r.output
