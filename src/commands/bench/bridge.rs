//! The bridge between hosts (DESIGN §9) on loopback: a learner-host `bridge-proc` and a
//! sim-host `bridge-proc`, real processes on two run ids of their own, as `lavatube run
//! --listen` and `lavatube join` start them. The bench holds the sim side's `rollout`
//! publisher and the learner side's `rollout` subscriber, and the reverse for
//! `policy/general`, so it stamps each send and sees the arrival on the other host's shared
//! memory with one clock: latency with one message in flight, then throughput with a few.
//! Then one sim's async env steps/s as a sim host behind the bridge against the same sim on
//! one host, through the real launchers.

use super::files::{read_json, write_config};
use crate::runtime::{Binaries, Child, Output, Role};
use anyhow::{Context, bail};
use common::config::PolicySlot;
use common::ipc::{self, Bus, Receiver, Sender};
use common::wire::{PolicyHeader, RolloutHeader};
use common::{Config, Transition};
use serde::Serialize;
use std::io::Read;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

/// Chunks in flight in the throughput phase: below the rollout service's buffer of 8. A
/// policy is a newest value (buffer 2): one in flight.
const CHUNK_WINDOW: usize = 4;
/// No arrival for this long fails the stage.
const TIMEOUT: Duration = Duration::from_secs(30);

/// One message kind through the bridge pair.
#[derive(Debug, Clone, Serialize)]
pub struct BridgeRow {
    /// `rollout chunk` (sim host → learner host) or `policy` (learner host → sim host).
    pub what: &'static str,
    pub bytes: usize,
    pub messages: usize,
    pub latency_p50_us: Option<f64>,
    pub latency_p99_us: Option<f64>,
    pub messages_per_s: f64,
    pub mb_per_s: f64,
}

/// Both hosts' ports as the bench holds them.
struct Ports {
    chunk_tx: Sender<Transition, RolloutHeader>,
    chunk_rx: Receiver<Transition, RolloutHeader>,
    policy_tx: Sender<f32, PolicyHeader>,
    policy_rx: Receiver<f32, PolicyHeader>,
}

/// Starts the two bridges, measures chunks and policies `messages` times each, stops them.
pub fn measure(
    cfg: &Config,
    bins: &Binaries,
    dir: &Path,
    bench_id: &str,
    weights: &[f32],
    messages: usize,
) -> anyhow::Result<Bridged> {
    let dir = dir.join("bridge");
    let mut cfg = cfg.clone();
    // The chunks go back to back, far above a sim host's rate: measured, not rate-limited.
    cfg.net.source_frames_per_s = 100_000;
    let cfg_path = keyed_config(&dir, &mut cfg)?;
    let endpoint = format!("tcp/127.0.0.1:{}", free_port()?);
    let (learner_run, sim_run) = (format!("{bench_id}-bl"), format!("{bench_id}-bs"));
    let (learner_bus, sim_bus) = (
        Bus::connect(&learner_run, "bench")?,
        Bus::connect(&sim_run, "bench")?,
    );
    let ports = Ports::open(&cfg, &learner_bus, &sim_bus, weights.len())?;
    let starter = Starter {
        bins,
        dir: &dir,
        cfg_path: &cfg_path,
    };
    // The learner host first, with a policy to give: the sim host then joins a run under way.
    ports.policy_tx.send(first_policy(&cfg, weights), weights)?;
    let mut bridges = vec![starter.spawn(
        "learner",
        &learner_run,
        &["--listen".into(), endpoint.clone()],
    )?];
    let measured = listening(&mut bridges[0]).and_then(|()| {
        let joined = Instant::now();
        bridges.push(starter.spawn(
            "sim",
            &sim_run,
            &[
                "--connect".into(),
                endpoint.clone(),
                "--source".into(),
                "1".into(),
            ],
        )?);
        run(&ports, &cfg, weights, messages, (&mut bridges, joined))
    });
    stop(&[&learner_bus, &sim_bus], &mut bridges)?;
    drop((ports, learner_bus, sim_bus));
    for run in [&learner_run, &sim_run] {
        if let Err(e) = ipc::remove_run(run) {
            eprintln!("lavatube: {e}");
        }
    }
    measured
}

