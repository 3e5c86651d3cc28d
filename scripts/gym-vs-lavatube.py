#!/usr/bin/env python3
"""lavatube's simulator under Gymnasium and Stable-Baselines3, against lavatube's own runtime
on the same config: by default `configs/default.toml`'s 8 flat envs and PPO settings (SPEC S6
but for a constant learning rate; a config with `ppo.anneal-lr = true` decays it linearly to
0 over the run for both learners, as the paper does).

1. Throughput: env steps/s of `lavatube.gym.VectorEnv` under random actions, of SB3's PPO
   learning on it, and of `lavatube run` (its own learner) in async and in sync mode.
2. Learning: SB3's PPO and lavatube's learner with the same hyperparameters, each for STEPS
   env steps with SEEDS seeds: success rate and mean episode return over env steps, one plot
   (`curves.png`) and a table (`results.md`).

Needs the release binaries (`cargo build --release`) and, in a virtual environment,
`pip install ./python[gym] stable-baselines3 matplotlib`.

    scripts/gym-vs-lavatube.py [--config C] [--out DIR] [--steps 300000] [--seeds 3]
                               [--report-only]
"""

import argparse
import csv
import json
import subprocess
import time
import tomllib
import uuid
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
BIN = ROOT / "target" / "release"
#: Steps of the random-action throughput measurement.
RANDOM_STEPS = 40_000
#: Student's t at 97.5 % by degrees of freedom, for 95 % intervals over a few seeds.
T975 = {1: 12.706, 2: 4.303, 3: 3.182, 4: 2.776, 5: 2.571, 6: 2.447, 7: 2.365, 8: 2.306,
        9: 2.262}


def lavatube_run(base: Path, out: Path, seed: int, steps: int, mode: str) -> dict:
    """`lavatube run` on the config `base` with its own learner: steps/s, the curve, and the
    `[ppo]` section it ran with (every default filled in)."""
    run_id = f"{mode}-{seed}-{uuid.uuid4().hex[:6]}"
    config = out / f"{run_id}.toml"
    config.write_text(f'extends = "{base}"\n[run]\nseed = {seed}\ntotal-steps = {steps}\n'
                      f'mode = "{mode}"\nout-dir = "{out}"\n')
    subprocess.run([BIN / "lavatube", "run", "--config", config, "--run-id", run_id, "--quiet"],
                   check=True, stdout=subprocess.DEVNULL)
    summary = json.loads((out / run_id / "summary.json").read_text())
    with (out / run_id / "metrics.csv").open() as f:
        rows = [r for r in csv.DictReader(f) if r["success_rate"]]
    with (out / run_id / "config.toml").open("rb") as f:
        ppo = tomllib.load(f)["ppo"]
    return {"steps_per_s": summary["env_steps_per_second"], "ppo": ppo,
            "curve": [(int(r["global_step"]), float(r["success_rate"]),
                       float(r["mean_episode_return"])) for r in rows]}


