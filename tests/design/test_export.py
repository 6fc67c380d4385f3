"""Export: STEP re-read by gmsh, STL manifold and volume, MJCF vs mass_properties.json,
atomic writes, and the `hapticopt export` command."""

import dataclasses
import json
import struct

import mujoco
import numpy as np
import pytest

from hapticopt.design import export as ex
from hapticopt.design import io
from hapticopt.design.mass_properties import Method

PARTS = {"base", "platform"} | {f"{k}_{i}" for k in ("rail", "screw", "motor", "carriage", "housing", "link1", "link2")
                                 for i in (1, 2, 3)}


#: one drawing per manufactured part geometry (the legs' identical parts share one; rails are placed per leg)
DRAWINGS = {"base", "rail_1", "rail_2", "rail_3", "carriage", "link1", "link2", "platform"}


@pytest.fixture(scope="module")
def paper():
    return io.load_preset("prrr-paper")


@pytest.fixture(scope="module")
def exported(paper, tmp_path_factory):
    out = tmp_path_factory.mktemp("export")
    return ex.export(paper, out, p=np.array([0.01, -0.02, 0.015]), drawings_2d=True)


@pytest.fixture(scope="module")
def cad_volumes_mm3(paper):
    from hapticopt.design.prrr import cad as cad_prrr

    return {n: s.volume for n, s in cad_prrr.build_parts(paper).items()}


def test_files(exported, paper):
    names = {f.relative_to(exported.out_dir).as_posix() for f in exported.files}
    assert names == ({f"{paper.name}.step", f"{paper.name}.xml", "mass_properties.json"}
                     | {f"parts/{n}.stl" for n in PARTS}
                     | {f"drawings/{n}.{e}" for n in DRAWINGS for e in ("svg", "dxf")})
    assert not list(exported.out_dir.rglob("*.tmp*"))


def test_step_reimported_by_gmsh_has_the_same_solids(exported, paper, cad_volumes_mm3):
    # acceptance: same number of solids, volumes within 0.1 % (gmsh's OpenCASCADE import)
    import gmsh

    gmsh.initialize(interruptible=False)
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        gmsh.model.occ.importShapes(str(exported.out_dir / f"{paper.name}.step"))
        gmsh.model.occ.synchronize()
        vols = gmsh.model.getEntities(3)
        got = sorted(gmsh.model.occ.getMass(3, tag) for _, tag in vols)
        labels = {gmsh.model.getEntityName(3, tag).split("/")[-1] for _, tag in vols}
    finally:
        gmsh.finalize()
    assert len(vols) == len(PARTS)
    want = sorted(cad_volumes_mm3.values())
    assert np.allclose(got, want, rtol=1e-3)
    assert PARTS <= labels  # part names survive the flat assembly


def _read_stl(path):
    data = path.read_bytes()
    (n,) = struct.unpack_from("<I", data, 80)
    rec = np.frombuffer(data, dtype=np.dtype([("n", "<f4", 3), ("v", "<f4", (3, 3)), ("a", "<u2")]), count=n, offset=84)
    verts, tris = np.unique(rec["v"].reshape(-1, 3), axis=0, return_inverse=True)
    return verts.astype(np.float32), tris.reshape(-1, 3).astype(np.uint32)


def test_every_stl_is_a_closed_manifold_with_the_solid_volume(exported, cad_volumes_mm3):
    # acceptance: manifold3d accepts every STL; volume within 0.5 % of the solid
    import manifold3d as m3d

    for name in PARTS:
        verts, tris = _read_stl(exported.out_dir / "parts" / f"{name}.stl")
        man = m3d.Manifold(m3d.Mesh(vert_properties=verts, tri_verts=tris))
        assert man.status() == m3d.Error.NoError, name
        assert man.genus() >= 0
        assert man.volume() == pytest.approx(cad_volumes_mm3[name], rel=5e-3), name


def test_mjcf_matches_mass_properties_json(exported, paper):
    data = json.loads((exported.out_dir / "mass_properties.json").read_text())
    model = mujoco.MjModel.from_xml_path(str(exported.out_dir / f"{paper.name}.xml"))
    # every CAD body, plus the three motor sides' equivalent mass M_m (seed 002 Table 4, not a part)
    assert model.body_mass.sum() == pytest.approx(data["total_mass_kg"] + 3 * paper.actuator.motor_mass, rel=1e-9)
    from hapticopt.design.prrr import cad as cad_prrr

    frames = cad_prrr.part_frames(paper, cad_prrr.solve_pose(paper, (0.0, 0.0, 0.0)))
    for name, body in data["bodies"].items():
        b = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, "ee" if name == "platform" else name)
        R = np.zeros(9)
        mujoco.mju_quat2Mat(R, model.body_iquat[b])
        R = R.reshape(3, 3)
        inertia_kg_mm2 = R @ np.diag(model.body_inertia[b]) @ R.T * 1e6
        assert model.body_mass[b] == pytest.approx(body["mass_kg"], rel=1e-9)
        # MJCF bodies are world-aligned at home; the JSON is in the part frame
        Rp = frames[name][:3, :3]
        want = Rp @ np.array(body["inertia_kg_mm2"]) @ Rp.T
        assert inertia_kg_mm2 == pytest.approx(want, rel=1e-6, abs=1e-9)


