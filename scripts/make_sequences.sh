#!/usr/bin/env bash
# Generates the simulator's standard sequences (fixed seeds) into out/sequences/NAME/: NAME.bag
# and groundtruth.txt (FORMAT=bag, the default), or also an Event Camera Dataset folder
# (FORMAT=ecd,bag; text files are large: ~20 bytes per event). A sequence is skipped when its
# stamp file matches the sequence name, seed, format and generator version.
# Usage: [FORMAT=bag|ecd|ecd,bag] [DRIVE=1] scripts/make_sequences.sh [NAME...]
# NAME_sSEED (e.g. street_drive_s7) is sequence NAME with the simulator seed SEED instead of its
# own: another scene, road, sensor noise and IMU noise on the same motion; street_drive_flat_s7 is
# its flat twin (the same scene).
# Without names: every listed sequence except the continuous-driving ones (street_drive,
# indoor_drive and their _flat twins, ~1.5 min each to simulate), which DRIVE=1 adds.
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
set +u  # ROS's setup scripts read unset variables
# shellcheck disable=SC1091
source "$ROOT/scripts/ros_env.sh"
set -u
BIN="${VWE_WS:-$ROOT/.build/ws}/devel/lib/vwe_vo/vwe_vo_sim"
VERSION="sim-v6"   # bump when the simulator's output changes: the stamp invalidates cached sequences
FORMAT="${FORMAT:-bag}"
OUT="$ROOT/out/sequences"
if [ ! -x "$BIN" ]; then echo "make_sequences: $BIN not built (run make build)" >&2; exit 1; fi
if [ $# -eq 0 ]; then
  mapfile -t names < <("$BIN" --list | tail -n +2 | awk '{print $1}' | \
    if [ "${DRIVE:-0}" = 1 ]; then cat; else grep -v -E '^(street_drive|indoor_drive)(_flat)?$'; fi)
else
  names=("$@")
fi
for name in "${names[@]}"; do
  dir="$OUT/$name"
  stamp="$dir/.stamp"
  sequence="$name"
  seed="$("$BIN" --list | awk -v n="$name" '$1 == n {print $4}')"
  if [ -z "$seed" ] && [[ "$name" =~ ^(.+)_s([0-9]+)$ ]] &&
     "$BIN" --list | awk '{print $1}' | grep -qx "${BASH_REMATCH[1]}"; then
    sequence="${BASH_REMATCH[1]}"
    seed="${BASH_REMATCH[2]}"
  fi
  if [ -z "$seed" ]; then "$BIN" --sequence "$name" --format ecd --out /dev/null/x 2>&1 | head -1 >&2; exit 2; fi
  want="name=$name seed=$seed format=$FORMAT version=$VERSION"
  if [ -f "$stamp" ] && [ "$(cat "$stamp")" = "$want" ] && [ -f "$dir/groundtruth.txt" ]; then
    echo "[make_sequences] $name: up to date"
    continue
  fi
  echo "[make_sequences] $name: generating into $dir"
  rm -rf "$dir"
  mkdir -p "$dir"
  "$BIN" --sequence "$sequence" --format "$FORMAT" --seed "$seed" --out "$dir" --images --depth-times 1.0,5.0 2> >(tee "$dir/sim.log" >&2)
  # The simulator names the bag after the sequence; a reseeded one after its folder.
  if [ "$sequence" != "$name" ] && [ -f "$dir/$sequence.bag" ]; then mv "$dir/$sequence.bag" "$dir/$name.bag"; fi
  echo "$want" > "$stamp"
done
