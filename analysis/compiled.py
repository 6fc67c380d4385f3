"""Whether a numba kernel module can run here (the one rule of every compiled path's fallback).

The collision check (:mod:`hapticopt.analysis.prrr.interference_fast`) and the frame condensation
(:mod:`hapticopt.analysis.prrr.frame_model`) ask :func:`unavailable` with a function that imports their kernel
module, and run their numpy path where the answer is a reason rather than None (the MuJoCo loops'
``mujoco_compiled.availability`` also checks that MuJoCo's library is reachable from compiled code).
"""

from __future__ import annotations

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
