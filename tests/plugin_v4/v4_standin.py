"""STAND-INS, for the tests only, of what the OpenPLC v4 runtime gives a Python plugin, so that
plc_project/v4_plugin/arm_io_plugin.py runs here as it runs there (Autonomy-Logic/
openplc-runtime, read file by file; the plugin's docstring lists the files):

- ``RuntimeTree``: a runtime checkout's layout in a temporary folder: the stand-in ``shared``
  package at core/src/drivers/plugins/python/shared/ (runtime_standin/shared/), the plugin
  installed by the README's own copy commands, a venv (venvs/arm_io/lib/pythonX.Y/
  site-packages/ holding the stand-in smbus2), and plugins.conf with the README's line.
- ``load_plugin``: python_plugin_get_symbols of plugin_driver.c: parse the line as
  plugin_config.c does, put the plugin's directory and the venv's site-packages first on
  sys.path, import the module by its file's stem, look its functions up.
- ``StandInRuntime``: the C side the capsule points to (plugin_runtime_args_t): the image
  tables (a NULL cell where the program declares no variable), image_lock/image_unlock (the
  image mutex, and a drain of the journal), journal_write_* (ordered, applied at the next
  drain: at the start of a scan, or by any image_lock), the log functions (which take the
  message as a printf FORMAT: an unescaped "%" is recorded as a fault, as it is undefined
  behaviour in log.c), and the plugin's config file path. ``capsule`` wraps it in a real
  PyCapsule named "openplc_runtime_args". Backed by a soft PLC's ProcessImage, so the
  controller program can run on the same image (``read_inputs`` is the scan's drain).
- ``SimI2CBus``: the I2C adapter behind the stand-in smbus2: the PCA9685 and GY-87 (MPU6050 +
  HMC5883L) models of sim/armbench/plant/, one transfer at a time, NACK for an absent
  address (OSError 121), ``down`` for a bus that fails every transfer.
"""

from __future__ import annotations

import ctypes
import importlib
import re
import shutil
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from types import ModuleType
from typing import Any

from armbench.plant.imu_chips import Gy87Board
from armbench.plant.pca9685 import PCA9685, I2CNackError
from armbench.registermap import controller_map
from armbench.softplc.image import ProcessImage

REPO = Path(__file__).resolve().parents[2]
PLUGIN_SRC = REPO / "plc_project" / "v4_plugin"
README = PLUGIN_SRC / "README.md"
STANDIN = Path(__file__).resolve().parent / "runtime_standin"
PYTHON_DIR = "core/src/drivers/plugins/python"
CAPSULE_NAME = b"openplc_runtime_args"  # a constant: PyCapsule_New keeps the pointer
# The module names of the plugins the runtime ships (plugins_default.conf): one interpreter
# holds them all, so a plugin's file stem must differ from each.
SHIPPED_MODULES = ("simple_modbus", "modbus_master_plugin", "plugin", "opcua_client_plugin")
MAX_FIELD = 255  # plugin_config.h: MAX_PLUGIN_NAME_LEN 64, MAX_PLUGIN_PATH_LEN 256 (with NUL)
MAX_NAME = 63

# ------------------------------------------------------------------------------ the C side

Entry = tuple[int, int, int | None, int]  # journal type, index, bit, value
JOURNAL_TABLES = {0: "bool_input", 1: "bool_output", 2: "bool_memory", 3: "byte_input",
                  4: "byte_output", 5: "int_input", 6: "int_output", 7: "int_memory",
                  8: "dint_input", 9: "dint_output", 10: "dint_memory", 11: "lint_input",
                  12: "lint_output", 13: "lint_memory"}
_AREAS = {("I", "X"): "bool_input", ("Q", "X"): "bool_output", ("I", "W"): "int_input",
          ("Q", "W"): "int_output", ("M", "D"): "dint_memory", ("M", "W"): "int_memory"}


@dataclass
class Cell:
    """One located variable: a pointer into the image (a view and an index)."""

    view: memoryview
    index: int

    def get(self) -> int:
        return int(self.view[self.index])

    def set(self, value: int) -> None:
        self.view[self.index] = value


