"""Diagnostics: the one table of error codes, the message record and how it renders.

A diagnostic is an error (the check fails), a warning (a target other than the ones checked
for refuses it, or a checked target only warns; the check passes) or a note. Which codes
depend on the target, and how, is in targets.py.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
from dataclasses import dataclass, field

from .limits import NESTING_LIMIT
from .source import SourcePos

# One table: code -> (title, what to write instead). docs/diagnostics.md is generated from it.
CODES: dict[str, tuple[str, str]] = {
    "E0001": ("cannot read source file", "check the path and file permissions"),
    "E0100": ("syntax error", "fix the ST syntax at the position shown"),
    "E0101": ("'//' line comment", "use (* ... *) comments: MatIEC rejects // comments"),
    "E0102": ("nested or C-style comment", "use flat (* ... *) comments"),
    "E0103": ("pragma OpenPLC's C build fails on, or C the soft PLC cannot run",
              "remove the pragma, or write its C as MatIEC's C needs it (docs/matiec-facts.md)"),
    "E0104": ("real literal without digits on both sides of the point",
              "write 1.0, 0.5, 1.0E3"),
    "E0105": ("unsupported construct", "rewrite with the IEC 61131-3 subset MatIEC accepts"),
    "E0106": ("'**' power operator", "use EXPT(x, 2.0) or x * x: OpenPLC lacks __expt"),
    "E0107": ("missing ';' after END_STRUCT", "write END_STRUCT; inside TYPE ... END_TYPE"),
    "E0108": ("nesting too deep", "MatIEC's parser stack overflows (e.g. beyond 63 nested IFs "
              "or 189 nested parentheses; see Limits below): move inner parts into variables or "
              "FUNCTIONs (long flat chains like a + b + c are fine)"),
    "E0120": ("STRING form OpenPLC v3 does not build",
              "declare STRING (MatIEC's 126-byte string; OpenPLC v3's build fails on STRING[n] "
              "and WSTRING) and write literals of at most 125 bytes with $N, not $L"),
    "E0121": ("STRING comparison or FIND computed differently by the targets",
              "OpenPLC v3 (MatIEC) compares only the common prefix of two STRINGs and its FIND "
              "skips after a partial match; OpenPLC v4 and CODESYS compare whole strings: "
              "compare LEN as well, FIND one character (a warning for --target openplc-v4, "
              "codesys and all)"),
    "E0111": ("CONFIGURATION out of form",
              "write CONFIGURATION Config0 / RESOURCE Res0 ON PLC / TASK MainTask(INTERVAL := "
              "T#10ms, PRIORITY := 0); / PROGRAM Inst WITH MainTask : Main; / END_RESOURCE / "
              "END_CONFIGURATION (Main: your PROGRAM; TASKs before the PROGRAM instances)"),
    "E0109": ("CONTINUE", "put the rest of the loop body under IF NOT (condition) THEN ... "
              "END_IF: STruC++ (OpenPLC v4) has no CONTINUE (an error for --target openplc-v4 "
              "and all, a warning for the others)"),
    "E0110": ("literal form STruC++ refuses", "write -DINT#8 (not DINT#-8), T#0s - T#250ms "
              "(not T#-250ms), the enumeration value alone (not Mode#Stop), 1000.0 (not "
              "1_000.0), untyped CASE labels (5:, 16#FF:, not INT#5:): STruC++ (OpenPLC v4) has "
              "no token or no grammar for these"),
    "E0200": ("undeclared name", "declare the variable, type or POU"),
    "E0201": ("duplicate declaration", "names are case-insensitive: rename one"),
    "E0202": ("reserved name", "rename it: MatIEC reserves keywords, type names and standard "
              "function/FB names"),
    "E0203": ("name collides with MatIEC's standard library",
              "rename it: a POU/type named like a variable of MatIEC's standard library "
              "breaks OpenPLC's build"),
    "E0204": ("name becomes a C macro", "rename it: upper-cased it collides with a C macro"),
    "E0205": ("VAR_EXTERNAL without matching VAR_GLOBAL",
              "declare the variable in the CONFIGURATION's VAR_GLOBAL with the same type"),
    "E0206": ("VAR_GLOBAL outside a CONFIGURATION",
              "pass values as inputs, or declare globals inside CONFIGURATION/RESOURCE"),
    "E0207": ("VAR_EXTERNAL in a FUNCTION", "pass the value as a VAR_INPUT"),
    "E0208": ("FB instance inside a FUNCTION", "make the caller a FUNCTION_BLOCK"),
    "E0209": ("recursion", "IEC 61131-3 forbids recursive calls: use a loop"),
    "E0210": ("type or FUNCTION_BLOCK contains itself", "a STRUCT, ARRAY type or FB instance "
              "cannot hold itself, directly or through others: keep the repeated part in an "
              "array and refer to it by index, or pass it as VAR_IN_OUT"),
    "E0211": ("types nested too deep", f"nest STRUCTs, ARRAY types and FB instances at most "
              f"{NESTING_LIMIT} levels deep (a limit of the bench)"),
    "E0212": ("type used before its declaration", "declare a type before the TYPEs that name "
              "it (STRUCT fields, ARRAY elements, aliases): MatIEC rejects later types there"),
    "E0213": ("your declaration replaces one the armbench library needs",
              "rename your TYPE or POU, or check with --no-library and pass the library files "
              "you need (docs/diagnostics.md, The armbench library)"),
    "E0214": ("name reserved in IEC 61131-3 (3rd edition), CODESYS, TwinCAT or RuSTy",
              "rename it (e.g. Bit -> ChannelBit, S -> Terms, Cal -> Calibration): keywords, "
              "data types and operators are refused as any name there, standard functions "
              "and FBs as POU or type names; an error for --target codesys and all, a "
              "warning for openplc (see Targets below)"),
    "E0215": ("identifier with consecutive or trailing underscores",
              "write one underscore between parts and none at the end (Lim_Sw, not Lim__Sw "
              "or Lim_Sw_): MatIEC refuses both, CODESYS refuses '__'"),
    "E0216": ("name STruC++ (OpenPLC v4) reserves", "rename it: its keywords (SUPER, PUBLIC, "
              "PROPERTY, ...) and the C macros its C++ sees (LITTLE_ENDIAN, MAXFLOAT, EIO, ...) "
              "as any name; the POUs and types of its runtime and libraries (ATAN2, ROUND, NEG, "
              "TO_INT, SCALE, TOGGLE, MC_POWER, ...) as POU, type or global names (see Targets "
              "below)"),
    "E0217": ("VAR_GLOBAL inside a RESOURCE", "declare the globals in the CONFIGURATION, before "
              "the RESOURCE: STruC++ (OpenPLC v4) takes them there only"),
    "E0300": ("type mismatch", "convert explicitly, e.g. INT_TO_REAL(x)"),
    "E0301": ("integer literal in REAL context", "write a real literal such as 2.0"),
    "E0302": ("not assignable", "assign only variables, not inputs of FUNCTIONs, constants "
              "or FB outputs"),
    "E0303": ("wrong operand type", "use an operand of the type the operator needs"),
    "E0304": ("constant out of range", "the folded constant does not fit its type"),
    "E0305": ("unknown member", "check the STRUCT field or FB variable name"),
    "E0306": ("not an array", "index only ARRAY variables"),
    "E0307": ("wrong number of indices", "give one index per array dimension"),
    "E0308": ("constant index out of bounds", "use an index inside the declared range"),
    "E0309": ("TRUNC narrowed implicitly", "receive TRUNC's result in a LINT (Turns : LINT; "
              "Turns := TRUNC(x)) or convert it with LINT_TO_DINT(TRUNC(x)): TRUNC returns "
              "LINT in RuSTy and DINT in CODESYS, so anything narrower warns there (a warning "
              "for --target codesys and all; MatIEC types TRUNC from its context)"),
    "E0310": ("NOT (...), ROL or ROR of a C++ int in STruC++", "apply NOT to each comparison "
              "(De Morgan: NOT ((a >= b) AND (a <= b)) is (a < b) OR (a > b)), or assign the "
              "expression to a BOOL variable first; type literals beside a WORD or BYTE "
              "(WORD#16#FF): STruC++'s NOT, ROL and ROR take IEC bit types only, and g++ fails on "
              "its C++ for NOT (x AND y) of two comparisons (Targets below)"),
    "E0311": ("decimal integer literal STruC++ writes with another value",
              "write LINT#9007199254740993 or 16#20000000000001: STruC++ (OpenPLC v4) passes "
              "untyped decimal literals above 2^53 through a JavaScript double; typed and "
              "hexadecimal literals are exact"),
    "E0312": ("conversion from or to TIME", "keep durations in TIME (T#3s, T#1ms * n), or in an "
              "integer of milliseconds you scale yourself: MatIEC converts TIME from and to "
              "seconds, STruC++ (OpenPLC v4) milliseconds (an error for --target all, a warning "
              "for openplc and openplc-v4)"),
    "E0400": ("bad call", "check the POU name and its parameters"),
    "E0401": ("call without arguments", "pass at least one argument: MatIEC rejects F()"),
    "E0402": ("mixed named and positional arguments", "pass all arguments named or all "
              "positional"),
    "E0403": ("function call as a statement", "assign the result: r := F(x);"),
    "E0404": ("field access on a call result", "assign the result to a variable first"),
    "E0405": ("call of a FUNCTION with an array VAR_INPUT",
              "pass it as VAR_IN_OUT, wrap it in a STRUCT, or use a FUNCTION_BLOCK input: "
              "OpenPLC's C build fails on calls with array inputs"),
    "E0406": ("anonymous ARRAY return type", "declare a named type: TYPE Mat4 : ARRAY[..] OF "
              "REAL; END_TYPE"),
    "E0407": ("unknown parameter", "use a parameter the POU declares"),
    "E0408": ("FB output written from outside", "read FB outputs; set inputs only"),
    "E0409": ("missing argument", "pass every input: missing ones are silently zero in MatIEC"),
    "E0410": ("call of a STRUCT-returning FUNCTION with outputs",
              "in a FUNCTION_BLOCK or PROGRAM, call only STRUCT-returning FUNCTIONs without "
              "VAR_OUTPUT/VAR_IN_OUT: return BOOL and pass the STRUCT as VAR_IN_OUT, or call it "
              "from a FUNCTION"),
    "E0411": ("array element bound to a FUNCTION's VAR_IN_OUT or VAR_OUTPUT in a "
              "FUNCTION_BLOCK or PROGRAM",
              "copy the element into a variable, call with the variable, copy it back (or "
              "pass the whole array as VAR_IN_OUT and the index as an input, or make the "
              "callee a FUNCTION_BLOCK): OpenPLC's C build fails on the element; inside a "
              "FUNCTION it builds (an error for --target openplc and all, a warning for "
              "codesys)"),
    "E0412": ("MUX, or AND/OR/XOR/MIN/MAX called by name, with arguments of different C++ "
              "types in STruC++", "type the literals (INT#5, REAL#1.0) or assign each expression "
              "to a variable first: STruC++'s runtime deduces one C++ type from a variable "
              "(IECVar<short>) and an untyped literal or expression (int), and g++ fails"),
    "E0413": ("standard function's named arguments out of its parameter order",
              "name the arguments in the order the function declares them (LIMIT(MN := .., IN := "
              ".., MX := ..)): STruC++ (OpenPLC v4) passes them in the order written and "
              "computes another value"),
    "E0500": ("array bound is not a literal", "write literal bounds: ARRAY[0..3]"),
    "E0501": ("ARRAY OF ARRAY", "use a multi-dimensional array ARRAY[a..b, c..d]"),
    "E0502": ("ARRAY of FB instances", "declare the instances one by one"),
    "E0503": ("too many initial values", "give at most as many values as the array holds"),
    "E0504": ("FB instance in a STRUCT", "declare the instance in the FUNCTION_BLOCK or "
              "PROGRAM that uses it: MatIEC accepts only data types as STRUCT fields"),
    "E0505": ("STRUCT or FB initialiser as an initial value", "assign the fields in the body "
              "(once, at the first scan), or let a zero value mean the default: STruC++ "
              "(OpenPLC v4) has no (name := value) initialisers"),
    "E0506": ("repeated value n(v) in an array initialiser", "write the values out: STruC++ "
              "(OpenPLC v4) has no repetition"),
    "E0507": ("initial value on a TYPE", "give the initial value at each variable of the type: "
              "STruC++ (OpenPLC v4) refuses one on an array TYPE and ignores one on an "
              "enumeration (its variables start at the first value)"),
    "E0508": ("array initial values STruC++ drops", "keep the table in a FUNCTION_BLOCK's VAR "
              "(CONSTANT) and call it, or fill the array at the first scan: STruC++ (OpenPLC v4) "
              "drops the initial values of a PROGRAM's arrays, of array VAR_GLOBALs and of array "
              "STRUCT fields, silently (they start at 0)"),
    "E0509": ("array of 3 or more dimensions subscripted or initialised",
              "use an array of STRUCTs that each hold a 2-D array (A[i].M[j, k]; in a FUNCTION: "
              "E0511): STruC++'s runtime (OpenPLC v4) has no element access and "
              "no initialiser for them"),
    "E0510": ("CONSTANT without an initial value", "give it an initial value, or make it a plain "
              "VAR that nothing writes (VAR_EXTERNAL: drop CONSTANT): STruC++ (OpenPLC v4) "
              "refuses a constant without one"),
    "E0511": ("array of 2 or 3 dimensions in a block's or program's state",
              "keep the matrix in a FUNCTION, or hold it as a 1-D array of STRUCTs (one row "
              "per element) or as 1-D arrays (one per row or column): the "
              "debugger's table of STruC++ (OpenPLC v4) cannot address the elements of a "
              "FUNCTION_BLOCK's VAR, VAR_INPUT, VAR_OUTPUT or VAR_IN_OUT, a PROGRAM's VAR, "
              "VAR_INPUT or VAR_OUTPUT, or a VAR_GLOBAL that is one or holds one"),
    "E0512": ("VAR_TEMP OpenPLC v3 does not build", "declare it in VAR: MatIEC has no VAR_TEMP "
              "in a FUNCTION, and OpenPLC's C build fails on a VAR_TEMP of an array or STRUCT "
              "type in a FUNCTION_BLOCK or PROGRAM (an error for --target openplc and all, a "
              "warning for codesys and openplc-v4)"),
    "E0600": ("bad located variable", "match sizes: %IX/%QX BOOL, %IW/%QW/%MW 16-bit, %MD "
              "32-bit, %ML 64-bit; no arrays; only in PROGRAM or CONFIGURATION"),
    "E0601": ("located and plain variables in one VAR block", "split them into two VAR blocks"),
    "E0602": ("configuration layout", "one RESOURCE, a periodic TASK, each PROGRAM instance "
              "WITH a TASK; the names Config0 and Res0 for OpenPLC's upload (an error for "
              "--target openplc and all, a warning for codesys and for build, run and serve: "
              "see Targets below)"),
    "E0700": ("C compiler failed", "an internal error of the bench: report it with the ST"),
    "N0001": ("file is not UTF-8: read as Windows-1252 (cp1252); a note, not an error",
              "nothing if the accented characters show right; else save the file as UTF-8"),
}


@dataclass(frozen=True)
class Diagnostic:
    pos: SourcePos
    code: str
    message: str
    severity: str = "error"  # "error" | "warning" | "note"

    def render(self) -> str:
        return f"{self.pos}: {self.severity}[{self.code}]: {self.message}"


@dataclass
class Diagnostics:
    """Collects diagnostics of one compilation; suppresses exact repeats.

    Adding one costs the same however many there are (a set finds repeats): a file with
    20,000 errors is reported in linear time."""

    items: list[Diagnostic] = field(default_factory=list)
    _seen: set[Diagnostic] = field(default_factory=set, repr=False)

    def error(self, pos: SourcePos, code: str, message: str) -> None:
        self._add(Diagnostic(pos, code, message))

    def warning(self, pos: SourcePos, code: str, message: str) -> None:
        """A portability problem that does not fail the check (see targets.py)."""
        self._add(Diagnostic(pos, code, message, "warning"))

    def report(self, severity: str, pos: SourcePos, code: str, message: str) -> None:
        """An error or a warning, as ``severity`` says (a target decides which)."""
        if severity not in ("error", "warning"):
            raise ValueError(f"severity must be 'error' or 'warning', not {severity!r}")
        self._add(Diagnostic(pos, code, message, severity))

    def note(self, pos: SourcePos, code: str, message: str) -> None:
        """Information that does not fail the check (e.g. the encoding a file was read in)."""
        self._add(Diagnostic(pos, code, message, "note"))

    def _add(self, d: Diagnostic) -> None:
        if d.code not in CODES:
            raise KeyError(f"diagnostic code {d.code} is not in the CODES table")
        if d not in self._seen:
            self._seen.add(d)
            self.items.append(d)

    def extend(self, items: Iterable[Diagnostic]) -> None:
        for d in items:
            self._add(d)

    def keep(self, wanted: Callable[[Diagnostic], bool]) -> None:
        """Drop the diagnostics for which ``wanted`` is false."""
        self.items = [d for d in self.items if wanted(d)]
        self._seen = set(self.items)

    @property
    def has_errors(self) -> bool:
        return any(d.severity == "error" for d in self.items)

    def sorted(self) -> list[Diagnostic]:
        return sorted(self.items, key=lambda d: (d.pos.file, d.pos.line, d.pos.col, d.code))

    def render(self) -> str:
        return "\n".join(d.render() for d in self.sorted())


class CompileFailed(Exception):
    """The sources have errors; str() is one rendered diagnostic per line."""

    def __init__(self, diagnostics: list[Diagnostic]) -> None:
        self.diagnostics = diagnostics
        super().__init__("\n".join(d.render() for d in diagnostics))
