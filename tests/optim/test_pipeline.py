"""Pipeline: optimise → fine re-evaluation → export → verify → report, and the bundled problems."""

from __future__ import annotations

import json
import math
import re
import sys
import time
from pathlib import Path

import pytest

from hapticopt.optim.pipeline import run_pipeline
from hapticopt.optim.problem import load_problem

DATA = Path(__file__).parent / "data"
BETA_ISO_DEG = math.degrees(math.atan(1.0 / math.sqrt(2.0)))  # seed 002 isotropic angle


@pytest.fixture(scope="module")
def beta_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("beta")
    return run_pipeline(load_problem(DATA / "beta-isotropic.toml"), out_dir=out, scheduler="inline",
                        export=False, verify=False)


def test_pipeline_writes_the_run_directory(beta_run):
    out = beta_run.out_dir
    for name in ("evaluations.sqlite", "optimum.toml", "result.json", "report.md", "report.html", "convergence.svg"):
        assert (out / name).is_file(), name
    result = json.loads((out / "result.json").read_text())
    assert abs(result["best_x"]["geometry.beta_deg"] - BETA_ISO_DEG) <= 0.01
    assert result["feasible_at_final_fidelity"] and result["improved_on_baseline"]
    assert [s["stage"] for s in result["stages"]][:3] == ["baseline", "optimise", "final"]
    from hapticopt.design import io

    opt = io.load_design(out / "optimum.toml")
    assert math.degrees(opt.geometry.beta) == pytest.approx(result["best_x"]["geometry.beta_deg"], abs=1e-9)


def test_report_tables_and_relative_images(beta_run):
    out = beta_run.out_dir
    md = (out / "report.md").read_text()
    html = (out / "report.html").read_text()
    assert "| geometry.beta_deg | deg | 10 | 80 | 60 | 35.2644 |" in md  # baseline prrr-paper 60°, optimum β*
    assert "max_force_N[2] >= 1000" in md and "jacobian_condition" in md
    # every image is linked relatively and exists
    srcs = re.findall(r'<img src="([^"]+)"', html)
    assert "convergence.svg" in srcs
    for src in srcs:
        assert not src.startswith(("/", "file:", "http")) and (out / src).is_file(), src
    svg = (out / "convergence.svg").read_text()
    assert "<svg" in svg[:400] and "jacobian_condition [-]" in svg and "evaluation (order of request) [-]" in svg


def test_final_fidelity_constraint_check(beta_run):
    (text, value, ok), = beta_run.constraints_final
    assert text == "max_force_N[2] >= 1000" and ok
    assert value == pytest.approx(3581.0, rel=1e-3)  # F_z max = 3 F_max (seed 002 Table 1)


def test_export_and_verify_stages_call_the_landed_modules(tmp_path, monkeypatch):
    """The pipeline calls hapticopt.design.export.export and the closed-loop runner (stand-ins here)."""
    from hapticopt.design import export as design_export

    calls = {}

    def export(design, out_dir, *, render=False, joint_limits=None):
        calls["export"] = design.name
        calls["joint_limits"] = joint_limits
        step = Path(out_dir) / f"{design.name}.step"
        step.write_text("ISO-10303-21;")
        return design_export.ExportResult(out_dir=Path(out_dir), files=(step,), timings_s={}, total_mass_kg=0.0)

    monkeypatch.setattr(design_export, "export", export)
    monkeypatch.syspath_prepend(str(DATA))  # the stand-in runner must import in the child process
    import fake_verifier

    import dataclasses

    problem = dataclasses.replace(load_problem(DATA / "beta-isotropic.toml"),
                                  scenes=("free-space", "unstable-scene", "soft-scene", "hangs"), verify_max_time_s=15.0)
    problem = problem.with_optimiser(max_evals=20, starts=1)
    res = run_pipeline(problem, out_dir=tmp_path, scheduler="inline", verifier=fake_verifier.run_scene)
    assert calls["export"] == "beta-isotropic-optimum"
    # the MJCF's R-joint ranges come from the joint-limits evaluator (issue 30): at least the elbow's
    assert calls["joint_limits"] is not None and calls["joint_limits"].r2 is not None
    stages = {s.name: s for s in res.stages}
    assert stages["export"].status == "ok" and "beta-isotropic-optimum.step" in stages["export"].files
    assert [(v.scene, v.passed) for v in res.verdicts] == [("free-space", True), ("unstable-scene", False),
                                                           ("soft-scene", False), ("hangs", False)]
    assert "stiffness error 25 % > 10 %" in res.verdicts[2].message  # issue 6's 10 % bound
    assert "no result within 15 s" in res.verdicts[3].message  # a spawned child under load needs > 5 s
    assert stages["verify"].status == "1/4 passed"
    md = (tmp_path / "report.md").read_text()
    assert "| unstable-scene | FAIL |" in md and "beta-isotropic-optimum.step" in md
    # every scene that returned traces has its time histories in the report; the hung one has none
    assert [v.history is not None for v in res.verdicts] == [True, True, True, False]
    for i, scene in enumerate(("free-space", "unstable-scene", "soft-scene")):
        assert f"![{scene}](plots/loop-{i}-{scene}.png)" in md and (tmp_path / f"plots/loop-{i}-{scene}.png").is_file()
    assert res.verdicts[1].history.stopped_at_s == pytest.approx(0.6)  # fake_verifier.STOP_TICK × PERIOD_S


