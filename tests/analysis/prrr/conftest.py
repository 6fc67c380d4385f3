"""Fixtures shared by the 3-PRRR tests."""

from __future__ import annotations

import dataclasses
import math
import sys
import tomllib
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

from hapticopt.design import io
from hapticopt.design.errors import InvalidDesign

sys.path.insert(0, str(Path(__file__).parent))  # prrr_stepped_loop: the plain reference loops of the tests here

PROBLEM = Path(__file__).resolve().parents[3] / "optim" / "problems" / "prrr-workspace.toml"


def _problem_sample(n: int, seed: int, accept: Callable | None = None) -> list:
    """``n`` prrr-paper variants drawn uniformly within the variable bounds of :data:`PROBLEM`
    (seeded). A draw the parameter rules refuse (``InvalidDesign``) — or that ``accept(design)``
    refuses by raising it — is skipped and the next one drawn."""
    base = io.load_preset("prrr-paper")
    variables = tomllib.loads(PROBLEM.read_text())["variables"]
    rng = np.random.default_rng(seed)
    out: list = []
    while len(out) < n:
        kw = {}
        for v in variables:
            section, name = v["key"].split(".")
            assert section == "geometry", v
            x = rng.uniform(v["lower"], v["upper"])
            field, unit = name.rsplit("_", 1)
            kw[field] = {"mm": x / 1000.0, "deg": math.radians(x)}[unit]
        try:
            d = dataclasses.replace(base, geometry=dataclasses.replace(base.geometry, **kw))
            if accept is not None:
                accept(d)
        except InvalidDesign:
            continue
        out.append(d)
    return out


@pytest.fixture
def problem_sample() -> Callable:
    """``problem_sample(n, seed, accept=None)``: designs within the bundled prrr-workspace problem's
    bounds (colliding, not-assemblable and empty ones among them unless ``accept`` filters)."""
    return _problem_sample


@pytest.fixture(scope="session")
def collision_reference():
    """The numpy reference of the collision kernel (``interference_reference.py`` beside this file: it
    proves ``_interference_kernels`` right and is not part of the package)."""
    return _beside("interference_reference.py")


@pytest.fixture(scope="session")
def sampled_wall():
    """The exact boundary of a 1-DOF sampled virtual wall (``loop/sampled_wall_reference.py``: the
    reference the 3-PRRR's sampled loop is checked against; not part of the package)."""
    return _beside("loop/sampled_wall_reference.py")


def _beside(relpath: str):
    """The module at ``relpath`` beside this file, loaded by path (tests/ is not a package)."""
    import importlib.util

    path = Path(__file__).parent / relpath
    spec = importlib.util.spec_from_file_location(path.stem, path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module
