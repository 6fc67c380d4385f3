"""The part steps of the batched draft evaluator, per design against the array forms, side by side.

The steps (``analysis.prrr.draft_batch._chunk`` before its core): which designs the CAD can lay out,
the part tables, the primitive tables of the interference model, the envelope, the workspace
parameters, the analytic mass model and height, and the interference sample weights.

* **per design**: ``assembly.parts``, ``cad.part_specs``, ``interference_fast.prepare``,
  ``draft_batch.envelopes``, ``workspace.workspace_params``, ``device_size.from_specs``,
  ``workspace.workspace_sample_weights`` (the evaluator's path before the array forms);
* **arrays**: ``draft_batch._part_tables`` (``cad_arrays.part_tables_many``),
  ``interference_fast.models_from_tables``, ``draft_batch.envelopes``, ``draft_batch._workspace_params``,
  ``device_size.from_tables``, ``draft_batch._samples``.

``python benchmarks/bench_part_steps.py [n]`` (default 1024 designs, ``bench_batched_draft.designs``):
interleaved rounds, medians of the wall time per design of each path, their ratio, the load average
and the per-step split of the array path. The two paths' device sizes and samples are compared first
(they must agree; the tests check them to 1e-12 or bit for bit).
"""

from __future__ import annotations

import os
import statistics
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_batched_draft import designs  # noqa: E402

from hapticopt.analysis.prrr import assembly  # noqa: E402
from hapticopt.analysis.prrr import device_size as DS  # noqa: E402
from hapticopt.analysis.prrr import draft_batch as DB  # noqa: E402
from hapticopt.analysis.prrr import interference_fast as FAST  # noqa: E402
from hapticopt.analysis.prrr import workspace as WS  # noqa: E402
from hapticopt.design.prrr import cad  # noqa: E402

ROUNDS = 7


def _step(split: dict | None, name: str, f, *a):
    t = time.perf_counter()
    out = f(*a)
    if split is not None:
        split.setdefault(name, []).append(time.perf_counter() - t)
    return out


def per_design(ds: list, split: dict | None = None) -> tuple[dict, dict]:
    no_parts = _step(split, "assembly.parts", lambda: {i for i, d in enumerate(ds) if assembly.parts(d)})
    specs = _step(split, "cad.part_specs", lambda: [DB._Blocked() if i in no_parts else DB._guard(cad.part_specs, d)
                                                    for i, d in enumerate(ds)])
    models = _step(split, "prepare", lambda: {i: FAST.prepare(d, specs=specs[i]) for i, d in enumerate(ds)
                                              if isinstance(specs[i], dict)})
    env = _step(split, "envelopes", DB.envelopes, ds, models, specs)
    wps = _step(split, "workspace_params", lambda: [
        WS.workspace_params(d, specs=s if isinstance(s, dict) else None, envelope=env.get(i))
        for i, (d, s) in enumerate(zip(ds, specs))])
    t = time.perf_counter()
    sizes = _step(split, "from_specs", lambda: {i: DS.from_specs(d, specs[i], t) for i, d in enumerate(ds)
                                                if isinstance(specs[i], dict)})
    samples = _step(split, "workspace_sample_weights", lambda: {
        i: WS.workspace_sample_weights(d, **WS.INTERFERENCE_SAMPLING, wp=wps[i]) for i, d in enumerate(ds)
        if i not in no_parts})
    return sizes, samples


def arrays(ds: list, split: dict | None = None) -> tuple[dict, dict]:
    def step(name, f, *a):
        return _step(split, name, f, *a)

    specs, tables, _ = step("part tables (+ per-design rest)", DB._part_tables, ds)

    def models():
        out = {}
        for t in tables:
            out.update(zip(t.index.tolist(), FAST.models_from_tables([ds[i] for i in t.index], t)))
        return out

    m = step("primitive tables", models)
    env = step("envelopes", DB.envelopes, ds, m, specs)
    wps = step("workspace params", DB._workspace_params, ds, specs, env)
    t0 = time.perf_counter()

    def sizes():
        out = {}
        for t in tables:
            out.update(zip(t.index.tolist(), DS.from_tables(t, t0)))
        return out

    sz = step("mass model + height", sizes)
    samples = step("sample weights", DB._samples, ds, specs, wps)
    return sz, samples


def main(n: int) -> None:
    ds = designs(n)
    ref, got = per_design(ds), arrays(ds)
    assert ref[0].keys() == got[0].keys() and ref[1].keys() == got[1].keys()
    for i, r in ref[0].items():
        a, b = np.array(list(r.metrics().values())), np.array(list(got[0][i].metrics().values()))
        assert np.allclose(a, b, rtol=1e-12, atol=0), i
    for i, (p, w) in ref[1].items():
        assert p.tobytes() == got[1][i][0].tobytes() and w.tobytes() == got[1][i][1].tobytes(), i
    t_ref, t_new, split, split_ref = [], [], {}, {}
    for _ in range(ROUNDS):
        t = time.perf_counter()
        per_design(ds, split_ref)
        t_ref.append(time.perf_counter() - t)
        t = time.perf_counter()
        arrays(ds, split)
        t_new.append(time.perf_counter() - t)
    a, b = statistics.median(t_ref), statistics.median(t_new)
    print(f"load average {' '.join(f'{x:.2f}' for x in os.getloadavg())}; {n} designs, {ROUNDS} interleaved rounds "
          f"(medians)")
    print(f"per design {1e3 * a / n:.3f} ms/design; arrays {1e3 * b / n:.4f} ms/design; ratio {a / b:.1f}x")
    for title, parts in (("per design", split_ref), ("arrays", split)):
        print(title)
        for k, v in parts.items():
            print(f"  {1e3 * statistics.median(v) / n:.4f} ms/design  {k}")


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 1024)
