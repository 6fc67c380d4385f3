"""The compiled collision check of the batched draft evaluator against its numpy reference and against the
previous compiled path, side by side in one process (interleaved rounds, medians; the load average printed
before and after):

* the checks one batched draft evaluation of ``n`` designs makes (``bench_batched_draft.designs``; the
  ``interference_fast.check_joints`` calls captured once, then replayed): ``check_joints`` compiled (the
  part frames built in the kernel), the previous compiled path (``cad.part_frames_arrays``' numpy frames
  + ``check_posed``'s frame kernel), and numpy (``check_joints(compiled=False)``);
* ``free_workspace`` alone, batched: ms per design, kernel and numpy;
* every draft evaluator, batched: designs/s, kernel and numpy, and the single path
  (``registry.evaluate_all`` per design, kernel) on the first ``N_SINGLE`` designs.

``python benchmarks/ratio_interference_kernel.py [n [rounds]]`` (default 1024, 3). The numpy runs
switch the kernel off through ``interference_fast.availability`` (as when numba is missing).

``python benchmarks/ratio_interference_kernel.py --compile`` times the kernel's first call in two fresh
processes sharing an empty ``NUMBA_CACHE_DIR``: the first compiles, the second loads the cache."""

from __future__ import annotations

import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_batched_draft import N_SINGLE, designs  # noqa: E402

from hapticopt.analysis.fidelity import Fidelity  # noqa: E402
from hapticopt.analysis.prrr import draft_batch as DB  # noqa: E402
from hapticopt.analysis.prrr import interference_fast as F  # noqa: E402
from hapticopt.analysis.registry import evaluate_all, evaluate_batch  # noqa: E402
from hapticopt.design.prrr import cad  # noqa: E402

_AVAILABLE = F.availability


def _numpy_only(on: bool) -> None:
    F.availability = (lambda: "switched off by the benchmark") if on else _AVAILABLE


def _timed(fn) -> float:
    t0 = time.perf_counter()
    fn()
    return time.perf_counter() - t0


def _load() -> str:
    return " ".join(f"{x:.2f}" for x in os.getloadavg())


def _frames_path(batch, owner, pts, sliders, theta, ok, geometry, **_):
    """The previous compiled path: numpy part frames, then check_posed's frame kernel."""
    g = geometry
    frames = cad.part_frames_arrays(g.beta[owner], g.d1[owner], g.d2[owner], g.d3[owner], g.theta_1p[owner],
                                    sliders, theta, pts)
    return F.check_posed(batch, owner, pts, frames, ok, compiled=True)


def main(n: int, rounds: int) -> None:
    print(f"load average {_load()}")
    ds = designs(n)
    few = ds[:N_SINGLE]
    calls = []
    orig = DB.FAST.check_joints

    def capture(*a, **k):
        calls.append((a, k))
        return orig(*a, **k)

    DB.FAST.check_joints = capture
    evaluate_batch(ds, fidelity=Fidelity.DRAFT)  # compile / load jax and numba, capture the calls
    DB.FAST.check_joints = orig
    poses = sum(len(a[2]) for a, _ in calls)
    for a, k in calls:  # the three paths agree bit for bit on every call
        ref = F.check_joints(*a, **k, compiled=False).depth
        assert np.array_equal(F.check_joints(*a, **k, compiled=True).depth.view(np.int64), ref.view(np.int64))
        assert np.array_equal(_frames_path(*a, **k).depth.view(np.int64), ref.view(np.int64))
    fw = ("free_workspace",)
    evaluate_batch(ds, fidelity=Fidelity.DRAFT, only=fw)
    t: dict[str, list[float]] = {k: [] for k in ("cj_nb", "cj_fr", "cj_np", "fw_nb", "fw_np", "all_nb", "all_np",
                                                  "single")}
    for _ in range(rounds):
        t["cj_fr"].append(_timed(lambda: [_frames_path(*a, **k) for a, k in calls]))
        for mode in ("nb", "np"):
            _numpy_only(mode == "np")
            t[f"cj_{mode}"].append(_timed(lambda: [F.check_joints(*a, **k, compiled=mode == "nb") for a, k in calls]))
            t[f"fw_{mode}"].append(_timed(lambda: evaluate_batch(ds, fidelity=Fidelity.DRAFT, only=fw)) / n)
            t[f"all_{mode}"].append(_timed(lambda: evaluate_batch(ds, fidelity=Fidelity.DRAFT)) / n)
        _numpy_only(False)
        t["single"].append(_timed(lambda: [evaluate_all(d, fidelity=Fidelity.DRAFT) for d in few]) / len(few))
    m = {k: statistics.median(v) for k, v in t.items()}
    print(f"{n} designs, {len(calls)} check_joints calls, {poses} poses, {rounds} rounds (medians); depths bit for "
          f"bit equal on every call")
    print(f"check_joints: kernel {1e6 * m['cj_nb'] / poses:.2f} µs/pose ({1e3 * m['cj_nb'] / n:.3f} ms/design), "
          f"numpy frames + frame kernel {1e6 * m['cj_fr'] / poses:.2f} µs/pose, numpy {1e6 * m['cj_np'] / poses:.2f} "
          f"µs/pose: frames path / kernel {m['cj_fr'] / m['cj_nb']:.2f}×, numpy / kernel {m['cj_np'] / m['cj_nb']:.2f}×")
    print(f"free_workspace batched: kernel {1e3 * m['fw_nb']:.3f} ms/design, numpy {1e3 * m['fw_np']:.3f}: "
          f"numpy / kernel {m['fw_np'] / m['fw_nb']:.2f}×")
    print(f"every draft evaluator batched: kernel {1 / m['all_nb']:.1f} designs/s, numpy {1 / m['all_np']:.1f} "
          f"(kernel / numpy {m['all_np'] / m['all_nb']:.2f}×); single path {1 / m['single']:.1f} designs/s: "
          f"batched (kernel) / single {m['single'] / m['all_nb']:.2f}×, batched (numpy) / single "
          f"{m['single'] / m['all_np']:.2f}×")
    print(f"load average {_load()}")


_FIRST_CALL = """
import time
t0 = time.perf_counter()
import numpy as np
from hapticopt.analysis.prrr import interference_fast as F
from hapticopt.analysis.prrr import workspace as W
from hapticopt.design import io
d = io.load_preset("prrr-paper")
pts, _ = W.workspace_sample_weights(d, n_phi=2, n_r=2, n_z=2)
m = F.prepare(d)
t1 = time.perf_counter()
F.check_points(m, pts, compiled=True)  # the kernel's first call: numba import, compile or cache load, run
t2 = time.perf_counter()
F.check_points(m, pts, compiled=True)
t3 = time.perf_counter()
assert F.availability() is None
print(f"{t2 - t1:.2f} s first call ({t3 - t2:.4f} s the second)")
"""


def compile_times() -> None:
    print(f"load average {_load()}")
    with tempfile.TemporaryDirectory() as cache:
        env = dict(os.environ, NUMBA_CACHE_DIR=cache)
        for label in ("compile (empty cache)", "cached load"):
            out = subprocess.run([sys.executable, "-c", _FIRST_CALL], env=env, capture_output=True, text=True,
                                 check=True).stdout.strip()
            print(f"{label}: {out}")
    print(f"load average {_load()}")


if __name__ == "__main__":
    if sys.argv[1:2] == ["--compile"]:
        compile_times()
    else:
        main(int(sys.argv[1]) if len(sys.argv) > 1 else 1024, int(sys.argv[2]) if len(sys.argv) > 2 else 3)
