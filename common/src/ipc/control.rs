//! The control channel: the launcher asks every process of a run to stop.

use super::{Bus, IpcError, Svc, ipc_err};
use iceoryx2::port::listener::Listener;
use iceoryx2::port::notifier::Notifier;
use iceoryx2::prelude::*;
use std::time::Duration;

/// Control event ids (launcher → every process).
pub const CONTROL_SHUTDOWN: usize = 1;

impl Bus {
    /// Whether this process should stop: a shutdown on the control channel, or SIGINT/SIGTERM
    /// (iceoryx2 catches them so the process can finish its current step cleanly).
    pub fn stop_requested(&self, control: &Listener<Svc>) -> bool {
        shutdown_requested(control) || self.node().wait(Duration::ZERO).is_err()
    }

    /// The launcher's side of the control channel.
    pub fn control_notifier(&self) -> Result<Notifier<Svc>, IpcError> {
        let name = self.service_name("control", None)?;
        self.event(&name)?
            .notifier_builder()
            .create()
            .map_err(|e| ipc_err("control notifier")(&e))
    }

    /// A process's side of the control channel.
    pub fn control_listener(&self) -> Result<Listener<Svc>, IpcError> {
        let name = self.service_name("control", None)?;
        self.event(&name)?
            .listener_builder()
            .create()
            .map_err(|e| ipc_err("control listener")(&e))
    }
}

/// Asks every process of the run to shut down.
pub fn request_shutdown(control: &Notifier<Svc>) -> Result<(), IpcError> {
    control
        .notify_with_custom_event_id(EventId::new(CONTROL_SHUTDOWN))
        .map(|_| ())
        .map_err(|e| ipc_err("request shutdown")(&e))
}

/// Whether a shutdown was requested on the control listener (drains it).
pub fn shutdown_requested(control: &Listener<Svc>) -> bool {
    let mut stop = false;
    let _ = control.try_wait(|id| stop |= id.id.as_value() == CONTROL_SHUTDOWN);
    stop
}
