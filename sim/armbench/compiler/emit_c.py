"""Emit C: CheckedProgram -> one C translation unit. Needs: a program with no diagnostics.

Layout: a cffi-parsable declarations section (image, types, POU structs, entry points), then
the code. Every POU is a struct plus `_init`/`_body` functions; FUNCTIONs get a frame struct
initialised on every call (MatIEC re-initialises function locals). Integer results are cast
back to their IEC type (wrap-around, compiled with -fwrapv); division, MOD, indices and loops
go through the runtime's checked helpers, which fault with the ST position.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass, field

from . import ast as A
from .stdlib import STD_FB_BODIES, STD_FBS
from .symbols import CheckedProgram, PouSym, VarSym
from .types import (
    BOOL,
    ELEMENTARY,
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
        return CUnit(decls + storage + "".join(self.ffi_only), code, shared=shared,
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
            return "0"
        assert isinstance(init, A.Expr)
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
        init: list[str] = ["memset(self, 0, sizeof *self);"]
        consts = "".join(
            f"const {self.ctype(v.type)} {const_name(cname, v)} = "
            f"{self.static_init(v.type, v.init)};\n"
            for v in sym.vars.values() if is_shared_constant(v))
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
        if sym.kind != "FUNCTION":  # a FUNCTION's frame is initialised on every call anyway
            for v in sym.vars.values():
                if v.kind == A.VAR_TEMP:
                    temps.append(f"memset(&self->{v.key}, 0, sizeof self->{v.key});")
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
            return f"{ind}{self.lvalue(s.target)} = {self.expr(s.value, want=tt)};\n"
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
            return (f"{ind}for ({v} = {self.expr(s.start, want=vt)}; ; ) {{\n"
                    f"{ind}    {ct} {stp} = {step};\n"
                    f"{ind}    if ({stp} >= 0 ? !({v} <= {end}) : !({v} >= {end})) break;\n"
                    f"{ind}    PLC__WD({self.pos(s)});\n"
                    f"{ind}    do {{\n{self.block(s.body, depth + 2)}{ind}    }} while (0);\n"
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
                out += f"{ind}    {inst}.{key} = {self.expr(e, want=v.type)};\n"
        out += f"{ind}    {cname}_body(&{inst});\n"
        for key, e in tgt.outputs:
            out += f"{ind}    {self.lvalue(e)} = {inst}.{key};\n"
        return out + f"{ind}}}\n"

    def fn_call(self, c: A.Call) -> str:
        tgt = self.p.calls[c]
        sym = tgt.pou
        assert sym is not None
        cname = self.pou_cname(sym)
        f = self.loc.tmp()
        parts = [f"{cname} {f}; {cname}_init(&{f});"]
        for key, e in tgt.inputs:
            v = sym.vars[key]
            if v.kind == A.VAR_IN_OUT:
                parts.append(f"{f}.{key} = &{self.lvalue(e)};")
            else:
                parts.append(f"{f}.{key} = {self.expr(e, want=v.type)};")
        parts.append(f"{cname}_body(&{f});")
        for key, e in tgt.outputs:
            parts.append(f"{self.lvalue(e)} = {f}.{key};")
        parts.append(f"{f}.ret_;")
        return "({ " + " ".join(parts) + " })"

    # ================================================================ expressions
    def var_ref(self, e: A.Expr) -> str:
        ref = self.p.names[e]
        v = ref.var
        assert v is not None
        if ref.kind == "pou_result":
            return "self->ret_"
        if ref.kind == "global":
            return f"(*plc_globals.{v.key})" if v.address else f"plc_globals.{v.key}"
        if is_shared_constant(v):
            assert self.cur is not None
            return const_name(self.pou_cname(self.cur), v)
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
                if isinstance(ie, A.Literal) and ie.kind == "int":
                    term = str(int(ie.value) - lo)
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
            tgt = self.p.calls[e]
            if tgt.kind == "function":
                return self.fn_call(e)
            if tgt.kind == "conv":
                assert tgt.conv is not None
                return self.conversion(self.expr(tgt.inputs[0][1], want=tgt.conv[0]),
                                       *tgt.conv)
            return self.std_call(e, t)
        raise AssertionError(f"expression {type(e).__name__}")

    def literal(self, e: A.Literal, t: Type | None, negate: bool = False) -> str:
        v = e.value
        if e.kind == "bool":
            return "1" if v else "0"
        if e.kind == "enum":
            return str(self.p.names[e].enum_value)
        if e.kind == "time":
            n = -int(v) if negate else int(v)
            return f"((int64_t){n}LL)"
        if isinstance(t, ElemType) and t.is_real:
            f = -float(v) if negate else float(v)
            if t.bits == 32:
                f32 = struct.unpack("f", struct.pack("f", f))[0]
                return f"({f32.hex()}f)"
            return f"({f.hex()})"
        n = -int(v) if negate else int(v)
        if isinstance(t, ElemType):
            if t.kind == "bool":
                return "1" if n else "0"
            if t.bits == 64:
                return f"(({t.ctype}){n}{'ULL' if t.kind in ('uint', 'bits') and n >= 0 else 'LL'})"
            return f"(({t.ctype}){n})"
        return f"((int64_t){n}LL)"

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
                spills.append(f"{bt.ctype} {tmp} = {acc};")
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
            return f"({a} {cmp[op]} {b})"
        assert isinstance(t, ElemType), f"binary {op} on {t}"
        ct = t.ctype
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
            assert isinstance(t, ElemType)
            return f"(({t.ctype})(int64_t)({x}))"
        if name == "EXPT":
            assert isinstance(t, ElemType)
            bt = self.p.expr_types[args[1]]
            x = self.expr(args[0], want=t)
            y = self.expr(args[1], want=bt)
            return f"pow{'f' if t.bits == 32 else ''}({x}, ({t.ctype}){y})"
        assert isinstance(t, ElemType)
        ct = t.ctype
        if name == "MOVE":
            return self.expr(args[0], want=t)
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
