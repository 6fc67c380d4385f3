"""Linear solves of the solid FEA: sparse direct factorisation up to a size, AMG-CG above it.

Every solid-FEA system here is a symmetric positive definite stiffness (clamped, reduced by exact
multi-point constraints) with a few load cases: one factorisation (or one AMG hierarchy) serves
them all. The choice (:data:`DIRECT_MAX_UNKNOWNS`, measured in docs/structure.md, "Linear solver"):

* ``Method.DIRECT`` — the Jacobi-scaled matrix S = D A D (D = diag(A)^-½) is factored once:
  CHOLMOD's supernodal Cholesky (scikit-sparse, an optional dependency: ``pip install
  hapticopt[cholmod]`` with SuiteSparse's headers) where it imports, otherwise SciPy's SuperLU
  in symmetric mode (``MMD_AT_PLUS_A`` ordering, diagonal pivots). Then a 1-norm reciprocal
  condition estimate of S (Hager/Higham, deterministic, two solves per step on the same factor).
* ``Method.AMG_CG`` — conjugate gradients preconditioned by pyamg smoothed aggregation with the
  six rigid-body modes as near-nullspace B (the pitfall: without them 6× more iterations),
  coarsened down to :data:`AMG_MAX_COARSE` unknowns (evolution strength measure: the symmetric
  measure at θ = 0.02 stopped after one level on the CAD solid, a dense 1266-unknown coarsest
  grid solved by a pseudo-inverse); the hierarchy is built once for all load cases.

Verdicts come from explicit numbers (docs/pitfalls.md), in this order, with either method:

1. a non-positive or non-finite diagonal entry: a DOF with no stiffness — ``singular``;
2. the smallest Rayleigh quotient of S on the near-nullspace span (the rigid-body modes):
   an upper bound of λ_min(S) while λ_max(S) ≥ 1 (S has a unit diagonal), so a value below
   :data:`~hapticopt.analysis.conditioning.RCOND_SINGULAR` proves rcond₂(S) below it: an
   unrestrained rigid motion (missing or insufficient clamp) — ``singular``;
3. direct only: the 1-norm rcond estimate of S below ``RCOND_SINGULAR`` (any other mechanism,
   e.g. a part that floats) — ``singular``; a relative residual above
   :data:`DIRECT_RESIDUAL_LIMIT` — ``failed``; AMG-CG only: CG that does not reach its tolerance
   in :data:`CG_MAXITER` iterations — ``failed`` with the residual reached.

Healthy FE stiffness matrices have rcond₁(S) ≈ 1e-9 (CAD solid, 3·10⁴–8·10⁴ unknowns; it falls as
h² under refinement), below the 1e-6 "ill-conditioned" band of :mod:`hapticopt.analysis.conditioning`,
which is meant for mechanism Jacobians and frame matrices, not discretised operators: only the
singular band applies here, and the estimate is reported. A non-ok solve returns NaN solutions,
so the stiffness computed from them is NaN and the caller's status is not ok.

BLAS threads are set explicitly around factorisation and solves (threadpoolctl,
:data:`BLAS_THREADS`): on the 2-core machine two OpenBLAS threads spin against each other under
load (docs/pitfalls.md).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from enum import StrEnum

import numpy as np
import scipy.sparse as sp
from hapticopt.analysis.conditioning import RCOND_SINGULAR
from hapticopt.analysis.status import Status
from scipy.sparse.linalg import cg, splu


class Method(StrEnum):
    AUTO = "auto"  # DIRECT up to DIRECT_MAX_UNKNOWNS, AMG_CG above
    DIRECT = "direct"
    AMG_CG = "amg-cg"


#: largest system [unknowns] that ``Method.AUTO`` factors directly (docs/structure.md, "Linear solver")
DIRECT_MAX_UNKNOWNS = 400_000
#: BLAS threads during factorisation and solves: one. Two gain nothing consistent for the direct solve
#: (docs/structure.md) and spin against each other in AMG-CG under load (docs/pitfalls.md); one thread
#: also leaves the other core to a parallel evaluation
BLAS_THREADS = 1
#: AMG-CG: coarsest grid size [unknowns] solved directly
AMG_MAX_COARSE = 500
#: AMG-CG: iteration limit per load case
CG_MAXITER = 3000
#: Hager/Higham estimate: at most this many steps (each two solves on the factor)
HAGER_STEPS = 5
#: a direct solve whose relative residual exceeds this failed (a backward-stable factorisation of a
#: matrix above the singular band leaves ~1e-12 and less; ten decades above rounding)
DIRECT_RESIDUAL_LIMIT = 1e-6


@dataclass(frozen=True, kw_only=True)
class LinearSolution:
    """Solutions of A X = F for every column of F, with the verdict and diagnostics."""

    x: np.ndarray  # (n, n_cases); NaN unless status is ok
    status: Status  # OK, SINGULAR or FAILED
    method: Method  # the method used (never AUTO)
    backend: str  # "cholmod", "superlu" or "pyamg-sa-cg"
    rcond: float  # 1-norm reciprocal condition estimate of the Jacobi-scaled matrix (direct); NaN for AMG-CG
    rigid_rayleigh: float  # smallest Rayleigh quotient of S on the near-nullspace span (≥ λ_min(S))
    iterations: tuple[int, ...]  # CG iterations per load case (0 for a direct solve)
    residuals: tuple[float, ...]  # ‖A x − f‖ / ‖f‖ per load case
    timings_s: dict[str, float] = field(default_factory=dict)
    message: str = ""


def choose(n: int, method: Method = Method.AUTO) -> Method:
    """The method used for ``n`` unknowns: ``method`` itself unless AUTO."""
    method = Method(method)
    if method is not Method.AUTO:
        return method
    return Method.DIRECT if n <= DIRECT_MAX_UNKNOWNS else Method.AMG_CG


def cholmod_available() -> bool:
    """Whether scikit-sparse's CHOLMOD imports (the optional fast direct backend)."""
    try:
        import sksparse.cholmod  # noqa: F401
    except ImportError:
        return False
    return True


