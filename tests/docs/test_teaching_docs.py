"""The teaching pages never rot: their code runs, their ST checks, their links resolve.

Conventions for fenced code blocks in docs/kinematics.md, docs/servo-pwm.md,
docs/frames-dh.md, docs/jacobians.md, docs/teachers-guide.md and docs/labs/*.md (the info
string after the opening fence; renderers use its first word):

* ```` ```python ````            runnable: executed, in order, one namespace per page (like a
                                  notebook), with the repository root as the working directory.
* ```` ```python no-run ````     shown only (needs a second terminal, a file the student
                                  writes, a real PLC, ...).
* ```` ```st pass ````           must pass ``armbench check``: with the declarations of the
                                  armbench library (st/, plc_project/controller/) it uses,
                                  as the command adds them.
* ```` ```st pass no-lib ````    must pass ``armbench check --no-library``: on its own.
* ```` ```st fail E0106 ````     ``armbench check`` must report that code (``no-lib`` as above).
                                  If the next block is a plain ```` ``` ```` block of
                                  ``file:line:col: error[...]`` lines, it must equal the real
                                  output (the file name aside).
* ```` ```st no-check ````       shown only.

Every ```` ```st ```` block must carry one of these marks. Relative links and images in
docs/*.md and docs/labs/*.md must point to existing files, and the figures that
armbench.plots.teaching writes must be the ones the pages show.
"""

from __future__ import annotations

import os
import re
from dataclasses import dataclass
from pathlib import Path

import pytest

from armbench.compiler import check_files

REPO = Path(__file__).resolve().parents[2]
DOCS = REPO / "docs"
CODE_PAGES = sorted([DOCS / "kinematics.md", DOCS / "servo-pwm.md", DOCS / "orientation.md",
                     DOCS / "frames-dh.md", DOCS / "jacobians.md", DOCS / "teachers-guide.md",
                     *(DOCS / "labs").glob("*.md")])
LINK_PAGES = sorted([*DOCS.glob("*.md"), *(DOCS / "labs").glob("*.md")])
# where `armbench check` looks names up (armbench.cli): the ST library, the controller's blocks
LIB = [*sorted((REPO / "st").glob("*.st")),
       *sorted((REPO / "plc_project" / "controller").glob("*.st"))]

_FENCE = re.compile(r"^```([^\n`]*)\n(.*?)^```\s*$", re.S | re.M)
_LINK = re.compile(r"!?\[[^\]]*\]\(([^)\s]+)(?:\s+\"[^\"]*\")?\)")
_DIAG = re.compile(r"^\S+?:(\d+:\d+: error\[E\d{4}\]: .*)$")


@dataclass(frozen=True)
class Block:
    page: Path
    line: int  # line of the opening fence, 1-based
    info: list[str]
    text: str

    @property
    def where(self) -> str:
        return f"{self.page.relative_to(REPO)}:{self.line}"


def blocks(page: Path) -> list[Block]:
    src = page.read_text(encoding="utf-8")
    return [Block(page, src.count("\n", 0, m.start()) + 1, m.group(1).split(), m.group(2))
            for m in _FENCE.finditer(src)]


def _id(p: Path) -> str:
    return str(p.relative_to(DOCS))


def test_pages_exist() -> None:
    labs = sorted((DOCS / "labs").glob("*.md"))
    assert len(labs) >= 4, labs
    for page in ("index.md", "kinematics.md", "servo-pwm.md"):
        assert (DOCS / page).is_file(), page


# --------------------------------------------------------------------------- python blocks

def _runnable(page: Path) -> list[Block]:
    return [b for b in blocks(page) if b.info[:1] == ["python"] and "no-run" not in b.info]


