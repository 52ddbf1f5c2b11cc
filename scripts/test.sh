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
# independent coordinate transform for the site import test.
if ! python3 -c "import laspy, numpy, pyproj" >/dev/null 2>&1; then
  python3 -m pip install --quiet laspy numpy pyproj 2>/dev/null \
    || python3 -m pip install --quiet --break-system-packages laspy numpy pyproj \
    || echo "warning: could not install laspy/pyproj: the LAS and site import tests will fail"
fi
RUNNER="cargo test --workspace"
if cargo nextest --version >/dev/null 2>&1; then
  RUNNER="cargo nextest run --workspace --no-fail-fast"
fi

say "format"
cargo fmt --all -- --check

say "clippy (all targets, warnings are errors)"
cargo clippy --workspace --all-targets -- -D warnings

say "core builds as no_std for the bare-metal target"
if rustup target list --installed 2>/dev/null | grep -qx "$THUMB"; then
  cargo build -p spherecal --no-default-features --target "$THUMB"
  cargo build -p spherecal --no-default-features --features sim --target "$THUMB"
else
  echo "warning: $THUMB is not installed: the no_std core is built for this machine instead"
  cargo build -p spherecal --no-default-features
fi

say "doc tests (nextest does not run them)"
cargo test --workspace --doc -q

say "tests"
$RUNNER

say "fuzzing: build every target, run each for ${FUZZ_SECONDS:-10} s from the committed corpus"
if ! cargo fuzz --version >/dev/null 2>&1; then
  cargo install cargo-fuzz --locked >/dev/null 2>&1 || echo "warning: could not install cargo-fuzz"
fi
if cargo fuzz --version >/dev/null 2>&1; then
  # cargo-fuzz needs nightly flags; RUSTC_BOOTSTRAP lets the stable toolchain take them.
  export RUSTC_BOOTSTRAP=1
  # No sanitizer: the code under test is safe Rust (forbid(unsafe_code)); libFuzzer's
  # coverage guidance and the panics are what find bugs here, 10-30x faster without ASan.
  (cd fuzz && cargo fuzz build -O -s none)
  work=$(mktemp -d)
  trap 'rm -rf "$work"' EXIT
  # One target per core at a time (each is single-threaded); a failing target's log is shown.
  fuzz_one() {
    local t=$1
    mkdir -p "$work/$t"
    # New inputs go to the scratch corpus; fuzz/seeds/$t (committed) is read only.
    if (cd fuzz && cargo fuzz run -O -s none "$t" "$work/$t" "seeds/$t" -- \
        -max_total_time="${FUZZ_SECONDS:-10}" -print_final_stats=1 >"$work/$t.log" 2>&1); then
      printf '%-16s %s\n' "$t" "$(grep -h 'stat::number_of_executed_units' "$work/$t.log" | awk '{print $2}') executions"
    else
      grep -A8 "panicked at" "$work/$t.log" | cut -c1-400 || true
      tail -20 "$work/$t.log" | cut -c1-400
      echo "error: fuzz target $t failed (reproducer in fuzz/artifacts/$t)" >&2
      return 1
    fi
  }
  failed=0
  for t in $(cd fuzz && cargo fuzz list); do
    while [ "$(jobs -rp | wc -l)" -ge "$(nproc)" ]; do wait -n || failed=1; done
    fuzz_one "$t" &
  done
  while [ "$(jobs -rp | wc -l)" -gt 0 ]; do wait -n || failed=1; done
  [ "$failed" -eq 0 ] || exit 1
else
  echo "warning: skipped: cargo-fuzz is not installed"
fi
say "done"
