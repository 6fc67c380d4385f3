"""Solid FEA of the CAD geometry of the 3-PRRR (issue 3's build123d solids) with bonded pins.

Geometry: the posed OpenCASCADE solids of :mod:`hapticopt.design.prrr.cad` (the same solids as the STEP
export) — ``carriage_i``, ``link1_i``, ``link2_i`` and the ``platform``; base and rails are left
out (the sliders are locked: the carriages are clamped on their rail slots).

Joints (**bonded pins**, the documented choice): the CAD parts are separate solids with bores
of ``bore_diameter`` and axial clearance gaps ``clearance`` between the layers of a joint. A pin
solid — a cylinder of the bore radius on the kinematic joint axis, spanning the axial extent of
both parts' bores (and the gap between them) — is added per joint, and gmsh's OpenCASCADE
``fragment`` of parts and pins makes the mesh conformal: the pin is bonded to both parts (it
transmits all six force/moment components, including the moment about the axis; compare with
``FrameOptions(joints=Joints.BONDED)``). Axial layering (from the plane Π through R1, T = link
thickness, g = clearance; see ``design/prrr/cad.py``): R1 pin spans [−3T/2−g, T/2] (clevis +
link1), R2 [−T/2, 3T/2+g] (link1 + link2), R3 [T/2+g, s_lug+T/2] (link2 boss with its riser +
platform lug).

Named physical groups: volumes ``carriage_i``, ``link1_i``, ``link2_i``, ``platform``,
``pin_r{1,2,3}_i``; surfaces ``support_leg{i}`` (the four faces of carriage i's rail slot,
clamped). Load: a rigid region of the platform is tied exactly to six master DOFs (a rigid-body
multi-point constraint, :func:`hapticopt.analysis.fem.solid.solve_with_rigid_region`) that carry the unit load
cases, forces at the load point P + Δz e_z. (An earlier version spread min-norm nodal forces over
the region and fitted its rigid motion: those point loads made the stiffness drift with the mesh
instead of converging, docs/structure.md.) ``rigid="stem"`` (default, comparable with the frame model, whose handle P → P + Δz e_z
and hub at P are rigid): the stem (the platform's material within the stem radius of the z axis,
where the three arms meet) and the handle ball. ``rigid="ball"``: the ball only, so the 10 mm
stem (handle post) bends too — the physical handle, reported separately (docs/structure.md).
"""

from __future__ import annotations

import functools
import time
from dataclasses import dataclass
from typing import Any

import numpy as np

from hapticopt.design import cad_import
from hapticopt.analysis.fem import hinge as fea_cad_hinge
from hapticopt.analysis.fem import solid as fea
from hapticopt.analysis.status import Status
import tempfile
from pathlib import Path
from hapticopt.design import parts as _parts
from hapticopt.analysis.prrr.structure import frame_model as fm
from hapticopt.analysis.fem.stress import p2_nodal_values
from hapticopt.design.prrr import cad as cad_prrr

#: mesh size [m] of refinement level k: link thickness · 1.5 / √2^k
LEVEL0_FACTOR = 1.5
#: level used by ``hapticopt evaluate --fidelity fine``: within 2 % of the extrapolated value (docs/structure.md)
DEFAULT_LEVEL = 2


def cad_level_size(design, level: int) -> float:
    """Mesh size [m] of refinement ``level`` of the CAD solid."""
    return LEVEL0_FACTOR * float(design.structure.link_thickness) / fea.REFINEMENT_RATIO**level


def _pins(design, pose, radius: float | None = None) -> list[dict[str, Any]]:
    """Pin cylinders [m]: name, start point, axis vector (length = span), radius (default the bore's)."""

    L = cad_prrr.layout(design)
    T, g, r4 = L.T, L.g, design.geometry.r4
    spans = {"r1": (-1.5 * T - g, 0.5 * T), "r2": (-0.5 * T, 1.5 * T + g),
             "r3": (0.5 * T + g - r4, L.s_lug + 0.5 * T - r4)}
    out = []
    for ax in cad_prrr.joint_axes(design, pose):
        kind = ax.name.split("_")[0]
        if kind not in spans:
            continue
        lo, hi = spans[kind]
        w = ax.direction / np.linalg.norm(ax.direction)
        out.append(dict(name=f"pin_{ax.name}", start=ax.point + lo * w, axis=(hi - lo) * w,
                        radius=L.r_bore if radius is None else radius))
    return out


