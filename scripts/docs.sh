#!/usr/bin/env bash
# Builds the documentation site from docs/ into site/ (open site/index.html; it works offline),
# in strict mode: a broken link, a missing figure or a formula that does not render fails.
# Installs the docs extra of pyproject.toml into .venv when it is missing.
set -euo pipefail
cd "$(dirname "$0")/.."
if [ ! -x .venv/bin/python ]; then
  echo "docs: no .venv: run bash scripts/student-setup.sh (or scripts/setup.sh) first" >&2
  exit 1
fi
.venv/bin/python -c 'import mkdocs, latex2mathml' 2>/dev/null \
  || .venv/bin/python -m pip install -q -e ".[docs]"
.venv/bin/python -m mkdocs build --strict "$@"
echo "docs: open site/index.html"
