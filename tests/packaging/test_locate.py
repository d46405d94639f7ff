"""Where the tools find the library (armbench.locate), and generators that write repository
files only ever writing into a checkout."""

from __future__ import annotations

import subprocess
import sys
from collections.abc import Callable
from pathlib import Path

import pytest

from armbench import docgen, locate, lutgen, registermap
from armbench.plots import teaching

REPO = Path(__file__).resolve().parents[2]


def test_from_the_checkout_the_tools_use_its_files() -> None:
    checkout = locate.package_checkout()
    assert checkout is not None and checkout.root.resolve() == REPO
    project = locate.default_project()
    assert project.library() == sorted((REPO / "st").glob("*.st"))
    assert project.controller.resolve() == REPO / "plc_project" / "Controller.st"
    assert registermap.CONTROLLER.resolve() == project.controller.resolve()


def test_find_checkout(tmp_path: Path) -> None:
    assert locate.find_checkout(start=REPO / "docs" / "figures").root == REPO
    assert locate.find_checkout(repo=REPO).root == REPO
    with pytest.raises(locate.NotACheckout, match="not inside a checkout"):
        locate.find_checkout(start=tmp_path)
    with pytest.raises(locate.NotACheckout, match="is not a checkout"):
        locate.find_checkout(repo=tmp_path)


@pytest.mark.parametrize("generator", [docgen.main, lutgen.main, teaching.main],
                         ids=["docgen", "lutgen", "teaching"])
def test_generators_outside_a_checkout_stop_with_a_message(
        generator: Callable[[list[str]], int], tmp_path: Path,
        monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]) -> None:
    monkeypatch.chdir(tmp_path)
    with pytest.raises(SystemExit) as exc:
        generator([])
    assert exc.value.code == 2
    assert "not inside a checkout" in capsys.readouterr().err
    assert list(tmp_path.iterdir()) == []


def test_registermap_outside_a_checkout(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                        capsys: pytest.CaptureFixture[str]) -> None:
    monkeypatch.chdir(tmp_path)
    assert registermap.main([]) == 2
    assert "not inside a checkout" in capsys.readouterr().err


def test_batchgen_outside_a_checkout(tmp_path: Path) -> None:
    proc = subprocess.run([sys.executable, "-m", "armbench.batchgen", "--check"], cwd=tmp_path,
                          capture_output=True, text=True, timeout=60)
    assert proc.returncode != 0
    assert proc.stderr.strip().count("\n") == 0 and "not inside a checkout" in proc.stderr


def test_generators_take_repo(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(tmp_path)
    assert docgen.main(["--check", "--repo", str(REPO)]) == 0
    assert lutgen.main(["--check", "--repo", str(REPO)]) == 0
