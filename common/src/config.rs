//! The configuration tree: one TOML file, parsed with unknown keys refused, then validated.
//!
//! Every field has a documented default, unit and range; every interpretation of the paper
//! (SPEC "(interpretation)") is a field here. Parsing and validation are two steps: serde
//! checks types and names, [`Config::validate`] checks ranges and cross-field rules.

use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// A configuration problem, always naming the field or file it is about.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ConfigError {
    #[error("cannot read config {path}: {reason}")]
    Read { path: PathBuf, reason: String },
    #[error("{path}:{line}:{column}: {message}")]
    Parse {
        path: PathBuf,
        line: usize,
        column: usize,
        message: String,
    },
    #[error("config field `{field}` = {value}: {reason}")]
    Invalid {
        field: &'static str,
        value: String,
        reason: String,
    },
}

fn invalid(
    field: &'static str,
    value: impl std::fmt::Debug,
    reason: impl Into<String>,
) -> ConfigError {
    ConfigError::Invalid {
        field,
        value: format!("{value:?}"),
        reason: reason.into(),
    }
}

/// Checks `lo <= value <= hi` (and finiteness) for one field.
fn in_range(field: &'static str, value: f64, lo: f64, hi: f64) -> Result<(), ConfigError> {
    if value.is_finite() && (lo..=hi).contains(&value) {
        Ok(())
    } else {
        Err(invalid(field, value, format!("must be in [{lo}, {hi}]")))
    }
}

fn count_in(field: &'static str, value: usize, lo: usize, hi: usize) -> Result<(), ConfigError> {
    if (lo..=hi).contains(&value) {
        Ok(())
    } else {
        Err(invalid(field, value, format!("must be in [{lo}, {hi}]")))
    }
}

/// The whole configuration of a run.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields, rename_all = "kebab-case", default)]
pub struct Config {
    pub run: RunConfig,
    pub sim: SimConfig,
    pub ppo: PpoConfig,
    pub estimator: EstimatorConfig,
    pub supervise: SuperviseConfig,
    pub reproduce: ReproduceConfig,
}

/// How runs are named, seeded and paced.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, rename_all = "kebab-case", default)]
pub struct RunConfig {
    /// Master seed; every process derives its streams from it. Any u64. Default 1.
    pub seed: u64,
    /// `sync`: the sim waits for the policy learned from each rollout (on-policy PPO);
    /// `async`: the sim never waits. Default `sync`.
    pub mode: LearnMode,
    /// Total environment steps (decision steps summed over envs) to train for. Default 2.5 M
    /// (SPEC S6). Range 1 ..= 10^10.
    pub total_steps: u64,
    /// Directory under which each run gets `<out-dir>/<run-id>/`. Default `runs`.
    pub out_dir: PathBuf,
    /// The learners of the run, one per policy slot (DESIGN §5). A `general` learner trains on
    /// every transition; a `flat` or `rough` one only on those the estimator assigned to its
    /// terrain (SPEC S8). Each slot at most once. Default `["general"]`.
    pub learners: Vec<PolicySlot>,
    /// Start every learner from this learner checkpoint's weights and observation statistics
    /// with fresh counters and optimizer (a warm start, e.g. the general model from the flat
    /// one). Relative paths are relative to the config file. Default none.
    pub init_from: Option<PathBuf>,
    /// Policy slots served frozen from a learner checkpoint, never trained (evaluation, e.g.
    /// switching between fixed FTM and RTM): `{ flat = "ftm.ckpt", rough = "rtm.ckpt" }`.
    /// Relative paths are relative to the config file. No slot may also be in `learners`.
    pub frozen: std::collections::BTreeMap<PolicySlot, PathBuf>,
    /// The sim also writes every env's per-tick telemetry to `<run dir>/telemetry.csv`, as
    /// `sim-proc --telemetry` does (one row per env and tick; large). Default false.
    pub telemetry_csv: bool,
}

/// A policy slot of the sim's pool (DESIGN §5): what a learner fills and an env acts with.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum PolicySlot {
    General,
    Flat,
    Rough,
}

impl PolicySlot {
    pub const ALL: [PolicySlot; 3] = [PolicySlot::General, PolicySlot::Flat, PolicySlot::Rough];

    /// The slot's index on the wire (`PolicyHeader::slot`, `Transition::slot`).
    pub fn index(self) -> usize {
        self as usize
    }

    pub fn name(self) -> &'static str {
        match self {
            PolicySlot::General => "general",
            PolicySlot::Flat => "flat",
            PolicySlot::Rough => "rough",
        }
    }

    /// The process (and shared-memory node) name of the slot's learner.
    pub fn learner_name(self) -> &'static str {
        match self {
            PolicySlot::General => "learner",
            PolicySlot::Flat => "learner-flat",
            PolicySlot::Rough => "learner-rough",
        }
    }

    /// Parses a slot name (`general`, `flat`, `rough`), for command lines.
    pub fn parse(name: &str) -> Result<Self, String> {
        Self::ALL
            .into_iter()
            .find(|s| s.name() == name)
            .ok_or_else(|| format!("unknown policy slot `{name}`: use general, flat or rough"))
    }

    /// The estimator class whose transitions the slot's learner trains on (class 0 is the
    /// mixture component with the lowest mean, i.e. flat); `None`: all.
    pub fn class(self) -> Option<u8> {
        match self {
            PolicySlot::General => None,
            PolicySlot::Flat => Some(0),
            PolicySlot::Rough => Some(1),
        }
    }

    /// The specialist for an estimator class (SPEC S8), if there is one.
    pub fn for_class(class: u8) -> Option<Self> {
        match class {
            0 => Some(PolicySlot::Flat),
            1 => Some(PolicySlot::Rough),
            _ => None,
        }
    }
}

/// Which slot an env acts with (DESIGN §5).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Acting {
    General,
    Flat,
    Rough,
    /// The specialist for the estimator's current class, changed only after the estimate has
    /// held for `switch-dwell` ticks (SPEC S8).
    Switch,
}

impl Acting {
    /// The slot every env acts with, unless switching.
    pub fn fixed(self) -> Option<PolicySlot> {
        match self {
            Acting::General => Some(PolicySlot::General),
            Acting::Flat => Some(PolicySlot::Flat),
            Acting::Rough => Some(PolicySlot::Rough),
            Acting::Switch => None,
        }
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum LearnMode {
    Sync,
    Async,
}

impl Default for RunConfig {
    fn default() -> Self {
        Self {
            seed: 1,
            mode: LearnMode::Sync,
            total_steps: 2_500_000,
            out_dir: PathBuf::from("runs"),
            learners: vec![PolicySlot::General],
            init_from: None,
            frozen: Default::default(),
            telemetry_csv: false,
        }
    }
}

/// Which area an env lives in: SPEC S1's two training areas, or the mixed course (our
/// extension, for issue 7's switching evaluation), flat ground that turns rough part-way.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum AreaKind {
    #[default]
    Flat,
    Rough,
    Mixed,
}

impl AreaKind {
    /// The wire and CSV code: 0 flat, 1 rough, 2 mixed. Telemetry never carries 2: a mixed
    /// env reports the ground under the robot.
    pub fn code(self) -> u8 {
        match self {
            AreaKind::Flat => 0,
            AreaKind::Rough => 1,
            AreaKind::Mixed => 2,
        }
    }

    pub fn name(self) -> &'static str {
        match self {
            AreaKind::Flat => "flat",
            AreaKind::Rough => "rough",
            AreaKind::Mixed => "mixed",
        }
    }
}

/// An axis-aligned rectangle on the ground (X-Z plane), metres.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, rename_all = "kebab-case")]
pub struct Rect {
    /// [min, max] along X, metres.
    pub x: [f64; 2],
    /// [min, max] along Z, metres.
    pub z: [f64; 2],
}

impl Rect {
    pub fn contains(&self, x: f64, z: f64, margin: f64) -> bool {
        x >= self.x[0] - margin
            && x <= self.x[1] + margin
            && z >= self.z[0] - margin
            && z <= self.z[1] + margin
    }
}

