"""One user-facing stage of this checkout against an older revision, side by side.

    python benchmarks/ab.py REV STAGE [--rounds N] [--n N] [--scene S] [--keep DIR]

REV is checked out into a temporary ``git worktree`` with its own venv: the running interpreter's
site-packages as plain path lines (so neither tree's editable install leaks into the other), then
``pip install --no-deps -e .``. For whole-command stages both trees first run the numba warm-up of
``make setup``. Each round runs the stage once per
tree, each in a fresh process, in an order that alternates by round; every process does the stage once
untimed first (jit traces, numba loads, caches) unless the stage is a whole command (make-run, startup);
with ``--fresh`` that first call evaluates other designs, so no memo (the closure verdicts) has seen the timed
ones. Prints the medians,
the ratio new/old (per round and its median), for the in-process stages also of the CPU time of all the
process's threads (less moved by other jobs on a loaded machine than the wall time), and the load average
before and after.

Stages (the figures docs/performance.md quotes):

* ``draft-batch`` — ``registry.evaluate_batch`` at draft of ``--n`` designs (default 1024), ms per design;
* ``draft-one`` — ``registry.evaluate_all`` at draft, one design at a time over ``--n`` designs (default 16);
* ``fea-fine`` — the structural evaluator at fine (frame model and solid FEA of the CAD) on prrr-paper;
* ``verify`` — ``verify.simulate`` of ``--scene`` (default stiffness-25) at standard on its device's preset;
* ``make-run`` — the three commands of ``make run`` in an empty folder (a fresh process each, imports included);
* ``startup`` — ``hapticopt evaluate --preset prrr-paper`` from a fresh interpreter to its first byte of output.

The designs are seeded, ±10 % around prrr-paper (the same as ``bench_batched_draft.designs``).
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
STAGES = ("draft-batch", "draft-one", "fea-fine", "verify", "make-run", "startup")
PRESET_OF = {"prrr": "prrr-paper", "master": "master-paper", "handle": "handle-paper"}


# ---- the child: runs in either tree's interpreter, imports only that tree's hapticopt ----

def _designs(n: int, seed: int = 0) -> list:
    import dataclasses

    import numpy as np

    from hapticopt.design import io
    from hapticopt.design.errors import InvalidDesign
    base = io.load_preset("prrr-paper")
    rng, g, out = np.random.default_rng(seed), base.geometry, []
    while len(out) < n:
        kw = dict(beta=g.beta * rng.uniform(0.9, 1.1), r_p=g.r_p * rng.uniform(0.9, 1.1),
                  d3=g.d3 * rng.uniform(0.9, 1.1), d4=g.d4 * rng.uniform(0.9, 1.1),
                  stroke=g.stroke * rng.uniform(0.9, 1.1))
        try:
            out.append(dataclasses.replace(base, geometry=dataclasses.replace(g, **kw)))
        except InvalidDesign:
            continue
    return out


def _stage_fn(stage: str, n: int | None, scene: str, seed: int = 0):
    """(the stage as a function of no arguments, the number of units its time is divided by, the unit);
    the draft stages' designs drawn with ``seed``."""
    from hapticopt.analysis import registry
    from hapticopt.analysis.fidelity import Fidelity
    if stage == "draft-batch":
        ds = _designs(n or 1024, seed)
        return (lambda: registry.evaluate_batch(ds, fidelity=Fidelity.DRAFT)), len(ds), "ms/design"
    if stage == "draft-one":
        ds = _designs(n or 16, seed)
        return (lambda: [registry.evaluate_all(d, fidelity=Fidelity.DRAFT) for d in ds]), len(ds), "ms/design"
    if stage == "fea-fine":
        from hapticopt.design import io
        d = io.load_preset("prrr-paper")
        return (lambda: registry.evaluate_all(d, fidelity=Fidelity.FINE, only=("structural_stiffness",))), 1, "ms"
    if stage == "verify":
        from hapticopt.analysis import verify
        from hapticopt.analysis.loop.scene import load_scene
        from hapticopt.design import io
        sc = load_scene(scene)
        d = io.load_preset(PRESET_OF[sc.device])
        return (lambda: verify.simulate(d, sc, fidelity=Fidelity.STANDARD)), 1, "ms"
    raise SystemExit(f"unknown stage {stage!r}; one of {', '.join(STAGES)}")


