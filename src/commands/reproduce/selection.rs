//! Stage e's choice of specialists: without candidates the fine-tuning's last checkpoints;
//! with `reproduce.specialist-candidates`, the general model and the fine-tuning's milestones
//! each drive validation courses of the specialist's terrain, and the [`best`] is kept in
//! `e-select/selection.json`.

use super::legs::{Cell, Legs, common_legs};
use super::stages::Pipeline;
use anyhow::Context;
use common::config::{AreaKind, PolicySlot};
use std::path::{Path, PathBuf};

/// A specialist's candidates on its terrain's validation courses (stage e), and the one
/// chosen. Without candidates (`reproduce.specialist-candidates` = 0, the paper's) the only
/// one is the fine-tuning's last checkpoint, not validated.
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
pub(super) struct Selection {
    pub(super) model: String,
    pub(super) area: AreaKind,
    pub(super) candidates: Vec<Candidate>,
    pub(super) chosen: usize,
}

#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
pub(super) struct Candidate {
    /// "general" (no fine-tuning) or "update N" of the fine-tuning.
    pub(super) label: String,
    pub(super) checkpoint: PathBuf,
    /// On the validation courses; `None` when not validated.
    pub(super) cell: Option<Cell>,
}

impl Selection {
    pub(super) fn checkpoint(&self) -> &Path {
        &self.candidates[self.chosen].checkpoint
    }
}

/// Where stage `e-select` keeps its [`Selection`]s.
const SELECTION_JSON: &str = "selection.json";

/// The candidate that is the general model, before any fine-tuning.
pub(super) const GENERAL: &str = "general";

/// Stage `e-select`'s choice, if it finished.
pub(super) fn chosen_before(p: &Pipeline) -> anyhow::Result<Option<Vec<Selection>>> {
    p.kept("e-select", SELECTION_JSON, "stage e's selection")
}

/// A terrain kind's specialist: its name in the tables and the slot that fine-tunes it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct Role {
    pub(super) model: &'static str,
    pub(super) slot: PolicySlot,
    pub(super) kind: AreaKind,
}

/// The specialist of each of `kinds` (`AreaKind::model`): SPEC S8's flat- and rough-terrain
/// models FTM and RTM, and beyond the paper one per other kind.
pub(super) fn roles(kinds: &[AreaKind]) -> Vec<Role> {
    kinds
        .iter()
        .filter_map(|&kind| {
            let model = kind.model()?;
            let slot = PolicySlot::for_class(kind.code())?;
            Some(Role { model, slot, kind })
        })
        .collect()
}

/// The terrain kind the specialist named `model` is for, if it is one ([`roles`]).
pub(super) fn kind_of(model: &str) -> Option<AreaKind> {
    roles(&AreaKind::KINDS)
        .into_iter()
        .find(|r| r.model == model)
        .map(|r| r.kind)
}

/// One specialist per terrain kind of the world (SPEC S8's FTM and RTM on the paper's):
/// stage e's last checkpoints, or with `specialist-candidates` the ones stage `e-select`
/// validates best ([`Pipeline::select`]), chosen once and kept.
pub(super) fn specialists(p: &Pipeline) -> anyhow::Result<Vec<Selection>> {
    let roles = roles(&p.kinds());
    if p.base.reproduce.specialist_candidates == 0 {
        return roles
            .into_iter()
            .map(
                |Role {
                     model,
                     slot,
                     kind: area,
                 }| {
                    let checkpoint = p.checkpoint("e-specialists", slot)?;
                    Ok(Selection {
                        model: model.into(),
                        area,
                        candidates: vec![Candidate {
                            label: "last checkpoint".into(),
                            checkpoint,
                            cell: None,
                        }],
                        chosen: 0,
                    })
                },
            )
            .collect();
    }
    if let Some(chosen) = chosen_before(p)? {
        return Ok(chosen);
    }
    let path = p.stage_dir("e-select").join(SELECTION_JSON);
    std::fs::create_dir_all(p.fresh("e-select")?)?;
    p.say("e-select: each specialist's candidates on validation courses of its terrain");
    let general = p.checkpoint("b-general", PolicySlot::General)?;
    let chosen = roles
        .into_iter()
        .map(|r| p.select(r.model, r.slot, r.kind, &general))
        .collect::<anyhow::Result<Vec<_>>>()?;
    std::fs::write(&path, serde_json::to_string_pretty(&chosen)?)
        .with_context(|| format!("cannot write {}", path.display()))?;
    p.finish("e-select", serde_json::json!({ "selection": path }))?;
    Ok(chosen)
}

impl Pipeline {
    /// Stage e's `ppo.milestone-every`: `reproduce.specialist-candidates` milestones spread
    /// evenly over each specialist's updates (one per rollout), the last one at the end.
    pub(super) fn milestone_every(&self) -> usize {
        let (r, ppo) = (&self.base.reproduce, &self.base.ppo);
        let updates = (r.finetune_steps / ppo.rollout_transitions as u64).max(1) as usize;
        updates
            .div_ceil(r.specialist_candidates.max(1))
            .next_multiple_of(ppo.checkpoint_every)
    }

