//! The two ends of a slice channel: a sender that wakes its readers, rationed if asked, and
//! a receiver that sleeps until woken.

use super::{IpcError, Svc, ipc_err};
use iceoryx2::port::listener::Listener;
use iceoryx2::port::notifier::Notifier;
use iceoryx2::port::publisher::Publisher;
use iceoryx2::port::subscriber::Subscriber;
use iceoryx2::port::update_connections::UpdateConnections;
use iceoryx2::prelude::*;
use iceoryx2::sample::Sample;
use std::cell::Cell;
use std::fmt::Debug;
use std::time::{Duration, Instant};

/// Publishing side of a slice channel.
pub struct Sender<
    T: Debug + Copy + ZeroCopySend + 'static,
    H: Debug + Copy + ZeroCopySend + 'static,
> {
    publisher: Publisher<Svc, [T], H>,
    notifier: Notifier<Svc>,
    name: String,
    wake: Wake,
}

/// When a sender wakes its readers: on every send, or at most once per `interval` with the
/// sends in between left `pending` until the next wake-up or [`Sender::flush`].
#[derive(Debug, Default)]
struct Wake {
    interval: Duration,
    last: Cell<Option<Instant>>,
    pending: Cell<bool>,
}

impl Wake {
    /// Whether a send now wakes the readers; records it either way. Reads the clock only
    /// when wake-ups are rationed.
    fn due(&self) -> bool {
        if self.interval.is_zero() {
            return true;
        }
        let now = Instant::now();
        let due = self
            .last
            .get()
            .is_none_or(|last| now.duration_since(last) >= self.interval);
        if due {
            self.last.set(Some(now));
        }
        self.pending.set(!due);
        due
    }
}

impl<T, H> Sender<T, H>
where
    T: Debug + Copy + Default + ZeroCopySend + 'static,
    H: Debug + Copy + Default + ZeroCopySend + 'static,
{
    /// Wakes on every send until [`with_wake_interval`](Self::with_wake_interval).
    pub(super) fn new(
        publisher: Publisher<Svc, [T], H>,
        notifier: Notifier<Svc>,
        name: String,
    ) -> Self {
        Self {
            publisher,
            notifier,
            name,
            wake: Wake::default(),
        }
    }

    /// Connects subscribers that arrived since the last send and hands them the history.
    /// iceoryx2 does this only when the publisher acts, so a publisher that has sent once and
    /// then waits (a learner before its first rollout) must call this while idle, or a late
    /// subscriber never sees the message it is waiting for.
    pub fn update_connections(&self) -> Result<(), IpcError> {
        self.publisher
            .update_connections()
            .map_err(|e| ipc_err(format!("update connections of `{}`", self.name))(&e))
    }

    /// Wakes the readers at most once per `interval` instead of on every send (0: every
    /// send). Samples are delivered as always; a reader that sleeps sees them at the next
    /// wake-up, so a sender that goes quiet must [`flush`](Self::flush) first.
    pub fn with_wake_interval(mut self, interval: Duration) -> Self {
        self.wake.interval = interval;
        self
    }

    /// Wakes the readers if a send since the last wake-up did not.
    pub fn flush(&self) -> Result<(), IpcError> {
        if self.wake.pending.replace(false) {
            self.wake.last.set(Some(Instant::now()));
            self.notify()?;
        }
        Ok(())
    }

    fn notify(&self) -> Result<(), IpcError> {
        self.notifier
            .notify()
            .map(drop)
            .map_err(|e| ipc_err(format!("notify on `{}`", self.name))(&e))
    }

    /// Copies `data` into a loaned shared-memory sample, sends it and wakes the readers (see
    /// [`with_wake_interval`](Self::with_wake_interval)).
    pub fn send(&self, header: H, data: &[T]) -> Result<(), IpcError> {
        let mut sample = self
            .publisher
            .loan_slice_uninit(data.len())
            .map_err(|e| ipc_err(format!("loan on `{}`", self.name))(&e))?;
        *sample.user_header_mut() = header;
        let sample = sample.write_from_slice(data);
        sample
            .send()
            .map_err(|e| ipc_err(format!("send on `{}`", self.name))(&e))?;
        if self.wake.due() {
            self.notify()?;
        }
        Ok(())
    }
}

/// Receiving side of a slice channel.
pub struct Receiver<
    T: Debug + Copy + ZeroCopySend + 'static,
    H: Debug + Copy + ZeroCopySend + 'static,
> {
    subscriber: Subscriber<Svc, [T], H>,
    listener: Listener<Svc>,
    name: String,
}

/// A received sample: header and slice, read in place from shared memory.
pub type Received<T, H> = Sample<Svc, [T], H>;

impl<T: Debug + Copy + ZeroCopySend + 'static, H: Debug + Copy + ZeroCopySend + 'static>
    Receiver<T, H>
{
    pub(super) fn new(
        subscriber: Subscriber<Svc, [T], H>,
        listener: Listener<Svc>,
        name: String,
    ) -> Self {
        Self {
            subscriber,
            listener,
            name,
        }
    }

    /// The next buffered sample, if any (never blocks).
    pub fn try_recv(&self) -> Result<Option<Received<T, H>>, IpcError> {
        self.subscriber
            .receive()
            .map_err(|e| ipc_err(format!("receive on `{}`", self.name))(&e))
    }

    /// The newest buffered sample, dropping older ones.
    pub fn latest(&self) -> Result<Option<Received<T, H>>, IpcError> {
        let mut last = None;
        while let Some(s) = self.try_recv()? {
            last = Some(s);
        }
        Ok(last)
    }

    /// The event listener, to attach to a [`WaitSet`].
    pub fn listener(&self) -> &Listener<Svc> {
        &self.listener
    }

    /// Sleeps until a writer signals or `timeout` passes; consumes the pending signals. A
    /// signal (SIGINT, SIGTERM) ends the wait early without an error: callers check
    /// [`Bus::stop_requested`](super::Bus::stop_requested).
    pub fn wait(&self, timeout: Duration) -> Result<(), IpcError> {
        match self.listener.timed_wait(|_| {}, timeout) {
            Ok(_) | Err(iceoryx2::port::listener::ListenerWaitError::InterruptSignal) => Ok(()),
            Err(e) => Err(ipc_err(format!("wait on `{}`", self.name))(&e)),
        }
    }
}
