"""hapticopt.analysis.prrr.shared: one registry call takes each shared step once, and its results are
those of every evaluator taking the steps itself."""

from __future__ import annotations

import math

import numpy as np
import pytest

from hapticopt.analysis import registry
from hapticopt.analysis.status import Status
from hapticopt.analysis.fidelity import Fidelity
from hapticopt.analysis.prrr import shared as shared_mod
from hapticopt.design import io
from hapticopt.design.errors import HapticoptError, InvalidInput

from .conftest import _problem_sample

BASE = io.load_preset("prrr-paper")


def _designs() -> list:
    """The preset; d2 = 300 mm (the chain does not close); θ_1p = 70° (the parts cannot be laid out);
    r_p = 100 mm (the φ140 collision-free cylinder is missed); seeded draws within the bundled
    problem's bounds."""
    edits = (["geometry.d2_mm=300"], ["geometry.theta_1p_deg=70"], ["geometry.r_p_mm=100"])
    return [BASE] + [io.apply_overrides(BASE, e) for e in edits] + _problem_sample(8, seed=5)


def _same(a, b) -> bool:
    if isinstance(a, float) and isinstance(b, float):
        return a == b or (math.isnan(a) and math.isnan(b))
    if isinstance(a, list) and isinstance(b, list):
        return len(a) == len(b) and all(_same(x, y) for x, y in zip(a, b))
    return a == b


@pytest.mark.parametrize("fidelity", [Fidelity.DRAFT, Fidelity.STANDARD])
def test_evaluate_all_equals_each_evaluator_alone(fidelity):
    # reference: every evaluator's evaluate(design) without the shared steps (each takes them itself)
    statuses = set()
    for d in _designs():
        ev = registry.evaluate_all(d, fidelity=fidelity)
        if registry.not_built(d):  # the one rule for a design that cannot be built: no evaluator runs
            assert set(ev.statuses.values()) == {Status.NOT_ASSEMBLABLE}
            statuses.add(("device_size", "not-assemblable"))
            continue
        for entry in registry.EVALUATORS["prrr"]:
            if str(fidelity) in entry.on_request_at:  # not run unless asked for (registry.EvaluatorEntry)
                assert entry.name not in ev.statuses
                continue
            try:
                ref = entry.load().evaluate(d, fidelity=fidelity)
            except Exception as exc:  # noqa: BLE001 - the registry's failure policy
                assert ev.messages[entry.name] == registry.describe_failure(exc)
                continue
            got = ev.results[entry.name]
            assert (got.status, got.message) == (ref.status, ref.message), entry.name
            m_ref, m_got = registry.jsonable(ref.metrics()), registry.jsonable(got.metrics())
            assert m_ref.keys() == m_got.keys() and all(_same(m_got[k], m_ref[k]) for k in m_ref), entry.name
            statuses.add((entry.name, ref.status.value))
    # the sample reaches the shared steps' paths: parts laid out (checked, colliding or not) and refused
    assert {("device_size", "ok"), ("device_size", "not-assemblable"), ("interference", "collides"),
            ("interference", "ok"), ("free_workspace", "not-met"), ("free_workspace", "ok")} <= statuses


def test_each_step_runs_once_per_call(monkeypatch):
    calls = []
    real = shared_mod.cad_prrr.part_specs
    monkeypatch.setattr(shared_mod.cad_prrr, "part_specs", lambda d, **kw: calls.append(d) or real(d, **kw))
    registry.evaluate_all(BASE, fidelity=Fidelity.DRAFT)
    assert calls == [BASE]  # workspace, interference, free workspace and device size: one part table
    calls.clear()
    registry.evaluate_all(BASE, fidelity=Fidelity.DRAFT)
    assert calls == [BASE]  # nothing outlives a call


def test_the_layout_runs_once_per_call(monkeypatch):
    """The part tables and the device height take the call's one layout (``assembly.parts``, which also
    lays the parts out, caches its verdict per design: warmed first)."""
    registry.evaluate_all(BASE, fidelity=Fidelity.DRAFT)
    calls = []
    real = shared_mod.cad_prrr.layout
    monkeypatch.setattr(shared_mod.cad_prrr, "layout", lambda d: calls.append(d) or real(d))
    ev = registry.evaluate_all(BASE, fidelity=Fidelity.DRAFT)
    assert calls == [BASE] and ev.statuses["device_size"].value == "ok"


def test_a_refused_layout_skips_the_envelopes_second_try(monkeypatch):
    """Where the CAD cannot lay the parts out, the shared envelope is ``workspace.fallback_envelope``
    without asking for the part tables again (``base_envelope`` would, and fall back to the same)."""
    from hapticopt.analysis.prrr.geometry import workspace
    refused = io.apply_overrides(BASE, ["geometry.theta_1p_deg=70"])  # the parts cannot be laid out
    calls = []
    real = shared_mod.cad_prrr.part_specs
    monkeypatch.setattr(shared_mod.cad_prrr, "part_specs", lambda d, **kw: calls.append(d) or real(d, **kw))
    steps = shared_mod.DesignSteps(refused)
    got = steps.envelope(refused)
    assert calls == []  # the shared layout refused: no part tables asked for
    assert got == workspace.base_envelope(refused) == workspace.fallback_envelope(refused)
    assert calls == [refused]  # base_envelope's own try
    with pytest.raises(HapticoptError):
        steps.part_specs(refused)


