"""Linear solve of the fine solid FEA (issue 22, item 1): the AMG-CG of before vs the size-chosen solver.

The system is the one ``hapticopt evaluate --fidelity fine`` solves: the 3-PRRR CAD solid with
bonded pins (prrr-paper, home pose) at ``fea_cad.DEFAULT_LEVEL``, reduced by the rigid-region
constraint, three load cases (unit forces x, y, z at the load point). It is captured once from
:func:`hapticopt.analysis.prrr.fea_cad.cad_fea` and every solver runs on the same matrix. The
compliance C = Fᵀ X (3 × 3) of every solver must equal the direct solve's to 1e-6 relative.

* ``legacy-amg-cg``: the solver before issue 22, settings verbatim (SA-AMG, symmetric strength
  θ = 0.02, max_coarse 300, pinv coarse solve, CG to 1e-7, BLAS threads left at the default);
* ``auto``: :func:`hapticopt.analysis.fem.linsolve.solve_spd` as the FEA calls it (direct at this size:
  CHOLMOD where scikit-sparse is installed, SuperLU otherwise);
* ``superlu``: the direct path without CHOLMOD; ``amg-cg``: the new AMG-CG (used above the size limit).

``test_direct_vs_legacy_ratio`` times ``auto`` and ``legacy-amg-cg`` alternately (5 rounds each,
medians) in one run, records the ratio (target ≥ 3×) and 1 vs 2 BLAS threads of the direct solve;
``test_fine_cad_fea_end_to_end_ratio`` does the same for the whole CAD FEA of the fine level.

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
from hapticopt.analysis.prrr import fea_cad
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


def legacy_amg_cg(A, B, F, *, blocked: bool, tol: float = 1e-7) -> np.ndarray:
    """The AMG-CG of ``analysis/fem/solid.py`` before issue 22 (settings verbatim), every column of F."""
    import pyamg
    from scipy.sparse.linalg import cg

    A = sp.csr_matrix(A)
    ml = pyamg.smoothed_aggregation_solver(A.tobsr(blocksize=(3, 3)) if blocked else A, B=B, symmetry="hermitian",
                                           max_coarse=300, strength=("symmetric", {"theta": 0.02}),
                                           smooth=("energy", {"krylov": "cg", "maxiter": 2, "degree": 1,
                                                              "weighting": "local"}),
                                           presmoother=("block_gauss_seidel", {"sweep": "forward"}),
                                           postsmoother=("block_gauss_seidel", {"sweep": "backward"}))
    M = ml.aspreconditioner(cycle="V")
    X = np.zeros_like(F)
    for k in range(F.shape[1]):
        X[:, k], info = cg(A, F[:, k], rtol=tol, atol=0.0, M=M, maxiter=3000)
        assert info == 0
    return X


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

    return {"legacy-amg-cg": lambda: legacy_amg_cg(A, B, F, blocked=blocked), "auto": new(Method.AUTO),
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


@pytest.mark.parametrize("name", ["legacy-amg-cg", "auto", "superlu", "amg-cg"])
def test_solve(benchmark, system, reference, name):
    X = benchmark.pedantic(solvers(system)[name], rounds=ROUNDS, iterations=1)
    C = compliance(system, X)
    np.testing.assert_allclose(np.diagonal(C), np.diagonal(reference), rtol=1e-6)
    benchmark.extra_info.update(level=system["level"], unknowns=int(system["A"].shape[0]),
                                load_average=os.getloadavg()[0])


def test_direct_vs_legacy_ratio(benchmark, system):
    """Acceptance: the fine level's solve ≥ 3× faster than the AMG-CG of before, same matrix, one run."""
    fns = solvers(system)
    med = benchmark.pedantic(interleaved_medians, args=({k: fns[k] for k in ("legacy-amg-cg", "auto",
                                                                             "auto-2-threads")},),
                             rounds=1, iterations=1)
    ratio = med["legacy-amg-cg"] / med["auto"]
    benchmark.extra_info.update(level=system["level"], unknowns=int(system["A"].shape[0]), medians_s=med,
                                ratio_legacy_over_new=ratio, ratio_2_over_1_threads=med["auto-2-threads"] / med["auto"],
                                backend="cholmod" if linsolve.cholmod_available() else "superlu",
                                load_average=os.getloadavg()[0])
    assert ratio >= 3.0


def test_fine_cad_fea_end_to_end_ratio(benchmark, system):
    """The whole level-``DEFAULT_LEVEL`` CAD FEA (mesh, assembly, reduction, solve), legacy AMG-CG vs the
    size-chosen solver swapped in at ``fea.solve_system``, alternately, medians of 5 (CAD build warm)."""
    design = io.load_preset("prrr-paper")
    real = fea.solve_system

    def legacy(A, B, rhs, *, blocked, tol, method=Method.AUTO):
        X = legacy_amg_cg(A, B, rhs, blocked=blocked, tol=tol)
        return linsolve.LinearSolution(x=X, status=Status.OK, method=Method.AMG_CG, backend="legacy-amg-cg",
                                       rcond=float("nan"), rigid_rayleigh=float("nan"), iterations=(),
                                       residuals=(), timings_s={})

    stiff = {}

    def run(name):
        def f():
            fea.solve_system = legacy if name == "legacy-amg-cg" else real
            try:
                stiff[name] = fea_cad.cad_fea(design, level=fea_cad.DEFAULT_LEVEL).stiffness_load
            finally:
                fea.solve_system = real
        return f

    med = benchmark.pedantic(interleaved_medians, args=({k: run(k) for k in ("legacy-amg-cg", "auto")},),
                             rounds=1, iterations=1)
    np.testing.assert_allclose(stiff["auto"], stiff["legacy-amg-cg"], rtol=1e-6)
    benchmark.extra_info.update(level=fea_cad.DEFAULT_LEVEL, medians_s=med,
                                ratio_legacy_over_new=med["legacy-amg-cg"] / med["auto"],
                                load_average=os.getloadavg()[0])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--levels", type=int, nargs="+", default=[fea_cad.DEFAULT_LEVEL])
    ap.add_argument("--rounds", type=int, default=ROUNDS)
    ap.add_argument("--solvers", nargs="+", default=["legacy-amg-cg", "auto", "superlu", "amg-cg", "auto-2-threads"])
    args = ap.parse_args()
    print(f"backend of auto: {'cholmod' if linsolve.cholmod_available() else 'superlu'}; medians of "
          f"{args.rounds} interleaved rounds [s]; ratio = legacy-amg-cg / solver")
    print("| level | unknowns | " + " | ".join(args.solvers) + " | max |ΔC_ii|/C_ii vs auto | load |")
    print("|---" * (len(args.solvers) + 4) + "|")
    for level in args.levels:
        s = capture(level)
        fns = solvers(s)
        ref = np.diagonal(compliance(s, fns["auto"]()))
        dev = max(float(np.max(np.abs(np.diagonal(compliance(s, fns[k]())) / ref - 1))) for k in args.solvers)
        med = interleaved_medians({k: fns[k] for k in args.solvers}, args.rounds)
        base = med.get("legacy-amg-cg")
        cells = [f"{med[k]:.2f}" + (f" ({base / med[k]:.1f}×)" if base else "") for k in args.solvers]
        print(f"| {level} | {s['A'].shape[0]} | " + " | ".join(cells) + f" | {dev:.1e} | {os.getloadavg()[0]:.1f} |",
              flush=True)


if __name__ == "__main__":
    main()