def sb3_run(base: Path, out: Path, seed: int, steps: int, ppo: dict) -> dict:
    """SB3's PPO with lavatube's hyperparameters (`ppo`, a resolved `[ppo]` section) on the
    gym env: steps/s and the curve (one point per rollout, as lavatube's learner reports)."""
    import torch
    from stable_baselines3 import PPO
    from stable_baselines3.common.callbacks import BaseCallback
    from stable_baselines3.common.vec_env import VecMonitor, VecNormalize

    from lavatube.sb3 import VecEnv

    class Curve(BaseCallback):
        """Episodes ended in each rollout: success rate and mean return."""

        def __init__(self):
            super().__init__()
            self.points, self.returns, self.successes = [], [], []

        def _on_step(self) -> bool:
            for info in self.locals["infos"]:
                if "episode" in info:
                    self.returns.append(info["episode"]["r"])
                    self.successes.append(info["is_success"])
            return True

        def _on_rollout_end(self) -> None:
            if self.returns:
                self.points.append((self.num_timesteps, float(np.mean(self.successes)),
                                    float(np.mean(self.returns))))
            self.returns, self.successes = [], []

    envs = VecEnv(base, overrides={"run": {"out-dir": str(out)}}, bin_dir=BIN)
    n = envs.num_envs
    rate = ppo["learning-rate"]
    # SB3 calls a schedule with the fraction of the run still to go: linear decay to 0.
    schedule = (lambda remaining: rate * remaining) if ppo["anneal-lr"] else rate
    env = VecNormalize(VecMonitor(envs), norm_obs=True, norm_reward=False,
                       clip_obs=ppo["obs-clip"], gamma=ppo["gamma"])
    model = PPO("MlpPolicy", env, seed=seed, device="cpu",
                n_steps=ppo["rollout-transitions"] // n, batch_size=ppo["minibatch-size"],
                n_epochs=ppo["epochs"], learning_rate=schedule,
                gamma=ppo["gamma"], gae_lambda=ppo["gae-lambda"], clip_range=ppo["clip-coef"],
                ent_coef=ppo["ent-coef"], vf_coef=ppo["vf-coef"],
                max_grad_norm=ppo["max-grad-norm"], normalize_advantage=ppo["norm-adv"],
                policy_kwargs={"net_arch": {"pi": ppo["hidden"], "vf": ppo["hidden"]},
                               "activation_fn": torch.nn.Tanh,
                               "log_std_init": ppo["init-log-std"],
                               "ortho_init": ppo["ortho-init"]})
    curve = Curve()
    started = time.monotonic()
    model.learn(steps, callback=curve)
    secs = time.monotonic() - started
    env.close()
    return {"steps_per_s": model.num_timesteps / secs, "curve": curve.points}


