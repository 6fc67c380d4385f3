"""hapticopt.analysis.loop.paper and each bundled seed-002 scene's [report]: the paper's quantity on
synthetic traces whose answer is known in closed form (RMS of A·sin over whole periods = A/√2)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from hapticopt.analysis.loop import paper
from hapticopt.analysis.loop.scene import PaperQuantity, load_scene
from hapticopt.analysis.loop.traces import Traces
from hapticopt.analysis.prrr.loop import closed_loop as cl
T, N = 1e-3, 3000  # 3 s at 1 kHz: whole periods of 1, 2 and 3 Hz
t = np.arange(N) * T


def _sin(amp: float, f: float, phase: float = 0.0, *, end: bool = False) -> np.ndarray:
    """amp·sin(2πft + phase) at the ticks' starts, or (``end``) at their ends t + T: the traces record the
    plant's forces at the end of tick k and the reference computed at its start (analysis.loop.traces)."""
    return amp * np.sin(2 * np.pi * f * (t + (T if end else 0.0)) + phase)


def test_axis_rms_counts_only_the_driven_axis():
    F = np.stack([_sin(0.5 * math.sqrt(2), 1.0), _sin(3.0, 1.0), np.full(N, 7.0)], axis=-1)
    assert paper.axis_rms(F, 0) == pytest.approx(0.5, rel=1e-12)  # A/√2
    assert paper.axis_rms(F, 2) == pytest.approx(7.0)  # a constant's RMS is itself


def test_axis_error_rms_and_plane_error_rms():
    ref = np.stack([_sin(80.0, 1.0), _sin(80.0, 1.0, math.pi / 2), np.zeros(N)], axis=-1)
    act = 0.9 * ref  # a circle 10 % small: the error vector has constant length 8 N
    assert paper.plane_error_rms(act, ref, (0, 1)) == pytest.approx(8.0, rel=1e-12)
    assert paper.axis_error_rms(act, ref, 0) == pytest.approx(8.0 / math.sqrt(2), rel=1e-12)
    assert paper.axis_error_rms(act, ref, 2) == 0.0


def _traces(position, hand, actuator, reference):
    ex = lambda a: a[:, None, :]  # noqa: E731  (ticks, batch 1, 3)
    return Traces(period=T, energy=np.zeros((N, 1)), saturated=np.zeros((N, 1), dtype=bool),
                  stop_tick=np.array([-1]), position=ex(position), velocity=ex(np.gradient(position, T, axis=0)),
                  hand_force=ex(hand), actuator_force=ex(actuator), force_reference=ex(reference))


def _report(prrr_paper, name, position, hand, actuator, reference):
    sc = load_scene(name)
    st = cl.setup(prrr_paper, sc)
    st = type(st)(**{**st.__dict__, "period": T, "ticks": N})
    return sc, cl.metrics_from_traces(_traces(position, hand, actuator, reference), st, 0)


@pytest.mark.parametrize("name, axis", [("free-space-x", 0), ("free-space-y", 1), ("free-space-x-2hz", 0),
                                        ("free-space-y-2hz", 1)])
def test_free_space_scenes_report_the_driven_axis_rms(prrr_paper, name, axis):
    """Fig 14: only the force along the driven axis counts (the other axes carry 3 N and 2 N here)."""
    hand = np.stack([_sin(1.0, 1.0), _sin(1.0, 1.0), _sin(1.0, 1.0)], axis=-1)
    hand[:, axis] = _sin(0.6, 2.0)  # RMS 0.6/√2 over the settled window (whole periods)
    hand[:, (axis + 1) % 3] = 3.0
    hand[:, (axis + 2) % 3] = 2.0
    sc, r = _report(prrr_paper, name, np.zeros((N, 3)), hand, np.zeros((N, 3)), np.zeros((N, 3)))
    assert sc.report.quantity == PaperQuantity.HAND_FORCE_AXIS_RMS and sc.report.axes == (axis,)
    assert r.paper_metric == pytest.approx(0.6 / math.sqrt(2), rel=1e-9)
    assert r.metrics()["paper_value"] == sc.report.value


def test_force_tracking_reports_the_fz_error(prrr_paper):
    """Fig 8: RMS of (F_z − F_z,r); an F_y error (paper 5.68 N) is a different number."""
    ref = np.stack([_sin(-57.7, 3.0), np.zeros(N), _sin(100.0, 3.0)], axis=-1)
    act = np.stack([_sin(-57.7, 3.0, end=True), np.zeros(N), _sin(100.0, 3.0, end=True)], axis=-1)
    act[:, 2] += _sin(5.0, 3.0, 1.0, end=True)
    act[:, 1] += 9.0
    _, r = _report(prrr_paper, "force-tracking", np.zeros((N, 3)), np.zeros((N, 3)), act, ref)
    assert r.paper_metric == pytest.approx(5.0 / math.sqrt(2), rel=1e-9)


@pytest.mark.parametrize("name, plane", [("force-circle-xy", (0, 1)), ("force-circle-xz", (0, 2))])
def test_force_circle_reports_the_plane_error(prrr_paper, name, plane):
    """Fig 9: a circle drawn 10 % small has a constant error |e| = 8 N: its RMS is 8 N."""
    ref = np.zeros((N, 3))
    ref[:, plane[0]], ref[:, plane[1]] = _sin(80.0, 1.0), _sin(80.0, 1.0, math.pi / 2)
    act = np.zeros((N, 3))
    act[:, plane[0]], act[:, plane[1]] = _sin(72.0, 1.0, end=True), _sin(72.0, 1.0, math.pi / 2, end=True)
    act[:, 3 - sum(plane)] += 4.0  # the off-plane axis does not count
    _, r = _report(prrr_paper, name, np.zeros((N, 3)), np.zeros((N, 3)), act, ref)
    assert r.paper_metric == pytest.approx(8.0, rel=1e-9)


def test_stiffness_scene_reports_the_fitted_error(prrr_paper):
    """Fig 15: a hand force 1.066 × 25 N/mm × x fits to 26.65 N/mm: error 6.6 %."""
    p = np.stack([_sin(4e-3, 1.0), np.zeros(N), np.zeros(N)], axis=-1)
    hand = 1.066 * 25e3 * p
    _, r = _report(prrr_paper, "stiffness-25", p, hand, np.zeros((N, 3)), np.zeros((N, 3)))
    assert r.paper_metric == pytest.approx(6.6, rel=1e-6)


def test_max_force_deviation_pct():
    """A 25 N/mm line over ±4 mm (peak 100 N) with a ±3 N square hysteresis: 3 % deviation."""
    p = np.stack([_sin(4e-3, 1.0), np.zeros(N), np.zeros(N)], axis=-1)
    F = 25e3 * p + 3.0 * np.sign(np.cos(2 * np.pi * t))[:, None] * np.array([1.0, 0.0, 0.0])
    assert paper.max_force_deviation_pct(F, p, 25e3, 0) == pytest.approx(3.0, rel=1e-9)
