#!/usr/bin/env bash
# pyright (pinned, from npm) into .cache/pyright, for the test that type-checks the generated Python adaptors
# in strict mode. Called by .ci/setup.sh --test; idempotent and quiet. Needs node and npm (Debian: nodejs npm).
set -euo pipefail
cd "$(dirname "$0")/.."

SUDO="${SUDO-}"
VERSION=1.1.414
PREFIX=.cache/pyright
BIN="$PREFIX/node_modules/.bin/pyright"

. .ci/node.sh
ensure_node setup-pyright "the pyright test skips without them" || exit 1

if [ -x "$BIN" ] && [ "$("$BIN" --version 2>/dev/null)" = "pyright $VERSION" ]; then
  exit 0
fi
mkdir -p "$PREFIX"
log="$(mktemp)"
if ! npm install --prefix "$PREFIX" --no-audit --no-fund --silent "pyright@$VERSION" >"$log" 2>&1; then
  cat "$log" >&2; rm -f "$log"
  echo "setup-pyright: npm install pyright@$VERSION failed" >&2
  exit 1
fi
rm -f "$log"
[ "$("$BIN" --version)" = "pyright $VERSION" ] || { echo "setup-pyright: $BIN is not pyright $VERSION" >&2; exit 1; }
