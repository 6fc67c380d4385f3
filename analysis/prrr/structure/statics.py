"""3-PRRR statics from the constant Jacobian: condition, equivalent mass, force and stiffness limits.

Closed forms of seed 002 (eq 2, 4, 7, 14–15, corrected as in the seed digest). The Jacobian is
constant over the workspace, so these hold everywhere; fidelity does not change them.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from hapticopt.design import jax_config  # noqa: F401  (float64 before any jax array)
import jax
import jax.numpy as jnp
import numpy as np

from hapticopt.analysis import conditioning
from hapticopt.analysis.prrr.geometry import assembly
from hapticopt.analysis.fidelity import Fidelity
from hapticopt.design.prrr.kinematics import (  # noqa: F401  (condition_* re-exported)
    PrrrParams, condition_2norm, condition_frobenius, jacobian, jacobian_inverse, params_np)
from hapticopt.analysis.status import Status
from hapticopt.design.prrr.params import PrrrDesign


def statics_arrays(params: PrrrParams, spring: jax.Array, force_limit: jax.Array, mass: jax.Array,
                   xp=jnp) -> dict:
    """All statics quantities in SI for one design (vmap over a leading batch for many).

    ``spring`` k [N/m], ``force_limit`` F_max per actuator [N], ``mass`` M [kg]. ``xp`` is the
    array module: ``jax.numpy`` (default; jit/vmap/grad) or ``numpy`` (single design, no compile).
    """
    J = jacobian(params.beta, xp=xp)
    Ji = jacobian_inverse(params.beta, xp=xp)
    stiffness = spring * Ji.T @ Ji  # eq 14: J⁻ᵀ (k I) J⁻¹ [N/m]
    return {
        "jacobian": J,
        "condition": condition_2norm(J, xp=xp),
        "condition_frobenius": condition_frobenius(J, xp=xp),
        "effective_mass": mass * J.T @ J,  # eq 7: Jᵀ diag(M,M,M) J [kg], slider space
        "stiffness_matrix": stiffness,
        "stiffness_limit": xp.diagonal(stiffness),
        # eq 4, F = J⁻ᵀ f with |f_i| ≤ F_max: per-axis maximum over the force box
        "max_force": force_limit * xp.sum(xp.abs(Ji), axis=0),
        # a pure force along one axis (other components zero): F_max / max_i |(J⁻ᵀ)⁻¹ e_axis|
        "max_pure_force": force_limit / xp.max(xp.abs(J.T), axis=0),
    }


@dataclass(frozen=True, kw_only=True)
class PrrrStatics:
    """Statics of one 3-PRRR design [SI]."""

    jacobian: np.ndarray  # (3, 3), Ḋ ↦ ṗ
    condition: float  # cond₂(J)
    condition_frobenius: float
    effective_mass: np.ndarray  # (3, 3) [kg], eq 7
    stiffness_matrix: np.ndarray  # (3, 3) [N/m], eq 14
    stiffness_limit: np.ndarray  # (3,) [N/m], k_x, k_y, k_z
    max_force: np.ndarray  # (3,) [N], per-axis maxima (other components free)
    max_pure_force: np.ndarray  # (3,) [N], pure-axis force limits
    status: Status = Status.OK
    message: str = ""

    def metrics(self) -> dict[str, object]:
        """Engineering-unit metrics (names carry their units); NaN unless the status is ok."""
        if self.status is not Status.OK:
            nan = float("nan")
            return {"jacobian_condition": nan, "jacobian_condition_frobenius": nan, "max_force_N": [nan] * 3,
                    "max_pure_force_N": [nan] * 3, "stiffness_limit_N_per_mm": [nan] * 3,
                    "effective_mass_kg": [[nan] * 3 for _ in range(3)]}
        return {
            "jacobian_condition": float(self.condition),
            "jacobian_condition_frobenius": float(self.condition_frobenius),
            "max_force_N": _floats(self.max_force),
            "max_pure_force_N": _floats(self.max_pure_force),
            "stiffness_limit_N_per_mm": [x * 1e-3 for x in _floats(self.stiffness_limit)],
            "effective_mass_kg": _floats(self.effective_mass),
        }


def _floats(a) -> list:
    """``a`` as (nested) lists of Python floats, converted in one call (``float`` of each element)."""
    return np.asarray(a, dtype=float).tolist()


def evaluate(design: PrrrDesign, *, fidelity: Fidelity = Fidelity.STANDARD, shared: Any = None) -> PrrrStatics:
    """Statics of ``design``. Exact closed forms: every fidelity gives the same result. ``shared``: the
    registry call's :class:`hapticopt.analysis.prrr.shared.DesignSteps` of ``design`` (its statics,
    computed once for this evaluator and the stability evaluator's stiffness limits).

    Status ``not-assemblable`` (metrics NaN, the arrays kept for callers that need the closed
    forms) when J is well conditioned but the chain does not close
    (:func:`hapticopt.analysis.prrr.geometry.assembly.closure`); otherwise the conditioning verdict of J.
    """
    del fidelity  # closed form
    if shared is not None:
        return shared.statics(design)
    a = design.actuator
    # numpy path: a single design needs no jit compile (the CLI's start-up budget); the jax
    # path (same function, xp=jnp) serves batches and gradients and is tested equal.
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        out = statics_arrays(params_np(design), a.spring, a.force_limit, design.end_effector.mass, xp=np)
    return from_arrays(design, out)


def from_arrays(design: PrrrDesign, out: dict) -> PrrrStatics:
    """The result of ``design`` from its :func:`statics_arrays` (numpy or a row of a jax batch):
    the one place the statics verdict is made."""
    out = {k: np.asarray(v) for k, v in out.items()}
    finite = all(np.all(np.isfinite(v)) for v in out.values())
    return _result(design, out, conditioning.rcond(out["jacobian"]), finite)


def from_arrays_many(designs: list[PrrrDesign], out: dict) -> list[PrrrStatics]:
    """:func:`from_arrays` of every design from the stacked :func:`statics_arrays` ``out`` (leading
    axis: the designs, the batched draft evaluator's): the reciprocal condition numbers in one
    batched SVD and the finiteness in one pass, the verdict of each design by the same rule."""
    out = {k: np.asarray(v) for k, v in out.items()}
    r = conditioning.rcond_many(out["jacobian"])
    finite = np.ones(len(designs), dtype=bool)
    for v in out.values():
        finite &= np.all(np.isfinite(v.reshape(len(designs), -1)), axis=1)
    rows = (dict(zip(out, vals)) for vals in zip(*(list(v) for v in out.values())))  # out[k][i] per design
    return [_result(d, row, rc, ok) for d, row, rc, ok in zip(designs, rows, r.tolist(), finite.tolist())]


def _result(design: PrrrDesign, out: dict, rcond: float, finite: bool) -> PrrrStatics:
    """The verdict and the result from the arrays, rcond(J) and whether every array is finite."""
    # the verdict: the reciprocal condition number of J, banded (analysis.conditioning), never
    # whether the numbers happened to come out finite
    verdict = conditioning.classify_rcond(rcond, what=f"the Jacobian at β = {math.degrees(design.geometry.beta):.12g}°")
    if verdict.ok and not finite:
        verdict = conditioning.Conditioning(status=Status.SINGULAR, rcond=verdict.rcond,
                                            message="the statics are not finite at this design")
    status, message = verdict.status, verdict.message
    # the constant-J closed forms hold only for a chain that closes; a J verdict other than ok already
    # says the numbers are meaningless and keeps its (issue 14) word
    blocked = assembly.closure(design) if verdict.ok else ""
    if blocked:
        status, message = Status.NOT_ASSEMBLABLE, blocked
    return PrrrStatics(
        jacobian=out["jacobian"],
        condition=float(out["condition"]),
        condition_frobenius=float(out["condition_frobenius"]),
        effective_mass=out["effective_mass"],
        stiffness_matrix=out["stiffness_matrix"],
        stiffness_limit=out["stiffness_limit"],
        max_force=out["max_force"],
        max_pure_force=out["max_pure_force"],
        status=status,
        message=message,
    )
