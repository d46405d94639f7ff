"""OpenPLC v4 runtime plugin: the arm controller's I/O on a Raspberry Pi.

What plc_project/psm/arm_io_psm.py does as OpenPLC v3's PSM, this does as a Python plugin of
the OpenPLC v4 runtime (Autonomy-Logic/openplc-runtime), which has no PSM: the controller's
PWM words (%QW0..15) go to a PCA9685 over I2C, its init request (%QX0.0) re-initialises the
chip, the driver's state goes to %IX0.0 (ready) and %IX0.1 (fault), and an MPU6050 +
HMC5883L sample goes to %IW0..9. The chip logic is NOT copied here: it is the PSM's
PCA9685Driver and ImuReader, loaded from arm_io_psm.py next to this file (the v3 PSM must stay
one file to paste into OpenPLC's web page, so the v4 plugin imports it rather than the other
way round). This file adds what v4 needs around them: the runtime's buffer API, its log,
plugins.conf's config file, threads, and the safety rules below. README.md beside this file
says how to install it.

Safety rules (what the PSM leaves to its loop, made explicit here):
- A missing bus, a chip that does not answer or an I2C error gives ONE log line per episode
  (repeats go to the debug level) and a line when it ends; the bus is reopened and the chip
  initialised again at most once per ``retry_s``.
- On any fault the servos are relaxed (every channel full OFF, the PSM's safe state: at once
  if the chip still answers, at the re-initialisation otherwise), and a relaxed servo is
  powered again only after the controller itself relaxes it (its word for the channel reads
  full OFF: command Relax, code 4). The plugin never powers a servo at a pulse it did not
  see the controller's output stage reach from relaxed, so no fault or recovery is a jump;
  otherwise it writes exactly the controller's words. %IX0.1 stays TRUE while it holds one.
- Nothing raises into the runtime: an exception escaping init() puts the PLC in ERROR
  (plugin_driver.c checks only for an exception), and a SystemExit handed to PyErr_Print
  would end the runtime's process; every entry point and both loops catch everything.

Read in Autonomy-Logic/openplc-runtime (one file at a time; what each gave):
- core/src/drivers/README.md: the lifecycle (init(capsule), start_loop, stop_loop, cleanup),
  the plugins.conf fields, SafeBufferAccess, PluginLogger, "the plugin directory is added to
  sys.path", Python plugins get no cycle hooks (native ones get cycle_start/cycle_end).
- core/src/drivers/plugin_driver.c: python_plugin_get_symbols imports the file by its stem
  (so module names are global to the one interpreter all plugins share: no "plugin"), puts
  the plugin's directory and <venv>/lib/pythonX.Y/site-packages on sys.path; init() runs for
  every listed plugin, enabled or not, and must not start threads or read buffers; only an
  exception from init fails (its False is not checked) and fails the whole PLC start;
  set_image_sizes(sizes) is looked up as a module attribute and called before init(), a
  non-zero return fails the start too; stop_loop's result must be true ("failed to stop
  cleanly" otherwise); the args capsule is released when the plugin is torn down.
- core/src/drivers/plugin_config.c, plugin_config.h: the line format name,path,enabled,
  type,config_path,venv_path, 255-character fields, no ".." in the path.
- plugins_default.conf: the shipped plugins' lines (./core/src/drivers/plugins/python/<dir>/,
  ./venvs/<name>), the model for ours.
- core/src/drivers/plugins/python/modbus_slave/simple_modbus.py: the model plugin: the
  shared package found through sys.path.insert(0, <plugin dir>/..), PluginLogger(name,
  runtime_args), SafeBufferAccess(...).get_config_file_args_as_map(), acquire_mutex() /
  read_*(thread_safe=False) / release_mutex(), its server thread started in start_loop.
- core/src/drivers/plugins/python/shared/safe_buffer_access_refactored.py, buffer_accessor.py,
  buffer_validator.py, mutex_manager.py: the (value, "Success") / (None, message) results, a
  NULL (unlocated) cell reads as an error, writes go to the runtime's journal and need no
  lock, acquire_mutex() is image_lock() (the image mutex, and a drain of the journal).
- core/src/drivers/plugins/python/shared/plugin_runtime_args.py, capsule_extraction.py,
  config_handler.py, image_sizes.py, plugin_logger.py, safe_logging_access.py: the capsule
  name "openplc_runtime_args", the JSON config file, the per-table sizes, and that a log
  message reaches the C log_info(fmt, ...) AS ITS FORMAT STRING: a "%" must be doubled.
- core/src/plc_app/utils/log.c, log.h: that printf format, a 1024-byte line, INFO by default.
- core/src/plc_app/journal_buffer.h, journal_buffer.c: plugin writes are applied in order at
  a drain that holds the image mutex, so writes made while holding that mutex land in one
  scan: how one IMU sample stays whole.
- core/src/plc_app/plc_state_manager.cpp: each PLC start re-reads plugins.conf, tears the
  plugins down (cleanup) and runs init again on the cached module; a stop cleans up the
  journal before stop_loop.
- webserver/plugin_config_model.py, webserver/plcapp_management.py: a program upload
  rewrites plugins.conf and disables every plugin without a conf/<name>.json in the upload.
- scripts/manage_plugin_venvs.sh, install.sh: a plugin's venv is ./venvs/<name>, built from
  core/src/drivers/plugins/python/<name>/requirements.txt.
"""

from __future__ import annotations

import importlib
import importlib.util
import math
import os
import re
import sys
import threading
import time
import traceback
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from types import ModuleType
from typing import Any, Protocol

PLUGIN_NAME = "arm_io"  # plugins.conf name; the upload looks for conf/arm_io.json
LOG_NAME = "ARM_IO"  # PluginLogger prefix: "[ARM_IO] ..."
PSM_FILE = "arm_io_psm.py"
# A private module name for the PSM file: every plugin shares one interpreter, and the v3
# name "arm_io_psm" may be taken by another copy of the file.
PSM_MODULE = "_arm_io_v4_psm"
LOG_LINE_MAX = 800  # log.c formats into 1024 bytes with its time stamp and level

