#!/usr/bin/env bash
# The one test command (README): sets up what the tests need on a fresh Debian machine with the
# Rust toolchain, then runs every check. Used as-is by .ci/run.
set -euo pipefail
cd "$(dirname "$0")/.."

say() { printf '\n== %s (%d s in)\n' "$*" "$SECONDS"; }

say "set-up"
rustup component add rustfmt clippy >/dev/null 2>&1 || echo "warning: could not add rustfmt/clippy components"
THUMB=thumbv7em-none-eabihf
if ! rustup target list --installed 2>/dev/null | grep -qx "$THUMB"; then
  rustup target add "$THUMB" >/dev/null 2>&1 || echo "warning: target $THUMB cannot be fetched here: the bare-metal build is skipped"
fi
# laspy (+ numpy): an independent LAS reader for the georef test; pyproj (PROJ 9): an
# independent coordinate transform for the site import test; rosbags and mcap: independent
# rosbag2 / MCAP writers for the ROS 2 bag tests (scripts/ros2-bag.py).
PY_TEST_PACKAGES="laspy numpy pyproj rosbags==0.11.9 mcap==1.6.0"
if ! python3 -c "import laspy, numpy, pyproj, rosbags, mcap" >/dev/null 2>&1; then
  python3 -m pip install --quiet $PY_TEST_PACKAGES 2>/dev/null \
    || python3 -m pip install --quiet --break-system-packages $PY_TEST_PACKAGES \
    || echo "warning: could not install $PY_TEST_PACKAGES: the LAS, site import and ROS 2 bag tests will fail"
fi
# ouster-sdk: Ouster's own decoder, the reference for the Ouster captures' test
# (scripts/ouster_xyz.py), in a folder of its own (target/py-ouster: it pins an older rosbags
# than the ROS 2 tests use); fetched beside the build (it is used only by that test).
OUSTER_PY=$PWD/target/py-ouster
ouster_pid=
if ! PYTHONPATH=$OUSTER_PY python3 -c "import ouster.sdk" >/dev/null 2>&1; then
  (python3 -m pip install --quiet --target "$OUSTER_PY" ouster-sdk==1.0.1 2>/dev/null \
    || python3 -m pip install --quiet --break-system-packages --target "$OUSTER_PY" ouster-sdk==1.0.1 \
    || echo "warning: could not install ouster-sdk: the Ouster decoding test will fail") >/dev/null 2>&1 &
  ouster_pid=$!
fi
# qemu-system-arm for the core on an emulated Cortex-M (scripts/qemu-check.sh, at the end),
# fetched beside the build.
qemu_pid=
if ! command -v qemu-system-arm >/dev/null 2>&1 && command -v apt-get >/dev/null 2>&1 && [ "$(id -u)" = 0 ]; then
  (apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq qemu-system-arm) >/dev/null 2>&1 &
  qemu_pid=$!
fi
RUNNER="cargo test --workspace"
if cargo nextest --version >/dev/null 2>&1; then
  RUNNER="cargo nextest run --workspace --no-fail-fast"
fi

work=$(mktemp -d)
# The built-in surveys the tests synthesise, once each per run (tools/src/synth/cache.rs): on
# the RAM disk when it has room (about 1 GB is used), else beside the other scratch files.
synth_cache=$work/synth-cache
shm_kb=$(df -Pk /dev/shm 2>/dev/null | awk 'NR == 2 { print $4 }')
if [ -n "$shm_kb" ] && [ "$shm_kb" -gt 8000000 ]; then
  synth_cache=$(mktemp -d /dev/shm/spherecal-synth-cache.XXXXXX)
fi
mkdir -p "$synth_cache"
export SPHERECAL_SYNTH_CACHE=$synth_cache
trap 'rm -rf "$work" "$synth_cache"' EXIT
# A clean build gains nothing from incremental compilation's records (it only writes them).
if [ "${CI:-}" = "true" ]; then
  export CARGO_INCREMENTAL=0
