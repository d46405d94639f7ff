"""STAND-IN, for the tests only, of the OpenPLC v4 runtime's ``shared`` package
(Autonomy-Logic/openplc-runtime, core/src/drivers/plugins/python/shared/): the part of its
interface plc_project/v4_plugin/arm_io_plugin.py uses, with the same names, signatures,
result tuples and messages as the runtime's files, read one by one:

- capsule_extraction.py: ``safe_extract_runtime_args_from_capsule(capsule)`` -> (args, "Success")
  or (None, message); the capsule's name is "openplc_runtime_args".
- safe_buffer_access_refactored.py, buffer_accessor.py, buffer_validator.py,
  mutex_manager.py, config_handler.py: ``SafeBufferAccess(args)`` with ``is_valid`` /
  ``error_msg``, ``acquire_mutex()`` / ``release_mutex()`` (the runtime's image_lock /
  image_unlock), ``read_*`` -> (value, "Success") or (None, message) - a NULL cell (a
  location the program does not declare) reads as "Buffer read error: NULL pointer access" -
  ``write_*`` -> (True, "Success") through the runtime's journal_write_* (no lock needed;
  applied in order at the next drain), each index bounded by its own table's length,
  ``get_config_path()`` and ``get_config_file_args_as_map()`` (JSON).
- plugin_logger.py: ``PluginLogger(name, runtime_args)`` whose messages, prefixed
  "[NAME] ", are handed to the runtime's log_info/log_warn/... AS THE printf FORMAT.

The runtime's C side (the image tables, the journal, the log functions) is played by
``v4_standin.StandInRuntime``, the object the capsule points to. Where the real package goes
through ctypes into C memory, this one calls that object's Python methods; the behaviour
the plugin can observe is the same.
"""

from __future__ import annotations

import ctypes
import json
from datetime import UTC, datetime
from typing import Any

from .image_sizes import table_capacity

CAPSULE_NAME = b"openplc_runtime_args"

# buffer_accessor.py's JOURNAL_TYPE_MAP (journal_buffer_type_t)
JOURNAL_TYPE_MAP = {
    "bool_input": 0, "bool_output": 1, "bool_memory": 2, "byte_input": 3, "byte_output": 4,
    "int_input": 5, "int_output": 6, "int_memory": 7, "dint_input": 8, "dint_output": 9,
    "dint_memory": 10, "lint_input": 11, "lint_output": 12, "lint_memory": 13,
}
# buffer_types.py: value ranges of the types
_RANGES = {"bool": (0, 1), "byte": (0, 0xFF), "int": (0, 0xFFFF), "dint": (0, 0xFFFFFFFF),
           "lint": (0, 0xFFFFFFFFFFFFFFFF)}


def safe_extract_runtime_args_from_capsule(capsule: Any) -> tuple[Any, str]:
    try:
        if not hasattr(capsule, "__class__") or capsule.__class__.__name__ != "PyCapsule":
            return None, f"Expected PyCapsule object, got {type(capsule)}"
        get = ctypes.pythonapi.PyCapsule_GetPointer
        get.argtypes = [ctypes.py_object, ctypes.c_char_p]
        get.restype = ctypes.c_void_p
        ptr = get(capsule, CAPSULE_NAME)
        if not ptr:
            return None, ("Failed to extract pointer from capsule - invalid capsule name or "
                          "corrupted data")
        runtime_args = ctypes.cast(ptr, ctypes.py_object).value
        is_valid, validation_msg = runtime_args.validate_pointers()
        if not is_valid:
            return None, f"Structure validation failed: {validation_msg}"
        return runtime_args, "Success"
    except (AttributeError, TypeError, ValueError, OverflowError, OSError, MemoryError) as e:
        return None, f"Exception during capsule extraction: {e}"


