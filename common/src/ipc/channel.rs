//! Typed service descriptors: a channel names its service, sizes it and fixes the types its
//! samples carry, so every process opens a service with the same element and header types
//! (the compiler refuses any other) and the same limits.

use crate::rollout::Transition;
use crate::wire::{
    EnvTick, GymActHeader, GymEnvStep, GymStepHeader, HostsHeader, PolicyHeader, RolloutHeader,
    SimHost, TerrainEstimate, TerrainHeader, TickHeader,
};
use std::fmt;
use std::marker::PhantomData;

/// How a channel's service is sized. Every process opening the service uses the same one.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Capacity {
    /// Samples a subscriber buffers; the oldest is overwritten when full.
    pub buffer: usize,
    /// Samples a late subscriber receives on connecting.
    pub history: usize,
    pub publishers: usize,
    pub subscribers: usize,
}

/// A publish-subscribe service whose samples are a slice of `T` under a header `H`, opened
/// with [`Bus::sender`](super::Bus::sender) and [`Bus::receiver`](super::Bus::receiver).
pub struct Channel<T, H> {
    /// The service's name under the run, `lavatube/<run>/<service>`.
    pub service: &'static str,
    pub capacity: Capacity,
    /// Only names the types; a function pointer so that a channel is `Send`, `Sync` and
    /// `Copy` whatever they are.
    types: PhantomData<fn() -> (T, H)>,
}

impl<T, H> Channel<T, H> {
    pub const fn new(service: &'static str, capacity: Capacity) -> Self {
        Self {
            service,
            capacity,
            types: PhantomData,
        }
    }
}

// By hand: derives would ask `T` and `H` to be `Clone` and `Debug` too.
impl<T, H> Clone for Channel<T, H> {
    fn clone(&self) -> Self {
        *self
    }
}

impl<T, H> Copy for Channel<T, H> {}

impl<T, H> fmt::Debug for Channel<T, H> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("Channel")
            .field("service", &self.service)
            .field("capacity", &self.capacity)
            .field("element", &std::any::type_name::<T>())
            .field("header", &std::any::type_name::<H>())
            .finish()
    }
}

/// sim → learner: T × N transitions plus N bootstrap observations.
pub const ROLLOUT: Channel<Transition, RolloutHeader> = Channel::new(
    "rollout",
    Capacity {
        buffer: 8,
        history: 0,
        publishers: 2,
        subscribers: 8,
    },
);
/// learner → sim: the latest weights of one slot (history 1: a late subscriber gets them).
pub const POLICY: Channel<f32, PolicyHeader> = Channel::new(
    "policy",
    Capacity {
        buffer: 2,
        history: 1,
        publishers: 2,
        subscribers: 8,
    },
);
/// sim → estimator, recorders, monitors: one tick of every env.
pub const TELEMETRY: Channel<EnvTick, TickHeader> = Channel::new(
    "telemetry",
    Capacity {
        buffer: 64,
        history: 0,
        publishers: 2,
        subscribers: 8,
    },
);
/// estimator → sim, monitors: per-env terrain class.
pub const TERRAIN: Channel<TerrainEstimate, TerrainHeader> = Channel::new(
    "terrain",
    Capacity {
        buffer: 4,
        history: 1,
        publishers: 2,
        subscribers: 8,
    },
);
/// learner host's bridge → `lavatube status`: the sim hosts it hears (DESIGN §9).
pub const HOSTS: Channel<SimHost, HostsHeader> = Channel::new(
    "hosts",
    Capacity {
        buffer: 2,
        history: 1,
        publishers: 1,
        subscribers: 8,
    },
);
/// gym client → sim (`sim.acting = "external"`): a step's actions, a reset or a close.
pub const GYM_ACT: Channel<f32, GymActHeader> = Channel::new(
    "gym/act",
    Capacity {
        buffer: 4,
        history: 0,
        publishers: 2,
        subscribers: 1,
    },
);
/// sim → gym client: every env after a reset or a step (history 1: a client that connects
/// reads the envs and the action limit from the newest message).
pub const GYM_STEP: Channel<GymEnvStep, GymStepHeader> = Channel::new(
    "gym/step",
    Capacity {
        buffer: 4,
        history: 1,
        publishers: 1,
        subscribers: 2,
    },
);
