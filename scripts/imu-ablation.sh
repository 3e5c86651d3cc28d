#!/usr/bin/env bash
# Which IMU error costs the terrain estimator most: stage c of a finished IMU pipeline
# (`lavatube reproduce --config configs/paper-imu.toml`) driven again by its general model,
# once with every error of `[sim.imu]`, once with none, and once with each error term set to
# zero in turn. Each collection is analysed as stage d does, on the IMU's sin θx, and again
# on the true sin θx of the same recording, so the IMU's cost is measured on the very same
# trajectories (each variant drives its own: the policy observes the IMU too).
# Prints per variant and window: accuracy % on the IMU's signal, on the truth's, and the
# difference in percentage points.
#
#   scripts/imu-ablation.sh SEED_DIR [OUT]    # SEED_DIR: e.g. reproduce/seed-1
set -euo pipefail
cd "$(dirname "$0")/.."
seed_dir=$(realpath "${1:?usage: scripts/imu-ablation.sh SEED_DIR [OUT]}")
out=$(realpath -m "${2:-target/imu-ablation}")
collect="$seed_dir/c-collect/traces.toml"
policy="$seed_dir/policies/general.policy"
for f in "$collect" "$policy"; do
  [ -f "$f" ] || { echo "imu-ablation: $f is missing: run the IMU pipeline to stage d first" >&2; exit 1; }
done
steps=$(grep -E '^collect-steps' "$seed_dir/config.toml" | tr -dc '0-9')
cargo build --release -p sim-proc -p estimator-proc
bin=target/release
mkdir -p "$out"

# Variant name, then the TOML laid over stage c's config.
variants=(
  "all errors" ""
  "no errors" $'[sim.imu.gyro]\nnoise-density = 0.0\nbias-walk = 0.0\nturn-on-bias = 0.0\nscale-error = 0.0\nbits = 0\n[sim.imu.accel]\nnoise-density = 0.0\nbias-walk = 0.0\nturn-on-bias = 0.0\nscale-error = 0.0\nbits = 0'
)
for sensor in gyro accel; do
  for term in noise-density bias-walk turn-on-bias scale-error bits; do
    zero=$([ "$term" = bits ] && echo 0 || echo 0.0)
    variants+=("no $sensor $term" $'[sim.imu.'"$sensor"$']\n'"$term = $zero")
  done
done

for ((i = 0; i < ${#variants[@]}; i += 2)); do
  name=${variants[i]}
  dir="$out/${name// /-}"
  mkdir -p "$dir"
  printf 'extends = "%s"\n%s\n' "$collect" "${variants[i + 1]}" > "$dir/config.toml"
  "$bin/sim-proc" --config "$dir/config.toml" --controller policy --weights "$policy" \
    --steps "$steps" --telemetry "$dir/traces.csv" > "$dir/sim.log" 2>&1
  for signal in imu truth; do
    "$bin/estimator-proc" analyze "$dir/traces.csv" --config "$dir/config.toml" \
      --signal "$signal" --out "$dir/$signal" > "$dir/$signal.log" 2>&1
    grep -oE '"accuracy": *[0-9.]+' "$dir/$signal/results.json" | grep -oE '[0-9.]+$' \
      > "$dir/$signal.accuracy"
  done
  echo "$name (window: IMU % / truth % / difference pp):$(paste "$dir/imu.accuracy" \
    "$dir/truth.accuracy" <(grep -oE '"window": *[0-9]+' "$dir/imu/results.json" \
    | grep -oE '[0-9]+$' | head -n "$(wc -l < "$dir/imu.accuracy")") | awk '{printf "  %d: %.2f / %.2f / %+.2f", $3, 100 * $1, 100 * $2, 100 * ($1 - $2)}')"
done
