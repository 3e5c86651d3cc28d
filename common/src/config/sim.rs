//! `[sim]`: the envs, their areas and the physics timing; terrain, robot and task have their
//! own sections.

use super::range::invalid;
use super::setting::{Setting, choices, count, flag, real, settings};
use super::{
    Acting, AttitudeSource, ConfigError, ExternalConfig, ImuConfig, PolicySlot, RobotConfig,
    TaskConfig, TerrainConfig,
};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

/// The longest physics step a simulated IMU works with, seconds: it samples once per step,
/// and below 50 Hz its attitude filter falls behind the chassis on rough ground.
pub const IMU_MAX_PHYSICS_DT: f64 = 0.02;

/// Which area an env lives in: a terrain kind's area (SPEC S1's flat and rough, and our
/// `slope`, `gravel` and `sand`), or the mixed course (our extension, for the switching evaluation),
/// flat ground that crosses other kinds part-way.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum AreaKind {
    #[default]
    Flat,
    Rough,
    Mixed,
    Slope,
    Gravel,
    Sand,
}

impl Setting for AreaKind {}

impl AreaKind {
    /// The terrain kinds, in code order (every area but the mixed course).
    pub const KINDS: [AreaKind; 5] = [
        AreaKind::Flat,
        AreaKind::Rough,
        AreaKind::Slope,
        AreaKind::Gravel,
        AreaKind::Sand,
    ];

    /// The wire and CSV code: 0 flat, 1 rough, 2 mixed, 3 slope, 4 gravel, 5 sand. Telemetry never
    /// carries 2: a mixed env reports the ground under the robot.
    pub fn code(self) -> u8 {
        match self {
            AreaKind::Flat => 0,
            AreaKind::Rough => 1,
            AreaKind::Mixed => 2,
            AreaKind::Slope => 3,
            AreaKind::Gravel => 4,
            AreaKind::Sand => 5,
        }
    }

    pub fn name(self) -> &'static str {
        match self {
            AreaKind::Flat => "flat",
            AreaKind::Rough => "rough",
            AreaKind::Mixed => "mixed",
            AreaKind::Slope => "slope",
            AreaKind::Gravel => "gravel",
            AreaKind::Sand => "sand",
        }
    }
}

settings! {
    /// An axis-aligned rectangle on the ground (X-Z plane), metres.
    #[derive(Copy)]
    pub struct Rect, required {
        /// [min, max] along X.
        pub x: [f64; 2] => real(-1000.0, 1000.0), "m", Advanced;
        /// [min, max] along Z.
        pub z: [f64; 2] => real(-1000.0, 1000.0), "m", Advanced;
    }
}

impl Rect {
    pub fn contains(&self, x: f64, z: f64, margin: f64) -> bool {
        x >= self.x[0] - margin
            && x <= self.x[1] + margin
            && z >= self.z[0] - margin
            && z <= self.z[1] + margin
    }
}

