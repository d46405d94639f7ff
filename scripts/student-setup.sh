#!/usr/bin/env bash
# Student set-up for the labs (docs/student-setup.md): a local virtual environment with only
# what the labs run (the armbench package with its pinned runtime dependencies, and pytest for
# Lab 4), without the developer tools and reference libraries of scripts/setup.sh.
# Idempotent. ARMBENCH_VENV=DIR puts the environment elsewhere (default .venv).
set -euo pipefail
cd "$(dirname "$0")/.."
venv="${ARMBENCH_VENV:-.venv}"
missing=()
command -v cc >/dev/null 2>&1 || missing+=("a C compiler (Debian/Ubuntu: sudo apt-get install gcc libc6-dev)")
if ! command -v python3 >/dev/null 2>&1; then
  missing+=("Python 3.11 or newer (Debian/Ubuntu: sudo apt-get install python3 python3-venv)")
elif ! python3 -c 'import sys; sys.exit(sys.version_info < (3, 11))'; then
  missing+=("Python 3.11 or newer (found $(python3 -V 2>&1))")
fi
if ((${#missing[@]})); then
  printf 'student-setup: missing %s\n' "${missing[@]}" >&2
  echo "student-setup: on Windows, run this inside WSL 2 (docs/student-setup.md)" >&2
  exit 1
fi
if [ ! -x "$venv/bin/python" ]; then
  python3 -m venv "$venv" || {
    echo "student-setup: python3 -m venv failed (Debian/Ubuntu: sudo apt-get install python3-venv)" >&2
    exit 1
  }
fi
"$venv/bin/python" -m pip install -q --upgrade pip
# pytest's pin is the one of the dev extra in pyproject.toml.
pytest_pin="$(grep -o '"pytest==[^"]*"' pyproject.toml | head -1 | tr -d '"')"
"$venv/bin/python" -m pip install -q -e . "${pytest_pin:-pytest}"
# The first compile builds and caches the library: a lab then starts in about a second.
"$venv/bin/python" - <<'PY'
from armbench.compiler import compile_files

mod = compile_files(["st/ArmAngles.st", "st/Kinematics.st"])
xyz = mod.call("ForwardKinematic_V1", Angles={"Base": 30.0, "Shoulder": 45.0, "Elbow": 100.0},
               Geometry={})
print("student-setup: ready; FK(30, 45, 100) = ({X:.2f}, {Y:.2f}, {Z:.2f}) mm".format(**xyz))
PY
echo "student-setup: start with docs/labs/lab1-fk-ik-python.md, using $venv/bin/python"
