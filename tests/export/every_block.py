"""A PROGRAM holding one instance of every FUNCTION_BLOCK a user may instantiate (st/ and the
controller's blocks, plc_project/controller/), in a CONFIGURATION: what OpenPLC v4's debugger
table (tests/export/test_strucpp.py) and OpenPLC v3's build (tests/export/test_export.py) must
take. The blocks come from the parsed sources, so a new block is in it without anyone listing
it."""

from __future__ import annotations

from pathlib import Path

from armbench.export.generate import load_sources
from armbench.locate import Project

REPO = Path(__file__).resolve().parents[2]
PROJECT = Project(REPO)
INSTANCE_PREFIX = "I_"


def block_files() -> list[Path]:
    """st/*.st and plc_project/controller/*.st."""
    return [*PROJECT.library(), *PROJECT.components()]


def every_block_program() -> str:
    """The PROGRAM EveryBlock (an instance I_<block> of each FUNCTION_BLOCK of block_files())
    and CONFIGURATION Config0 running it."""
    _, sources = load_sources(block_files(), PROJECT, library=[], need_config=False)
    blocks = [p.name for s in sources for p in s.unit.pous if p.kind == "FUNCTION_BLOCK"]
    assert len(blocks) >= 40, f"only {len(blocks)} FUNCTION_BLOCKs parsed: {blocks}"
    instances = "\n".join(f"    {INSTANCE_PREFIX}{b} : {b};" for b in blocks)
    return f"""PROGRAM EveryBlock
  VAR
{instances}
    Scans : DINT;
  END_VAR
  Scans := Scans + 1;
END_PROGRAM

CONFIGURATION Config0
  RESOURCE Res0 ON PLC
    TASK MainTask(INTERVAL := T#10ms, PRIORITY := 0);
    PROGRAM Every WITH MainTask : EveryBlock;
  END_RESOURCE
END_CONFIGURATION
"""


def every_block_source(folder: Path) -> Path:
    """The whole of block_files() (every declaration, dependency order) and the program, in
    one upload file ``folder``/every_block.st."""
    folder.mkdir(parents=True, exist_ok=True)
    probe = folder / "every_block_program.st"
    probe.write_text(every_block_program(), encoding="utf-8")
    _, library = load_sources(block_files(), PROJECT, library=[], need_config=False)
    source = folder / "every_block.st"
    source.write_text("\n".join([*(s.text for s in library), probe.read_text("utf-8")]),
                      encoding="utf-8")
    return source