class SafeBufferAccess:
    def __init__(self, runtime_args: Any) -> None:
        self.runtime_args = runtime_args
        self._is_valid, self._error_msg = runtime_args.validate_pointers()

    @property
    def is_valid(self) -> bool:
        return bool(self._is_valid)

    @property
    def error_msg(self) -> str:
        return str(self._error_msg)

    # -- mutex_manager.py
    def acquire_mutex(self) -> tuple[bool, str]:
        if not self.runtime_args.image_lock:
            return False, "Failed to acquire mutex"
        self.runtime_args.image_lock()
        return True, "Success"

    def release_mutex(self) -> tuple[bool, str]:
        if not self.runtime_args.image_unlock:
            return False, "Failed to release mutex"
        self.runtime_args.image_unlock()
        return True, "Success"

    # -- buffer_validator.py
    def _validate(self, table: str, idx: int, bit: int | None, value: Any = None) -> str | None:
        if idx < 0:
            return f"Buffer index cannot be negative: {idx}"
        reach = table_capacity(table, self.runtime_args.buffer_size)
        if idx >= reach:
            return f"Buffer index out of range for {table}: {idx} >= {reach}"
        is_bool = table.startswith("bool")
        if is_bool:
            if bit is None:
                return f"Bit index required for {table}"
            if bit < 0:
                return f"Bit index cannot be negative: {bit}"
            if bit >= self.runtime_args.bits_per_buffer:
                return f"Bit index out of range: {bit} >= {self.runtime_args.bits_per_buffer}"
        elif bit is not None:
            return f"Bit index not allowed for {table}"
        if value is not None:
            if is_bool:
                if isinstance(value, bool) or (isinstance(value, int | float)
                                               and value in (0, 1)):
                    return None
                return f"Boolean value must be 0 or 1, got: {value}"
            if not isinstance(value, int | float):
                return f"Value must be numeric, got: {type(value)}"
            low, high = _RANGES[table.split("_")[0]]
            if int(value) < low:
                return f"Value too small: {int(value)} < {low}"
            if int(value) > high:
                return f"Value too large: {int(value)} > {high}"
        return None

    # -- buffer_accessor.py
    def _read(self, table: str, idx: int, bit: int | None, thread_safe: bool) -> tuple[Any, str]:
        problem = self._validate(table, idx, bit)
        if problem is not None:
            return None, problem

        def do_read() -> tuple[Any, str]:
            row = self.runtime_args.tables[table][idx]
            cell = row[bit] if bit is not None else row
            if cell is None:
                return None, "Buffer read error: NULL pointer access"
            value = cell.get()
            return (bool(value) if bit is not None else value), "Success"

        if not thread_safe:
            return do_read()
        if not self.acquire_mutex()[0]:
            return False, "Failed to acquire mutex"
        try:
            return do_read()
        finally:
            self.release_mutex()

    def _write(self, table: str, idx: int, value: Any, bit: int | None) -> tuple[bool, str]:
        problem = self._validate(table, idx, bit, value)
        if problem is not None:
            return False, problem
        journal_type = JOURNAL_TYPE_MAP[table]
        args = self.runtime_args
        if bit is not None:
            result = args.journal_write_bool(journal_type, idx, bit, 1 if value else 0)
        elif table.startswith("int"):
            result = args.journal_write_int(journal_type, idx, int(value) & 0xFFFF)
        elif table.startswith("dint"):
            result = args.journal_write_dint(journal_type, idx, int(value) & 0xFFFFFFFF)
        else:
            return False, f"Unsupported buffer type: {table}"
        if result != 0:
            return False, f"Journal write failed with code {result}"
        return True, "Success"

    def read_bool_input(self, buffer_idx: int, bit_idx: int,
                        thread_safe: bool = True) -> tuple[Any, str]:
        return self._read("bool_input", buffer_idx, bit_idx, thread_safe)

    def read_bool_output(self, buffer_idx: int, bit_idx: int,
                         thread_safe: bool = True) -> tuple[Any, str]:
        return self._read("bool_output", buffer_idx, bit_idx, thread_safe)

    def write_bool_input(self, buffer_idx: int, bit_idx: int, value: bool,
                         thread_safe: bool = True) -> tuple[bool, str]:
        return self._write("bool_input", buffer_idx, value, bit_idx)

    def write_bool_output(self, buffer_idx: int, bit_idx: int, value: bool,
                          thread_safe: bool = True) -> tuple[bool, str]:
        return self._write("bool_output", buffer_idx, value, bit_idx)

    def read_int_input(self, buffer_idx: int, thread_safe: bool = True) -> tuple[Any, str]:
        return self._read("int_input", buffer_idx, None, thread_safe)

    def write_int_input(self, buffer_idx: int, value: int,
                        thread_safe: bool = True) -> tuple[bool, str]:
        return self._write("int_input", buffer_idx, value, None)

    def read_int_output(self, buffer_idx: int, thread_safe: bool = True) -> tuple[Any, str]:
        return self._read("int_output", buffer_idx, None, thread_safe)

    def write_int_output(self, buffer_idx: int, value: int,
                         thread_safe: bool = True) -> tuple[bool, str]:
        return self._write("int_output", buffer_idx, value, None)

    def read_dint_memory(self, buffer_idx: int, thread_safe: bool = True) -> tuple[Any, str]:
        return self._read("dint_memory", buffer_idx, None, thread_safe)

    def write_dint_memory(self, buffer_idx: int, value: int,
                          thread_safe: bool = True) -> tuple[bool, str]:
        return self._write("dint_memory", buffer_idx, value, None)

    # -- config_handler.py
    def get_config_path(self) -> tuple[str, str]:
        raw = self.runtime_args.plugin_specific_config_file_path
        return raw.decode("utf-8").rstrip("\x00").strip(), "Success"

    def get_config_file_args_as_map(self) -> tuple[dict[str, Any], str]:
        config_path, err_msg = self.get_config_path()
        if not config_path:
            return {}, f"Failed to get config path: {err_msg}"
        try:
            with open(config_path, encoding="utf-8") as config_file:
                config_data = json.load(config_file)
                if not isinstance(config_data, dict):
                    return {}, "Configuration file must contain a JSON object at the top level"
                return config_data, "Success"
        except FileNotFoundError:
            return {}, f"Configuration file not found: {config_path}"
        except json.JSONDecodeError as e:
            return {}, f"JSON parsing error in config file {config_path}: {e}"
        except (OSError, MemoryError) as e:
            return {}, f"Exception reading config file {config_path}: {e}"
        except UnicodeDecodeError as e:
            return {}, f"Encoding error reading config file {config_path}: {e}"


class PluginLogger:
    def __init__(self, plugin_name: str, runtime_args: Any = None) -> None:
        self.plugin_name = plugin_name
        self._prefix = f"[{plugin_name}]"
        self._args = runtime_args

    def _send(self, level: str, message: str) -> bool:
        formatted = f"{self._prefix} {message}"
        if self._args is None:
            stamp = datetime.now(UTC).strftime("%Y-%m-%d %H:%M:%S")
            print(f"[{stamp}] [{level.upper()}] {formatted}")
            return False
        getattr(self._args, f"log_{level}")(formatted.encode("utf-8"))
        return True

    def info(self, message: str) -> bool:
        return self._send("info", message)

    def error(self, message: str) -> bool:
        return self._send("error", message)

    def warn(self, message: str) -> bool:
        return self._send("warn", message)

    def debug(self, message: str) -> bool:
        return self._send("debug", message)


__all__ = ["PluginLogger", "SafeBufferAccess", "safe_extract_runtime_args_from_capsule"]
