#!/usr/bin/env bash
# The core on an emulated Cortex-M (issue 49). Builds the firmware crate (firmware/) for
# thumbv7em-none-eabihf twice: for the Cortex-M7 (its double-precision FPU: -C
# target-cpu=cortex-m7) run on QEMU's mps2-an500, and for the Cortex-M4 (single-precision FPU:
# the core's f64 in software) on mps2-an386; both under instruction counting (-icount shift=0).
# Runs the same stages on the host and exits 0 only when every digest line of both chips equals
# the host's, bit for bit, and the Cortex-M7's budgets hold. Prints the figures.
# Installs qemu-system-arm with apt when missing; without it (or the thumb target) it skips
# with a loud warning.
set -euo pipefail
cd "$(dirname "$0")/.."
THUMB=thumbv7em-none-eabihf
# Budgets: an STM32H7-class part (1 MiB flash, 512 KiB RAM), and a 480 MHz Cortex-M7 keeping
# up with a VLP-16 at 600 rpm (754 data packets/s) with half its time free.
FLASH_MAX=$((1024 * 1024))
RAM_MAX=$((512 * 1024))
INSTR_MAX=300000

if ! command -v qemu-system-arm >/dev/null 2>&1; then
  if command -v apt-get >/dev/null 2>&1 && [ "$(id -u)" = 0 ]; then
    echo "qemu-check: installing qemu-system-arm"
    (apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq qemu-system-arm >/dev/null) ||
      echo "qemu-check: apt-get could not install qemu-system-arm" >&2
  fi
fi
if ! command -v qemu-system-arm >/dev/null 2>&1; then
  echo "WARNING: qemu-system-arm is missing and cannot be installed here: the core was NOT run on an emulated Cortex-M" >&2
  exit 0
fi
if ! rustup target list --installed 2>/dev/null | grep -qx "$THUMB"; then
  rustup target add "$THUMB" >/dev/null 2>&1 || {
    echo "WARNING: the $THUMB target cannot be installed here: the core was NOT run on an emulated Cortex-M" >&2
    exit 0
  }
fi

work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
# The host's digest from the tests' profile (their build already holds the core's
# dependencies; cargo writes that profile's binaries to target/debug): IEEE arithmetic gives
# the same bits in any profile.
cargo build -q -p spherecal-firmware --profile test
target/debug/spherecal-firmware >"$work/host"
figures() { grep -e '^flash ' -e '^ram ' -e '^stack ' -e '^instructions ' "$1"; }
value() { grep "^$1 " "$2" | awk '{print $(NF)=="bytes" ? $(NF-1) : $NF}'; }

# build CPU: the firmware for CPU, in a target folder of its own.
build() {
  CARGO_PROFILE_RELEASE_DEBUG=false RUSTFLAGS="-C target-cpu=$1 -D warnings" \
    cargo build -q --release -p spherecal-firmware --target "$THUMB" --target-dir "target/firmware-$1"
}

# run CPU MACHINE: the CPU's build on MACHINE, compared with the host; the output in $work/CPU.
run() {
  local cpu=$1 machine=$2 out="$work/$1"
  timeout 300 qemu-system-arm -machine "$machine" -nographic -monitor none -serial none \
    -icount shift=0,align=off,sleep=off -semihosting-config enable=on,target=native \
    -kernel "target/firmware-$cpu/$THUMB/release/spherecal-firmware" >"$out" || {
    echo "qemu-check: the firmware failed on $machine ($cpu):" >&2
    cat "$out" >&2
    return 1
  }
  if ! diff "$work/host" <(grep -v -e '^flash ' -e '^ram ' -e '^stack ' -e '^instructions ' "$out") >&2; then
    echo "qemu-check: $machine ($cpu): the digest differs from the host's (above: < host, > chip)" >&2
    return 1
  fi
  echo "qemu-check: $machine ($cpu): the digest equals the host's, bit for bit ($(wc -l <"$work/host") lines)"
  figures "$out" | sed "s/^/  $cpu: /"
}

# The two builds side by side (each waits on its core crate's codegen), then the runs.
build cortex-m7 &
m7_build=$!
build cortex-m4
wait "$m7_build"
run cortex-m7 mps2-an500
run cortex-m4 mps2-an386
m7="$work/cortex-m7"
flash=$(value flash "$m7")
ram=$(value ram "$m7")
stack=$(value stack "$m7")
per_packet=$(value "instructions per data packet" "$m7")
fail=0
[ "$flash" -le "$FLASH_MAX" ] || { echo "qemu-check: flash $flash bytes, over the budget of $FLASH_MAX" >&2; fail=1; }
[ $((ram + stack)) -le "$RAM_MAX" ] || { echo "qemu-check: RAM $ram + stack $stack bytes, over the budget of $RAM_MAX" >&2; fail=1; }
[ "$per_packet" -le "$INSTR_MAX" ] || { echo "qemu-check: $per_packet instructions per data packet, over the budget of $INSTR_MAX" >&2; fail=1; }
[ "$fail" -eq 0 ] && echo "qemu-check: the Cortex-M7 within its budgets (flash $FLASH_MAX, RAM $RAM_MAX bytes, $INSTR_MAX instructions per data packet)"
exit $fail
