#!/bin/sh
# The peer tools that tests run side by side with printapp: PrusaSlicer (its SL1 layers against
# ours) and ADMesh (our STL checked by another tool). Blender, a benchmark peer only, is left to
# `make bench`'s user.
exec sh "$(dirname "$0")/apt-install.sh" "command -v prusa-slicer && command -v admesh" \
    "the tests that compare with them will be skipped" prusa-slicer admesh
