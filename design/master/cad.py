"""Parametric CAD of the PHANToM-type surgical master (seed 003).

Frames come from :func:`hapticopt.design.master.kinematics.link_frames` (x along the link, y along the
joint axis a, origin on the proximal joint), so every bore lies on its kinematic axis.

Parts (name → body): ``base`` (plate below z = 0) → base; ``turret`` (drum on the θ1 axis and
a column carrying the shoulder axis) → turret; ``upper_arm`` (S→E, rear extension to the m2
counterweight) and ``counterweight_upper`` → upper_arm; ``driver_link`` (θ3 driver, S along −f,
extended to the m4 counterweight) and ``counterweight_forearm`` → driver_link; ``coupler``
(driver tip → forearm rear, parallel to the upper arm) → coupler; ``forearm`` (rear pivot −d to
the handle) and ``handle`` (ball at the handle centre p) → forearm.

Layers along the joint axis a (k·(T + g), T = link thickness, g = clearance): forearm 0 (the
kinematic plane, so the handle ball is centred on p), upper arm 1, coupler 1 (parallel to the
upper arm at distance d·sin φ, never touching it), driver 2, turret column 3. Counterweights are
steel discs on the side of their link, sized from their mass (seed 003: m2 at r2x, m4 at r4z).
The coupler and forearm use the light cross-section (``light_link_*``).

Mass that exists: the analytic mass model (:func:`hapticopt.design.master.mass.analytic_mass_properties`,
the reference of every evaluator and of the MJCF) gives each moving body a mass and a CoM (the
drivers' capstan drum sectors included). Each moving body gets one ``ballast_<body>`` part, a
disc of the counterweight material (steel, 7850 kg/m³) and length, sized and placed so that the
body's CAD mass and in-plane CoM (x along the link, z normal to it) equal the model's; the disc
sits on the negative-a side of its link, where no other part of the arm passes (upper arm: below
its counterweight; driver link: an eccentric disc on the shoulder shaft beyond the upper arm's
ballast; coupler and forearm: beside the bar). The CoM along the joint axis a is left where the
layers put it: an offset along a horizontal axis moves no gravity torque about it (θ1 is
vertical). A model body lighter than its link's structure raises :class:`InvalidDesign`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from hapticopt.design import mass_properties as _mp
from hapticopt.design import parts as _parts
from hapticopt.design.errors import InvalidDesign, InvalidInput
from hapticopt.design.master.params import MasterDesign
from hapticopt.design.parts import (
    JointAxis,
    PartSpec,
    Role,
    bar_with_bosses,
    cylinder,
    frame,
    sphere,
    transform,
)
from hapticopt.design.master.kinematics import forward_kinematics, params_of
from hapticopt.design.master.kinematics import inverse_kinematics
from hapticopt.design.master.kinematics import link_frames
from hapticopt.design.master.mass import analytic_mass_properties

MIN_FEATURE = 0.5e-3
#: [kg] a body whose model mass exceeds its structure by less than this gets no ballast (CoM error < 1 µm·kg)
BALLAST_MIN_MASS = 1e-6
#: the moving bodies that carry a ballast disc, and the model fields whose sum they must weigh
BALLAST_FIELDS = {"upper_arm": "links.upper_arm_mass_kg + counterweights.upper_mass_kg",
                  "driver_link": "links.driver_link_mass_kg + counterweights.forearm_mass_kg",
                  "coupler": "links.coupler_mass_kg",
                  "forearm": "links.forearm_mass_kg + links.handle_mass_kg"}
EX, EY, EZ = np.eye(3)


@dataclass(frozen=True, kw_only=True)
class MasterPose:
    p: np.ndarray  # handle centre (3,) [m]
    q: np.ndarray  # joint angles (θ1, θ2, θ3) [rad]


def _layer(design: MasterDesign, k: int) -> float:
    s = design.structure
    return k * (s.link_thickness + s.clearance)


def _cw_radius(design: MasterDesign, mass: float) -> float:
    s = design.structure
    return math.sqrt(mass / (s.counterweight_density * math.pi * s.counterweight_length))


def _check(design: MasterDesign) -> None:
    s, g = design.structure, design.geometry
    for key, val in (("link_thickness_mm", s.link_thickness), ("link_width_mm", s.link_width),
                     ("clearance_mm", s.clearance), ("base_thickness_mm", s.base_thickness)):
        if val < MIN_FEATURE:
            raise InvalidDesign(f"structure.{key} = {val * 1e3:g} is too thin for the CAD: allowed ≥ "
                                f"{MIN_FEATURE * 1e3:g} (mm)")
    R, r = s.boss_diameter / 2, s.bore_diameter / 2
    if R - r < MIN_FEATURE:
        raise InvalidDesign(f"structure.bore_diameter_mm = {2 * r * 1e3:g} leaves a boss wall of {(R - r) * 1e3:g} mm: "
                            f"allowed ≤ structure.boss_diameter_mm − {2 * MIN_FEATURE * 1e3:g} (mm)")
    for key, L in (("upper_arm_mm", g.upper_arm), ("forearm_mm", g.forearm), ("driver_link_mm", g.driver_link)):
        if L < 2 * R + MIN_FEATURE:
            raise InvalidDesign(f"geometry.{key} = {L * 1e3:g} is too short for two bosses of "
                                f"structure.boss_diameter_mm = {2 * R * 1e3:g}: allowed ≥ {(2 * R + MIN_FEATURE) * 1e3:g} (mm)")
    drum = 2 * s.turret_radius + s.clearance
    if g.shoulder_height < drum + R + MIN_FEATURE:
        raise InvalidDesign(f"geometry.shoulder_height_mm = {g.shoulder_height * 1e3:g} leaves no room for the "
                            f"turret drum of structure.turret_radius_mm = {s.turret_radius * 1e3:g}: allowed ≥ "
                            f"{(drum + R + MIN_FEATURE) * 1e3:g} (mm)")
    for key, val in (("light_link_thickness_mm", s.light_link_thickness), ("light_link_width_mm", s.light_link_width)):
        if val < MIN_FEATURE:
            raise InvalidDesign(f"structure.{key} = {val * 1e3:g} is too thin for the CAD: allowed ≥ "
                                f"{MIN_FEATURE * 1e3:g} (mm)")
        if val > s.boss_diameter - MIN_FEATURE:
            raise InvalidDesign(f"structure.{key} = {val * 1e3:g} is wider than the joint boss: allowed ≤ "
                                f"structure.boss_diameter_mm − {MIN_FEATURE * 1e3:g} (mm)")
    if s.handle_diameter / 2 <= min(s.light_link_width, s.light_link_thickness) / 2 + MIN_FEATURE:
        raise InvalidDesign(f"structure.handle_diameter_mm = {s.handle_diameter * 1e3:g} must exceed the forearm "
                            f"cross-section min(light_link_width, light_link_thickness) + {2 * MIN_FEATURE * 1e3:g} (mm)")


def part_specs(design: MasterDesign) -> dict[str, PartSpec]:
    """Every part in its body's frame (see module docstring), SI."""
    _check(design)
    s, g, cw = design.structure, design.geometry, design.counterweights
    T, W, R, r = s.link_thickness, s.link_width, s.boss_diameter / 2, s.bore_diameter / 2
    rho, rho_cw, ell = s.density, s.counterweight_density, s.counterweight_length
    kw = dict(width=W, thickness=T, boss_radius=R, bore_radius=r)
    Wl, Tl = s.light_link_width, s.light_link_thickness
    light = dict(kw, width=Wl, thickness=Tl)
    # link frames: x along the link, y = a (joint axis), z = x × y; layers are along y
    F = frame(EX, EY)  # rotation taking bar-local (x, y, z=layer axis) to link (x, −z, y)
    out: dict[str, PartSpec] = {}

    def spec(name: str, body: str, prims, density=rho) -> None:
        out[name] = PartSpec(name=name, body=body, density=density, primitives=tuple(prims))

    # base plate (world frame), top face at z = 0
    spec("base", "base", [cylinder((0, 0, -s.base_thickness / 2), EZ, s.base_radius, s.base_thickness)])
    # turret (turret frame: x = e_ρ, y = −a, z up): drum and column to the shoulder
    h = g.shoulder_height
    drum_h = 2 * s.turret_radius
    turret = [cylinder((0, 0, s.clearance + drum_h / 2), EZ, s.turret_radius, drum_h)]
    col = frame(-EZ, -EY)  # bar x down from S, layer axis along a = −y_turret
    top = s.clearance + drum_h
    turret += bar_with_bosses(col, (0, 0, h), 0.0, h - top, z=_layer(design, 3), bosses=(0.0,), **kw)
    spec("turret", "turret", turret)
    # upper arm: S → E, rear extension to the counterweight
    x0 = -cw.upper_distance if cw.upper_distance >= R + MIN_FEATURE else 0.0
    spec("upper_arm", "upper_arm", bar_with_bosses(F, np.zeros(3), x0, g.upper_arm, z=_layer(design, 1),
                                                  bosses=(0.0, g.upper_arm), **kw))
    if cw.upper_mass > 0:
        rc = _cw_radius(design, cw.upper_mass)
        spec("counterweight_upper", "upper_arm",
             [cylinder((-cw.upper_distance, _layer(design, 1) - T / 2 - ell / 2, 0), EY, rc, ell)], rho_cw)
    # driver link: S along −f to the coupler pivot (d) and on to its counterweight
    d = g.driver_link
    x1 = cw.forearm_distance if cw.forearm_distance >= d + R + MIN_FEATURE else d
    spec("driver_link", "driver_link", bar_with_bosses(F, np.zeros(3), 0.0, x1, z=_layer(design, 2),
                                                      bosses=(0.0, d), **kw))
    if cw.forearm_mass > 0:
        rc = _cw_radius(design, cw.forearm_mass)
        spec("counterweight_forearm", "driver_link",
             [cylinder((cw.forearm_distance, _layer(design, 2) + T / 2 + ell / 2, 0), EY, rc, ell)], rho_cw)
    # coupler: driver tip → forearm rear, parallel to the upper arm
    spec("coupler", "coupler", bar_with_bosses(F, np.zeros(3), 0.0, g.upper_arm, z=_layer(design, 1),
                                              bosses=(0.0, g.upper_arm), **light))
    # forearm: rear pivot (−d) → elbow (0) → handle; in the kinematic plane
    rh = s.handle_diameter / 2
    gap = 3e-3
    L4 = g.forearm
    spec("forearm", "forearm", bar_with_bosses(F, np.zeros(3), -d, L4 - rh - gap, z=0.0, bosses=(-d, 0.0), **light))
    # handle ball at p with a stub to the forearm end (forearm frame)
    rs = min(Wl, Tl) / 2
    stub = rh + gap
    inside = math.sqrt(rh * rh - rs * rs)
    spec("handle", "forearm", [sphere((L4, 0, 0), rh), cylinder((L4 - stub / 2, 0, 0), EX, rs, stub),
                               cylinder((L4 - inside / 2, 0, 0), EX, rs, inside, role=Role.OVERLAP)])
    # ballast discs (module docstring): the top face (largest a) of each, on the negative-a side
    below_upper = _layer(design, 1) - T / 2 - ell  # bottom face of the upper counterweight's slot
    tops = {"upper_arm": below_upper, "driver_link": below_upper - ell - s.clearance,
            "coupler": _layer(design, 1) - Tl / 2, "forearm": -Tl / 2}
    targets = model_bodies(design)
    structure = [p for p in out.values() if p.body in tops]
    props = _parts.volume_properties_many([p.primitives for p in structure])  # one batched call
    for body, y_top in tops.items():
        own = [(p.density * vp.volume, vp.centroid) for p, vp in zip(structure, props) if p.body == body]
        ballast = _ballast(design, body, own, targets[body], y_top)
        if ballast is not None:
            out[ballast.name] = ballast
    return out


