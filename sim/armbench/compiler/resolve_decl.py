"""Declarations: TYPEs, POU variables, located addresses and the CONFIGURATION, checked and
turned into types and symbols. Needs: lowered units. Part of the Checker (resolve.py), which
holds the tables these methods fill.
"""

from __future__ import annotations

from . import ast as A
from .config_syntax import configuration_form, instance_form, task_form
from .diagnostics import Diagnostics
from .emit_c import split_address
from .symbols import ConfigModel, InstanceModel, PouSym, TaskModel, VarSym
from .types import ELEMENTARY, ERROR_T, ArrayType, ElemType, EnumType, PouType, StructType, Type


class Declarations:
    """Mixin of Checker: the declaration half of the checks."""

    d: Diagnostics
    types: dict[str, Type]
    type_decls: dict[str, A.TypeDecl]
    pous: dict[str, PouSym]
    globals: dict[str, VarSym]
    global_consts: dict[str, int]
    enum_values: dict[str, list[tuple[EnumType, int]]]

    def check_init(self, init: A.Init, t: Type) -> None:
        raise NotImplementedError  # resolve.Checker types initial values

    def named_type(self, td: A.TypeDecl, seen: set[str]) -> Type:
        key = td.name.upper()
        if key in self.types:
            return self.types[key]
        if key in seen:
            self.d.error(td.pos, "E0200", f"type '{td.name}' is defined through itself")
            return ERROR_T
        seen.add(key)
        t = self.type_from_ref(td.definition, seen, name=td.name)
        self.types[key] = t
        if td.init is not None:
            init = td.init
            value_name = init.name if isinstance(init, A.Name) else \
                str(init.value) if isinstance(init, A.Literal) and init.kind == "enum" else None
            if isinstance(t, EnumType) and value_name is not None and \
                    value_name.upper() in t.values:
                t.default = t.values[value_name.upper()][1]
            elif isinstance(t, EnumType):
                self.d.error(init.pos, "E0300", f"the default of {t.name} must be one of its "
                             "values")
            elif isinstance(t, ArrayType | StructType):
                self.check_init(init, t)
                t.default = init
            else:
                self.d.error(init.pos, "E0105", "unsupported construct: a default value on "
                             "an alias of an elementary type (give the variables initial "
                             "values instead)")
        return t

    def type_from_ref(self, ref: A.TypeRef, seen: set[str] | None = None,
                      name: str = "") -> Type:
        seen = seen if seen is not None else set()
        if isinstance(ref, A.NamedTypeRef):
            key = ref.name.upper()
            if key in ELEMENTARY:
                return ELEMENTARY[key]
            if key in self.types:
                return self.types[key]
            if key in self.type_decls:
                return self.named_type(self.type_decls[key], seen)
            if key.startswith("WSTRING"):
                self.d.error(ref.pos, "E0120", "WSTRING: OpenPLC v3's build fails on it (its "
                             "MatIEC stops with an internal error); use STRING")
                return ERROR_T
            if key.startswith("STRING"):
                self.d.error(ref.pos, "E0120", f"{ref.name}: OpenPLC v3 builds only plain "
                             "STRING (126 bytes); it fails on STRING[n] and STRING(n)")
                return ELEMENTARY["STRING"]
            self.d.error(ref.pos, "E0200", f"unknown type '{ref.name}'")
            return ERROR_T
        if isinstance(ref, A.ArrayTypeRef):
            dims: list[tuple[int, int]] = []
            for lo_e, hi_e in ref.ranges:
                lo, hi = self.literal_bound(lo_e), self.literal_bound(hi_e)
                if lo is None or hi is None:
                    return ERROR_T
                if hi < lo:
                    self.d.error(lo_e.pos, "E0500", f"empty array range {lo}..{hi}")
                    return ERROR_T
                dims.append((lo, hi))
            if isinstance(ref.element, A.ArrayTypeRef):
                self.d.error(ref.element.pos, "E0501", "ARRAY OF ARRAY is rejected by MatIEC")
                return ERROR_T
            elem = self.type_from_ref(ref.element, seen)
            if isinstance(elem, ArrayType):
                self.d.error(ref.element.pos, "E0501", "ARRAY OF an array type is rejected by "
                             "MatIEC")
                return ERROR_T
            if isinstance(elem, PouType):
                self.d.error(ref.element.pos, "E0502", f"ARRAY OF {elem.name}: arrays of FB "
                             "instances are rejected by MatIEC")
                return ERROR_T
            return ArrayType(dims, elem, name)
        if isinstance(ref, A.StructTypeRef):
            st = StructType(name or "<struct>")
            self.types.setdefault(name.upper(), st) if name else None
            for f in ref.fields:
                if f.name.upper() in st.fields:
                    self.d.error(f.pos, "E0201", f"duplicate field '{f.name}'")
                    continue
                ft = self.type_from_ref(f.type, seen)
                if isinstance(ft, PouType):
                    self.d.error(f.pos, "E0504", f"field '{f.name}' is an instance of "
                                 f"{ft.kind} {ft.name}: MatIEC accepts only "
                                 "data types in a STRUCT")
                    ft = ERROR_T
                st.fields[f.name.upper()] = (f.name, ft)
                if f.init is not None:
                    st.inits[f.name.upper()] = f.init
                    self.check_init(f.init, ft)
            return st
        if isinstance(ref, A.EnumTypeRef):
            et = EnumType(name or "<enum>")
            nxt = 0
            for v in ref.values:
                if v.value is not None:
                    self.d.error(v.pos, "E0105", f"explicit enumeration value '{v.name} := ...': "
                                 "MatIEC rejects it; list the values without numbers")
                    c = self.literal_bound(v.value)
                    nxt = c if c is not None else nxt
                et.values[v.name.upper()] = (v.name, nxt)
                self.enum_values.setdefault(v.name.upper(), []).append((et, nxt))
                nxt += 1
            return et
        if isinstance(ref, A.SubrangeTypeRef):
            base = ELEMENTARY.get(ref.base.upper())
            if base is None or not base.is_int:
                self.d.error(ref.pos, "E0300", "a subrange needs an integer base type")
                return ERROR_T
            return base
        self.d.error(ref.pos, "E0105", "unsupported construct: type")
        return ERROR_T

    def literal_bound(self, e: A.Expr) -> int | None:
        if isinstance(e, A.Literal) and e.kind == "int" and e.type_prefix is None:
            return int(e.value)
        if isinstance(e, A.Unary) and e.op == "-" and isinstance(e.operand, A.Literal) and \
                e.operand.kind == "int":
            return -int(e.operand.value)
        if isinstance(e, A.Name) and e.name.upper() in self.global_consts:
            return self.global_consts[e.name.upper()]
        self.d.error(e.pos, "E0500", "array bounds and enum values must be integer literals "
                     "or CONFIGURATION constants (MatIEC rejects POU constants and "
                     "expressions here)")
        return None

    def declare_pou_vars(self, p: PouSym) -> None:
        assert p.node is not None
        node = p.node
        if node.kind == "FUNCTION":
            if node.return_type is None:
                self.d.error(node.pos, "E0400", f"FUNCTION {node.name} needs a return type")
                p.return_type = ERROR_T
            else:
                if isinstance(node.return_type, A.ArrayTypeRef):
                    self.d.error(node.return_type.pos, "E0406", "a FUNCTION cannot return an "
                                 "anonymous ARRAY type")
                p.return_type = self.type_from_ref(node.return_type)
        for blk in node.blocks:
            if blk.kind == A.VAR_GLOBAL:
                self.d.error(blk.pos, "E0206", "VAR_GLOBAL inside a POU")
                continue
            if blk.kind == A.VAR_EXTERNAL and node.kind == "FUNCTION":
                self.d.error(blk.pos, "E0207", "VAR_EXTERNAL inside a FUNCTION is rejected by "
                             "MatIEC")
            self.check_block_mix(blk)
            for decl in blk.decls:
                key = decl.name.upper()
                if key in p.vars or (node.kind == "FUNCTION" and key == p.key):
                    self.d.error(decl.pos, "E0201", f"'{decl.name}' is declared twice in "
                                 f"{p.name} (names are case-insensitive)")
                    continue
                t = self.type_from_ref(decl.type)
                if isinstance(t, PouType):
                    if node.kind == "FUNCTION":
                        self.d.error(decl.pos, "E0208", f"FB instance '{decl.name}' inside "
                                     f"FUNCTION {p.name}")
                    elif t.kind == "PROGRAM":
                        self.d.error(decl.pos, "E0300", "a PROGRAM cannot be instantiated in "
                                     "a POU")
                if decl.address is not None:
                    if node.kind != "PROGRAM":
                        self.d.error(decl.pos, "E0600", "located variables are allowed only in "
                                     "a PROGRAM or CONFIGURATION, never in a "
                                     f"{node.kind.replace('_', ' ')}")
                    self.check_location(decl, t)
                if blk.kind == A.VAR_IN_OUT and decl.init is not None:
                    self.d.error(decl.pos, "E0300", "a VAR_IN_OUT cannot have an initial value")
                p.vars[key] = VarSym(decl.name, t, blk.kind, blk.constant, decl.pos, decl.init,
                                     decl.address)

    def check_block_mix(self, blk: A.VarBlock) -> None:
        located = [d for d in blk.decls if d.address]
        if located and len(located) != len(blk.decls):
            self.d.error(blk.pos, "E0601", f"located and plain variables share one "
                         f"{blk.kind} block (MatIEC rejects this)")

    def check_location(self, decl: A.VarDecl, t: Type) -> None:
        addr = decl.address or ""
        if isinstance(t, ElemType) and t.kind == "string":
            self.d.error(decl.pos, "E0600", f"STRING '{decl.name}' at {addr}: no location "
                         "holds a STRING (MatIEC: bit sizes incompatible; OpenPLC's Modbus "
                         "maps no STRING); keep it unlocated")
            return
        if isinstance(t, ArrayType) or not isinstance(t, ElemType):
            self.d.error(decl.pos, "E0600", f"'{decl.name}' at {addr}: only elementary "
                         "variables can be located")
            return
        try:
            area, size, nums = split_address(addr)
        except ValueError:
            area, size, nums = "", "", []
        size_bits = {"X": 1, "W": 16, "D": 32, "L": 64, "B": 8}.get(size)
        ok_bits = t.bits if t.kind != "bool" else 1
        if size_bits is None or area not in ("I", "Q", "M") or not nums or \
                len(nums) != (2 if size == "X" else 1):
            self.d.error(decl.pos, "E0600", f"'{addr}' is not a valid location (e.g. %IX0.1, "
                         "%QW3, %MD0)")
        elif size_bits != ok_bits:
            self.d.error(decl.pos, "E0600", f"{t.name} '{decl.name}' does not fit {addr}: the "
                         f"location holds {size_bits} bits, the type {ok_bits}")
        elif nums[0] >= 1024 or (len(nums) > 1 and nums[1] > 7):
            self.d.error(decl.pos, "E0600", f"{addr} is outside OpenPLC's buffers "
                         "(index 0..1023, bit 0..7)")

    # ================================================================ configuration
    def configuration(self, c: A.Configuration) -> ConfigModel | None:
        # the names OpenPLC's upload needs (Config0, Res0) depend on the target: dialects.py
        if len(c.resources) != 1:
            self.d.error(c.pos, "E0602", "the bench and OpenPLC run exactly one RESOURCE: "
                         f"`{configuration_form()}`")
            if not c.resources:
                return None
        res = c.resources[0]
        for blk in c.globals + res.globals:
            self.check_block_mix(blk)
            for decl in blk.decls:
                key = decl.name.upper()
                if key in self.globals:
                    self.d.error(decl.pos, "E0201", f"global '{decl.name}' declared twice")
                    continue
                t = self.type_from_ref(decl.type)
                if decl.address:
                    self.check_location(decl, t)
                v = VarSym(decl.name, t, A.VAR_GLOBAL, blk.constant, decl.pos, decl.init,
                           decl.address)
                self.globals[key] = v
                if decl.init is not None:
                    self.check_init(decl.init, t)
        tasks: list[TaskModel] = []
        for td in res.tasks:
            interval = td.params.get("INTERVAL")
            prio = td.params.get("PRIORITY")
            iv = 0
            if interval is None:
                self.d.error(td.pos, "E0602", f"TASK {td.name} has no INTERVAL: the bench and "
                             f"OpenPLC run periodic tasks only; write `{task_form(td.name)}`")
            elif isinstance(interval, A.Literal) and interval.kind == "time" and \
                    int(interval.value) > 0:
                iv = int(interval.value)
            else:
                self.d.error(interval.pos, "E0602", f"INTERVAL must be a positive TIME "
                             f"literal: `{task_form(td.name)}`")
            pv = int(prio.value) if isinstance(prio, A.Literal) and prio.kind == "int" else 0
            tasks.append(TaskModel(td.name, iv, pv, td.pos))
        if not tasks:
            first = res.programs[0] if res.programs else None
            self.d.error(res.pos, "E0602", f"RESOURCE {res.name} declares no TASK: the bench "
                         "and OpenPLC run a PROGRAM instance only under a periodic TASK; write "
                         f"`{task_form()}` before "
                         + (f"`{instance_form(first.name, prog=first.type_name)}`"
                            if first is not None else "the PROGRAM instances"))
        task_names = {t.name.upper() for t in tasks}
        instances: list[InstanceModel] = []
        for pi in res.programs:
            pou = self.pous.get(pi.type_name.upper())
            if pou is None or pou.kind != "PROGRAM":
                self.d.error(pi.pos, "E0200", f"'{pi.type_name}' is not a PROGRAM")
                continue
            if pi.task is None or pi.task.upper() not in task_names:
                given = "names no TASK" if pi.task is None else \
                    f"names {pi.task}, which is not a TASK of RESOURCE {res.name}"
                task = tasks[0].name if tasks else None
                self.d.error(pi.pos, "E0602", f"program instance {pi.name} {given}: write "
                             f"`{instance_form(pi.name, task, pi.type_name)}`")
            instances.append(InstanceModel(pi.name, pi.task, pou, pi.pos))
        return ConfigModel(c.name, res.name, self.globals, tasks, instances)
