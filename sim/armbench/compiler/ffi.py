"""FFI: load a built library with cffi and drive it from Python. With declarations.py, which
writes the library's C declarations for cffi, the only compiler module importing cffi (the soft
PLC's Modbus fast path, softplc/fastpath.py, loads its own library).

`Module.call` runs any FUNCTION, `Module.new_fb` / `new_program` make instances whose inputs,
outputs and internals are read and written by (case-insensitive) ST name; values cross as
Python bool/int/float, dicts for STRUCTs and nested lists for ARRAYs.
"""

from __future__ import annotations

import os
import shutil
import sys
import tempfile
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

from ..faults import PlcFault
from . import ast as A
from .declarations import load_declarations
from .emit_c import const_name, is_shared_constant
from .symbols import CheckedProgram, PouSym, VarSym
from .types import STRING, STRING_MAX, ArrayType, ElemType, EnumType, PouType, StructType, Type

if TYPE_CHECKING:
    from .build import BuiltLibrary


class PlcArgumentError(ValueError):
    """A Python value does not fit the ST variable or parameter it is meant for."""


def _pou_cname(sym: PouSym) -> str:
    return {"FUNCTION": "FN_", "FUNCTION_BLOCK": "FB_", "PROGRAM": "PRG_"}[sym.kind] + sym.key


class Values:
    """Converts between cffi data and Python values, guided by the ST type."""

    def __init__(self, ffi: Any) -> None:
        self.ffi = ffi

    def to_py(self, c: Any, t: Type) -> Any:
        if isinstance(t, ElemType):
            if t.kind == "bool":
                return bool(c)
            if t.kind == "string":
                n = min(max(int(c.len), 0), STRING_MAX)
                return bytes(c.body[0:n]).decode("latin-1")
            return c
        if isinstance(t, EnumType):
            return int(c)
        if isinstance(t, ArrayType):
            flat = [self.to_py(c.v[i], t.element) for i in range(t.size)]
            return self._reshape(flat, [hi - lo + 1 for lo, hi in t.dims])
        if isinstance(t, StructType):
            return {spelling: self.to_py(getattr(c, key), ft)
                    for key, (spelling, ft) in t.fields.items()}
        if isinstance(t, PouType):
            sym = t.symbol
            assert isinstance(sym, PouSym)
            return {v.name: self.to_py(getattr(c, v.key), v.type) for v in sym.vars.values()
                    if v.kind not in (A.VAR_EXTERNAL, A.VAR_IN_OUT, A.VAR_TEMP)
                    and not v.address and not is_shared_constant(v)}
        raise TypeError(f"cannot convert {t}")

    def _reshape(self, flat: list[Any], shape: list[int]) -> list[Any]:
        # innermost dimension first, in a loop: an array may have thousands of dimensions
        out = flat
        for size in reversed(shape[1:]):
            out = [out[i:i + size] for i in range(0, len(out), size)]
        return out

    def assign(self, owner: Any, key: str, t: Type, value: Any, what: str) -> None:
        """owner.key = value, converting and checking."""
        if t is STRING:
            self.set_string(getattr(owner, key), value, what)
            return
        if isinstance(t, ElemType | EnumType):
            setattr(owner, key, self.scalar(t, value, what))
            return
        target = getattr(owner, key)
        self.fill(target, t, value, what)

    def set_string(self, target: Any, value: Any, what: str) -> None:
        """A STRING (a str of latin-1 characters, or bytes) into a plc_string_t."""
        if isinstance(value, str):
            try:
                data = value.encode("latin-1")
            except UnicodeEncodeError:
                raise PlcArgumentError(f"{what}: {value!r} has characters outside latin-1 "
                                       "(a STRING holds bytes)") from None
        elif isinstance(value, bytes | bytearray):
            data = bytes(value)
        else:
            raise PlcArgumentError(f"{what}: expected a str for STRING, got {value!r}")
        if len(data) > STRING_MAX:
            raise PlcArgumentError(f"{what}: {len(data)} characters; a STRING holds at most "
                                   f"{STRING_MAX} (MatIEC's STR_MAX_LEN)")
        target.body = list(data.ljust(STRING_MAX, b"\0"))
        target.len = len(data)

    def scalar(self, t: Type, value: Any, what: str) -> Any:
        if isinstance(t, ElemType) and t.is_real:
            if isinstance(value, bool) or not isinstance(value, int | float):
                raise PlcArgumentError(f"{what}: expected a number for {t}, got {value!r}")
            return float(value)
        if isinstance(t, ElemType) and t.kind == "bool":
            if not isinstance(value, bool | int):
                raise PlcArgumentError(f"{what}: expected a bool, got {value!r}")
            return 1 if value else 0
        if isinstance(value, bool) or not isinstance(value, int):
            raise PlcArgumentError(f"{what}: expected an integer for {t}, got {value!r}")
        if isinstance(t, ElemType) and t.kind != "time":
            lo, hi = t.int_range()
            if not lo <= value <= hi:
                raise PlcArgumentError(f"{what}: {value} is outside {t.name} ({lo}..{hi})")
        return value

    def fill(self, target: Any, t: Type, value: Any, what: str) -> None:
        if isinstance(t, ArrayType):
            flat = self._flatten(value)
            if len(flat) != t.size:
                raise PlcArgumentError(f"{what}: expected {t.size} values for {t}, got {len(flat)}")
            for i, v in enumerate(flat):
                if t.element is STRING:
                    self.set_string(target.v[i], v, f"{what}[{i}]")
                elif isinstance(t.element, ElemType | EnumType):
                    target.v[i] = self.scalar(t.element, v, f"{what}[{i}]")
                else:
                    self.fill(target.v[i], t.element, v, f"{what}[{i}]")
            return
        if isinstance(t, StructType):
            if not isinstance(value, dict):
                raise PlcArgumentError(f"{what}: expected a dict for {t.name}, got {value!r}")
            for k, v in value.items():
                f = t.fields.get(str(k).upper())
                if f is None:
                    raise PlcArgumentError(f"{what}: {t.name} has no field {k!r} (fields: "
                                      f"{', '.join(s for s, _ in t.fields.values())})")
                self.assign(target, str(k).upper(), f[1], v, f"{what}.{k}")
            return
        raise PlcArgumentError(f"{what}: cannot set a {t} from Python")

    def _flatten(self, value: Any) -> list[Any]:
        if isinstance(value, list | tuple):
            out: list[Any] = []
            end = object()
            pending = [iter(value)]  # a stack, not recursion: nesting depth is the caller's
            while pending:
                v = next(pending[-1], end)
                if v is end:
                    pending.pop()
                elif isinstance(v, list | tuple):
                    pending.append(iter(v))
                else:
                    out.append(v)
            return out
        # An array only the caller can have made: numpy is not imported for every program
        np = sys.modules.get("numpy")
        if np is not None and isinstance(value, np.ndarray):
            return [x.item() for x in value.ravel()]
        raise PlcArgumentError(f"expected a list, got {value!r}")