def model_bodies(design: MasterDesign) -> dict[str, tuple[float, np.ndarray]]:
    """Mass [kg] and CoM (3,) [m] of each CAD body in the analytic mass model, in the body's frame
    (the model's ``handle`` frame is the forearm's moved by L4 along x, so the handle joins the forearm)."""
    out: dict[str, tuple[float, np.ndarray]] = {}
    for b in analytic_mass_properties(design):
        body = "forearm" if b.frame == "handle" else b.frame
        c = np.asarray(b.com, dtype=float) + (np.array([design.geometry.forearm, 0.0, 0.0]) if b.frame == "handle" else 0.0)
        m, mc = out.get(body, (0.0, np.zeros(3)))
        out[body] = (m + b.mass, mc + b.mass * c)
    return {k: (m, mc / m if m > 0 else np.zeros(3)) for k, (m, mc) in out.items()}


def _ballast(design: MasterDesign, body: str, parts: list[tuple[float, np.ndarray]], target: tuple[float, np.ndarray],
             y_top: float) -> PartSpec | None:
    """The steel disc that brings ``parts`` (mass [kg], CoM (3,) [m] of each part of one body) to the
    model's mass and in-plane CoM ``target``; None if the structure already weighs the model's mass
    (within :data:`BALLAST_MIN_MASS`)."""
    s = design.structure
    m_e = sum(m for m, _ in parts)
    mc_e = sum(m * c for m, c in parts)
    M, c = target
    m_s = M - m_e
    if m_s < -BALLAST_MIN_MASS:
        raise InvalidDesign(f"{BALLAST_FIELDS[body]} = {M:.6g} is below the {body} structure's own "
                            f"{m_e:.6g} (structure.* sections and densities): allowed ≥ {m_e:.6g} (kg)")
    if m_s <= BALLAST_MIN_MASS:
        return None
    xs, _, zs = (M * c - mc_e) / m_s
    ell = s.counterweight_length
    prim = cylinder((xs, y_top - ell / 2, zs), EY, _cw_radius(design, m_s), ell)
    return PartSpec(name=f"ballast_{body}", body=body, density=s.counterweight_density, primitives=(prim,))


