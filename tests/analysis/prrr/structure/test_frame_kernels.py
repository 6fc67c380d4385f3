"""The numba kernel of the legs' assembly and condensation against the numpy route.

Reference: :func:`hapticopt.analysis.prrr.structure.frame_model.condense_legs` with ``xp=numpy`` (LAPACK's
partial-pivoting LU per leg) on the legs that ``frame_condense.assemble_terms`` assembles; the kernel
factorises by Cholesky over the envelope, so the two agree to rounding, not bitwise.
"""

import numpy as np
import pytest

from hapticopt.analysis.prrr.structure import frame_condense as FC
from hapticopt.analysis.prrr.structure import frame_beam as FBEAM
from hapticopt.analysis.prrr.structure import frame_model as fm
pytest.importorskip("numba")


def _paper_legs(options):
    """prrr-paper's leg terms at home (G, K_s, P contiguous), the terms' columns, the leg size n and the
    legs' numpy-assembled stiffness K (element_stiffness + assemble_terms)."""
    from hapticopt.design import io

    G, Ks, P, _ = fm.frame_leg_terms(fm.frame_params_of(io.load_preset("prrr-paper"), xp=np), np.zeros(3), options,
                                     xp=np)
    G, Ks, P = (np.ascontiguousarray(x) for x in (G, Ks, P))
    cols = fm.term_columns(options)
    n = fm._leg_layout(options)[0]
    return G, Ks, P, cols, n, FC.assemble_terms(G, np.concatenate([FBEAM.element_stiffness(P, np), Ks], axis=1), cols, n)


def test_assembling_kernel_equals_numpy_assembly():
    # the paper's legs as terms: assemble_condense_kernel (elements built in it, the factorisation over the
    # structure of the terms' columns, K_PP − Yᵀ Y with Y = L⁻¹ d K_iP) against element_stiffness +
    # assemble_terms and the numpy reference (condense_legs: LAPACK's LU; the condensation to 1e-10; the
    # condition estimate, Hager's two steps on two factorisations of a matrix of condition ~1e4, to 1e-10)
    from hapticopt.analysis.prrr.structure._frame_kernels import assemble_condense_kernel

    options = fm.FrameOptions()
    G, Ks, P, cols, n, K = _paper_legs(options)
    out = np.empty((3, 6, 6)), np.empty(3), np.empty((3, 6))
    assemble_condense_kernel(G, Ks, P, FBEAM._PATTERNS, cols.astype(np.int64), n, *out)
    lu_contrib, lu_cond, lu_rec = fm.condense_legs(K, np)
    np.testing.assert_allclose(out[0], lu_contrib, rtol=1e-10, atol=1e-12 * np.abs(lu_contrib).max())
    np.testing.assert_allclose(out[1], lu_cond, rtol=1e-10)
    removed = np.einsum("lai,lia->la", K[:, :6, 6:], lu_rec)
    np.testing.assert_allclose(out[2], np.abs(np.diagonal(K[:, :6, :6], axis1=1, axis2=2)) + np.abs(removed),
                               rtol=1e-10)


@pytest.mark.parametrize("options", [
    fm.FrameOptions(sea=True), fm.FrameOptions(offsets=fm.Offsets.RIGID),
    fm.FrameOptions(joints=fm.Joints.BONDED), fm.FrameOptions(pin_model=fm.PinModel.BEAM)], ids=str)
def test_assembling_kernel_on_other_topologies(options):
    # the envelope (_structure) is derived from each topology's columns: the kernel against the numpy
    # reference (condense_legs, LAPACK's LU) on each. Measured on prrr-paper: ≤ 8.6e-12 of the largest
    # entry (the condensation) and ≤ 1.9e-12 relative (the condition estimate), as the previous kernel
    # (fc9af43: 8.6e-12, 1.8e-12); a decade's margin
    from hapticopt.analysis.prrr.structure._frame_kernels import assemble_condense_kernel

    G, Ks, P, cols, n, K = _paper_legs(options)
    lu_contrib, lu_cond, _ = fm.condense_legs(K, np)
    out = np.empty((3, 6, 6)), np.empty(3), np.empty((3, 6))
    assemble_condense_kernel(G, Ks, P, FBEAM._PATTERNS, cols.astype(np.int64), n, *out)
    np.testing.assert_allclose(out[0], lu_contrib, rtol=0, atol=1e-10 * np.abs(lu_contrib).max())
    np.testing.assert_allclose(out[1], lu_cond, rtol=1e-11)


def test_structure_is_the_envelope():
    # a star on the internal DOFs (0 coupled to 1, 2, 3; P to 3): every row starts at column 0, so the
    # envelope is the whole lower triangle (where eliminating 0 fills every pair of 1, 2, 3; closed form:
    # the elimination graph); and a chain (0-1, 1-2, 2-3): a band of one
    from hapticopt.analysis.prrr.structure._frame_kernels import _structure

    star = np.array([[6, 7], [6, 8], [6, 9], [0, 9]], dtype=np.int64)
    fcol, last, first = _structure(star, 10)
    assert fcol.tolist() == [0, 0, 0, 0] and last.tolist() == [3, 3, 3, 3] and first == 3
    chain = np.array([[6, 7], [7, 8], [8, 9], [0, 7]], dtype=np.int64)
    fcol, last, first = _structure(chain, 10)
    assert fcol.tolist() == [0, 0, 1, 2] and last.tolist() == [1, 2, 3, 3] and first == 1


def test_assembling_kernel_leg_not_positive_definite_is_nan():
    # one leg's joint spring turned strongly negative: its internal block is not positive definite, so
    # that leg's outputs are NaN (the batch's verdict then solves the design by the single path); the
    # other legs are untouched
    from hapticopt.analysis.prrr.structure._frame_kernels import assemble_condense_kernel
    from hapticopt.design import io

    options = fm.FrameOptions()
    G, Ks, P, _ = fm.frame_leg_terms(fm.frame_params_of(io.load_preset("prrr-paper"), xp=np), np.zeros(3), options,
                                     xp=np)
    G, Ks, P = (np.ascontiguousarray(x) for x in (G, Ks, P))
    Ks[1] *= -1.0
    cols = fm.term_columns(options).astype(np.int64)
    out = np.empty((3, 6, 6)), np.empty(3), np.empty((3, 6))
    assemble_condense_kernel(G, Ks, P, FBEAM._PATTERNS, cols, fm._leg_layout(options)[0], *out)
    assert np.all(np.isnan(out[0][1])) and np.isnan(out[1][1]) and np.all(np.isnan(out[2][1]))
    assert np.all(np.isfinite(out[0][[0, 2]])) and np.all(np.isfinite(out[1][[0, 2]]))
