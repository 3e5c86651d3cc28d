//! A process's node in a run, and the services it opens there.

use super::{Channel, IpcError, Receiver, Sender, Svc, ipc_err, run_config, validate_run_id};
use iceoryx2::prelude::*;
use std::fmt::Debug;

/// One process's connection to a run's services.
pub struct Bus {
    node: Node<Svc>,
    run: String,
}

impl Bus {
    /// Creates this process's node in run `run`; `who` names the node (`sim`, `learner`, …).
    pub fn connect(run: &str, who: &str) -> Result<Self, IpcError> {
        validate_run_id(run).map_err(|reason| IpcError {
            what: "run id".into(),
            reason,
        })?;
        let cfg = run_config(run)?;
        let name: NodeName = who.try_into().map_err(|e| ipc_err("node name")(&e))?;
        let node = NodeBuilder::new()
            .name(&name)
            .config(&cfg)
            .signal_handling_mode(SignalHandlingMode::HandleTerminationRequests)
            .create::<Svc>()
            .map_err(|e| ipc_err(format!("create node `{who}`"))(&e))?;
        // A process killed with SIGKILL leaves its node behind; whoever starts next cleans up.
        node.try_cleanup_dead_nodes();
        Ok(Self {
            node,
            run: run.to_string(),
        })
    }

    pub fn node(&self) -> &Node<Svc> {
        &self.node
    }

    pub fn run(&self) -> &str {
        &self.run
    }

    /// `lavatube/<run>/<service>[/<sub>]`.
    pub fn service_name(&self, service: &str, sub: Option<&str>) -> Result<ServiceName, IpcError> {
        let s = match sub {
            Some(sub) => format!("lavatube/{}/{service}/{sub}", self.run),
            None => format!("lavatube/{}/{service}", self.run),
        };
        s.as_str()
            .try_into()
            .map_err(|e| ipc_err(format!("service name `{s}`"))(&e))
    }

    pub(super) fn event(
        &self,
        name: &ServiceName,
    ) -> Result<iceoryx2::service::port_factory::event::PortFactory<Svc>, IpcError> {
        let ready = format!("{name}.ready");
        let ready: ServiceName = ready
            .as_str()
            .try_into()
            .map_err(|e| ipc_err("event name")(&e))?;
        self.node
            .service_builder(&ready)
            .event()
            .max_notifiers(8)
            .max_listeners(16)
            .open_or_create()
            .map_err(|e| ipc_err(format!("open event `{ready}`"))(&e))
    }

    fn pubsub<T, H>(
        &self,
        channel: &Channel<T, H>,
        name: &ServiceName,
    ) -> Result<
        iceoryx2::service::port_factory::publish_subscribe::PortFactory<Svc, [T], H>,
        IpcError,
    >
    where
        T: Debug + Copy + ZeroCopySend + 'static,
        H: Debug + Copy + Default + ZeroCopySend + 'static,
    {
        self.node
            .service_builder(name)
            .publish_subscribe::<[T]>()
            .user_header::<H>()
            .enable_safe_overflow(true)
            .subscriber_max_buffer_size(channel.capacity.buffer)
            .history_size(channel.capacity.history)
            .max_publishers(channel.capacity.publishers)
            .max_subscribers(channel.capacity.subscribers)
            .max_nodes(32)
            .open_or_create()
            .map_err(|e| open_error::<T, H>(name, &e))
    }

    /// A publisher on `channel`'s service (`sub` picks e.g. a policy slot).
    pub fn sender<T, H>(
        &self,
        channel: &Channel<T, H>,
        sub: Option<&str>,
        max_len: usize,
    ) -> Result<Sender<T, H>, IpcError>
    where
        T: Debug + Copy + Default + ZeroCopySend + 'static,
        H: Debug + Copy + Default + ZeroCopySend + 'static,
    {
        let name = self.service_name(channel.service, sub)?;
        let publisher = self
            .pubsub(channel, &name)?
            .publisher_builder()
            .initial_max_slice_len(max_len.max(1))
            .allocation_strategy(AllocationStrategy::PowerOfTwo)
            .create()
            .map_err(|e| ipc_err(format!("publisher on `{name}`"))(&e))?;
        let notifier = self
            .event(&name)?
            .notifier_builder()
            .create()
            .map_err(|e| ipc_err(format!("notifier on `{name}`"))(&e))?;
        Ok(Sender::new(publisher, notifier, name.to_string()))
    }

    /// A subscriber on `channel`'s service.
    pub fn receiver<T, H>(
        &self,
        channel: &Channel<T, H>,
        sub: Option<&str>,
    ) -> Result<Receiver<T, H>, IpcError>
    where
        T: Debug + Copy + ZeroCopySend + 'static,
        H: Debug + Copy + Default + ZeroCopySend + 'static,
    {
        let name = self.service_name(channel.service, sub)?;
        let subscriber = self
            .pubsub(channel, &name)?
            .subscriber_builder()
            .create()
            .map_err(|e| ipc_err(format!("subscriber on `{name}`"))(&e))?;
        let listener = self
            .event(&name)?
            .listener_builder()
            .create()
            .map_err(|e| ipc_err(format!("listener on `{name}`"))(&e))?;
        Ok(Receiver::new(subscriber, listener, name.to_string()))
    }

    /// Removes the resources of the run's dead nodes (processes killed with SIGKILL), so their
    /// ports stop counting against the services' limits. Returns how many nodes were removed.
    pub fn cleanup_dead_nodes(&self) -> usize {
        self.node.try_cleanup_dead_nodes().cleanups as usize
    }
}

/// The error for a service that could not be opened. A layout mismatch gets its own message:
/// the other side was built from a different version of the wire types, and this process
/// must not join (the processes already connected are unaffected).
fn open_error<T, H>(
    name: &ServiceName,
    e: &iceoryx2::service::builder::publish_subscribe::PublishSubscribeOpenOrCreateError,
) -> IpcError {
    use iceoryx2::service::builder::publish_subscribe::{
        PublishSubscribeOpenError as Open, PublishSubscribeOpenOrCreateError as Either,
    };
    match e {
        Either::PublishSubscribeOpenError(Open::IncompatibleTypes) => IpcError {
            what: format!("open service `{name}`"),
            reason: format!(
                "the run's processes use a different version of its message types (this one: `[{}]` with header `{}`); build every process from one checkout",
                std::any::type_name::<T>(),
                std::any::type_name::<H>()
            ),
        },
        e => ipc_err(format!("open service `{name}`"))(e),
    }
}
