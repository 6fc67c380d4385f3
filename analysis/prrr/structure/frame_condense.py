"""The frame model's legs assembled and condensed over a batch of designs outside jit (numpy arrays,
leading design axis n).

The batched draft evaluator jits only the legs' unassembled terms (:func:`.frame_model.frame_leg_terms`);
:func:`condense_terms_many` builds each element, assembles each leg and condenses it onto the
end-effector node, by one of two routes the caller's :class:`~hapticopt.analysis.compute.Compute`
chooses: numpy (:func:`.frame_beam.element_stiffness`, :func:`assemble_terms`,
:func:`.frame_model.condense_legs`: LAPACK's LU per leg) or the numba kernel (:mod:`._frame_kernels`:
Cholesky along each leg's chain of DOFs). Both equal the single path (:func:`.frame_model.solve_frame`)
to 1e-9 and each other to 1e-10 (tested).
"""

from __future__ import annotations

import functools

import numpy as np

from hapticopt.analysis import compute as compute_
from hapticopt.analysis.compute import DEFAULT, Compute
from hapticopt.analysis.prrr.structure.frame_beam import _PATTERNS, element_stiffness
from hapticopt.analysis.prrr.structure.frame_model import (FrameOptions, _leg_layout, compliance_outputs, condense_legs,
                                                 term_columns)

#: At or above this cancellation on the condensed stiffness's diagonal (Σ_legs |K_PP,aa| + |(K_Pi K_ii⁻¹ K_iP)_aa|
#: over |K_P,aa|, largest over a) :func:`condense_terms_many` returns NaN (digits left ≈ 16 − log10 of it).
#: At the home pose every design the single path solves stays below 10^6; β = 89.999999° (singular) is 10^16.7.
CANCELLATION_LIMIT = 1e8
#: ``Compute(backend="auto")`` runs :func:`condense_terms_many`'s numba kernel for calls of this many designs
#: or more: the kernel is faster per call once loaded, but loading it (numba's import and the cached kernel)
#: costs more than a call of a few designs by numpy, so a small call (one design from the CLI, a handful in a
#: test) runs numpy and never loads numba.
KERNEL_FROM_DESIGNS = 8


@functools.cache
def kernel_availability() -> str | None:
    """None when :func:`condense_terms_many`'s numba kernel can run here, else why not (one line); the
    numpy route runs then, whatever the :class:`Compute`."""
    return compute_.unavailable(_load_kernels, "the compiled frame kernel's module")


def _load_kernels() -> None:
    from hapticopt.analysis.prrr.structure import _frame_kernels  # noqa: F401


def assemble_terms(G, Kt, cols: np.ndarray, n: int) -> np.ndarray:
    """Legs' stiffness (L, n, n) from their terms (:func:`.frame_model.frame_leg_terms`; ``G`` (L, T, 12, M),
    ``Kt`` (L, T, 12, 12), ``cols`` (T, M)): sym(Σ_t G_tᵀ K_t G_t) scattered onto ``cols``."""
    G, Kt = np.asarray(G, dtype=float), np.asarray(Kt, dtype=float)
    K = np.zeros((G.shape[0], n, n))
    for t, c in enumerate(cols):
        m = 1 + int(np.count_nonzero(c[1:] != c[0]))  # the padding repeats c[0] (its map columns are zero)
        small = np.swapaxes(G[:, t, :, :m], -1, -2) @ Kt[:, t] @ G[:, t, :, :m]  # (L, m, m)
        K[:, c[:m, None], c[None, :m]] += small  # c[:m] distinct: no index repeats within a term
    return 0.5 * (K + np.swapaxes(K, -1, -2))


