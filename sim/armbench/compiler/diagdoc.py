"""Render docs/diagnostics.md from the CODES table (a test fails when the page is stale)."""

from __future__ import annotations

import sys

from .diagnostics import CODES
from .limits import DECLARATION_ROOM, MAX_PARENTHESES, NESTING_LIMIT, PARSER_STACK, STATEMENT_ROOM

HEADER = """# Diagnostics of `armbench check`

Generated from `sim/armbench/compiler/diagnostics.py` by
`python -m armbench.compiler.diagdoc > docs/diagnostics.md`; do not edit by hand.

Every diagnostic is one line, `file:line:col: error[CODE]: message` (warnings,
`warning[CODE]`, and notes, `note[N...]`, do not fail the check). `armbench check` ends with a
one-line summary. The portability rules mirror what MatIEC (the compiler inside OpenPLC) or
OpenPLC's C build rejects, as measured on the real tools (see docs/matiec-facts.md): code that
passes `armbench check` compiles there too. `--target` adds what OpenPLC v4's STruC++ refuses
or builds with other values (docs/strucpp-facts.md) and what IEC 61131-3's 3rd edition and the
CODESYS family refuse (Targets, below).

| code | what it means | what to write instead |
|---|---|---|
"""


TARGETS = """
## Targets (E0214, E0215, E0309, E0411, E0512, E0602 and STruC++'s codes)

`armbench check --target openplc|openplc-v4|codesys|all` (default `all`; in Python
`check_files(paths, target=Target.named("codesys"))`) says which compilers the code is for:
`openplc` is OpenPLC v3's MatIEC, `openplc-v4` OpenPLC v4's STruC++ (ST to C++17, built by the
v4 runtime with g++), `codesys` IEC 61131-3's 3rd edition and the CODESYS family (CODESYS V3,
TwinCAT 3, RuSTy, which follows CODESYS). All the other codes are the subset the bench compiles
and are errors for every target. These are enforced by some dialects only, so their severity
follows the target: an **error** when a dialect you check for refuses the construct, a
**warning** when only one you do not check for refuses it (it builds where you deploy, not
everywhere) or when one you check for only warns. STruC++ "refuses" what its parser or checker
rejects, what g++ then fails on in its C++, and what it compiles to another value than the
source says. A construct MatIEC and STruC++ both build with different values (E0312) is an
error when you check for both, a warning for one of them. `all` is the default because the library
must build everywhere. `export` writes the OpenPLC upload: it uses `openplc` and fails only on
its errors; its CODESYS XML carries the same text, so it also prints what `codesys` refuses,
as warnings. `build`, `run`, `serve` and the pytest plugin compile what OpenPLC runs, for the
bench's soft PLC: `openplc`, except that the names OpenPLC's upload needs (E0602's Config0 and
Res0) are a warning on stderr, since the soft PLC runs any names.

| code | `--target openplc` | `--target openplc-v4` | `--target codesys` | `--target all` |
|---|---|---|---|---|
| E0214 reserved name | warning | warning | error | error |
| E0215 `__`, trailing `_` | error | warning | error (`__`), warning (trailing) | error |
| E0309 TRUNC narrowed | nothing | nothing | warning | warning |
| E0411 array element as in-out | error | warning | warning | error |
| E0512 VAR_TEMP in a FUNCTION, or of an array or STRUCT type | error | warning | warning | error |
| the other STruC++ codes (below) | warning | error | warning | error |
| E0312 TIME conversion | warning | warning | nothing | error |
| E0602 CONFIGURATION not Config0, RESOURCE not Res0 | error | warning | warning | error |
| E0100 forms only MatIEC refuses (below) | error | warning | warning | error |

- **E0214.** One list, `sim/armbench/compiler/reserved.py`, with its sources: IEC 61131-3
  (3rd edition) keywords, data types, standard functions and FBs; the keywords of CODESYS's
  online help and TwinCAT 3's keyword list, which include IL's instructions (`CAL`, `LD`,
  `R`, `S`, `ST`, `JMP`, ...) and CODESYS's `BIT`; RuSTy's lexer keywords and standard
  library. Keywords, data types and operators are refused as any name (variable, field,
  enumeration value, POU, type); a standard function or FB only as a POU or type name: a
  variable `Round` shadows RuSTy's `ROUND`, but a `FUNCTION Atan2` is a second declaration of
  RuSTy's `ATAN2` (its code generation stopped there). MatIEC's own reserved names are E0202.
  Write instead: a longer name (`Calibration`, not `Cal`; `ChannelBit`, not `Bit`; `ArcTan2`,
  not `Atan2`).
- **E0215.** `Lim__Sw` and `Lim_Sw_` fail in iec2c ("invalid located variable declaration");
  a leading underscore (`_Lim`) builds. Write `Lim_Sw`. STruC++ takes all three.
- **E0309.** TRUNC's result type differs: MatIEC takes it from the context, CODESYS returns
  DINT, RuSTy LINT. RuSTy warns wherever the LINT goes into a narrower integer: an
  assignment, an argument, a FUNCTION's result, through arithmetic and ABS, LIMIT, MIN, MAX,
  SEL, MUX; not in a comparison, an index, a CASE selector or a FOR bound, and the check
  follows it there. Write `Turns : LINT; Turns := TRUNC(x);` (CODESYS widens its DINT) or
  `D := LINT_TO_DINT(TRUNC(x));`; both build in MatIEC and give the same values.
- **E0411.** In a FUNCTION_BLOCK or PROGRAM, iec2c wraps a call of a FUNCTION with
  VAR_IN_OUT or VAR_OUTPUT in a C helper that writes an array element (`a[i]`, `s.v[i]`,
  `a[i].x`) as `.table1`, which g++ refuses. The same call inside a FUNCTION, an FB instance's
  VAR_IN_OUT given an element, and a STRUCT field without an index build. Write
  `Tmp := Arr[I]; Ok := Bump(Val := Tmp); Arr[I] := Tmp;`, or pass the whole array as
  VAR_IN_OUT with the index as an input, or make the callee a FUNCTION_BLOCK.
- **E0512.** iec2c's grammar has no VAR_TEMP in a FUNCTION ("unexpected temporary located
  variable(s) declaration in function declaration"), and in a FUNCTION_BLOCK or PROGRAM it
  initialises a VAR_TEMP of an array or STRUCT type as `__SET_VAR(data__->,M,,)`, which g++
  refuses ("expected primary-expression"); elementary and enumeration VAR_TEMPs build.
  STruC++ builds all of them. Write instead: VAR (a FUNCTION's starts afresh at every call;
  a block's keeps its value, so write it before you read it), or move the computation into a
  FUNCTION.
- **E0100, MatIEC's grammar.** Forms STruC++ and CODESYS take and iec2c fails on: an empty
  `VAR ... END_VAR` block; CONSTANT on VAR_INPUT, VAR_OUTPUT, VAR_IN_OUT or VAR_TEMP; a lone
  `;`; a typed or based CASE label (`DINT#5:`, `16#FF:`, `2#101:`, also as a range's bound:
  MatIEC takes decimal labels, their ranges and enumeration values only, "invalid case
  element(s)"); a FUNCTION, FUNCTION_BLOCK or PROGRAM with no statement ("no body defined",
  "unknown error in function block declaration"). Write the label in decimal (`255:`); give
  every POU a statement. The soft PLC runs all of them (a warning there).
- **E0602, the names.** OpenPLC v3's upload needs `CONFIGURATION Config0` and `RESOURCE Res0`
  (its runtime's build looks for the C files MatIEC names after them); MatIEC compiles any
  names, CODESYS takes any, and the soft PLC runs any, saying
  `warning[E0602]: CONFIGURATION 'Plant': OpenPLC's upload needs it to be named Config0 (the
  bench's soft PLC runs it as it is)`. The rest of E0602 (one RESOURCE, a periodic TASK, each
  PROGRAM instance WITH a TASK) is what the bench runs, an error for every target.
  VAR_IN_OUT with the index as an input, or make the callee a FUNCTION_BLOCK. STruC++ builds
  all of them.

### What STruC++ (OpenPLC v4) refuses or builds differently

Measured on STruC++ 0.6.1 (fb7980f) with its runtime headers and g++ 12 run as the v4 runtime
runs it (`-std=c++17 -O1 -pipe -fPIC -DSTRUCPP_THREADED`); docs/strucpp-facts.md has the
measurements, and `tests/compiler/test_strucpp_verdicts.py` runs every corpus case of these codes
through the real STruC++ (its verdict must be the checker's). The forms to write instead
build in MatIEC, STruC++, RuSTy and CODESYS alike.

- **E0109 `CONTINUE`.** Not in STruC++'s grammar. Put the rest of the loop body under
  `IF NOT (condition) THEN ... END_IF;` (EXIT is in its grammar).
- **E0110 literal forms.** Its lexer has no token for a sign after `#` (`DINT#-8`,
  `T#-250ms`), an enumeration's `Mode#Running`, or `_` in a REAL literal (`1_000.0`), and
  its grammar no typed literal as a CASE label (`INT#5:`). Write `-DINT#8`, `T#0s - T#250ms`,
  `Running`, `1000.0`, and untyped labels (`5:`, `-8:`, `16#FF:`, ranges).
- **E0216 reserved names.** STruC++ upper-cases every name into its C++, beside its runtime
  and the POUs of the libraries its command line loads: its keywords (`SUPER`, `PUBLIC`,
  `PROPERTY`, ...), the C macros that C++ sees (`LITTLE_ENDIAN`, `MAXFLOAT`, `EIO`,
  `CPU_SET`, ...) and its runtime's `IEC_*` types break any declaration; the functions and
  types of its runtime (`TIME_TO_NS`, `DT_TO_MS`, ...), of its standard libraries (`ROUND`,
  `ATAN2`, `NEG`, `TO_INT`, `SEMA`, `MC_POWER`, ...) and of the bundled OSCAT Basic library
  (564 names: `TOGGLE`, `SCALE`, `DELAY`, `FACT`, `INC`, `CALENDAR`, ...) break a POU, TYPE or
  VAR_GLOBAL of that name ("redefinition of class TOGGLE"). The lists are data files in
  `sim/armbench/compiler/data/` (strucpp-*.txt). As variables and fields those names are fine.
  Rename (`FlipFlop`, not `Toggle`).
- **E0217 VAR_GLOBAL in a RESOURCE.** Its grammar takes VAR_GLOBAL in the CONFIGURATION only:
  move the block before the RESOURCE.
- **E0310 NOT (...), ROL, ROR of a C++ int.** `NOT` followed by a parenthesis is a call of
  its runtime's `NOT` template, which takes IEC bit types only (`bool`, the unsigned
  integers, their `IECVar` wrappers). Its `AND`/`OR`/`XOR` are C++'s `& | ^`; variables are
  `IECVar<T>`, whose operators keep the wrapper for one `T` (`IECVar<bool> & bool` is
  `IECVar<bool>`), and anything else is C++'s built-in operator with its promotions: a
  comparison, `TRUE`, `NOT x` written without parentheses and a VAR_EXTERNAL read are raw
  `bool`, and `bool & bool` is `int`, left to right (`(a > b) AND (a < b) AND Ready` is
  `int`, `Ready AND (a > b) AND (a < b)` is `IECVar<bool>`); a WORD or BYTE beside an
  untyped literal is `int` too. g++ then fails ("no matching function for call to
  NOT(int)"). Assigned, compared, XORed or passed to a BOOL input, that `int` is converted
  and fine. Write NOT on each comparison (De Morgan: `NOT ((a >= b) AND (a <= b))` is
  `(a < b) OR (a > b)`), assign the expression to a BOOL first, or type the literal
  (`WORD#16#FF`).
- **E0311 decimal literals above 2^53.** It parses an untyped decimal literal into a
  JavaScript double and writes the double back: `9007199254740993` becomes
  `9007199254740992`, `2^61` `2305843009213694000`, `2^63 - 1` `9223372036854776000`, which
  g++ takes as a 128-bit constant and wraps; in statements, CASE labels and FUNCTION_BLOCK
  or FUNCTION initial values (a PROGRAM's or a VAR_GLOBAL's elementary initial value is
  copied as written). Typed (`LINT#...`) and based (`16#`, `8#`, `2#`) literals are exact.
- **E0312 TIME conversions.** MatIEC converts TIME from and to integers and REALs in seconds,
  STruC++ in milliseconds (`DINT_TO_TIME(3)` is 3 s against 3 ms; `REAL_TO_TIME(1.5)` 1.5 s
  against 1 ms). Write `T#1ms * n` or keep durations in TIME.
- **E0412 mixed C++ argument types.** Its runtime's `MUX` is `T MUX(IEC_INT k, T in0, T in1,
  ...)`, its `AND`/`OR`/`XOR` functions and `MIN`/`MAX` of three or more arguments deduce
  one `T` as well; STruC++ casts untyped literals for `AND`, `OR`, `XOR`, `MIN`, `MAX`, not
  for `MUX`. A variable beside an untyped literal or an arithmetic expression (`A + 1` is
  `int`, `Y * 2.0` `double`, `-B` `int`) fails. Type the literal (`INT#5`) or assign the
  expression to a variable first. SEL, LIMIT and two-argument MIN/MAX have overloads for
  mixed types.
- **E0413 named arguments out of order.** It passes a standard function's arguments in the
  order written and ignores their names: `LIMIT(IN := v, MN := 0, MX := 10)` is
  `LIMIT(v, 0, 10)`. Write them in the function's order (`MN, IN, MX`; `G, IN0, IN1`;
  `IN, N`). The order of MIN's, MAX's, AND's, OR's, XOR's inputs does not change the value.
- **E0505 STRUCT initialisers.** No `(X := 0.0, Y := 1.0)` initial values, in any VAR
  block (FB instance initialisers neither). Assign the fields once at the first scan, or let
  a zero input mean the default.
- **E0506 repeated values.** No `[3(1.0)]` in array initialisers: write the values out.
- **E0507 TYPE initial values.** Refused on an array TYPE; on an enumeration TYPE taken and
  ignored (its variables start at the first value). Give the value at each variable.
- **E0508 dropped array initial values.** It accepts and drops the initial values of a
  PROGRAM's arrays (VAR and VAR CONSTANT), of array VAR_GLOBALs and of array STRUCT fields:
  they start at 0. A FUNCTION_BLOCK's or FUNCTION's arrays keep theirs: keep tables in a
  FUNCTION_BLOCK's VAR CONSTANT, or fill the array at the first scan.
- **E0509 arrays of 3 or more dimensions.** Its runtime's 3-D array has no element access
  and no initialiser, and its deeper arrays (nested 1-D arrays) no `at(i, j, k, l)`:
  declaring, copying and passing them whole builds, a subscript or an initial value fails.
  Use an array of STRUCTs that each hold a 2-D array (`A[i].M[j, k]`), in a FUNCTION
  (E0511).
- **E0510 CONSTANT without a value.** "CONSTANT variable must have an initializer", for any
  type, in VAR, VAR_TEMP and VAR_EXTERNAL CONSTANT (which cannot have one). Give the value,
  or use a plain VAR of a code STRUCT that nothing writes (a VAR_EXTERNAL without CONSTANT).
- **E0511 2-D and 3-D arrays in a block's or program's state.** The v4 editor also uploads
  the debugger's table `generated_debug.cpp` (STruC++'s compile API writes it; its command
  line does not), which takes the address of every element of every variable of each
  PROGRAM instance and of the FB instances inside: a FUNCTION_BLOCK's VAR (CONSTANT too),
  VAR_INPUT, VAR_OUTPUT and VAR_IN_OUT, a PROGRAM's VAR, VAR_INPUT and VAR_OUTPUT, and the
  VAR_GLOBALs, through STRUCT fields and array elements. It writes an element of a 2-D or
  3-D array as `X[i][j]`, which the runtime's `IEC_ARRAY_2D`/`IEC_ARRAY_3D` cannot index
  (they have `(i, j)` and `at(i, j)`), and g++ fails (4-D and deeper arrays are nested 1-D
  arrays there and build). Keep matrices in a FUNCTION (its variables are not in the table;
  neither is VAR_TEMP, but OpenPLC v3 builds no VAR_TEMP of an array or STRUCT type), or
  hold them as a 1-D array of STRUCTs (`Rows[i].Cols[j]`) or as one 1-D array per row or
  column; a block's matrix output becomes its columns
  (`ForwardKinematic5Axis.ToolAxisX`..`ToolAxisZ`). STruC++ 0.6.1 and its newest sources
  seen (main, August 2026) write the table so.
"""