/// The simulator: envs, physics timing, terrain, robot and task rules.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, rename_all = "kebab-case", default)]
pub struct SimConfig {
    /// Envs in the flat area. 0 ..= 1024. Default 9 (SPEC S6, initial flat model).
    pub flat_envs: usize,
    /// Envs in the rough area. 0 ..= 1024. Default 0.
    pub rough_envs: usize,
    /// Envs on the mixed course (`terrain.mixed-area`), after the rough ones. 0 ..= 1024.
    /// Default 0.
    pub mixed_envs: usize,
    /// Threads stepping the worlds (1 is allowed). 1 ..= 64. Default 2.
    pub threads: usize,
    /// The policy slot the envs act with, or `switch` (DESIGN §5). A slot without a policy
    /// yet falls back to `general`, then to any slot that has one. Default `general`.
    pub acting: Acting,
    /// Switching: ticks a new terrain estimate must hold before an env changes policy. 1 ..= 10000. Default 10.
    pub switch_dwell: usize,
    /// Act with each policy's mean action instead of a sample (evaluation; the rollouts'
    /// log-probabilities are then not those of the actions). Default false.
    pub mean_actions: bool,
    /// Telemetry readers (estimator, launcher) are woken at most once per this many
    /// microseconds; every tick is still published and read, in batches. A wake-up is a
    /// datagram per reader, about 20 µs of a ~220 µs single-env tick, so waking per tick costs
    /// the sim a tenth of its speed; the price is up to this much delay before a reader sees
    /// a tick. 0: wake them on every tick. 0 ..= 1000000. Default 1000.
    pub telemetry_notify_us: usize,
    /// Physics time step, seconds. SPEC S2 (interpretation: Unity's default). (0, 0.1]. Default 0.02.
    pub physics_dt: f64,
    /// Physics steps per decision step. SPEC S2. 1 ..= 100. Default 5.
    pub substeps: usize,
    pub terrain: TerrainConfig,
    pub robot: RobotConfig,
    pub task: TaskConfig,
}

impl Default for SimConfig {
    fn default() -> Self {
        Self {
            flat_envs: 9,
            rough_envs: 0,
            mixed_envs: 0,
            threads: 2,
            acting: Acting::General,
            switch_dwell: 10,
            mean_actions: false,
            telemetry_notify_us: 1000,
            physics_dt: 0.02,
            substeps: 5,
            terrain: TerrainConfig::default(),
            robot: RobotConfig::default(),
            task: TaskConfig::default(),
        }
    }
}

impl SimConfig {
    pub fn num_envs(&self) -> usize {
        self.flat_envs + self.rough_envs + self.mixed_envs
    }

    /// The area of env `i`: flat envs first, then rough, then mixed.
    pub fn area_of(&self, env: usize) -> AreaKind {
        if env < self.flat_envs {
            AreaKind::Flat
        } else if env < self.flat_envs + self.rough_envs {
            AreaKind::Rough
        } else {
            AreaKind::Mixed
        }
    }

    /// "4 flat + 4 rough envs", with "+ n mixed" when the mixed course has envs.
    pub fn describe_envs(&self) -> String {
        let mixed = if self.mixed_envs > 0 {
            format!(" + {} mixed", self.mixed_envs)
        } else {
            String::new()
        };
        format!(
            "{} flat + {} rough{mixed} envs",
            self.flat_envs, self.rough_envs
        )
    }

    /// `n` envs, all in `area`.
    pub fn only_in(&mut self, area: AreaKind, n: usize) {
        self.flat_envs = if area == AreaKind::Flat { n } else { 0 };
        self.rough_envs = if area == AreaKind::Rough { n } else { 0 };
        self.mixed_envs = if area == AreaKind::Mixed { n } else { 0 };
    }

    /// Decision step, seconds (0.1 by default, SPEC S2).
    pub fn decision_dt(&self) -> f64 {
        self.physics_dt * self.substeps as f64
    }
}

/// The lava-tube floor (SPEC S1).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, rename_all = "kebab-case", default)]
pub struct TerrainConfig {
    /// Seed of the procedural floor (independent of the run seed, so runs can share a floor).
    pub seed: u64,
    /// Flat area rectangle. Default x ∈ [-2.5, 0.5], z ∈ [-1.0, 0.5] (SPEC S1).
    pub flat_area: Rect,
    /// Rough area rectangle. Default x ∈ [-9.0, -7.5], z ∈ [1.5, 5.0] (SPEC S1).
    pub rough_area: Rect,
    /// The mixed course (not in the paper): a strip whose robots cross between flat and rough
    /// ground. Default x ∈ [-6.0, -3.0], z ∈ [2.25, 3.25], between the two areas.
    pub mixed_area: Rect,
    /// The rough part of the mixed course: its bumps are the rough area's, with the same
    /// `blend` at the edge; the rest of the course is flat. Default x ∈ [-6.0, -4.5],
    /// z ∈ [2.25, 3.25] (the half towards the rough area).
    pub mixed_rough: Rect,
    /// Heightfield cell size, metres. [0.005, 0.5]. Default 0.04.
    pub cell_size: f64,
    /// Extra floor around each area, metres, so a robot at the edge still has ground. [0.5, 10]. Default 1.0.
    pub border: f64,
    /// Peak height of the micro-relief everywhere (RMS ≈ ⅓ of it), metres. [0, 0.05]. Default 0.007
    /// (calibrated so go-to-target driving gives SPEC S1's flat rolling std of sin θx).
    pub flat_relief: f64,
    /// Wavelength of the micro-relief, metres. [0.01, 5]. Default 0.15.
    pub flat_wavelength: f64,
    /// Peak amplitude of the rough area's bumps before `roughness-scale`, metres. [0, 1]. Default 0.07
    /// (calibrated to SPEC S1's rough rolling std).
    pub rough_amplitude: f64,
    /// Wavelength of the rough area's largest octave, metres. [0.02, 10]. Default 0.4.
    pub rough_wavelength: f64,
    /// Octaves of value noise in the rough area. 1 ..= 8. Default 5.
    pub rough_octaves: usize,
    /// Scale of the rough area's unevenness (SPEC S1: the paper used 80 % of the scan). [0, 2]. Default 0.8.
    pub roughness_scale: f64,
    /// Width of the blend between areas and the surrounding floor, metres. [0, 5]. Default 0.3.
    pub blend: f64,
    /// A measured heightmap to use instead of the procedural floor.
    pub heightmap: Option<HeightmapConfig>,
}

impl Default for TerrainConfig {
    fn default() -> Self {
        Self {
            seed: 2026,
            flat_area: Rect {
                x: [-2.5, 0.5],
                z: [-1.0, 0.5],
            },
            rough_area: Rect {
                x: [-9.0, -7.5],
                z: [1.5, 5.0],
            },
            mixed_area: Rect {
                x: [-6.0, -3.0],
                z: [2.25, 3.25],
            },
            mixed_rough: Rect {
                x: [-6.0, -4.5],
                z: [2.25, 3.25],
            },
            cell_size: 0.04,
            border: 1.0,
            flat_relief: 0.007,
            flat_wavelength: 0.15,
            rough_amplitude: 0.07,
            rough_wavelength: 0.4,
            rough_octaves: 5,
            roughness_scale: 0.8,
            blend: 0.3,
            heightmap: None,
        }
    }
}

/// A user heightmap: a 16-bit grayscale PNG or a plain grid (`.grid` text: first line
/// `rows cols`, then `rows` lines of `cols` heights in metres, row = +Z, column = +X).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, rename_all = "kebab-case")]
pub struct HeightmapConfig {
    /// The file, relative to the config file's directory.
    pub path: PathBuf,
    /// Ground distance between samples, metres. (0, 1].
    pub metres_per_pixel: f64,
    /// Height of the brightest 16-bit value (65535), metres (PNG only). (0, 100]. Default 1.
    #[serde(default = "one")]
    pub height_scale: f64,
    /// World X, Z of the map's first sample (row 0, column 0), metres.
    pub origin: [f64; 2],
}

fn one() -> f64 {
    1.0
}

/// Wheel collider shape: balls are 2–3× cheaper to collide with a heightfield (DESIGN §10).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum WheelShape {
    Ball,
    Cylinder,
}

