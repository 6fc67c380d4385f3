"""Surgical-master CAD: closed-form volumes, counterweight masses, CAD axes = kinematic axes."""

import math

import numpy as np
import pytest

from hapticopt.design import export as design_export
from hapticopt.design.master import cad as cad_master
from hapticopt.design import io, mass_properties as mp
from hapticopt.design.errors import InvalidDesign, InvalidInput


@pytest.fixture(scope="module")
def paper():
    return io.load_preset("master-paper")


@pytest.fixture(scope="module")
def solids(paper):
    return cad_master.build_parts(paper)


def test_parts_are_single_valid_solids(solids):
    assert set(solids) == {"base", "turret", "upper_arm", "counterweight_upper", "driver_link",
                           "counterweight_forearm", "coupler", "forearm", "handle", "ballast_upper_arm",
                           "ballast_driver_link", "ballast_coupler", "ballast_forearm"}
    for s in solids.values():
        assert s.is_valid and len(s.solids()) == 1


def test_coupler_volume_is_the_closed_form(paper, solids):
    s = paper.structure
    R, r, W, T = s.boss_diameter / 2, s.bore_diameter / 2, s.light_link_width, s.light_link_thickness
    h = W / 2
    cap = h * math.sqrt(R * R - h * h) + R * R * math.asin(h / R)  # ∫_{-h}^{h} sqrt(R² − y²) dy
    area = paper.geometry.upper_arm * W + 2 * (math.pi * R * R - cap) - 2 * math.pi * r * r
    assert solids["coupler"].volume * 1e-9 == pytest.approx(area * T, rel=1e-6)


def test_counterweights_have_the_design_masses(paper):
    # seed 003: m2 (upper) and m4 (forearm) are design values; the CAD sizes the discs from them
    cad = design_export.mass_properties(paper, method=mp.Method.CAD)
    assert cad.parts["counterweight_upper"].mass == pytest.approx(paper.counterweights.upper_mass, rel=1e-6)
    assert cad.parts["counterweight_forearm"].mass == pytest.approx(paper.counterweights.forearm_mass, rel=1e-6)
    # and sit at r2x / r4z along their links (link frames: x along the link)
    assert cad.parts["counterweight_upper"].com[0] == pytest.approx(-paper.counterweights.upper_distance, abs=1e-9)
    assert cad.parts["counterweight_forearm"].com[0] == pytest.approx(paper.counterweights.forearm_distance, abs=1e-9)


def test_analytic_matches_cad(paper):
    ana, cad = design_export.mass_properties(paper), design_export.mass_properties(paper, method=mp.Method.CAD)
    for name, c in cad.parts.items():
        a = ana.parts[name]
        assert a.mass == pytest.approx(c.mass, rel=0.02), name
        assert np.linalg.norm(a.inertia - c.inertia) <= 0.05 * np.linalg.norm(c.inertia), name


def _bore_lines(solid, radius_mm):
    from build123d import GeomType
    from OCP.BRepAdaptor import BRepAdaptor_Surface

    out = []
    for f in solid.faces():
        if f.geom_type == GeomType.CYLINDER:
            cyl = BRepAdaptor_Surface(f.wrapped).Cylinder()
            if abs(cyl.Radius() - radius_mm) < 1e-6:
                loc, d = cyl.Axis().Location(), cyl.Axis().Direction()
                out.append((np.array([loc.X(), loc.Y(), loc.Z()]), np.array([d.X(), d.Y(), d.Z()])))
    return out


@pytest.mark.parametrize("q", [(0.0, 0.0, 0.0), (0.4, 0.5, -0.3)])
def test_cad_joint_axes_are_the_kinematic_axes(paper, solids, q):
    pose = cad_master.pose_from_q(paper, q)
    placed = cad_master.posed(solids, cad_master.part_frames(paper, pose))
    r = paper.structure.bore_diameter / 2 * 1e3
    for ax in cad_master.joint_axes(paper, pose):
        if ax.name == "theta1":  # the turret drum is centred on the θ1 axis
            c = np.array(tuple(placed["turret"].faces().sort_by()[0].center()))
            assert np.linalg.norm(c[:2]) < 1e-6
            continue
        p = ax.point * 1e3
        for part in (ax.parent, ax.child):
            ok = [1 for o, d in _bore_lines(placed[part], r)
                  if abs(abs(d @ ax.direction) - 1) < 1e-9 and np.linalg.norm((p - o) - ((p - o) @ d) * d) < 1e-6]
            assert ok, f"{ax.name}: no bore of {part} on the kinematic axis"


def test_home_pose_and_workspace_poses_are_interference_free(paper):
    from hapticopt.analysis import interference as itf

    model = itf.prepare(paper)
    for q in [(0.0, 0.0, 0.0), (0.5, 0.3, -0.5), (0.0, 1.2, 0.2)]:
        frames = cad_master.part_frames(paper, cad_master.pose_from_q(paper, q))
        assert itf.check_frames(model, frames) == ()
    res = itf.check_pose(model, cad_master.home_point(paper))
    assert res.ok


def test_pose_errors(paper):
    with pytest.raises(InvalidInput, match="not reachable"):
        cad_master.solve_pose(paper, (2.0, 0.0, 0.0))


