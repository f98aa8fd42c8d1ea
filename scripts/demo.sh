#!/usr/bin/env bash
# make demo: simulate the standard sequences (cached), run the pipeline offline, evaluate
# against ground truth, plot, and write the metrics table into out/demo/.
# Sourced environment: scripts/ros_env.sh (the Makefile does it). usage: demo.sh [SEQUENCE...]
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
bin="${VWE_WS:-$root/.build/ws}/devel/lib/vwe_vo"
out="$root/out/demo"
seqs=("$@")
[ ${#seqs[@]} -gt 0 ] || seqs=(indoor_long street_long)
mkdir -p "$out"

echo "[demo] 1/4 sequences: ${seqs[*]} (generated once, cached in out/sequences)"
bash "$root/scripts/make_sequences.sh" "${seqs[@]}"

for s in "${seqs[@]}"; do
  seq_dir="$root/out/sequences/$s"
  d="$out/$s"
  mkdir -p "$d"
  # Per-sequence speed: the street sequence is a car, the others a turtlebot.
  speed=$(/usr/bin/python3 - "$seq_dir/groundtruth.txt" <<'PY'
import sys, math
rows = [list(map(float, l.split())) for l in open(sys.argv[1]) if l.strip() and not l.startswith('#')]
dist = sum(math.hypot(b[1]-a[1], b[2]-a[2]) for a, b in zip(rows, rows[1:]))
moving = sum(b[0]-a[0] for a, b in zip(rows, rows[1:]) if math.hypot(b[1]-a[1], b[2]-a[2]) > 1e-4 * (b[0]-a[0]))
print("%.3f" % (dist / max(moving, 1e-6)))
PY
)
  echo "[demo] 2/4 $s: pipeline (nominal speed $speed m/s = mean moving speed of the sequence)"
  "$bin/vwe_vo_offline" --ecd "$seq_dir" --nominal-speed "$speed" --out "$d"
  echo "[demo] 3/4 $s: evaluation"
  for m in frontend backend; do
    [ -f "$d/$m.tum" ] || continue
    cp "$seq_dir/groundtruth.txt" "$d/groundtruth.tum"
    "$bin/vwe_vo_eval" --gt "$d/groundtruth.tum" --est "$d/$m.tum" --json "$d/eval_$m.json" \
        --series "$d/errors_$m.csv" > "$d/eval_$m.txt"
  done
  est_args=()
  for m in frontend backend; do [ -f "$d/$m.tum" ] && est_args+=(--est "$m=$d/$m.tum"); done
  series=()
  [ -f "$d/errors_backend.csv" ] && series=(--series "$d/errors_backend.csv") || series=(--series "$d/errors_frontend.csv")
  /usr/bin/python3 "$root/scripts/plot_trajectory.py" --gt "$d/groundtruth.tum" "${est_args[@]}" "${series[@]}" --out "$d/$s"
  /usr/bin/python3 "$root/scripts/plot_arcs.py" --arcs "$d/arcs.csv" --gt "$d/groundtruth.tum" --out "$d/${s}_arcs.png"
done

echo "[demo] 4/4 metrics table"
/usr/bin/python3 "$root/scripts/metrics_table.py" "$out"
echo "[demo] done: trajectories, plots, reports and metrics.md/metrics.json in $out"
