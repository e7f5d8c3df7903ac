#!/usr/bin/env bash
# Sets up bomc-bt in ./.venv: Python >= 3.10 venv, the package (editable) and its test tools.
# Safe to run again: it only installs what is missing.
set -euo pipefail
cd "$(dirname "$0")/.."

PY=${PYTHON:-python3}
if ! "$PY" -c 'import sys; sys.exit(sys.version_info < (3, 10))' 2>/dev/null; then
  echo "setup: bomc-bt needs Python >= 3.10 (py_trees 2.x); set PYTHON=/path/to/python3.11" >&2
  exit 2
fi

apt_install() {  # best effort: only where we are root and apt exists
  if [ "$(id -u)" = 0 ] && command -v apt-get >/dev/null; then
    DEBIAN_FRONTEND=noninteractive apt-get install -y -q "$@" >/dev/null 2>&1 \
      || { apt-get update -q >/dev/null 2>&1 && DEBIAN_FRONTEND=noninteractive apt-get install -y -q "$@" >/dev/null 2>&1; } \
      || return 1
  else
    return 1
  fi
}

if [ ! -x .venv/bin/python ]; then
  if ! "$PY" -m venv .venv 2>/dev/null; then
    rm -rf .venv
    apt_install python3-venv || { echo "setup: cannot create a venv (install python3-venv)" >&2; exit 2; }
    "$PY" -m venv .venv
  fi
fi

stamp=.venv/.bomc-installed
# constraints.txt pins every package's version: the same arithmetic (numpy, OpenCV) on any
# machine set up later, so benchmark numbers and CI reproduce.
if [ ! -f "$stamp" ] || [ pyproject.toml -nt "$stamp" ] || [ constraints.txt -nt "$stamp" ]; then
  .venv/bin/python -m pip install -q --upgrade pip >/dev/null
  .venv/bin/python -m pip install -q -c constraints.txt -e ".[test]"
  touch "$stamp"
fi
# Optional system packages: ROS 1 (Debian's, for --ros, sim-ros and tests/test_ros.py),
# Chromium with its driver (the viewer tests) and PostgreSQL (the central store's tests start
# their own server with initdb / pg_ctl; as root they run it as the package's 'postgres' user). Best effort: installed only where we are root
# and apt-get exists; without them those tests skip and say why, and setup still succeeds.
optional="$(.venv/bin/python -c 'from bomc_bt.ros import APT_PACKAGES; print(APT_PACKAGES)') chromium chromium-driver postgresql"
missing=""
for pkg in $optional; do
  dpkg -s "$pkg" >/dev/null 2>&1 || missing="$missing $pkg"
done
if [ -n "$missing" ]; then
  # shellcheck disable=SC2086  # one word per package
  if apt_install $missing; then
    echo "setup: installed$missing"
  else
    echo "setup: optional packages missing (ROS / viewer / central-store tests will skip): as root, apt-get install -y$missing" >&2
  fi
fi
echo "setup: ready (.venv/bin/bomc)"