def child(stage: str, n: int | None, scene: str, fresh: bool = False) -> None:
    fn, units, unit = _stage_fn(stage, n, scene)
    # untimed: traces, compiled kernels, caches; with ``fresh`` on other designs of the same number, so the
    # timed call meets designs no memo has seen (as an optimiser's next batch does)
    (_stage_fn(stage, n, scene, seed=1)[0] if fresh else fn)()
    t, c = time.perf_counter(), time.process_time()
    fn()
    t, c = time.perf_counter() - t, time.process_time() - c
    print(json.dumps({"value": 1e3 * t / units, "cpu": 1e3 * c / units, "unit": unit}))


# ---- the parent ----

def _make_run(py: str, work: Path) -> float:
    """Wall seconds of `make run`'s three commands, in ``work`` (empty), through ``py``."""
    cli = [py, "-m", "hapticopt.optim.cli"]
    t = time.perf_counter()
    for args, ok in ((["evaluate", "--preset", "prrr-paper"], (0, 3)),
                     (["export", "--preset", "prrr-paper", "--render"], (0,)),
                     (["optimise", "prrr-workspace", "--quiet"], (0, 3))):
        rc = subprocess.run(cli + args, cwd=work, capture_output=True, text=True)
        if rc.returncode not in ok:
            raise SystemExit(f"{py}: {' '.join(args)} exited {rc.returncode}:\n{rc.stderr[-2000:]}")
    return time.perf_counter() - t


def _first_output(py: str, work: Path) -> float:
    """Wall seconds from starting ``hapticopt evaluate --preset prrr-paper`` to its first byte on stdout."""
    t = time.perf_counter()
    proc = subprocess.Popen([py, "-m", "hapticopt.optim.cli", "evaluate", "--preset", "prrr-paper"], cwd=work,
                            stdout=subprocess.PIPE, stderr=subprocess.DEVNULL)
    proc.stdout.read(1)
    t = time.perf_counter() - t
    proc.communicate()
    return t


def once(py: str, stage: str, n: int | None, scene: str, fresh: bool = False) -> tuple[float, float | None, str]:
    """(wall time, CPU time of the process's threads or None for whole commands, unit) of one run."""
    with tempfile.TemporaryDirectory(prefix="ab-run-") as work:
        if stage == "make-run":
            return _make_run(py, Path(work)), None, "s"
        if stage == "startup":
            return _first_output(py, Path(work)), None, "s"
        args = [py, str(Path(__file__).resolve()), "--child", stage, "--scene", scene]
        args += (["--n", str(n)] if n else []) + (["--fresh"] if fresh else [])
        out = subprocess.run(args, cwd=work, capture_output=True, text=True)
        if out.returncode:
            raise SystemExit(f"{py} {stage} exited {out.returncode}:\n{out.stderr[-3000:]}")
        r = json.loads(out.stdout.strip().splitlines()[-1])
        return r["value"], r.get("cpu"), r["unit"]


def site_paths() -> list[str]:
    """The running interpreter's package folders (its venv's and any it names by a plain path line)."""
    return [p for p in sys.path if p.rstrip("/").endswith(("site-packages", "dist-packages")) and Path(p).is_dir()]


def old_tree(rev: str, where: Path) -> str:
    """Check ``rev`` out at ``where`` with a venv of its own; the venv's python."""
    subprocess.run(["git", "-C", str(ROOT), "worktree", "add", "-q", "--detach", str(where), rev], check=True)
    subprocess.run([sys.executable, "-m", "venv", str(where / ".venv")], check=True)
    py = str(where / ".venv" / "bin" / "python")
    mine = subprocess.run([py, "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"],
                          check=True, capture_output=True, text=True).stdout.strip()
    Path(mine, "zz_ab_site.pth").write_text("".join(p + "\n" for p in site_paths()))
    subprocess.run([py, "-m", "pip", "install", "-q", "--no-deps", "-e", "."], cwd=where, check=True,
                   capture_output=True)
    return py


