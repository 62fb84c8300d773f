#!/usr/bin/env bash
# Set up td2adaptor in ./.venv on a fresh Debian/Ubuntu machine (root, or sudo available).
#   bash .ci/setup.sh          the tool itself
#   bash .ci/setup.sh --test   plus everything the test suite needs
set -euo pipefail
cd "$(dirname "$0")/.."

want_test=0
for arg in "$@"; do
  case "$arg" in
    --test) want_test=1 ;;
    *) echo "usage: $0 [--test]" >&2; exit 2 ;;
  esac
done

SUDO=""
if [ "$(id -u)" != 0 ] && command -v sudo >/dev/null; then SUDO="sudo"; fi
# apt_get/apt_install wait while another package manager holds the dpkg or package-list lock
. .ci/apt.sh
install_packages() {
  if ! command -v apt-get >/dev/null; then
    echo "setup: please install these packages yourself: $*" >&2; return 1
  fi
  apt_install "$@" >/dev/null
}

PY="${PYTHON:-python3}"
if ! command -v "$PY" >/dev/null; then install_packages python3 python3-venv; fi
"$PY" - <<'PYCHECK' || { echo "setup: Python >= 3.10 is required" >&2; exit 1; }
import sys
raise SystemExit(sys.version_info < (3, 10))
PYCHECK

if [ ! -x .venv/bin/python ]; then
  if ! "$PY" -m venv .venv 2>/dev/null; then
    rm -rf .venv
    install_packages python3-venv
    "$PY" -m venv .venv
  fi
fi
.venv/bin/python -m pip install -q --upgrade pip >/dev/null 2>&1 || true
if [ "$want_test" = 1 ]; then
  .venv/bin/python -m pip install -q -e '.[test]'
  # what the real-middleware tests need (ROS 2 wheels, ROS 1 from Debian, cross compiler, broker, ...)
  for part in .ci/setup-*.sh; do
    [ -e "$part" ] || continue
    echo "setup: $part"
    SUDO="$SUDO" bash "$part"
  done
else
  .venv/bin/python -m pip install -q -e .
fi
echo "setup: td2adaptor $(.venv/bin/td2adaptor --version | cut -d' ' -f2) ready in .venv"