# Where the controller publishes the PRE_SCALE its words are computed with (PwmPrescale,
# DINT; docs/register-map.md). The v3 PSM cannot read %MD and computes its own.
DEFAULT_PRESCALE_FROM = "%MD14"
DEFAULT_PERIOD_S = 0.005  # half the controller's 10 ms task: every scan's words are seen
DEFAULT_RETRY_S = 1.0
PRESCALE_WAIT_S = 2.0  # a prescale still unpublished after this long is reported
STOP_JOIN_S = 3.0  # an I2C transfer times out in about 1 s on the Pi


class BufferAccess(Protocol):
    """The part of the runtime's shared.SafeBufferAccess this plugin uses."""

    is_valid: bool
    error_msg: str

    def acquire_mutex(self) -> tuple[bool, str]: ...

    def release_mutex(self) -> tuple[bool, str]: ...

    def read_int_output(self, buffer_idx: int, thread_safe: bool = True) -> tuple[Any, str]: ...

    def read_bool_output(self, buffer_idx: int, bit_idx: int,
                         thread_safe: bool = True) -> tuple[Any, str]: ...

    def read_dint_memory(self, buffer_idx: int, thread_safe: bool = True) -> tuple[Any, str]: ...

    def write_int_input(self, buffer_idx: int, value: int,
                        thread_safe: bool = True) -> tuple[bool, str]: ...

    def write_bool_input(self, buffer_idx: int, bit_idx: int, value: bool,
                         thread_safe: bool = True) -> tuple[bool, str]: ...

    def get_config_file_args_as_map(self) -> tuple[dict[str, Any], str]: ...

    def get_config_path(self) -> tuple[str, str]: ...


class Bus(Protocol):
    """An open smbus2.SMBus, as far as the PSM's driver and reader use it."""

    def write_i2c_block_data(self, i2c_addr: int, register: int, data: list[int]) -> None: ...

    def write_byte_data(self, i2c_addr: int, register: int, value: int) -> None: ...

    def read_i2c_block_data(self, i2c_addr: int, register: int, length: int) -> list[int]: ...

    def close(self) -> None: ...


BusOpener = Callable[[int], Bus]
Clock = Callable[[], float]
LogSink = Callable[[str, str], None]  # (level: info/warn/error/debug, message)


def open_smbus(bus_number: int) -> Bus:
    """/dev/i2c-<bus_number> through smbus2, imported here: a missing package is then one
    log line and a retry, not a plugin that fails to load."""
    from smbus2 import SMBus

    bus: Bus = SMBus(bus_number)
    return bus


# ------------------------------------------------------------------------------ settings

class SettingsError(ValueError):
    """A setting of arm_io.json the plugin cannot run with; the message says which and why."""


@dataclass(frozen=True)
class Settings:
    """arm_io.json. The defaults are the PSM's own settings (its module constants), so both
    runtimes drive the same board the same way unless the file says otherwise."""

    i2c_bus: int
    pca9685_address: int
    oscillator_hz: float
    prescale_from: str | None
    pwm_frequency_hz: float
    period_s: float
    retry_s: float
    relax_on_stop: bool
    imu_enabled: bool
    mpu6050_address: int
    hmc5883l_address: int
    mag_on_aux_bus: bool
    mag_axes: tuple[tuple[int, int], tuple[int, int], tuple[int, int]]
    imu_period_s: float
    imu_retry_s: float

    @classmethod
    def defaults(cls, psm: ModuleType) -> dict[str, Any]:
        return {
            "i2c_bus": psm.I2C_BUS_NUMBER,
            "pca9685_address": psm.PCA9685_ADDRESS,
            "oscillator_hz": psm.OSCILLATOR_HZ,
            "prescale_from": DEFAULT_PRESCALE_FROM,
            "pwm_frequency_hz": psm.PWM_FREQUENCY_HZ,
            "period_s": DEFAULT_PERIOD_S,
            "retry_s": DEFAULT_RETRY_S,
            "relax_on_stop": psm.FULL_OFF_ON_EXIT,
            "imu_enabled": psm.IMU_ENABLED,
            "mpu6050_address": psm.MPU6050_ADDRESS,
            "hmc5883l_address": psm.HMC5883L_ADDRESS,
            "mag_on_aux_bus": psm.MAG_ON_AUX_BUS,
            "mag_axes": psm.MAG_AXES,
            "imu_period_s": psm.SAMPLE_PERIOD_S,
            "imu_retry_s": psm.IMU_RETRY_S,
        }

    @classmethod
    def from_map(cls, raw: dict[str, Any], psm: ModuleType) -> tuple[Settings, list[str]]:
        """The settings, and the names in ``raw`` this plugin does not know (ignored)."""
        merged = cls.defaults(psm)
        unknown = sorted(k for k in raw if k not in merged and not k.startswith("_"))
        merged.update({k: v for k, v in raw.items() if k in merged})
        prescale_from = merged["prescale_from"]
        if prescale_from is not None:
            if not isinstance(prescale_from, str) or not re.fullmatch(
                    r"%MD\d+", prescale_from.strip(), re.IGNORECASE):
                raise SettingsError(f"prescale_from must be a %MD location (the controller's "
                                    f"PwmPrescale is %MD14) or null, got {prescale_from!r}")
            prescale_from = prescale_from.strip().upper()
        settings = cls(
            i2c_bus=_integer(merged, "i2c_bus", 0, 255),
            pca9685_address=_integer(merged, "pca9685_address", 0x40, 0x7F),
            oscillator_hz=_number(merged, "oscillator_hz", 1e6, 50e6),
            prescale_from=prescale_from,
            pwm_frequency_hz=_number(merged, "pwm_frequency_hz", 1.0, 2000.0),
            period_s=_number(merged, "period_s", 0.001, 0.1),
            retry_s=_number(merged, "retry_s", 0.1, 60.0),
            relax_on_stop=_flag(merged, "relax_on_stop"),
            imu_enabled=_flag(merged, "imu_enabled"),
            mpu6050_address=_integer(merged, "mpu6050_address", 0x68, 0x69),
            hmc5883l_address=_integer(merged, "hmc5883l_address", 0x03, 0x77),
            mag_on_aux_bus=_flag(merged, "mag_on_aux_bus"),
            mag_axes=_axes(merged["mag_axes"]),
            imu_period_s=_number(merged, "imu_period_s", 0.005, 1.0),
            imu_retry_s=_number(merged, "imu_retry_s", 0.1, 60.0),
        )
        return settings, unknown

    @property
    def bus_path(self) -> str:
        return f"/dev/i2c-{self.i2c_bus}"


