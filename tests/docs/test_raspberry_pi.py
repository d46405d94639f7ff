"""docs/raspberry-pi.md, checked where it can be checked without a Pi: its register numbers and
command codes against the map derived from Controller.st, the Modbus server counts it names
against the exported v4 project, its plugin settings against plc_project/v4_plugin, the
plugins.conf edit it gives run with sed on a line as the v4 runtime writes it, its OpenPLC v3
facts against the OpenPLC v3 source (a checkout named by the environment variable
OPENPLC_SRC; skipped, saying so, without it), its install and export commands as a user
outside a checkout runs them, and its steps 7 and 8 end to end: the controller in the soft
PLC, the chip code the v4 plugin and the v3 PSM share driving the PCA9685 model through a fake
I2C bus and reading/writing the PLC's variables, and the page's own Python snippet run against
it.
"""

from __future__ import annotations

import contextlib
import io
import json
import os
import re
import shlex
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pytest

from armbench.demo import serve_controller
from armbench.plant.imu_chips import Gy87Board
from armbench.plant.pca9685 import PCA9685
from armbench.registermap import controller_constants, controller_map
from psm_script import PSM_PATH, ImageVars, SimBus, load_psm_script

REPO = Path(__file__).resolve().parents[2]
DOC = REPO / "docs" / "raspberry-pi.md"
OPENPLC_SRC_VAR = "OPENPLC_SRC"  # a checkout of OpenPLC v3 (github.com/thiagoralves/OpenPLC_v3)
OSC_HZ = 25e6
PRESCALE = 121
TICK_US = 1e6 * (PRESCALE + 1) / OSC_HZ  # PCA9685 data sheet: one count at PRE_SCALE 121
TABLES = {"holding": "holding", "coil": "coil", "discrete": "discrete", "input": "input"}


def doc_text() -> str:
    return DOC.read_text(encoding="utf-8")


def table_rows(header_start: str) -> list[list[str]]:
    """The body rows of every markdown table whose header line starts with header_start."""
    lines = doc_text().splitlines()
    starts = [i for i, ln in enumerate(lines) if ln.startswith(header_start)]
    assert starts, f"no table headed {header_start!r}"
    rows = []
    for start in starts:
        for ln in lines[start + 2:]:
            if not ln.startswith("|"):
                break
            rows.append([c.strip() for c in ln.strip().strip("|").split("|")])
    return rows


def test_doc_registers_are_the_controllers() -> None:
    rows = table_rows("| what | name | location | Modbus |")
    assert len(rows) >= 10
    cmap = controller_map()
    for _, name, location, modbus in rows:
        reg = cmap[name.strip("`").upper()]
        assert location.strip("`") == reg.location, name
        table, address = modbus.split()
        assert (TABLES[table], int(address)) == (reg.table, reg.address), name


def test_doc_commands_are_the_controllers() -> None:
    rows = table_rows("| command | code | effect |")
    k = controller_constants()
    for name, code, _ in rows:
        assert k["Cmd" + name.strip("`")] == int(code), name
    # every "Name (code N)" in the prose too
    prose = re.findall(r"`(\w+)` \(code (\d+)\)", doc_text())
    assert len(prose) >= 3
    for name, code in prose:
        assert k["Cmd" + name] == int(code), name


def test_doc_numbers_follow_the_data_sheet() -> None:
    text = doc_text()
    # PRE_SCALE for 50 Hz (data sheet equation 1), one tick, the centre word
    assert round(OSC_HZ / (4096 * 50.0)) - 1 == PRESCALE
    assert f"PRE_SCALE {PRESCALE}" in text
    assert f"{TICK_US:.2f} µs" in text
    assert f"1500 µs, word {round(1500.0 / TICK_US)}" in text
    assert "4096 (full off)" in text and 0x1000 == 4096