def condense_many(K, load_height) -> dict[str, np.ndarray]:
    """:func:`.frame_model.condense_legs` (numpy: LAPACK's LU per leg) and
    :func:`.frame_model.compliance_outputs` of n designs' legs' stiffness ``K`` (n, 3, N, N); the keys of
    ``compliance_outputs`` with a leading axis n, NaN rows as :func:`condense_terms_many`."""
    K = np.ascontiguousarray(K, dtype=float)
    n, legs, N = K.shape[0], K.shape[1], K.shape[-1]
    flat = K.reshape(n * legs, N, N)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        contrib, cond, recovery = condense_legs(flat, np)
        removed = np.einsum("lai,lia->la", flat[:, :6, 6:], recovery)  # diagonal of K_Pi K_ii⁻¹ K_iP
        gross = np.abs(np.diagonal(flat[:, :6, :6], axis1=-2, axis2=-1)) + np.abs(removed)
        return _outputs_many(contrib, cond, gross, n, legs, load_height)


def condense_terms_many(G, Ks, P, options: FrameOptions, load_height, *,
                        compute: Compute = DEFAULT) -> dict[str, np.ndarray]:
    """Each leg of n designs assembled from its terms (:func:`.frame_model.frame_leg_terms` over designs:
    ``G`` (n, 3, T, 12, M), ``Ks`` (n, 3, S, 12, 12), ``P`` (n, 3, E, 18)) and condensed onto the
    end-effector node; the keys of :func:`.frame_model.compliance_outputs`, leading axis n.

    ``compute.use_numba(n, KERNEL_FROM_DESIGNS)`` (and :func:`kernel_availability`) picks the numba kernel
    (each element's stiffness over the nonzeros of its patterns, each leg's Σ Gᵀ K G over the maps'
    nonzeros, Cholesky along the chain); else numpy (:func:`.frame_beam.element_stiffness`,
    :func:`assemble_terms`, :func:`condense_many`). NaN rows: a leg whose scaled internal matrix is not
    positive definite (the kernel), and a design whose condensation K_P = Σ (K_PP − K_Pi K_ii⁻¹ K_iP)
    cancels by :data:`CANCELLATION_LIMIT` or more on its diagonal (either route): there the numbers are
    rounding that differs between eliminations; the batched draft evaluator solves such a design again
    by the single path."""
    cols = term_columns(options)
    N = _leg_layout(options)[0]
    G, Ks, P = (np.asarray(x, dtype=float) for x in (G, Ks, P))
    n, legs = G.shape[:2]
    G, Ks, P = (np.ascontiguousarray(x.reshape((n * legs,) + x.shape[2:])) for x in (G, Ks, P))
    if not (compute.use_numba(n, KERNEL_FROM_DESIGNS) and kernel_availability() is None):
        K = assemble_terms(G, np.concatenate([element_stiffness(P, np), Ks], axis=1), cols, N)
        return condense_many(K.reshape(n, legs, N, N), load_height)
    from hapticopt.analysis.prrr.structure._frame_kernels import assemble_condense_kernel
    contrib, cond, gross = np.empty((n * legs, 6, 6)), np.empty(n * legs), np.empty((n * legs, 6))
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        assemble_condense_kernel(G, Ks, P, _PATTERNS, np.ascontiguousarray(cols, dtype=np.int64), N, contrib, cond,
                                 gross)
        return _outputs_many(contrib, cond, gross, n, legs, load_height)


def _outputs_many(contrib, cond, gross, n: int, legs: int, load_height) -> dict[str, np.ndarray]:
    """:func:`.frame_model.compliance_outputs` of n designs from their legs' condensation (legs × n
    flattened), NaN rows where the condensation cancels by :data:`CANCELLATION_LIMIT` or more."""
    KP = np.sum(contrib.reshape(n, legs, 6, 6), axis=1)
    cancel = np.max(np.sum(gross.reshape(n, legs, 6), axis=1) / np.abs(np.diagonal(KP, axis1=-2, axis2=-1)), axis=1)
    out = compliance_outputs(KP, np.max(cond.reshape(n, legs), axis=1), np.asarray(load_height, dtype=float), np)
    bad = ~(cancel < CANCELLATION_LIMIT)  # NaN too
    for v in out.values():
        v[bad] = np.nan
    return out
