"""Names that become file names, and output paths that must stay inside ``--out`` (issue 14, item 1)."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import pytest
from typer.testing import CliRunner

from hapticopt.design import io
from hapticopt.design.errors import InvalidDesign, InvalidInput
from hapticopt.design.paths import NAME_MAX, check_name, inside
from hapticopt.optim.cli import app

BAD_NAMES = ["/abs/evil", "../x", "a/b", "a\\b", "..", "x..y", ".hidden", "a\x00b", "a\nb", "a\x1bb", "",
             "   ", "n" * (NAME_MAX + 1), "a\u2028b"]


@pytest.mark.parametrize("name", BAD_NAMES)
def test_bad_names_are_refused_with_one_line(name):
    with pytest.raises(InvalidInput) as exc:
        check_name(name, "name")
    assert "\n" not in str(exc.value) and str(exc.value).startswith("name = ")


@pytest.mark.parametrize("name", ["prrr-paper", "a_b.c", "Ω-device", "n" * NAME_MAX, "x y"])
def test_good_names_pass(name):
    assert check_name(name, "name") == name


@pytest.mark.parametrize("value", [1, ["a"], {"a": 1}, None, True])
def test_a_name_must_be_a_string(value):
    with pytest.raises(InvalidInput, match="must be a string"):
        check_name(value, "name")


def test_design_file_name_is_checked_where_it_enters(tmp_path):
    text = io.dumps(io.load_preset("prrr-paper")).replace('name = "prrr-paper"', 'name = "../evil"')
    (tmp_path / "d.toml").write_text(text)
    with pytest.raises(InvalidDesign, match=r"d.toml: name = '../evil' must not contain a path separator"):
        io.load_design(tmp_path / "d.toml")
    nul = io.dumps(io.load_preset("prrr-paper")).replace('name = "prrr-paper"', 'name = "a\\u0000b"')
    (tmp_path / "n.toml").write_text(nul)
    with pytest.raises(InvalidDesign, match="control character U\\+0000"):
        io.load_design(tmp_path / "n.toml")


def test_inside_refuses_escapes_and_symlinks_out(tmp_path):
    root = tmp_path / "out"
    root.mkdir()
    assert inside(root, "a.step") == root / "a.step"
    assert inside(root, Path("parts") / "x.stl") == root / "parts" / "x.stl"
    for target in ("../x", "/abs/evil", root / ".." / "y"):
        with pytest.raises(InvalidInput, match="outside the output folder"):
            inside(root, target)
    (root / "link").symlink_to(tmp_path)  # a link inside --out that points out of it
    with pytest.raises(InvalidInput, match="outside the output folder"):
        inside(root, "link/z.png")


def test_export_refuses_a_design_whose_name_escapes(tmp_path):
    from hapticopt.design import export as ex

    # a design built in code (not through the loaders) with a bad name is still refused before any write
    design = dataclasses.replace(io.load_preset("prrr-paper"), name="../escape")
    with pytest.raises(InvalidDesign, match="design name = '../escape'"):
        ex.export(design, tmp_path / "out")
    assert not any(tmp_path.rglob("*"))


def _tree(*roots: Path) -> set[Path]:
    return {p for r in roots for p in r.rglob("*")}


@pytest.mark.parametrize("name", ["/abs/evil", "../x"])
@pytest.mark.parametrize("command", ["export", "evaluate", "verify"])
def test_cli_set_name_escape_exits_2_with_one_line_and_writes_nothing(tmp_path, monkeypatch, name, command):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "work").mkdir()
    monkeypatch.chdir(tmp_path / "work")
    evil = name if not name.startswith("/") else str(tmp_path / "abs" / "evil")
    args = [command, "--preset", "prrr-paper", "--set", f"name={evil}"]
    args += {"export": ["--out", "out"], "evaluate": ["--plots", "out"], "verify": ["--plots", "out"]}[command]
    res = CliRunner().invoke(app, args)
    assert res.exit_code == 2
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1 and "--set name" in lines[0] and "path separator" in lines[0]
    assert "Traceback" not in res.output
    assert _tree(tmp_path) == {tmp_path / "work"}  # nothing written anywhere


@pytest.mark.parametrize("name", ["/abs/evil", "../x", "a\\u0000b"])
def test_cli_problem_name_escape_exits_2_and_writes_nothing(tmp_path, monkeypatch, name):
    monkeypatch.chdir(tmp_path)
    p = tmp_path / "p.toml"
    p.write_text(f'name = "{name}"\nbase = "prrr-paper"\n[[variables]]\nkey = "geometry.beta_deg"\n'
                 'lower = 20.0\nupper = 70.0\n[objective]\nmetric = "jacobian_condition"\n')
    before = _tree(tmp_path)
    res = CliRunner().invoke(app, ["optimise", str(p), "--out", "run", "--scheduler", "inline", "--quiet"])
    assert res.exit_code == 2, res.output
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1 and "p.toml: name = " in lines[0]
    assert _tree(tmp_path) == before


def test_names_are_limited_in_bytes_too():
    """Issue 37: a 64-emoji name (256 bytes in UTF-8) passed the character limit and failed late."""
    from hapticopt.design.paths import NAME_MAX_BYTES

    with pytest.raises(InvalidInput, match=f"is 256 bytes long in UTF-8 \\(at most {NAME_MAX_BYTES}\\)"):
        check_name("\U0001F600" * 64, "name")
    assert check_name("Ω" * NAME_MAX, "name")  # 128 bytes


def test_the_output_root_may_be_a_link_but_nothing_below_it(tmp_path):
    """Issue 37: ``--out`` itself is the user's choice (it may be a link); a link below it is refused."""
    from hapticopt.design.atomic import write_text
    from hapticopt.design.errors import InputFileError
    from hapticopt.design.paths import make_dirs, no_links, output_root

    real = tmp_path / "real"
    real.mkdir()
    out = tmp_path / "out"
    out.symlink_to(real, target_is_directory=True)
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    with output_root(out):
        make_dirs(out / "plots" / "deep")
        write_text(out / "plots" / "a.txt", "x")
        (out / "plots" / "link").symlink_to(elsewhere, target_is_directory=True)
        for target in (out / "plots" / "link" / "b.txt", out / "plots" / "link"):
            with pytest.raises(InputFileError, match="plots/link is a symbolic link"):
                write_text(target, "y") if target.name == "b.txt" else make_dirs(target / "sub")
    assert (real / "plots" / "a.txt").read_text() == "x" and list(elsewhere.iterdir()) == []
    assert no_links(out / "plots" / "a.txt", out) == out / "plots" / "a.txt"
