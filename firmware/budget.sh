#!/usr/bin/env bash
# The firmware's budget table: every board × rate × analytical part that builds.
#
# Instructions per control tick come from QEMU runs of the whole El Centro record, counted with
# SysTick around the control task's measured section (DAQ read, control step, command write, log)
# under -icount (one guest instruction = a fixed slice of virtual time). Two emulated boards:
#   qemu-netduinoplus2  Cortex-M4 (STM32F405; f64 in software), -icount shift=0
#   qemu-mps2-an500     Cortex-M7 (double-precision FPU, built with `cargo build-m7`), shift=3
# The real boards are cross-built for their flash and static RAM; their instruction and stack
# figures are their QEMU twin's (same core, same code path; "instr_source" says which):
#   stm32f407  Cortex-M4 at 168 MHz      twin: qemu-netduinoplus2
#   stm32h743  Cortex-M7 at 480 MHz      twin: qemu-mps2-an500 (when boards/stm32h743 builds)
# % of the tick = instr_max × 1.5 cycles per instruction / clock × rate: QEMU counts instructions,
# not cycles; 1.5 is the M4 budget's assumption (docs/firmware.md) and is kept for the dual-issue M7
# (conservative there: its f64 divide and square root take more than one cycle each, most others
# issue at one per cycle or better). An emulated board's row uses its real twin's clock.
#
# Checks (exit 1 on failure): the LR and LRX paths of the M4 within 10 % of the tick, LR ≤ 2000
# instructions; every path of the M7 within 10 %, LR ≤ 500 instructions; every build ≤ 128 KiB of
# flash and ≤ 64 KiB of static RAM; no panic reachable from the control step, the supervisor
# (UART4) or telemetry (USART3) of any build; no software f64 routine reachable on an M7 build.
# RNN-10 overruns the M4's tick (software f64): the stm32f407 refuses to build it (compile-time) and
# its qemu-netduinoplus2 row is marked "fits": false.
#
#   ./budget.sh          the human-readable table (needs qemu-system-arm)
#   ./budget.sh --json   one JSON object {"rows": [...], ...} on stdout (progress on stderr)
set -euo pipefail
cd "$(dirname "$0")"
JSON=0
if [ "${1:-}" = --json ]; then JSON=1; fi
CPI=1.5
LIMIT_PCT=10
M4_LR_MAX_INSTR=2000
M7_LR_MAX_INSTR=500
FLASH_MAX=$((128 * 1024))
RAM_MAX=$((64 * 1024))
OUT=target/budget
mkdir -p "$OUT"

say() { if [ "$JSON" = 1 ]; then echo "$@" >&2; else echo "$@"; fi; }

if ! command -v qemu-system-arm >/dev/null; then
  say "SKIPPED: budget (qemu-system-arm is not installed)"
  if [ "$JSON" = 1 ]; then echo '{"rows":[],"skipped":"qemu-system-arm is not installed"}'; fi
  exit 0
fi
SIZE=$(command -v size || command -v llvm-size || ls "$(rustc --print sysroot)"/lib/rustlib/*/bin/llvm-size 2>/dev/null | head -1 || true)
if [ -z "$SIZE" ]; then
  say "FAIL: no size or llvm-size (install binutils or rustup component add llvm-tools)"
  exit 1
fi

# The runners of .cargo/config.toml (one source of truth): the target's for the M4, `run-m7`'s for
# the M7.
M4_RUNNER=$(sed -n 's/^runner = "\(.*\)"$/\1/p' .cargo/config.toml)
M7_RUNNER=$(sed -n "s/^run-m7 = .*runner='\([^']*\)'.*/\1/p" .cargo/config.toml)

field() { # field JSON KEY -> the number after "KEY":
  sed -n "s/.*\"$2\":\(-\{0,1\}[0-9.e+-]*\).*/\1/p" <<<"$1"
}

sizes() { # sizes ELF -> "flash ram" (flash = vector table + text + rodata + data; RAM = data + bss + uninit)
  "$SIZE" -A "$1" | awk '
    $1 == ".vector_table" || $1 == ".text" || $1 == ".rodata" { flash += $2 }
    $1 == ".data" { flash += $2; ram += $2 }
    $1 == ".bss" || $1 == ".uninit" { ram += $2 }
    END { printf "%d %d\n", flash, ram }'
}

fail=0
panics() { # panics ELF CORE -> panic entry points reachable from the three roots (0 expected)
  local n=0 root soft=-1
  if [ "$2" = cortex-m7 ]; then soft=0; fi
  for root in control_step UART4 USART3; do
    if ! SOFT_F64_MAX=$soft ./panic-check.sh "$1" "$root" >&2; then
      n=$((n + 1))
    fi
  done
  echo "$n"
}

# build BOARD PATH -> the ELF copied to $OUT/BOARD-PATH.elf (exit status of the build)
build() {
  local board=$1 path=$2 feat sub elf
  case $path in
    lr) feat=model-lr ;; lrx) feat=model-lrx ;; rnn-10) feat=model-rnn ;; fe-ats) feat=fe-ats ;;
  esac
  case $board in
    qemu-netduinoplus2) sub=(build --release); feat="board-qemu,$feat"; elf=target/thumbv7em-none-eabihf ;;
    stm32f407) sub=(build --release); feat="board-stm32f4,$feat"; elf=target/thumbv7em-none-eabihf ;;
    qemu-mps2-an500) sub=(build-m7); feat="board-mps2-an500,$feat"; elf=target/m7/thumbv7em-none-eabihf ;;
    stm32h743) sub=(build-m7); feat="board-stm32h743,$feat"; elf=target/m7/thumbv7em-none-eabihf ;;
  esac
  say "building $board $path ($feat)"
  cargo "${sub[@]}" --quiet --no-default-features --features "$feat" >&2 || return 1
  cp "$elf/release/rths-firmware" "$OUT/$board-$path.elf"
}

