#!/usr/bin/env bash
# The test command of the README (and of CI): set up, lint, type-check, then the test suites.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
.venv/bin/ruff check sim tests bench
.venv/bin/mypy sim
.venv/bin/armbench check st/
set +e
.venv/bin/python -m pytest "$@"
rc=$?
set -e
if [ "$rc" = 5 ]; then echo "test.sh: pytest collected no tests" >&2; exit 1; fi
exit "$rc"