def _integer(values: dict[str, Any], name: str, low: int, high: int) -> int:
    raw = values[name]
    value = raw
    if isinstance(raw, str):  # JSON has no hex literals: "0x40" is accepted
        try:
            value = int(raw, 0)
        except ValueError:
            value = None
    if not isinstance(value, int) or isinstance(value, bool) or not low <= value <= high:
        raise SettingsError(f"{name} must be an integer {low:#x}..{high:#x} ({low}..{high}), "
                            f"got {raw!r}")
    return value


def _number(values: dict[str, Any], name: str, low: float, high: float) -> float:
    raw = values[name]
    if (not isinstance(raw, int | float) or isinstance(raw, bool) or not math.isfinite(raw)
            or not low <= raw <= high):
        raise SettingsError(f"{name} must be a number {low:g}..{high:g}, got {raw!r}")
    return float(raw)


def _flag(values: dict[str, Any], name: str) -> bool:
    raw = values[name]
    if not isinstance(raw, bool):
        raise SettingsError(f"{name} must be true or false, got {raw!r}")
    return raw


def _axes(raw: object) -> tuple[tuple[int, int], tuple[int, int], tuple[int, int]]:
    try:
        pairs = [(int(a), int(s)) for a, s in raw]  # type: ignore[attr-defined]
        if len(pairs) != 3:
            raise ValueError
    except (TypeError, ValueError):
        raise SettingsError(f"mag_axes must be three [axis, sign] pairs, e.g. "
                            f"[[0, 1], [1, 1], [2, 1]], got {raw!r}") from None
    return pairs[0], pairs[1], pairs[2]


# ------------------------------------------------------------------------------ the log

def _kind(message: str) -> str:
    """What a message is about, without its detail: the text before its first colon."""
    return message.split(":", 1)[0]


@dataclass
class EpisodeLog:
    """One line when a fault starts, one when it ends, per source; while it lasts, further
    messages of the same kind (a retry that failed again, a different errno) go to the debug
    level. Thread-safe: the PWM and IMU loops share one."""

    sink: LogSink
    _active: dict[str, str] = field(default_factory=dict)
    _lock: threading.Lock = field(default_factory=threading.Lock)

    def fault(self, source: str, message: str, level: str = "error") -> None:
        kind = _kind(message)
        with self._lock:
            repeat = self._active.get(source) == kind
            self._active[source] = kind
        self.sink("debug" if repeat else level, message)

    def clear(self, source: str, message: str, *, quiet: bool = True) -> None:
        """The fault of ``source`` is over; the message goes to the debug level when there
        was none, unless ``quiet`` is False."""
        with self._lock:
            was = self._active.pop(source, None) is not None
        self.sink("info" if was or not quiet else "debug", message)

    def active(self, source: str) -> bool:
        with self._lock:
            return source in self._active

    def info(self, message: str) -> None:
        self.sink("info", message)


def runtime_log_sink(logger: Any) -> LogSink:
    """A LogSink over the runtime's PluginLogger: the message reaches C's log_info(fmt, ...)
    as its format, so every "%" is doubled ("%QW1" would otherwise be a conversion and read
    a missing argument), and long messages are cut to fit log.c's line."""

    def emit(level: str, message: str) -> None:
        text = message if len(message) <= LOG_LINE_MAX else message[:LOG_LINE_MAX] + "..."
        text = text.replace("%", "%%")
        try:
            getattr(logger, level if level in ("info", "warn", "error", "debug") else "info")(
                text)
        except Exception:  # a log call must never take the I/O loop down
            print(f"[{LOG_NAME}] {message}", flush=True)

    return emit


def print_sink(level: str, message: str) -> None:
    """Before the runtime's logger exists (init failing early): its stdout is the log too."""
    print(f"[{level.upper()}] [{LOG_NAME}] {message}", flush=True)


# ------------------------------------------------------------------------------ the image

_LOCATION = re.compile(r"%?([IQM])([XWD])(\d+)(?:\.([0-7]))?", re.IGNORECASE)


def _slot(name: str) -> tuple[str, int, int | None]:
    """("QW", 3, None) for "QW3", ("QX", 0, 0) for "QX0.0", ("MD", 14, None) for "%MD14"."""
    m = _LOCATION.fullmatch(name.strip())
    if m is None or (m.group(2).upper() == "X") != (m.group(4) is not None):
        raise ValueError(f"{name!r} is not a %IX/%QX/%IW/%QW/%MD location")
    bit = None if m.group(4) is None else int(m.group(4))
    return (m.group(1) + m.group(2)).upper(), int(m.group(3)), bit


