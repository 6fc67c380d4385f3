"""Whether a numba kernel module can run here (the one rule of every compiled path's fallback).

The collision check (:mod:`hapticopt.analysis.prrr.interference_fast`) and the frame condensation
(:mod:`hapticopt.analysis.prrr.frame_model`) ask :func:`unavailable` with a function that imports their kernel
module, and run their numpy path where the answer is a reason rather than None (the MuJoCo loops'
``mujoco_compiled.availability`` also checks that MuJoCo's library is reachable from compiled code).
"""

from __future__ import annotations

import os
from collections.abc import Callable


def unavailable(load: Callable[[], object], what: str) -> str | None:
    """None when numba imports and ``load()`` (which imports a kernel module) succeeds, else why not, one
    line naming ``what``. numba raises at decoration when no cache folder is writable (``NUMBA_CACHE_DIR``,
    ``__pycache__``, ``~/.cache``): that is an OSError or RuntimeError from ``load``."""
    try:
        import numba  # noqa: F401
    except ImportError as e:  # pragma: no cover - numba is a dependency
        return f"numba not importable ({e})"
    try:
        load()
    except (OSError, RuntimeError) as e:
        return f"{what} did not load: {e}"
    return None


# ---------------------------------------------------------------------------- kernel threads
_threads: int | None = None


def threads() -> int:
    """How many threads a batch's compiled kernels may run on at once (kernels that release the GIL, each
    thread on its own share of the designs): :func:`set_threads`' value, else the CPUs this process may run
    on (``os.sched_getaffinity``). A pool worker of a run is set to 1 (its siblings use the other CPUs)."""
    if _threads is not None:
        return _threads
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # pragma: no cover - platforms without affinity
        return max(1, os.cpu_count() or 1)


def set_threads(n: int | None) -> None:
    """Set :func:`threads` to ``n`` (≥ 1), or back to the CPU count with None."""
    global _threads
    if n is not None and (not isinstance(n, int) or n < 1):
        raise ValueError(f"threads = {n!r} is not allowed: an integer ≥ 1")
    _threads = n