def test_doc_psm_settings_are_the_scripts() -> None:
    src = PSM_PATH.read_text()
    assert re.search(r"^I2C_BUS_NUMBER = 1\b", src, re.M)
    assert re.search(r"^PCA9685_ADDRESS = 0x40\b", src, re.M)
    assert re.search(r"^AUTO_INIT = True\b", src, re.M)
    assert "/dev/i2c-1" in doc_text() and "0x40" in doc_text()
    # the IMU section (step 9)
    assert re.search(r"^IMU_ENABLED = True\b", src, re.M)
    assert re.search(r"^SAMPLE_PERIOD_S = 0\.02\b", src, re.M)
    assert re.search(r"^MPU6050_ADDRESS = 0x68\b", src, re.M)
    assert re.search(r"^HMC5883L_ADDRESS = 0x1E\b", src, re.M)
    text = doc_text()
    assert "`SAMPLE_PERIOD_S` (0.02 s)" in text and "with 0.02" in text
    assert "address 0x68" in text and "(magnetometer, 0x1E)" in text


def openplc_src() -> Path:
    """The OpenPLC v3 checkout that OPENPLC_SRC names; skips the test, saying why, without
    one."""
    value = os.environ.get(OPENPLC_SRC_VAR)
    if not value:
        pytest.skip(f"{OPENPLC_SRC_VAR} is not set: point it at a checkout of OpenPLC v3 to "
                    "check the page's OpenPLC facts against its source")
    src = Path(value)
    if not (src / "background_installer.sh").is_file():
        pytest.skip(f"{OPENPLC_SRC_VAR}={value} is not an OpenPLC v3 checkout "
                    "(no background_installer.sh)")
    return src


def test_doc_openplc_facts_are_in_its_source() -> None:
    src = openplc_src()
    web = src / "webserver"
    text = doc_text()
    psm_cpp = (web / "core" / "hardware_layers" / "psm.cpp").read_text()
    assert '"../.venv/bin/python3 -u ./core/psm/main.py' in psm_cpp
    assert "`../.venv/bin/python3 -u ./core/psm/main.py`" in text
    page = (web / "webserver.py").read_text()
    assert ">Python on Linux (PSM)<" in page
    assert "with open('./core/psm/main.py', 'w+') as f: f.write(custom_layer_code)" in page
    assert "port=8080" in page
    assert "'openplc','openplc'" in (web / "check_openplc_db.py").read_text().replace(
        ", ", ",").replace("'openplc@openplc.com',", "")
    installer = (src / "background_installer.sh").read_text()
    rpi = installer[installer.index('elif [ "$1" == "rpi" ]'):]
    rpi = rpi[: rpi.index("elif", 5)]
    assert "install_systemd_service" in rpi  # "starts at boot"
    assert 'VENV_DIR="$OPENPLC_DIR/.venv"' in installer
    psm_py = (web / "core" / "psm" / "psm.py").read_text()
    for fn in ("def get_var", "def set_var", "def should_quit", "def start", "def stop"):
        assert fn in psm_py  # what the PSM script calls
    # `install.sh rpi` installs WiringPi: the distribution's package, else WiringPi's arm64
    # .deb, which only a 64-bit OS installs; the page must say so
    assert "install_wiringpi" in rpi
    wiring = installer[installer.index("function install_wiringpi"):]
    wiring = wiring[: wiring.index("\n}\n")]
    assert "apt-get install -y wiringpi" in wiring and "_arm64.deb" in wiring
    assert 'fail "Failed to install wiringpi."' in wiring
    assert "Raspberry Pi OS 64-bit" in text and "`arm64` `.deb`" in text
    assert '"Failed to install wiringpi."' in " ".join(text.split())


# ------------------------------------------------------- the page's commands, as a user runs them

def shell_commands() -> list[str]:
    """The lines of the page's ```sh blocks, comments removed."""
    blocks = re.findall(r"```sh\n(.*?)```", doc_text(), re.S)
    lines = (ln.split("#", 1)[0].strip() for block in blocks for ln in block.splitlines())
    return [ln for ln in lines if ln]


