"""SQLite files checked before they are trusted (issue 37): checksums, links, time-limited readers."""

from __future__ import annotations

import sqlite3
import time

import pytest

from hapticopt.design.errors import InputFileError
from hapticopt.optim.sqlite_checks import check_db_paths, connect_readonly, restart_clock, row_checksum


def test_row_checksum_is_exact_and_order_sensitive():
    assert row_checksum("a", "1.0") != row_checksum("a", "1.00")  # the stored text, not its value
    assert row_checksum("a", "b") != row_checksum("b", "a")
    assert row_checksum("a", None) == row_checksum("a", None)


def test_a_recursive_query_is_interrupted_by_the_time_limit(tmp_path):
    path = tmp_path / "d.sqlite"
    with sqlite3.connect(path) as db:
        db.execute("CREATE VIEW endless AS WITH RECURSIVE c(x) AS (SELECT 1 UNION ALL SELECT x + 1 FROM c) "
                   "SELECT x FROM c")
    db = connect_readonly(path, limit_s=0.5)
    t0 = time.monotonic()
    with pytest.raises(sqlite3.OperationalError, match="interrupted"):
        db.execute("SELECT count(*) FROM endless").fetchall()
    assert time.monotonic() - t0 < 3.0
    restart_clock(db)
    assert db.execute("SELECT 1").fetchone() == (1,)  # the next query gets its full time again
    with pytest.raises(sqlite3.OperationalError, match="readonly"):
        db.execute("CREATE TABLE t (a)")
    db.close()


@pytest.mark.parametrize("suffix", ["", "-wal", "-shm", "-journal"])
def test_a_link_at_a_database_or_its_side_files_is_refused(tmp_path, suffix):
    (tmp_path / f"d.sqlite{suffix}").symlink_to(tmp_path / "nowhere")
    with pytest.raises(InputFileError, match="symbolic link"):
        check_db_paths(tmp_path / "d.sqlite")
