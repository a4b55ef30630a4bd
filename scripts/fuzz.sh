#!/usr/bin/env bash
# Fuzzes every parser of cutload with libFuzzer (docs/fuzzing.md):
#
#   scripts/fuzz.sh [SECONDS_PER_TARGET]      (default 60)
#
# builds the fuzz configuration (clang, address and undefined-behaviour sanitizers) into
# ${CUTLOAD_FUZZ_BUILD_DIR:-build-fuzz}, seeds each target's corpus from the bundled data and
# tests/fuzz/seeds, runs each target for the given time and prints executions, crashes, time-outs
# and out-of-memory stops per target. Exit status: 0 when every target ran clean, 1 when one found
# something (the input is kept under <build>/artifacts/<target>/), 77 when clang or libFuzzer is
# missing (the test suite reports the test as skipped).
#
# Environment: CUTLOAD_FUZZ_TARGETS (a subset, e.g. "nc_program run_spec"), CUTLOAD_JOBS (build
# jobs), CUTLOAD_FUZZ_TIMEOUT_S (one input's limit, default 10), CUTLOAD_FUZZ_RSS_MB (default 2048).
set -euo pipefail
cd "$(dirname "$0")/.."
ROOT=$(pwd)

SECONDS_PER_TARGET=${1:-60}
if ! [[ "$SECONDS_PER_TARGET" =~ ^[0-9]+$ ]] || [ "$SECONDS_PER_TARGET" -lt 1 ]; then
  echo "usage: scripts/fuzz.sh [SECONDS_PER_TARGET]" >&2
  exit 2
