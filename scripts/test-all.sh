#!/usr/bin/env bash
# Everything CI checks, in one command: system packages, formatting, lints, all tests (headless),
# docs, the windowed examples rendered to screenshots under Xvfb, and the screenshot checks.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/install-deps.sh
export CARGO_INCREMENTAL=0 CARGO_TERM_COLOR=never
log=target/test-all.log
mkdir -p target
: > "$log"
step() { echo; echo "==> $* (at ${SECONDS} s)"; }
# Free disk and memory, at the start and again if a step fails (a full disk or an out-of-memory
# linker shows up in CI only as a failed link).
resources() { df -h . ; free -g | sed -n 1,2p; }
step "disk and memory"
resources
trap 'echo; echo "==> a step failed; disk and memory now:"; resources' ERR

step "cargo fmt --check"
cargo fmt --all -- --check
step "cargo clippy (all targets, all features, -D warnings)"
cargo clippy --all-targets --all-features -- -D warnings
# Without features: what a game that does not use avian or the renderer compiles. No test behaves
# differently without features (they only add items), so the tests run once, below, with all of
# them; this build is checked, not run, and must stay free of avian.
step "cargo check (no features: headless, without avian)"
if cargo tree -e normal --prefix none | grep -q '^avian3d '; then
  echo "avian3d is in the build without features"
  exit 1
fi
cargo check --all-targets
# All features: the examples need the renderer anyway, so one build of Bevy serves the tests, the
# examples and the screenshots.
step "cargo test (all features)"
cargo test --all-features --lib --tests 2>&1 | tee -a "$log"
cargo test --all-features --doc 2>&1 | tee -a "$log"
step "cargo doc (all features, warnings are errors)"
RUSTDOCFLAGS="-D warnings" cargo doc --no-deps --all-features
step "screenshots of the windowed examples (Xvfb + lavapipe)"
bash scripts/screenshots.sh
step "screenshot checks"
cargo test --all-features --test screenshots -- --ignored 2>&1 | tee -a "$log"

step "summary"
awk '/^test result:/ { p += $4; f += $6; i += $8 } END {
  printf "all test binaries: %d passed, %d failed, %d ignored\n", p, f, i }' "$log"
grep -q "^test result: FAILED" "$log" && exit 1
echo "OK"
