#!/usr/bin/env bash
# Runs every benchmark binary of the workspace with JSON output into OUTDIR (default out/bench)
# and prints a one-line summary per benchmark. usage: run_bench.sh WS [OUTDIR] [FILTER]
set -euo pipefail
ws="${1:?workspace}"
out="${2:-$(cd "$(dirname "$0")/.." && pwd)/out/bench}"
filter="${3:-.}"
bin="$ws/devel/lib/vwe_vo"
mkdir -p "$out"
shopt -s nullglob
found=0
for b in "$bin"/bench_*; do
  [ -x "$b" ] || continue
  found=1
  name=$(basename "$b")
  echo "[bench] $name"
  "$b" --benchmark_filter="$filter" --benchmark_out="$out/$name.json" --benchmark_out_format=json \
       --benchmark_counters_tabular=true
done
[ "$found" = 1 ] || { echo "[bench] no benchmark binaries in $bin (is libbenchmark-dev installed?)"; exit 1; }
# The whole front-end + back-end on the simulated sequences (real-time factor and accuracy).
if [ "$filter" = "." ] || [[ "pipeline" =~ $filter ]]; then
  /usr/bin/python3 "$(dirname "$0")/bench_pipeline.py" --ws "$ws" --out "$out"
  # Continuous driving with suspension, with and without the IMU; from four start times with and
  # without /odom, beside the flat twins, with /odom also with two more subsampling seeds and on
  # the scenes the simulator makes with seeds 7 and 11 (bench_pipeline_drive.json).
  /usr/bin/python3 "$(dirname "$0")/bench_pipeline.py" --ws "$ws" --out "$out" --repeat 1 --imu \
    --starts 0.5,1.1,2.3 --without-odom --flat-twins --starts-seeds 2,3 --scene-seeds 7,11 \
    --json bench_pipeline_drive.json indoor_drive street_drive
fi
# The whole system live: replay_check at rate 1 and 2 (CPU per node, drops, /vwe/odom accuracy).
if [ "$filter" = "." ] || [[ "live" =~ $filter ]]; then
  /usr/bin/python3 "$(dirname "$0")/bench_live.py" --out "$out"
fi
echo "[bench] JSON results in $out"