def cad_mesh(design, *, size: float, p=(0.0, 0.0, 0.0), branch: int | None = None,
             pin_radius: float | None = None) -> tuple[fea.TetMesh, dict]:
    """Tetrahedral mesh [m] of the posed CAD parts plus bonded pins; returns (mesh, info).

    ``pin_radius`` [m] (diagnostic): None = the bore radius (the physical pin); the boss radius
    fills each joint's bosses and gaps solid (a "rigid joint zone" like the frame model's).
    """

    cad_import.build123d()  # imported without scikit-learn (0.55 s)
    from build123d import export_brep


    branch = cad_prrr.DEFAULT_BRANCH if branch is None else branch
    pose = cad_prrr.solve_pose(design, p, branch=branch)
    # the load path only: fixed parts (base, rails, screws, motors) and the SEA spring housings (beside
    # the carriage, not between the rail slot and R1) are left out
    specs = {k: v for k, v in cad_prrr.part_specs(design).items()
             if not (k == "base" or k.startswith(("rail_", "screw_", "motor_", "housing_")))}

    solids = _parts.posed(_parts.build_all(specs), cad_prrr.part_frames(design, pose))
    L = cad_prrr.layout(design)
    gmsh = fea.gmsh_start("prrr_cad")
    tags: dict[str, list[int]] = {}
    with tempfile.TemporaryDirectory() as tmp:
        for name, solid in solids.items():
            path = Path(tmp) / f"{name}.brep"
            export_brep(solid, str(path))
            dimtags = gmsh.model.occ.importShapes(str(path))
            tags[name] = [t for d, t in dimtags if d == 3]
    for pin in _pins(design, pose, pin_radius):
        s, a = pin["start"] * 1e3, pin["axis"] * 1e3
        tags[pin["name"]] = [gmsh.model.occ.addCylinder(*s, *a, pin["radius"] * 1e3)]
    objects = [(3, t) for v in tags.values() for t in v]
    _, out_map = gmsh.model.occ.fragment(objects, [])
    gmsh.model.occ.synchronize()
    # fragment output: per input volume, the volumes it became (pins bridging gaps stay whole)
    groups_3d: dict[str, list[int]] = {}
    k = 0
    for name, vols in tags.items():
        new = []
        for _ in vols:
            new += [t for d, t in out_map[k] if d == 3]
            k += 1
        groups_3d[name] = sorted(set(new))
    # the pin volume inside a bore is shared with no part (the bore is a hole), so volumes are
    # disjoint; a volume claimed by two inputs would mean overlapping parts
    owners: dict[int, str] = {}
    for name, vols in groups_3d.items():
        for t in vols:
            if t in owners and not (pin_radius is not None and name.startswith("pin_")):
                gmsh.finalize()
                raise RuntimeError(f"parts {owners[t]} and {name} overlap (volume {t})")
            owners.setdefault(t, name)
    # supports: the rail-slot faces of each carriage (carriage frame: x = u, y = t, z = e_z)
    groups_2d: dict[str, list[int]] = {}
    frames = cad_prrr.part_frames(design, pose)
    for i in cad_prrr.LEGS:
        Tm = frames[f"carriage_{i}"]
        faces = []
        for vol in groups_3d[f"carriage_{i}"]:
            for d, f in gmsh.model.getBoundary([(3, vol)], oriented=False):
                com = (np.asarray(gmsh.model.occ.getCenterOfMass(2, f)) * 1e-3 - Tm[:3, 3]) @ Tm[:3, :3]
                on_slot = abs(max(abs(com[0] - design.geometry.r_p), abs(com[1])) - L.slot) < 1e-6
                mid_height = L.block_z[0] + 1e-6 < com[2] < L.block_z[1] - 1e-6  # not the block's end faces
                if on_slot and mid_height:
                    faces.append(f)
        if len(faces) < 4:
            gmsh.finalize()
            raise RuntimeError(f"found {len(faces)} rail-slot faces on carriage_{i} (expected 4)")
        groups_2d[f"support_leg{i}"] = faces
    vols = sorted(owners)
    mesh = fea.gmsh_mesh(gmsh, size * 1e3, groups_2d, vols, groups_3d=groups_3d)
    centre = np.asarray(pose.p, dtype=float) + L.ball_z * np.array([0.0, 0.0, 1.0])
    info = dict(pose=pose, ball_centre=centre, ball_radius=0.5 * float(design.end_effector.handle_diameter),
                stem_radius=0.5 * float(design.structure.stem_diameter),
                n_pins=sum(1 for n in groups_3d if n.startswith("pin_")), branch=branch)
    return mesh, info


