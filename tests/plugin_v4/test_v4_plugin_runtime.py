"""The v4 plugin as the runtime sees it: its plugins.conf line parsed as plugin_config.c
parses it, its install by the README's commands, its loading as plugin_driver.c loads it,
init/start_loop/stop_loop/cleanup twice on the cached module with its threads running beside
the runtime's scans, and every entry point's failures (conftest's ``loaded``)."""

from __future__ import annotations

import ast
import ctypes
import json
import re
import shutil
import sys
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import pytest
from v4_rig import ADDR, PRESCALE, Loaded
from v4_standin import (
    PLUGIN_SRC,
    REPO,
    SHIPPED_MODULES,
    SimI2CBus,
    StandInRuntime,
    capsule,
    conf_line,
    controller_locations,
    load_plugin,
    parse_conf_line,
    readme,
    wait_for,
)

from armbench.plant.imu_chips import Gy87Board
from armbench.plant.pca9685 import PCA9685
from armbench.registermap import controller_map
from armbench.softplc.image import ProcessImage

CONFIGURED = ("[ARM_IO] configured from ./core/src/drivers/plugins/python/arm_io/arm_io.json: "
              "PCA9685 0x40 on /dev/i2c-1, PRE_SCALE from %MD14, every 0.005 s; IMU (MPU6050 "
              "0x68, HMC5883L 0x1E) every 0.02 s")


WRONG_NAME = b"not_openplc"  # a constant: a capsule keeps the pointer to its name


def new_runtime(loaded: Loaded, **kwargs: Any) -> StandInRuntime:
    """The runtime args of one program load: a fresh image, the controller at power-up."""
    runtime = StandInRuntime(ProcessImage.allocate(), controller_locations(),
                             config_path=loaded.tree.line.config_path, **kwargs)
    for ch in range(16):
        runtime.set(f"%QW{ch}", 0x1000)
    runtime.set("%MD14", PRESCALE)
    return runtime


def plugin_threads() -> list[str]:
    return [t.name for t in threading.enumerate() if t.name.startswith("arm_io")]


# ------------------------------------------------------------------ the line and the tree

def test_readme_line_is_one_plugin_config_c_takes() -> None:
    line = parse_conf_line(conf_line())
    assert (line.name, line.enabled, line.type) == ("arm_io", 1, 0)  # a Python plugin, on
    plugin_dir = "./core/src/drivers/plugins/python/arm_io"
    assert line.path == f"{plugin_dir}/arm_io_plugin.py"
    # one interpreter holds every plugin: the module name must be no shipped plugin's
    assert Path(line.path).stem not in SHIPPED_MODULES
    # an upload's conf/arm_io.json is copied to the plugin's folder under that very name
    assert line.config_path == f"{plugin_dir}/{line.name}.json"
    # manage_plugin_venvs.sh builds ./venvs/<name> from <plugin folder>/requirements.txt
    assert line.venv_path == f"./venvs/{line.name}" and Path(plugin_dir).name == line.name
    assert (PLUGIN_SRC / "requirements.txt").read_text().split() == ["smbus2==0.6.1"]
    assert "smbus2==0.6.1" in (REPO / "docs" / "raspberry-pi.md").read_text()  # v3's pin


def test_install_commands_copy_the_repository_files(loaded: Loaded) -> None:
    installed = loaded.tree.plugin_dir
    assert sorted(p.name for p in installed.iterdir() if p.is_file()) == [
        "arm_io.json", "arm_io_plugin.py", "arm_io_psm.py", "requirements.txt"]
    for name in ("arm_io_plugin.py", "arm_io.json", "requirements.txt"):
        assert (installed / name).read_bytes() == (PLUGIN_SRC / name).read_bytes()
    psm = REPO / "plc_project" / "psm" / "arm_io_psm.py"
    assert (installed / "arm_io_psm.py").read_bytes() == psm.read_bytes()
    assert Path(loaded.psm.__file__) == (installed / "arm_io_psm.py").resolve()


def test_the_psm_is_found_beside_or_in_this_repositorys_layout(loaded: Loaded) -> None:
    """Installed, arm_io_psm.py sits next to the plugin; in a checkout it is ../psm/."""
    psm = loaded.module.load_psm(str(PLUGIN_SRC))
    assert Path(psm.__file__) == (REPO / "plc_project" / "psm" / "arm_io_psm.py").resolve()
    assert sys.modules[loaded.module.PSM_MODULE] is psm