class Instance:
    """A FUNCTION_BLOCK or PROGRAM instance living in C memory."""

    def __init__(self, module: Module, sym: PouSym, cdata: Any | None = None) -> None:
        object.__setattr__(self, "_m", module)
        object.__setattr__(self, "_sym", sym)
        object.__setattr__(self, "_keep", {})
        cname = _pou_cname(sym)
        if cdata is None:
            cdata = module.ffi.new(f"{cname} *")
            getattr(module.lib, f"{cname}_init")(cdata)
        object.__setattr__(self, "_c", cdata)
        object.__setattr__(self, "_run", getattr(module.lib, f"{cname}_run"))

    def _var(self, name: str) -> VarSym:
        sym: PouSym = self._sym
        v = sym.vars.get(name.upper())
        if v is None or v.kind == A.VAR_EXTERNAL:
            names = ", ".join(x.name for x in self._sym.vars.values())
            raise AttributeError(f"{self._sym.name} has no variable {name!r} (it has: {names})")
        return v

    def get(self, name: str) -> Any:
        v = self._var(name)
        if is_shared_constant(v):
            shared = getattr(self._m.lib, const_name(_pou_cname(self._sym), v))
            return self._m.values.to_py(shared, v.type)
        c = getattr(self._c, v.key)
        if v.kind == A.VAR_IN_OUT or v.address:
            if c == self._m.ffi.NULL:
                raise PlcArgumentError(f"VAR_IN_OUT {v.name} of {self._sym.name} is not bound yet")
            c = c[0]
        return self._m.values.to_py(c, v.type)

    def set(self, **values: Any) -> None:
        for name, value in values.items():
            v = self._var(name)
            what = f"{self._sym.name}.{v.name}"
            if v.constant:
                raise PlcArgumentError(f"{what} is a CONSTANT")
            if v.kind == A.VAR_IN_OUT:
                ffi = self._m.ffi
                item = ffi.typeof(getattr(self._c, v.key)).item
                store = ffi.new(f"{ffi.getctype(item)} *")
                if v.type is STRING:
                    self._m.values.set_string(store[0], value, what)
                elif isinstance(v.type, ElemType | EnumType):
                    store[0] = self._m.values.scalar(v.type, value, what)
                else:
                    self._m.values.fill(store[0], v.type, value, what)
                self._keep[v.key] = store
                setattr(self._c, v.key, store)
            elif v.address:
                ptr = getattr(self._c, v.key)
                ptr[0] = self._m.values.scalar(v.type, value, what)
            else:
                self._m.values.assign(self._c, v.key, v.type, value, what)

    def __call__(self, **inputs: Any) -> Instance:
        self.set(**inputs)
        if self._run(self._c) != 0:
            raise self._m.fault()
        return self

    def vars(self) -> dict[str, Any]:
        return {v.name: self.get(v.name) for v in self._sym.vars.values()
                if v.kind not in (A.VAR_EXTERNAL, A.VAR_TEMP)
                and not (v.kind == A.VAR_IN_OUT and
                         getattr(self._c, v.key) == self._m.ffi.NULL)}

    def __getattr__(self, name: str) -> Any:
        if name.startswith("_"):
            raise AttributeError(name)
        return self.get(name)

    def __getitem__(self, name: str) -> Any:
        return self.get(name)

    def __setattr__(self, name: str, value: Any) -> None:
        self.set(**{name: value})


