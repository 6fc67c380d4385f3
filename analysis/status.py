"""Outcome of an evaluation, as a value (failure is a value with a message).

``ok`` means the requirement the evaluator reports holds (and its numbers are to be used);
every other status names what does not hold and comes with a message. Two families:

* **the numbers hold, the requirement does not** (:attr:`Status.metrics_hold`): ``not-met``
  (a required value is missed: the φ140 × 89 mm cylinder does not fit, a joint limit cuts it),
  ``collides`` (parts of the mechanism collide over part of its workspace), ``empty`` (no
  workspace: the metrics are 0). The optimiser keeps these numbers: it steers on them.
* **the numbers do not hold** (metrics NaN, the optimiser treats the point as failed):
  ``not-assemblable`` (the mechanism cannot be put together as described: no pose closes every
  leg within its reach and slider stroke, or the CAD cannot lay its parts out), ``singular``,
  ``ill-conditioned``, ``not-positive-definite``, ``unstable``, ``inconclusive``, ``failed``.

Records written before these statuses existed hold ``infeasible`` where ``not-met`` is now
written; :meth:`Status.parse` reads both.
"""

from __future__ import annotations

from enum import StrEnum


class Status(StrEnum):
    OK = "ok"  # the requirement the evaluator reports holds
    NOT_MET = "not-met"  # computed, but a required value is missed (numbers kept)
    COLLIDES = "collides"  # parts collide over part of the workspace (numbers kept: the colliding share)
    EMPTY = "empty"  # e.g. an empty workspace: metrics are 0, not NaN
    NOT_ASSEMBLABLE = "not-assemblable"  # the chain cannot be closed, or the parts cannot be laid out
    SINGULAR = "singular"  # rcond below analysis.conditioning.RCOND_SINGULAR: no answer exists
    ILL_CONDITIONED = "ill-conditioned"  # rcond below RCOND_ILL: the answer has lost most of its digits
    NOT_POSITIVE_DEFINITE = "not-positive-definite"  # a stiffness/mass matrix with a non-positive eigenvalue
    UNSTABLE = "unstable"
    INCONCLUSIVE = "inconclusive"  # the run cannot decide what it measures: too short for the instability
    # detector, or too little motion (≤ 100 encoder quanta) to fit the rendered stiffness
    FAILED = "failed"

    @property
    def metrics_hold(self) -> bool:
        """Whether the metrics reported with this status are numbers to use (ok, not-met, collides, empty)."""
        return self in (Status.OK, Status.NOT_MET, Status.COLLIDES, Status.EMPTY)

    @classmethod
    def parse(cls, value: str) -> Status:
        """The status written as ``value``, including the words of older records (``infeasible`` →
        ``not-met``); raises ``ValueError`` for an unknown word."""
        return cls(LEGACY.get(value, value))


#: words older run records hold → the status that now means the same
LEGACY: dict[str, str] = {"infeasible": Status.NOT_MET.value}


def upgrade(statuses: dict[str, str]) -> dict[str, str]:
    """Evaluator → status word of a run record, older words replaced by today's (other words kept
    as written: a record is shown as it is, never rejected for a word this version does not know)."""
    return {name: LEGACY.get(word, word) for name, word in statuses.items()}