    /// Early stopping for the specialist `model`, fine-tuned in stage e by the learner of
    /// `slot`: the general model (`general`, no fine-tuning), stage e's milestones and its
    /// last checkpoint each drive validation courses in `area`; the [`best`] wins.
    fn select(
        &self,
        model: &str,
        slot: PolicySlot,
        area: AreaKind,
        general: &Path,
    ) -> anyhow::Result<Selection> {
        let dir = self.stage_dir("e-select");
        let every = self.milestone_every() as u64;
        let all = self.checkpoints("e-specialists", slot)?;
        let last = all.len() - 1;
        let mut tried = vec![(GENERAL.to_string(), general.to_path_buf())];
        tried.extend(
            all.into_iter()
                .enumerate()
                .filter(|(i, (update, _))| *i == last || update.is_multiple_of(every))
                .map(|(_, (update, ckpt))| (format!("update {update}"), ckpt)),
        );
        let courses = self.validation_courses("e-select");
        let mut candidates = Vec::new();
        let mut legs = Vec::new();
        for (k, (label, checkpoint)) in tried.into_iter().enumerate() {
            let weights = dir.join(format!("{}-{k}.policy", model.to_lowercase()));
            self.export(&checkpoint, &weights)?;
            let name = format!("{model}-{}", label.replace(' ', "-"));
            let driven = self.evaluate_policy(&name, &weights, area, courses, &dir)?;
            candidates.push(Candidate {
                label,
                checkpoint,
                cell: Some(Cell::of(&driven.legs, self.base.sim.decision_dt())),
            });
            legs.push(driven.legs);
        }
        let chosen = best(&legs, self.base.reproduce.margin_pp);
        self.say(&format!(
            "e-select: {model} is {} ({} candidates)",
            candidates[chosen].label,
            candidates.len()
        ));
        Ok(Selection {
            model: model.into(),
            area,
            candidates,
            chosen,
        })
    }
}

/// The best of several models' `legs` on the same courses: among those whose success rate
/// on the legs all drove is within `margin_pp` of the highest (closer is noise at validation
/// sizes), the one with the shortest mean reach time on the legs all of those reached; the
/// first of equals (the least fine-tuned candidate, in [`Pipeline::select`]'s order).
pub(super) fn best(legs: &[Legs], margin_pp: f64) -> usize {
    let all: Vec<&Legs> = legs.iter().collect();
    let driven = common_legs(&all);
    let success: Vec<f64> = (0..legs.len())
        .map(|k| 100.0 * driven.iter().filter(|l| l[k].is_some()).count() as f64)
        .map(|s| s / driven.len().max(1) as f64)
        .collect();
    let top = success.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    let near: Vec<usize> = (0..legs.len())
        .filter(|&k| success[k] >= top - margin_pp)
        .collect();
    let reached: Vec<Vec<u32>> = common_legs(&near.iter().map(|&k| &legs[k]).collect::<Vec<_>>())
        .into_iter()
        .filter_map(|leg| leg.into_iter().collect())
        .collect();
    let reach = |i: usize| reached.iter().map(|r| u64::from(r[i])).sum::<u64>();
    (0..near.len())
        .reduce(|b, i| if reach(i) < reach(b) { i } else { b })
        .map_or(0, |i| near[i])
}

#[cfg(test)]
mod tests {
    use super::*;
    use common::Config;

    #[test]
    fn the_best_candidate_succeeds_within_the_margin_then_reaches_soonest() {
        // One part, one env, ten legs; `None` failed.
        let legs = |l: &[Option<u32>]| -> Legs { vec![vec![l.to_vec()]] };
        let all = |t: u32| vec![Some(t); 10];
        let mut nine = all(30);
        nine[9] = None;
        // 100 % at 40 steps against 90 % at 30: 10 pp apart, success wins.
        assert_eq!(best(&[legs(&nine), legs(&all(40))], 1.0), 1);
        // Within a 10 pp margin the sooner wins, timed on the legs both reached (the failed
        // leg is left out of both: a 99-step leg there does not count against the first).
        let mut slow_last = all(30);
        slow_last[9] = Some(99);
        assert_eq!(best(&[legs(&slow_last), legs(&nine)], 10.0), 0);
        assert_eq!(best(&[legs(&all(31)), legs(&nine)], 10.0), 1);
        // Equals keep the first (the general model before any fine-tuning).
        assert_eq!(best(&[legs(&all(30)), legs(&all(30))], 1.0), 0);
        // Legs only one model drove (it drove more) do not count.
        let mut longer = all(30);
        longer.extend([Some(1); 5]);
        assert_eq!(best(&[legs(&all(30)), legs(&longer)], 1.0), 0);
        // No candidate reached a target: the first.
        assert_eq!(best(&[legs(&[None; 4]), legs(&[None; 4])], 1.0), 0);
    }

    #[test]
    fn milestones_spread_over_the_fine_tuning() {
        let mut base = Config::default();
        base.reproduce.finetune_steps = 2_000_000;
        base.reproduce.specialist_candidates = 4;
        let every = |base: &Config| {
            Pipeline {
                base: base.clone(),
                out: PathBuf::new(),
                quiet: true,
            }
            .milestone_every()
        };
        // 976 updates of 2,048 transitions: milestones at 244, 488, 732 and 976.
        assert_eq!(every(&base), 244);
        // Only written checkpoints can be kept: the next multiple of checkpoint-every.
        base.ppo.checkpoint_every = 5;
        assert_eq!(every(&base), 245);
        base.ppo.checkpoint_every = 1;
        base.reproduce.specialist_candidates = 100;
        base.reproduce.finetune_steps = 4096;
        assert_eq!(every(&base), 1);
    }

    #[test]
    fn every_kind_has_a_specialist_named_after_it() {
        let all = roles(&AreaKind::KINDS);
        let names: Vec<&str> = all.iter().map(|r| r.model).collect();
        assert_eq!(names, ["FTM", "RTM", "STM", "GTM", "DTM"]);
        assert!(all.iter().all(|r| r.slot.kind() == Some(r.kind)));
        assert_eq!(kind_of("STM"), Some(AreaKind::Slope));
        assert_eq!(kind_of("general"), None);
        assert!(roles(&[AreaKind::Mixed]).is_empty());
    }
}
