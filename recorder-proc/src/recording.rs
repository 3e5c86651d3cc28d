//! The `.rrd` file and everything logged to it: the static scene once (view coordinates,
//! the floor mesh, each robot's marker and body, the series' names), then per logged tick
//! each robot's pose, trail and target, and the metric series.
//!
//! Rerun SDK calls used (rerun 0.36.3): `RecordingStreamBuilder::{enabled, recording_name,
//! save}` (a file sink, no viewer), `RecordingStream::{log, log_static, set_time_sequence, set_log_time_enabled,
//! flush_blocking}`, and the archetypes `ViewCoordinates`, `Mesh3D`, `Points3D`, `Boxes3D`,
//! `Transform3D`, `LineStrips3D`, `Scalars`, `SeriesLines`. Values go in as plain arrays:
//! rerun's own glam is another version than the sim's.

use crate::decimate::Every;
use crate::entity;
use crate::error::{RecorderError, Result};
use crate::mesh::{GridMesh, MAX_VERTICES};
use crate::options::RecordOptions;
use crate::pose::unity_quaternion;
use crate::sample::{EstimateSample, RobotSample};
use crate::trail::Trails;
use common::terrain::Terrain;
use rerun::{AsComponents, RecordingStream};
use std::path::{Path, PathBuf};

/// The application id the viewer groups lavatube recordings under.
pub const APPLICATION_ID: &str = "lavatube";

/// A robot is ~10 cm long on a floor of ~10 m: its marker, a ball this far above the axle
/// (clear of the chassis, which shows pitch and heading), is what finds it. Metres.
const MARKER_HEIGHT: f32 = 0.12;
const MARKER_RADIUS: f32 = 0.04;
const TARGET_RADIUS: f32 = 0.04;
const TRAIL_RADIUS: f32 = 0.01;

/// What a finished recording holds.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Summary {
    pub path: PathBuf,
    /// Ticks whose robots were logged, and ticks whose estimates were.
    pub robot_ticks: u64,
    pub estimate_ticks: u64,
    /// Size of the closed file.
    pub bytes: u64,
}

/// An open recording of one run.
pub struct Recording {
    rec: RecordingStream,
    path: PathBuf,
    envs: usize,
    robots_every: Every,
    estimates_every: Every,
    trails: Trails,
    /// The target last logged per env, to log one only when it changes.
    targets: Vec<Option<[f64; 2]>>,
    /// The floor, for the height of targets (which are given on the ground plane).
    ground: Option<Terrain>,
    robot_ticks: u64,
    estimate_ticks: u64,
}

