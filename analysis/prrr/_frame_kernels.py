"""numba kernels of :func:`hapticopt.analysis.prrr.frame_model.condense_legs` over many legs, from the
legs' stiffness (:func:`condense_legs_kernel`) or from their unassembled terms
(:func:`assemble_condense_kernel`: the elements' stiffness from their parameters, Σ Gᵀ K G over the
maps' nonzero entries, then the same condensation) or from the legs' points at the home pose
(:func:`home_legs_condense_kernel`: the terms themselves built per leg, the draft frame's elements,
springs and maps as ``frame_model.frame_leg_terms`` builds them, then :func:`assemble_condense_kernel`'s
assembly and condensation; the batched draft evaluator's route, no terms over the batch). Imported only
through :func:`hapticopt.analysis.prrr.frame_model.condense_many` / ``condense_terms_many`` /
``condense_home_many``, so numba loads on first use.

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

:func:`assemble_condense_kernel` reads the pattern from the terms' columns instead (the topology's, the
same for every leg: :func:`_structure` once per call): a leg's K is nonzero only where one term couples
two DOFs, and along the chain each row of K_ii starts a few DOFs left of the diagonal, so the factor
lives in that envelope (no fill outside it; none at all in the legs' topologies measured). The factor's
updates and the solves' steps then run over contiguous ranges (each column also kept as a row, so both
operands of an update are contiguous), the solves multiply by the diagonal's reciprocals and take the
backward step by rows (no serial sum), and the condensation is K_PP − Yᵀ Y with Y = L⁻¹ d K_iP: a forward
solve from the first row coupled to P (the rows of the chain's far end), no backward solve and no
recovery. The factor and the condition estimate's solves visit each entry in the order the nonzero scan
does (entries it skips are products with zeros), so the factorisation is the same; the condensation's
rounding is that of the other product (tested to 1e-10 of LAPACK's LU on five topologies).
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
    for k in range(m):  # forward: L y = x, column by column (a zero entry updates nothing: the
        xk = x[k] / L[k, k]  # right-hand sides K_iP and e_j are zero on most of the chain)
        x[k] = xk
        if xk != 0.0:
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
def _solve_many_into(L, nz, cnt, X):
    """X ← (L Lᵀ)⁻¹ X in place for the columns of X (m, r): :func:`_solve_into` per column, the same
    operations in the same order, with each index read once for all columns."""
    m, r = X.shape
    for k in range(m):
        lkk = L[k, k]
        for c in range(r):
            X[k, c] = X[k, c] / lkk
        for t in range(cnt[k]):
            i = nz[k, t]
            lik = L[i, k]
            for c in range(r):
                X[i, c] -= lik * X[k, c]
    for k in range(m - 1, -1, -1):
        for t in range(cnt[k]):
            i = nz[k, t]
            lik = L[i, k]
            for c in range(r):
                X[k, c] -= lik * X[i, c]
        lkk = L[k, k]
        for c in range(r):
            X[k, c] = X[k, c] / lkk


@njit(cache=True)
def _condense_leg(Kl, A, d, nz, cnt, sol, x, recovery, contrib, gross):
    """One leg (``Kl`` (n, n)): writes ``recovery`` (n−6, 6), ``contrib`` (6, 6), ``gross`` (6,); returns
    the condition estimate (NaN, and NaN outputs, where the scaled K_ii is not positive definite).
    ``A``, ``d``, ``nz``, ``cnt``, ``sol``, ``x``: scratch of the internal size."""
    n = Kl.shape[0]
    m = n - 6
    for i in range(m):
        d[i] = 1.0 / math.sqrt(abs(Kl[6 + i, 6 + i]))
    # the scaled lower triangle (all the factorisation reads) and ‖K_ii,s‖₁: K is symmetric, so column
    # j's sum is row j's; each off-diagonal entry counts in the sums of its row and of its column
    for j in range(m):
        x[j] = 0.0
    for i in range(m):
        di = d[i]
        for j in range(i + 1):
            v = Kl[6 + i, 6 + j]
            if v != 0.0:
                a = di * v * d[j]
                A[i, j] = a
                x[i] += abs(a)
                if j != i:
                    x[j] += abs(a)
            else:
                A[i, j] = 0.0
    norm1 = 0.0
    for j in range(m):
        norm1 = max(norm1, x[j])
    # Cholesky on the lower triangle, right-looking, over each column's nonzero rows
    for k in range(m):
        akk = A[k, k]
        if not akk > 0.0:
            contrib[:, :] = np.nan
            recovery[:, :] = np.nan
            gross[:] = np.nan
            return np.nan
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
    for i in range(m):  # right-hand sides: d K_iP, then the probe (1/m)·1
        for r in range(6):
            sol[i, r] = d[i] * Kl[r, 6 + i]
        sol[i, 6] = 1.0 / m
    _solve_many_into(A, nz, cnt, sol)
    for i in range(m):
        for r in range(6):
            recovery[i, r] = d[i] * sol[i, r]
    for a in range(6):  # K_PP − K_Pi K_ii⁻¹ K_iP over the nonzeros of K_Pi (in the order of i)
        for b in range(6):
            contrib[a, b] = 0.0
        for i in range(m):
            kai = Kl[a, 6 + i]
            if kai != 0.0:
                for b in range(6):
                    contrib[a, b] += kai * recovery[i, b]
        gross[a] = abs(Kl[a, a]) + abs(contrib[a, a])
        for b in range(6):
            contrib[a, b] = Kl[a, b] - contrib[a, b]
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
    return norm1 * max(s1, s2)


@njit(cache=True)
def condense_legs_kernel(K, contrib, cond, recovery, gross):
    """``K`` (L, n, n) legs' stiffness on [P (6) | internal]; writes each leg's K_PP − K_Pi K_ii⁻¹ K_iP
    into ``contrib`` (L, 6, 6), its scaled internal matrix's condition estimate into ``cond`` (L,),
    K_ii⁻¹ K_iP into ``recovery`` (L, n−6, 6) and the magnitudes |K_PP,aa| + |(K_Pi K_ii⁻¹ K_iP)_aa| of
    the diagonal's two terms into ``gross`` (L, 6) (the size of the cancellation)."""
    m = K.shape[1] - 6
    A, d, x = np.empty((m, m)), np.empty(m), np.empty(m)
    nz, cnt = np.empty((m, m), dtype=np.int64), np.empty(m, dtype=np.int64)
    sol = np.empty((m, 7))
    for leg in range(K.shape[0]):
        cond[leg] = _condense_leg(K[leg], A, d, nz, cnt, sol, x, recovery[leg], contrib[leg], gross[leg])


