#!/usr/bin/env bash
# Fuzzes the OBJ parser, the RON scene parser and the mesh builders with cargo-fuzz
# (libFuzzer): each target for SECONDS seconds (default 240), starting from the committed seeds in
# fuzz/seeds/<target> plus whatever fuzz/corpus/<target> has gathered. A crash stops the run and
# leaves its input in fuzz/artifacts/<target>/; reproduce it with
# `cargo +nightly fuzz run <target> fuzz/artifacts/<target>/<file>`.
#
#   scripts/fuzz.sh                      # obj scene subdivision mesh, 240 s each, AddressSanitizer
#   SECONDS_PER_TARGET=60 scripts/fuzz.sh obj
#   SANITIZER=none scripts/fuzz.sh       # no sanitizer: quicker build and more executions
#
# Needs a nightly toolchain and cargo-fuzz (`cargo install cargo-fuzz`). The fuzz crate has its own
# workspace and target directory (fuzz/target), so its sanitizer flags never touch the main build.
set -euo pipefail
cd "$(dirname "$0")/.."
seconds=${SECONDS_PER_TARGET:-240}
sanitizer=${SANITIZER:-address}
targets=("$@")
[ ${#targets[@]} -gt 0 ] || targets=(obj scene subdivision mesh)
nice="nice -n ${NICE:-15}"

$nice cargo +nightly fuzz build -s "$sanitizer"
mkdir -p fuzz/logs
for t in "${targets[@]}"; do
  mkdir -p "fuzz/corpus/$t"
  echo "==> $t: ${seconds} s (sanitizer: $sanitizer), log in fuzz/logs/$t.log"
  # New inputs go to fuzz/corpus/<t>; the seeds are read only. -max_len: bigger inputs only make
  # each run slower; -timeout: one input running this long is a hang; -rss_limit_mb: libFuzzer's
  # default, stated for the record.
  status=0
  $nice cargo +nightly fuzz run -s "$sanitizer" "$t" "fuzz/corpus/$t" "fuzz/seeds/$t" -- \
    -max_total_time="$seconds" -max_len=4096 -timeout=10 -rss_limit_mb=2048 \
    -print_final_stats=1 > "fuzz/logs/$t.log" 2>&1 || status=$?
  grep -E "^#[0-9]+[[:space:]]+(INITED|DONE)|^stat::(number_of_executed_units|average_exec_per_sec|peak_rss_mb|new_units_added)|^Done|SUMMARY|panicked" \
    "fuzz/logs/$t.log" || true
  if [ "$status" -ne 0 ]; then
    echo "!! $t failed (exit $status): see fuzz/logs/$t.log and fuzz/artifacts/$t/" >&2
    exit "$status"
  fi
done