fi
# The bare-metal and fuzz builds go to the RAM disk when it has room, in a target folder of
# their own either way (cargo's lock on the tests' folder would hold the tests' runs).
SIDE_TARGET=$PWD/target/side
free_kb=$(df -Pk /dev/shm 2>/dev/null | awk 'NR == 2 { print $4 }')
if [ -n "$free_kb" ] && [ "$free_kb" -gt 6000000 ]; then
  SIDE_TARGET=/dev/shm/spherecal-side-target
fi

# Fuzzing: build every target, then run each for FUZZ_SECONDS (5) from the committed corpus, as
# many side by side as there are CPUs.
fuzz_stage() {
  if ! cargo fuzz --version >/dev/null 2>&1; then
    echo "warning: skipped: cargo-fuzz is not installed"
    return 0
  fi
  # cargo-fuzz needs nightly flags; RUSTC_BOOTSTRAP lets the stable toolchain take them.
  export RUSTC_BOOTSTRAP=1
  local dir=(--target-dir "$SIDE_TARGET/fuzz")
  # No sanitizer: the code under test is safe Rust (forbid(unsafe_code)); libFuzzer's
  # coverage guidance and the panics are what find bugs here, 10-30x faster without ASan.
  # 16 codegen units: the build takes a third of one unit's CPU (~300 s here), for 5 s runs.
  dir+=(--codegen-units 16)
  (cd fuzz && cargo fuzz build -O -s none "${dir[@]}") || return 1
  local targets t failed=0 jobs release pids=()
  targets=$(cd fuzz && cargo fuzz list)
  jobs=$(nproc)
  # Each target's binary as `cargo fuzz run` starts it (its artifacts in fuzz/artifacts/$t/);
  # new inputs go to the scratch corpus; fuzz/seeds/$t (committed) is read only.
  release=$SIDE_TARGET/fuzz/$(rustc -vV | sed -n 's/^host: //p')/release
  for t in $targets; do
    mkdir -p "$work/$t" "fuzz/artifacts/$t"
    ("$release/$t" -artifact_prefix="$PWD/fuzz/artifacts/$t/" -max_total_time="${FUZZ_SECONDS:-5}" \
      -print_final_stats=1 "$work/$t" "fuzz/seeds/$t" >"$work/$t.log" 2>&1; echo $? >"$work/$t.rc") &
    pids+=($!)
    if [ "${#pids[@]}" -eq "$jobs" ]; then
      wait "${pids[@]}"
      pids=()
    fi
  done
  [ "${#pids[@]}" -eq 0 ] || wait "${pids[@]}"
  for t in $targets; do
    if [ "$(cat "$work/$t.rc")" = 0 ]; then
      printf '%-16s %s\n' "$t" "$(grep -h 'stat::number_of_executed_units' "$work/$t.log" | awk '{print $2}') executions"
    else
      grep -A8 "panicked at" "$work/$t.log" | cut -c1-400 || true
      tail -20 "$work/$t.log" | cut -c1-400
      echo "error: fuzz target $t failed (reproducer in fuzz/artifacts/$t)" >&2
      failed=1
    fi
  done
  return "$failed"
}

# clippy, in the side target folder. (In the tests' folder and profile it took their build
# scripts and proc macros as built, 175 s of CPU instead of 308, but its ~190 MB of writes to
# the disk beside the rig tests once overflowed a rig's log ring: 14,477 packets unlogged.)
lints() {
  say "clippy (all targets, warnings are errors)"
  cargo clippy --target-dir "$SIDE_TARGET" --workspace --all-targets -- -D warnings
}

# The core for the bare-metal target, with and without the simulator (in the side target
# folder: its own lock).
bare_metal() {
  say "core builds as no_std for the bare-metal target"
  local dir=(--target-dir "$SIDE_TARGET")
  if rustup target list --installed 2>/dev/null | grep -qx "$THUMB"; then
    cargo build "${dir[@]}" -p spherecal --no-default-features --target "$THUMB" || return 1
    cargo build "${dir[@]}" -p spherecal --no-default-features --features sim --target "$THUMB" || return 1
  else
    echo "warning: $THUMB is not installed: the no_std core is built for this machine instead"
    cargo build "${dir[@]}" -p spherecal --no-default-features || return 1
  fi
}

