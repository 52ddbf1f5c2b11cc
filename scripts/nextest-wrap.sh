#!/bin/sh
# nextest wrapper (.config/nextest.toml): runs one test ("$@" is the test binary and its
# arguments) in a scratch folder of its own (TMPDIR, which the tests and the programs they start
# write to), removed when the test passes and kept, named on stderr, when it fails.
#   nextest-wrap.sh rig   ...  the rig tests: TMPDIR on the real disk (they measure logging with
#                              fsync), full CPU priority (they replay in real time);
#   nextest-wrap.sh batch ...  every other test: at nice 15 so that a rig's replay is never
#                              starved, and on a RAM disk (/dev/shm, when it has 4 GB free) so
#                              that their files do not stall the rig's fsync behind them.
kind=$1
shift
root=${TMPDIR:-/tmp}
prio=0
if [ "$kind" = batch ]; then
  prio=15
  free_kb=$(df -Pk /dev/shm 2>/dev/null | awk 'NR == 2 { print $4 }')
  if [ -n "$free_kb" ] && [ "$free_kb" -gt 4000000 ]; then
    root=/dev/shm
  fi
fi
dir=$(mktemp -d "$root/spherecal-test.XXXXXX") || exit 1
TMPDIR=$dir nice -n "$prio" "$@"
rc=$?
if [ "$rc" -eq 0 ]; then
  rm -rf "$dir"
else
  echo "nextest-wrap: the failed test's files are kept in $dir" >&2
fi
exit "$rc"
