#!/usr/bin/env bash
# Makes sure the browser tests (tests/browser) have their browser: Debian's chromium.
#
# `make test` runs this before the suite. When the browser is there it only looks at one
# file and exits. When it is absent and this machine may install packages (root, or
# passwordless sudo, with apt-get), it installs Debian's `chromium` package; otherwise, or
# when the install fails, it says so in one line. It always exits 0: without a browser the
# browser tests skip and say why, they never fail the run for lack of one.
#
# It never downloads Playwright's own browsers (`playwright install`): Playwright only
# drives the system's chromium. CLARK_CHROMIUM names another browser binary to use.
set -u

chromium="${CLARK_CHROMIUM:-/usr/bin/chromium}"
if [ -x "$chromium" ]; then
    exit 0
fi
if [ -n "${CLARK_CHROMIUM:-}" ]; then
    echo "ensure_browser: CLARK_CHROMIUM=$chromium is not an executable; the browser tests will skip"
    exit 0
fi
if [ "$(uname -s)" != Linux ] || ! command -v apt-get >/dev/null 2>&1; then
    echo "ensure_browser: no /usr/bin/chromium and no apt-get to install it; the browser tests will skip (set CLARK_CHROMIUM to a Chromium to run them)"
    exit 0
fi
if [ "$(id -u)" -eq 0 ]; then
    as_root=(env)
elif command -v sudo >/dev/null 2>&1 && sudo -n true 2>/dev/null; then
    as_root=(sudo -n env)
else
    echo "ensure_browser: no /usr/bin/chromium, and installing it needs root or passwordless sudo; the browser tests will skip (apt-get install chromium to run them)"
    exit 0
fi

log="$(mktemp)"
trap 'rm -f "$log"' EXIT
install() {
    "${as_root[@]}" DEBIAN_FRONTEND=noninteractive \
        apt-get install -y -q --no-install-recommends chromium >>"$log" 2>&1
}
echo "ensure_browser: installing Debian's chromium for the browser tests (apt-get)"
# A fresh machine may have no package lists yet: update them only when the install needs it.
if install || { "${as_root[@]}" apt-get update -q >>"$log" 2>&1 && install; }; then
    if [ -x /usr/bin/chromium ]; then
        exit 0
    fi
    echo "ensure_browser: apt-get installed chromium but /usr/bin/chromium is absent; the browser tests will skip"
    exit 0
fi
reason="$(grep -E '^(E:|W:)' "$log" | head -n 1)"
echo "ensure_browser: could not install Debian's chromium (${reason:-apt-get failed}); the browser tests will skip"
exit 0