def test_init_prepares_without_touching_bus_buffers_or_threads(loaded: Loaded) -> None:
    runtime = new_runtime(loaded)
    assert loaded.module.set_image_sizes(runtime.image_sizes()) == 0
    assert loaded.shared.image_sizes.sizes_known()
    cap = capsule(runtime)
    assert loaded.module.init(cap) is True
    assert runtime.shown() == [CONFIGURED]
    # init() runs for every listed plugin, enabled or not: no I2C, no buffer, no thread
    assert loaded.smbus2.ATTEMPTS == [] and runtime.lock_holds == 0 and runtime.drains == []
    assert plugin_threads() == []
    assert loaded.module.cleanup() is True


# ------------------------------------------------------------------ two runs, with threads

@contextmanager
def scanning(runtime: StandInRuntime) -> Iterator[None]:
    """The runtime's scan: a drain of the journal under the image lock every 2 ms."""
    stop = threading.Event()

    def scan() -> None:
        while not stop.is_set():
            with runtime.lock:
                runtime.drain()
            stop.wait(0.002)

    thread = threading.Thread(target=scan, daemon=True)
    thread.start()
    try:
        yield
    finally:
        stop.set()
        thread.join(5.0)


def one_run(loaded: Loaded, chip: PCA9685, board: Gy87Board, run: int) -> None:
    """One PLC start and stop, as the runtime makes them: set_image_sizes, init with a new
    capsule over a new image, start_loop; the journal cleaned up, stop_loop, cleanup."""
    module = loaded.module
    assert load_plugin(loaded.tree) is module  # imported once for the process
    runtime = new_runtime(loaded, scan_between_writes=True)
    assert module.set_image_sizes(runtime.image_sizes()) == 0
    cap = capsule(runtime)
    assert module.init(cap) is True
    tick = (PRESCALE + 1) / 25e6 * 1e6
    with scanning(runtime):
        assert module.start_loop() is True
        assert module.start_loop() is True  # a second call starts nothing more
        assert sorted(plugin_threads()) == ["arm_io IMU", "arm_io PWM"]
        wait_for(lambda: runtime.get("%IX0.0") == 1, what="PwmDriverReady")
        assert runtime.get("%IX0.1") == 0 and chip.prescale == PRESCALE
        runtime.set("%QW0", 300 + run)
        wait_for(lambda: chip.pulse_width_us(0) > 0, what="the word on the chip")
        assert chip.pulse_width_us(0) == pytest.approx((300 + run) * tick)
        wait_for(lambda: runtime.get("%IW9") > 0, what="the IMU's first sample")
        board.load([run, 2, 3], [4, 5, 16384], [7, 8, 9])  # the chips awake: it sticks
        seq = runtime.get("%IW9")
        wait_for(lambda: runtime.get("%IW9") - seq >= 3, what="three IMU samples")
        assert [runtime.get(f"%IW{i}") for i in range(9)] == [run, 2, 3, 4, 5, 16384, 7, 8, 9]
        runtime.journal_cleanup()  # a stop: the journal goes before the plugins
        time.sleep(0.05)
    assert module.stop_loop() is True
    assert plugin_threads() == []
    assert module.cleanup() is True
    assert chip.pulse_width_us(0) == pytest.approx((300 + run) * tick)  # the pose is held
    assert [t for level, t in runtime.lines if level == "error" or "unexpected" in t] == []
    assert runtime.shown()[0] == CONFIGURED, runtime.shown()
    assert runtime.format_faults == []
    for drain in runtime.drains:  # 5: JOURNAL_INT_INPUT
        words = sorted(i for t, i, _b, _v in drain if t == 5)
        assert words in ([], list(range(10))), f"a scan took half a sample: {words}"


def test_two_runs_on_the_cached_module(loaded: Loaded) -> None:
    """Two PLC runs with the plugin's threads beside the runtime's scans."""
    chip = PCA9685(address=ADDR)
    board = Gy87Board()
    bus = SimI2CBus(pca=chip, imu=board)
    loaded.smbus2.BUSES[1] = bus
    one_run(loaded, chip, board, 1)
    one_run(loaded, chip, board, 2)
    assert bus.opened == bus.closed == 4  # each run: the PWM and the IMU handle


