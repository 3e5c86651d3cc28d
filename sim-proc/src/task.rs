//! The paper's episode and reward rules (SPEC S3–S4) as pure functions plus the per-episode
//! bookkeeping that applies them. Positions are X-Z ground coordinates in metres.

use common::config::TaskConfig;

/// X-Z distance between two ground points.
pub fn dist(a: [f64; 2], b: [f64; 2]) -> f64 {
    ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2)).sqrt()
}

/// SPEC S3: maximum episode steps, MES = 300 + 200·ID (ID in metres).
pub fn max_episode_steps(cfg: &TaskConfig, id: f64) -> u32 {
    (cfg.mes_base + cfg.mes_per_metre * id).floor() as u32
}

/// SPEC S3: the distance limit PED = (ID + 2Δ) − kΔ after `k` Δ-approaches.
pub fn penalty_distance(cfg: &TaskConfig, id: f64, k: u32) -> f64 {
    id + cfg.ped_slack * cfg.delta - f64::from(k) * cfg.delta
}

/// SPEC S4: truncates (not rounds) a non-negative distance to one decimal.
pub fn truncate_one_decimal(x: f64) -> f64 {
    // The epsilon keeps 0.3 (stored as 0.2999…) at 0.3.
    ((x * 10.0) + 1e-9).floor() / 10.0
}

/// SPEC S4: ProgressReward = 100·PD, PD = the travelled X-Z distance truncated to 0.1 m.
pub fn progress_reward(cfg: &TaskConfig, travelled: f64) -> f64 {
    cfg.progress_scale * truncate_one_decimal(travelled)
}

/// SPEC S4: N = ⌊ID/Δ⌋ (with a small epsilon so 0.3/0.1 gives 3), capped at 5.
pub fn circles(cfg: &TaskConfig, id: f64) -> u32 {
    ((id / cfg.delta + 1e-9).floor() as u32).min(5)
}

/// SPEC S4: BR = 100 + 10·RD with RD = 15 − Σ_{k=1..N} k.
pub fn base_reward(cfg: &TaskConfig, id: f64) -> f64 {
    let n = f64::from(circles(cfg, id));
    100.0 + 10.0 * (15.0 - n * (n + 1.0) / 2.0)
}

/// SPEC S4: FinalReward = BR + OR − TP, OR = 50·mean(cos θx), TP = steps / MES.
pub fn final_reward(cfg: &TaskConfig, id: f64, mean_cos_pitch: f64, steps: u32) -> f64 {
    let mes = f64::from(max_episode_steps(cfg, id));
    base_reward(cfg, id) + 50.0 * mean_cos_pitch - f64::from(steps) / mes
}

/// How an episode ended on a step.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Ending {
    /// Reached the target (terminal, pays the final reward).
    Success,
    /// Farther than PED from the target (terminal failure).
    TooFar,
    /// Out of the area or tipped over (terminal failure, respawn).
    LeftOrTipped,
    /// Stood within `stall-distance` of one spot for `stall-steps` (terminal failure, respawn;
    /// not the paper's rule, off by default).
    Stalled,
    /// MES reached (truncation: bootstrap the value).
    TimeLimit,
    /// Non-finite physics (truncation, respawn).
    Fault,
}

impl Ending {
    pub fn terminated(self) -> bool {
        matches!(
            self,
            Ending::Success | Ending::TooFar | Ending::LeftOrTipped | Ending::Stalled
        )
    }

    pub fn truncated(self) -> bool {
        !self.terminated()
    }

    /// Whether the robot must be put back at a random pose in its area (SPEC S3).
    pub fn respawns(self) -> bool {
        matches!(self, Ending::LeftOrTipped | Ending::Stalled | Ending::Fault)
    }
}

