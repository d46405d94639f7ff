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

A few rules are the upload's, not the compiler's: OpenPLC's upload needs the CONFIGURATION
named Config0 and its RESOURCE Res0, though MatIEC compiles any names and the bench's soft
PLC runs them. ``upload_severity`` grades those: as above for a check or an export, and at
most a warning for ``SOFT_PLC``, what `armbench build`, `run`, `serve` and the pytest plugin
compile for (the dialect OpenPLC's, the program run by the bench, not uploaded).

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
    # False: compiled to run on the bench's soft PLC, not to be uploaded to a PLC of these
    # dialects, so what only an upload refuses is a warning (upload_severity)
    upload: bool = True

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

    def upload_severity(self, refused_by: frozenset[str]) -> str | None:
        """Like severity, for a construct the upload to a PLC of ``refused_by`` refuses (the
        dialect's compiler takes it): at most a warning when nothing is uploaded."""
        severity = self.severity(refused_by)
        return "warning" if severity == "error" and not self.upload else severity

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
SOFT_PLC = Target(frozenset({OPENPLC}), upload=False)
