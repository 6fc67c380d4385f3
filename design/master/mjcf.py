"""MJCF (MuJoCo XML) of the surgical master: turret, upper arm, θ3 driver link, parallelogram
coupler (closed by an equality ``connect``), forearm, handle, counterweights, joint motors.

Frames and joint signs follow :mod:`hapticopt.design.master.kinematics` (z up; θ2, θ3 about the link
frames' y axis). Joint vector of the compiled model (qpos order):
``[theta1, theta2, forearm_rel, theta3, coupler_rel]`` with forearm_rel = θ3 − θ2 and
coupler_rel = θ2 − θ3 (the parallelogram closure). :data:`REDUCTION` maps the reduced joint
velocities (θ̇1, θ̇2, θ̇3) to the full ones: M_red = Sᵀ M S, G_red = Sᵀ qfrc_bias.

Mass properties: :func:`hapticopt.analysis.master.dynamics.analytic_mass_properties` unless a list of
:class:`hapticopt.analysis.master.dynamics.BodyMass` is given (e.g. from the CAD). Every part becomes a
joint-less child body with an explicit ``<inertial>`` (so visual geoms add no mass). MuJoCo
rejects massless moving bodies: masses below 1e-13 kg are floored to 1e-13 kg (gravity torque
error < 1e-12 N·m). Joint ranges: θ1 and θ3 from the design's limits (``range``, ``limited``),
the parallelogram angle φ = 90° − θ2 + θ3 on the relative joint ``forearm_rel`` = θ3 − θ2 as
φ − 90°; actuators are torque motors with the design's continuous torque limit.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from hapticopt.design.master.params import MasterDesign
from hapticopt.design.master.mass import analytic_mass_properties
from hapticopt.design.units import GRAVITY

#: reduced → full joint velocities, rows [theta1, theta2, forearm_rel, theta3, coupler_rel]
REDUCTION = np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, -1.0, 1.0], [0.0, 0.0, 1.0], [0.0, 1.0, -1.0]])
ACTUATED = ("theta1", "theta2", "theta3")
_MIN_MASS = 1e-13  # [kg] MuJoCo needs mass on every moving body; 1e-13 kg × g × 0.5 m ≈ 5e-13 N·m of gravity torque
_MIN_INERTIA = 1e-12


def full_qpos(q: Any) -> np.ndarray:
    """Compiled-model qpos (5,) for the reduced joint angles q = (θ1, θ2, θ3) [rad]."""
    t1, t2, t3 = (float(x) for x in q)
    return np.array([t1, t2, t3 - t2, t3, t2 - t3])


def _quat_mul(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    w1, x1, y1, z1 = a
    w2, x2, y2, z2 = b
    return np.array([w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2, w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2,
                     w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2, w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2])


def _quat_y(angle: float) -> np.ndarray:
    return np.array([math.cos(angle / 2), 0.0, math.sin(angle / 2), 0.0])


_Q_BASE = np.array([0.0, 1.0, 0.0, 0.0])  # 180° about x: link frame (x = e_ρ, y = (0, −1, 0), z = −e_z)


def _v(x: Any) -> str:
    return " ".join(f"{float(v):.12g}" for v in np.ravel(x))


def _part(body: Any, indent: str) -> str:
    m = max(float(body.mass), _MIN_MASS)
    inertia = np.asarray(body.inertia, dtype=float) + np.eye(3) * _MIN_INERTIA
    full = [inertia[0, 0], inertia[1, 1], inertia[2, 2], inertia[0, 1], inertia[0, 2], inertia[1, 2]]
    return (f'{indent}<body name="{body.name}_mass" pos="{_v(body.com)}">\n'
            f'{indent}  <inertial pos="0 0 0" mass="{m:.12g}" fullinertia="{_v(full)}"/>\n'
            f'{indent}  <geom type="sphere" size="0.006" contype="0" conaffinity="0" group="1" rgba="0.8 0.3 0.2 1"/>\n'
            f'{indent}</body>\n')


def master_mjcf(design: MasterDesign, mass_properties: Any = None, *, gravity: bool = True,
                timestep: float = 5e-4) -> str:
    """MJCF text of ``design``'s master arm (SI units, radians)."""
    bodies = analytic_mass_properties(design) if mass_properties is None else tuple(mass_properties)
    by_frame: dict[str, list[Any]] = {}
    for b in bodies:
        by_frame.setdefault(b.frame, []).append(b)
    g, a = design.geometry, design.actuators
    L5, L4, d, h = g.upper_arm, g.forearm, g.driver_link, g.shoulder_height

    def parts(frame: str, indent: str) -> str:
        return "".join(_part(b, indent) for b in by_frame.get(frame, []))

    j = design.joints
    ranges = {"theta1": (j.theta1_min, j.theta1_max), "theta3": (j.theta3_min, j.theta3_max),
              "forearm_rel": (j.parallelogram_min - math.pi / 2, j.parallelogram_max - math.pi / 2)}

    def joint(name: str, actuated: bool) -> str:
        extra = (f' armature="{a.rotor_inertia:.12g}" damping="{a.viscous:.12g}" frictionloss="{a.coulomb:.12g}"'
                 if actuated else "")
        if name in ranges:
            extra += f' range="{ranges[name][0]:.12g} {ranges[name][1]:.12g}"'
        axis = "0 0 1" if name == "theta1" else "0 1 0"
        return f'<joint name="{name}" type="hinge" axis="{axis}"{extra}/>'

    tiny = f'<inertial pos="0 0 0" mass="{_MIN_MASS}" diaginertia="{_MIN_INERTIA} {_MIN_INERTIA} {_MIN_INERTIA}"/>'
    q_upper = _Q_BASE
    q_driver = _quat_mul(_Q_BASE, _quat_y(math.pi / 2))
    q_rel = _quat_y(-math.pi / 2)
    grav = f"0 0 {-GRAVITY}" if gravity else "0 0 0"
    lim = a.torque_limit
    rod = 'type="capsule" size="0.005" contype="0" conaffinity="0" group="1"'
    xml = f"""<mujoco model="{design.name}">
  <compiler angle="radian" autolimits="true"/>
  <option timestep="{timestep:.12g}" gravity="{grav}" integrator="implicitfast">
    <flag contact="disable"/>
  </option>
  <worldbody>
    <body name="turret" pos="0 0 0">
      {joint("theta1", True)}
      {tiny}
      <geom type="cylinder" size="0.04 {h / 2:.12g}" pos="0 0 {h / 2:.12g}" contype="0" conaffinity="0" group="1"/>
{parts("turret", "      ")}      <body name="upper_arm" pos="0 0 {h:.12g}" quat="{_v(q_upper)}">
        {joint("theta2", True)}
        {tiny}
        <geom {rod} fromto="0 0 0 {L5:.12g} 0 0"/>
{parts("upper_arm", "        ")}        <body name="forearm" pos="{L5:.12g} 0 0" quat="{_v(q_rel)}">
          {joint("forearm_rel", False)}
          {tiny}
          <geom {rod} fromto="{-d:.12g} 0 0 {L4:.12g} 0 0"/>
{parts("forearm", "          ")}          <site name="forearm_rear" pos="{-d:.12g} 0 0"/>
          <body name="handle" pos="{L4:.12g} 0 0">
            {tiny}
            <site name="handle" pos="0 0 0" size="0.008"/>
{parts("handle", "            ")}          </body>
        </body>
      </body>
      <body name="driver_link" pos="0 0 {h:.12g}" quat="{_v(q_driver)}">
        {joint("theta3", True)}
        {tiny}
        <geom {rod} fromto="0 0 0 {d:.12g} 0 0"/>
{parts("driver_link", "        ")}        <body name="coupler" pos="{d:.12g} 0 0" quat="{_v(q_rel)}">
          {joint("coupler_rel", False)}
          {tiny}
          <geom {rod} fromto="0 0 0 {L5:.12g} 0 0"/>
{parts("coupler", "          ")}        </body>
      </body>
    </body>
  </worldbody>
  <equality>
    <connect name="parallelogram" body1="coupler" body2="forearm" anchor="{L5:.12g} 0 0" solref="0.002 1"/>
  </equality>
  <actuator>
    <motor name="theta1" joint="theta1" ctrlrange="{-lim:.12g} {lim:.12g}"/>
    <motor name="theta2" joint="theta2" ctrlrange="{-lim:.12g} {lim:.12g}"/>
    <motor name="theta3" joint="theta3" ctrlrange="{-lim:.12g} {lim:.12g}"/>
  </actuator>
</mujoco>
"""
    return xml
