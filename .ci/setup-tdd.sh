#!/usr/bin/env bash
# A real W3C WoT Thing Description Directory for the discovery tests (tests/runtime/test_discovery*.py): the
# Eclipse Thingweb Domus TDD API on an Oxigraph SPARQL server, pinned PyPI packages (.ci/tdd-requirements.txt)
# in their own virtual environment, .cache/tdd/venv (their dependencies are not td2adaptor's). Domus frames
# JSON-LD with node, so node is installed too. Called by .ci/setup.sh --test; idempotent and quiet.
set -euo pipefail
cd "$(dirname "$0")/.."

SUDO="${SUDO-}"
VENV=.cache/tdd/venv
REQUIREMENTS=.ci/tdd-requirements.txt
STAMP="$VENV/installed-requirements.txt"

. .ci/node.sh
ensure_node setup-tdd "the discovery tests skip without a directory" || exit 1

if [ -f "$STAMP" ] && cmp -s "$STAMP" "$REQUIREMENTS" && [ -x "$VENV/bin/flask" ] && [ -x "$VENV/bin/oxigraph" ]; then
  exit 0
fi
PY="${PYTHON:-python3}"
rm -rf "$VENV"
mkdir -p "$(dirname "$VENV")"
"$PY" -m venv "$VENV"
log="$(mktemp)"
if ! "$VENV/bin/python" -m pip install -q --no-deps -r "$REQUIREMENTS" >"$log" 2>&1; then
  cat "$log" >&2; rm -f "$log"
  echo "setup-tdd: pip install -r $REQUIREMENTS into $VENV failed" >&2
  exit 1
fi
rm -f "$log"
"$VENV/bin/python" -m pip check >/dev/null || { "$VENV/bin/python" -m pip check >&2; exit 1; }
cp "$REQUIREMENTS" "$STAMP"
