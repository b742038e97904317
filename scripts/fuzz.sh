#!/usr/bin/env bash
# Fuzzes DigiView's inputs: each target in fuzz/ (the DigiView protocol's frames, the control
# server's frame handling, MAVLink messages into the link, its cameras and gimbals, the web
# API's bodies, lens.cal, state files and the serve configuration, the external detector's
# lines) runs MINUTES (default 10) under cargo-fuzz, which this script installs with the
# nightly toolchain it needs when they are missing. The corpus each run grows is minimised
# into fuzz/corpus/TARGET, which is committed: `cargo test` replays it (tests/it/fuzz_corpus.rs).
# A failing input is kept in fuzz/artifacts/TARGET and the script exits 1, naming it.
#
#   bash scripts/fuzz.sh [MINUTES] [TARGET...]
set -euo pipefail
cd "$(dirname "$0")/.."

minutes=${1:-10}
if ! [[ $minutes =~ ^[1-9][0-9]*$ ]]; then
  echo "fuzz: MINUTES is a whole number of minutes, 1 or more, not '$minutes'" >&2
  exit 2
fi
shift || true

if ! rustup run nightly rustc --version >/dev/null 2>&1; then
  echo "fuzz: installing the nightly Rust toolchain (cargo-fuzz's sanitizers need it)"
  rustup toolchain install nightly --profile minimal
fi
if ! cargo +nightly fuzz --version >/dev/null 2>&1; then
  echo "fuzz: installing cargo-fuzz"
  cargo install cargo-fuzz --locked
fi

targets=("$@")
if ((${#targets[@]} == 0)); then
  mapfile -t targets < <(cargo +nightly fuzz list)
fi

failed=()
for t in "${targets[@]}"; do
  corpus=fuzz/corpus/$t
  mkdir -p "$corpus"
  echo "fuzz: $t for $minutes min (corpus: $(find "$corpus" -type f | wc -l) inputs)"
  if ! cargo +nightly fuzz run "$t" "$corpus" -- \
      -max_total_time=$((minutes * 60)) -timeout=10 -rss_limit_mb=4096 -print_final_stats=1; then
    failed+=("$t")
    continue
  fi
  # The committed corpus keeps only the inputs that add coverage.
  cargo +nightly fuzz cmin "$t" "$corpus" >/dev/null 2>&1
  echo "fuzz: $t done (corpus: $(find "$corpus" -type f | wc -l) inputs)"
done

if ((${#failed[@]})); then
  echo "fuzz: failures in ${failed[*]}: see fuzz/artifacts/" >&2
  exit 1
fi
echo "fuzz: every target ran $minutes min and found nothing"
