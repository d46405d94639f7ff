#!/usr/bin/env bash
# Prints every lab as a PDF handout into handouts/ (offline): builds the site with
# scripts/docs.sh, then Chromium prints each lab page (armbench.handouts). Needs the developer
# set-up (bash scripts/setup.sh: chromium and Playwright).
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/docs.sh
.venv/bin/python -m armbench.handouts --site site --out handouts "$@"
