"""``hapticopt sensitivity``: strict JSON, the ranked table, the tornado plot, one-line errors."""

from __future__ import annotations

import json

from typer.testing import CliRunner

from hapticopt.optim.cli import app

runner = CliRunner()
#: the statics only, at standard fidelity (numpy, no batch compile), two keys
FAST = ["--preset", "prrr-paper", "--evaluator", "statics", "--fidelity", "standard",
        "--key", "geometry.beta_deg", "--key", "actuator.spring_N_per_mm"]


def _strict(text: str):
    def no_constant(name):
        raise AssertionError(f"{name} is not RFC 8259 JSON")
    return json.loads(text, parse_constant=no_constant)


def test_json_is_strict_and_ranked(tmp_path):
    res = runner.invoke(app, ["sensitivity", *FAST, "--json", "--plots", str(tmp_path)])
    assert res.exit_code == 0, res.output
    out = _strict(res.stdout)
    rows = out["sensitivities"]
    fx = next(r for r in rows if r["metric"] == "max_force_N[0]" and r["key"] == "geometry.beta_deg")
    # seed 002: F_x max = 2 F_max / tan β → ∂/∂β = −2 F_max / sin²β · π/180 = −55.556 N/deg at 60°
    assert abs(fx["derivative"] - (-2 * 3581 / 3 / 0.75 * 3.141592653589793 / 180)) < 1e-9
    assert fx["metric_unit"] == "N" and fx["key_unit"] == "deg" and fx["method"] == "jax"
    assert (tmp_path / "prrr-paper_sensitivity_tornado.png").stat().st_size > 1000
    el = [abs(r["elasticity"]) for r in rows if r["elasticity"] is not None]
    assert el == sorted(el, reverse=True)


def test_table():
    res = runner.invoke(app, ["sensitivity", *FAST, "--top", "3"])
    assert res.exit_code == 0, res.output
    assert "elasticity" in res.stdout and "jax" in res.stdout
    assert "40 pairs; 20 with a zero derivative not shown" in res.stdout  # 20 statics scalars × 2 keys


def test_bad_input_is_one_line_and_exit_2():
    for extra in (["--key", "geometry.nope_mm"], ["--metrics", "nope_N"], ["--top", "0"], ["--evaluator", "nope"]):
        res = runner.invoke(app, ["sensitivity", *FAST, *extra])
        assert res.exit_code == 2, (extra, res.output)
        assert len(res.stderr.strip().splitlines()) == 1 and res.stderr.startswith("error:")
