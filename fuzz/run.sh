#!/usr/bin/env bash
# Time-boxed fuzz run of every target: ./run.sh [SECONDS_PER_TARGET]  (default 30).
# Needs a nightly toolchain and cargo-fuzz. Prints one summary line per target (executions, crashes);
# exits non-zero if any target crashed (the crashing input is left in fuzz/artifacts/<target>/).
set -euo pipefail
cd "$(dirname "$0")"
SECS=${1:-30}
status=0
# Every target in one build (the targets link side by side); a target that does not build fails
# the run here, with the compiler's message.
if ! cargo +nightly fuzz build -O; then
  echo "FAIL: the fuzz targets did not build"
  exit 1
fi
for t in at2 csv history model_file nl_model_file meta_model_file rig_file structure_file link_device recording site_protocol; do
  mkdir -p "corpus/$t"
  log=$(mktemp)
  if cargo +nightly fuzz run -O "$t" "corpus/$t" "seeds/$t" -- \
      -max_total_time="$SECS" -max_len=4096 -print_final_stats=1 >"$log" 2>&1; then
    crashes=0
  else
    crashes=1
    status=1
    tail -40 "$log"
  fi
  runs=$(grep -o 'stat::number_of_executed_units: *[0-9]*' "$log" | grep -o '[0-9]*$' || echo '?')
  echo "fuzz $t: ${SECS} s, executions: ${runs}, crashes: ${crashes}, corpus: $(ls "corpus/$t" | wc -l) inputs"
  rm -f "$log"
done
exit $status