@dataclass
class ImageIo:
    """The PSM's get_var/set_var (its PlcVars) over the runtime's buffers, one loop step at a
    time: ``refresh`` reads every location in ``reads`` under one hold of the image lock (one
    scan's outputs, not a mix of two), ``get_var`` answers from that, ``set_var`` queues, and
    ``flush`` writes the queue in order under one hold of the lock, so the runtime's journal
    applies it in one drain: a list (the IMU's ten words) reaches the program whole. The
    lock is never held across an I2C transfer: the scan never waits for the bus.

    A location the program does not declare reads as None (a NULL cell of the image)."""

    access: BufferAccess
    reads: Sequence[str]
    values: dict[str, object] = field(default_factory=dict)
    queued: list[tuple[str, object]] = field(default_factory=list)
    problems: list[str] = field(default_factory=list)
    reported: set[str] = field(default_factory=set)

    def refresh(self) -> None:
        self.values = dict.fromkeys(self.reads)
        locked, why = self.access.acquire_mutex()
        if not locked:
            self.problems.append(f"image lock: {why}")
            return
        try:
            for name in self.reads:
                self.values[name] = self._read(name)
        finally:
            self.access.release_mutex()

    def _read(self, name: str) -> object:
        area, index, bit = _slot(name)
        if area == "QW":
            value, status = self.access.read_int_output(index, thread_safe=False)
        elif area == "QX":
            assert bit is not None
            value, status = self.access.read_bool_output(index, bit, thread_safe=False)
        elif area == "MD":
            value, status = self.access.read_dint_memory(index, thread_safe=False)
        else:
            raise ValueError(f"%{name} is not an output or memory location this plugin reads")
        if status != "Success":
            self.problems.append(f"%{name}: {status}")
            return None
        return bool(value) if area == "QX" else int(value)

    def get_var(self, name: str) -> object:
        return self.values[name]

    def set_var(self, name: str, value: object) -> None:
        self.queued.append((name, value))

    def flush(self) -> None:
        if not self.queued:
            return
        queued, self.queued = self.queued, []
        locked, why = self.access.acquire_mutex()
        try:
            for name, value in queued:
                area, index, bit = _slot(name)
                values = value if isinstance(value, list) else [value]
                for offset, item in enumerate(values):
                    if area == "IX":
                        assert bit is not None
                        ok, status = self.access.write_bool_input(index, bit, bool(item))
                    elif area == "IW":
                        ok, status = self.access.write_int_input(index + offset,
                                                                 int(item) & 0xFFFF)
                    else:
                        raise ValueError(f"%{name} is not an input this plugin writes")
                    if not ok:
                        where = f"{area}{index + offset}" if area == "IW" else name
                        self.problems.append(f"%{where}: {status}")
        finally:
            if locked:
                self.access.release_mutex()
        if not locked:
            self.problems.append(f"image lock: {why}")

    def report(self, sink: LogSink) -> None:
        """Each distinct problem once, at the debug level: an undeclared location reads as
        NULL at every step, and writes fail while the PLC stops (the runtime cleans its
        journal up before it stops the plugins)."""
        problems, self.problems = self.problems, []
        for problem in problems:
            if problem not in self.reported and len(self.reported) < 256:
                self.reported.add(problem)
                sink("debug", f"image: {problem}")


@dataclass
class OutputGate:
    """Which servo channels may carry the controller's pulse. A channel is held (driven full
    OFF) from the start and after every fault until the controller's own word for it reads
    full OFF, i.e. the controller relaxed it too; from then on it carries the controller's
    words unchanged. The controller powers a relaxed servo at the pulse it was relaxed at, at
    rest (its output stage), so a servo is never powered at a pulse the stage did not reach
    from relaxed."""

    psm: ModuleType
    held: list[bool] = field(default_factory=lambda: [True] * 16)
    blocked: list[bool] = field(default_factory=lambda: [False] * 16)

    def hold_all(self) -> None:
        self.held = [True] * len(self.held)

    @property
    def holding(self) -> bool:
        """A channel is held while the controller asks for a pulse on it."""
        return any(self.blocked)

    def word(self, channel: int, raw: object) -> object:
        """What the driver may write for the controller's word ``raw`` (None: not declared)."""
        full_off = self.psm.LED_FULL << 8
        if raw is None:
            self.blocked[channel] = False
            return full_off  # a channel the program does not have stays off, no fault
        try:
            off = self.psm.channel_bytes(raw) == self.psm.FULL_OFF_BYTES
        except ValueError:
            # The driver reports the bad word and drives the channel off: hold it like a fault.
            self.held[channel] = True
            self.blocked[channel] = False
            return raw
        if off:
            self.held[channel] = False
        self.blocked[channel] = self.held[channel] and not off
        return full_off if self.blocked[channel] else raw


@dataclass
class GatedVars:
    """What the PSM's PCA9685Driver sees of the image: the channel words through the gate,
    and a fault flag that stays TRUE while the gate holds a servo the controller powers."""

    io: ImageIo
    gate: OutputGate
    channels: dict[str, int]
    fault_var: str

    def get_var(self, name: str) -> object:
        channel = self.channels.get(name)
        raw = self.io.get_var(name)
        return raw if channel is None else self.gate.word(channel, raw)

    def set_var(self, name: str, value: object) -> None:
        if name == self.fault_var:
            value = bool(value) or self.gate.holding
        self.io.set_var(name, value)


# ------------------------------------------------------------------------------ the bus

class _NoBus:
    """The bus of a driver or reader before one is open: every transfer fails as a missing
    adapter does."""

    def _fail(self, *_args: object) -> Any:
        raise OSError(19, "no I2C bus open")

    write_i2c_block_data = write_byte_data = read_i2c_block_data = _fail

    def close(self) -> None:
        pass


@dataclass
class WatchedBus:
    """The open bus, remembering whether a transfer failed since ``failed`` was cleared: the
    PSM's driver turns an OSError into a log message and carries on; the plugin needs to know
    it happened, to relax and retry."""

    bus: Bus
    failed: BaseException | None = None

    def write_i2c_block_data(self, i2c_addr: int, register: int, data: list[int]) -> None:
        self._run(self.bus.write_i2c_block_data, i2c_addr, register, data)

    def write_byte_data(self, i2c_addr: int, register: int, value: int) -> None:
        self._run(self.bus.write_byte_data, i2c_addr, register, value)

    def read_i2c_block_data(self, i2c_addr: int, register: int, length: int) -> list[int]:
        result: list[int] = self._run(self.bus.read_i2c_block_data, i2c_addr, register, length)
        return result

    def close(self) -> None:
        try:
            self.bus.close()
        except Exception:  # closing a bus that already failed may fail again
            pass

    def _run(self, method: Callable[..., Any], *args: Any) -> Any:
        try:
            return method(*args)
        except BaseException as exc:
            self.failed = exc
            raise