/// The two-wheeled differential robot (SPEC S2).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, rename_all = "kebab-case", default)]
pub struct RobotConfig {
    /// Wheel radius, metres. SPEC S2: ≈ 3–4 cm. [0.01, 0.2]. Default 0.035.
    pub wheel_radius: f64,
    /// Wheel width (cylinder wheels), metres. [0.002, 0.1]. Default 0.015.
    pub wheel_width: f64,
    /// Distance between the wheel centres, metres. [0.03, 1]. Default 0.10.
    pub track_width: f64,
    /// Wheel collider shape. Default `ball`.
    pub wheel_shape: WheelShape,
    /// Chassis box half extents (x across, y up, z along), metres. Default [0.035, 0.015, 0.05].
    pub chassis_half_extents: [f64; 3],
    /// Chassis mass, kg. (0, 100]. Default 0.30.
    pub chassis_mass: f64,
    /// Mass of each wheel, kg. (0, 10]. Default 0.03.
    pub wheel_mass: f64,
    /// Radius of the passive ball support (caster) at the rear, metres. [0.002, 0.1]. Default 0.012.
    pub caster_radius: f64,
    /// Ground friction coefficient of wheels. [0, 5]. Default 1.0.
    pub wheel_friction: f64,
    /// Friction of the passive support (a low-friction skid). [0, 5]. Default 0.05.
    pub caster_friction: f64,
    /// Wheel motor torque limit, N·m. (0, 10]. Default 0.1.
    pub motor_max_torque: f64,
    /// Velocity motor gain (rapier acceleration-based damping; higher tracks the command more
    /// stiffly: 1000 reaches 98 % of the commanded speed on flat ground). (0, 10^6]. Default 1000.
    pub motor_damping: f64,
    /// Action clip: each wheel command in [-limit, limit] rad/s (SPEC S2). (0, 100]. Default 3.0.
    pub action_limit: f64,
    /// rapier's length unit, metres (a robot this small halves its step cost at ≈ 0.2). [0.01, 10]. Default 0.2.
    pub length_unit: f64,
}

impl Default for RobotConfig {
    fn default() -> Self {
        Self {
            wheel_radius: 0.035,
            wheel_width: 0.015,
            track_width: 0.10,
            wheel_shape: WheelShape::Ball,
            chassis_half_extents: [0.035, 0.015, 0.05],
            chassis_mass: 0.30,
            wheel_mass: 0.03,
            caster_radius: 0.012,
            wheel_friction: 1.0,
            caster_friction: 0.05,
            motor_max_torque: 0.1,
            motor_damping: 1000.0,
            action_limit: 3.0,
            length_unit: 0.2,
        }
    }
}

/// The paper's episode and reward rules (SPEC S3–S4).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, rename_all = "kebab-case", default)]
pub struct TaskConfig {
    /// Δ, metres (SPEC S3). (0, 1]. Default 0.1.
    pub delta: f64,
    /// Target annulus radii in units of Δ (SPEC S3: Δ ≤ r ≤ 5Δ). Default [1, 5].
    pub target_annulus: [f64; 2],
    /// MES = mes-base + mes-per-metre · ID (SPEC S3). Default 300, 200.
    pub mes_base: f64,
    pub mes_per_metre: f64,
    /// PED = ID + ped-slack·Δ − kΔ (SPEC S3). [0, 100]. Default 2.
    pub ped_slack: f64,
    /// Leaving the area by more than this ends the episode and respawns (SPEC S3, interpretation), metres. Default 0.2.
    pub leave_margin: f64,
    /// |roll| or |pitch| above this ends the episode and respawns (SPEC S3, interpretation), degrees. (0, 180]. Default 60.
    pub tip_limit_deg: f64,
    /// ProgressReward = progress-scale · PD (SPEC S4). Default 100.
    pub progress_scale: f64,
    /// Redraws before giving up on a target inside the area (then the last draw is clamped into the area). 1 ..= 10^6. Default 1000.
    pub max_target_draws: usize,
    /// Where episodes start: "chained" (SPEC S3) or "course" (paired evaluation). Default "chained".
    pub episodes: EpisodeStart,
    /// Not the paper's (SPEC S3 extension): a robot that has stayed within `stall-distance`
    /// of one spot for this many decision steps of an episode has stalled: the episode ends
    /// as a failure (terminal, like PED's) and the robot is respawned. Without it, a policy
    /// that stops on rough ground sees a truncation bootstrapped from the very state it sits
    /// in, so stopping costs it almost nothing and it may never learn to leave. 0 = off (the
    /// paper's rules). 0 ..= 100000. Default 0.
    pub stall_steps: u32,
    /// The stall rule's radius, metres: moving farther than this from where the robot stood
    /// restarts the count. (0, 10]. Default 0.02.
    pub stall_distance: f64,
}

/// Where an env's next episode starts.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum EpisodeStart {
    /// SPEC S3: where the robot stands, with a new target drawn around it.
    Chained,
    /// A course of seeded waypoints, the same for every policy: leg k starts with the robot
    /// placed at waypoint k (the last leg's target, whatever happened on that leg) facing a
    /// seeded heading, and drives to waypoint k + 1, drawn around it by SPEC S3's rule. Two
    /// policies on one seed drive the same legs, so their outcomes pair leg by leg.
    Course,
}

impl TaskConfig {
    /// The longest an episode can last, decision steps: SPEC S3's MES at the farthest target
    /// the annulus allows (a target clamped into the area only comes closer).
    pub fn longest_episode_ticks(&self) -> u64 {
        (self.mes_base + self.mes_per_metre * self.target_annulus[1] * self.delta).floor() as u64
    }
}

impl Default for TaskConfig {
    fn default() -> Self {
        Self {
            delta: 0.1,
            target_annulus: [1.0, 5.0],
            mes_base: 300.0,
            mes_per_metre: 200.0,
            ped_slack: 2.0,
            leave_margin: 0.2,
            tip_limit_deg: 60.0,
            progress_scale: 100.0,
            max_target_draws: 1000,
            episodes: EpisodeStart::Chained,
            stall_steps: 0,
            stall_distance: 0.02,
        }
    }
}

/// PPO hyperparameters (SPEC S6, Table 2) and implementation details.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, rename_all = "kebab-case", default)]
pub struct PpoConfig {
    /// Transitions per update, summed over envs (SPEC S6, interpretation). 64 ..= 10^6. Default 2048.
    pub rollout_transitions: usize,
    /// Minibatch size ("batch size" in ML-Agents). 1 ..= rollout. Default 64.
    pub minibatch_size: usize,
    /// Epochs per update. 1 ..= 100. Default 10.
    pub epochs: usize,
    /// Adam learning rate. (0, 1]. Default 3e-4.
    pub learning_rate: f64,
    /// Decay the learning rate linearly to 0 over `run.total-steps`. Default true.
    pub anneal_lr: bool,
    /// Adam epsilon. (0, 1]. Default 1e-5.
    pub adam_eps: f64,
    /// Discount γ. [0, 1]. Default 0.99.
    pub gamma: f64,
    /// GAE λ. [0, 1]. Default 0.95.
    pub gae_lambda: f64,
    /// Surrogate clip ε. (0, 1]. Default 0.2.
    pub clip_coef: f64,
    /// Clip the value loss around the old value too. Default false.
    pub clip_vloss: bool,
    /// Entropy coefficient. [0, 1]. Default 5e-4.
    pub ent_coef: f64,
    /// Value-loss coefficient. [0, 10]. Default 0.5.
    pub vf_coef: f64,
    /// Global gradient-norm clip. (0, 1000]. Default 0.5.
    pub max_grad_norm: f64,
    /// Normalise advantages per minibatch. Default true.
    pub norm_adv: bool,
    /// Stop an update's epochs early when approx KL exceeds this. Default none.
    pub target_kl: Option<f64>,
    /// Hidden layer widths of actor and critic (SPEC S6, interpretation: ML-Agents' 2 × 128).
    pub hidden: Vec<usize>,
    /// Orthogonal init (hidden √2, policy head 0.01, value head 1). Default true.
    pub ortho_init: bool,
    /// Initial log standard deviation of the action distribution. [-5, 2]. Default 0.
    pub init_log_std: f64,
    /// Running observation normalisation. Default true.
    pub obs_norm: bool,
    /// Clip of normalised observations. (0, 100]. Default 10.
    pub obs_clip: f64,
    /// Write a checkpoint every this many updates. 1 ..= 10^6. Default 1: a learner killed
    /// at any moment then loses no update and its replacement continues the version
    /// sequence exactly (DESIGN §4); larger values trade that for less disk traffic.
    pub checkpoint_every: usize,
    /// Checkpoints kept (oldest removed). 1 ..= 1000. Default 3.
    pub keep_checkpoints: usize,
    /// Also keep, for good, every checkpoint whose update count is a multiple of this: a
    /// learning run's milestones, to pick the best of by validation (`lavatube reproduce`
    /// does, see `reproduce.specialist-candidates`). 0 or a multiple of `checkpoint-every`,
    /// ..= 10^6. Default 0: none.
    pub milestone_every: usize,
    /// In async mode, drop transitions more than this many policy versions old. 0 ..= 1000. Default 4.
    pub max_policy_lag: u32,
}

