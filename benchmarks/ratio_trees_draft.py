"""This tree's draft evaluation against an older revision's, both whole, side by side in one process
(interleaved rounds, medians): ``python benchmarks/ratio_trees_draft.py REV [n [rounds]]`` (default
n = 1024 designs of ``bench_batched_draft.designs``, 5 rounds).

The older revision's ``analysis``, ``design`` and ``optim`` are unpacked from ``git archive REV`` into
a temporary folder and imported as a second ``hapticopt`` package; the two packages take turns in
``sys.modules`` (each one's lazy imports resolve inside its own tree). Each round times, for each tree:

* ``batch``: ``registry.evaluate_batch`` of the n designs (every draft evaluator);
* ``results``: the batch's per-design result steps inside that call (the statics, structure, workspace,
  joint-limit, free-workspace, interference and stability verdicts and results, and the registry's
  ``_collect``), each step's function timed where it is entered from outside another timed one
  (a timer costs ≈ 1 µs a call, counted in both trees: the older one makes more calls);
* ``single``: ``registry.evaluate_all`` of the first :data:`N_SINGLE` designs one by one, after the
  batches (so the collision check's compiled kernel is in use in both trees:
  ``interference_fast.KERNEL_AFTER_POSES``);
* ``batch of 1``: ``registry.evaluate_batch`` of each of those designs alone (``bench_batched_draft``'s
  batch 1).

Prints ms per design of each, the ratios old / new, and the load average before and after.
"""

from __future__ import annotations

import functools
import importlib
import io
import os
import statistics
import subprocess
import sys
import tarfile
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_batched_draft import designs  # noqa: E402

from hapticopt.analysis.fidelity import Fidelity as NewFidelity  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
N_SINGLE = 16
#: (module, function) of the per-design result steps (those a tree lacks are skipped)
RESULT_STEPS = (
    ("analysis.prrr.statics", "from_arrays"), ("analysis.prrr.statics", "from_arrays_many"),
    ("analysis.prrr.draft_batch", "_structure"), ("analysis.prrr.structure", "from_arrays_many"),
    ("analysis.prrr.workspace", "_result"), ("analysis.prrr.joint_limits", "from_angles"),
    ("analysis.prrr.joint_limits", "from_angles_many"), ("analysis.prrr.joint_limits", "from_ranges_many"),
    ("analysis.prrr.free_workspace", "finish"),
    ("analysis.prrr.interference", "from_fractions"), ("analysis.prrr.draft_batch", "_stability"),
    ("analysis.prrr.stability", "evaluate"), ("analysis.prrr.stability", "evaluate_many"),
    ("analysis.prrr.workspace", "_result_of"), ("analysis.prrr.structure", "from_ok_arrays"),
    ("analysis.prrr.device_size", "from_tables"),
    ("analysis.registry", "_collect"), ("analysis.registry", "_collect_found"),
)


def _ours(name: str) -> bool:
    return name == "hapticopt" or name.startswith("hapticopt.")


class Tree:
    """One ``hapticopt`` package and its modules, swapped into ``sys.modules`` by :meth:`use`."""

    active: Tree | None = None

    def __init__(self, label: str, modules: dict) -> None:
        self.label, self.modules, self.spent = label, modules, [0.0]

    def use(self) -> Tree:
        if Tree.active is not self:
            if Tree.active is not None:
                Tree.active.modules = {k: v for k, v in sys.modules.items() if _ours(k)}
            for k in [k for k in sys.modules if _ours(k)]:
                del sys.modules[k]
            sys.modules.update(self.modules)
            Tree.active = self
        return self

    def mod(self, name: str):
        self.use()
        return importlib.import_module(f"hapticopt.{name}")

    def time_steps(self) -> None:
        """Wrap the result steps with one outermost-call timer adding to ``self.spent``."""
        depth = [0]
        for m, f in RESULT_STEPS:
            mod = self.mod(m)
            if not hasattr(mod, f):
                continue

            def timed(*a, _fn=getattr(mod, f), **k):
                if depth[0]:
                    return _fn(*a, **k)
                depth[0] += 1
                t0 = time.perf_counter()
                try:
                    return _fn(*a, **k)
                finally:
                    self.spent[0] += time.perf_counter() - t0
                    depth[0] -= 1

            functools.update_wrapper(timed, getattr(mod, f))
            setattr(mod, f, timed)


