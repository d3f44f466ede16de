#!/bin/sh
# Install Debian packages when apt-get and root (or password-less sudo) allow, else warn and carry on.
#
#   sh scripts/apt-install.sh CHECK WARNING PACKAGE...
#
# CHECK is a shell command that succeeds once what the packages provide is there (it is run
# before and after installing); WARNING completes "could not install PACKAGE... (needs apt-get and
# root); " in the one line printed when they cannot be installed. Always exits 0: what needs the
# packages degrades or skips, as WARNING says.
check=$1
warning=$2
shift 2
sh -c "$check" >/dev/null 2>&1 && exit 0
if command -v apt-get >/dev/null 2>&1; then
    if [ "$(id -u)" = 0 ]; then SUDO=""; elif command -v sudo >/dev/null 2>&1 && sudo -n true 2>/dev/null; then SUDO="sudo -n"; else SUDO=none; fi
    if [ "$SUDO" != none ]; then
        export DEBIAN_FRONTEND=noninteractive
        if $SUDO apt-get install -y -q "$@" >/dev/null 2>&1 || { $SUDO apt-get update -q >/dev/null 2>&1 && $SUDO apt-get install -y -q "$@" >/dev/null 2>&1; }; then
            sh -c "$check" >/dev/null 2>&1 && exit 0
        fi
    fi
fi
echo "warning: could not install $* (needs apt-get and root); $warning" >&2
exit 0