def test_verify_scenes_share_one_worker_and_survive_a_crash_and_a_hang(tmp_path, monkeypatch):
    """Issue 22: the scenes run in one worker process; a scene that segfaults or hangs fails its own verdict
    only, and the scenes after it run in a fresh process (the safety the process per scene gave)."""
    monkeypatch.syspath_prepend(str(DATA))
    import fake_verifier

    from hapticopt.analysis.fidelity import Fidelity
    from hapticopt.optim.pipeline import _verify, verification_worker

    scenes = ("free-space", "soft-scene", "segfaults", "free-space", "hangs", "free-space")
    with verification_worker() as w:
        stage, verdicts = _verify(None, scenes, tmp_path, Fidelity.DRAFT, 3.0, fake_verifier.crashes, w)
        assert w.starts == 3  # one, then one after the crash, one after the hang
    assert [v.passed for v in verdicts] == [True, False, False, True, False, True]
    assert verdicts[1].metrics["stiffness_error_pct"] == 25.0
    assert verdicts[2].metrics == {} and verdicts[2].message == "the worker process died (killed by SIGSEGV)"
    assert "no result within 3 s" in verdicts[4].message
    assert stage.status == "3/6 passed"


@pytest.mark.slow
def test_bundled_prrr_problem_improves_on_the_paper_design(tmp_path):
    import dataclasses

    from hapticopt.analysis.fidelity import Fidelity

    # standard instead of fine for the final check: fine adds the CAD solid FEA (minutes; make run does it)
    problem = dataclasses.replace(load_problem("prrr-workspace"), fidelity_final=Fidelity.STANDARD)
    res = run_pipeline(problem, out_dir=tmp_path, scheduler="inline", export=False, verify=False)
    assert res.improved and res.feasible_final
    obj = problem.objective.metric
    assert obj.value(res.optimum.metrics) > obj.value(res.baseline.metrics)
    assert all(ok for _, _, ok in res.constraints_final)


@pytest.mark.slow
def test_local_runs_overlap_in_a_side_process_with_the_inline_numbers(tmp_path, beta_run):
    """The local scheduler: the base design's final-fidelity evaluation queued in the optimisation's
    pool, the export in the side process (optim/side.py). Every number equals the inline run's
    (each evaluation is a pure function of design and fidelity), the export files are there."""
    res = run_pipeline(load_problem(DATA / "beta-isotropic.toml"), out_dir=tmp_path, scheduler="local", workers=2,
                       export=True, verify=False)
    for ev in ("baseline", "optimum"):
        for key in ("metrics", "statuses", "messages", "modules"):
            assert json.dumps(getattr(getattr(res, ev), key)) == json.dumps(getattr(getattr(beta_run, ev), key))
    assert res.run.best.x == beta_run.run.best.x
    stage = {s.name: s for s in res.stages}
    assert stage["baseline"].message == ("draft fidelity computed; standard fidelity computed in worker processes "
                                         "beside the optimisation and the final evaluation")
    assert stage["export"].status == "ok" and "in a second process" in stage["export"].message
    assert any(f.endswith(".step") for f in stage["export"].files)
    assert all((tmp_path / f).is_file() for f in stage["export"].files)


