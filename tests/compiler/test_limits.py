"""Limits of the checker: deep nesting, long chains, recursive containment.

Each audit finding has a test here: inputs that crashed `armbench check` with RecursionError
(a 329-term sum, 492 nested IFs, 984 nested parentheses, a chain of 990 calls) and types or
FBs that contain themselves (passed check, then failed in gcc). Results of long chains are
compared with closed forms or with numpy's float32 arithmetic, step by step.
"""

from __future__ import annotations

import re
from collections.abc import Callable
from pathlib import Path
from typing import TypeVar

import numpy as np
import pytest
from st_deep import CONFIG, LIMITS_TARGET, MATIEC_MAX, matiec_view, program

from armbench.compiler import ast as A
from armbench.compiler import check_files, compile_files
from armbench.compiler.driver import analyse
from armbench.compiler.emit_c import SPILL_EVERY, emit
from armbench.compiler.limits import NESTING_LIMIT

T = TypeVar("T")
# frames a caller may already use when it calls the compiler (pytest itself adds ~40 more)
CALLER_FRAMES = 250


def deep_caller(frames: int, f: Callable[[], T]) -> T:
    """Call f with `frames` more Python frames on the stack, as a deeply nested caller would."""
    return f() if frames == 0 else deep_caller(frames - 1, f)


def write(tmp_path: Path, name: str, text: str) -> Path:
    path = tmp_path / f"{name}.st"
    path.write_text(text, encoding="utf-8")
    return path


def codes(path: Path) -> list[str]:
    return [d.code for d in matiec_view(check_files([path], target=LIMITS_TARGET))]


# ------------------------------------------------------------------ the audit's inputs
@pytest.mark.parametrize(("construct", "n"), [("if", 492), ("paren", 984), ("calls", 990),
                                              ("std_calls", 990), ("not", 3000)])
def test_deep_nesting_is_one_diagnostic(tmp_path: Path, construct: str, n: int) -> None:
    ds = check_files([write(tmp_path, construct, program(construct, n))])
    assert [d.code for d in ds] == ["E0108"], [d.render() for d in ds]
    assert re.fullmatch(rf"{construct}\.st:\d+:\d+: error\[E0108\]: nesting too deep for "
                        r"MatIEC \(\d+ nested .*", ds[0].render().rsplit("/", 1)[-1])


@pytest.mark.parametrize(("construct", "literal"), [("paren_time", "T#1s"),
                                                     ("paren_neg_time", "T#-1s")])
def test_e0108_at_a_literal_too_long_for_its_place(tmp_path: Path, construct: str,
                                                   literal: str) -> None:
    """One parenthesis more than MATIEC_MAX still fits MatIEC's stack (a name would), the
    literal inside it does not: the diagnostic is at the literal."""
    src = program(construct, MATIEC_MAX[construct] + 1)
    ds = check_files([write(tmp_path, construct, src)])
    line = src[:src.index(literal)].count("\n") + 1
    col = src.index(literal) - src.rindex("\n", 0, src.index(literal))
    assert [(d.code, d.pos.line, d.pos.col) for d in ds] == [("E0108", line, col)], \
        [d.render() for d in ds]


def test_e0108_points_at_the_first_level_too_many(tmp_path: Path) -> None:
    # program(): line 1 is empty, PROGRAM .. END_VAR take lines 2..8, the first IF is line 9
    ds = check_files([write(tmp_path, "ifs", program("if", MATIEC_MAX["if"] + 5))])
    assert [(d.pos.line, d.pos.col) for d in ds] == [(9 + MATIEC_MAX["if"], 1)]
    ds = check_files([write(tmp_path, "parens", program("paren", MATIEC_MAX["paren"] + 5))])
    line = program("paren", 1).splitlines().index("x := (x);") + 1
    assert [(d.pos.line, d.pos.col) for d in ds] == [(line, len("x := ") + MATIEC_MAX["paren"]
                                                      + 1)]


