"""What the docs and the package's messages point a reader to is there.

* Every file or folder named in README.md and docs/**/*.md (in prose, code spans or code
  blocks) exists in the repository, unless it is one of the few names listed below that are
  not ours to ship (a file the reader writes, a path inside the OpenPLC runtime, a file a run
  writes); every document (``*.md``) and every repository path (``st/...``, ``docs/...``)
  named in a string of the package under sim/ (its messages, help texts and docstrings)
  exists too.
* No tracker-issue numbers (``issue #9``, ``task 12``, ``(#8)``) in the product: the package,
  the ST library, the controller project and the docs. A reader has no tracker.
* Every source document cited by number (``document 002``) is listed in docs/sources.md.

Names are read with regular expressions, so each check is first shown to find what it looks
for in a sample text.
"""

from __future__ import annotations

import ast
import fnmatch
import os
import re
from collections.abc import Iterator
from functools import cache
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
PAGES = sorted([REPO / "README.md", *(REPO / "docs").rglob("*.md")])
PRODUCT_DIRS = ("sim", "st", "plc_project", "docs")
TOP_DIRS = ("st", "sim", "plc_project", "docs", "tests", "bench", "scripts", ".ci")
EXTENSIONS = "md|st|py|sh|xml|txt|png|c|h|toml|json|csv|in|whl"

# A file name with one of EXTENSIONS, with or without folders; a path under a top folder.
_FILE = re.compile(r"(?<![\w./~$<-])((?:\.\.?/)?(?:[\w*.-]+/)*[\w*-][\w*.-]*\.(?:"
                   + EXTENSIONS + r"))(?![\w/-])")
_TOP = re.compile(r"(?<![\w./~$<-])((?:" + "|".join(re.escape(d) for d in TOP_DIRS)
                  + r")/[\w./*-]*)")

# Names on the pages that are not files of this repository, and why.
NOT_OURS = {
    # files the reader writes (the CLI's and the labs' examples)
    "my_program.st", "angle.st", "gvl.st", "half.st", "len.st", "planar2.st", "reach.st",
    "sampler.st", "steps.st", "sum.st", "user.st", "lab2.st", "lab2-fixes.st",
    # the OpenPLC Editor's project file, the OpenPLC runtime's own files, MatIEC's library
    "plc.xml", "./install.sh", "./core/psm/main.py", "core/psm/main.py",
    "webserver/core/psm/main.py", "webserver/core/psm/psm.py",
    "bistable.txt", "edge_detection.txt", "pid_st.txt", "timer.txt", "background_installer.sh",
    "iec_std_lib.h", "iec_std_functions.h", "webserver/openplc.py",
    "Config0.c", "Res0.c", "POUS.h",  # MatIEC's generated C files
    "run-st.sh",  # the MatIEC run script a user provides (MATIEC_RUN)
    # OpenPLC v4's runtime and pymodbus's, read for docs/modbus-parity.md's v4 rules
    "core/src/drivers/plugins/python/modbus_slave/simple_modbus.py", "simple_modbus.py",
    "shared/image_sizes.py", "image_sizes.py", "image_tables.h", "journal_buffer.c",
    "journal_buffer.h", "mutex_manager.py", "modbus_slave.json", "test_modbus_slave.py",
    "test_inputs.py", "register_message.py", "bit_message.py", "requesthandler.py",
    "context.py", "framer/socket.py", "transport.py",
    # OpenPLC v4's runtime files and the paths it installs into, named by docs/raspberry-pi.md
    "install.sh", "compile.sh", "scripts/compile.sh", "manage_plugin_venvs.sh",
    "scripts/manage_plugin_venvs.sh", "plcapp_management.py", "webserver/plcapp_management.py",
    "webserver/plugin_config_model.py", "conf/modbus_slave.json",
    "./core/src/drivers/plugins/python/arm_io/arm_io.json",
    "./core/src/drivers/plugins/python/arm_io/arm_io_plugin.py",
    # RuSTy's own files, in its checkout (docs/exports.md: building it)
    "Cargo.toml", "include/*.st", "libs/stdlib/iec61131-st/*.st", "scripts/build.sh",
    # a script's argument placeholder
    "FILE.st",
    # written by a command the page gives (the demo, docs/raspberry-pi.md's export)
    "out/demo/velocities.png", "upload/openplc/arm_controller.st",
    # a wheel the reader builds (README, docs/raspberry-pi.md)
    "armbench-*.whl", "dist/armbench-*.whl", "dist/armbench-0.1.0-py3-none-any.whl",
}


@cache
def _repo_files() -> tuple[str, ...]:
    skip = {".git", ".venv", ".venv-lowest", "build", "__pycache__", "out", ".mypy_cache",
            ".ruff_cache", ".pytest_cache"}
    found = []
    for folder, dirs, files in os.walk(REPO):
        dirs[:] = [d for d in dirs if d not in skip and not d.endswith(".egg-info")]
        rel = Path(folder).relative_to(REPO)
        found += [(rel / name).as_posix() for name in (*dirs, *files)]
    return tuple(found)


def named_paths(text: str) -> set[str]:
    found = {m.group(1) for m in _FILE.finditer(text)}
    found |= {m.group(1).rstrip("./") for m in _TOP.finditer(text)}
    return {f for f in found if f not in TOP_DIRS}