@njit(cache=True)
def _nonzeros(patterns):
    """The nonzero entries of the (10, 12, 12) Timoshenko patterns (``frame_model._PATTERNS``), row by row:
    ``idx`` (nk, 3) = (a, b, pattern c), ``val`` (nk,) (each (a, b) in one pattern: the patterns are
    disjoint)."""
    nk = 0
    for a in range(12):
        for b in range(12):
            for c in range(10):
                if patterns[c, a, b] != 0.0:
                    nk += 1
    idx, val = np.empty((nk, 3), dtype=np.int64), np.empty(nk)
    t = 0
    for a in range(12):
        for b in range(12):
            for c in range(10):
                if patterns[c, a, b] != 0.0:
                    idx[t, 0], idx[t, 1], idx[t, 2] = a, b, c
                    val[t] = patterns[c, a, b]
                    t += 1
    return idx, val


@njit(cache=True)
def _element_stiffness(p, kidx, kval, coef, T, kT, Ke):
    """``Ke`` ← the 12 × 12 global stiffness of the element with parameters ``p`` (18,)
    (``frame_model.element_stiffness``: ``beam_global_stiffness`` term by term): Tᵀ k T, k placed from the
    patterns' nonzeros (``kidx``, ``kval``: :func:`_nonzeros`), the products over the nonzeros of k and
    over the blocks of T = blockdiag(R M1, R M2) (M the end zones' rigid maps: [[R, R S], [0, R]] per node).
    ``coef`` (10,): scratch (the patterns' coefficients); ``T``, ``kT``: 12 × 12 scratch."""
    d0, d1, d2 = p[3] - p[0], p[4] - p[1], p[5] - p[2]
    length = math.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
    ex0, ex1, ex2 = d0 / length, d1 / length, d2 / length
    zx = p[6] * ex0 + p[7] * ex1 + p[8] * ex2
    z0, z1, z2 = p[6] - zx * ex0, p[7] - zx * ex1, p[8] - zx * ex2
    zn = math.sqrt(z0 * z0 + z1 * z1 + z2 * z2)
    ez0, ez1, ez2 = z0 / zn, z1 / zn, z2 / zn
    ey0, ey1, ey2 = ez1 * ex2 - ez2 * ex1, ez2 * ex0 - ez0 * ex2, ez0 * ex1 - ez1 * ex0  # ez × ex
    a1 = min(p[9], 0.4 * length)
    a2 = min(p[10], 0.4 * length)
    L = length - a1 - a2
    A, i_y, i_z, J, kap, G, E = p[11], p[12], p[13], p[14], p[15], p[16], p[17]
    phi_y = 12.0 * E * i_z / (kap * G * A * L**2)
    phi_z = 12.0 * E * i_y / (kap * G * A * L**2)
    cy = E * i_z / ((1.0 + phi_y) * L**3)
    cz = E * i_y / ((1.0 + phi_z) * L**3)
    coef[0], coef[1], coef[2], coef[3] = E * A / L, G * J / L, 12.0 * cy, 6.0 * L * cy
    coef[4], coef[5] = (4.0 + phi_y) * L**2 * cy, (2.0 - phi_y) * L**2 * cy
    coef[6], coef[7], coef[8], coef[9] = 12.0 * cz, 6.0 * L * cz, (4.0 + phi_z) * L**2 * cz, (2.0 - phi_z) * L**2 * cz
    R = ((ex0, ex1, ex2), (ey0, ey1, ey2), (ez0, ez1, ez2))
    for node in range(2):
        r = a1 if node == 0 else -a2
        r0, r1, r2 = r * ex0, r * ex1, r * ex2
        # rigid_map(r): [[I, S], [0, I]] with S_ij = Σ_k ε_ijk r_k; R·rigid_map = [[R, R S], [0, R]]
        S = ((0.0, r2, -r1), (-r2, 0.0, r0), (r1, -r0, 0.0))
        o = 6 * node
        for i in range(3):
            for j in range(3):
                T[o + i, o + j] = R[i][j]
                T[o + 3 + i, o + 3 + j] = R[i][j]
                T[o + i, o + 3 + j] = R[i][0] * S[0][j] + R[i][1] * S[1][j] + R[i][2] * S[2][j]
                T[o + 3 + i, o + j] = 0.0
    for a in range(12):  # kT = k T over the nonzeros of k (row by row, in the order of the columns r)
        for b in range(12):
            kT[a, b] = 0.0
    for t in range(kidx.shape[0]):
        a, r = kidx[t, 0], kidx[t, 1]
        kar = coef[kidx[t, 2]] * kval[t]
        o = 6 if r >= 6 else 0  # T's row r is nonzero on its node's block only
        for b in range(o, o + 6):
            kT[a, b] += kar * T[r, b]
    for a in range(12):  # Ke = Tᵀ (k T) over T's blocks (row r: columns of its node, from 3 on for rotations)
        for b in range(12):
            Ke[a, b] = 0.0
    for r in range(12):
        o = 6 if r >= 6 else 0
        for a in range(o + (3 if r - o >= 3 else 0), o + 6):
            tra = T[r, a]
            for b in range(12):
                Ke[a, b] += tra * kT[r, b]