@pytest.mark.parametrize("n", [329, 5000])
def test_long_integer_sum_compiles_and_computes(tmp_path: Path, n: int) -> None:
    src = (f"FUNCTION SumN : DINT\nVAR_INPUT\n  a : DINT;\nEND_VAR\n"
           f"  SumN := {' + '.join(['a'] * n)};\nEND_FUNCTION\n"
           f"FUNCTION Countdown : DINT\nVAR_INPUT\n  a : DINT;\nEND_VAR\n"
           f"  Countdown := a{' - 1' * n};\nEND_FUNCTION\n")
    m = compile_files([write(tmp_path, "sum", src)])
    assert m.call("SumN", 3) == 3 * n
    assert m.call("SumN", -7) == -7 * n
    assert m.call("Countdown", 10_000) == 10_000 - n
    # DINT wraps around: 2**30 * n reduced to 32 bits, as two's complement
    wrapped = (2**30 * n + 2**31) % 2**32 - 2**31
    assert m.call("SumN", 2**30) == wrapped


def test_long_real_sum_rounds_like_float32_left_to_right(tmp_path: Path) -> None:
    n = 3000
    src = (f"FUNCTION SumR : REAL\nVAR_INPUT\n  a : REAL;\nEND_VAR\n"
           f"  SumR := {' + '.join(['a'] * n)};\nEND_FUNCTION\n")
    m = compile_files([write(tmp_path, "rsum", src)])
    a = np.float32(0.1)
    ref = a
    for _ in range(n - 1):
        ref = np.float32(ref + a)
    got = m.call("SumR", 0.1)
    assert np.float32(got) == ref
    assert abs(float(ref) - 300.0) > 1e-4  # rounding differs from the exact sum: a real check


def _max_paren_depth(code: str) -> int:
    depth = best = 0
    for ch in code:
        if ch == "(":
            depth += 1
            best = max(best, depth)
        elif ch == ")":
            depth -= 1
    return best


def test_generated_c_nests_boundedly_for_any_chain_length(tmp_path: Path) -> None:
    """gcc's parser recurses too (it crashes near 20,000 nested parentheses): the C of a long
    chain must not nest deeper with its length."""
    depths = []
    for n in (2_000, 20_000):
        prog, diags = analyse([write(tmp_path, f"chain{n}", program("sum", n))])
        assert prog is not None, diags.render()
        depths.append(_max_paren_depth(emit(prog).code))
    assert depths[0] == depths[1] < 4 * SPILL_EVERY


def test_20000_term_sum_builds_and_runs(tmp_path: Path) -> None:
    n = 20_000
    src = program("sum", n).replace("x := x + x", "x := 1;\nx := x + x", 1)
    m = compile_files([write(tmp_path, "big", src)])
    inst = m.new_program("Main")
    inst()
    assert inst.get("x") == n


# ------------------------------------------------------------------ at the limit
AT_LIMIT = [*sorted(MATIEC_MAX.items()),
            ("struct_fields", NESTING_LIMIT - 1), ("fb_chain", NESTING_LIMIT - 1)]


@pytest.mark.parametrize(("construct", "n"), AT_LIMIT)
def test_nesting_at_the_limit_passes_from_a_deep_caller(tmp_path: Path, construct: str,
                                                        n: int) -> None:
    """Exactly at the limit every pass works, with CALLER_FRAMES already on the stack; one
    more level is E0108 (or E0211 for types)."""
    ok = write(tmp_path, "ok", program(construct, n))

    def run() -> str:
        prog, diags = analyse([ok], target=LIMITS_TARGET)
        assert prog is not None, diags.render()
        return emit(prog).code

    assert "PRG_MAIN" in deep_caller(CALLER_FRAMES, run)
    deeper = write(tmp_path, "deeper", program(construct, n + 1))
    assert set(codes(deeper)) & {"E0108", "E0211"}


def test_build_and_read_at_the_limit(tmp_path: Path) -> None:
    calls = write(tmp_path, "calls", program("calls", MATIEC_MAX["calls"]))
    fbs = write(tmp_path, "fbs", program("fb_chain", NESTING_LIMIT - 1))

    def run() -> tuple[int, int]:
        main = compile_files([calls]).new_program("Main")
        main()  # x starts at 0 and goes through Inc() MATIEC_MAX["calls"] times
        fb = compile_files([fbs]).new_program("Main")
        fb()
        depth, v = 0, fb.get("f")
        while isinstance(v, dict) and "inner" in v:  # the FFI walks the nested instances
            v, depth = v["inner"], depth + 1
        return int(main.get("x")), depth

    assert deep_caller(CALLER_FRAMES, run) == (MATIEC_MAX["calls"], NESTING_LIMIT - 1)