def old_tree(rev: str, folder: Path) -> Tree:
    data = subprocess.run(["git", "archive", rev, "analysis", "design", "optim"], cwd=ROOT, check=True,
                          capture_output=True).stdout
    pkg = folder / "hapticopt"
    pkg.mkdir()
    (pkg / "__init__.py").write_text('"""older revision"""\n')
    with tarfile.open(fileobj=io.BytesIO(data)) as tar:
        tar.extractall(pkg, filter="data")
    new = {k: v for k, v in sys.modules.items() if _ours(k)}
    for k in new:
        del sys.modules[k]
    sys.path.insert(0, str(folder))
    importlib.import_module("hapticopt.analysis.registry")
    sys.path.remove(str(folder))
    old = {k: v for k, v in sys.modules.items() if _ours(k)}
    for k in old:
        del sys.modules[k]
    sys.modules.update(new)
    return Tree(f"old {rev}", old)


def main(rev: str, n: int, rounds: int) -> None:
    print(f"load average before {' '.join(f'{x:.2f}' for x in os.getloadavg())}", flush=True)
    with tempfile.TemporaryDirectory() as tmp:
        trees = [old_tree(rev, Path(tmp)), Tree("new", {k: v for k, v in sys.modules.items() if _ours(k)})]
        Tree.active = trees[1]
        ds = designs(n)
        few = ds[:N_SINGLE]
        draft = NewFidelity.DRAFT.value
        for tree in trees:
            tree.time_steps()
            reg = tree.mod("analysis.registry")
            reg.evaluate_batch(ds, fidelity=draft)  # compile or load, and pass KERNEL_AFTER_POSES
            for d in few:
                reg.evaluate_all(d, fidelity=draft)
                reg.evaluate_batch([d], fidelity=draft)
        t = {(tree.label, k): [] for tree in trees for k in ("batch", "results", "single", "batch of 1")}
        for _ in range(rounds):
            for tree in trees:
                reg = tree.mod("analysis.registry")
                tree.spent[0] = 0.0
                t0 = time.perf_counter()
                reg.evaluate_batch(ds, fidelity=draft)
                t[tree.label, "batch"].append((time.perf_counter() - t0) / n)
                t[tree.label, "results"].append(tree.spent[0] / n)
            for tree in trees:
                reg = tree.mod("analysis.registry")
                t0 = time.perf_counter()
                for d in few:
                    reg.evaluate_all(d, fidelity=draft)
                t[tree.label, "single"].append((time.perf_counter() - t0) / len(few))
            for tree in trees:
                reg = tree.mod("analysis.registry")
                t0 = time.perf_counter()
                for d in few:
                    reg.evaluate_batch([d], fidelity=draft)
                t[tree.label, "batch of 1"].append((time.perf_counter() - t0) / len(few))
        med = {k: statistics.median(v) for k, v in t.items()}
        print(f"{n} designs, {rounds} rounds, medians [ms/design]; single on the first {len(few)}")
        old, new = trees[0].label, trees[1].label
        for k in ("batch", "results", "single", "batch of 1"):
            print(f"{k:10s} {old}: {1e3 * med[old, k]:8.3f}   {new}: {1e3 * med[new, k]:8.3f}   "
                  f"old/new {med[old, k] / med[new, k]:5.2f}")
    print(f"load average after {' '.join(f'{x:.2f}' for x in os.getloadavg())}")


if __name__ == "__main__":
    main(sys.argv[1], int(sys.argv[2]) if len(sys.argv) > 2 else 1024, int(sys.argv[3]) if len(sys.argv) > 3 else 5)
