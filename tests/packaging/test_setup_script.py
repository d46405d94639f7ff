"""scripts/setup.sh (run by scripts/test.sh and scripts/demo.sh) is quiet when it works and
loud when it fails: apt-get's and dpkg's progress goes to a log, whose last lines are shown
only when the install fails.

It runs here in a sandbox: a copy of the script beside an installed-looking .venv, and a PATH
with no C compiler or chromium, where `id` says root and `apt-get` is a stand-in that prints
what dpkg prints whatever apt-get's -qq says (a line per package unpacked and set up) and,
when told to, fails as apt-get does for a package it cannot find.
"""

from __future__ import annotations

import os
import shutil
import subprocess
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
BASH = shutil.which("bash")

APT_GET = """#!{bash}
if [ "$1" = install ] || [ "$2" = install ] || [ "$3" = install ] || [ "$4" = install ]; then
  for pkg in "$@"; do
    case "$pkg" in -*|install) continue ;; esac
    if [ "$pkg" = "$APT_FAIL" ]; then
      echo "E: Unable to locate package $pkg" >&2
      exit 100
    fi
    for i in $(seq 1 40); do
      echo "Selecting previously unselected package lib$pkg-$i."
      echo "Unpacking lib$pkg-$i (1.0-$i) ..."
      echo "Setting up lib$pkg-$i (1.0-$i) ..."
    done
  done
fi
exit 0
"""


def sandbox(tmp_path: Path) -> tuple[Path, dict[str, str]]:
    repo, bin_ = tmp_path / "repo", tmp_path / "bin"
    (repo / "scripts").mkdir(parents=True)
    shutil.copy2(REPO / "scripts" / "setup.sh", repo / "scripts" / "setup.sh")
    (repo / ".venv" / "bin").mkdir(parents=True)
    for stub, text in (("python", "#!/bin/sh\nexit 0\n"),):
        (repo / ".venv" / "bin" / stub).write_text(text)
        (repo / ".venv" / "bin" / stub).chmod(0o755)
    (repo / ".venv" / ".armbench-installed").touch()  # no pyproject.toml newer: no pip
    bin_.mkdir()
    assert BASH is not None
    stubs = {"apt-get": APT_GET.format(bash=BASH), "id": "#!/bin/sh\necho 0\n",
             "python3": "#!/bin/sh\nexit 0\n"}
    for name, text in stubs.items():
        (bin_ / name).write_text(text)
        (bin_ / name).chmod(0o755)
    for tool in ("dirname", "mktemp", "tail", "rm", "touch", "seq"):
        found = shutil.which(tool)
        assert found is not None, tool
        (bin_ / tool).symlink_to(found)
    env = {"PATH": str(bin_), "HOME": str(tmp_path), "TMPDIR": str(tmp_path)}
    return repo, env


def run_setup(repo: Path, env: dict[str, str], **extra: str) -> subprocess.CompletedProcess[str]:
    assert BASH is not None
    return subprocess.run([BASH, str(repo / "scripts" / "setup.sh")], env={**env, **extra},
                          capture_output=True, text=True, timeout=60)


@pytest.mark.skipif(BASH is None or os.name != "posix", reason="needs bash on POSIX")
def test_a_working_install_says_one_line_per_step(tmp_path: Path) -> None:
    repo, env = sandbox(tmp_path)
    proc = run_setup(repo, env)
    out = proc.stdout + proc.stderr
    assert proc.returncode == 0, out
    assert out.splitlines() == [
        "setup: installing gcc libc6-dev with apt-get",
        "setup: installing chromium with apt-get (for the live view's browser test)"], out
    assert not list(tmp_path.glob("armbench-setup.*")), "logs of steps that worked are removed"


@pytest.mark.skipif(BASH is None or os.name != "posix", reason="needs bash on POSIX")
def test_a_failed_install_shows_apts_own_words_and_stops(tmp_path: Path) -> None:
    repo, env = sandbox(tmp_path)
    proc = run_setup(repo, env, APT_FAIL="libc6-dev")
    assert proc.returncode == 100, proc.stdout + proc.stderr
    err = proc.stderr.splitlines()
    assert "setup: apt-get install gcc libc6-dev failed (exit 100); the last lines of its " \
           "output (" in err[1], proc.stderr
    assert err[-1] == "E: Unable to locate package libc6-dev", proc.stderr
    assert "Setting up libgcc-40 (1.0-40) ..." in err  # what came before the failure
    assert len(err) <= 2 + 25, proc.stderr


@pytest.mark.skipif(BASH is None or os.name != "posix", reason="needs bash on POSIX")
def test_chromium_failing_is_a_warning_with_the_reason(tmp_path: Path) -> None:
    repo, env = sandbox(tmp_path)
    proc = run_setup(repo, env, APT_FAIL="chromium")
    assert proc.returncode == 0, proc.stdout + proc.stderr
    err = proc.stderr
    assert "E: Unable to locate package chromium" in err
    assert err.rstrip().endswith("setup: could not install chromium: the browser test of the "
                                 "live view will skip"), err
    assert "Selecting previously unselected package libgcc-1." not in err  # gcc's went well
