#!/usr/bin/env bash
# The project's test command: the no_std core under std (host-tests/) and the host tools (tools/).
# Each crate is built for the machine running cargo (their .cargo/config.toml sets host-tuple);
# both are members of one host workspace (tools/Cargo.toml) with one lock file, tools/Cargo.lock.
# Ends with one summary line over both crates: "tests: N passed, M failed, K ignored".
# `./test.sh --full` also runs the slow tier (the tools' `slow-tests` feature: whole diagnoses
# that each guard one past regression, listed as ignored otherwise).
set -euo pipefail
cd "$(dirname "$0")"
features=()
case "${1:-}" in
  "") ;;
  --full) features=(--features slow-tests) ;;
  *) echo "usage: ./test.sh [--full]" >&2; exit 2 ;;
esac
log=$(mktemp)
trap 'rm -f "$log"' EXIT
status=0
(cd host-tests && cargo test --locked --no-fail-fast) 2>&1 | tee -a "$log" || status=1
(cd tools && cargo test --locked --no-fail-fast "${features[@]}") 2>&1 | tee -a "$log" || status=1
passed=$(grep -oE 'test result: [a-zA-Z]+\. [0-9]+ passed' "$log" | awk '{s += $4} END {print s + 0}')
failed=$(grep -oE '[0-9]+ failed;' "$log" | awk '{s += $1} END {print s + 0}')
ignored=$(grep -oE '[0-9]+ ignored;' "$log" | awk '{s += $1} END {print s + 0}')
echo "tests: ${passed} passed, ${failed} failed, ${ignored} ignored"
exit $status
