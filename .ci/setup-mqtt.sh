#!/usr/bin/env bash
# Mosquitto (MQTT broker) from Debian packages, for the event runtime's real-broker tests.
# Called by .ci/setup.sh --test with $SUDO set ("" as root, "sudo" otherwise). Idempotent and quiet.
# The tests start their own broker on a free loopback port; the packaged system service is stopped and
# disabled so it never holds port 1883 (or anything else) in their way.
set -euo pipefail

SUDO="${SUDO-}"
. "$(dirname "${BASH_SOURCE[0]}")/apt.sh"  # apt_install: waits for another apt's locks
PACKAGES=(mosquitto mosquitto-clients openssl)  # openssl: the TLS tests make their own certificates

if ! command -v apt-get >/dev/null; then
  echo "setup-mqtt: no apt-get; install these Debian packages yourself: ${PACKAGES[*]}" >&2
  exit 1
fi

missing=()
for pkg in "${PACKAGES[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$pkg" 2>/dev/null | grep -q "install ok installed"; then
    missing+=("$pkg")
  fi
done

if [ "${#missing[@]}" -gt 0 ]; then
  # No service may start while installing (containers without systemd, and machines with it alike).
  policy_added=0
  if [ ! -e /usr/sbin/policy-rc.d ]; then
    printf '#!/bin/sh\nexit 101\n' | $SUDO tee /usr/sbin/policy-rc.d >/dev/null
    $SUDO chmod 755 /usr/sbin/policy-rc.d
    policy_added=1
  fi
  log="$(mktemp)"
  if ! { apt_install "${missing[@]}"; } >"$log" 2>&1; then
    cat "$log" >&2; rm -f "$log"
    if [ "$policy_added" = 1 ]; then $SUDO rm -f /usr/sbin/policy-rc.d; fi
    echo "setup-mqtt: installing ${missing[*]} failed" >&2
    exit 1
  fi
  rm -f "$log"
  if [ "$policy_added" = 1 ]; then $SUDO rm -f /usr/sbin/policy-rc.d; fi
fi

# A system broker left running (systemd, or sysvinit inside containers) must not hold the default port.
if command -v systemctl >/dev/null && [ -d /run/systemd/system ]; then
  $SUDO systemctl disable --now mosquitto >/dev/null 2>&1 || true
elif [ -x /etc/init.d/mosquitto ]; then
  $SUDO /etc/init.d/mosquitto stop >/dev/null 2>&1 || true
fi

MOSQ=/usr/sbin/mosquitto
[ -x "$MOSQ" ] || MOSQ="$(command -v mosquitto || true)"
[ -n "$MOSQ" ] && [ -x "$MOSQ" ] || { echo "setup-mqtt: mosquitto is not installed" >&2; exit 1; }
command -v mosquitto_passwd >/dev/null || { echo "setup-mqtt: mosquitto_passwd is not on PATH" >&2; exit 1; }
command -v openssl >/dev/null || { echo "setup-mqtt: openssl is not on PATH" >&2; exit 1; }
