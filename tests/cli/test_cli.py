"""The armbench command line: exit codes, JSON dump, and serve answering Modbus."""

from __future__ import annotations

import json
import socket
import struct
import subprocess
import sys
import time
from pathlib import Path

import pytest

from armbench.cli import main


def test_check_ok_and_error(prog: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["check", str(prog)]) == 0
    bad = tmp_path / "bad.st"
    bad.write_text(prog.read_text().replace("rate * DINT_TO_REAL(n)", "rate * n"))
    assert main(["check", str(bad)]) == 1
    out = capsys.readouterr().out.strip().splitlines()
    assert len(out) == 1 and out[0].startswith(f"{bad}:13:")
    assert "error[E0300]" in out[0]


def test_check_target(prog: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """A name CODESYS reserves: an error for codesys and all (the default), a warning that
    does not fail the check for openplc."""
    bit = tmp_path / "bit.st"
    bit.write_text(prog.read_text().replace("rate", "Bit"))
    for target, rc, severity in ((None, 1, "error"), ("all", 1, "error"),
                                 ("codesys", 1, "error"), ("openplc", 0, "warning")):
        option = [] if target is None else ["--target", target]
        assert main(["check", *option, str(bit)]) == rc
        out, err = capsys.readouterr()
        lines = out.strip().splitlines()
        assert len(lines) == 1 and lines[0].startswith(f"{bit}:5:3: {severity}[E0214]: "
                                                       "variable 'Bit' is a data type of "
                                                       "CODESYS and TwinCAT"), out
        assert err.strip().endswith(": 1 error" if rc else ": 0 errors, 1 warning"), err
    assert main(["check", "--target", "twincat", str(bit)]) == 2
    assert "invalid choice: 'twincat'" in capsys.readouterr().err
    assert main(["check", "--target", "codesys", str(prog)]) == 0


def test_usage_errors_exit_2(tmp_path: Path) -> None:
    assert main(["frobnicate"]) == 2
    assert main(["check", str(tmp_path / "missing.st")]) == 2


def test_run_dump_is_json(prog: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["run", str(prog), "--cycles", "4", "--dump"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert data["inst0"]["n"] == 4
    assert data["inst0"]["val"] == 2.0  # 0.5 * 4, computed in REAL


def test_run_reports_fault_with_position(prog: Path, tmp_path: Path,
                                         capsys: pytest.CaptureFixture[str]) -> None:
    src = tmp_path / "div.st"
    src.write_text(prog.read_text().replace("n := n + 1;",
                                   "n := n + 1;\n  IF n >= 3 THEN n := 10 / (n - n); END_IF;"))
    assert main(["run", str(src), "--cycles", "5"]) == 1
    # the position is the division's: line 12, column of `10 / ...`
    assert f"{src}:12:23: PLC fault: integer division by zero" in capsys.readouterr().err


def test_build_is_cached(prog: Path, capsys: pytest.CaptureFixture[str]) -> None:
    main(["build", str(prog)])
    capsys.readouterr()
    assert main(["build", str(prog)]) == 0
    assert "cached" in capsys.readouterr().out


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port: int = s.getsockname()[1]
        return port


def test_serve_answers_modbus(prog: Path) -> None:
    port = _free_port()
    proc = subprocess.Popen([sys.executable, "-m", "armbench.cli", "serve", str(prog),
                             "--port", str(port), "--duration", "3"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        assert proc.stdout is not None
        assert "serving Modbus TCP" in proc.stdout.readline()
        deadline = time.monotonic() + 2.0
        with socket.create_connection(("127.0.0.1", port), timeout=2) as s:
            # FC3 read holding registers 2 (%QW2) and 2048..2049 (%MD0), raw MBAP frames
            while True:
                s.sendall(struct.pack(">HHHBBHH", 1, 0, 6, 1, 3, 2048, 2))
                reply = s.recv(64)
                hi, lo = struct.unpack(">HH", reply[9:13])
                val = struct.unpack(">f", struct.pack(">HH", hi, lo))[0]
                if val > 1.0 or time.monotonic() > deadline:
                    break
            assert val > 1.0 and val == int(val * 2) / 2  # 0.5 * n
            s.sendall(struct.pack(">HHHBBHH", 2, 0, 6, 1, 3, 2, 1))
            reply = s.recv(64)
            assert struct.unpack(">H", reply[9:11])[0] >= 2
        assert proc.wait(timeout=10) == 0
    finally:
        proc.kill()
        proc.wait()


def test_serve_the_codesys_layout(prog: Path) -> None:
    """--flavor codesys: what the program writes (val %MD0 -> %QD0, out %QW2 -> %QW2, neither
    moved) is read as input registers with function 4, the REAL least significant word
    first; OpenPLC's %MD0 (holding register 2048) is not on this device."""
    port = _free_port()
    proc = subprocess.Popen([sys.executable, "-m", "armbench.cli", "serve", str(prog),
                             "--port", str(port), "--duration", "3", "--flavor", "codesys"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        assert proc.stdout is not None
        line = proc.stdout.readline()
        assert "serving Modbus TCP" in line and "CODESYS variant's register layout" in line
        deadline = time.monotonic() + 2.0
        with socket.create_connection(("127.0.0.1", port), timeout=2) as s:
            while True:
                s.sendall(struct.pack(">HHHBBHH", 1, 0, 6, 1, 4, 0, 3))
                reply = s.recv(64)
                lo, hi, out = struct.unpack(">HHH", reply[9:15])
                val = struct.unpack("<f", struct.pack("<HH", lo, hi))[0]
                if val > 1.0 or time.monotonic() > deadline:
                    break
            assert val > 1.0 and val == int(val * 2) / 2  # 0.5 * n
            assert out >= 2
            s.sendall(struct.pack(">HHHBBHH", 2, 0, 6, 1, 3, 2048, 2))
            assert s.recv(64)[7:9] == bytes((0x83, 2))
        assert proc.wait(timeout=10) == 0
    finally:
        proc.kill()
        proc.wait()


def test_serve_web_speaks_openplc_only(prog: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["serve", str(prog), "--web", "--flavor", "codesys", "--port", "0"]) == 2
    assert "--web: the live view speaks OpenPLC's register map only" in capsys.readouterr().err


def test_configuration_names_are_the_openplc_uploads_rule(
        prog: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """Config0 and Res0 are what OpenPLC's upload needs, not what the bench or CODESYS needs:
    an error for check --target openplc and all and for export (the OpenPLC upload), a
    warning for --target codesys and for build and run, which compile for the soft PLC and
    run the program as it is."""
    plant = tmp_path / "plant.st"
    plant.write_text(prog.read_text().replace("CONFIGURATION Config0", "CONFIGURATION Plant")
                     .replace("RESOURCE Res0", "RESOURCE Cpu"))
    named = ("plant.st:15:1: {}[E0602]: CONFIGURATION 'Plant': OpenPLC's upload needs it to be "
             "named Config0{}", "plant.st:16:3: {}[E0602]: RESOURCE 'Cpu': OpenPLC's upload "
             "needs it to be named Res0{}")

    def said(text: str, severity: str, why: str = "") -> bool:
        return all(line.format(severity, why) in text for line in named)

    for target, rc, severity in (("all", 1, "error"), ("openplc", 1, "error"),
                                 ("codesys", 0, "warning")):
        assert main(["check", "--target", target, str(plant)]) == rc
        out, err = capsys.readouterr()
        assert said(out, severity, " (CODESYS takes any name)" if rc == 0 else ""), out
        assert len(out.strip().splitlines()) == 2, out
    soft = " (the bench's soft PLC runs it as it is)"
    assert main(["run", str(plant), "--cycles", "3", "--dump"]) == 0
    out, err = capsys.readouterr()
    assert json.loads(out)["inst0"]["n"] == 3
    assert said(err, "warning", soft), err
    assert main(["build", str(plant)]) == 0
    assert said(capsys.readouterr().err, "warning", soft)
    assert main(["export", str(plant), "--out", str(tmp_path / "out")]) == 1
    out, err = capsys.readouterr()
    assert said(out + err, "error"), out + err
    assert not (tmp_path / "out").exists()
    # the right names: nothing to say anywhere
    for argv in (["check", "--target", "codesys", str(prog)], ["run", str(prog)],
                 ["build", str(prog)]):
        assert main(argv) == 0
        out, err = capsys.readouterr()
        assert "E0602" not in out + err, argv
