"""MJCF (MuJoCo XML) of the 3-PRRR: the one generator, for the multibody plant and for export.

Tree (every body frame parallel to the world frame at the home pose p = 0, the CAD's elbow
branch, so every hinge axis is the kinematic w_i): per leg i, ``motor_i`` (the SEA's motor side,
equivalent mass M_m of seed 002 Table 4, slide along z) and ``carriage_i`` (the output slider,
slide along z) → ``link1_i`` (hinge R1 at A_i) → ``link2_i`` (hinge R2 at B_i); the platform body
``ee``; the legs close on it at their R3 points by ``<connect>`` (one per leg with a
translational platform, two per leg on the R3 axis with a free one). The SEA spring is a fixed
tendon D_e − D of stiffness k between the two slides; the actuators are force motors on the
motor sides (on the output slider without a motor side). ``qpos0`` is the home pose;
:func:`pose_qpos` gives the joint vector of any reachable pose.

Options (:class:`MjcfOptions`) select what the model contains:

* masses: ``LUMPED`` (all of M in the end-effector, seed 002 Table 4), ``REAL`` (links from the
  mass model, the platform the rest of M), ``CAD`` (every body from the CAD mass properties:
  base, carriages with their SEA housings, links, platform: the exported model);
* ``geoms``: the CAD part primitives as geoms (boxes, cylinders, spheres of the part tables), in
  every body; ``contacts``: they collide, neighbours excluded (parts joined by a joint or
  sliding on each other, :func:`hapticopt.design.prrr.cad.neighbours`);
* ``slider_limits``: the stroke ±L/2 on the output sliders (and the motor sides);
  ``joint_limits``: R1/R2 hinge ranges and the R3 range as a tendon θ1 + θ2 (:class:`RJointLimits`, from
  the joint-limits evaluator: ``analysis.prrr.loop.mujoco_model.export_joint_limits``);
  ``force_limits``: actuator force ±F_max; ``motor_efficiency``: the motor actuators' gear is η (a motor-force
  command F drives the screw with ηF, seed 002 eq 6; the plant applies η itself);
* ``hand``: an operator hand body (mass, spring, damper per axis) welded to the handle;
* friction, damping, gravity, the solver settings.

The multibody plant (:mod:`hapticopt.analysis.prrr.loop.mujoco_model`) and ``hapticopt export``
(:func:`export_options`) both call :func:`prrr_mjcf`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from enum import StrEnum
from typing import Any
from xml.sax.saxutils import quoteattr

import numpy as np

from hapticopt.design.errors import InvalidDesign
from hapticopt.design.mass_properties import MassProperties
from hapticopt.design.parts import Kind, Role
from hapticopt.design.prrr import cad as cad_prrr
from hapticopt.design.prrr.kinematics import inverse_kinematics, leg_chain, leg_frames, params_of
from hapticopt.design.prrr.params import PrrrDesign
from hapticopt.design.units import GRAVITY

#: mass of a link [kg] when link masses are lumped into the end-effector (0.15 % of M each): light
#: enough to leave M as it is, heavy enough that the links' fast constraint modes dissipate little
#: energy (docs/multibody.md)
LUMPED_LINK_MASS = 1e-3
#: output slider (carriage) mass [kg] of the lumped and real models; the paper's two-mass model
#: has none, MuJoCo needs > 0
CARRIAGE_MASS = 1e-3
#: elbow branch of every leg: the CAD's (hapticopt.design.prrr.cad.DEFAULT_BRANCH)
BRANCH = cad_prrr.DEFAULT_BRANCH
#: length along w of the second R3 closure point of the FREE platform [m]
AXIS_ARM = 0.04


class LinkMasses(StrEnum):
    LUMPED = "lumped"
    REAL = "real"
    CAD = "cad"


class Platform(StrEnum):
    TRANSLATIONAL = "translational"
    FREE = "free"


@dataclass(frozen=True, kw_only=True)
class HandBody:
    """Operator hand coupled to the handle: mass [kg], spring [N/m] and damper [N·s/m] per axis."""

    mass: float
    stiffness: float
    damping: float


@dataclass(frozen=True, kw_only=True)
class RJointLimits:
    """R-joint ranges about the home pose [rad] (angle − home angle, the CAD's elbow branch); None: unlimited.
    R3 of a translating platform turns by −(Δθ1 + Δθ2): its range is written on the fixed tendon
    θ1 + θ2 (``r3_<leg>``), i.e. ``r3`` bounds −Δθ3."""

    r1: tuple[float, float] | None = None
    r2: tuple[float, float] | None = None
    r3: tuple[float, float] | None = None


@dataclass(frozen=True, kw_only=True)
class Solver:
    """Solver settings written into ``<option>`` and the equality defaults."""

    timestep: float = 1e-4  # [s]
    integrator: str = "RK4"
    solref: tuple[float, float] = (2e-4, 1.0)
    solimp: tuple[float, float, float, float, float] = (0.9999, 0.9999, 0.001, 0.5, 2.0)
    iterations: int = 50
    tolerance: float = 1e-12


@dataclass(frozen=True, kw_only=True)
class MjcfOptions:
    """What the generated model contains (SI)."""

    link_masses: LinkMasses = LinkMasses.LUMPED
    platform: Platform = Platform.TRANSLATIONAL
    sea_compliance: bool = True  # series spring between motor and output slider
    motor_dynamics: bool = True  # motor-side mass M_m (else the force acts on the slider)
    viscous_friction: bool = False  # ξ on the motor joint (on the slider when no motor side)
    coulomb_friction: bool = False  # frictionloss on the output slider
    r_joint_friction: bool = False  # frictionloss structure.joint_friction on R1, R2 and an R3 tendon θ1 + θ2
    gravity: bool = False
    gravity_compensated_sliders: bool = True  # gravcomp on the motor and carriage bodies (the plant's convention)
    joint_damping: float = 0.0  # R-joint viscous damping [N·m·s/rad]
    hand: HandBody | None = None
    spring_override: float | None = None  # SEA spring [N/m] instead of the design's
    solver: Solver = field(default_factory=Solver)
    geoms: bool = False  # CAD part primitives as geoms
    contacts: bool = False  # the geoms collide (neighbours excluded)
    slider_limits: bool = False  # stroke limits on the sliders
    joint_limits: RJointLimits | None = None  # R-joint ranges about home [rad]
    force_limits: bool = False  # actuator forces within ±F_max (the motor command within ±F_max/η with motor_efficiency)
    motor_efficiency: bool = False  # the motor actuators' gear is η (seed 002 eq 6: η F drives the screw)


def export_options(joint_limits: RJointLimits | None = None) -> MjcfOptions:
    """The exported, drivable model with the dynamics the plants model: CAD masses and geoms, contacts,
    stroke and force limits, gravity acting on every body, the SEA spring, the screw's viscous friction ξ on
    the motor joints and η as the motor actuators' gear (seed 002 eq 6), the R joints' Coulomb friction
    (``structure.joint_friction_Nm``, where the seed-002 scenes put it; none when it is 0), the R-joint
    ranges ``joint_limits`` (the joint-limits evaluator's), solver settings of the plant's standard level."""
    return MjcfOptions(link_masses=LinkMasses.CAD, gravity=True, gravity_compensated_sliders=False,
                       geoms=True, contacts=True, slider_limits=True, force_limits=True,
                       viscous_friction=True, motor_efficiency=True, r_joint_friction=True,
                       joint_limits=joint_limits,
                       solver=Solver(timestep=1e-4, integrator="implicitfast", solref=(2e-4, 1.0)))


def _v(x: Any) -> str:
    return " ".join(f"{float(c):.12g}" for c in np.ravel(x))


def quat_of(R: np.ndarray) -> np.ndarray:
    """Unit quaternion (w, x, y, z) of a rotation matrix."""
    tr = np.trace(R)
    if tr > 0:
        s = math.sqrt(tr + 1.0) * 2
        q = [0.25 * s, (R[2, 1] - R[1, 2]) / s, (R[0, 2] - R[2, 0]) / s, (R[1, 0] - R[0, 1]) / s]
    else:
        i = int(np.argmax(np.diag(R)))
        j, k = (i + 1) % 3, (i + 2) % 3
        s = math.sqrt(1.0 + R[i, i] - R[j, j] - R[k, k]) * 2
        q = [0.0] * 4
        q[0] = (R[k, j] - R[j, k]) / s
        q[1 + i] = 0.25 * s
        q[1 + j] = (R[j, i] + R[i, j]) / s
        q[1 + k] = (R[k, i] + R[i, k]) / s
    q = np.asarray(q)
    return q / np.linalg.norm(q)


def home_pose(design: PrrrDesign) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(sliders (3,), A, B, Q (3 legs, 3), w (3 legs, 3)) at p = 0, the CAD's elbow branch [m]."""
    params = params_of(design)
    ik = inverse_kinematics(params, np.zeros(3))
    if not bool(ik.reachable):
        raise InvalidDesign(f"design {design.name!r}: the home pose p = 0 is not reachable")
    theta = ik.theta[BRANCH]
    pts = leg_chain(params, ik.sliders, theta)
    frames = leg_frames(params.beta)
    return (np.asarray(ik.sliders), np.asarray(pts.a), np.asarray(pts.b), np.asarray(pts.q),
            np.asarray(frames.w))


def _world_inertials(design: PrrrDesign, masses: MassProperties) -> dict[str, tuple[float, np.ndarray, np.ndarray]]:
    """Body name → (mass [kg], CoM (3,) world at home [m], inertia (3, 3) world axes [kg·m²])."""
    frames = cad_prrr.part_frames(design, cad_prrr.solve_pose(design, (0.0, 0.0, 0.0), branch=BRANCH))
    out = {}
    for name, pm in masses.bodies().items():
        T = frames[name]
        R = T[:3, :3]
        out[name] = (pm.mass, R @ pm.com + T[:3, 3], R @ pm.inertia @ R.T)
    return out


def _inertial(mass: float, com: np.ndarray, inertia: np.ndarray, origin: np.ndarray) -> str:
    full = [inertia[0, 0], inertia[1, 1], inertia[2, 2], inertia[0, 1], inertia[0, 2], inertia[1, 2]]
    return f'<inertial pos="{_v(com - origin)}" mass="{mass:.12g}" fullinertia="{_v(full)}"/>'


def _point_inertial(mass: float, pos: np.ndarray, diag: float = 1e-9) -> str:
    return f'<inertial pos="{_v(pos)}" mass="{mass:.12g}" diaginertia="{diag:.9g} {diag:.9g} {diag:.9g}"/>'


_RGBA = {"base": "0.6 0.6 0.65 1", "carriage": "0.2 0.4 0.8 1", "link1": "0.8 0.5 0.2 1",
         "link2": "0.8 0.7 0.2 1", "ee": "0.3 0.8 0.3 1"}


def _geoms(design: PrrrDesign, specs: dict, frames: dict, body: str, origin: np.ndarray, contacts: bool) -> str:
    """Geoms of every CAD part carried by ``body`` (its frame world-aligned at ``origin``)."""
    cad_body = "platform" if body == "ee" else body
    col = 'contype="1" conaffinity="1"' if contacts else 'contype="0" conaffinity="0"'
    rgba = _RGBA[body.split("_")[0]]
    out = []
    for name, spec in specs.items():
        if spec.body != cad_body:
            continue
        T = frames[name]
        for k, p in enumerate(spec.primitives):
            if p.role != Role.SOLID:
                continue
            a, b, c = p.dims
            if p.kind == Kind.BOX:
                typ, size = "box", _v([a / 2, b / 2, c / 2])
            elif p.kind == Kind.CYLINDER:
                typ, size = "cylinder", _v([a, b / 2])
            else:
                typ, size = "sphere", _v([a])
            R = T[:3, :3] @ p.R
            pos = T[:3, :3] @ p.o + T[:3, 3] - origin
            out.append(f'<geom name="{name}_g{k}" type="{typ}" size="{size}" pos="{_v(pos)}" '
                       f'quat="{_v(quat_of(R))}" {col} rgba="{rgba}"/>')
    return "".join(out)


def prrr_mjcf(design: PrrrDesign, options: MjcfOptions = MjcfOptions(), *, ee_mass: float | None = None,
              mass_properties: MassProperties | None = None, pose=None) -> str:
    """MJCF text of the 3-PRRR for ``options``.

    ``ee_mass`` [kg]: the platform's mass in the LUMPED and REAL modes (default: M − the lumped
    link masses). ``mass_properties``: the CAD's (default: the analytic mass model), used by
    REAL (links) and CAD (every body). ``pose`` [m]: also a keyframe ``pose`` at that
    end-effector position (:func:`pose_qpos`).
    """
    o = options
    sliders, A, B, Q, W = home_pose(design)
    g = design.geometry
    act = design.actuator
    sol = o.solver
    k = act.spring if o.spring_override is None else o.spring_override
    M = design.end_effector.mass
    need_cad = o.link_masses is not LinkMasses.LUMPED or o.geoms
    masses = (mass_properties if mass_properties is not None else cad_prrr.mass_properties(design)) if need_cad else None
    inert = _world_inertials(design, masses) if masses is not None else {}
    specs = cad_prrr.part_specs(design) if o.geoms else {}
    frames = cad_prrr.part_frames(design, cad_prrr.solve_pose(design, (0.0, 0.0, 0.0), branch=BRANCH)) if o.geoms else {}
    gc = ' gravcomp="1"' if o.gravity_compensated_sliders else ""

    def geoms(body: str, origin: np.ndarray) -> str:
        return _geoms(design, specs, frames, body, origin, o.contacts) if o.geoms else ""

    def link_inertial(name: str, start: np.ndarray, end: np.ndarray, origin: np.ndarray) -> str:
        if o.link_masses is LinkMasses.LUMPED:  # a negligible point mass mid-way (frame-relative)
            return _point_inertial(LUMPED_LINK_MASS, (start + end) / 2 - origin)
        return _inertial(*inert[name], origin)

    half = g.stroke / 2.0
    srange = f' range="{-half:.12g} {half:.12g}"' if o.slider_limits else ""
    legs, tendons = [], []
    for i in range(3):
        n = i + 1
        w = W[i]
        jd = f' damping="{o.joint_damping:.9g}"' if o.joint_damping > 0 else ""
        lim = o.joint_limits or RJointLimits()
        rng = lambda r: "" if r is None else f' range="{r[0]:.12g} {r[1]:.12g}"'  # noqa: E731
        rf = ""
        if o.r_joint_friction and design.structure.joint_friction > 0:
            # Coulomb friction in the R joints (seed 002 puts it there); R3 turns by −(θ1 + θ2)
            rf = (f' frictionloss="{design.structure.joint_friction:.9g}" solreffriction="{_v(sol.solref)}" '
                  f'solimpfriction="{_v(sol.solimp)}"')
            jd += rf
        if rf or lim.r3 is not None:
            tendons.append(f'<fixed name="r3_{n}"{rf}{rng(lim.r3)}><joint joint="r1_{n}" coef="1"/>'
                           f'<joint joint="r2_{n}" coef="1"/></fixed>')
        r1, r2 = rng(lim.r1), rng(lim.r2)
        link2 = link_inertial(f"link2_{n}", B[i], Q[i] - g.r4 * w, B[i])
        body_link2 = (f'<body name="link2_{n}" pos="{_v(B[i] - A[i])}">'
                      f'<joint name="r2_{n}" type="hinge" axis="{_v(w)}"{jd}{r2}/>{link2}'
                      f'{geoms(f"link2_{n}", B[i])}</body>')
        body_link1 = (f'<body name="link1_{n}" pos="0 0 0">'
                      f'<joint name="r1_{n}" type="hinge" axis="{_v(w)}"{jd}{r1}/>'
                      f'{link_inertial(f"link1_{n}", A[i], B[i], A[i])}{geoms(f"link1_{n}", A[i])}{body_link2}</body>')
        slider_damp = f' damping="{act.viscous:.9g}"' if o.viscous_friction and not o.motor_dynamics else ""
        fric = ""
        if o.coulomb_friction:  # friction of the output slider on its rail, as hard as the closures
            fric = (f' frictionloss="{act.coulomb_friction:.9g}" solreffriction="{_v(sol.solref)}" '
                    f'solimpfriction="{_v(sol.solimp)}"')
        if o.link_masses is LinkMasses.CAD:
            carriage_inertial = _inertial(*inert[f"carriage_{n}"], A[i])
        else:
            carriage_inertial = _point_inertial(CARRIAGE_MASS, np.zeros(3))
        motor_inertial = _point_inertial(act.motor_mass, np.zeros(3), 1e-3)
        mdamp = f' damping="{act.viscous:.9g}"' if o.viscous_friction else ""
        carriage_geoms = geoms(f"carriage_{n}", A[i])
        if o.motor_dynamics and o.sea_compliance:
            # motor and output slider each slide on the rail; the SEA spring is a fixed tendon
            # L = D_e − D between them (no relative joint: the rail friction acts on D_e)
            # the motor side's M_m is a reflected rotor/screw inertia, not a weight: always gravity-compensated
            leg = (f'<body name="motor_{n}" pos="{_v(A[i])}" gravcomp="1">'
                   f'<joint name="motor_{n}" type="slide" axis="0 0 1"{mdamp}{srange}/>{motor_inertial}</body>'
                   f'<body name="carriage_{n}" pos="{_v(A[i])}"{gc}>'
                   f'<joint name="slider_{n}" type="slide" axis="0 0 1"{fric}{srange}/>'
                   f'{carriage_inertial}{carriage_geoms}{body_link1}</body>')
            tendons.append(f'<fixed name="sea_{n}" stiffness="{k:.9g}" springlength="0">'
                           f'<joint joint="slider_{n}" coef="1"/><joint joint="motor_{n}" coef="-1"/></fixed>')
        elif o.motor_dynamics:  # rigid transmission: motor mass moves with the slider
            leg = (f'<body name="carriage_{n}" pos="{_v(A[i])}"{gc}>'
                   f'<joint name="slider_{n}" type="slide" axis="0 0 1"{mdamp}{fric}{srange}/>{motor_inertial}'
                   f'{carriage_geoms}{body_link1}</body>')
        else:  # ideal force source on the output slider (the spring force equals the command)
            leg = (f'<body name="carriage_{n}" pos="{_v(A[i])}"{gc}>'
                   f'<joint name="slider_{n}" type="slide" axis="0 0 1"{slider_damp}{fric}{srange}/>'
                   f'{carriage_inertial}{carriage_geoms}{body_link1}</body>')
        legs.append((leg, Q[i] - B[i], w))

    if o.link_masses is LinkMasses.CAD:
        ee_inertial = _inertial(*inert["platform"], np.zeros(3))
        ee_mass = inert["platform"][0]
    else:
        if ee_mass is None:
            ee_mass = M - 6 * LUMPED_LINK_MASS
        r_ball = design.end_effector.handle_diameter / 2.0
        i_ball = 0.4 * max(ee_mass, 1e-6) * r_ball**2
        ee_inertial = f'<inertial pos="0 0 0" mass="{ee_mass:.12g}" diaginertia="{i_ball:.9g} {i_ball:.9g} {i_ball:.9g}"/>'
    if o.platform is Platform.TRANSLATIONAL:
        ee_joints = ('<joint name="ee_x" type="slide" axis="1 0 0"/>'
                     '<joint name="ee_y" type="slide" axis="0 1 0"/>'
                     '<joint name="ee_z" type="slide" axis="0 0 1"/>')
    else:
        ee_joints = '<freejoint name="ee_free"/>'
    ee = (f'<body name="ee" pos="0 0 0">{ee_joints}{ee_inertial}{geoms("ee", np.zeros(3))}'
          f'<site name="handle" pos="0 0 0"/></body>')
    base = ""
    if o.link_masses is LinkMasses.CAD or o.geoms:
        base_inertial = _inertial(*inert["base"], np.zeros(3)) if o.link_masses is LinkMasses.CAD else ""
        base = f'<body name="base" pos="0 0 0">{base_inertial}{geoms("base", np.zeros(3))}</body>'
    hand = ""
    eqs = []
    for i, (_, anchor, w) in enumerate(legs):
        n = i + 1
        eqs.append(f'<connect name="close_{n}" body1="link2_{n}" body2="ee" anchor="{_v(anchor)}"/>')
        if o.platform is Platform.FREE:
            eqs.append(f'<connect name="close_{n}_axis" body1="link2_{n}" body2="ee" '
                       f'anchor="{_v(anchor + AXIS_ARM * w)}"/>')
    if o.hand is not None:
        h = o.hand
        hj = "".join(f'<joint name="hand_{a}" type="slide" axis="{ax}" stiffness="{h.stiffness:.9g}" '
                     f'damping="{h.damping:.9g}"/>'
                     for a, ax in (("x", "1 0 0"), ("y", "0 1 0"), ("z", "0 0 1")))
        hand = (f'<body name="hand" pos="0 0 0" gravcomp="1">{hj}<inertial pos="0 0 0" mass="{h.mass:.9g}" '
                f'diaginertia="1e-5 1e-5 1e-5"/></body>')
        eqs.append('<connect name="hand_grip" body1="hand" body2="ee" anchor="0 0 0"/>')
    actuated = [f"motor_{n}" if o.motor_dynamics and o.sea_compliance else f"slider_{n}" for n in (1, 2, 3)]
    gear = act.efficiency if o.motor_efficiency and o.motor_dynamics else 1.0
    cmax = act.force_limit / gear
    frange = f' ctrlrange="{-cmax:.12g} {cmax:.12g}"' if o.force_limits else ""
    acts = "".join(f'<motor name="force_{n}" joint="{j}" gear="{gear:.12g}"{frange}/>' for n, j in zip((1, 2, 3), actuated))
    contact = ""
    if o.contacts:
        pairs = set()
        for n in (1, 2, 3):
            pairs |= {("base", f"carriage_{n}"), (f"link2_{n}", "ee")}
        contact = "<contact>" + "".join(f'<exclude body1="{a}" body2="{b}"/>' for a, b in sorted(pairs)) + "</contact>"
    keyframe = ""
    if pose is not None:
        keyframe = f'<keyframe><key name="pose" qpos="{_v(pose_qpos(design, pose, options=o))}"/></keyframe>'
    flags = [f'gravity="{"enable" if o.gravity else "disable"}"',
             f'contact="{"enable" if o.contacts else "disable"}"']
    return f"""<mujoco model={quoteattr(design.name)}>
  <compiler angle="radian" inertiafromgeom="false" autolimits="true"/>
  <option timestep="{sol.timestep:.9g}" integrator="{sol.integrator}" iterations="{sol.iterations}"
          tolerance="{sol.tolerance:.3g}" gravity="0 0 {-GRAVITY:g}" cone="pyramidal" jacobian="dense">
    <flag {' '.join(flags)}/>
  </option>
  <default>
    <geom contype="0" conaffinity="0"/>
    <equality solref="{_v(sol.solref)}" solimp="{_v(sol.solimp)}"/>
  </default>
  <worldbody>
    {base}
    {''.join(leg for leg, _, _ in legs)}
    {ee}
    {hand}
  </worldbody>
  <tendon>{''.join(tendons)}</tendon>
  <equality>{''.join(eqs)}</equality>
  <actuator>{acts}</actuator>
  {contact}
  {keyframe}
</mujoco>
"""


def pose_qpos(design: PrrrDesign, p, *, options: MjcfOptions = MjcfOptions()) -> np.ndarray:
    """Joint vector of the model of :func:`prrr_mjcf` at end-effector position ``p`` [m], at rest
    with relaxed springs (joint order: per leg motor (with a motor side), slider, r1, r2; the
    platform; the hand)."""
    params = params_of(design)
    ik = inverse_kinematics(params, np.asarray(p, dtype=float))
    if not bool(ik.reachable):
        raise InvalidDesign(f"pose {np.asarray(p) * 1e3} mm is not reachable by {design.name}")
    home = inverse_kinematics(params, np.zeros(3))
    dz = np.asarray(ik.sliders) - np.asarray(home.sliders)
    dth = np.asarray(ik.theta[BRANCH]) - np.asarray(home.theta[BRANCH])
    q: list[float] = []
    for i in range(3):
        if options.motor_dynamics and options.sea_compliance:
            q.append(dz[i])
        q += [dz[i], dth[i, 0], dth[i, 1]]
    q += list(np.asarray(p, dtype=float)) if options.platform is Platform.TRANSLATIONAL else \
        list(np.asarray(p, dtype=float)) + [1.0, 0.0, 0.0, 0.0]
    if options.hand is not None:
        q += list(np.asarray(p, dtype=float))
    return np.asarray(q)
