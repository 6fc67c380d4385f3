"""Sweeps: axes and their one-line errors, closed-form values along β, resume after an
interruption, and a 2-D sweep on a Dask cluster (loopback) equal bit for bit to the process pool."""

from __future__ import annotations

import math

import numpy as np
import pytest

from hapticopt.analysis.fidelity import Fidelity
from hapticopt.design import io
from hapticopt.design.errors import InvalidInput
from hapticopt.optim.evaluation import Outcome
from hapticopt.optim.executor import InlineExecutor, make_executor
from hapticopt.optim.recorder import Recorder
from hapticopt.optim.sweep import Sweep, csv_text, metric_label, parse_axis, run_sweep

BASE = io.load_preset("prrr-paper")
ONLY = ("statics",)


def _sweep(*axes: str) -> Sweep:
    return Sweep(base=BASE, axes=tuple(parse_axis(a, BASE) for a in axes), fidelity=Fidelity.DRAFT, only=ONLY)


def test_axis_values_include_both_ends():
    a = parse_axis("geometry.beta_deg = 30:70:5", BASE)
    assert a.values == (30.0, 40.0, 50.0, 60.0, 70.0) and a.unit == "deg" and a.label == "geometry.beta_deg [deg]"
    s = _sweep("geometry.beta_deg=30:70:3", "actuator.spring_N_per_mm=20:100:2")
    assert s.points() == [(30.0, 20.0), (30.0, 100.0), (50.0, 20.0), (50.0, 100.0), (70.0, 20.0), (70.0, 100.0)]


@pytest.mark.parametrize("text, match", [
    ("geometry.gamma_deg=1:2:3", "is not a numeric key of the design: allowed keys in \\[geometry\\]"),
    ("geometry.beta_deg=70:30:3", "lo = 70 must be below hi = 30 \\(deg\\)"),
    ("geometry.beta_deg=30:70:1", "n = 1 is out of range: allowed 2 ≤ n ≤ 100000"),
    ("geometry.beta_deg=30:70:x", "n = 'x' must be a whole number"),
    ("name=1:2:3", "is not a numeric design key"),
    ("description=1:2:3", "is not a numeric design key"),
    ("geometry.beta_deg=30:95:3", "hi = 95 is out of range: allowed 0 < beta_deg < 90 \\(deg\\)"),
    ("geometry.beta_deg=a:b:3", "must have the form section.key=lo:hi:n"),
    ("handle.mass_kg=1:2:3", "handle is not a section of a prrr design"),
])
def test_bad_axes_are_one_line_errors(text, match):
    with pytest.raises(InvalidInput, match=match):
        parse_axis(text, BASE)


def test_bad_sweeps():
    with pytest.raises(InvalidInput, match="given twice"):
        _sweep("geometry.beta_deg=30:70:3", "geometry.beta_deg=30:60:3")
    with pytest.raises(InvalidInput, match="1 or 2 axes"):
        _sweep("geometry.beta_deg=30:70:3", "geometry.d3_mm=60:90:3", "geometry.d4_mm=60:90:3")
    with pytest.raises(InvalidInput, match="--only 'nope' is not an evaluator of a prrr design"):
        Sweep(base=BASE, axes=(parse_axis("geometry.beta_deg=30:70:3", BASE),), only=("nope",))


def test_1d_sweep_follows_the_closed_form():
    """x-axis rendered-stiffness limit of the 3-PRRR: k_x = 3k/(2 tan²β) (seed 002 eq 15: k/2 at 60°)."""
    # 28…60°: prrr-paper's parts are laid out there (outside, analysis.prrr.geometry.assembly.check_built refuses:
    # no carriage face carries the R1 clevis below ≈ 21°, the R3 lugs meet the stem above 60°)
    s = _sweep("geometry.beta_deg=28:60:9")
    res = run_sweep(s, executor=InlineExecutor())
    k = BASE.actuator.spring * 1e-3  # N/mm
    assert res.n_ok == 9 and res.n_evaluated == 9
    for (beta,), r in zip(res.points, res.results):
        expected = 3.0 * k / (2.0 * math.tan(math.radians(beta)) ** 2)
        assert r.metrics["stiffness_limit_N_per_mm"][0] == pytest.approx(expected, rel=1e-12)
    head = csv_text(res).splitlines()[0].split(",")
    assert head[:2] == ["geometry.beta_deg [deg]", "outcome"] and "stiffness_limit_N_per_mm[0]" in head
    assert metric_label("stiffness_limit_N_per_mm[0]") == "stiffness_limit_N_per_mm[0] [N/mm]"
    assert metric_label("jacobian_condition") == "jacobian_condition [-]"