LIMITS = f"""
## Limits (E0108, E0210, E0211, E0212)

- **Nesting (E0108).** MatIEC is a bison parser built as C++, so its stack cannot grow past
  bison's initial {PARSER_STACK} entries: deeper nesting is a syntax error in OpenPLC ("Parsing
  failed because of too many consecutive syntax errors"). The checker replays, on the syntax
  tree, how many grammar symbols MatIEC's stack holds and reports the first construct beyond
  it, once per file, naming the constructs around it. The figures below were measured on
  OpenPLC's own iec2c (`iec2c -f -l -p -r -R -a`, thiagoralves/OpenPLC_v3 @ bb35f69) by binary
  search; the checker reproduces each exactly, and 750 random mixtures of them near the limit
  gave the same verdict as iec2c.

  | nested alone, in one statement of a PROGRAM | MatIEC's maximum | stack entries per level |
  |---|---|---|
  | `IF b THEN` (first statement of the branch / a later one) | 63 / 47 | 3 / 4 |
  | `IF b THEN x := 0; ELSE` | 31 | 6 |
  | `IF b THEN x := 0; ELSIF b THEN` | 23 | 8 |
  | `CASE x OF 1:` (first branch / a later branch / `ELSE`) | 38 / 31 / 38 | 5 / 6 / 5 |
  | `FOR i := 0 TO 1 DO` / with `BY 1` | 27 / 21 | 7 / 9 |
  | `WHILE b DO` | 63 | 3 |
  | `REPEAT` (first statement / a later one) | 189 / 95 | 1 / 2 |
  | parentheses `((x))` | {MAX_PARENTHESES} | 1 |
  | `-(`, `NOT (`, `f(`, `a[` | 94 | 2 |
  | `f(a := `, `f(x, `, `a[x, `, `x + x * (` | 47, 47, 47, 37 | 4, 4, 4, 5 |
  | `x + (` | 63 | 3 |
  | nested STRUCT initial values `(n := (n := ...))` in VAR | 61 | 3 |

  A statement of a PROGRAM or FUNCTION_BLOCK has {STATEMENT_ROOM["program_declaration"]} entries
  (a FUNCTION {STATEMENT_ROOM["function_declaration"]}: 188 parentheses), a declaration
  {DECLARATION_ROOM}; the number of VAR blocks and POUs before does not matter. What a construct
  keeps on the stack follows MatIEC's grammar: `IF`, condition, `THEN`, the statements so far
  (from the second statement on), `ELSIF`/`ELSE` after the branch lists, a binary operator's
  left operand and the operator, a call's name, `(` and earlier arguments, and so on. Literals
  take more than one entry: `T#1s` 7, `TIME#1s` and `T#-1s` 8, `DT#...` 9, `D#...` 6,
  `DATE#`/`TOD#` 7, `DINT#5` 3, `DINT#-5` 4, `-5` 2. Where the bench is stricter, by one entry
  at most: `BOOL#1` is counted as a typed literal of 2, `T#..` with both `TIME#` and a sign 9,
  and a FUNCTION_BLOCK call statement as 3. Nesting is per statement: nothing accumulates
  across statements or POUs.
- **Nesting the bench refuses (E0108).** Independently, the bench's own passes recurse over the
  syntax tree, so more than {NESTING_LIMIT} levels of it are refused. MatIEC's stack is the
  tighter limit except for chains of field accesses and indices on one variable
  (`s.f.f[1].f`), which MatIEC parses flat (16,384 levels measured): the bench stops them at
  {NESTING_LIMIT} levels (100 for `.f[1]` steps), and the types they need stop at E0211 anyway.
- **Long chains are not nesting.** `a + b + c + ...`, `x AND y AND z ...` and other
  left-associative chains of binary operators, long ELSIF and CASE lists, CASE value lists,
  statement lists, VAR lists, enumerations, STRUCT fields, ARRAY initial values and POUs are
  left-recursive in MatIEC's grammar: 5,000 of each were measured to pass iec2c. The bench
  accepts any length (tested to 20,000 terms; its C splits long chains every 100 operators).
  Checking time grows linearly with the input, for nesting, chains, statements and errors
  alike (tested from 2,000 to 20,000 tokens): a chain of unary operators is one E0105 and
  one E0108, not one per operator.
- **Containment (E0210).** A STRUCT may not contain itself, directly, through other STRUCTs or
  through an ARRAY of itself; a FUNCTION_BLOCK may not hold an instance of itself, directly or
  through other FBs. Each cycle group is reported once, at the declaration that comes first
  in the file, naming one cycle: `STRUCT A contains itself through A.b -> B.a`. VAR_IN_OUT
  and VAR_EXTERNAL are references, not containment.
- **Type depth (E0211).** STRUCTs, ARRAY types and FB instances may hold one another at most
  {NESTING_LIMIT} levels deep (an alias `TYPE T1 : T2; END_TYPE` adds no level). This is the
  bench's limit: MatIEC takes 500 STRUCT levels declared in order.
- **Declaration order (E0212).** A TYPE may name only types declared before it in the file: a
  STRUCT field, an ARRAY element type or an alias naming a later type (STRUCT, ARRAY, enum,
  subrange or alias; in the same TYPE block or a later one) fails in MatIEC even with `-p`
  ("invalid specification in structure element declaration", "invalid item data type in array
  specification", "invalid specification in data type declaration"). POUs are not affected:
  a variable of a later type, an instance of a later FUNCTION_BLOCK, a FUNCTION whose input or
  result has a later type and a call of a later FUNCTION all build in OpenPLC. Reported once
  per file with a count of the others; types from another file are not checked (OpenPLC gets
  one file: the export puts the types first).
"""


