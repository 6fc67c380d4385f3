"""Mass properties (mass, centre of mass, inertia tensor) of every part and rigid body.

Two sources of the same numbers:

* :func:`analytic` — closed forms summed over the part tables of :mod:`design.parts`
  (boxes, cylinders, spheres, boss/bar overlaps as cap segments). No solid is built; this is the
  model for evaluators and the optimiser.
* :func:`from_cad` — OpenCASCADE's volume integrals of the build123d solids (the reference).

Every quantity is SI and expressed in the part's own frame (the frame of the body that carries
it; see :func:`hapticopt.design.prrr.cad.part_frames`); inertia is about the centre of mass.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from enum import StrEnum
from typing import Any

import numpy as np

from hapticopt.design import cad_units
from hapticopt.design import parts as _parts


class Method(StrEnum):
    ANALYTIC = "analytic"
    CAD = "cad"


@dataclass(frozen=True, kw_only=True)
class PartMass:
    """Mass properties of one part (or one body): SI, in its frame, inertia about the CoM."""

    name: str
    body: str
    mass: float  # [kg]
    com: np.ndarray  # (3,) [m]
    inertia: np.ndarray  # (3, 3) [kg·m²] about the CoM
    volume: float  # [m³]

    def as_dict(self) -> dict[str, Any]:
        return {"body": self.body, "mass_kg": self.mass, "volume_mm3": self.volume * 1e9,
                "com_mm": [float(x) * 1e3 for x in self.com],
                "inertia_kg_mm2": [[float(x) * 1e6 for x in row] for row in self.inertia]}


@dataclass(frozen=True, kw_only=True)
class MassProperties:
    """Mass properties of every part of a design, and of every rigid body (parts combined)."""

    design: str
    method: Method
    parts: dict[str, PartMass]

    @property
    def total_mass(self) -> float:
        """[kg] of every part, fixed ones included."""
        return float(sum(p.mass for p in self.parts.values()))

    def bodies(self) -> dict[str, PartMass]:
        """Parts combined per rigid body (parts of one body share its frame)."""
        out: dict[str, PartMass] = {}
        for body in dict.fromkeys(p.body for p in self.parts.values()):
            members = [p for p in self.parts.values() if p.body == body]
            out[body] = combine(body, body, members)
        return out

    def moving_mass(self, fixed: str = "base") -> float:
        """[kg] of every part not carried by the fixed body."""
        return float(sum(p.mass for p in self.parts.values() if p.body != fixed))

    def to_json(self) -> str:
        payload = {
            "design": self.design,
            "method": str(self.method),
            "units": {"mass": "kg", "length": "mm", "inertia": "kg·mm² about the CoM, in the part/body frame"},
            "total_mass_kg": self.total_mass,
            "parts": {n: p.as_dict() for n, p in self.parts.items()},
            "bodies": {n: p.as_dict() for n, p in self.bodies().items()},
        }
        return json.dumps(payload, indent=2)


def combine(name: str, body: str, members: list[PartMass]) -> PartMass:
    """Mass properties of several parts expressed in one frame."""
    m = sum(p.mass for p in members)
    com = sum(p.mass * p.com for p in members) / m
    inertia = np.zeros((3, 3))
    for p in members:
        d = p.com - com
        inertia += p.inertia + p.mass * ((d @ d) * np.eye(3) - np.outer(d, d))
    return PartMass(name=name, body=body, mass=float(m), com=com, inertia=inertia,
                    volume=float(sum(p.volume for p in members)))


def analytic(design: Any, *, specs: dict[str, _parts.PartSpec]) -> MassProperties:
    """Closed-form mass properties from the part tables (no solids built).

    ``specs`` is the device's part table (``design.<device>.cad.part_specs``); each device's
    ``cad.mass_properties(design)`` calls this with its own.
    """
    unique: dict[int, int] = {}  # parts that share one primitive table are integrated once
    for spec in specs.values():
        unique.setdefault(id(spec.primitives), len(unique))
    props = _parts.volume_properties_many(list({id(s.primitives): s.primitives for s in specs.values()}.values()))
    out: dict[str, PartMass] = {}
    for name, spec in specs.items():
        vp = props[unique[id(spec.primitives)]]
        rho = spec.density
        out[name] = PartMass(name=name, body=spec.body, mass=rho * vp.volume, com=vp.centroid,
                             inertia=rho * vp.inertia, volume=vp.volume)
    return MassProperties(design=design.name, method=Method.ANALYTIC, parts=out)


def from_cad(design: Any, *, solids: dict[str, Any], specs: dict[str, _parts.PartSpec]) -> MassProperties:
    """Mass properties from OpenCASCADE's volume integrals of the part solids (in part frames)."""
    out: dict[str, PartMass] = {}
    for name, spec in specs.items():
        s = solids[name]
        rho = spec.density
        vol = cad_units.volume_from_mm3(s.volume)
        com = cad_units.from_mm(np.array(tuple(s.center())))
        # OCCT: second moments about the centre of mass for unit density, mm⁵
        J = cad_units.inertia_from_mm5(np.array(s.matrix_of_inertia))
        out[name] = PartMass(name=name, body=spec.body, mass=rho * vol, com=com, inertia=rho * 0.5 * (J + J.T),
                             volume=vol)
    return MassProperties(design=design.name, method=Method.CAD, parts=out)


def of(design: Any, *, specs: dict[str, _parts.PartSpec], build_solids: Any, method: Method = Method.ANALYTIC,
       solids: dict[str, Any] | None = None) -> MassProperties:
    """:func:`analytic` or :func:`from_cad` (``solids``, else ``build_solids(design)``) for a part table."""
    if Method(method) == Method.ANALYTIC:
        return analytic(design, specs=specs)
    return from_cad(design, solids=solids if solids is not None else build_solids(design), specs=specs)
