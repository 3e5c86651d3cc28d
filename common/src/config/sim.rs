//! `[sim]`: the envs, their areas and the physics timing; terrain, robot and task have their
//! own sections.

use super::range::invalid;
use super::setting::{choices, count, flag, real, settings};
use super::{
    Acting, AreaKind, AttitudeSource, ConfigError, ExternalConfig, ImuConfig, PolicySlot,
    RandomizeConfig, RobotConfig, TaskConfig, TerrainConfig,
};
use std::collections::BTreeMap;

/// The longest physics step a simulated IMU works with, seconds: it samples once per step,
/// and below 50 Hz its attitude filter falls behind the chassis on rough ground.
pub const IMU_MAX_PHYSICS_DT: f64 = 0.02;

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
        /// Envs per area, e.g. `{ flat = 4, rough = 4 }`: a terrain kind's (which needs its area
        /// in `terrain.areas`) or `mixed` (the course). Envs are numbered in area order, kinds
        /// first, whatever the table's order. In a config that `extends` another it replaces
        /// the base's table. SPEC S6's initial flat model: 9 flat.
        pub envs: BTreeMap<AreaKind, usize> = BTreeMap::from([(AreaKind::Flat, 9)])
            => count(0, 1024), "envs", Essential;
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
        /// Gravity's magnitude, pulling along -y: 9.81 on Earth (the paper's world), 1.62 on the
        /// Moon. The IMU's accelerometer reads it and its filter trusts readings near it.
        pub gravity: f64 = 9.81 => real(0.1, 50.0), "m/s²", Advanced;
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
        /// Domain randomization: each episode's world drawn from ranges (off by default).
        pub randomize: RandomizeConfig = RandomizeConfig::default();
    }
}

impl SimConfig {
    /// Switching: the ticks a new estimate must hold before an env leaves `slot` (its
    /// `leave-dwell`, else `switch-dwell`; at least 1).
    pub fn dwell_leaving(&self, slot: PolicySlot) -> u32 {
        self.leave_dwell
            .get(&slot)
            .copied()
            .unwrap_or(self.switch_dwell)
            .max(1) as u32
    }

    /// Whether each env carries the simulated IMU and its filter.
    pub fn simulates_imu(&self) -> bool {
        self.observation == AttitudeSource::Imu || self.imu.simulate
    }

    /// The envs in `area`.
    pub fn envs_in(&self, area: AreaKind) -> usize {
        self.envs.get(&area).copied().unwrap_or(0)
    }

    pub fn num_envs(&self) -> usize {
        self.envs.values().sum()
    }

    /// The area of env `i`: areas in [`AreaKind::ALL`]'s order, the kinds' first and the mixed
    /// course's last (an index past the last env counts as mixed).
    pub fn area_of(&self, env: usize) -> AreaKind {
        let mut first = 0;
        for (area, n) in &self.envs {
            first += n;
            if env < first {
                return *area;
            }
        }
        AreaKind::Mixed
    }

    /// "4 flat + 4 rough envs", with "+ n slope", …, "+ n mixed" for the other areas that
    /// have envs.
    pub fn describe_envs(&self) -> String {
        let others: String = self
            .envs
            .iter()
            .filter(|(area, n)| **n > 0 && !matches!(area, AreaKind::Flat | AreaKind::Rough))
            .map(|(area, n)| format!(" + {n} {}", area.name()))
            .collect();
        format!(
            "{} flat + {} rough{others} envs",
            self.envs_in(AreaKind::Flat),
            self.envs_in(AreaKind::Rough)
        )
    }

    /// `n` envs, all in `area`.
    pub fn only_in(&mut self, area: AreaKind, n: usize) {
        self.spread(&[area], n);
    }

    /// `n` envs in each of `areas`, none elsewhere.
    pub fn spread(&mut self, areas: &[AreaKind], n: usize) {
        self.envs = areas.iter().map(|a| (*a, n)).collect();
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
                "sim.envs",
                &self.envs,
                "needs at least one env, e.g. `envs = { flat = 4 }`",
            ));
        }
        for (area, n) in &self.envs {
            if *n > 0 && *area != AreaKind::Mixed && self.terrain.area(*area).is_none() {
                return Err(invalid(
                    &format!("sim.envs.{}", area.name()),
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
        self.randomize.validate()?;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn areas_are_assigned_flat_first() {
        use AreaKind::{Flat, Gravel, Mixed, Rough, Slope};
        let s = SimConfig {
            envs: BTreeMap::from([(Mixed, 1), (Gravel, 2), (Slope, 1), (Rough, 1), (Flat, 2)]),
            ..SimConfig::default()
        };
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
