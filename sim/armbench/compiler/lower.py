"""Lower: tree-sitter syntax tree -> AST (ast.py). Needs: a ParsedFile from parse.py.

Constructs outside the supported subset are reported as E0105 and skipped, never raised.
"""

from __future__ import annotations

import re

import tree_sitter as ts

from . import ast as A
from .diagnostics import Diagnostics
from .parse import ParsedFile, pragma_has_code
from .source import SourcePos
from .strings import StringLiteralError, string_literal

_TIME_UNITS = {"D": 86_400_000_000_000, "H": 3_600_000_000_000, "M": 60_000_000_000,
               "S": 1_000_000_000, "MS": 1_000_000, "US": 1_000, "NS": 1}
_TIME_PART = re.compile(r"(\d+(?:\.\d+)?)(ms|us|ns|d|h|m|s)", re.IGNORECASE)


class _Unsupported(Exception):
    def __init__(self, node: ts.Node, what: str) -> None:
        super().__init__(what)
        self.node = node
        self.what = what


# a ';' right after another, a comment, THEN, ELSE, DO, OF, REPEAT, a CASE label's ':' or at
# a line's start: where a lone ';' can be (the syntax tree then says whether it is one)
_MAYBE_EMPTY = re.compile(rb"(?:;|\*\)|\bTHEN|\bELSE|\bDO|\bOF|\bREPEAT|:)\s*;|^\s*;",
                          re.I | re.M)


def parse_int_literal(text: str) -> int:
    t = text.replace("_", "")
    sign = 1
    if t.startswith(("-", "+")):
        sign = -1 if t[0] == "-" else 1
        t = t[1:]
    if "#" in t:
        base, digits = t.split("#", 1)
        return sign * int(digits, int(base))
    return sign * int(t)


def parse_time_literal(text: str) -> int:
    """T#1s500ms -> nanoseconds."""
    body = text.split("#", 1)[1].replace("_", "")
    sign = 1
    if body.startswith("-"):
        sign, body = -1, body[1:]
    total = 0.0
    pos = 0
    for m in _TIME_PART.finditer(body):
        if m.start() != pos:
            raise ValueError(f"bad time literal {text!r}")
        total += float(m.group(1)) * _TIME_UNITS[m.group(2).upper()]
        pos = m.end()
    if pos != len(body) or pos == 0:
        raise ValueError(f"bad time literal {text!r}")
    return sign * int(round(total))


