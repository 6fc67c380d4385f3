"""The batched draft evaluator's frame group, this tree against an older revision's, side by side in one
process (interleaved rounds, medians): ``python benchmarks/ratio_frame_group_rev.py REV [n [rounds]]``
(default n = 1024 designs of ``bench_batched_draft.designs``, 7 rounds).

Stages, each timed for both trees on the same designs: ``params`` (``frame_model.frame_params_many``:
the stacking and the carriage brackets), ``terms`` (the jitted, vmapped ``frame_leg_terms`` at the home
pose, as the draft core runs it; compiled before timing) and ``condense`` (``condense_terms_many`` with
its numba kernel); ``total`` their sum. A tree with ``frame_model.condense_home_many`` (the frame group
out of XLA) has no ``terms`` stage (≈ 0) and its ``condense`` is that function (the legs' points over the
batch in numpy, then the numba kernel that builds, assembles and condenses the legs). The older revision's ``frame_model`` and ``_frame_kernels`` are
loaded from git (``revisions.module_from``, the kernels from a temporary file so that numba caches
them; its other imports resolve in this tree). Prints ms per design,
the ratios old / new and the load average before and after."""

from __future__ import annotations

import importlib
import os
import statistics
import subprocess
import tempfile
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_batched_draft import designs  # noqa: E402
from revisions import ROOT, module_from  # noqa: E402

import jax  # noqa: E402
import jax.numpy as jnp  # noqa: E402

from hapticopt.analysis.prrr import frame_model as new  # noqa: E402


def stages(fm, kernels, ds):
    opt = fm.FrameOptions()
    if hasattr(fm, "condense_home_many"):  # no terms in XLA: the legs' points in numpy, the rest in numba
        return (lambda: fm.frame_params_many(ds)), (lambda fp: fp), (lambda fp: fm.condense_home_many(fp, fm.LOAD_HEIGHT))
    terms_fn = jax.jit(jax.vmap(lambda fp: fm.frame_leg_terms(fp, jnp.zeros(3), opt)[:3]))

    def params():
        return fm.frame_params_many(ds)

    def terms(fp):
        return tuple(np.asarray(x) for x in terms_fn(jax.tree.map(jnp.asarray, fp)))

    def condense(t):
        fm.condense_terms_many(*t, opt, fm.LOAD_HEIGHT, compiled=True)

    return params, terms, condense


def _kernels_from(rev: str):
    """The older revision's numba kernels, from a file (numba caches compiled kernels beside a file)."""
    src = subprocess.run(["git", "show", f"{rev}:analysis/prrr/_frame_kernels.py"], cwd=ROOT, check=True,
                         capture_output=True, text=True).stdout
    folder = Path(tempfile.gettempdir()) / "hapticopt_old_kernels"
    folder.mkdir(exist_ok=True)
    name = f"frame_kernels_{rev}"
    path = folder / f"{name}.py"
    if not path.exists() or path.read_text() != src:
        path.write_text(src)
    sys.path.insert(0, str(folder))  # an importable module: numba's cache reloads it by name
    return importlib.import_module(name)


def main(rev: str, n: int, rounds: int) -> None:
    old = module_from(rev, "analysis/prrr/frame_model.py", "old_frame_model")
    old_k = _kernels_from(rev)
    ds = designs(n)
    trees = {"old": stages(old, old_k, ds), "new": stages(new, None, ds)}
    # the old condense imports this tree's kernel module by name: point its call at the old kernels
    import hapticopt.analysis.prrr._frame_kernels as cur
    kernels = {"old": old_k.assemble_condense_kernel, "new": cur.assemble_condense_kernel}
    times = {k: {s: [] for s in ("params", "terms", "condense")} for k in trees}
    load0 = os.getloadavg()
    for r in range(rounds + 1):  # round 0 compiles
        for name, (params, terms, condense) in trees.items():
            cur.assemble_condense_kernel = kernels[name]
            t0 = time.perf_counter()
            fp = params()
            t1 = time.perf_counter()
            t = terms(fp)
            t2 = time.perf_counter()
            condense(t)
            t3 = time.perf_counter()
            if r:
                times[name]["params"].append(t1 - t0)
                times[name]["terms"].append(t2 - t1)
                times[name]["condense"].append(t3 - t2)
    cur.assemble_condense_kernel = kernels["new"]
    load1 = os.getloadavg()
    print(f"{n} designs, {rounds} rounds; load average before {load0[0]:.2f}, after {load1[0]:.2f}")
    med = {k: {s: statistics.median(v) for s, v in st.items()} for k, st in times.items()}
    for k in med:
        med[k]["total"] = sum(med[k].values())
    for s in ("params", "terms", "condense", "total"):
        o, w = med["old"][s], med["new"][s]
        print(f"{s:9s} old {1e3 * o / n:7.4f} ms/design  new {1e3 * w / n:7.4f} ms/design  old/new {o / w:5.2f}")


if __name__ == "__main__":
    main(sys.argv[1], int(sys.argv[2]) if len(sys.argv) > 2 else 1024, int(sys.argv[3]) if len(sys.argv) > 3 else 7)
