#!/usr/bin/env bash
# Toolchains for the mROS backend tests (called by .ci/setup.sh --test with $SUDO set; idempotent, quiet):
#   host:   g++ (C++98 syntax checks, the wire-format and behaviour harnesses)
#   target: Debian's arm-none-eabi GCC 12 with binutils, newlib and the libstdc++ headers (Cortex-A9
#           objects, arm-none-eabi-nm/-size, the footprint benchmark)
# MROS_FULL_TOOLCHAIN=1 also installs libstdc++-arm-none-eabi-newlib (313 MB download, 1.5 GB installed),
# which is only needed to *link* a Cortex-A9 image; the tests compile objects and check their symbols.
set -euo pipefail
SUDO="${SUDO-}"

want=(g++ gcc-arm-none-eabi binutils-arm-none-eabi libnewlib-arm-none-eabi libstdc++-arm-none-eabi-dev)
if [ "${MROS_FULL_TOOLCHAIN:-0}" = 1 ]; then want+=(libstdc++-arm-none-eabi-newlib); fi

missing=()
for pkg in "${want[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$pkg" 2>/dev/null | grep -q "install ok installed"; then missing+=("$pkg"); fi
done
if [ "${#missing[@]}" -gt 0 ]; then
  if ! command -v apt-get >/dev/null; then
    echo "setup-mros: please install these packages yourself: ${missing[*]}" >&2; exit 1
  fi
  log="$(mktemp)"
  if ! { $SUDO apt-get update -qq && DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq \
         --no-install-recommends "${missing[@]}"; } >"$log" 2>&1; then
    cat "$log" >&2; rm -f "$log"
    echo "setup-mros: installing ${missing[*]} failed" >&2; exit 1
  fi
  rm -f "$log"
fi
for tool in g++ arm-none-eabi-g++ arm-none-eabi-gcc arm-none-eabi-ld arm-none-eabi-nm arm-none-eabi-size; do
  command -v "$tool" >/dev/null || { echo "setup-mros: $tool not found after installation" >&2; exit 1; }
done
