#!/usr/bin/env bash
# Is any panic reachable from the control task? Disassembles the firmware ELF, builds the static call
# graph (every direct branch to another symbol: bl, b.w, conditional tail branches) and walks it from
# `control_step`, the measured section of the `control` task (DAQ read, Controller::tick, command
# write, log record); ROOT=TIM2 walks the whole task, test harness and simulated plant included. Fails if a panic entry point is reachable, and reports the
# indirect branches met on the way (the walk cannot follow those).
#
#   ./panic-check.sh [ELF] [ROOT_SYMBOL]
set -euo pipefail
cd "$(dirname "$0")"
ELF=${1:-target/thumbv7em-none-eabihf/release/rths-firmware}
# The measured section of the control task (an out-of-line function; mangled names contain it).
ROOT=${2:-control_step}

OBJDUMP=$(command -v llvm-objdump || true)
if [ -z "$OBJDUMP" ]; then
  OBJDUMP=$(ls "$(rustc --print sysroot)"/lib/rustlib/*/bin/llvm-objdump 2>/dev/null | head -1 || true)
fi
if [ -z "$OBJDUMP" ]; then
  echo "SKIPPED: panic check (no llvm-objdump: install llvm or rustup component add llvm-tools)"
  exit 0
fi

"$OBJDUMP" -d --no-show-raw-insn "$ELF" | awk -v root="$ROOT" '
  /^[0-9a-f]+ <[^>]+>:$/ {
    name = $2; gsub(/[<>:]/, "", name)
    # ARM mapping symbols ($t code, $d data) are not functions.
    if (name !~ /^\$/) { fn = name; fns[fn] = 1 }
    next
  }
  fn != "" && /\tb[a-z.]*\t0x[0-9a-f]+ <[^>]+>/ {
    t = $0; sub(/.*</, "", t); sub(/>.*/, "", t); sub(/\+0x[0-9a-f]+$/, "", t)
    if (t != fn && t !~ /^\$/) { edge[fn] = edge[fn] " " t }
    next
  }
  fn != "" && /\t(blx|bx)\tr[0-9]+/ { indirect[fn]++ }
  END {
    for (f in fns) if (index(f, root) > 0) { start = f }
    if (start == "") { print "panic check: no symbol containing " root; exit 2 }
    n = 1; queue[1] = start; seen[start] = 1
    for (i = 1; i <= n; i++) {
      f = queue[i]; k = split(edge[f], ts, " ")
      for (j = 1; j <= k; j++) if (!(ts[j] in seen)) { seen[ts[j]] = 1; queue[++n] = ts[j]; from[ts[j]] = f }
    }
    bad = 0; ind = 0
    for (f in seen) {
      if (f ~ /panic|rust_begin_unwind|slice_index_fail|slice_(start|end)_index|assert_failed|unwrap_failed|expect_failed|panic_bounds_check|already_borrowed/) {
        bad++; path = f; g = f; while (g in from) { g = from[g]; path = g " <- " path }
        print "REACHABLE PANIC: " path
      }
      ind += indirect[f]
    }
    printf "panic check: %d functions reachable from %s, %d panic entry points reachable, %d indirect branches (not followed)\n", n, root, bad, ind
    exit bad > 0
  }'
