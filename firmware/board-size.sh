#!/usr/bin/env bash
# Builds the real-board firmware (STM32F407, `--features board-stm32f4,model-lr`) and prints its flash and
# static RAM use from `size -A` (flash = vector table + text + rodata + data; RAM = data + bss +
# uninit), as budget.sh does for the emulated board. It cannot run here: flashing needs the board and a
# probe (`cargo run-stm32f4`, see .cargo/config.toml).
set -euo pipefail
cd "$(dirname "$0")"
cargo build --release --no-default-features --features board-stm32f4,model-lr
# The same binary name as the emulated board's: copy it before another build replaces it.
elf=target/board-stm32f4.elf
cp target/thumbv7em-none-eabihf/release/rths-firmware "$elf"
size -A "$elf" | awk '
  $1 == ".vector_table" || $1 == ".text" || $1 == ".rodata" { flash += $2 }
  $1 == ".data" { flash += $2; ram += $2 }
  $1 == ".bss" || $1 == ".uninit" { ram += $2 }
  END { printf "STM32F407 board build: flash %d bytes (%.1f%% of 1 MiB), static RAM %d bytes (%.1f%% of 128 KiB)\n",
        flash, 100 * flash / 1048576, ram, 100 * ram / 131072 }'
# No panic reachable from the board's control step either (drivers and HAL SPI included), nor from
# its telemetry task.
./panic-check.sh "$elf"
./panic-check.sh "$elf" USART3
