#!/usr/bin/env bash
# Timing budget of the firmware, from QEMU runs (-icount shift=0: 1 instruction = 1 ns, counted with
# SysTick around the control task's measured section: DAQ read, control step, command write, log).
#
# For each analytical part (LR = lr-online, RNN-10 = rnn-online-10, FE+ATS = fe-online-ats,
# LRX = lrx-online) it builds
# the firmware, runs the whole El Centro record in QEMU and prints the instructions per control tick
# and their share of the 488 µs tick at 168 MHz, assuming 1.5 cycles per instruction. Then flash and
# RAM use (`size`), the measured stack depth, and the panic check of the control path.
# Fails if the LR or LRX path's worst tick exceeds 10% of the tick (LR also: ≤ 2000 instructions).
#
#   ./budget.sh            (needs qemu-system-arm)
set -euo pipefail
cd "$(dirname "$0")"
ELF=target/thumbv7em-none-eabihf/release/rths-firmware
CPU_HZ=168000000
CPI=1.5
LIMIT_PCT=10
LR_MAX_INSTR=2000
RUNNER=$(sed -n 's/^runner = "\(.*\)"$/\1/p' .cargo/config.toml)

if ! command -v qemu-system-arm >/dev/null; then
  echo "SKIPPED: budget (qemu-system-arm is not installed)"
  exit 0
fi

field() { # field JSON KEY -> the number after "KEY":
  sed -n "s/.*\"$2\":\(-\{0,1\}[0-9.e+-]*\).*/\1/p" <<<"$1"
}

declare -A RESULTS
run_path() { # run_path LABEL FEATURES...
  local label=$1; shift
  cargo build --release --quiet "$@"
  local out
  out=$(cd "$(mktemp -d)" && $RUNNER "$OLDPWD/$ELF" || true)
  local line
  line=$(grep '^RESULT ' <<<"$out" | tail -1)
  if [ -z "$line" ]; then
    echo "no RESULT line from the $label build:"; echo "$out"; exit 1
  fi
  RESULTS[$label]=$line
  if [ "$label" = LR ]; then
    cp "$ELF" target/budget-lr.elf
  fi
}

run_path LR
run_path RNN-10 --no-default-features --features board-qemu,model-rnn
run_path FE+ATS --no-default-features --features board-qemu,fe-ats
run_path LRX --no-default-features --features board-qemu,model-lrx

printf '\n%-8s %-14s %8s %8s %8s %9s %10s  %s\n' path scenario min mean max "max µs" "of tick" model
fail=0
for label in LR RNN-10 FE+ATS LRX; do
  r=${RESULTS[$label]}
  scen=$(sed -n 's/.*"scenario":"\([^"]*\)".*/\1/p' <<<"$r")
  model=$(sed -n 's/.*"model":"\([^"]*\)".*/\1/p' <<<"$r")
  ip=$(sed -n 's/.*"instr_per_tick":{\([^}]*\)}.*/\1/p' <<<"$r")
  min=$(field "$ip" min); mean=$(field "$ip" mean); max=$(field "$ip" max)
  read -r us pct < <(awk -v m="$max" -v c="$CPI" -v f="$CPU_HZ" \
    'BEGIN { us = m * c / f * 1e6; printf "%.1f %.2f\n", us, 100 * us / (1e6 / 2048) }')
  printf '%-8s %-14s %8s %8s %8s %9s %9s%%  %s\n' "$label" "$scen" "$min" "$mean" "$max" "$us" "$pct" "$model"
  if { [ "$label" = LR ] || [ "$label" = LRX ]; } && awk -v p="$pct" -v l="$LIMIT_PCT" 'BEGIN { exit !(p > l) }'; then
    echo "FAIL: the $label control tick exceeds $LIMIT_PCT% of the tick"
    fail=1
  fi
  if [ "$label" = LR ] && [ "$max" -gt "$LR_MAX_INSTR" ]; then
    echo "FAIL: the LR control tick takes $max instructions (target: at most $LR_MAX_INSTR)"
    fail=1
  fi
done
echo "(tick 488.3 µs = 82031 cycles at 168 MHz; $CPI cycles per instruction assumed; budget: LR and LRX ≤ $LIMIT_PCT%)"

r=${RESULTS[LR]}
echo
echo "LR build: overruns $(field "$r" overruns), faults $(field "$r" faults), NRMSE $(field "$r" nrmse_pct) %," \
  "stack high-water $(field "$r" stack_bytes) of $(field "$r" stack_avail_bytes) bytes"
if command -v size >/dev/null; then
  size -A target/budget-lr.elf | awk '
    $1 == ".vector_table" || $1 == ".text" || $1 == ".rodata" { flash += $2 }
    $1 == ".data" { flash += $2; ram += $2 }
    $1 == ".bss" || $1 == ".uninit" { ram += $2 }
    END { printf "LR build: flash %d bytes (%.1f%% of 1 MiB), static RAM %d bytes (%.1f%% of 128 KiB)\n",
          flash, 100 * flash / 1048576, ram, 100 * ram / 131072 }'
else
  echo "SKIPPED: flash/RAM (no size)"
fi
echo
if ! ./panic-check.sh target/budget-lr.elf; then
  echo "FAIL: panic paths reachable from the control step (listed above)"
  fail=1
fi
# The other two tasks of the controller: the supervisor (UART4) and telemetry (USART3).
for task in UART4 USART3; do
  if ! ./panic-check.sh target/budget-lr.elf "$task"; then
    echo "FAIL: panic paths reachable from the $task task (listed above)"
    fail=1
  fi
done

if [ "$fail" = 1 ]; then
  exit 1
fi
