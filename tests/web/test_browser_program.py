"""The live view of a program that is not the arm controller, and its trace panel, in Debian's
chromium driven by Playwright.

tests/web/st/counter.st runs in the soft PLC. The page shows its located variables and their
values as they change; the trace panel samples the variables ticked, plots them, pauses, and
downloads its buffer as CSV, whose rows are checked against the program's own arithmetic
(Wave = SIN(Scans * 0.1) in float32) and against the samples the page holds.
"""

from __future__ import annotations

import csv
import math
import time
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest
from playwright.sync_api import APIResponse, Browser, Page, Route
from webview_helpers import COUNTER, get, post, serve_program, wait_for

from armbench.web.app import WebView
from armbench.web.variables import program_variables


def wave(scans: int) -> float:
    """The program's Wave for a scan count as the PLC computes it: the REAL literal 0.1 makes
    C compute the product in double (MatIEC's C), SIN takes it rounded to float32."""
    arg = np.float32(float(np.float32(scans)) * 0.1)
    return float(np.float32(math.sin(float(arg))))


@pytest.fixture(scope="module")
def counter_view() -> Iterator[WebView]:
    with serve_program([COUNTER]) as r, WebView(
            r.host, r.port, program=program_variables([COUNTER], "counter.st"), web_port=0,
            local_plc=r.plc) as w:
        wait_for(lambda: get(w, "api/state").get("connected") is True, "the view's first poll")
        yield w


@pytest.fixture()
def page(browser: Browser, counter_view: WebView) -> Iterator[Page]:
    pg = browser.new_page(viewport={"width": 1300, "height": 900}, accept_downloads=True)
    errors: list[str] = []
    pg.on("pageerror", lambda e: errors.append(str(e)))
    pg.goto(counter_view.url)
    # the table is built from the program's declarations before the first snapshot arrives;
    # the connection badge only changes with that snapshot
    pg.wait_for_function("window.armbench.info !== null && window.armbench.messages > 0 && "
                         "document.querySelectorAll('#registers tbody tr').length > 0",
                         timeout=15000)
    yield pg
    pg.close()
    assert errors == [], errors


def value(page: Page, name: str) -> str:
    return page.inner_text(f"#registers tr[data-name={name}] td.value")


def test_variables_of_another_program_shown_and_updated(page: Page) -> None:
    assert page.inner_text("#conn") == "connected"
    assert "counter.st" in page.inner_text("#progname")
    # no arm, no commands: the variables are the page
    assert page.is_hidden("#view-arm") and page.is_hidden("#commands")
    assert page.is_visible("#view-variables")
    names = page.eval_on_selector_all("#registers tbody tr", "rs => rs.map(r => r.dataset.name)")
    assert names == ["Wide", "Scans", "Wave", "Level", "Lamp", "Hold", "Inp"]
    row = page.inner_text("#registers tr[data-name=Wave]")
    assert "%MD1" in row and "holding 2050" in row and "REAL" in row and "SIN(Scans" in row
    assert value(page, "Hold") == "42.5" and value(page, "Wide") == "0.125"
    first = int(value(page, "Scans"))
    page.wait_for_function("n => +document.querySelector('#registers tr[data-name=Scans] "
                           "td.value').textContent > n + 20", arg=first, timeout=10000)
    assert "Flag (%MX0.0)" in page.inner_text("#unreachable")


