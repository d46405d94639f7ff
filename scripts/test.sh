#!/usr/bin/env bash
# The test command of the README (and of CI): set up, lint, type-check, then the test suites.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
# the docs site's build test needs the docs extra
.venv/bin/python -c "import mkdocs, latex2mathml" 2>/dev/null \
  || .venv/bin/python -m pip install -q --disable-pip-version-check -e ".[docs]" -c tests/packaging/constraints-current.txt
.venv/bin/ruff check sim tests bench
.venv/bin/mypy sim
.venv/bin/armbench check st/
# Two pytest-xdist workers where there are two CPUs: the suites are safe in parallel (free
# ports, per-worker soft PLCs, atomic build cache) and on 2 cores this cut the run from 269 s
# to 165 s (docs/parallel-runs.md). ARMBENCH_TEST_WORKERS=N chooses, 0 runs in one process.
workers="${ARMBENCH_TEST_WORKERS:-$( [ "$(nproc 2>/dev/null || echo 1)" -ge 2 ] && echo 2 || echo 0 )}"
set +e
.venv/bin/python -m pytest -n "$workers" "$@"
rc=$?
set -e
if [ "$rc" = 5 ]; then echo "test.sh: pytest collected no tests" >&2; exit 1; fi
exit "$rc"