# ------------------------------------------------------------------ containment
def _st(decls: str, main_vars: str = "x : DINT;", body: str = "x := 1;") -> str:
    return f"{decls}\nPROGRAM Main\nVAR\n  {main_vars}\nEND_VAR\n  {body}\nEND_PROGRAM\n{CONFIG}"


CYCLES = {
    "struct_self": ("TYPE\n  Node : STRUCT\n    next : Node;\n  END_STRUCT;\nEND_TYPE\n",
                    ["STRUCT Node contains itself through Node.next"]),
    "struct_mutual": ("TYPE\n  A1 : STRUCT\n    b : B1;\n  END_STRUCT;\n"
                      "  B1 : STRUCT\n    a : A1;\n  END_STRUCT;\nEND_TYPE\n",
                      ["STRUCT A1 contains itself through A1.b -> B1.a"]),
    "struct_array": ("TYPE\n  Tree : STRUCT\n    kids : ARRAY[0..3] OF Tree;\n  END_STRUCT;\n"
                     "END_TYPE\n", ["STRUCT Tree contains itself through Tree.kids"]),
    "array_type": ("TYPE\n  Cell : STRUCT\n    row : Row;\n  END_STRUCT;\n"
                   "  Row : ARRAY[0..3] OF Cell;\nEND_TYPE\n",
                   ["STRUCT Cell contains itself through Cell.row -> Row"]),
    "alias": ("TYPE\n  T1 : T2;\n  T2 : T1;\nEND_TYPE\n",
              ["TYPE T1 contains itself through T1 -> T2"]),
    "nested_inline": ("TYPE\n  Outer2 : STRUCT\n    inner : STRUCT\n      back : Outer2;\n"
                      "    END_STRUCT;\n  END_STRUCT;\nEND_TYPE\n",
                      ["STRUCT Outer2 contains itself through Outer2.inner.back"]),
    "fb_self": ("FUNCTION_BLOCK Loop1\nVAR\n  me : Loop1;\n  n : DINT;\nEND_VAR\n  n := 1;\n"
                "END_FUNCTION_BLOCK\n",
                ["FUNCTION_BLOCK Loop1 contains itself through Loop1.me"]),
    # (each with a statement: MatIEC refuses an FB with none, E0100)
    "fb_three": ("FUNCTION_BLOCK Fa\nVAR\n  b : Fb;\n  n : DINT;\nEND_VAR\n  n := 1;\n"
                 "END_FUNCTION_BLOCK\n"
                 "FUNCTION_BLOCK Fb\nVAR\n  c : Fc;\n  n : DINT;\nEND_VAR\n  n := 1;\n"
                 "END_FUNCTION_BLOCK\n"
                 "FUNCTION_BLOCK Fc\nVAR_OUTPUT\n  a : Fa;\n  n : DINT;\nEND_VAR\n  n := 1;\n"
                 "END_FUNCTION_BLOCK\n",
                 ["FUNCTION_BLOCK Fa contains itself through Fa.b -> Fb.c -> Fc.a"]),
    # two cycles through one group of types: one report, naming the shortest from the first
    "two_cycles": ("TYPE\n  Pa : STRUCT\n    q : Qa;\n  END_STRUCT;\n"
                   "  Qa : STRUCT\n    p : Pa;\n    q : Qa;\n  END_STRUCT;\nEND_TYPE\n",
                   ["STRUCT Pa contains itself through Pa.q -> Qa.p"]),
}


@pytest.mark.parametrize("name", sorted(CYCLES))
def test_containment_cycle_reported_once(tmp_path: Path, name: str) -> None:
    decls, expected = CYCLES[name]
    ds = check_files([write(tmp_path, name, _st(decls))])
    msgs = [d.message for d in ds if d.code == "E0210"]
    assert len(msgs) == len(expected), [d.render() for d in ds]
    for msg, want in zip(msgs, expected, strict=True):
        assert msg.startswith(want + ":"), msg
    assert all(d.code == "E0210" for d in ds), [d.render() for d in ds]


