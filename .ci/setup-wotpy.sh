#!/usr/bin/env bash
# wotpy (the Python WoT runtime, from PyPI, pinned) in a virtual environment of its own, .cache/wotpy: the
# WoT-consumer tests run it as an independent client of the robots' Thing Descriptions. Its own environment
# because its dependencies (amqtt, tornado, pydantic, ...) are none of td2adaptor's and must not move our pins.
# Called by .ci/setup.sh --test; idempotent and quiet. tests/runtime/test_edge_node_wotpy.py skips without it.
set -euo pipefail
cd "$(dirname "$0")/.."

VERSION="0.18.0"
VENV=.cache/wotpy
PYTHON="${PYTHON:-python3}"

if [ -x "$VENV/bin/python" ] && "$VENV/bin/python" -c "import importlib.metadata as m, sys; sys.exit(m.version('wotpy') != '$VERSION')" 2>/dev/null; then
  exit 0
fi
rm -rf "$VENV"
"$PYTHON" -m venv "$VENV"
log="$(mktemp)"
if ! "$VENV/bin/pip" install --disable-pip-version-check --quiet "wotpy==$VERSION" >"$log" 2>&1; then
  cat "$log" >&2; rm -f "$log"
  echo "setup-wotpy: pip install wotpy==$VERSION failed" >&2
  exit 1
fi
rm -f "$log"
