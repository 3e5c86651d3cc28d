//! iceoryx2 plumbing shared by every process: one node per process with a per-run config,
//! the run's service names (`lavatube/<run>/<service>`), and typed slice channels, each a
//! publish-subscribe service paired with an event service so readers sleep until data comes.
//!
//! Ports of the `ipc` service type hold an `Rc`: keep all of a process's ports on one thread.

use crate::wire::{SwapReply, SwapRequest};
use iceoryx2::node::NodeView;
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

pub type Svc = ipc::Service;

/// An iceoryx2 operation failed; says which and why.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("shared memory: {what}: {reason}")]
pub struct IpcError {
    pub what: String,
    pub reason: String,
}

fn ipc_err(what: impl Into<String>) -> impl FnOnce(&dyn Debug) -> IpcError {
    let what = what.into();
    move |e| IpcError {
        what,
        reason: format!("{e:?}"),
    }
}

/// Checks a run id: 1–32 characters of `[A-Za-z0-9-]` (it becomes part of file names, where
/// `_` separates it from the rest).
pub fn validate_run_id(run: &str) -> Result<(), String> {
    let ok = !run.is_empty()
        && run.len() <= 32
        && run.bytes().all(|b| b.is_ascii_alphanumeric() || b == b'-');
    if ok {
        Ok(())
    } else {
        Err(format!(
            "run id `{run}` must be 1–32 characters of A-Z a-z 0-9 -"
        ))
    }
}

/// The file-name prefix of every shared-memory resource of run `run`, so one run's resources
/// are easy to find, list and remove, and two runs never collide.
pub fn resource_prefix(run: &str) -> String {
    format!("lavatube_{run}_")
}

/// The iceoryx2 config of a run, set in code (the config file is otherwise searched relative
/// to the current directory).
pub fn run_config(run: &str) -> Result<iceoryx2::config::Config, IpcError> {
    let mut cfg = iceoryx2::config::Config::default();
    cfg.global.prefix = resource_prefix(run)
        .as_str()
        .try_into()
        .map_err(|e| ipc_err("run prefix")(&e))?;
    Ok(cfg)
}

/// How a slice channel is set up. Every process opening a service uses the same spec.
#[derive(Debug, Clone, Copy)]
pub struct ChannelSpec {
    pub service: &'static str,
    /// Samples a subscriber buffers; the oldest is overwritten when full.
    pub buffer: usize,
    /// Samples a late subscriber receives on connecting.
    pub history: usize,
    pub publishers: usize,
    pub subscribers: usize,
}

/// sim → learner: T × N transitions plus N bootstrap observations.
pub const ROLLOUT: ChannelSpec = ChannelSpec {
    service: "rollout",
    buffer: 8,
    history: 0,
    publishers: 2,
    subscribers: 8,
};
/// learner → sim: the latest weights of one slot (history 1: a late subscriber gets them).
pub const POLICY: ChannelSpec = ChannelSpec {
    service: "policy",
    buffer: 2,
    history: 1,
    publishers: 2,
    subscribers: 8,
};
/// sim → estimator, recorders, monitors: one tick of every env.
pub const TELEMETRY: ChannelSpec = ChannelSpec {
    service: "telemetry",
    buffer: 64,
    history: 0,
    publishers: 2,
    subscribers: 8,
};
/// estimator → sim, monitors: per-env terrain class.
pub const TERRAIN: ChannelSpec = ChannelSpec {
    service: "terrain",
    buffer: 4,
    history: 1,
    publishers: 2,
    subscribers: 8,
};

