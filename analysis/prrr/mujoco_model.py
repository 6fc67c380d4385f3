"""MuJoCo multibody model of the 3-PRRR (seed 002), generated from the design.

Three legs, each: (motor mass M_m on a vertical slide →) series spring k → output slider
(carriage) → R1 hinge → link 1 → R2 hinge → link 2, closed on the end-effector at the R3 axis
by equality constraints. Geometry comes from :mod:`hapticopt.design.prrr.kinematics` (``leg_chain`` at
the home pose p = 0, elbow branch 0); every body frame is parallel to the world frame at the
home pose, so joint axes are the kinematic ``w_i``.

Two closures (:class:`Platform`):

* ``TRANSLATIONAL`` — the end-effector has three slide joints and each leg is closed by one
  ``<connect>`` at its R3 point. For a platform that only translates this is exact (the R3
  hinge is the only relative rotation a translating platform can have with a link turning about
  ``w_i``) and not redundant: 12 DOF, 9 constraint rows, mobility 3.
* ``FREE`` — the end-effector is a free body and each leg is closed by two ``<connect>`` on its
  R3 axis (a hinge closure, 5 independent rows per leg; the mechanism is over-constrained, as
  the real one is). Only this model can rotate: it measures the platform rotation that soft
  constraints allow.

Link masses (:class:`LinkMasses`): ``REAL`` gives each link the mass, centre of mass and inertia
of the analytic mass model (``hapticopt.design.mass_properties``, itself tested against the CAD), at
the CAD's elbow branch, and the platform
the rest of the equivalent mass M (seed 002 Table 4: M includes the links as a point mass, so
the moving mass is the same in both modes — what differs is where it sits); ``LUMPED`` puts all
of M into the end-effector (links get a negligible ``LUMPED_LINK_MASS``).

Effects are switched in the model, not in the step loop: gravity off → ``<flag gravity=
"disable">``; contacts always off (no collision geometry, ``<flag contact="disable">``); the
screw viscous friction ξ is the motor joint's ``damping``; Coulomb friction the output
slider's ``frictionloss``; SEA compliance off → no spring joint (ideal force source on the
output slider, with or without the motor mass).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from enum import StrEnum
from typing import Any

import numpy as np

from hapticopt.design.prrr.kinematics import (
    inverse_kinematics,
    jacobian,
    leg_chain,
    leg_frames,
    params_of,
    slider_offset,
)
from hapticopt.design.errors import InvalidDesign
from hapticopt.design.prrr.params import PrrrDesign
from hapticopt.design.units import GRAVITY
from hapticopt.analysis.loop.mujoco_solver import SOLVER_BY_FIDELITY, ZERO_HEALTH, Health, Integrator, SolverSettings  # noqa: F401
from hapticopt.analysis.loop.operator import Operator
from hapticopt.design.prrr import cad as cad_prrr
from hapticopt.design.prrr.kinematics import inverse_kinematics as ik_fn
import time as _time
import dataclasses

#: mass of a link [kg] when link masses are lumped into the end-effector (0.15 % of M each; at
#: 1e-4 kg the links' fast constraint modes dissipate 3 % of the energy in 10 periods, measured
#: in docs/multibody.md; 1e-3 kg: 0.3 %)
LUMPED_LINK_MASS = 1e-3
#: output slider (carriage) mass [kg]; the paper's two-mass model has none, MuJoCo needs > 0
CARRIAGE_MASS = 1e-3
#: elbow branch of every leg: the CAD's (hapticopt.design.prrr.cad.DEFAULT_BRANCH), so link inertias match
BRANCH = 1
#: length along w of the second R3 closure point of the FREE platform [m]
_AXIS_ARM = 0.04


class LinkMasses(StrEnum):
    LUMPED = "lumped"
    REAL = "real"


class Platform(StrEnum):
    TRANSLATIONAL = "translational"
    FREE = "free"




@dataclass(frozen=True, kw_only=True)
class ModelOptions:
    """Which physics the model contains (a scene's effects map onto these)."""

    link_masses: LinkMasses = LinkMasses.LUMPED
    platform: Platform = Platform.TRANSLATIONAL
    sea_compliance: bool = True  # series spring between motor and output slider
    motor_dynamics: bool = True  # motor-side mass M_m (else the force acts on the slider)
    viscous_friction: bool = False  # ξ on the motor joint (on the slider when no motor side)
    coulomb_friction: bool = False  # frictionloss on the output slider
    r_joint_friction: bool = False  # frictionloss τ_c (structure.joint_friction_Nm) on R1, R2 and, as a fixed
    #                                 tendon θ1 + θ2 = −θ3, on R3 (a translating platform turns R3 by −(θ1 + θ2))
    gravity: bool = False
    joint_damping: float = 0.0  # R-joint viscous damping [N·m·s/rad]
    hand: Operator | None = None  # operator hand body coupled to the handle
    spring_override: float | None = None  # SEA spring [N/m] instead of the design's
    solver: SolverSettings = field(default_factory=SolverSettings)


@dataclass(frozen=True, kw_only=True)
class PrrrMj:
    """A compiled model with the addresses a plant needs. ``model`` is MuJoCo's (mutable) MjModel."""

    design: PrrrDesign
    model: Any
    xml: str
    options: ModelOptions
    jacobian: np.ndarray  # J, Ḋ ↦ ṗ (3×3)
    c_e: float  # eq (1) slider offset [m] = home slider position
    ee_mass: float  # platform mass [kg]
    link_mass: float  # total link mass [kg]
    motor_qpos: np.ndarray | None  # qpos addresses of the motor slides (None: no separate motor side)
    slider_qpos: np.ndarray  # qpos addresses of the output sliders (from home)
    actuator_joint_dof: np.ndarray  # dof address the actuator drives per leg
    ee_body: int
    carriage_body: np.ndarray  # (3,) body ids of the output sliders
    carriage_home_z: np.ndarray  # (3,) their world z at the home pose [m]
    ee_qpos: np.ndarray  # (3,) slide addresses (TRANSLATIONAL) or (7,) free joint
    hand_qpos: np.ndarray | None  # (3,) hand slide addresses
    hand_dof: np.ndarray | None
    eq_rows: int  # number of equality constraint rows

    def sliders(self, qpos: np.ndarray) -> np.ndarray:
        """Output slider positions D_e [m] (absolute, home = c_e)."""
        return qpos[self.slider_qpos] + self.c_e

    def motors(self, qpos: np.ndarray) -> np.ndarray:
        """Motor-side positions D [m] (= output sliders without a motor side)."""
        if self.motor_qpos is None:
            return self.sliders(qpos)
        return qpos[self.motor_qpos] + self.c_e

    def deflection(self, qpos: np.ndarray) -> np.ndarray:
        """SEA spring deflection x = D − D_e [m] (zeros without SEA compliance)."""
        if self.motor_qpos is None:
            return np.zeros(3)
        return qpos[self.motor_qpos] - qpos[self.slider_qpos]


def _v(x: Any) -> str:
    return " ".join(f"{float(c):.12g}" for c in np.ravel(x))


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


def _real_link_inertials(design: PrrrDesign) -> dict[str, Any]:
    """Link inertias of the analytic mass model (``hapticopt.design.mass_properties``, tested against
    the CAD), moved from the CAD body frames at the home pose into this model's world-aligned body
    frames: name → (body origin [m] ↦ ``<inertial>`` element)."""
    bodies = cad_prrr.mass_properties(design).bodies()
    frames = cad_prrr.part_frames(design, cad_prrr.solve_pose(design, (0.0, 0.0, 0.0), branch=BRANCH))
    out: dict[str, Any] = {}
    for name, pm in bodies.items():
        if not name.startswith("link"):
            continue
        T = frames[name]
        R = T[:3, :3]
        com = R @ pm.com + T[:3, 3]
        inertia = R @ pm.inertia @ R.T
        full = [inertia[0, 0], inertia[1, 1], inertia[2, 2], inertia[0, 1], inertia[0, 2], inertia[1, 2]]

        def element(origin: np.ndarray, com=com, full=full, mass=pm.mass) -> str:
            return f'<inertial pos="{_v(com - origin)}" mass="{mass:.12g}" fullinertia="{_v(full)}"/>'

        out[name] = element
    return out


def build_xml(design: PrrrDesign, options: ModelOptions, *, ee_mass: float | None = None) -> str:
    """MJCF text of the 3-PRRR for ``options``; ``ee_mass`` [kg] defaults to M − link masses (lumped)."""
    sliders, A, B, Q, W = home_pose(design)
    g = design.geometry
    act = design.actuator
    sol = options.solver
    k = act.spring if options.spring_override is None else options.spring_override
    M = design.end_effector.mass

    def link_geoms(start: np.ndarray, end: np.ndarray, w: np.ndarray, origin: np.ndarray) -> str:
        """Lumped link: a negligible point mass mid-way (frame-relative)."""
        a, b = start - origin, end - origin
        return (f'<inertial pos="{_v((a + b) / 2)}" mass="{LUMPED_LINK_MASS:.6g}" '
                f'diaginertia="1e-9 1e-9 1e-9"/>')

    real_links = _real_link_inertials(design) if options.link_masses is LinkMasses.REAL else {}

    def link1_inertial(i: int, origin: np.ndarray) -> str:
        if options.link_masses is LinkMasses.REAL:
            return real_links[f"link1_{i + 1}"](origin)
        return link_geoms(A[i], B[i], W[i], origin)

    legs = []
    tendons: list[str] = []
    g_struct = design.structure
    for i in range(3):
        w = W[i]
        jd = f' damping="{options.joint_damping:.9g}"' if options.joint_damping > 0 else ""
        if options.r_joint_friction:
            rf = (f' frictionloss="{g_struct.joint_friction:.9g}" solreffriction="{_v(sol.solref)}" '
                  f'solimpfriction="{_v(sol.solimp)}"')
            jd += rf
            tendons.append(f'<fixed name="r3_{i}"{rf}><joint joint="r1_{i}" coef="1"/>'
                           f'<joint joint="r2_{i}" coef="1"/></fixed>')
        # link 2: B → (B + d4 e) → Q (the r4 offset along w as a second bar)
        bq_in_plane = Q[i] - g.r4 * w
        link2 = link_geoms(B[i], bq_in_plane, w, B[i])
        if options.link_masses is LinkMasses.REAL:
            link2 = real_links[f"link2_{i + 1}"](B[i])  # issue 3's mass model
        closure_anchor = Q[i] - B[i]
        body_link2 = (f'<body name="link2_{i}" pos="{_v(B[i] - A[i])}">'
                      f'<joint name="r2_{i}" type="hinge" axis="{_v(w)}"{jd}/>{link2}</body>')
        body_link1 = (f'<body name="link1_{i}" pos="0 0 0">'
                      f'<joint name="r1_{i}" type="hinge" axis="{_v(w)}"{jd}/>'
                      f'{link1_inertial(i, A[i])}{body_link2}</body>')
        slider_damp = ""
        if options.viscous_friction and not options.motor_dynamics:
            slider_damp = f' damping="{act.viscous:.9g}"'
        fric = ""
        if options.coulomb_friction:  # friction of the output slider on its rail, as hard as the closures
            fric = (f' frictionloss="{act.coulomb_friction:.9g}" solreffriction="{_v(sol.solref)}" '
                    f'solimpfriction="{_v(sol.solimp)}"')
        carriage_inertial = f'<inertial pos="0 0 0" mass="{CARRIAGE_MASS:.6g}" diaginertia="1e-9 1e-9 1e-9"/>'
        motor_inertial = f'<inertial pos="0 0 0" mass="{act.motor_mass:.9g}" diaginertia="1e-3 1e-3 1e-3"/>'
        mdamp = f' damping="{act.viscous:.9g}"' if options.viscous_friction else ""
        if options.motor_dynamics and options.sea_compliance:
            # motor and output slider each slide on the rail; the SEA spring is a fixed tendon
            # L = D_e − D between them (no relative joint: the rail friction acts on D_e)
            leg = (f'<body name="motor_{i}" pos="{_v(A[i])}" gravcomp="1">'
                   f'<joint name="motor_{i}" type="slide" axis="0 0 1"{mdamp}/>{motor_inertial}</body>'
                   f'<body name="carriage_{i}" pos="{_v(A[i])}" gravcomp="1">'
                   f'<joint name="slider_{i}" type="slide" axis="0 0 1"{fric}/>'
                   f'{carriage_inertial}{body_link1}</body>')
            tendons.append(f'<fixed name="sea_{i}" stiffness="{k:.9g}" springlength="0">'
                           f'<joint joint="slider_{i}" coef="1"/><joint joint="motor_{i}" coef="-1"/></fixed>')
        elif options.motor_dynamics:  # rigid transmission: motor mass moves with the slider
            leg = (f'<body name="carriage_{i}" pos="{_v(A[i])}" gravcomp="1">'
                   f'<joint name="slider_{i}" type="slide" axis="0 0 1"{mdamp}{fric}/>{motor_inertial}'
                   f'{body_link1}</body>')
        else:  # ideal force source on the output slider (the spring force equals the command)
            leg = (f'<body name="carriage_{i}" pos="{_v(A[i])}" gravcomp="1">'
                   f'<joint name="slider_{i}" type="slide" axis="0 0 1"{slider_damp}{fric}/>'
                   f'{carriage_inertial}{body_link1}</body>')
        legs.append((leg, closure_anchor, w))

    if ee_mass is None:
        ee_mass = M - 6 * LUMPED_LINK_MASS
    return _assemble(design, options, legs, tendons, ee_mass, sol)


def _assemble(design: PrrrDesign, options: ModelOptions, legs: list, tendons: list[str], ee_mass: float,
              sol: SolverSettings) -> str:
    flags = [f'gravity="{"enable" if options.gravity else "disable"}"', 'contact="disable"']
    r_ball = design.end_effector.handle_diameter / 2.0
    i_ball = 0.4 * max(ee_mass, 1e-6) * r_ball**2
    if options.platform is Platform.TRANSLATIONAL:
        ee_joints = ('<joint name="ee_x" type="slide" axis="1 0 0"/>'
                     '<joint name="ee_y" type="slide" axis="0 1 0"/>'
                     '<joint name="ee_z" type="slide" axis="0 0 1"/>')
    else:
        ee_joints = '<freejoint name="ee_free"/>'
    ee = (f'<body name="ee" pos="0 0 0">{ee_joints}'
          f'<inertial pos="0 0 0" mass="{ee_mass:.12g}" diaginertia="{i_ball:.9g} {i_ball:.9g} {i_ball:.9g}"/>'
          f'<site name="handle" pos="0 0 0"/></body>')
    hand = ""
    eqs = []
    for i, (_, anchor, w) in enumerate(legs):
        eqs.append(f'<connect name="close_{i}" body1="link2_{i}" body2="ee" anchor="{_v(anchor)}"/>')
        if options.platform is Platform.FREE:
            eqs.append(f'<connect name="close_{i}_axis" body1="link2_{i}" body2="ee" '
                       f'anchor="{_v(anchor + _AXIS_ARM * w)}"/>')
    if options.hand is not None:
        h = options.hand
        hj = "".join(f'<joint name="hand_{a}" type="slide" axis="{ax}" stiffness="{h.stiffness:.9g}" '
                     f'damping="{h.damping:.9g}"/>'
                     for a, ax in (("x", "1 0 0"), ("y", "0 1 0"), ("z", "0 0 1")))
        hand = (f'<body name="hand" pos="0 0 0" gravcomp="1">{hj}<inertial pos="0 0 0" mass="{h.mass:.9g}" '
                f'diaginertia="1e-5 1e-5 1e-5"/></body>')
        eqs.append('<connect name="hand_grip" body1="hand" body2="ee" anchor="0 0 0"/>')
    actuated = []
    for i in range(3):
        if options.motor_dynamics and options.sea_compliance:
            actuated.append(f"motor_{i}")
        else:
            actuated.append(f"slider_{i}")
    acts = "".join(f'<motor name="force_{i}" joint="{j}" gear="1"/>' for i, j in enumerate(actuated))
    solref = _v(sol.solref)
    solimp = _v(sol.solimp)
    return f"""<mujoco model="{design.name}">
  <compiler angle="radian" inertiafromgeom="auto" autolimits="true"/>
  <option timestep="{sol.timestep:.9g}" integrator="{sol.integrator.value}" iterations="{sol.iterations}"
          tolerance="{sol.tolerance:.3g}" gravity="0 0 {-GRAVITY:g}" cone="pyramidal" jacobian="dense">
    <flag {' '.join(flags)}/>
  </option>
  <default>
    <geom contype="0" conaffinity="0"/>
    <equality solref="{solref}" solimp="{solimp}"/>
  </default>
  <worldbody>
    {''.join(leg for leg, _, _ in legs)}
    {ee}
    {hand}
  </worldbody>
  <tendon>{''.join(tendons)}</tendon>
  <equality>{''.join(eqs)}</equality>
  <actuator>{acts}</actuator>
</mujoco>
"""


def build(design: PrrrDesign, options: ModelOptions | None = None) -> PrrrMj:
    """Compile the MuJoCo model of ``design`` with ``options`` (default: lumped, translational)."""
    import mujoco

    options = options or ModelOptions()
    xml = build_xml(design, options)
    model = mujoco.MjModel.from_xml_string(xml)
    link_ids = [mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, f"link{j}_{i}")
                for i in range(3) for j in (1, 2)]
    link_mass = float(sum(model.body_mass[b] for b in link_ids))
    ee_body = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, "ee")
    if options.link_masses is LinkMasses.REAL:  # second pass: the platform gets M − links
        rest = design.end_effector.mass - link_mass
        if rest <= 0.05 * design.end_effector.mass:
            raise InvalidDesign(
                f"end_effector.mass_kg = {design.end_effector.mass:g} must exceed the link mass "
                f"{link_mass:.4g} kg of the structure by 5 % (M includes the links, seed 002 Table 4)")
        xml = build_xml(design, options, ee_mass=rest)
        model = mujoco.MjModel.from_xml_string(xml)
    ee_mass = float(model.body_mass[ee_body])

    def jq(name: str) -> int:
        return int(model.jnt_qposadr[mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, name)])

    def jd(name: str) -> int:
        return int(model.jnt_dofadr[mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, name)])

    has_motor = options.motor_dynamics and options.sea_compliance
    if has_motor:
        motor_qpos = np.array([jq(f"motor_{i}") for i in range(3)])
        act_dof = np.array([jd(f"motor_{i}") for i in range(3)])
    else:
        motor_qpos = None
        act_dof = np.array([jd(f"slider_{i}") for i in range(3)])
    slider_qpos = np.array([jq(f"slider_{i}") for i in range(3)])
    if options.platform is Platform.TRANSLATIONAL:
        ee_qpos = np.array([jq(n) for n in ("ee_x", "ee_y", "ee_z")])
    else:
        a = jq("ee_free")
        ee_qpos = np.arange(a, a + 7)
    hand_qpos = hand_dof = None
    if options.hand is not None:
        hand_qpos = np.array([jq(f"hand_{a}") for a in "xyz"])
        hand_dof = np.array([jd(f"hand_{a}") for a in "xyz"])
    params = params_of(design)
    carriage = np.array([mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, f"carriage_{i}") for i in range(3)])
    return PrrrMj(
        carriage_body=carriage, carriage_home_z=home_pose(design)[1][:, 2],
        design=design, model=model, xml=xml, options=options,
        jacobian=np.asarray(jacobian(params.beta)), c_e=float(slider_offset(params)),
        ee_mass=ee_mass, link_mass=link_mass,
        motor_qpos=motor_qpos, slider_qpos=slider_qpos,
        actuator_joint_dof=act_dof, ee_body=ee_body, ee_qpos=ee_qpos,
        hand_qpos=hand_qpos, hand_dof=hand_dof,
        eq_rows=int(sum(3 for _ in range(model.neq))),
    )




