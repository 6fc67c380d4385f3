"""``hapticopt sweep``: files written (CSV with units, one plot per metric, the overview page), bad input exits 2 with
one line and writes nothing, an existing sweep is refused and resumed."""

from __future__ import annotations

import pytest
from typer.testing import CliRunner

from hapticopt.optim.cli import app
from hapticopt.optim.runs import RunReader

runner = CliRunner()


def test_sweep_writes_table_plots_and_record(tmp_path):
    out = tmp_path / "s"
    # beta <= 60 deg: prrr-paper's parts lay out (at 70 deg its R3 lugs run into the stem: not-assemblable)
    args = ["sweep", "--preset", "prrr-paper", "geometry.beta_deg=50:60:3", "actuator.spring_N_per_mm=40:60:2",
            "--only", "statics", "--scheduler", "inline", "--quiet", "--out", str(out)]
    res = runner.invoke(app, args)
    assert res.exit_code == 0, res.output
    assert "6 points, 6 ok, 0 not ok; 6 evaluated, 0 replayed" in res.stdout
    rows = (out / "sweep.csv").read_text().splitlines()
    assert rows[0].startswith("geometry.beta_deg [deg],actuator.spring_N_per_mm [N/mm],outcome,") and len(rows) == 7
    assert (out / "plots" / "sweep_stiffness_limit_N_per_mm_0.png").stat().st_size > 1000
    assert f"overview: {out / 'overview.html'} (every metric against the swept keys)" in res.stdout
    assert (out / "overview.png").stat().st_size > 1000
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
    ("geometry.beta_deg=30:70:1", "n = 1 is out of range: allowed 2 ≤ n ≤ 100000 (points"),
    # issue 37: an integer key's grid was built (2.6 GB) before the point limit was checked
    ("geometry.beta_deg=30:70:300000001", "n = 300000001 is out of range: allowed 2 ≤ n ≤ 100000"),
    ("geometry.beta_deg=30:70:1" + "0" * 5000, "must be a whole number of points"),
    ("name=1:2:3", "is not a numeric design key"),
    # issue 37: the scheduler was checked after the run directory's lock and record were made
    ("geometry.beta_deg=30:70:3 --scheduler bogus", "--scheduler = 'bogus' is not allowed"),
])
def test_bad_sweep_one_line_exit_2_no_files(tmp_path, axis, match):
    out = tmp_path / "out"
    res = runner.invoke(app, ["sweep", "--preset", "prrr-paper", *axis.split(" "), "--out", str(out), "--quiet"])
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


def test_an_integer_key_is_bounded_before_its_values_exist(tmp_path, monkeypatch):
    """Issue 37: an integer key's axis built all its values (2.6 GB) to check they are whole."""
    from hapticopt.optim import sweep as sw

    monkeypatch.setattr(sw.Axis, "values", property(lambda self: pytest.fail("the axis values were built")))
    for axis, match in (("firmware.upsampling=1:64:300000001", "n = 300000001 is out of range"),
                        ("firmware.upsampling=1:64:5", "takes whole numbers: 1:64:5 gives fractions")):
        res = runner.invoke(app, ["sweep", "--preset", "handle-paper", axis, "--out", str(tmp_path / "o"), "--quiet"])
        assert res.exit_code == 2 and match in res.stderr, res.output


def test_two_axes_are_refused_by_their_product_before_the_grid_exists(tmp_path, monkeypatch):
    """Issue 37: 100,000-point limit checked from the axes' sizes, never by building the grid."""
    from hapticopt.optim import sweep as sw

    monkeypatch.setattr(sw.Sweep, "points", lambda self: pytest.fail("the grid was built"))
    res = runner.invoke(app, ["sweep", "--preset", "prrr-paper", "geometry.beta_deg=30:70:1000",
                              "actuator.spring_N_per_mm=40:60:1000", "--out", str(tmp_path / "o"), "--quiet"])
    assert res.exit_code == 2 and "the sweep has 1000000 points: allowed at most 100000" in res.stderr


@pytest.mark.parametrize("workers", ["0", "257", "100000"])
def test_sweep_workers_are_bounded(tmp_path, workers):
    res = runner.invoke(app, ["sweep", "--preset", "prrr-paper", "geometry.beta_deg=30:70:2", "--workers", workers,
                              "--out", str(tmp_path / "o"), "--quiet"])
    assert res.exit_code == 2 and f"--workers = {workers} is out of range: allowed 1 ≤ --workers ≤ 256" in res.stderr
    assert not (tmp_path / "o").exists()


def test_a_second_concurrent_sweep_resume_is_refused_in_one_line(tmp_path):
    """Issue 37, item 4: two ``sweep --resume`` of one directory both ran and repeated every point."""
    import subprocess
    import sys

    out = tmp_path / "s"
    args = ["sweep", "--preset", "prrr-paper", "geometry.beta_deg=50:70:2", "--only", "statics", "--scheduler",
            "inline", "--quiet", "--no-plots", "--out", str(out)]
    assert runner.invoke(app, args).exit_code == 0
    holder = subprocess.Popen([sys.executable, "-c", "import sys, time; from hapticopt.optim.recorder import run_lock\n"
                               "with run_lock(sys.argv[1]):\n    print('held', flush=True); time.sleep(60)", str(out)],
                              stdout=subprocess.PIPE, text=True)
    try:
        assert holder.stdout.readline().strip() == "held"
        res = runner.invoke(app, args + ["--resume"])
    finally:
        holder.kill()
        holder.wait()
        holder.stdout.close()
    assert res.exit_code == 2, res.output
    (line,) = res.stderr.strip().splitlines()
    assert f"--out {out} is in use by another hapticopt run (pid {holder.pid})" in line
    with RunReader(out) as r:
        assert len(r) == 2 and r.n_repeated == 0


def test_an_empty_only_is_refused(tmp_path):
    """Issue 37: ``--only ""`` reported every point ok while evaluating nothing."""
    res = runner.invoke(app, ["sweep", "--preset", "prrr-paper", "geometry.beta_deg=30:70:2", "--only", "",
                              "--out", str(tmp_path / "o"), "--quiet"])
    assert res.exit_code == 2 and "--only names no evaluator: allowed one or more of statics" in res.stderr
    assert not (tmp_path / "o").exists()
