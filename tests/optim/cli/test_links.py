"""Issue 37, item 1: no write follows a link planted in ``--out``.

A symbolic link is planted at each name a command writes (the run lock, the run record and the
evaluation cache with their SQLite side files, the sweep's table and plots, the export's files, the
comparison report); the command must exit 2 with one line naming the link, and nothing outside
``--out`` may change: the link's target keeps its bytes, a dangling link's target is not created,
a linked folder stays empty. Most cases stop at the first write; the late ones (``sweep.csv``,
``plots/``) resume a finished sweep copied from a template, so no point is evaluated again.
"""

from __future__ import annotations

import os
import shutil
from pathlib import Path

import pytest
from typer.testing import CliRunner

from hapticopt.optim.cli import app

runner = CliRunner()
DATA = Path(__file__).resolve().parents[1] / "data"

SWEEP = ["sweep", "--preset", "prrr-paper", "geometry.beta_deg=50:70:2", "--only", "statics", "--scheduler", "inline",
         "--quiet"]
#: names a sweep writes (the record and cache with their SQLite side files, the lock, the table, plots, overview)
SWEEP_NAMES = [".hapticopt.lock", "evaluations.sqlite", "evaluations.sqlite-wal", "evaluations.sqlite-shm",
               "evaluations.sqlite-journal", "evaluation-cache.sqlite", "evaluation-cache.sqlite-wal",
               "evaluation-cache.sqlite-shm", "evaluation-cache.sqlite-journal", "sweep.csv", "plots",
               "plots/sweep_jacobian_condition.png", "overview.png", "overview.html"]
FIRST_WRITES = [".hapticopt.lock", "evaluations.sqlite", "evaluations.sqlite-wal", "evaluations.sqlite-shm",
                "evaluation-cache.sqlite", "evaluation-cache.sqlite-wal"]
KINDS = ["to-a-file", "dangling"]


@pytest.fixture(scope="module")
def finished_sweep(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("template") / "run"
    res = runner.invoke(app, [*SWEEP, "--out", str(out)])
    assert res.exit_code == 0, res.output
    return out


def _outside(tmp_path: Path) -> Path:
    out = tmp_path / "outside"
    out.mkdir()
    (out / "victim").write_bytes(b"keep me")
    (out / "victim_dir").mkdir()
    return out


def _plant(run: Path, name: str, kind: str, outside: Path) -> None:
    link = run / name
    if link.is_dir() and not link.is_symlink():
        shutil.rmtree(link)
    elif link.exists() or link.is_symlink():
        link.unlink()
    link.parent.mkdir(parents=True, exist_ok=True)
    is_dir = "." not in Path(name).name  # plots, parts
    target = outside / ("ghost" if kind == "dangling" else "victim_dir" if is_dir else "victim")
    link.symlink_to(target, target_is_directory=is_dir)


def _assert_untouched(res, outside: Path) -> None:
    assert res.exit_code == 2, res.output
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1 and "refused" in lines[0], res.stderr
    # the link named (paths.no_links), or where it leads (paths.inside, the export's older check)
    assert "symbolic link" in lines[0] or "outside the output folder" in lines[0], res.stderr
    assert (outside / "victim").read_bytes() == b"keep me"
    assert sorted(p.name for p in outside.iterdir()) == ["victim", "victim_dir"]  # no ghost created
    assert list((outside / "victim_dir").iterdir()) == []


@pytest.mark.parametrize("kind", KINDS)
@pytest.mark.parametrize("name", SWEEP_NAMES)
def test_sweep_resume_refuses_a_link_at_every_name_it_writes(tmp_path, finished_sweep, name, kind):
    run = tmp_path / "run"
    shutil.copytree(finished_sweep, run, symlinks=True)
    outside = _outside(tmp_path)
    _plant(run, name, kind, outside)
    _assert_untouched(runner.invoke(app, [*SWEEP, "--out", str(run), "--resume"]), outside)


@pytest.mark.parametrize("kind", KINDS)
@pytest.mark.parametrize("name", FIRST_WRITES)
def test_a_new_sweep_refuses_a_link_at_its_first_writes(tmp_path, name, kind):
    run = tmp_path / "run"
    run.mkdir()
    outside = _outside(tmp_path)
    _plant(run, name, kind, outside)
    _assert_untouched(runner.invoke(app, [*SWEEP, "--out", str(run), "--force"]), outside)


@pytest.mark.parametrize("kind", KINDS)
@pytest.mark.parametrize("name", FIRST_WRITES + ["plots", "parts", "report.md", "result.json", "optimum.toml"])
def test_optimise_refuses_a_link_at_its_first_writes(tmp_path, name, kind):
    run = tmp_path / "run"
    run.mkdir()
    outside = _outside(tmp_path)
    _plant(run, name, kind, outside)
    res = runner.invoke(app, ["optimise", str(DATA / "resume-problem.toml"), "--out", str(run), "--force",
                              "--max-evals", "2", "--scheduler", "inline", "--no-export", "--no-verify", "--quiet"])
    _assert_untouched(res, outside)


def test_the_lock_link_target_is_untouched_and_a_hard_link_refused(tmp_path):
    """The issue's first case: ``ln -s FILE RUN/.hapticopt.lock`` truncated FILE and wrote the pid."""
    from hapticopt.design.errors import InputFileError
    from hapticopt.optim.recorder import run_lock

    outside = _outside(tmp_path)
    run = tmp_path / "run"
    run.mkdir()
    (run / ".hapticopt.lock").symlink_to(outside / "victim")
    with pytest.raises(InputFileError, match="symbolic link"):
        run_lock(run).__enter__()
    assert (outside / "victim").read_bytes() == b"keep me"
    (run / ".hapticopt.lock").unlink()
    os.link(outside / "victim", run / ".hapticopt.lock")
    with pytest.raises(InputFileError, match="hard links"):
        run_lock(run).__enter__()
    assert (outside / "victim").read_bytes() == b"keep me"


@pytest.mark.parametrize("kind", KINDS)
@pytest.mark.parametrize("name", [".hapticopt.lock", "report.md"])
def test_compare_report_refuses_a_link(tmp_path, name, kind):
    folder = tmp_path / "rep"
    folder.mkdir()
    outside = _outside(tmp_path)
    _plant(folder, name, kind, outside)
    res = runner.invoke(app, ["compare", "handle-paper", "handle-paper", "--fidelity", "draft", "--no-cache",
                              "--report", str(folder / "report.md")])
    _assert_untouched(res, outside)


@pytest.mark.parametrize("name", [".hapticopt.lock", "parts"])
def test_export_into_an_existing_folder_refuses_a_link(tmp_path, name):
    folder = tmp_path / "exp"
    folder.mkdir()
    outside = _outside(tmp_path)
    _plant(folder, name, "to-a-file", outside)
    _assert_untouched(runner.invoke(app, ["export", "--preset", "prrr-paper", "--out", str(folder)]), outside)
