"""Real filesystem faults (issue 14): a full tmpfs, a read-only one, ``--out`` that is a file.

Each gives exit 2 and one line with the operating system's reason, and leaves the previous file
set as it was. The tmpfs cases mount a small tmpfs and need root (skipped otherwise).
"""

from __future__ import annotations

import subprocess
from pathlib import Path

import pytest
from typer.testing import CliRunner

from hapticopt.optim.cli import app

DATA = Path(__file__).parents[1] / "data"
runner = CliRunner()


@pytest.fixture
def tmpfs(tmp_path):
    """Mount a tmpfs of the requested size [kB] at tmp_path/fs; unmounted afterwards."""
    mounted: list[Path] = []

    def mount(size_k: int, *, read_only: bool = False) -> Path:
        where = tmp_path / f"fs{len(mounted)}"
        where.mkdir()
        opts = f"size={size_k}k" + (",ro" if read_only else "")
        res = subprocess.run(["mount", "-t", "tmpfs", "-o", opts, "tmpfs", str(where)], capture_output=True)
        if res.returncode != 0:
            pytest.skip(f"cannot mount a tmpfs here: {res.stderr.decode().strip()}")
        mounted.append(where)
        return where

    yield mount
    for where in mounted:
        subprocess.run(["umount", "-l", str(where)], capture_output=True)


def _line(res) -> str:
    assert res.exit_code == 2, res.output
    assert "Traceback" not in res.output
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1, res.stderr
    return lines[0]


def test_out_is_a_file(tmp_path):
    (tmp_path / "f").write_text("x")
    res = runner.invoke(app, ["optimise", str(DATA / "beta-isotropic.toml"), "--out", str(tmp_path / "f"),
                              "--quiet", "--scheduler", "inline", "--no-export", "--no-verify"])
    assert "File exists" in _line(res)
    assert (tmp_path / "f").read_text() == "x"


def test_read_only_out(tmpfs):
    ro = tmpfs(64, read_only=True)
    res = runner.invoke(app, ["optimise", str(DATA / "beta-isotropic.toml"), "--out", str(ro / "run"), "--quiet",
                              "--scheduler", "inline", "--no-export", "--no-verify"])
    assert "Read-only file system" in _line(res)


def test_recorder_on_a_full_disk_names_the_sqlite_reason(tmpfs):
    """The recorder's message was 'cannot rollback - no transaction is active'."""
    fs = tmpfs(120)  # --no-cache: the evaluation cache would meet the full disk first (one warning line, its own case)
    res = runner.invoke(app, ["optimise", str(DATA / "beta-isotropic.toml"), "--out", str(fs / "run"), "--quiet",
                              "--scheduler", "inline", "--no-export", "--no-verify", "--no-cache"])
    line = _line(res)
    assert "database or disk is full" in line and "rollback" not in line


def test_export_to_a_full_disk_keeps_the_previous_set(tmpfs):
    """An export to a full disk left 14 of 18 files: now the previous set stays, nothing new appears."""
    fs = tmpfs(1024)  # the prrr-paper set is ~1.8 MB
    out = fs / "out"
    previous = {"prrr-paper.step": "old step", "prrr-paper.xml": "old xml", "mass_properties.json": "{}",
                "parts/base.stl": "old stl"}
    for name, text in previous.items():
        (out / name).parent.mkdir(parents=True, exist_ok=True)
        (out / name).write_text(text)
    res = runner.invoke(app, ["export", "--preset", "prrr-paper", "--out", str(out)])
    assert "No space left on device" in _line(res)
    # the run lock an export into an existing folder takes (issue 37) is the one file beside the set
    now = {p.relative_to(out).as_posix(): p.read_text() for p in out.rglob("*") if p.is_file()
           and p.name != ".hapticopt.lock"}
    assert now == previous
    assert [p.name for p in out.rglob(".*")] == [".hapticopt.lock"]
