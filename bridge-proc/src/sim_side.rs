//! A sim host's bridge (DESIGN §9): forwards the local sim's rollout chunks to the learner
//! host, and republishes the learner host's policies on the local `policy/<slot>` services
//! (history 1, so a sim that starts late gets the newest weights). Until it has a policy of
//! every slot it asks the learner host for the newest ones, and asks again whenever the
//! learner host (re)appears, so a host that joins mid-run acts within a second. It takes the
//! run's start id from the learner host's token, seals its chunks for that start and takes
//! policies of that start only; until it has one, its chunks wait. Once the sim's last
//! chunk (`run.total-steps`) is out, the bridge closes its Zenoh connection, which sends
//! what is still queued, and exits.

use crate::directions::{Counts, Stop, both_directions};
use crate::frame::{Key, Kind, Opener, Place, Sealer, Streams};
use crate::link::{self, Net, zerr};
use common::config::PolicySlot;
use common::ipc::{self, Bus, Sender};
use common::refusals::Refusals;
use common::wire::PolicyHeader;
use common::{ACT_DIM, Config, OBS_DIM, PolicyLayout};
use std::collections::BTreeMap;
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::{Duration, Instant};
use zenoh::Wait;
use zenoh::qos::CongestionControl;
use zenoh::query::{ConsolidationMode, QueryTarget};
use zenoh::sample::SampleKind;

/// Forwards rollout chunks and receives policies until the run stops this process.
pub fn run(cfg: &Config, run_id: &str, endpoint: &str, source: u32) -> anyhow::Result<()> {
    let secret = cfg.net.read_key()?;
    let key = Key::new(&secret);
    let net = link::connect(endpoint, &link::Credentials::new(&secret))?;
    let _token = net
        .liveliness()
        .declare_token(link::sim_token(source))
        .wait()
        .map_err(zerr("liveliness token"))?;
    tracing::info!(endpoint, source, "sim host bridge up");
    // The learner host's start id, 0 until its token has been seen.
    let start = Arc::new(AtomicU64::new(0));
    let (net2, run) = (net.clone(), run_id.to_string());
    let sealer = Sealer::new(&key, Kind::Rollout, source);
    let total = cfg.run.total_steps;
    let seen = start.clone();
    let ran = both_directions(
        "rollouts",
        move |stop| forward_rollouts(&run, &net2, sealer, (&seen, total), stop),
        |stop| receive_policies(cfg, run_id, &net, (&key, &start), stop),
    );
    net.close()
        .wait()
        .map_err(zerr("closing the Zenoh connection"))?;
    ran
}

/// Forwards the sim's chunks, sealed by `sealer` (this host's source) for the learner host's
/// current start, until the run stops or the chunk that completes `total` env steps is out.
fn forward_rollouts(
    run_id: &str,
    net: &Net,
    mut sealer: Sealer,
    (start, total): (&AtomicU64, u64),
    stop: &Stop,
) -> anyhow::Result<()> {
    let source = sealer.source();
    let bus = Bus::connect(run_id, "bridge-rollouts")?;
    let control = bus.control_listener()?;
    let rx = bus.receiver(&ipc::ROLLOUT, None)?;
    let publisher = net
        .declare_publisher(link::rollout_key(source))
        .congestion_control(CongestionControl::Block)
        .wait()
        .map_err(zerr("rollout publisher"))?;
    let mut sent = Counts::default();
    let mut last_out = false;
    while !last_out {
        // A stop still forwards what the sim has sent.
        let stopping = stop.is_set() || bus.stop_requested(&control);
        if !stopping {
            rx.wait(Duration::from_millis(100))?;
        }
        // No chunk leaves before the learner host's start is known: it would be refused.
        let now = start.load(Ordering::Relaxed);
        if now == 0 {
            last_out |= stopping;
            continue;
        }
        while let Some(sample) = rx.try_recv()? {
            // The chunk leaves stamped with this host's source id, whatever the sim said.
            let mut h = *sample.user_header();
            h.source = source;
            let bytes = sealer.seal(now, &h, sample.payload());
            sent.add(bytes.len());
            publisher
                .put(bytes)
                .wait()
                .map_err(|e| anyhow::anyhow!("rollout chunk {} not sent: {e}", h.chunk))?;
            last_out |= h.env_steps >= total;
        }
        last_out |= stopping;
    }
    tracing::info!(
        frames = sent.frames,
        bytes = sent.bytes,
        "rollout chunks forwarded"
    );
    Ok(())
}

/// The local policy publishers, one per slot the config's learners fill.
struct Republisher {
    senders: BTreeMap<PolicySlot, Sender<f32, PolicyHeader>>,
    /// Per slot, the (learner, version) last republished: query replies repeat it.
    last: BTreeMap<PolicySlot, (u32, u32)>,
    refused: Refusals,
    received: Counts,
    /// The weights of the frame being checked.
    items: Vec<f32>,
    opener: Opener,
    /// Which frames of each slot's stream have come, this start.
    streams: Streams,
}

