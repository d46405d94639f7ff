"""The live view's JSON endpoints, WebSocket and command path against the soft PLC.

Values are checked against an independent Modbus client of the same PLC and against the
numpy reference kinematics (armbench.plant.arm), not against the view's own output.
"""

from __future__ import annotations

import json
import math
import re
import socket
import subprocess
import sys
import time
import urllib.request
from typing import Any

import pytest
from websockets.sync.client import connect
from webview_helpers import get, post, wait_for

from armbench.controller_client import ArmControllerClient
from armbench.demo import RunningPlc, serve_controller
from armbench.faults import PlcFault
from armbench.plant import arm
from armbench.registermap import controller_constants, controller_map
from armbench.softplc import modbus_map as mm
from armbench.softplc.modbus_client import PlcClient
from armbench.web.app import WS_WINDOW, WebView, exposure_warning
from armbench.web.commands import COMMANDS, CommandSpec, CommandTable, Field

PWM_STEP_DEG = 0.6  # one 12-bit count is 4.88 us, 0.59 deg of MG996R travel


def read(running: RunningPlc, name: str) -> float:
    """A controller register read by a client of our own (not the view's)."""
    reg = controller_map()[name.upper()]
    with PlcClient(running.host, running.port) as plc:
        words = plc.read_holding_registers(reg.address, reg.count)
    t = reg.st_type.upper()
    return (mm.words_to_real(words) if t == "REAL" else mm.words_to_udint(words)
            if t == "UDINT" else mm.words_to_dint(words) if t == "DINT" else words[0])


def channel_words(running: RunningPlc) -> list[int]:
    with PlcClient(running.host, running.port) as plc:
        return plc.read_holding_registers(controller_map()["CH00OFF"].address, 16)


def test_state_follows_the_plc(web: WebView, running: RunningPlc) -> None:
    a = get(web, "api/state")
    time.sleep(0.3)
    b = get(web, "api/state")
    assert a["connected"] and b["connected"]
    assert b["seq"] > a["seq"] and b["scan_count"] > a["scan_count"]
    assert b["plc"]["state"] == "RUNNING" and b["plc"]["fault"] is None
    assert b["plc"]["tasks"][0]["interval_ms"] == pytest.approx(10.0)
    assert abs(read(running, "ScanCount") - b["scan_count"]) < 100  # same counter, ~1 s apart
    assert len(b["mailboxes"]) == controller_constants()["MailboxMax"]
    assert [c["channel"] for c in b["channels"]] == list(range(16))


def test_commands_table_comes_from_the_controller(web: WebView) -> None:
    cmds = {c["name"]: c for c in get(web, "api/commands")["commands"]}
    k = controller_constants()
    for name in ("CmdMoveXyz", "CmdMoveJoints", "CmdInitPwm", "CmdRelax", "CmdSolveBatch"):
        assert cmds[name]["code"] == k[name]
    assert [f["slot"] for f in cmds["CmdMoveXyz"]["fields"]] == ["Arg1", "Arg2", "Arg3", "Int1"]


def test_a_new_command_is_one_table_entry() -> None:
    jog = CommandSpec("CmdJogTest", "Jog", "a command the controller may add",
                      (Field("speed", "Speed", "Arg1", unit="mm/s"),
                       Field("axis", "Axis", "Int1", "choice", 0, choices=((0, "x"), (1, "y")))))
    without = CommandTable(specs=(*COMMANDS, jog))
    assert "CmdJogTest" not in [c["name"] for c in without.describe()]
    with_it = CommandTable(specs=(*COMMANDS, jog),
                           constants={**controller_constants(), "CmdJogTest": 11})
    assert [c for c in with_it.describe() if c["name"] == "CmdJogTest"][0]["code"] == 11
    p = with_it.prepare("CmdJogTest", {"speed": "12.5", "axis": 1})
    assert (p.code, p.ints, p.args) == (11, (1, 0), (12.5,))