impl Default for PpoConfig {
    fn default() -> Self {
        Self {
            rollout_transitions: 2048,
            minibatch_size: 64,
            epochs: 10,
            learning_rate: 3e-4,
            anneal_lr: true,
            adam_eps: 1e-5,
            gamma: 0.99,
            gae_lambda: 0.95,
            clip_coef: 0.2,
            clip_vloss: false,
            ent_coef: 5e-4,
            vf_coef: 0.5,
            max_grad_norm: 0.5,
            norm_adv: true,
            target_kl: None,
            hidden: vec![128, 128],
            ortho_init: true,
            init_log_std: 0.0,
            obs_norm: true,
            obs_clip: 10.0,
            checkpoint_every: 1,
            keep_checkpoints: 3,
            milestone_every: 0,
            max_policy_lag: 4,
        }
    }
}

impl PpoConfig {
    /// Steps per env per rollout: enough that T × N covers `rollout-transitions`.
    pub fn rollout_steps(&self, num_envs: usize) -> usize {
        self.rollout_transitions.div_ceil(num_envs.max(1))
    }
}

/// Terrain estimation (SPEC S7) and switching (SPEC S8).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, rename_all = "kebab-case", default)]
pub struct EstimatorConfig {
    /// Rolling-window sizes analysed offline, ticks (SPEC S7). Each 2 ..= 10^5. Default [10, 20, 40, 70].
    pub windows: Vec<usize>,
    /// Window used online, ticks. 2 ..= 10^5. Default 70 (the paper's best).
    pub online_window: usize,
    /// Ticks dropped at the start of each series (SPEC S7). 0 ..= 10^6. Default 100.
    pub warmup_ticks: usize,
    /// Mixture components (terrain classes). 2 ..= 16. Default 2.
    pub components: usize,
    /// EM restarts from different initialisations; the best likelihood wins. 1 ..= 100. Default 5.
    pub restarts: usize,
    /// EM iteration cap. 1 ..= 10^5. Default 500.
    pub max_iter: usize,
    /// EM stops when the mean log-likelihood improves by less than this. (0, 1]. Default 1e-8.
    pub tol: f64,
    /// Variance floor of each component. (0, 1]. Default 1e-10.
    pub var_floor: f64,
    /// Hold the mixing weights at 1/K instead of fitting them (interpretation; SPEC S7's
    /// mixture fits them). Default false. A terrain whose windows are not one Gaussian (its
    /// envs differ in level) lets free weights settle on a sub-cluster with a higher
    /// likelihood than the split by terrain; collection drives every area alike, so equal
    /// weights are also the prior the data was drawn with. Wrong for data far from equal
    /// shares: at 90 / 10 the fit splits the larger terrain instead.
    pub equal_weights: bool,
    /// Online: refit the mixture every this many ticks; 0 never refits (the first fit, or
    /// `model`, classifies throughout). 0 ..= 10^6. Default 500.
    pub refit_every: usize,
    /// Online: most recent window-std values kept for refitting. 10 ..= 10^7. Default 20000.
    pub pool_size: usize,
    /// Online: probability of staying on the same terrain per tick in the HMM filter; 0 disables the filter. [0, 1). Default 0.98.
    pub stay_prob: f64,
    /// A window in which the robot's mean speed over the ground (path length ÷ window
    /// duration) is below this says nothing about the terrain: a robot wedged on a bump
    /// holds its pitch still and reads as flat ground. Such windows are left out of every fit
    /// and score, offline (SPEC S7) and online, where the env keeps its previous estimate.
    /// m/s, [0, 10]; 0 counts every window, as the paper did. Default 0.02 (interpretation:
    /// a quarter of the robot's usual 0.08 m/s, so a window counts once most of it is driven).
    pub min_speed: f64,
    /// Online: a mixture fitted offline to classify with from the first full window (SPEC
    /// S7): a `results.json` of `estimator-proc analyze`, whose fit for `online-window` is
    /// taken; refits warm-start from it. Without one the first online fit defines the
    /// classes, so it needs every terrain in its pool: a run on one terrain would split it
    /// into two. Relative to the config file. Default none.
    pub model: Option<PathBuf>,
    /// What the mixture is fitted on, offline and online: "std", each window's std of
    /// sin θx (SPEC S7), or "log-std", its natural log (interpretation). Default "std".
    pub feature: MixtureFeature,
}

/// The value of a window the terrain mixture sees (SPEC S7: the window's std of sin θx).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum MixtureFeature {
    /// The std itself, as the paper.
    #[default]
    Std,
    /// Its natural log, floored at [`MixtureFeature::LOG_FLOOR`]. A window's std is
    /// positive and skewed to the right, most on rough ground, where a few bumpy windows
    /// stretch one Gaussian so wide that it takes in the upper half of flat ground; in log
    /// space both terrains are closer to Gaussian.
    LogStd,
}

impl MixtureFeature {
    /// The std below which `log-std` reads the floor (a robot standing perfectly still).
    pub const LOG_FLOOR: f64 = 1e-6;

    /// The feature of a window whose std of sin θx is `std`.
    pub fn of(self, std: f64) -> f64 {
        match self {
            MixtureFeature::Std => std,
            MixtureFeature::LogStd => std.max(Self::LOG_FLOOR).ln(),
        }
    }

    pub fn name(self) -> &'static str {
        match self {
            MixtureFeature::Std => "std",
            MixtureFeature::LogStd => "log-std",
        }
    }
}

/// A terrain mixture fitted offline, as [`EstimatorConfig::model`] holds it: components by
/// ascending mean (0 = flat), over `feature` (files written before it existed: `std`).
#[derive(Debug, Clone, PartialEq, Deserialize)]
pub struct OfflineMixture {
    pub window: usize,
    #[serde(default)]
    pub feature: MixtureFeature,
    pub weights: Vec<f64>,
    pub means: Vec<f64>,
    pub stds: Vec<f64>,
}

impl EstimatorConfig {
    /// The fit of [`model`](Self::model) for `online-window`; `None` without a model.
    pub fn offline_mixture(&self) -> Result<Option<OfflineMixture>, ConfigError> {
        #[derive(Deserialize)]
        struct Analysis {
            windows: Vec<OfflineMixture>,
        }
        let Some(path) = &self.model else {
            return Ok(None);
        };
        let bad = |reason: String| invalid("estimator.model", path, reason);
        let text = std::fs::read_to_string(path).map_err(|e| bad(e.to_string()))?;
        let analysis: Analysis = serde_json::from_str(&text).map_err(|e| {
            bad(format!(
                "not the results.json of `estimator-proc analyze`: {e}"
            ))
        })?;
        let found: Vec<usize> = analysis.windows.iter().map(|m| m.window).collect();
        let m = analysis
            .windows
            .into_iter()
            .find(|m| m.window == self.online_window)
            .ok_or_else(|| {
                bad(format!(
                    "holds fits for windows {found:?}, none for estimator.online-window {}",
                    self.online_window
                ))
            })?;
        if m.feature != self.feature {
            return Err(bad(format!(
                "its fit is over `{}`, but estimator.feature is `{}`",
                m.feature.name(),
                self.feature.name()
            )));
        }
        let k = self.components;
        if [&m.weights, &m.means, &m.stds].iter().any(|v| v.len() != k) {
            return Err(bad(format!(
                "its fit for window {} does not have estimator.components = {k} components",
                m.window
            )));
        }
        let finite = m.weights.iter().chain(&m.means).all(|v| v.is_finite());
        if !finite || !m.stds.iter().all(|s| s.is_finite() && *s > 0.0) {
            return Err(bad(format!(
                "its fit for window {} has a non-finite parameter or a std that is not positive",
                m.window
            )));
        }
        Ok(Some(m))
    }
}

