"""The README stays true: its quick start is the two commands, and every command line it shows
names a real subcommand with real options (the cheap ones are run)."""

from __future__ import annotations

import re
import shlex
from pathlib import Path

import pytest
from typer.testing import CliRunner

from hapticopt.optim.cli import app

README = Path(__file__).resolve().parents[1] / "README.md"
runner = CliRunner()


def command_lines(*, with_exit: bool = False) -> list:
    """The README's hapticopt command lines (argv), with the exit code its comment states
    ("exit 3: …"; 0 when it says none) if ``with_exit``."""
    lines = []
    for block in re.findall(r"```sh\n(.*?)```", README.read_text(), flags=re.S):
        for raw in block.splitlines():
            line, _, comment = raw.partition("#")
            line = line.strip()
            if line.startswith(".venv/bin/hapticopt"):
                code = re.search(r"\bexit (\d)\b", comment)
                argv = shlex.split(line)[1:]
                lines.append((argv, int(code.group(1)) if code else 0) if with_exit else argv)
    return lines


def test_quick_start_is_make_run_and_make_test():
    block = re.search(r"## Quick start\s+```sh\n(.*?)```", README.read_text(), flags=re.S).group(1)
    assert [ln.split("#")[0].strip() for ln in block.strip().splitlines()] == ["make run", "make test"]
    makefile = (README.parent / "Makefile").read_text()
    assert re.search(r"^run:", makefile, flags=re.M) and re.search(r"^test:", makefile, flags=re.M)


@pytest.mark.parametrize("argv", command_lines(), ids=lambda a: " ".join(a))
def test_readme_command_uses_real_subcommand_and_options(argv):
    help_text = runner.invoke(app, [argv[0], "--help"]).stdout
    assert "Usage" in help_text, f"unknown subcommand {argv[0]}"
    for token in argv[1:]:
        if token.startswith("--"):
            assert token in help_text, f"{argv[0]} has no option {token}"


def test_cheap_readme_commands_run():
    for argv, code in command_lines(with_exit=True):
        if argv[0] in ("presets", "problems") or (argv[0] == "evaluate" and "prrr-paper" in argv and "--plots" not in argv):
            res = runner.invoke(app, argv)
            assert res.exit_code == code, (argv, res.output)  # the exit code the README states


def test_python_section_runs_outside_the_repository(tmp_path, monkeypatch):
    """The README's Python block, run as a user would: from another directory, by the installed names."""
    blocks = re.findall(r"## Python.*?```python\n(.*?)```", README.read_text(), flags=re.S)
    assert len(blocks) == 1
    monkeypatch.chdir(tmp_path)
    namespace: dict = {}
    exec(compile(blocks[0], "README.md", "exec"), namespace)  # noqa: S102 - our own README
    assert namespace["after"].metrics()["max_force_N"] != namespace["before"].metrics()["max_force_N"]
    assert (tmp_path / "cad_out" / "prrr-beta45" / "prrr-paper.step").is_file()


def test_the_top_level_folders_are_not_importable_outside_the_repository(tmp_path):
    """Installed as hapticopt.*: `import design` fails outside the repository, `import hapticopt.design` works."""
    import subprocess
    import sys

    ok = subprocess.run([sys.executable, "-c", "import hapticopt.analysis, hapticopt.design, hapticopt.optim"],
                        cwd=tmp_path, capture_output=True, text=True)
    assert ok.returncode == 0, ok.stderr
    for name in ("design", "analysis", "optim"):
        bad = subprocess.run([sys.executable, "-c", f"import {name}"], cwd=tmp_path, capture_output=True, text=True)
        assert bad.returncode != 0 and "ModuleNotFoundError" in bad.stderr
