"""``optim.cli.progress``: at 80 columns the count and the elapsed time survive a long text."""

from __future__ import annotations

import io
import re
from pathlib import Path

from rich.console import Console
from typer.testing import CliRunner

from hapticopt.optim.cli import app, render
from hapticopt.optim.cli.progress import StageLine, make_progress

DATA = Path(__file__).parents[1] / "data"
ELAPSED = re.compile(r"\b\d+:\d\d:\d\d\b")  # rich's TimeElapsedColumn, h:mm:ss


def _frames(text: str) -> list[str]:
    """Distinct lines a live display drew (frames are separated by cursor movements)."""
    out: list[str] = []
    for frame in re.split(r"\r|\x1b\[[0-9;?]*[A-Za-z]", text):
        frame = frame.strip("\n")
        for line in frame.splitlines():
            if line.strip() and line not in out:
                out.append(line)
    return out


def test_count_and_elapsed_survive_80_columns():
    buf = io.StringIO()
    console = Console(width=80, force_terminal=True, color_system=None, file=buf)
    with make_progress(console) as bar:
        line = StageLine(bar, "baseline", 300)
        line.stage("optimise", 300)
        line.count(123)
        line.note("best workspace_free_footprint_ratio = 0.535312 (infeasible (violation 3.1 %)) " * 3)
    last = _frames(buf.getvalue())[-1]
    assert len(last) <= 80
    assert "optimise" in last and "123/300" in last and ELAPSED.search(last), last
    assert last.rstrip().endswith("…")  # only the free text is shortened


def test_optimise_progress_names_stages_with_count_and_elapsed(tmp_path, monkeypatch):
    """The real optimise command, its stderr drawn as a terminal of 80 columns."""
    buf = io.StringIO()
    monkeypatch.setattr(render, "console", lambda **kw: Console(file=buf, width=80, force_terminal=True,
                                                                color_system=None))
    res = CliRunner().invoke(app, ["optimise", str(DATA / "beta-isotropic.toml"), "--out", str(tmp_path),
                                   "--scheduler", "inline", "--max-evals", "12", "--no-export", "--no-verify"])
    assert res.exit_code == 0, res.output
    lines = [ln for ln in _frames(buf.getvalue()) if ELAPSED.search(ln)]
    assert lines and all(len(ln) <= 80 for ln in lines)
    stages = {ln.split()[0] for ln in lines}
    assert {"baseline", "optimise", "final", "plots", "report", "done"} <= stages, stages  # each drawn at its start
    # baseline at both fidelities of the problem (draft to optimise, standard final), counted in evaluators
    assert any(re.search(r"baseline .* \d/8 \d+:\d\d:\d\d (draft|standard): ", ln) for ln in lines), lines
    assert any(re.search(r"optimise .* \d+/12 \d+:\d\d:\d\d ", ln) for ln in lines), lines


def _terminal_stderr(monkeypatch) -> io.StringIO:
    """Route the commands' stderr console to an 80-column terminal we can read."""
    buf = io.StringIO()
    monkeypatch.setattr(render, "console", lambda stderr=False, quiet=False: Console(
        file=buf if stderr else io.StringIO(), width=80, force_terminal=stderr, color_system=None, quiet=quiet))
    return buf


def test_evaluate_shows_its_evaluators(monkeypatch):
    buf = _terminal_stderr(monkeypatch)
    res = CliRunner().invoke(app, ["evaluate", "--preset", "prrr-paper", "--fidelity", "draft"])
    assert res.exit_code == 0, res.output
    lines = [ln for ln in _frames(buf.getvalue()) if ELAPSED.search(ln)]
    assert any(re.search(r"^evaluate .* \d/8 \d+:\d\d:\d\d draft: [a-z_]+", ln) for ln in lines), lines


def test_export_shows_its_steps(monkeypatch, tmp_path):
    buf = _terminal_stderr(monkeypatch)
    res = CliRunner().invoke(app, ["export", "--preset", "master-paper", "--out", str(tmp_path)])
    assert res.exit_code == 0, res.output
    lines = [ln for ln in _frames(buf.getvalue()) if ELAPSED.search(ln)]
    assert any(re.search(r"^export .* 0/4 \d+:\d\d:\d\d cad", ln) for ln in lines), lines
    assert all(len(ln) <= 80 for ln in lines)