def test_a_plugin_without_image_sizes_runs_on_a_square_image(loaded: Loaded) -> None:
    """A runtime whose image stays square (another plugin without set_image_sizes): every
    table as long as the longest, the sizes never delivered."""
    runtime = new_runtime(loaded, square=True)
    chip = PCA9685(address=ADDR)
    loaded.smbus2.BUSES[1] = SimI2CBus(pca=chip)
    assert loaded.module.init(capsule(runtime)) is True
    with scanning(runtime):
        assert loaded.module.start_loop() is True
        runtime.set("%QW2", 307)
        wait_for(lambda: chip.pulse_width_us(2) > 0, what="the word on the chip")
        assert runtime.get("%IX0.0") == 1
    assert loaded.module.stop_loop() is True


# ------------------------------------------------------------------ entry points never raise

def test_entry_points_in_the_wrong_order_or_with_garbage(loaded: Loaded,
                                                         capsys: pytest.CaptureFixture[str],
                                                         monkeypatch: pytest.MonkeyPatch
                                                         ) -> None:
    module = loaded.module
    assert module.start_loop() is False  # no init: nothing to start, said once
    assert module.start_loop() is False
    out = capsys.readouterr().out
    assert out.count("not started: init() failed") == 1
    assert module.stop_loop() is True and module.cleanup() is True
    assert module.init(None) is False
    assert "init() needs the runtime's capsule" in capsys.readouterr().out
    new = ctypes.pythonapi.PyCapsule_New
    new.argtypes = [ctypes.c_void_p, ctypes.c_char_p, ctypes.c_void_p]
    new.restype = ctypes.py_object
    wrong = new(1, WRONG_NAME, None)
    assert module.init(wrong) is False
    assert "runtime arguments: Exception during capsule extraction" in capsys.readouterr().out
    assert module.set_image_sizes(object()) == 0 and module.set_image_sizes(None) == 0

    def explode(_capsule: object) -> bool:
        raise SystemExit(3)  # PyErr_Print would end the runtime's process on this

    monkeypatch.setattr(module._LIFECYCLE, "init", explode)
    assert module.init(capsule(new_runtime(loaded))) is False
    assert "unexpected SystemExit(3)" in capsys.readouterr().out


@pytest.mark.parametrize(("config", "said", "ok"), [
    ("{not json", "JSON parsing error in config file ./core/src/drivers/plugins/python/arm_io/"
                  "arm_io.json", False),
    ('{"pca9685_address": "0x30"}', "pca9685_address must be an integer 0x40..0x7f", False),
    ('{"period_s": 0}', "period_s must be a number 0.001..0.1, got 0", False),
    ('{"mag_axes": [[0, 1], [0, 1], [2, 1]]}', "MAG_AXES must use each axis", False),
    ('{"relax_on_stop": "yes"}', "relax_on_stop must be true or false", False),
    ('{"prescale_from": "%QW3"}', "prescale_from must be a %MD location", False),
    ('{"i2c_bus": 1, "colour": "red"}', "unknown setting(s) ignored: colour", True),
    (None, "Configuration file not found", True),
])
def test_config_problems_are_one_line(loaded: Loaded, config: str | None, said: str,
                                      ok: bool) -> None:
    path = loaded.tree.config_file
    if config is None:
        path.unlink()
    else:
        path.write_text(config)
    runtime = new_runtime(loaded)
    assert loaded.module.init(capsule(runtime)) is ok
    lines = runtime.shown()
    assert len([line for line in lines if said in line]) == 1, lines
    assert len(lines) == (2 if ok else 1), lines  # and the "configured" line when it runs
    if not ok:
        assert "the plugin stays off" in lines[0]
        assert loaded.module.start_loop() is False
        assert runtime.shown()[-1] == "[ARM_IO] not started: init() failed (see its line above)"
    assert runtime.format_faults == []


def test_no_config_file_in_the_line_means_the_defaults(loaded: Loaded) -> None:
    runtime = new_runtime(loaded)
    runtime.config_path = ""
    assert loaded.module.init(capsule(runtime)) is True
    assert runtime.shown() == [CONFIGURED.replace(
        "./core/src/drivers/plugins/python/arm_io/arm_io.json",
        "defaults (no config file in plugins.conf)")]


