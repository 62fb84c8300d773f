# Sourced by .ci/setup.sh and its parts (not run on its own). apt-get that waits while another package manager
# (unattended-upgrades on a fresh machine, a second setup, an admin's apt) holds a lock, instead of failing:
#   apt_get ARGS...      apt-get ARGS as root (${SUDO-}), non-interactive, its output on stdout
#   apt_install PKG...   update the package lists once per shell, then install PKG... without recommends
# Both wait up to TD2ADAPTOR_APT_LOCK_TIMEOUT seconds (default 900), saying so once. A command that failed on a
# lock runs again: with apt's own documented wait for the dpkg lock (-o DPkg::Lock::Timeout) and, since that does
# not cover the package lists' lock `apt-get update` takes (apt 2.6), every two seconds, until the limit.
TD2ADAPTOR_APT_LOCK_TIMEOUT="${TD2ADAPTOR_APT_LOCK_TIMEOUT:-900}"
_td2adaptor_apt_updated=0

apt_get() {
  local log status start=$SECONDS left wait_opt=()
  log="$(mktemp)"
  while :; do
    status=0
    ${SUDO-} env DEBIAN_FRONTEND=noninteractive apt-get ${wait_opt[@]+"${wait_opt[@]}"} "$@" >"$log" 2>&1 \
      || status=$?
    left=$((TD2ADAPTOR_APT_LOCK_TIMEOUT - (SECONDS - start)))
    if [ "$status" = 0 ] || [ "$left" -le 0 ] || ! grep -q "Could not get lock" "$log"; then
      cat "$log"; rm -f "$log"
      return "$status"
    fi
    if [ "${#wait_opt[@]}" = 0 ]; then
      echo "apt: another package manager holds a lock ($(grep -m1 "Could not get lock" "$log" | cut -c4-));" \
        "waiting for it, at most ${TD2ADAPTOR_APT_LOCK_TIMEOUT} s" >&2
    else
      sleep 2
    fi
    wait_opt=(-o "DPkg::Lock::Timeout=$left")
  done
}

apt_install() {
  if [ "$_td2adaptor_apt_updated" = 0 ]; then
    apt_get update -qq || return
    _td2adaptor_apt_updated=1
  fi
  apt_get install -y -qq --no-install-recommends "$@"
}
