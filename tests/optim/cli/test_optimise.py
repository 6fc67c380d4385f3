"""``hapticopt optimise`` / ``problems``: a run, --resume replays everything, bad problems exit 2."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from typer.testing import CliRunner

from hapticopt.optim.cli import app

runner = CliRunner()
DATA = Path(__file__).parents[1] / "data"


def invoke(*args: str):
    return runner.invoke(app, list(args))


def test_problems_lists_bundled():
    res = invoke("problems")
    assert res.exit_code == 0
    assert "prrr-workspace" in res.stdout and "master-transparency" in res.stdout


def test_optimise_then_resume_replays_everything(tmp_path):
    args = ["optimise", str(DATA / "beta-isotropic.toml"), "--out", str(tmp_path), "--scheduler", "inline",
            "--no-export", "--no-verify", "--quiet", "--max-evals", "40"]
    first = invoke(*args)
    assert first.exit_code == 0, first.output
    assert "jacobian_condition baseline 2.44949 -> optimum 1.0" in first.stdout  # cond(J) at 60°: √6 (seed digest)
    assert "(improved)" in first.stdout
    r1 = json.loads((tmp_path / "result.json").read_text())
    again = invoke(*args, "--resume")
    assert again.exit_code == 0, again.output
    r2 = json.loads((tmp_path / "result.json").read_text())
    assert r2["n_evaluated"] == 0 and r2["n_replayed"] == r1["n_evaluated"]
    assert r2["best_x"] == r1["best_x"]
    # a different problem is a different run: resuming it is refused with one line
    other = tmp_path / "other.toml"
    other.write_text((DATA / "beta-isotropic.toml").read_text().replace("upper = 80.0", "upper = 75.0"))
    bad = invoke("optimise", str(other), *args[2:], "--resume")
    assert bad.exit_code == 2 and "different problem or optimiser settings" in bad.stderr


def _md5(path):
    import hashlib

    return hashlib.md5(path.read_bytes()).hexdigest()


def test_existing_run_is_refused_forced_or_extended(tmp_path):
    """Issue 20 item 1: a second run without flags is refused (exit 2, one line, file unchanged);
    --force replaces it; --resume --max-evals N extends it with 0 repeated evaluations."""
    from hapticopt.optim.runs import RunReader

    args = ["optimise", str(DATA / "beta-isotropic.toml"), "--out", str(tmp_path), "--scheduler", "inline",
            "--no-export", "--no-verify", "--quiet"]
    first = invoke(*args, "--max-evals", "12")
    assert first.exit_code == 0, first.output
    db = tmp_path / "evaluations.sqlite"
    before = _md5(db)
    again = invoke(*args, "--max-evals", "12")
    assert again.exit_code == 2
    (line,) = again.stderr.strip().splitlines()
    assert "already holds a run" in line and "--resume" in line and "--force" in line
    assert _md5(db) == before
    both = invoke(*args, "--resume", "--force")
    assert both.exit_code == 2 and "contradict" in both.stderr and _md5(db) == before
    with RunReader(tmp_path) as r:
        n1 = len(r)
    assert r.status == "finished" and n1 == 12 - 1  # 12 points asked, one (the start) asked twice: cache
    ext = invoke(*args, "--resume", "--max-evals", "40")
    assert ext.exit_code == 0, ext.output
    r2 = json.loads((tmp_path / "result.json").read_text())
    with RunReader(tmp_path) as r:
        sessions = r.sessions()
        assert r.n_repeated == 0 and len(r) == n1 + r2["n_evaluated"]
        keys = [c.x for c in r.cases()]
    assert len(keys) == len(set(keys))  # every recorded point is distinct
    assert r2["n_replayed"] == n1 and r2["n_evaluated"] > 0
    assert [(s["max_evals"], s["evaluated"], s["replayed"], s["repeated"]) for s in sessions] == \
        [(12, n1, 0, 0), (40, r2["n_evaluated"], n1, 0)]
    forced = invoke(*args, "--max-evals", "12", "--force")
    assert forced.exit_code == 0, forced.output
    with RunReader(tmp_path) as r:
        assert len(r) == n1 and len(r.sessions()) == 1


def _write(tmp_path, text):
    p = tmp_path / "p.toml"
    p.write_text(text)
    return str(p)


HEAD = 'name = "x"\nbase = "prrr-paper"\n'
VAR = '[[variables]]\nkey = "geometry.beta_deg"\nlower = 20.0\nupper = 70.0\n'
OBJ = '[objective]\nmetric = "jacobian_condition"\n'


@pytest.mark.parametrize("text, match", [
    (HEAD + VAR + '[objective]\nmetric = "no_such_metric_N"\n', "'no_such_metric_N' is not a metric of a prrr design"),
    (HEAD + '[[variables]]\nkey = "geometry.beta_deg"\nlower = 70.0\nupper = 20.0\n' + OBJ, "must be below upper"),
    (HEAD + '[[variables]]\nkey = "geometry.gamma_deg"\n' + OBJ, "is not a variable of the design"),
    (HEAD + '[[variables]]\nkey = "geometry.beta_deg"\nlower = 20.0\nupper = 50.0\n' + OBJ, "infeasible start"),
    (HEAD + VAR + OBJ + '[[constraints]]\nmetric = "max_force_N"\nmin = 3.0\n', "give a component index"),
    ("name = [\n", "is not valid TOML"),
])
def test_bad_problem_files_one_line_exit_2(tmp_path, text, match):
    res = invoke("optimise", _write(tmp_path, text), "--out", str(tmp_path / "run"), "--quiet",
                 "--scheduler", "inline")
    assert res.exit_code == 2
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: ")
    assert match in lines[0]
    assert not (tmp_path / "run").exists()  # no partial run: the corrected rerun needs no --force


def test_a_misspelt_metric_is_found_before_any_work_and_the_fixed_rerun_needs_no_force(tmp_path, monkeypatch):
    """issue 33 acceptance: `workspace_volum_mm3` took 12 s of work to find, without a did-you-mean, and
    left a partial run that the corrected rerun refused without --force."""
    from hapticopt.optim import pipeline

    text = (DATA / "beta-isotropic.toml").read_text()
    typo = _write(tmp_path, text.replace('[[constraints]]\nmetric = "max_force_N[2]"\nmin = 1000.0',
                                         '[[constraints]]\nmetric = "workspace_volum_mm3"\nmin = 1.0'))
    out = tmp_path / "run"
    args = ["--out", str(out), "--quiet", "--scheduler", "inline", "--no-export", "--no-verify", "--max-evals", "4"]
    with monkeypatch.context() as m:  # nothing is evaluated before the problem is found bad
        m.setattr(pipeline, "run_pipeline", lambda *a, **k: pytest.fail("the pipeline ran on a bad problem"))
        res = invoke("optimise", typo, *args)
    assert res.exit_code == 2
    (line,) = res.stderr.strip().splitlines()
    assert "did you mean workspace_volume_mm3?" in line and "constraints (workspace_volum_mm3 >= 1)" in line
    assert sorted(p.name for p in tmp_path.iterdir()) == ["p.toml"]  # no files written
    fixed = _write(tmp_path, text.replace('metric = "max_force_N[2]"\nmin = 1000.0',
                                          'metric = "workspace_volume_mm3"\nmin = 1.0'))
    again = invoke("optimise", fixed, *args)  # no --force
    assert again.exit_code == 0, again.output


def test_missing_problem_and_bad_options(tmp_path):
    res = invoke("optimise", "no-such-problem", "--quiet")
    assert res.exit_code == 2 and "allowed problems are" in res.stderr
    res = invoke("optimise", str(DATA / "beta-isotropic.toml"), "--out", str(tmp_path), "--scheduler", "ftp://x",
                 "--quiet", "--no-export", "--no-verify")
    assert res.exit_code == 2 and "--scheduler" in res.stderr
    res = invoke("optimise", str(DATA / "beta-isotropic.toml"), "--max-evals", "1", "--quiet")
    assert res.exit_code == 2 and "--max-evals = 1" in res.stderr


def test_two_objective_problem_traces_a_front(tmp_path):
    from hapticopt.optim.runs import RunReader

    text = (DATA / "beta-front.toml").read_text().replace("points = 41", "points = 5").replace("max_evals = 2000",
                                                                                              "max_evals = 200")
    problem = tmp_path / "front.toml"
    problem.write_text(text)
    out = tmp_path / "run"
    res = invoke("optimise", str(problem), "--out", str(out), "--scheduler", "inline", "--quiet")
    assert res.exit_code == 0, res.output
    assert "Pareto front of stiffness_limit_N_per_mm[0] and workspace_height_at_diameter_mm: 5 points" in res.stdout
    for name in ("front.csv", "front.svg", "chosen.toml", "result.json", "report.md", "report.html"):
        assert (out / name).is_file(), name
    result = json.loads((out / "result.json").read_text())
    assert len(result["front"]) == 5 and result["chosen"]["feasible_at_final_fidelity"]
    assert "front.svg" in (out / "report.html").read_text() and "polyline" in (out / "front.svg").read_text()
    with RunReader(out) as r:
        assert r.kind == "pareto" and r.status == "finished" and len(r.objectives) == 2
        assert len([d for d in r.designs() if d.role == "front"]) == 5 and r.design("chosen") is not None
    again = invoke("optimise", str(problem), "--out", str(out), "--scheduler", "inline", "--quiet")
    assert again.exit_code == 2 and "already holds a run" in again.stderr
    resumed = invoke("optimise", str(problem), "--out", str(out), "--scheduler", "inline", "--quiet", "--resume")
    assert resumed.exit_code == 0 and "0 evaluated" in resumed.stdout


def test_an_infeasible_final_point_is_best_infeasible_and_exits_3(tmp_path):
    # max_force_N[2] = 3 F_max = 3581 N at every β (seed 002 Table 1: z force of the three SEAs in
    # parallel, independent of β), so a 10 kN minimum cannot hold anywhere
    prob = tmp_path / "impossible.toml"
    prob.write_text((DATA / "beta-isotropic.toml").read_text().replace("min = 1000.0", "min = 10000.0")
                    .replace('name = "beta-isotropic"', 'name = "impossible"'))
    out = tmp_path / "run"
    res = invoke("optimise", str(prob), "--out", str(out), "--scheduler", "inline", "--no-export", "--no-verify",
                 "--quiet", "--max-evals", "6")
    assert res.exit_code == 3, res.output
    assert "NOT satisfied" in res.stdout
    assert res.stderr.startswith("not met: the final point is infeasible") and "max_force_N[2]" in res.stderr
    assert (out / "best_infeasible.toml").is_file() and not (out / "optimum.toml").exists()
    result = json.loads((out / "result.json").read_text())
    assert not result["feasible_at_final_fidelity"] and result["files"]["best_infeasible"] == "best_infeasible.toml"
    assert "optimum" not in result["files"]


def test_a_failed_export_exits_5_with_one_line(tmp_path, monkeypatch):
    """Issue 37, item 5: a failed export (full disk, a path refused) exited 0 with a stdout line only."""
    from hapticopt.optim import side

    monkeypatch.setattr(side, "export", lambda design, out_dir, on_step=None: (
        "failed", "No space left on device: parts/base.stl", (), 0.0))
    out = tmp_path / "run"
    res = invoke("optimise", str(DATA / "beta-isotropic.toml"), "--out", str(out), "--scheduler", "inline",
                 "--no-verify", "--quiet", "--max-evals", "6")
    assert res.exit_code == 5, res.output
    (line,) = res.stderr.strip().splitlines()
    assert line.startswith("error: export failed: No space left on device: parts/base.stl")
    assert (out / "report.html").is_file() and (out / "optimum.toml").is_file()  # the rest of the run is written


def test_resume_that_adds_nothing_says_why_in_one_line_and_keeps_the_export(tmp_path):
    """issue 33: `--resume --max-evals 600` on a finished run reported 0 new evaluations, redid export and
    report, and did not say why. β alone with xtol_rel 1e-3 converges (COBYLA) inside 40 evaluations."""
    problem = _write(tmp_path, (DATA / "beta-isotropic.toml").read_text().replace("xtol_rel = 1e-8", "xtol_rel = 1e-3"))
    args = ["optimise", problem, "--out", str(tmp_path / "run"), "--scheduler", "inline", "--no-verify", "--quiet"]
    tmp_path = tmp_path / "run"
    first = invoke(*args, "--max-evals", "40")
    assert first.exit_code == 0, first.output
    r1 = json.loads((tmp_path / "result.json").read_text())
    assert all(s["status"] != "maxeval_reached" for s in r1["starts"]), r1["starts"]  # converged on its own
    assert r1["exported"] and all((tmp_path / f).is_file() for f in r1["exported"])
    stamps = {f: (tmp_path / f).stat().st_mtime_ns for f in r1["exported"]}
    same = invoke(*args, "--resume", "--max-evals", "40")  # no new budget
    assert same.exit_code == 0, same.output
    (line,) = [ln for ln in same.stderr.splitlines() if ln.startswith("resume:")]
    assert "already finished with its budget of 40" in line and "its export was kept" in line
    assert {f: (tmp_path / f).stat().st_mtime_ns for f in r1["exported"]} == stamps  # not recomputed
    r2 = json.loads((tmp_path / "result.json").read_text())
    assert r2["n_evaluated"] == 0 and r2["exported"] == r1["exported"]
    more = invoke(*args, "--resume", "--max-evals", "80")  # a larger budget the converged optimiser cannot use
    assert more.exit_code == 0, more.output
    (line,) = [ln for ln in more.stderr.splitlines() if ln.startswith("resume:")]
    assert "0 new evaluations" in line and "stopped on its own before its budget of 40" in line
    assert "xtol_reached" in line or "ftol_reached" in line or "success" in line
