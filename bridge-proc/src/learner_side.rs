//! The learner host's bridge (DESIGN §9): republishes every sim host's rollout chunks on the
//! local `rollout` service, and forwards the local learners' policies to the sim hosts,
//! answering a sim host's query with the newest policy of each slot. It logs the sim hosts
//! as they join and leave (Zenoh liveliness) and what each sent, and publishes that table
//! every second on the local `hosts` service for `lavatube status`.

use crate::directions::{Counts, Stop, both_directions};
use crate::frame::{self, Key, Kind, Opener, Place, Sealer, Streams};
use crate::gate::Door;
use crate::link::{self, Net, zerr};
use common::config::PolicySlot;
use common::ipc::{self, Bus, Receiver, Sender};
use common::refusals::Refusals;
use common::wire::{HostsHeader, PolicyHeader, RolloutHeader, SimHost};
use common::{Config, Transition, rollout};
use std::collections::BTreeMap;
use std::time::{Duration, Instant};
use zenoh::Wait;
use zenoh::handlers::FifoChannel;
use zenoh::qos::CongestionControl;
use zenoh::sample::SampleKind;

/// Receives rollout chunks and forwards policies until the run stops this process.
pub fn run(cfg: &Config, run_id: &str, endpoint: &str) -> anyhow::Result<()> {
    let secret = cfg.net.read_key()?;
    let key = Key::new(&secret);
    let net = link::listen(endpoint, &link::Credentials::new(&secret))?;
    // This start's id: rollout frames must name it, so none sealed before it (of
    // another run, or of this one before the learner host restarted) is taken.
    let start = frame::new_id();
    let _token = net
        .liveliness()
        .declare_token(link::learner_token(start))
        .wait()
        .map_err(zerr("liveliness token"))?;
    tracing::info!(
        endpoint,
        start = format!("{start:016x}"),
        "learner host bridge listening"
    );
    let slots: Vec<PolicySlot> = cfg
        .run
        .learners
        .iter()
        .chain(cfg.run.frozen.keys())
        .copied()
        .collect();
    let (net2, key2, run) = (net.clone(), key.clone(), run_id.to_string());
    both_directions(
        "policies",
        move |stop| forward_policies(&run, &slots, &net2, (&key2, start), stop),
        |stop| receive_rollouts(cfg, run_id, &net, (&key, start), stop),
    )
}

fn forward_policies(
    run_id: &str,
    slots: &[PolicySlot],
    net: &Net,
    (key, start): (&Key, u64),
    stop: &Stop,
) -> anyhow::Result<()> {
    let bus = Bus::connect(run_id, "bridge-policies")?;
    let control = bus.control_listener()?;
    let mut ports = Vec::new();
    for &slot in slots {
        let rx: Receiver<f32, PolicyHeader> = bus.receiver(&ipc::POLICY, Some(slot.name()))?;
        let publisher = net
            .declare_publisher(link::policy_key(slot.name()))
            .congestion_control(CongestionControl::Block)
            .wait()
            .map_err(zerr("policy publisher"))?;
        // Each slot's frames are one stream, in this start's epoch.
        let sealer = Sealer::in_epoch(key, Kind::Policy, slot.index() as u32, start);
        ports.push((slot, rx, publisher, sealer));
    }
    let queries = net
        .declare_queryable(link::POLICY_ALL)
        .with(FifoChannel::new(16))
        .wait()
        .map_err(zerr("policy queryable"))?;
    // The newest frame of each slot, for a sim host that asks.
    let mut newest: BTreeMap<PolicySlot, Vec<u8>> = BTreeMap::new();
    let mut sent = Counts::default();
    while !stop.is_set() && !bus.stop_requested(&control) {
        if let Some((_, first, _, _)) = ports.first() {
            first.wait(Duration::from_millis(10))?;
        }
        for (slot, rx, publisher, sealer) in &mut ports {
            while let Some(sample) = rx.try_recv()? {
                let h = *sample.user_header();
                let bytes = sealer.seal(start, &h, sample.payload());
                sent.add(bytes.len());
                publisher
                    .put(bytes.clone())
                    .wait()
                    .map_err(|e| anyhow::anyhow!("policy version {} not sent: {e}", h.version))?;
                newest.insert(*slot, bytes);
            }
        }
        while let Some(query) = queries.try_recv().map_err(zerr("policy queryable"))? {
            for (slot, bytes) in &newest {
                query
                    .reply(link::policy_key(slot.name()), bytes.clone())
                    .wait()
                    .map_err(zerr("policy reply"))?;
            }
        }
    }
    tracing::info!(
        frames = sent.frames,
        bytes = sent.bytes,
        "policy frames forwarded"
    );
    Ok(())
}

