"""hapticopt.analysis.loop.traces.tracking_pair and the metrics that read it: seed 002's tracking error
e(t) = F_d(t) − F(t) is taken at one instant.

Closed form: a sampled first-order force loop F_{k+1} = a F_k + (1 − a) F_d,k has H(z) = (1 − a)/(z − a)
(F = H F_d). The traces record F at the end of tick k (F_{k+1}) beside the reference of tick k (F_d,k), so
the same-instant error of a sine F_d = A sin ωkT is, in the steady state, A |1 − H(e^{jωT})| (RMS ÷ √2);
pairing each record with itself gives A |1 − e^{jωT} H(e^{jωT})| instead, the force one tick late.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from hapticopt.analysis.loop.scene import load_scene
from hapticopt.analysis.loop.traces import Traces, tracking_pair
from hapticopt.analysis.prrr.loop import closed_loop as cl

T, N = 1e-3, 3000  # 3 s at 1 kHz: whole periods of 3 Hz over the settled window (0.5 s … 3 s)
A, F_HZ, POLE = 100.0, 3.0, 0.9  # Fig 8's amplitude and frequency; a = 0.9: a 9.5 ms time constant


def _first_order_traces(axis: int) -> Traces:
    k = np.arange(N)
    ref = np.zeros((N, 3))
    ref[:, axis] = A * np.sin(2 * np.pi * F_HZ * k * T)
    F = np.zeros((N + 1, 3))  # F[k] = F(kT), F(0) = 0
    for i in range(N):
        F[i + 1] = POLE * F[i] + (1 - POLE) * ref[i]
    ex = lambda a: a[:, None, :]  # noqa: E731  (ticks, batch 1, 3)
    return Traces(period=T, energy=np.zeros((N, 1)), saturated=np.zeros((N, 1), dtype=bool),
                  stop_tick=np.array([-1]), position=ex(np.zeros((N, 3))), velocity=ex(np.zeros((N, 3))),
                  hand_force=ex(np.zeros((N, 3))), actuator_force=ex(F[1:]), force_reference=ex(ref))


def _H(z: complex) -> complex:
    return (1 - POLE) / (z - POLE)


def test_tracking_pair_aligns_the_reference_with_the_force_at_its_instant():
    tr = _first_order_traces(2)
    F, Fr = tracking_pair(tr, slice(0, 10))
    assert F.shape == Fr.shape == (9, 3)  # F(0) is not recorded: the window starts at tick 1
    # F(kT) = a F((k−1)T) + (1 − a) F_d((k−1)T): the pair at tick k is F(kT), F_d(kT)
    assert F[1, 2] == pytest.approx(POLE * F[0, 2] + (1 - POLE) * tr.force_reference[1, 0, 2], rel=1e-12)
    assert np.array_equal(Fr, tr.force_reference[1:10, 0])


def test_force_tracking_metric_is_the_same_instant_error_of_a_known_loop(prrr_paper):
    """Fig 8's metric on the first-order loop: A|1 − H|/√2 (derived above), not A|1 − zH|/√2."""
    z = np.exp(2j * np.pi * F_HZ * T)
    expected = A * abs(1 - _H(z)) / math.sqrt(2)
    one_tick_late = A * abs(1 - z * _H(z)) / math.sqrt(2)
    assert expected / one_tick_late > 1.1  # the two readings differ (11 %) by far more than the tolerance below
    sc = load_scene("force-tracking")
    st = cl.setup(prrr_paper, sc)
    st = type(st)(**{**st.__dict__, "period": T, "ticks": N})
    r = cl.metrics_from_traces(_first_order_traces(2), st, 0)
    # the transient a^k has decayed (0.9^500 ≈ 1e-23) by the settled window's start (0.5 s)
    assert r.paper_metric == pytest.approx(expected, rel=1e-6)
    assert r.force_tracking_rms == pytest.approx(expected, rel=1e-6)  # the one error, on every axis (only z moves)


def test_force_circle_metric_is_the_same_instant_error_of_a_known_loop(prrr_paper):
    """Fig 9's plane error on the first-order loop, x and y 90° apart: |e| is constant, A|1 − H| (derived above)."""
    k = np.arange(N)
    tr = _first_order_traces(0)
    ref = tr.force_reference[:, 0].copy()
    ref[:, 1] = A * np.cos(2 * np.pi * 1.0 * k * T)
    ref[:, 0] = A * np.sin(2 * np.pi * 1.0 * k * T)
    F = np.zeros((N + 1, 3))
    for i in range(N):
        F[i + 1] = POLE * F[i] + (1 - POLE) * ref[i]
    tr = Traces(**{**tr.__dict__, "actuator_force": F[1:, None, :], "force_reference": ref[:, None, :]})
    sc = load_scene("force-circle-xy")
    st = cl.setup(prrr_paper, sc)
    st = type(st)(**{**st.__dict__, "period": T, "ticks": N})
    r = cl.metrics_from_traces(tr, st, 0)
    z = np.exp(2j * np.pi * 1.0 * T)
    assert r.paper_metric == pytest.approx(A * abs(1 - _H(z)), rel=1e-6)