impl Recording {
    /// Creates the file at `path` (and its directory; an existing file is replaced), named
    /// `name` in the viewer, and logs the static scene of `cfg`: its envs and, if its floor
    /// can be built, the floor mesh (a floor that cannot is left out with a warning; the
    /// robots are still recorded).
    pub fn create(
        path: &Path,
        name: &str,
        cfg: &common::Config,
        options: &RecordOptions,
    ) -> Result<Self> {
        let create_err = |reason: String| RecorderError::Create {
            path: path.to_path_buf(),
            reason,
        };
        if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
            std::fs::create_dir_all(dir).map_err(|e| create_err(e.to_string()))?;
        }
        let rec = rerun::RecordingStreamBuilder::new(APPLICATION_ID)
            // Recording is this process's whole job: a `RERUN=off` left in the environment
            // must not turn it into an empty file.
            .enabled(true)
            .recording_name(name)
            .save(path)
            .map_err(|e| create_err(e.to_string()))?;
        // The wall clock of each log call says nothing about the run and costs 8 bytes a row.
        rec.set_log_time_enabled(false);
        let envs = cfg.sim.num_envs();
        let ground = match Terrain::build(&cfg.sim.terrain) {
            Ok(t) => Some(t),
            Err(e) => {
                tracing::warn!(error = %e, "floor left out of the recording");
                None
            }
        };
        let recording = Self {
            rec,
            path: path.to_path_buf(),
            envs,
            robots_every: Every::new(options.every),
            estimates_every: Every::new(options.every),
            trails: Trails::new(envs, options.trail),
            targets: vec![None; envs],
            ground,
            robot_ticks: 0,
            estimate_ticks: 0,
        };
        recording.log_scene(cfg)?;
        Ok(recording)
    }

    /// The static part: coordinates, floor, each robot's marker and body, series names.
    fn log_scene(&self, cfg: &common::Config) -> Result<()> {
        self.log_static(entity::WORLD, &rerun::ViewCoordinates::RIGHT_HAND_Y_UP())?;
        if let Some(terrain) = &self.ground {
            let mesh = GridMesh::of(terrain, MAX_VERTICES);
            tracing::info!(
                vertices = mesh.positions.len(),
                stride = mesh.stride,
                "floor mesh"
            );
            let mesh3d = rerun::Mesh3D::new(mesh.positions)
                .with_triangle_indices(mesh.triangles)
                .with_vertex_normals(mesh.normals)
                .with_vertex_colors(mesh.colors);
            self.log_static(entity::TERRAIN, &mesh3d)?;
        }
        let half = cfg.sim.robot.chassis_half_extents.map(|v| v as f32);
        for env in 0..self.envs {
            let color = cfg.sim.area_of(env).colour();
            let marker = rerun::Points3D::new([[0.0, MARKER_HEIGHT, 0.0]])
                .with_radii([MARKER_RADIUS])
                .with_colors([color])
                .with_labels([format!("env {env}")]);
            self.log_static(&entity::robot(env), &marker)?;
            // The chassis about the axle's midpoint, the pose's origin (the collider sits a
            // centimetre or two off it; close enough to show pitch and heading).
            let body = rerun::Boxes3D::from_half_sizes([half])
                .with_colors([color])
                .with_fill_mode(rerun::FillMode::Solid);
            self.log_static(&entity::body(env), &body)?;
            let trail = rerun::LineStrips3D::update_fields()
                .with_colors([color])
                .with_radii([TRAIL_RADIUS]);
            self.log_static(&entity::trail(env), &trail)?;
        }
        let names: Vec<String> = (0..self.envs).map(|env| format!("env {env}")).collect();
        for metric in entity::METRICS {
            self.log_static(metric, &rerun::SeriesLines::new().with_names(names.clone()))?;
        }
        Ok(())
    }

    /// Logs the robots of `tick` if it is one to log (see [`Every`]); returns whether it
    /// was. Every tick counts for the trails, logged or not: an episode that ended starts
    /// its robot's trail over. Envs beyond the config's are ignored; an env missing from
    /// `samples` is NaN in the series (a gap).
    pub fn robots(&mut self, tick: u64, samples: &[RobotSample]) -> Result<bool> {
        let logged = self.robots_every.take(tick);
        if logged {
            self.set_tick(tick);
            let mut sin_pitch = vec![f64::NAN; self.envs];
            let mut reward = vec![f64::NAN; self.envs];
            let envs = self.envs;
            for s in samples.iter().filter(|s| s.env < envs) {
                self.log_robot(s)?;
                sin_pitch[s.env] = s.sin_pitch;
                reward[s.env] = s.reward;
            }
            self.log(entity::SIN_PITCH, &rerun::Scalars::new(sin_pitch))?;
            self.log(entity::REWARD, &rerun::Scalars::new(reward))?;
            self.robot_ticks += 1;
        }
        for s in samples.iter().filter(|s| s.episode_end) {
            self.trails.restart(s.env);
        }
        Ok(logged)
    }

    /// One robot's pose, trail and (when it changed) target, at the current tick.
    fn log_robot(&mut self, s: &RobotSample) -> Result<()> {
        let pos = s.pos.map(|v| v as f32);
        let pose = rerun::Transform3D::update_fields()
            .with_translation(pos)
            .with_quaternion(rerun::Quaternion::from_xyzw(unity_quaternion(s.euler)));
        self.log(&entity::robot(s.env), &pose)?;
        if let Some(trail) = self.trails.push(s.env, pos) {
            let strip: Vec<[f32; 3]> = trail.iter().copied().collect();
            let strips = rerun::LineStrips3D::update_fields().with_strips([strip]);
            self.log(&entity::trail(s.env), &strips)?;
        }
        if let Some(target) = s.target
            && self.targets[s.env] != Some(target)
        {
            self.targets[s.env] = Some(target);
            let [x, z] = target;
            // Resting on the ground rather than half in it.
            let ground = self.ground.as_ref().map_or(0.0, |g| g.height_at(x, z));
            let y = ground + f64::from(TARGET_RADIUS);
            let point = rerun::Points3D::new([[x as f32, y as f32, z as f32]])
                .with_radii([TARGET_RADIUS])
                .with_labels([format!("target {}", s.env)]);
            self.log(&entity::target(s.env), &point)?;
        }
        Ok(())
    }

    /// Logs the estimator's view at `tick` if it is one to log; returns whether it was.
    /// An unknown class is logged as -1 (its posterior and window std as the estimator
    /// sent them: 0).
    pub fn estimates(&mut self, tick: u64, samples: &[EstimateSample]) -> Result<bool> {
        if !self.estimates_every.take(tick) {
            return Ok(false);
        }
        self.set_tick(tick);
        let mut window_std = vec![f64::NAN; self.envs];
        let mut class = vec![f64::NAN; self.envs];
        let mut posterior = vec![f64::NAN; self.envs];
        for s in samples.iter().filter(|s| s.env < self.envs) {
            window_std[s.env] = s.window_std;
            class[s.env] = s.class.map_or(-1.0, f64::from);
            posterior[s.env] = s.posterior;
        }
        self.log(entity::WINDOW_STD, &rerun::Scalars::new(window_std))?;
        self.log(entity::CLASS, &rerun::Scalars::new(class))?;
        self.log(entity::POSTERIOR, &rerun::Scalars::new(posterior))?;
        self.estimate_ticks += 1;
        Ok(true)
    }

    /// Flushes everything logged to the file and closes it (the file sink writes its footer
    /// when the stream is dropped), so the file is complete and readable.
    pub fn finish(self) -> Result<Summary> {
        let Self {
            rec,
            path,
            robot_ticks,
            estimate_ticks,
            ..
        } = self;
        let failed = |reason: String| RecorderError::Finish {
            path: path.clone(),
            reason,
        };
        rec.flush_blocking().map_err(|e| failed(e.to_string()))?;
        // The last handle: dropping it shuts the sink down and joins its writer thread.
        drop(rec);
        let bytes = std::fs::metadata(&path)
            .map_err(|e| failed(e.to_string()))?
            .len();
        Ok(Summary {
            path,
            robot_ticks,
            estimate_ticks,
            bytes,
        })
    }

    fn set_tick(&self, tick: u64) {
        self.rec
            .set_time_sequence(entity::TIMELINE, i64::try_from(tick).unwrap_or(i64::MAX));
    }

    fn log(&self, entity: &str, data: &impl AsComponents) -> Result<()> {
        self.rec
            .log(entity, data)
            .map_err(|e| log_error(entity, &e))
    }

    fn log_static(&self, entity: &str, data: &impl AsComponents) -> Result<()> {
        self.rec
            .log_static(entity, data)
            .map_err(|e| log_error(entity, &e))
    }
}

fn log_error(entity: &str, e: &rerun::RecordingStreamError) -> RecorderError {
    RecorderError::Log {
        entity: entity.to_string(),
        reason: e.to_string(),
    }
}
