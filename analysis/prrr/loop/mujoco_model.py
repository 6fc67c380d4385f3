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
    jacobian,
    params_of,
    slider_offset,
)
from hapticopt.design.errors import InvalidDesign
from hapticopt.design.prrr.params import PrrrDesign
from hapticopt.analysis.fidelity import Fidelity
from hapticopt.analysis.status import Status
from hapticopt.analysis.loop.mujoco_solver import SOLVER_BY_FIDELITY, ZERO_HEALTH, Health, Integrator, SolverSettings  # noqa: F401
from hapticopt.analysis.loop.operator import Operator
from hapticopt.design.prrr import mjcf
from hapticopt.design.prrr.kinematics import inverse_kinematics as ik_fn
import time as _time
import dataclasses

#: the generator's constants and option enums (design/prrr/mjcf.py: one 3-PRRR MJCF generator)
LUMPED_LINK_MASS = mjcf.LUMPED_LINK_MASS
CARRIAGE_MASS = mjcf.CARRIAGE_MASS
BRANCH = mjcf.BRANCH
Platform = mjcf.Platform


class LinkMasses(StrEnum):
    """The plant's mass modes (the generator's ``CAD`` mode is the exported model's)."""

    LUMPED = "lumped"
    REAL = "real"


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


home_pose = mjcf.home_pose


def mjcf_options(options: ModelOptions) -> mjcf.MjcfOptions:
    """The generator's options for a plant configuration (hand and solver as plain values)."""
    sol = options.solver
    hand = None if options.hand is None else mjcf.HandBody(mass=options.hand.mass, stiffness=options.hand.stiffness,
                                                           damping=options.hand.damping)
    return mjcf.MjcfOptions(
        link_masses=mjcf.LinkMasses(options.link_masses.value), platform=options.platform, sea_compliance=options.sea_compliance,
        motor_dynamics=options.motor_dynamics, viscous_friction=options.viscous_friction,
        coulomb_friction=options.coulomb_friction, r_joint_friction=options.r_joint_friction,
        gravity=options.gravity, joint_damping=options.joint_damping,
        hand=hand, spring_override=options.spring_override,
        solver=mjcf.Solver(timestep=sol.timestep, integrator=sol.integrator.value, solref=tuple(sol.solref),
                           solimp=tuple(sol.solimp), iterations=sol.iterations, tolerance=sol.tolerance))


def build_xml(design: PrrrDesign, options: ModelOptions, *, ee_mass: float | None = None) -> str:
    """MJCF text of the 3-PRRR for ``options`` (:func:`hapticopt.design.prrr.mjcf.prrr_mjcf`);
    ``ee_mass`` [kg] defaults to M − link masses (lumped)."""
    return mjcf.prrr_mjcf(design, mjcf_options(options), ee_mass=ee_mass)


def build(design: PrrrDesign, options: ModelOptions | None = None) -> PrrrMj:
    """Compile the MuJoCo model of ``design`` with ``options`` (default: lumped, translational)."""
    import mujoco

    options = options or ModelOptions()
    xml = build_xml(design, options)
    model = mujoco.MjModel.from_xml_string(xml)
    link_ids = [mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, f"link{j}_{i}")
                for i in (1, 2, 3) for j in (1, 2)]
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
        motor_qpos = np.array([jq(f"motor_{i}") for i in (1, 2, 3)])
        act_dof = np.array([jd(f"motor_{i}") for i in (1, 2, 3)])
    else:
        motor_qpos = None
        act_dof = np.array([jd(f"slider_{i}") for i in (1, 2, 3)])
    slider_qpos = np.array([jq(f"slider_{i}") for i in (1, 2, 3)])
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
    carriage = np.array([mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, f"carriage_{i}") for i in (1, 2, 3)])
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
            jid = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, f"{name}_{i + 1}")
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


#: a range at least this wide [rad] never acts: the joint is left unlimited (a parts' sweep that met nothing
#: returns ±π about the reference)
_FREE_WIDTH = 2.0 * math.pi - 1e-9


def export_joint_limits(design: PrrrDesign, *, fidelity: Any = None) -> mjcf.RJointLimits | None:
    """The R-joint ranges of the exported MJCF (``mjcf.export_options``) from the joint-limits evaluator
    (:func:`hapticopt.analysis.prrr.geometry.joint_limits.evaluate`), as angles about the home pose [rad]:
    R2 within the folded-elbow limit |θ2| ≤ θ2_max, intersected with the parts' stops; R1 and R3 the
    parts' stops (at fine fidelity only: manifold3d sweeps, about as costly as the export itself; none at
    lower levels); a stop range of 2π or more is no limit. R3 bounds the tendon θ1 + θ2 = −Δθ3. The legs are identical (leg 1's
    ranges). None when the evaluator finds no assembled device (the export's own checks then name why);
    raises :class:`InvalidDesign` when the evaluator failed."""
    from hapticopt.analysis.prrr.geometry import joint_limits

    res = joint_limits.evaluate(design, fidelity=Fidelity.FINE if fidelity is None else fidelity)
    if res.status is Status.NOT_ASSEMBLABLE:
        return None
    if res.status is Status.FAILED or not math.isfinite(res.elbow_limit):
        raise InvalidDesign(f"design {design.name!r}: no R-joint limits for the MJCF: {res.message or res.status}")
    home = np.asarray(ik_fn(params_of(design), np.zeros(3), xp=np).theta)[BRANCH, 0]  # leg 1: θ1, θ2, θ3 [rad]
    stops = res.stops or {}

    def about_home(j: int, lo: float, hi: float) -> tuple[float, float] | None:
        return None if hi - lo >= _FREE_WIDTH else (lo - home[j], hi - home[j])

    def meet(a, b):
        if a is None or b is None:
            return a if b is None else b
        return (max(a[0], b[0]), min(a[1], b[1]))

    e = res.elbow_limit
    r1 = about_home(0, *stops["r1"]) if "r1" in stops else None
    r2 = meet((-e - home[1], e - home[1]), about_home(1, *stops["r2"]) if "r2" in stops else None)
    d3 = about_home(2, *stops["r3"]) if "r3" in stops else None
    r3 = None if d3 is None else (-d3[1], -d3[0])  # the tendon θ1 + θ2 is −Δθ3
    return mjcf.RJointLimits(r1=r1, r2=r2, r3=r3)
