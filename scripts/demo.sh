#!/usr/bin/env bash
# The README's main command: set up, then run the demo (soft PLC drives the arm over Modbus).
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
exec .venv/bin/armbench demo "$@"
