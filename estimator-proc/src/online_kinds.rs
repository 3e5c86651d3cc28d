//! Online K-kind estimation (`estimator.kinds-model`; beyond SPEC S7, which names two
//! classes). Each env's last `online-window` ticks are described by the stored classifier's
//! features, computed by [`crate::features`] exactly as `estimator-proc kinds` computed them
//! when it fitted and named the classifier, and the window is named after the kind of its
//! most probable component. Never refitted: the naming came from a labelled recording, which
//! a run does not have.
//!
//! As online SPEC S7 estimation: windows the robot barely moved in (`estimator.min-speed`)
//! keep the env's previous estimate (unless the classifier reads slip and the wheels were
//! driven: [`features::counts`]), and a respawn ([`KindsEstimator::reset_env`]) starts a
//! new window. A window no component explains (`estimator.unknown-beyond`) is unknown.

use crate::analysis::Series;
use crate::features::{self, Wheels};
use crate::kinds::StoredKinds;
use crate::rolling::RollingPath;
use crate::{EstimatorError, Result};
use common::AreaKind;
use common::Config;
use common::config::WindowFeature;
use std::collections::VecDeque;

/// One env's estimate after one tick.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct KindEstimate {
    /// The kind the window looks like; `None` until a full moving window, or when no
    /// component explains it.
    pub kind: Option<AreaKind>,
    /// The posterior of the chosen component; 0 without a kind.
    pub posterior: f64,
    /// The window's std of sin θx when the classifier uses it (SPEC S7's feature).
    pub pitch_std: Option<f64>,
}

/// What the estimator reads of one env's tick.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct KindTick {
    pub sin_pitch: f64,
    /// sin θz.
    pub sin_roll: f64,
    /// The robot's X-Z position, metres.
    pub at: [f64; 2],
    /// The wheels' mean command, rad/s (the slip feature's).
    pub command: f64,
}

#[derive(Debug, Clone)]
struct EnvWindow {
    /// The last `window` ticks, their positions shifted by `offset`.
    ticks: VecDeque<KindTick>,
    travel: RollingPath,
    held: KindEstimate,
    /// Added to every position read, so a window carried across placements is one path.
    offset: [f64; 2],
    /// The next tick follows a placement ([`KindsEstimator::jump_env`]).
    jumped: bool,
}

/// Per-env K-kind classifier over a stored, named mixture.
#[derive(Debug, Clone)]
pub struct KindsEstimator {
    stored: StoredKinds,
    beyond: f64,
    /// Path over a window below which it is stationary, metres.
    min_travel: f64,
    /// Wheel radius and decision step, for the commanded path.
    wheels: Wheels,
    /// Whether the classifier reads slip (then a window whose wheels were driven counts).
    slip: bool,
    envs: Vec<EnvWindow>,
    /// Where the classifier's features hold the std of sin θx, if they do.
    pitch_std_at: Option<usize>,
    /// Full windows left out as stationary.
    stationary: u64,
    /// The window being classified, refilled in place each tick.
    series: Series,
}

impl KindsEstimator {
    /// The classifier of `estimator.kinds-model` for `online-window`, for the run's envs and
    /// robot. The config is assumed validated ([`common::Config::validate`]).
    pub fn from_config(config: &Config) -> anyhow::Result<Self> {
        let cfg = &config.estimator;
        let path = cfg
            .kinds_model
            .as_deref()
            .ok_or_else(|| anyhow::anyhow!("estimator.kinds-model is not set"))?;
        let stored = crate::kinds::read_stored(path)?
            .into_iter()
            .find(|s| s.window == cfg.online_window)
            .ok_or_else(|| {
                anyhow::anyhow!(
                    "{}: no classifier for estimator.online-window {}",
                    path.display(),
                    cfg.online_window
                )
            })?;
        let wheels = Wheels {
            radius: config.sim.robot.wheel_radius,
            dt: config.sim.decision_dt(),
        };
        Ok(Self::new(
            stored,
            config.sim.num_envs(),
            cfg.unknown_beyond,
            (config.min_step_travel(), wheels),
        )?)
    }

