#!/usr/bin/env bash
# amqtt (pinned, from PyPI) into its own venv under .cache/amqtt: a second, independent MQTT broker
# implementation, so the MQTT tests show the edge node needs nothing mosquitto-specific. Its own venv keeps
# its dependencies (websockets, transitions, ...) out of td2adaptor's. Called by .ci/setup.sh --test;
# idempotent and quiet.
set -euo pipefail
cd "$(dirname "$0")/.."

VERSION=0.12.1
VENV=.cache/amqtt/venv
PY="${PYTHON:-python3}"

if [ -x "$VENV/bin/amqtt" ] && [ "$("$VENV/bin/python" -c 'import importlib.metadata as m; print(m.version("amqtt"))' 2>/dev/null)" = "$VERSION" ]; then
  exit 0
fi
rm -rf "$VENV"
"$PY" -m venv "$VENV"
log="$(mktemp)"
if ! "$VENV/bin/python" -m pip install -q --disable-pip-version-check "amqtt==$VERSION" >"$log" 2>&1; then
  cat "$log" >&2; rm -f "$log"
  echo "setup-amqtt: pip install amqtt==$VERSION failed" >&2
  exit 1
fi
rm -f "$log"
[ -x "$VENV/bin/amqtt" ] || { echo "setup-amqtt: $VENV/bin/amqtt is missing" >&2; exit 1; }