impl Config {
    /// The travel per decision step below which [`EstimatorConfig::min_speed`] deems a
    /// window stationary, metres.
    pub fn min_step_travel(&self) -> f64 {
        self.estimator.min_speed * self.sim.decision_dt()
    }
}

impl Default for EstimatorConfig {
    fn default() -> Self {
        Self {
            windows: vec![10, 20, 40, 70],
            online_window: 70,
            warmup_ticks: 100,
            components: 2,
            restarts: 5,
            max_iter: 500,
            tol: 1e-8,
            var_floor: 1e-10,
            equal_weights: false,
            refit_every: 500,
            pool_size: 20_000,
            stay_prob: 0.98,
            min_speed: 0.02,
            model: None,
            feature: MixtureFeature::Std,
        }
    }
}

/// When the launcher restarts a process that exited.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Restart {
    /// An exit ends the run (a failure fails it).
    Never,
    /// Restart after a non-zero exit or a signal; a clean exit is final.
    OnFailure,
    /// Restart after any exit while the run goes on.
    Always,
}

/// One process's restart policy.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, rename_all = "kebab-case")]
pub struct RestartPolicy {
    pub restart: Restart,
    /// Restarts allowed over the run; one more exit ends it. 0 ..= 1000.
    pub max_restarts: u32,
    /// Wait before the first restart, doubled for each further one (capped at 30 s). 0 ..= 600000.
    pub backoff_ms: u64,
}

impl RestartPolicy {
    /// The wait before restart number `n` (0-based).
    pub fn backoff(&self, n: u32) -> std::time::Duration {
        let ms = self.backoff_ms.saturating_mul(1 << n.min(16)).min(30_000);
        std::time::Duration::from_millis(ms)
    }

    /// Whether a process that exited (`success`) after `restarts` restarts comes back.
    pub fn restarts_after(&self, success: bool, restarts: u32) -> bool {
        let wanted = match self.restart {
            Restart::Never => false,
            Restart::OnFailure => !success,
            Restart::Always => true,
        };
        wanted && restarts < self.max_restarts
    }
}

/// How `lavatube run` supervises its processes (DESIGN §4).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, rename_all = "kebab-case", default)]
pub struct SuperviseConfig {
    /// Default: on-failure, 5 restarts, 1 s backoff (it resumes from its newest checkpoint).
    pub learner: RestartPolicy,
    /// Default: on-failure, 5 restarts, 1 s backoff (the sim keeps its last estimates meanwhile).
    pub estimator: RestartPolicy,
    /// Default: never (the sim is the run; its failure ends it).
    pub sim: RestartPolicy,
    /// How long a process gets to stop on request before SIGTERM, and again before SIGKILL,
    /// milliseconds. 100 ..= 600000. Default 5000.
    pub grace_ms: u64,
}

impl Default for SuperviseConfig {
    fn default() -> Self {
        let on_failure = RestartPolicy {
            restart: Restart::OnFailure,
            max_restarts: 5,
            backoff_ms: 1000,
        };
        Self {
            learner: on_failure,
            estimator: on_failure,
            sim: RestartPolicy {
                restart: Restart::Never,
                max_restarts: 0,
                backoff_ms: 0,
            },
            grace_ms: 5000,
        }
    }
}

/// `lavatube reproduce`: the paper's pipeline, stage by stage (DESIGN §6, SPEC S6–S8). The
/// other sections give everything else (PPO, terrain, estimator) for every stage.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, rename_all = "kebab-case", default)]
pub struct ReproduceConfig {
    /// (a) Envs of the initial flat model, all on flat ground. 1 ..= 1024. Default 9 (SPEC S6).
    pub flat_envs: usize,
    /// (a) Its environment steps. 1 ..= 10^10. Default 2.5 M (SPEC S6).
    pub flat_steps: u64,
    /// (b), (c), (e) Envs per area of the mixed stages. 1 ..= 512. Default 4 (SPEC S6: 4 + 4).
    pub envs_per_area: usize,
    /// (b) Environment steps of the general model, from (a). 1 ..= 10^10. Default 2.5 M.
    pub general_steps: u64,
    /// (c) Decision steps per env collected with the general model. 1 ..= 10^6. Default 500 (SPEC S7).
    pub collect_steps: u64,
    /// (c) Envs per area of the collection. 1 ..= 512. Default unset: `envs-per-area`. More
    /// robots make Table 3 depend less on what the few of them happened to drive over.
    pub collect_envs: Option<usize>,
    /// (e) Environment steps of the FTM/RTM fine-tuning, from (b). 1 ..= 10^10. Default 500 k.
    pub finetune_steps: u64,
    /// (f) Episodes per model × area cell. 1 ..= 10^6. Default 200.
    pub eval_episodes: u64,
    /// (f) Envs per evaluation cell. 1 ..= 1024. Default 8.
    pub eval_envs: usize,
    /// (e) `sim.terrain.roughness-scale` of the fine-tuning. [0, 2]. Default unset: the
    /// `[sim]` one, as in the paper. Rougher ground than the general model saw gives the
    /// rough-terrain model something to specialise in.
    pub finetune_roughness_scale: Option<f64>,
    /// (f) `sim.terrain.roughness-scale` of the evaluation, every model and area alike.
    /// [0, 2]. Default unset: the `[sim]` one (SPEC S1's 0.8).
    pub eval_roughness_scale: Option<f64>,
    /// (e) `ppo.learning-rate` of the fine-tuning (it decays from there like every stage's).
    /// (0, 1]. Default unset: the `[ppo]` one. Fine-tuning a converged model at the rate it
    /// was trained from scratch with can move it away from what it already does well.
    pub finetune_learning_rate: Option<f64>,
    /// (e) Checkpoints of each specialist's fine-tuning kept as candidates, evenly spaced
    /// (`ppo.milestone-every`). 0 ..= 100. Default 0, the paper's: FTM and RTM are the
    /// fine-tuning's last checkpoints. With N > 0, each specialist is the one of the general
    /// model (no fine-tuning), the N milestones and the last checkpoint that does best on its
    /// own terrain over validation courses, seeds apart from stage f's (early stopping).
    pub specialist_candidates: usize,
    /// (e) Episodes each candidate drives on the validation courses. 1 ..= 10^6. Default 500.
    pub validation_episodes: u64,
    /// (g) Non-inferiority margins of the shape checks: "A at least as good as B" reads "no"
    /// only when A falls short of B by more than `margin-pp` percentage points of success,
    /// or by more than `margin-s` seconds of reach time, beyond the noise of the paired
    /// comparison. [0, 100] and [0, 10]. Default 1 pp and 0.05 s (half a decision step: the
    /// legs' reach times count whole steps). 0 and 0 for the strict test.
    pub margin_pp: f64,
    pub margin_s: f64,
}

impl Default for ReproduceConfig {
    fn default() -> Self {
        Self {
            flat_envs: 9,
            flat_steps: 2_500_000,
            envs_per_area: 4,
            general_steps: 2_500_000,
            collect_steps: 500,
            collect_envs: None,
            finetune_steps: 500_000,
            eval_episodes: 200,
            eval_envs: 8,
            finetune_roughness_scale: None,
            eval_roughness_scale: None,
            finetune_learning_rate: None,
            specialist_candidates: 0,
            validation_episodes: 500,
            margin_pp: 1.0,
            margin_s: 0.05,
        }
    }
}

impl Config {
    /// Reads, parses and validates a config file.
    pub fn load(path: &Path) -> Result<Self, ConfigError> {
        let text = std::fs::read_to_string(path).map_err(|e| ConfigError::Read {
            path: path.to_path_buf(),
            reason: e.to_string(),
        })?;
        let mut cfg = Self::parse(&text, path)?;
        if let Some(dir) = path.parent() {
            // Absolute, so the resolved config in the run directory names the same files.
            let resolve = |p: &mut PathBuf| {
                let joined = dir.join(&*p);
                *p = std::fs::canonicalize(&joined).unwrap_or(joined);
            };
            cfg.run.init_from.iter_mut().for_each(resolve);
            cfg.run.frozen.values_mut().for_each(resolve);
            cfg.estimator.model.iter_mut().for_each(resolve);
        }
        if let (Some(h), Some(dir)) = (cfg.sim.terrain.heightmap.as_mut(), path.parent()) {
            // Absolute, so the resolved config the launcher writes into the run directory
            // still points at the same file from there.
            let joined = dir.join(&h.path);
            h.path = std::fs::canonicalize(&joined).unwrap_or(joined);
        }
        cfg.validate()?;
        Ok(cfg)
    }

