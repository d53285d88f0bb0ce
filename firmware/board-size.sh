#!/usr/bin/env bash
# Builds the real boards' one image, STM32F407 (`--features board-stm32f4`) and STM32H743
# (`cargo build-m7 --features board-stm32h743`), with the default model (the shipped LR; any kind is
# uploaded over the link), and prints their flash and static RAM use
# from `size -A` (flash = vector table + text + rodata + data; RAM = data + bss + uninit), as
# budget.sh does for every path. They cannot run here: flashing needs the board and a probe
# (`cargo run-stm32f4`, see .cargo/config.toml; docs/hardware.md for the H743).
set -euo pipefail
cd "$(dirname "$0")"

report() { # report NAME ELF FLASH_TOTAL RAM_TOTAL
  size -A "$2" | awk -v name="$1" -v ft="$3" -v rt="$4" '
    $1 == ".vector_table" || $1 == ".text" || $1 == ".rodata" { flash += $2 }
    $1 == ".data" { flash += $2; ram += $2 }
    $1 == ".bss" || $1 == ".uninit" { ram += $2 }
    END { printf "%s board build: flash %d bytes (%.1f%% of %d KiB), static RAM %d bytes (%.1f%% of %d KiB)\n",
          name, flash, 100 * flash / ft, ft / 1024, ram, 100 * ram / rt, rt / 1024 }'
}

cargo build --release --no-default-features --features board-stm32f4
# The same binary name as the emulated board's: copy it before another build replaces it.
f4=target/board-stm32f4.elf
cp target/thumbv7em-none-eabihf/release/rths-firmware "$f4"
report STM32F407 "$f4" 1048576 131072
# No panic reachable from the board's control step (drivers and HAL SPI included), nor from its
# telemetry task.
./panic-check.sh "$f4"
./panic-check.sh "$f4" USART3

cargo build-m7 --no-default-features --features board-stm32h743
h7=target/board-stm32h743.elf
cp target/m7/thumbv7em-none-eabihf/release/rths-firmware "$h7"
report STM32H743 "$h7" 2097152 131072
# The same, and no software f64 routine reachable (the M7's FPU does f64).
SOFT_F64_MAX=0 ./panic-check.sh "$h7"
SOFT_F64_MAX=0 ./panic-check.sh "$h7" USART3