def ee_position(mj: PrrrMj, data: Any) -> np.ndarray:
    return data.xpos[mj.ee_body].copy()


def health(mj: PrrrMj, data: Any) -> Health:
    """Constraint residuals of ``data``.

    Uses only quantities of one instant (``efc_pos``, ``xpos``, ``xquat``: after ``mj_step``
    they belong to the state before the last step, ``qpos`` to the state after it).
    """
    import mujoco

    eq = data.efc_type[: data.nefc] == mujoco.mjtConstraint.mjCNSTR_EQUALITY
    viol = float(np.max(np.abs(data.efc_pos[: data.nefc][eq]))) if np.any(eq) else 0.0
    quat = data.xquat[mj.ee_body]
    rot = 2.0 * math.atan2(float(np.linalg.norm(quat[1:])), abs(float(quat[0])))
    p = data.xpos[mj.ee_body]
    sliders = data.xpos[mj.carriage_body, 2] - mj.carriage_home_z + mj.c_e
    fk = mj.jacobian @ (sliders - mj.c_e)
    return Health(violation=viol, rotation=rot, closure=float(np.linalg.norm(p - fk)))


def set_pose(mj: PrrrMj, data: Any, p: np.ndarray) -> None:
    """Place the mechanism exactly at end-effector position ``p`` [m] (IK, branch 0), at rest."""
    import mujoco


    params = params_of(mj.design)
    ik = ik_fn(params, np.asarray(p, dtype=float))
    home = ik_fn(params, np.zeros(3))
    dz = np.asarray(ik.sliders) - np.asarray(home.sliders)
    dth = np.asarray(ik.theta[BRANCH]) - np.asarray(home.theta[BRANCH])
    m = mj.model
    data.qpos[:] = m.qpos0
    data.qvel[:] = 0.0
    data.qpos[mj.slider_qpos] = dz
    if mj.motor_qpos is not None:
        data.qpos[mj.motor_qpos] = dz  # spring relaxed
    for i in range(3):
        for j, name in ((0, "r1"), (1, "r2")):
            jid = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, f"{name}_{i}")
            data.qpos[m.jnt_qposadr[jid]] = dth[i, j]
    if mj.options.platform is Platform.TRANSLATIONAL:
        data.qpos[mj.ee_qpos] = p
    else:
        data.qpos[mj.ee_qpos[:3]] = p
    if mj.hand_qpos is not None:
        data.qpos[mj.hand_qpos] = p
    mujoco.mj_forward(m, data)