/// How often the bridge logs what each sim host sent, and publishes it on `hosts`.
const LOG_EVERY: Duration = Duration::from_secs(10);
const PUBLISH_EVERY: Duration = Duration::from_secs(1);
/// Most sim hosts a `hosts` message lists (`net.sim-hosts` allows as many).
const MAX_HOSTS: usize = 1024;

/// How many frames each source may still send this second.
struct Budget {
    per_s: u32,
    second: Instant,
    used: BTreeMap<u32, u32>,
}

impl Budget {
    fn new(per_s: u32) -> Self {
        Self {
            per_s,
            second: Instant::now(),
            used: BTreeMap::new(),
        }
    }

    /// Whether `source` may send one more frame this second.
    fn take(&mut self, source: u32) -> bool {
        if self.second.elapsed() >= Duration::from_secs(1) {
            self.second = Instant::now();
            self.used.clear();
        }
        let used = self.used.entry(source).or_default();
        *used += 1;
        *used <= self.per_s
    }
}

/// What has come from one sim host.
#[derive(Debug, Default)]
struct Host {
    joined: bool,
    lost: u64,
    received: Counts,
    last_chunk: u64,
    env_steps: u64,
    /// `received` at the last log line.
    logged: Counts,
    /// `received` and `env_steps` at the last `hosts` message.
    published: (Counts, u64),
}

/// One line per sim host: chunks since the last line, rate, loss.
fn log_hosts(hosts: &mut BTreeMap<u32, Host>, secs: f64) {
    for (source, h) in hosts.iter_mut() {
        let frames = h.received.frames - h.logged.frames;
        let mb = (h.received.bytes - h.logged.bytes) as f64 / 1e6;
        tracing::info!(
            source,
            chunks = frames,
            last_chunk = h.last_chunk,
            mb_per_s = format!("{:.2}", mb / secs.max(1e-9)),
            lost = h.lost,
            joined = h.joined,
            "rollouts from sim host"
        );
        h.logged = h.received;
    }
}

/// The table of sim hosts, with their rates over the last `secs`.
fn publish_hosts(
    tx: &Sender<SimHost, HostsHeader>,
    hosts: &mut BTreeMap<u32, Host>,
    secs: f64,
) -> anyhow::Result<()> {
    let per_s = |x: u64| (x as f64 / secs.max(1e-9)) as f32;
    let table: Vec<SimHost> = hosts
        .iter_mut()
        .take(MAX_HOSTS)
        .map(|(&source, h)| {
            let (counts, steps) = h.published;
            h.published = (h.received, h.env_steps);
            SimHost {
                source,
                joined: u32::from(h.joined),
                chunks: h.received.frames,
                last_chunk: h.last_chunk,
                env_steps: h.env_steps,
                lost: h.lost,
                steps_per_s: per_s(h.env_steps.saturating_sub(steps)),
                bytes_per_s: per_s(h.received.bytes - counts.bytes),
            }
        })
        .collect();
    let header = HostsHeader {
        sent_ns: common::wire::monotonic_ns(),
        hosts: table.len() as u32,
        _reserved: 0,
    };
    tx.send(header, &table)?;
    Ok(())
}