impl Ports {
    /// The sim host's chunk publisher and policy subscriber on `sim_bus` and the learner
    /// host's chunk subscriber and policy publisher on `learner_bus`, sized for `cfg`'s
    /// rollout chunks and policies of `weights` floats.
    fn open(
        cfg: &Config,
        learner_bus: &Bus,
        sim_bus: &Bus,
        weights: usize,
    ) -> anyhow::Result<Self> {
        let n = cfg.sim.num_envs();
        let t = cfg.ppo.rollout_steps(n);
        let general = Some(PolicySlot::General.name());
        Ok(Self {
            chunk_tx: sim_bus.sender(&ipc::ROLLOUT, None, t * n + n)?,
            chunk_rx: learner_bus.receiver(&ipc::ROLLOUT, None)?,
            policy_tx: learner_bus.sender(&ipc::POLICY, general, weights)?,
            policy_rx: sim_bus.receiver(&ipc::POLICY, general)?,
        })
    }
}

/// Starts `bridge-proc`s on the bench's config file, each with its log in a directory of its
/// run's name.
struct Starter<'a> {
    bins: &'a Binaries,
    dir: &'a Path,
    cfg_path: &'a Path,
}

impl Starter<'_> {
    /// Starts the bridge of host `side` (`learner` or `sim`) on run `run`, with `extra`
    /// arguments after the config and run id.
    fn spawn(&self, side: &str, run: &str, extra: &[String]) -> anyhow::Result<Child> {
        let mut args = vec![
            side.to_string(),
            "--config".into(),
            self.cfg_path.display().to_string(),
            "--run-id".into(),
            run.to_string(),
        ];
        args.extend_from_slice(extra);
        let log_dir = self.dir.join(run);
        std::fs::create_dir_all(&log_dir)?;
        Child::spawn(
            Role::Bridge.name(),
            &self.bins.bridge,
            &args,
            &log_dir,
            Output::File,
        )
    }
}

/// Asks both hosts' runs to shut down, then waits for each bridge, killing one that does not
/// stop within [`TIMEOUT`].
fn stop(buses: &[&Bus], bridges: &mut [Child]) -> anyhow::Result<()> {
    for bus in buses {
        ipc::request_shutdown(&bus.control_notifier()?)?;
    }
    for b in bridges {
        if !b.wait_for(TIMEOUT)? {
            b.signal(libc::SIGKILL);
            b.wait_for(TIMEOUT)?;
        }
    }
    Ok(())
}

/// The learner host's first policy, version 0 of the general slot.
fn first_policy(cfg: &Config, weights: &[f32]) -> PolicyHeader {
    let layout = common::PolicyLayout::new(common::OBS_DIM, &cfg.ppo.hidden, common::ACT_DIM);
    debug_assert_eq!(layout.len(), weights.len());
    PolicyHeader::new(
        &layout,
        0,
        PolicySlot::General.index() as u32,
        cfg.ppo.obs_clip as f32,
    )
}

/// Waits for the learner-host bridge's Zenoh router to listen (its log says so).
fn listening(bridge: &mut Child) -> anyhow::Result<()> {
    let since = Instant::now();
    loop {
        let log = std::fs::read_to_string(bridge.log()).unwrap_or_default();
        if log.contains("learner host bridge listening") {
            return Ok(());
        }
        check(std::slice::from_mut(bridge), since)?;
        std::thread::sleep(Duration::from_millis(10));
    }
}

/// What the bridge pair measured.
#[derive(Debug, Clone, Serialize)]
pub struct Bridged {
    /// Rollout chunks, then policies.
    pub rows: Vec<BridgeRow>,
    /// From starting a sim host's bridge (the learner host already up, with a policy) to
    /// that policy in the sim host's shared memory: process start, connection, query, reply.
    pub join_to_policy_ms: f64,
}