def test_json_is_the_cad_mass_properties(exported, paper):
    data = json.loads((exported.out_dir / "mass_properties.json").read_text())
    assert data["method"] == "cad"
    cad = ex.mass_properties(paper, method=Method.CAD)
    assert data["parts"]["platform"]["mass_kg"] == pytest.approx(cad.parts["platform"].mass, rel=1e-12)


def test_a_failing_writer_leaves_the_previous_set(paper, tmp_path, monkeypatch):
    """Issue 14: an export to a full disk left 14 of 18 files. The set is staged and moved in at
    the end: a writer failing at the 5th STL leaves the previous export byte for byte, no staging."""
    import build123d

    first = ex.export(paper, tmp_path / "out")
    before = {p: p.read_bytes() for p in first.files}
    real, calls = build123d.export_stl, []

    def full_disk(*args, **kwargs):
        calls.append(1)
        if len(calls) == 5:
            raise OSError(28, "No space left on device")
        return real(*args, **kwargs)

    monkeypatch.setattr(build123d, "export_stl", full_disk)
    with pytest.raises(OSError, match="No space left"):
        ex.export(dataclasses.replace(paper, name="other"), tmp_path / "out")
    after = {p for p in (tmp_path / "out").rglob("*") if p.is_file()}
    assert after == set(before) and all(p.read_bytes() == b for p, b in before.items())
    assert not [p for p in (tmp_path / "out").rglob(".*")]


def test_invalid_design_writes_nothing(paper, tmp_path):
    from hapticopt.design.errors import InvalidDesign

    bad = io.apply_overrides(paper, ["structure.bore_diameter_mm=23.8"])
    with pytest.raises(InvalidDesign, match="bore_diameter_mm"):
        ex.export(bad, tmp_path / "out")
    assert not (tmp_path / "out").exists()


def test_cli_export_and_errors(tmp_path):
    from typer.testing import CliRunner

    from hapticopt.optim.cli import app

    runner = CliRunner()
    res = runner.invoke(app, ["export", "--preset", "prrr-paper", "--out", str(tmp_path / "o"), "--pose", "0,0,10"])
    assert res.exit_code == 0, res.output
    assert "interference: none" in res.output
    assert (tmp_path / "o" / "prrr-paper.step").is_file()
    res = runner.invoke(app, ["export", "--preset", "prrr-paper", "--out", str(tmp_path / "p"), "--pose", "1,2"])
    assert res.exit_code == 2 and "--pose" in res.output
    res = runner.invoke(app, ["export", "--preset", "prrr-paper", "--out", str(tmp_path / "q"), "--pose", "500,0,0"])
    assert res.exit_code == 2 and "not reachable" in res.output
    assert not (tmp_path / "q").exists()
    # --out is a file: one line with the OS reason, before any CAD is built
    (tmp_path / "f").write_text("x")
    res = runner.invoke(app, ["export", "--preset", "prrr-paper", "--out", str(tmp_path / "f")])
    assert res.exit_code == 2 and res.stderr.count("\n") == 1 and "File exists" in res.stderr, res.output




def test_handle_has_no_cad_one_line(tmp_path):
    # seed 000's handle is an analysis device (one axis): export refuses it with one line, not a KeyError
    from hapticopt.design import export, io
    from hapticopt.design.errors import InvalidDesign

    with pytest.raises(InvalidDesign, match=r"^device = 'handle' of design 'handle-paper' has no CAD model to export: "
                                            r"allowed prrr, master$"):
        export.export(io.load_preset("handle-paper"), tmp_path)


def test_drawings_overall_dimensions_match_the_step_to_001_mm(exported, paper):
    """Every drawing's overall size (its title block, measured from the projected views) equals the
    bounding box of each of its parts in the exported STEP, moved back into the part's frame, to 0.01 mm;
    the title names the material and the mass; the DXF holds the same layers."""
    import re

    import ezdxf

    from hapticopt.design import cad_import, parts
    from hapticopt.design.prrr import cad as cad_prrr

    cad_import.build123d()
    from build123d import import_step

    step = import_step(str(exported.out_dir / f"{paper.name}.step"))
    solids = {c.label: c for c in step.children}  # the flat assembly: one labelled solid per part
    frames = cad_prrr.part_frames(paper, cad_prrr.solve_pose(paper, np.array([0.01, -0.02, 0.015])))
    for name in DRAWINGS:
        svg = (exported.out_dir / "drawings" / f"{name}.svg").read_text()
        desc = re.search(r"<desc>(.*?)</desc>", svg).group(1)
        assert "material 6061-T6" in desc and re.search(r"mass \d+\.\d g each", desc), desc
        size = [float(v) for v in re.search(r"overall ([\d.]+) x ([\d.]+) x ([\d.]+) mm", desc).groups()]
        shown = re.search(r"qty (\d+)(: (.*?))?\)", desc)
        members = shown.group(3).split(", ") if shown.group(3) else [name]
        for part in members:
            local = solids[part].moved(parts.location(frames[part]).inverse()).bounding_box(optimal=True)
            np.testing.assert_allclose(size, [local.size.X, local.size.Y, local.size.Z], atol=0.01, err_msg=part)
        doc = ezdxf.readfile(str(exported.out_dir / "drawings" / f"{name}.dxf"))
        layers = {e.dxf.layer for e in doc.modelspace()}
        assert {"visible", "dimensions"} <= layers, layers
