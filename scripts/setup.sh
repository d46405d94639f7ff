#!/usr/bin/env bash
# Set-up shared by the README commands: a C compiler (Debian) and a local virtual environment
# with the Python packages at the locked versions (tests/packaging/constraints-current.txt). Idempotent; safe to run on every invocation.
set -euo pipefail
cd "$(dirname "$0")/.."
need_apt=()
command -v cc >/dev/null 2>&1 || need_apt+=(gcc libc6-dev)
command -v python3 >/dev/null 2>&1 || need_apt+=(python3 python3-venv)
if ((${#need_apt[@]})); then
  if [ "$(id -u)" = 0 ]; then
    apt-get update -qq && apt-get install -y -qq "${need_apt[@]}"
  else
    echo "setup: missing ${need_apt[*]}: install them (Debian: sudo apt-get install ${need_apt[*]})" >&2
    exit 1
  fi
fi
# The live view's browser test drives Debian's chromium (Playwright never downloads a browser
# here); without it that test skips, saying why, so it is installed only where apt-get can.
if ! command -v chromium >/dev/null 2>&1; then
  if [ "$(id -u)" = 0 ] && command -v apt-get >/dev/null 2>&1; then
    (apt-get update -qq && apt-get install -y -qq --no-install-recommends chromium) \
      || echo "setup: could not install chromium: the browser test of the live view will skip" >&2
  else
    echo "setup: chromium is missing (Debian: sudo apt-get install --no-install-recommends chromium): the browser test of the live view will skip" >&2
  fi
fi
if [ ! -x .venv/bin/python ]; then
  python3 -m venv .venv
fi
stamp=.venv/.armbench-installed
lock=tests/packaging/constraints-current.txt
if [ ! -f "$stamp" ] || [ pyproject.toml -nt "$stamp" ] || [ "$lock" -nt "$stamp" ]; then
  .venv/bin/python -m pip install -q --upgrade pip
  .venv/bin/python -m pip install -q -e ".[dev]" -c tests/packaging/constraints-current.txt
  touch "$stamp"
fi
