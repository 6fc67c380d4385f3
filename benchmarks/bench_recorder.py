"""Cost of one recorded evaluation, SQLite synchronous=FULL (the recorder's setting) vs NORMAL.

Run: ``pytest benchmarks/bench_recorder.py -o python_files='bench_*.py' --benchmark-enable``.
Issue 14 asks for the cost per evaluation of FULL; an evaluation itself takes ~10 ms (draft
statics) to seconds, so the difference is what matters.
"""

from __future__ import annotations

import itertools

import pytest

from hapticopt.optim import recorder as recorder_mod
from hapticopt.optim.evaluation import Outcome, PointResult
from hapticopt.optim.recorder import Recorder

POINT = PointResult(x=(45.0, 0.1), outcome=Outcome.OK, message="", values=(1.0, 0.5), gradients=None,
                    gradient_source="none", metrics={"jacobian_condition": 2.449, "stiffness_limit_N_per_mm": [1.0] * 3},
                    statuses={"statics": "ok"}, timings_s={"statics": 1e-3})


@pytest.mark.parametrize("mode", ["FULL", "NORMAL"])
def test_record_one_evaluation(benchmark, tmp_path, monkeypatch, mode):
    monkeypatch.setattr(recorder_mod, "SYNCHRONOUS", mode)
    counter = itertools.count()
    with Recorder(tmp_path, fingerprint="bench", resume=False) as rec:
        benchmark(lambda: rec.record(f"k{next(counter)}", POINT, start=0, stage="search", fidelity="draft"))