settings! {
    /// The simulator: envs, physics timing, terrain, robot and task rules.
    pub struct SimConfig {
        /// Envs in the flat area (SPEC S6, initial flat model: 9).
        pub flat_envs: usize = 9 => count(0, 1024), "envs", Essential;
        /// Envs in the rough area.
        pub rough_envs: usize = 0 => count(0, 1024), "envs", Essential;
        /// Envs in the slope area (not in the paper; needs one in `terrain.areas`), after the
        /// rough ones.
        pub slope_envs: usize = 0 => count(0, 1024), "envs", Essential;
        /// Envs in the gravel area (not in the paper; needs one in `terrain.areas`), after the
        /// slope ones.
        pub gravel_envs: usize = 0 => count(0, 1024), "envs", Essential;
        /// Envs in the sand area (not in the paper; needs one in `terrain.areas`), after the
        /// gravel ones.
        pub sand_envs: usize = 0 => count(0, 1024), "envs", Essential;
        /// Envs on the mixed course (`terrain.mixed-area`), after all the others.
        pub mixed_envs: usize = 0 => count(0, 1024), "envs", Essential;
        /// Threads stepping the worlds (1 is allowed).
        pub threads: usize = 2 => count(1, 64), "threads", Advanced;
        /// The policy slot the envs act with, `switch` (DESIGN §5), or `external` (a gym client
        /// acts; the run has no learners). A slot without a policy yet falls back to `general`,
        /// then to any slot that has one.
        pub acting: Acting = Acting::General => choices::<Acting>(), "", Essential;
        /// The gym client of `acting = "external"`.
        pub external: ExternalConfig = ExternalConfig::default();
        /// Switching: ticks a new terrain estimate must hold before an env changes policy.
        pub switch_dwell: usize = 10 => count(1, 10_000), "ticks", Research;
        /// Switching, beyond SPEC S8: ticks a new estimate must hold before an env leaves the
        /// named slots' policies, where leaving a cautious one by mistake costs more than keeping
        /// it (e.g. `{ sand = 30 }`); other slots use `switch-dwell`.
        pub leave_dwell: BTreeMap<PolicySlot, usize> = BTreeMap::new()
            => count(1, 10_000), "ticks", Research;
        /// Act with each policy's mean action instead of a sample (evaluation; the rollouts'
        /// log-probabilities are then not those of the actions).
        pub mean_actions: bool = false => flag(), "", Research;
        /// Telemetry readers (estimator, launcher) are woken at most once per this many
        /// microseconds; every tick is still published and read, in batches. A wake-up is a
        /// datagram per reader, about 20 µs of a ~220 µs single-env tick, so waking per tick costs
        /// the sim a tenth of its speed; the price is up to this much delay before a reader sees
        /// a tick. 0: wake them on every tick.
        pub telemetry_notify_us: usize = 1000 => count(0, 1_000_000), "µs", Advanced;
        /// Physics time step: contacts are found once per step (SPEC S2); a simulated IMU, which
        /// samples once per step, needs at most 0.02.
        pub physics_dt: f64 = 1.0 / 30.0 => real(1e-4, 0.1), "s", Advanced;
        /// Physics steps per decision step (SPEC S2).
        pub substeps: usize = 3 => count(1, 100), "steps", Advanced;
        /// The floor: areas, procedural relief or a heightmap.
        pub terrain: TerrainConfig = TerrainConfig::default();
        /// The robot's body, wheels and motors.
        pub robot: RobotConfig = RobotConfig::default();
        /// Where the observation's attitude terms come from: `truth` (the paper's) or `imu`.
        pub observation: AttitudeSource = AttitudeSource::Truth
            => choices::<AttitudeSource>(), "", Research;
        /// The simulated IMU and its filter: run when `observation` or `estimator.signal` is
        /// `imu`, or with `imu.simulate`.
        pub imu: ImuConfig = ImuConfig::default();
        /// The episode and reward rules.
        pub task: TaskConfig = TaskConfig::default();
    }
}

/// `sim.acting`'s choices are [`Acting`]'s names.
impl Setting for Acting {}

impl SimConfig {
    /// Whether each env carries the simulated IMU and its filter.
    pub fn simulates_imu(&self) -> bool {
        self.observation == AttitudeSource::Imu || self.imu.simulate
    }

    /// The env counts per area, in env order: flat, rough, slope, gravel, sand, mixed.
    pub fn env_counts(&self) -> [(AreaKind, usize); 6] {
        [
            (AreaKind::Flat, self.flat_envs),
            (AreaKind::Rough, self.rough_envs),
            (AreaKind::Slope, self.slope_envs),
            (AreaKind::Gravel, self.gravel_envs),
            (AreaKind::Sand, self.sand_envs),
            (AreaKind::Mixed, self.mixed_envs),
        ]
    }

    pub fn num_envs(&self) -> usize {
        self.env_counts().iter().map(|(_, n)| n).sum()
    }

    /// The area of env `i`: flat envs first, then rough, slope, gravel, sand and mixed (an index
    /// past the last env counts as mixed).
    pub fn area_of(&self, env: usize) -> AreaKind {
        let mut first = 0;
        for (area, n) in self.env_counts() {
            first += n;
            if env < first {
                return area;
            }
        }
        AreaKind::Mixed
    }

