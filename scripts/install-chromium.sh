#!/bin/sh
# Debian's Chromium, for the test that opens report.html in a real (headless) browser.
# Without root or apt-get, print one warning line and carry on: that one test is skipped.
command -v chromium >/dev/null 2>&1 && exit 0
if command -v apt-get >/dev/null 2>&1; then
    if [ "$(id -u)" = 0 ]; then SUDO=""; elif command -v sudo >/dev/null 2>&1 && sudo -n true 2>/dev/null; then SUDO="sudo -n"; else SUDO=none; fi
    if [ "$SUDO" != none ]; then
        if $SUDO apt-get install -y -q chromium >/dev/null 2>&1 || { $SUDO apt-get update -q >/dev/null 2>&1 && $SUDO apt-get install -y -q chromium >/dev/null 2>&1; }; then
            command -v chromium >/dev/null 2>&1 && exit 0
        fi
    fi
fi
echo "warning: could not install Debian's chromium (needs apt-get and root); the report's browser test will be skipped" >&2
exit 0
