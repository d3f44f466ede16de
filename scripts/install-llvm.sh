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
# `install-llvm.sh --check` only checks: the installer runs it before and after installing.
if [ "${1:-}" = --check ]; then
    have_llvm
    exit $?
fi
exec sh "$(dirname "$0")/apt-install.sh" "sh '$0' --check" \
    "printapp will render on Mitsuba's slower scalar_rgb variant" libllvm19