# cargo-fuzz when missing (a debug build: it only runs cargo, and unoptimised it builds in half
# the time).
fuzz_tool() {
  if ! cargo fuzz --version >/dev/null 2>&1; then
    cargo install cargo-fuzz --locked --debug --target-dir "$SIDE_TARGET/install" >/dev/null 2>&1 \
      || echo "warning: could not install cargo-fuzz"
  fi
}

checks() {
  lints && bare_metal
}

# A process and its descendants, each pid on a line.
descendants() {
  echo "$1"
  local c
  for c in $(ps -o pid= --ppid "$1" 2>/dev/null); do
    descendants "$c"
  done
}

# Let a process tree (the rest of the tests, started on the last CPU) run on every CPU: twice,
# for the processes started meanwhile by one not yet moved.
widen() {
  command -v taskset >/dev/null 2>&1 || return 0
  local all="0-$(($(nproc) - 1))" p
  for _ in 1 2; do
    for p in $(descendants "$1"); do
      taskset -a -p -c "$all" "$p" >/dev/null 2>&1 || true
    done
    sleep 0.2
  done
}

# Where chrt can: the idle scheduling class (a job in it takes only the cycles the others leave).
idle_class() {
  if command -v chrt >/dev/null 2>&1 && chrt -i 0 true 2>/dev/null; then
    echo chrt -i 0
  fi
}

# One core's work beside the build and the rig tests, one job at a time, on the last CPU only
# (taskset) so that a core stays free for the rig (the idle cycles of the rig's core are not
# worth it: on it, even in the idle class, the side job slowed the real-time replay measurably:
# 597 rpm heard for 600), at nice 19 and in the idle class (it takes only what the build
# leaves): the bare-metal builds, cargo-fuzz (when missing), clippy; all in their own target
# folder on the RAM disk, so that nothing is written to the disk the rig tests log to.
side_jobs() {
  local pin=()
  if command -v taskset >/dev/null 2>&1 && [ "$(nproc)" -ge 2 ]; then
    pin=(taskset -c "$(($(nproc) - 1))")
  fi
  export CARGO_BUILD_JOBS=1
  "${pin[@]}" $(idle_class) nice -n 19 bash -c "SECONDS=$SECONDS; $(declare -f say lints bare_metal fuzz_tool); $(declare -p work THUMB SIDE_TARGET)
    bare_metal; built=\$?
    fuzz_tool
    touch \"\$work/fuzz-ready\"
    [ \$built -eq 0 ] || exit 1
    lints && say 'side job finished'"
}

# The fuzzing, from when the rig tests end, on every CPU in the idle class: it takes what the
# rest of the tests leave (their single-threaded moments), then both CPUs when they end (it was
# the last to finish, on one CPU: 406 s after the tests).
fuzz_job() {
  # Until the side job says the fuzz build may start, or ends without saying it.
  while [ -d "$work" ] && [ ! -e "$work/fuzz-ready" ] && kill -0 "$side_pid" 2>/dev/null; do
    sleep 1
  done
  $(idle_class) nice -n 19 bash -c "SECONDS=$SECONDS; $(declare -f say fuzz_stage); $(declare -p work SIDE_TARGET); fuzz_stage && say 'fuzzing finished'"
}

say "format"
cargo fmt --all -- --check

# The rig tests replay surveys in real time; measured here, they stall (INS silences through
# the pseudo-terminal) when both cores are busy, so they run first, one at a time, with a core
# to themselves: beside them, on the last CPU only, the side job (clippy, the bare-metal builds),
# then the rest of the tests; those widen to every CPU when the rig tests end, the fuzzing and
# the Cortex-M check beside them in the idle class.
RIG='(binary(e2e) & test(/^rig::/)) | test(rig_steady_state)'
if [ "$RUNNER" = "cargo test --workspace" ]; then
  checks
  say "doc tests"
  cargo test --workspace --doc -q
  say "tests (cargo test: nextest is not installed)"
  [ -z "$ouster_pid" ] || wait "$ouster_pid" || true
  $RUNNER
  fuzz_tool
  fuzz_stage