    /// Parses TOML text (no validation); `path` only labels errors.
    pub fn parse(text: &str, path: &Path) -> Result<Self, ConfigError> {
        toml::from_str(text).map_err(|e| {
            let (line, column) = e.span().map(|s| line_col(text, s.start)).unwrap_or((1, 1));
            ConfigError::Parse {
                path: path.to_path_buf(),
                line,
                column,
                message: e.message().replace('\n', " "),
            }
        })
    }

    /// The config as TOML, for the run directory.
    pub fn to_toml(&self) -> String {
        toml::to_string_pretty(self).unwrap_or_else(|e| format!("# cannot serialise config: {e}\n"))
    }

    /// Range and cross-field checks.
    pub fn validate(&self) -> Result<(), ConfigError> {
        let r = &self.run;
        if r.total_steps == 0 {
            return Err(invalid(
                "run.total-steps",
                r.total_steps,
                "must be at least 1",
            ));
        }
        if (r.learners.is_empty() && r.frozen.is_empty())
            || (1..r.learners.len()).any(|i| r.learners[..i].contains(&r.learners[i]))
            || r.learners.iter().any(|s| r.frozen.contains_key(s))
        {
            return Err(invalid(
                "run.learners",
                &r.learners,
                "needs at least one slot (or a frozen one), each at most once and not also in run.frozen",
            ));
        }
        if let Some(p) = r.frozen.values().find(|p| !p.is_file()) {
            return Err(invalid("run.frozen", p, "file not found"));
        }
        if let Some(p) = &r.init_from
            && !p.is_file()
        {
            return Err(invalid("run.init-from", p, "file not found"));
        }
        let s = &self.sim;
        count_in("sim.flat-envs", s.flat_envs, 0, 1024)?;
        count_in("sim.rough-envs", s.rough_envs, 0, 1024)?;
        count_in("sim.mixed-envs", s.mixed_envs, 0, 1024)?;
        if s.num_envs() == 0 {
            return Err(invalid(
                "sim.flat-envs",
                s.flat_envs,
                "flat-envs + rough-envs + mixed-envs must be at least 1",
            ));
        }
        count_in("sim.switch-dwell", s.switch_dwell, 1, 10_000)?;
        count_in(
            "sim.telemetry-notify-us",
            s.telemetry_notify_us,
            0,
            1_000_000,
        )?;
        count_in("sim.threads", s.threads, 1, 64)?;
        in_range("sim.physics-dt", s.physics_dt, 1e-4, 0.1)?;
        count_in("sim.substeps", s.substeps, 1, 100)?;
        let t = &s.terrain;
        for (field, a) in [
            ("sim.terrain.flat-area", t.flat_area),
            ("sim.terrain.rough-area", t.rough_area),
            ("sim.terrain.mixed-area", t.mixed_area),
            ("sim.terrain.mixed-rough", t.mixed_rough),
        ] {
            if !(a.x[0] < a.x[1] && a.z[0] < a.z[1])
                || a.x.iter().chain(&a.z).any(|v| !v.is_finite())
            {
                return Err(invalid(field, a, "needs finite min < max on x and z"));
            }
        }
        in_range("sim.terrain.cell-size", t.cell_size, 0.005, 0.5)?;
        in_range("sim.terrain.border", t.border, 0.5, 10.0)?;
        in_range("sim.terrain.flat-relief", t.flat_relief, 0.0, 0.05)?;
        in_range("sim.terrain.flat-wavelength", t.flat_wavelength, 0.01, 5.0)?;
        in_range("sim.terrain.rough-amplitude", t.rough_amplitude, 0.0, 1.0)?;
        in_range(
            "sim.terrain.rough-wavelength",
            t.rough_wavelength,
            0.02,
            10.0,
        )?;
        count_in("sim.terrain.rough-octaves", t.rough_octaves, 1, 8)?;
        in_range("sim.terrain.roughness-scale", t.roughness_scale, 0.0, 2.0)?;
        in_range("sim.terrain.blend", t.blend, 0.0, 5.0)?;
        if let Some(h) = &t.heightmap {
            in_range(
                "sim.terrain.heightmap.metres-per-pixel",
                h.metres_per_pixel,
                1e-4,
                1.0,
            )?;
            in_range(
                "sim.terrain.heightmap.height-scale",
                h.height_scale,
                1e-6,
                100.0,
            )?;
            if !h.path.exists() {
                return Err(invalid(
                    "sim.terrain.heightmap.path",
                    &h.path,
                    "file not found",
                ));
            }
        }
        let b = &s.robot;
        in_range("sim.robot.wheel-radius", b.wheel_radius, 0.01, 0.2)?;
        in_range("sim.robot.wheel-width", b.wheel_width, 0.002, 0.1)?;
        in_range("sim.robot.track-width", b.track_width, 0.03, 1.0)?;
        for v in b.chassis_half_extents {
            in_range("sim.robot.chassis-half-extents", v, 0.001, 1.0)?;
        }
        in_range("sim.robot.chassis-mass", b.chassis_mass, 1e-4, 100.0)?;
        in_range("sim.robot.wheel-mass", b.wheel_mass, 1e-4, 10.0)?;
        in_range("sim.robot.caster-radius", b.caster_radius, 0.002, 0.1)?;
        in_range("sim.robot.wheel-friction", b.wheel_friction, 0.0, 5.0)?;
        in_range("sim.robot.caster-friction", b.caster_friction, 0.0, 5.0)?;
        in_range("sim.robot.motor-max-torque", b.motor_max_torque, 1e-6, 10.0)?;
        in_range("sim.robot.motor-damping", b.motor_damping, 1e-6, 1e6)?;
        in_range("sim.robot.action-limit", b.action_limit, 1e-6, 100.0)?;
        in_range("sim.robot.length-unit", b.length_unit, 0.01, 10.0)?;
        if b.caster_radius >= b.wheel_radius {
            return Err(invalid(
                "sim.robot.caster-radius",
                b.caster_radius,
                "must be smaller than wheel-radius",
            ));
        }
        let k = &s.task;
        in_range("sim.task.delta", k.delta, 1e-3, 1.0)?;
        let [lo, hi] = k.target_annulus;
        if !(lo.is_finite() && hi.is_finite() && 0.0 < lo && lo <= hi && hi <= 50.0) {
            return Err(invalid(
                "sim.task.target-annulus",
                k.target_annulus,
                "needs 0 < min <= max <= 50",
            ));
        }
        in_range("sim.task.mes-base", k.mes_base, 1.0, 1e6)?;
        in_range("sim.task.mes-per-metre", k.mes_per_metre, 0.0, 1e6)?;
        in_range("sim.task.ped-slack", k.ped_slack, 0.0, 100.0)?;
        in_range("sim.task.leave-margin", k.leave_margin, 0.0, 100.0)?;
        in_range("sim.task.tip-limit-deg", k.tip_limit_deg, 1.0, 180.0)?;
        in_range("sim.task.progress-scale", k.progress_scale, 0.0, 1e6)?;
        count_in("sim.task.stall-steps", k.stall_steps as usize, 0, 100_000)?;
        in_range("sim.task.stall-distance", k.stall_distance, 1e-6, 10.0)?;
        count_in(
            "sim.task.max-target-draws",
            k.max_target_draws,
            1,
            1_000_000,
        )?;
        let p = &self.ppo;
        count_in(
            "ppo.rollout-transitions",
            p.rollout_transitions,
            64,
            1_000_000,
        )?;
        let batch = p.rollout_steps(s.num_envs()) * s.num_envs();
        count_in("ppo.minibatch-size", p.minibatch_size, 1, batch)?;
        count_in("ppo.epochs", p.epochs, 1, 100)?;
        in_range("ppo.learning-rate", p.learning_rate, 1e-12, 1.0)?;
        in_range("ppo.adam-eps", p.adam_eps, 1e-12, 1.0)?;
        in_range("ppo.gamma", p.gamma, 0.0, 1.0)?;
        in_range("ppo.gae-lambda", p.gae_lambda, 0.0, 1.0)?;
        in_range("ppo.clip-coef", p.clip_coef, 1e-6, 1.0)?;
        in_range("ppo.ent-coef", p.ent_coef, 0.0, 1.0)?;
        in_range("ppo.vf-coef", p.vf_coef, 0.0, 10.0)?;
        in_range("ppo.max-grad-norm", p.max_grad_norm, 1e-6, 1000.0)?;
        if let Some(kl) = p.target_kl {
            in_range("ppo.target-kl", kl, 1e-9, 10.0)?;
        }
        if p.hidden.is_empty() || p.hidden.len() > crate::policy::MAX_HIDDEN {
            return Err(invalid(
                "ppo.hidden",
                &p.hidden,
                format!("needs 1 ..= {} layers", crate::policy::MAX_HIDDEN),
            ));
        }
        for &h in &p.hidden {
            count_in("ppo.hidden", h, 1, 4096)?;
        }
        in_range("ppo.init-log-std", p.init_log_std, -5.0, 2.0)?;
        in_range("ppo.obs-clip", p.obs_clip, 1e-3, 100.0)?;
        count_in("ppo.checkpoint-every", p.checkpoint_every, 1, 1_000_000)?;
        count_in("ppo.keep-checkpoints", p.keep_checkpoints, 1, 1000)?;
        count_in("ppo.milestone-every", p.milestone_every, 0, 1_000_000)?;
        if !p.milestone_every.is_multiple_of(p.checkpoint_every) {
            return Err(invalid(
                "ppo.milestone-every",
                p.milestone_every,
                format!(
                    "must be a multiple of ppo.checkpoint-every ({}): only written checkpoints can be kept",
                    p.checkpoint_every
                ),
            ));
        }
        count_in("ppo.max-policy-lag", p.max_policy_lag as usize, 0, 1000)?;
        let e = &self.estimator;
        if e.windows.is_empty() {
            return Err(invalid(
                "estimator.windows",
                &e.windows,
                "needs at least one window",
            ));
        }
        for &w in &e.windows {
            count_in("estimator.windows", w, 2, 100_000)?;
        }
        count_in("estimator.online-window", e.online_window, 2, 100_000)?;
        count_in("estimator.warmup-ticks", e.warmup_ticks, 0, 1_000_000)?;
        count_in("estimator.components", e.components, 2, 16)?;
        count_in("estimator.restarts", e.restarts, 1, 100)?;
        count_in("estimator.max-iter", e.max_iter, 1, 100_000)?;
        in_range("estimator.tol", e.tol, 1e-15, 1.0)?;
        in_range("estimator.var-floor", e.var_floor, 1e-15, 1.0)?;
        in_range("estimator.min-speed", e.min_speed, 0.0, 10.0)?;
        count_in("estimator.refit-every", e.refit_every, 0, 1_000_000)?;
        count_in("estimator.pool-size", e.pool_size, 10, 10_000_000)?;
        if !(e.stay_prob.is_finite() && (0.0..1.0).contains(&e.stay_prob)) {
            return Err(invalid(
                "estimator.stay-prob",
                e.stay_prob,
                "must be in [0, 1)",
            ));
        }
        e.offline_mixture()?;
        let v = &self.supervise;
        for (field, backoff, max) in [
            (
                "supervise.learner",
                v.learner.backoff_ms,
                v.learner.max_restarts,
            ),
            (
                "supervise.estimator",
                v.estimator.backoff_ms,
                v.estimator.max_restarts,
            ),
            ("supervise.sim", v.sim.backoff_ms, v.sim.max_restarts),
        ] {
            if backoff > 600_000 || max > 1000 {
                return Err(invalid(
                    field,
                    (backoff, max),
                    "needs backoff-ms <= 600000 and max-restarts <= 1000",
                ));
            }
        }
        let p = &self.reproduce;
        count_in("reproduce.flat-envs", p.flat_envs, 1, 1024)?;
        count_in("reproduce.envs-per-area", p.envs_per_area, 1, 512)?;
        count_in("reproduce.eval-envs", p.eval_envs, 1, 1024)?;
        if let Some(n) = p.collect_envs {
            count_in("reproduce.collect-envs", n, 1, 512)?;
        }
        count_in(
            "reproduce.specialist-candidates",
            p.specialist_candidates,
            0,
            100,
        )?;
        for (field, v) in [
            (
                "reproduce.finetune-roughness-scale",
                p.finetune_roughness_scale,
            ),
            ("reproduce.eval-roughness-scale", p.eval_roughness_scale),
        ] {
            if let Some(v) = v {
                in_range(field, v, 0.0, 2.0)?;
            }
        }
        if let Some(lr) = p.finetune_learning_rate {
            in_range("reproduce.finetune-learning-rate", lr, 1e-12, 1.0)?;
        }
        in_range("reproduce.margin-pp", p.margin_pp, 0.0, 100.0)?;
        in_range("reproduce.margin-s", p.margin_s, 0.0, 10.0)?;
        for (field, v, hi) in [
            ("reproduce.flat-steps", p.flat_steps, 10_000_000_000),
            ("reproduce.general-steps", p.general_steps, 10_000_000_000),
            ("reproduce.collect-steps", p.collect_steps, 1_000_000),
            ("reproduce.finetune-steps", p.finetune_steps, 10_000_000_000),
            ("reproduce.eval-episodes", p.eval_episodes, 1_000_000),
            (
                "reproduce.validation-episodes",
                p.validation_episodes,
                1_000_000,
            ),
        ] {
            if !(1..=hi).contains(&v) {
                return Err(invalid(field, v, format!("must be in [1, {hi}]")));
            }
        }
        if !(100..=600_000).contains(&v.grace_ms) {
            return Err(invalid(
                "supervise.grace-ms",
                v.grace_ms,
                "must be in [100, 600000]",
            ));
        }
        Ok(())
    }
}