def test_missing_psm_file_or_shared_package_is_one_line(loaded: Loaded,
                                                        capsys: pytest.CaptureFixture[str]
                                                        ) -> None:
    (loaded.tree.plugin_dir / "arm_io_psm.py").unlink()
    runtime = new_runtime(loaded)
    assert loaded.module.init(capsule(runtime)) is False
    assert runtime.shown() == [
        f"[ARM_IO] arm_io_psm.py is not next to the plugin ({loaded.tree.plugin_dir.resolve()}"
        "/arm_io_psm.py): copy plc_project/psm/arm_io_psm.py there; the plugin runs its chip "
        "logic"]
    shutil.rmtree(loaded.tree.root / "core/src/drivers/plugins/python/shared")
    for name in ("shared", "shared.image_sizes"):
        sys.modules.pop(name, None)
    assert loaded.module.init(capsule(runtime)) is False
    assert "the runtime's shared package is not importable" in capsys.readouterr().out


def test_log_lines_double_percent_signs_and_fit_log_c(loaded: Loaded) -> None:
    runtime = new_runtime(loaded)
    sink = loaded.module.runtime_log_sink(loaded.shared.PluginLogger("ARM_IO", runtime))
    sink("warn", "invalid channel word(s), driven full OFF: %QW1: 100% %s %n")
    sink("error", "x" * 5000)
    assert runtime.format_faults == []
    assert runtime.lines[0] == ("warn", "[ARM_IO] invalid channel word(s), driven full OFF: "
                                        "%QW1: 100% %s %n")
    assert runtime.lines[1][0] == "error" and len(runtime.lines[1][1]) < 1024 - 40


# ------------------------------------------------------------------ one chip logic

def _top_level_names(path: Path) -> set[str]:
    names = set()
    for node in ast.parse(path.read_text()).body:
        if isinstance(node, ast.FunctionDef | ast.ClassDef):
            names.add(node.name)
        elif isinstance(node, ast.Assign):
            names |= {t.id for t in node.targets if isinstance(t, ast.Name)}
        elif isinstance(node, ast.AnnAssign) and isinstance(node.target, ast.Name):
            names.add(node.target.id)
    return names


def test_the_chip_logic_is_the_psms(loaded: Loaded) -> None:
    """The plugin drives the chips with the PSM's classes and settings, and defines none of
    the PSM's names itself (no second copy to drift)."""
    module, psm = loaded.module, loaded.psm
    runtime = new_runtime(loaded)
    settings, _ = module.Settings.from_map({}, psm)
    plugin = module.ArmIoPlugin.create(
        psm, settings, loaded.shared.SafeBufferAccess(runtime), lambda _l, _m: None)
    assert type(plugin.pwm.driver) is psm.PCA9685Driver
    assert plugin.imu is not None and type(plugin.imu.reader) is psm.ImuReader
    shared_names = _top_level_names(PLUGIN_SRC / "arm_io_plugin.py") & _top_level_names(
        REPO / "plc_project" / "psm" / "arm_io_psm.py")
    assert shared_names == set(), shared_names
    # the shipped settings are the defaults, and the defaults the PSM's settings
    shipped = json.loads((PLUGIN_SRC / "arm_io.json").read_text())
    assert module.Settings.from_map(shipped, psm)[0] == settings
    assert (settings.i2c_bus, settings.pca9685_address, settings.mpu6050_address,
            settings.hmc5883l_address, settings.imu_period_s, settings.relax_on_stop) == (
        psm.I2C_BUS_NUMBER, psm.PCA9685_ADDRESS, psm.MPU6050_ADDRESS, psm.HMC5883L_ADDRESS,
        psm.SAMPLE_PERIOD_S, psm.FULL_OFF_ON_EXIT)


def test_readme_tables_are_the_plugins(loaded: Loaded) -> None:
    text = readme()
    rows = re.findall(r"^\| `(\w+)` \| `([^`]+)` \| ", text, re.M)
    shipped = json.loads((PLUGIN_SRC / "arm_io.json").read_text())
    assert [name for name, _ in rows] == list(shipped)
    for name, default in rows:
        assert json.loads(default) == shipped[name], name
    fields = set(loaded.module.Settings.__dataclass_fields__)
    assert set(shipped) == fields
    cmap = controller_map()
    io_rows = re.findall(r"^\| [^|]+ \| `(\w+)`(?:\.\.`(\w+)`)? \| `(%\w+(?:\.\d)?)`", text, re.M)
    assert len(io_rows) == 6
    for first, _last, location in io_rows:
        assert cmap[first.upper()].location == location, first
    assert loaded.module.DEFAULT_PRESCALE_FROM == cmap["PWMPRESCALE"].location
