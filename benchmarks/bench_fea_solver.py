"""Linear solve of the fine solid FEA: the size-chosen solver against the others on the same matrix.

The system is the one ``hapticopt evaluate --fidelity fine`` solves: the 3-PRRR CAD solid with
bonded pins (prrr-paper, home pose) at ``fea_cad.DEFAULT_LEVEL``, reduced by the rigid-region
constraint, three load cases (unit forces x, y, z at the load point). It is captured once from
:func:`hapticopt.analysis.prrr.structure.fea_cad.cad_fea` and every solver runs on the same matrix. The
compliance C = Fᵀ X (3 × 3) of every solver must equal the direct solve's to 1e-6 relative.

* ``auto``: :func:`hapticopt.analysis.fem.linsolve.solve_spd` as the FEA calls it (direct at this size:
  CHOLMOD where scikit-sparse is installed, SuperLU otherwise);
* ``superlu``: the direct path without CHOLMOD; ``amg-cg``: the new AMG-CG (used above the size limit).

Run: ``make bench`` or ``pytest benchmarks/bench_fea_solver.py --benchmark-enable``; the table of
docs/structure.md ("Linear solver"): ``python benchmarks/bench_fea_solver.py --levels 0 1 2``.
"""

from __future__ import annotations

import argparse
import os
import statistics
import time

import numpy as np
import pytest
import scipy.sparse as sp
from hapticopt.analysis.fem import linsolve
from hapticopt.analysis.fem import solid as fea
from hapticopt.analysis.fem.linsolve import Method
from hapticopt.analysis.prrr.structure import fea_cad
from hapticopt.analysis.status import Status
from hapticopt.design import io

ROUNDS = 5


def capture(level: int) -> dict:
    """The reduced system (A, B, F, blocked) of the CAD FEA at ``level`` (solved once by the default solver)."""
    store = {}
    real = fea.solve_system

    def spy(A, B, rhs, *, blocked, tol, method=Method.AUTO):
        store.update(A=sp.csr_matrix(A), B=B, F=rhs, blocked=blocked)
        return real(A, B, rhs, blocked=blocked, tol=tol, method=method)

    fea.solve_system = spy
    try:
        r = fea_cad.cad_fea(io.load_preset("prrr-paper"), level=level)
    finally:
        fea.solve_system = real
    store.update(level=level, stiffness=r.stiffness_load)
    return store


def solvers(sys_: dict) -> dict:
    A, B, F, blocked = sys_["A"], sys_["B"], sys_["F"], sys_["blocked"]

    def new(method, *, cholmod=True, threads=None):
        def run():
            saved = linsolve.cholmod_available
            if not cholmod:
                linsolve.cholmod_available = lambda: False
            try:
                lin = linsolve.solve_spd(A, F, near_nullspace=B, blocked=blocked, method=method, threads=threads)
            finally:
                linsolve.cholmod_available = saved
            assert lin.status is Status.OK, lin.message
            return lin.x
        return run

    return {"auto": new(Method.AUTO),
            "superlu": new(Method.DIRECT, cholmod=False), "amg-cg": new(Method.AMG_CG),
            "auto-2-threads": new(Method.AUTO, threads=2)}


def compliance(sys_: dict, X: np.ndarray) -> np.ndarray:
    """(n_cases, n_cases) Fᵀ X: the load-point compliance [m/N] per unit load case."""
    return sys_["F"].T @ X


def interleaved_medians(fns: dict, rounds: int = ROUNDS) -> dict[str, float]:
    """Median wall time [s] of each function, the functions run alternately (same machine load)."""
    times = {k: [] for k in fns}
    for _ in range(rounds):
        for k, fn in fns.items():
            t = time.perf_counter()
            fn()
            times[k].append(time.perf_counter() - t)
    return {k: statistics.median(v) for k, v in times.items()}


@pytest.fixture(scope="module")
def system():
    return capture(fea_cad.DEFAULT_LEVEL)


@pytest.fixture(scope="module")
def reference(system):
    return compliance(system, solvers(system)["auto"]())


@pytest.mark.parametrize("name", ["auto", "superlu", "amg-cg"])
def test_solve(benchmark, system, reference, name):
    X = benchmark.pedantic(solvers(system)[name], rounds=ROUNDS, iterations=1)
    C = compliance(system, X)
    np.testing.assert_allclose(np.diagonal(C), np.diagonal(reference), rtol=1e-6)
    benchmark.extra_info.update(level=system["level"], unknowns=int(system["A"].shape[0]),
                                load_average=os.getloadavg()[0])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--levels", type=int, nargs="+", default=[fea_cad.DEFAULT_LEVEL])
    ap.add_argument("--rounds", type=int, default=ROUNDS)
    ap.add_argument("--solvers", nargs="+", default=["auto", "superlu", "amg-cg", "auto-2-threads"])
    args = ap.parse_args()
    print(f"backend of auto: {'cholmod' if linsolve.cholmod_available() else 'superlu'}; medians of "
          f"{args.rounds} interleaved rounds [s]; ratio = amg-cg / solver")
    print("| level | unknowns | " + " | ".join(args.solvers) + " | max |ΔC_ii|/C_ii vs auto | load |")
    print("|---" * (len(args.solvers) + 4) + "|")
    for level in args.levels:
        s = capture(level)
        fns = solvers(s)
        ref = np.diagonal(compliance(s, fns["auto"]()))
        dev = max(float(np.max(np.abs(np.diagonal(compliance(s, fns[k]())) / ref - 1))) for k in args.solvers)
        med = interleaved_medians({k: fns[k] for k in args.solvers}, args.rounds)
        base = med.get("amg-cg")
        cells = [f"{med[k]:.2f}" + (f" ({base / med[k]:.1f}×)" if base else "") for k in args.solvers]
        print(f"| {level} | {s['A'].shape[0]} | " + " | ".join(cells) + f" | {dev:.1e} | {os.getloadavg()[0]:.1f} |",
              flush=True)


if __name__ == "__main__":
    main()
