"""Mass model of the surgical master: every moving part as a rigid body fixed to a link frame.

The link frames are those of :func:`hapticopt.design.master.kinematics.link_frames` (turret,
upper arm, driver link, coupler, forearm, handle). :func:`analytic_mass_properties` is the model
of evaluators and the optimiser (slender rods, point-like counterweights and handle);
:func:`bodies_from_mass_properties` takes the CAD engineer's part table instead. The dynamics
(M, C, G) built on these bodies are in :mod:`hapticopt.analysis.master.dynamics`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from hapticopt.design.master import kinematics as mk
from hapticopt.design.master.params import MasterDesign

FRAMES = mk.LinkFrames._fields  # ("turret", "upper_arm", "driver_link", "coupler", "forearm", "handle")

#: geometric assumptions of the analytic mass model (documented in docs/master.md)
ROD_RADIUS = 0.005  # [m] radius used for the links' axial inertia
COUNTERWEIGHT_DENSITY = 7850.0  # [kg/m³] steel: a sphere of this density for the inertia of point masses


@dataclass(frozen=True, kw_only=True)
class BodyMass:
    """Mass properties of one rigid part [SI], in the axes of the link frame it is fixed to."""

    name: str
    frame: str  # one of FRAMES
    mass: float  # [kg]
    com: tuple[float, float, float]  # CoM in the frame [m]
    inertia: tuple[tuple[float, float, float], ...]  # 3×3 about the CoM, frame axes [kg·m²]


def _rod(name: str, frame: str, mass: float, length: float, com: float) -> BodyMass:
    it = mass * (3 * ROD_RADIUS**2 + length**2) / 12.0
    ia = 0.5 * mass * ROD_RADIUS**2
    return BodyMass(name=name, frame=frame, mass=mass, com=(com, 0.0, 0.0),
                    inertia=((ia, 0.0, 0.0), (0.0, it, 0.0), (0.0, 0.0, it)))


def _ball(name: str, frame: str, mass: float, x: float) -> BodyMass:
    r = (3.0 * mass / (4.0 * np.pi * COUNTERWEIGHT_DENSITY)) ** (1.0 / 3.0)
    i = 0.4 * mass * r**2
    return BodyMass(name=name, frame=frame, mass=mass, com=(x, 0.0, 0.0),
                    inertia=((i, 0.0, 0.0), (0.0, i, 0.0), (0.0, 0.0, i)))


def analytic_mass_properties(design: MasterDesign) -> tuple[BodyMass, ...]:
    """Analytic mass model of a design: links as slender rods (radius 5 mm) with their CoM where the
    design puts it, counterweights and handle as steel spheres, the turret as its inertia about θ1.

    Counterweights: ``upper`` at −r2x on the upper arm's rear extension; ``forearm`` at +r4z along
    the driver link (which points away from the forearm), see :mod:`hapticopt.design.master.params`.
    """
    g, ln, cw = design.geometry, design.links, design.counterweights
    it = ln.turret_inertia
    return (
        BodyMass(name="turret", frame="turret", mass=0.0, com=(0.0, 0.0, 0.0),
                 inertia=((0.5 * it, 0.0, 0.0), (0.0, 0.5 * it, 0.0), (0.0, 0.0, it))),
        _rod("upper_arm", "upper_arm", ln.upper_arm_mass, g.upper_arm, ln.upper_arm_com),
        _ball("upper_counterweight", "upper_arm", cw.upper_mass, -cw.upper_distance),
        _rod("driver_link", "driver_link", ln.driver_link_mass, g.driver_link, ln.driver_link_com),
        _ball("forearm_counterweight", "driver_link", cw.forearm_mass, cw.forearm_distance),
        _rod("coupler", "coupler", ln.coupler_mass, g.upper_arm, ln.coupler_com),
        _rod("forearm", "forearm", ln.forearm_mass, g.forearm, ln.forearm_com),
        _ball("handle", "handle", ln.handle_mass, 0.0),
    )


def bodies_from_mass_properties(props) -> tuple[BodyMass, ...]:
    """Bodies from :class:`hapticopt.design.mass_properties.MassProperties` (the CAD engineer's analytic or
    CAD model; part frames = link frames); parts on the fixed base are dropped."""
    return tuple(BodyMass(name=pm.name, frame=pm.body, mass=float(pm.mass), com=tuple(float(x) for x in pm.com),
                          inertia=tuple(tuple(float(x) for x in row) for row in pm.inertia))
                 for pm in props.parts.values() if pm.body in FRAMES)
