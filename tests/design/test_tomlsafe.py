"""The bounded reader and parser of user TOML (issue 37: an 8 GB file was read whole before the size check)."""

from __future__ import annotations

import time

import pytest
from typer.testing import CliRunner

from hapticopt.design import io, tomlsafe
from hapticopt.design.errors import InputFileError
from hapticopt.optim.cli import app


def test_a_huge_file_is_refused_by_its_size_before_it_is_read(tmp_path):
    big = tmp_path / "big.toml"
    with open(big, "wb") as fh:
        fh.truncate(8 << 30)  # sparse: 8 GiB long, no blocks written
    t0 = time.monotonic()
    with pytest.raises(InputFileError, match=r"is 8589934592 bytes long: allowed at most 1000000 bytes"):
        io.load_design(big)
    assert time.monotonic() - t0 < 2.0
    res = CliRunner().invoke(app, ["evaluate", str(big)])
    assert res.exit_code == 2 and res.stderr.count("\n") == 1 and "8589934592 bytes long" in res.stderr


def test_the_limit_is_the_module_constant(tmp_path, monkeypatch):
    path = tmp_path / "d.toml"
    path.write_text("a = 1\n")  # 6 bytes
    monkeypatch.setattr(tomlsafe, "MAX_BYTES", 3)
    with pytest.raises(InputFileError, match="bytes long: allowed at most 3 bytes"):
        tomlsafe.read_text(path, source="design file d.toml")


def test_text_that_is_not_utf8_is_one_line(tmp_path):
    path = tmp_path / "d.toml"
    path.write_bytes(b"name = '\xff'\n")
    with pytest.raises(InputFileError, match="is not UTF-8 text"):
        tomlsafe.read_text(path, source="design file d.toml")


@pytest.mark.parametrize("text, key", [("[geometry]\nbeta_deg = 1" + "0" * 5000 + "\n", "geometry.beta_deg"),
                                       ("name = 'x'\nlist = [1, " + "9" * 5000 + "]\n", "list")])
def test_a_5000_digit_integer_names_its_key(text, key):
    """Issue 37: the error named the file, not the key (tomllib refuses to convert > 4300 digits)."""
    with pytest.raises(InputFileError, match=rf"d.toml: {key} = an integer of more than 4300 digits"):
        tomlsafe.loads(text, source="d.toml")