def test_move_xyz_moves_setpoints_and_plant(web: WebView, running: RunningPlc) -> None:
    status, answer = post(web, {"name": "CmdInitPwm", "fields": {}})
    assert status == 200 and answer["ok"], answer
    target = (150.0, 20.0, 100.0)
    status, answer = post(web, {"name": "CmdMoveXyz",
                                "fields": {"x": "150", "y": 20, "z": " 100 ", "elbow": "0"}})
    assert status == 200 and answer["ok"] and answer["result"] == 0, answer
    expected = arm.inverse(*target, elbow_up=True)
    plc = [read(running, f"{j}Deg") for j in ("Base", "Shoulder", "Elbow")]
    assert plc == pytest.approx(expected, abs=1e-3)

    def settled() -> bool:
        s = get(web, "api/state")
        # MoveXyz is a motion of many scans: the PWM words change until the PLC says done
        return (read(running, "MotionBusy") == 0
                and s["joints"]["plc"] == pytest.approx(expected, abs=1e-3)
                and s["joints"]["plant"] == pytest.approx(expected, abs=PWM_STEP_DEG)
                and not any(s["plant"]["moving"]))
    wait_for(settled, "the plant to follow the MoveXyz")
    # the view polls: its next snapshot after the motion ended shows the final words
    wait_for(lambda: [c["word"] for c in get(web, "api/state")["channels"][:3]]
             == channel_words(running)[:3], "the view's channel words to be the PLC's")
    s = get(web, "api/state")
    assert s["points"]["plc"][3] == pytest.approx(target, abs=0.01)
    # the achieved tool point: within what the PWM step allows (demo: 1.6 mm)
    assert math.dist(s["points"]["plant"][3], target) < 2.5
    assert s["plant"]["pca_running"] and s["controller"]["pwm_ready"]


@pytest.mark.parametrize("fields, message", [
    ({"x": "abc", "y": 0, "z": 120}, "X must be a number, got 'abc'"),
    ({"x": "NaN", "y": 0, "z": 120}, "X must be a finite number"),
    ({"x": 150, "y": "-inf", "z": 120}, "Y must be a finite number"),
    ({"x": 150, "y": 0, "z": ""}, "Z is empty"),
    ({"x": None, "y": 0, "z": 120}, "X must be a number, got None"),
    ({"x": True, "y": 0, "z": 120}, "X must be a number, got True"),
    ({"x": [1], "y": 0, "z": 120}, "X must be a number, got list"),
    ({"x": "1e40", "y": 0, "z": 120}, "X must be within"),
    ({"x": 150, "y": 0, "z": 120, "elbow": 2}, "Elbow must be one of 0 (elbow up)"),
    ({"x": 150, "y": 0, "z": 120, "elbow": "0.5"}, "Elbow must be a whole number"),
    ({"x": 150, "y": 0, "z": 120, "speed": 3}, "unknown field(s) speed"),
])
def test_bad_input_is_a_message_and_sends_nothing(web: WebView, running: RunningPlc,
                                                  fields: dict[str, Any], message: str) -> None:
    answered = read(running, "CommandsAnswered")
    words = channel_words(running)
    status, answer = post(web, {"name": "CmdMoveXyz", "fields": fields})
    assert status == 400 and not answer["ok"]
    assert answer["message"].startswith("Move to X/Y/Z: ") and message in answer["message"]
    assert "Traceback" not in answer["message"]
    assert read(running, "CommandsAnswered") == answered  # nothing reached a mailbox
    assert channel_words(running) == words  # no servo moved


@pytest.mark.parametrize("body, raw, message", [
    ({"name": "CmdFly", "fields": {}}, None, "unknown command 'CmdFly'"),
    ({"fields": {}}, None, "command name must be text"),
    ([1, 2], None, "must be a JSON object"),
    (None, b"{not json", "must be JSON"),
    ({"name": "CmdMoveJoints", "fields": [1, 2, 3]}, None, "must be an object"),
    ({"name": "CmdSolveBatch", "fields": {"points": "1 2\n"}}, None, "line 1 needs 3 numbers"),
    ({"name": "CmdSolveBatch", "fields": {"points": "1 2 nan"}}, None, "3 finite numbers"),
    ({"name": "CmdSolveBatch", "fields": {"points": "\n\n"}}, None, "give 1..32 points, got 0"),
    ({"name": "CmdSolveBatch", "fields": {"points": "150 0 120\n" * 33}}, None, "got 33"),
])
def test_bad_requests(web: WebView, body: object, raw: bytes | None, message: str) -> None:
    status, answer = post(web, body, raw)
    assert status == 400 and message in answer["message"], answer