def random_steps_per_s(base: Path, out: Path) -> float:
    """The gym env alone: random actions, no learner."""
    from lavatube.gym import VectorEnv

    envs = VectorEnv(base, overrides={"run": {"out-dir": str(out)}}, bin_dir=BIN)
    try:
        envs.reset(seed=1)
        envs.action_space.seed(1)
        actions = [envs.action_space.sample() for _ in range(64)]
        started = time.monotonic()
        for t in range(RANDOM_STEPS // envs.num_envs):
            envs.step(actions[t % len(actions)])
        return RANDOM_STEPS / (time.monotonic() - started)
    finally:
        envs.close()


def on_grid(curves: list, grid: np.ndarray, column: int) -> np.ndarray:
    """Each run's column interpolated onto `grid` (env steps), one row per run."""
    return np.array([np.interp(grid, [p[0] for p in c], [p[column] for p in c])
                     for c in curves])


def mean_ci(values, fmt: str = ",.0f") -> str:
    """Mean ± the half-width of its 95 % interval (Student's t) over seeds."""
    values = np.asarray(values, dtype=float)
    if len(values) < 2:
        return f"{values.mean():{fmt}}"
    t = T975.get(len(values) - 1, 1.96)
    half = t * values.std(ddof=1) / np.sqrt(len(values))
    return f"{values.mean():{fmt}} ± {half:{fmt}}"


def measure(base: Path, out: Path, steps: int, seeds: int) -> dict:
    """Every run of the comparison on the config `base`; also written to `out/results.json`."""
    print("gym env, random actions ...", flush=True)
    random = random_steps_per_s(base, out)
    print("lavatube run, async ...", flush=True)
    lavatube_async = lavatube_run(base, out, 1, steps, "async")["steps_per_s"]
    runs = {"lavatube": [], "sb3": []}
    for seed in range(1, seeds + 1):
        print(f"seed {seed}: lavatube's learner (sync) ...", flush=True)
        runs["lavatube"].append(lavatube_run(base, out, seed, steps, "sync"))
        print(f"seed {seed}: SB3 PPO on the gym env ...", flush=True)
        runs["sb3"].append(sb3_run(base, out, seed, steps, runs["lavatube"][-1]["ppo"]))
    results = {"config": str(base), "steps": steps, "random_steps_per_s": random,
               "lavatube_async_steps_per_s": lavatube_async, "runs": runs}
    (out / "results.json").write_text(json.dumps(results, indent=1))
    return results


def report(out: Path, results: dict):
    """`results.md` and `curves.png` in `out`: throughput, and per learner and seed the
    success rate and mean return over the last 20 % of the steps and the steps it took to
    reach 90 % success."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    runs, steps = results["runs"], results["steps"]
    grid = np.linspace(0, steps, 61)[1:]
    tail = grid >= 0.8 * steps
    lines = [f"# Gymnasium + SB3 against lavatube's runtime, {len(runs['sb3'])} seeds × "
             f"{steps:,} env steps, `{Path(results['config']).name}`", "",
             "| what | env steps/s |", "|---|---:|",
             f"| gym env, random actions (8 envs) | {results['random_steps_per_s']:,.0f} |",
             f"| `lavatube run`, async | {results['lavatube_async_steps_per_s']:,.0f} |",
             f"| `lavatube run`, sync (the learning runs) | "
             f"{mean_ci([r['steps_per_s'] for r in runs['lavatube']])} |",
             f"| SB3 PPO on the gym env (the learning runs) | "
             f"{mean_ci([r['steps_per_s'] for r in runs['sb3']])} |", "",
             "| learner | seed | success %, last 20 % of steps | mean return, last 20 % | "
             "env steps to 90 % success |", "|---|---|---:|---:|---:|"]
    fig, axes = plt.subplots(1, 2, figsize=(11, 4))
    for name, colour in (("lavatube", "tab:red"), ("sb3", "tab:blue")):
        curves = [r["curve"] for r in runs[name]]
        success, ret = on_grid(curves, grid, 1), on_grid(curves, grid, 2)
        late_success, late_return = 100 * success[:, tail].mean(axis=1), ret[:, tail].mean(axis=1)
        for seed, (s, r, row) in enumerate(zip(late_success, late_return, success), 1):
            reach = f"{grid[np.argmax(row >= 0.9)]:,.0f}" if (row >= 0.9).any() else "never"
            lines.append(f"| {name} | {seed} | {s:.1f} | {r:.1f} | {reach} |")
        lines.append(f"| {name} | mean ± 95 % CI | {mean_ci(late_success, '.1f')} | "
                     f"{mean_ci(late_return, '.1f')} | |")
        label = {"lavatube": "lavatube's learner", "sb3": "Stable-Baselines3 PPO"}[name]
        for ax, values in zip(axes, (success, ret)):
            for row in values:
                ax.plot(grid, row, color=colour, alpha=0.25, linewidth=0.8)
            ax.plot(grid, values.mean(axis=0), color=colour, linewidth=2, label=label)
    for ax, title in zip(axes, ("success rate", "mean episode return")):
        ax.set_xlabel("env steps")
        ax.set_title(title)
        ax.grid(alpha=0.3)
    axes[0].legend()
    fig.tight_layout()
    fig.savefig(out / "curves.png", dpi=120)
    (out / "results.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))
    print(f"plot: {out / 'curves.png'}")


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--config", type=Path, default=ROOT / "configs" / "default.toml")
    parser.add_argument("--out", type=Path, default=Path("runs/gym-vs-lavatube"))
    parser.add_argument("--steps", type=int, default=300_000)
    parser.add_argument("--seeds", type=int, default=3)
    parser.add_argument("--report-only", action="store_true",
                        help="redo results.md and curves.png from OUT/results.json")
    args = parser.parse_args()
    out = args.out.resolve()
    out.mkdir(parents=True, exist_ok=True)
    if args.report_only:
        results = json.loads((out / "results.json").read_text())
    else:
        results = measure(args.config.resolve(), out, args.steps, args.seeds)
    report(out, results)


if __name__ == "__main__":
    main()
