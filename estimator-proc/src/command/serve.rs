//! `estimator-proc serve`: the online estimator inside a run. Reads every telemetry tick,
//! classifies each env's terrain from its rolling pitch statistics (or, with
//! `estimator.kinds-model`, names its terrain kind from the stored classifier's features),
//! and publishes the estimates on `terrain` (SPEC S7 online; DESIGN §1).

use crate::OnlineEstimator;
use crate::online_kinds::{KindTick, KindsEstimator};
use common::AreaKind;
use common::config::{AttitudeSource, OnPlacement};
use common::ipc::{self, Bus};
use common::wire::{self, EnvTick, TerrainEstimate, TerrainHeader, TickHeader};
use std::time::Duration;

/// The classifier a run serves: SPEC S7's two classes, or terrain kinds by a stored,
/// named classifier (`estimator.kinds-model`).
enum Classifying {
    Classes(OnlineEstimator),
    Kinds(KindsEstimator),
}

impl Classifying {
    fn reset_env(&mut self, env: usize) -> crate::Result<()> {
        match self {
            Classifying::Classes(e) => e.reset_env(env),
            Classifying::Kinds(e) => e.reset_env(env),
        }
    }

    fn jump_env(&mut self, env: usize) -> crate::Result<()> {
        match self {
            Classifying::Classes(e) => e.jump_env(env),
            Classifying::Kinds(e) => e.jump_env(env),
        }
    }

    /// Env `t.env`'s estimate after tick `t`, its attitude read from `signal`.
    fn observe(&mut self, t: &EnvTick, signal: AttitudeSource) -> crate::Result<TerrainEstimate> {
        let env = t.env as usize;
        let at = [f64::from(t.pos[0]), f64::from(t.pos[2])];
        let (sin_pitch, euler) = match signal {
            AttitudeSource::Truth => (t.sin_pitch, t.euler),
            AttitudeSource::Imu => (t.imu_sin_pitch, t.imu_euler),
        };
        let (class, posterior, window_std, window) = match self {
            Classifying::Classes(est) => {
                let e = est.observe_at(env, f64::from(sin_pitch), Some(at))?;
                let class = e.class.map_or(wire::CLASS_UNKNOWN, |c| c.min(254) as u8);
                (class, e.posterior, e.window_std, e.window)
            }
            Classifying::Kinds(est) => {
                let tick = KindTick {
                    sin_pitch: f64::from(sin_pitch),
                    sin_roll: f64::from(euler[2]).sin(),
                    at,
                    command: 0.5 * f64::from(t.command[0] + t.command[1]),
                };
                let e = est.observe(env, tick)?;
                let class = e.kind.map_or(wire::CLASS_UNKNOWN, AreaKind::code);
                (class, e.posterior, e.pitch_std, est.window())
            }
        };
        Ok(TerrainEstimate {
            env: t.env,
            class,
            posterior: posterior as f32,
            window_std: window_std.unwrap_or(0.0) as f32,
            window: window as u32,
            ..TerrainEstimate::default()
        })
    }

    /// Whether an estimate of `class` on ground `area` is right; `None`: not scored.
    fn scores(&self, class: u8, area: u8) -> Option<bool> {
        match self {
            Classifying::Classes(_) => scores(class, area),
            Classifying::Kinds(_) => (class != wire::CLASS_UNKNOWN).then_some(class == area),
        }
    }

    fn refits(&self) -> u64 {
        match self {
            Classifying::Classes(e) => e.stats().fits,
            Classifying::Kinds(_) => 0,
        }
    }

    fn stationary(&self) -> u64 {
        match self {
            Classifying::Classes(e) => e.stats().stationary,
            Classifying::Kinds(e) => e.stationary(),
        }
    }
}