def exists(name: str, base: Path) -> bool:
    """``name`` relative to the repository root or ``base``, or, for a name without a folder
    or one relative to a folder the text speaks of (``openplc/arm_controller.st`` in the
    paragraph on plc_project/), a file of the repository ending in it."""
    for root in (REPO, base):
        if "*" in name:
            if any(root.glob(name)):
                return True
        elif (root / name).exists():
            return True
    if name.startswith(("./", "../")):
        return False
    if "*" in name:
        return "/" not in name and any(fnmatch.fnmatch(f.rsplit("/", 1)[-1], name)
                                       for f in _repo_files())
    return any(f == name or f.endswith("/" + name) for f in _repo_files())


def _missing_on(page: Path) -> list[str]:
    return sorted(n for n in named_paths(page.read_text(encoding="utf-8"))
                  if n not in NOT_OURS and not exists(n, page.parent))


def test_path_reader_finds_names() -> None:
    text = ("see DESIGN.md §5, `docs/matiec-facts.md`, st/*.st and (plc_project/Controller.st); "
            "16#FF, T#10ms, 1.5, e.g. and https://example.org/x.md are not files")
    assert named_paths(text) == {"DESIGN.md", "docs/matiec-facts.md", "st/*.st",
                                 "plc_project/Controller.st"}
    assert not exists("DESIGN.md", REPO) and exists("Controller.st", REPO)
    assert exists("openplc/arm_controller.st", REPO) and exists("st/*.st", REPO)


@pytest.mark.parametrize("page", PAGES, ids=lambda p: p.relative_to(REPO).as_posix())
def test_files_named_in_the_docs_exist(page: Path) -> None:
    missing = _missing_on(page)
    assert not missing, (f"{page.relative_to(REPO)} names files the repository lacks: "
                         f"{missing} (point to a file that is here, e.g. docs/matiec-facts.md)")


def _strings(path: Path) -> Iterator[tuple[int, str]]:
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Constant) and isinstance(node.value, str):
            yield node.lineno, node.value


def test_files_named_in_the_packages_messages_exist() -> None:
    missing = []
    for path in sorted((REPO / "sim").rglob("*.py")):
        for line, text in _strings(path):
            for name in named_paths(text):
                # a document, or a repository path; a file name alone is often an output
                if not (name.endswith(".md") or name.split("/", 1)[0] in TOP_DIRS):
                    continue
                if name not in NOT_OURS and not exists(name, path.parent):
                    missing.append(f"{path.relative_to(REPO)}:{line}: {name}")
    assert not missing, "messages name files the repository lacks:\n" + "\n".join(missing)


# ------------------------------------------------------------------ tracker-issue numbers

TRACKER = re.compile(
    r"\b(?:issues?|tickets?|bugs?|PRs?|pull requests?|tasks?|items?)\s+#?\d+\b"
    r"|\b(?:issue|task|ticket)\s*#\d+\b"
    r"|(?<![\w#&/\"'])#\d+\b(?!\.\d|[#\w])"  # "(#12)", "see #9"; not 16#FF, T#10ms, colours
    r"|\b(?:the|this|that) issue(?:'s)?\b(?! (?:is|was|with|here)\b)",
    re.IGNORECASE)


def test_tracker_pattern() -> None:
    for hit in ("(issue #9)", "issue 12", "Issue #8, item 6", "task 3", "see #10.", "(#11)",
                "against the issue's bound", "the issue found a client"):
        assert TRACKER.search(hit), hit
    for miss in ("16#FF", "T#10ms", "INT#5", "TASK task0(INTERVAL := T#20ms)", '"#388e3c"',
                 "{x:#010x}", "## 5. Load the PSM", "the issue is that", "tissue 3"):
        assert not TRACKER.search(miss), miss


def _product_files() -> Iterator[Path]:
    yield REPO / "README.md"
    for top in PRODUCT_DIRS:
        for path in sorted((REPO / top).rglob("*")):
            if path.is_file() and path.suffix in (".py", ".st", ".md", ".xml", ".js", ".html",
                                                   ".css", ".c", ".h", ".txt", ".csv"):
                yield path


def test_no_tracker_numbers_in_the_product() -> None:
    hits = []
    for path in _product_files():
        for n, line in enumerate(path.read_text(encoding="utf-8").splitlines(), 1):
            m = TRACKER.search(line)
            if m:
                hits.append(f"{path.relative_to(REPO)}:{n}: {m.group(0)!r}")
    assert not hits, ("tracker references in the product (say what the text means "
                      "instead):\n" + "\n".join(hits))


# ------------------------------------------------------------------------ source documents

_DOCUMENT = re.compile(r"\bdocuments? (\d{3})\b(?:(?: and |, )(\d{3})\b)*", re.IGNORECASE)


def test_cited_source_documents_are_listed() -> None:
    listed = set(re.findall(r"^## (\d{3}) ", (REPO / "docs" / "sources.md").read_text(
        encoding="utf-8"), re.M))
    assert listed == {"000", "001", "002", "003", "004"}
    cited: dict[str, str] = {}
    for path in _product_files():
        for n, line in enumerate(path.read_text(encoding="utf-8").splitlines(), 1):
            for m in _DOCUMENT.finditer(line):
                for number in re.findall(r"\d{3}", m.group(0)):
                    cited.setdefault(number, f"{path.relative_to(REPO)}:{n}")
            assert "SEEDS" not in line, (f"{path.relative_to(REPO)}:{n}: SEEDS is not in the "
                                         "repository: cite docs/sources.md")
    assert cited, "no source document cited: the pattern is broken"
    unlisted = {k: v for k, v in cited.items() if k not in listed}
    assert not unlisted, f"documents cited but not in docs/sources.md: {unlisted}"
