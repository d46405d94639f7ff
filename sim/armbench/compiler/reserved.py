"""Every name an IEC 61131-3 dialect we target reserves, in one place.

Two families of targets (docs/diagnostics.md, "Targets"):

- MatIEC, the compiler inside OpenPLC v3: its keywords, its elementary type names and the
  POUs of its standard library (data/stdlib-pou-names.txt, extracted from OpenPLC v3's
  webserver/lib). A name reserved there is E0202 for every target.
- IEC 61131-3 3rd edition and the CODESYS family (CODESYS V3, Beckhoff TwinCAT 3, RuSTy,
  which follows CODESYS): keywords, data types, operators and standard functions and FBs that
  MatIEC, an implementation of the 2nd edition, does not reserve. E0214.

Sources of the second family (names are case-insensitive everywhere; stored upper case):

- IEC 61131-3:2013 (3rd edition): its keywords, elementary and generic data types, standard
  functions (numeric, arithmetic, bit shift, bitwise, selection, comparison, character
  string, time and date, endianness, validation, typed and overloaded conversions) and
  standard FBs (bistables, edge detection, counters and timers with their typed variants).
  The standard is not public: the words are those of the two public implementations, MatIEC
  (2nd edition, above) and RuSTy, which follows the 3rd (github.com/PLC-lang/rusty @ ebf72fb8:
  the keywords of src/lexer/tokens.rs, the POUs of libs/stdlib/iec61131-st/*.st;
  tests/export/test_rusty.py checks that each of those POUs is reserved here), plus the
  3rd-edition words neither implements: NAMESPACE, END_NAMESPACE, USING, LOWER_BOUND,
  UPPER_BOUND, the long date and time types and the CHAR and generic types.
- CODESYS Development System online help: "Keywords"
  (content.helpme-codesys.com/en/CODESYS Development System/_cds_keywords.html: ACTION,
  END_ACTION, END_FUNCTION, END_FUNCTION_BLOCK, END_PROGRAM, VAR_ACCESS, READ_ONLY, READ_WRITE,
  PARAMS, and "keywords that denote scopes, data types or operators cannot be used as variable
  names"), "Operators" (_cds_struct_reference_operators.html), "Data type BIT"
  (_cds_datatype_bit.html) and the other data type pages, "Operator TRUNC"
  (_cds_operator_trunc.html: REAL to DINT).
- Beckhoff Information System, TwinCAT 3 PLC, "Keywords"
  (infosys.beckhoff.com/content/1031/tc3_plc_intro/2529971595.html): the full list of the
  keywords, from ABS to XORN, including the IL operators (CAL, JMP, LD, R, S, ST, ...),
  which TwinCAT refuses as variable names in every language. Its own standard library shows
  it: the counter CTD takes LOAD where IEC 61131-3 says LD
  (infosys.beckhoff.com/content/1033/tcplclib_tc2_standard/74398987.html).
- RuSTy ebf72fb8 itself, where it refuses more than the documents: its lexer takes GET, SET,
  PROPERTY and the one-word spellings ENDIF, ENDVAR, VARINPUT, ... as keywords (a VAR_INPUT
  named Get is three errors in `plc --check`), and its standard library declares ATAN2, ROUND
  and the *_EXT string functions (a library FUNCTION Atan2 stopped its code generation).

Names with two consecutive underscores or a trailing one are not listed: MatIEC refuses both
(measured on OpenPLC v3's iec2c) and CODESYS the first ("Multiple consecutive underscores are
not permitted", online help "Rules" for identifiers, _cds_rules.html; it keeps "__" for its
own __NEW, __XINT, ...). That is E0215 (dialects.py).
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from functools import cache
from pathlib import Path

from .types import ELEMENTARY

DATA = Path(__file__).parent / "data"

# ------------------------------------------------------------------ MatIEC (OpenPLC v3)
# SINGLE, a TASK parameter, is no keyword of MatIEC's: a variable, field, FB or FUNCTION named
# so builds in OpenPLC v3 (measured).
MATIEC_KEYWORDS = frozenset({
    "ACTION", "END_ACTION", "ARRAY", "OF", "AT", "CASE", "ELSE", "END_CASE", "CONFIGURATION",
    "END_CONFIGURATION", "CONSTANT", "DO", "BY", "EXIT", "CONTINUE", "FALSE", "TRUE", "FOR",
    "TO", "END_FOR", "FROM", "FUNCTION", "END_FUNCTION", "FUNCTION_BLOCK",
    "END_FUNCTION_BLOCK", "IF", "THEN", "ELSIF", "END_IF", "INITIAL_STEP", "INTERVAL",
    "NON_RETAIN", "NOT", "AND", "OR", "XOR", "MOD", "ON", "PRIORITY", "PROGRAM", "END_PROGRAM",
    "READ_ONLY", "READ_WRITE", "REPEAT", "UNTIL", "END_REPEAT", "RESOURCE", "END_RESOURCE",
    "RETAIN", "RETURN", "STEP", "END_STEP", "STRUCT", "END_STRUCT", "TASK",
    "TRANSITION", "END_TRANSITION", "TYPE", "END_TYPE", "VAR", "END_VAR", "VAR_INPUT",
    "VAR_OUTPUT", "VAR_IN_OUT", "VAR_TEMP", "VAR_EXTERNAL", "VAR_GLOBAL", "VAR_ACCESS",
    "VAR_CONFIG", "WHILE", "END_WHILE", "WITH", "EN", "ENO", "STRING", "WSTRING", "TIME",
    "DATE", "TIME_OF_DAY", "TOD", "DATE_AND_TIME", "DT", "ANY", "ANY_NUM", "ANY_INT",
    "ANY_REAL", "ANY_BIT", "ANY_DERIVED", "ANY_ELEMENTARY", "ANY_MAGNITUDE", "ANY_DATE",
    "ANY_STRING", "REF", "REF_TO", "NULL", "POINTER", "METHOD", "INTERFACE", "EXTENDS",
    "R_EDGE", "F_EDGE",  # edge qualifiers of VAR_INPUT declarations (measured: names fail)
})


@cache
def matiec_pou_names() -> frozenset[str]:
    """POU names of MatIEC's standard library (standard functions, typed variants, FBs)."""
    lines = (DATA / "stdlib-pou-names.txt").read_text().splitlines()
    return frozenset(ln.strip().upper() for ln in lines if ln.strip() and not ln.startswith("#"))


