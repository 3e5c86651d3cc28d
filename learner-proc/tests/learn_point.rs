//! PPO learns a real control task: a differential-drive point robot must reach a target with
//! the simulator's interface (10-float observation as SPEC S5, two wheel commands clipped to
//! ±3, decision step 0.1 s), episodes end on success (terminated) or at a time limit
//! (truncated, bootstrapped), and the next target is drawn around wherever the robot stopped
//! (SPEC S3). The learner sees it only through `Rollout`s, as it will see the simulator.

use std::f64::consts::PI;

use common::config::Config;
use common::policy::{PolicyLayout, Scratch};
use common::{ACT_DIM, OBS_DIM, Policy, Rng, Transition};
use learner_proc::{EpisodeOutcome, Learner, MetricsLog, Rollout};

const DT: f32 = 0.1;
const ACTION_LIMIT: f32 = 3.0;
/// Metres per second of forward speed per unit of mean wheel command.
const SPEED: f32 = 0.05;
const TRACK: f32 = 0.1;
const REACH: f32 = 0.05;
const TIME_LIMIT: u32 = 60;

struct PointEnv {
    rng: Rng,
    x: f32,
    z: f32,
    yaw: f32,
    target: [f32; 2],
    dist: f32,
    steps: u32,
    ret: f32,
}

impl PointEnv {
    fn new(seed: u64) -> Self {
        let mut rng = Rng::new(seed);
        let yaw = rng.range(-PI, PI) as f32;
        let mut env = Self {
            rng,
            x: 0.0,
            z: 0.0,
            yaw,
            target: [0.0; 2],
            dist: 0.0,
            steps: 0,
            ret: 0.0,
        };
        env.new_target();
        env
    }

    /// A target 0.1–0.5 m away in any direction (SPEC S3's annulus with Δ = 0.1).
    fn new_target(&mut self) {
        let r = self.rng.range(0.1, 0.5) as f32;
        let a = self.rng.range(-PI, PI) as f32;
        self.target = [self.x + r * a.cos(), self.z + r * a.sin()];
        self.dist = r;
        self.steps = 0;
        self.ret = 0.0;
    }

    /// SPEC S5's observation on flat ground: the target in the robot frame, its distance, and
    /// cos/sin of pitch, yaw and roll.
    fn obs(&self) -> [f32; OBS_DIM] {
        let (dx, dz) = (self.target[0] - self.x, self.target[1] - self.z);
        let (s, c) = self.yaw.sin_cos();
        let forward = dx * c + dz * s;
        let left = -dx * s + dz * c;
        [left, 0.0, forward, self.dist, 1.0, 0.0, c, s, 1.0, 0.0]
    }

    /// Steps with the clipped wheel commands; returns (reward, terminated, truncated).
    fn step(&mut self, action: [f32; ACT_DIM]) -> (f32, bool, bool) {
        let [l, r] = action.map(|a| a.clamp(-ACTION_LIMIT, ACTION_LIMIT));
        let v = SPEED * 0.5 * (l + r);
        let w = SPEED * (r - l) / TRACK;
        self.yaw += w * DT;
        self.x += v * self.yaw.cos() * DT;
        self.z += v * self.yaw.sin() * DT;
        let before = self.dist;
        self.dist = ((self.target[0] - self.x).powi(2) + (self.target[1] - self.z).powi(2)).sqrt();
        self.steps += 1;
        let success = self.dist < REACH;
        let reward = 10.0 * (before - self.dist) + if success { 1.0 } else { 0.0 };
        self.ret += reward;
        (reward, success, !success && self.steps >= TIME_LIMIT)
    }
}

/// Success rate and mean return of the deterministic policy over fixed episodes.
fn evaluate(weights: Vec<f32>, layout: &PolicyLayout, obs_clip: f32) -> (f64, f64) {
    let policy = Policy::new(layout.clone(), weights, obs_clip).expect("layout");
    let mut scratch = Scratch::default();
    let episodes = 64;
    let (mut successes, mut total) = (0, 0.0f64);
    for e in 0..episodes {
        let mut env = PointEnv::new(10_000 + e);
        loop {
            let mut a = [0.0; ACT_DIM];
            policy.mean_action(&env.obs(), &mut a, &mut scratch);
            let (_, terminated, truncated) = env.step(a);
            if terminated || truncated {
                successes += usize::from(terminated);
                total += f64::from(env.ret);
                break;
            }
        }
    }
    (successes as f64 / episodes as f64, total / episodes as f64)
}

#[test]
fn ppo_learns_to_reach_targets() {
    const ENVS: usize = 8;
    const STEPS: usize = 128;
    const UPDATES: u64 = 60;
    let mut cfg = Config::default();
    cfg.ppo.hidden = vec![64, 64];
    cfg.run.total_steps = UPDATES * (ENVS * STEPS) as u64;
    let layout = PolicyLayout::new(OBS_DIM, &cfg.ppo.hidden, ACT_DIM);
    let mut learner = Learner::new(&cfg, layout.clone(), 7).expect("learner");
    let obs_clip = cfg.ppo.obs_clip as f32;
    let before = evaluate(learner.policy_weights(), &layout, obs_clip);

    let run_dir = tempfile::tempdir().expect("tempdir");
    let mut log = MetricsLog::open(run_dir.path()).expect("metrics");
    let mut envs: Vec<PointEnv> = (0..ENVS as u64).map(PointEnv::new).collect();
    let mut rng = Rng::new(99);
    let mut transitions = Vec::with_capacity(ENVS * STEPS);
    let mut episodes = Vec::new();
    let mut last_success = Vec::new();
    for _ in 0..UPDATES {
        transitions.clear();
        episodes.clear();
        for _ in 0..STEPS {
            let obs: Vec<[f32; OBS_DIM]> = envs.iter().map(PointEnv::obs).collect();
            let sampled = learner.sample_actions(&obs, &mut rng).expect("sample");
            for (e, (env, s)) in envs.iter_mut().zip(sampled).enumerate() {
                let (reward, terminated, truncated) = env.step(s.action);
                let mut t = Transition {
                    obs: obs[e],
                    action: s.action,
                    logprob: s.logprob,
                    reward,
                    policy_version: learner.policy_version(),
                    env: e as u32,
                    terminated: u8::from(terminated),
                    truncated: u8::from(truncated),
                    ..Transition::default()
                };
                if terminated || truncated {
                    t.final_obs = env.obs();
                    episodes.push(EpisodeOutcome {
                        env: e as u32,
                        episode_return: env.ret,
                        steps: env.steps,
                        success: terminated,
                    });
                    env.new_target();
                }
                transitions.push(t);
            }
        }
        let bootstrap: Vec<[f32; OBS_DIM]> = envs.iter().map(PointEnv::obs).collect();
        let metrics = learner
            .update(&Rollout {
                transitions: &transitions,
                bootstrap_obs: &bootstrap,
                episodes: &episodes,
            })
            .expect("update");
        log.append(&metrics).expect("log");
        last_success.push(metrics.success_rate.unwrap_or(0.0));
    }
    let after = evaluate(learner.policy_weights(), &layout, obs_clip);
    eprintln!(
        "success rate, mean return: before {before:?}, after {after:?}; per update {last_success:?}"
    );
    let rows = std::fs::read_to_string(log.path())
        .expect("csv")
        .lines()
        .count();
    assert_eq!(rows, UPDATES as usize + 1);
    assert!(
        after.0 >= 0.8 && after.0 >= before.0 + 0.4 && after.1 > before.1 + 1.0,
        "success rate and mean return before {before:?}, after {after:?}; training success per update {last_success:?}"
    );
}
