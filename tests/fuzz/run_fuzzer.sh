#!/usr/bin/env bash
# Runs a libFuzzer binary for a bounded time from committed seed corpora.
#   run_fuzzer.sh BINARY SECONDS WORKDIR SEED_DIR...
# New inputs go to WORKDIR/corpus (never into the committed seeds); a crash,
# leak or timeout leaves its input in WORKDIR/artifacts and fails the test.
set -euo pipefail
bin=$1; seconds=$2; work=$3; shift 3
mkdir -p "$work/corpus" "$work/artifacts"
exec "$bin" -max_total_time="$seconds" -timeout=5 -rss_limit_mb=2048 -max_len=4096 \
  -print_final_stats=1 -artifact_prefix="$work/artifacts/" "$work/corpus" "$@"
