"""Where the batched draft evaluator's time goes: seconds per stage of one ``registry.evaluate_batch``
of ``n`` designs (``bench_batched_draft.designs``), each stage timed by wrapping its function in
this process (nested stages overlap: ``check_posed`` runs inside ``_interference`` and
``_free_workspace``). ``python benchmarks/profile_batched_draft.py [n [evaluator…]]`` (default 1024, every
evaluator; names after n: ``only``); run once
to compile, the second run is printed."""

from __future__ import annotations

import collections
import os
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_batched_draft import designs  # noqa: E402

from hapticopt.analysis import registry  # noqa: E402
from hapticopt.analysis.fidelity import Fidelity  # noqa: E402
from hapticopt.analysis.prrr import draft_batch as DB  # noqa: E402

T: collections.Counter = collections.Counter()


def wrap(mod, name: str, label: str | None = None) -> None:
    f = getattr(mod, name)

    def timed(*a, **k):
        t = time.perf_counter()
        try:
            return f(*a, **k)
        finally:
            T[label or f"{mod.__name__.rsplit('.', 1)[-1]}.{name}"] += time.perf_counter() - t

    setattr(mod, name, timed)


def main(n: int, only: tuple[str, ...] | None = None) -> None:
    for name in ("start_core", "finish_core", "stack_inputs", "_interference", "_free_workspace", "_structure", "envelopes"):
        wrap(DB, name)
    for mod, name, *label in ((DB.cad, "part_specs"), (DB.cad, "part_frames_arrays"), (DB.WS, "workspace_params"),
                      (DB.WS, "workspace_sample_weights"), (DB.FAST, "prepare"), (DB.FAST, "check_posed"),
                      (DB.DS, "from_specs"), (DB.stability, "evaluate"), (DB.statics, "from_arrays"),
                      (DB.JL, "from_angles"), (DB.FW, "finish"), (registry, "_collect"),
                      (DB.cad_arrays, "part_tables_many"), (DB.FAST, "models_from_tables"), (DB.DS, "from_tables"),
                      (DB.WS, "workspace_params_many"), (DB.WS, "workspace_sample_weights_many"),
                      (DB._Checker, "__call__", "checker (pose IK, cos / sin, check)"), (DB._Checker, "_planar_ik"),
                      (DB.FAST, "joint_cos_sin"), (DB.FAST, "deepest_joints"), (DB.FAST, "check_joints")):
        wrap(mod, name, *label)
    ds = designs(n)
    registry.evaluate_batch(ds, fidelity=Fidelity.DRAFT, only=only)
    T.clear()
    t0 = time.perf_counter()
    registry.evaluate_batch(ds, fidelity=Fidelity.DRAFT, only=only)
    total = time.perf_counter() - t0
    print(f"load average {' '.join(f'{x:.2f}' for x in os.getloadavg())}; {n} designs: {total:.3f} s, "
          f"{n / total:.1f} designs/s")
    for k, v in T.most_common():
        print(f"{v:8.3f} s {1e3 * v / n:7.3f} ms/design {100 * v / total:5.1f} %  {k}")


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 1024, tuple(sys.argv[2:]) or None)