def hager_inverse_norm(solve, n: int, *, steps: int = HAGER_STEPS) -> float:
    """Hager's estimate of ‖S⁻¹‖₁ for symmetric S given ``solve(b) = S⁻¹ b`` (Higham 1988, LAPACK
    xLACON): a lower bound, usually within a factor 3; deterministic (starts from ones / n)."""
    x = np.full(n, 1.0 / n)
    est = 0.0
    last = -1
    for _ in range(steps):
        y = solve(x)
        if not np.all(np.isfinite(y)):
            return math.inf
        new = float(np.abs(y).sum())
        if new <= est:
            break
        est = new
        z = solve(np.sign(y) + (y == 0.0))  # S symmetric: S⁻ᵀ = S⁻¹
        if not np.all(np.isfinite(z)):
            return math.inf
        j = int(np.argmax(np.abs(z)))
        if j == last:
            break
        last = j
        x = np.zeros(n)
        x[j] = 1.0
    return est


def _rigid_rayleigh(S: sp.csr_matrix, Y: np.ndarray) -> float:
    """Smallest Rayleigh quotient of S on span(Y) (Rayleigh–Ritz; an upper bound of λ_min(S))."""
    Q, R = np.linalg.qr(Y)
    keep = np.abs(np.diagonal(R)) > 1e-12 * np.abs(np.diagonal(R)).max(initial=0.0)
    Q = Q[:, keep]
    if Q.shape[1] == 0:
        return math.inf
    G = Q.T @ (S @ Q)
    return float(np.linalg.eigvalsh(0.5 * (G + G.T))[0])


def _failed(n_cases: int, n: int, *, status: Status, method: Method, backend: str, rcond: float,
            rigid: float, timings: dict[str, float], message: str) -> LinearSolution:
    return LinearSolution(x=np.full((n, n_cases), np.nan), status=status, method=method, backend=backend,
                          rcond=rcond, rigid_rayleigh=rigid, iterations=(), residuals=(), timings_s=timings,
                          message=message)