/// Classifies every env's terrain in the run `args` names and publishes the estimates until
/// the run asks it to stop.
pub fn execute(args: &common::cli::JoinArgs) -> anyhow::Result<()> {
    let cfg = super::input::load_config(Some(&args.config))?;
    let n = cfg.sim.num_envs();
    let bus = Bus::connect(&args.run_id, "estimator")?;
    let control = bus.control_listener()?;
    let rx = bus.receiver::<EnvTick, TickHeader>(&ipc::TELEMETRY, None)?;
    let tx = bus.sender::<TerrainEstimate, TerrainHeader>(&ipc::TERRAIN, None, n)?;
    let est = if cfg.estimator.kinds_model.is_some() {
        Classifying::Kinds(KindsEstimator::from_config(&cfg)?)
    } else {
        Classifying::Classes(
            OnlineEstimator::from_config(&cfg.estimator, n, cfg.run.seed)?
                .gate_stationary(cfg.min_step_travel()),
        )
    };
    let mut serving = Serving {
        est,
        signal: cfg.estimator.signal,
        out: vec![TerrainEstimate::default(); n],
        settling: Settling::new(cfg.estimator.settle_ticks, n),
        on_placement: cfg.estimator.on_placement,
        scored: 0,
        correct: 0,
        ticks: 0,
    };
    tracing::info!(
        envs = n,
        window = cfg.estimator.online_window,
        signal = ?cfg.estimator.signal,
        kinds = matches!(serving.est, Classifying::Kinds(_)),
        "estimator serving"
    );
    while !bus.stop_requested(&control) {
        tx.update_connections()?;
        rx.wait(Duration::from_millis(100))?;
        while let Some(sample) = rx.try_recv()? {
            let h = *sample.user_header();
            serving.read(sample.payload())?;
            tx.send(serving.header(h.tick), &serving.out)?;
            serving.ticks += 1;
        }
    }
    serving.finish();
    Ok(())
}

/// The estimator in a run: its classifier, every env's newest estimate, and its scores.
struct Serving {
    est: Classifying,
    /// Whose attitude the classifier reads (`estimator.signal`).
    signal: AttitudeSource,
    /// Every env's newest estimate, as published.
    out: Vec<TerrainEstimate>,
    settling: Settling,
    on_placement: OnPlacement,
    scored: u64,
    correct: u64,
    ticks: u64,
}

impl Serving {
    /// Reads one telemetry tick of every env into its estimate, scoring it by the env's
    /// true ground.
    fn read(&mut self, ticks: &[EnvTick]) -> anyhow::Result<()> {
        let n = self.out.len();
        for t in ticks.iter().filter(|t| (t.env as usize) < n) {
            let env = t.env as usize;
            let (placed, read) = self.settling.tick(env, t.events);
            if placed {
                self.place(env)?;
            }
            if !read {
                continue;
            }
            let e = match self.est.observe(t, self.signal) {
                Ok(e) => e,
                Err(err) => {
                    tracing::warn!(env, error = %err, "observation skipped");
                    continue;
                }
            };
            if let Some(right) = self.est.scores(e.class, t.area) {
                // Labels score the estimator; they never reach the fit.
                self.scored += 1;
                self.correct += u64::from(right);
            }
            self.out[env] = e;
        }
        Ok(())
    }

    /// Env `env`'s robot was placed somewhere new: its window runs on across the jump, or
    /// (`new-window`) a new one starts, with no estimate until it fills.
    fn place(&mut self, env: usize) -> crate::Result<()> {
        match self.on_placement {
            OnPlacement::Carry => self.est.jump_env(env),
            OnPlacement::NewWindow => {
                self.est.reset_env(env)?;
                self.out[env] = TerrainEstimate {
                    env: env as u32,
                    class: wire::CLASS_UNKNOWN,
                    ..TerrainEstimate::default()
                };
                Ok(())
            }
        }
    }

    /// The header of the estimates after telemetry tick `tick`.
    fn header(&self, tick: u64) -> TerrainHeader {
        TerrainHeader {
            tick,
            scored: self.scored,
            correct: self.correct,
            envs: self.out.len() as u32,
            refits: self.est.refits() as u32,
        }
    }

    /// Logs the closing line: ticks read, scores, refits and stationary windows.
    fn finish(&self) {
        tracing::info!(
            ticks = self.ticks,
            scored = self.scored,
            correct = self.correct,
            refits = self.est.refits(),
            stationary_windows = self.est.stationary(),
            "estimator done"
        );
    }
}

/// Which ticks follow a placement and which are read: a robot put somewhere new (a respawn, a
/// fault's respawn, or an evaluation course's next leg) is placed, and its first `ticks`
/// ticks, the placement's own included, are left out while it settles
/// (`estimator.settle-ticks`).
struct Settling {
    ticks: usize,
    /// Ticks each env still leaves out.
    left: Vec<usize>,
}

impl Settling {
    fn new(ticks: usize, envs: usize) -> Self {
        Self {
            ticks,
            left: vec![0; envs],
        }
    }

