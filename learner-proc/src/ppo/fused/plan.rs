//! Who computes what in a fused update: the actor and the critic are separate networks with
//! separate parameters, so each gets its own group of workers. With two threads, one trains
//! the actor and the other the critic, and nothing but a few scalars (the norms, the losses)
//! crosses between the two cores; more threads split each network's shards within its group.

use std::ops::Range;

use crate::net::NetShape;

/// One of the two networks.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Net {
    /// The policy: its dense layers and the log-std.
    Actor,
    Critic,
}

impl Net {
    pub(super) const BOTH: [Net; 2] = [Net::Actor, Net::Critic];

    /// The network's span of the flat parameter vector.
    pub(super) fn range(self, shape: &NetShape) -> Range<usize> {
        match self {
            Net::Actor => 0..shape.actor_len(),
            Net::Critic => shape.actor_len()..shape.len(),
        }
    }
}

/// Floats per part: the unit of the flat parameter vector that one worker adds up, measures
/// and steps. Fixed, so the norm is added up in the same order for any thread count.
const PART: usize = 2048;

/// A run of parameters within one network.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(super) struct Part {
    pub net: Net,
    pub range: Range<usize>,
}

/// The workers of each network and the parts each worker owns.
pub(super) struct Plan {
    /// The actor's workers, then the critic's: the even and the odd ones, or worker 0 for both
    /// when there is one.
    groups: [Vec<usize>; 2],
    /// Each network's span cut into runs of at most [`PART`] floats, actor first.
    pub parts: Vec<Part>,
    /// The parts each worker adds up and steps, of its own network, balanced by size.
    pub owned: Vec<Vec<usize>>,
}

impl Plan {
    pub(super) fn new(shape: &NetShape, threads: usize) -> Self {
        let threads = threads.max(1);
        let groups = if threads == 1 {
            [vec![0], vec![0]]
        } else {
            [
                (0..threads).step_by(2).collect(),
                (1..threads).step_by(2).collect(),
            ]
        };
        let parts: Vec<Part> = Net::BOTH
            .into_iter()
            .flat_map(|net| {
                let span = net.range(shape);
                (span.start..span.end).step_by(PART).map(move |at| Part {
                    net,
                    range: at..(at + PART).min(span.end),
                })
            })
            .collect();
        let mut owned = vec![Vec::new(); threads];
        let mut load = vec![0usize; threads];
        for (p, part) in parts.iter().enumerate() {
            let group = &groups[part.net as usize];
            let w = group.iter().copied().min_by_key(|&w| load[w]).unwrap_or(0);
            load[w] += part.range.len();
            owned[w].push(p);
        }
        Self {
            groups,
            parts,
            owned,
        }
    }

    /// The worker that computes shard `s` of `net`.
    pub(super) fn worker(&self, net: Net, s: usize) -> usize {
        let group = &self.groups[net as usize];
        group[s % group.len()]
    }

    /// Whether worker `w` computes shards of `net` (and so needs its parameters).
    pub(super) fn computes(&self, w: usize, net: Net) -> bool {
        self.groups[net as usize].contains(&w)
    }

    /// Whether other workers than a part's owner need `net`'s parameters.
    pub(super) fn shared(&self, net: Net) -> bool {
        self.groups[net as usize].len() > 1
    }

    /// Whether any network has more than one worker.
    pub(super) fn shares_any(&self) -> bool {
        Net::BOTH.into_iter().any(|net| self.shared(net))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use common::policy::PolicyLayout;
    use common::{ACT_DIM, OBS_DIM};

    /// Every part has one owner, in its network's group; two threads split the networks,
    /// four split each network's parts about evenly; parts cover the vector in order.
    #[test]
    fn networks_go_to_groups_and_parts_to_one_owner_each() {
        let shape = NetShape::new(&PolicyLayout::new(OBS_DIM, &[128, 128], ACT_DIM));
        for threads in 1..=4 {
            let plan = Plan::new(&shape, threads);
            let mut all: Vec<usize> = plan.owned.concat();
            all.sort_unstable();
            assert_eq!(all, (0..plan.parts.len()).collect::<Vec<_>>());
            for (w, parts) in plan.owned.iter().enumerate() {
                for &p in parts {
                    assert!(
                        plan.computes(w, plan.parts[p].net),
                        "{threads}: {w} owns {p}"
                    );
                }
            }
            let ends: Vec<usize> = plan.parts.iter().map(|p| p.range.end).collect();
            let starts: Vec<usize> = plan.parts.iter().map(|p| p.range.start).collect();
            assert_eq!(starts[0], 0);
            assert_eq!(&starts[1..], &ends[..ends.len() - 1]);
            assert_eq!(*ends.last().expect("parts"), shape.len());
        }
        let two = Plan::new(&shape, 2);
        assert_eq!(
            (two.worker(Net::Actor, 1), two.worker(Net::Critic, 0)),
            (0, 1)
        );
        assert!(!two.shares_any() && !Plan::new(&shape, 1).shares_any());
        let four = Plan::new(&shape, 4);
        let load = |w: usize| -> usize {
            four.owned[w]
                .iter()
                .map(|&p| four.parts[p].range.len())
                .sum()
        };
        assert!(
            load(0).abs_diff(load(2)) <= 2048,
            "{} vs {}",
            load(0),
            load(2)
        );
        assert_eq!(
            (four.worker(Net::Critic, 0), four.worker(Net::Critic, 1)),
            (1, 3)
        );
        assert!(four.shared(Net::Actor) && four.shares_any());
    }
}
