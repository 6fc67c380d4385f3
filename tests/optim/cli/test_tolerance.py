"""``hapticopt tolerance``: strict JSON, a spec file, reproducible with a seed, one-line errors."""

from __future__ import annotations

import json

from typer.testing import CliRunner

from hapticopt.optim.cli import app

runner = CliRunner()


def _strict(text: str):
    def no_constant(name):
        raise AssertionError(f"{name} is not RFC 8259 JSON")
    return json.loads(text, parse_constant=no_constant)


def test_json_is_strict_and_seeded(tmp_path):
    spec = tmp_path / "tight.toml"
    spec.write_text('preset = "ISO2768-f"\n[features]\nangles = 0.01\n')
    args = ["tolerance", "--preset", "prrr-paper", "--spec", str(spec), "--samples", "12", "--seed", "3", "--json"]
    a, b = runner.invoke(app, args), runner.invoke(app, args)
    assert a.exit_code == 0, a.output
    assert a.stdout == b.stdout
    out = _strict(a.stdout)
    assert out["samples"] == 12 and out["spec"]["tolerance"]["r1_tilt_v"] == 0.01
    assert out["spec"]["units"]["r1_tilt_v"] == "deg"
    assert set(out["monte_carlo"]) == set(out["percentiles"]) >= {"constancy", "cond_home", "rotation", "margin_loss"}
    assert 0.0 <= out["yield"]["yield"] <= 1.0


def test_table_for_a_preset():
    res = runner.invoke(app, ["tolerance", "--preset", "prrr-paper", "--spec", "ISO2768-c", "--samples", "8"])
    assert res.exit_code == 0, res.output
    assert "Monte Carlo of 8 devices" in res.stdout and "yield" in res.stdout


def test_bad_input_is_one_line_and_exit_2(tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text("[features]\nnope = 1\n")
    for extra in (["--spec", "ISO2768-q"], ["--spec", str(bad)], ["--samples", "1"], ["--require", "x<=1"]):
        res = runner.invoke(app, ["tolerance", "--preset", "prrr-paper", "--samples", "4", *extra])
        assert res.exit_code == 2, (extra, res.output)
        assert len(res.stderr.strip().splitlines()) == 1 and res.stderr.startswith("error:")
    res = runner.invoke(app, ["tolerance", "--preset", "master-paper", "--samples", "4"])
    assert res.exit_code == 2 and "3-PRRR" in res.stderr