    /// For env `env`'s tick with `events`: whether the robot was placed somewhere new, and
    /// whether the estimator reads the tick.
    fn tick(&mut self, env: usize, events: u8) -> (bool, bool) {
        let placed = events & (wire::EVENT_PLACED | wire::EVENT_FAULT) != 0;
        if placed {
            self.left[env] = self.ticks;
        }
        let read = self.left[env] == 0;
        self.left[env] = self.left[env].saturating_sub(1);
        (placed, read)
    }
}

/// Whether an estimate of `class` is right on ground `area` (`AreaKind::code`), or `None`
/// when it is not scored: an unknown class, or ground other than SPEC S7's flat and rough,
/// which the two-class estimator cannot name (a slope or gravel would count as "rough").
fn scores(class: u8, area: u8) -> Option<bool> {
    let flat = AreaKind::Flat.code();
    let rough = AreaKind::Rough.code();
    (class != wire::CLASS_UNKNOWN && (area == flat || area == rough))
        .then_some((class > 0) == (area == rough))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_placement_or_a_fault_is_seen_and_its_settling_ticks_are_not_read() {
        let mut s = Settling::new(2, 2);
        let placed = wire::EVENT_TRUNCATED | wire::EVENT_PLACED;
        let seen: Vec<_> = [0, placed, 0, 0, 0].iter().map(|&e| s.tick(0, e)).collect();
        assert_eq!(
            seen,
            [
                (false, true),
                (true, false),
                (false, false),
                (false, true),
                (false, true)
            ]
        );
        // A fault's respawn is a placement too; the other env never noticed.
        assert_eq!(
            s.tick(0, wire::EVENT_TERMINATED | wire::EVENT_FAULT),
            (true, false)
        );
        assert_eq!(s.tick(1, 0), (false, true));
        // A chained episode's success: the robot drives on from where it is.
        let mut s = Settling::new(0, 1);
        assert_eq!(
            s.tick(0, wire::EVENT_TERMINATED | wire::EVENT_SUCCESS),
            (false, true)
        );
        // No settling: the placement's own tick is read.
        assert_eq!(s.tick(0, placed), (true, true));
    }

    /// An env classified, then placed: carried, it keeps its estimate through the settling
    /// ticks and after; with a new window it has none until the window fills again.
    #[test]
    fn a_placement_keeps_the_estimate_or_starts_a_new_window() {
        use crate::gmm::Gmm;
        let serving = |on_placement| {
            let model = Gmm::new(vec![0.5, 0.5], vec![0.02, 0.08], vec![1e-4, 1e-3]).expect("gmm");
            let cfg = common::config::EstimatorConfig {
                online_window: 10,
                refit_every: 0,
                ..Default::default()
            };
            Serving {
                est: Classifying::Classes(
                    OnlineEstimator::with_model(&cfg, 1, 1, model).expect("estimator"),
                ),
                signal: AttitudeSource::Truth,
                out: vec![TerrainEstimate::default(); 1],
                settling: Settling::new(3, 1),
                on_placement,
                scored: 0,
                correct: 0,
                ticks: 0,
            }
        };
        let classes = |s: &mut Serving| -> Vec<u8> {
            (0..16)
                .map(|t| {
                    let tick = EnvTick {
                        sin_pitch: if t % 2 == 0 { 0.08 } else { -0.08 },
                        pos: [0.01 * t as f32, 0.0, 0.0],
                        events: if t == 12 { wire::EVENT_PLACED } else { 0 },
                        ..EnvTick::default()
                    };
                    s.read(&[tick]).expect("read");
                    s.out[0].class
                })
                .collect()
        };
        let unknown = wire::CLASS_UNKNOWN;
        let carried = classes(&mut serving(OnPlacement::Carry));
        assert_eq!(carried[..9], [unknown; 9]);
        assert_eq!(carried[9..], [1; 7], "rough from the first full window on");
        let renewed = classes(&mut serving(OnPlacement::NewWindow));
        assert_eq!(renewed[9..12], [1; 3]);
        assert_eq!(renewed[12..], [unknown; 4], "placed at 12: a new window");
    }

    #[test]
    fn only_flat_and_rough_ground_is_scored() {
        assert_eq!(scores(0, AreaKind::Flat.code()), Some(true));
        assert_eq!(scores(1, AreaKind::Flat.code()), Some(false));
        assert_eq!(scores(1, AreaKind::Rough.code()), Some(true));
        assert_eq!(scores(wire::CLASS_UNKNOWN, AreaKind::Rough.code()), None);
        assert_eq!(scores(1, AreaKind::Slope.code()), None);
        assert_eq!(scores(0, AreaKind::Gravel.code()), None);
    }
}