def test_trace_select_plot_pause_and_download_csv(page: Page, counter_view: WebView,
                                                  tmp_path: Path) -> None:
    page.click("#views button[data-view=trace]")
    assert page.is_visible("#trace-plot")
    for name in ("Scans", "Wave"):
        page.check(f"#trace-vars input[value={name}]")
    page.wait_for_function("window.armbench.trace.rows.length > 200 && "
                           "+document.getElementById('trace-plot').dataset.drawn > 0",
                           timeout=15000)
    assert page.evaluate("window.armbench.trace.names") == ["Scans", "Wave"]
    assert page.inner_text("#trace-legend").count("Scans") == 1

    page.click("#trace-pause")
    assert page.inner_text("#trace-pause") == "Resume"
    held = page.evaluate("window.armbench.trace.rows.length")
    server_before = get(counter_view, "api/trace?since=0")["samples"][-1][0]
    time.sleep(0.5)
    # the server keeps sampling; the paused page shows and keeps what it had
    assert get(counter_view, "api/trace?since=0")["samples"][-1][0] > server_before + 20
    assert page.evaluate("window.armbench.trace.rows.length") == held

    with page.expect_download() as d:
        page.click("#trace-csv")
    path = tmp_path / d.value.suggested_filename
    d.value.save_as(path)
    assert path.suffix == ".csv"
    with path.open(newline="") as f:
        table = list(csv.reader(f))
    assert table[0] == ["time_s", "unix_time_s", "Scans", "Wave"]
    body = [[float(x) for x in r] for r in table[1:]]
    assert len(body) == held
    page_rows = page.evaluate("window.armbench.trace.rows")
    assert [r[2] for r in body] == [r[1] for r in page_rows]
    assert body[0][0] == 0.0
    assert all(b[0] > a[0] for a, b in zip(body, body[1:], strict=False))
    assert all(b[2] >= a[2] for a, b in zip(body, body[1:], strict=False))
    for r in body:
        assert r[1] - r[0] == pytest.approx(body[0][1], abs=1e-5)
        assert abs(r[1] - time.time()) < 60.0
        assert r[3] == pytest.approx(wave(int(r[2])), abs=1e-6)

    # resumed, the page catches up on what was sampled meanwhile, with no gap
    page.click("#trace-pause")
    page.wait_for_function("n => window.armbench.trace.rows.length > n + 50", arg=held)
    assert page.evaluate("window.armbench.trace.gaps") == 0


def test_two_boxes_ticked_before_the_first_answer_both_count(page: Page) -> None:
    """The trace's selection is what the user ticked, however slow the server answers: the
    second box ticked while the first box's request is still out must not drop the first."""
    held: list[Route] = []

    def hold(route: Route) -> None:
        if route.request.method == "POST":
            held.append(route)
        else:
            route.continue_()

    page.click("#views button[data-view=trace]")
    page.route("**/api/trace", hold)
    for name in ("Scans", "Wave"):
        page.check(f"#trace-vars input[value={name}]")
    deadline = time.monotonic() + 10.0
    while time.monotonic() < deadline:
        while held:
            held.pop(0).continue_()
        if page.evaluate("window.armbench.trace.names.length") == 2:
            break
        page.wait_for_timeout(50)
    page.unroute("**/api/trace")
    page.wait_for_timeout(300)  # a late answer would land here
    assert page.evaluate("window.armbench.trace.names") == ["Scans", "Wave"]
    assert page.is_checked("#trace-vars input[value=Scans]")


def test_a_sample_answer_from_before_a_new_selection_is_dropped(page: Page,
                                                               counter_view: WebView) -> None:
    """A poll that the server answered under the previous selection and that arrives after the
    page took the new one is stale: it must not bring the old selection back (it did, until
    the next poll, and a test waiting for samples could see the old variables)."""
    status, answer = post(counter_view, {"variables": ["Scans"]}, path="api/trace")
    assert status == 200 and answer["ok"], answer
    page.click("#views button[data-view=trace]")
    page.wait_for_function("window.armbench.trace.names.join() === 'Scans'")
    stale: list[tuple[Route, APIResponse]] = []
    later: list[Route] = []
    released: list[bool] = []

    def polls(url: str) -> bool:
        return "/api/trace?" in url

    def hold(route: Route) -> None:
        if released:
            route.continue_()
        elif not stale:
            stale.append((route, route.fetch()))  # answered now, under the one-variable trace
        else:
            later.append(route)  # the polls after it wait until the end

    page.route(polls, hold)
    for _ in range(500):  # Playwright calls the handler while the page waits, not in a sleep
        if stale:
            break
        page.wait_for_timeout(20)
    assert stale, "no poll for samples in 10 s"
    page.check("#trace-vars input[value=Wave]")
    page.wait_for_function("window.armbench.trace.names.length === 2")
    route, answer = stale[0]
    route.fulfill(response=answer)
    page.wait_for_timeout(300)  # the stale answer is handled; the next poll waits in `later`
    try:
        assert page.evaluate("window.armbench.trace.names") == ["Scans", "Wave"]
        assert page.is_checked("#trace-vars input[value=Scans]")
        assert page.is_checked("#trace-vars input[value=Wave]")
    finally:
        released.append(True)
        for r in later:
            r.continue_()
        page.unroute(polls)