def matiec_reserves(name: str) -> bool:
    up = name.upper()
    return up in MATIEC_KEYWORDS or up in ELEMENTARY or up in matiec_pou_names()


def matiec_refuses_name(name: str, what: str) -> bool:
    """Whether MatIEC refuses ``name`` declared as ``what`` (rules.DeclaredName.what), measured
    on OpenPLC v3's build: keywords and elementary types as any name; its standard library's
    POU names (MAX, SEL, MIN_TIME, TON...) as any name but a STRUCT field (builds) or a
    FUNCTION's name (builds; a call of that FUNCTION does not: rules.check_names)."""
    up = name.upper()
    if up in MATIEC_KEYWORDS or up in ELEMENTARY:
        return True
    return up in matiec_pou_names() and what not in ("field", "function")


# ------------------------------------------------------------------ IEC 3rd ed. / CODESYS family
_IEC3_KEYWORDS = """
    ABSTRACT ACTION END_ACTION AND ARRAY AT BY CASE END_CASE CLASS END_CLASS CONFIGURATION
    END_CONFIGURATION CONSTANT CONTINUE DO ELSE ELSIF EN ENO EXIT EXTENDS FALSE FINAL FOR
    END_FOR FROM FUNCTION END_FUNCTION FUNCTION_BLOCK END_FUNCTION_BLOCK IF THEN END_IF
    IMPLEMENTS INITIAL_STEP INTERFACE END_INTERFACE INTERNAL INTERVAL METHOD END_METHOD MOD
    NAMESPACE END_NAMESPACE NON_RETAIN NOT NULL OF ON OR OVERRIDE PRIORITY PRIVATE
    PROGRAM END_PROGRAM PROTECTED PUBLIC READ_ONLY READ_WRITE REF REF_TO REPEAT UNTIL
    END_REPEAT RESOURCE END_RESOURCE RETAIN RETURN SINGLE STEP END_STEP STRUCT END_STRUCT SUPER
    TASK THIS TO TRANSITION END_TRANSITION TRUE TYPE END_TYPE USING VAR END_VAR VAR_ACCESS
    VAR_CONFIG VAR_EXTERNAL VAR_GLOBAL VAR_INPUT VAR_IN_OUT VAR_OUTPUT VAR_TEMP WHILE END_WHILE
    WITH XOR
"""
# Elementary and generic types of the 3rd edition (the conversions below are built from the
# elementary ones).
_IEC3_ELEMENTARY = """
    BOOL BYTE WORD DWORD LWORD SINT INT DINT LINT USINT UINT UDINT ULINT REAL LREAL TIME LTIME
    DATE LDATE TIME_OF_DAY LTIME_OF_DAY TOD LTOD DATE_AND_TIME LDATE_AND_TIME DT LDT STRING
    WSTRING CHAR WCHAR
"""
_IEC3_GENERIC = """
    ANY ANY_DERIVED ANY_ELEMENTARY ANY_MAGNITUDE ANY_NUM ANY_REAL ANY_INT ANY_UNSIGNED
    ANY_SIGNED ANY_DURATION ANY_BIT ANY_CHARS ANY_STRING ANY_CHAR ANY_DATE
"""
_IEC3_FUNCTIONS = """
    ABS SQRT LN LOG EXP SIN COS TAN ASIN ACOS ATAN ADD MUL SUB DIV EXPT MOVE SHL SHR ROL
    ROR SEL MAX MIN LIMIT MUX GT GE EQ LE LT NE LEN LEFT RIGHT MID CONCAT INSERT DELETE REPLACE
    FIND TRUNC ADD_TIME ADD_LTIME ADD_TOD_TIME ADD_LTOD_LTIME ADD_DT_TIME ADD_LDT_LTIME SUB_TIME
    SUB_LTIME SUB_DATE_DATE SUB_LDATE_LDATE SUB_TOD_TIME SUB_LTOD_LTIME SUB_TOD_TOD
    SUB_LTOD_LTOD SUB_DT_TIME SUB_LDT_LTIME SUB_DT_DT SUB_LDT_LDT MUL_TIME MUL_LTIME DIV_TIME
    DIV_LTIME CONCAT_DATE CONCAT_DATE_TOD CONCAT_DATE_LTOD CONCAT_DT CONCAT_LDT CONCAT_TOD
    CONCAT_LTOD SPLIT_DATE SPLIT_TOD SPLIT_LTOD SPLIT_DT SPLIT_LDT DAY_OF_WEEK TO_BIG_ENDIAN
    TO_LITTLE_ENDIAN FROM_BIG_ENDIAN FROM_LITTLE_ENDIAN IS_VALID IS_VALID_BCD LOWER_BOUND
    UPPER_BOUND
"""
_IEC3_FBS = """
    SR RS R_TRIG F_TRIG CTU CTU_INT CTU_DINT CTU_LINT CTU_UDINT CTU_ULINT CTD CTD_INT CTD_DINT
    CTD_LINT CTD_UDINT CTD_ULINT CTUD CTUD_INT CTUD_DINT CTUD_LINT CTUD_UDINT CTUD_ULINT TP
    TP_TIME TP_LTIME TON TON_TIME TON_LTIME TOF TOF_TIME TOF_LTIME
"""
# TwinCAT 3's keyword list as published (CODESYS V3 listed the same as "Reserved keywords"),
# then the words of CODESYS's "Keywords" page that are not in it.
_CODESYS_KEYWORDS = """
    ABS ACOS ADD ADR AND ANDN ARRAY ASIN AT ATAN BITADR BOOL BY BYTE CAL CALC CALCN CASE
    CONSTANT COS DATE DINT DIV DO DT DWORD ELSE ELSIF END_CASE END_FOR END_IF END_REPEAT
    END_STRUCT END_TYPE END_VAR END_WHILE EQ EXIT EXP EXPT FALSE FOR FUNCTION FUNCTION_BLOCK GE
    GT IF INDEXOF INT JMP JMPC JMPCN LD LDN LE LINT LN LOG LREAL LT LTIME LWORD MAX METHOD MIN
    MOD MOVE MUL MUX NE NOT OF OR ORN PARAMS PERSISTENT POINTER PROGRAM R READ_ONLY READ_WRITE
    REAL REFERENCE REPEAT RET RETAIN RETC RETCN RETURN ROL ROR S SEL SHL SHR SIN SINT SIZEOF
    SUPER SQRT ST STN STRING STRUCT SUB TAN THEN THIS TIME TO TOD TRUE TRUNC TYPE UDINT UINT
    ULINT UNTIL USINT VAR VAR_CONFIG VAR_EXTERNAL VAR_GLOBAL VAR_IN_OUT VAR_INPUT VAR_OUTPUT
    VAR_STAT VAR_TEMP WHILE WORD WSTRING XOR XORN
    ACTION END_ACTION END_FUNCTION END_FUNCTION_BLOCK END_PROGRAM VAR_ACCESS
"""
# CODESYS data types and operators beyond IEC 61131-3, from the online help.
_CODESYS_TYPES = "BIT UNION END_UNION"
_CODESYS_OPERATORS = "AND_THEN OR_ELSE XSIZEOF TRUNC_INT INI PROPERTY END_PROPERTY VAR_INST"
# RuSTy ebf72fb8: lexer keywords and standard library POUs beyond the lists above.
_RUSTY_KEYWORDS = """
    GET END_GET SET END_SET ACTIONS END_ACTIONS ENDACTION ENDACTIONS ENDCASE ENDCLASS ENDFOR
    ENDFUNCTION ENDFUNCTIONBLOCK ENDGET ENDIF ENDINTERFACE ENDMETHOD ENDPROGRAM ENDPROPERTY
    ENDREPEAT ENDSET ENDSTRUCT ENDTYPE ENDVAR ENDWHILE FUNCTIONBLOCK NONRETAIN REFTO VARGLOBAL
    VARINOUT VARINPUT VAROUTPUT VARTEMP
"""
_RUSTY_FUNCTIONS = """
    ATAN2 ROUND CONCAT_EXT DELETE_EXT INSERT_EXT LEFT_EXT MID_EXT REPLACE_EXT RIGHT_EXT STRING_EQUAL
    STRING_GREATER STRING_LESS WSTRING_EQUAL WSTRING_GREATER WSTRING_LESS BYTE_TO_STRING_EXT
    DATE_TO_STRING_EXT DT_TO_STRING_EXT LINT_TO_STRING_EXT LREAL_TO_STRING_EXT
    LWORD_TO_STRING_EXT STRING_TO_WSTRING_EXT TIME_TO_STRING_EXT TOD_TO_STRING_EXT
    WSTRING_TO_STRING_EXT
"""

