#!/usr/bin/env bash
# Eclipse Thingweb node-wot (core + MQTT binding, pinned, from npm, --ignore-scripts: pure JavaScript) into
# .cache/node-wot: the independent WoT client the edge-node tests consume the robot's published TD with.
# Called by .ci/setup.sh --test; idempotent and quiet. Needs node and npm (Debian: nodejs npm).
set -euo pipefail
cd "$(dirname "$0")/.."

SUDO="${SUDO-}"
VERSION=0.8.16  # keep in step with NODE_WOT in tests/runtime/test_edge_node_wot.py
PREFIX=.cache/node-wot

. .ci/node.sh
ensure_node setup-nodewot "the node-wot tests fail without them" || exit 1

installed() {
  local manifest="$PREFIX/node_modules/@node-wot/$1/package.json"
  [ -f "$manifest" ] && [ "$(node -p "require('./$manifest').version" 2>/dev/null)" = "$VERSION" ]
}
installed core && installed binding-mqtt && exit 0

mkdir -p "$PREFIX"
[ -f "$PREFIX/package.json" ] || echo '{"name": "td2adaptor-node-wot", "private": true}' > "$PREFIX/package.json"
log="$(mktemp)"
if ! (cd "$PREFIX" && npm install --ignore-scripts --no-audit --no-fund --loglevel=error \
    "@node-wot/core@$VERSION" "@node-wot/binding-mqtt@$VERSION") >"$log" 2>&1; then
  cat "$log" >&2; rm -f "$log"
  echo "setup-nodewot: npm install of node-wot $VERSION failed" >&2
  exit 1
fi
rm -f "$log"
installed core && installed binding-mqtt || { echo "setup-nodewot: $PREFIX lacks node-wot $VERSION" >&2; exit 1; }
