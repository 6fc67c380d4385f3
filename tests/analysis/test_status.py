"""``analysis/status.py``: which statuses keep their numbers, and the words of older records."""

from __future__ import annotations

import pytest

from hapticopt.analysis.status import LEGACY, Status, upgrade


def test_ok_and_the_requirement_statuses_keep_their_numbers():
    # not-met / collides / empty: computed, the requirement misses (the optimiser steers on them)
    assert {s for s in Status if s.metrics_hold} == {Status.OK, Status.NOT_MET, Status.COLLIDES, Status.EMPTY}
    for s in (Status.NOT_ASSEMBLABLE, Status.SINGULAR, Status.ILL_CONDITIONED, Status.NOT_POSITIVE_DEFINITE,
              Status.UNSTABLE, Status.INCONCLUSIVE, Status.FAILED):
        assert not s.metrics_hold, s


def test_the_status_words_renderers_see():
    # the exact strings of run records, --json and the reports (other branches' renderers match them)
    assert [str(s) for s in Status] == ["ok", "not-met", "collides", "empty", "not-assemblable", "singular",
                                        "ill-conditioned", "not-positive-definite", "unstable", "inconclusive",
                                        "failed"]


def test_older_records_read_back_with_todays_words():
    assert Status.parse("infeasible") is Status.NOT_MET
    assert Status.parse("collides") is Status.COLLIDES
    assert upgrade({"free_workspace": "infeasible", "statics": "ok", "x": "someday"}) == {
        "free_workspace": "not-met", "statics": "ok", "x": "someday"}  # unknown words are shown as written
    assert set(LEGACY) == {"infeasible"}
    with pytest.raises(ValueError):
        Status.parse("someday")
