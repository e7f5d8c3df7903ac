#!/usr/bin/env bash
# Sets everything up, then runs the whole test suite (what CI runs).
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
.venv/bin/ruff check bomc_bt behaviours tests benchmarks
# one test worker per core, at most 4 (the office-s passes, one group, take a third of the
# suite: more workers wait for them); BOMC_TEST_WORKERS=N to choose, 0 runs in this process.
# One test file per worker at a time (tests/conftest.py), the office-s passes together.
exec .venv/bin/python -m pytest -p no:cacheprovider -n "${BOMC_TEST_WORKERS:-auto}" --maxprocesses 4 \
  --dist loadgroup "$@"