_ELEMENTARY_ALT = "|".join(sorted(_IEC3_ELEMENTARY.split(), key=len, reverse=True))
# The conversion families of the 3rd edition: typed T1_TO_T2, overloaded TO_T, BCD_TO_T and
# T_TO_BCD (and MatIEC's T_BCD_TO_T2, T_TO_BCD_T2), TRUNC_T and typed T1_TRUNC_T2.
_CONVERSION = re.compile(
    rf"^(?:(?:{_ELEMENTARY_ALT}|BCD)_TO_(?:{_ELEMENTARY_ALT}|BCD)|TO_(?:{_ELEMENTARY_ALT})"
    rf"|(?:{_ELEMENTARY_ALT})_BCD_TO_(?:{_ELEMENTARY_ALT})|(?:{_ELEMENTARY_ALT})_TO_BCD_"
    rf"(?:{_ELEMENTARY_ALT})|(?:(?:REAL|LREAL)_)?TRUNC_(?:{_ELEMENTARY_ALT}))$")


@dataclass(frozen=True)
class Reservation:
    """Why a name is reserved: what it is, which dialects say so, and whether it is refused
    as every name (a keyword, data type or operator) or only as a POU or type name (a
    standard function or FB: a variable of that name shadows it, and RuSTy builds one named
    Round, but a POU of that name is a second declaration of it)."""

    what: str  # "a keyword", "a data type", ...
    where: str  # "IEC 61131-3 (3rd edition)", "CODESYS and TwinCAT", ...
    every_name: bool

    def __str__(self) -> str:
        return f"{self.what} of {self.where}"


