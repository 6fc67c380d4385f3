"""The material library: sourced mechanical properties of the materials parts can be made of.

``design/materials.toml`` (packaged data) holds one table per material: Young's modulus, Poisson's
ratio, density, yield and ultimate strength, one S-N point (fully reversed stress amplitude
``fatigue`` survived for ``fatigue_cycles`` cycles), the manufacturing process, the source of the
numbers and a note (anisotropy of printed and fibre parts). Values in SI here; the TOML keys carry
their units. A design names a material per part group (``structure.material`` of the 3-PRRR);
mass (density), stiffness (E, ν) and strength (yield, fatigue) all read it.

A material is categorical: the optimiser's continuous methods (NLopt) cannot move it, so a study
compares materials by enumeration (one optimisation per material, the discrete outer loop;
docs/strength.md), each run with the material fixed.
"""

from __future__ import annotations

import functools
import tomllib
from dataclasses import dataclass
from importlib import resources

from hapticopt.design.errors import InvalidDesign, short

#: the library's packaged file
LIBRARY = "materials.toml"


@dataclass(frozen=True, kw_only=True)
class Material:
    """One library entry [SI]."""

    name: str
    youngs_modulus: float  # [Pa]
    poisson_ratio: float  # [-]
    density: float  # [kg/m³]
    yield_strength: float  # [Pa] 0.2 % proof (weakest build direction for printed parts)
    ultimate_strength: float  # [Pa]
    fatigue_strength: float  # [Pa] fully reversed amplitude survived for ``fatigue_cycles``
    fatigue_cycles: float  # [-] cycles of that S-N point
    process: str
    source: str
    note: str


_KEYS = {"youngs_modulus_GPa": ("youngs_modulus", 1e9), "poisson_ratio": ("poisson_ratio", 1.0),
         "density_kg_per_m3": ("density", 1.0), "yield_MPa": ("yield_strength", 1e6),
         "ultimate_MPa": ("ultimate_strength", 1e6), "fatigue_MPa": ("fatigue_strength", 1e6),
         "fatigue_cycles": ("fatigue_cycles", 1.0)}
_TEXT = ("process", "source", "note")


@functools.cache
def library() -> dict[str, Material]:
    """Every material of the packaged library by name (parsed and checked once)."""
    text = (resources.files("hapticopt.design") / LIBRARY).read_text(encoding="utf-8")
    out = {}
    for name, table in tomllib.loads(text).items():
        missing = sorted((set(_KEYS) | set(_TEXT)) - set(table))
        if missing:
            raise InvalidDesign(f"{LIBRARY} [{name}] lacks {', '.join(missing)}")  # a packaging error
        values = {field: float(table[key]) * scale for key, (field, scale) in _KEYS.items()}
        if not all(v > 0.0 for v in values.values()) or values["poisson_ratio"] >= 0.5:
            raise InvalidDesign(f"{LIBRARY} [{name}] has a non-positive value or poisson_ratio >= 0.5")
        out[name] = Material(name=name, **values, **{k: str(table[k]) for k in _TEXT})
    return out


def names() -> tuple[str, ...]:
    """The library's material names, in file order."""
    return tuple(library())


def material(name: object, where: str = "structure.material") -> Material:
    """The library entry ``name``; :class:`InvalidDesign` (one line naming ``where`` and the known
    materials; exit 2 at the CLI) for any other value."""
    lib = library()
    if not isinstance(name, str) or name not in lib:
        raise InvalidDesign(f"{where} = {short(name)} is not a known material: allowed {', '.join(lib)} "
                            f"(design/{LIBRARY})")
    return lib[name]