/// 1-based line and column of a byte offset.
fn line_col(text: &str, offset: usize) -> (usize, usize) {
    let before = &text[..offset.min(text.len())];
    let line = before.matches('\n').count() + 1;
    let column = before.len() - before.rfind('\n').map_or(0, |i| i + 1) + 1;
    (line, column)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(text: &str) -> Result<Config, ConfigError> {
        let c = Config::parse(text, Path::new("t.toml"))?;
        c.validate()?;
        Ok(c)
    }

    #[test]
    fn learner_slots_are_checked() {
        let c = parse("[run]\nlearners = [\"flat\", \"rough\"]\n[sim]\nacting = \"switch\"\n")
            .expect("valid");
        assert_eq!(c.run.learners, [PolicySlot::Flat, PolicySlot::Rough]);
        assert_eq!(c.sim.acting.fixed(), None);
        assert_eq!(PolicySlot::for_class(1), Some(PolicySlot::Rough));
        assert_eq!(PolicySlot::Flat.class(), Some(0));
        let err = parse("[run]\nlearners = [\"flat\", \"flat\"]\n").expect_err("twice");
        assert!(err.to_string().contains("run.learners"), "{err}");
        let err = parse("[run]\ninit-from = \"/nonexistent.ckpt\"\n").expect_err("missing");
        assert!(err.to_string().contains("run.init-from"), "{err}");
    }

    /// SPEC S7: the online estimator can start from the offline analysis's mixture for its
    /// window; a file without one is refused when the config is checked.
    #[test]
    fn an_offline_model_is_read_for_the_online_window() {
        let dir = tempfile::tempdir().expect("tempdir");
        let results = dir.path().join("results.json");
        let fit = |w: usize, std: f64| {
            format!(
                r#"{{"window": {w}, "n": 9, "weights": [0.5, 0.5], "means": [0.02, 0.08], "stds": [0.01, {std}], "accuracy": 0.9}}"#
            )
        };
        let write = |fits: &[String]| {
            let text = format!(r#"{{"input": "t.csv", "windows": [{}]}}"#, fits.join(","));
            std::fs::write(&results, text).expect("write");
        };
        write(&[fit(10, 0.04), fit(70, 0.03)]);
        let mut e = EstimatorConfig {
            model: Some(results.clone()),
            refit_every: 0,
            ..EstimatorConfig::default()
        };
        let m = e.offline_mixture().expect("read").expect("a model");
        assert_eq!(
            (m.window, m.means, m.stds),
            (70, vec![0.02, 0.08], vec![0.01, 0.03])
        );
        e.online_window = 40;
        let err = e.offline_mixture().expect_err("no fit for 40").to_string();
        assert!(
            err.contains("windows [10, 70], none for estimator.online-window 40"),
            "{err}"
        );
        e.online_window = 70;
        // A fit over log std is refused by a config that classifies the std itself.
        write(&[fit(70, 0.03).replace(r#""n": 9"#, r#""feature": "log-std", "n": 9"#)]);
        let err = e.offline_mixture().expect_err("other feature").to_string();
        assert!(
            err.contains("over `log-std`, but estimator.feature is `std`"),
            "{err}"
        );
        e.feature = MixtureFeature::LogStd;
        assert!(e.offline_mixture().expect("read").is_some());
        e.feature = MixtureFeature::Std;
        write(&[fit(70, 0.0)]);
        let err = e.offline_mixture().expect_err("zero std").to_string();
        assert!(err.contains("std that is not positive"), "{err}");
        std::fs::write(&results, "[]").expect("write");
        let err = e
            .offline_mixture()
            .expect_err("not an analysis")
            .to_string();
        assert!(err.starts_with("config field `estimator.model`"), "{err}");
        let cfg = Config {
            estimator: e,
            ..Config::default()
        };
        assert!(cfg.validate().is_err(), "checked with the config");
    }

    #[test]
    fn restart_policies_decide_and_back_off() {
        let c = parse(
            "[supervise]\nlearner = { restart = \"always\", max-restarts = 2, backoff-ms = 500 }\n",
        )
        .expect("valid");
        let l = c.supervise.learner;
        assert!(l.restarts_after(true, 0) && l.restarts_after(false, 1));
        assert!(!l.restarts_after(false, 2), "the third exit is final");
        assert_eq!(
            [l.backoff(0), l.backoff(1), l.backoff(2), l.backoff(10)].map(|d| d.as_millis()),
            [500, 1000, 2000, 30_000]
        );
        let e = c.supervise.estimator;
        assert!(e.restarts_after(false, 0) && !e.restarts_after(true, 0));
        assert!(!c.supervise.sim.restarts_after(false, 0));
        let err = parse("[supervise]\ngrace-ms = 5\n").expect_err("too short");
        assert!(err.to_string().contains("supervise.grace-ms"), "{err}");
    }

    #[test]
    fn defaults_are_valid_and_round_trip() {
        let c = Config::default();
        c.validate().expect("default config valid");
        let back = parse(&c.to_toml()).expect("round trip");
        assert_eq!(back, c);
        assert!((c.sim.decision_dt() - 0.1).abs() < 1e-12);
    }

    #[test]
    fn unknown_key_names_its_line() {
        let e = parse("[sim]\nflat-envs = 2\nwheel = 3\n").expect_err("unknown");
        let msg = e.to_string();
        assert!(
            msg.starts_with("t.toml:3:1: unknown field `wheel`"),
            "{msg}"
        );
        assert!(!msg.contains('\n'));
    }

    #[test]
    fn out_of_range_names_the_field() {
        let e = parse("[sim.robot]\nwheel-radius = 2.0\n").expect_err("range");
        assert_eq!(
            e.to_string(),
            "config field `sim.robot.wheel-radius` = 2.0: must be in [0.01, 0.2]"
        );
        let e = parse("[sim]\nflat-envs = 0\n").expect_err("no envs");
        assert!(e.to_string().contains("sim.flat-envs"));
        let e = parse("[reproduce]\neval-roughness-scale = 2.5\n").expect_err("range");
        assert_eq!(
            e.to_string(),
            "config field `reproduce.eval-roughness-scale` = 2.5: must be in [0, 2]"
        );
        let e = parse("[reproduce]\nmargin-s = -0.1\n").expect_err("negative margin");
        assert!(e.to_string().contains("reproduce.margin-s"), "{e}");
        let e =
            parse("[ppo]\ncheckpoint-every = 4\nmilestone-every = 10\n").expect_err("unwritten");
        assert_eq!(
            e.to_string(),
            "config field `ppo.milestone-every` = 10: must be a multiple of ppo.checkpoint-every (4): only written checkpoints can be kept"
        );
        let e = parse("[reproduce]\ncollect-envs = 0\n").expect_err("no robots");
        assert_eq!(
            e.to_string(),
            "config field `reproduce.collect-envs` = 0: must be in [1, 512]"
        );
        let e = parse("[reproduce]\nspecialist-candidates = 101\n").expect_err("range");
        assert!(
            e.to_string().contains("reproduce.specialist-candidates"),
            "{e}"
        );
        let e = parse("[sim.task]\nepisodes = \"reset\"\n").expect_err("unknown start");
        assert!(
            e.to_string().contains("chained") && e.to_string().contains("course"),
            "{e}"
        );
    }

    #[test]
    fn the_mixture_feature_is_the_std_or_its_floored_log() {
        assert_eq!(MixtureFeature::Std.of(0.05), 0.05);
        assert_eq!(MixtureFeature::LogStd.of(std::f64::consts::E), 1.0);
        assert_eq!(MixtureFeature::LogStd.of(0.0), (1e-6f64).ln());
    }

    #[test]
    fn the_longest_episode_is_the_farthest_targets_limit() {
        // SPEC S3: MES = 300 + 200 · ID, ID at most 5Δ = 0.5 m.
        assert_eq!(TaskConfig::default().longest_episode_ticks(), 400);
    }

    #[test]
    fn stage_roughness_is_optional_and_round_trips() {
        let c =
            parse("[reproduce]\nfinetune-roughness-scale = 1.2\nfinetune-learning-rate = 1e-4\n")
                .expect("valid");
        assert_eq!(c.reproduce.finetune_roughness_scale, Some(1.2));
        assert_eq!(c.reproduce.eval_roughness_scale, None);
        assert_eq!(c.reproduce.finetune_learning_rate, Some(1e-4));
        let e = parse("[reproduce]\nfinetune-learning-rate = 0.0\n").expect_err("zero rate");
        assert!(
            e.to_string().contains("reproduce.finetune-learning-rate"),
            "{e}"
        );
        assert_eq!(parse(&c.to_toml()).expect("round trip"), c);
    }

    #[test]
    fn heightmap_path_survives_being_rewritten_elsewhere() {
        let dir = std::env::temp_dir().join(format!("lavatube-hm-{}", std::process::id()));
        std::fs::create_dir_all(dir.join("run")).expect("dirs");
        std::fs::write(dir.join("floor.grid"), "2 2\n0 0\n0 0\n").expect("grid");
        let cfg_path = dir.join("c.toml");
        let body = "[sim.terrain.heightmap]\npath = \"floor.grid\"\nmetres-per-pixel = 0.1\norigin = [0.0, 0.0]\n";
        std::fs::write(&cfg_path, body).expect("config");
        let cfg = Config::load(&cfg_path).expect("relative to the config file");
        let hm = cfg.sim.terrain.heightmap.clone().expect("heightmap");
        assert!(hm.path.is_absolute() && hm.path.exists(), "{:?}", hm.path);
        // The launcher writes the resolved config into the run directory; children load it there.
        let resolved = dir.join("run/config.toml");
        std::fs::write(&resolved, cfg.to_toml()).expect("resolved");
        assert_eq!(Config::load(&resolved).expect("still found"), cfg);
        std::fs::remove_dir_all(&dir).ok();
    }

    #[test]
    fn rollout_steps_cover_the_batch() {
        let p = PpoConfig::default();
        assert_eq!(p.rollout_steps(8), 256);
        assert_eq!(p.rollout_steps(9), 228); // 228 × 9 = 2052 ≥ 2048
    }

    #[test]
    fn areas_are_assigned_flat_first() {
        let s = SimConfig {
            flat_envs: 2,
            rough_envs: 1,
            mixed_envs: 1,
            ..SimConfig::default()
        };
        use AreaKind::{Flat, Mixed, Rough};
        assert_eq!(
            (0..4).map(|i| s.area_of(i)).collect::<Vec<_>>(),
            vec![Flat, Flat, Rough, Mixed]
        );
        let mut only = s.clone();
        only.only_in(Mixed, 3);
        assert_eq!((only.num_envs(), only.area_of(0)), (3, Mixed));
    }
}
