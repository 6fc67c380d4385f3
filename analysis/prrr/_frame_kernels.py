"""numba kernel of :func:`hapticopt.analysis.prrr.frame_model.condense_legs` over many legs (imported
only through :func:`hapticopt.analysis.prrr.frame_model.condense_many`, so numba loads on first use).

Per leg, the same quantities as the numpy/jax reference: the Jacobi scaling d of K_ii, the scaled
matrix's solves with K_iP (six right-hand sides) and the probe (1/n)·1, K_PP − K_Pi K_ii⁻¹ K_iP, and
Hager's two-step estimate of ‖K_ii,s⁻¹‖₁ (two more solves). The difference is the factorisation: a
Cholesky factorisation of the scaled matrix (symmetric positive definite for every design whose
verdict is ok) that visits only the nonzero entries of each column. A leg's internal DOFs form a
chain (carriage bracket → link d3 → link d4 → platform arm, 6-DOF nodes and three hinge angles), so
a column holds ≈ 12–19 nonzeros below its diagonal with the fill-in, not 57: the elimination along
the chain costs ≈ Σ nnz² instead of the dense LU's n³/3 and each solve ≈ 2 Σ nnz instead of n².
A pivot ≤ 0 (a matrix that is not positive definite: singular or worse) makes every output of that
leg NaN, which the batch's verdict reads as not ok and solves again by the single path.
Results differ from the reference's partial-pivoting LU by the rounding of a different elimination
(relative ≈ condition × 1e-16; tested to 1e-9 against it).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit


@njit(cache=True)
def _solve_into(L, nz, cnt, x):
    """x ← (L Lᵀ)⁻¹ x in place: L lower-triangular (its nonzero rows below the diagonal of column k
    are nz[k, :cnt[k]])."""
    m = x.shape[0]
    for k in range(m):  # forward: L y = x, column by column
        xk = x[k] / L[k, k]
        x[k] = xk
        for t in range(cnt[k]):
            i = nz[k, t]
            x[i] -= L[i, k] * xk
    for k in range(m - 1, -1, -1):  # backward: Lᵀ z = y
        s = x[k]
        for t in range(cnt[k]):
            i = nz[k, t]
            s -= L[i, k] * x[i]
        x[k] = s / L[k, k]


@njit(cache=True)
def condense_legs_kernel(K, contrib, cond, recovery, gross):
    """``K`` (L, n, n) legs' stiffness on [P (6) | internal]; writes each leg's K_PP − K_Pi K_ii⁻¹ K_iP
    into ``contrib`` (L, 6, 6), its scaled internal matrix's condition estimate into ``cond`` (L,),
    K_ii⁻¹ K_iP into ``recovery`` (L, n−6, 6) and the magnitudes |K_PP,aa| + |(K_Pi K_ii⁻¹ K_iP)_aa| of
    the diagonal's two terms into ``gross`` (L, 6) (the size of the cancellation)."""
    nl, n = K.shape[0], K.shape[1]
    m = n - 6
    A = np.empty((m, m))
    d = np.empty(m)
    nz = np.empty((m, m), dtype=np.int64)
    cnt = np.empty(m, dtype=np.int64)
    sol = np.empty((m, 7))
    x = np.empty(m)
    for leg in range(nl):
        Kl = K[leg]
        for i in range(m):
            d[i] = 1.0 / math.sqrt(abs(Kl[6 + i, 6 + i]))
        norm1 = 0.0  # ‖K_ii,s‖₁ (symmetric: the largest column sum)
        for j in range(m):
            col = 0.0
            for i in range(m):
                a = d[i] * Kl[6 + i, 6 + j] * d[j]
                A[i, j] = a
                col += abs(a)
            norm1 = max(norm1, col)
        # Cholesky on the lower triangle, right-looking, over each column's nonzero rows
        ok = True
        for k in range(m):
            akk = A[k, k]
            if not akk > 0.0:
                ok = False
                break
            lkk = math.sqrt(akk)
            A[k, k] = lkk
            c = 0
            for i in range(k + 1, m):
                if A[i, k] != 0.0:
                    A[i, k] /= lkk
                    nz[k, c] = i
                    c += 1
            cnt[k] = c
            for t in range(c):
                i = nz[k, t]
                lik = A[i, k]
                for u in range(t + 1):  # nz[k] ascending: j ≤ i, the lower triangle
                    j = nz[k, u]
                    A[i, j] -= lik * A[j, k]
        if not ok:
            contrib[leg] = np.nan
            cond[leg] = np.nan
            recovery[leg] = np.nan
            gross[leg] = np.nan
            continue
        for r in range(7):  # right-hand sides: d K_iP, then the probe (1/m)·1
            for i in range(m):
                x[i] = d[i] * Kl[r, 6 + i] if r < 6 else 1.0 / m
            _solve_into(A, nz, cnt, x)
            for i in range(m):
                sol[i, r] = x[i]
        for i in range(m):
            for r in range(6):
                recovery[leg, i, r] = d[i] * sol[i, r]
        for a in range(6):
            for b in range(6):
                s = 0.0
                for i in range(m):
                    s += Kl[a, 6 + i] * recovery[leg, i, b]
                contrib[leg, a, b] = Kl[a, b] - s
                if a == b:
                    gross[leg, a] = abs(Kl[a, a]) + abs(s)
        # Hager's estimate of ‖A⁻¹‖₁ (frame_model._inverse_norm1): y = A⁻¹ (1/m)·1, ξ = sign(y), z = A⁻¹ ξ,
        # j = argmax |z|, y2 = A⁻¹ e_j; max(‖y‖₁, ‖y2‖₁)
        s1 = 0.0
        for i in range(m):
            s1 += abs(sol[i, 6])
            x[i] = 1.0 if sol[i, 6] >= 0.0 else -1.0
        _solve_into(A, nz, cnt, x)
        jmax, zmax = 0, -1.0
        for i in range(m):
            if abs(x[i]) > zmax:  # first of equal maxima, as argmax
                jmax, zmax = i, abs(x[i])
        for i in range(m):
            x[i] = 0.0
        x[jmax] = 1.0
        _solve_into(A, nz, cnt, x)
        s2 = 0.0
        for i in range(m):
            s2 += abs(x[i])
        cond[leg] = norm1 * max(s1, s2)