def test_rejected_command_is_a_fault_event(web: WebView, running: RunningPlc) -> None:
    before = [read(running, f"{j}Deg") for j in ("Base", "Shoulder", "Elbow")]
    status, answer = post(web, {"name": "CmdMoveXyz", "fields": {"x": 400, "y": 0, "z": 0}})
    unreachable = controller_constants()["Err.Unreachable"]
    assert status == 200 and not answer["ok"] and answer["result"] == unreachable
    assert answer["result_name"] == "Unreachable"
    assert [read(running, f"{j}Deg") for j in ("Base", "Shoulder", "Elbow")] == before
    wait_for(lambda: any(e["kind"] == "fault" and "Unreachable" in e["text"]
                         for e in get(web, "api/state")["events"]), "the fault event")


def test_another_clients_command_and_rejection_show(web: WebView,
                                                    other: ArmControllerClient) -> None:
    k = other.open()
    wait_for(lambda: get(web, "api/state")["mailboxes"][k - 1]["owner"] == other.session,
             "the other client's mailbox")
    st = other.move_joints(10.0, 70.0, 65.0)
    assert st.error_id == 0
    wait_for(lambda: get(web, "api/state")["joints"]["plc"] == pytest.approx([10, 70, 65]),
             "the other client's MoveJoints")
    m = get(web, "api/state")["mailboxes"][k - 1]
    assert (m["session"], m["ack_seq"], m["result"]) == (other.session, m["seq"], 0)
    assert m["command"] == "MoveJoints" and not m["pending"]
    st = other.move_xyz(0.0, 0.0, 900.0)
    assert st.error_id != 0
    wait_for(lambda: any(f"mailbox {k} (session {other.session})" in e["text"]
                         and e["kind"] == "fault" for e in get(web, "api/state")["events"]),
             "the other client's rejection as an event")


def test_batch_results(web: WebView) -> None:
    pts = [(150.0, 0.0, 120.0), (160.0, 20.0, 110.0), (400.0, 0.0, 0.0)]
    status, answer = post(web, {"name": "CmdSolveBatch", "fields": {
        "points": "\n".join(", ".join(f"{c:g}" for c in p) for p in pts), "elbow": 0}})
    assert status == 200 and answer["ok"], answer
    rows = answer["batch"]
    assert len(rows) == 3
    for p, row in zip(pts[:2], rows[:2], strict=True):
        assert row["error_id"] == 0
        assert row["joints"] == pytest.approx(arm.inverse(*p), abs=1e-3)
        assert row["echo"] == pytest.approx(p, abs=0.01)
    assert rows[2]["error_id"] == controller_constants()["Err.Unreachable"]


def test_relax_turns_the_channels_off(web: WebView, running: RunningPlc) -> None:
    status, answer = post(web, {"name": "CmdRelax", "fields": {}})
    assert status == 200 and answer["ok"], answer
    assert all(w & 0x1000 for w in channel_words(running)[:3])

    def limp() -> bool:
        ch = get(web, "api/state")["channels"]
        return all(c["full_off"] and c["plant_pulse_us"] == 0.0 for c in ch[:3])
    wait_for(limp, "the plant's pulses to stop")


def test_register_table(web: WebView, running: RunningPlc) -> None:
    time.sleep(0.6)  # the table is read every 0.5 s
    rows = {r["name"]: r for r in get(web, "api/registers")["registers"]}
    cmap = controller_map()
    assert {n.upper() for n in rows} == set(cmap)
    for name in ("BaseDeg", "PwmPrescale", "BaseCalMinPulseUs", "InitReg1"):
        assert rows[name]["value"] == pytest.approx(read(running, name), abs=1e-6), name
        assert rows[name]["address"] == cmap[name.upper()].address
    assert rows["PwmInitRequest"]["table"] == "coil"
    assert isinstance(rows["PwmDriverReady"]["value"], bool)


