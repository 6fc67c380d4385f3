"""The pipeline's baseline stage of a second ``make run``-like invocation, cold vs warm evaluation cache
(issue 22 item 2).

The stage is what :func:`hapticopt.optim.pipeline.run_pipeline` does before optimising
``prrr-workspace``: the base design (``prrr-paper``) at the optimisation fidelity (draft) and at the
final fidelity (fine), each through :func:`hapticopt.optim.pipeline._recorded_evaluation` with a
new run record (a fresh ``--out``, or ``--force``: nothing to replay). Cold: no cache (every run
before this branch; ``--no-cache``). Warm: the cache file already holds both evaluations (written by
an earlier run).

Run: ``pytest benchmarks/bench_cache.py -o python_files='bench_*.py' --benchmark-enable`` (in one
process: jit and imports warm after the first round), or side by side in fresh processes, as a
second ``make run`` meets it::

    python benchmarks/bench_cache.py [--rounds 5]
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import pytest

PROBLEM = "prrr-workspace"


def baseline_stage(out: Path, cache: Path | None) -> dict:
    """Run the baseline stage of PROBLEM into a new run directory ``out``; stage wall time and provenance."""
    from hapticopt.optim.cache import EvaluationCache
    from hapticopt.optim.pipeline import _provenance_note, _recorded_evaluation
    from hapticopt.optim.problem import load_problem
    from hapticopt.optim.recorder import Recorder

    problem = load_problem(PROBLEM)
    t0 = time.perf_counter()
    with Recorder(out, fingerprint="bench", resume=False, force=True) as rec, \
            EvaluationCache(cache) if cache is not None else _Null() as ecache:
        draft = _recorded_evaluation(rec, problem.base, problem.fidelity_optimise, "baseline", cache=ecache)
        fine = _recorded_evaluation(rec, problem.base, problem.fidelity_final, "baseline", cache=ecache)
    return {"stage_s": time.perf_counter() - t0, "provenance": _provenance_note(draft, fine),
            "metrics": json.dumps(fine.metrics)}


class _Null:
    def __enter__(self):
        return None

    def __exit__(self, *exc):
        return None


@pytest.mark.parametrize("warm", [False, True], ids=["cold", "warm"])
def test_baseline_stage(benchmark, tmp_path, warm):
    cache = tmp_path / "evaluation-cache.sqlite"
    if warm:
        baseline_stage(tmp_path / "fill", cache)
    counter = iter(range(1000))
    result = benchmark.pedantic(lambda: baseline_stage(tmp_path / f"run{next(counter)}", cache if warm else None),
                                rounds=3 if not warm else 5, iterations=1)
    assert ("from the evaluation cache" in result["provenance"]) == warm


_CHILD = """
import json, sys
from pathlib import Path
sys.path.insert(0, {here!r})
from bench_cache import baseline_stage
print(json.dumps(baseline_stage(Path(sys.argv[1]), None if sys.argv[2] == '-' else Path(sys.argv[2]))))
"""


def _fresh(out: Path, cache: Path | None) -> dict:
    t0 = time.perf_counter()
    res = subprocess.run([sys.executable, "-c", _CHILD.format(here=str(Path(__file__).parent)), str(out),
                          str(cache) if cache else "-"], capture_output=True, text=True, check=True)
    d = json.loads(res.stdout.strip().splitlines()[-1])
    d["process_s"] = time.perf_counter() - t0
    return d


def main() -> None:
    ap = argparse.ArgumentParser(description="baseline stage, cold vs warm evaluation cache, fresh processes")
    ap.add_argument("--rounds", type=int, default=5)
    ns = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        cache = work / "evaluation-cache.sqlite"
        _fresh(work / "fill", cache)  # the first run: fills the cache
        cold, warm = [], []
        for i in range(ns.rounds):  # interleaved, side by side
            cold.append(_fresh(work / f"cold{i}", None))
            warm.append(_fresh(work / f"warm{i}", cache))
        assert all("from the evaluation cache" in w["provenance"] for w in warm)
        served = {w["metrics"] for w in warm}
        assert len(served) == 1, "the cache served different values"
        computed = [c["metrics"] for c in cold]
    for key in ("stage_s", "process_s"):
        c, w = statistics.median(r[key] for r in cold), statistics.median(r[key] for r in warm)
        print(f"{key}: cold median {c:.3f} s, warm median {w:.3f} s, ratio cold/warm {c / w:.1f} "
              f"({ns.rounds} interleaved fresh processes each)")
    reference = json.loads(served.pop())
    for i, text in enumerate(computed):
        diff = _differences(reference, json.loads(text))
        print(f"cold round {i}: fine metrics " + ("equal the cached ones bit for bit" if not diff else
              f"differ from the cached ones in {len(diff)} values: " + "; ".join(diff[:8])))


def _differences(a, b, path: str = "") -> list[str]:
    """Paths where two JSON values differ (floats compared exactly), with the relative difference."""
    if isinstance(a, dict) and isinstance(b, dict):
        return [d for k in sorted(set(a) | set(b)) for d in _differences(a.get(k), b.get(k), f"{path}.{k}")]
    if isinstance(a, list) and isinstance(b, list) and len(a) == len(b):
        return [d for i, (x, y) in enumerate(zip(a, b)) for d in _differences(x, y, f"{path}[{i}]")]
    if isinstance(a, float) and isinstance(b, float):
        if a == b or (a != a and b != b):
            return []
        return [f"{path.lstrip('.')} {a!r} vs {b!r} (rel {abs(a - b) / max(abs(a), abs(b)):.1e})"]
    return [] if a == b else [f"{path.lstrip('.')} {a!r} vs {b!r}"]


if __name__ == "__main__":
    main()
