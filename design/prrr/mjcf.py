"""MJCF (MuJoCo XML) of the 3-PRRR, generated from the CAD part tables and mass properties.

Tree: world → ``base`` (fixed; base plate and rails) → per leg ``carriage_i`` (slide along z)
→ ``link1_i`` (hinge R1) → ``link2_i`` (hinge R2); the ``platform`` hangs from ``link2_1`` by
its hinge R3. Legs 2 and 3 close on the platform by two ``<equality connect>`` each, at two
points of their R3 axis (a revolute closure; one equation per leg is redundant, which MuJoCo's
soft constraints tolerate). The model is built at a pose: ``qpos0 = 0`` is that pose, closed
exactly. Inertias come from :mod:`design.mass_properties` (pass the CAD ones for export).

The firmware/SEA plant (issue 8) builds on this generator: it is a pure function of
(design, pose, mass properties, options) returning the XML text.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from xml.sax.saxutils import quoteattr

import numpy as np

from hapticopt.design.prrr import cad as cad_prrr
from hapticopt.design.mass_properties import MassProperties, PartMass
from hapticopt.design.parts import Kind, Role
from hapticopt.design.prrr.params import PrrrDesign
from hapticopt.design.units import GRAVITY


@dataclass(frozen=True, kw_only=True)
class MjcfOptions:
    """Simulation switches of the generated model (SI)."""

    gravity: bool = True
    contacts: bool = False  # contacts between non-neighbouring parts
    hold_sliders: bool = False  # equality constraints fixing every slider at its pose value
    timestep: float = 2e-4  # [s]
    integrator: str = "implicitfast"
    constraint_timeconst: float = 1e-3  # solref time constant of the closures [s] (≥ 2·timestep)
    constraint_dampratio: float = 1.0
    constraint_impedance: float = 0.9999  # solimp dmin = dmax (stiff closures)
    closure_span: float = 0.02  # distance of the two connect points along each R3 axis [m]
    slider_damping: float = 0.0  # [N·s/m]
    joint_damping: float = 0.0  # [N·m·s/rad]


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


def _v(x) -> str:
    return " ".join(f"{float(a):.12g}" for a in np.ravel(x))


def _rel(T_parent: np.ndarray, T_child: np.ndarray) -> np.ndarray:
    return np.linalg.inv(T_parent) @ T_child


def _pose_attrs(T: np.ndarray) -> str:
    return f'pos="{_v(T[:3, 3])}" quat="{_v(quat_of(T[:3, :3]))}"'


def _inertial(pm: PartMass) -> str:
    I = pm.inertia
    full = [I[0, 0], I[1, 1], I[2, 2], I[0, 1], I[0, 2], I[1, 2]]
    return f'<inertial pos="{_v(pm.com)}" mass="{pm.mass:.12g}" fullinertia="{_v(full)}"/>'


def _geoms(spec, contacts: bool, rgba: str) -> list[str]:
    out = []
    col = 'contype="1" conaffinity="1"' if contacts else 'contype="0" conaffinity="0"'
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
        out.append(f'<geom name="{spec.name}_g{k}" type="{typ}" size="{size}" pos="{_v(p.o)}" '
                   f'quat="{_v(quat_of(p.R))}" {col} rgba="{rgba}"/>')
    return out


def prrr_mjcf(design: PrrrDesign, *, p=(0.0, 0.0, 0.0), branch: int = cad_prrr.DEFAULT_BRANCH,
              mass_properties: MassProperties | None = None, options: MjcfOptions = MjcfOptions()) -> str:
    """MJCF text of the 3-PRRR posed at end-effector position ``p`` [m]."""
    specs = cad_prrr.part_specs(design)
    masses = mass_properties if mass_properties is not None else cad_prrr.mass_properties(design)
    bodies = masses.bodies()
    pose = cad_prrr.solve_pose(design, p, branch=branch)
    frames = cad_prrr.part_frames(design, pose)
    axes = {a.name: a for a in cad_prrr.joint_axes(design, pose)}
    o = options
    solref = f'solref="{o.constraint_timeconst:.6g} {o.constraint_dampratio:.6g}"'
    solimp = f'solimp="{o.constraint_impedance} {o.constraint_impedance} 0.001 0.5 2"'
    flags = []
    if not o.gravity:
        flags.append('gravity="disable"')
    if not o.contacts:
        flags.append('contact="disable"')
    lines = [f'<mujoco model={quoteattr(design.name)}>',
             '  <compiler angle="radian" inertiafromgeom="false" autolimits="true"/>',
             f'  <option timestep="{o.timestep:.6g}" integrator="{o.integrator}" gravity="0 0 {-GRAVITY:g}">'
             + (f'<flag {" ".join(flags)}/>' if flags else "") + '</option>',
             '  <worldbody>']
    ind = "    "
    # fixed base: plate and rails, one body welded to the world
    lines.append(f'{ind}<body name="base" pos="0 0 0">')
    lines.append(f'{ind}  {_inertial(bodies["base"])}')
    for name, spec in specs.items():
        if spec.body == "base":
            lines += [f"{ind}  {g}" for g in _geoms(spec, o.contacts, "0.6 0.6 0.65 1")]
    for i in cad_prrr.LEGS:
        c, l1, l2 = f"carriage_{i}", f"link1_{i}", f"link2_{i}"
        lines.append(f'{ind}  <body name="{c}" {_pose_attrs(_rel(frames["base"], frames[c]))}>')
        lines.append(f'{ind}    <joint name="slider_{i}" type="slide" axis="0 0 1" damping="{o.slider_damping}"/>')
        lines.append(f'{ind}    {_inertial(bodies[c])}')
        lines += [f"{ind}    {g}" for g in _geoms(specs[c], o.contacts, "0.2 0.4 0.8 1")]
        lines.append(f'{ind}    <body name="{l1}" {_pose_attrs(_rel(frames[c], frames[l1]))}>')
        lines.append(f'{ind}      <joint name="r1_{i}" type="hinge" axis="0 0 1" damping="{o.joint_damping}"/>')
        lines.append(f'{ind}      {_inertial(bodies[l1])}')
        lines += [f"{ind}      {g}" for g in _geoms(specs[l1], o.contacts, "0.8 0.5 0.2 1")]
        lines.append(f'{ind}      <body name="{l2}" {_pose_attrs(_rel(frames[l1], frames[l2]))}>')
        lines.append(f'{ind}        <joint name="r2_{i}" type="hinge" axis="0 0 1" damping="{o.joint_damping}"/>')
        lines.append(f'{ind}        {_inertial(bodies[l2])}')
        lines += [f"{ind}        {g}" for g in _geoms(specs[l2], o.contacts, "0.8 0.7 0.2 1")]
        if i == 1:
            Tp = frames["platform"]
            ax = axes["r3_1"]
            Tinv = np.linalg.inv(Tp)
            jp = Tinv[:3, :3] @ ax.point + Tinv[:3, 3]
            jd = Tinv[:3, :3] @ ax.direction
            lines.append(f'{ind}        <body name="platform" {_pose_attrs(_rel(frames[l2], Tp))}>')
            lines.append(f'{ind}          <joint name="r3_1" type="hinge" pos="{_v(jp)}" axis="{_v(jd)}" '
                         f'damping="{o.joint_damping}"/>')
            lines.append(f'{ind}          {_inertial(bodies["platform"])}')
            lines += [f"{ind}          {g}" for g in _geoms(specs["platform"], o.contacts, "0.3 0.8 0.3 1")]
            lines.append(f'{ind}          <site name="ee" pos="0 0 0" size="0.004"/>')
            lines.append(f'{ind}        </body>')
        lines += [f'{ind}      </body>', f'{ind}    </body>', f'{ind}  </body>']
    lines += [f'{ind}</body>', '  </worldbody>', '  <equality>']
    for i in cad_prrr.LEGS[1:]:
        ax = axes[f"r3_{i}"]
        T2inv = np.linalg.inv(frames[f"link2_{i}"])
        for s_ in (0.0, o.closure_span):
            anchor = T2inv[:3, :3] @ (ax.point + s_ * ax.direction) + T2inv[:3, 3]
            lines.append(f'    <connect name="close_{i}_{"a" if s_ == 0 else "b"}" body1="link2_{i}" body2="platform" '
                         f'anchor="{_v(anchor)}" {solref} {solimp}/>')
    if o.hold_sliders:
        for i in cad_prrr.LEGS:
            lines.append(f'    <joint name="hold_{i}" joint1="slider_{i}" polycoef="0 0 0 0 0" {solref} {solimp}/>')
    lines.append('  </equality>')
    if o.contacts:
        lines.append('  <contact>')
        for pair in sorted(tuple(sorted(pr)) for pr in cad_prrr.neighbours()):
            a, b = (specs[x].body for x in pair)
            if a != b:
                lines.append(f'    <exclude body1="{a}" body2="{b}"/>')
        lines.append('  </contact>')
    lines.append('</mujoco>')
    return "\n".join(lines) + "\n"


def closure_errors(model, data) -> dict[str, float]:
    """Distance [m] between the two sides of every connect constraint (from ``data.efc``-free
    geometry: anchors recomputed from body poses)."""
    import mujoco

    out = {}
    for k in range(model.neq):
        if model.eq_type[k] != mujoco.mjtEq.mjEQ_CONNECT:
            continue
        b1, b2 = model.eq_obj1id[k], model.eq_obj2id[k]
        a1 = model.eq_data[k, 0:3]
        a2 = model.eq_data[k, 3:6]
        p1 = data.xpos[b1] + data.xmat[b1].reshape(3, 3) @ a1
        p2 = data.xpos[b2] + data.xmat[b2].reshape(3, 3) @ a2
        out[mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_EQUALITY, k)] = float(np.linalg.norm(p1 - p2))
    return out
