"""``armbench demo``: a short run ends well and explains its PLC timing figures in plain words;
the explanation itself, for a calm and a loaded machine (the figures a loaded 2-core VM gave:
p99 2 ms, max 152 ms)."""

from __future__ import annotations

import re

import pytest

from armbench.cli import main
from armbench.demo import scan_report
from armbench.softplc.scan import Distribution, TaskStats

MS = 1_000_000


def stats(jitter_p50_ms: float, jitter_p99_ms: float, jitter_max_ms: float, scans: int,
          overruns: int) -> TaskStats:
    def dist(p50: float, p99: float, top: float) -> Distribution:
        return Distribution(scans, 0, p50 * MS, int(top * MS), int(p50 * MS), int(p99 * MS))

    return TaskStats("MainTask", 10 * MS, scans, overruns, dist(0.04, 0.2, 0.9),
                     dist(jitter_p50_ms, jitter_p99_ms, jitter_max_ms))


def test_a_loaded_machine_is_explained() -> None:
    text = "\n".join(scan_report(stats(0.06, 2.0, 152.0, scans=2386, overruns=14), 24.0, 1.2))
    head, *rest = text.splitlines()
    assert head == ("PLC task MainTask: 2386 scans every 10 ms = 23.86 s of the controller's "
                    "time in 24.00 s on the wall clock; execution mean 40 us, max 900 us; "
                    "start jitter p50 60 us, p99 2 ms, max 152 ms; overruns 14")
    assert rest and all(line.startswith("  ") and len(line) <= 96 for line in rest)
    words = " ".join(" ".join(rest).split())
    for said in ("The scan period, 10 ms (the TASK's INTERVAL), is how often the soft PLC runs",
                 "half the scans within p50, 99 in 100 within p99, max is the single worst",
                 "not a real-time runtime", "loaded or shared machine",
                 "the worst scan started 152 ms late, more than a period: the 14 releases "
                 "missed were skipped (overruns)", "controller's time is behind the wall clock",
                 "one fixed 10 ms step per scan (ScanPeriodS in Controller.st), in its own time",
                 "pauses the motion on the wall clock without making it jump (the largest "
                 "servo step in one scan was 1.200 deg)", "settle in simulated time",
                 "accuracy figures are the same on a busy machine",
                 "On a real PLC driving real servos the wall clock is the servos' clock"):
        assert said in words, said


def test_a_calm_machine_says_so() -> None:
    words = " ".join(" ".join(scan_report(stats(0.02, 0.3, 0.8, 500, 0), 5.0)).split())
    assert "Here even the worst scan started within the 10 ms period." in words
    assert "releases missed" not in words and "largest servo step" not in words


def test_durations_read_without_an_exponent() -> None:
    # a loaded machine's jitter reached 1.06e+03 ms in a run; a reader gets seconds instead
    from armbench.demo import _ms

    assert [_ms(v) for v in (5e5, 1.5e6, 152e6, 999.4e6, 1.06e9, 12345e9)] == [
        "500 us", "1.5 ms", "152 ms", "999 ms", "1.06 s", "12345 s"]


def test_a_short_demo_explains_its_figures(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["demo", "--points", "8", "--no-plots"]) == 0
    out = capsys.readouterr().out
    lines = out.splitlines()
    task = next(i for i, line in enumerate(lines) if line.startswith("PLC task MainTask: "))
    assert re.search(r"start jitter p50 [\d.]+ [um]?s, p99 [\d.]+ [um]?s, max [\d.]+ [um]?s",
                     lines[task]), lines[task]
    explained = " ".join(" ".join(lines[task + 1:]).split())
    assert "Jitter is how late a scan started" in explained, out
    assert "simulated time" in explained, out