def solve_spd(A, rhs: np.ndarray, *, near_nullspace: np.ndarray, blocked: bool = False, tol: float = 1e-7,
              method: Method = Method.AUTO, threads: int | None = None) -> LinearSolution:
    """Solve the symmetric positive definite stiffness system ``A X = rhs`` (every column).

    ``A`` (n, n) sparse; ``rhs`` (n,) or (n, n_cases); ``near_nullspace`` (n, k): the rigid-body
    modes expressed in the unknowns (AMG's B, and the singularity check). ``blocked``: the
    unknowns come in node blocks of 3 (AMG aggregates nodes). ``tol``: CG's relative residual
    (AMG-CG only; a direct solve is exact to rounding). ``threads``: BLAS threads (default
    :data:`BLAS_THREADS`). See the module docstring for the verdicts.
    """
    from threadpoolctl import threadpool_limits

    t0 = time.perf_counter()
    A = sp.csr_matrix(A)
    F = np.asarray(rhs, dtype=float)
    F = F[:, None] if F.ndim == 1 else F
    n = A.shape[0]
    chosen = choose(n, method)
    backend = "pyamg-sa-cg" if chosen is Method.AMG_CG else ("cholmod" if cholmod_available() else "superlu")
    d = A.diagonal()
    if not np.all(np.isfinite(d)) or np.any(d <= 0.0):
        i = int(np.nonzero(~(np.isfinite(d) & (d > 0.0)))[0][0])
        return _failed(F.shape[1], n, status=Status.SINGULAR, method=chosen, backend=backend, rcond=0.0, rigid=0.0,
                       timings={"check": time.perf_counter() - t0},
                       message=f"stiffness diagonal {d[i]:.3g} at unknown {i} is not positive: a DOF without stiffness")
    s = 1.0 / np.sqrt(d)
    rows = np.repeat(np.arange(n), np.diff(A.indptr))
    S = sp.csr_matrix((A.data * s[rows] * s[A.indices], A.indices.copy(), A.indptr.copy()), shape=A.shape)
    rigid = _rigid_rayleigh(S, np.asarray(near_nullspace, dtype=float) / s[:, None])
    t_check = time.perf_counter() - t0
    if not rigid >= RCOND_SINGULAR:
        return _failed(F.shape[1], n, status=Status.SINGULAR, method=chosen, backend=backend, rcond=float("nan"),
                       rigid=rigid, timings={"check": t_check},
                       message=(f"stiffness is singular: a rigid-body motion is unrestrained (Rayleigh quotient "
                                f"{rigid:.3g} < {RCOND_SINGULAR:g}; missing or insufficient supports?)"))
    with threadpool_limits(limits=BLAS_THREADS if threads is None else int(threads), user_api="blas"):
        if chosen is Method.DIRECT:
            return _direct(A, S, s, F, backend=backend, rigid=rigid, t0=t0, t_check=t_check)
        return _amg_cg(A, F, near_nullspace, blocked=blocked, tol=tol, rigid=rigid, t0=t0, t_check=t_check)


def _factor(S: sp.csr_matrix, backend: str):
    """(solve, backend actually used): CHOLMOD, or SuperLU when CHOLMOD is absent or finds no
    positive pivot (SuperLU then serves the condition estimate, which gives the verdict)."""
    if backend == "cholmod":
        from sksparse.cholmod import CholmodNotPositiveDefiniteError, cholesky

        try:
            factor = cholesky(sp.csc_matrix(S), ordering_method="amd")
            return factor, "cholmod"
        except CholmodNotPositiveDefiniteError:
            pass
    try:
        lu = splu(sp.csc_matrix(S), permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0,
                  options={"SymmetricMode": True})
    except RuntimeError:  # an exactly zero pivot: rcond = 0
        return None, "superlu"
    return lu.solve, "superlu"