@pytest.mark.parametrize("page", [p for p in CODE_PAGES if _runnable(p)], ids=_id)
def test_python_blocks_run(page: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    runnable = _runnable(page)
    monkeypatch.chdir(REPO)
    namespace: dict[str, object] = {"__name__": f"docs_{page.stem.replace('-', '_')}"}
    for b in runnable:
        code = compile(b.text, b.where, "exec")
        try:
            exec(code, namespace)
        except Exception as exc:  # report which block broke
            raise AssertionError(f"python block at {b.where} failed: {exc!r}") from exc


# --------------------------------------------------------------------------- ST blocks

def _st_cases() -> list[tuple[Block, Block | None]]:
    out: list[tuple[Block, Block | None]] = []
    for page in CODE_PAGES:
        bs = blocks(page)
        for i, b in enumerate(bs):
            if b.info[:1] == ["st"]:
                out.append((b, bs[i + 1] if i + 1 < len(bs) else None))
    return out


ST_CASES = _st_cases()


def test_there_are_st_blocks_of_both_kinds() -> None:
    kinds = {b.info[1] for b, _ in ST_CASES if len(b.info) > 1}
    assert {"pass", "fail"} <= kinds, kinds


@pytest.mark.parametrize("block,after", ST_CASES, ids=[b.where for b, _ in ST_CASES])
def test_st_block(block: Block, after: Block | None, tmp_path: Path) -> None:
    marks = block.info[1:]
    assert marks and marks[0] in ("pass", "fail", "no-check"), (
        f"{block.where}: mark the ```st block 'pass', 'fail E####' or 'no-check'")
    if marks[0] == "no-check":
        return
    src = tmp_path / "block.st"
    src.write_text(block.text, encoding="utf-8")
    assert "+lib" not in marks, f"{block.where}: the library is added by use; drop '+lib'"
    diags = check_files([src], [] if "no-lib" in marks else LIB)
    rendered = [d.render() for d in diags]
    if marks[0] == "pass":
        assert not diags, f"{block.where} should pass armbench check:\n" + "\n".join(rendered)
        return
    codes = [m for m in marks[1:] if re.fullmatch(r"E\d{4}", m)]
    assert len(codes) == 1, f"{block.where}: write the expected code, e.g. ```st fail E0106"
    assert any(f"error[{codes[0]}]" in r for r in rendered), (
        f"{block.where} should give {codes[0]}, got:\n" + "\n".join(rendered or ["(nothing)"]))
    # The diagnostics printed under the block must be the real ones.
    if after is not None and not after.info:
        shown = [m.group(1) for line in after.text.splitlines() if (m := _DIAG.match(line))]
        if shown:
            real = [m.group(1) for r in rendered if (m := _DIAG.match(r))]
            assert shown == real, f"{after.where}: the page shows\n{shown}\nbut check says\n{real}"


# --------------------------------------------------------------------------- links, figures

def _links(page: Path) -> list[str]:
    text = _FENCE.sub("", page.read_text(encoding="utf-8"))  # links in code are not links
    return _LINK.findall(text)


@pytest.mark.parametrize("page", LINK_PAGES, ids=_id)
def test_relative_links_resolve(page: Path) -> None:
    broken = []
    for target in _links(page):
        if re.match(r"^[a-z][a-z0-9+.-]*:", target) or target.startswith("#"):
            continue  # http:, https:, mailto:, in-page anchors
        path = target.split("#", 1)[0]
        if not (page.parent / path).exists():
            broken.append(target)
    assert not broken, f"{_id(page)}: broken links {broken}"


def test_teaching_figures_are_the_ones_the_pages_show() -> None:
    from armbench.plots import teaching

    shown = {os.path.basename(t) for page in LINK_PAGES for t in _links(page)
             if t.startswith("figures/") and t.endswith(".png")}
    made = set(teaching.FIGURES)
    assert made <= shown, f"figures written but shown nowhere: {sorted(made - shown)}"
    for name in shown:
        assert (DOCS / "figures" / name).is_file(), name


def test_teaching_script_writes_its_figures(tmp_path: Path) -> None:
    from armbench.plots import teaching

    assert teaching.main(["--out", str(tmp_path)]) == 0
    for name in teaching.FIGURES:
        png = tmp_path / name
        assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n", name
        assert png.stat().st_size > 10_000, name
