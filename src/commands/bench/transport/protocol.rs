//! What both ends of the transport comparison agree on: the stamp every message carries and
//! its flags, the channels, the payload kinds, the pacing and the latencies the echo reports.

use anyhow::bail;
use common::Transition;
use common::ipc::{Capacity, Channel};
use common::wire::EnvTick;
use iceoryx2::prelude::ZeroCopySend;
use serde::{Deserialize, Serialize};
use std::time::Duration;

/// The header of every bench message on both transports. Local to the launcher (it is both
/// ends), so it lives here rather than in `common::wire`.
#[derive(Debug, Clone, Copy, Default, PartialEq, ZeroCopySend)]
#[repr(C)]
#[type_name("lavatube.BenchStamp.v1")]
pub struct Stamp {
    pub seq: u64,
    /// [`common::wire::monotonic_ns`] just before the send.
    pub sent_ns: u64,
    pub test: u32,
    /// Bits `RECORD`, `ACK`, `CONTROL`, `OVER_SOCKET`; payload kind in bits 8–15 of a control frame.
    pub flags: u32,
}

/// The receiver records this message's one-way latency.
pub(super) const RECORD: u32 = 1;
/// The receiver acknowledges after this message (with the count received so far).
pub(super) const ACK: u32 = 2;
/// A control frame (socket only): a test starts; `seq` is its message count.
pub(super) const CONTROL: u32 = 4;
/// Control: the test runs over the socket, not iceoryx2.
pub(super) const OVER_SOCKET: u32 = 8;

/// Messages in flight in the throughput phase, and how often the receiver acknowledges.
pub(super) const WINDOW: u64 = 16;
pub(super) const ACK_EVERY: u64 = 4;
/// No progress for this long fails the comparison (a dead or stuck partner).
pub(super) const TIMEOUT: Duration = Duration::from_secs(60);

/// The bench channels: room for a whole window, one writer, one reader.
const fn channel<T>(service: &'static str) -> Channel<T, Stamp> {
    Channel::new(
        service,
        Capacity {
            buffer: 2 * WINDOW as usize,
            history: 0,
            publishers: 1,
            subscribers: 1,
        },
    )
}
pub(super) const TELEMETRY: Channel<EnvTick, Stamp> = channel("bench/telemetry");
pub(super) const ROLLOUT: Channel<Transition, Stamp> = channel("bench/rollout");
pub(super) const WEIGHTS: Channel<f32, Stamp> = channel("bench/weights");
pub(super) const ACKS: Channel<u64, Stamp> = channel("bench/acks");

/// Which message of the runtime a payload copies.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Kind {
    /// One telemetry tick: `N` [`EnvTick`]s.
    Telemetry,
    /// One rollout chunk: `T × N + N` [`Transition`]s.
    Rollout,
    /// One policy: the flat actor's `f32` weights.
    Weights,
}

impl Kind {
    pub fn name(self) -> &'static str {
        match self {
            Kind::Telemetry => "telemetry",
            Kind::Rollout => "rollout chunk",
            Kind::Weights => "weights",
        }
    }

    pub(super) fn code(self) -> u32 {
        match self {
            Kind::Telemetry => 0,
            Kind::Rollout => 1,
            Kind::Weights => 2,
        }
    }

    pub(super) fn from_code(c: u32) -> anyhow::Result<Self> {
        Ok(match c {
            0 => Kind::Telemetry,
            1 => Kind::Rollout,
            2 => Kind::Weights,
            _ => bail!("unknown payload kind {c}"),
        })
    }

    pub(super) fn element_bytes(self) -> usize {
        match self {
            Kind::Telemetry => size_of::<EnvTick>(),
            Kind::Rollout => size_of::<Transition>(),
            Kind::Weights => size_of::<f32>(),
        }
    }
}

/// Latencies the echo recorded in one latency phase.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Latency {
    pub count: usize,
    pub p50_us: f64,
    pub p99_us: f64,
}
