"""Singular / ill-conditioned / not positive definite, from an explicit reciprocal condition number.

``numpy.linalg.solve`` raises only on an exactly zero pivot; a near-singular matrix returns
finite garbage whose sign depends on the BLAS kernel (``docs/pitfalls.md``). Every verdict here
comes from the reciprocal condition number ``rcond = σ_min/σ_max`` of the *scaled* matrix
(symmetric Jacobi scaling ``D⁻½ A D⁻½`` for a symmetric matrix, so units and stiff/soft DOF
ratios do not count as ill-conditioning; the plain singular values otherwise), classified with
fixed bands decades away from rounding (float64 ε = 2.2e-16), in a fixed order:

1. ``rcond < RCOND_SINGULAR`` (1e-12, four decades above ε): singular;
2. ``rcond < RCOND_ILL`` (1e-6: a solve keeps fewer than 10 of 16 digits, and a mechanism
   whose force or motion transmission spans six decades is at a singularity for any practical
   purpose): ill-conditioned;
3. symmetric and required positive definite, with ``λ_min/λ_max < -RCOND_ILL`` (a clearly
   negative eigenvalue) or a non-positive diagonal: not positive definite.

An rcond computed by SVD moves by O(ε) between BLAS kernels, so a matrix two decades from a band
gets the same verdict on every CPU.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from hapticopt.analysis.status import Status

#: below this reciprocal condition number a matrix is singular (4 decades above float64 ε)
RCOND_SINGULAR = 1e-12
#: below this it is ill-conditioned (see the module docstring)
RCOND_ILL = 1e-6


@dataclass(frozen=True, kw_only=True)
class Conditioning:
    status: Status  # OK, SINGULAR, ILL_CONDITIONED or NOT_POSITIVE_DEFINITE
    rcond: float  # σ_min/σ_max of the scaled matrix (0 for a zero or non-finite matrix)
    message: str = ""

    @property
    def ok(self) -> bool:
        return self.status is Status.OK


def rcond(A: np.ndarray, *, symmetric: bool = False) -> float:
    """Reciprocal 2-norm condition number of ``A`` after scaling (see the module docstring)."""
    A = np.asarray(A, dtype=float)
    if A.size == 0 or not np.all(np.isfinite(A)):
        return 0.0
    if symmetric:
        d = np.abs(np.diagonal(A))
        if np.any(d == 0.0) or not np.all(np.isfinite(1.0 / np.sqrt(d))):
            return 0.0
        s = 1.0 / np.sqrt(d)
        A = s[:, None] * A * s[None, :]
    sv = np.linalg.svd(A, compute_uv=False)
    if sv[0] == 0.0 or not math.isfinite(sv[0]):
        return 0.0
    return float(sv[-1] / sv[0])


def rcond_many(A: np.ndarray) -> np.ndarray:
    """:func:`rcond` (plain singular values, not symmetric) of each matrix of a stack ``A`` (n, m, m):
    one batched SVD (LAPACK's routine on each matrix, as for one; tested bitwise equal)."""
    A = np.asarray(A, dtype=float)
    out = np.zeros(len(A))
    finite = np.all(np.isfinite(A), axis=(1, 2))
    if A.shape[1] * A.shape[2] == 0 or not finite.any():
        return out
    sv = np.linalg.svd(A[finite], compute_uv=False)
    top = sv[:, 0]
    ok = (top != 0.0) & np.isfinite(top)
    out[np.flatnonzero(finite)[ok]] = sv[ok, -1] / top[ok]
    return out


def classify(A: np.ndarray, *, what: str, symmetric: bool = False, positive_definite: bool = False) -> Conditioning:
    """The conditioning verdict of matrix ``A`` (named ``what`` in the message)."""
    A = np.asarray(A, dtype=float)
    r = rcond(A, symmetric=symmetric)
    verdict = classify_rcond(r, what=what)
    if verdict.status is not Status.OK:
        return verdict
    if symmetric and positive_definite:
        d = 1.0 / np.sqrt(np.abs(np.diagonal(A)))
        lam = np.linalg.eigvalsh(d[:, None] * A * d[None, :])
        if lam[0] < -RCOND_ILL * abs(lam[-1]) or (np.any(np.diagonal(A) <= 0.0)):
            return Conditioning(status=Status.NOT_POSITIVE_DEFINITE, rcond=r,
                                message=f"{what} is not positive definite: smallest scaled eigenvalue {lam[0]:.3g}")
    return verdict


def classify_rcond(r: float, *, what: str) -> Conditioning:
    """The verdict for an rcond computed elsewhere (e.g. 1/cond of a closed form)."""
    r = float(r) if math.isfinite(r) else 0.0
    if r < RCOND_SINGULAR:
        return Conditioning(status=Status.SINGULAR, rcond=r,
                            message=f"{what} is singular: reciprocal condition number {r:.3g} < {RCOND_SINGULAR:g}")
    if r < RCOND_ILL:
        return Conditioning(status=Status.ILL_CONDITIONED, rcond=r,
                            message=f"{what} is ill-conditioned: reciprocal condition number {r:.3g} < {RCOND_ILL:g}")
    return Conditioning(status=Status.OK, rcond=r)
