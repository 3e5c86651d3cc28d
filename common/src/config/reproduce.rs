//! `[reproduce]`: the stages of `lavatube reproduce` (DESIGN §6, SPEC S6–S8).

use super::range::invalid;
use super::setting::{choices, count, form, real, settings};
use super::{AreaKind, ConfigError};
use std::path::PathBuf;

settings! {
    /// `lavatube reproduce`: the paper's pipeline, stage by stage (DESIGN §6, SPEC S6–S8).
    /// The other sections give everything else (PPO, terrain, estimator) for every stage.
    pub struct ReproduceConfig {
        /// (a) Envs of the initial flat model, all on flat ground (SPEC S6).
        pub flat_envs: usize = 9 => count(1, 1024), "envs", Essential;
        /// (a) Its environment steps (SPEC S6).
        pub flat_steps: u64 = 2_500_000 => count(1, 10_000_000_000), "steps", Essential;
        /// (b), (c), (e) Envs per area of the mixed stages (SPEC S6: 4 + 4).
        pub envs_per_area: usize = 4 => count(1, 512), "envs", Essential;
        /// (b) Environment steps of the general model, from (a).
        pub general_steps: u64 = 2_500_000 => count(1, 10_000_000_000), "steps", Essential;
        /// (c) Decision steps per env collected with the general model (SPEC S7).
        pub collect_steps: u64 = 500 => count(1, 1_000_000), "steps", Essential;
        /// (c) Envs per area of the collection; unset: `envs-per-area`. More robots make
        /// Table 3 depend less on what the few of them happened to drive over.
        pub collect_envs: Option<usize> = None => count(1, 512), "envs", Essential;
        /// (e) Environment steps of the FTM/RTM fine-tuning, from (b).
        pub finetune_steps: u64 = 500_000 => count(1, 10_000_000_000), "steps", Essential;
        /// (f) Episodes per model × area cell.
        pub eval_episodes: u64 = 200 => count(1, 1_000_000), "episodes", Essential;
        /// (f) Envs per evaluation cell.
        pub eval_envs: usize = 8 => count(1, 1024), "envs", Essential;
        /// (e) `sim.terrain.roughness-scale` of the fine-tuning; unset: the `[sim]` one, as
        /// in the paper. Rougher ground than the general model saw gives the rough-terrain
        /// model something to specialise in.
        pub finetune_roughness_scale: Option<f64> = None => real(0.0, 2.0), "", Research;
        /// (f) `sim.terrain.roughness-scale` of the evaluation, every model and area alike;
        /// unset: the `[sim]` one (SPEC S1's 0.8).
        pub eval_roughness_scale: Option<f64> = None => real(0.0, 2.0), "", Research;
        /// (e) `ppo.learning-rate` of the fine-tuning (it decays from there like every
        /// stage's); unset: the `[ppo]` one. Fine-tuning a converged model at the rate it was
        /// trained from scratch with can move it away from what it already does well.
        pub finetune_learning_rate: Option<f64> = None => real(1e-12, 1.0), "", Research;
        /// (e) Terrain kinds of the world whose specialist trains from new weights at
        /// `ppo.learning-rate` instead of fine-tuning the general model: kinds the general
        /// model drives in a way fine-tuning rarely unlearns (sand's gentle driving,
        /// EXPERIMENT E19). Empty: every specialist fine-tuned, as in the paper.
        pub fresh_specialists: Vec<AreaKind> = Vec::new() => choices::<AreaKind>(), "", Research;
        /// (e) Checkpoints of each specialist's fine-tuning kept as candidates, evenly spaced
        /// (`ppo.milestone-every`). 0, the paper's: FTM and RTM are the fine-tuning's last
        /// checkpoints. With N > 0, each specialist is the one of the general model (no
        /// fine-tuning), the N milestones and the last checkpoint that does best on its own
        /// terrain over validation courses, seeds apart from stage f's (early stopping).
        pub specialist_candidates: usize = 0 => count(0, 100), "checkpoints", Research;
        /// (e) Episodes each candidate drives on the validation courses.
        pub validation_episodes: u64 = 500 => count(1, 1_000_000), "episodes", Advanced;
        /// (e) Online windows the switching model tries on the mixed validation courses,
        /// each one of `estimator.windows`; the best of them and `switch-dwells` drives stage
        /// f (EXPERIMENT E21). Empty: `estimator.online-window` alone, as in the paper.
        pub switch_windows: Vec<usize> = Vec::new() => count(2, 100_000), "ticks", Research;
        /// (e) Values of `sim.switch-dwell` tried with each of `switch-windows`. Empty:
        /// `sim.switch-dwell` alone, as in the paper.
        pub switch_dwells: Vec<usize> = Vec::new() => count(1, 10_000), "ticks", Research;
        /// (f) A worlds file (`lavatube evaluate --worlds`, e.g. `worlds/robustness.toml`):
        /// stage f also drives the general model and switching on the mixed course in each of
        /// its worlds, laid over this config without its `[sim.randomize]`; none: no such drive.
        pub robustness_worlds: Option<PathBuf> = None => form("a file path"), "", Research;
        /// (f) Episodes per model and robustness world.
        pub robustness_episodes: u64 = 200 => count(1, 1_000_000), "episodes", Advanced;
        /// (g) Non-inferiority margin of the shape checks in success: "A at least as good as
        /// B" reads "no" only when A falls short of B by more than this many percentage
        /// points of success (or by more than `margin-s`), beyond the noise of the paired
        /// comparison. 0 with `margin-s` 0 for the strict test.
        pub margin_pp: f64 = 1.0 => real(0.0, 100.0), "pp", Advanced;
        /// (g) Non-inferiority margin of the shape checks in reach time, as `margin-pp`: 0.05
        /// s is half a decision step (the legs' reach times count whole steps).
        pub margin_s: f64 = 0.05 => real(0.0, 10.0), "s", Advanced;
    }
}

impl ReproduceConfig {
    /// The rules between fields and the world (each field's own range is
    /// [`super::setting::Setting::check`]'s); `kinds` are the world's terrain kinds and
    /// `windows` the ones stage d fits a classifier for (`estimator.windows`).
    pub(super) fn validate(
        &self,
        kinds: &[AreaKind],
        windows: &[usize],
    ) -> Result<(), ConfigError> {
        if let Some(k) = self.fresh_specialists.iter().find(|k| !kinds.contains(k)) {
            return Err(invalid(
                "reproduce.fresh-specialists",
                &self.fresh_specialists,
                format!("needs a `{}` area in sim.terrain.areas", k.name()),
            ));
        }
        if let Some(w) = self.switch_windows.iter().find(|w| !windows.contains(w)) {
            return Err(invalid(
                "reproduce.switch-windows",
                &self.switch_windows,
                format!("{w} is not one of estimator.windows {windows:?}, which stage d fits"),
            ));
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
    fn switch_windows_are_windows_stage_d_fits() {
        let e = parse("[reproduce]\nswitch-windows = [20, 30]\n").expect_err("30 not fitted");
        assert!(e.to_string().contains("reproduce.switch-windows"), "{e}");
        assert!(
            e.to_string().contains("30 is not one of estimator.windows"),
            "{e}"
        );
        let c = parse("[reproduce]\nswitch-windows = [20, 70]\nswitch-dwells = [5, 10]\n")
            .expect("valid");
        assert_eq!(c.reproduce.switch_windows, [20, 70]);
        assert_eq!(c.reproduce.switch_dwells, [5, 10]);
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