class Module:
    """A compiled set of ST files loaded into this process.

    ``decls`` are the library's C declarations (CUnit.decls): its declarations module is
    written anew from them should it be unusable."""

    def __init__(self, prog: CheckedProgram, library: BuiltLibrary, decls: str) -> None:
        self.program = prog
        self.ffi: Any = load_declarations(library.declarations, decls)
        # a private copy: two Modules built from the same sources must not share C globals
        fd, private = tempfile.mkstemp(suffix=".so", prefix="armbench_")
        os.close(fd)
        shutil.copyfile(library.path, private)
        try:
            self.lib: Any = self.ffi.dlopen(private)
        finally:
            os.unlink(private)
        self.values = Values(self.ffi)

    def fault(self) -> PlcFault:
        msg = self.ffi.string(self.lib.plc_fault_msg()).decode()
        pos = self.ffi.string(self.lib.plc_fault_pos()).decode()
        return PlcFault(msg, pos)

    def pou(self, name: str, kinds: Sequence[str]) -> PouSym:
        sym = self.program.pous.get(name.upper())
        if sym is None or sym.kind not in kinds:
            avail = ", ".join(p.name for p in self.program.pous.values() if p.kind in kinds)
            raise KeyError(f"no {' or '.join(kinds)} named {name!r} (available: {avail})")
        return sym

    def call(self, name: str, *args: Any, **kwargs: Any) -> Any:
        """Call a FUNCTION; returns its result (see call_full for outputs)."""
        return self.call_full(name, *args, **kwargs)[0]

    def call_full(self, name: str, *args: Any, **kwargs: Any) -> tuple[Any, dict[str, Any]]:
        sym = self.pou(name, ("FUNCTION",))
        inputs = sym.inputs()
        if args and kwargs:
            raise PlcArgumentError(f"{sym.name}: pass arguments all positional or all named")
        if len(args) > len(inputs):
            raise PlcArgumentError(f"{sym.name} takes {len(inputs)} inputs, {len(args)} given")
        frame = Instance(self, sym)
        named = dict(zip((v.name for v in inputs), args, strict=False)) if args else kwargs
        frame.set(**named)
        for v in inputs:
            if v.kind == A.VAR_IN_OUT and v.key not in frame._keep:
                raise PlcArgumentError(f"{sym.name}: VAR_IN_OUT {v.name} must be passed")
        if frame._run(frame._c) != 0:
            raise self.fault()
        assert sym.return_type is not None
        ret = self.values.to_py(frame._c.ret_, sym.return_type)
        outs = {v.name: frame.get(v.name) for v in sym.vars.values()
                if v.kind in (A.VAR_OUTPUT, A.VAR_IN_OUT)}
        return ret, outs

    def new_fb(self, name: str) -> Instance:
        return Instance(self, self.pou(name, ("FUNCTION_BLOCK",)))

    def new_program(self, name: str) -> Instance:
        return Instance(self, self.pou(name, ("PROGRAM",)))

    # ---------------------------------------------------------------- configuration access
    def image_buffer(self) -> memoryview:
        return memoryview(self.ffi.buffer(self.ffi.addressof(self.lib, "plc_image")))

    def config_init(self) -> None:
        self.lib.plc_config_init()

    def run_task_index(self, index: int, now_ns: int) -> None:
        self.lib.plc_set_time(now_ns)
        rc = self.lib.plc_run_task(index)
        if rc == 1:
            raise self.fault()
        if rc != 0:
            raise PlcArgumentError(f"no task with index {index}")

    def instance(self, name: str) -> Instance:
        cfg = self.program.config
        if cfg is None:
            raise KeyError("the sources have no CONFIGURATION")
        for inst in cfg.instances:
            if inst.name.upper() == name.upper():
                c = self.ffi.addressof(self.lib.plc_globals, inst.name.upper())
                return Instance(self, inst.pou, c)
        raise KeyError(f"no program instance {name!r} in {cfg.name}")

    def set_time(self, ns: int) -> None:
        """Set the PLC clock (ns) that TON/TOF/TP read: lets tests drive timers through the
        Python API without waiting (the soft PLC sets it before every scan)."""
        self.lib.plc_set_time(ns)

    def set_watchdog(self, ns: int) -> None:
        self.lib.plc_set_watchdog(ns)