def test_interrupted_sweep_resumes_without_recomputing(tmp_path):
    s = _sweep("geometry.beta_deg=30:60:7", "actuator.spring_N_per_mm=20:100:3")  # 30…60°: buildable (above)
    full = run_sweep(s, executor=InlineExecutor())

    class Stop(BaseException):
        pass

    def stop_after(done, total):
        if done >= 8:
            raise Stop

    with Recorder(tmp_path, fingerprint=s.fingerprint(), resume=False) as rec:
        with pytest.raises(Stop):
            run_sweep(s, executor=InlineExecutor(), recorder=rec, progress=stop_after)
    with Recorder(tmp_path, fingerprint=s.fingerprint(), resume=True) as rec:
        again = run_sweep(s, executor=InlineExecutor(), recorder=rec)
        assert rec.n_repeated == 0
    assert again.n_replayed == 8 and again.n_evaluated == 21 - 8
    assert [r.metrics for r in again.results] == [r.metrics for r in full.results]


def test_2d_sweep_on_dask_loopback_equals_process_pool_bit_for_bit():
    from distributed import LocalCluster

    s = _sweep("geometry.beta_deg=30:60:4", "geometry.d3_mm=60:100:3")  # 30…60°: buildable (above)
    with make_executor("local", workers=2) as pool:
        pooled = run_sweep(s, executor=pool, timeout_s=120)
    with LocalCluster(n_workers=1, threads_per_worker=2, processes=False, protocol="tcp", host="127.0.0.1",
                      dashboard_address=None) as cluster:
        assert cluster.scheduler_address.startswith("tcp://127.0.0.1:")
        with make_executor(cluster.scheduler_address) as dask_ex:
            dasked = run_sweep(s, executor=dask_ex, timeout_s=60)  # bounded in time
    assert pooled.n_ok == dasked.n_ok == 12
    assert [r.outcome for r in pooled.results] == [Outcome.OK] * 12
    assert csv_text(pooled) == csv_text(dasked)  # every value printed with repr: bit for bit
    assert [r.metrics for r in pooled.results] == [r.metrics for r in dasked.results]


def test_batched_statics_sweep_equals_the_per_point_sweep():
    """The batched form is one jit-compiled vmap of the same statics_arrays (jax instead of numpy):
    equal to the registry's per-point evaluation to rounding (1e-12 relative), statuses equal."""
    s = _sweep("geometry.beta_deg=20:80:13", "actuator.spring_N_per_mm=20:100:3")
    per_point = run_sweep(s, executor=InlineExecutor())
    batched = run_sweep(s, executor=InlineExecutor(), batch=True)
    assert batched.n_evaluated == per_point.n_evaluated == 39
    for a, b in zip(per_point.results, batched.results):
        assert a.outcome == b.outcome and a.statuses == b.statuses and a.x == b.x
        assert list(a.metrics) == list(b.metrics)
        for name in a.metrics:
            assert np.allclose(a.metrics[name], b.metrics[name], rtol=1e-12, atol=1e-12, equal_nan=True), name
    with pytest.raises(InvalidInput, match="--batch needs a 3-PRRR draft sweep, or --only naming evaluators"):
        run_sweep(Sweep(base=BASE, axes=s.axes, fidelity=Fidelity.STANDARD), executor=InlineExecutor(), batch=True)


def test_batched_draft_sweep_of_every_evaluator_equals_the_per_point_sweep():
    """A 3-PRRR draft sweep with every evaluator through the batched draft evaluator
    (analysis.prrr.draft_batch): outcomes, statuses and metrics equal to the per-point sweep
    (1e-9 relative; the evaluator-level sample is tests/analysis/prrr/test_draft_batch.py)."""
    s = Sweep(base=io.load_preset("prrr-paper"), axes=(parse_axis("geometry.r_p_mm=100:125:3", BASE),))
    per_point = run_sweep(s, executor=InlineExecutor())
    batched = run_sweep(s, executor=InlineExecutor(), batch=True)
    for a, b in zip(per_point.results, batched.results):
        assert a.outcome == b.outcome and a.statuses == b.statuses and a.message == b.message
        assert list(a.metrics) == list(b.metrics)
        for name in a.metrics:
            assert np.allclose(a.metrics[name], b.metrics[name], rtol=1e-9, atol=0.0, equal_nan=True), name
    seen = {st for r in per_point.results for st in r.statuses.values()}
    assert "ok" in seen and seen & {"collides", "not-met"}  # r_p = 100 mm: the links reach the next rail


def test_batched_statics_sweep_says_not_assemblable_as_the_evaluator_does():
    # d2 = 300 mm cannot close the chain (tests/analysis/prrr/geometry/test_assembly.py derives why)
    s = _sweep("geometry.d2_mm=80:300:3")
    per_point = run_sweep(s, executor=InlineExecutor())
    batched = run_sweep(s, executor=InlineExecutor(), batch=True)
    assert [r.statuses for r in batched.results] == [r.statuses for r in per_point.results]
    assert batched.results[-1].statuses == {"statics": "not-assemblable"}
    assert batched.results[0].statuses == {"statics": "ok"}
