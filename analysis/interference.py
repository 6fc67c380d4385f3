"""Part interference with manifold3d: colliding pairs and overlap volumes at a pose or over many
poses, and joint-angle ranges free of collisions between neighbouring parts (joint limits from
geometry).

Meshes come from the same part tables as the CAD (:mod:`design.parts`), built once per design
by :func:`prepare` (in each part's own frame, mm) and only moved per pose, so a check costs a
few bounding-box tests plus one exact boolean per candidate pair.

Usage::

    model = prepare(design)                   # once per design
    res = check_pose(model, p)                # p (3,) [m]; res.collisions, res.overlap_mm3
    many = check_poses(model, points)         # points (n, 3) [m]
    limits = joint_limits(model)              # per joint: collision-free angle range [rad]
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from hapticopt.analysis.status import Status
from hapticopt.design import cad_units
from hapticopt.design import parts
from hapticopt.design.errors import InvalidInput
from hapticopt.design.master import cad as cad_master
from hapticopt.design.prrr import cad as cad_prrr
from hapticopt.design.prrr.kinematics import inverse_kinematics, params_np

#: overlaps below this volume are tessellation noise, not interference [mm³]
NOISE_MM3 = 1.0
#: segments per full circle of the interference meshes
SEGMENTS = 32


@dataclass(frozen=True, kw_only=True)
class Collision:
    a: str
    b: str
    overlap_mm3: float


@dataclass(frozen=True, kw_only=True)
class InterferenceResult:
    """Interference at one pose. ``status`` is OK when no pair collides, COLLIDES otherwise
    (the message names the pairs); unreachable poses give status EMPTY."""

    pose_mm: tuple[float, float, float]
    collisions: tuple[Collision, ...]
    status: Status
    message: str = ""

    @property
    def ok(self) -> bool:
        return self.status == Status.OK

    @property
    def pairs(self) -> list[tuple[str, str]]:
        return [(c.a, c.b) for c in self.collisions]

    @property
    def overlap_mm3(self) -> float:
        return float(sum(c.overlap_mm3 for c in self.collisions))

    def metrics(self) -> dict[str, Any]:
        return {"interference_pairs": len(self.collisions), "interference_overlap_mm3": self.overlap_mm3}


@dataclass(frozen=True, kw_only=True)
class JointLimit:
    """Collision-free range of one joint, from its angle at the reference pose [rad]."""

    joint: str
    parent: str
    child: str
    reference: float  # joint angle at the reference pose (kinematic convention) [rad]
    lo: float  # [rad]
    hi: float  # [rad]
    free: bool  # True: no collision over the full turn

    def as_dict(self) -> dict[str, Any]:
        return {"joint": self.joint, "parent": self.parent, "child": self.child,
                "reference_deg": math.degrees(self.reference), "lo_deg": math.degrees(self.lo),
                "hi_deg": math.degrees(self.hi), "free": self.free}


@dataclass(frozen=True, kw_only=True, eq=False)
class InterferenceModel:
    """Per-design precomputation: part meshes in their own frames (mm), the pairs to skip."""

    design: Any
    meshes: dict[str, Any]
    skip: frozenset
    bodies: dict[str, str] = field(default_factory=dict)


def _cad(design: Any):
    return {"prrr": cad_prrr, "master": cad_master}[design.device]


def prepare(design: Any) -> InterferenceModel:
    """Build the interference meshes of a design once (from its part tables)."""
    cad = _cad(design)
    specs = cad.part_specs(design)
    cache: dict[int, Any] = {}
    meshes = {}
    for name, spec in specs.items():
        key = id(spec.primitives)
        if key not in cache:
            cache[key] = parts.manifold_of(spec, segments=SEGMENTS)
        meshes[name] = cache[key]
    bodies = {n: s.body for n, s in specs.items()}
    skip = set(cad.neighbours())
    names = list(specs)
    for i, a in enumerate(names):  # parts of one rigid body never move against each other
        for b in names[i + 1:]:
            if bodies[a] == bodies[b]:
                skip.add(frozenset((a, b)))
    return InterferenceModel(design=design, meshes=meshes, skip=frozenset(skip), bodies=bodies)


def _moved(mesh: Any, T_m: np.ndarray) -> Any:
    T = cad_units.transform_to_mm(T_m)
    return mesh.transform(T[:3, :4])


def _aabb(mesh: Any) -> tuple[np.ndarray, np.ndarray]:
    b = mesh.bounding_box()
    return np.asarray(b[:3]), np.asarray(b[3:])


def check_frames(model: InterferenceModel, frames: dict[str, np.ndarray], *,
                 include_neighbours: bool = False) -> tuple[Collision, ...]:
    """Colliding pairs for parts placed at ``frames`` (name -> 4×4 [m]).

    The bounding-box test of every pair is one array comparison; the pairs whose boxes meet get the
    exact boolean, in the order of the part table (a, b with a before b), as a pair loop would."""
    names = [n for n in model.meshes if n in frames]
    moved = [_moved(model.meshes[n], frames[n]) for n in names]
    boxes = np.array([m.bounding_box() for m in moved], dtype=float).reshape(len(names), 6)
    lo, hi = boxes[:, :3], boxes[:, 3:]
    apart = np.any(lo[:, None, :] > hi[None, :, :], axis=2)
    meet = np.triu(~(apart | apart.T), 1)
    out = []
    for i, j in zip(*np.nonzero(meet)):  # row-major: the order of the pair loop
        a, b = names[i], names[j]
        pair = frozenset((a, b))
        if pair in model.skip and not (include_neighbours and model.bodies[a] != model.bodies[b]):
            continue
        vol = (moved[i] ^ moved[j]).volume()
        if vol > NOISE_MM3:
            out.append(Collision(a=a, b=b, overlap_mm3=float(vol)))
    return tuple(out)


def _result(p: np.ndarray, collisions: tuple[Collision, ...]) -> InterferenceResult:
    pose = tuple(float(x) * 1e3 for x in p)
    if not collisions:
        return InterferenceResult(pose_mm=pose, collisions=(), status=Status.OK)
    msg = "; ".join(f"{c.a} × {c.b}: {c.overlap_mm3:.4g} mm³" for c in collisions)
    return InterferenceResult(pose_mm=pose, collisions=collisions, status=Status.COLLIDES,
                              message=f"interference at ({', '.join(f'{x:g}' for x in pose)}) mm: {msg}")


def _frames_at(model: InterferenceModel, p, branch: int | None) -> dict[str, np.ndarray]:
    design = model.design
    if design.device == "prrr":
        pose = cad_prrr.solve_pose(design, p, branch=cad_prrr.DEFAULT_BRANCH if branch is None else branch)
        return cad_prrr.part_frames(design, pose)
    return cad_master.part_frames(design, cad_master.solve_pose(design, p))


def check_pose(model_or_design: Any, p, *, branch: int | None = None) -> InterferenceResult:
    """Interference at end-effector position ``p`` (3,) [m] (IK branch of the CAD by default)."""

    model = model_or_design if isinstance(model_or_design, InterferenceModel) else prepare(model_or_design)
    p = np.asarray(p, dtype=float)
    try:
        frames = _frames_at(model, p, branch)
    except InvalidInput as exc:
        return InterferenceResult(pose_mm=tuple(float(x) * 1e3 for x in p), collisions=(), status=Status.EMPTY,
                                  message=str(exc))
    return _result(p, check_frames(model, frames))


def check_poses(model_or_design: Any, points, *, branch: int | None = None) -> list[InterferenceResult]:
    """:func:`check_pose` over points (n, 3) [m].

    For the 3-PRRR the inverse kinematics and the part frames of all points are computed in one
    vectorised numpy pass (:func:`_prrr_frames_many`) instead of one jax call per point: the same
    formulas, so poses agree with :func:`check_pose`'s to rounding (the last bit of a sine), and the
    verdicts with them (``tests/analysis/test_interference.py`` compares both paths)."""
    model = model_or_design if isinstance(model_or_design, InterferenceModel) else prepare(model_or_design)
    pts = np.atleast_2d(np.asarray(points, dtype=float))
    if model.design.device != "prrr" or len(pts) == 0:
        return [check_pose(model, p, branch=branch) for p in pts]
    frames = _prrr_frames_many(model.design, pts, cad_prrr.DEFAULT_BRANCH if branch is None else branch)
    return [check_pose(model, p, branch=branch) if f is None else _result(p, check_frames(model, f))
            for p, f in zip(pts, frames)]


#: a point whose numpy reach margin is within this of zero is decided by :func:`check_pose` (its
#: reachability then is exactly the single-pose path's, which rounding could flip) [m]
_REACH_EDGE = 1e-9


def _prrr_frames_many(design: Any, pts: np.ndarray, branch: int) -> list[dict[str, np.ndarray] | None]:
    """Part frames (name -> 4×4 [m]) of the 3-PRRR at each point (n, 3) [m] on elbow ``branch``, from
    one numpy pass of :func:`hapticopt.design.prrr.kinematics.inverse_kinematics` and
    :func:`hapticopt.design.prrr.cad.part_frames_batch`; None where the point is not clearly
    reachable (out of reach, or within :data:`_REACH_EDGE` of its limit)."""
    ik = inverse_kinematics(params_np(design), pts, xp=np)
    clear = np.asarray(ik.reachable) & (np.asarray(ik.reach_margin) > _REACH_EDGE)
    posed = cad_prrr.part_frames_batch(design, np.asarray(ik.sliders), np.asarray(ik.theta)[:, branch], pts)
    return [{name: parts.transform(R[k], o[k]) for name, (R, o) in posed.items()} if clear[k] else None
            for k in range(len(pts))]


def _rotation(axis: np.ndarray, angle: float) -> np.ndarray:
    a = axis / np.linalg.norm(axis)
    K = np.array([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])
    return np.eye(3) + math.sin(angle) * K + (1 - math.cos(angle)) * K @ K


def joint_limits(model_or_design: Any, p=(0.0, 0.0, 0.0), *, step_deg: float = 2.0,
                 legs: tuple[int, ...] = (1,)) -> list[JointLimit]:
    """Collision-free range of each revolute joint between its two neighbouring parts, rotating
    the child about the joint axis from the pose at ``p`` (chain closure ignored: this is the
    limit the two parts impose on each other). 3-PRRR legs are identical by symmetry, so leg 1
    is swept by default."""
    model = model_or_design if isinstance(model_or_design, InterferenceModel) else prepare(model_or_design)
    design = model.design
    if design.device != "prrr":
        return _master_joint_limits(model, step_deg=step_deg)
    pose = cad_prrr.solve_pose(design, p)
    frames = cad_prrr.part_frames(design, pose)
    out = []
    for ax in cad_prrr.joint_axes(design, pose):
        if ax.kind != "hinge" or int(ax.name.split("_")[1]) not in legs:
            continue
        k = int(ax.name[1]) - 1  # r1 -> θ1 ...
        ref = float(pose.theta[int(ax.name.split("_")[1]) - 1, k]) if k < 2 else float(
            pose.theta[int(ax.name.split("_")[1]) - 1, 2])
        out.append(sweep_joint(model, frames, ax.parent, ax.child, ax.point, ax.direction, ref,
                               name=ax.name, step_deg=step_deg))
    return out


def sweep_joint(model: InterferenceModel, frames: dict[str, np.ndarray], parent: str, child: str,
                point: np.ndarray, direction: np.ndarray, reference: float, *, name: str,
                step_deg: float = 2.0) -> JointLimit:
    """Rotate ``child`` about the axis (point, direction) [m] relative to ``parent``; return the
    contiguous collision-free angle range around the reference angle."""
    parent_mesh = _moved(model.meshes[parent], frames[parent])
    lo_p, hi_p = _aabb(parent_mesh)
    step = math.radians(step_deg)
    n = int(round(math.pi / step))

    def hits(delta: float) -> bool:
        Rm = _rotation(direction, delta)
        T = np.eye(4)
        T[:3, :3] = Rm
        T[:3, 3] = point - Rm @ point
        m = _moved(model.meshes[child], T @ frames[child])
        lo_c, hi_c = _aabb(m)
        if np.any(lo_c > hi_p) or np.any(lo_p > hi_c):
            return False
        return (parent_mesh ^ m).volume() > NOISE_MM3

    hi = lo = None
    for k in range(1, n + 1):
        if hits(k * step):
            hi = (k - 1) * step
            break
    for k in range(1, n + 1):
        if hits(-k * step):
            lo = -(k - 1) * step
            break
    free = hi is None and lo is None
    hi = math.pi if hi is None else hi
    lo = -math.pi if lo is None else lo
    return JointLimit(joint=name, parent=parent, child=child, reference=reference, lo=reference + lo,
                      hi=reference + hi, free=free)


def _master_joint_limits(model: InterferenceModel, *, step_deg: float = 2.0, q=None) -> list[JointLimit]:
    """Collision-free ranges of θ2 (upper arm vs turret), θ3 (driver vs turret) and the elbow
    (forearm vs upper arm) from the pose ``q`` (home by default); see
    :func:`sweep_joint`."""
    design = model.design
    pose = cad_master.pose_from_q(design, cad_master.home_q(design) if q is None else q)
    frames = cad_master.part_frames(design, pose)
    out = []
    for ax in cad_master.joint_axes(design, pose):
        if ax.name in ("theta2", "theta3", "elbow"):
            out.append(sweep_joint(model, frames, ax.parent, ax.child, ax.point, ax.direction, ax.reference,
                                   name=ax.name, step_deg=step_deg))
    return out