def _open_problem(settings: Settings, exc: BaseException) -> str:
    """The one line for a bus that would not open, saying what to do (the same from both
    loops, whichever tries first)."""
    return _open_reason(settings, exc) + (f"; servos stay relaxed, retrying every "
                                          f"{settings.retry_s:g} s")


def _open_reason(settings: Settings, exc: BaseException) -> str:
    path = settings.bus_path
    if isinstance(exc, ImportError):
        return (f"I2C bus {path}: the smbus2 package is missing ({exc}); install it into the "
                f"plugin's venv: ./venvs/{PLUGIN_NAME}/bin/pip install -r "
                f"core/src/drivers/plugins/python/{PLUGIN_NAME}/requirements.txt")
    if isinstance(exc, FileNotFoundError):
        return (f"I2C bus {path}: not found; enable I2C (sudo raspi-config nonint do_i2c 0) "
                f"and reboot, or set i2c_bus in {PLUGIN_NAME}.json")
    if isinstance(exc, PermissionError):
        return (f"I2C bus {path}: no permission ({exc}); run the runtime as root or add its "
                "user to the i2c group")
    return f"I2C bus {path}: cannot open it: {exc!r}"


# ------------------------------------------------------------------------------ the loops

@dataclass
class PwmLoop:
    """The PCA9685 side: each step, the controller's words from the image through the PSM's
    PCA9685Driver to the chip, and the driver's ready/fault flags back."""

    psm: ModuleType
    settings: Settings
    access: BufferAccess
    log: EpisodeLog
    opener: BusOpener
    sleep: Callable[[float], None]
    gate: OutputGate = field(init=False)
    io: ImageIo = field(init=False)
    driver: Any = field(init=False)
    bus: WatchedBus | None = field(init=False, default=None)
    retry_at: float = field(init=False, default=-math.inf)
    check_at: float = field(init=False, default=-math.inf)
    waiting_since: float | None = field(init=False, default=None)
    fixed_prescale: int | None = field(init=False, default=None)

    def __post_init__(self) -> None:
        psm = self.psm
        self.gate = OutputGate(psm)
        reads = [*psm.CHANNEL_VARS, psm.INIT_REQUEST_VAR]
        if self.settings.prescale_from is None:
            self.fixed_prescale = psm.prescale_for(self.settings.oscillator_hz,
                                                   self.settings.pwm_frequency_hz)
        else:
            reads.append(self.settings.prescale_from.lstrip("%"))
        self.io = ImageIo(self.access, reads)
        gated = GatedVars(self.io, self.gate,
                          {name: ch for ch, name in enumerate(psm.CHANNEL_VARS)},
                          psm.FAULT_VAR)
        self.driver = psm.PCA9685Driver(
            bus=_NoBus(), plc=gated, address=self.settings.pca9685_address,
            oscillator_hz=self.settings.oscillator_hz,
            frequency_hz=self.settings.pwm_frequency_hz, sleep=self.sleep,
            log=self._driver_said)

    def _driver_said(self, message: str) -> None:
        if message == "PCA9685 OK":  # its bus error or bad word is over
            self.log.clear("words", "every channel word is valid again")
        elif message.startswith("invalid channel word"):
            self.log.fault("words", message + "; such a channel stays relaxed until the "
                           "controller's word for it is full OFF", level="warn")
        else:
            self._chip_fault(message)

    def _chip_fault(self, message: str) -> None:
        self.log.fault("pca9685", message + f"; servos relaxed, retrying every "
                       f"{self.settings.retry_s:g} s; each servo stays relaxed until the "
                       "controller relaxes it too (Relax, code 4)")

    def _check_chip(self, now: float) -> None:
        """Once per retry_s, read MODE1 back. The driver only writes, and writes only what
        changed: an arm at rest writes nothing, so a bus that failed, or a board that lost
        power (it wakes up asleep, every output off), would go unseen until the next motion,
        and a woken chip would then take words without a pulse."""
        assert self.bus is not None
        if now < self.check_at:
            return
        self.check_at = now + self.settings.retry_s
        address = self.settings.pca9685_address
        try:
            mode1 = self.bus.read_i2c_block_data(address, self.psm.MODE1, 1)[0]
        except OSError as exc:
            problem = f"on I2C: {exc}; check wiring, power and address"
        else:
            if not mode1 & self.psm.MODE1_SLEEP and mode1 & self.psm.MODE1_AI:
                return
            problem = f"was reset (MODE1 reads 0x{mode1:02X}, asleep: it lost power?)"
        self._chip_fault(f"PCA9685 at 0x{address:02X} {problem}")
        self._fault(now)
        self._publish(ready=False, fault=True)  # after the driver's flags of this step

    def step(self, now: float) -> None:
        try:
            self._step(now)
        except Exception as exc:
            self.log.fault("loop", f"PWM loop: unexpected {exc!r}; servos relaxed, retrying "
                                   f"every {self.settings.retry_s:g} s")
            self.log.sink("debug", traceback.format_exc())
            self._fault(now)
        finally:
            self._flush()

    def _step(self, now: float) -> None:
        self.io.refresh()
        prescale = self._prescale(now)
        if self.bus is None:
            if now < self.retry_at:
                self._publish(ready=False, fault=True)
                return
            try:
                self.bus = WatchedBus(self.opener(self.settings.i2c_bus))
            except Exception as exc:
                self.log.fault("bus", _open_problem(self.settings, exc))
                self._fault(now)
                self._publish(ready=False, fault=True)
                return
            if self.log.active("bus"):
                self.log.clear("bus", f"I2C bus {self.settings.bus_path} open")
            self.driver.bus = self.bus
        if prescale is None:
            return
        if prescale != self.driver.prescale:
            # PRE_SCALE is written only asleep: a new one means a new initialisation.
            self.driver.prescale = prescale
            self.driver.initialised = False
        self.bus.failed = None
        self.driver.poll()
        if self.bus.failed is not None:
            self._fault(now)
            return
        if self.driver.initialised:
            self._check_chip(now)
        if self.bus is None or not self.driver.initialised:
            return
        if self.log.active("pca9685"):
            self.log.clear("pca9685", f"PCA9685 at 0x{self.settings.pca9685_address:02X} "
                                      "answers again; servos follow the controller once it "
                                      "has relaxed them")
        if self.log.active("loop"):
            self.log.clear("loop", "PWM loop runs again")

    def _prescale(self, now: float) -> int | None:
        """The PRE_SCALE the controller computes its words with; None until it is valid."""
        if self.fixed_prescale is not None:
            return self.fixed_prescale
        assert self.settings.prescale_from is not None
        value = self.io.get_var(self.settings.prescale_from.lstrip("%"))
        if isinstance(value, int) and 3 <= value <= 255:
            self.waiting_since = None
            if self.log.active("prescale"):
                self.log.clear("prescale", f"PwmPrescale ({self.settings.prescale_from}) "
                                           f"is {value}")
            return value
        # 0 until the program's first scan; absent in a program that is not the controller
        if self.waiting_since is None:
            self.waiting_since = now
        elif now - self.waiting_since >= PRESCALE_WAIT_S:
            what = "not declared by the program" if value is None else f"{value}"
            self.log.fault("prescale", (
                f"PwmPrescale ({self.settings.prescale_from}): {what}, not a PCA9685 PRE_SCALE "
                "(3..255); the chip stays uninitialised. Is the arm controller running? For "
                f"another program set prescale_from null and pwm_frequency_hz in "
                f"{PLUGIN_NAME}.json"), level="warn")
        return None

    def _fault(self, now: float) -> None:
        """Relax now if the chip still listens, and come back only after ``retry_s``."""
        self.gate.hold_all()
        self.driver.initialised = False
        if self.bus is not None:
            try:
                self.driver.shutdown()  # ALL_LED_OFF_H full OFF: every servo limp
            except Exception:
                pass  # the chip is gone: its outputs stop with it, or at the re-init
            self.bus.close()
            self.bus = None
            self.driver.bus = _NoBus()
        self.retry_at = now + self.settings.retry_s

    def _publish(self, *, ready: bool, fault: bool) -> None:
        self.io.set_var(self.psm.READY_VAR, ready)
        self.io.set_var(self.psm.FAULT_VAR, fault)

    def _flush(self) -> None:
        try:
            self.io.flush()
        except Exception as exc:
            self.io.problems.append(repr(exc))
        self.io.report(self.log.sink)

    def stop(self, *, relax: bool) -> None:
        """After the loop's thread ended: relax if asked, and close the bus."""
        if self.bus is None:
            return
        if relax:
            try:
                self.driver.shutdown()
                self.log.info("servos relaxed on stop (relax_on_stop)")
            except Exception as exc:
                self.log.sink("warn", f"relax on stop failed: {exc!r}")
        self.bus.close()
        self.bus = None
        self.driver.bus = _NoBus()


