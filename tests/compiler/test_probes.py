"""The checker against MatIEC's ground truth: shared/matiec/probes, 129 files whose verdicts
were measured on OpenPLC's own iec2c and C build. We must accept exactly the files OpenPLC
accepts (iec2c accepted and C build ok), and those must also compile and load here."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from armbench.compiler import check_files
from armbench.compiler.build import build
from armbench.compiler.driver import emit_files
from armbench.compiler.targets import OPENPLC_ONLY

PROBES = Path(__file__).resolve().parents[2].parent / "shared" / "matiec" / "probes"
VERDICTS = PROBES / "verdicts.json"


def _cases() -> list[tuple[str, bool]]:
    if not VERDICTS.exists():
        return []
    data = json.loads(VERDICTS.read_text())
    return [(name, v.get("iec2c") == "accepted" and v.get("openplc_c_build", "ok") == "ok")
            for name, v in sorted(data.items())]


CASES = _cases()


@pytest.mark.skipif(not CASES, reason=f"MatIEC probes not found at {PROBES} (../shared)")
@pytest.mark.parametrize(("name", "accepted"), CASES, ids=[c[0] for c in CASES])
def test_probe_verdict(name: str, accepted: bool) -> None:
    path = PROBES / f"{name}.st"
    # OpenPLC's verdict: what other dialects refuse is a warning for --target openplc
    diags = [d for d in check_files([path], target=OPENPLC_ONLY) if d.severity == "error"]
    if accepted:
        assert diags == [], "\n".join(d.render() for d in diags)
        build(emit_files([path])[1])
    else:
        assert diags, f"{name}: OpenPLC rejects it, armbench check accepts it"
        assert all(d.code != "E0001" for d in diags)