def neighbours() -> frozenset[frozenset[str]]:
    """Parts joined by a joint (never reported as colliding with each other)."""
    pairs = [("base", "turret"), ("turret", "upper_arm"), ("turret", "driver_link"), ("upper_arm", "driver_link"),
             ("upper_arm", "forearm"), ("driver_link", "coupler"), ("coupler", "forearm"),
             ("counterweight_upper", "upper_arm"), ("counterweight_forearm", "driver_link"), ("handle", "forearm"),
             ("ballast_upper_arm", "counterweight_upper"), ("ballast_upper_arm", "upper_arm"),
             ("ballast_driver_link", "driver_link"), ("ballast_coupler", "coupler"), ("ballast_forearm", "forearm"),
             ("ballast_forearm", "handle")]
    return frozenset(frozenset(p) for p in pairs)


# ---------------------------------------------------------------------------- pose
def home_q(design: MasterDesign) -> np.ndarray:
    """Home joint angles: θ1 = 0, upper arm horizontal, forearm vertical (φ = 90°) [rad]."""
    return np.zeros(3)


def home_point(design: MasterDesign) -> np.ndarray:
    """Handle centre at :func:`home_q` [m]."""

    return np.asarray(forward_kinematics(params_of(design), home_q(design)))


def pose_from_q(design: MasterDesign, q) -> MasterPose:

    q = np.asarray(q, dtype=float)
    return MasterPose(p=np.asarray(forward_kinematics(params_of(design), q)), q=q)


