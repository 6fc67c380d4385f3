"""``hapticopt evaluate --sweep NAME``: parameter sweeps that write a plot and a CSV table."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from hapticopt.design.errors import InvalidInput
from rich.console import Console
from rich.table import Table
from hapticopt.design.atomic import write_text
from hapticopt.design.paths import check_name, inside

SWEEPS = {"master": ("counterweight",)}


def run_sweep(design: Any, name: str, out_dir: Path, fidelity: Any) -> list[Path]:
    """Run the sweep ``name`` for ``design``; returns the files written (table, plot)."""
    allowed = SWEEPS.get(design.device, ())
    if name not in allowed:
        raise InvalidInput(f"--sweep = {name!r} is not a sweep for a {design.device} design: "
                           f"allowed {', '.join(allowed) if allowed else 'none'}")

    from hapticopt.analysis.master import plots as master_plots, tradeoff as master_tradeoff

    rows = master_tradeoff.counterweight_sweep(design, fidelity=fidelity)
    out_dir = Path(out_dir)
    check_name(design.name, "design name")
    table_path = inside(out_dir, f"{design.name}_sweep_counterweight.csv")
    plot_target = inside(out_dir, f"{design.name}_sweep_counterweight.png")
    out_dir.mkdir(parents=True, exist_ok=True)
    write_text(table_path, master_tradeoff.rows_to_csv(rows))
    plot_path = master_plots.sweep_plot(rows, plot_target)
    table = Table(title=f"{design.name}: counterweight sweep (seed 003 trade-off)")
    for key in rows[0]:
        table.add_column(key)
    for r in rows:
        table.add_row(*(f"{v:.4g}" for v in r.values()))
    Console(stderr=True).print(table)
    return [table_path, plot_path]
