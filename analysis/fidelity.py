"""Fidelity levels shared by every evaluator and simulator."""

from __future__ import annotations

from enum import StrEnum


class Fidelity(StrEnum):
    """Accuracy/time trade-off; ``FINE`` is the reference the cheaper levels are tested against."""

    DRAFT = "draft"
    STANDARD = "standard"
    FINE = "fine"
