"""Emit C: CheckedProgram -> one C translation unit. Needs: a program with no diagnostics.

Layout: a cffi-parsable declarations section (image, types, POU structs, entry points), then
the code. Every FUNCTION_BLOCK and PROGRAM is a struct plus `_init`/`_body` functions. A
FUNCTION is a C function, `FN_x_fn`, whose locals are C locals initialised on every call
(MatIEC re-initialises function locals), so that the C compiler keeps them in registers: its
scalar inputs are parameters, a STRUCT input the body never writes is passed by pointer (else
copied on entry), VAR_IN_OUT and VAR_OUTPUT by pointer, a scalar result is returned and an
aggregate one written through a pointer (see FnParams); its frame struct with `_init`/`_run`
remains, holding the inputs, outputs and result, for the FFI. Integer results are cast back to
their IEC type (wrap-around, compiled with -fwrapv); division, MOD, indices and loops go
through the runtime's checked helpers, which fault with the ST position.
"""

from __future__ import annotations

import struct
from collections.abc import Iterator
from dataclasses import dataclass, field

from . import ast as A
from .stdlib import STD_FB_BODIES, STD_FBS
from .strings import c_initializer, string_literal
from .symbols import CallTarget, CheckedProgram, PouSym, VarSym
from .types import (
    BOOL,
    DINT,
    ELEMENTARY,
    REAL,
    STRING,
    ArrayType,
    ElemType,
    EnumType,
    LiteralType,
    PouType,
    StructType,
    Type,
)

IMAGE_DECL = """typedef struct {
    uint8_t  ix[8192];
    uint8_t  qx[8192];
    uint16_t iw[1024];
    uint16_t qw[1024];
    uint16_t mw[1024];
    uint32_t md[1024];
    uint64_t ml[1024];
} plc_image_t;
"""

API_DECL = """const char *plc_fault_pos(void);
const char *plc_fault_msg(void);
void plc_set_time(int64_t ns);
void plc_set_watchdog(int64_t ns);
"""


# links of a binary chain per C temporary (see Emitter.binary)
SPILL_EVERY = 100
# counted FOR loops (Emitter.fixed_for) of at most UNROLL_TRIPS iterations and UNROLL_NODES
# AST nodes written out are emitted iteration by iteration (Emitter.unrolled_for)
UNROLL_TRIPS = 8
UNROLL_NODES = 1200
# what a FUNCTION's frame struct holds (its other variables are locals of its C function)
FN_FRAME_KINDS = (A.VAR_INPUT, A.VAR_IN_OUT, A.VAR_OUTPUT)


# the string functions whose ENO MatIEC clears for a negative argument (TEST_EN_COND)
_STRING_ENO_ARGS = {"LEFT": ("L",), "RIGHT": ("L",), "MID": ("L", "P"), "INSERT": ("P",),
                    "DELETE": ("L", "P"), "REPLACE": ("L", "P")}

STRING_CDEF = "typedef struct { int8_t len; uint8_t body[126]; } plc_string_t;\n"


@dataclass
class CUnit:
    """The emitted C: `decls` is valid input for cffi's cdef, `code` the whole source.

    `code` is also `shared`, then every piece of `pieces`, then `main` (after the runtime
    header): a build may compile the pieces as several translation units, each with the
    shared part, and `main` in one of them (see build.py)."""

    decls: str
    code: str
    c_names: dict[str, str] = field(default_factory=dict)  # ST type key -> C type name
    shared: str = ""  # types, prototypes, the standard FBs: what every unit needs
    pieces: list[str] = field(default_factory=list)  # one per POU, callees first
    main: str = ""  # the program's storage and the configuration's entry points


@dataclass
class FnParams:
    """How a FUNCTION's variables are passed and named in its C function ``FN_x_fn``.

    ``by_pointer``: the STRUCT inputs the body never writes (no assignment to them or to a
    part of them, never a VAR_IN_OUT argument or an output target): passed as a pointer to
    the caller's value, read in place. The other STRUCT inputs are passed as a pointer too and
    copied into a local on entry (``copied``)."""

    by_pointer: set[str] = field(default_factory=set)
    copied: set[str] = field(default_factory=set)
    # can a call of it write anything of the caller's (a VAR_IN_OUT or VAR_OUTPUT)?
    writes_caller: bool = False
    # an aggregate result: the local that every exit returns (`F := B;` before each RETURN
    # and at the end, the result used nowhere else) lives in the result's place
    result_local: str = ""
    # an aggregate result whose initial value nobody sees (written whole at the end, no
    # RETURN, used nowhere else): not initialised on entry
    result_init: bool = True
    # aggregate locals written whole by the body's first statements before being read:
    # not initialised on entry
    no_init: set[str] = field(default_factory=set)


class _Local:
    """Per-function emission state (temporaries)."""

    def __init__(self) -> None:
        self.n = 0

    def tmp(self) -> str:
        self.n += 1
        return f"t__{self.n}"