impl Republisher {
    fn new(cfg: &Config, bus: &Bus, key: &Key) -> anyhow::Result<Self> {
        let len = PolicyLayout::new(OBS_DIM, &cfg.ppo.hidden, ACT_DIM).len();
        let mut senders = BTreeMap::new();
        for slot in cfg.run.learners.iter().chain(cfg.run.frozen.keys()) {
            senders.insert(*slot, bus.sender(&ipc::POLICY, Some(slot.name()), len)?);
        }
        Ok(Self {
            senders,
            last: BTreeMap::new(),
            refused: Refusals::new("policy frame"),
            received: Counts::default(),
            items: Vec::with_capacity(len),
            opener: Opener::new(key),
            streams: Streams::default(),
        })
    }

    /// Whether every slot has had a policy.
    fn complete(&self) -> bool {
        self.last.len() == self.senders.len()
    }

    /// Checks one frame of run start `start` and republishes its policy.
    fn take(&mut self, start: u64, bytes: &[u8]) -> anyhow::Result<()> {
        self.received.add(bytes.len());
        let f = match self
            .opener
            .open::<PolicyHeader, f32>(Kind::Policy, bytes, &mut self.items)
        {
            Ok(f) => f,
            Err(r) => {
                self.refused.refuse(r.kind, &r.detail);
                return Ok(());
            }
        };
        if f.stamp.start != start {
            self.refused.refuse(
                "other start",
                &format!(
                    "sealed for start {:016x}, not the learner host's {start:016x}",
                    f.stamp.start
                ),
            );
            return Ok(());
        }
        match self.streams.admit(f.stamp) {
            Ok(Place::New { .. } | Place::Restarted) => {}
            // A query's reply repeats the newest policy: nothing to do.
            Ok(Place::Last) => return Ok(()),
            Err(r) => {
                self.refused.refuse(r.kind, &r.detail);
                return Ok(());
            }
        }
        let Some((&slot, tx)) = self
            .senders
            .iter()
            .find(|(s, _)| s.index() as u32 == f.stamp.source)
        else {
            self.refused
                .refuse("unknown slot", &format!("slot {}", f.stamp.source));
            return Ok(());
        };
        if let Some(kind) = f.header.refusal(slot, &self.items) {
            self.refused
                .refuse(kind, &format!("version {}", f.header.version));
            return Ok(());
        }
        let id = (f.header.learner, f.header.version);
        if self.last.get(&slot) == Some(&id) {
            return Ok(());
        }
        tx.send(f.header, &self.items)?;
        if !self.last.contains_key(&slot) {
            tracing::info!(
                slot = slot.name(),
                version = f.header.version,
                "first policy"
            );
        }
        self.last.insert(slot, id);
        Ok(())
    }
}

fn receive_policies(
    cfg: &Config,
    run_id: &str,
    net: &Net,
    (key, start): (&Key, &AtomicU64),
    stop: &Stop,
) -> anyhow::Result<()> {
    let bus = Bus::connect(run_id, "bridge-policies")?;
    let control = bus.control_listener()?;
    let mut local = Republisher::new(cfg, &bus, key)?;
    let policies = link::subscribe(net, link::POLICY_ALL, 16)?;
    let learner_host = link::watch_tokens(net, link::LEARNER_ALL, 8)?;
    let every = Duration::from_millis(cfg.net.policy_query_ms);
    // Ask as soon as the learner host's token shows it reachable; a query sent before the
    // connection is up would wait out its timeout. Without the token, ask every `every`.
    let mut next_query = Instant::now() + every;
    while !stop.is_set() && !bus.stop_requested(&control) {
        for tx in local.senders.values() {
            tx.update_connections()?;
        }
        while let Some(s) = learner_host.try_recv().map_err(zerr("liveliness"))? {
            let Some(id) = link::token_start(s.key_expr().as_str()) else {
                continue;
            };
            if s.kind() == SampleKind::Put {
                tracing::info!(
                    start = format!("{id:016x}"),
                    "learner host reachable: asking for the newest policies"
                );
                start.store(id, Ordering::Relaxed);
                local.last.clear();
                local.streams.clear();
                next_query = Instant::now();
            } else if id == start.load(Ordering::Relaxed) {
                tracing::warn!("learner host gone: the sim keeps acting on its last policies");
            }
        }
        let now = start.load(Ordering::Relaxed);
        if now != 0 && !local.complete() && Instant::now() >= next_query {
            let replies = net
                .get(link::POLICY_ALL)
                .target(QueryTarget::All)
                .consolidation(ConsolidationMode::None)
                .timeout(every)
                .wait()
                .map_err(zerr("policy query"))?;
            while let Ok(reply) = replies.recv() {
                if let Ok(sample) = reply.result() {
                    local.take(now, &sample.payload().to_bytes())?;
                }
            }
            next_query = Instant::now() + every;
        }
        if let Some(sample) = policies
            .recv_timeout(Duration::from_millis(50))
            .map_err(zerr("policy subscriber"))?
        {
            local.take(now, &sample.payload().to_bytes())?;
        }
    }
    tracing::info!(
        frames = local.received.frames,
        bytes = local.received.bytes,
        refused = %local.refused.summary(),
        "policy frames received"
    );
    Ok(())
}