/// One episode's state: where it started, its target and what it has paid.
#[derive(Debug, Clone, PartialEq)]
pub struct Episode {
    pub start: [f64; 2],
    pub target: [f64; 2],
    /// ID: X-Z distance from the start to the target.
    pub initial_distance: f64,
    pub mes: u32,
    pub steps: u32,
    /// k: Δ-circles crossed so far (SPEC S3–S4).
    pub k: u32,
    /// Bit j−1 set when the circle of radius jΔ has paid.
    paid: u8,
    sum_cos_pitch: f64,
    /// The stall rule's spot: where the robot last moved to, and the step it got there.
    spot: [f64; 2],
    spot_step: u32,
}

/// What one step of an episode produced.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StepResult {
    pub reward: f64,
    pub ending: Option<Ending>,
}

impl Episode {
    pub fn new(cfg: &TaskConfig, start: [f64; 2], target: [f64; 2]) -> Self {
        let id = dist(start, target);
        Self {
            start,
            target,
            initial_distance: id,
            mes: max_episode_steps(cfg, id),
            steps: 0,
            k: 0,
            paid: 0,
            sum_cos_pitch: 0.0,
            spot: start,
            spot_step: 0,
        }
    }

    /// Applies SPEC S3–S4 after one decision step that left the robot at `pos` with pitch
    /// cosine `cos_pitch`. `out_or_tipped` reports the respawn rule's condition.
    pub fn step(
        &mut self,
        cfg: &TaskConfig,
        pos: [f64; 2],
        cos_pitch: f64,
        out_or_tipped: bool,
    ) -> StepResult {
        self.steps += 1;
        self.sum_cos_pitch += cos_pitch;
        let d = dist(pos, self.target);
        let mut reward = 0.0;
        // SPEC S4: each circle jΔ < ID pays once, the first time the distance drops below it.
        for j in 1..=5u32 {
            let radius = f64::from(j) * cfg.delta;
            let bit = 1u8 << (j - 1);
            if radius < self.initial_distance && d < radius && self.paid & bit == 0 {
                self.paid |= bit;
                self.k += 1;
                reward += progress_reward(cfg, dist(pos, self.start));
            }
        }
        if dist(pos, self.spot) > cfg.stall_distance {
            (self.spot, self.spot_step) = (pos, self.steps);
        }
        // SPEC S3 extension: a stall ends the episode as a failure, terminal like PED's.
        let stalled = cfg.stall_steps > 0 && self.steps - self.spot_step >= cfg.stall_steps;
        let ending = if d < cfg.delta {
            let mean_cos = self.sum_cos_pitch / f64::from(self.steps);
            reward += final_reward(cfg, self.initial_distance, mean_cos, self.steps);
            Some(Ending::Success)
        } else if out_or_tipped {
            Some(Ending::LeftOrTipped)
        } else if d > penalty_distance(cfg, self.initial_distance, self.k) {
            Some(Ending::TooFar)
        } else if stalled {
            Some(Ending::Stalled)
        } else if self.steps >= self.mes {
            Some(Ending::TimeLimit)
        } else {
            None
        };
        StepResult { reward, ending }
    }
}

/// SPEC S3: a target uniform over the annulus Δ·[lo, hi] around `from`, redrawn until it lies
/// inside `area` (interpretation); after `max-target-draws` misses the last draw is clamped in.
pub fn draw_target(
    cfg: &TaskConfig,
    area: &common::config::Rect,
    from: [f64; 2],
    rng: &mut common::Rng,
) -> [f64; 2] {
    let (r0, r1) = (
        cfg.target_annulus[0] * cfg.delta,
        cfg.target_annulus[1] * cfg.delta,
    );
    let mut t = from;
    for _ in 0..cfg.max_target_draws {
        // Uniform over the annulus' area: r² is uniform.
        let r = rng.range(r0 * r0, r1 * r1).sqrt();
        let a = rng.range(0.0, std::f64::consts::TAU);
        t = [from[0] + r * a.cos(), from[1] + r * a.sin()];
        if area.contains(t[0], t[1], 0.0) {
            return t;
        }
    }
    [
        t[0].clamp(area.x[0], area.x[1]),
        t[1].clamp(area.z[0], area.z[1]),
    ]
}