LIBRARY = """
## The armbench library (E0213)

`armbench check`, `build`, `run`, `serve` and `export` look the names your files use up in the
armbench library (the ST library `st/*.st` and the controller's blocks
`plc_project/controller/*.st`, shipped with the package) and add exactly the TYPEs and POUs
your program uses, with the ones those use in turn. Names are compared case-insensitively, as
ST does: `ARCTAN2(y, x)` is the library's `ArcTan2`. `ATAN2(y, x)` is E0400 with or without
the library: MatIEC has no ATAN2 standard function, and the library's arc tangent is not
named so because RuSTy's standard library declares ATAN2. `--no-library` adds nothing.

- A TYPE or POU of your own with a library name is yours: the library's is not added, nor
  anything only it would need. A program declaring `TYPE Vec3` or `FUNCTION DegToRad` and
  using nothing of the library checks exactly as without it.
- A library POU that you use and that refers to such a name gets your declaration (a modified
  copy of a library type or block replaces the library's; a note names them). When the
  library POU does not check with yours, one E0213 at your declaration stands for all the
  errors inside the library: rename yours, or check with `--no-library` and pass the library
  files you need.
- A library file you pass yourself, or a file of yours with the same name, replaces the
  library's file.
- `export` copies library files whole: each file holding something your program uses, and
  the files those need. When one of them declares a name your files declare too, `export`
  stops with one line saying which.
"""


def render() -> str:
    rows = "".join(f"| {code} | {title} | {fix} |\n" for code, (title, fix) in CODES.items())
    return HEADER + rows + TARGETS + LIMITS + LIBRARY


if __name__ == "__main__":
    sys.stdout.write(render())