def inline_commands(program: str) -> list[str]:
    """Every `program ...` code span in the page's prose and its sh blocks."""
    spans = re.findall(r"`(" + re.escape(program) + r" [^`]+)`", doc_text())
    return spans + [c for c in shell_commands() if c.startswith(program + " ")]


def test_doc_installs_the_bench_from_a_file_or_a_checkout() -> None:
    """armbench is on no package index: every `pip install` of it installs a wheel file or a
    checkout, and the page says how to build that wheel."""
    installs = [c for c in (*inline_commands("pip"), *inline_commands("python -m pip"))
                if re.search(r"\binstall\b", c)]
    ours = [c for c in installs if "armbench" in c or c.rstrip().endswith(" .")]
    assert ours, "the page does not say how to install the bench"
    for command in ours:
        args = [a for a in shlex.split(command) if not a.startswith("-")]
        target = args[-1]
        assert target == "." or target.endswith(".whl") or "/" in target, (
            f"{command!r}: armbench is on no package index; install a wheel or a checkout")
    builds = [c for c in (*inline_commands("pip"), *inline_commands("python -m pip"))
              if " wheel " in f" {c} "]
    assert builds, "the page does not say how to build the wheel"
    assert all("--no-deps" in c and "-w dist" in c for c in builds), builds