    /// An estimator over `stored` for `num_envs` envs; windows shorter than `min_step_travel`
    /// metres per tick (of `wheels`' robot) are stationary.
    pub fn new(
        stored: StoredKinds,
        num_envs: usize,
        beyond: f64,
        (min_step_travel, wheels): (f64, Wheels),
    ) -> Result<Self> {
        if num_envs == 0 {
            return Err(EstimatorError::NoEnvs);
        }
        let w = stored.window;
        let env = EnvWindow {
            ticks: VecDeque::with_capacity(w),
            travel: RollingPath::new(w)?,
            held: KindEstimate::default(),
            offset: [0.0; 2],
            jumped: false,
        };
        Ok(Self {
            min_travel: min_step_travel * (w - 1) as f64,
            wheels,
            slip: stored.features.contains(&WindowFeature::Slip),
            pitch_std_at: stored
                .features
                .iter()
                .position(|f| *f == WindowFeature::PitchStd),
            beyond,
            envs: vec![env; num_envs],
            stationary: 0,
            stored,
            series: Series {
                env: 0,
                area: AreaKind::Flat,
                first_tick: 0,
                sin_pitch: Vec::with_capacity(w),
                sin_roll: Vec::with_capacity(w),
                xz: Vec::with_capacity(w),
                command: Vec::with_capacity(w),
            },
        })
    }

    pub fn window(&self) -> usize {
        self.stored.window
    }

    /// Full windows left out as stationary so far.
    pub fn stationary(&self) -> u64 {
        self.stationary
    }

    /// Forgets env `env`'s window and estimate (after a respawn).
    pub fn reset_env(&mut self, env: usize) -> Result<()> {
        let state = self.env_mut(env)?;
        state.ticks.clear();
        state.travel.clear();
        state.held = KindEstimate::default();
        state.offset = [0.0; 2];
        state.jumped = false;
        Ok(())
    }

    /// Keeps env `env`'s window and estimate across a placement (`estimator.on-placement =
    /// "carry"`): its next tick is read as if the robot stood where the last one left it.
    pub fn jump_env(&mut self, env: usize) -> Result<()> {
        self.env_mut(env)?.jumped = true;
        Ok(())
    }

    /// Feeds env `env`'s tick and returns its estimate. A non-finite value is refused and
    /// not fed.
    pub fn observe(&mut self, env: usize, tick: KindTick) -> Result<KindEstimate> {
        let values = [
            tick.sin_pitch,
            tick.sin_roll,
            tick.at[0],
            tick.at[1],
            tick.command,
        ];
        if let Some(&value) = values.iter().find(|v| !v.is_finite()) {
            return Err(EstimatorError::NonFiniteObservation { env, value });
        }
        let w = self.stored.window;
        let (min_travel, slip, wheels) = (self.min_travel, self.slip, self.wheels);
        let state = self.env_mut(env)?;
        if std::mem::take(&mut state.jumped)
            && let Some(last) = state.ticks.back()
        {
            state.offset = [last.at[0] - tick.at[0], last.at[1] - tick.at[1]];
        }
        let tick = KindTick {
            at: [tick.at[0] + state.offset[0], tick.at[1] + state.offset[1]],
            ..tick
        };
        if state.ticks.len() == w {
            state.ticks.pop_front();
        }
        state.ticks.push_back(tick);
        let Some(path) = state.travel.push(tick.at) else {
            return Ok(state.held);
        };
        // The moves into every tick but the first, as the rolling path counts them.
        let driven = || {
            let rim = state
                .ticks
                .iter()
                .skip(1)
                .map(|t| wheels.rim_path(t.command));
            rim.sum::<f64>()
        };
        if !features::counts(path, if slip { driven() } else { 0.0 }, min_travel) {
            self.stationary += 1;
            return Ok(self.envs[env].held);
        }
        let x = self.features_of(env)?;
        let model = &self.stored.model;
        let estimate = if model.explains(&x, self.beyond) {
            let (c, posterior) = model.posterior(&x);
            KindEstimate {
                kind: Some(self.stored.component_kinds[c]),
                posterior,
                pitch_std: None,
            }
        } else {
            KindEstimate::default()
        };
        let estimate = KindEstimate {
            pitch_std: self.pitch_std_at.map(|i| x[i]),
            ..estimate
        };
        self.envs[env].held = estimate;
        Ok(estimate)
    }