@dataclass(frozen=True, kw_only=True)
class CadFeaResult:
    """Stiffness of the CAD solid with bonded pins at the load point [SI]."""

    compliance_load: np.ndarray  # (3, 3) [m/N] at P + Δz e_z (columns: unit forces x, y, z)
    stiffness_load: np.ndarray  # (3,) [N/m] k_i = 1 / C_ii
    load_height: float
    size: float
    n_dofs: int
    iterations: tuple[int, ...]
    wall_s: float
    timings_s: dict[str, float]
    branch: int
    status: Status = Status.OK
    message: str = ""
    mesh: fea.TetMesh | None = None
    displacement: np.ndarray | None = None  # (3, n_nodes) [m] for a unit x force at the load point
    #: (3, n_edges) [m] the same field at the edge midpoints (P2 DOFs; edges of skfem's
    #: MeshTet(mesh.points, mesh.tets)), for the stress (hapticopt.analysis.fem.stress)
    displacement_edges: np.ndarray | None = None


def cad_fea(design, *, level: int = 0, size: float | None = None, p=(0.0, 0.0, 0.0), branch: int | None = None,
            load_height: float | None = None, tol: float = 1e-7, keep_fields: bool = False,
            pin_radius: float | None = None, rigid: str = "stem", joints: str = "bonded",
            release_side: str = "frame") -> CadFeaResult:
    """Stiffness [N/m] of the posed CAD parts, for forces Δz above p (3 load cases).

    ``joints``: "bonded" (pins fused into both parts) or "released" (every revolute joint a
    frictionless bilateral cylindrical interface on one bore, :mod:`hapticopt.analysis.fem.hinge`;
    ``release_side`` "frame" or "swapped" picks the bore).
    """

    if joints not in ("bonded", "released"):
        raise ValueError(f"joints = {joints!r}: allowed 'bonded' or 'released'")
    if joints == "released" and pin_radius is not None:
        raise ValueError("pin_radius applies to bonded joints only (a released pin must be the bore's)")
    t0 = time.perf_counter()
    h = fm.LOAD_HEIGHT if load_height is None else float(load_height)
    size = cad_level_size(design, level) if size is None else float(size)
    p = np.asarray(p, dtype=float)
    mesh, info = cad_mesh(design, size=size, p=p, branch=branch, pin_radius=pin_radius)
    split = None
    if joints == "released":
        split = fea_cad_hinge.split_hinges(mesh, cad_hinges(design, info["pose"], side=release_side))
        mesh = split.mesh
    t_mesh = time.perf_counter() - t0
    hub_nodes = mesh.node_sets["platform"]
    H = np.concatenate([np.eye(3), -np.array([[0, -h, 0], [h, 0, 0], [0, 0, 0]])], axis=1)  # u_L = H [u_P; θ]
    is_platform = np.zeros(mesh.points.shape[1], dtype=bool)
    is_platform[hub_nodes] = True

    def region(basis):
        x = basis.doflocs
        in_ball = np.linalg.norm(x - info["ball_centre"][:, None], axis=0) <= info["ball_radius"] * (1 + 1e-9)
        if rigid == "stem":
            on_platform = np.zeros(basis.N, dtype=bool)
            n_vert = mesh.points.shape[1]
            e = basis.mesh.edges
            for c in fea.component_dofs(basis):
                on_platform[c[:n_vert]] = is_platform
                # edge DOFs: on the platform when both end vertices are
                on_platform[c[n_vert:]] = is_platform[e[0]] & is_platform[e[1]]
            radial = np.hypot(x[0] - p[0], x[1] - p[1])
            in_ball |= on_platform & (radial <= info["stem_radius"] * (1 + 1e-6))
        elif rigid != "ball":
            raise ValueError(f"rigid = {rigid!r}: allowed 'stem' or 'ball'")
        # whole DOF locations only (all three components), so the reduced system keeps node blocks
        comps = fea.component_dofs(basis)
        whole = in_ball[comps[0]] & in_ball[comps[1]] & in_ball[comps[2]]
        out = np.zeros(basis.N, dtype=bool)
        for c in comps:
            out[c] = whole
        return out

    names = [n for n in mesh.node_sets if n.startswith("support")]
    s = design.structure
    if split is None:
        sol = fea.solve_with_rigid_region(mesh, youngs_modulus=s.youngs_modulus, poisson_ratio=s.poisson_ratio,
                                          fixed=names, region=region, centre=p, wrenches=H.T, tol=tol)
    else:
        sol = fea_cad_hinge.solve_released(split, youngs_modulus=s.youngs_modulus, poisson_ratio=s.poisson_ratio,
                                           fixed=names, region=region, centre=p, wrenches=H.T, tol=tol)
    C = H @ sol.master  # (3, 3) load-point displacement per unit force at the load point
    C = 0.5 * (C + C.T)
    k = 1.0 / np.diagonal(C)
    disp = disp_edges = None
    if keep_fields:
        disp, disp_edges = p2_nodal_values(sol.basis, sol.displacements[:, 0])
    status, message = Status.OK, ""
    if not np.all(np.isfinite(k)) or np.any(k <= 0):
        status, message = Status.SINGULAR, "CAD FEA stiffness not positive (insufficient supports?)"
    return CadFeaResult(compliance_load=C, stiffness_load=k, load_height=h, size=size, n_dofs=sol.n_dofs,
                        iterations=sol.iterations, wall_s=time.perf_counter() - t0,
                        timings_s={"mesh": t_mesh, **sol.timings_s}, branch=info["branch"], status=status,
                        message=message, mesh=mesh if keep_fields else None, displacement=disp,
                        displacement_edges=disp_edges)


