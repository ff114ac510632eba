#!/usr/bin/env bash
# The closed-loop study of issue 8: `idi-rmp sim` on every track under rmp/app/tracks at 0.5 and
# 1.0 m/s (rendered cameras, stereo tape perception, planner, the RMP over the virtual CAN bus), one
# summary line per run, and each run's JSON report and plot under OUT (default results/rmp-tracks).
# Usage: tests/bench/rmp_tracks.sh [BUILD_DIR=build/default] [OUT=results/rmp-tracks] [SPEEDS="0.5 1.0"]
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/../.."
build="${1:-build/default}"
out="${2:-results/rmp-tracks}"
speeds="${3:-0.5 1.0}"
mkdir -p "$out"
failed=0
for track in rmp/app/tracks/*.yaml; do
  name="$(basename "$track" .yaml)"
  for v in $speeds; do
    line="$("$build/rmp/idi-rmp" -q sim --track "$track" --speed-mps "$v" --report "$out/$name-$v.json" \
      --png "$out/$name-$v.png" 2>&1 | tail -1)" || failed=$((failed + 1))
    printf '%-16s %4s m/s  %s\n' "$name" "$v" "$line"
  done
done
exit $((failed > 0))