def solve_pose(design: MasterDesign, p) -> MasterPose:
    """Joint angles reaching the handle position ``p`` [m]; raises :class:`InvalidInput` outside
    the reach or the joint ranges."""

    p = np.asarray(p, dtype=float)
    ik = inverse_kinematics(params_of(design), p)
    where = f"pose = ({', '.join(f'{x * 1e3:g}' for x in p)}) mm"
    if not bool(ik.reachable):
        raise InvalidInput(f"{where} is not reachable by {design.name} (arm reach |L5 − L4| … L5 + L4)")
    if not bool(ik.in_range):
        raise InvalidInput(f"{where} is outside the joint ranges of {design.name} (joints.* limits)")
    return MasterPose(p=p, q=np.asarray(ik.q))


def part_frames(design: MasterDesign, pose: MasterPose) -> dict[str, np.ndarray]:
    """4×4 world transform of every part's frame at ``pose`` [m]."""

    lf = link_frames(params_of(design), pose.q)

    def T(fr) -> np.ndarray:
        return transform(np.asarray(fr.rotation), np.asarray(fr.origin))

    out = {"base": np.eye(4), "turret": T(lf.turret), "upper_arm": T(lf.upper_arm),
           "driver_link": T(lf.driver_link), "coupler": T(lf.coupler), "forearm": T(lf.forearm)}
    out["counterweight_upper"] = out["upper_arm"]
    out["counterweight_forearm"] = out["driver_link"]
    out["handle"] = out["forearm"]
    for body in BALLAST_FIELDS:
        out[f"ballast_{body}"] = out[body]
    return out