#[cfg(test)]
mod tests {
    use super::*;
    use common::config::Rect;

    fn cfg() -> TaskConfig {
        TaskConfig::default()
    }

    #[test]
    fn spec_s3_mes_and_ped() {
        assert_eq!(max_episode_steps(&cfg(), 0.1), 320);
        assert_eq!(max_episode_steps(&cfg(), 0.5), 400);
        assert_eq!(max_episode_steps(&cfg(), 0.25), 350);
        // PED = 0.3 + 0.2 − 2·0.1 = 0.3
        assert!((penalty_distance(&cfg(), 0.3, 2) - 0.3).abs() < 1e-12);
        assert!((penalty_distance(&cfg(), 0.42, 0) - 0.62).abs() < 1e-12);
    }

    #[test]
    fn spec_s4_progress_truncates() {
        assert!((truncate_one_decimal(0.29) - 0.2).abs() < 1e-12);
        assert!((truncate_one_decimal(0.3) - 0.3).abs() < 1e-12);
        assert!((truncate_one_decimal(0.1 + 0.2) - 0.3).abs() < 1e-12);
        assert!((progress_reward(&cfg(), 0.2799) - 20.0).abs() < 1e-9);
    }

    #[test]
    fn spec_s4_base_and_final_reward() {
        // N = 3: RD = 15 − 6 = 9, BR = 190.
        assert_eq!(circles(&cfg(), 0.3), 3);
        assert!((base_reward(&cfg(), 0.3) - 190.0).abs() < 1e-12);
        // N = 5 (capped): RD = 0, BR = 100.
        assert!((base_reward(&cfg(), 0.5) - 100.0).abs() < 1e-12);
        assert!((base_reward(&cfg(), 0.7) - 100.0).abs() < 1e-12);
        // N = 1: RD = 14, BR = 240.
        assert!((base_reward(&cfg(), 0.15) - 240.0).abs() < 1e-12);
        // ID 0.3: MES 360; 90 steps → TP = 0.25; MO = 0.9 → OR = 45.
        assert!((final_reward(&cfg(), 0.3, 0.9, 90) - (190.0 + 45.0 - 0.25)).abs() < 1e-9);
    }

    #[test]
    fn spec_s3_s4_episode_pays_each_circle_once_and_counts_k() {
        let c = cfg();
        let mut e = Episode::new(&c, [0.0, 0.0], [0.35, 0.0]);
        assert_eq!(e.mes, 370);
        // Cross 3Δ (0.3): d = 0.29 → pays 100·trunc(0.06) = 0.
        let r = e.step(&c, [0.06, 0.0], 1.0, false);
        assert_eq!((r.reward, r.ending, e.k), (0.0, None, 1));
        // Cross 2Δ: at x = 0.16, d = 0.19, PD = trunc(0.16) = 0.1 → 10.
        let r = e.step(&c, [0.16, 0.0], 1.0, false);
        assert!((r.reward - 10.0).abs() < 1e-9 && e.k == 2);
        // Back out and in again: no second payment.
        e.step(&c, [0.10, 0.0], 1.0, false);
        let r = e.step(&c, [0.17, 0.0], 1.0, false);
        assert_eq!(r.reward, 0.0);
        // Reach: crosses 1Δ (pays 100·0.2 = 20) and succeeds: ID 0.35 → N 3, BR 190;
        // MO = 1 → OR 50; 5 steps / MES 370.
        let r = e.step(&c, [0.27, 0.0], 1.0, false);
        assert_eq!(r.ending, Some(Ending::Success));
        assert!(
            (r.reward - (20.0 + 190.0 + 50.0 - 5.0 / 370.0)).abs() < 1e-9,
            "{}",
            r.reward
        );
        assert_eq!(e.k, 3);
    }

