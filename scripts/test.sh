#!/usr/bin/env bash
# Sets everything up, then runs the whole test suite (what CI runs).
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
.venv/bin/ruff check bomc_bt behaviours tests benchmarks
exec .venv/bin/python -m pytest -p no:cacheprovider "$@"