@dataclass
class ImuLoop:
    """The IMU side, on its own bus handle and thread: the PSM's ImuReader resets the MPU6050
    with a 100 ms pause, which must not hold up the servos' words."""

    psm: ModuleType
    settings: Settings
    access: BufferAccess
    log: EpisodeLog
    opener: BusOpener
    sleep: Callable[[float], None]
    io: ImageIo = field(init=False)
    reader: Any = field(init=False)
    bus: WatchedBus | None = field(init=False, default=None)
    retry_at: float = field(init=False, default=-math.inf)

    def __post_init__(self) -> None:
        self.io = ImageIo(self.access, ())
        self.reader = self.psm.ImuReader(
            bus=_NoBus(), plc=self.io, period_s=self.settings.imu_period_s,
            mpu_address=self.settings.mpu6050_address,
            hmc_address=self.settings.hmc5883l_address,
            mag_on_aux_bus=self.settings.mag_on_aux_bus, mag_axes=self.settings.mag_axes,
            retry_s=self.settings.imu_retry_s, sleep=self.sleep, log=self._reader_said)

    def _reader_said(self, message: str) -> None:
        if message.startswith("IMU ready"):
            self.log.clear("imu", message, quiet=False)
        elif message == "IMU OK":
            self.log.sink("debug", message)
        else:
            self.log.fault("imu", message + f"; retrying every {self.settings.imu_retry_s:g} "
                           f"s (no IMU wired? set imu_enabled false in {PLUGIN_NAME}.json)",
                           level="warn")

    def step(self, now: float) -> None:
        try:
            self._step(now)
        except Exception as exc:
            self.log.fault("imu", f"IMU loop: unexpected {exc!r}; retrying every "
                                  f"{self.settings.imu_retry_s:g} s", level="warn")
            self.log.sink("debug", traceback.format_exc())
            self._close(now)
        finally:
            try:
                self.io.flush()
            except Exception as exc:
                self.io.problems.append(repr(exc))
            self.io.report(self.log.sink)

    def _step(self, now: float) -> None:
        if self.bus is None:
            if now < self.retry_at:
                return
            try:
                self.bus = WatchedBus(self.opener(self.settings.i2c_bus))
            except Exception as exc:
                self.log.fault("bus", _open_problem(self.settings, exc))
                self.retry_at = now + self.settings.imu_retry_s
                return
            self.reader.bus = self.bus
        self.reader.poll(now)
        if not self.reader.initialised:  # it failed, and retries after imu_retry_s itself
            self._close(now)

    def _close(self, now: float) -> None:
        self.reader.initialised = False
        if self.bus is not None:
            self.bus.close()
            self.bus = None
            self.reader.bus = _NoBus()
        self.retry_at = now + self.settings.imu_retry_s

    def stop(self) -> None:
        if self.bus is not None:
            self.bus.close()
            self.bus = None
            self.reader.bus = _NoBus()


