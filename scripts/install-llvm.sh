#!/bin/sh
# Make a shared libLLVM >= 16 available for Mitsuba's llvm_ad_rgb variant (Debian: libllvm19).
# Without root or apt-get, print one warning line and carry on: printapp then renders on
# Mitsuba's scalar_rgb variant.
have_llvm() {
    for f in /usr/lib/*/libLLVM*.so* /usr/lib/libLLVM*.so* /usr/lib/llvm-*/lib/libLLVM*.so*; do
        [ -e "$f" ] || continue
        major=$(basename "$f" | sed -n -e 's/^libLLVM-\([0-9][0-9]*\).*/\1/p' -e 's/^libLLVM\.so\.\([0-9][0-9]*\).*/\1/p')
        [ -n "$major" ] && [ "$major" -ge 16 ] && return 0
    done
    return 1
}
have_llvm && exit 0
if command -v apt-get >/dev/null 2>&1; then
    if [ "$(id -u)" = 0 ]; then SUDO=""; elif command -v sudo >/dev/null 2>&1 && sudo -n true 2>/dev/null; then SUDO="sudo -n"; else SUDO=none; fi
    if [ "$SUDO" != none ]; then
        if $SUDO apt-get install -y -q libllvm19 >/dev/null 2>&1 || { $SUDO apt-get update -q >/dev/null 2>&1 && $SUDO apt-get install -y -q libllvm19 >/dev/null 2>&1; }; then
            have_llvm && exit 0
        fi
    fi
fi
echo "warning: could not install libllvm19 (needs apt-get and root); printapp will render on Mitsuba's slower scalar_rgb variant" >&2
exit 0