@njit(cache=True)
def _structure(cols, n):
    """A leg's envelope from its terms' columns ``cols`` (T, M) (K is nonzero only on the pairs of one
    term's columns), internal indices (0 … m−1 for the leg's DOFs 6 … n−1): ``fcol`` (m,), the first
    column of each row of the internal block's lower triangle; ``last`` (m,), the last row i > k with
    fcol[i] ≤ k of each column k (k itself if none); ``first``, the first internal DOF coupled to P (the
    rows of K_iP above it are zero). A Cholesky factor has its nonzeros inside the rows' envelope (no
    fill outside it), and column k's below the diagonal within rows k+1 … last[k]: a chain of 6-DOF
    nodes and hinge angles, whose envelope is its pattern (a leg's terms couple consecutive nodes)."""
    m = n - 6
    pat = np.zeros((n, n), dtype=np.bool_)
    for t in range(cols.shape[0]):
        for a in range(cols.shape[1]):
            for b in range(cols.shape[1]):
                pat[cols[t, a], cols[t, b]] = True
    fcol, last = np.empty(m, dtype=np.int64), np.empty(m, dtype=np.int64)
    for i in range(m):
        fcol[i] = i
        for j in range(i - 1, -1, -1):
            if pat[6 + i, 6 + j]:
                fcol[i] = j
    for k in range(m):
        last[k] = k
        for i in range(k + 1, m):
            if fcol[i] <= k:
                last[k] = i
    first = m
    for i in range(m - 1, -1, -1):
        for a in range(6):
            if pat[a, 6 + i]:
                first = i
    return fcol, last, first


