#!/usr/bin/env bash
# Time a whole printapp command as an earlier commit runs it and as the working tree does, in turn.
#
#   bash scripts/compare-commits.sh REV REPEATS ARGS...
#   e.g. bash scripts/compare-commits.sh 5adbedc 4 demo
#        bash scripts/compare-commits.sh 5adbedc 1 design examples/part_relief.toml --force
#        OUT_EXT=.sl1 bash scripts/compare-commits.sh 98f5701 5 slice /path/to/model.stl
#
# OUT_EXT is appended to the output's name (`slice` writes a file that must end in .sl1;
# `demo` and `design` write a folder, the default).
# REV is checked out into a temporary worktree that runs on this checkout's .venv (its
# packages first on PYTHONPATH), its numba kernels compiled once into its own cache before
# any timing. Each repeat runs REV, then the working tree, so that a load on the machine falls
# on both alike (the machine is shared: compare the two medians, never a single time).
# Outputs go to temporary folders (or files); prints each time (with a design's stages from its
# manifest, where it writes one) and the two medians.
set -euo pipefail
rev=$1
repeats=$2
shift 2
root=$(cd "$(dirname "$0")/.." && pwd)
python="$root/.venv/bin/python"
base=$(mktemp -d)
trap 'git -C "$root" worktree remove --force "$base/tree" >/dev/null 2>&1 || true; rm -rf "$base"' EXIT
git -C "$root" worktree add --detach "$base/tree" "$rev" >/dev/null
(cd "$base/tree" && PYTHONPATH="$base/tree" "$python" -m printapp warmup --quiet >/dev/null)
# Design files named relative to the checkout are read from the working tree by both.
args=()
for arg in "$@"; do
    if [ -e "$root/$arg" ]; then args+=("$root/$arg"); else args+=("$arg"); fi
done
times_rev=()
times_now=()
for _ in $(seq "$repeats"); do
    for which in rev now; do
        if [ "$which" = rev ]; then tree="$base/tree"; else tree="$root"; fi
        start=$(date +%s.%N)
        (cd "$tree" && PYTHONPATH="$tree" "$python" -m printapp "${args[@]}" -o "$base/out-$which${OUT_EXT:-}" --quiet \
            >/dev/null 2>&1) || echo "($which exited $?)"
        seconds=$(awk -v a="$start" -v b="$(date +%s.%N)" 'BEGIN {printf "%.2f", b - a}')
        manifest="$base/out-$which${OUT_EXT:-}/manifest.json"
        if [ -f "$manifest" ]; then
            # A design's own stages, as its manifest records them (background ones included).
            stages=$("$python" -c 'import json, sys
stages = json.load(open(sys.argv[1]))["stages_s"]
print(" ".join(f"{k}={v:.2f}" for k, v in stages.items()))' "$manifest")
            echo "$which $seconds  $stages"
        else
            echo "$which $seconds"
        fi
        if [ "$which" = rev ]; then times_rev+=("$seconds"); else times_now+=("$seconds"); fi
    done
done
median() { printf '%s\n' "$@" | sort -n | awk '{a[NR]=$1} END {print (NR % 2) ? a[(NR + 1) / 2] : (a[NR / 2] + a[NR / 2 + 1]) / 2}'; }
echo "median: $rev $(median "${times_rev[@]}") s, working tree $(median "${times_now[@]}") s"