def _direct(A, S, s, F, *, backend: str, rigid: float, t0: float, t_check: float) -> LinearSolution:
    solve, backend = _factor(S, backend)
    t1 = time.perf_counter()
    norm_s = float(abs(S).sum(axis=0).max())
    inv = math.inf if solve is None else hager_inverse_norm(solve, S.shape[0])
    rcond = 1.0 / (norm_s * inv) if math.isfinite(inv) and inv > 0.0 else 0.0
    t2 = time.perf_counter()
    timings = {"check": t_check, "factor": t1 - t0 - t_check, "condition": t2 - t1}
    if not rcond >= RCOND_SINGULAR:
        return _failed(F.shape[1], S.shape[0], status=Status.SINGULAR, method=Method.DIRECT, backend=backend,
                       rcond=rcond, rigid=rigid, timings=timings,
                       message=(f"stiffness is singular: reciprocal condition number {rcond:.3g} < {RCOND_SINGULAR:g} "
                                f"(a mechanism or a loose part?)"))
    X = s[:, None] * np.asarray(solve(s[:, None] * F)).reshape(F.shape)
    res = tuple(float(np.linalg.norm(A @ X[:, k] - F[:, k]) / max(np.linalg.norm(F[:, k]), 1e-300))
                for k in range(F.shape[1]))
    timings["solve"] = time.perf_counter() - t2
    if not max(res) <= DIRECT_RESIDUAL_LIMIT:
        return _failed(F.shape[1], S.shape[0], status=Status.FAILED, method=Method.DIRECT, backend=backend,
                       rcond=rcond, rigid=rigid, timings=timings,
                       message=(f"direct solve ({backend}) left a relative residual {max(res):.3g} > "
                                f"{DIRECT_RESIDUAL_LIMIT:g}"))
    return LinearSolution(x=X, status=Status.OK, method=Method.DIRECT, backend=backend, rcond=rcond,
                          rigid_rayleigh=rigid, iterations=(0,) * F.shape[1], residuals=res, timings_s=timings)


def amg_hierarchy(A, B: np.ndarray, *, blocked: bool):
    """pyamg smoothed aggregation for elasticity: rigid-body modes B, evolution strength, energy-minimising
    prolongation smoothing, symmetric block Gauss–Seidel V-cycle, coarsening to AMG_MAX_COARSE."""
    import pyamg

    A = sp.csr_matrix(A)
    return pyamg.smoothed_aggregation_solver(
        A.tobsr(blocksize=(3, 3)) if blocked else A, B=B, symmetry="hermitian", strength="evolution",
        max_coarse=AMG_MAX_COARSE, max_levels=20, coarse_solver="splu",
        smooth=("energy", {"krylov": "cg", "maxiter": 2, "degree": 1, "weighting": "local"}),
        presmoother=("block_gauss_seidel", {"sweep": "forward"}),
        postsmoother=("block_gauss_seidel", {"sweep": "backward"}))


def _amg_cg(A, F, B, *, blocked: bool, tol: float, rigid: float, t0: float, t_check: float) -> LinearSolution:
    ml = amg_hierarchy(A, B, blocked=blocked)
    M = ml.aspreconditioner(cycle="V")
    t1 = time.perf_counter()
    X = np.zeros_like(F)
    its, res = [], []
    for k in range(F.shape[1]):
        count = [0]

        def cb(_xk, count=count):
            count[0] += 1

        x, info = cg(A, F[:, k], rtol=tol, atol=0.0, M=M, maxiter=CG_MAXITER, callback=cb)
        r = float(np.linalg.norm(A @ x - F[:, k]) / max(np.linalg.norm(F[:, k]), 1e-300))
        if info != 0 or not r <= 10.0 * tol:
            return _failed(F.shape[1], A.shape[0], status=Status.FAILED, method=Method.AMG_CG, backend="pyamg-sa-cg",
                           rcond=float("nan"), rigid=rigid,
                           timings={"check": t_check, "amg_setup": t1 - t0 - t_check},
                           message=(f"CG did not converge on load case {k}: relative residual {r:.3g} after "
                                    f"{count[0]} iterations (allowed ≤ {tol:g})"))
        X[:, k] = x
        its.append(count[0])
        res.append(r)
    return LinearSolution(x=X, status=Status.OK, method=Method.AMG_CG, backend="pyamg-sa-cg", rcond=float("nan"),
                          rigid_rayleigh=rigid, iterations=tuple(its), residuals=tuple(res),
                          timings_s={"check": t_check, "amg_setup": t1 - t0 - t_check,
                                     "solve": time.perf_counter() - t1})
