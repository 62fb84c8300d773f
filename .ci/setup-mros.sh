#!/usr/bin/env bash
# Toolchains for the mROS backend tests (called by .ci/setup.sh --test with $SUDO set; idempotent, quiet):
#   host:   g++ (C++98 syntax checks, the wire-format and behaviour harnesses), make
#   target: Debian's arm-none-eabi GCC 12 with binutils, newlib, the libstdc++ headers and newlib's libstdc++
#           (libstdc++-arm-none-eabi-newlib, ~300 MB: linking a whole mROS image, asp.elf/asp.bin)
#   TOPPERS configurator: Boost headers and libraries, to build it from the source in the mROS tree
#           (tests/backends/mros/real_tree.py; the tree itself is test material beside the repository)
set -euo pipefail
SUDO="${SUDO-}"
. "$(dirname "${BASH_SOURCE[0]}")/apt.sh"  # apt_install: waits for another apt's locks

want=(g++ make gcc-arm-none-eabi binutils-arm-none-eabi libnewlib-arm-none-eabi libstdc++-arm-none-eabi-dev
      libstdc++-arm-none-eabi-newlib
      libboost-dev libboost-program-options-dev libboost-filesystem-dev libboost-regex-dev libboost-system-dev)

missing=()
for pkg in "${want[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$pkg" 2>/dev/null | grep -q "install ok installed"; then missing+=("$pkg"); fi
done
if [ "${#missing[@]}" -gt 0 ]; then
  if ! command -v apt-get >/dev/null; then
    echo "setup-mros: please install these packages yourself: ${missing[*]}" >&2; exit 1
  fi
  log="$(mktemp)"
  if ! { apt_install "${missing[@]}"; } >"$log" 2>&1; then
    cat "$log" >&2; rm -f "$log"
    echo "setup-mros: installing ${missing[*]} failed" >&2; exit 1
  fi
  rm -f "$log"
fi
for tool in g++ arm-none-eabi-g++ arm-none-eabi-gcc arm-none-eabi-ld arm-none-eabi-nm arm-none-eabi-size; do
  command -v "$tool" >/dev/null || { echo "setup-mros: $tool not found after installation" >&2; exit 1; }
done
