#!/usr/bin/env bash
# Is any panic reachable from the control task? Disassembles the firmware ELF, builds the static call
# graph (every direct branch to another symbol: bl, b.w, conditional tail branches) and walks it from
# `control_step`, the measured section of the `control` task (DAQ read, Controller::tick, command
# write, log record); ROOT=TIM2 walks the whole task, test harness and simulated plant included. Fails if a panic entry point is reachable, and reports the
# indirect branches met on the way (the walk cannot follow those). It also counts the software
# double-precision routines (`__aeabi_d*`, `__*df*`) reachable: many on the Cortex-M4 (no f64 FPU),
# none expected on the Cortex-M7 (`SOFT_F64_MAX=0` makes any a failure).
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

# Decoded as Cortex-M7 code: a superset of the M4's instructions (FPv5 double precision), so both
# boards' images decode fully.
"$OBJDUMP" -d --no-show-raw-insn --mcpu=cortex-m7 "$ELF" | awk -v root="$ROOT" -v soft_max="${SOFT_F64_MAX:--1}" '
  /^[0-9a-f]+ <[^>]+>:$/ {
    name = $2; gsub(/[<>:]/, "", name)
    # ARM mapping symbols ($t code, $d data) are not functions.
    if (name !~ /^\$/) { fn = name; fns[fn] = 1 }
    next
  }
  fn != "" && /\tb[a-z.]*\t0x[0-9a-f]+ <[^>]+>/ {
    t = $0; sub(/.*</, "", t); sub(/>.*/, "", t)
    # A branch into the middle of another function is not a call: it is padding or data decoded
    # as an instruction (seen after the last return of a function). Calls and tail calls go to a start.
    if (t ~ /\+0x[0-9a-f]+$/) { next }
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
    bad = 0; ind = 0; soft = 0
    for (f in seen) {
      if (f ~ /^__aeabi_(d[a-z0-9]+|[fiul]2d|d2[fiul][a-z]*)$|^__[a-z]*df[0-9a-z]*$/) { soft++ }
      if (f ~ /panic|rust_begin_unwind|slice_index_fail|slice_(start|end)_index|assert_failed|unwrap_failed|expect_failed|panic_bounds_check|already_borrowed/) {
        bad++; path = f; g = f; while (g in from) { g = from[g]; path = g " <- " path }
        print "REACHABLE PANIC: " path
      }
      ind += indirect[f]
    }
    printf "panic check: %d functions reachable from %s, %d panic entry points reachable, %d indirect branches (not followed), %d software f64 routines\n", n, root, bad, ind, soft
    if (soft_max >= 0 && soft > soft_max) { print "SOFTWARE F64: " soft " routines reachable from " root " (at most " soft_max ")"; bad++ }
    exit bad > 0
  }'