@njit(cache=True)
def _solve_env(L, Lt, inv, fcol, last, x):
    """x ← (L Lᵀ)⁻¹ x in place over the envelope (L in the lower triangle of ``L``, its columns as the rows
    of ``Lt``, ``inv`` the reciprocals of its diagonal): the forward substitution by columns, the backward
    one by the rows of L (the columns of Lᵀ), each step a scaling and a contiguous update (no serial sum:
    each unknown waits for one multiplication, not for a chain of them)."""
    m = x.shape[0]
    for k in range(m):
        xk = x[k] * inv[k]
        x[k] = xk
        if xk != 0.0:
            for i in range(k + 1, last[k] + 1):
                x[i] -= Lt[k, i] * xk
    for k in range(m - 1, -1, -1):
        xk = x[k] * inv[k]
        x[k] = xk
        for j in range(fcol[k], k):
            x[j] -= L[k, j] * xk


@njit(cache=True)
def _condense_leg_env(Kl, A, Lt, d, inv, fcol, last, first, Y, x, contrib, gross):
    """:func:`_condense_leg` of a leg ``Kl`` (n, n) assembled on the envelope of :func:`_structure` (its
    entries off that envelope are zero; the lower and upper triangles not yet symmetrised: each entry
    read is ½(K_ij + K_ji)), without the recovery: the scaled lower triangle and ‖K_ii,s‖₁ row by row and
    the right-looking Cholesky factorisation (each entry's updates in the order of :func:`_condense_leg`;
    those it skips are products with zeros), over the envelope's contiguous rows and columns; then
    K_PP − Yᵀ Y with Y = L⁻¹ d K_iP (a forward solve from row ``first``: the rows above are zero; no
    backward solve), and the probe's and Hager's solves as :func:`_condense_leg` (:func:`_solve_env`).
    ``A``, ``Lt`` (m, m), ``d``, ``inv``, ``x`` (m,), ``Y`` (m, 6): scratch. Returns the condition
    estimate (NaN, and NaN outputs, where the scaled K_ii is not positive definite)."""
    n = Kl.shape[0]
    m = n - 6
    for i in range(m):
        d[i] = 1.0 / math.sqrt(abs(Kl[6 + i, 6 + i]))
        x[i] = 0.0
        for j in range(i + 1, last[i] + 1):  # the column's range below the envelope's rows (zeros there)
            A[j, i] = 0.0
    for i in range(m):  # the scaled lower triangle and the column sums of |K_ii,s| (K symmetric)
        di = d[i]
        for j in range(fcol[i], i):
            a = di * (0.5 * (Kl[6 + i, 6 + j] + Kl[6 + j, 6 + i])) * d[j]
            A[i, j] = a
            x[i] += abs(a)
            x[j] += abs(a)
        a = di * Kl[6 + i, 6 + i] * di
        A[i, i] = a
        x[i] += abs(a)
    norm1 = 0.0
    for j in range(m):
        norm1 = max(norm1, x[j])
    for k in range(m):  # Cholesky on the lower triangle, right-looking; column k also kept as Lt's row k
        akk = A[k, k]
        if not akk > 0.0:
            contrib[:, :] = np.nan
            gross[:] = np.nan
            return np.nan
        lkk = math.sqrt(akk)
        A[k, k] = lkk
        inv[k] = 1.0 / lkk
        e = last[k] + 1
        for i in range(k + 1, e):
            v = A[i, k] / lkk
            A[i, k] = v
            Lt[k, i] = v
        for i in range(k + 1, e):
            lik = Lt[k, i]
            if lik != 0.0:
                for j in range(k + 1, i + 1):
                    A[i, j] -= lik * Lt[k, j]
    for i in range(first, m):  # Y = L⁻¹ d K_iP: forward substitution from the first nonzero row
        for r in range(6):
            Y[i, r] = d[i] * (0.5 * (Kl[r, 6 + i] + Kl[6 + i, r]))
    for k in range(first, m):
        ik = inv[k]
        for c in range(6):
            Y[k, c] = Y[k, c] * ik
        for i in range(k + 1, last[k] + 1):
            lik = Lt[k, i]
            for c in range(6):
                Y[i, c] -= lik * Y[k, c]
    for a in range(6):  # Yᵀ Y (= K_Pi K_ii⁻¹ K_iP), symmetric: its lower triangle, each sum in the order of i
        for b in range(a + 1):
            contrib[a, b] = 0.0
    for i in range(first, m):
        for a in range(6):
            ya = Y[i, a]
            for b in range(a + 1):
                contrib[a, b] += ya * Y[i, b]
    for a in range(6):  # K_PP − Yᵀ Y; gross: |K_PP,aa| + (Yᵀ Y)_aa
        gross[a] = abs(Kl[a, a]) + contrib[a, a]
        contrib[a, a] = Kl[a, a] - contrib[a, a]
        for b in range(a):
            v = 0.5 * (Kl[a, b] + Kl[b, a]) - contrib[a, b]
            contrib[a, b] = v
            contrib[b, a] = v
    # the probe y = K_ii,s⁻¹ (1/m)·1 and Hager's estimate of ‖K_ii,s⁻¹‖₁ (as _condense_leg)
    for i in range(m):
        x[i] = 1.0 / m
    _solve_env(A, Lt, inv, fcol, last, x)
    s1 = 0.0
    for i in range(m):
        s1 += abs(x[i])
        x[i] = 1.0 if x[i] >= 0.0 else -1.0
    _solve_env(A, Lt, inv, fcol, last, x)
    jmax, zmax = 0, -1.0
    for i in range(m):
        if abs(x[i]) > zmax:  # first of equal maxima, as argmax
            jmax, zmax = i, abs(x[i])
    for i in range(m):
        x[i] = 0.0
    x[jmax] = 1.0
    _solve_env(A, Lt, inv, fcol, last, x)
    s2 = 0.0
    for i in range(m):
        s2 += abs(x[i])
    return norm1 * max(s1, s2)


