#!/usr/bin/env bash
# The W3C WoT reference data the conformance tests use as an oracle when ../shared/wot is not beside the
# repository: the official TD and TM 1.1 schemas and the Thingweb Playground corpus, pinned npm packages
# (data only: --ignore-scripts) in .cache/wot; and the AsyncAPI parser the events backend's AsyncAPI documents
# are checked with (pure JavaScript, also --ignore-scripts). Called by .ci/setup.sh --test; idempotent and quiet.
# Needs node and npm (Debian: nodejs npm). tests/wot_corpus.py says what the tests take from here.
set -euo pipefail
cd "$(dirname "$0")/.."

SUDO="${SUDO-}"
PREFIX=.cache/wot
PACKAGES=(
  "wot-thing-description-types@1.1.0-12-March-2025"
  "wot-thing-model-types@1.1.0-12-March-2025"
  "@thing-description-playground/core@1.4.0"
  "@asyncapi/parser@3.6.3"
)

. .ci/node.sh
ensure_node setup-wot "the corpus tests skip without ../shared/wot" || exit 1

installed() {  # name@version -> is that exact version in $PREFIX?
  local name="${1%@*}" version="${1##*@}" manifest
  manifest="$PREFIX/node_modules/$name/package.json"
  [ -f "$manifest" ] && [ "$(node -p "require('./$manifest').version" 2>/dev/null)" = "$version" ]
}

missing=0
for pkg in "${PACKAGES[@]}"; do installed "$pkg" || missing=1; done
[ "$missing" = 0 ] && exit 0

mkdir -p "$PREFIX"
log="$(mktemp)"
if ! npm install --prefix "$PREFIX" --ignore-scripts --save-exact --no-audit --no-fund --silent "${PACKAGES[@]}" >"$log" 2>&1; then
  cat "$log" >&2; rm -f "$log"
  echo "setup-wot: npm install ${PACKAGES[*]} failed" >&2
  exit 1
fi
rm -f "$log"
for pkg in "${PACKAGES[@]}"; do
  installed "$pkg" || { echo "setup-wot: $PREFIX has no $pkg after npm install" >&2; exit 1; }
done