@cache
def _table() -> dict[str, Reservation]:
    """Name -> its first reservation, in the order of the sources above."""
    iec = "IEC 61131-3 (3rd edition)"
    groups = [
        (_IEC3_KEYWORDS, Reservation("a keyword", iec, True)),
        (_IEC3_ELEMENTARY, Reservation("a data type", iec, True)),
        (_IEC3_GENERIC, Reservation("a generic data type", iec, True)),
        # CODESYS and TwinCAT make these operators, so keywords there
        (_CODESYS_KEYWORDS, Reservation("a keyword", "CODESYS and TwinCAT", True)),
        (_CODESYS_TYPES, Reservation("a data type", "CODESYS and TwinCAT", True)),
        (_CODESYS_OPERATORS, Reservation("an operator or keyword", "CODESYS", True)),
        (_RUSTY_KEYWORDS, Reservation("a keyword", "RuSTy", True)),
        (_IEC3_FUNCTIONS, Reservation("a standard function", iec, False)),
        (_IEC3_FBS, Reservation("a standard function block", iec, False)),
        (_RUSTY_FUNCTIONS, Reservation("a standard function", "RuSTy", False)),
    ]
    table: dict[str, Reservation] = {}
    for words, why in groups:
        for w in words.split():
            table.setdefault(w, why)
    return table