@dataclass
class StandInRuntime:
    """plugin_runtime_args_t and the runtime functions behind its pointers (see module doc).
    ``lock`` is the image mutex: the soft PLC's scan lock when a program runs on ``image``."""

    image: ProcessImage
    locations: Sequence[str]
    lock: Any = field(default_factory=threading.Lock)
    config_path: str = ""
    # A plugin without set_image_sizes makes the runtime keep every table as long as the
    # longest (a "square" image); with it, each table is as long as the program needs.
    square: bool = False
    tables: dict[str, list[Any]] = field(init=False)
    capacities: dict[str, int] = field(init=False)
    buffer_size: int = field(init=False)
    bits_per_buffer: int = 8
    journal: list[Entry] = field(default_factory=list)
    drains: list[list[Entry]] = field(default_factory=list)
    journal_ready: bool = True
    lines: list[tuple[str, str]] = field(default_factory=list)
    format_faults: list[str] = field(default_factory=list)
    lock_holds: int = 0
    # A scan that starts between two journal writes whenever the image lock is free: what
    # the runtime's scan may do to a writer that does not hold the lock.
    scan_between_writes: bool = False
    _journal_lock: threading.Lock = field(default_factory=threading.Lock)

    def __post_init__(self) -> None:
        views = {"bool_input": self.image.ix, "bool_output": self.image.qx,
                 "int_input": self.image.iw, "int_output": self.image.qw,
                 "dint_memory": self.image.md, "int_memory": self.image.mw}
        # v4 sizes each table to what the program declares (RTOP-284): up to its last one
        found: dict[str, set[tuple[int, int | None]]] = {t: set() for t in views}
        for loc in self.locations:
            m = re.fullmatch(r"%([IQM])([XWD])(\d+)(?:\.(\d))?", loc)
            assert m, loc
            table = _AREAS[(m.group(1), m.group(2))]
            found[table].add((int(m.group(3)), None if m.group(4) is None else int(m.group(4))))
        self.tables, self.capacities = {}, {}
        longest = max(max((i for i, _ in f), default=-1) + 1 for f in found.values())
        for table, view in views.items():
            size = longest if self.square else max((i for i, _ in found[table]), default=-1) + 1
            self.capacities[table] = size
            if table.startswith("bool"):
                self.tables[table] = [[Cell(view, 8 * i + b) if (i, b) in found[table] else None
                                       for b in range(8)] for i in range(size)]
            else:
                self.tables[table] = [Cell(view, i) if (i, None) in found[table] else None
                                      for i in range(size)]
        # the smallest table (RTOP-284); a square image's one length
        self.buffer_size = min(c for c in self.capacities.values() if c > 0)

    # -- plugin_runtime_args_t fields
    @property
    def plugin_specific_config_file_path(self) -> bytes:
        return self.config_path.encode("utf-8")

    def validate_pointers(self) -> tuple[bool, str]:
        if not 0 < self.buffer_size <= 65536:
            return False, f"buffer_size is {self.buffer_size}, outside 1..65536"
        return True, "All pointers valid"

    def safe_access_buffer_size(self) -> tuple[int, str]:
        return self.buffer_size, "Success"

    def image_sizes(self) -> list[int]:
        """What plugin_driver.c hands set_image_sizes, in shared/image_sizes.py's order."""
        order = ["bool_input", "bool_output", "byte_input", "byte_output", "int_input",
                 "int_output", "dint_input", "dint_output", "lint_input", "lint_output",
                 "int_memory", "dint_memory", "lint_memory", "bool_memory"]
        return [self.capacities.get(t, 0) for t in order]

    # -- image_lock / image_unlock: the image mutex, and a drain (flush-on-lock)
    def image_lock(self) -> None:
        self.lock.acquire()
        self.lock_holds += 1
        self.drain()

    def image_unlock(self) -> None:
        self.lock.release()

    # -- journal_write_*: lock-free for the caller, applied in order at the next drain
    def _journal(self, entry: Entry) -> int:
        with self._journal_lock:
            if not self.journal_ready:
                return -1
            self.journal.append(entry)
        if self.scan_between_writes and self.lock.acquire(blocking=False):
            try:
                self.drain()
            finally:
                self.lock.release()
        return 0

    def journal_write_bool(self, jtype: int, index: int, bit: int, value: int) -> int:
        return self._journal((jtype, index, bit, value))

    def journal_write_int(self, jtype: int, index: int, value: int) -> int:
        return self._journal((jtype, index, None, value & 0xFFFF))

    def journal_write_dint(self, jtype: int, index: int, value: int) -> int:
        return self._journal((jtype, index, None, value & 0xFFFFFFFF))

    def drain(self) -> None:
        """journal_apply_and_clear (the caller holds the image mutex): apply in order; an
        index outside its table or a NULL cell drops the write, silently, as the runtime."""
        with self._journal_lock:
            entries, self.journal = self.journal, []
        if not entries:
            return
        self.drains.append(entries)
        for jtype, index, bit, value in entries:
            table = self.tables.get(JOURNAL_TABLES[jtype])
            if table is None or not 0 <= index < len(table):
                continue
            cell = table[index][bit] if bit is not None else table[index]
            if cell is not None:
                cell.set(value)

    def journal_cleanup(self) -> None:
        """What a PLC stop does before stop_loop: plugin writes fail from then on."""
        with self._journal_lock:
            self.journal_ready = False
            self.journal = []

    # -- the soft PLC's ScanIo: the scan's drain, under its own hold of the lock
    def read_inputs(self) -> None:
        self.drain()

    def write_outputs(self) -> None:
        pass

    # -- log_info(fmt, ...) and friends: the message IS the printf format
    def _log(self, level: str, fmt: bytes) -> None:
        text = fmt.decode("utf-8")
        stray = re.sub(r"%%", "", text)
        if "%" in stray:
            self.format_faults.append(text)
        self.lines.append((level, text.replace("%%", "%")))

    def log_info(self, fmt: bytes) -> None:
        self._log("info", fmt)

    def log_debug(self, fmt: bytes) -> None:
        self._log("debug", fmt)

    def log_warn(self, fmt: bytes) -> None:
        self._log("warn", fmt)

    def log_error(self, fmt: bytes) -> None:
        self._log("error", fmt)

    def shown(self) -> list[str]:
        """The lines at INFO and above: what log.c (level INFO by default) lets through."""
        return [text for level, text in self.lines if level != "debug"]

    # -- test helpers
    def set(self, location: str, value: int) -> None:
        """The program writing a located variable (direct, as a scan does)."""
        table, index, bit = self.slot(location)
        row = self.tables[table][index]
        cell = row[bit] if bit is not None else row
        assert cell is not None, f"{location} is not declared"
        with self.lock:
            cell.set(value)

    def get(self, location: str) -> int:
        table, index, bit = self.slot(location)
        row = self.tables[table][index]
        cell = row[bit] if bit is not None else row
        assert cell is not None, f"{location} is not declared"
        with self.lock:
            return cell.get()

    @staticmethod
    def slot(location: str) -> tuple[str, int, int | None]:
        m = re.fullmatch(r"%([IQM])([XWD])(\d+)(?:\.(\d))?", location)
        assert m, location
        bit = None if m.group(4) is None else int(m.group(4))
        return _AREAS[(m.group(1), m.group(2))], int(m.group(3)), bit