    /// "4 flat + 4 rough envs", with "+ n slope", "+ n gravel", "+ n sand", "+ n mixed" for the areas
    /// that have envs.
    pub fn describe_envs(&self) -> String {
        let others: String = self.env_counts()[2..]
            .iter()
            .filter(|(_, n)| *n > 0)
            .map(|(area, n)| format!(" + {n} {}", area.name()))
            .collect();
        format!(
            "{} flat + {} rough{others} envs",
            self.flat_envs, self.rough_envs
        )
    }

    /// `n` envs, all in `area`.
    pub fn only_in(&mut self, area: AreaKind, n: usize) {
        self.spread(&[area], n);
    }

    /// `n` envs in each of `areas`, none elsewhere.
    pub fn spread(&mut self, areas: &[AreaKind], n: usize) {
        let count = |a: AreaKind| if areas.contains(&a) { n } else { 0 };
        self.flat_envs = count(AreaKind::Flat);
        self.rough_envs = count(AreaKind::Rough);
        self.slope_envs = count(AreaKind::Slope);
        self.gravel_envs = count(AreaKind::Gravel);
        self.sand_envs = count(AreaKind::Sand);
        self.mixed_envs = count(AreaKind::Mixed);
    }

    /// Decision step, seconds (0.1 by default, SPEC S2).
    pub fn decision_dt(&self) -> f64 {
        self.physics_dt * self.substeps as f64
    }

    /// The rules between fields (each field's own range is [`super::setting::Setting::check`]'s),
    /// then terrain's, robot's and task's.
    pub(super) fn validate(&self) -> Result<(), ConfigError> {
        if self.num_envs() == 0 {
            return Err(invalid(
                "sim.flat-envs",
                self.flat_envs,
                "the envs of all areas (flat-envs, rough-envs, slope-envs, gravel-envs, sand-envs, mixed-envs) must be at least 1",
            ));
        }
        for (field, area, n) in [
            ("sim.flat-envs", AreaKind::Flat, self.flat_envs),
            ("sim.rough-envs", AreaKind::Rough, self.rough_envs),
            ("sim.slope-envs", AreaKind::Slope, self.slope_envs),
            ("sim.gravel-envs", AreaKind::Gravel, self.gravel_envs),
            ("sim.sand-envs", AreaKind::Sand, self.sand_envs),
        ] {
            if n > 0 && self.terrain.area(area).is_none() {
                return Err(invalid(
                    field,
                    n,
                    format!("needs a `{}` area in sim.terrain.areas", area.name()),
                ));
            }
        }
        if self.simulates_imu() && self.physics_dt > IMU_MAX_PHYSICS_DT + 1e-12 {
            return Err(invalid(
                "sim.physics-dt",
                self.physics_dt,
                format!(
                    "the simulated IMU samples once per physics step and needs at most \
                     {IMU_MAX_PHYSICS_DT} s: set sim.physics-dt = 0.02, sim.substeps = 5 and \
                     sim.robot.solver-iterations = 4"
                ),
            ));
        }
        self.terrain.validate()?;
        self.robot.validate()?;
        self.task.validate()?;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn areas_are_assigned_flat_first() {
        let s = SimConfig {
            flat_envs: 2,
            rough_envs: 1,
            slope_envs: 1,
            gravel_envs: 2,
            mixed_envs: 1,
            ..SimConfig::default()
        };
        use AreaKind::{Flat, Gravel, Mixed, Rough, Slope};
        assert_eq!(
            (0..7).map(|i| s.area_of(i)).collect::<Vec<_>>(),
            vec![Flat, Flat, Rough, Slope, Gravel, Gravel, Mixed]
        );
        assert_eq!(
            s.describe_envs(),
            "2 flat + 1 rough + 1 slope + 2 gravel + 1 mixed envs"
        );
        let mut only = s.clone();
        only.only_in(Mixed, 3);
        assert_eq!((only.num_envs(), only.area_of(0)), (3, Mixed));
    }
}