@pytest.mark.parametrize("override, match", [
    ("structure.link_thickness_mm=0.2", "link_thickness_mm"),
    ("structure.bore_diameter_mm=17.9", "bore_diameter_mm"),
    ("geometry.driver_link_mm=10", "driver_link_mm"),
    ("geometry.shoulder_height_mm=40", "shoulder_height_mm"),
    ("structure.light_link_width_mm=18", "light_link_width_mm"),
    ("links.coupler_mass_kg=0.01", "links.coupler_mass_kg"),  # below the coupler's own 26 g of aluminium
])
def test_hard_cases(paper, override, match):
    with pytest.raises(InvalidDesign, match=match):
        cad_master.part_specs(io.apply_overrides(paper, [override]))


def test_export_master(paper, tmp_path):
    from hapticopt.design.export import export

    import json

    import mujoco

    res = export(paper, tmp_path)
    names = {f.name for f in res.files}
    assert {f"{paper.name}.step", "mass_properties.json", "handle.stl"} <= names
    assert json.loads((tmp_path / "mass_properties.json").read_text())["bodies"]  # the CAD's own mass table
    if f"{paper.name}.xml" in names:  # issue 16: the MJCF carries the mass model of evaluate and verify
        from hapticopt.design.master.mass import analytic_mass_properties

        model = mujoco.MjModel.from_xml_path(str(tmp_path / f"{paper.name}.xml"))
        moving = sum(b.mass for b in analytic_mass_properties(paper))
        assert model.body_mass.sum() == pytest.approx(moving, rel=1e-9)


# ---------------------------------------------------------------------------- mass that exists (issue 31)
def _model_bodies(paper):
    """The analytic mass model (the reference of evaluate, verify and the MJCF) per CAD body: mass [kg]
    and CoM [m] in the body frame; the model's handle frame is the forearm's moved by L4 along x."""
    from hapticopt.design.master.mass import analytic_mass_properties

    out = {}
    for b in analytic_mass_properties(paper):
        body, c = b.frame, np.asarray(b.com)
        if body == "handle":
            body, c = "forearm", c + np.array([paper.geometry.forearm, 0.0, 0.0])
        m, mc = out.get(body, (0.0, np.zeros(3)))
        out[body] = (m + b.mass, mc + b.mass * c)
    return {k: (m, mc / m) for k, (m, mc) in out.items() if m > 0}


def _step_bodies(paper, step_file):
    """Mass [kg] and CoM [m] per body, from the solids of the written STEP (OpenCASCADE's integrals of
    the file read back, each solid named after its part) and the part densities, brought from the
    posed (home) world frame back into each body's frame."""
    from build123d import import_step

    specs = cad_master.part_specs(paper)
    frames = cad_master.part_frames(paper, cad_master.solve_pose(paper, cad_master.home_point(paper)))
    acc = {}
    for solid in import_step(step_file).children:
        spec, T = specs[solid.label], frames[solid.label]
        m = spec.density * solid.volume * 1e-9
        c = T[:3, :3].T @ (np.array(tuple(solid.center())) * 1e-3 - T[:3, 3])
        mb, mc = acc.get(spec.body, (0.0, np.zeros(3)))
        acc[spec.body] = (mb + m, mc + m * c)
    return {k: (m, mc / m) for k, (m, mc) in acc.items()}


@pytest.fixture(scope="module")
def exported(paper, tmp_path_factory):
    from hapticopt.design.export import export

    out = tmp_path_factory.mktemp("master-export")
    export(paper, out)
    return out


def _close_in_plane(c, ref):
    # x along the link, z normal to it; a (y) is the joint axis, where an offset moves no gravity torque
    tol = max(1e-3, 0.01 * float(np.linalg.norm(ref[[0, 2]])))
    return float(np.linalg.norm((c - ref)[[0, 2]])) <= tol


def test_step_and_mass_properties_json_carry_the_model_mass(paper, exported):
    import json

    model = _model_bodies(paper)
    moving = sum(m for m, _ in model.values())
    assert moving == pytest.approx(1.30, rel=0.01)  # the preset's M (seed 003 eq 7/12)
    table = json.loads((exported / "mass_properties.json").read_text())["bodies"]
    sources = {"step": _step_bodies(paper, exported / f"{paper.name}.step"),
               "json": {k: (v["mass_kg"], np.asarray(v["com_mm"]) * 1e-3) for k, v in table.items()}}
    for src, bodies in sources.items():
        assert sum(m for k, (m, _) in bodies.items() if k not in ("base", "turret")) == pytest.approx(moving, rel=0.01), src
        for body, (m, c) in model.items():
            assert bodies[body][0] == pytest.approx(m, rel=0.01), (src, body)
            assert _close_in_plane(bodies[body][1], c), (src, body, bodies[body][1], c)


def test_unbalance_from_the_step_meets_the_requirement(paper, exported):
    from hapticopt.analysis.master import balance as mb, dynamics as md
    from hapticopt.design.master.mass import BodyMass

    zero = ((0.0, 0.0, 0.0),) * 3  # inertia plays no part in the gravity torque
    bodies = tuple(BodyMass(name=k, frame=k, mass=m, com=tuple(c), inertia=zero)
                   for k, (m, c) in _step_bodies(paper, exported / f"{paper.name}.step").items()
                   if k not in ("base", "turret"))
    res = mb.evaluate_parameters(paper, md.gravity_parameters(md.model_of(paper, bodies)))
    assert res.max_force <= mb.FORCE_JND_N  # seed 003: 0.1 N over the workspace
