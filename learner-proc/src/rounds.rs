//! Sync mode with several sims (DESIGN §9): one update per round, on one chunk from each
//! source, merged in ascending source order, so a run across hosts is reproducible from its
//! seed whatever order the chunks arrive in.

use crate::EpisodeOutcome;
use common::{OBS_DIM, Transition};
use std::collections::BTreeMap;

/// One source's chunk, waiting for the round to fill.
#[derive(Debug)]
struct Part {
    chunk: u64,
    steps: usize,
    transitions: Vec<Transition>,
    bootstrap_obs: Vec<[f32; OBS_DIM]>,
    episodes: Vec<EpisodeOutcome>,
}

/// A full round as one rollout: the sources' envs side by side in each step's row.
#[derive(Debug, PartialEq)]
pub struct Merged {
    pub transitions: Vec<Transition>,
    pub bootstrap_obs: Vec<[f32; OBS_DIM]>,
    pub episodes: Vec<EpisodeOutcome>,
    /// What the policy learned from the round answers: every source's chunk id is below it.
    pub chunks_seen: u64,
}

/// The chunks of the round in progress, by source.
#[derive(Debug, Default)]
pub struct Round {
    pending: BTreeMap<u32, Part>,
}

impl Round {
    /// Adds `source`'s chunk of `steps` × envs transitions. A source's newer chunk replaces
    /// one still waiting (a restarted sim starts its sequence again).
    pub fn add(
        &mut self,
        source: u32,
        chunk: u64,
        steps: usize,
        transitions: Vec<Transition>,
        bootstrap_obs: Vec<[f32; OBS_DIM]>,
        episodes: Vec<EpisodeOutcome>,
    ) {
        self.pending.insert(
            source,
            Part {
                chunk,
                steps,
                transitions,
                bootstrap_obs,
                episodes,
            },
        );
    }

    /// The merged round once `sources` sources have a chunk waiting, all of `steps` steps.
    /// Env `e` of the k-th source (ascending ids) becomes env `e` plus the envs of the
    /// sources before it.
    pub fn complete(&mut self, sources: usize) -> Option<Merged> {
        if self.pending.len() < sources {
            return None;
        }
        let parts: Vec<Part> = std::mem::take(&mut self.pending).into_values().collect();
        let steps = parts[0].steps;
        if parts.iter().any(|p| p.steps != steps) {
            tracing::error!("a round's chunks have different rollout lengths: dropped");
            return None;
        }
        let envs: Vec<usize> = parts.iter().map(|p| p.bootstrap_obs.len()).collect();
        let offsets: Vec<u32> = envs
            .iter()
            .scan(0, |acc, &n| {
                let o = *acc;
                *acc += n;
                Some(o as u32)
            })
            .collect();
        let mut transitions = Vec::with_capacity(steps * envs.iter().sum::<usize>());
        for s in 0..steps {
            for ((p, &n), &offset) in parts.iter().zip(&envs).zip(&offsets) {
                transitions.extend(
                    p.transitions[s * n..(s + 1) * n]
                        .iter()
                        .map(|t| Transition {
                            env: t.env + offset,
                            ..*t
                        }),
                );
            }
        }
        let mut merged = Merged {
            transitions,
            bootstrap_obs: Vec::new(),
            episodes: Vec::new(),
            chunks_seen: parts.iter().map(|p| p.chunk + 1).max().unwrap_or(0),
        };
        for (p, &offset) in parts.into_iter().zip(&offsets) {
            merged.bootstrap_obs.extend(p.bootstrap_obs);
            merged
                .episodes
                .extend(p.episodes.into_iter().map(|e| EpisodeOutcome {
                    env: e.env + offset,
                    ..e
                }));
        }
        Some(merged)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A chunk of `steps` × `envs` whose transitions record (source, step, env) in reward.
    fn chunk(source: u32, steps: usize, envs: usize) -> (Vec<Transition>, Vec<[f32; OBS_DIM]>) {
        let t = (0..steps * envs)
            .map(|i| Transition {
                env: (i % envs) as u32,
                reward: (source * 100 + (i / envs) as u32 * 10 + (i % envs) as u32) as f32,
                ..Transition::default()
            })
            .collect();
        let boot = (0..envs)
            .map(|e| [source as f32 * 10.0 + e as f32; OBS_DIM])
            .collect();
        (t, boot)
    }

    #[test]
    fn a_round_merges_its_sources_in_id_order_whatever_order_they_came_in() {
        let mut round = Round::default();
        let (t2, b2) = chunk(2, 2, 1);
        round.add(2, 5, 2, t2, b2, Vec::new());
        assert_eq!(round.complete(2), None, "one source of two");
        let (t1, b1) = chunk(1, 2, 2);
        let ended = EpisodeOutcome {
            env: 1,
            episode_return: 1.5,
            steps: 9,
            success: true,
        };
        round.add(1, 4, 2, t1, b1, vec![ended]);
        let m = round.complete(2).expect("both sources");
        // Row 0: source 1's envs 0, 1, then source 2's env 0 as env 2; then row 1.
        let got: Vec<(u32, f32)> = m.transitions.iter().map(|t| (t.env, t.reward)).collect();
        assert_eq!(
            got,
            [
                (0, 100.0),
                (1, 101.0),
                (2, 200.0),
                (0, 110.0),
                (1, 111.0),
                (2, 210.0)
            ]
        );
        let boot: Vec<f32> = m.bootstrap_obs.iter().map(|o| o[0]).collect();
        assert_eq!(boot, [10.0, 11.0, 20.0]);
        assert_eq!(m.episodes, [ended]);
        assert_eq!(
            m.chunks_seen, 6,
            "answers chunk 4 of source 1 and chunk 5 of source 2"
        );
        assert_eq!(round.complete(2), None, "the round starts empty again");
    }
}
