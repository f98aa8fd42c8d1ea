#!/usr/bin/env bash
# Scripted test of vwe_vo_offline on faulty recordings made from a short simulated bag with
# scripts/glitch_bag.py: timestamp jumps of 99 ms every 0.5 s (absorbed: no reset, counted in
# report.json), a 2 s jump back (one reset, said), duplicated and reordered packets, a bag cut
# short (.bag.active, recovered, exit 0) and empty input (an error naming what is missing).
# Usage: scripts/check_bag_faults.sh [WORKDIR]   (prints "N passed, N failed"; exit 1 on a failure)
set -uo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
set +u
# shellcheck disable=SC1091
source "$ROOT/scripts/ros_env.sh"
set -u
BIN="${VWE_WS:-$ROOT/.build/ws}/devel/lib/vwe_vo"
WORK="${1:-$(mktemp -d)}"
mkdir -p "$WORK"
passed=0 failed=0
check() {  # check NAME CONDITION-EXIT-CODE
  if [ "$2" -eq 0 ]; then passed=$((passed + 1)); echo "[check_bag_faults] ok   $1"
  else failed=$((failed + 1)); echo "[check_bag_faults] FAIL $1"; fi
}
json() {  # json FILE PYTHON-EXPRESSION-ON-r -> exit 0 if true
  /usr/bin/python3 -c "import json,sys; r=json.load(open('$1')); sys.exit(0 if ($2) else 1)"
}
offline() {  # offline NAME BAG -> runs vwe_vo_offline into WORK/NAME, log in WORK/NAME.log, sets rc
  "$BIN/vwe_vo_offline" --bag "$2" --use-odom --no-map --quiet --out "$WORK/$1" > "$WORK/$1.log" 2>&1
  rc=$?
}

"$BIN/vwe_vo_sim" --sequence indoor_long --format bag --duration 6 --out "$WORK/sim" > "$WORK/sim.log" 2>&1 \
  || { echo "vwe_vo_sim failed: $(tail -3 "$WORK/sim.log")"; exit 1; }
CLEAN="$WORK/sim/indoor_long.bag"
G="/usr/bin/python3 $ROOT/scripts/glitch_bag.py"

offline clean "$CLEAN"
check "clean bag: exit 0, no jump, no reset" $([ $rc -eq 0 ] && json "$WORK/clean/report.json" \
  'r["input"]["backward_jumps"] == 0 and r["input"]["resets"] == 0 and r["dropped"]["resets"] == 0'; echo $?)

$G "$CLEAN" "$WORK/jump.bag" --jump-s 0.099 --period-s 0.5 > "$WORK/jump.json"
offline jump "$WORK/jump.bag"
shifted=$(/usr/bin/python3 -c "import json; print(json.load(open('$WORK/jump.json'))['shifted'])")
check "99 ms every 0.5 s: $shifted jumps counted, 0 resets" $([ $rc -eq 0 ] && json "$WORK/jump/report.json" \
  "r['input']['backward_jumps'] == $shifted and r['input']['resets'] == 0 and r['dropped']['resets'] == 0 and \
   r.get('stages', {}).get('backend', {}).get('resets', 0) == 0 and 0.09 < r['input']['largest_backward_jump_s'] <= 0.099"; echo $?)
check "99 ms jumps: warned on the terminal" $(grep -q "backward timestamp jump" "$WORK/jump.log"; echo $?)
check "99 ms jumps: windows as in the clean run (+-1)" $(/usr/bin/python3 -c "
import json,sys; a=json.load(open('$WORK/clean/report.json')); b=json.load(open('$WORK/jump/report.json'))
sys.exit(0 if abs(a['windows'] - b['windows']) <= 1 else 1)"; echo $?)

$G "$CLEAN" "$WORK/loop.bag" --jump-s 2.0 --period-s 3.0 --persist > /dev/null
offline loop "$WORK/loop.bag"
check "2 s jump back: one reset, said" $([ $rc -eq 0 ] && json "$WORK/loop/report.json" \
  'r["input"]["resets_backward_jump"] == 1 and r["input"]["resets"] == 1' && grep -q "jump back 2.000 s" "$WORK/loop.log"; echo $?)

$G "$CLEAN" "$WORK/dup.bag" --duplicate-every 7 --reorder-every 11 > /dev/null
offline dup "$WORK/dup.bag"
check "duplicated and reordered packets: absorbed, no reset" $([ $rc -eq 0 ] && json "$WORK/dup/report.json" \
  'r["input"]["backward_jumps"] > 0 and r["input"]["resets"] == 0'; echo $?)

half_mb=$(( $(stat -c %s "$CLEAN") / 2 / 1048576 ))
[ "$half_mb" -ge 1 ] || half_mb=1
$G "$CLEAN" "$WORK/cut.bag" --truncate-mb "$half_mb" > /dev/null
offline cut "$WORK/cut.bag.active"
check "bag cut at $half_mb MB: exit 0, warned, shorter trajectory" $([ $rc -eq 0 ] && grep -q "cut short" "$WORK/cut.log" && \
  /usr/bin/python3 -c "
import json,sys; a=json.load(open('$WORK/clean/report.json')); b=json.load(open('$WORK/cut/report.json'))
sys.exit(0 if 0 < b['input']['recovered_from_unindexed_s'] and 0 < b['duration_s'] < a['duration_s'] else 1)"; echo $?)

"$BIN/vwe_vo_offline" --bag "$CLEAN" --events-topic /nothing --no-map --quiet --out "$WORK/none" > "$WORK/none.log" 2>&1
rc=$?
check "no events on the topic: error naming it, exit != 0" $([ $rc -ne 0 ] && grep -q "no events on /nothing" "$WORK/none.log"; echo $?)
mkdir -p "$WORK/ecd"
: > "$WORK/ecd/events.txt"
printf '226.38 226.15 173.64 133.73 0 0 0 0 0\n' > "$WORK/ecd/calib.txt"
"$BIN/vwe_vo_offline" --ecd "$WORK/ecd" --no-map --quiet --out "$WORK/ecd_out" > "$WORK/ecd.log" 2>&1
rc=$?
check "empty events.txt: error naming the file, exit != 0" $([ $rc -ne 0 ] && grep -q "events.txt: no events" "$WORK/ecd.log"; echo $?)

echo "check_bag_faults: $passed passed, $failed failed"
[ "$failed" -eq 0 ]