def test_containment_cycle_position_is_the_declaration(tmp_path: Path) -> None:
    decls = CYCLES["struct_mutual"][0]
    ds = check_files([write(tmp_path, "pos", _st(decls))])
    assert [(d.pos.line, d.pos.col) for d in ds] == [(2, 3)]  # `A1 : STRUCT`


def test_legal_containment_is_not_a_cycle(tmp_path: Path) -> None:
    """A diamond (two fields of one type), an in-out of the FB's own type and a type used by
    several FBs are not cycles."""
    decls = ("TYPE\n  Leaf : STRUCT\n    v : DINT;\n  END_STRUCT;\n"
             "  Pair : STRUCT\n    l : Leaf;\n    rt : Leaf;\n  END_STRUCT;\nEND_TYPE\n"
             "FUNCTION_BLOCK Holder\nVAR\n  p : Pair;\n  q : ARRAY[0..1] OF Pair;\n"
             "  n : DINT;\nEND_VAR\n  n := 1;\nEND_FUNCTION_BLOCK\n"
             "FUNCTION_BLOCK User\nVAR\n  h1 : Holder;\n  h2 : Holder;\n  n : DINT;\n"
             "END_VAR\n  n := 1;\nEND_FUNCTION_BLOCK\n")
    path = write(tmp_path, "legal", _st(decls, "x : DINT;\n  u : User;", "u();\n  x := 1;"))
    assert codes(path) == []
    m = compile_files([path])
    inst = m.new_program("Main")
    inst()
    assert inst.get("u")["h2"]["q"][1]["rt"]["v"] == 0


def test_fb_instance_in_struct_is_rejected(tmp_path: Path) -> None:
    decls = ("FUNCTION_BLOCK Lag\nVAR_INPUT\n  x : REAL;\nEND_VAR\n  x := x;\n"
             "END_FUNCTION_BLOCK\n"
             "TYPE\n  Chan : STRUCT\n    f : Lag;\n  END_STRUCT;\nEND_TYPE\n")
    ds = check_files([write(tmp_path, "fbs", _st(decls))])
    assert [(d.code, d.pos.line) for d in ds] == [("E0504", 9)]  # the field


def test_types_nested_too_deep(tmp_path: Path) -> None:
    """PROGRAM Main holds top : Lvl0, Lvl0 holds Lvl1, ...: n STRUCT levels plus Main's own."""
    def types_only(n: int) -> Path:
        text = re.sub(r"x := top(\.f)+\.v;", "x := 1;", program("struct_fields", n))
        return write(tmp_path, f"types{n}", text)

    assert codes(types_only(NESTING_LIMIT - 1)) == []
    ds = check_files([types_only(NESTING_LIMIT)])
    assert [d.code for d in ds] == ["E0211"]
    assert ds[0].message.startswith(f"PROGRAM Main nests types or instances {NESTING_LIMIT + 1} "
                                    "levels deep")


def test_in_out_of_own_and_later_fb_type_builds(tmp_path: Path) -> None:
    """A VAR_IN_OUT is a reference, not containment: an FB may take its own type, or a type
    that takes it back, as in-out (gcc used to reject the C: the pointer named a struct type
    not declared yet)."""
    decls = ("FUNCTION_BLOCK Linked\nVAR_IN_OUT\n  peer : Linked;\nEND_VAR\n"
             "VAR_OUTPUT\n  n : DINT;\nEND_VAR\n  n := peer.n + 10;\nEND_FUNCTION_BLOCK\n"
             "FUNCTION_BLOCK Ping\nVAR_IN_OUT\n  other : Pong;\nEND_VAR\n"
             "VAR_OUTPUT\n  n : DINT;\nEND_VAR\n  n := other.n + 1;\nEND_FUNCTION_BLOCK\n"
             "FUNCTION_BLOCK Pong\nVAR_IN_OUT\n  other : Ping;\nEND_VAR\n"
             "VAR_OUTPUT\n  n : DINT;\nEND_VAR\n  n := other.n + 100;\nEND_FUNCTION_BLOCK\n")
    main_vars = "a : Linked;\n  b : Linked;\n  pi : Ping;\n  po : Pong;"
    body = "b(peer := a);\n  a(peer := b);\n  po(other := pi);\n  pi(other := po);"
    path = write(tmp_path, "inout", _st(decls, main_vars, body))
    assert codes(path) == []
    inst = compile_files([path]).new_program("Main")
    inst()
    assert (inst.get("b")["n"], inst.get("a")["n"]) == (10, 20)
    assert (inst.get("po")["n"], inst.get("pi")["n"]) == (100, 101)