fn run(
    ports: &Ports,
    cfg: &Config,
    weights: &[f32],
    messages: usize,
    (bridges, joined): (&mut [Child], Instant),
) -> anyhow::Result<Bridged> {
    let n = cfg.sim.num_envs();
    let t = cfg.ppo.rollout_steps(n);
    let chunk: Vec<Transition> = (0..t * n + n)
        .map(|i| Transition {
            env: (i % n) as u32,
            ..Transition::default()
        })
        .collect();
    let policy = first_policy(cfg, weights);
    // env_steps stays 0: a chunk completing run.total-steps would end the sim-host bridge.
    let header = |i: usize| RolloutHeader {
        chunk: i as u64,
        env_steps: 0,
        steps: t as u32,
        envs: n as u32,
        source: 1,
        _reserved: 0,
    };
    let send_chunk = |i: usize| ports.chunk_tx.send(header(i), &chunk);
    let send_policy = |i: usize| {
        let mut h = policy;
        h.version = i as u32;
        ports.policy_tx.send(h, weights)
    };
    // The sim-host bridge asks for the newest policy once it is connected.
    while ports.policy_rx.latest()?.is_none() {
        check(bridges, joined)?;
        ports.policy_tx.update_connections()?;
        ports.policy_rx.wait(Duration::from_millis(1))?;
    }
    let join_to_policy_ms = joined.elapsed().as_secs_f64() * 1e3;
    // A chunk sent before the sim-host bridge subscribed is gone (the service keeps no
    // history): send until one arrives, then drain any late copies.
    let started = Instant::now();
    'warm: loop {
        send_chunk(0)?;
        let sent = Instant::now();
        while sent.elapsed() < Duration::from_millis(200) {
            if ports.chunk_rx.try_recv()?.is_some() {
                break 'warm;
            }
            ports.chunk_rx.wait(Duration::from_millis(10))?;
        }
        check(bridges, started)?;
    }
    std::thread::sleep(Duration::from_millis(300));
    while ports.chunk_rx.try_recv()?.is_some() {}
    let chunk_row = phase(
        ("rollout chunk", CHUNK_WINDOW),
        std::mem::size_of_val(&chunk[..]) + size_of::<RolloutHeader>(),
        messages,
        &send_chunk,
        &|| Ok(ports.chunk_rx.try_recv()?.is_some()),
        &|d| Ok(ports.chunk_rx.wait(d)?),
        bridges,
    )?;
    let policy_row = phase(
        ("policy", 1),
        std::mem::size_of_val(weights) + size_of::<PolicyHeader>(),
        messages,
        &|i| send_policy(i + 1),
        &|| Ok(ports.policy_rx.try_recv()?.is_some()),
        &|d| Ok(ports.policy_rx.wait(d)?),
        bridges,
    )?;
    Ok(Bridged {
        rows: vec![chunk_row, policy_row],
        join_to_policy_ms,
    })
}

/// Fails when a bridge died or nothing arrived for [`TIMEOUT`].
fn check(bridges: &mut [Child], since: Instant) -> anyhow::Result<()> {
    for b in bridges.iter_mut() {
        if b.poll()?.is_some() {
            bail!("{} exited early; log: {}", b.name, b.log().display());
        }
    }
    if since.elapsed() > TIMEOUT {
        bail!("nothing arrived through the bridges within {TIMEOUT:?}");
    }
    Ok(())
}

