"""``armbench demo-imu``: bad options are one-line usage errors (rc 2); a short run prints the
per-second table and a summary whose figures are within the bounds of
tests/controller/test_follow.py."""

from __future__ import annotations

import re

import pytest

from armbench.cli import main


@pytest.mark.parametrize(("argv", "option"), [
    (["--seconds", "0"], "--seconds"),
    (["--seconds", "nan"], "--seconds"),
    (["--heading", "400"], "--heading"),
    (["--rate", "33"], "--rate"),
    (["--rate", "-100"], "--rate"),
    (["--seed", "-1"], "--seed"),
])
def test_usage_errors(argv: list[str], option: str, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["demo-imu", *argv]) == 2
    out, err = capsys.readouterr()
    assert out == ""
    lines = err.strip().splitlines()
    assert len(lines) == 1 and option in lines[0] and "error" in lines[0], err


def test_short_run(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["demo-imu", "--seconds", "4"]) == 0
    out = capsys.readouterr().out
    rows = [ln for ln in out.splitlines() if re.match(r"^\s+\d+\.0\s", ln)]
    assert len(rows) == 5  # t = 0, 1, 2, 3, 4 s
    m = re.search(r"95 % ([\d.]+) deg, max ([\d.]+) deg; held point drift max ([\d.]+) mm",
                  out)
    assert m is not None, out
    assert float(m.group(1)) < 3.5 and float(m.group(2)) < 5.0 and float(m.group(3)) < 5.0