def warm(py: str) -> None:
    """The install step of `make setup` (numba kernels compiled into their cache), for the stages whose
    timed rounds are whole commands; the other stages' untimed first call compiles or loads them."""
    subprocess.run([py, "-m", "hapticopt.analysis.warmup"], cwd=tempfile.gettempdir(), capture_output=True)


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("rev", nargs="?")
    ap.add_argument("stage", choices=STAGES)
    ap.add_argument("--rounds", type=int, default=5)
    ap.add_argument("--n", type=int, default=None, help="designs (draft-batch, draft-one)")
    ap.add_argument("--scene", default="stiffness-25", help="the verify stage's scene")
    ap.add_argument("--keep", type=Path, help="build the old tree here and keep it (reused when it exists)")
    ap.add_argument("--fresh", action="store_true",
                    help="draft stages: the untimed first call evaluates other designs (seed 1), so the timed "
                         "call's designs are new to every memo (an optimiser's next batch)")
    ap.add_argument("--child", action="store_true", help=argparse.SUPPRESS)
    a = ap.parse_args(argv)
    if a.child:
        return child(a.stage, a.n, a.scene, a.fresh)
    if not a.rev:
        ap.error("REV is required")
    tmp = Path(tempfile.mkdtemp(prefix="ab-"))
    where = a.keep or tmp / "old"
    try:
        sha = subprocess.run(["git", "-C", str(ROOT), "rev-parse", "--short", a.rev], check=True,
                             capture_output=True, text=True).stdout.strip()
        if a.keep and (where / ".venv" / "bin" / "python").exists():
            py_old = str(where / ".venv" / "bin" / "python")
        else:
            print(f"building {a.rev} ({sha}) in {where} ...", flush=True)
            py_old = old_tree(a.rev, where)
        trees = {"old": py_old, "new": sys.executable}
        if a.stage in ("make-run", "startup"):
            for py in trees.values():
                warm(py)
        load0 = os.getloadavg()
        times: dict[str, list[float]] = {"old": [], "new": []}
        cpu: dict[str, list[float]] = {"old": [], "new": []}
        unit = ""
        for r in range(a.rounds):
            for name in (("old", "new") if r % 2 == 0 else ("new", "old")):
                v, c, unit = once(trees[name], a.stage, a.n, a.scene, a.fresh)
                times[name].append(v)
                if c is not None:
                    cpu[name].append(c)
            line = (f"round {r + 1}: old {times['old'][-1]:.3f}, new {times['new'][-1]:.3f} {unit}, "
                    f"new/old {times['new'][-1] / times['old'][-1]:.3f}")
            if cpu["new"]:
                line += f"; CPU old {cpu['old'][-1]:.3f}, new {cpu['new'][-1]:.3f}"
            print(f"{line}; load {os.getloadavg()[0]:.2f}", flush=True)
        mo, mn = statistics.median(times["old"]), statistics.median(times["new"])
        ratios = [b / o for o, b in zip(times["old"], times["new"])]
        load1 = os.getloadavg()
        stage = (a.stage + (f" {a.scene}" if a.stage == "verify" else "") + (f" n={a.n}" if a.n else "")
                 + (" fresh" if a.fresh else ""))
        print(f"{stage}: old {a.rev} ({sha}) {mo:.3f} {unit}, new {ROOT.name} {mn:.3f} {unit}; "
              f"new/old {mn / mo:.3f} (median of per-round ratios {statistics.median(ratios):.3f}, "
              f"{a.rounds} interleaved rounds); load {load0[0]:.2f}/{load0[1]:.2f}/{load0[2]:.2f} before, "
              f"{load1[0]:.2f}/{load1[1]:.2f}/{load1[2]:.2f} after")
        if cpu["new"]:
            co, cn = statistics.median(cpu["old"]), statistics.median(cpu["new"])
            per_round = statistics.median(b / o for o, b in zip(cpu["old"], cpu["new"]))
            print(f"CPU time (all threads): old {co:.3f} {unit}, new {cn:.3f} {unit}; new/old {cn / co:.3f} "
                  f"(median of per-round ratios {per_round:.3f})")
    finally:
        if not a.keep:
            subprocess.run(["git", "-C", str(ROOT), "worktree", "remove", "--force", str(where)], capture_output=True)
            shutil.rmtree(tmp, ignore_errors=True)


if __name__ == "__main__":
    main()
