//! The learner host's bridge (DESIGN §9): republishes every sim host's rollout chunks on the
//! local `rollout` service, and forwards the local learners' policies to the sim hosts,
//! answering a sim host's query with the newest policy of each slot. It logs the sim hosts
//! as they join and leave (Zenoh liveliness) and what each sent, and publishes that table
//! every second on the local `hosts` service for `lavatube status`.

use crate::directions::{Counts, Stop, both_directions};
use crate::frame::{self, Key, Kind};
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
    let key = Key::new(&cfg.net.read_key()?);
    let net = link::listen(endpoint)?;
    let _token = net
        .liveliness()
        .declare_token(link::LEARNER_TOKEN)
        .wait()
        .map_err(zerr("liveliness token"))?;
    tracing::info!(endpoint, "learner host bridge listening");
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
        move |stop| forward_policies(&run, &slots, &net2, &key2, stop),
        |stop| receive_rollouts(cfg, run_id, &net, &key, stop),
    )
}

fn forward_policies(
    run_id: &str,
    slots: &[PolicySlot],
    net: &Net,
    key: &Key,
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
        ports.push((slot, rx, publisher));
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
        if let Some((_, first, _)) = ports.first() {
            first.wait(Duration::from_millis(10))?;
        }
        for (slot, rx, publisher) in &ports {
            while let Some(sample) = rx.try_recv()? {
                let h = *sample.user_header();
                let bytes = frame::encode(
                    key,
                    Kind::Policy,
                    slot.index() as u32,
                    sent.frames,
                    &h,
                    sample.payload(),
                );
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

/// What has come from one sim host.
#[derive(Debug, Default)]
struct Host {
    joined: bool,
    next_seq: u64,
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
    key: &Key,
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
        key,
        max_len,
        tx,
        hosts_tx,
        hosts: BTreeMap::new(),
        refused: Refusals::new("rollout frame"),
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
        intake.take(&sample.payload().to_bytes())?;
    }
    intake.finish();
    Ok(())
}

/// The rollout side of the learner host's bridge: where chunks go, and what each sim host
/// has sent.
struct Intake<'a> {
    key: &'a Key,
    /// The most transitions a chunk of this run holds.
    max_len: usize,
    tx: Sender<Transition, RolloutHeader>,
    hosts_tx: Sender<SimHost, HostsHeader>,
    hosts: BTreeMap<u32, Host>,
    refused: Refusals,
    /// One chunk's elements, decoded into the same memory every time.
    items: Vec<Transition>,
    logged: Instant,
    published: Instant,
}

impl Intake<'_> {
    /// Logs the sim hosts every [`LOG_EVERY`] and publishes their table every
    /// [`PUBLISH_EVERY`].
    fn report_hosts(&mut self) -> anyhow::Result<()> {
        self.hosts_tx.update_connections()?;
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

    /// Takes one rollout frame: refuses it or republishes its chunk, and counts it in its
    /// sim host's sequence.
    fn take(&mut self, bytes: &[u8]) -> anyhow::Result<()> {
        let f = match frame::decode::<RolloutHeader, _>(
            self.key,
            Kind::Rollout,
            bytes,
            &mut self.items,
        ) {
            Ok(f) => f,
            Err(r) => {
                self.refused.refuse(r.kind, &r.detail);
                return Ok(());
            }
        };
        // An authenticated frame counts in its source's sequence, even if its chunk is refused.
        let host = self.hosts.entry(f.source).or_default();
        if f.seq > host.next_seq {
            host.lost += f.seq - host.next_seq;
            tracing::warn!(source = f.source, lost = host.lost, "rollout frames lost");
        }
        host.next_seq = host.next_seq.max(f.seq + 1);
        // DESIGN §2: what a sim host sends is checked as a local chunk would be.
        let refusal = if f.header.source != f.source {
            Some("source mismatch")
        } else if self.items.len() > self.max_len {
            Some("larger than the run's chunks")
        } else {
            rollout::chunk_refusal(&f.header, &self.items)
        };
        if let Some(kind) = refusal {
            self.refused.refuse(
                kind,
                &format!("source {} chunk {}", f.source, f.header.chunk),
            );
            return Ok(());
        }
        host.received.add(bytes.len());
        host.last_chunk = f.header.chunk;
        host.env_steps = f.header.env_steps;
        self.tx.send(f.header, &self.items)?;
        Ok(())
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
        tracing::info!(refused = %self.refused.summary(), "learner host bridge done");
    }
}
