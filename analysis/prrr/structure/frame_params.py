"""What the frame model reads from a design: :class:`FrameParams` [SI], of one design or of a batch.

:func:`frame_params_many` stacks the fields of many designs as numpy arrays with a leading design axis:
the link section and material, the layer pitch and platform lug of the CAD's layout
(:func:`hapticopt.design.prrr.cad.layout`), and the carriage's R1 bracket as the frame carries it
(:func:`_brackets_many`). :func:`frame_params_of` is its batch of one.
"""

from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from hapticopt.design import jax_config  # noqa: F401  (float64 before any jax array)
from hapticopt.analysis.prrr.structure.frame_beam import Section, _cross, bond_stiffness
from hapticopt.design.errors import InvalidDesign
from hapticopt.design.prrr import layout as prrr_layout
from hapticopt.design.prrr.cad import carriage_bracket
from hapticopt.design.prrr.kinematics import PrrrParams

#: :func:`frame_params_many` takes the brackets in their array form from this many designs on (per design
#: below, where the arrays' fixed cost is larger than the per-design formula's).
BRACKET_ARRAYS_FROM = 8


class FrameParams(NamedTuple):
    """Everything the frame model reads from a design [SI] (a jax pytree, batchable)."""

    kin: PrrrParams
    r_p: jax.Array  # rail radius [m]
    theta_1p: jax.Array  # rail angle from u_i about z [rad] (seed 002 θ_1p)
    section: Section
    spring: jax.Array  # SEA spring k [N/m] (used with ``FrameOptions(sea=True)``)
    joint_zone: jax.Array  # radius of the rigid joint zone (the joint boss) [m]
    pin_diameter: jax.Array  # pin (bore) diameter [m] (``FrameOptions(pins=True)``)
    layer: jax.Array  # layer pitch along the joint axis, link thickness + clearance [m]
    lug_offset: jax.Array  # platform lug layer above the kinematic R3 point along w, s_lug − r4 [m]
    stem_radius: jax.Array  # platform stem radius; the platform arms are stem_diameter wide [m]
    bracket_points: jax.Array  # (3, 3) C, J, E of the R1 bracket, carriage frame (x = u', y = t', z) [m] (:func:`_brackets_many`)
    root_zref: jax.Array  # (3,) thickness direction (±w) of the bracket's root beam, carriage frame
    root_section: jax.Array  # (2,) root beam width (along the arm e_l) and thickness (along w) [m]
    bracket_bonds: jax.Array  # (2, 6, 6) root-on-block and arm-on-root bond stiffness, carriage frame, [u; θ] [SI]


def frame_params_of(design, xp=jnp) -> FrameParams:
    """Frame-model parameters of one :class:`hapticopt.design.prrr.params.PrrrDesign`: row 0 of
    :func:`frame_params_many` as ``xp`` arrays (``xp=np``: numpy)."""
    return jax.tree.map(lambda x: xp.asarray(x[0]), frame_params_many([design]))


def frame_params_many(designs) -> FrameParams:
    """The frame-model parameters of many designs stacked along a leading batch axis (numpy): the scalar
    fields and the carriage's brackets (:func:`_brackets_many`) as arrays over the batch."""
    g = [d.geometry for d in designs]
    s = [d.structure for d in designs]

    def col(objs, name):
        return np.array([float(getattr(o, name)) for o in objs])

    kin = PrrrParams(*(col(g, f) for f in ("beta", "d1", "d2", "d3", "d4", "r4", "b5", "stroke")))
    sec = Section(*(col(s, f) for f in ("link_width", "link_thickness", "youngs_modulus", "poisson_ratio")))
    layer = sec.thickness + col(s, "clearance")  # hapticopt.design.prrr.cad.layout: s_link2 = T + g
    s_lug = np.maximum(kin.r4, 2.0 * layer)  # hapticopt.design.prrr.cad.layout: s_lug = max(r4, 2T + 2g)
    br = _brackets_many(designs, sec)
    return FrameParams(kin=kin, r_p=col(g, "r_p"), theta_1p=col(g, "theta_1p"), section=sec,
                       spring=np.array([float(d.actuator.spring) for d in designs]),
                       joint_zone=0.5 * col(s, "boss_diameter"), pin_diameter=col(s, "bore_diameter"), layer=layer,
                       lug_offset=s_lug - kin.r4, stem_radius=0.5 * col(s, "stem_diameter"), **br)


