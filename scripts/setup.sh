#!/usr/bin/env bash
# Set-up shared by the README commands: a C compiler (Debian) and a local virtual environment
# with the Python packages at the locked versions (tests/packaging/constraints-current.txt). Idempotent; safe to run on every invocation.
# Quiet when it works: apt-get's and dpkg's progress (a hundred lines and more) goes to a log
# that is shown, its last lines on stderr, only when a step fails; pip runs with -q.
set -euo pipefail
cd "$(dirname "$0")/.."

# quietly WHAT CMD...: run CMD with its output in a log; on failure say WHAT failed, show the
# log's last lines on stderr and return CMD's status (the log is kept and named).
quietly() {
  local what=$1 log rc=0
  shift
  log=$(mktemp "${TMPDIR:-/tmp}/armbench-setup.XXXXXX")
  "$@" >"$log" 2>&1 || rc=$?
  if [ "$rc" != 0 ]; then
    echo "setup: $what failed (exit $rc); the last lines of its output ($log):" >&2
    tail -n 25 "$log" >&2
    return "$rc"
  fi
  rm -f "$log"
}

apt_install() {
  apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq "$@"
}

need_apt=()
command -v cc >/dev/null 2>&1 || need_apt+=(gcc libc6-dev)
command -v python3 >/dev/null 2>&1 || need_apt+=(python3 python3-venv)
if ((${#need_apt[@]})); then
  if [ "$(id -u)" = 0 ]; then
    echo "setup: installing ${need_apt[*]} with apt-get" >&2
    quietly "apt-get install ${need_apt[*]}" apt_install "${need_apt[@]}"
  else
    echo "setup: missing ${need_apt[*]}: install them (Debian: sudo apt-get install ${need_apt[*]})" >&2
    exit 1
  fi
fi
# The live view's browser test drives Debian's chromium (Playwright never downloads a browser
# here); without it that test skips, saying why, so it is installed only where apt-get can.
if ! command -v chromium >/dev/null 2>&1; then
  if [ "$(id -u)" = 0 ] && command -v apt-get >/dev/null 2>&1; then
    echo "setup: installing chromium with apt-get (for the live view's browser test)" >&2
    quietly "apt-get install chromium" apt_install --no-install-recommends chromium \
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
  .venv/bin/python -m pip install -q --disable-pip-version-check --upgrade pip
  .venv/bin/python -m pip install -q --disable-pip-version-check -e ".[dev]" -c tests/packaging/constraints-current.txt
  touch "$stamp"
fi
