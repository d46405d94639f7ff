"""The live view of the arm controller in a real headless browser: Debian's chromium driven by
Playwright.

The page loads and draws; the drawing follows a MoveXyz and a straight line sent by another
Modbus client (the joint angles the page drew are read from the canvas, compared with the
numpy reference IK); pressing the page's buttons moves the arm (output stage at once, the
plant's servos after); a rejected command and bad input show in the header banner, which stays
in view; the commands sit in tabs. A screenshot goes to the test's tmp_path.
"""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import pytest
from playwright.sync_api import Browser, Page
from webview_helpers import get

from armbench.controller_client import ArmControllerClient
from armbench.demo import RunningPlc
from armbench.plant import arm
from armbench.web.app import WebView
from armbench.web.commands import GROUPS

PWM_STEP_DEG = 0.6


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


def show(page: Page, command: str) -> str:
    """Open the tab holding a command's form; its selector."""
    form = f"form[data-command={command}]"
    group = page.get_attribute(form, "data-group")
    if group:
        page.click(f"#cmdtabs button[data-group='{group}']")
    return form


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


def in_view(page: Page, selector: str) -> bool:
    return bool(page.eval_on_selector(selector, "e => { const r = e.getBoundingClientRect();"
                                      " return r.height > 0 && r.top >= 0 &&"
                                      " r.bottom <= window.innerHeight; }"))


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


def test_commands_are_grouped_in_tabs(page: Page, web: WebView) -> None:
    table = {c["name"]: c["group"] for c in get(web, "api/commands")["commands"]}
    tabs = page.eval_on_selector_all("#cmdtabs button", "bs => bs.map(b => b.dataset.group)")
    assert tabs == [g for g in GROUPS if g in table.values()]

    def visible() -> set[str]:
        return set(page.eval_on_selector_all(
            "form.cmd", "fs => fs.filter(f => f.offsetParent !== null)"
                        ".map(f => f.dataset.command)"))
    always = {n for n, g in table.items() if g == ""}
    assert always == {"CmdStop"}
    for group in tabs:
        page.click(f"#cmdtabs button[data-group='{group}']")
        assert visible() == {n for n, g in table.items() if g in (group, "")}, group
        assert page.get_attribute(f"#cmdtabs button[data-group='{group}']",
                                  "aria-selected") == "true"


def test_drawing_follows_another_clients_move_xyz(page: Page,
                                                  other: ArmControllerClient) -> None:
    for target in [(160.0, -30.0, 90.0), (120.0, 60.0, 150.0)]:
        st = other.move_xyz(*target)
        assert st.error_id == 0
        expected = arm.inverse(*target, elbow_up=True)
        wait_drawn(page, "plc", expected, 1e-3)


def test_drawing_follows_a_straight_line(page: Page, other: ArmControllerClient) -> None:
    """A MoveLinear moves no BaseDeg..: the orange arm is the output stage, so it ends on the
    reference IK of the line's target; the motion's end shows in the header."""
    assert other.move_joints(0.0, 70.0, 65.0, wait=True).error_id == 0
    target = (170.0, 40.0, 100.0)
    assert other.move_linear(target, 100.0, 500.0, wait=True).error_id == 0
    wait_drawn(page, "plc", arm.inverse(*target, elbow_up=True), 1e-2)
    tool = [float(v) for v in (page.get_attribute("#arm", "data-tool") or "").split(",")]
    assert tool == pytest.approx(target, abs=0.05)
    page.wait_for_function("document.getElementById('motionstate').textContent"
                           ".startsWith('Line done')")


def test_buttons_move_the_arm_and_the_banner_shows_results(page: Page, running: RunningPlc,
                                                           tmp_path: Path) -> None:
    page.click(show(page, "CmdInitPwm") + " button")
    page.wait_for_function("window.armbench.lastResult && window.armbench.lastResult.ok")
    form = show(page, "CmdMoveJoints")
    page.fill(f"{form} input[name=base]", "25")
    page.fill(f"{form} input[name=shoulder]", "80")
    page.fill(f"{form} input[name=elbow]", "100")
    page.click(f"{form} button")
    wait_drawn(page, "plc", (25.0, 80.0, 100.0), 1e-3)
    # the plant's servos get there at their rated speed, within one PWM step
    wait_drawn(page, "plant", (25.0, 80.0, 100.0), PWM_STEP_DEG)
    assert "done" in (page.get_attribute("#lastcmd", "class") or "")
    assert "Move joints: result 0 NoError" in page.inner_text("#lastcmd")

    # a command the PLC rejects: in the banner and as a fault event, the arm stays put
    xyz = show(page, "CmdMoveXyz")
    page.fill(f"{xyz} input[name=x]", "400")
    page.fill(f"{xyz} input[name=y]", "0")
    page.fill(f"{xyz} input[name=z]", "0")
    page.click(f"{xyz} button")
    page.wait_for_function("document.getElementById('lastcmd').className.includes('error')")
    assert "Move to X/Y/Z: result 1 Unreachable" in page.inner_text("#lastcmd")
    page.wait_for_function("[...document.querySelectorAll('#events li.fault')]"
                           ".some(li => li.textContent.includes('Unreachable'))")
    assert drawn(page, "plc") == pytest.approx([25.0, 80.0, 100.0], abs=1e-3)
    # the banner is in view wherever the page is scrolled to
    page.evaluate("window.scrollTo(0, document.body.scrollHeight)")
    assert page.evaluate("window.scrollY") > 0
    assert in_view(page, "#lastcmd")

    # bad input: a message in the banner, nothing sent
    page.fill(f"{xyz} input[name=x]", "twelve")
    page.click(f"{xyz} button")
    page.wait_for_function("document.getElementById('lastcmd').textContent.includes('twelve')")
    assert "Move to X/Y/Z: X must be a number, got 'twelve'" in page.inner_text("#lastcmd")
    page.fill(f"{xyz} input[name=x]", "NaN")
    page.click(f"{xyz} button")
    page.wait_for_function("document.getElementById('lastcmd').textContent.includes('finite')")
    assert drawn(page, "plc") == pytest.approx([25.0, 80.0, 100.0], abs=1e-3)

    # a motion that ends in an error is a fault in the banner while it stands
    jog = show(page, "CmdJogStart")
    page.click(f"{jog} button")
    page.wait_for_function("document.getElementById('faults').textContent"
                           ".includes('JogTimeout')", timeout=10000)
    assert in_view(page, "#faults")

    page.evaluate("window.scrollTo(0, 0)")
    shot = tmp_path / "web-view.png"
    page.screenshot(path=str(shot))
    assert shot.stat().st_size > 10_000
    print(f"screenshot: {shot}")
