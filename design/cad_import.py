"""build123d without scikit-learn until it is needed.

``import build123d`` imports ``build123d.brep_from_stl`` (primitive detection on STL meshes), which
imports scikit-learn's ``DBSCAN`` and with it ``scipy.stats``: a large share of the build123d import
(docs/performance.md), in every process that builds CAD (``hapticopt export`` and the
pipeline's side process). Nothing here detects primitives. :func:`build123d` imports build123d with a
stand-in for that one module in ``sys.modules``: ``build123d.detect_primitives`` and every other name of
the module still work, and the first use imports the real module.

Call it before every ``from build123d import …`` (it only returns the module once build123d is imported).
"""

from __future__ import annotations

import importlib
import sys
import types
from typing import Any

#: the build123d module that imports scikit-learn
DEFERRED = "build123d.brep_from_stl"


class _StandIn(types.ModuleType):
    """``build123d.brep_from_stl`` until first use: any name read from it imports the real module."""

    def __getattr__(self, name: str) -> Any:
        if name.startswith("__") and name.endswith("__"):  # probes (__path__, __file__ …) import nothing
            raise AttributeError(name)
        return getattr(_real(), name)


def _real() -> types.ModuleType:
    """The real module (imported now if the stand-in is still in ``sys.modules``)."""
    if isinstance(sys.modules.get(DEFERRED), _StandIn):
        del sys.modules[DEFERRED]
    module = importlib.import_module(DEFERRED)
    parent = sys.modules.get("build123d")
    if parent is not None:
        parent.__dict__["brep_from_stl"] = module
    return module


def detect_primitives(*args: Any, **kwargs: Any) -> Any:
    """``build123d.detect_primitives`` (the real one, imported on this first call)."""
    return _real().detect_primitives(*args, **kwargs)


def build123d() -> types.ModuleType:
    """The build123d module; imported here (the first time) with a stand-in for :data:`DEFERRED`,
    which is also its ``brep_from_stl`` attribute until the real module is imported."""
    if "build123d" in sys.modules:
        return sys.modules["build123d"]
    stand_in = None
    if DEFERRED not in sys.modules:
        stand_in = _StandIn(DEFERRED, "stand-in for build123d.brep_from_stl (hapticopt.design.cad_import)")
        stand_in.detect_primitives = detect_primitives
        sys.modules[DEFERRED] = stand_in
    module = importlib.import_module("build123d")
    if stand_in is not None and sys.modules.get(DEFERRED) is stand_in:
        module.__dict__.setdefault("brep_from_stl", stand_in)
    return module