class Emitter:
    def __init__(self, prog: CheckedProgram) -> None:
        self.p = prog
        self.typedefs: list[str] = []
        self.type_names: dict[int, str] = {}
        self.declared: set[str] = set()
        self.forward: list[str] = []  # prototypes and constants the code refers to
        self.protos: list[str] = []
        self.cur: PouSym | None = None
        self.loc = _Local()
        self.unmapped = 0
        self.storage: list[str] = []  # the definitions of the current piece's unmapped storage
        self.ffi_only: list[str] = []
        self.std_code: list[str] = []
        self.pieces: list[str] = []
        self.fn_params: dict[str, FnParams] = {}
        # the FOR variables whose values are known in the loop being emitted (fixed_for)
        self.for_ranges: dict[VarSym, tuple[int, int]] = {}
        self.inout_bound_memo: dict[str, set[VarSym]] = {}
        self.cur_fp: FnParams | None = None  # params_of(cur) while a FUNCTION is emitted
        self.fixed_memo: dict[int, tuple[int, int, int] | None] = {}
        self.unroll_memo: dict[int, int] = {}  # FOR node -> nodes in its body
        self.unroll_scale = 1  # iterations of the loops being written out, multiplied
        # expression node -> does evaluating it call a FUNCTION that writes the caller's
        self.writes_memo: dict[int, bool] = {}

    # ================================================================ types
    def ctype(self, t: Type) -> str:
        if isinstance(t, ElemType):
            return t.ctype
        if isinstance(t, EnumType):
            return "int32_t"
        if isinstance(t, LiteralType):
            return "double" if t.is_real else "int64_t"
        key = id(t)
        if key in self.type_names:
            return self.type_names[key]
        if isinstance(t, ArrayType):
            elem = self.ctype(t.element)
            # one C type per shape and element: ST assigns between a named array type and an
            # anonymous array of the same shape
            name = f"ARR_{elem}_{t.shape_key()}"
            self.type_names[key] = name
            if name not in self.declared:
                self.declared.add(name)
                self.typedefs.append(f"typedef struct {{ {elem} v[{t.size}]; }} {name};\n")
            return name
        if isinstance(t, StructType):
            name = "S_" + t.name.upper()
            self.type_names[key] = name
            fields = "".join(f"    {self.ctype(ft)} {fk};\n" for fk, (_, ft) in t.fields.items())
            self.typedefs.append(f"typedef struct {{\n{fields}}} {name};\n")
            return name
        if isinstance(t, PouType):
            sym = t.symbol
            assert isinstance(sym, PouSym)
            name = ("FB_" if sym.kind == "FUNCTION_BLOCK" else "PRG_") + sym.key
            self.type_names[key] = name
            return name
        raise AssertionError(f"no C type for {t}")

    # ================================================================ whole unit
    def emit(self) -> CUnit:
        for name, fields in STD_FBS.items():
            t = self.p.types[name]
            cname = self.ctype(t)
            body = "".join(f"    {ELEMENTARY[f.type].ctype} {f.name};\n" for f in fields)
            self.typedefs.append(f"typedef struct {{\n{body}}} {cname};\n")
            self.std_code.append(f"static void {cname}_init({cname} *s) "
                                 "{ memset(s, 0, sizeof *s); }\n"
                                 f"static void {cname}_body({cname} *s) "
                                 f"{{{STD_FB_BODIES[name]}\n}}\n")
        for t in self.p.types.values():
            if isinstance(t, StructType | ArrayType):
                self.ctype(t)
        # named structs declared up front: a VAR_IN_OUT may point to its own FB type, or to
        # one declared later (containment by value is acyclic: resolve reports E0210)
        for sym in self.p.pous.values():
            cname = self.pou_cname(sym)
            self.typedefs.append(f"typedef struct {cname} {cname};\n")
        for sym in self.p.pous.values():
            self.pou_struct(sym)
        self.globals_struct()
        for sym in self.p.pous.values():
            self.pou_code(sym)
        main = ("#ifndef ARMBENCH_BARE_METAL\n"
                "plc_image_t plc_image;\nplc_globals_t plc_globals;\n#endif\n" +
                self.config_code())
        decls = IMAGE_DECL + "".join(self.typedefs) + API_DECL + "".join(self.protos)
        storage = "extern plc_image_t plc_image;\nextern plc_globals_t plc_globals;\n"
        shared = decls + storage + "".join(self.forward) + "".join(self.std_code)
        code = "#include \"iec_runtime.h\"\n" + shared + "".join(self.pieces) + main
        # the runtime header defines plc_string_t for the C; cffi sees only the declarations
        ffi_decls = STRING_CDEF + decls if "plc_string_t" in decls else decls
        return CUnit(ffi_decls + storage + "".join(self.ffi_only), code, shared=shared,
                     pieces=self.pieces, main=main)

    def pou_struct(self, sym: PouSym) -> None:
        cname = self.pou_cname(sym)
        lines = []
        for v in sym.vars.values():
            if v.kind == A.VAR_EXTERNAL:
                continue
            ct = self.ctype(v.type)
            if is_shared_constant(v):
                # one read-only copy for all instances and calls, not one per instance
                # cffi (ABI mode) reads it as a plain global; C sees the const definition
                self.ffi_only.append(f"extern {ct} {const_name(cname, v)};\n")
                self.forward.append(f"extern const {ct} {const_name(cname, v)};\n")
                continue
            if sym.kind == "FUNCTION" and v.kind not in FN_FRAME_KINDS:
                continue  # a local of FN_x_fn: the frame holds what the FFI passes and reads
            ptr = "*" if v.kind == A.VAR_IN_OUT or v.address else ""
            lines.append(f"    {ct} {ptr}{v.key};\n")
        if sym.kind == "FUNCTION":
            assert sym.return_type is not None
            lines.append(f"    {self.ctype(sym.return_type)} ret_;\n")
        if not lines:
            lines.append("    uint8_t unused_;\n")
        self.typedefs.append(f"struct {cname} {{\n{''.join(lines)}}};\n")
        self.protos.append(f"void {cname}_init({cname} *self);\n"
                           f"int {cname}_run({cname} *self);\n")

    def pou_cname(self, sym: PouSym) -> str:
        return {"FUNCTION": "FN_", "FUNCTION_BLOCK": "FB_", "PROGRAM": "PRG_"}[sym.kind] + sym.key

    def globals_struct(self) -> None:
        lines = []
        cfg = self.p.config
        if cfg is not None:
            for v in cfg.globals.values():
                ptr = "*" if v.address else ""
                lines.append(f"    {self.ctype(v.type)} {ptr}{v.key};\n")
            for inst in cfg.instances:
                lines.append(f"    {self.pou_cname(inst.pou)} {inst.name.upper()};\n")
        if not lines:
            lines.append("    uint8_t unused_;\n")
        self.typedefs.append(f"typedef struct {{\n{''.join(lines)}}} plc_globals_t;\n")
        self.protos.append("void plc_config_init(void);\nint plc_run_task(int task);\n")

    # ================================================================ initial values
    def init_value(self, target: str, t: Type, init: A.Init | None, out: list[str]) -> None:
        """Append statements that give `target` (a C lvalue) its initial value."""
        if isinstance(t, PouType):
            sym = t.symbol
            assert isinstance(sym, PouSym)
            out.append(f"{self.pou_cname(sym) if not sym.builtin else self.ctype(t)}"
                       f"_init(&{target});")
            return
        init = effective_init(t, init)
        if isinstance(t, StructType):
            for fk, ft, finit in field_inits(t, init):
                self.init_value(f"{target}.{fk}", ft, finit, out)
            return
        if isinstance(t, ArrayType):
            if isinstance(init, A.Literal | A.Unary | A.Binary):
                init = A.ArrayInit(init.pos, [(A.Literal(init.pos, "int", t.size, ""), init)])
            needs_loop = isinstance(t.element, StructType | PouType)
            if init is None:
                if needs_loop:
                    i = self.loc.tmp()
                    inner: list[str] = []
                    self.init_value(f"{target}.v[{i}]", t.element, None, inner)
                    out.append(f"for (int {i} = 0; {i} < {t.size}; {i}++) {{ "
                               f"{' '.join(inner)} }}")
                return
            assert isinstance(init, A.ArrayInit)
            flat = 0
            filled: list[str] = []
            for count_e, val in init.items:
                count = 1
                if count_e is not None:
                    count = int(self.const_int(count_e))
                if count > 4:
                    i = self.loc.tmp()
                    inner = []
                    self.init_value(f"{target}.v[{i}]", t.element, val, inner)
                    filled.append(f"for (int {i} = {flat}; {i} < {flat + count}; {i}++) {{ "
                                  f"{' '.join(inner)} }}")
                else:
                    for k in range(count):
                        self.init_value(f"{target}.v[{flat + k}]", t.element, val, filled)
                flat += count
            if needs_loop and flat < t.size:
                i = self.loc.tmp()
                inner = []
                self.init_value(f"{target}.v[{i}]", t.element, None, inner)
                filled.append(f"for (int {i} = {flat}; {i} < {t.size}; {i}++) {{ "
                              f"{' '.join(inner)} }}")
            out.extend(filled)
            return
        if init is None:
            if isinstance(t, EnumType) and t.values:
                first = next(iter(t.values.values()))[1]
                out.append(f"{target} = {first if t.default is None else t.default};")
            return
        assert isinstance(init, A.Expr)
        out.append(f"{target} = {self.expr(init, want=t)};")

    def static_init(self, t: Type, init: A.Init | None) -> str:
        """A C constant initialiser for a value of type t (for `static const` data)."""
        init = effective_init(t, init)
        if isinstance(t, StructType):
            parts = [self.static_init(ft, finit) for _, ft, finit in field_inits(t, init)]
            return "{ " + ", ".join(parts) + " }"
        if isinstance(t, ArrayType):
            if isinstance(init, A.Literal | A.Unary | A.Binary):
                init = A.ArrayInit(init.pos, [(A.Literal(init.pos, "int", t.size, ""), init)])
            items: list[str] = []
            if isinstance(init, A.ArrayInit):
                for count_e, val in init.items:
                    count = 1 if count_e is None else int(self.const_int(count_e))
                    items.extend([self.static_init(t.element, val)] * count)
            return "{ { " + (", ".join(items) if items else "0") + " } }"
        if init is None:
            if isinstance(t, EnumType) and t.values:
                first = next(iter(t.values.values()))[1]
                return str(first if t.default is None else t.default)
            return "{0}" if t is STRING else "0"
        assert isinstance(init, A.Expr)
        if isinstance(init, A.Literal) and init.kind == "string":
            return self.string_init(init)
        # file scope: fewer than SPILL_EVERY operators here (is_shared_constant), no spill
        return self.expr(init, want=t)

    def const_int(self, e: A.Expr) -> int:
        if isinstance(e, A.Literal):
            return int(e.value)
        if isinstance(e, A.Unary) and e.op == "-":
            return -self.const_int(e.operand)
        raise AssertionError("not a constant")

    # ================================================================ POU code
    def pou_code(self, sym: PouSym) -> None:
        assert sym.node is not None
        self.cur = sym
        self.loc = _Local()
        cname = self.pou_cname(sym)
        consts = "".join(
            f"const {self.ctype(v.type)} {const_name(cname, v)} = "
            f"{self.static_init(v.type, v.init)};\n"
            for v in sym.vars.values() if is_shared_constant(v))
        if sym.kind == "FUNCTION":
            self.cur_fp = self.params_of(sym)
            try:
                self.function_code(sym, consts)
            finally:
                self.cur = self.cur_fp = None
            return
        init: list[str] = ["memset(self, 0, sizeof *self);"]
        for v in sym.vars.values():
            if v.kind in (A.VAR_EXTERNAL, A.VAR_IN_OUT) or is_shared_constant(v):
                continue
            if v.address:
                init.append(f"self->{v.key} = {self.address_ptr(v)};")
                if v.init is not None:
                    self.init_value(f"(*self->{v.key})", v.type, v.init, init)
                continue
            self.init_value(f"self->{v.key}", v.type, v.init, init)
        self.forward.append(f"PLC__INTERNAL void {cname}_body({cname} *self);\n")
        temps: list[str] = []
        for v in sym.vars.values():
            if v.kind == A.VAR_TEMP:
                temps.append(f"PLC__ZERO(self->{v.key});")
                self.init_value(f"self->{v.key}", v.type, v.init, temps)
        body = ("    int plc__brk_ = 0;\n    (void)plc__brk_;\n" +
                "".join(f"    {t}\n" for t in temps) + self.block(sym.node.body, 1))
        self.pieces.append(
            "".join(self.storage) + consts +
            f"void {cname}_init({cname} *self) {{\n    " + "\n    ".join(init) + "\n}\n"
            f"PLC__INTERNAL void {cname}_body({cname} *self) {{\n{body}}}\n"
            f"int {cname}_run({cname} *self) {{\n"
            f"    if (setjmp(plc__jmp)) return 1;\n    plc__wd_begin();\n"
            f"    {cname}_body(self);\n    return 0;\n}}\n")
        self.storage = []
        self.cur = None

    def function_code(self, sym: PouSym, consts: str) -> None:
        """A FUNCTION: its C function FN_x_fn (FnParams), and for the FFI the frame's _init
        (the inputs' initial values) and _run (FN_x_fn on the frame)."""
        assert sym.node is not None and sym.return_type is not None
        cname = self.pou_cname(sym)
        fp = self.params_of(sym)
        init: list[str] = ["memset(self, 0, sizeof *self);"]
        for v in sym.vars.values():
            if v.kind == A.VAR_INPUT:
                self.init_value(f"self->{v.key}", v.type, v.init, init)
        params: list[str] = []
        run_args: list[str] = []
        prologue = ["int plc__brk_ = 0;", "(void)plc__brk_;"]
        outputs: list[str] = []
        for v in sym.vars.values():
            if v.kind not in FN_FRAME_KINDS:
                continue
            ct = self.ctype(v.type)
            if v.kind == A.VAR_INPUT and is_scalar(v.type):
                params.append(f"{ct} a_{v.key}")
                run_args.append(f"self->{v.key}")
            elif v.kind == A.VAR_INPUT:
                params.append(f"const {ct} *a_{v.key}")
                run_args.append(f"&self->{v.key}")
                if v.key in fp.copied:
                    prologue.append(f"{ct} l_{v.key}; PLC__COPY(l_{v.key}, *a_{v.key});")
            elif v.kind == A.VAR_IN_OUT:
                params.append(f"{ct} *a_{v.key}")
                run_args.append(f"self->{v.key}")
            else:  # VAR_OUTPUT: the caller's, from its initial value on
                params.append(f"{ct} *a_{v.key}")
                run_args.append(f"&self->{v.key}")
                outputs.append(f"PLC__ZERO(*a_{v.key});")
                self.init_value(f"(*a_{v.key})", v.type, v.init, outputs)
        # inputs are copied before anything is written: the caller may pass a pointer to
        # what the result or an output will be written to (fn_call)
        prologue += outputs
        rt = self.ctype(sym.return_type)
        # the result starts at its type's initial value (a STRUCT's field defaults), as
        # MatIEC's does
        if is_scalar(sym.return_type):
            ret_c = rt
            prologue.append(self.declare("l_ret_", sym.return_type, None))
            run_call = f"self->ret_ = {cname}_fn({', '.join(run_args)});"
            epilogue = "    return l_ret_;\n"
        else:
            ret_c = "void"
            params.append(f"{rt} *plc__ret")
            run_args.append("&self->ret_")
            if fp.result_init and not fp.result_local:
                prologue.append("PLC__ZERO(*plc__ret);")
                self.init_value("(*plc__ret)", sym.return_type, None, prologue)
            run_call = f"{cname}_fn({', '.join(run_args)});"
            epilogue = ""
        for v in sym.vars.values():
            if v.kind not in (A.VAR, A.VAR_TEMP) or is_shared_constant(v):
                continue
            if v.key == fp.result_local:
                if v.key not in fp.no_init:
                    init_ret = ["PLC__ZERO(*plc__ret);"]
                    self.init_value("(*plc__ret)", v.type, v.init, init_ret)
                    prologue += init_ret
            elif v.key in fp.no_init:
                prologue.append(f"{self.ctype(v.type)} l_{v.key};")
            else:
                prologue.append(self.declare(f"l_{v.key}", v.type, v.init))
        sig = f"{ret_c} {cname}_fn({', '.join(params) or 'void'})"
        self.forward.append(f"PLC__INTERNAL {sig};\n")
        body = "".join(f"    {x}\n" for x in prologue) + self.block(sym.node.body, 1) + epilogue
        self.pieces.append(
            consts +
            f"void {cname}_init({cname} *self) {{\n    " + "\n    ".join(init) + "\n}\n"
            f"PLC__INTERNAL {sig} {{\n{body}}}\n"
            f"int {cname}_run({cname} *self) {{\n"
            f"    if (setjmp(plc__jmp)) return 1;\n    plc__wd_begin();\n"
            f"    {run_call}\n    return 0;\n}}\n")

    def assign_c(self, lhs: str, value: A.Expr, t: Type) -> str:
        """`lhs := value` as a C statement (see copy_c)."""
        if not is_scalar(t) and isinstance(value, A.Name | A.Member | A.Index):
            return self.copy_c(lhs, self.expr(value, want=t), t)
        return f"{lhs} = {self.expr(value, want=t)};"

    def copy_c(self, lhs: str, rhs: str, t: Type) -> str:
        """An assignment of the C lvalue rhs to lhs: a large STRUCT or array through the
        runtime's PLC__COPY (the C library's memmove)."""
        return f"{lhs} = {rhs};" if is_scalar(t) else f"PLC__COPY({lhs}, {rhs});"

    def declare(self, name: str, t: Type, init: A.Init | None) -> str:
        """A C local ``name`` of type t with its initial value (statements)."""
        out: list[str] = []
        self.init_value(name, t, init, out)
        ct = self.ctype(t)
        if is_scalar(t):
            return " ".join([f"{ct} {name} = 0;", *out])
        return " ".join([f"{ct} {name};", f"PLC__ZERO({name});", *out])

    def params_of(self, sym: PouSym) -> FnParams:
        """How FUNCTION sym takes its STRUCT inputs (FnParams), from what its body writes."""
        fp = self.fn_params.get(sym.key)
        if fp is not None:
            return fp
        assert sym.node is not None
        written: set[str] = set()
        body_nodes = nodes(sym.node.body)
        for node in body_nodes:
            if isinstance(node, A.Assign):
                written.add(self.root_key(node.target))
            elif isinstance(node, A.For):
                written.add(self.root_key(node.var))
            elif isinstance(node, A.Call):
                tgt = self.p.calls.get(node)
                if tgt is None or tgt.pou is None:
                    continue
                for key, e in tgt.inputs:
                    if tgt.pou.vars[key].kind == A.VAR_IN_OUT:
                        written.add(self.root_key(e))
                for _, e in tgt.outputs:
                    written.add(self.root_key(e))
        fp = FnParams(writes_caller=any(v.kind in (A.VAR_IN_OUT, A.VAR_OUTPUT)
                                        for v in sym.vars.values()))
        for v in sym.vars.values():
            if v.kind == A.VAR_INPUT and not is_scalar(v.type):
                (fp.copied if v.key in written else fp.by_pointer).add(v.key)
        assert sym.return_type is not None
        if not is_scalar(sym.return_type):
            self.result_analysis(sym, fp, body_nodes)
        self.first_writes(sym, fp)
        self.fn_params[sym.key] = fp
        return fp

    def result_analysis(self, sym: PouSym, fp: FnParams, body_nodes: list[A.Node]) -> None:
        """FnParams.result_local and result_init of a FUNCTION with an aggregate result."""
        assert sym.node is not None
        body = sym.node.body
        whole: list[A.Assign] = []  # `F := ...`
        refs = 0  # every use of F
        for node in body_nodes:
            if isinstance(node, A.Name) and self.is_result(node):
                refs += 1
            elif isinstance(node, A.Assign) and self.is_result(node.target):
                whole.append(node)
        last = body[-1] if body else None
        if not whole or refs != len(whole) or not isinstance(last, A.Assign) or \
                not self.is_result(last.target):
            return
        lists = list(statement_lists(body))
        has_return = any(isinstance(st, A.Return) for sl in lists for st in sl)
        if not has_return:
            fp.result_init = False
        # the named result: `F := B` with one local B, before every RETURN and at the end
        keys = {self.local_key(a.value) for a in whole}
        key = keys.pop() if len(keys) == 1 else ""
        v = sym.vars.get(key)
        assert sym.return_type is not None
        if not key or v is None or v.kind != A.VAR or is_shared_constant(v) or \
                self.ctype(v.type) != self.ctype(sym.return_type):
            return
        for sl in lists:
            for i, st in enumerate(sl):
                before = sl[i - 1] if i > 0 else None
                if isinstance(st, A.Return) and not (
                        isinstance(before, A.Assign) and self.is_result(before.target)):
                    return
        fp.result_local = key

    def first_writes(self, sym: PouSym, fp: FnParams) -> None:
        """FnParams.no_init: the aggregate locals the body's leading whole assignments write
        before anything reads them."""
        assert sym.node is not None
        seen: set[str] = set()
        for st in sym.node.body:
            if not isinstance(st, A.Assign):
                break
            read = {self.local_key(n) for n in nodes(st.value) if isinstance(n, A.Name)}
            seen |= read
            key = self.local_key(st.target)
            v = sym.vars.get(key)
            if key and key not in seen and v is not None and v.kind in (A.VAR, A.VAR_TEMP) \
                    and not is_scalar(v.type) and not is_shared_constant(v):
                fp.no_init.add(key)
            seen.add(key)

    def is_result(self, e: A.Expr) -> bool:
        ref = self.p.names.get(e) if isinstance(e, A.Name) else None
        return ref is not None and ref.kind == "pou_result"

    def local_key(self, e: A.Expr) -> str:
        """The key of the variable e names ("" when e is no plain variable name)."""
        ref = self.p.names.get(e) if isinstance(e, A.Name) else None
        return ref.var.key if ref is not None and ref.var is not None and \
            ref.kind == "var" else ""

    def root_key(self, e: A.Expr) -> str:
        """The key of the variable an lvalue is part of ("" when it is none)."""
        while isinstance(e, A.Member | A.Index):
            e = e.obj
        ref = self.p.names.get(e) if isinstance(e, A.Name) else None
        return ref.var.key if ref is not None and ref.var is not None and \
            ref.kind == "var" else ""

    def root_of(self, e: A.Expr) -> tuple[object, str] | None:
        """The variable an lvalue of the current POU is part of (its VarSym; the POU's for
        a FUNCTION's result), and how it is reached: "fresh" (a FUNCTION's own local or
        result, or a shared constant: nothing else the FUNCTION can reach points to it; a
        caller passes a result's place only when none of the arguments is that place),
        "direct" (an instance's or the configuration's own storage) or "indirect" (through a
        pointer: a VAR_IN_OUT, a FUNCTION's STRUCT input or output, a located variable).
        None: not a variable."""
        while isinstance(e, A.Member | A.Index):
            e = e.obj
        ref = self.p.names.get(e) if isinstance(e, A.Name) else None
        if ref is not None and ref.kind == "pou_result":
            return self.cur, "fresh"
        if ref is None or ref.var is None or ref.kind not in ("var", "global"):
            return None
        v = ref.var
        if self.in_function() and v.kind == A.VAR:
            assert self.cur is not None
            if v.key == self.params_of(self.cur).result_local:
                return self.cur, "fresh"
        if v.address or v.kind in (A.VAR_IN_OUT, A.VAR_OUTPUT) and self.in_function():
            return v, "indirect"
        if v.kind == A.VAR_IN_OUT:
            return v, "indirect"
        if ref.kind == "global":
            return v, "direct"
        if is_shared_constant(v):
            return v, "fresh"
        if self.in_function():
            assert self.cur is not None
            if v.kind == A.VAR_INPUT and v.key in self.params_of(self.cur).by_pointer:
                return v, "indirect"
            return v, "fresh"
        return v, "direct"

    def in_function(self) -> bool:
        return self.cur is not None and self.cur.kind == "FUNCTION"

    def address_ptr(self, v: VarSym) -> str:
        area, size, nums = split_address(v.address or "")
        ct = self.ctype(v.type)
        if size == "X" and area in "IQ":
            bits = "ix" if area == "I" else "qx"
            return f"({ct} *)&plc_image.{bits}[{nums[0] * 8 + nums[1]}]"
        arr = {("I", "W"): "iw", ("Q", "W"): "qw", ("M", "W"): "mw", ("M", "D"): "md",
               ("M", "L"): "ml"}.get((area, size))
        if arr is None:
            # valid in OpenPLC but outside its Modbus map: plain storage of its own
            self.unmapped += 1
            # beside the one function that points to it: in the same translation unit
            self.storage.append(f"static {ct} plc__unmapped_{self.unmapped};\n")
            return f"&plc__unmapped_{self.unmapped}"
        return f"({ct} *)&plc_image.{arr}[{nums[0]}]"

    def config_code(self) -> str:
        cfg = self.p.config
        lines = ["memset(&plc_globals, 0, sizeof plc_globals);"]
        tasks: list[str] = []
        if cfg is not None:
            self.loc = _Local()
            for v in cfg.globals.values():
                if v.address:
                    lines.append(f"plc_globals.{v.key} = {self.address_ptr(v)};")
                    if v.init is not None:
                        self.init_value(f"(*plc_globals.{v.key})", v.type, v.init, lines)
                else:
                    self.init_value(f"plc_globals.{v.key}", v.type, v.init, lines)
            for inst in cfg.instances:
                lines.append(f"{self.pou_cname(inst.pou)}_init(&plc_globals.{inst.name.upper()});")
            for i, task in enumerate(cfg.tasks):
                runs = "".join(
                    f"        {self.pou_cname(inst.pou)}_body(&plc_globals.{inst.name.upper()});\n"
                    for inst in cfg.instances if (inst.task or "").upper() == task.name.upper())
                tasks.append(f"    case {i}:\n{runs}        break;\n")
        storage, self.storage = "".join(self.storage), []
        return (
            "#ifndef ARMBENCH_BARE_METAL\n" + storage +
            "void plc_config_init(void) {\n    " + "\n    ".join(lines) + "\n}\n"
            "static plc_image_t plc__image_backup;\n"
            "int plc_run_task(int task) {\n"
            "    memcpy(&plc__image_backup, &plc_image, sizeof plc_image);\n"
            "    if (setjmp(plc__jmp)) {\n"
            "        memcpy(&plc_image, &plc__image_backup, sizeof plc_image);\n"
            "        return 1;\n    }\n"
            "    plc__wd_begin();\n"
            "    switch (task) {\n" + "".join(tasks) + "    default: return 2;\n    }\n"
            "    return 0;\n}\n#endif\n")

    # ================================================================ statements
    def unrollable(self, s: A.For, trip: int) -> bool:
        """A counted loop (fixed_for) small enough to be written out iteration by
        iteration, with no EXIT or CONTINUE in it: its body, times its iterations and those
        of the loops written out around it, at most UNROLL_NODES nodes."""
        if trip > UNROLL_TRIPS:
            return False
        if id(s) not in self.unroll_memo:
            body = nodes(s.body)
            has_exit = any(isinstance(node, A.Exit | A.Continue) for node in body)
            self.unroll_memo[id(s)] = UNROLL_NODES + 1 if has_exit else len(body)
        return self.unroll_memo[id(s)] * trip * self.unroll_scale <= UNROLL_NODES

    def unrolled_for(self, s: A.For, var: VarSym, trip: int, ind: str, depth: int) -> str:
        """A small counted loop written out: the variable set to each value in turn before
        its copy of the body (indices by it are constant offsets then, and the C compiler
        keeps values from one iteration to the next in registers), then to the value the
        loop leaves it at."""
        vt = self.p.expr_types[s.var]
        assert isinstance(vt, ElemType)
        v = self.lvalue(s.var)
        ct = self.ctype(vt)
        start = literal_int(s.start)
        step = 1 if s.step is None else literal_int(s.step)
        assert start is not None and step is not None
        out = [f"{ind}PLC__WD_N({self.pos(s)}, {trip});\n"] if trip else []
        scale = self.unroll_scale
        self.unroll_scale *= max(trip, 1)
        try:
            for k in range(trip):
                value = start + k * step
                self.for_ranges[var] = (value, value)
                out.append(f"{ind}{v} = ({ct}){value};\n{ind}{{\n"
                           f"{self.block(s.body, depth + 1)}{ind}}}\n")
        finally:
            self.for_ranges.pop(var, None)
            self.unroll_scale = scale
        out.append(f"{ind}{v} = ({ct}){start + trip * step};\n")
        return "".join(out)

    def fixed_for(self, s: A.For) -> tuple[int, int, int] | None:
        """(lowest, highest value of the variable, iterations) of a FOR loop with literal
        bounds and step whose variable, a plain local, nothing in the loop can change, and
        that ends without the variable wrapping around; at most 65536 iterations."""
        if id(s) not in self.fixed_memo:  # an unrolled loop emits the loops in it again
            self.fixed_memo[id(s)] = self.find_fixed_for(s)
        return self.fixed_memo[id(s)]

    def find_fixed_for(self, s: A.For) -> tuple[int, int, int] | None:
        ref = self.p.names.get(s.var)
        vt = self.p.expr_types.get(s.var)
        if ref is None or ref.kind != "var" or ref.var is None or \
                not isinstance(vt, ElemType) or vt.kind not in ("sint", "uint"):
            return None
        v = ref.var
        if v.kind not in (A.VAR, A.VAR_TEMP) or v.address or v.constant:
            return None
        start, end = literal_int(s.start), literal_int(s.end)
        step = 1 if s.step is None else literal_int(s.step)
        if start is None or end is None or step is None:
            return None
        tlo, thi = vt.int_range()
        if step == 0 or not (tlo <= end + step <= thi) or not tlo <= start <= thi:
            return None
        trip = max(0, (end - start) // step + 1)
        if trip > 65536 or self.writes_var(s.body, v):
            return None
        # an FB called in the loop may write through a VAR_IN_OUT bound at an earlier call
        if not self.in_function() and v in self.inout_bound_vars():
            return None
        last = start + (trip - 1) * step
        return min(start, last), max(start, last), trip

    def writes_var(self, body: list[A.Stmt], v: VarSym) -> bool:
        """Does something in body assign v, loop over it, or pass it as a VAR_IN_OUT or an
        output target?"""
        for node in nodes(body):
            if isinstance(node, A.Assign) and self.root_var(node.target) is v:
                return True
            if isinstance(node, A.For) and self.root_var(node.var) is v:
                return True
            if isinstance(node, A.Call):
                tgt = self.p.calls.get(node)
                if tgt is None or tgt.pou is None:
                    continue
                if any(self.root_var(e) is v for _, e in tgt.outputs) or any(
                        tgt.pou.vars[key].kind == A.VAR_IN_OUT and self.root_var(e) is v
                        for key, e in tgt.inputs):
                    return True
        return False

    def inout_bound_vars(self) -> set[VarSym]:
        """The variables of the current POU passed as a VAR_IN_OUT somewhere in its body."""
        assert self.cur is not None and self.cur.node is not None
        found = self.inout_bound_memo.get(self.cur.key)
        if found is None:
            found = set()
            for node in nodes(self.cur.node.body):
                if isinstance(node, A.Call):
                    tgt = self.p.calls.get(node)
                    if tgt is not None and tgt.pou is not None:
                        for key, e in tgt.inputs:
                            v = self.root_var(e)
                            if v is not None and tgt.pou.vars[key].kind == A.VAR_IN_OUT:
                                found.add(v)
            self.inout_bound_memo[self.cur.key] = found
        return found

    def root_var(self, e: A.Expr) -> VarSym | None:
        while isinstance(e, A.Member | A.Index):
            e = e.obj
        ref = self.p.names.get(e) if isinstance(e, A.Name) else None
        return ref.var if ref is not None and ref.kind == "var" else None

    def known_range(self, e: A.Expr) -> tuple[int, int] | None:
        """The values an index expression can take, where the emitter knows them: a FOR
        variable of fixed_for, plus or minus an integer literal."""
        if isinstance(e, A.Name):
            ref = self.p.names.get(e)
            return self.for_ranges.get(ref.var) if ref is not None and ref.kind == "var" \
                and ref.var is not None else None
        if isinstance(e, A.Binary) and e.op in ("+", "-"):
            for a, b, sign in ((e.left, e.right, 1), (e.right, e.left, 1)):
                if e.op == "-" and a is e.right:
                    continue
                r = self.known_range(a)
                if r is not None and isinstance(b, A.Literal) and b.kind == "int":
                    k = int(b.value) * (-1 if e.op == "-" else sign)
                    return r[0] + k, r[1] + k
        return None

    def block(self, body: list[A.Stmt], depth: int) -> str:
        out: list[str] = []
        for s in body:
            out.append(self.stmt(s, depth))
        return "".join(out)

    def pos(self, n: A.Node) -> str:
        return '"' + str(n.pos).replace("\\", "/").replace('"', "'") + '"'

    def stmt(self, s: A.Stmt, depth: int) -> str:
        ind = "    " * depth
        if isinstance(s, A.Assign):
            tt = self.p.expr_types[s.target]
            if self.in_function() and self.is_result(s.target):
                assert self.cur is not None
                local = self.params_of(self.cur).result_local
                if local and self.local_key(s.value) == local:
                    return ""  # the named result is the result itself
            if isinstance(s.value, A.Call) and not is_scalar(tt):
                call = self.p.calls[s.value]
                if call.kind == "function" and call.en is None and call.eno is None and \
                        self.may_target(s.target, call):
                    return f"{ind}{self.fn_call(s.value, dest=s.target)};\n"
            return f"{ind}{self.assign_c(self.lvalue(s.target), s.value, tt)}\n"
        if isinstance(s, A.CallStmt):
            return self.fb_call(s.call, ind)
        if isinstance(s, A.If):
            out = ""
            for i, (cond, body) in enumerate(s.branches):
                kw = "if" if i == 0 else "} else if"
                out += f"{ind}{kw} ({self.expr(cond, want=BOOL)}) {{\n{self.block(body, depth + 1)}"
            if s.orelse is not None:
                out += f"{ind}}} else {{\n{self.block(s.orelse, depth + 1)}"
            return out + f"{ind}}}\n"
        if isinstance(s, A.Case):
            st = self.p.expr_types[s.subject]
            tmp = self.loc.tmp()
            out = f"{ind}{{ {self.ctype(st)} {tmp} = {self.expr(s.subject)};\n"
            first = True
            for cl in s.clauses:
                conds = []
                for lab in cl.labels:
                    lo = self.expr(lab.low, want=st)
                    if lab.high is None:
                        conds.append(f"{tmp} == {lo}")
                    else:
                        conds.append(f"({tmp} >= {lo} && {tmp} <= {self.expr(lab.high, want=st)})")
                kw = "if" if first else "} else if"
                first = False
                cond_c = " || ".join(conds) or "0"
                out += f"{ind}{kw} ({cond_c}) {{\n{self.block(cl.body, depth + 1)}"
            if s.orelse is not None:
                out += (f"{ind}}} else {{\n" if not first else f"{ind}{{\n") + \
                    self.block(s.orelse, depth + 1)
                first = False
            if not first:
                out += f"{ind}}}\n"
            return out + f"{ind}}}\n"
        if isinstance(s, A.For):
            vt = self.p.expr_types[s.var]
            v = self.lvalue(s.var)
            ct = self.ctype(vt)
            step = self.expr(s.step, want=vt) if s.step is not None else "1"
            end = self.expr(s.end, want=vt)
            stp = self.loc.tmp()
            fixed = self.fixed_for(s)
            before, each = "", f"{ind}    PLC__WD({self.pos(s)});\n"
            var = self.p.names[s.var].var
            if fixed is not None and var is not None and self.unrollable(s, fixed[2]):
                return self.unrolled_for(s, var, fixed[2], ind, depth)
            if fixed is not None and var is not None:
                # a known number of iterations: counted once for the watchdog, and the
                # variable's range known inside (indices need no bounds check)
                before, each = f"{ind}PLC__WD_N({self.pos(s)}, {fixed[2]});\n", ""
                self.for_ranges[var] = (fixed[0], fixed[1])
            try:
                inner = self.block(s.body, depth + 2)
            finally:
                if var is not None:
                    self.for_ranges.pop(var, None)
            return (f"{before}{ind}for ({v} = {self.expr(s.start, want=vt)}; ; ) {{\n"
                    f"{ind}    {ct} {stp} = {step};\n"
                    f"{ind}    if ({stp} >= 0 ? !({v} <= {end}) : !({v} >= {end})) break;\n"
                    f"{each}"
                    f"{ind}    do {{\n{inner}{ind}    }} while (0);\n"
                    f"{ind}    if (plc__brk_) {{ plc__brk_ = 0; break; }}\n"
                    f"{ind}    {v} = ({ct})({v} + {stp});\n{ind}}}\n")
        if isinstance(s, A.While):
            return (f"{ind}while ({self.expr(s.cond, want=BOOL)}) {{\n"
                    f"{ind}    PLC__WD({self.pos(s)});\n"
                    f"{ind}    do {{\n{self.block(s.body, depth + 2)}{ind}    }} while (0);\n"
                    f"{ind}    if (plc__brk_) {{ plc__brk_ = 0; break; }}\n{ind}}}\n")
        if isinstance(s, A.Repeat):
            return (f"{ind}for (;;) {{\n{ind}    PLC__WD({self.pos(s)});\n"
                    f"{ind}    do {{\n{self.block(s.body, depth + 2)}{ind}    }} while (0);\n"
                    f"{ind}    if (plc__brk_) {{ plc__brk_ = 0; break; }}\n"
                    f"{ind}    if ({self.expr(s.cond, want=BOOL)}) break;\n{ind}}}\n")
        if isinstance(s, A.Exit):
            return f"{ind}{{ plc__brk_ = 1; break; }}\n"
        if isinstance(s, A.Continue):
            return f"{ind}break;\n"
        if isinstance(s, A.Return):
            if self.in_function():
                assert self.cur is not None and self.cur.return_type is not None
                if is_scalar(self.cur.return_type):
                    return f"{ind}return l_ret_;\n"
            return f"{ind}return;\n"
        raise AssertionError(f"statement {type(s).__name__}")

    # ================================================================ calls
    def fb_call(self, c: A.Call, ind: str) -> str:
        tgt = self.p.calls[c]
        assert tgt.pou is not None
        inst = self.lvalue(c.callee)
        sym = tgt.pou
        cname = self.ctype(self.p.expr_types[c.callee])
        out = f"{ind}{{\n"
        for key, e in tgt.inputs:
            v = sym.vars[key]
            if v.kind == A.VAR_IN_OUT:
                out += f"{ind}    {inst}.{key} = &{self.lvalue(e)};\n"
            else:
                out += f"{ind}    {self.assign_c(f'{inst}.{key}', e, v.type)}\n"
        if tgt.en is None and tgt.eno is None:
            out += f"{ind}    {cname}_body(&{inst});\n"
        else:
            # EN FALSE: the inputs are set and the outputs copied, the body does not run
            en = self.loc.tmp()
            en_c = self.expr(tgt.en, want=BOOL) if tgt.en is not None else "1"
            out += f"{ind}    uint8_t {en} = {en_c};\n{ind}    if ({en}) {cname}_body(&{inst});\n"
            if tgt.eno is not None:
                out += f"{ind}    {self.lvalue(tgt.eno)} = {en};\n"
        for key, e in tgt.outputs:
            out += f"{ind}    {self.copy_c(self.lvalue(e), f'{inst}.{key}', sym.vars[key].type)}\n"
        return out + f"{ind}}}\n"

    def fn_call(self, c: A.Call, dest: A.Expr | None = None) -> str:
        """A FUNCTION call: its arguments evaluated in the order written, each into a
        temporary, then FN_x_fn. A STRUCT input goes by pointer to the argument itself when
        nothing can change it before the callee is done with it (see may_point), else by
        pointer to a copy. ``dest``: the variable the aggregate result is written to
        directly (may_target), the call then a statement."""
        tgt = self.p.calls[c]
        sym = tgt.pou
        assert sym is not None and sym.return_type is not None
        cname = self.pou_cname(sym)
        fp = self.params_of(sym)
        # may evaluating an argument write to what another one points to?
        side_effects = any(self.writes_caller(e) for _, e in tgt.inputs)
        inout_roots = [self.root_of(e) for key, e in tgt.inputs
                       if sym.vars[key].kind == A.VAR_IN_OUT]
        parts: list[str] = []
        if dest is not None:
            d = self.loc.tmp()
            parts.append(f"{self.ctype(sym.return_type)} *{d} = &{self.lvalue(dest)};")
        passed: dict[str, str] = {}
        for key, e in tgt.inputs:
            v = sym.vars[key]
            ct = self.ctype(v.type)
            t = self.loc.tmp()
            if v.kind == A.VAR_IN_OUT:
                parts.append(f"{ct} *{t} = &{self.lvalue(e)};")
                passed[key] = t
            elif is_scalar(v.type):
                parts.append(f"{ct} {t} = {self.expr(e, want=v.type)};")
                passed[key] = t
            elif not side_effects and self.may_point(e, key in fp.by_pointer, inout_roots):
                parts.append(f"const {ct} *{t} = &{self.lvalue(e)};")
                passed[key] = t
            else:
                parts.append(f"{ct} {t}; {self.assign_c(t, e, v.type)}")
                passed[key] = f"&{t}"
        args: list[str] = []
        outs: dict[str, str] = {}
        for v in sym.vars.values():
            if v.kind not in FN_FRAME_KINDS:
                continue
            if v.key in passed:
                args.append(passed[v.key])
                continue
            t = self.loc.tmp()
            if v.kind == A.VAR_IN_OUT:
                args.append("0")
            elif v.kind == A.VAR_OUTPUT:
                parts.append(f"{self.ctype(v.type)} {t};")
                args.append(f"&{t}")
                outs[v.key] = t
            else:  # an input not given: its initial value
                parts.append(self.declare(t, v.type, v.init))
                args.append(t if is_scalar(v.type) else f"&{t}")
        after = [self.copy_c(self.lvalue(e), outs[key], sym.vars[key].type)
                 for key, e in tgt.outputs]
        if is_scalar(sym.return_type):
            call = f"{cname}_fn({', '.join(args)})"
            if not after:
                return "({ " + " ".join([*parts, f"{call};"]) + " })"
            r = self.loc.tmp()
            parts.append(f"{self.ctype(sym.return_type)} {r} = {call};")
        elif dest is not None:
            args.append(d)
            parts.append(f"{cname}_fn({', '.join(args)});")
            return "({ " + " ".join([*parts, *after]) + " })"
        else:
            r = self.loc.tmp()
            parts.append(f"{self.ctype(sym.return_type)} {r};")
            args.append(f"&{r}")
            parts.append(f"{cname}_fn({', '.join(args)});")
        return "({ " + " ".join([*parts, *after, f"{r};"]) + " })"

    def writes_caller(self, e: A.Expr) -> bool:
        """Does evaluating e call a FUNCTION that writes through a VAR_IN_OUT or VAR_OUTPUT?
        Every node below e gets its answer at once (children first, with a stack), so that
        nested calls cost linear time."""
        memo = self.writes_memo
        if id(e) in memo:
            return memo[id(e)]
        order: list[A.Node] = []
        stack: list[object] = [e]
        while stack:
            cur = stack.pop()
            if isinstance(cur, A.Node):
                if id(cur) in memo:
                    continue
                order.append(cur)
                stack.extend(cur.__dict__.values())
            elif isinstance(cur, list | tuple):
                stack.extend(cur)
        for node in reversed(order):  # every node after the nodes below it
            own = False
            if isinstance(node, A.Call):
                tgt = self.p.calls.get(node)
                own = tgt is not None and tgt.kind == "function" and tgt.pou is not None \
                    and self.params_of(tgt.pou).writes_caller
            memo[id(node)] = own or any(memo.get(id(child), False)
                                        for child in children(node))
        return memo[id(e)]

    def may_point(self, e: A.Expr, read_only: bool,
                  inout_roots: list[tuple[object, str] | None]) -> bool:
        """May a STRUCT input be passed as a pointer to the argument e itself? A callee that
        copies it on entry (not read_only) needs only an lvalue; one that reads it in place
        needs also that none of the call's VAR_IN_OUT arguments can be the same storage."""
        if not isinstance(e, A.Name | A.Member | A.Index):
            return False
        root = self.root_of(e)
        if root is None:
            return False
        if not read_only:
            return True
        return not any(may_alias(root, other) for other in inout_roots)

    def may_target(self, target: A.Expr, tgt: CallTarget) -> bool:
        """May the FUNCTION call `tgt` write its aggregate result straight into `target`
        (the caller's variable)? Only when none of its STRUCT and VAR_IN_OUT arguments can
        be that variable: the callee writes its result from entry on."""
        root = self.root_of(target)
        if root is None or tgt.pou is None:
            return False
        for key, e in tgt.inputs:
            if is_scalar(tgt.pou.vars[key].type):
                continue
            if isinstance(e, A.Name | A.Member | A.Index) and \
                    may_alias(root, self.root_of(e)):
                return False
        return True

    # ================================================================ expressions
    def var_ref(self, e: A.Expr) -> str:
        ref = self.p.names[e]
        v = ref.var
        assert v is not None
        if ref.kind == "pou_result":
            assert self.cur is not None and self.cur.return_type is not None
            return "l_ret_" if is_scalar(self.cur.return_type) else "(*plc__ret)"
        if ref.kind == "global":
            return f"(*plc_globals.{v.key})" if v.address else f"plc_globals.{v.key}"
        if is_shared_constant(v):
            assert self.cur is not None
            return const_name(self.pou_cname(self.cur), v)
        fp = self.cur_fp
        if fp is not None:
            if v.kind == A.VAR_INPUT:
                if is_scalar(v.type):
                    return f"a_{v.key}"
                if v.key in fp.by_pointer:
                    return f"(*a_{v.key})"
            elif v.kind in (A.VAR_IN_OUT, A.VAR_OUTPUT):
                return f"(*a_{v.key})"
            elif v.kind == A.VAR and v.key == fp.result_local:
                return "(*plc__ret)"
            return f"l_{v.key}"
        if v.kind == A.VAR_IN_OUT or v.address:
            return f"(*self->{v.key})"
        return f"self->{v.key}"

    def lvalue(self, e: A.Expr) -> str:
        if isinstance(e, A.Name):
            return self.var_ref(e)
        if isinstance(e, A.Member):
            ot = self.p.expr_types[e.obj]
            base = self.lvalue(e.obj)
            key = e.member.upper()
            if isinstance(ot, PouType):
                sym = ot.symbol
                assert isinstance(sym, PouSym)
                if sym.vars[key].kind == A.VAR_IN_OUT:
                    return f"(*{base}.{key})"
                if is_shared_constant(sym.vars[key]):
                    return const_name(self.pou_cname(sym), sym.vars[key])
            return f"{base}.{key}"
        if isinstance(e, A.Index):
            at = self.p.expr_types[e.obj]
            assert isinstance(at, ArrayType)
            # row-major offset as a flat sum of index * stride: no C nesting per dimension
            terms: list[str] = []
            stride = at.size
            for ie, (lo, hi) in zip(e.indices, at.dims, strict=True):
                stride //= hi - lo + 1
                known = self.known_range(ie)
                if isinstance(ie, A.Literal) and ie.kind == "int":
                    term = str(int(ie.value) - lo)
                elif known is not None and lo <= known[0] and known[1] <= hi:
                    term = f"((int32_t){self.expr(ie)} - {lo})"
                else:
                    term = f"plc__idx({self.expr(ie)}, {lo}, {hi}, {self.pos(ie)})"
                terms.append(term if stride == 1 else f"{term} * {stride}")
            return f"{self.lvalue(e.obj)}.v[{' + '.join(terms)}]"
        raise AssertionError(f"not an lvalue: {type(e).__name__}")

    def expr(self, e: A.Expr, want: Type | None = None) -> str:
        t = self.p.expr_types.get(e)
        if isinstance(t, LiteralType) and isinstance(want, ElemType):
            t = want
        if isinstance(e, A.Literal):
            return self.literal(e, t)
        if isinstance(e, A.Name | A.Member | A.Index):
            ref = self.p.names.get(e)
            if ref is not None and ref.kind == "enum":
                return str(ref.enum_value)
            return self.lvalue(e)
        if isinstance(e, A.Unary):
            if e.op == "-" and isinstance(e.operand, A.Literal) and isinstance(t, ElemType) \
                    and not isinstance(e.operand.value, bool):
                return self.literal(e.operand, t, negate=True)
            a = self.expr(e.operand, want=t)
            if e.op == "NOT":
                return f"(!{a})" if t is BOOL else f"(({self.ctype(t or BOOL)})~{a})"
            if e.op == "+":
                return a
            if isinstance(t, ElemType) and t.is_real:
                return f"(-{a})"
            return f"(({self.ctype(t or BOOL)})(-{a}))"
        if isinstance(e, A.Binary):
            return self.binary(e, t)
        if isinstance(e, A.Call):
            if self.p.calls[e].en is not None or self.p.calls[e].eno is not None:
                return self.en_call(e, t, want)
            return self.call_value(e, t, want)
        raise AssertionError(f"expression {type(e).__name__}")

    def en_call(self, e: A.Call, t: Type | None, want: Type | None) -> str:
        """A call with EN/ENO, as MatIEC's C runs it: with EN FALSE nothing is computed, the
        result is 0 (zero bytes), a FUNCTION's outputs are not written, ENO is FALSE."""
        tgt = self.p.calls[e]
        rt = t if not isinstance(t, LiteralType) else want if isinstance(want, ElemType) else t
        assert rt is not None
        en, r = self.loc.tmp(), self.loc.tmp()
        en_c = self.expr(tgt.en, want=BOOL) if tgt.en is not None else "1"
        eno = f" {self.lvalue(tgt.eno)} = {en};" if tgt.eno is not None else ""
        value = self.call_value(e, t, want)
        div = tgt.alias if isinstance(tgt.alias, A.Binary) and tgt.alias.op == "DIV" else None
        if div is not None and isinstance(rt, ElemType):
            # DIV by zero: 0 and ENO FALSE, as MatIEC's DIV (TEST_EN_COND)
            x, y = self.loc.tmp(), self.loc.tmp()
            q = self.binary_node(A.Binary(div.pos, "/", div.left, div.right), rt, x, y)
            value = (f"({{ {rt.ctype} {x} = {self.expr(div.left, want=rt)}; {rt.ctype} {y} = "
                     f"{self.expr(div.right, want=rt)}; if ({y} == 0) {en} = 0; "
                     f"{y} == 0 ? ({rt.ctype})0 : {q}; }})")
        std_name = tgt.std.name if tgt.kind == "std" and tgt.std is not None else ""
        neg = _STRING_ENO_ARGS.get(std_name)
        if neg is not None:
            # MatIEC's TEST_EN_COND: a negative length or position gives '' and ENO FALSE
            temps, decls = [], []
            for _key, a in tgt.inputs:
                at = self.p.expr_types[a]
                x = self.loc.tmp()
                temps.append(x)
                if at is STRING:
                    decls.append(f"plc_string_t {x} = {self.expr(a, want=STRING)};")
                else:
                    want_t = at if not isinstance(at, LiteralType) else DINT
                    decls.append(f"int64_t {x} = (int64_t)({self.expr(a, want=want_t)});")
            bad = " || ".join(f"{temps[i]} < 0" for i, (key, _) in enumerate(tgt.inputs)
                              if key in neg)
            fn = "plc__str_" + std_name.lower()
            value = (f"({{ {' '.join(decls)} if ({bad}) {en} = 0; "
                     f"{fn}({', '.join(temps)}, {self.pos(e)}); }})")
        return (f"({{ uint8_t {en} = {en_c}; {self.ctype(rt)} {r}; "
                f"if ({en}) {r} = {value}; else PLC__ZERO({r});"
                f"{eno} {r}; }})")

    def call_value(self, e: A.Call, t: Type | None, want: Type | None) -> str:
        """The value of a call without EN/ENO."""
        tgt = self.p.calls[e]
        if tgt.kind == "function":
            return self.fn_call(e)
        if tgt.kind == "alias":
            assert tgt.alias is not None
            in_real = self.call_form_in_real(tgt)
            if in_real is not None:
                return in_real
            return self.expr(tgt.alias, want=want if t is None else t)
        if tgt.kind == "conv":
            assert tgt.conv is not None
            return self.conversion(self.expr(tgt.inputs[0][1], want=tgt.conv[0]),
                                   *tgt.conv)
        return self.std_call(e, t)

    def call_form_in_real(self, tgt: CallTarget) -> str | None:
        """ADD(...), MUL(...), GT(...) ... on REAL inputs as MatIEC's standard functions
        compute them: each input passed as (REAL)(...), so rounded to float where a REAL
        literal made C compute it in double, and every step in float; the operator form
        (`x + 1.4 + 1.4`) computes in double and rounds once. None for other types."""
        assert tgt.alias is not None
        args = [x for _, x in tgt.inputs]
        types = [self.p.expr_types.get(x) for x in args]
        if REAL not in types or not all(x is REAL or isinstance(x, LiteralType) for x in types):
            return None
        vals = [f"((float){self.expr(x, want=REAL)})" for x in args]
        node = tgt.alias
        while isinstance(node, A.Binary) and node.op == "AND":
            node = node.left  # an extensible comparison: (a > b) AND (b > c) ...
        assert isinstance(node, A.Binary)
        if node.op in ("=", "<>", "<", "<=", ">", ">="):
            pairs = [self.binary_node(node, BOOL, vals[i], vals[i + 1])
                     for i in range(len(vals) - 1)]
            return "(" + " && ".join(pairs) + ")"
        acc = vals[0]
        for v in vals[1:]:
            acc = self.binary_node(node, REAL, acc, v)
        return acc

    def literal(self, e: A.Literal, t: Type | None, negate: bool = False) -> str:
        v = e.value
        if e.kind == "string":
            return f"((plc_string_t){self.string_init(e)})"
        if e.kind == "bool":
            return "1" if v else "0"
        if e.kind == "enum":
            return str(self.p.names[e].enum_value)
        if e.kind == "time":
            n = -int(v) if negate else int(v)
            return f"((int64_t){n}LL)"
        if isinstance(t, ElemType) and t.is_real:
            f = -float(v) if negate else float(v)
            if t.bits == 32 and e.type_prefix is not None:
                # REAL#1.5 is MatIEC's __REAL_LITERAL(1.5), (REAL)1.5: a float
                f32 = struct.unpack("f", struct.pack("f", f))[0]
                return f"({f32.hex()}f)"
            # MatIEC writes an untyped literal's text into its C as it is, a double even in a
            # REAL expression: C's promotions then compute `x * 0.1` (x REAL) in double, and
            # the value is rounded to float only where it lands in a REAL (an assignment, an
            # argument, a conversion's input), never between the operators
            return f"({f.hex()})"
        n = -int(v) if negate else int(v)
        if isinstance(t, ElemType):
            if t.kind == "bool":
                return "1" if n else "0"
            if t.bits == 64:
                return f"(({t.ctype}){n}{'ULL' if t.kind in ('uint', 'bits') and n >= 0 else 'LL'})"
            return f"(({t.ctype}){n})"
        return f"((int64_t){n}LL)"

    def string_init(self, e: A.Literal) -> str:
        return c_initializer(string_literal(e.text[e.text.index("'"):] if "'" in e.text
                                            else e.text))

    def binary(self, e: A.Binary, t: Type | None) -> str:
        """`a + b + c + ...` in a loop: its left spine is as deep as the chain is long. Inside
        a function every SPILL_EVERY links go to a temporary, so the C nests no deeper than
        that whatever the length (gcc's recursive parser crashes near 20,000 levels)."""
        spine: list[tuple[A.Binary, Type | None, Type | None]] = []
        node: A.Expr = e
        while isinstance(node, A.Binary):
            operand_t = self.operand_type(node, t)
            spine.append((node, t, operand_t))
            node = node.left
            t = self.p.expr_types.get(node)
            if isinstance(t, LiteralType) and isinstance(operand_t, ElemType):
                t = operand_t
        acc = self.expr(node, want=spine[-1][2])
        spills: list[str] = []
        for i, (b, bt, operand_t) in enumerate(reversed(spine)):
            acc = self.binary_node(b, bt, acc, self.expr(b.right, want=operand_t))
            if (i + 1) % SPILL_EVERY == 0 and b is not e and isinstance(bt, ElemType):
                tmp = self.loc.tmp()
                # __auto_type: the operator's C type, double where a REAL literal made it so
                # (a float here would round where MatIEC's C does not)
                spills.append(f"__auto_type {tmp} = {acc};")
                acc = tmp
        return "({ " + " ".join(spills) + f" {acc}; }})" if spills else acc

    def operand_type(self, e: A.Binary, t: Type | None) -> Type | None:
        lt = self.p.expr_types[e.left]
        rt = self.p.expr_types[e.right]
        operand_t: Type | None = lt if not isinstance(lt, LiteralType) else rt
        if isinstance(operand_t, LiteralType):
            operand_t = t if e.op not in ("=", "<>", "<", "<=", ">", ">=") else operand_t
        return operand_t

    def binary_node(self, e: A.Binary, t: Type | None, a: str, b: str) -> str:
        op = e.op
        cmp = {"=": "==", "<>": "!=", "<": "<", "<=": "<=", ">": ">", ">=": ">="}
        if op in cmp:
            if self.p.expr_types.get(e.left) is STRING:
                return f"(plc__str_cmp({a}, {b}) {cmp[op]} 0)"
            return f"({a} {cmp[op]} {b})"
        assert isinstance(t, ElemType), f"binary {op} on {t}"
        ct = t.ctype
        if op == "DIV":  # MatIEC's DIV function: a zero divisor gives 0 (the operator traps)
            x, y = self.loc.tmp(), self.loc.tmp()
            q = self.binary_node(A.Binary(e.pos, "/", e.left, e.right), t, x, y)
            return f"({{ {ct} {x} = {a}; {ct} {y} = {b}; {y} == 0 ? ({ct})0 : {q}; }})"
        if op in ("AND", "OR", "XOR"):
            c = {"AND": "&", "OR": "|", "XOR": "^"}[op]
            return f"({a} {c} {b})" if t.kind == "bool" else f"(({ct})({a} {c} {b}))"
        if t.is_real:
            if op == "MOD":
                raise AssertionError("MOD on REAL")
            return f"({a} {op} {b})"
        signed = t.kind in ("sint", "time")
        if op in ("/", "MOD"):
            # 32-bit helpers for types up to 32 bits: one hardware divide on a Cortex-M3
            width = "32" if t.bits <= 32 else ""
            cast = ("int32_t" if width else "int64_t") if signed else \
                ("uint32_t" if width else "uint64_t")
            kind = ("div" if op == "/" else "mod") + ("_s" if signed else "_u") + width
            pos = f", {self.pos(e)}" if op == "/" else ""
            return f"(({ct})plc__{kind}(({cast}){a}, ({cast}){b}{pos}))"
        if t.bits == 64 or t.bits == 32:
            # do 32/64-bit arithmetic unsigned to avoid C overflow UB, then cast back
            ut = "uint64_t" if t.bits == 64 else "uint32_t"
            return f"(({ct})(({ut}){a} {op} ({ut}){b}))"
        return f"(({ct})({a} {op} {b}))"

    def conversion(self, a: str, src: ElemType, dst: ElemType) -> str:
        if src is REAL:
            # MatIEC passes the input as (REAL)(...): rounded to float first, whatever a
            # REAL literal in it made C compute in double
            a = f"((float){a})"
        if dst is STRING:
            # MatIEC's *_TO_STRING: snprintf formats, REAL through double with %.10g
            if src.kind == "bool":
                return f"plc__str_fmt_bool({a})"
            if src.kind == "bits":
                return f"plc__str_fmt_bits((uint64_t){a})"
            if src.kind == "sint":
                return f"plc__str_fmt_s((int64_t){a})"
            if src.kind == "uint":
                return f"plc__str_fmt_u((uint64_t){a})"
            if src.is_real:
                return f"plc__str_fmt_real((double){a})"
            return f"plc__str_fmt_time({a})"
        if src is STRING:
            if dst.kind == "bool":
                return f"((uint8_t)plc__str_to_bool({a}))"
            if dst.is_real:
                return f"(({dst.ctype})plc__str_to_real({a}))"
            if dst.kind == "time":
                return f"plc__str_to_time({a})"
            return f"(({dst.ctype})plc__str_to_int({a}))"
        if dst.kind == "bool":
            return f"({a} != 0)"
        # TIME converts in seconds, as MatIEC does (verified with its runtime)
        if src.kind == "time":
            if dst.is_real:
                return f"(({dst.ctype})((double){a} / 1.0e9))"
            a = f"({a} / 1000000000LL)"
            src = ELEMENTARY["LINT"]
        if dst.kind == "time":
            if src.is_real:
                return f"((int64_t)nearbyint((double){a} * 1.0e9))"
            return f"((int64_t){a} * 1000000000LL)"
        if dst.is_real:
            return f"(({dst.ctype}){a})"
        if src.is_real:
            if dst.kind == "sint":
                return f"(({dst.ctype})plc__r2i({a}))"
            return f"(({dst.ctype})plc__r2u({a}))"
        return f"(({dst.ctype}){a})"

    def std_call(self, c: A.Call, t: Type | None) -> str:
        tgt = self.p.calls[c]
        f = tgt.std
        assert f is not None
        name = f.name
        args = [e for _, e in tgt.inputs]
        if name in ("SQRT", "LN", "LOG", "EXP", "SIN", "COS", "TAN", "ASIN", "ACOS", "ATAN"):
            assert isinstance(t, ElemType)
            fn = {"LN": "log", "LOG": "log10"}.get(name, name.lower())
            return f"{fn}{'f' if t.bits == 32 else ''}({self.expr(args[0], want=t)})"
        if name == "TRUNC":
            at = self.p.expr_types[args[0]]
            x = self.expr(args[0], want=at)
            if at is REAL:
                x = f"((float){x})"
            assert isinstance(t, ElemType)
            return f"(({t.ctype})(int64_t)({x}))"
        if name == "EXPT":
            assert isinstance(t, ElemType)
            bt = self.p.expr_types[args[1]]
            x = self.expr(args[0], want=t)
            y = self.expr(args[1], want=bt)
            if t is REAL and bt is not REAL:
                # MatIEC's C++ pow(float, <integer or double>) is the double pow (C++11's
                # std::pow promotes), rounded to REAL on return; pow(float, float) is powf
                return f"((float)pow((float){x}, (double){y}))"
            return f"pow{'f' if t.bits == 32 else ''}({x}, ({t.ctype}){y})"
        if f.kind.startswith("str_"):
            return self.string_call(c, name, args, t)
        assert isinstance(t, ElemType)
        ct = t.ctype
        if name == "MOVE":
            return f"((float){self.expr(args[0], want=t)})" if t is REAL else \
                self.expr(args[0], want=t)
        if name == "ABS":
            if t.is_real:
                return f"fabs{'f' if t.bits == 32 else ''}({self.expr(args[0], want=t)})"
            x = self.loc.tmp()
            return f"({{ {ct} {x} = {self.expr(args[0], want=t)}; ({ct})({x} < 0 ? -{x} : {x}); }})"
        if name == "NOT":
            return f"(!{self.expr(args[0], want=t)})" if t is BOOL else \
                f"(({ct})~{self.expr(args[0], want=t)})"
        if name in ("MIN", "MAX", "LIMIT", "SEL", "MUX", "MOD", "AND", "OR", "XOR"):
            temps = []
            decl = []
            for i, a in enumerate(args):
                at = t
                if (name == "SEL" and i == 0):
                    at = BOOL
                if name == "MUX" and i == 0:
                    at = self.p.expr_types[a]
                    if isinstance(at, LiteralType):
                        at = ELEMENTARY["DINT"]
                x = self.loc.tmp()
                temps.append(x)
                decl.append(f"{self.ctype(at)} {x} = {self.expr(a, want=at)};")
            r = self.loc.tmp()
            if name in ("MIN", "MAX"):
                cmpop = "<" if name == "MIN" else ">"
                body = f"{ct} {r} = {temps[0]}; " + "".join(
                    f"if ({x} {cmpop} {r}) {r} = {x}; " for x in temps[1:])
            elif name == "LIMIT":
                mn, val, mx = temps
                body = f"{ct} {r} = {val} < {mn} ? {mn} : ({val} > {mx} ? {mx} : {val}); "
            elif name == "SEL":
                body = f"{ct} {r} = {temps[0]} ? {temps[2]} : {temps[1]}; "
            elif name == "MUX":
                cases = "".join(f"case {i}: {r} = {x}; break; "
                                for i, x in enumerate(temps[1:]))
                body = (f"{ct} {r}; switch ({temps[0]}) {{ {cases}default: "
                        f"plc__fault({self.pos(c)}, \"MUX selector out of range\"); }} ")
            elif name == "MOD":
                signed = t.kind == "sint"
                fn = "plc__mod_s" if signed else "plc__mod_u"
                body = f"{ct} {r} = ({ct}){fn}({temps[0]}, {temps[1]}); "
            else:
                c_op = {"AND": "&", "OR": "|", "XOR": "^"}[name]
                body = f"{ct} {r} = " + f" {c_op} ".join(temps) + "; "
            return "({ " + " ".join(decl) + " " + body + f"{r}; }})"
        if name in ("SHL", "SHR", "ROL", "ROR"):
            x = self.expr(args[0], want=t)
            ut = "uint32_t" if t.bits <= 32 else "uint64_t"
            lit = args[1]
            if isinstance(lit, A.Literal) and lit.kind == "int":
                # a constant shift count needs no range check at run time
                k = int(lit.value)
                if name in ("ROL", "ROR"):
                    k %= t.bits
                    if k == 0:
                        return x
                    left = k if name == "ROL" else t.bits - k
                    return (f"(({ct})((({ut}){x} << {left}) | "
                            f"(({ut}){x} >> {t.bits - left})))")
                if not 0 <= k < t.bits:
                    return f"(({ct})0)"
                return f"(({ct})(({ut}){x} {'<<' if name == 'SHL' else '>>'} {k}))"
            nt = self.p.expr_types[args[1]]
            n = self.expr(args[1], want=nt if not isinstance(nt, LiteralType) else
                          ELEMENTARY["DINT"])
            if t.bits <= 32 and name in ("SHL", "SHR"):
                return f"(({ct})plc__{name.lower()}32((uint32_t){x}, (int32_t){n}, {t.bits}))"
            return f"(({ct})plc__{name.lower()}((uint64_t){x}, (int64_t){n}, {t.bits}))"
        raise AssertionError(f"std function {name}")


    def string_call(self, c: A.Call, name: str, args: list[A.Expr], t: Type | None) -> str:
        """MatIEC's string functions (runtime plc__str_*); every argument evaluated once, in
        the order written."""
        vals = []
        for a in args:
            at = self.p.expr_types[a]
            vals.append(self.expr(a, want=at if not isinstance(at, LiteralType) else DINT))
        pos = self.pos(c)
        if name == "LEN":
            ct = t.ctype if isinstance(t, ElemType) else "int64_t"
            return f"(({ct})({vals[0]}).len)"
        if name == "FIND":
            ct = t.ctype if isinstance(t, ElemType) else "int64_t"
            return f"(({ct})plc__str_find({vals[0]}, {vals[1]}))"
        if name == "CONCAT":
            r = self.loc.tmp()
            cats = " ".join(f"plc__str_cat(&{r}, {v});" for v in vals)
            return f"({{ plc_string_t {r} = plc__str_empty(); {cats} {r}; }})"
        fn = {"LEFT": "left", "RIGHT": "right", "MID": "mid", "INSERT": "insert",
              "DELETE": "delete", "REPLACE": "replace"}[name]
        ints = [f"(int64_t)({v})" if self.p.expr_types[a] is not STRING else v
                for a, v in zip(args, vals, strict=True)]
        return f"plc__str_{fn}({', '.join(ints)}, {pos})"


def nodes(obj: object) -> list[A.Node]:
    """Every AST node in obj (a node or a list of them), with a stack: A.walk, faster (no
    dataclass field lists) and the nodes only."""
    out: list[A.Node] = []
    stack: list[object] = [obj]
    node_t, seq_t = A.Node, (list, tuple)
    while stack:
        cur = stack.pop()
        if isinstance(cur, node_t):
            out.append(cur)
            stack.extend(cur.__dict__.values())
        elif isinstance(cur, seq_t):
            stack.extend(cur)
    return out


def children(node: A.Node) -> Iterator[A.Node]:
    """The AST nodes directly below node (inside its fields, lists and tuples included)."""
    stack: list[object] = list(node.__dict__.values())
    while stack:
        cur = stack.pop()
        if isinstance(cur, A.Node):
            yield cur
        elif isinstance(cur, list | tuple):
            stack.extend(cur)


def literal_int(e: A.Expr) -> int | None:
    """The value of an integer literal, negated or not; None for anything else."""
    if isinstance(e, A.Unary) and e.op == "-":
        v = literal_int(e.operand)
        return None if v is None else -v
    if isinstance(e, A.Literal) and e.kind == "int" and not isinstance(e.value, bool):
        return int(e.value)
    return None


def may_alias(a: tuple[object, str] | None, b: tuple[object, str] | None) -> bool:
    """May two lvalues with these roots (Emitter.root_of) share storage?"""
    if a is None or b is None or a[0] is b[0]:
        return True
    kinds = {a[1], b[1]}
    return "fresh" not in kinds and kinds != {"direct"}


def statement_lists(body: list[A.Stmt]) -> Iterator[list[A.Stmt]]:
    """body and every statement list nested in it (branches, loop bodies), with a stack."""
    stack = [body]
    while stack:
        sl = stack.pop()
        yield sl
        for st in sl:
            if isinstance(st, A.If):
                stack.extend(b for _, b in st.branches)
            if isinstance(st, A.Case):
                stack.extend(cl.body for cl in st.clauses)
            if isinstance(st, A.If | A.Case) and st.orelse is not None:
                stack.append(st.orelse)
            if isinstance(st, A.For | A.While | A.Repeat):
                stack.append(st.body)


def is_scalar(t: Type) -> bool:
    """Held in one C scalar (an elementary or enumerated type), not a STRUCT, ARRAY or
    STRING (a C struct, copied and passed as the STRUCTs are)."""
    return isinstance(t, EnumType | LiteralType) or (isinstance(t, ElemType) and
                                                     t.kind != "string")


def effective_init(t: Type, init: A.Init | None) -> A.Init | None:
    """The variable's own initial value, else its named type's default."""
    if init is None and isinstance(t, ArrayType | StructType) and t.default is not None:
        return t.default  # type: ignore[return-value]
    return init


def field_inits(t: StructType, init: A.Init | None) -> list[tuple[str, Type, A.Init | None]]:
    """Each field with the value it starts from: the initialiser's, else the field default."""
    out: list[tuple[str, Type, A.Init | None]] = []
    for fk, (_, ft) in t.fields.items():
        finit: A.Init | None = None
        if isinstance(init, A.StructInit):
            finit = next((v for n, v in init.fields if n.upper() == fk), None)
        if finit is None:
            finit = t.inits.get(fk)  # type: ignore[assignment]
        out.append((fk, ft, finit))
    return out


def is_shared_constant(v: VarSym) -> bool:
    """A VAR CONSTANT is never written (the checker refuses it), so all instances and calls
    can share one read-only copy. Not when its initial value is a long operator chain: the
    shared copy's initialiser is at file scope, where C allows no temporaries to split it (see
    Emitter.binary), so such a constant is initialised per instance like a variable."""
    return v.constant and v.kind == A.VAR and not v.address and \
        not isinstance(v.type, PouType) and _operators_in(v.init) < SPILL_EVERY


def _operators_in(init: A.Init | None) -> int:
    count = 0
    stack: list[A.Init] = [init] if init is not None else []
    while stack:
        x = stack.pop()
        if isinstance(x, A.ArrayInit):
            stack.extend(v for _, v in x.items)
        elif isinstance(x, A.StructInit):
            stack.extend(v for _, v in x.fields)
        elif isinstance(x, A.Binary):
            count += 1
            stack += (x.left, x.right)
        elif isinstance(x, A.Unary):
            stack.append(x.operand)
    return count


def const_name(pou_cname: str, v: VarSym) -> str:
    return f"K_{pou_cname}_{v.key}"


def split_address(addr: str) -> tuple[str, str, list[int]]:
    """'%QX2.5' -> ('Q', 'X', [2, 5]); a missing size prefix means X (a bit)."""
    area = addr[1:2]
    rest = addr[2:]
    size = "X"
    if rest[:1].isalpha():
        size, rest = rest[0], rest[1:]
    return area, size, [int(x) for x in rest.split(".")]


def emit(prog: CheckedProgram) -> CUnit:
    return Emitter(prog).emit()