    /// The stored features of env `env`'s full window, by the offline code.
    fn features_of(&mut self, env: usize) -> Result<Vec<f64>> {
        let ticks = &self.envs[env].ticks;
        let s = &mut self.series;
        s.sin_pitch.clear();
        s.sin_pitch.extend(ticks.iter().map(|t| t.sin_pitch));
        s.sin_roll.clear();
        s.sin_roll.extend(ticks.iter().map(|t| t.sin_roll));
        s.xz.clear();
        s.xz.extend(ticks.iter().map(|t| t.at));
        s.command.clear();
        s.command.extend(ticks.iter().map(|t| t.command));
        // The gate was applied by the caller.
        let windows = features::window_features(
            std::slice::from_ref(s),
            self.stored.window,
            &self.stored.features,
            0.0,
            self.wheels,
        )?;
        Ok(windows.values)
    }

    fn env_mut(&mut self, env: usize) -> Result<&mut EnvWindow> {
        let envs = self.envs.len();
        self.envs
            .get_mut(env)
            .ok_or(EstimatorError::EnvOutOfRange { env, envs })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::gmm::Gmm;
    use crate::kinds::Classifier;

    /// A one-feature (pitch std) classifier: component 0 near 0.01 is slope, 1 near 0.1
    /// gravel, over windows of 4 ticks.
    fn estimator(min_step_travel: f64) -> KindsEstimator {
        let gmm = Gmm::new(vec![0.5, 0.5], vec![0.01, 0.1], vec![1e-4, 1e-4]).expect("gmm");
        let stored = StoredKinds {
            window: 4,
            features: vec![WindowFeature::PitchStd],
            component_kinds: vec![AreaKind::Slope, AreaKind::Gravel],
            model: Classifier::OneFeature(gmm),
        };
        KindsEstimator::new(stored, 2, 0.0, (min_step_travel, WHEELS)).expect("estimator")
    }

    const WHEELS: Wheels = Wheels {
        radius: 0.05,
        dt: 0.1,
    };

    /// A tick at sin θx `p`, at `x` along X, no roll, wheels still.
    fn tick(p: f64, x: f64) -> KindTick {
        KindTick {
            sin_pitch: p,
            at: [x, 0.0],
            ..KindTick::default()
        }
    }

    #[test]
    fn a_full_window_is_named_by_its_component_kind() {
        let mut e = estimator(0.0);
        let pitches = [0.0, 0.2, 0.0, 0.2, 0.0];
        let got: Vec<KindEstimate> = pitches
            .iter()
            .enumerate()
            .map(|(t, &p)| e.observe(0, tick(p, t as f64)).expect("observe"))
            .collect();
        assert!(
            got[..3].iter().all(|g| g.kind.is_none()),
            "no full window yet"
        );
        // (0, 0.2, 0, 0.2): mean 0.1, sample variance 4 · 0.01 / 3, std 0.1155: gravel.
        assert_eq!(got[3].kind, Some(AreaKind::Gravel));
        let std = got[3].pitch_std.expect("pitch std");
        assert!((std - (0.04f64 / 3.0).sqrt()).abs() < 1e-12, "{std}");
        assert!(got[3].posterior > 0.99);
        // The other env has its own window.
        assert_eq!(e.observe(1, tick(0.0, 0.0)).expect("observe").kind, None);
        for t in 0..4 {
            e.observe(0, tick(0.01 * f64::from(t % 2), f64::from(t)))
                .expect("observe");
        }
        assert_eq!(e.envs[0].held.kind, Some(AreaKind::Slope));
        e.reset_env(0).expect("reset");
        assert_eq!(e.envs[0].held.kind, None);
    }

    /// Carried across a placement, a window reads the ticks after it as if the robot drove
    /// on from where it stood: every estimate is the one without the jump.
    #[test]
    fn a_carried_window_reads_on_across_a_placement() {
        let mut e = estimator(0.1);
        for t in 0..12 {
            let p = 0.2 * f64::from(t % 2);
            let x = 0.5 * f64::from(t);
            if t == 6 {
                e.jump_env(1).expect("jump");
            }
            let placed = if t >= 6 { x - 40.0 } else { x };
            let a = e.observe(0, tick(p, x)).expect("observe");
            let b = e.observe(1, tick(p, placed)).expect("observe");
            assert_eq!(a, b, "tick {t}");
        }
        assert_eq!(e.envs[1].held.kind, Some(AreaKind::Gravel));
        assert_eq!(e.stationary(), 0);
        // Reset forgets the offset with the window.
        e.reset_env(1).expect("reset");
        assert_eq!(e.envs[1].offset, [0.0; 2]);
    }

    #[test]
    fn a_stationary_window_keeps_the_last_kind_and_bad_values_are_refused() {
        let mut e = estimator(0.1);
        for (t, p) in [0.0, 0.2, 0.0, 0.2].into_iter().enumerate() {
            e.observe(0, tick(p, 0.5 * t as f64)).expect("observe");
        }
        assert_eq!(e.envs[0].held.kind, Some(AreaKind::Gravel));
        // Standing still with a smooth pitch: a moving window would read slope.
        // The first two windows still span the drive; the next four see no movement.
        for _ in 0..6 {
            let g = e.observe(0, tick(0.0, 1.5)).expect("observe");
            assert_eq!(g.kind, Some(AreaKind::Gravel));
        }
        assert_eq!(e.stationary(), 4);
        assert!(e.observe(0, tick(f64::NAN, 0.0)).is_err());
        assert!(e.observe(2, tick(0.0, 0.0)).is_err());
    }

    #[test]
    fn a_slip_classifier_names_a_robot_whose_wheels_turn_where_it_stands() {
        // Slip alone: component 0 near 0 (rolling) is flat, 1 near 1 (dug in) sand.
        let gmm = Gmm::new(vec![0.5, 0.5], vec![0.0, 1.0], vec![0.01, 0.01]).expect("gmm");
        let stored = StoredKinds {
            window: 4,
            features: vec![WindowFeature::Slip],
            component_kinds: vec![AreaKind::Flat, AreaKind::Sand],
            model: Classifier::OneFeature(gmm),
        };
        let mut e = KindsEstimator::new(stored, 1, 0.0, (0.005, WHEELS)).expect("estimator");
        // Rolling at the command: 2 rad/s × 0.05 m × 0.1 s = 1 cm a tick, slip 0.
        for t in 0..4 {
            let g = e.observe(
                0,
                KindTick {
                    command: 2.0,
                    ..tick(0.0, 0.01 * f64::from(t))
                },
            );
            assert_eq!(g.expect("observe").kind, (t == 3).then_some(AreaKind::Flat));
        }
        // Dug in: the wheels turn, the robot stays. The window counts, and reads sand once
        // its three moves are all in place.
        let got: Vec<_> = (0..3)
            .map(|_| {
                let t = KindTick {
                    command: 2.0,
                    ..tick(0.0, 0.03)
                };
                e.observe(0, t).expect("observe").kind
            })
            .collect();
        assert_eq!(got[2], Some(AreaKind::Sand), "{got:?}");
        assert_eq!(e.stationary(), 0);
        // Wheels still too: stationary, the estimate holds.
        for _ in 0..4 {
            let g = e.observe(0, tick(0.0, 0.03)).expect("observe");
            assert_eq!(g.kind, Some(AreaKind::Sand));
        }
        assert!(e.stationary() > 0);
    }
}
