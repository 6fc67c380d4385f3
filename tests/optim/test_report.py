"""optim/report.py: units, the optimiser's name, the improvement verdict, the starts table, the figures."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest

from hapticopt.analysis.loop.traces import Traces
from hapticopt.optim import report
from hapticopt.optim.driver import EvalRecord, RunResult, Source, StartResult, StartStatus
from hapticopt.optim.evaluation import Outcome
from hapticopt.optim.pipeline import run_pipeline
from hapticopt.optim.problem import Algorithm, OptimiserConfig, Sense, load_problem
from hapticopt.optim.results import TimeHistory, Verdict

DATA = Path(__file__).parent / "data"


@pytest.fixture(scope="module")
def beta_run(tmp_path_factory):
    problem = load_problem(DATA / "beta-isotropic.toml").with_optimiser(max_evals=30, starts=2)
    return run_pipeline(problem, out_dir=tmp_path_factory.mktemp("rep"), scheduler="inline", export=False,
                        verify=False)


@pytest.mark.parametrize("name, unit", [("stiffness_limit_N_per_mm[0]", "N/mm"), ("min(max_force_N)", "N"),
                                        ("stiffness_error_pct", "%"), ("jacobian_condition", "-"),
                                        ("workspace_volume_mm3", "mm³"), ("transparency_bandwidth_Hz", "Hz"),
                                        # issue 33: von Mises per newton was printed "N"
                                        ("structural_fea_max_von_mises_MPa_per_N", "MPa/N"),
                                        ("zwidth_peak_damping_Ns_per_m", "N·s/m"), ("pade_minus_exact_pct", "%")])
def test_metric_unit_from_the_name(name, unit):
    assert report.metric_unit(name) == unit


def test_optimiser_named_as_it_runs():
    """The local algorithm appears only where optim.driver uses it (AUGLAG's subsidiary, the polish
    after a global search; a constrained polish falls back to LN_COBYLA: driver._Start.run_start)."""
    assert report.optimiser_text(OptimiserConfig(algorithm=Algorithm.LN_COBYLA), constrained=True) == "LN_COBYLA"
    assert report.optimiser_text(OptimiserConfig(algorithm=Algorithm.AUGLAG, local=Algorithm.LN_BOBYQA),
                                 constrained=True) == "AUGLAG with subsidiary LN_BOBYQA"
    text = report.optimiser_text(OptimiserConfig(algorithm=Algorithm.GN_ISRES, local=Algorithm.LN_BOBYQA),
                                 constrained=True)
    assert text.startswith("GN_ISRES, then local polish with LN_COBYLA") and "LN_BOBYQA cannot" in text
    assert report.optimiser_text(OptimiserConfig(algorithm=Algorithm.GN_ISRES, local=Algorithm.LN_BOBYQA),
                                 constrained=False) == "GN_ISRES, then local polish with LN_BOBYQA"


def test_report_names_the_optimiser_without_an_unused_local(beta_run):
    md = (beta_run.out_dir / "report.md").read_text()
    assert "Optimiser: LN_COBYLA, 2 start(s)" in md and "BOBYQA" not in md


def test_improvement_judged_against_a_feasible_baseline_only(beta_run):
    word, _ = report.improvement_text(beta_run)
    assert word == "improved"  # cond(J) from √6 at 60° to 1 at the isotropic angle (seed 002)
    # the same optimum against a baseline that violates max_force_N[2] >= 1000
    metrics = dict(beta_run.baseline.metrics)
    metrics["max_force_N"] = [1.0, 1.0, 500.0]
    weak = dataclasses.replace(beta_run, baseline=dataclasses.replace(beta_run.baseline, metrics=metrics))
    word, sentence = report.improvement_text(weak)
    assert word == "feasible (baseline infeasible)" and "violates max_force_N[2] >= 1000" in sentence
    word, _ = report.improvement_text(dataclasses.replace(weak, feasible_final=False))
    assert word == "infeasible"


def _record(index, start, x, objective, feasible):
    return EvalRecord(index=index, start=start, stage="search", x=(x,), objective=objective, f=-objective,
                      constraints=(0.0 if feasible else 0.5,), feasible=feasible, outcome=Outcome.OK, message="",
                      source=Source.EVALUATED)


def test_starts_table_objective_in_the_users_sense_and_feasibility(beta_run):
    """A maximised objective: nlopt minimises −f (StartResult.f = −96.24), the table shows +96.24."""
    problem = dataclasses.replace(beta_run.problem, objective=dataclasses.replace(beta_run.problem.objective,
                                                                                 sense=Sense.MAXIMISE))
    hist = (_record(0, 0, 50.0, 90.0, True), _record(1, 0, 40.0, 96.24, True), _record(2, 1, 20.0, 99.0, False))
    starts = (StartResult(start=0, x0=(60.0,), x=(40.0,), f=-96.24, status=StartStatus.XTOL_REACHED, message="",
                          n_points=2),
              StartResult(start=1, x0=(20.0,), x=(20.0,), f=-99.0, status=StartStatus.MAXEVAL_REACHED, message="",
                          n_points=1))
    run = RunResult(problem_name="p", objective_metric="jacobian_condition", starts=starts, history=hist,
                    best=hist[1], feasible=True, n_evaluated=3, n_replayed=0, n_cached=0, notes=(), wall_s=0.0)
    head, rows = report._start_rows(dataclasses.replace(beta_run, problem=problem, run=run))
    col = {h.split(" [")[0]: i for i, h in enumerate(head)}
    assert rows[0][col["objective at result"]] == "96.24" and rows[0][col["feasible"]] == "yes"
    assert rows[0][col["start"]] == "0 (best)"
    assert rows[1][col["feasible"]] == "no" and rows[1][col["largest violation"]] == "50 %"
    assert rows[1][col["best feasible in start"]] == "none feasible"
    assert rows[0][col["variables: start → result"]] == ["geometry.beta_deg: 60 → 40 deg"]


def test_convergence_svg_labels_starts_and_feasibility(beta_run):
    svg = report.convergence_svg(beta_run.run.history, metric="jacobian_condition", sense_max=False)
    for text in ("jacobian_condition [-]", "evaluation (order of request) [-]", "start 0", "start 1",
                 "feasible point", "infeasible point", "best feasible so far"):
        assert text in svg, text


def _traces(n=5000, stop=-1):
    t = np.arange(n) * 1e-3
    pos = np.zeros((n, 1, 3))
    pos[:, 0, 1] = 0.002 * np.sin(t)
    return Traces(period=1e-3, energy=np.zeros((n, 1)), saturated=np.zeros((n, 1), dtype=bool),
                  stop_tick=np.array([stop]), position=pos, hand_force=pos * 1e4, actuator_force=None,
                  force_reference=None)


def test_time_history_from_traces_in_engineering_units():
    h = TimeHistory.from_traces(_traces())
    assert h.stride == 3 and len(h.t) == 1667  # ⌈5000 / 2000⌉ ticks per sample
    assert h.position[1, 1] == pytest.approx(2.0 * math.sin(3e-3))  # 2 mm amplitude, in mm
    assert h.stopped_at_s is None and h.actuator_force is None
    h = TimeHistory.from_traces(_traces(stop=1000))
    assert h.t[-1] < 1.0 and h.stopped_at_s == pytest.approx(1.0)  # nothing after the stop tick
    assert TimeHistory.from_traces(None) is None


def test_time_history_figure_axes_carry_units():
    v = Verdict(scene="s", passed=True, metrics={}, history=TimeHistory.from_traces(_traces()))
    fig = report.history_figure(v)
    labels = [ax.get_ylabel() for ax in fig.axes] + [fig.axes[-1].get_xlabel()]
    assert labels == ["position [mm]", "force on the hand [N]", "time t [s]"]
    assert [t.get_text() for t in fig.axes[0].get_legend().get_texts()] == ["y"]  # x and z are zero: left out
    import matplotlib.pyplot as plt

    plt.close(fig)


def test_evaluator_statuses_are_a_table_and_a_summary_line(beta_run, tmp_path):
    """Every evaluator's status at final fidelity, baseline and optimum, with its message: a not-met of an
    evaluator the problem does not constrain is shown (it does not make the optimum infeasible)."""
    head, rows = report._tables(beta_run)["statuses"]
    assert head[0] == "evaluator" and {r[0] for r in rows} == set(beta_run.optimum.statuses)
    # the β optimum (35.26°) no longer holds the φ140 × 89 mm cylinder: its table rows say so (seed 002 eq 1:
    # the reach shrinks with tan β)
    assert all([r[1], r[2]] == [str(beta_run.baseline.statuses.get(r[0], "—")), str(beta_run.optimum.statuses[r[0]])]
               for r in rows)
    assert next(r for r in rows if r[0] == "workspace")[2] == "not-met"
    st = {**beta_run.optimum.statuses, "joint_limits": "not-met"}
    msg = {**beta_run.optimum.messages, "joint_limits": "a joint limit cuts the φ140 mm cylinder by 22.9 deg"}
    hurt = dataclasses.replace(beta_run, optimum=dataclasses.replace(beta_run.optimum, statuses=st, messages=msg),
                               out_dir=tmp_path)
    row = next(r for r in report._tables(hurt)["statuses"][1] if r[0] == "joint_limits")
    assert row[2:] == ["not-met", "optimum: a joint limit cuts the φ140 mm cylinder by 22.9 deg"]
    report.write(hurt)
    html = (tmp_path / "report.html").read_text(encoding="utf-8")
    assert "<h2>Evaluator statuses</h2>" in html and "joint_limits not-met" in html
    assert "a joint limit cuts the φ140 mm cylinder by 22.9 deg" in html


def _metrics_rows(page: str) -> list[list[str]]:
    """The cells of the report's metrics table, with each cell's class (``class|text``)."""
    import html as _html
    import re

    table = page.split("<h2>Metrics</h2>", 1)[1].split("</table>", 1)[0]
    rows = re.findall(r"<tr>(.*?)</tr>", table.split("<tbody>", 1)[1])
    return [[f"{cls}|{_html.unescape(text)}" for cls, text in re.findall(r"<td(?: class='(\w*)')?>(.*?)</td>", r)]
            for r in rows]


def test_report_units_come_from_the_registry_and_changes_are_judged(beta_run):
    """issue 33: every metric row's unit is the registry's (analysis/registry.metric_unit); the change
    column is coloured by the metric's direction: cond(J) from √6 to 1 (seed 002 eq 2) is better."""
    from hapticopt.analysis.registry import metric_unit

    rows = _metrics_rows((beta_run.out_dir / "report.html").read_text(encoding="utf-8"))
    assert len(rows) == len(set(beta_run.baseline.metrics) | set(beta_run.optimum.metrics))
    for row in rows:
        name, unit = row[0].split("|", 1)[1], row[1].split("|", 1)[1]
        assert unit == (metric_unit(name) or "-"), (name, unit)
    by_name = {r[0].split("|", 1)[1]: r for r in rows}
    assert by_name["jacobian_condition"][4].startswith("better|") and "▲ better" in by_name["jacobian_condition"][4]
    assert by_name["workspace_required_diameter_mm"][4] == "same|="  # a design input, unchanged
    assert "rounding, shown as =" in (beta_run.out_dir / "report.md").read_text(encoding="utf-8")