def controller_locations() -> list[str]:
    """Every location Controller.st declares (the v4 image holds exactly these)."""
    return sorted({r.location for r in controller_map().values()})


def capsule(args: StandInRuntime) -> Any:
    """A PyCapsule named "openplc_runtime_args" holding the address of ``args``, as
    plugin_driver.c's create_python_runtime_args_capsule wraps the C struct. The caller keeps
    ``args`` alive (the runtime keeps the struct for the plugin's life)."""
    new = ctypes.pythonapi.PyCapsule_New
    new.argtypes = [ctypes.c_void_p, ctypes.c_char_p, ctypes.c_void_p]
    new.restype = ctypes.py_object
    return new(id(args), CAPSULE_NAME, None)


# ------------------------------------------------------------------------------ the bus

@dataclass
class SimI2CBus:
    """The adapter behind /dev/i2c-N (see module doc). ``clock`` is the time the PCA9685
    model advances by between transfers (its 500 us RESTART rule)."""

    pca: PCA9685 | None = None
    imu: Gy87Board | None = None
    clock: Callable[[], float] = time.monotonic
    down: bool = False
    fail_next: int = 0
    log: list[tuple[float, int, int, bytes | int]] = field(default_factory=list)
    opened: int = 0
    closed: int = 0
    failures: int = 0  # transfers that failed (down, fail_next)
    _lock: threading.Lock = field(default_factory=threading.Lock)
    _last: float | None = None

    def open(self) -> int:
        with self._lock:
            self.opened += 1
            return 100 + self.opened

    def close(self) -> None:
        with self._lock:
            self.closed += 1

    def _transfer(self) -> float:
        now = self.clock()
        if self.pca is not None and self._last is not None and now > self._last:
            # to the nanosecond: a fake clock's float sums must not make 500 us read 499.99
            self.pca.advance(round(now - self._last, 9))
        self._last = now
        if self.down or self.fail_next:
            self.fail_next = max(0, self.fail_next - 1)
            self.failures += 1
            raise OSError(121, "Remote I/O error")
        return now

    def write(self, address: int, register: int, data: bytes) -> None:
        with self._lock:
            now = self._transfer()
            self.log.append((now, address, register, bytes(data)))
            if self.pca is not None and self.pca.acknowledges(address):
                self.pca.write(address, register, bytes(data))
            elif self.imu is not None:
                self.imu.write_i2c_block_data(address, register, list(data))
            else:
                raise I2CNackError(f"no device acknowledged address 0x{address:02X}")

    def read(self, address: int, register: int, length: int) -> bytes:
        with self._lock:
            now = self._transfer()
            self.log.append((now, address, register, length))
            if self.pca is not None and address == self.pca.address:
                return self.pca.read(address, register, length)
            if self.imu is not None:
                return bytes(self.imu.read_i2c_block_data(address, register, length))
            raise I2CNackError(f"no device acknowledged address 0x{address:02X}")

    def writes_to(self, address: int) -> list[tuple[int, bytes]]:
        with self._lock:
            return [(reg, data) for _t, a, reg, data in self.log
                    if a == address and isinstance(data, bytes)]