declare -A RESULT
run_twin() { # run_twin BOARD PATH: run the emulated board's ELF, keep its RESULT line
  local board=$1 path=$2 runner out line
  case $board in
    qemu-netduinoplus2) runner=$M4_RUNNER ;; qemu-mps2-an500) runner=$M7_RUNNER ;;
  esac
  say "running $board $path in QEMU"
  out=$(cd "$(mktemp -d)" && $runner "$OLDPWD/$OUT/$board-$path.elf" || true)
  line=$(grep '^RESULT ' <<<"$out" | tail -1)
  if [ -z "$line" ]; then
    say "no RESULT line from $board $path:"; say "$out"; exit 1
  fi
  RESULT[$board/$path]=$line
}

PATHS="lr lrx rnn-10 fe-ats"
ROWS=()
add_row() { # add_row BOARD CORE CLOCK_HZ PATH TWIN
  local board=$1 core=$2 clock=$3 path=$4 twin=$5
  local r=${RESULT[$twin/$path]} ip min mean max stack pct flash ram p fits=true rate=2048
  ip=$(sed -n 's/.*"instr_per_tick":{\([^}]*\)}.*/\1/p' <<<"$r")
  min=$(field "$ip" min); mean=$(field "$ip" mean); max=$(field "$ip" max)
  stack=$(field "$r" stack_bytes)
  pct=$(awk -v m="$max" -v c="$CPI" -v f="$clock" -v r="$rate" 'BEGIN { printf "%.2f", 100 * m * c * r / f }')
  read -r flash ram < <(sizes "$OUT/$board-$path.elf")
  p=$(panics "$OUT/$board-$path.elf" "$core")
  if awk -v p="$pct" -v l=100 'BEGIN { exit !(p > l) }'; then fits=false; fi
  ROWS+=("$board|$core|$rate|$path|$max|$mean|$pct|$stack|$flash|$ram|$p|$twin|$fits|$clock|$min")
  # The goals.
  local over_limit
  over_limit=$(awk -v p="$pct" -v l="$LIMIT_PCT" 'BEGIN { print (p > l) ? 1 : 0 }')
  if [ "$core" = cortex-m4 ] && { [ "$path" = lr ] || [ "$path" = lrx ]; } && [ "$over_limit" = 1 ]; then
    say "FAIL: $board $path: $pct% of the tick (budget $LIMIT_PCT%)"; fail=1
  fi
  if [ "$core" = cortex-m7 ] && [ "$over_limit" = 1 ]; then
    say "FAIL: $board $path: $pct% of the tick (budget $LIMIT_PCT%)"; fail=1
  fi
  if [ "$path" = lr ] && [ "$core" = cortex-m4 ] && [ "$max" -gt "$M4_LR_MAX_INSTR" ]; then
    say "FAIL: $board LR: $max instructions per tick (target: at most $M4_LR_MAX_INSTR)"; fail=1
  fi
  if [ "$path" = lr ] && [ "$core" = cortex-m7 ] && [ "$max" -gt "$M7_LR_MAX_INSTR" ]; then
    say "FAIL: $board LR: $max instructions per tick (target: at most $M7_LR_MAX_INSTR)"; fail=1
  fi
  if [ "$flash" -gt "$FLASH_MAX" ] || [ "$ram" -gt "$RAM_MAX" ]; then
    say "FAIL: $board $path: flash $flash bytes, static RAM $ram bytes (at most $FLASH_MAX / $RAM_MAX)"; fail=1
  fi
  if [ "$p" != 0 ]; then
    say "FAIL: $board $path: the panic check failed on $p of its roots (listed above)"; fail=1
  fi
}