def test_websocket_sends_new_snapshots_within_its_window(web: WebView) -> None:
    with connect(web.url.replace("http", "ws") + "ws", open_timeout=10) as ws:
        seqs = []
        for _ in range(10):
            seqs.append(json.loads(ws.recv(timeout=5))["seq"])
            ws.send("drawn")
        assert seqs == sorted(seqs) and len(set(seqs)) == len(seqs)  # each one newer
        # a page that stops acknowledging gets at most WS_WINDOW more, then nothing; the first
        # of them waits for the next poll, which a loaded machine may take longer than 0.5 s for
        ws.recv(timeout=5)
        extra = 1
        with pytest.raises(TimeoutError):
            while True:
                ws.recv(timeout=0.5)
                extra += 1
        assert 1 <= extra <= WS_WINDOW
        ws.send("drawn")
        assert json.loads(ws.recv(timeout=5))["seq"] > seqs[-1]


def test_plc_fault_shows(monkeypatch: pytest.MonkeyPatch) -> None:
    """The controller is written never to fault, so the fault is raised where compiled ST
    raises it (the program's task call); the soft PLC then enters FAULT as for a real one."""
    with serve_controller() as r, WebView(r.host, r.port, web_port=0, local_plc=r.plc) as w:
        wait_for(lambda: get(w, "api/state").get("connected") is True, "the first poll")

        def division_by_zero(task: str, now_ns: int) -> None:
            raise PlcFault("integer division by zero", "Controller.st:1234:5")
        monkeypatch.setattr(r.plc.program, "run_task", division_by_zero)

        def faulted() -> bool:
            s = get(w, "api/state")
            return (s["plc"]["state"] == "FAULT" and s["plc"]["fault"] is not None
                    and any(e["kind"] == "fault" and "PLC fault" in e["text"]
                            for e in s["events"]))
        wait_for(faulted, "the PLC fault on the page")
        assert get(w, "api/state")["plc"]["fault"] == (
            "Controller.st:1234:5: integer division by zero")
        # the PLC holds its outputs and keeps answering Modbus: the view stays connected
        assert get(w, "api/state")["connected"]


def test_exposure_warning() -> None:
    assert exposure_warning("127.0.0.1", 8080) is None
    assert exposure_warning("localhost", 8080) is None
    w = exposure_warning("0.0.0.0", 8080)
    assert w is not None and "move the arm" in w


