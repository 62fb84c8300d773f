# Sourced by the .ci/setup-*.sh parts that install npm packages (not run on its own).
# ensure_node PART WHY: node and npm on PATH, installed with apt when missing; PART names the caller in
# messages, WHY says what does without them. Uses $SUDO like the callers.
. "$(dirname "${BASH_SOURCE[0]}")/apt.sh"  # apt_install: waits for another apt's locks
ensure_node() {
  local part="$1" why="$2" log
  if command -v npm >/dev/null && command -v node >/dev/null; then
    return 0
  fi
  if ! command -v apt-get >/dev/null; then
    echo "$part: no apt-get; install node and npm yourself ($why)" >&2
    return 1
  fi
  log="$(mktemp)"
  if ! { apt_install nodejs npm; } >"$log" 2>&1; then
    cat "$log" >&2; rm -f "$log"
    echo "$part: installing nodejs and npm failed" >&2
    return 1
  fi
  rm -f "$log"
}