/// Republishes the sim hosts' rollout chunks on the local `rollout` service until the run
/// stops this process or the other direction ends.
fn receive_rollouts(
    cfg: &Config,
    run_id: &str,
    net: &Net,
    (key, start): (&Key, u64),
    stop: &Stop,
) -> anyhow::Result<()> {
    let bus = Bus::connect(run_id, "bridge-rollouts")?;
    let control = bus.control_listener()?;
    let n = cfg.sim.num_envs();
    let max_len = cfg.ppo.rollout_steps(n) * n + n;
    let tx = bus.sender::<Transition, RolloutHeader>(&ipc::ROLLOUT, None, max_len)?;
    let hosts_tx = bus.sender::<SimHost, HostsHeader>(&ipc::HOSTS, None, MAX_HOSTS)?;
    let chunks = link::subscribe(net, link::ROLLOUT_ALL, 64)?;
    let sims = link::watch_tokens(net, link::SIM_ALL, 16)?;
    let mut intake = Intake {
        opener: Opener::new(key),
        start,
        streams: Streams::default(),
        budget: Budget::new(cfg.net.source_frames_per_s),
        max_len,
        tx,
        hosts_tx,
        hosts: BTreeMap::new(),
        refused: Refusals::new("rollout frame"),
        door: Door::default(),
        connections: Refusals::new("connection"),
        items: Vec::with_capacity(max_len),
        logged: Instant::now(),
        published: Instant::now(),
    };
    while !stop.is_set() && !bus.stop_requested(&control) {
        intake.report_hosts()?;
        while let Some(s) = sims.try_recv().map_err(zerr("liveliness"))? {
            intake.see_sim_host(s.key_expr().as_str(), s.kind() == SampleKind::Put);
        }
        let Some(sample) = chunks
            .recv_timeout(Duration::from_millis(50))
            .map_err(zerr("rollout subscriber"))?
        else {
            continue;
        };
        intake.take(sample.key_expr().as_str(), &sample.payload().to_bytes())?;
    }
    intake.finish();
    Ok(())
}

/// The rollout side of the learner host's bridge: where chunks go, and what each sim host
/// has sent.
struct Intake {
    opener: Opener,
    /// This start's id, which every rollout frame must name.
    start: u64,
    /// Which frames of each sim host's stream have come.
    streams: Streams,
    budget: Budget,
    /// The most transitions a chunk of this run holds.
    max_len: usize,
    tx: Sender<Transition, RolloutHeader>,
    hosts_tx: Sender<SimHost, HostsHeader>,
    hosts: BTreeMap<u32, Host>,
    refused: Refusals,
    door: Door,
    /// Connections the handshake refused, by kind.
    connections: Refusals,
    /// One chunk's elements, decoded into the same memory every time.
    items: Vec<Transition>,
    logged: Instant,
    published: Instant,
}

impl Intake {
    /// Logs the sim hosts every [`LOG_EVERY`] and publishes their table every
    /// [`PUBLISH_EVERY`].
    fn report_hosts(&mut self) -> anyhow::Result<()> {
        self.hosts_tx.update_connections()?;
        self.door.take(&mut self.connections);
        if self.logged.elapsed() >= LOG_EVERY {
            log_hosts(&mut self.hosts, self.logged.elapsed().as_secs_f64());
            self.logged = Instant::now();
        }
        if self.published.elapsed() >= PUBLISH_EVERY {
            let secs = self.published.elapsed().as_secs_f64();
            publish_hosts(&self.hosts_tx, &mut self.hosts, secs)?;
            self.published = Instant::now();
        }
        Ok(())
    }