@njit(cache=True)
def assemble_condense_kernel(G, Ks, P, patterns, cols, n, contrib, cond, gross):
    """Legs given as terms (``frame_model.frame_leg_terms``): maps ``G`` (L, T, 12, M) on ``cols`` (T, M),
    springs' stiffness ``Ks`` (L, S, 12, 12), elements' parameters ``P`` (L, E, 18) (terms: the E
    elements, then the S springs); ``patterns`` the (10, 12, 12) Timoshenko patterns
    (``frame_model._PATTERNS``). Each leg's K = sym(Σ_t G_tᵀ K_t G_t) (n × n; the products over the
    nonzero entries of G_t), then :func:`condense_legs_kernel`'s outputs but the recovery, over the
    envelope that ``cols`` gives (:func:`_structure`, once per call: :func:`_condense_leg_env`)."""
    m = n - 6
    fcol, last, first = _structure(cols, n)
    kidx, kval = _nonzeros(patterns)
    Kl, A, Lt, d, inv, x = np.empty((n, n)), np.empty((m, m)), np.empty((m, m)), np.empty(m), np.empty(m), np.empty(m)
    Y = np.empty((m, 6))
    T, M = cols.shape
    KG = np.empty((12, M))
    gr, gb, gv = np.empty(12 * M, dtype=np.int64), np.empty(12 * M, dtype=np.int64), np.empty(12 * M)
    width = np.empty(T, dtype=np.int64)  # each term's distinct columns (the padding repeats the first)
    for t in range(T):
        width[t] = 1
        for b in range(1, M):
            if cols[t, b] != cols[t, 0]:
                width[t] += 1
    coef, T12, kT, Ke = np.empty(10), np.empty((12, 12)), np.empty((12, 12)), np.empty((12, 12))
    for leg in range(G.shape[0]):
        _assemble_leg(Kl, G[leg], Ks[leg], P[leg], cols, width, kidx, kval, coef, T12, kT, Ke, KG, gr, gb, gv)
        cond[leg] = _condense_leg_env(Kl, A, Lt, d, inv, fcol, last, first, Y, x, contrib[leg], gross[leg])


