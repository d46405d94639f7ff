#!/usr/bin/env bash
# The lower ends of pyproject.toml's dependency ranges, tested (CI runs this after
# scripts/test.sh): a second virtual environment, .venv-lowest, holds every dependency at its
# lower bound (tests/packaging/constraints-lowest.txt, and the oldest setuptools of
# [build-system], which builds the editable install) and runs the suites of the modules that
# use each dependency. Arguments go to pytest. Idempotent: the environment is rebuilt only
# when pyproject.toml or the constraints change.
set -euo pipefail
cd "$(dirname "$0")/.."
constraints=tests/packaging/constraints-lowest.txt
venv=.venv-lowest
# the oldest Python of requires-python where the machine has it
python=$(command -v python3.11 || command -v python3)
if [ ! -x "$venv/bin/python" ]; then
  "$python" -m venv "$venv"
fi
stamp=$venv/.armbench-installed
if [ ! -f "$stamp" ] || [ pyproject.toml -nt "$stamp" ] || [ "$constraints" -nt "$stamp" ]; then
  "$venv/bin/python" -m pip install -q --disable-pip-version-check --upgrade pip
  "$venv/bin/python" -m pip install -q --disable-pip-version-check -c "$constraints" setuptools
  "$venv/bin/python" -m pip install -q --disable-pip-version-check -c "$constraints" \
    --no-build-isolation -e . pytest hypothesis pytest-xdist
  touch "$stamp"
fi
# Every package the constraints name is installed at exactly that version (pip would have
# refused a conflict, but a stale environment would not say so).
"$venv/bin/python" - "$constraints" <<'PY'
import sys
from importlib import metadata

wrong = []
for line in open(sys.argv[1], encoding="utf-8"):
    line = line.split("#", 1)[0].strip()
    if line:
        name, version = line.split("==")
        have = metadata.version(name)
        if have != version:
            wrong.append(f"{name} {have} (want {version})")
if wrong:
    sys.exit("test-lowest: .venv-lowest does not hold the lowest versions: " + ", ".join(wrong))
print("test-lowest: lowest versions installed:", sys.version.split()[0],
      ", ".join(ln.split("#")[0].strip() for ln in open(sys.argv[1], encoding="utf-8")
                if ln.split("#")[0].strip()))
PY
# One suite per dependency, less its slowest tests (-k; about 3 min on 2 cores): tree-sitter and the grammar (the
# diagnostics corpus, the nesting limits), cffi and numpy (ST blocks against the numpy
# reference), pymodbus (OpenPLC's map through a real client), numpy (plant models), lxml
# (PLCopen XML, byte for byte the committed exports), matplotlib (the figure scripts),
# starlette, uvicorn and websockets (the live view's server), pytest, pytest's plugin and tqdm
# (a PLC that does not answer; xdist workers with the progress bar), and the metadata checks.
set +e
"$venv/bin/python" -m pytest -p no:cacheprovider "$@" \
  -k "not (rebuild or write_and_check or deterministic or checks_and_compiles or nth_address or plc_share or bad_addresses or more_workers)" \
  tests/compiler/test_diagnostics.py tests/compiler/test_limits.py \
  tests/unit/test_kinematics.py \
  tests/softplc/test_softplc_modbus_map.py \
  tests/plant \
  tests/export/test_export.py \
  tests/docs/test_figure_scripts.py \
  tests/web/test_server.py \
  tests/harness/test_plugin_abort.py \
  tests/harness/test_plugin_workers.py \
  tests/packaging/test_metadata.py::test_installed_versions_are_inside_the_ranges
rc=$?
set -e
if [ "$rc" = 5 ]; then echo "test-lowest.sh: pytest collected no tests" >&2; exit 1; fi
exit "$rc"