# --------------------------------------------------------------------------- accuracy probe
@dataclass(frozen=True, kw_only=True)
class ProbeResult:
    """Worst constraint health over a stress run, and its cost."""

    health: Health
    wall_s: float
    steps: int
    warnings: tuple[str, ...]
    finite: bool


def stress_probe(design: PrrrDesign, options: ModelOptions, *, duration: float = 1.0,
                 amplitude: float = 0.03, force: float = 100.0, period: float = 1e-3) -> ProbeResult:
    """Drive the linkage hard and record the worst closed-chain health.

    The operator hand (20 kN/m) pulls the end-effector along a Lissajous path of ``amplitude``
    [m] per axis (2, 3 and 2.5 Hz: ≈ 0.4–0.5 m/s, accelerations ≈ 10 m/s²) while the output
    sliders are pushed by ±``force`` [N] (what a 25 N/mm wall at 4 mm asks for), updated every
    ``period`` [s] as a controller would. Returns the worst violation, rotation and closure.
    """

    import mujoco

    if options.hand is None:
        options = _replace(options, hand=Operator())
    mj = build(design, options)
    m = mj.model
    data = mujoco.MjData(m)
    set_pose(mj, data, np.zeros(3))
    ticks = int(round(duration / period))
    n_sub = max(1, int(round(period / m.opt.timestep)))
    freq = np.array([2.0, 3.0, 2.5])
    fforce = np.array([1.5, 2.2, 2.9])
    worst = ZERO_HEALTH
    spring_adr = m.jnt_qposadr[[mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, f"hand_{a}") for a in "xyz"]]
    t0 = _time.perf_counter()
    finite = True
    for n in range(ticks):
        t = (n + 0.5) * period
        ref = amplitude * np.sin(2 * np.pi * freq * t)
        m.qpos_spring[spring_adr] = ref
        data.qfrc_applied[mj.hand_dof] = Operator().damping * amplitude * 2 * np.pi * freq * np.cos(2 * np.pi * freq * t)
        data.ctrl[:] = force * np.sin(2 * np.pi * fforce * t)
        mujoco.mj_step(m, data, nstep=n_sub)
        if not np.all(np.isfinite(data.qpos)):
            finite = False
            break
        worst = worst.worst(health(mj, data))
    wall = _time.perf_counter() - t0
    warns = tuple(str(mujoco.mjtWarning(i)).split(".")[-1] for i in range(len(data.warning))
                  if data.warning[i].number > 0)
    return ProbeResult(health=worst, wall_s=wall, steps=ticks * n_sub, warnings=warns, finite=finite)


def _replace(obj: Any, **kw: Any) -> Any:

    return dataclasses.replace(obj, **kw)