@pytest.fixture(scope="module")
def verified_run(tmp_path_factory, beta_run):
    """A short run whose verification returns time histories (the stand-in runner of fake_verifier)."""
    import dataclasses

    sys.path.insert(0, str(DATA))  # the stand-in runner must import in the child process
    try:
        import fake_verifier

        problem = dataclasses.replace(load_problem(DATA / "beta-isotropic.toml"), scenes=("free-space", "unstable-scene"),
                                      verify_max_time_s=30.0).with_optimiser(max_evals=20, starts=2)
        return run_pipeline(problem, out_dir=tmp_path_factory.mktemp("verified"), scheduler="inline", export=False,
                            verifier=fake_verifier.run_scene)
    finally:
        sys.path.remove(str(DATA))


def test_report_opens_in_headless_chromium(verified_run):
    """scripts/check_report_browser.py: the HTML report loads in a real browser with every image, no
    console error and no horizontal overflow (page width ≤ window width at 1200 and 800 px); the
    full-page screenshot is a picture of the whole page, not blank. Skipped only without chromium
    (CI installs it: .ci/run)."""
    import importlib.util
    import shutil

    if shutil.which("chromium") is None:
        pytest.skip("Debian package chromium is not installed (apt-get install chromium)")
    script = Path(__file__).parents[2] / "scripts" / "check_report_browser.py"
    spec = importlib.util.spec_from_file_location("check_report_browser", script)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    out = verified_run.out_dir
    shot = out.parent / "report-1200.png"
    assert module.check(out, width=1200, screenshot=shot) == []
    assert module.check(out, width=800) == []
    from PIL import Image

    with Image.open(shot) as im:
        assert im.width == 1200 and im.height > 2000  # the whole report, several screens tall
        grey = im.convert("L")
        assert grey.getextrema()[0] < 100  # text and figures, not a blank page
    broken = out.parent / "broken"
    shutil.copytree(out, broken)
    html = (broken / "report.html").read_text().replace('src="convergence.svg"', 'src="nope.png"')
    (broken / "report.html").write_text(html)
    assert "image did not load: nope.png" in module.check(broken)
    wide = out.parent / "wide"
    shutil.copytree(out, wide)
    html = (wide / "report.html").read_text().replace("</body>", '<div style="width:3000px">x</div></body>')
    (wide / "report.html").write_text(html)
    assert any(p.startswith("horizontal overflow") for p in module.check(wide))
    noisy = out.parent / "noisy"
    shutil.copytree(out, noisy)
    html = (noisy / "report.html").read_text().replace("</body>", "<script>console.error('boom')</script></body>")
    (noisy / "report.html").write_text(html)
    assert any("boom" in p for p in module.check(noisy))


def test_the_record_describes_itself(beta_run):
    """Issue 20 item 2: variables with units, objectives and constraints, baseline and final rows."""
    from hapticopt.optim.runs import RunReader

    with RunReader(beta_run.out_dir) as r:
        assert r.kind == "optimise" and r.problem == "beta-isotropic" and r.status == "finished"
        assert r.variables == [{"key": "geometry.beta_deg", "unit": "deg", "lower": 10.0, "upper": 80.0,
                                "start": 60.0}]
        assert r.objectives == [{"metric": "jacobian_condition", "sense": "minimise"}]
        assert r.constraints == [{"metric": "max_force_N[2]", "op": ">=", "value": 1000.0}]
        assert "isotropic" in r.info["problem_text"] and r.info["fidelity"] == {"optimise": "draft",
                                                                                 "final": "standard"}
        base, final = r.design("baseline"), r.design("final")
        assert base.fidelity == "draft" and final.fidelity == "standard"
        assert base.metrics["jacobian_condition"] == pytest.approx(math.sqrt(6.0))  # cond(J) at 60°: √6
        assert final.x == beta_run.run.best.x
        assert r.best().x == beta_run.run.best.x and r.n_repeated == 0