@njit(cache=True)
def _assemble_leg(Kl, G, Ks, P, cols, width, kidx, kval, coef, T12, kT, Ke, KG, gr, gb, gv):
    """``Kl`` (n, n) ← Σ_t G_tᵀ K_t G_t of one leg's terms (``G`` (T, 12, M) on ``cols``, ``Ks`` (S, 12, 12),
    ``P`` (E, 18): the elements first), unsymmetrised (:func:`assemble_condense_kernel`'s assembly);
    ``width`` (T,) each term's distinct columns; the rest scratch."""
    Kl[:, :] = 0.0
    T = cols.shape[0]
    E = P.shape[0]
    for t in range(T):
        g = G[t]
        if t < E:
            _element_stiffness(P[t], kidx, kval, coef, T12, kT, Ke)
            k = Ke
        else:
            k = Ks[t - E]
        mt = width[t]
        c = 0  # the nonzeros of G_t, row by row (its columns past mt are the padding: zero)
        for r in range(12):
            for b in range(mt):
                grb = g[r, b]
                if grb != 0.0:
                    gr[c], gb[c], gv[c] = r, b, grb
                    c += 1
        for a in range(12):  # KG = K_t G_t
            for b in range(mt):
                KG[a, b] = 0.0
        for q in range(c):
            r, b, grb = gr[q], gb[q], gv[q]
            for a in range(12):
                KG[a, b] += k[a, r] * grb
        for q in range(c):  # K[cols_a, cols_b] += Σ_r G[r, a] KG[r, b]
            r, ca, gra = gr[q], cols[t, gb[q]], gv[q]
            for b in range(mt):
                Kl[ca, cols[t, b]] += gra * KG[r, b]


@njit(cache=True)
def _sel(out, i):
    """out (6, n) ← the selector of the six DOFs from ``i`` (``frame_model._free``)."""
    out[:, :] = 0.0
    for k in range(6):
        out[k, i + k] = 1.0


@njit(cache=True)
def _hinge_into(out, src, i, w):
    """out ← ``src`` with the hinge rotation DOF ``i`` about ``w`` added to its rotation rows
    (``frame_model._hinge``)."""
    out[:, :] = src
    for j in range(3):
        out[3 + j, i] += w[j]


@njit(cache=True)
def _rigid_into(out, r, src):
    """out ← rigid_map(r) @ src (``frame_model.rigid_map``: [[I, S], [0, I]], S_ij = Σ_k ε_ijk r_k), over
    the columns of ``src`` (6, n)."""
    s01, s02, s10, s12, s20, s21 = r[2], -r[1], -r[2], r[0], r[1], -r[0]
    for c in range(src.shape[1]):
        u0, u1, u2 = src[3, c], src[4, c], src[5, c]
        out[0, c] = src[0, c] + s01 * u1 + s02 * u2
        out[1, c] = src[1, c] + s10 * u0 + s12 * u2
        out[2, c] = src[2, c] + s20 * u0 + s21 * u1
        out[3, c], out[4, c], out[5, c] = u0, u1, u2


@njit(cache=True)
def _put_element(Gt, cols, width, G1, G2):
    """Gt (12, M) ← [G1; G2] on the term's columns ``cols`` (M,) (its first ``width`` distinct; the
    padding zero), as ``frame_model._leg_terms``."""
    for b in range(Gt.shape[1]):
        if b < width:
            c = cols[b]
            for r in range(6):
                Gt[r, b] = G1[r, c]
                Gt[6 + r, b] = G2[r, c]
        else:
            for r in range(12):
                Gt[r, b] = 0.0


@njit(cache=True)
def _put_spring(Gt, cols, width, Da, Db):
    """Gt (12, M) ← [Da − Db; 0] on the term's columns (a joint spring's relative motion, 6 rows)."""
    for b in range(Gt.shape[1]):
        for r in range(12):
            Gt[r, b] = 0.0
        if b < width:
            c = cols[b]
            for r in range(6):
                Gt[r, b] = Da[r, c] - Db[r, c]


@njit(cache=True)
def _neck_into(Gt, cols, width, G1, G2, x1, x2, R1, R2):
    """Gt ← a pin's neck spring between layers x1 (map ``G1``) and x2 (``G2``): rigid_map(mid − x2) G2 −
    rigid_map(mid − x1) G1 at the gap's mid-plane (``frame_model._leg_stiffness_pins``' pin_joint);
    ``R1``, ``R2`` (6, n) scratch."""
    mid = 0.5 * (x1 + x2)
    _rigid_into(R1, mid - x2, G2)
    _rigid_into(R2, mid - x1, G1)
    _put_spring(Gt, cols, width, R1, R2)