fi
BUILD_DIR=${CUTLOAD_FUZZ_BUILD_DIR:-build-fuzz}
case "$BUILD_DIR" in /*) ;; *) BUILD_DIR="$ROOT/$BUILD_DIR" ;; esac
JOBS=${CUTLOAD_JOBS:-$(nproc)}
TIMEOUT_S=${CUTLOAD_FUZZ_TIMEOUT_S:-10}
RSS_MB=${CUTLOAD_FUZZ_RSS_MB:-2048}
ALL_TARGETS="log_csv shdr nc_program run_spec dyno_csv channel_map forces_bin"
TARGETS=${CUTLOAD_FUZZ_TARGETS:-$ALL_TARGETS}

# ---- clang and libFuzzer present? (Debian: clang, libclang-rt-dev) ----
CLANGXX=${CUTLOAD_FUZZ_CXX:-$(command -v clang++ || true)}
if [ -z "$CLANGXX" ]; then
  echo "cutload fuzz: skipped: clang++ not found (Debian: apt-get install clang libclang-rt-dev)"
  exit 77
fi
probe=$(mktemp -d)
trap 'rm -rf "$probe"' EXIT
printf 'extern "C" int LLVMFuzzerTestOneInput(const unsigned char*, unsigned long) { return 0; }\n' >"$probe/p.cpp"
if ! "$CLANGXX" -fsanitize=fuzzer,address,undefined "$probe/p.cpp" -o "$probe/p" >/dev/null 2>&1; then
  echo "cutload fuzz: skipped: $CLANGXX cannot link a libFuzzer target (Debian: apt-get install libclang-rt-dev)"
  exit 77
fi

# ---- build ----
launcher=()
if command -v ccache >/dev/null 2>&1; then launcher=(-DCMAKE_CXX_COMPILER_LAUNCHER=ccache); fi
echo "cutload fuzz: building the fuzz targets in $BUILD_DIR"
mkdir -p "$BUILD_DIR"
# Line tables only: the sanitizers' reports name file and line, and the build stays short. -O2: the
# clock stage's period scan runs 3 times slower at -O1 under the sanitizers.
cmake -S . -B "$BUILD_DIR" -DCUTLOAD_FUZZ=ON -DCMAKE_CXX_COMPILER="$CLANGXX" -DCMAKE_BUILD_TYPE=RelWithDebInfo \
  -DCMAKE_CXX_FLAGS_RELWITHDEBINFO="-O2 -gline-tables-only -DNDEBUG" \
  -DCUTLOAD_BUILD_TESTS=OFF -DCUTLOAD_BUILD_BENCH=OFF "${launcher[@]}" >"$BUILD_DIR/configure.log" 2>&1 ||
  { cat "$BUILD_DIR/configure.log" >&2; exit 1; }
build_targets=()
for t in $TARGETS; do build_targets+=("fuzz_$t"); done
cmake --build "$BUILD_DIR" -j "$JOBS" --target "${build_targets[@]}" >"$BUILD_DIR/build.log" 2>&1 ||
  { tail -50 "$BUILD_DIR/build.log" >&2; exit 1; }

# ---- seeds: the bundled data, cut short ----
# 25 rows: enough moving readings for the clock stage's period scan, which on a stretch under 257
# readings costs about 0.1 s per 10 rows even without the sanitizers (docs/fuzzing.md).
SEEDS="$BUILD_DIR/seeds"
rm -rf "$SEEDS"
for t in $ALL_TARGETS; do
  mkdir -p "$SEEDS/$t" "$BUILD_DIR/corpus/$t"
  cp tests/fuzz/seeds/"$t"/* "$SEEDS/$t/"
done
for log in data/demo_dryrun.csv data/demo2_dryrun.csv; do
  name=$(basename "$log" .csv)
  head -n 26 "$log" >"$SEEDS/log_csv/${name}_start.csv"
  { head -n 1 "$log"; sed -n '1200,1224p' "$log"; } >"$SEEDS/log_csv/${name}_cutting.csv"
done
# The first demo's start as an SHDR stream: one line per reading, each at its own time stamp.
awk -F, 'function stamp(s) { return sprintf("2024-01-01T00:%02d:%09.6fZ", int(s / 60), s - 60 * int(s / 60)) }
  NR > 1 && NR <= 26 {
    print stamp($1) "|Sspeed|" $2
    print stamp($3) "|path_feedrate|" $4 / 60
    print stamp($5) "|path_pos|" $6 " " $7 " " $8 "|block|" $9
  }' data/demo_dryrun.csv >"$SEEDS/shdr/demo_start.txt"
cp data/*.nc "$SEEDS/nc_program/"
cp data/*_run.json "$SEEDS/run_spec/"
cp data/maps/*.json "$SEEDS/channel_map/"

# ---- run ----
printf '\n%-12s %8s %12s %9s %8s %9s %6s %8s\n' target seconds executions exec/s corpus crashes time-outs oom
status=0
for t in $TARGETS; do
  # This run's findings only (a finding of an earlier run is reproduced by running the target on it).
  out="$BUILD_DIR/artifacts/$t"
  rm -rf "$out"
  mkdir -p "$out"
  log="$BUILD_DIR/$t.log"
  dict=()
  [ -f "tests/fuzz/dict/$t.dict" ] && dict=(-dict="tests/fuzz/dict/$t.dict")
  rc=0
  "$BUILD_DIR/tests/fuzz/fuzz_$t" "$BUILD_DIR/corpus/$t" "$SEEDS/$t" "${dict[@]}" \
    -max_total_time="$SECONDS_PER_TARGET" -timeout="$TIMEOUT_S" -rss_limit_mb="$RSS_MB" -max_len=16384 \
    -print_final_stats=1 -error_exitcode=1 -artifact_prefix="$out/" >"$log" 2>&1 || rc=$?
  execs=$(sed -n 's/^stat::number_of_executed_units: *//p' "$log" | tail -1)
  secs=$(sed -n 's/^Done [0-9]* runs in \([0-9]*\) second.*/\1/p' "$log" | tail -1)
  crashes=$(find "$out" -name 'crash-*' -o -name 'leak-*' | wc -l)
  timeouts=$(find "$out" -name 'timeout-*' | wc -l)
  ooms=$(find "$out" -name 'oom-*' | wc -l)
  corpus=$(find "$BUILD_DIR/corpus/$t" -type f | wc -l)
  rate=0
  [ -n "$execs" ] && [ -n "$secs" ] && [ "$secs" -gt 0 ] && rate=$((execs / secs))
  printf '%-12s %8s %12s %9s %8s %9s %6s %8s\n' "$t" "${secs:-?}" "${execs:-?}" "$rate" "$corpus" "$crashes" "$timeouts" "$ooms"
  if [ "$rc" -ne 0 ] || [ "$crashes" -gt 0 ] || [ "$timeouts" -gt 0 ] || [ "$ooms" -gt 0 ]; then
    status=1
    echo "  $t: exit $rc; inputs in $out/, the run's output in $log:" >&2
    grep -E -m 8 'ERROR|SUMMARY|runtime error|invariant broken|terminate called|what\(\)|ALARM|out-of-memory' "$log" >&2 || tail -20 "$log" >&2
  fi
done
exit $status