def _brackets_many(designs, sec: Section) -> dict[str, np.ndarray]:
    """:func:`bracket_frame` of many designs (leading batch axis): the brackets over the batch
    (:func:`hapticopt.design.prrr.layout.brackets_many`, the array form of
    :func:`hapticopt.design.prrr.cad.carriage_bracket`, from :data:`BRACKET_ARRAYS_FROM` designs on; its
    ``rest``, the designs no face carries or near a rule's threshold or branch point, and the designs of a
    smaller batch by the per-design function, as :func:`bracket_frame`), the bonds' :func:`bond_stiffness`
    over the batch (:func:`_bond_stiffness_many`)."""
    if len(designs) < BRACKET_ARRAYS_FROM:
        each = [_bracket_fields(_bracket_of(d)) for d in designs]
        b = {k: np.array([f[k] for f in each], dtype=float) for k in each[0]}
    else:
        b, rest = prrr_layout.brackets_many(designs)
        for i in rest:
            for k, v in _bracket_fields(_bracket_of(designs[i])).items():
                b[k][i] = v
    Ac, e_l, e_f, arm_length = b["clevis"], b["root_axes"][:, :, 0], b["root_axes"][:, :, 1], b["arm_length"]
    contact = b["contact"]
    # cad.Bracket.root_joint and .arm_end over the batch
    root_joint = contact - np.sum((contact - Ac) * e_f, axis=-1)[:, None] * e_f
    pts = np.stack([contact, root_joint, Ac + arm_length[:, None] * e_l], axis=1)
    zref, size = b["root_axes"][:, :, 2], b["root_size"][:, [0, 2]]
    N, n_p, w = b["normal"], b["n_p"], b["axis"]
    lc, wc = b["contact_size"][:, 0], b["contact_size"][:, 1]
    E_, nu = sec.youngs_modulus, sec.poisson_ratio
    k_root = bond_stiffness(lc * wc, (lc * wc**3 / 12.0, wc * lc**3 / 12.0), lc * wc * (lc**2 + wc**2) / 12.0,
                                  (N, e_l, n_p), E_, nu)
    W, T = sec.width, sec.thickness
    e_m = _cross(w, e_l, np)
    k_arm = bond_stiffness(W * T, (W * T**3 / 12.0, T * W**3 / 12.0), W * T * (W**2 + T**2) / 12.0,
                                 (e_l, e_m, w), E_, nu)
    return {"bracket_points": pts, "root_zref": np.ascontiguousarray(zref), "root_section": np.ascontiguousarray(size),
            "bracket_bonds": np.stack([k_root, k_arm], axis=1)}


def _bracket_fields(b) -> dict:
    """The fields of :func:`hapticopt.design.prrr.layout.brackets_many` of one :class:`cad.Bracket`."""
    return dict(clevis=b.clevis, axis=b.axis, normal=b.normal, e_l=b.e_l, arm_length=b.arm_length,
                root_axes=b.root_axes, root_size=b.root_size, contact=b.contact_centre, n_p=b.contact_axes[:, 1],
                contact_size=b.contact_size)


def _bracket_of(design):
    """The carriage's bracket (:func:`hapticopt.design.prrr.cad.carriage_bracket`, the CAD's one formula),
    unchecked where the CAD refuses it (such a design still gets a frame, as its links do)."""
    try:
        return carriage_bracket(design)
    except InvalidDesign:
        return carriage_bracket(design, checked=False)
