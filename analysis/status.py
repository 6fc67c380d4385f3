"""Outcome of an evaluation, as a value (failure is a value with a message)."""

from __future__ import annotations

from enum import StrEnum


class Status(StrEnum):
    OK = "ok"
    EMPTY = "empty"  # e.g. an empty workspace: metrics are 0, not NaN
    SINGULAR = "singular"  # a singular or ill-conditioned configuration was met
    UNSTABLE = "unstable"
    FAILED = "failed"
    INFEASIBLE = "infeasible"  # computed, but the requirement the metric reports does not hold (numbers kept)