/// Control event ids (launcher → every process).
pub const CONTROL_SHUTDOWN: usize = 1;

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

    /// Whether this process should stop: a shutdown on the control channel, or SIGINT/SIGTERM
    /// (iceoryx2 catches them so the process can finish its current step cleanly).
    pub fn stop_requested(&self, control: &Listener<Svc>) -> bool {
        shutdown_requested(control) || self.node.wait(Duration::ZERO).is_err()
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

    fn event(
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
        spec: &ChannelSpec,
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
            .subscriber_max_buffer_size(spec.buffer)
            .history_size(spec.history)
            .max_publishers(spec.publishers)
            .max_subscribers(spec.subscribers)
            .max_nodes(32)
            .open_or_create()
            .map_err(|e| open_error::<T, H>(name, &e))
    }

    /// A publisher on `spec`'s service (`sub` picks e.g. a policy slot).
    pub fn sender<T, H>(
        &self,
        spec: &ChannelSpec,
        sub: Option<&str>,
        max_len: usize,
    ) -> Result<Sender<T, H>, IpcError>
    where
        T: Debug + Copy + Default + ZeroCopySend + 'static,
        H: Debug + Copy + Default + ZeroCopySend + 'static,
    {
        let name = self.service_name(spec.service, sub)?;
        let publisher = self
            .pubsub::<T, H>(spec, &name)?
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
        Ok(Sender {
            publisher,
            notifier,
            name: name.to_string(),
            wake: Wake::default(),
        })
    }

    /// A subscriber on `spec`'s service.
    pub fn receiver<T, H>(
        &self,
        spec: &ChannelSpec,
        sub: Option<&str>,
    ) -> Result<Receiver<T, H>, IpcError>
    where
        T: Debug + Copy + ZeroCopySend + 'static,
        H: Debug + Copy + Default + ZeroCopySend + 'static,
    {
        let name = self.service_name(spec.service, sub)?;
        let subscriber = self
            .pubsub::<T, H>(spec, &name)?
            .subscriber_builder()
            .create()
            .map_err(|e| ipc_err(format!("subscriber on `{name}`"))(&e))?;
        let listener = self
            .event(&name)?
            .listener_builder()
            .create()
            .map_err(|e| ipc_err(format!("listener on `{name}`"))(&e))?;
        Ok(Receiver {
            subscriber,
            listener,
            name: name.to_string(),
        })
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
    /// [`Bus::stop_requested`].
    pub fn wait(&self, timeout: Duration) -> Result<(), IpcError> {
        match self.listener.timed_wait(|_| {}, timeout) {
            Ok(_) | Err(iceoryx2::port::listener::ListenerWaitError::InterruptSignal) => Ok(()),
            Err(e) => Err(ipc_err(format!("wait on `{}`", self.name))(&e)),
        }
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

/// Service ports of the `swap` request-response service (`lavatube swap-learner` → launcher).
pub type SwapServer = iceoryx2::port::server::Server<Svc, SwapRequest, (), SwapReply, ()>;
pub type SwapClient = iceoryx2::port::client::Client<Svc, SwapRequest, (), SwapReply, ()>;

impl Bus {
    fn swap_service(
        &self,
    ) -> Result<
        iceoryx2::service::port_factory::request_response::PortFactory<
            Svc,
            SwapRequest,
            (),
            SwapReply,
            (),
        >,
        IpcError,
    > {
        let name = self.service_name("swap", None)?;
        self.node
            .service_builder(&name)
            .request_response::<SwapRequest, SwapReply>()
            .open_or_create()
            .map_err(|e| ipc_err(format!("open service `{name}`"))(&e))
    }

    /// The launcher's side of `swap`.
    pub fn swap_server(&self) -> Result<SwapServer, IpcError> {
        self.swap_service()?
            .server_builder()
            .create()
            .map_err(|e| ipc_err("swap server")(&e))
    }

    /// `lavatube swap-learner`'s side of `swap`.
    pub fn swap_client(&self) -> Result<SwapClient, IpcError> {
        self.swap_service()?
            .client_builder()
            .create()
            .map_err(|e| ipc_err("swap client")(&e))
    }

    /// Removes the resources of the run's dead nodes (processes killed with SIGKILL), so their
    /// ports stop counting against the services' limits. Returns how many nodes were removed.
    pub fn cleanup_dead_nodes(&self) -> usize {
        self.node.try_cleanup_dead_nodes().cleanups as usize
    }
}

/// A node of a run, as `lavatube status` shows it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct NodeInfo {
    pub name: String,
    pub pid: i32,
    pub alive: bool,
}

/// The nodes registered in run `run`, alive or dead.
pub fn list_nodes(run: &str) -> Result<Vec<NodeInfo>, IpcError> {
    let cfg = run_config(run)?;
    let mut out = Vec::new();
    Node::<Svc>::list(&cfg, |state| {
        let (view_details, alive) = match &state {
            NodeState::Alive(v) => (v.details().clone(), true),
            NodeState::Dead(v) => (v.details().clone(), false),
            NodeState::Inaccessible(_) | NodeState::Undefined(_) => (None, false),
        };
        if let Some(d) = view_details {
            out.push(NodeInfo {
                name: d.name().to_string(),
                pid: d.process_id().value(),
                alive,
            });
        }
        CallbackProgression::Continue
    })
    .map_err(|e| ipc_err(format!("list nodes of run `{run}`"))(&e))?;
    Ok(out)
}

/// Directories where iceoryx2 keeps files: the shared-memory mount and its root path.
fn resource_dirs() -> Vec<std::path::PathBuf> {
    let root = iceoryx2::config::Config::default()
        .global
        .root_path()
        .to_string();
    vec![
        std::path::PathBuf::from("/dev/shm"),
        std::path::PathBuf::from(root),
    ]
}

fn walk(dir: &std::path::Path, out: &mut Vec<std::path::PathBuf>) {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    for e in entries.flatten() {
        let p = e.path();
        if p.is_dir() {
            walk(&p, out);
        } else {
            out.push(p);
        }
    }
}

/// Every file of run `run` in the shared-memory mount and iceoryx2's root path.
pub fn run_files(run: &str) -> Vec<std::path::PathBuf> {
    let prefix = resource_prefix(run);
    let mut all = Vec::new();
    for d in resource_dirs() {
        walk(&d, &mut all);
    }
    all.retain(|p| {
        p.file_name()
            .is_some_and(|n| n.to_string_lossy().starts_with(&prefix))
    });
    all
}

/// Run ids that have files left, from their file names.
pub fn runs_with_files() -> Vec<String> {
    let mut all = Vec::new();
    for d in resource_dirs() {
        walk(&d, &mut all);
    }
    let mut runs: Vec<String> = all
        .iter()
        .filter_map(|p| {
            let name = p.file_name()?.to_string_lossy().into_owned();
            let rest = name.strip_prefix("lavatube_")?;
            Some(rest.split('_').next()?.to_string())
        })
        .collect();
    runs.sort();
    runs.dedup();
    runs
}

/// Removes run `run`'s shared-memory resources: dead nodes' through iceoryx2, then any file
/// left with the run's prefix. Refuses while a node of the run is alive. Returns the number
/// of files removed.
pub fn remove_run(run: &str) -> Result<usize, IpcError> {
    let cfg = run_config(run)?;
    let nodes = list_nodes(run)?;
    if let Some(n) = nodes.iter().find(|n| n.alive) {
        return Err(IpcError {
            what: format!("clean run `{run}`"),
            reason: format!("node `{}` (pid {}) is still alive", n.name, n.pid),
        });
    }
    Node::<Svc>::list(&cfg, |state| {
        if let NodeState::Dead(v) = state {
            let _ = v.try_remove_stale_resources();
        }
        CallbackProgression::Continue
    })
    .map_err(|e| ipc_err(format!("list nodes of run `{run}`"))(&e))?;
    let files = run_files(run);
    let mut removed = 0;
    for f in &files {
        if std::fs::remove_file(f).is_ok() {
            removed += 1;
        }
    }
    Ok(removed)
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn run_ids_are_checked() {
        assert!(validate_run_id("run-1a").is_ok());
        assert!(validate_run_id("run_1").is_err());
        assert!(validate_run_id("").is_err());
        assert!(validate_run_id("a/b").is_err());
        assert!(validate_run_id(&"x".repeat(33)).is_err());
    }

    #[test]
    fn a_shutdown_request_reaches_a_listener() {
        let run = format!("c{}", std::process::id());
        let bus = Bus::connect(&run, "test").expect("node");
        // The launcher's notifier exists before the processes' listeners.
        let notifier = bus.control_notifier().expect("notifier");
        let listener = bus.control_listener().expect("listener");
        assert!(!bus.stop_requested(&listener));
        request_shutdown(&notifier).expect("notify");
        assert!(bus.stop_requested(&listener));
        drop((notifier, listener, bus));
        remove_run(&run).expect("clean");
    }

    #[test]
    fn a_late_subscriber_gets_the_last_policy_once_the_publisher_updates() {
        let run = format!("h{}", std::process::id());
        let bus = Bus::connect(&run, "test").expect("node");
        let tx: Sender<f32, crate::wire::PolicyHeader> =
            bus.sender(&POLICY, Some("general"), 3).expect("sender");
        let header = crate::wire::PolicyHeader {
            version: 4,
            ..Default::default()
        };
        tx.send(header, &[1.0, 2.0, 3.0]).expect("send");
        // The sim connects after the learner published, then the learner idles.
        let rx: Receiver<f32, crate::wire::PolicyHeader> =
            bus.receiver(&POLICY, Some("general")).expect("receiver");
        tx.update_connections().expect("update");
        let s = rx
            .latest()
            .expect("receive")
            .expect("history delivers the last policy");
        assert_eq!(
            (s.user_header().version, s.payload()),
            (4, &[1.0f32, 2.0, 3.0][..])
        );
        drop((s, rx, tx, bus));
        remove_run(&run).expect("clean");
    }

    #[test]
    fn a_slice_with_its_header_crosses_a_channel() {
        let run = format!("t{}", std::process::id());
        let bus = Bus::connect(&run, "test").expect("node");
        let rx: Receiver<u32, crate::wire::TickHeader> =
            bus.receiver(&TELEMETRY, None).expect("receiver");
        let tx: Sender<u32, crate::wire::TickHeader> =
            bus.sender(&TELEMETRY, None, 4).expect("sender");
        let header = crate::wire::TickHeader {
            tick: 7,
            envs: 3,
            ..Default::default()
        };
        tx.send(header, &[1, 2, 3]).expect("send");
        rx.wait(Duration::from_secs(1)).expect("wait");
        let s = rx.try_recv().expect("receive").expect("a sample");
        assert_eq!((s.user_header().tick, s.payload()), (7, &[1u32, 2, 3][..]));
        // Longer than the initial max: the publisher grows its segment.
        tx.send(header, &[9; 100]).expect("send grown");
        assert_eq!(
            rx.latest()
                .expect("receive")
                .expect("a sample")
                .payload()
                .len(),
            100
        );
        drop(s);
        let nodes = list_nodes(&run).expect("list");
        assert_eq!(nodes.len(), 1);
        assert!(nodes[0].alive && nodes[0].name == "test");
        assert!(remove_run(&run).is_err(), "refuses while a node is alive");
        drop((tx, rx, bus));
        assert!(
            !run_files(&run).is_empty(),
            "iceoryx2 keeps its global segment"
        );
        assert!(runs_with_files().contains(&run));
        remove_run(&run).expect("clean");
        assert!(run_files(&run).is_empty(), "{:?}", run_files(&run));
    }

    /// Wake-ups the listener has pending (drains them).
    fn wakeups<T, H>(rx: &Receiver<T, H>) -> usize
    where
        T: Debug + Copy + ZeroCopySend + 'static,
        H: Debug + Copy + ZeroCopySend + 'static,
    {
        let mut n = 0;
        rx.listener().try_wait(|_| n += 1).expect("try_wait");
        n
    }

    #[test]
    fn a_wake_interval_batches_wakeups_but_delivers_every_sample() {
        let run = format!("w{}", std::process::id());
        let bus = Bus::connect(&run, "test").expect("node");
        let rx: Receiver<u32, crate::wire::TickHeader> =
            bus.receiver(&TELEMETRY, None).expect("receiver");
        let interval = Duration::from_millis(200);
        let tx: Sender<u32, crate::wire::TickHeader> = bus
            .sender(&TELEMETRY, None, 1)
            .expect("sender")
            .with_wake_interval(interval);
        let send = |tick| {
            let h = crate::wire::TickHeader {
                tick,
                ..Default::default()
            };
            tx.send(h, &[tick as u32]).expect("send");
        };
        send(0);
        assert_eq!(wakeups(&rx), 1, "the first send wakes");
        send(1);
        send(2);
        assert_eq!(wakeups(&rx), 0, "sends within the interval do not");
        tx.flush().expect("flush");
        assert_eq!(wakeups(&rx), 1, "flush wakes for the pending sends");
        tx.flush().expect("flush");
        assert_eq!(wakeups(&rx), 0, "nothing pending, no wake-up");
        std::thread::sleep(interval);
        send(3);
        assert_eq!(wakeups(&rx), 1, "a send after the interval wakes");
        let mut ticks = Vec::new();
        while let Some(s) = rx.try_recv().expect("receive") {
            ticks.push(s.user_header().tick);
        }
        assert_eq!(ticks, [0, 1, 2, 3]);
        drop((tx, rx, bus));
        remove_run(&run).expect("clean");
    }
}
