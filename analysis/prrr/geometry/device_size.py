"""Size and mass of the 3-PRRR as built by the CAD (seed 002 Table 1: φ260 × 231 mm, 4.4 kg).

Masses come from the analytic mass model of the part tables
(:func:`hapticopt.design.mass_properties.analytic`, tested against OpenCASCADE's integrals), split
into the SEA modules (motor with belt, ball screw, spring housing: ``sea_module`` of the design),
the moving links (links 1 and 2, platform) and the frame (base plate, rails, carriages). The
height is the base plate's bottom to the rail tops (:func:`hapticopt.design.prrr.cad.device_height`);
the footprint is the workspace evaluator's ``footprint_diameter_mm``.
"""

from __future__ import annotations

import dataclasses
import time
from dataclasses import dataclass
from typing import Any

import numpy as np

from hapticopt.analysis.fidelity import Fidelity
from hapticopt.analysis.prrr.geometry import assembly
from hapticopt.analysis.status import Status
from hapticopt.design.errors import HapticoptError
from hapticopt.design import mass_properties as _mp
from hapticopt.design import parts as _parts
from hapticopt.design.prrr import cad as cad_prrr
from hapticopt.design.prrr.params import PrrrDesign

#: part-name prefixes of each mass group
SEA_PARTS = ("motor_", "screw_", "housing_")
LINK_PARTS = ("link1_", "link2_", "platform")


@dataclass(frozen=True, kw_only=True)
class DeviceSize:
    mass: float  # [kg] every part
    sea_mass: float  # [kg] the three SEA modules
    link_mass: float  # [kg] links and platform
    frame_mass: float  # [kg] base plate, rails, carriages
    height: float  # [m]
    wall_s: float
    status: Status = Status.OK
    message: str = ""

    def metrics(self) -> dict[str, float]:
        return {"device_mass_kg": self.mass, "device_mass_sea_modules_kg": self.sea_mass,
                "device_mass_links_kg": self.link_mass, "device_mass_frame_kg": self.frame_mass,
                "device_height_mm": self.height * 1e3}


def evaluate(design: PrrrDesign, *, fidelity: Fidelity = Fidelity.STANDARD, shared: Any = None) -> DeviceSize:
    """Mass split and height (closed forms, the same at every fidelity).

    Status ``ok`` when computed (the seed gives no limit to hold them to); ``not-assemblable``
    (NaN) when the chain does not close or the CAD cannot lay the parts out
    (:mod:`hapticopt.analysis.prrr.geometry.assembly`); ``failed`` when the mass model refuses the parts.
    ``shared``: the registry call's :class:`hapticopt.analysis.prrr.shared.DesignSteps` of ``design``
    (the part tables).
    """
    Fidelity(fidelity)
    t0 = time.perf_counter()
    blocked = assembly.check(design, with_parts=True)
    if blocked:
        return dataclasses.replace(failed(None, t0), status=Status.NOT_ASSEMBLABLE, message=blocked)
    try:
        specs = cad_prrr.part_specs(design) if shared is None else shared.part_specs(design)
    except HapticoptError as exc:
        return failed(exc, t0)
    return from_specs(design, specs, t0, lay=None if shared is None else shared.layout(design))


def failed(exc: Exception, t0: float) -> DeviceSize:
    """The result where the CAD cannot lay the parts out (status failed, NaN metrics)."""
    nan = float("nan")
    return DeviceSize(mass=nan, sea_mass=nan, link_mass=nan, frame_mass=nan, height=nan,
                      wall_s=time.perf_counter() - t0, status=Status.FAILED, message=f"size not computed: {exc}")


def from_specs(design: PrrrDesign, specs: dict, t0: float, *, lay: Any = None) -> DeviceSize:
    """Mass split and height from the part tables ``specs`` (:func:`hapticopt.design.prrr.cad.part_specs`
    of ``design``, shared with the batched draft evaluator's other steps; ``lay``: their
    :func:`hapticopt.design.prrr.cad.layout` when the caller has it). The masses are the analytic mass
    model's (:func:`hapticopt.design.mass_properties.analytic`)."""
    try:
        masses = {name: p.mass for name, p in _mp.analytic(design, specs=specs).parts.items()}
        height = cad_prrr.device_height(design, lay=lay)
    except HapticoptError as exc:
        return failed(exc, t0)
    sea = sum(m for n, m in masses.items() if n.startswith(SEA_PARTS))
    links = sum(m for n, m in masses.items() if n.startswith(LINK_PARTS))
    total = sum(masses.values())
    return DeviceSize(mass=total, sea_mass=sea, link_mass=links, frame_mass=total - sea - links, height=height,
                      wall_s=time.perf_counter() - t0)


def from_tables(tables, t0: float) -> list[DeviceSize]:
    """:func:`from_specs` of every design of one part layout at once, from the stacked part tables
    ``tables`` (:class:`hapticopt.design.prrr.layout.PartTables`, which carry the device height):
    each part's mass is its density times its signed volume (SOLID − OVERLAP − HOLE, the closed forms
    of :func:`hapticopt.design.parts.volume_properties`: :func:`hapticopt.design.parts.volumes`), summed in part order as :func:`from_specs`
    sums them (tested equal to it)."""
    m, P = tables.dims.shape[:2]
    kind = np.broadcast_to(np.asarray(tables.kind), (m, P)).reshape(-1)
    v = _parts.volumes(kind, tables.dims.reshape(-1, 3)).reshape(m, P)
    sign = np.array([1.0 if role == _parts.Role.SOLID else -1.0 for role in tables.role])
    prim_part = np.asarray(tables.prim_part)
    starts = np.flatnonzero(np.r_[True, prim_part[1:] != prim_part[:-1]])
    volume = np.add.reduceat(v * sign, starts, axis=1)  # (m, parts): prim_part is in part order
    mass = tables.density[:, prim_part[starts]] * volume
    sea = links = total = np.zeros(m)
    for j in range(mass.shape[1]):
        name = tables.part_names[prim_part[starts[j]]]
        if name.startswith(SEA_PARTS):
            sea = sea + mass[:, j]
        if name.startswith(LINK_PARTS):
            links = links + mass[:, j]
        total = total + mass[:, j]
    frame = (total - sea - links).tolist()  # each design's float(total[k] - sea[k] - links[k])
    total, sea, links, height = (np.asarray(x, dtype=float).tolist() for x in (total, sea, links, tables.height))
    wall = time.perf_counter() - t0
    return [DeviceSize(mass=total[k], sea_mass=sea[k], link_mass=links[k], frame_mass=frame[k], height=height[k],
                       wall_s=wall) for k in range(m)]