@dataclass
class PeriodicThread:
    """Calls ``step(clock())`` every ``period_s`` on a deadline grid until stopped; a step
    that overruns is followed at once, a stall of a whole period resets the grid."""

    name: str
    step: Callable[[float], None]
    period_s: float
    clock: Clock
    log: EpisodeLog
    stop_event: threading.Event = field(default_factory=threading.Event)
    thread: threading.Thread | None = None

    def start(self) -> None:
        self.stop_event.clear()
        self.thread = threading.Thread(target=self._run, name=self.name, daemon=True)
        self.thread.start()

    def _run(self) -> None:
        deadline = self.clock()
        while not self.stop_event.is_set():
            try:
                self.step(self.clock())
            except BaseException as exc:  # the steps catch Exception; this is the last net
                self.log.fault(self.name, f"{self.name}: {exc!r}")
            deadline += self.period_s
            delay = deadline - self.clock()
            if delay < -self.period_s:
                deadline = self.clock()
                delay = 0.0
            self.stop_event.wait(max(delay, 0.0))

    def stop(self, timeout_s: float) -> bool:
        """True when the thread has ended."""
        self.stop_event.set()
        if self.thread is None:
            return True
        self.thread.join(timeout_s)
        ended = not self.thread.is_alive()
        if ended:
            self.thread = None
        return ended


# ------------------------------------------------------------------------------ the plugin

@dataclass
class ArmIoPlugin:
    """One init()..cleanup() of the plugin: the two loops and their threads."""

    settings: Settings
    log: EpisodeLog
    pwm: PwmLoop
    imu: ImuLoop | None
    clock: Clock
    pwm_thread: PeriodicThread | None = None
    imu_thread: PeriodicThread | None = None

    @classmethod
    def create(cls, psm: ModuleType, settings: Settings, access: BufferAccess, sink: LogSink,
               *, opener: BusOpener = open_smbus, clock: Clock = time.monotonic,
               sleep: Callable[[float], None] = time.sleep) -> ArmIoPlugin:
        """Raises SettingsError for settings the PSM's classes refuse."""
        log = EpisodeLog(sink)
        try:
            pwm = PwmLoop(psm, settings, access, log, opener, sleep)
            imu = ImuLoop(psm, settings, access, log, opener, sleep) \
                if settings.imu_enabled else None
        except ValueError as exc:
            raise SettingsError(str(exc)) from exc
        return cls(settings, log, pwm, imu, clock)

    def step(self, now: float) -> None:
        """One step of both loops (what the threads do, each at its period)."""
        self.pwm.step(now)
        if self.imu is not None:
            self.imu.step(now)

    @property
    def running(self) -> bool:
        return self.pwm_thread is not None or self.imu_thread is not None

    def start(self) -> None:
        if self.running:
            return
        self.pwm_thread = PeriodicThread("arm_io PWM", self.pwm.step, self.settings.period_s,
                                         self.clock, self.log)
        self.pwm_thread.start()
        if self.imu is not None:
            self.imu_thread = PeriodicThread("arm_io IMU", self.imu.step,
                                             self.settings.period_s, self.clock, self.log)
            self.imu_thread.start()

    def stop(self) -> bool:
        """Stop the threads; then relax (relax_on_stop) and close the buses. False when a
        thread is still stuck in a transfer after STOP_JOIN_S: its bus is left to it."""
        pwm_done = self.pwm_thread is None or self.pwm_thread.stop(STOP_JOIN_S)
        imu_done = self.imu_thread is None or self.imu_thread.stop(STOP_JOIN_S)
        if pwm_done:
            self.pwm_thread = None
            self.pwm.stop(relax=self.settings.relax_on_stop)
        if imu_done:
            self.imu_thread = None
            if self.imu is not None:
                self.imu.stop()
        if not (pwm_done and imu_done):
            self.log.sink("error", f"a loop did not stop within {STOP_JOIN_S:g} s (an I2C "
                                   "transfer hanging?)")
        return pwm_done and imu_done


# ------------------------------------------------------------------------------ loading

def load_psm(plugin_dir: str) -> ModuleType:
    """The PSM file next to this one (installed layout), else ../psm/ (this repository's
    layout), as module PSM_MODULE. It imports neither psm nor smbus2 at module level."""
    here = os.path.join(plugin_dir, PSM_FILE)
    candidates = [here, os.path.join(plugin_dir, os.pardir, "psm", PSM_FILE)]
    path = next((p for p in candidates if os.path.isfile(p)), None)
    if path is None:
        raise FileNotFoundError(f"{PSM_FILE} is not next to the plugin ({here}): copy "
                                f"plc_project/psm/{PSM_FILE} there; the plugin runs its "
                                "chip logic")
    path = os.path.realpath(path)
    loaded = sys.modules.get(PSM_MODULE)
    if loaded is not None and getattr(loaded, "__file__", None) == path:
        return loaded
    spec = importlib.util.spec_from_file_location(PSM_MODULE, path)
    if spec is None or spec.loader is None:
        raise ImportError(f"cannot load {path}")
    module = importlib.util.module_from_spec(spec)
    sys.modules[PSM_MODULE] = module  # dataclasses look their module up while building
    try:
        spec.loader.exec_module(module)
    except BaseException:
        del sys.modules[PSM_MODULE]
        raise
    return module


def import_shared(plugin_dir: str) -> ModuleType:
    """The runtime's ``shared`` package, found as the shipped plugins find it: in the
    directory above the plugin's (core/src/drivers/plugins/python/)."""
    try:
        return importlib.import_module("shared")
    except ImportError:
        parent = os.path.realpath(os.path.join(plugin_dir, os.pardir))
        if parent not in sys.path:
            sys.path.insert(0, parent)
        return importlib.import_module("shared")