@functools.lru_cache(maxsize=2)
def fine_fea(design) -> CadFeaResult:
    """The ``fine`` level's FEA of ``design`` (level :data:`DEFAULT_LEVEL`, fields kept), made once per
    process for the evaluators that read it (structural stiffness and strength); an exception is not
    cached."""
    return cad_fea(design, level=DEFAULT_LEVEL, keep_fields=True)


#: released part per joint kind: the frame model's hinge at the pin's link-side end (frame_model.py)
RELEASED_PART = {"frame": {"r1": "link1", "r2": "link2", "r3": "link2"},
                 "swapped": {"r1": "carriage", "r2": "link1", "r3": "platform"}}


def cad_hinges(design, pose, *, side: str = "frame") -> list[fea_cad_hinge.Hinge]:
    """The nine released joints of the posed 3-PRRR CAD (pins of :func:`_pins`)."""
    if side not in RELEASED_PART:
        raise ValueError(f"side = {side!r}: allowed {sorted(RELEASED_PART)}")
    out = []
    for pin in _pins(design, pose):
        kind, leg = pin["name"].split("_")[1:]
        axis = pin["axis"] / np.linalg.norm(pin["axis"])
        part = RELEASED_PART[side][kind]
        part = part if part == "platform" else f"{part}_{leg}"
        out.append(fea_cad_hinge.Hinge(name=f"{kind}_{leg}", pin=pin["name"], part=part,
                         point=np.asarray(pin["start"], dtype=float), axis=axis, radius=float(pin["radius"])))
    return out