# ------------------------------------------------------------------------------ the tree

def readme() -> str:
    return README.read_text(encoding="utf-8")


def conf_line() -> str:
    """The plugins.conf line the README gives (its one ```text block starting "arm_io,")."""
    lines = re.findall(r"^(arm_io,[^\n]*)$", readme(), re.M)
    assert len(lines) == 1, lines
    return lines[0]


def install_commands() -> str:
    """The README's ```sh block that copies the plugin into the runtime's tree."""
    blocks = [b for b in re.findall(r"```sh\n(.*?)```", readme(), re.S)
              if re.search(r"^cp ", b, re.M)]
    assert len(blocks) == 1, blocks
    return blocks[0]


@dataclass(frozen=True)
class PluginLine:
    """One plugins.conf entry, as plugin_config.c's parser reads it."""

    name: str
    path: str
    enabled: int
    type: int
    config_path: str
    venv_path: str


def parse_conf_line(line: str) -> PluginLine:
    """parse_plugin_config_internal: strtok on ',' (so an empty field is skipped, not kept),
    fields cut at 255 characters, trailing blanks stripped, a ".." component refused, the
    venv field optional."""
    assert len(line) + 1 < 512, "fgets reads 511 characters a line"
    assert not line.startswith("#")
    tokens = [t for t in line.split(",") if t != ""]
    assert len(tokens) == len(line.split(",")), "an empty field shifts the next one (strtok)"
    name, path, enabled, ptype, config_path, *rest = tokens
    for value, limit in ((name, MAX_NAME), (path, MAX_FIELD), (config_path, MAX_FIELD),
                         *((v, MAX_FIELD) for v in rest)):
        assert len(value) <= limit, f"{value!r} is cut at {limit} characters"
    assert not any(part == ".." for part in re.split(r"[/\\]", path)), "'..' is refused"
    return PluginLine(name.rstrip(), path.rstrip(), int(enabled), int(ptype),
                      config_path.rstrip(), rest[0].rstrip() if rest else "")


