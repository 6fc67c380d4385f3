"""``hapticopt export`` says where it checked interference (issue 15: honest statuses)."""

from typer.testing import CliRunner

from hapticopt.design import io
from hapticopt.optim.cli import export as cli_export
from hapticopt.optim.cli import app

runner = CliRunner()


def test_default_export_names_the_home_pose(tmp_path):
    res = runner.invoke(app, ["export", "--preset", "prrr-paper", "--out", str(tmp_path)])
    assert res.exit_code == 0, res.output
    assert "interference: none at the home pose — only this pose was checked" in res.output
    # the drawings (≈ 100 s for prrr-paper) are written only with --drawings (tests/design/test_export.py draws them)
    assert (tmp_path / "prrr-paper.step").is_file() and not (tmp_path / "drawings").exists()


def test_poses_option_checks_the_workspace():
    paper = io.load_preset("prrr-paper")
    assert cli_export._check_many(paper, 24) == "none at 24 workspace poses"  # 3 × 2 × 2 × 2: exactly 24
    # issue 33: --poses 216 checked 192 poses without saying so; 30 asks for 3 × 2 × 2 × 2.5 heights → 24
    assert cli_export._check_many(paper, 30) == ("none at 24 workspace poses (24 checked of the 30 asked: the "
                                                 "workspace samples form a grid of 3 × 2 angles × 2 radii × 2 "
                                                 "heights, the nearest to the number asked)")
    # the layout before issue 15 (rails on u_i at r_p = 100, the old part sizes): part of the
    # workspace collides, and the line says how much
    legacy = io.apply_overrides(paper, ["geometry.theta_1p_deg=0", "geometry.r_p_mm=100", "structure.rail_width_mm=20",
                                        "structure.carriage_wall_mm=8", "structure.carriage_height_mm=50",
                                        "structure.sea_envelope_mm=25"])
    msg = cli_export._check_many(legacy, 24)
    assert " workspace poses collide (" in msg and "×" in msg


def test_rail_too_close_is_one_line_exit_2(tmp_path):
    # r_p too small for the carriage: one line naming r_p and θ_1p, exit 2
    res = runner.invoke(app, ["export", "--preset", "prrr-paper", "--set", "geometry.r_p_mm=10",
                              "--out", str(tmp_path)])
    assert res.exit_code == 2
    lines = [ln for ln in res.output.splitlines() if ln.strip()]
    assert len(lines) == 1 and "r_p_mm = 10" in lines[0] and "theta_1p_deg" in lines[0]


def test_poses_are_bounded_in_one_line(tmp_path):
    """Issue 37: --poses had no upper bound (each pose is a boolean of every part pair)."""
    for n in ("1001", "-1"):
        res = runner.invoke(app, ["export", "--preset", "prrr-paper", "--poses", n, "--out", str(tmp_path / "e")])
        assert res.exit_code == 2, res.output
        (line,) = res.stderr.strip().splitlines()
        assert f"--poses = {n} is out of range: allowed 0 ≤ --poses ≤ 1000 (poses)" in line
    assert not (tmp_path / "e").exists()


def test_exports_are_named_after_the_design_exported():
    """issue 33: `export --preset prrr-paper --set geometry.beta_deg=45` wrote prrr-paper.step. The name is
    the design's plus a short hash of its TOML: equal designs, equal names; another design, another name."""
    from hapticopt.optim.cli.export import exported_name

    paper = io.load_preset("prrr-paper")
    b45 = io.apply_overrides(paper, ["geometry.beta_deg=45"])
    named = exported_name(b45, ["geometry.beta_deg=45"]).name
    assert named.startswith("prrr-paper-") and len(named) == len("prrr-paper-") + 8
    assert exported_name(io.apply_overrides(paper, ["geometry.beta_deg=45.0"]), ["geometry.beta_deg=45.0"]).name == named
    b50 = io.apply_overrides(paper, ["geometry.beta_deg=50"])
    assert exported_name(b50, ["geometry.beta_deg=50"]).name != named
    assert exported_name(paper, []).name == "prrr-paper"  # no override: the preset's own name
    mine = io.apply_overrides(paper, ["geometry.beta_deg=45", "name=beta45"])
    assert exported_name(mine, ["geometry.beta_deg=45", "name=beta45"]).name == "beta45"  # a chosen name stands