class Lowerer:
    def __init__(self, pf: ParsedFile, diags: Diagnostics) -> None:
        self.pf = pf
        self.diags = diags

    # ------------------------------------------------------------ helpers
    def pos(self, node: ts.Node) -> SourcePos:
        return self.pf.pos(node)

    def text(self, node: ts.Node) -> str:
        return self.pf.text_of(node)

    def field(self, node: ts.Node, name: str) -> ts.Node:
        child = node.child_by_field_name(name)
        if child is None:
            raise _Unsupported(node, f"{node.type} without {name}")
        return child

    def fields(self, node: ts.Node, name: str) -> list[ts.Node]:
        return [c for c in node.children_by_field_name(name) if c.is_named and
                c.type != "comment"]

    def named(self, node: ts.Node) -> list[ts.Node]:
        return [c for c in node.named_children if c.type not in ("comment", "pragma")]

    def unsupported(self, node: ts.Node, what: str) -> None:
        self.diags.error(self.pos(node), "E0105", f"unsupported construct: {what}")

    # ------------------------------------------------------------ top level
    def lower_file(self) -> A.SourceUnit:
        root = self.pf.tree.root_node
        unit = A.SourceUnit(self.pos(root))
        for child in self.named(root):
            try:
                if child.type == "type_declaration":
                    unit.types.extend(self.type_declaration(child))
                elif child.type in ("function_declaration", "function_block_declaration",
                                    "program_declaration"):
                    unit.pous.append(self.pou(child))
                elif child.type == "configuration_declaration":
                    unit.configs.append(self.configuration(child))
                elif child.type == "global_var_declaration_block":
                    unit.stray_globals.extend(self.var_block(c, A.VAR_GLOBAL)
                                              for c in self.named(child))
                elif child.type == "var_global":
                    unit.stray_globals.append(self.var_block(child, A.VAR_GLOBAL))
                elif child.type == "ERROR":
                    continue
                else:
                    self.unsupported(child, child.type.replace("_", " "))
            except _Unsupported as exc:
                self.unsupported(exc.node, exc.what)
        return unit

    # ------------------------------------------------------------ types
    def type_declaration(self, node: ts.Node) -> list[A.TypeDecl]:
        out: list[A.TypeDecl] = []
        for td in self.named(node):
            if td.type != "type_definition":
                continue
            name = self.text(self.field(td, "name"))
            definition = self.type_ref(self.field(td, "definition"))
            init_nodes = self.fields(td, "default") or self.fields(td, "initial_value")
            init = self.init(init_nodes) if init_nodes else None
            out.append(A.TypeDecl(self.pos(td), name, definition, init))
        return out

    def type_ref(self, node: ts.Node) -> A.TypeRef:
        p = self.pos(node)
        t = node.type
        if t in ("elementary_type", "identifier", "string_type", "generic_type"):
            return A.NamedTypeRef(p, self.text(node).strip())
        if t == "array_type":
            ranges = []
            for r in self.fields(node, "range"):
                ranges.append((self.expr(self.field(r, "lower")),
                               self.expr(self.field(r, "upper"))))
            return A.ArrayTypeRef(p, ranges, self.type_ref(self.field(node, "element_type")))
        if t == "structure_type_inline":
            fields = []
            for f in self.named(node):
                if f.type != "structure_field":
                    continue
                inits = self.fields(f, "default") or self.fields(f, "initial_value")
                fields.append(A.StructField(self.pos(f), self.text(self.field(f, "name")),
                                            self.type_ref(self.field(f, "type")),
                                            self.init(inits) if inits else None))
            return A.StructTypeRef(p, fields)
        if t == "enumerated_type_inline":
            values = []
            for e in self.named(node):
                if e.type != "enumerator":
                    continue
                v = e.child_by_field_name("value")
                values.append(A.EnumValue(self.pos(e), self.text(self.field(e, "name")),
                                          self.expr(v) if v is not None else None))
            return A.EnumTypeRef(p, values)
        if t == "subrange_type":
            kids = self.named(node)
            if len(kids) != 3:
                raise _Unsupported(node, "subrange type")
            return A.SubrangeTypeRef(p, self.text(kids[0]), self.expr(kids[1]),
                                     self.expr(kids[2]))
        raise _Unsupported(node, t.replace("_", " "))

    def init(self, nodes: list[ts.Node]) -> A.Init:
        if len(nodes) == 1 and nodes[0].type == "index_expression":
            obj = nodes[0].child_by_field_name("object")
            if obj is not None and obj.is_missing:
                return self.default_array_init(nodes[0])
        if len(nodes) == 1 and nodes[0].type not in ("array_repetition",):
            n = nodes[0]
            if n.type == "structure_initializer":
                return self.struct_init(n)
            if n.type == "array_initializer":
                return self.init(self.named(n))
            return self.expr(n)
        items: list[tuple[A.Expr | None, A.Init]] = []
        for n in nodes:
            if n.type == "array_repetition":
                count = self.expr(self.field(n, "count"))
                vals = [c for c in self.named(n) if c != n.child_by_field_name("count")]
                items.append((count, self.init(vals) if vals else
                              A.Literal(self.pos(n), "int", 0, "0")))
            elif n.type == "structure_initializer":
                items.append((None, self.struct_init(n)))
            else:
                items.append((None, self.expr(n)))
        return A.ArrayInit(self.pos(nodes[0]), items)

    def default_array_init(self, node: ts.Node) -> A.ArrayInit:
        """`[a, n(b), ...]` as a TYPE/field default (see parse.is_array_default_hole)."""
        items: list[tuple[A.Expr | None, A.Init]] = []
        for i in self.fields(node, "index"):
            fn = i.child_by_field_name("function") if i.type == "call_expression" else None
            if fn is not None and fn.type == "integer_literal":
                args = i.child_by_field_name("arguments")
                vals = self.named(args) if args is not None else []
                if len(vals) != 1:
                    raise _Unsupported(i, "repetition n(v) needs exactly one value")
                items.append((self.expr(fn), self.expr(vals[0])))
            else:
                items.append((None, self.expr(i)))
        return A.ArrayInit(self.pos(node), items)

    def struct_init(self, node: ts.Node) -> A.StructInit:
        fields: list[tuple[str, A.Init]] = []
        for f in self.named(node):
            if f.type != "structure_initializer_field":
                continue
            name = self.text(self.field(f, "name"))
            vals = [c for c in self.named(f) if c != f.child_by_field_name("name")]
            fields.append((name, self.init(vals)))
        return A.StructInit(self.pos(node), fields)

    # ------------------------------------------------------------ declarations
    _BLOCK_KINDS = {"var_input": A.VAR_INPUT, "var_output": A.VAR_OUTPUT,
                    "var_in_out": A.VAR_IN_OUT, "var_temp": A.VAR_TEMP,
                    "var_external": A.VAR_EXTERNAL, "var_global": A.VAR_GLOBAL,
                    "global_var_declaration_block": A.VAR_GLOBAL, "var_block": A.VAR}

    def var_block(self, node: ts.Node, kind: str | None = None) -> A.VarBlock:
        kind = kind or self._BLOCK_KINDS[node.type]
        constant = False
        decls: list[A.VarDecl] = []
        for c in self.named(node):
            if c.type == "var_qualifier_list":
                quals = {self.text(q).upper() for q in self.named(c)}
                constant = "CONSTANT" in quals
            elif c.type == "variable_declaration":
                decls.extend(self.var_decl(c))
            elif c.type == "ERROR":
                continue
            else:
                self.unsupported(c, c.type.replace("_", " "))
        return A.VarBlock(self.pos(node), kind, constant, decls)

    def var_decl(self, node: ts.Node) -> list[A.VarDecl]:
        type_ref = self.type_ref(self.field(node, "type"))
        inits = self.fields(node, "initial_value")
        init = self.init(inits) if inits else None
        addr_node = node.child_by_field_name("address")
        addr = self.text(addr_node).upper() if addr_node is not None else None
        return [A.VarDecl(self.pos(n), self.text(n), type_ref, init, addr)
                for n in self.fields(node, "names")]

    def pou(self, node: ts.Node) -> A.Pou:
        kind = {"function_declaration": "FUNCTION",
                "function_block_declaration": "FUNCTION_BLOCK",
                "program_declaration": "PROGRAM"}[node.type]
        name = self.text(self.field(node, "name"))
        rt = node.child_by_field_name("return_type")
        if node.child_by_field_name("extends") is not None or \
                node.child_by_field_name("implements") is not None:
            raise _Unsupported(node, "EXTENDS/IMPLEMENTS (object-oriented extensions)")
        blocks = []
        for c in self.named(node):
            if c.type in self._BLOCK_KINDS:
                blocks.append(self.var_block(c))
            elif c.type in ("method_declaration", "property_declaration"):
                self.unsupported(c, "methods and properties (object-oriented extensions)")
        body = self.stmts(self.fields(node, "body"))
        end = node.end_point
        end_pos = SourcePos(self.pf.path, end.row + 1, end.column + 1)
        return A.Pou(self.pos(node), kind, name, self.type_ref(rt) if rt else None, blocks, body,
                     end_pos, self.c_pragmas(node), self.empty_statements(node))

    _COMPOUND = frozenset({"if_statement", "case_statement", "for_statement", "while_statement",
                           "repeat_statement"})

    def empty_statements(self, node: ts.Node) -> tuple[SourcePos, ...]:
        """Where the POU's body has a lone ';': not the one the grammar reads as an empty
        statement after END_IF, END_CASE, END_FOR, END_WHILE or END_REPEAT."""
        if not _MAYBE_EMPTY.search(self.pf.data, node.start_byte, node.end_byte):
            return ()
        found = []
        stack = [node]
        while stack:
            n = stack.pop()
            if n.type == "empty_statement":
                prev = n.prev_sibling
                while prev is not None and prev.type in ("comment", "pragma"):
                    prev = prev.prev_sibling
                if prev is None or prev.type not in self._COMPOUND:
                    found.append(self.pos(n))
            elif n.type not in ("comment", "pragma"):
                stack.extend(n.children)
        return tuple(sorted(found, key=lambda p: (p.line, p.col)))

    def c_pragmas(self, node: ts.Node) -> tuple[SourcePos, ...]:
        """Where the POU's body has {pragmas} with C in them (rules.py says which fail)."""
        if b"{" not in self.pf.data[node.start_byte:node.end_byte]:
            return ()
        found = []
        stack = [node]
        while stack:
            n = stack.pop()
            if n.type == "pragma":
                if pragma_has_code(self.text(n)):
                    found.append(self.pos(n))
            elif n.type != "comment":
                stack.extend(n.children)
        return tuple(sorted(found, key=lambda p: (p.line, p.col)))

    def configuration(self, node: ts.Node) -> A.Configuration:
        name = self.text(self.field(node, "name"))
        globals_: list[A.VarBlock] = []
        resources: list[A.Resource] = []
        for c in self.named(node):
            if c.type in ("var_global", "global_var_declaration_block"):
                globals_.append(self.var_block(c, A.VAR_GLOBAL))
            elif c.type == "resource_declaration":
                resources.append(self.resource(c))
            elif c.type in ("task_declaration", "program_assignment"):
                # a configuration without RESOURCE: treat as one anonymous resource
                if not resources or resources[-1].name != "":
                    resources.append(A.Resource(self.pos(c), "", [], [], []))
                self._resource_item(c, resources[-1])
            elif c.type != "identifier":
                self.unsupported(c, c.type.replace("_", " "))
        return A.Configuration(self.pos(node), name, globals_, resources)

    def resource(self, node: ts.Node) -> A.Resource:
        res = A.Resource(self.pos(node), self.text(self.field(node, "name")), [], [], [])
        for c in self.named(node):
            if c in (node.child_by_field_name("name"), node.child_by_field_name("cpu_type")):
                continue
            self._resource_item(c, res)
        return res

    def _resource_item(self, c: ts.Node, res: A.Resource) -> None:
        if c.type in ("var_global", "global_var_declaration_block"):
            res.globals.append(self.var_block(c, A.VAR_GLOBAL))
        elif c.type == "task_declaration":
            params = {}
            for p in self.named(c):
                if p.type == "task_parameter":
                    params[self.text(self.field(p, "name")).upper()] = \
                        self.expr(self.field(p, "value"))
            res.tasks.append(A.TaskDecl(self.pos(c), self.text(self.field(c, "name")), params))
        elif c.type == "program_assignment":
            task = c.child_by_field_name("task")
            res.programs.append(A.ProgramInst(
                self.pos(c), self.text(self.field(c, "name")),
                self.text(task) if task is not None else None,
                self.text(self.field(c, "program_type"))))
        elif c.type not in ("identifier", "ERROR"):
            self.unsupported(c, c.type.replace("_", " "))

    # ------------------------------------------------------------ statements
    def stmts(self, nodes: list[ts.Node]) -> list[A.Stmt]:
        out: list[A.Stmt] = []
        for n in nodes:
            if n.type in ("comment", "pragma", "ERROR"):
                continue
            try:
                s = self.stmt(n)
            except _Unsupported as exc:
                self.unsupported(exc.node, exc.what)
                continue
            if s is not None:
                out.append(s)
        return out

    def stmt(self, n: ts.Node) -> A.Stmt | None:
        p = self.pos(n)
        t = n.type
        if t == "assignment_statement":
            return A.Assign(p, self.expr(self.field(n, "left")), self.expr(self.field(n, "right")))
        if t == "invocation_statement":
            call = self.expr(self.named(n)[0])
            if not isinstance(call, A.Call):
                raise _Unsupported(n, "statement")
            return A.CallStmt(p, call)
        if t == "if_statement":
            branches = [(self.expr(self.field(n, "condition")),
                         self.stmts(self.fields(n, "consequence")))]
            orelse = None
            for c in self.named(n):
                if c.type == "elsif_clause":
                    branches.append((self.expr(self.field(c, "condition")),
                                     self.stmts(self.fields(c, "body"))))
                elif c.type == "else_clause":
                    orelse = self.stmts(self.fields(c, "body"))
            return A.If(p, branches, orelse)
        if t == "case_statement":
            clauses = []
            orelse = None
            for c in self.named(n):
                if c.type == "case_clause":
                    labels = []
                    for v in self.named(c):
                        if v.type != "case_value":
                            continue
                        inner = self.named(v)[0]
                        if inner.type == "subrange":
                            labels.append(A.CaseLabel(self.pos(v),
                                                      self.expr(self.field(inner, "lower")),
                                                      self.expr(self.field(inner, "upper"))))
                        else:
                            labels.append(A.CaseLabel(self.pos(v), self.expr(inner), None))
                    clauses.append(A.CaseClause(self.pos(c), labels,
                                                self.stmts(self.fields(c, "body"))))
                elif c.type == "else_clause":
                    orelse = self.stmts(self.fields(c, "body"))
            return A.Case(p, self.expr(self.field(n, "subject")), clauses, orelse)
        if t == "for_statement":
            ctrl = self.expr(self.field(n, "control"))
            if not isinstance(ctrl, A.Name):
                raise _Unsupported(n, "FOR control variable must be a plain variable")
            step = n.child_by_field_name("step")
            return A.For(p, ctrl, self.expr(self.field(n, "start")),
                         self.expr(self.field(n, "end")),
                         self.expr(step) if step is not None else None,
                         self.stmts(self.fields(n, "body")))
        if t == "while_statement":
            return A.While(p, self.expr(self.field(n, "condition")),
                           self.stmts(self.fields(n, "body")))
        if t == "repeat_statement":
            return A.Repeat(p, self.stmts(self.fields(n, "body")),
                            self.expr(self.field(n, "condition")))
        if t == "exit_statement":
            return A.Exit(p)
        if t == "continue_statement":
            return A.Continue(p)
        if t == "return_statement":
            return A.Return(p)
        if t == "empty_statement":
            return None
        raise _Unsupported(n, t.replace("_", " "))

    # ------------------------------------------------------------ expressions
    def op_token(self, n: ts.Node) -> str:
        op = n.child_by_field_name("operator")
        if op is not None:
            return self.text(op).upper()
        for c in n.children:
            if not c.is_named:
                return self.text(c).upper()
        raise _Unsupported(n, "operator")

    def expr(self, n: ts.Node) -> A.Expr:
        p = self.pos(n)
        t = n.type
        if t == "identifier":
            if any(n.start_byte < off < n.end_byte for off in self.pf.enum_hash_offsets):
                off = next(o for o in self.pf.enum_hash_offsets if n.start_byte < o < n.end_byte)
                type_name = self.pf.data[n.start_byte:off].decode()
                value = self.pf.data[off + 1:n.end_byte].decode()
                return A.Literal(p, "enum", value, self.text(n), type_name)
            return A.Name(p, self.text(n))
        if t == "parenthesized_expression":
            return self.expr(self.named(n)[0])
        if t == "binary_expression":
            return self.binary_chain(n)
        if t == "unary_expression":
            operand = self.field(n, "operand")
            return A.Unary(p, self.op_token(n), self.expr(operand),
                           operand.type == "parenthesized_expression")
        if t == "member_access_expression":
            return A.Member(p, self.expr(self.field(n, "object")),
                            self.text(self.field(n, "member")))
        if t == "index_expression":
            return A.Index(p, self.expr(self.field(n, "object")),
                           [self.expr(i) for i in self.fields(n, "index")])
        if t == "call_expression":
            args_node = n.child_by_field_name("arguments")
            args: list[A.Arg] = []
            if args_node is not None:
                for a in self.named(args_node):
                    if a.type == "named_argument":
                        is_out = any(not c.is_named and self.text(c) == "=>" for c in a.children)
                        args.append(A.Arg(self.pos(a), self.text(self.field(a, "name")),
                                          self.expr(self.field(a, "value")), is_out))
                    else:
                        args.append(A.Arg(self.pos(a), None, self.expr(a)))
            return A.Call(p, self.expr(self.field(n, "function")), args)
        if t in ("integer_literal", "real_literal", "boolean_literal", "time_literal",
                 "string_literal"):
            return self.literal(n, None)
        if t == "typed_literal":
            prefix = self.text(self.field(n, "type")).upper()
            return self.literal(self.field(n, "value"), prefix, n)
        raise _Unsupported(n, t.replace("_", " "))

    def binary_chain(self, n: ts.Node) -> A.Binary:
        """`a + b + c + ...` nests to the left as deep as it is long: walk it in a loop."""
        spine = [n]
        left = self.field(n, "left")
        while left.type == "binary_expression":
            spine.append(left)
            left = self.field(left, "left")
        acc = self.expr(left)
        for b in reversed(spine):
            op = self.op_token(b)
            acc = A.Binary(self.pos(b), "AND" if op == "&" else op, acc,
                           self.expr(self.field(b, "right")))
        assert isinstance(acc, A.Binary)
        return acc

    def literal(self, n: ts.Node, prefix: str | None, whole: ts.Node | None = None) -> A.Literal:
        text = self.text(whole if whole is not None else n)
        raw = self.text(n)
        p = self.pos(whole if whole is not None else n)
        try:
            if n.type == "integer_literal":
                return A.Literal(p, "int", parse_int_literal(raw), text, prefix)
            if n.type == "real_literal":
                return A.Literal(p, "real", float(raw.replace("_", "")), text, prefix)
            if n.type == "boolean_literal":
                return A.Literal(p, "bool", raw.upper() == "TRUE", text, prefix)
            if n.type == "time_literal":
                return A.Literal(p, "time", parse_time_literal(raw), text, prefix)
            if n.type == "string_literal":
                if prefix is not None:
                    raise StringLiteralError(f"{prefix}#'...': MatIEC's grammar has no typed "
                                             "string literal; write the '...' alone")
                return A.Literal(p, "string", string_literal(raw).data.decode("latin-1"),
                                 text, prefix)
        except StringLiteralError as exc:
            self.diags.error(p, "E0120", str(exc))
            return A.Literal(p, "string", "", text, prefix)
        except ValueError as exc:
            raise _Unsupported(n, f"malformed literal {raw!r}") from exc
        raise _Unsupported(n, f"literal {raw!r}")


def lower(pf: ParsedFile, diags: Diagnostics) -> A.SourceUnit:
    """The file's AST. Only for a file the nesting guard passed (frontend.check_syntax): the
    lowering recurses as deep as the file nests."""
    if not pf.guarded:
        raise ValueError(f"{pf.path}: lowered before the nesting guard passed it "
                         "(call frontend.check_syntax first)")
    return Lowerer(pf, diags).lower_file()