def test_killed_at_random_moments_then_resumed(tmp_path):
    """Issue 14: kill the pipeline (pool workers, verification child) with SIGKILL during the
    baseline and at a random later moment; every child is gone within 5 s, ``--resume`` finishes
    with the uninterrupted result, no evaluation is repeated and no temp file is left. A second
    process on the same run directory is refused while one is alive. (scripts/kill_resume.py
    does the same at ≥ 10 moments, export included.)"""
    import random
    import subprocess
    import sys as _sys

    sys.path.insert(0, str(Path(__file__).parent))
    import killing
    from hapticopt.optim import driver

    problem = load_problem(DATA / "beta-isotropic.toml").with_optimiser(max_evals=30, starts=2)
    reference = driver.run(problem, only=("statics",))  # what the pipeline's optimiser must reach
    run = tmp_path / "run"
    rng = random.Random(14)

    # 1. during the baseline: as soon as the run database exists, before any stage is recorded
    p = killing.start(run)
    t0 = time.monotonic()
    while not (run / "evaluations.sqlite").exists():
        assert p.poll() is None and time.monotonic() - t0 < 60
        time.sleep(0.02)
    killed, kids, gone_s = killing.kill_after(p, 0.0)
    assert killed and gone_s <= 5.0
    n1, _ = killing.recorded(run)

    # 2. resume, and kill again at a random moment (optimise, final, plots, verify or report)
    p = killing.start(run, "--resume")
    t0 = time.monotonic()
    while killing.recorded(run)[1] == 0:  # the baseline recorded: the run is under way again
        assert p.poll() is None and time.monotonic() - t0 < 60
        time.sleep(0.05)
    # meanwhile a second process on the same directory is refused with one line
    other = subprocess.run([_sys.executable, str(killing.SCRIPT), str(run), "--resume"], env=killing.env(),
                           capture_output=True, text=True)
    assert other.returncode != 0 and "is in use by another hapticopt run" in other.stderr
    killed, kids, gone_s = killing.kill_after(p, rng.uniform(0.5, 6.0))
    assert gone_s <= 5.0, f"children outlived the parent: {kids}"
    n2, _ = killing.recorded(run)

    # 3. resume to the end
    out = subprocess.run([_sys.executable, str(killing.SCRIPT), str(run), "--resume"], env=killing.env(),
                         capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr[-2000:]
    res = json.loads(out.stdout.strip().splitlines()[-1])
    assert res["best_x"] == list(reference.best.x) and res["best_f"] == reference.best.f
    assert res["n_replayed"] == n2 and res["n_evaluated"] == reference.n_evaluated - n2  # nothing repeated
    assert killing.recorded(run)[0] == reference.n_evaluated
    assert killing.leftovers(run) == []
    assert json.loads((run / "result.json").read_text())["n_evaluated"] == res["n_evaluated"]
    del n1, killed


def test_the_base_design_is_evaluated_once_across_runs(tmp_path):
    """Evaluation cache (issue 22): a second run into the same --out (--force), and a run of another
    problem on the same base design, serve the base design's evaluations from the cache, bit for bit,
    and say so in the stage message and result.json; without a cache they are computed."""
    out, cache = tmp_path / "run", tmp_path / "run" / "evaluation-cache.sqlite"
    problem = load_problem(DATA / "beta-isotropic.toml")
    kw = dict(scheduler="inline", export=False, verify=False)
    first = run_pipeline(problem, out_dir=out, cache=cache, **kw)
    second = run_pipeline(problem, out_dir=out, force=True, cache=cache, **kw)
    note = lambda res: next(s.message for s in res.stages if s.name == "baseline")  # noqa: E731
    assert note(first) == "draft fidelity computed; standard fidelity computed"
    assert note(second).count(f"from the evaluation cache {cache}") == 2
    assert json.dumps(second.baseline.metrics) == json.dumps(first.baseline.metrics)  # repr: every bit of every float
    stage = next(s for s in json.loads((out / "result.json").read_text())["stages"] if s["stage"] == "baseline")
    assert "from the evaluation cache" in stage["message"]
    other_text = (DATA / "beta-isotropic.toml").read_text().replace('name = "beta-isotropic"', 'name = "beta-other"')
    (tmp_path / "other.toml").write_text(other_text.replace('metric = "max_force_N[2]"', 'metric = "max_force_N[1]"'))
    other = run_pipeline(load_problem(tmp_path / "other.toml"), out_dir=tmp_path / "other", cache=cache, **kw)
    assert note(other).count("from the evaluation cache") == 2
    fresh = run_pipeline(problem, out_dir=out, force=True, cache=None, **kw)
    assert note(fresh) == "draft fidelity computed; standard fidelity computed"


def test_verification_worker_warms_the_compiled_mujoco_loops_only_when_a_scene_needs_them():
    """A verify scene on a MuJoCo plant (any master scene, a 3-PRRR scene with link dynamics): the worker loads the
    compiled loops at start (numba import + cache load, docs/performance.md); lumped scenes: it does not."""
    from hapticopt.optim.pipeline import verification_worker, warm_verification

    lumped = verification_worker(["free-space", "stiffness-25", "virtual-box"])
    assert lumped._warm is warm_verification
    for scenes in (["master-wall"], ["stiffness-25", "stiffness-25-links"]):
        warm = verification_worker(scenes)._warm
        assert warm.func is warm_verification and warm.args == (True,)
