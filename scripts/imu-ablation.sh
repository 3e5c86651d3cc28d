#!/usr/bin/env bash
# What the simulated IMU costs, and which of its errors costs most: stage c of a finished IMU
# pipeline (`lavatube reproduce --config configs/paper-imu.toml`) driven again by its general
# model, once with every error of `[sim.imu]`, once with none, once with each error term set
# to zero in turn, and once observing the true attitude (the IMU still recorded).
#
# Per variant it prints
# - Table 3 as stage d computes it, on the IMU's sin θx and on the true sin θx of the same
#   recording, and their difference in percentage points: the IMU's cost to the estimator on
#   the very same trajectories (each variant drives its own, as the policy observes the IMU);
# - the general model's success rate per area over the episodes the recording ended.
#
#   scripts/imu-ablation.sh SEED_DIR [OUT] [STEPS] [ROUGHNESS]
#
# SEED_DIR is e.g. reproduce/seed-1; STEPS the decision steps per env (default stage c's);
# ROUGHNESS the ground's `roughness-scale` (default stage c's; stage f drives on
# `reproduce.eval-roughness-scale`).
set -euo pipefail
cd "$(dirname "$0")/.."
usage="usage: scripts/imu-ablation.sh SEED_DIR [OUT] [STEPS] [ROUGHNESS]"
seed_dir=$(realpath "${1:?$usage}")
out=$(realpath -m "${2:-target/imu-ablation}")
collect="$seed_dir/c-collect/traces.toml"
policy="$seed_dir/policies/general.policy"
for f in "$collect" "$policy"; do
  [ -f "$f" ] || { echo "imu-ablation: $f is missing: run the IMU pipeline to stage d first" >&2; exit 1; }
done
steps=${3:-$(grep -E '^collect-steps' "$seed_dir/config.toml" | tr -dc '0-9')}
ground=${4:+$'\n[sim.terrain]\nroughness-scale = '"$4"}
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
variants+=("true attitude observed" $'[sim]\nobservation = "truth"\n[sim.imu]\nsimulate = true')

for ((i = 0; i < ${#variants[@]}; i += 2)); do
  name=${variants[i]}
  dir="$out/${name// /-}"
  mkdir -p "$dir"
  printf 'extends = "%s"\n%s\n%s\n' "$collect" "${variants[i + 1]}" "$ground" > "$dir/config.toml"
  "$bin/sim-proc" --config "$dir/config.toml" --controller policy --weights "$policy" \
    --steps "$steps" --telemetry "$dir/traces.csv" > "$dir/sim.log" 2>&1
  for signal in imu truth; do
    "$bin/estimator-proc" analyze "$dir/traces.csv" --config "$dir/config.toml" \
      --signal "$signal" --out "$dir/$signal" > "$dir/$signal.log" 2>&1
    grep -oE '"accuracy": *[0-9.]+' "$dir/$signal/results.json" | grep -oE '[0-9.]+$' \
      > "$dir/$signal.accuracy"
  done
  table3=$(paste "$dir/imu.accuracy" "$dir/truth.accuracy" \
    <(grep -oE '"window": *[0-9]+' "$dir/imu/results.json" | grep -oE '[0-9]+$' \
      | head -n "$(wc -l < "$dir/imu.accuracy")") \
    | awk '{printf "  %d: %.2f / %.2f / %+.2f", $3, 100 * $1, 100 * $2, 100 * ($1 - $2)}')
  success=$(awk -F, 'NR == 1 { for (i = 1; i <= NF; i++) col[$i] = i; next }
    $col["terminated"] == "true" || $col["truncated"] == "true" {
      ended[$col["area"]]++; if ($col["success"] == "true") won[$col["area"]]++ }
    END { for (a in ended) printf "  %s %.1f %% of %d", a, 100 * won[a] / ended[a], ended[a] }' \
    "$dir/traces.csv")
  echo "$name"
  echo "  Table 3 (window: IMU % / truth % / difference pp):$table3"
  echo "  success:$success"
done
