"""How a computation runs: the one explicit route value a caller passes down.

A :class:`Compute` travels from the CLI (``--backend``, ``--threads``) or a problem file through the
pipeline and the registry to every evaluator and kernel that has more than one route. Nothing else
chooses a route: no process counter, no probe of ``sys.modules``, no pool sized at first use. The same
``Compute`` and the same input always take the same code path (MuJoCo's ``Rollout(nthread=…)`` is the
model: the caller says how to run, the library does not guess from its history).

``backend``:

* ``"auto"``: decide from the size of this call's work (:meth:`Compute.use_numba` with a per-route
  threshold), never from what the process did before;
* ``"numpy"``: plain numpy everywhere (no numba import);
* ``"numba"``: the compiled kernel wherever a route has one;
* ``"jax"``: the jitted jax path where a route has one (else as ``"auto"``).

``threads``: how many threads a batch's GIL-free kernels may use (each on its own share of the
designs); None means the CPUs this process may run on. A run's pool workers get ``threads=1``.
Results are the same bits at any thread count (tested per route).
"""

from __future__ import annotations

import os
from collections.abc import Callable
from dataclasses import dataclass
from enum import StrEnum


class Backend(StrEnum):
    AUTO = "auto"
    NUMPY = "numpy"
    NUMBA = "numba"
    JAX = "jax"


#: the most kernel threads a Compute may ask for (bounds memory and thread start-up)
MAX_THREADS = 256


@dataclass(frozen=True, kw_only=True, slots=True)
class Compute:
    """The route and thread count of a computation (frozen; pass it down, never store it globally)."""

    backend: Backend = Backend.AUTO
    threads: int | None = None

    def __post_init__(self) -> None:
        try:
            object.__setattr__(self, "backend", Backend(self.backend))
        except ValueError:
            allowed = ", ".join(b.value for b in Backend)
            raise ValueError(f"backend = {self.backend!r} is not allowed: one of {allowed}") from None
        t = self.threads
        if t is not None and (isinstance(t, bool) or not isinstance(t, int) or not 1 <= t <= MAX_THREADS):
            raise ValueError(f"threads = {t!r} is not allowed: an integer from 1 to {MAX_THREADS}, or None for the CPU count")

    def thread_count(self) -> int:
        """``threads``, else the CPUs this process may run on (``os.sched_getaffinity``)."""
        if self.threads is not None:
            return self.threads
        try:
            return max(1, len(os.sched_getaffinity(0)))
        except AttributeError:  # pragma: no cover - platforms without affinity
            return max(1, os.cpu_count() or 1)

    def use_numba(self, work: int, threshold: int) -> bool:
        """Whether a route with a numba kernel takes it for ``work`` items (poses, designs, ticks):
        always with ``"numba"``, never with ``"numpy"``, from ``threshold`` items on with ``"auto"``
        (and ``"jax"``, which has no numba route of its own to replace)."""
        if self.backend is Backend.NUMBA:
            return True
        if self.backend is Backend.NUMPY:
            return False
        return work >= threshold


#: the default: decide by the size of each call, all CPUs
DEFAULT = Compute()


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