def _is_capsule(obj: object) -> bool:
    return type(obj).__name__ == "PyCapsule"


@dataclass
class Lifecycle:
    """init/start_loop/stop_loop/cleanup of the runtime, kept in the one module-level object
    the runtime's interface forces (it calls module functions, and imports the module once
    for the life of the process: every PLC start runs cleanup() then init() again on it)."""

    plugin_dir: str
    plugin: ArmIoPlugin | None = None
    sink: LogSink = print_sink
    lock: threading.Lock = field(default_factory=threading.Lock)
    not_ready_said: bool = False

    def init(self, capsule: object) -> bool:
        with self.lock:
            self._drop()
            self.sink = print_sink
            self.not_ready_said = False
            try:
                shared = import_shared(self.plugin_dir)
            except Exception as exc:
                self.sink("error", f"the runtime's shared package is not importable ({exc!r}):"
                          f" install the plugin in core/src/drivers/plugins/python/"
                          f"{PLUGIN_NAME}/")
                return False
            if not _is_capsule(capsule):
                self.sink("error", f"init() needs the runtime's capsule, got {type(capsule)}")
                return False
            args, why = shared.safe_extract_runtime_args_from_capsule(capsule)
            if args is None:
                self.sink("error", f"runtime arguments: {why}")
                return False
            logger_class = getattr(shared, "PluginLogger", None)
            if logger_class is not None:
                self.sink = runtime_log_sink(logger_class(LOG_NAME, args))
            access = shared.SafeBufferAccess(args)
            if not access.is_valid:
                self.sink("error", f"buffer access: {access.error_msg}")
                return False
            try:
                psm = load_psm(self.plugin_dir)
            except Exception as exc:
                self.sink("error", f"{exc}")
                return False
            raw, where = self._config(access)
            if raw is None:
                return False
            try:
                settings, unknown = Settings.from_map(raw, psm)
                self.plugin = ArmIoPlugin.create(psm, settings, access, self.sink)
            except SettingsError as exc:
                self.sink("error", f"{where}: {exc}; the plugin stays off")
                return False
            if unknown:
                self.sink("warn", f"{where}: unknown setting(s) ignored: {', '.join(unknown)}")
            imu = (f"IMU (MPU6050 0x{settings.mpu6050_address:02X}, HMC5883L "
                   f"0x{settings.hmc5883l_address:02X}) every {settings.imu_period_s:g} s"
                   if settings.imu_enabled else "no IMU")
            prescale = (f"PRE_SCALE from {settings.prescale_from}"
                        if settings.prescale_from else
                        f"{settings.pwm_frequency_hz:g} Hz")
            self.sink("info", f"configured from {where}: PCA9685 0x"
                              f"{settings.pca9685_address:02X} on {settings.bus_path}, "
                              f"{prescale}, every {settings.period_s:g} s; {imu}")
            return True

    def _config(self, access: BufferAccess) -> tuple[dict[str, Any] | None, str]:
        path, _ = access.get_config_path()
        raw, status = access.get_config_file_args_as_map()
        if status == "Success":
            return raw, path
        if not path:
            return {}, "defaults (no config file in plugins.conf)"
        if "not found" in status:
            self.sink("warn", f"{status}; running with the defaults")
            return {}, "defaults"
        self.sink("error", f"{status}; the plugin stays off")
        return None, path

    def start_loop(self) -> bool:
        with self.lock:
            if self.plugin is None:
                if not self.not_ready_said:
                    self.sink("error", "not started: init() failed (see its line above)")
                    self.not_ready_said = True
                return False
            self.plugin.start()
            return True

    def stop_loop(self) -> bool:
        with self.lock:
            if self.plugin is None:
                return True
            return self.plugin.stop()

    def cleanup(self) -> bool:
        with self.lock:
            self._drop()
            return True

    def _drop(self) -> None:
        """Stop and forget the plugin: the runtime releases the args it reads through."""
        if self.plugin is not None:
            self.plugin.stop()
            self.plugin = None


_LIFECYCLE = Lifecycle(os.path.dirname(os.path.realpath(__file__)))


def _guard(entry: Callable[[], Any], failed: Any) -> Any:
    """Run an entry point; nothing may leave it (see the module docstring)."""
    try:
        return entry()
    except BaseException as exc:
        try:
            _LIFECYCLE.sink("error", f"unexpected {exc!r} (the runtime was not told)")
            _LIFECYCLE.sink("debug", traceback.format_exc())
        except BaseException:
            pass
        return failed


def init(runtime_args_capsule: object) -> bool:
    """Runtime entry point: parse the config, prepare; no thread, no I2C, no buffer read."""
    return bool(_guard(lambda: _LIFECYCLE.init(runtime_args_capsule), False))


def start_loop() -> bool:
    """Runtime entry point: start the PWM (and IMU) loop."""
    return bool(_guard(_LIFECYCLE.start_loop, False))


def stop_loop() -> bool:
    """Runtime entry point: stop the loops (relax first if relax_on_stop)."""
    return bool(_guard(_LIFECYCLE.stop_loop, False))


def cleanup() -> bool:
    """Runtime entry point: stop if needed and drop every reference into the runtime."""
    return bool(_guard(_LIFECYCLE.cleanup, True))


def set_image_sizes(sizes: object) -> int:
    """Runtime entry point, before init(): the image's table lengths, handed to the shared
    package's store that SafeBufferAccess bounds every index with. Its presence tells the
    runtime this plugin copes with tables of different lengths (it reads and writes only
    through SafeBufferAccess). Always 0: non-zero would fail the whole PLC start."""

    def forward() -> int:
        import_shared(_LIFECYCLE.plugin_dir)
        from shared.image_sizes import set_image_sizes as store

        store(sizes)
        return 0

    _guard(forward, 0)
    return 0
