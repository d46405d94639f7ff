"""The live view in a real headless browser: Debian's chromium driven by Playwright.

The page loads and draws; the drawing follows a MoveXyz sent by another Modbus client (the
joint angles the page drew are read from the canvas, compared with the numpy reference IK);
pressing the page's buttons moves the arm (PLC setpoint at once, the plant's servos after);
a rejected command and bad input show on the page. A screenshot goes to the test's tmp_path.

scripts/setup.sh installs chromium with apt-get where it is missing; Playwright is pointed at
that browser (``playwright install`` would download one, which these machines cannot).
"""

from __future__ import annotations

import shutil
from collections.abc import Iterator
from pathlib import Path

import pytest
from playwright.sync_api import Browser, Page, sync_playwright
from webview_helpers import get

from armbench.controller_client import ArmControllerClient
from armbench.demo import RunningPlc
from armbench.plant import arm
from armbench.web.app import WebView

PWM_STEP_DEG = 0.6


def chromium_path() -> str | None:
    for name in ("chromium", "chromium-browser"):
        found = shutil.which(name)
        if found:
            return found
    return None


@pytest.fixture(scope="module")
def browser() -> Iterator[Browser]:
    path = chromium_path()
    if path is None:
        pytest.skip("chromium is not installed and could not be: scripts/setup.sh installs it "
                    "with apt-get (Debian package chromium) where apt-get runs as root")
    with sync_playwright() as p:
        b = p.chromium.launch(executable_path=path, args=["--no-sandbox"])
        yield b
        b.close()


@pytest.fixture()
def page(browser: Browser, web: WebView) -> Iterator[Page]:
    pg = browser.new_page(viewport={"width": 1300, "height": 1000})
    errors: list[str] = []
    pg.on("pageerror", lambda e: errors.append(str(e)))
    pg.goto(web.url)
    pg.wait_for_function("window.armbench.frames > 2 && document.querySelector("
                         "'form[data-command=CmdMoveXyz]') !== null", timeout=15000)
    yield pg
    pg.close()
    assert errors == [], errors  # no script error on the page


def drawn(page: Page, which: str) -> list[float]:
    """The joint angles the page drew last (the canvas carries them)."""
    text = page.get_attribute("#arm", f"data-{which}-joints")
    assert text
    return [float(v) for v in text.split(",")]


def wait_drawn(page: Page, which: str, expected: tuple[float, ...], tol: float) -> None:
    js = ("([w, e, tol]) => { const t = document.getElementById('arm').dataset[w + 'Joints'];"
          " if (!t) return false; const a = t.split(',').map(Number);"
          " return a.length === 3 && a.every((v, i) => Math.abs(v - e[i]) <= tol); }")
    page.wait_for_function(js, arg=[which, list(expected), tol], timeout=15000)


def test_page_loads(page: Page, web: WebView) -> None:
    assert page.title() == "armbench live view"
    assert page.inner_text("#conn") == "connected"
    assert page.inner_text("#plcstate") == "RUNNING"
    names = page.eval_on_selector_all("form.cmd", "fs => fs.map(f => f.dataset.command)")
    assert {"CmdMoveXyz", "CmdMoveJoints", "CmdInitPwm", "CmdRelax", "CmdSolveBatch"} <= set(names)
    assert page.eval_on_selector_all("#mailboxes tbody tr", "rs => rs.length") == 16
    assert page.eval_on_selector_all("#channels tbody tr", "rs => rs.length") == 16
    page.wait_for_function("document.querySelectorAll('#registers tbody tr').length > 100")
    # the drawing shows what the server polled
    state = get(web, "api/state")
    assert drawn(page, "plc") == pytest.approx(state["joints"]["plc"], abs=1e-3)


def test_drawing_follows_another_clients_move_xyz(page: Page,
                                                  other: ArmControllerClient) -> None:
    for target in [(160.0, -30.0, 90.0), (120.0, 60.0, 150.0)]:
        st = other.move_xyz(*target)
        assert st.error_id == 0
        expected = arm.inverse(*target, elbow_up=True)
        wait_drawn(page, "plc", expected, 1e-3)


def test_buttons_move_the_arm_and_faults_show(page: Page, running: RunningPlc,
                                              tmp_path: Path) -> None:
    page.click("form[data-command=CmdInitPwm] button")
    page.wait_for_function("window.armbench.lastResult && window.armbench.lastResult.ok")
    form = "form[data-command=CmdMoveJoints]"
    page.fill(f"{form} input[name=base]", "25")
    page.fill(f"{form} input[name=shoulder]", "80")
    page.fill(f"{form} input[name=elbow]", "100")
    page.click(f"{form} button")
    wait_drawn(page, "plc", (25.0, 80.0, 100.0), 1e-3)
    # the plant's servos get there at their rated speed, within one PWM step
    wait_drawn(page, "plant", (25.0, 80.0, 100.0), PWM_STEP_DEG)
    assert "done" in (page.get_attribute("#cmdmsg", "class") or "")

    # a command the PLC rejects: message and a fault event, the arm stays where it is
    xyz = "form[data-command=CmdMoveXyz]"
    page.fill(f"{xyz} input[name=x]", "400")
    page.fill(f"{xyz} input[name=y]", "0")
    page.fill(f"{xyz} input[name=z]", "0")
    page.click(f"{xyz} button")
    page.wait_for_function("document.getElementById('cmdmsg').className === 'error'")
    assert "Unreachable" in page.inner_text("#cmdmsg")
    page.wait_for_function("[...document.querySelectorAll('#events li.fault')]"
                           ".some(li => li.textContent.includes('Unreachable'))")
    assert drawn(page, "plc") == pytest.approx([25.0, 80.0, 100.0], abs=1e-3)

    # bad input: a message on the page, nothing sent
    page.fill(f"{xyz} input[name=x]", "twelve")
    page.click(f"{xyz} button")
    page.wait_for_function("document.getElementById('cmdmsg').textContent.includes('twelve')")
    msg = page.inner_text("#cmdmsg")
    assert msg == "Move to X/Y/Z: X must be a number, got 'twelve'"
    page.fill(f"{xyz} input[name=x]", "NaN")
    page.click(f"{xyz} button")
    page.wait_for_function("document.getElementById('cmdmsg').textContent.includes('finite')")
    assert drawn(page, "plc") == pytest.approx([25.0, 80.0, 100.0], abs=1e-3)

    shot = tmp_path / "web-view.png"
    page.screenshot(path=str(shot))
    assert shot.stat().st_size > 10_000
    print(f"screenshot: {shot}")
