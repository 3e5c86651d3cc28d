//! `[reproduce]`: the stages of `lavatube reproduce` (DESIGN §6, SPEC S6–S8).

use super::range::{count_in, in_range, invalid};
use super::{AreaKind, ConfigError};
use serde::{Deserialize, Serialize};

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
    /// (e) Terrain kinds of the world whose specialist trains from new weights at
    /// `ppo.learning-rate` instead of fine-tuning the general model: kinds the general model
    /// drives in a way fine-tuning rarely unlearns (sand's gentle driving, EXPERIMENT E19).
    /// Default none: every specialist fine-tuned, as in the paper.
    pub fresh_specialists: Vec<AreaKind>,
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
            fresh_specialists: Vec::new(),
            specialist_candidates: 0,
            validation_episodes: 500,
            margin_pp: 1.0,
            margin_s: 0.05,
        }
    }
}

impl ReproduceConfig {
    /// Its own fields; `kinds` are the world's terrain kinds.
    pub(super) fn validate(&self, kinds: &[AreaKind]) -> Result<(), ConfigError> {
        if let Some(k) = self.fresh_specialists.iter().find(|k| !kinds.contains(k)) {
            return Err(invalid(
                "reproduce.fresh-specialists",
                &self.fresh_specialists,
                format!("needs a `{}` area in sim.terrain.areas", k.name()),
            ));
        }
        count_in("reproduce.flat-envs", self.flat_envs, 1, 1024)?;
        count_in("reproduce.envs-per-area", self.envs_per_area, 1, 512)?;
        count_in("reproduce.eval-envs", self.eval_envs, 1, 1024)?;
        if let Some(n) = self.collect_envs {
            count_in("reproduce.collect-envs", n, 1, 512)?;
        }
        count_in(
            "reproduce.specialist-candidates",
            self.specialist_candidates,
            0,
            100,
        )?;
        for (field, v) in [
            (
                "reproduce.finetune-roughness-scale",
                self.finetune_roughness_scale,
            ),
            ("reproduce.eval-roughness-scale", self.eval_roughness_scale),
        ] {
            if let Some(v) = v {
                in_range(field, v, 0.0, 2.0)?;
            }
        }
        if let Some(lr) = self.finetune_learning_rate {
            in_range("reproduce.finetune-learning-rate", lr, 1e-12, 1.0)?;
        }
        in_range("reproduce.margin-pp", self.margin_pp, 0.0, 100.0)?;
        in_range("reproduce.margin-s", self.margin_s, 0.0, 10.0)?;
        for (field, v, hi) in [
            ("reproduce.flat-steps", self.flat_steps, 10_000_000_000),
            (
                "reproduce.general-steps",
                self.general_steps,
                10_000_000_000,
            ),
            ("reproduce.collect-steps", self.collect_steps, 1_000_000),
            (
                "reproduce.finetune-steps",
                self.finetune_steps,
                10_000_000_000,
            ),
            ("reproduce.eval-episodes", self.eval_episodes, 1_000_000),
            (
                "reproduce.validation-episodes",
                self.validation_episodes,
                1_000_000,
            ),
        ] {
            count_in(field, v, 1, hi)?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use crate::config::tests::parse;

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
    fn fresh_specialists_are_kinds_of_the_world() {
        let e = parse("[reproduce]\nfresh-specialists = [\"sand\"]\n").expect_err("no sand");
        assert!(e.to_string().contains("reproduce.fresh-specialists"), "{e}");
        assert!(e.to_string().contains("`sand` area"), "{e}");
        let c = parse("[reproduce]\nfresh-specialists = [\"rough\"]\n").expect("valid");
        assert_eq!(c.reproduce.fresh_specialists, [super::AreaKind::Rough]);
    }
}
