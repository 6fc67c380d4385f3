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


def command_lines() -> list[list[str]]:
    lines = []
    for block in re.findall(r"```sh\n(.*?)```", README.read_text(), flags=re.S):
        for line in block.splitlines():
            line = line.split("#", 1)[0].strip()
            if line.startswith(".venv/bin/hapticopt"):
                lines.append(shlex.split(line)[1:])
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
    for argv in command_lines():
        if argv[0] in ("presets", "problems") or (argv[0] == "evaluate" and "prrr-paper" in argv and "--plots" not in argv):
            res = runner.invoke(app, argv)
            assert res.exit_code == 0, (argv, res.output)
