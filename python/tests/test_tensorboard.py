"""The TensorBoard event files of a finished smoke run (conftest.py's `run` fixture), read with
TensorBoard's own reader, against the `metrics.csv` beside them and the launcher's scalars."""

import csv

import numpy as np
from tensorboard.backend.event_processing.event_accumulator import EventAccumulator

# Mirrors ML_AGENTS_TAGS in learner-proc/src/metrics.rs: the columns under ML-Agents' names.
# Every other numeric column `c` is `lavatube/c`.
ML_AGENTS_TAGS = {
    "mean_episode_return": "Environment/Cumulative Reward",
    "policy_loss": "Losses/Policy Loss",
    "value_loss": "Losses/Value Loss",
    "entropy": "Policy/Entropy",
    "learning_rate": "Policy/Learning Rate",
}
#: Columns that are not numbers, hence not scalars.
NOT_SCALARS = {"chunks_by_source"}


def tag(column):
    return ML_AGENTS_TAGS.get(column, f"lavatube/{column}")


def load(directory):
    events = EventAccumulator(str(directory), size_guidance={"scalars": 0})  # 0: keep all
    events.Reload()
    return events


def test_event_files_hold_the_metrics_csv_and_the_launcher_scalars(run):
    assert run.proc.wait() == 0, "the run failed or was killed by the watchdog"

    with (run.dir / "metrics.csv").open(newline="") as f:
        rows = list(csv.DictReader(f))
    assert rows, "metrics.csv has no rows"
    columns = [c for c in rows[0] if c not in NOT_SCALARS]
    events = load(run.dir)
    # A column empty in every row has no tag at all; no tag comes from elsewhere.
    assert sorted(events.Tags()["scalars"]) == sorted(
        tag(c) for c in columns if any(r[c] != "" for r in rows))

    for c in columns:
        # An empty cell (no episode ended in that update) has no event at that step.
        kept = [r for r in rows if r[c] != ""]
        if not kept:
            continue
        scalars = events.Scalars(tag(c))
        assert [s.step for s in scalars] == [int(r["global_step"]) for r in kept], c
        # `simple_value` is a float32: the CSV's number rounded to float32, exactly.
        np.testing.assert_array_equal(
            np.array([s.value for s in scalars], dtype=np.float32),
            np.array([float(r[c]) for r in kept], dtype=np.float32), err_msg=c)

    launcher = load(run.dir / "launcher").Tags()["scalars"]
    assert {"lavatube/policy_lag", "Environment/Success Rate"} <= set(launcher), launcher