@njit(cache=True)
def _put_params(Pe, x1, x2, z, a1, a2, sc, props, E):
    """One element's parameters (``frame_model.element_stiffness``' rows): x1, x2, zref, a1, a2, section
    properties ``sc[props:props + 6]``, E."""
    for k in range(3):
        Pe[k], Pe[3 + k], Pe[6 + k] = x1[k], x2[k], z[k]
    Pe[9], Pe[10] = a1, a2
    for k in range(6):
        Pe[11 + k] = sc[props + k]
    Pe[17] = E


@njit(cache=True, nogil=True)
def home_legs_condense_kernel(geo, Kb, sc, lay, patterns, cols, n, contrib, cond, gross):
    """The legs of the draft frame (``frame_model.FrameOptions()``: pins with neck springs, the CAD's
    carriage bracket, released joints, no SEA spring) from their points, built, assembled and condensed
    here: :func:`assemble_condense_kernel` of the terms that ``frame_model.frame_leg_terms`` computes
    (``frame_model._leg_stiffness_pins``' elements, springs and maps, term by term in its order), with
    the maps built on each leg's DOFs (selectors, hinge columns, rigid maps) and taken on the terms'
    columns in place (no (T, 12, M) array over the batch).

    Per leg (L legs): ``geo`` (L, 9, 3) = w, S, A, B, Q, the bracket's C, J, E, the root's thickness
    direction (world axes [m]); ``Kb`` (L, 2, 6, 6) the bracket's bonds in world axes; ``sc`` (L, 28) =
    joint zone a, layer pitch λ, lug offset, stem radius, r4 [m], E [Pa], the neck's (axial, lateral,
    rocking, torsion) stiffness, then the section properties (area, i_y, i_z, torsion, κ, G) of the link,
    the bracket's root and the platform arm; ``lay`` (12,) the leg's DOF indices of Rb, Rj, Ae, A, Ap,
    phi1, B, B2, phi2, Qp, Q2, phi3 (``frame_model._leg_layout``). Outputs as
    :func:`assemble_condense_kernel`. Runs without the GIL (threads over designs may share it out; run
    before ``finish_core`` waits for XLA's groups it measured 0.97×, 1.553 vs 1.599 ms per design for the
    whole batch of 1024 at load 4.2–4.5, so it runs after)."""
    m = n - 6
    fcol, last, first = _structure(cols, n)
    kidx, kval = _nonzeros(patterns)
    Kl, A_, Lt, d, inv, x = np.empty((n, n)), np.empty((m, m)), np.empty((m, m)), np.empty(m), np.empty(m), np.empty(m)
    Y = np.empty((m, 6))
    T, M = cols.shape
    NE, NS = 5, 5
    KG = np.empty((12, M))
    gr, gb, gv = np.empty(12 * M, dtype=np.int64), np.empty(12 * M, dtype=np.int64), np.empty(12 * M)
    width = np.empty(T, dtype=np.int64)
    for t in range(T):
        width[t] = 1
        for b in range(1, M):
            if cols[t, b] != cols[t, 0]:
                width[t] += 1
    coef, T12, kT, Ke = np.empty(10), np.empty((12, 12)), np.empty((12, 12)), np.empty((12, 12))
    G = np.empty((T, 12, M))
    Ks = np.zeros((NS, 12, 12))
    P = np.empty((NE, 18))
    nm = np.empty((18, 6, n))  # the node maps, a zero map and two scratch maps
    Rb, Rj, Ae, Ai, Ap, phi1, Bi, B2i, phi2, Qp, Q2i, phi3 = (lay[0], lay[1], lay[2], lay[3], lay[4], lay[5],
                                                             lay[6], lay[7], lay[8], lay[9], lay[10], lay[11])
    for leg in range(geo.shape[0]):
        g, s = geo[leg], sc[leg]
        w, S, A, B, Q, C, Jr, Eb, zr = g[0], g[1], g[2], g[3], g[4], g[5], g[6], g[7], g[8]
        a, lam, s_q, stem, r4, E = s[0], s[1], s[2], s[3], s[4], s[5]
        sb = w[2]
        Ac = A - lam * w
        B2 = B + lam * w
        Bp2 = Q - r4 * w + lam * w
        Ql = Q + s_q * w
        Q2 = Ql - lam * w
        v = np.array([-(w[2] * w[0]), -(w[2] * w[1]), w[0] * w[0] + w[1] * w[1]])  # w × (e_z × w)
        v = v / math.sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2])
        Pa = Ql - (math.sqrt(Ql[0] * Ql[0] + Ql[1] * Ql[1]) / sb) * v  # p = 0
        G_Rb, G_Rj, G_E, G_Ac, G_Ql, G_P = nm[0], nm[1], nm[2], nm[3], nm[4], nm[5]
        G_Pa, G_Ap, G_Aph, G_Bc, G_B2, G_B2h = nm[6], nm[7], nm[8], nm[9], nm[10], nm[11]
        G_Q2, G_Q2h, G_Bp, Z, R1, R2 = nm[12], nm[13], nm[14], nm[15], nm[16], nm[17]
        _sel(G_Rb, Rb)
        _sel(G_Rj, Rj)
        _sel(G_E, Ae)
        _sel(G_Ac, Ai)
        _sel(G_Ql, Qp)
        _sel(G_P, 0)
        _rigid_into(G_Pa, Pa, G_P)
        _sel(G_Ap, Ap)
        _hinge_into(G_Aph, G_Ap, phi1, w)
        _sel(G_Bc, Bi)
        _sel(G_B2, B2i)
        _hinge_into(G_B2h, G_B2, phi2, w)
        _sel(G_Q2, Q2i)
        _hinge_into(G_Q2h, G_Q2, phi3, w)
        _rigid_into(G_Bp, Bp2 - Q2, G_Q2h)
        Z[:, :] = 0.0
        # elements (frame_model._leg_stiffness_pins' order): root C → J, clevis arm E → Ac, platform arm
        # Ql → Pa, link d3 A → B, link d4 B2 → Bp2
        _put_element(G[0], cols[0], width[0], G_Rb, G_Rj)
        _put_params(P[0], C, Jr, zr, 0.0, 0.0, s, 16, E)
        _put_element(G[1], cols[1], width[1], G_E, G_Ac)
        _put_params(P[1], Eb, Ac, w, 0.0, a, s, 10, E)
        _put_element(G[2], cols[2], width[2], G_Ql, G_Pa)
        _put_params(P[2], Ql, Pa, w, a, 1.0 * stem / sb, s, 22, E)
        _put_element(G[3], cols[3], width[3], G_Aph, G_Bc)
        _put_params(P[3], A, B, w, a, a, s, 10, E)
        _put_element(G[4], cols[4], width[4], G_B2h, G_Bp)
        _put_params(P[4], B2, Bp2, w, a, a, s, 10, E)
        # springs: the root bonded on the (clamped) block at C, the arm on the root's end face at E, the
        # R1, R2, R3 pins' necks at their gaps' mid-planes
        _rigid_into(R1, C - S, Z)
        _put_spring(G[5], cols[5], width[5], G_Rb, R1)
        _rigid_into(R1, Eb - Jr, G_Rj)
        _put_spring(G[6], cols[6], width[6], G_E, R1)
        _neck_into(G[7], cols[7], width[7], G_Ac, G_Ap, Ac, A, R1, R2)
        _neck_into(G[8], cols[8], width[8], G_Bc, G_B2, B, B2, R1, R2)
        _neck_into(G[9], cols[9], width[9], G_Ql, G_Q2, Ql, Q2, R1, R2)
        for i in range(6):
            for j in range(6):
                Ks[0, i, j] = Kb[leg, 0, i, j]
                Ks[1, i, j] = Kb[leg, 1, i, j]
        k0, k1, k2, k3 = s[6], s[7], s[8], s[9]
        for i in range(3):
            for j in range(3):
                ww = w[i] * w[j]
                e = 1.0 if i == j else 0.0
                kt = k1 * (e - ww) + k0 * ww
                kr = k2 * (e - ww) + k3 * ww
                for q in range(2, 5):
                    Ks[q, i, j] = kt
                    Ks[q, 3 + i, 3 + j] = kr
        _assemble_leg(Kl, G, Ks, P, cols, width, kidx, kval, coef, T12, kT, Ke, KG, gr, gb, gv)
        cond[leg] = _condense_leg_env(Kl, A_, Lt, d, inv, fcol, last, first, Y, x, contrib[leg], gross[leg])