    #[test]
    fn spec_s3_endings() {
        let c = cfg();
        // PED with k = 0 is ID + 0.2: moving 0.21 away fails.
        let mut e = Episode::new(&c, [0.0, 0.0], [0.2, 0.0]);
        assert_eq!(
            e.step(&c, [-0.21, 0.0], 1.0, false).ending,
            Some(Ending::TooFar)
        );
        let mut e = Episode::new(&c, [0.0, 0.0], [0.2, 0.0]);
        assert_eq!(
            e.step(&c, [0.0, 0.0], 1.0, true).ending,
            Some(Ending::LeftOrTipped)
        );
        let mut e = Episode::new(&c, [0.0, 0.0], [0.2, 0.0]);
        for _ in 0..339 {
            assert_eq!(e.step(&c, [0.0, 0.0], 1.0, false).ending, None);
        }
        let end = e
            .step(&c, [0.0, 0.0], 1.0, false)
            .ending
            .expect("time limit");
        assert_eq!(end, Ending::TimeLimit);
        assert!(end.truncated() && !end.terminated() && !end.respawns());
        assert!(
            Ending::TooFar.terminated() && Ending::Fault.respawns() && Ending::Fault.truncated()
        );
    }

    #[test]
    fn spec_s3_extension_a_stall_ends_the_episode_and_respawns() {
        let c = TaskConfig {
            stall_steps: 3,
            stall_distance: 0.02,
            ..cfg()
        };
        let mut e = Episode::new(&c, [0.0, 0.0], [0.3, 0.0]);
        // Creeping 1.5 cm stays on the spot; the third step there is a stall.
        assert_eq!(e.step(&c, [0.01, 0.0], 1.0, false).ending, None);
        assert_eq!(e.step(&c, [0.015, 0.0], 1.0, false).ending, None);
        let end = e.step(&c, [0.015, 0.0], 1.0, false).ending;
        assert_eq!(end, Some(Ending::Stalled));
        assert!(Ending::Stalled.terminated() && Ending::Stalled.respawns());
        // Leaving the spot (2.5 cm) restarts the count from there.
        let mut e = Episode::new(&c, [0.0, 0.0], [0.3, 0.0]);
        e.step(&c, [0.0, 0.0], 1.0, false);
        e.step(&c, [0.025, 0.0], 1.0, false);
        assert_eq!(e.step(&c, [0.025, 0.0], 1.0, false).ending, None);
        assert_eq!(e.step(&c, [0.03, 0.0], 1.0, false).ending, None);
        assert_eq!(
            e.step(&c, [0.03, 0.0], 1.0, false).ending,
            Some(Ending::Stalled)
        );
        // Off (the paper's rules): standing still only runs into MES.
        let c = cfg();
        let mut e = Episode::new(&c, [0.0, 0.0], [0.3, 0.0]);
        assert!((0..100).all(|_| e.step(&c, [0.0, 0.0], 1.0, false).ending.is_none()));
    }

    #[test]
    fn spec_s3_targets_lie_in_the_annulus_and_the_area() {
        let c = cfg();
        let area = Rect {
            x: [-2.5, 0.5],
            z: [-1.0, 0.5],
        };
        let mut rng = common::Rng::new(5);
        let mut radii = Vec::new();
        for _ in 0..2000 {
            let from = [rng.range(-2.5, 0.5), rng.range(-1.0, 0.5)];
            let t = draw_target(&c, &area, from, &mut rng);
            let r = dist(from, t);
            assert!((0.1 - 1e-9..=0.5 + 1e-9).contains(&r), "{r}");
            assert!(area.contains(t[0], t[1], 0.0));
            radii.push(r);
        }
        // Uniform over the annulus' area: P(r < 0.3) = (0.09 − 0.01) / (0.25 − 0.01) = 1/3.
        let inner = radii.iter().filter(|&&r| r < 0.3).count() as f64 / radii.len() as f64;
        assert!((inner - 1.0 / 3.0).abs() < 0.05, "{inner}");
    }
}