# The emulated boards: build and run every path.
for path in $PATHS; do
  build qemu-netduinoplus2 "$path"
  run_twin qemu-netduinoplus2 "$path"
  add_row qemu-netduinoplus2 cortex-m4 168000000 "$path" qemu-netduinoplus2
  build qemu-mps2-an500 "$path"
  run_twin qemu-mps2-an500 "$path"
  add_row qemu-mps2-an500 cortex-m7 480000000 "$path" qemu-mps2-an500
done
# The real boards: cross-build every path they accept.
for path in $PATHS; do
  if [ "$path" = rnn-10 ]; then
    # Must not build: RNN-10 overruns the F407's tick.
    if cargo build --release --quiet --no-default-features --features board-stm32f4,model-rnn 2>/dev/null; then
      say "FAIL: the stm32f407 built the RNN-10 path (it must refuse: it does not fit the tick)"; fail=1
    else
      say "stm32f407 rnn-10: refused at compile time, as it must be"
    fi
  else
    build stm32f407 "$path"
    add_row stm32f407 cortex-m4 168000000 "$path" qemu-netduinoplus2
  fi
  if [ -d ../boards/stm32h743 ]; then
    build stm32h743 "$path"
    add_row stm32h743 cortex-m7 480000000 "$path" qemu-mps2-an500
  fi
done

if [ "$JSON" = 1 ]; then
  printf '{"cycles_per_instr":%s,"budget_pct":%s,"rows":[' "$CPI" "$LIMIT_PCT"
  sep=
  for row in "${ROWS[@]}"; do
    IFS='|' read -r board core rate path max mean pct stack flash ram p twin fits clock min <<<"$row"
    printf '%s\n{"board":"%s","core":"%s","rate_hz":%s,"path":"%s","instr_max":%s,"instr_mean":%s,"pct_tick":%s,"stack_bytes":%s,"flash_bytes":%s,"ram_bytes":%s,"instr_min":%s,"clock_hz":%s,"instr_source":"%s","fits":%s,"panics_reachable":%s}' \
      "$sep" "$board" "$core" "$rate" "$path" "$max" "$mean" "$pct" "$stack" "$flash" "$ram" "$min" "$clock" "$twin" "$fits" "$p"
    sep=,
  done
  printf '\n],"refused":[{"board":"stm32f407","path":"rnn-10","reason":"RNN-10 overruns the Cortex-M4 tick (f64 in software)"}]}\n'
else
  printf '\n%-19s %-9s %5s %-7s %7s %8s %7s %6s %7s %7s %6s  %s\n' board core rate path max mean "% tick" stack flash ram panics "instructions from"
  for row in "${ROWS[@]}"; do
    IFS='|' read -r board core rate path max mean pct stack flash ram p twin fits clock min <<<"$row"
    printf '%-19s %-9s %5s %-7s %7s %8s %6s%% %6s %7s %7s %6s  %s%s\n' "$board" "$core" "$rate" "$path" "$max" "$mean" "$pct" "$stack" "$flash" "$ram" "$p" "$twin" "$([ "$fits" = true ] || echo ' (DOES NOT FIT)')"
  done
  echo "(% of the tick at the board's clock, 168 MHz M4 / 480 MHz M7, $CPI cycles per instruction assumed;"
  echo " budget: $LIMIT_PCT% for LR and LRX on the M4 and every path on the M7; LR ≤ $M4_LR_MAX_INSTR (M4) / ≤ $M7_LR_MAX_INSTR (M7)"
  echo " instructions; flash ≤ $((FLASH_MAX / 1024)) KiB, static RAM ≤ $((RAM_MAX / 1024)) KiB; stack = measured high-water, bytes)"
fi

if [ "$fail" = 1 ]; then
  exit 1
fi