@pytest.mark.parametrize("text", ["1 + 2 * 3 - (4 - 5) * 6", "(1 + 2) * 3 MOD (4 + 5)",
                                  " + ".join(["1"] * 3000), " - ".join(["7"] * 3000)])
def test_export_renders_long_and_nested_initial_values(tmp_path: Path, text: str) -> None:
    """`armbench export` writes initial values back as ST text; a 3,000-term one used to
    raise RecursionError there."""
    from armbench.export.sttext import expr_text

    prog, diags = analyse([write(tmp_path, "init", program("const_sum", 1).replace(
        "k : DINT := 1;", f"k : DINT := {text};"))])
    assert prog is not None, diags.render()
    main = next(p for u in prog.units for p in u.pous if p.name == "Main")
    init = next(d.init for b in main.blocks for d in b.decls if d.name == "k")
    assert isinstance(init, A.Expr)
    assert expr_text(init) == text


def test_array_with_thousands_of_dimensions(tmp_path: Path) -> None:
    """Dimensions are a flat list in the source; the C offset, reading and writing through the
    FFI must not nest per dimension."""
    n = 3000
    one = ", ".join(["0"] * n)
    decls = f"  m : ARRAY[{', '.join(['0..0'] * n)}] OF DINT;\n  k : DINT;\n"
    body = f"k := m[{', '.join(['x'] * n)}] + 1;\nm[{one}] := k;"
    path = write(tmp_path, "dims", program("sum", 1).replace("x := x;", body).replace(
        "END_VAR", decls + "END_VAR", 1))
    assert codes(path) == []
    inst = compile_files([path]).new_program("Main")
    nested: list[object] | int = 41
    for _ in range(n):
        nested = [nested]
    inst.set(m=nested)
    inst()
    v = inst.get("m")
    for _ in range(n):
        assert isinstance(v, list) and len(v) == 1
        v = v[0]
    assert (v, inst.get("k")) == (42, 42)


def test_multi_dimensional_offsets_match_numpy(tmp_path: Path) -> None:
    body = ("FOR i := -1 TO 1 DO FOR j := 2 TO 5 DO FOR k2 := 0 TO 2 DO\n"
            "  m[i, j, k2] := INT_TO_DINT(i * 100 + j * 10 + k2);\n"
            "END_FOR; END_FOR; END_FOR;\nx := m[1, 3, 2];")
    decls = "  m : ARRAY[-1..1, 2..5, 0..2] OF DINT;\n  j : INT;\n  k2 : INT;\n"
    path = write(tmp_path, "md", program("sum", 1).replace("x := x;", body).replace(
        "END_VAR", decls + "END_VAR", 1))
    inst = compile_files([path]).new_program("Main")
    inst()
    i, j, k = np.meshgrid(np.arange(-1, 2), np.arange(2, 6), np.arange(0, 3), indexing="ij")
    assert np.array_equal(np.array(inst.get("m")), i * 100 + j * 10 + k)
    assert inst.get("x") == 132


@pytest.mark.parametrize("n", [3, 20_000])
def test_long_constant_initial_value_builds(tmp_path: Path, n: int) -> None:
    """A VAR CONSTANT shares one C constant at file scope, where its initialiser cannot be
    split into temporaries: a 20,000-term one crashed gcc; it is now set per instance."""
    src = program("sum", 1).replace("VAR\n", "VAR CONSTANT\n  k : DINT := " +
                                    " + ".join(["1"] * n) + ";\nEND_VAR\nVAR\n", 1)
    path = write(tmp_path, "k", src.replace("x := x;", "x := k;"))
    prog, diags = analyse([path])
    assert prog is not None, diags.render()
    assert ("K_PRG_MAIN_K" in emit(prog).code) == (n < SPILL_EVERY)  # still shared when short
    inst = compile_files([path]).new_program("Main")
    inst()
    assert inst.get("x") == n