    /// Notes a sim host's liveliness token `token` appearing (`joined`) or going away.
    fn see_sim_host(&mut self, token: &str, joined: bool) {
        let source = link::token_source(token);
        if joined {
            tracing::info!(?source, "sim host joined");
        } else {
            tracing::warn!(?source, "sim host gone; training goes on with the others");
        }
        if let Some(source) = source {
            self.hosts.entry(source).or_default().joined = joined;
        }
    }

    /// Takes one rollout frame published on `key_expr`: refuses it or republishes its chunk,
    /// and counts it in its sim host's stream.
    fn take(&mut self, key_expr: &str, bytes: &[u8]) -> anyhow::Result<()> {
        let Some(source) = key_expr
            .strip_prefix("lavatube/rollout/")
            .and_then(|s| s.parse::<u32>().ok())
        else {
            self.refused.refuse("malformed", &format!("key {key_expr}"));
            return Ok(());
        };
        // Read no further than each host's share: a flood is dropped before it costs a
        // decryption.
        if !self.budget.take(source) {
            self.refused
                .refuse("over the source's rate", &format!("source {source}"));
            return Ok(());
        }
        let f = match self
            .opener
            .open::<RolloutHeader, _>(Kind::Rollout, bytes, &mut self.items)
        {
            Ok(f) => f,
            Err(r) => {
                self.refused.refuse(r.kind, &r.detail);
                return Ok(());
            }
        };
        let stamp = f.stamp;
        if stamp.start != self.start {
            self.refused.refuse(
                "other start",
                &format!(
                    "sealed for start {:016x}, not this run's {:016x}",
                    stamp.start, self.start
                ),
            );
            return Ok(());
        }
        if stamp.source != source || f.header.source != source {
            self.refused.refuse(
                "source mismatch",
                &format!(
                    "on {key_expr}: frame of source {}, chunk of {}",
                    stamp.source, f.header.source
                ),
            );
            return Ok(());
        }
        // A chunk is trained on once: a frame its stream has had is refused, the newest too.
        if !self.admit(stamp) {
            return Ok(());
        }
        let host = self.hosts.entry(source).or_default();
        // DESIGN §2: what a sim host sends is checked as a local chunk would be.
        let refusal = if self.items.len() > self.max_len {
            Some("larger than the run's chunks")
        } else {
            rollout::chunk_refusal(&f.header, &self.items)
        };
        if let Some(kind) = refusal {
            self.refused
                .refuse(kind, &format!("source {source} chunk {}", f.header.chunk));
            return Ok(());
        }
        host.received.add(bytes.len());
        host.last_chunk = f.header.chunk;
        host.env_steps = f.header.env_steps;
        self.tx.send(f.header, &self.items)?;
        Ok(())
    }

    /// Whether a sealed frame of `stamp` is new in its sim host's stream (counting frames lost
    /// before it); a frame the stream has had is refused and counted.
    fn admit(&mut self, stamp: frame::Stamp) -> bool {
        let source = stamp.source;
        let host = self.hosts.entry(source).or_default();
        match self.streams.admit(stamp) {
            Ok(Place::New { lost }) => {
                if lost > 0 {
                    host.lost += lost;
                    tracing::warn!(source, lost = host.lost, "rollout frames lost");
                }
                true
            }
            Ok(Place::Restarted) => {
                tracing::info!(source, "sim host bridge started again");
                true
            }
            Ok(Place::Last) => {
                self.refused
                    .refuse("replayed", &format!("source {source} frame {}", stamp.seq));
                false
            }
            Err(r) => {
                self.refused.refuse(r.kind, &r.detail);
                false
            }
        }
    }

    /// Logs what each sim host sent, and the frames refused.
    fn finish(self) {
        for (source, h) in &self.hosts {
            tracing::info!(
                source,
                frames = h.received.frames,
                bytes = h.received.bytes,
                lost = h.lost,
                "rollout frames received"
            );
        }
        tracing::info!(
            refused = %self.refused.summary(),
            refused_connections = %self.connections.summary(),
            "learner host bridge done"
        );
    }
}