def test_report_opens_with_a_headline(beta_run):
    """issue 33: the report opens with one paragraph: what was optimised, by how much (cond(J) from √6 at
    60° to 1 at the isotropic β, seed 002 eq 2: -59.2 %), the active constraints, what to check next."""
    head = report.headline(beta_run)
    b, o = (beta_run.problem.objective.metric.value(e.metrics) for e in (beta_run.baseline, beta_run.optimum))
    assert b == pytest.approx(6 ** 0.5) and 1.0 <= o < 1.01  # 30 evaluations come within 1 % of the isotropic 1
    assert head.startswith("Minimise jacobian_condition of preset prrr-paper over geometry.beta_deg: improved "
                           f"from 2.44949 to {o:.6g} ({100 * (o - b) / b:+.3g} %)")  # about -59 %
    assert "No constraint is active." in head  # max_force_N[2] ≥ 1000 N holds with margin at the isotropic β
    assert "Check next:" in head and "no scene was verified" in head  # verify=False in this run
    md = (beta_run.out_dir / "report.md").read_text(encoding="utf-8").splitlines()
    assert md[2] == head  # right under the title
    assert f"<p class='headline'><b>{head}</b></p>" in (beta_run.out_dir / "report.html").read_text(encoding="utf-8")


def test_verify_plot_of_a_stopped_run_marks_the_stop_and_the_verdict(tmp_path):
    """issue 33: an unstable run "stopped at 0.1 s" was plotted by `verify --plots` as 3 s of bounded trace
    with no marker and no title. The standalone plot is the report's: the scene and verdict in the title,
    the traces up to the stop tick (1000 ticks of 1 ms here: 1 s), that tick marked."""
    from types import SimpleNamespace

    from hapticopt.optim.cli.verify import _plot

    written = _plot(SimpleNamespace(traces=_traces(stop=1000), status="unstable"), tmp_path, "wall")
    assert [p.name for p in written] == ["verify-wall.png"] and written[0].stat().st_size > 0
    fig = report.history_figure(Verdict(scene="wall", passed=False, metrics={}, message="unstable",
                                        history=TimeHistory.from_traces(_traces(stop=1000))))
    title = fig._suptitle.get_text()
    assert title.startswith("wall: FAIL — unstable") and "stopped at t = 1 s" in title
    for ax in fig.axes:
        drawn = [line for line in ax.get_lines() if line.get_label() != "run stopped (instability detected)"]
        assert all(max(line.get_xdata()) < 1.0 for line in drawn)  # nothing drawn after the stop
        assert any(line.get_label() == "run stopped (instability detected)" for line in ax.get_lines())
    import matplotlib.pyplot as plt

    plt.close(fig)
