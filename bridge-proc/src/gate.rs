//! Connections refused at the door (DESIGN §9): Zenoh's handshake turns away a peer without
//! the run's credentials before it can publish, subscribe or declare anything, so what it
//! sends never reaches the bridge as a frame. These are counted here instead, by kind, from
//! the events Zenoh's handshake emits when it refuses a link.
//!
//! The count is a layer beside the process's log ([`layer`]), with its own filter, so it
//! counts whatever `RUST_LOG` says; [`Door::take`] moves new counts into a [`Refusals`].

use common::refusals::Refusals;
use std::sync::atomic::{AtomicU64, Ordering};
use tracing_subscriber::Layer;
use tracing_subscriber::filter::{Filtered, Targets};

/// Where Zenoh (pinned exactly) reports a link it would not accept, at debug level.
const HANDSHAKE: &str = "zenoh_transport::unicast::establishment::accept";

/// Why a connection was refused.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Refusal {
    /// The peer showed no user and password at all.
    NoCredentials,
    /// The peer showed a user or password that is not this run's (another key file).
    WrongCredentials,
}

impl Refusal {
    const ALL: [Refusal; 2] = [Refusal::NoCredentials, Refusal::WrongCredentials];

    /// The kind as counted and logged.
    pub fn kind(self) -> &'static str {
        match self {
            Self::NoCredentials => "without credentials",
            Self::WrongCredentials => "with another run's credentials",
        }
    }

    /// The refusal a handshake failure's message describes; `None` for failures that are not
    /// about credentials (a peer that hung up, a version mismatch).
    pub fn of(message: &str) -> Option<Self> {
        if !message.contains("UsrPwd extension") {
            None
        } else if message.contains("Expected extension") {
            Some(Self::NoCredentials)
        } else {
            Some(Self::WrongCredentials)
        }
    }

    fn counter(self) -> &'static AtomicU64 {
        static NO: AtomicU64 = AtomicU64::new(0);
        static WRONG: AtomicU64 = AtomicU64::new(0);
        match self {
            Self::NoCredentials => &NO,
            Self::WrongCredentials => &WRONG,
        }
    }
}

/// Counts the refusals Zenoh's handshake reports in this process.
pub struct Counter;

/// The counting layer, filtered to Zenoh's handshake events: pass it to
/// [`common::logging::init_with`].
pub fn layer() -> Filtered<Counter, Targets, tracing_subscriber::Registry> {
    Counter.with_filter(Targets::new().with_target(HANDSHAKE, tracing::Level::DEBUG))
}

impl<S: tracing::Subscriber> Layer<S> for Counter {
    fn on_event(&self, event: &tracing::Event<'_>, _: tracing_subscriber::layer::Context<'_, S>) {
        let mut message = Message(String::new());
        event.record(&mut message);
        if let Some(r) = Refusal::of(&message.0) {
            r.counter().fetch_add(1, Ordering::Relaxed);
        }
    }
}

/// An event's `message` field as text.
struct Message(String);

impl tracing::field::Visit for Message {
    fn record_debug(&mut self, field: &tracing::field::Field, value: &dyn std::fmt::Debug) {
        if field.name() == "message" {
            self.0 = format!("{value:?}");
        }
    }
}

/// What this process has already moved into its refusals, per kind.
#[derive(Default)]
pub struct Door {
    taken: [u64; Refusal::ALL.len()],
}

impl Door {
    /// Adds the refusals counted since the last call to `refused` (which warns the first
    /// time of each kind).
    pub fn take(&mut self, refused: &mut Refusals) {
        for (i, r) in Refusal::ALL.into_iter().enumerate() {
            let now = r.counter().load(Ordering::Relaxed);
            refused.refuse_many(r.kind(), now - self.taken[i], "the Zenoh handshake");
            self.taken[i] = now;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The messages Zenoh 1.10.2's handshake logs, as a learner host's bridge recorded them.
    #[test]
    fn handshake_failures_are_told_apart_by_kind() {
        let none = "UsrPwd extension - Recv InitSyn. Expected extension. at src/unicast/establishment/ext/auth/usrpwd.rs:380.";
        let wrong = "UsrPwd extension - Recv OpenSyn. Invalid password. at usrpwd.rs:424.";
        let user = "UsrPwd extension - Recv OpenSyn. Invalid user. at usrpwd.rs:418.";
        assert_eq!(Refusal::of(none), Some(Refusal::NoCredentials));
        assert_eq!(Refusal::of(wrong), Some(Refusal::WrongCredentials));
        assert_eq!(Refusal::of(user), Some(Refusal::WrongCredentials));
        assert_eq!(
            Refusal::of("Received a close message (reason MAX_LINKS)"),
            None
        );
    }

    #[test]
    fn the_layer_counts_the_handshakes_refusals_whatever_the_log_level() {
        use tracing_subscriber::layer::SubscriberExt;
        let subscriber = tracing_subscriber::registry().with(layer());
        let mut refused = Refusals::new("connection");
        let mut door = Door::default();
        tracing::subscriber::with_default(subscriber, || {
            for _ in 0..3 {
                tracing::debug!(target: HANDSHAKE, "UsrPwd extension - Recv InitSyn. Expected extension.");
            }
            tracing::debug!(target: HANDSHAKE, "UsrPwd extension - Recv OpenSyn. Invalid password.");
            tracing::debug!(target: HANDSHAKE, "Received a close message");
            tracing::debug!("UsrPwd extension - Recv InitSyn. Expected extension.");
            door.take(&mut refused);
            tracing::debug!(target: HANDSHAKE, "UsrPwd extension - Recv OpenSyn. Invalid user.");
            door.take(&mut refused);
        });
        assert_eq!(refused.count(Refusal::NoCredentials.kind()), 3);
        assert_eq!(refused.count(Refusal::WrongCredentials.kind()), 2);
    }
}