def test_a_refused_step_raises_the_same_error_each_time(monkeypatch):
    steps = shared_mod.DesignSteps(BASE)
    refused = HapticoptError("the CAD refuses this layout")
    monkeypatch.setattr(shared_mod.cad_prrr, "part_specs", lambda d, **kw: (_ for _ in ()).throw(refused))
    for _ in range(2):
        with pytest.raises(HapticoptError) as caught:
            steps.part_specs(BASE)
        assert caught.value is refused
    with pytest.raises(HapticoptError) as caught:
        steps.fast_model(BASE)
    assert caught.value is refused


def test_steps_of_another_design_raise():
    steps = shared_mod.DesignSteps(BASE)
    other = io.apply_overrides(BASE, ["geometry.r_p_mm=100"])
    with pytest.raises(InvalidInput, match="allowed only the design they were made for"):
        steps.envelope(other)


def test_reach_entries_do_not_depend_on_the_radial_sampling():
    # what DesignSteps.reach_core relies on: the free workspace evaluator's core (n_r = 2) and the
    # draft workspace evaluator's (n_r = 8) agree bit for bit on the entries the former reads
    from hapticopt.analysis.prrr.geometry import workspace as W
    for d in _designs():
        wp = W.workspace_params(d)
        a, b = W.workspace_core(wp, n_phi=48, n_r=2), W.workspace_core(wp, n_phi=48, n_r=8)
        for k in ("reach_radius", "empty", "footprint_diameter"):
            assert np.array_equal(a[k], b[k]), k


def test_reach_core_hands_out_the_core_computed_first():
    from hapticopt.analysis.prrr.geometry import workspace as W
    steps = shared_mod.DesignSteps(BASE)
    wp = W.workspace_params(BASE)
    first = steps.workspace_core(BASE, wp, n_phi=48, n_r=8)
    assert steps.reach_core(BASE, wp, n_phi=48, n_r=2) is first
    assert steps.workspace_core(BASE, wp, n_phi=48, n_r=2) is not first  # asked as such: its own sampling
    fresh = shared_mod.DesignSteps(BASE)
    assert fresh.reach_core(BASE, wp, n_phi=48, n_r=2)["volume"] == W.workspace_core(wp, n_phi=48, n_r=2)["volume"]


def test_point_checker_equals_check_points_bitwise_and_makes_the_joint_tables_once(monkeypatch):
    # reference: interference_fast.check_points of each pass (the per-design steps taken at every call)
    from hapticopt.analysis.prrr.collision import interference_fast as F  # noqa: PLC0415
    from hapticopt.analysis.prrr.geometry import workspace as W  # noqa: PLC0415

    made = []
    real = F.joint_tables
    for d in _problem_sample(3, seed=11, accept=F.prepare):
        model = F.prepare(d)
        pts, _ = W.workspace_sample_weights(d, **W.INTERFERENCE_SAMPLING)
        passes = [pts[:40], pts[40:41], pts[41:]]  # as the free workspace's grid, then bisection passes
        refs = [F.check_points(model, p, branch=W.ELBOW_BRANCH) for p in passes]
        monkeypatch.setattr(F, "joint_tables", lambda *a: made.append(1) or real(*a))
        check = F.point_checker(model, branch=W.ELBOW_BRANCH)
        made.clear()
        for p, ref in zip(passes, refs):
            got = check(p)
            assert np.array_equal(got.depth.view(np.int64), ref.depth.view(np.int64))
            assert np.array_equal(got.collides, ref.collides) and np.array_equal(got.reachable, ref.reachable)
        assert len(made) == 1
        monkeypatch.setattr(F, "joint_tables", real)


def test_statics_runs_once_per_call_for_statics_and_stability(monkeypatch):
    # reference: the statics evaluator and stability.stiffness_limits each evaluate the statics alone
    from hapticopt.analysis.prrr.loop import stability  # noqa: PLC0415
    from hapticopt.analysis.prrr.structure import statics

    calls = []
    real = statics.statics_arrays
    monkeypatch.setattr(statics, "statics_arrays", lambda *a, **k: calls.append(1) or real(*a, **k))
    ev = registry.evaluate_all(BASE, fidelity=Fidelity.DRAFT, only=("statics", "stability"))
    assert len(calls) == 1
    calls.clear()
    alone = stability.evaluate(BASE)
    assert len(calls) == 1 and statics.evaluate(BASE).metrics() == ev.results["statics"].metrics()
    assert np.array_equal(ev.results["stability"].stiffness_limits, alone.stiffness_limits)
    assert ev.results["stability"].metrics() == alone.metrics()