def test_cli_serve_web(tmp_path: Any) -> None:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        web_port = s.getsockname()[1]
    proc = subprocess.Popen([sys.executable, "-m", "armbench.cli", "serve", "--web", "--port",
                             "0", "--web-port", str(web_port), "--duration", "20"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        assert proc.stdout is not None
        lines = [proc.stdout.readline(), proc.stdout.readline()]
        m = re.search(r"live view on (http://127\.0\.0\.1:(\d+)/)", lines[1])
        assert m is not None and int(m.group(2)) == web_port, lines
        html = urllib.request.urlopen(m.group(1), timeout=10).read().decode()
        assert '<canvas id="arm"' in html
        js = urllib.request.urlopen(m.group(1) + "static/app.js", timeout=10).read().decode()
        assert "WebSocket" in js
        wait_for(lambda: json.load(urllib.request.urlopen(m.group(1) + "api/state",
                                                          timeout=10))["connected"], "a poll")
    finally:
        proc.terminate()
        proc.wait(10)


@pytest.mark.parametrize("argv, option", [
    (["--web-rate", "0"], "--web-rate"), (["--web-rate", "nan"], "--web-rate"),
    (["--web-port", "70000"], "--web-port")])
def test_cli_web_usage_errors(argv: list[str], option: str,
                              capsys: pytest.CaptureFixture[str]) -> None:
    from armbench.cli import main

    assert main(["serve", "--web", *argv]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and option in err[0]


def test_cli_web_port_taken() -> None:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        s.listen(1)
        port = s.getsockname()[1]
        proc = subprocess.run([sys.executable, "-m", "armbench.cli", "serve", "--web",
                               "--port", "0", "--web-port", str(port), "--duration", "5"],
                              capture_output=True, text=True, timeout=60)
    assert proc.returncode == 1
    assert f"cannot listen on 127.0.0.1:{port} for the web view" in proc.stderr
    assert "Traceback" not in proc.stderr


def test_motion_commands_from_the_page(web: WebView, running: RunningPlc) -> None:
    """A straight line sent from the page ends where the reference IK puts the target, and a
    jog started from the page stops by itself (dead-man) when nobody keeps it alive."""
    status, answer = post(web, {"name": "CmdInitPwm", "fields": {}})
    assert status == 200 and answer["ok"], answer
    status, answer = post(web, {"name": "CmdMoveJoints",
                                "fields": {"base": 0, "shoulder": 70, "elbow": 65}})
    assert status == 200 and answer["result"] == 0, answer
    wait_for(lambda: read(running, "MotionDone") == 1, "the joint move to finish")
    start_line = read(running, "MotionStarts")
    target = (160.0, 30.0, 110.0)
    status, answer = post(web, {"name": "CmdMoveLinear", "fields": {
        "x": target[0], "y": target[1], "z": target[2], "speed": 60, "accel": 300,
        "fineness": 2, "method": 2, "elbow": 0}})
    assert status == 200 and answer["ok"] and answer["result"] == 0, answer
    assert read(running, "MotionKind") == controller_constants()["KindLine"]
    wait_for(lambda: read(running, "MotionStarts") > start_line
             and read(running, "MotionDone") == 1, "the line to finish")
    expected = arm.inverse(*target, elbow_up=True)
    got = [read(running, f"Set{j}Deg") for j in ("Base", "Shoulder", "Elbow")]
    assert got == pytest.approx(expected, abs=1e-2)

    status, answer = post(web, {"name": "CmdJogStart", "fields": {
        "sx": 0.0, "sy": 0.0, "sz": 0.3, "speed": 20, "accel": 200, "elbow": 0}})
    assert status == 200 and answer["result"] == 0, answer
    assert read(running, "MotionKind") == controller_constants()["KindJog"]
    wait_for(lambda: read(running, "MotionErrorId") == 109, "the jog's dead-man stop",
             timeout_s=5.0)
    assert read(running, "MotionBusy") == 0


def test_five_axis_command_from_the_page(web: WebView, other: ArmControllerClient) -> None:
    """A tool pose sent from the page reaches the PLC through the handshake: the 5-axis echo
    (the PLC's FK of the joints it moves to) is the commanded tip, pitch and roll."""
    status, answer = post(web, {"name": "CmdMoveToolAngles", "fields": {
        "x": 170, "y": 20, "z": 80, "pitch": -30, "roll": 15, "mode": 0}})
    assert status == 200 and answer["ok"] and answer["result"] == 0, answer
    echo = other.five_axis_echo()
    assert echo.error_id == 0
    assert echo.tip_mm == pytest.approx((170.0, 20.0, 80.0), abs=0.01)
    assert (echo.tool_pitch_deg, echo.tool_roll_deg) == pytest.approx((-30.0, 15.0), abs=1e-3)
    # the pitch as a direction: elevation of the unit tool vector
    assert math.degrees(math.asin(echo.direction[2])) == pytest.approx(-30.0, abs=1e-3)
    status, answer = post(web, {"name": "CmdMoveToolAngles", "fields": {
        "x": 170, "y": 20, "z": 80, "pitch": -30, "roll": 15, "mode": 4}})
    assert status == 400 and "Elbow / mode must be one of" in answer["message"], answer


def test_wrist_jog_and_gripper_from_the_page(web: WebView, running: RunningPlc,
                                             other: ArmControllerClient) -> None:
    """The wrist jog and the gripper entries reach the PLC: the jog runs as MotionKind 5 and
    stops by its dead-man (the page sends no updates); the gripper's pulse is the MG996R
    mapping of the opening over the default travel (-60..+60 deg = 1000..2000 us)."""
    k = controller_constants()
    assert other.move_tool_angles((170.0, 20.0, 80.0), -30.0, 0.0, wait=True).error_id == 0
    status, answer = post(web, {"name": "CmdJogWrist", "fields": {
        "pitch": 10, "roll": -5, "speed": 0, "accel": 0, "mode": 2}})
    assert status == 200 and answer["ok"] and answer["result"] == 0, answer
    assert read(running, "MotionKind") == k["KindJogWrist"]
    wait_for(lambda: read(running, "MotionErrorId") == k["CtlErr.JogTimeout"],
             "the wrist jog's dead-man stop", timeout_s=5.0)
    status, answer = post(web, {"name": "CmdSetGripper", "fields": {"opening": 30}})
    assert status == 200 and answer["ok"] and answer["result"] == 0, answer
    wait_for(lambda: read(running, "GripperMoving") == 0
             and read(running, "GripperOpeningPct") == 30.0, "the gripper to arrive")
    assert read(running, "GripperPulseUs") == pytest.approx(1000.0 + 0.3 * 1000.0, abs=1e-3)
    status, answer = post(web, {"name": "CmdSetGripper", "fields": {"opening": 130}})
    assert status == 200 and answer["result"] == k["Err.BadParameter"], answer
    assert read(running, "GripperOpeningPct") == 30.0
    status, answer = post(web, {"name": "CmdSetGripper", "fields": {"opening": "wide"}})
    assert status == 400 and "Opening" in answer["message"], answer


JOINT_NAMES = ("Base", "Shoulder", "Elbow")


def _drawn_is_the_output_stage(web: WebView, running: RunningPlc) -> bool:
    """The view's arm (joints and drawn points) is the output stage's angles, read here by
    a client of our own, and its tool point is the reference FK of those angles."""
    out = [read(running, f"Out{j}Deg") for j in JOINT_NAMES]
    s = get(web, "api/state")
    return (s["joints"]["plc"] == pytest.approx(out, abs=1e-4)
            and s["points"]["plc"][3] == pytest.approx(arm.forward(*out), abs=1e-3)
            and s["tool"]["output"] == pytest.approx(arm.forward(*out), abs=1e-3))


def test_drawn_arm_is_what_the_servos_get_for_every_motion_kind(
        web: WebView, running: RunningPlc, other: ArmControllerClient) -> None:
    """After a straight line, a jog and a profiled joint move the arm the view draws is the
    output stage (OutBaseDeg..), whose tool point is the line's target by the reference IK:
    BaseDeg.. hold the last *joint* move's target only and stay behind."""
    k = controller_constants()
    assert other.move_joints(0.0, 70.0, 65.0).error_id == 0
    other.wait_motion()
    target = (165.0, -35.0, 105.0)
    assert other.move_linear(target, 80.0, 400.0, wait=True).error_id == 0
    assert read(running, "MotionKind") == k["KindLine"]
    expected = arm.inverse(*target, elbow_up=True)
    wait_for(lambda: _drawn_is_the_output_stage(web, running), "the line's end drawn")
    s = get(web, "api/state")
    assert s["joints"]["plc"] == pytest.approx(expected, abs=1e-2)
    assert s["tool"]["output"] == pytest.approx(target, abs=0.05)
    assert [read(running, f"{j}Deg") for j in JOINT_NAMES] == pytest.approx([0, 70, 65])

    assert other.jog_start((0.0, 0.0, 0.4), 30.0, 300.0).error_id == 0
    wait_for(lambda: read(running, "MotionBusy") == 0, "the jog's dead-man stop")
    wait_for(lambda: _drawn_is_the_output_stage(web, running), "the jog's end drawn")
    assert get(web, "api/state")["tool"]["output"][2] > target[2] + 1.0  # it went up

    assert other.move_joints_profile((20.0, 75.0, 90.0), 2, 60.0, 300.0,
                                     wait=True).error_id == 0
    wait_for(lambda: _drawn_is_the_output_stage(web, running), "the joint move drawn")
    assert get(web, "api/state")["joints"]["plc"] == pytest.approx([20, 75, 90], abs=1e-3)
