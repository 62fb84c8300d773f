#!/usr/bin/env bash
# Headless Chromium and its WebDriver from Debian packages, for the dashboard's browser tests (Selenium drives the
# system's browser: nothing is downloaded at test time). Called by .ci/setup.sh --test with $SUDO set ("" as root,
# "sudo" otherwise). Idempotent and quiet.
set -euo pipefail

SUDO="${SUDO-}"
. "$(dirname "${BASH_SOURCE[0]}")/apt.sh"  # apt_install: waits for another apt's locks
PACKAGES=(chromium chromium-driver)

if ! command -v apt-get >/dev/null; then
  echo "setup-browser: no apt-get; install these Debian packages yourself: ${PACKAGES[*]}" >&2
  exit 1
fi

missing=()
for pkg in "${PACKAGES[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$pkg" 2>/dev/null | grep -q "install ok installed"; then
    missing+=("$pkg")
  fi
done

if [ "${#missing[@]}" -gt 0 ]; then
  log="$(mktemp)"
  if ! { apt_install "${missing[@]}"; } >"$log" 2>&1; then
    cat "$log" >&2; rm -f "$log"
    echo "setup-browser: installing ${missing[*]} failed" >&2
    exit 1
  fi
  rm -f "$log"
fi

command -v chromium >/dev/null || { echo "setup-browser: chromium is not on PATH" >&2; exit 1; }
command -v chromedriver >/dev/null || { echo "setup-browser: chromedriver is not on PATH" >&2; exit 1; }