def joint_axes(design: MasterDesign, pose: MasterPose) -> list[JointAxis]:
    """Joint axes from the kinematics (points and directions, m)."""

    lf = link_frames(params_of(design), pose.q)
    a = np.asarray(lf.upper_arm.rotation)[:, 1]
    S = np.asarray(lf.upper_arm.origin)
    E = np.asarray(lf.forearm.origin)
    C = np.asarray(lf.coupler.origin)
    f = np.asarray(lf.forearm.rotation)[:, 0]
    t1, t2, t3 = (float(x) for x in pose.q)
    phi = math.pi / 2 - t2 + t3
    return [
        JointAxis(name="theta1", parent="base", child="turret", point=np.zeros(3), direction=EZ.copy(), reference=t1),
        JointAxis(name="theta2", parent="turret", child="upper_arm", point=S, direction=a, reference=t2),
        JointAxis(name="theta3", parent="turret", child="driver_link", point=S, direction=a, reference=t3),
        JointAxis(name="elbow", parent="upper_arm", child="forearm", point=E, direction=a, reference=phi),
        JointAxis(name="driver_coupler", parent="driver_link", child="coupler", point=C, direction=a,
                  reference=t2 - t3),
        JointAxis(name="coupler_forearm", parent="coupler", child="forearm", point=E - design.geometry.driver_link * f,
                  direction=a, reference=phi),
    ]


# ---------------------------------------------------------------------------- build123d
def build_parts(design: MasterDesign) -> dict[str, object]:
    """Every part as a build123d solid in its body's frame (mm)."""
    return _parts.build_all(part_specs(design))


def posed(solids: dict[str, object], frames: dict[str, np.ndarray]) -> dict[str, object]:
    return _parts.posed(solids, frames)


def mass_properties(design, *, method: _mp.Method = _mp.Method.ANALYTIC, solids=None) -> _mp.MassProperties:
    """Mass properties of every part: closed forms (default) or OpenCASCADE's integrals of the solids."""
    return _mp.of(design, specs=part_specs(design), build_solids=build_parts, method=method, solids=solids)
