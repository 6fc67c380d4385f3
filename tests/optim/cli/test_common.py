"""The CLI's one error boundary: every exception leaves as one stderr line and an exit code."""

from __future__ import annotations

import errno

import pytest
from typer.testing import CliRunner

from hapticopt.analysis.compute import Compute
from hapticopt.optim.cli import app
from hapticopt.optim.cli import evaluate as cli_evaluate
from hapticopt.optim.cli.common import parse_compute

runner = CliRunner()


def _one_line(res) -> str:
    assert "Traceback" not in res.output
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1, res.stderr
    return lines[0]


@pytest.mark.parametrize("exc, code, words", [
    (OSError(errno.ENOSPC, "No space left on device", "/x/out.step"), 2, ["No space left on device", "/x/out.step"]),
    (OSError(errno.EROFS, "Read-only file system", "/ro/a"), 2, ["Read-only file system"]),
    (PermissionError(errno.EACCES, "Permission denied", "/p"), 2, ["Permission denied"]),
    (RuntimeError("boom\nsecond line"), 4, ["internal error: RuntimeError: boom second line", "--debug"]),
    (RecursionError("maximum recursion depth exceeded"), 4, ["internal error: RecursionError"]),
])
def test_any_exception_is_one_line_and_an_exit_code(monkeypatch, exc, code, words):
    def raiser(*args, **kwargs):
        raise exc

    monkeypatch.setattr(cli_evaluate, "evaluate_all", raiser)
    res = runner.invoke(app, ["evaluate", "--preset", "prrr-paper"])
    assert res.exit_code == code
    line = _one_line(res)
    assert line.startswith("error: ") and all(w in line for w in words), line


def test_debug_adds_the_traceback(monkeypatch):
    def raiser(*args, **kwargs):
        raise RuntimeError("boom")

    monkeypatch.setattr(cli_evaluate, "evaluate_all", raiser)
    res = runner.invoke(app, ["--debug", "evaluate", "--preset", "prrr-paper"])
    assert res.exit_code == 4 and "Traceback" in res.stderr and res.stderr.strip().endswith(
        "(hapticopt --debug shows the traceback)")


def test_error_lines_are_short_for_huge_values(tmp_path):
    """Issue 14: a 10⁶-element array was echoed back in a megabyte-long line (10⁵ here: the file stays
    under the parser's 1 MB bound, which refuses larger ones in one line too)."""
    d = tmp_path / "d.toml"
    d.write_text('name = "x"\ndevice = "prrr"\n[geometry]\nbeta_deg = [' + ", ".join(["1"] * 10**5) + "]\n")
    res = runner.invoke(app, ["evaluate", str(d)])
    assert res.exit_code == 2
    line = _one_line(res)
    assert "geometry.beta_deg" in line and len(line) < 400


@pytest.mark.parametrize("args, words", [
    (["--max-evals", str(2**31)], ["--max-evals", "1 ≤ --max-evals ≤ 1000000"]),
    (["--workers", "0"], ["--workers"]),
    (["--scheduler", "udp://x"], ["--scheduler"]),
])
def test_optimise_options_are_bounded_before_any_work(tmp_path, args, words):
    res = runner.invoke(app, ["optimise", "prrr-workspace", "--out", str(tmp_path / "run"), "--quiet", *args])
    assert res.exit_code == 2
    line = _one_line(res)
    assert all(w in line for w in words), line
    assert not (tmp_path / "run" / "evaluations.sqlite").exists()


def test_every_command_documents_the_exit_codes():
    from hapticopt.optim.cli import common

    assert (common.EXIT_OK, common.EXIT_BAD_INPUT, common.EXIT_NOT_MET, common.EXIT_INTERNAL) == (0, 2, 3, 4)
    commands = [c.name for c in app.registered_commands]
    assert len(commands) >= 11
    for name in [None, *commands]:
        res = runner.invoke(app, ([name] if name else []) + ["--help"], env={"COLUMNS": "120"})
        assert res.exit_code == 0, name
        text = " ".join(res.stdout.split())
        for words in ("Exit codes:", "0 done; every requirement", "2 bad input", "3 done, but the result breaks",
                      "best_infeasible.toml", "4 internal error"):
            assert words in text, (name, words)


ROUTE_COMMANDS = (["evaluate", "--preset", "prrr-paper"], ["verify", "--preset", "prrr-paper"],
                  ["optimise", "no-such-problem"], ["sweep", "--preset", "prrr-paper", "geometry.beta_deg=30:70:3"])


@pytest.mark.parametrize("command", ROUTE_COMMANDS, ids=lambda c: c[0])
@pytest.mark.parametrize(("flags", "expected"), [
    (["--compute", "fast"], "error: --compute = 'fast' is not allowed: one of auto, numpy, numba, jax"),
    (["--threads", "0"], "error: --threads = 0 is not allowed: an integer from 1 to 256"),
    (["--compute", "numba", "--threads", "257"], "error: --threads = 257 is not allowed: an integer from 1 to 256"),
])
def test_a_bad_route_flag_is_one_line_naming_it_exit_2(command, flags, expected):
    """Every command that evaluates, verifies, optimises or sweeps takes --compute and --threads, checked
    first (before the design, problem or scene is read)."""
    res = runner.invoke(app, command + flags)
    assert res.exit_code == 2
    assert _one_line(res) == expected


@pytest.mark.parametrize(("backend", "threads"), [("auto", None), ("numpy", 1), ("numba", 2), ("jax", 256)])
def test_parse_compute_gives_the_route_value(backend, threads):
    assert parse_compute(backend, threads) == Compute(backend=backend, threads=threads)


def test_evaluate_hands_the_route_to_the_registry(monkeypatch):
    seen = []

    def evaluate_all(design, **kw):
        seen.append(kw["compute"])
        raise RuntimeError("stop here")

    monkeypatch.setattr(cli_evaluate, "evaluate_all", evaluate_all)
    runner.invoke(app, ["evaluate", "--preset", "prrr-paper", "--compute", "numpy", "--threads", "1"])
    assert seen == [Compute(backend="numpy", threads=1)]
