"""The dialects `armbench check --target` checks for, and what each refuses.

Three compilers take the library's ST: OpenPLC v3's MatIEC (target ``openplc``), OpenPLC v4's
STruC++ (target ``openplc-v4``: ST to C++17, built by the v4 runtime with g++), and the
CODESYS family with IEC 61131-3's 3rd edition (target ``codesys``: CODESYS V3, TwinCAT 3,
RuSTy). ``all`` is all three, the default: the library must build everywhere.

Most rules of the checker are the portable subset the bench compiles, and are errors whatever
the target. A rule that only some dialects enforce names them (``Rule``); its severity for a
check then follows from the target:

- error, when a dialect checked for refuses the construct (STruC++ "refuses" what its parser
  or checker rejects, what g++ then fails on, and what it compiles to a different value than
  the source says: each breaks the program where it is deployed);
- warning, when only a dialect not checked for refuses it (a heads-up: the code builds where
  you deploy, but not everywhere), or when a dialect checked for only warns about it;
- nothing, when only dialects not checked for warn about it.

So a name CODESYS reserves is an error for ``codesys`` and ``all`` but a warning for
``openplc``, where it builds; an array element MatIEC's C cannot bind is an error for
``openplc`` and ``all`` and a warning for ``codesys``.

A construct two dialects both build but compute differently (``severity_between``) is an
error when the check is for both of them (the code cannot mean the same on both), a warning
when it is for one of them, and nothing otherwise.
"""

from __future__ import annotations

from dataclasses import dataclass

OPENPLC = "openplc"
OPENPLC_V4 = "openplc-v4"
CODESYS = "codesys"
DIALECTS = (OPENPLC, OPENPLC_V4, CODESYS)
TARGET_NAMES = (*DIALECTS, "all")


@dataclass(frozen=True)
class Target:
    """The dialects one check is for."""

    dialects: frozenset[str]

    @classmethod
    def named(cls, name: str) -> Target:
        key = name.strip().lower()
        if key == "all":
            return cls(frozenset(DIALECTS))
        if key in DIALECTS:
            return cls(frozenset({key}))
        raise ValueError(f"unknown target {name!r}: use {', '.join(TARGET_NAMES)}")

    @property
    def name(self) -> str:
        return "all" if self.dialects == frozenset(DIALECTS) else next(iter(self.dialects))

    def severity(self, refused_by: frozenset[str],
                 warned_by: frozenset[str] = frozenset()) -> str | None:
        """"error", "warning" or None for a construct the given dialects refuse or warn about."""
        if refused_by & self.dialects:
            return "error"
        if refused_by or warned_by & self.dialects:
            return "warning"
        return None

    def severity_between(self, differing: frozenset[str]) -> str | None:
        """"error", "warning" or None for a construct ``differing`` all build, with a
        different value in each."""
        checked = differing & self.dialects
        if checked == differing:
            return "error"
        return "warning" if checked else None


ALL = Target.named("all")
OPENPLC_ONLY = Target.named(OPENPLC)
OPENPLC_V4_ONLY = Target.named(OPENPLC_V4)
CODESYS_ONLY = Target.named(CODESYS)
