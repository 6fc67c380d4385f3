"""A refactoring changed no number: CLI JSON against a committed regression snapshot.

Snapshot: tests/snapshots/metrics.json, made by ``scripts/snapshot_metrics.py`` on 1531152, the
code before the one-path consolidation (issue 29): the three presets at draft, standard and fine
fidelity, and the scenes stiffness-25, free-space-x, master-transparency and handle-ball. Wall times, the free-text reasons (which name module
paths) and which closed-loop engine ran are not compared. A later change that moves a metric on purpose regenerates the snapshot
with that script and says why in its commit.
"""

from __future__ import annotations

import importlib.util
import json
import math
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
SNAPSHOT = ROOT / "tests" / "snapshots" / "metrics.json"
# closed_loop_engine: which loop ran (compiled or Python) — they are bit-identical (tests/analysis/loop/test_mujoco_compiled.py)
IGNORED_KEYS = {"timings_s", "wall_time_s", "backend_reason", "resolution_reason", "closed_loop_engine",
                # a wall-clock time reported beside the solid FEA's result (metrics of time, not of the design)
                "structural_fea_wall_s"}
#: a float equal to this relative tolerance is the same number (BLAS kernels differ at ~1e-12)
REL_TOL = 1e-9


def _script():
    spec = importlib.util.spec_from_file_location("snapshot_metrics", ROOT / "scripts" / "snapshot_metrics.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _compare(old, new, path: str) -> list[str]:
    if isinstance(old, dict) and isinstance(new, dict):
        out = [f"{path}/{k}: missing now" for k in old.keys() - new.keys() if k not in IGNORED_KEYS]
        out += [f"{path}/{k}: new key" for k in new.keys() - old.keys() if k not in IGNORED_KEYS]
        for key in old.keys() & new.keys():
            if key not in IGNORED_KEYS:
                out += _compare(old[key], new[key], f"{path}/{key}")
        return out
    if isinstance(old, list) and isinstance(new, list):
        if len(old) != len(new):
            return [f"{path}: length {len(old)} -> {len(new)}"]
        return [d for i, (a, b) in enumerate(zip(old, new)) for d in _compare(a, b, f"{path}[{i}]")]
    if isinstance(old, float) and isinstance(new, float):
        if math.isnan(old) and math.isnan(new):
            return []
        # equal to rounding: another BLAS kernel (OPENBLAS_CORETYPE) moves the last digits (1e-12 measured)
        if math.isclose(old, new, rel_tol=REL_TOL, abs_tol=1e-300):
            return []
    return [] if old == new else [f"{path}: {old!r} -> {new!r}"]


SCRIPT = _script()


@pytest.mark.parametrize("case", sorted(SCRIPT.CASES))
def test_metrics_equal_the_snapshot(case):
    snapshot = json.loads(SNAPSHOT.read_text())
    now = SCRIPT.run_case(SCRIPT.CASES[case])
    differences = _compare(snapshot[case], now, case)
    assert not differences, "\n".join(differences[:20])


def test_the_comparison_sees_a_changed_number():
    """The comparator itself: a changed metric is reported, a changed timing is not."""
    assert _compare({"a": 1.0, "timings_s": {"x": 1.0}}, {"a": 1.0, "timings_s": {"x": 2.0}}, "") == []
    assert _compare({"structural_fea_wall_s": 28.4}, {"structural_fea_wall_s": 51.4}, "") == []
    assert _compare({"a": 1.0}, {"a": 1.0000001}, "") == ["/a: 1.0 -> 1.0000001"]
    assert _compare({"a": 1.0}, {"a": 1.0 + 1e-12}, "") == []  # another BLAS kernel's rounding
