"""Outcome of an evaluation, as a value (failure is a value with a message).

A status other than ``ok``, ``empty`` or ``infeasible`` means the evaluator's numbers do not hold:
its metrics are NaN, and the optimiser treats the point as failed (:attr:`Status.metrics_hold`).
``infeasible`` keeps its numbers: they were computed, only the requirement they report is missed.
"""

from __future__ import annotations

from enum import StrEnum


class Status(StrEnum):
    OK = "ok"
    EMPTY = "empty"  # e.g. an empty workspace: metrics are 0, not NaN
    SINGULAR = "singular"  # rcond below analysis.conditioning.RCOND_SINGULAR: no answer exists
    ILL_CONDITIONED = "ill-conditioned"  # rcond below RCOND_ILL: the answer has lost most of its digits
    NOT_POSITIVE_DEFINITE = "not-positive-definite"  # a stiffness/mass matrix with a non-positive eigenvalue
    UNSTABLE = "unstable"
    INCONCLUSIVE = "inconclusive"  # the run cannot decide what it measures: too short for the instability
    # detector, or too little motion (≤ 100 encoder quanta) to fit the rendered stiffness
    FAILED = "failed"
    INFEASIBLE = "infeasible"  # computed, but the requirement the metric reports does not hold (numbers kept)

    @property
    def metrics_hold(self) -> bool:
        """Whether the metrics reported with this status are numbers to use (ok, empty, infeasible)."""
        return self in (Status.OK, Status.EMPTY, Status.INFEASIBLE)