else
  # The side job starts now, in the idle class on one core: the bare-metal builds and
  # cargo-fuzz take what the build leaves (its single-threaded tails and links).
  side_jobs >"$work/side.out" 2>&1 &
  side_pid=$!
  say "tests: build (the side job started beside it)"
  cargo nextest run --workspace --no-run
  say "doc tests (nextest does not run them)"
  cargo test --workspace --doc -q
  say "tests: the rig tests (real time), beside clippy on one core"
  $RUNNER -E "$RIG" &
  rig_pid=$!
  # The last CPU is the side job's until it ends (measured: minutes before the rig tests end):
  # then the rest of the tests start there (their output follows the rig tests').
  while kill -0 "$rig_pid" 2>/dev/null && kill -0 "$side_pid" 2>/dev/null; do
    sleep 1
  done
  rest_pin=()
  if kill -0 "$rig_pid" 2>/dev/null && command -v taskset >/dev/null 2>&1 && [ "$(nproc)" -ge 2 ]; then
    rest_pin=(taskset -c "$(($(nproc) - 1))")
  fi
  [ -z "$ouster_pid" ] || wait "$ouster_pid" || true
  say "tests: the rest start (on the last CPU while the rig tests run)"
  "${rest_pin[@]}" $RUNNER -E "not ($RIG)" >"$work/rest.out" 2>&1 &
  rest_pid=$!
  rig_rc=0
  wait "$rig_pid" || rig_rc=$?
  say "tests: the rig tests ended; the rest widen to every CPU, the fuzzing and the Cortex-M check beside them"
  widen "$rest_pid"
  fuzz_job >"$work/fuzz.out" 2>&1 &
  fuzz_pid=$!
  # The core on emulated Cortex-M chips (issue 49), at nice 19: it takes what the rest of the
  # tests leave (their last, single-threaded minutes).
  [ -z "$qemu_pid" ] || wait "$qemu_pid" || true
  qemu_pid=
  nice -n 19 scripts/qemu-check.sh >"$work/qemu.out" 2>&1 &
  qemu_check_pid=$!
  rest_rc=0
  wait "$rest_pid" || rest_rc=$?
  say "tests: the rest ended"
  cat "$work/rest.out"
  side_rc=0
  wait "$side_pid" || side_rc=$?
  say "clippy and the bare-metal builds (run beside the build and the rig tests)"
  cat "$work/side.out"
  fuzz_rc=0
  wait "$fuzz_pid" || fuzz_rc=$?
  say "the fuzzing (run beside the rest)"
  cat "$work/fuzz.out"
  qemu_rc=0
  wait "$qemu_check_pid" || qemu_rc=$?
  say "the core on an emulated Cortex-M (scripts/qemu-check.sh, run beside the rest)"
  cat "$work/qemu.out"
  [ "$qemu_rc" -eq 0 ] || echo "error: the Cortex-M check failed (above)" >&2
  [ "$rig_rc" -eq 0 ] || echo "error: the rig tests failed (above)" >&2
  [ "$rest_rc" -eq 0 ] || echo "error: tests failed (above)" >&2
  [ "$side_rc" -eq 0 ] || echo "error: clippy or a bare-metal build failed (above)" >&2
  [ "$fuzz_rc" -eq 0 ] || echo "error: a fuzz target failed (above)" >&2
  [ "$rig_rc" -eq 0 ] && [ "$rest_rc" -eq 0 ] && [ "$side_rc" -eq 0 ] && [ "$fuzz_rc" -eq 0 ] \
    && [ "$qemu_rc" -eq 0 ] || exit 1
fi
# Without nextest (no side job): the core on emulated Cortex-M7 and Cortex-M4 chips, its
# digests equal to the host's and the M7's budgets (issue 49).
if [ "$RUNNER" = "cargo test --workspace" ]; then
  [ -z "$qemu_pid" ] || wait "$qemu_pid" || true
  say "the core on an emulated Cortex-M (scripts/qemu-check.sh)"
  scripts/qemu-check.sh || exit 1
fi
say "done"