def codesys_family_reserves(name: str) -> Reservation | None:
    """Why IEC 61131-3 (3rd edition), CODESYS, TwinCAT or RuSTy refuse ``name``, or None."""
    up = name.upper()
    found = _table().get(up)
    if found is not None:
        return found
    if _CONVERSION.match(up):
        return Reservation("a standard conversion function", "IEC 61131-3 (3rd edition)",
                           False)
    return None


def reserved_anywhere(name: str) -> bool:
    """True when any dialect we target reserves ``name``."""
    return matiec_reserves(name) or codesys_family_reserves(name) is not None


# ------------------------------------------------------------------ STruC++ (OpenPLC v4)
# Measured on STruC++ 0.6.1 (fb7980f), its runtime headers and g++ 12 as the v4 runtime runs
# it (-std=c++17 -DSTRUCPP_THREADED), one name at a time as a FUNCTION_BLOCK name and as a
# FUNCTION_BLOCK's INT variable (tests/corpus/diagnostics/E0216_*). STruC++ upper-cases every
# identifier, so C++'s own keywords (class, new, int, ...) are never hit.
#
# Its lexer's keywords that its declarations refuse as any name (`Public : INT;` is "Expected
# END_VAR"), and those it takes as variables but not as POU or type names.
_STRUCPP_KEYWORDS_ANY = """
    DREF END_GET END_INTERFACE END_METHOD END_PROPERTY END_SET IMPLEMENTS PRIVATE PROPERTY
    PROTECTED PUBLIC REFERENCE_TO SUPER THIS VAR_INST
"""
_STRUCPP_KEYWORDS_GLOBAL = "ABSTRACT FINAL GET SET"


@dataclass(frozen=True)
class _StrucppNames:
    """The names STruC++ refuses, from the data files (each says where its names come from):
    as any name (keywords, C macros, the runtime's IEC_* types) or as a global name only: a
    POU, a TYPE or a VAR_GLOBAL, which STruC++ declares at namespace scope beside its
    runtime's functions and its libraries' POUs."""

    any_name: dict[str, str]
    global_name: dict[str, str]


def _data_names(file: str) -> list[tuple[str, str]]:
    """(name, section) of a data file: `# section: ...` lines name the section of the names
    below them."""
    out: list[tuple[str, str]] = []
    section = ""
    for line in (DATA / file).read_text().splitlines():
        line = line.strip()
        if line.startswith("# section:"):
            section = line.removeprefix("# section:").strip()
        elif line and not line.startswith("#"):
            out.append((line.upper(), section))
    return out


@cache
def _strucpp_names() -> _StrucppNames:
    any_name: dict[str, str] = {}
    global_name: dict[str, str] = {}
    for w in _STRUCPP_KEYWORDS_ANY.split():
        any_name[w] = "a keyword of STruC++"
    for w in _STRUCPP_KEYWORDS_GLOBAL.split():
        global_name[w] = "a keyword of STruC++"
    for name, _ in _data_names("strucpp-macros.txt"):
        any_name.setdefault(name, "a C macro in STruC++'s C++")
    for name, section in _data_names("strucpp-runtime-names.txt"):
        target = any_name if section == "types" else global_name
        target.setdefault(name, "a name of STruC++'s C++ runtime")
    for name, section in _data_names("strucpp-library-names.txt"):
        global_name.setdefault(name, f"a POU or type of STruC++'s library {section}")
    return _StrucppNames(any_name, global_name)


def strucpp_reserves(name: str, global_scope: bool) -> str | None:
    """Why STruC++ refuses ``name`` (as a POU, type or global when ``global_scope``), or
    None. Names MatIEC reserves are E0202 and C macros of E0204's list are E0204: those are
    errors for every target and not repeated here."""
    up = name.upper()
    names = _strucpp_names()
    why = names.any_name.get(up)
    if why is None and global_scope:
        why = names.global_name.get(up)
    return why