def site_packages(venv: Path) -> Path:
    """Where plugin_driver.c looks in a plugin's venv: <venv>/lib/pythonX.Y/site-packages."""
    return venv / "lib" / f"python{sys.version_info.major}.{sys.version_info.minor}" \
        / "site-packages"


@dataclass
class RuntimeTree:
    """A runtime checkout in ``root``, the plugin installed as the README says."""

    root: Path
    line: PluginLine = field(init=False)

    def __post_init__(self) -> None:
        shutil.copytree(STANDIN / "shared", self.root / PYTHON_DIR / "shared")
        # the README's copy commands, run as written, from the runtime's root
        proc = subprocess.run(["bash", "-euc", install_commands()], cwd=self.root,
                              env={"ARM": str(REPO), "PATH": "/usr/bin:/bin"},
                              capture_output=True, text=True, timeout=60)
        assert proc.returncode == 0, proc.stdout + proc.stderr
        self.line = parse_conf_line(conf_line())
        (self.root / "plugins.conf").write_text(conf_line() + "\n", encoding="utf-8")
        sp = site_packages(self.root / self.line.venv_path)
        sp.mkdir(parents=True)
        shutil.copyfile(STANDIN / "smbus2.py", sp / "smbus2.py")

    @property
    def plugin_dir(self) -> Path:
        return (self.root / self.line.path).parent

    @property
    def config_file(self) -> Path:
        return self.root / self.line.config_path


# Modules the loading puts in sys.modules; a test's fixture removes them again.
LOADED_MODULES = ("arm_io_plugin", "_arm_io_v4_psm", "shared", "shared.image_sizes", "smbus2")


def load_plugin(tree: RuntimeTree) -> ModuleType:
    """python_plugin_get_symbols, run from the runtime's root (the caller's cwd): the
    plugin's directory and its venv's site-packages first on sys.path, then the import of the
    file's stem, and the five functions the runtime looks up."""
    line = tree.line
    assert line.type == 0, "type 0 is a Python plugin"
    module_name = Path(line.path).stem
    plugin_dir = str(Path(line.path).parent)
    sys.path.insert(0, plugin_dir)  # "import sys; sys.path.insert(0, '<dir>')", relative
    if line.venv_path:
        sp = str(site_packages(Path(line.venv_path)))
        if sp not in sys.path:
            sys.path.insert(0, sp)
    module = importlib.import_module(module_name)
    for name in ("init", "start_loop", "stop_loop", "cleanup", "set_image_sizes"):
        assert callable(getattr(module, name, None)), f"{name} missing"
    return module


def unload(saved_path: list[str]) -> None:
    """Forget what loading added: the modules, the sys.path entries, and their finders
    (importlib keeps one per entry, bound to the absolute folder it first saw: a relative
    entry must not lead the next test's tree back to this one)."""
    for name in LOADED_MODULES:
        sys.modules.pop(name, None)
    for entry in set(sys.path) - set(saved_path):
        sys.path_importer_cache.pop(entry, None)
    sys.path[:] = saved_path
    importlib.invalidate_caches()


def wait_for(predicate: Callable[[], bool], timeout_s: float = 5.0,
             what: str = "condition") -> None:
    deadline = time.monotonic() + timeout_s
    while not predicate():
        assert time.monotonic() < deadline, f"timed out waiting for {what}"
        time.sleep(0.002)


def iter_pulses(chip: PCA9685, channels: Sequence[int]) -> Iterator[float]:
    for ch in channels:
        yield chip.pulse_width_us(ch)
