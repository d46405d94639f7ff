"""One scan of a library program on the real MatIEC (OpenPLC's build, the script MATIEC_RUN or
run-st.sh beside MATIEC_CHECK) and in the bench compiler, for the tests that compare them."""

from __future__ import annotations

import os
import re
import shutil
import subprocess
from collections.abc import Sequence
from pathlib import Path
from typing import Any

REPO = Path(__file__).resolve().parents[2]
ST = REPO / "st"
SKIP_REASON = ("MATIEC_RUN (or a run-st.sh beside MATIEC_CHECK) not set or no file: see the "
               "README's 'Checking against the real MatIEC'")


def run_tool() -> Path | None:
    """The script that builds and runs a file the way OpenPLC does, if the user has one."""
    check = os.environ.get("MATIEC_CHECK")
    if not check:
        return None
    run = Path(os.environ.get("MATIEC_RUN", Path(check).with_name("run-st.sh")))
    return run if run.is_file() else None


def first_scan_both(folder: Path, name: str, files: Sequence[str], program: str,
                    timeout: float = 600.0) -> tuple[dict[str, str], Any]:
    """Write the library files and `program` as one file (as OpenPLC uploads it), run one scan
    on the real MatIEC and in the bench compiler: MatIEC's printed values of instance0 by
    upper-case name, and the bench's instance0."""
    from armbench.compiler import compile_files

    run_st = run_tool()
    assert run_st is not None, SKIP_REASON
    source = folder / name
    source.write_text("\n".join((ST / f).read_text(encoding="utf-8") for f in files)
                      + "\n" + program, encoding="utf-8")
    bash = shutil.which("bash") or "/bin/bash"
    run = subprocess.run([bash, str(run_st), "-n", "1", str(source)], capture_output=True,
                         text=True, timeout=timeout, check=False)
    assert run.returncode == 0, run.stdout[-3000:] + run.stderr[-3000:]
    real = {k.upper(): v for k, v in
            re.findall(r"^instance0\.(\w+)=(\S+)$", run.stdout, flags=re.M)}
    mod = compile_files([source])
    prog = mod.instance("instance0")
    mod.config_init()
    mod.run_task_index(0, 0)
    return real, prog
