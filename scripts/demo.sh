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
  # The street sequences are simulated with a car mount (config/car.yaml), the others with the
  # turtlebot mount of config/vwe_vo.yaml: the pipeline must use the extrinsics of the recording.
  # Only street_drive's car pitches and rolls on a suspension; street_long's and the flat twins'
  # body is rigid (config/car_rigid.yaml): the configuration describes the vehicle.
  cfg="$root/config/vwe_vo.yaml"
  case "$s" in
    street_drive*_flat*) cfg="$root/config/car_rigid.yaml" ;;
    street_drive*) cfg="$root/config/car.yaml" ;;
    street*) cfg="$root/config/car_rigid.yaml" ;;
  esac
  echo "[demo] 2/4 $s: pipeline with $(basename "$cfg") (speed from the bag's /odom, as on a robot with wheel odometry)"
  "$bin/vwe_vo_offline" --bag "$seq_dir/$s.bag" --config "$cfg" --use-odom --depth-png --out "$d"
  # The frame baseline in a run of its own: each method's real-time factor is its own.
  "$bin/vwe_vo_offline" --bag "$seq_dir/$s.bag" --config "$cfg" --use-odom --baseline-only --quiet \
      --out "$d/baseline_run"
  cp "$d/baseline_run/baseline.tum" "$d/baseline.tum"
  echo "[demo] 3/4 $s: evaluation"
  cp "$seq_dir/groundtruth.txt" "$d/groundtruth.tum"
  # odom: the continuous odometry backend_node would publish live (/vwe/odom).
  for m in frontend backend odom baseline; do
    [ -f "$d/$m.tum" ] || continue
    arcs=()
    [ "$m" = frontend ] && arcs=(--arcs "$d/arcs.csv")
    "$bin/vwe_vo_eval" --gt "$d/groundtruth.tum" --est "$d/$m.tum" --json "$d/eval_$m.json" \
        --series "$d/errors_$m.csv" "${arcs[@]}" > "$d/eval_$m.txt"
  done
  est_args=()
  for m in frontend backend baseline; do [ -f "$d/$m.tum" ] && est_args+=(--est "$m=$d/$m.tum"); done
  series=()
  [ -f "$d/errors_backend.csv" ] && series=(--series "$d/errors_backend.csv") || series=(--series "$d/errors_frontend.csv")
  /usr/bin/python3 "$root/scripts/plot_trajectory.py" --gt "$d/groundtruth.tum" "${est_args[@]}" "${series[@]}" --out "$d/$s"
  /usr/bin/python3 "$root/scripts/plot_arcs.py" --arcs "$d/arcs.csv" --gt "$d/groundtruth.tum" --out "$d/${s}_arcs.png"
  if [ -f "$d/map.ply" ]; then
    /usr/bin/python3 "$root/scripts/plot_map.py" "$d/map.ply" "$d/${s}_map" --tum "$d/groundtruth.tum"
  fi
done

echo "[demo] 4/4 metrics table"
/usr/bin/python3 "$root/scripts/metrics_table.py" "$out"
echo "[demo] done: trajectories, plots, reports and metrics.md/metrics.json in $out"
