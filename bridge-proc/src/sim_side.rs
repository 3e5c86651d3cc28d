//! A sim host's bridge (DESIGN §9): forwards the local sim's rollout chunks to the learner
//! host, and republishes the learner host's policies on the local `policy/<slot>` services
//! (history 1, so a sim that starts late gets the newest weights). Until it has a policy of
//! every slot it asks the learner host for the newest ones, and asks again whenever the
//! learner host (re)appears, so a host that joins mid-run acts within a second. Once the
//! sim's last chunk (`run.total-steps`) is out, the bridge closes its Zenoh connection,
//! which sends what is still queued, and exits.

use crate::directions::{Counts, Stop, both_directions};
use crate::frame::{self, Key, Kind};
use crate::link::{self, Net, zerr};
use common::config::PolicySlot;
use common::ipc::{self, Bus, Sender};
use common::refusals::Refusals;
use common::wire::PolicyHeader;
use common::{ACT_DIM, Config, OBS_DIM, PolicyLayout};
use std::collections::BTreeMap;
use std::time::{Duration, Instant};
use zenoh::Wait;
use zenoh::qos::CongestionControl;
use zenoh::query::{ConsolidationMode, QueryTarget};
use zenoh::sample::SampleKind;

/// Forwards rollout chunks and receives policies until the run stops this process.
pub fn run(cfg: &Config, run_id: &str, endpoint: &str, source: u32) -> anyhow::Result<()> {
    let key = Key::new(&cfg.net.read_key()?);
    let net = link::connect(endpoint)?;
    let _token = net
        .liveliness()
        .declare_token(link::sim_token(source))
        .wait()
        .map_err(zerr("liveliness token"))?;
    tracing::info!(endpoint, source, "sim host bridge up");
    let (net2, key2, run) = (net.clone(), key.clone(), run_id.to_string());
    let total = cfg.run.total_steps;
    let ran = both_directions(
        "rollouts",
        move |stop| forward_rollouts(&run, &net2, &key2, (source, total), stop),
        |stop| receive_policies(cfg, run_id, &net, &key, stop),
    );
    net.close()
        .wait()
        .map_err(zerr("closing the Zenoh connection"))?;
    ran
}

/// Forwards the sim's chunks, stamped with `source`, until the run stops or the chunk that
/// completes `total` env steps is out.
fn forward_rollouts(
    run_id: &str,
    net: &Net,
    key: &Key,
    (source, total): (u32, u64),
    stop: &Stop,
) -> anyhow::Result<()> {
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
        while let Some(sample) = rx.try_recv()? {
            // The chunk leaves stamped with this host's source id, whatever the sim said.
            let mut h = *sample.user_header();
            h.source = source;
            let bytes = frame::encode(
                key,
                Kind::Rollout,
                source,
                sent.frames,
                &h,
                sample.payload(),
            );
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
}

impl Republisher {
    fn new(cfg: &Config, bus: &Bus) -> anyhow::Result<Self> {
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
        })
    }

    /// Whether every slot has had a policy.
    fn complete(&self) -> bool {
        self.last.len() == self.senders.len()
    }

    /// Checks one frame and republishes its policy.
    fn take(&mut self, key: &Key, bytes: &[u8]) -> anyhow::Result<()> {
        self.received.add(bytes.len());
        let f = match frame::decode::<PolicyHeader, f32>(key, Kind::Policy, bytes, &mut self.items)
        {
            Ok(f) => f,
            Err(r) => {
                self.refused.refuse(r.kind, &r.detail);
                return Ok(());
            }
        };
        let Some((&slot, tx)) = self
            .senders
            .iter()
            .find(|(s, _)| s.index() as u32 == f.source)
        else {
            self.refused
                .refuse("unknown slot", &format!("slot {}", f.source));
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
    key: &Key,
    stop: &Stop,
) -> anyhow::Result<()> {
    let bus = Bus::connect(run_id, "bridge-policies")?;
    let control = bus.control_listener()?;
    let mut local = Republisher::new(cfg, &bus)?;
    let policies = link::subscribe(net, link::POLICY_ALL, 16)?;
    let learner_host = link::watch_tokens(net, link::LEARNER_TOKEN, 8)?;
    let every = Duration::from_millis(cfg.net.policy_query_ms);
    // Ask as soon as the learner host's token shows it reachable; a query sent before the
    // connection is up would wait out its timeout. Without the token, ask every `every`.
    let mut next_query = Instant::now() + every;
    while !stop.is_set() && !bus.stop_requested(&control) {
        for tx in local.senders.values() {
            tx.update_connections()?;
        }
        while let Some(s) = learner_host.try_recv().map_err(zerr("liveliness"))? {
            if s.kind() == SampleKind::Put {
                tracing::info!("learner host reachable: asking for the newest policies");
                local.last.clear();
                next_query = Instant::now();
            } else {
                tracing::warn!("learner host gone: the sim keeps acting on its last policies");
            }
        }
        if !local.complete() && Instant::now() >= next_query {
            let replies = net
                .get(link::POLICY_ALL)
                .target(QueryTarget::All)
                .consolidation(ConsolidationMode::None)
                .timeout(every)
                .wait()
                .map_err(zerr("policy query"))?;
            while let Ok(reply) = replies.recv() {
                if let Ok(sample) = reply.result() {
                    local.take(key, &sample.payload().to_bytes())?;
                }
            }
            next_query = Instant::now() + every;
        }
        if let Some(sample) = policies
            .recv_timeout(Duration::from_millis(50))
            .map_err(zerr("policy subscriber"))?
        {
            local.take(key, &sample.payload().to_bytes())?;
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
