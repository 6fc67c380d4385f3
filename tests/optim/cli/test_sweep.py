"""``hapticopt sweep``: files written (CSV with units, one plot per metric), bad input exits 2 with
one line and writes nothing, an existing sweep is refused and resumed."""

from __future__ import annotations

import pytest
from typer.testing import CliRunner

from hapticopt.optim.cli import app
from hapticopt.optim.runs import RunReader

runner = CliRunner()


def test_sweep_writes_table_plots_and_record(tmp_path):
    out = tmp_path / "s"
    args = ["sweep", "--preset", "prrr-paper", "geometry.beta_deg=50:70:3", "actuator.spring_N_per_mm=40:60:2",
            "--only", "statics", "--scheduler", "inline", "--quiet", "--out", str(out)]
    res = runner.invoke(app, args)
    assert res.exit_code == 0, res.output
    assert "6 points, 6 ok, 0 not ok; 6 evaluated, 0 replayed" in res.stdout
    rows = (out / "sweep.csv").read_text().splitlines()
    assert rows[0].startswith("geometry.beta_deg [deg],actuator.spring_N_per_mm [N/mm],outcome,") and len(rows) == 7
    assert (out / "plots" / "sweep_stiffness_limit_N_per_mm_0.png").stat().st_size > 1000
    with RunReader(out) as r:
        assert r.kind == "sweep" and r.status == "finished" and len(r) == 6
        assert [v["key"] for v in r.variables] == ["geometry.beta_deg", "actuator.spring_N_per_mm"]
    again = runner.invoke(app, args)
    assert again.exit_code == 2 and "already holds a run" in again.stderr
    resumed = runner.invoke(app, args + ["--resume", "--no-plots"])
    assert resumed.exit_code == 0 and "0 evaluated, 6 replayed" in resumed.stdout


@pytest.mark.parametrize("axis, match", [
    ("geometry.nope_mm=1:2:3", "is not a numeric key of the design"),
    ("geometry.beta_deg=70:30:3", "lo = 70 must be below hi = 30 (deg)"),
    ("geometry.beta_deg=30:70:1", "n = 1 must be ≥ 2"),
    ("name=1:2:3", "is not a numeric design key"),
])
def test_bad_sweep_one_line_exit_2_no_files(tmp_path, axis, match):
    out = tmp_path / "out"
    res = runner.invoke(app, ["sweep", "--preset", "prrr-paper", axis, "--out", str(out), "--quiet"])
    assert res.exit_code == 2
    (line,) = res.stderr.strip().splitlines()
    assert line.startswith("error: ") and match in line
    assert not out.exists() and list(tmp_path.iterdir()) == []


def test_a_second_sweep_serves_points_from_the_evaluation_cache(tmp_path):
    cache = tmp_path / "shared.sqlite"
    args = ["sweep", "--preset", "prrr-paper", "geometry.beta_deg=50:70:3", "--only", "statics", "--scheduler",
            "inline", "--quiet", "--no-plots", "--cache", str(cache)]
    first = runner.invoke(app, args + ["--out", str(tmp_path / "a")])
    second = runner.invoke(app, args + ["--out", str(tmp_path / "b")])
    assert first.exit_code == 0 and second.exit_code == 0, first.output + second.output
    assert "from the evaluation cache" not in first.stdout
    assert f"3 evaluated, 0 replayed (3 from the evaluation cache {cache})" in second.stdout
    assert (tmp_path / "a" / "sweep.csv").read_text() == (tmp_path / "b" / "sweep.csv").read_text()
    with RunReader(tmp_path / "b") as r:
        assert [c.stage for c in r.cases()] == ["sweep (evaluation cache)"] * 3
