"""``hapticopt tolerance``: Monte Carlo and linear stack of a 3-PRRR's manufacturing tolerances."""

from __future__ import annotations

import math
from typing import Annotated, Optional
from pathlib import Path

import numpy as np
import typer

from hapticopt.optim import strict_json

from hapticopt.design.errors import InvalidInput
from hapticopt.optim.cli import render
from hapticopt.optim.cli.common import load_design_arg, one_line_errors


def _clean(x):
    """Strict JSON: non-finite floats become null."""
    if isinstance(x, float):
        return x if math.isfinite(x) else None
    if isinstance(x, dict):
        return {k: _clean(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_clean(v) for v in x]
    return x


def report(design, spec, *, samples: int | None, seed: int, requirements) -> dict:
    """The tolerance report of ``design`` under ``spec`` (JSON-ready): MC statistics and percentiles,
    yield, the linear stack (RSS, worst case, variance shares) and their agreement."""
    from hapticopt.optim import tolerance as tol  # jax (design/prrr/kinematics.py): loaded only here

    mc = tol.monte_carlo(design, spec, samples=samples, seed=seed)
    stack = tol.linear_stack(design, spec)
    stats = mc.stats()
    rng = np.random.default_rng(seed)
    lin = tol.linearised_constancy(design, stack, tol.draw(spec, rng, mc.samples))[mc.results.converged]
    return _clean({
        "design": design.name, "spec": spec.as_dict(), "samples": mc.samples, "converged": mc.converged,
        "seed": seed, "stopped": mc.stopped,
        "units": {"constancy": "1", "cond_home": "1", "cond_home_frobenius": "1", "cond_spread": "1",
                  "rotation": "rad", "misfit": "rad", "margin_loss": "m", "margin": "m"},
        "nominal": {k: v for k, v in stack.nominal.items() if k != "converged"}, "monte_carlo": stats, "percentiles": mc.percentiles(),
        "yield": mc.yield_of(requirements),
        "linear_stack": {"rss_std": stack.rss_std, "worst_case": stack.worst_case,
                         "constancy_rss": stack.constancy_rss, "constancy_worst_case": stack.constancy_worst,
                         "constancy_linearised_std": float(np.std(lin, ddof=1)) if len(lin) > 1 else None,
                         "variance_shares": {**stack.shares, "constancy": stack.constancy_shares}},
    })


@one_line_errors
def tolerance(
    file: Annotated[Optional[Path], typer.Argument(help="Design TOML file (or use --preset).", show_default=False)] = None,
    preset: Annotated[Optional[str], typer.Option("--preset", help="Bundled preset name (see `hapticopt presets`).")] = None,
    set_: Annotated[Optional[list[str]], typer.Option("--set", help="Override a TOML key (repeatable).")] = None,
    spec: Annotated[str, typer.Option("--spec", help="ISO2768-f, ISO2768-m, ISO2768-c, ISO2768-v, or a tolerance spec TOML file.")] = "ISO2768-m",
    samples: Annotated[Optional[int], typer.Option("--samples", help="Monte Carlo devices (default: until the std of cond(J) has a 2 % standard error).")] = None,
    seed: Annotated[int, typer.Option("--seed", help="Seed of the error draw (the same seed: the same devices).")] = 0,
    require: Annotated[Optional[list[str]], typer.Option("--require", help="Yield requirement name<=value or name>=value over the per-device results (repeatable; default cond_spread<=0.01 and margin>=0).")] = None,
    as_json: Annotated[bool, typer.Option("--json", help="Print strict JSON.")] = False,
) -> None:
    """Tolerance analysis of a 3-PRRR as manufactured: Jacobian constancy, cond(J), parasitic rotation and workspace margin under a tolerance spec, by Monte Carlo and a linear stack."""
    from hapticopt.optim import tolerance as tol

    design = load_design_arg(file, preset, set_)
    if design.device != "prrr":
        raise InvalidInput(f"tolerance analyses the 3-PRRR; {design.name} is a {design.device} design")
    if samples is not None and not 2 <= samples <= tol.MAX_SAMPLES:
        raise InvalidInput(f"--samples = {samples} must be between 2 and {tol.MAX_SAMPLES}")
    if seed < 0:
        raise InvalidInput(f"--seed = {seed} must be ≥ 0")
    reqs = [tol.parse_requirement(r) for r in (require or tol.DEFAULT_REQUIREMENTS)]
    the_spec = tol.load_spec(design, spec)
    out = report(design, the_spec, samples=samples, seed=seed, requirements=reqs)
    if as_json:
        typer.echo(strict_json.dumps(out, indent=2))
        return
    console = render.console()
    scale = {"rotation": ("mrad", 1e3), "misfit": ("mrad", 1e3), "margin_loss": ("mm", 1e3), "margin": ("mm", 1e3)}
    rows = []
    for name, st in out["monte_carlo"].items():
        unit, f = scale.get(name, ("-", 1.0))
        pc = out["percentiles"][name]
        rows.append((name, unit, *(render.number(v * f) if v is not None else "-" for v in
                                   (out["nominal"][name], st["mean"], st["std"], pc["p5"], pc["p50"], pc["p95"], pc["p99"]))))
    console.print(render.table(f"{design.name} under {the_spec.name}: Monte Carlo of {out['samples']} devices "
                               f"(seed {seed}, {out['stopped']}; {out['converged']} reach every pose)",
                               ("output", "unit", "nominal", "mean", "std", "p5", "p50", "p95", "p99"), rows))
    ls = out["linear_stack"]
    console.print(f"linear stack: std cond₂(J) {render.number(ls['rss_std']['cond_home'])} (MC "
                  f"{render.number(out['monte_carlo']['cond_home']['std'])}), std cond_F(J) "
                  f"{render.number(ls['rss_std']['cond_home_frobenius'])} (MC "
                  f"{render.number(out['monte_carlo']['cond_home_frobenius']['std'])}), constancy RSS "
                  f"{render.number(ls['constancy_rss'])}, worst case {render.number(ls['constancy_worst_case'])}")
    top = list(ls["variance_shares"]["constancy"].items())[:5]
    console.print("constancy variance shares: " + ", ".join(f"{k} {100 * v:.1f} %" for k, v in top))
    y = out["yield"]
    lo, hi = y["yield_ci95"]
    console.print(f"yield {100 * y['yield']:.2f} % (95 % interval {100 * lo:.2f} … {100 * hi:.2f} %) for "
                  f"{' and '.join(y['requirements'])}")