/// Latency (one in flight, `messages` times), then throughput (`window` in flight).
fn phase(
    (what, window): (&'static str, usize),
    bytes: usize,
    messages: usize,
    send: &dyn Fn(usize) -> Result<(), ipc::IpcError>,
    arrived: &dyn Fn() -> anyhow::Result<bool>,
    wait: &dyn Fn(Duration) -> anyhow::Result<()>,
    bridges: &mut [Child],
) -> anyhow::Result<BridgeRow> {
    let receive = |bridges: &mut [Child]| -> anyhow::Result<()> {
        let since = Instant::now();
        while !arrived()? {
            check(bridges, since)?;
            wait(Duration::from_millis(5))?;
        }
        Ok(())
    };
    let mut latencies = Vec::with_capacity(messages);
    for i in 0..messages {
        let sent = Instant::now();
        send(i)?;
        receive(bridges)?;
        latencies.push(sent.elapsed().as_nanos() as u64);
    }
    latencies.sort_unstable();
    let started = Instant::now();
    let (mut sent, mut got) = (0, 0);
    while got < messages {
        while sent < messages && sent - got < window {
            send(messages + sent)?;
            sent += 1;
        }
        receive(bridges)?;
        got += 1;
    }
    let secs = started.elapsed().as_secs_f64().max(1e-9);
    Ok(BridgeRow {
        what,
        bytes,
        messages,
        latency_p50_us: super::reader::percentile_us(&latencies, 0.50),
        latency_p99_us: super::reader::percentile_us(&latencies, 0.99),
        messages_per_s: messages as f64 / secs,
        mb_per_s: (messages * bytes) as f64 / secs / 1e6,
    })
}

/// One sim's async env steps/s behind the bridge against the same sim on one host.
#[derive(Debug, Clone, Serialize)]
pub struct SimRates {
    pub env_steps: u64,
    /// `lavatube run`: sim, learner and estimator on one host.
    pub local_steps_per_s: f64,
    /// `lavatube run --listen` and `lavatube join` on this machine, over loopback.
    pub bridged_steps_per_s: f64,
    pub bridged_over_local: f64,
}

/// How long each launcher of [`sim_rates`] may take.
const LAUNCH_TIMEOUT: Duration = Duration::from_secs(900);

/// Runs the runtime config in async mode for `steps` env steps, first on one host, then as
/// a learner host and a sim host (real launchers, one after the other), and reads each
/// sim's rate from its run's `summary.json`.
pub fn sim_rates(
    cfg: &Config,
    launcher: &Path,
    dir: &Path,
    bench_id: &str,
    steps: u64,
) -> anyhow::Result<SimRates> {
    let dir = dir.join("bridge-sim");
    let mut cfg = cfg.clone();
    cfg.run.mode = common::config::LearnMode::Async;
    cfg.run.total_steps = steps;
    cfg.run.out_dir = dir.join("runs");
    let cfg_path = keyed_config(&dir, &mut cfg)?;
    let config = cfg_path.display().to_string();
    let endpoint = format!("tcp/127.0.0.1:{}", free_port()?);
    let launch = |name: &'static str, args: &[&str]| -> anyhow::Result<Child> {
        let args: Vec<String> = args.iter().map(|a| (*a).to_string()).collect();
        Child::spawn(name, launcher, &args, &dir, Output::File)
    };
    let (local, learner_host, sim_host) = (
        format!("{bench_id}-local"),
        format!("{bench_id}-lhost"),
        format!("{bench_id}-shost"),
    );
    finish(launch(
        "local",
        &["run", "--config", &config, "--run-id", &local, "--quiet"],
    )?)?;
    let listening = launch(
        "learner-host",
        &[
            "run",
            "--config",
            &config,
            "--run-id",
            &learner_host,
            "--listen",
            &endpoint,
            "--quiet",
        ],
    )?;
    let joined = launch(
        "sim-host",
        &[
            "join",
            "--config",
            &config,
            "--run-id",
            &sim_host,
            "--connect",
            &endpoint,
            "--source",
            "1",
            "--quiet",
        ],
    )?;
    finish(joined)?;
    finish(listening)?;
    let out_dir = &cfg.run.out_dir;
    let (local_steps_per_s, bridged_steps_per_s) = (
        env_steps_per_s(out_dir, &local)?,
        env_steps_per_s(out_dir, &sim_host)?,
    );
    Ok(SimRates {
        env_steps: steps,
        local_steps_per_s,
        bridged_steps_per_s,
        bridged_over_local: bridged_steps_per_s / local_steps_per_s.max(1e-9),
    })
}

/// Waits for launcher `c` to finish; fails when it does not within [`LAUNCH_TIMEOUT`]
/// (interrupting it) or fails.
fn finish(mut c: Child) -> anyhow::Result<()> {
    let timeout = LAUNCH_TIMEOUT;
    if !c.wait_for(timeout)? {
        c.signal(libc::SIGINT);
        c.wait_for(timeout)?;
        bail!(
            "{} did not finish within {timeout:?}; log: {}",
            c.name,
            c.log().display()
        );
    }
    c.failure().map_or(Ok(()), |f| Err(anyhow::anyhow!(f)))
}

/// The env steps per second in the `summary.json` of run `run` under `out_dir`.
fn env_steps_per_s(out_dir: &Path, run: &str) -> anyhow::Result<f64> {
    let path = out_dir.join(run).join(common::run_dir::SUMMARY_JSON);
    Ok(read_json::<crate::runtime::Summary>(&path)?.env_steps_per_second)
}

/// Makes `dir`, gives `cfg` a fresh shared key there and writes it as the config the
/// processes started there read; its path.
fn keyed_config(dir: &Path, cfg: &mut Config) -> anyhow::Result<PathBuf> {
    std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
    cfg.net.key_file = Some(write_key(dir)?);
    write_config(dir, cfg)
}

/// A fresh 32-byte shared key in `dir/run.key`.
fn write_key(dir: &Path) -> anyhow::Result<PathBuf> {
    let key = dir.join("run.key");
    let mut secret = [0u8; 32];
    std::fs::File::open("/dev/urandom")
        .and_then(|mut f| f.read_exact(&mut secret))
        .context("cannot read /dev/urandom for the bridge's key")?;
    std::fs::write(&key, secret).with_context(|| format!("cannot write {}", key.display()))?;
    Ok(key)
}

/// A TCP port on 127.0.0.1 that was free a moment ago.
fn free_port() -> anyhow::Result<u16> {
    Ok(std::net::TcpListener::bind("127.0.0.1:0")
        .and_then(|l| l.local_addr())
        .context("no free loopback port")?
        .port())
}