def test_doc_export_command_runs_outside_a_checkout(tmp_path: Path) -> None:
    """Step 4's `armbench export` command, run where a user of the installed bench runs it
    (a folder that is no checkout), writes the upload file the page names, and that file is
    the committed plc_project/openplc/arm_controller.st (byte for byte)."""
    exports = [c for c in inline_commands("armbench") if c.startswith("armbench export")]
    assert len(exports) == 1, exports
    args = shlex.split(exports[0])[1:]
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    env["PYTHONPATH"] = str(REPO / "sim")
    proc = subprocess.run([sys.executable, "-m", "armbench.cli", *args], cwd=tmp_path,
                          env=env, capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    upload = re.search(r"writes\s+`([\w./-]+arm_controller\.st)`", doc_text())
    assert upload, "the page does not name the file that the export writes"
    written = tmp_path / upload.group(1)
    assert written.is_file(), sorted(str(p.relative_to(tmp_path)) for p in tmp_path.rglob("*"))
    committed = REPO / "plc_project" / "openplc" / "arm_controller.st"
    assert written.read_bytes() == committed.read_bytes()
    # and the v4 project folder the page names, file for file the committed one
    folder = re.search(r"v4 project folder\s+`([\w./-]+)/`", doc_text())
    assert folder, "the page does not name the v4 project folder the export writes"
    v4 = tmp_path / folder.group(1)
    ours = REPO / "plc_project" / "openplc-v4" / "arm_controller"
    got = sorted(p.relative_to(v4) for p in v4.rglob("*") if p.is_file())
    assert got == sorted(p.relative_to(ours) for p in ours.rglob("*") if p.is_file())
    for rel in got:
        assert (v4 / rel).read_bytes() == (ours / rel).read_bytes(), rel


# ------------------------------------------------------------------ the v4 runtime's settings

V4_PROJECT = REPO / "plc_project" / "openplc-v4" / "arm_controller" / "project.json"
PLUGIN_DIR = REPO / "plc_project" / "v4_plugin"
BUFFER_ROWS = {"Holding Registers %QW": [("holdingRegisters", "qwCount")],
               "Holding Registers %MW": [("holdingRegisters", "mwCount")],
               "Holding Registers %MD, %ML": [("holdingRegisters", "mdCount"),
                                              ("holdingRegisters", "mlCount")],
               "Coils %QX, %MX": [("coils", "qxBits"), ("coils", "mxBits")],
               "Discrete Inputs %IX": [("discreteInputs", "ixBits")],
               "Input Registers %IW": [("inputRegisters", "iwCount")]}


def test_doc_modbus_counts_are_the_exported_projects() -> None:
    """Step 4's Buffer Mapping table is what the exported project carries (which
    tests/export/test_openplc_v4.py checks against the register map and the editor's code)."""
    project = json.loads(V4_PROJECT.read_text("utf-8"))
    (server,) = project["data"]["servers"]
    config = server["modbusSlaveConfig"]
    assert (config["enabled"], config["port"]) == (True, 502)
    assert f"`{server['name']}`" in doc_text()
    rows = table_rows("| segment | count | why |")
    assert sorted(r[0] for r in rows) == sorted(BUFFER_ROWS)
    for segment, counts, _ in rows:
        want = [config["bufferMapping"][g][k] for g, k in BUFFER_ROWS[segment]]
        assert [int(c) for c in counts.split(",")] == want, segment


def test_doc_plugin_settings_are_the_plugins() -> None:
    settings = json.loads((PLUGIN_DIR / "arm_io.json").read_text("utf-8"))
    assert (settings["i2c_bus"], settings["pca9685_address"]) == (1, "0x40")
    assert settings["prescale_from"] == "%MD14"
    assert (settings["imu_enabled"], settings["imu_period_s"]) == (True, 0.02)
    text = doc_text()
    for name in ("i2c_bus", "pca9685_address", "imu_enabled", "imu_period_s"):
        assert f"`{name}`" in text, name
    assert "`PwmPrescale` (`%MD14`, 121 for 50 Hz" in " ".join(text.split())
    assert "smbus2" in (PLUGIN_DIR / "requirements.txt").read_text()
    assert "requirements.txt` (smbus2)" in " ".join(text.split())


def plugins_conf_line() -> str:
    lines = [c for c in shell_commands() if c.startswith("echo 'arm_io,")]
    assert len(lines) == 1, lines
    return shlex.split(lines[0])[1]


def test_doc_plugins_conf_line_is_the_plugins_readme() -> None:
    readme = (PLUGIN_DIR / "README.md").read_text("utf-8")
    line = plugins_conf_line()
    assert line in readme
    name, path, enabled, kind, config, venv = line.split(",")
    assert (name, enabled, kind, venv) == ("arm_io", "1", "0", "./venvs/arm_io")
    folder = "./core/src/drivers/plugins/python/arm_io/"
    assert (path, config) == (folder + "arm_io_plugin.py", folder + "arm_io.json")


def test_doc_sed_re_enables_the_plugin_after_an_upload(tmp_path: Path) -> None:
    """After an upload the runtime writes every plugins.conf line as
    ``name,path,enabled,type,config_path[,venv_path]`` (webserver/plugin_config_model.py,
    PluginConfig.to_line) with enabled 0 for the plugins the upload carried no configuration
    for; the page's sed sets arm_io's back to 1 and touches nothing else."""
    line = plugins_conf_line()
    fields = line.split(",")
    disabled = ",".join([*fields[:2], "0", *fields[3:]])
    others = ["# name,path,enabled,type,config_path,venv_path",
              "modbus_slave,./core/src/drivers/plugins/python/modbus_slave/simple_modbus.py,1,0,"
              "./core/src/drivers/plugins/python/modbus_slave/modbus_slave.json,./venvs/modbus_slave",
              "arm_io_old,./x/arm_io.py,0,0,./x/arm_io.json,./venvs/x",
              "s7comm,./build/plugins/libs7comm.so,0,1,"]
    conf = tmp_path / "plugins.conf"
    conf.write_text("\n".join([others[0], others[1], disabled, others[2], others[3]]) + "\n")
    seds = [c for c in shell_commands() if c.startswith("sudo sed -i ")]
    assert len(seds) == 1, seds
    args = shlex.split(seds[0])[1:]  # without sudo
    assert args[-1] == "plugins.conf"
    subprocess.run([*args[:-1], str(conf)], check=True, timeout=60)
    assert conf.read_text().splitlines() == [others[0], others[1], line, others[2], others[3]]


# ---------------------------------------------------------------- steps 7 and 8 in the bench




@dataclass
class PsmThreadLoop:
    """A PSM main loop (one step, a 5 ms sleep) in a thread, as the runtime runs it beside the
    PLC; ``step`` is the driver's poll or the IMU reader's."""

    step: Callable[[], None]
    stop: threading.Event = field(default_factory=threading.Event)
    errors: list[BaseException] = field(default_factory=list)

    def run(self) -> None:
        try:
            while not self.stop.is_set():
                self.step()
                self.stop.wait(0.005)
        except BaseException as exc:  # a test must see a crash of the loop
            self.errors.append(exc)


@contextlib.contextmanager
def pi_rehearsal() -> Iterator[tuple[str, int, PCA9685, ImageVars]]:
    psm = load_psm_script("arm_io_psm_doc")
    chip = PCA9685(address=psm.PCA9685_ADDRESS)
    with serve_controller() as running:
        plc_vars = ImageVars(running.plc.image, running.plc.lock)
        driver = psm.PCA9685Driver(bus=SimBus(chip), plc=plc_vars, sleep=chip.advance,
                                   log=lambda _msg: None)
        loop = PsmThreadLoop(driver.poll)
        thread = threading.Thread(target=loop.run, daemon=True)
        thread.start()
        try:
            yield running.host, running.port, chip, plc_vars
        finally:
            loop.stop.set()
            thread.join(5.0)
        assert not loop.errors, loop.errors


def python_snippet(step: int) -> str:
    """The Python block of step 8 (the PWM check) or step 9 (the IMU)."""
    blocks = re.findall(r"```python\n(.*?)```", doc_text(), re.S)
    assert len(blocks) == 2
    return blocks[{8: 0, 9: 1}[step]]


def test_first_power_up_and_the_pwm_check_in_the_bench() -> None:
    from armbench.controller_client import ArmControllerClient
    from armbench.softplc.modbus_client import PlcClient

    with pi_rehearsal() as (host, port, chip, plc_vars):
        with PlcClient(host, port) as link, ArmControllerClient(link) as arm:
            arm.wait_scans(5)
            # step 7: relaxed at power-up, the PSM ready, no fault, no pulse on the chip
            assert arm.channel_words()[:3] == [4096, 4096, 4096]
            deadline_scans = 0
            while not plc_vars.get_var("IX0.0") and deadline_scans < 50:
                arm.wait_scans(1)
                deadline_scans += 1
            assert link.read_discrete_inputs(0, 2) == [True, False]  # Ready, not Fault
            assert chip.running
            assert [chip.pulse_width_us(ch) for ch in range(3)] == [0.0, 0.0, 0.0]
            # step 8: the page's own snippet, run against this PLC
            out = io.StringIO()
            with contextlib.redirect_stdout(out):
                exec(python_snippet(8), {"HOST": host, "PORT": port})  # noqa: S102
            printed = out.getvalue()
            assert "at power-up: [4096, 4096, 4096]" in printed
            assert "InitPwm result 0 prescale 121 ready True" in printed
            centre = round(1500.0 / TICK_US)
            assert f"centre words [{centre}, {centre}, {centre}]" in printed
            assert "PLC pulse widths [1500.0, 1500.0, 1500.0]" in printed
            assert "relaxed [4096, 4096, 4096]" in printed
            # what the model made of it: 50 Hz, and the relaxed channels carry no pulse
            assert chip.prescale == PRESCALE
            assert chip.update_rate_hz == pytest.approx(OSC_HZ / (4096 * (PRESCALE + 1)))
            assert abs(chip.update_rate_hz - 50.0) < 0.1
            arm.move_joints(0.0, 70.0, 65.0)
            for _ in range(50):
                if chip.pulse_width_us(0) > 0.0:
                    break
                arm.wait_scans(1)
            for ch in range(3):
                assert chip.pulse_width_us(ch) == pytest.approx(centre * TICK_US)
                assert abs(chip.pulse_width_us(ch) - 1500.0) <= TICK_US / 2
            arm.relax()
            for _ in range(50):
                if chip.pulse_width_us(0) == 0.0:
                    break
                arm.wait_scans(1)
            assert [chip.pulse_width_us(ch) for ch in range(3)] == [0.0, 0.0, 0.0]


def test_imu_step_in_the_bench() -> None:
    from armbench.controller_client import ArmControllerClient
    from armbench.softplc.modbus_client import PlcClient

    psm = load_psm_script("arm_io_psm_doc")
    logs: list[str] = []
    with serve_controller() as running:
        plc_vars = ImageVars(running.plc.image, running.plc.lock)
        board = Gy87Board()
        reader = psm.ImuReader(bus=board, plc=plc_vars, log=logs.append)

        def imu_step() -> None:
            # the GY-87 board resting flat: gravity up, a field
            board.load([3, -2, 1], [120, -80, 16384], [300, -40, -520])
            reader.poll(time.monotonic())

        loop = PsmThreadLoop(imu_step)
        thread = threading.Thread(target=loop.run, daemon=True)
        thread.start()
        try:
            with PlcClient(running.host, running.port) as link, \
                    ArmControllerClient(link) as arm:
                out = io.StringIO()
                with contextlib.redirect_stdout(out):
                    exec(python_snippet(9), {"HOST": running.host,  # noqa: S102
                                             "PORT": running.port,
                                             "PlcClient": PlcClient,
                                             "ArmControllerClient": ArmControllerClient})
                first = arm.imu_state()
                time.sleep(1.0)
                second = arm.imu_state()
        finally:
            loop.stop.set()
            thread.join(5.0)
        assert not loop.errors, loop.errors
    assert logs and logs[0].startswith("IMU ready") and "ImuSetPeriod 0.02" in logs[0]
    assert out.getvalue().strip(), "the snippet printed nothing"
    grown = second.samples - first.samples
    print(f"\nIMU step: {grown} samples in 1 s through the PSM, {second.missed} missed")
    # 50 per second, less what a loaded machine's thread stalls cost; the PLC accounts for
    # every sample since the restart (filtered or counted as missed), and loses few
    assert 30 <= grown <= 52
    published = (second.last_seq - first.last_seq) + first.samples + first.missed
    assert second.samples + second.missed == published
    assert second.missed <= max(2, second.samples // 10)
    assert second.error_id == 0 and abs(float(np.linalg.norm(second.quat)) - 1.0) < 1e-5


def test_doc_asks_for_a_64_bit_os() -> None:
    """OpenPLC's `install.sh rpi` falls back to WiringPi's arm64 package (checked against the
    installer by test_doc_openplc_facts_are_in_its_source): the page asks for a 64-bit OS
    before the first step."""
    text = doc_text()
    assert "Raspberry Pi OS 64-bit" in text[: text.index("## 1.")]


def test_doc_plugin_install_is_the_one_tests_plugin_v4_runs() -> None:
    """Step 3's mkdir and copy are the plugin README's, which tests/plugin_v4 runs in a
    runtime tree (here with sudo, the runtime's checkout being root's)."""
    readme = (PLUGIN_DIR / "README.md").read_text("utf-8")
    blocks = [b for b in re.findall(r"```sh\n(.*?)```", readme, re.S)
              if re.search(r"^cp ", b, re.M)]
    assert len(blocks) == 1, blocks
    theirs = [ln.strip() for ln in blocks[0].splitlines() if ln.strip()]
    ours = [c.removeprefix("sudo ") for c in shell_commands()
            if c.startswith(("sudo mkdir -p core/", "sudo cp \"$ARM/"))]
    assert ours == theirs
    # the venv: the runtime's script, which the README names as doing the same
    assert "sudo bash scripts/manage_plugin_venvs.sh create arm_io" in shell_commands()
    assert "`bash scripts/manage_plugin_venvs.sh create arm_io` does the same" in readme