# ------------------------------------------------------------------ against the real MatIEC
@pytest.mark.parametrize("construct", sorted(MATIEC_MAX))
def test_matiec_limit_is_the_checkers(matiec, construct: str,  # type: ignore[no-untyped-def]
                                      tmp_path: Path) -> None:
    """MATIEC_MAX is what iec2c accepts: its maximum passes there, one more level does not."""
    top = MATIEC_MAX[construct]
    at = write(tmp_path, f"{construct}_{top}", program(construct, top))
    over = write(tmp_path, f"{construct}_{top + 1}", program(construct, top + 1))
    assert codes(at) == [] and codes(over) == ["E0108"]
    accepted, _, out = matiec.verdict(at)
    assert accepted, out
    accepted, _, out = matiec.verdict(over)
    assert not accepted, out


_LATER_TYPE = {  # TYPE declarations naming a later type: MatIEC rejects each of them
    "struct_field": "A : STRUCT n : B; END_STRUCT;\n  B : STRUCT v : DINT; END_STRUCT;",
    "array_element": "A : ARRAY[0..1] OF B;\n  B : STRUCT v : DINT; END_STRUCT;",
    "field_array": "A : STRUCT n : ARRAY[0..1] OF B; END_STRUCT;\n  B : DINT;",
    "alias": "A : B;\n  B : DINT;",
    "field_enum": "A : STRUCT n : B; END_STRUCT;\n  B : (Red, Green);",
    "field_subrange": "A : STRUCT n : B; END_STRUCT;\n  B : INT (0..10);",
}
_LATER_POU = {  # POUs using later types, FBs and FUNCTIONs: MatIEC accepts each of them
    "var_of_later_struct": ("PROGRAM", "TYPE\n  Rec : STRUCT v : DINT; END_STRUCT;\nEND_TYPE\n"),
    "fb_of_later_fb": ("FUNCTION_BLOCK Cnt\nVAR_OUTPUT\n  v : DINT;\nEND_VAR\n  v := v + 1;\n"
                       "END_FUNCTION_BLOCK\n", ""),
    "call_of_later_function": ("FUNCTION Inc : DINT\nVAR_INPUT\n  a : DINT;\nEND_VAR\n"
                               "  Inc := a + 1;\nEND_FUNCTION\n", ""),
}


@pytest.mark.parametrize("name", sorted(_LATER_TYPE))
def test_type_naming_a_later_type_is_e0212(tmp_path: Path, name: str) -> None:
    text = f"TYPE\n  {_LATER_TYPE[name]}\nEND_TYPE\n" + _st("", "x : DINT;\n  a : A;")
    ds = check_files([write(tmp_path, name, text)])
    assert [(d.code, d.pos.line) for d in ds] == [("E0212", 2)], [d.render() for d in ds]
    assert "uses B, which is declared later (line 3)" in ds[0].message


def _later_pou(name: str) -> str:
    pou, after = _LATER_POU[name]
    if name == "var_of_later_struct":
        return _st("", "x : DINT;\n  item : Rec;", "x := item.v;").replace("\nCONFIGURATION",
                                                                    after + "CONFIGURATION")
    body = "f();\n  x := f.v;" if name == "fb_of_later_fb" else "x := Inc(x);"
    decls = "x : DINT;\n  f : Cnt;" if name == "fb_of_later_fb" else "x : DINT;"
    return _st("", decls, body).replace("\nCONFIGURATION", pou + "CONFIGURATION")


@pytest.mark.parametrize("name", sorted(_LATER_POU))
def test_pou_using_later_declarations_passes(tmp_path: Path, name: str) -> None:
    assert codes(write(tmp_path, name, _later_pou(name))) == []


@pytest.mark.parametrize("name", sorted(_LATER_TYPE) + sorted(_LATER_POU))
def test_matiec_agrees_on_declaration_order(matiec, name: str,  # type: ignore[no-untyped-def]
                                            tmp_path: Path) -> None:
    if name in _LATER_TYPE:
        text = f"TYPE\n  {_LATER_TYPE[name]}\nEND_TYPE\n" + _st("", "x : DINT;\n  a : A;")
    else:
        text = _later_pou(name)
    accepted, _, out = matiec.verdict(write(tmp_path, name, text))
    assert accepted == (name in _LATER_POU), out
