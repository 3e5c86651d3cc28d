#!/usr/bin/env bash
# The churn soak: two runs side by side for SECS seconds (default 1800), so both see the
# same machine: one whose learner and estimator are killed every 20-60 s and whose learner
# is swapped every 3 minutes, and one left alone. Each writes its report (JSON: restarts,
# swaps, policy versions, chunks missed, ticks/s and RSS over time, shared-memory files left,
# success rate) to OUT/faults.json and OUT/quiet.json.
#
#   scripts/soak.sh [SECS] [OUT]
set -euo pipefail
cd "$(dirname "$0")/.."
secs=${1:-1800}
out=${2:-target/soak}
mkdir -p "$out"
cargo build --workspace --bins
cargo test --no-run --test soak
for faults in 1 0; do
  name=$([ "$faults" = 1 ] && echo faults || echo quiet)
  LAVATUBE_SOAK_SECS=$secs LAVATUBE_SOAK_FAULTS=$faults LAVATUBE_SOAK_REPORT="$out/$name.json" \
    cargo test --test soak -- --ignored --nocapture > "$out/$name.log" 2>&1 &
done
status=0
for job in $(jobs -p); do wait "$job" || status=1; done
echo "reports: $out/faults.json $out/quiet.json (logs beside them)"
exit $status
