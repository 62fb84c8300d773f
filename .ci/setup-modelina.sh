#!/usr/bin/env bash
# AsyncAPI Modelina (pinned, from npm, --ignore-scripts: pure JavaScript) into .cache/modelina: the model
# generator behind `asyncapi generate models` (@asyncapi/cli 6.2 runs Modelina 5.10), with which the tests
# generate Python and TypeScript models from the events backend's AsyncAPI documents. Called by
# .ci/setup.sh --test; idempotent and quiet. Needs node and npm (Debian: nodejs npm).
set -euo pipefail
cd "$(dirname "$0")/.."

SUDO="${SUDO-}"
VERSION=5.10.1  # keep in step with MODELINA in tests/backends/events/test_asyncapi_models.py
PREFIX=.cache/modelina

. .ci/node.sh
ensure_node setup-modelina "the AsyncAPI model generation tests skip without them" || exit 1

installed() {
  local manifest="$PREFIX/node_modules/@asyncapi/modelina/package.json"
  [ -f "$manifest" ] && [ "$(node -p "require('./$manifest').version" 2>/dev/null)" = "$VERSION" ]
}
installed && exit 0

mkdir -p "$PREFIX"
[ -f "$PREFIX/package.json" ] || echo '{"name": "td2adaptor-modelina", "private": true}' > "$PREFIX/package.json"
log="$(mktemp)"
if ! (cd "$PREFIX" && npm install --ignore-scripts --save-exact --no-audit --no-fund --loglevel=error \
    "@asyncapi/modelina@$VERSION") >"$log" 2>&1; then
  cat "$log" >&2; rm -f "$log"
  echo "setup-modelina: npm install of @asyncapi/modelina $VERSION failed" >&2
  exit 1
fi
rm -f "$log"
installed || { echo "setup-modelina: $PREFIX lacks @asyncapi/modelina $VERSION" >&2; exit 1; }
