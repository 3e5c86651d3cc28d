//! Issue 8, item 2: the same bytes between the same two processes over iceoryx2 (the
//! runtime's own `common::ipc` channels: copy into a loaned sample, send, notify; the reader
//! sleeps until notified) and over a Unix domain stream socket, for a telemetry tick, a
//! rollout chunk and a weight vector, so the shared-memory advantage is a measured ratio.
//!
//! The launcher sends; `lavatube bench-echo` (hidden) receives. Each payload runs two phases
//! per transport: *latency* (one message in flight; the receiver records now − the send
//! timestamp, both `CLOCK_MONOTONIC`) and *throughput* (a window of messages in flight,
//! acknowledged in batches, so neither transport ever drops or overwrites one). The socket
//! also carries the control frames that start each test, and its closing ends the echo.
//!
//! What "received" means differs exactly as the transports do: an iceoryx2 reader has the
//! payload in place in shared memory; a socket reader has copied it out of the kernel.

use super::child::Child;
use super::reader::percentile_us;
use anyhow::{Context, bail, ensure};
use common::Transition;
use common::ipc::{Bus, ChannelSpec, Receiver, Sender};
use common::wire::{self, EnvTick};
use iceoryx2::prelude::ZeroCopySend;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::io::{ErrorKind, Read, Write};
use std::os::unix::net::{UnixListener, UnixStream};
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::{Duration, Instant};

/// The header of every bench message on both transports. Local to the launcher (it is both
/// ends), so it lives here rather than in `common::wire`.
#[derive(Debug, Clone, Copy, Default, PartialEq, ZeroCopySend)]
#[repr(C)]
#[type_name("lavatube.BenchStamp.v1")]
pub struct Stamp {
    pub seq: u64,
    /// [`wire::monotonic_ns`] just before the send.
    pub sent_ns: u64,
    pub test: u32,
    /// Bits `RECORD`, `ACK`, `CONTROL`, `OVER_SOCKET`; payload kind in bits 8–15 of a control frame.
    pub flags: u32,
}

/// The receiver records this message's one-way latency.
const RECORD: u32 = 1;
/// The receiver acknowledges after this message (with the count received so far).
const ACK: u32 = 2;
/// A control frame (socket only): a test starts; `seq` is its message count.
const CONTROL: u32 = 4;
/// Control: the test runs over the socket, not iceoryx2.
const OVER_SOCKET: u32 = 8;

/// Messages in flight in the throughput phase, and how often the receiver acknowledges.
const WINDOW: u64 = 16;
const ACK_EVERY: u64 = 4;
/// No progress for this long fails the comparison (a dead or stuck partner).
const TIMEOUT: Duration = Duration::from_secs(60);

/// The bench channels: room for a whole window, one writer, one reader.
const fn channel(service: &'static str) -> ChannelSpec {
    ChannelSpec {
        service,
        buffer: 2 * WINDOW as usize,
        history: 0,
        publishers: 1,
        subscribers: 1,
    }
}
const TELEMETRY: ChannelSpec = channel("bench/telemetry");
const ROLLOUT: ChannelSpec = channel("bench/rollout");
const WEIGHTS: ChannelSpec = channel("bench/weights");
const ACKS: ChannelSpec = channel("bench/acks");

/// Socket frame: the stamp, the payload length, the payload.
const FRAME_HEADER: usize = 32;

/// Which message of the runtime a payload copies.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Kind {
    /// One telemetry tick: `N` [`EnvTick`]s.
    Telemetry,
    /// One rollout chunk: `T × N + N` [`Transition`]s.
    Rollout,
    /// One policy: the flat actor's `f32` weights.
    Weights,
}

impl Kind {
    pub fn name(self) -> &'static str {
        match self {
            Kind::Telemetry => "telemetry",
            Kind::Rollout => "rollout chunk",
            Kind::Weights => "weights",
        }
    }

    fn code(self) -> u32 {
        match self {
            Kind::Telemetry => 0,
            Kind::Rollout => 1,
            Kind::Weights => 2,
        }
    }

    fn from_code(c: u32) -> anyhow::Result<Self> {
        Ok(match c {
            0 => Kind::Telemetry,
            1 => Kind::Rollout,
            2 => Kind::Weights,
            _ => bail!("unknown payload kind {c}"),
        })
    }

    fn element_bytes(self) -> usize {
        match self {
            Kind::Telemetry => size_of::<EnvTick>(),
            Kind::Rollout => size_of::<Transition>(),
            Kind::Weights => size_of::<f32>(),
        }
    }
}

/// One payload to compare.
#[derive(Debug, Clone, Copy)]
pub struct Payload {
    pub kind: Kind,
    /// The env count it belongs to (none for weights).
    pub envs: Option<usize>,
    pub elements: usize,
}

impl Payload {
    pub fn bytes(&self) -> usize {
        self.elements * self.kind.element_bytes()
    }

    pub fn label(&self) -> String {
        match self.envs {
            Some(n) => format!("{} N={n}", self.kind.name()),
            None => self.kind.name().to_string(),
        }
    }
}

/// One transport's numbers for one payload.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct LinkResult {
    pub latency_p50_us: f64,
    pub latency_p99_us: f64,
    pub messages_per_s: f64,
}

/// How much better shared memory did: above 1 means iceoryx2 wins.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Ratios {
    pub latency_p50_uds_over_iceoryx2: f64,
    pub latency_p99_uds_over_iceoryx2: f64,
    pub messages_per_s_iceoryx2_over_uds: f64,
}

/// One payload over both transports.
#[derive(Debug, Clone, Serialize)]
pub struct TransportRow {
    pub payload: Kind,
    pub envs: Option<usize>,
    pub elements: usize,
    /// Payload bytes per message (plus a 24-byte stamp; the socket adds an 8-byte length).
    pub bytes: usize,
    /// Messages per phase (the latency phase records all but the first tenth, a warm-up).
    pub messages: usize,
    pub iceoryx2: LinkResult,
    pub uds: LinkResult,
    pub ratios: Ratios,
}

/// Latencies the echo recorded in one latency phase.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Latency {
    pub count: usize,
    pub p50_us: f64,
    pub p99_us: f64,
}

fn encode(stamp: &Stamp, len: u64, out: &mut [u8]) {
    out[0..8].copy_from_slice(&stamp.seq.to_le_bytes());
    out[8..16].copy_from_slice(&stamp.sent_ns.to_le_bytes());
    out[16..20].copy_from_slice(&stamp.test.to_le_bytes());
    out[20..24].copy_from_slice(&stamp.flags.to_le_bytes());
    out[24..32].copy_from_slice(&len.to_le_bytes());
}

/// Reads a frame header; `None` when the socket closed before one began.
fn read_header(stream: &mut UnixStream) -> anyhow::Result<Option<(Stamp, usize)>> {
    let mut b = [0u8; FRAME_HEADER];
    match stream.read_exact(&mut b) {
        Ok(()) => {}
        Err(e) if e.kind() == ErrorKind::UnexpectedEof => return Ok(None),
        Err(e) => return Err(e).context("socket read"),
    }
    let u64_at = |i: usize| {
        let mut w = [0u8; 8];
        w.copy_from_slice(&b[i..i + 8]);
        u64::from_le_bytes(w)
    };
    let u32_at = |i: usize| {
        let mut w = [0u8; 4];
        w.copy_from_slice(&b[i..i + 4]);
        u32::from_le_bytes(w)
    };
    let stamp = Stamp {
        seq: u64_at(0),
        sent_ns: u64_at(8),
        test: u32_at(16),
        flags: u32_at(20),
    };
    let len = usize::try_from(u64_at(24)).context("frame length")?;
    Ok(Some((stamp, len)))
}

/// The sending side of one transport.
trait Link {
    fn send(&mut self, stamp: Stamp) -> anyhow::Result<()>;
    /// Waits for at least one acknowledgement; the highest count acknowledged.
    fn acked(&mut self) -> anyhow::Result<u64>;
}

struct IpcLink<'a, T: std::fmt::Debug + Copy + ZeroCopySend + 'static> {
    tx: &'a Sender<T, Stamp>,
    data: &'a [T],
    acks: &'a Receiver<u64, Stamp>,
}

impl<T: std::fmt::Debug + Copy + Default + ZeroCopySend + 'static> Link for IpcLink<'_, T> {
    fn send(&mut self, stamp: Stamp) -> anyhow::Result<()> {
        Ok(self.tx.send(stamp, self.data)?)
    }

    fn acked(&mut self) -> anyhow::Result<u64> {
        let since = Instant::now();
        loop {
            let mut best = None;
            while let Some(s) = self.acks.try_recv()? {
                best = best.max(s.payload().first().copied());
            }
            if let Some(n) = best {
                return Ok(n);
            }
            if since.elapsed() > TIMEOUT {
                bail!("no acknowledgement over iceoryx2 for {TIMEOUT:?}");
            }
            self.acks.wait(Duration::from_millis(100))?;
        }
    }
}

struct SocketLink<'a> {
    stream: &'a mut UnixStream,
    /// Header and payload, sent with one write.
    frame: Vec<u8>,
}

impl Link for SocketLink<'_> {
    fn send(&mut self, stamp: Stamp) -> anyhow::Result<()> {
        let len = (self.frame.len() - FRAME_HEADER) as u64;
        encode(&stamp, len, &mut self.frame[..FRAME_HEADER]);
        self.stream.write_all(&self.frame).context("socket write")
    }

    fn acked(&mut self) -> anyhow::Result<u64> {
        let mut b = [0u8; 8];
        self.stream
            .read_exact(&mut b)
            .context("no acknowledgement over the socket")?;
        Ok(u64::from_le_bytes(b))
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Phase {
    Latency,
    Throughput,
}

/// Sends `m` messages of one phase; messages per second from the first send to the last
/// acknowledgement.
fn run_phase(link: &mut dyn Link, test: u32, phase: Phase, m: u64) -> anyhow::Result<f64> {
    let (window, ack_every, warmup) = match phase {
        Phase::Latency => (1, 1, m / 10),
        Phase::Throughput => (WINDOW, ACK_EVERY, m),
    };
    let started = Instant::now();
    let (mut sent, mut acked) = (0u64, 0u64);
    while acked < m {
        while sent < m && sent - acked < window {
            let mut flags = 0;
            if sent >= warmup {
                flags |= RECORD;
            }
            if (sent + 1) % ack_every == 0 || sent + 1 == m {
                flags |= ACK;
            }
            link.send(Stamp {
                seq: sent,
                sent_ns: wire::monotonic_ns(),
                test,
                flags,
            })?;
            sent += 1;
        }
        acked = acked.max(link.acked()?);
    }
    Ok(m as f64 / started.elapsed().as_secs_f64())
}

/// Accepts the echo's connection, giving up if it exits or `TIMEOUT` passes.
fn accept(listener: &UnixListener, echo: &mut Child) -> anyhow::Result<UnixStream> {
    listener
        .set_nonblocking(true)
        .context("socket nonblocking")?;
    let since = Instant::now();
    loop {
        match listener.accept() {
            Ok((stream, _)) => {
                stream.set_nonblocking(false).context("socket blocking")?;
                return Ok(stream);
            }
            Err(e) if e.kind() == ErrorKind::WouldBlock => {}
            Err(e) => return Err(e).context("socket accept"),
        }
        if echo.poll()? {
            bail!(
                "the echo process exited before connecting; log: {}",
                echo.log.display()
            );
        }
        if since.elapsed() > TIMEOUT {
            bail!("the echo process did not connect within {TIMEOUT:?}");
        }
        std::thread::sleep(Duration::from_millis(5));
    }
}

/// The launcher's iceoryx2 ports and the data it sends on them.
struct IpcSide<'a> {
    tele_tx: Sender<EnvTick, Stamp>,
    rollout_tx: Sender<Transition, Stamp>,
    weights_tx: Sender<f32, Stamp>,
    acks: Receiver<u64, Stamp>,
    /// Default records: for ticks and chunks only the size matters.
    ticks: Vec<EnvTick>,
    chunk: Vec<Transition>,
    weights: &'a [f32],
}

impl<'a> IpcSide<'a> {
    fn new(bus: &Bus, payloads: &[Payload], weights: &'a [f32]) -> anyhow::Result<Self> {
        let most = |k: Kind| {
            payloads
                .iter()
                .filter(|p| p.kind == k)
                .map(|p| p.elements)
                .max()
                .unwrap_or(1)
        };
        Ok(Self {
            tele_tx: bus.sender(&TELEMETRY, None, most(Kind::Telemetry))?,
            rollout_tx: bus.sender(&ROLLOUT, None, most(Kind::Rollout))?,
            weights_tx: bus.sender(&WEIGHTS, None, weights.len())?,
            acks: bus.receiver(&ACKS, None)?,
            ticks: vec![EnvTick::default(); most(Kind::Telemetry)],
            chunk: vec![Transition::default(); most(Kind::Rollout)],
            weights,
        })
    }

    /// Connects the subscribers that arrived since the senders were made.
    fn update_connections(&self) -> anyhow::Result<()> {
        self.tele_tx.update_connections()?;
        self.rollout_tx.update_connections()?;
        self.weights_tx.update_connections()?;
        Ok(())
    }

    fn run(&self, p: &Payload, test: u32, phase: Phase, m: u64) -> anyhow::Result<f64> {
        match p.kind {
            Kind::Telemetry => run_phase(
                &mut IpcLink {
                    tx: &self.tele_tx,
                    data: &self.ticks[..p.elements],
                    acks: &self.acks,
                },
                test,
                phase,
                m,
            ),
            Kind::Rollout => run_phase(
                &mut IpcLink {
                    tx: &self.rollout_tx,
                    data: &self.chunk[..p.elements],
                    acks: &self.acks,
                },
                test,
                phase,
                m,
            ),
            Kind::Weights => run_phase(
                &mut IpcLink {
                    tx: &self.weights_tx,
                    data: self.weights,
                    acks: &self.acks,
                },
                test,
                phase,
                m,
            ),
        }
    }
}

/// Which payload, transport and phase each test id is, and the throughput of each payload
/// and transport.
type Outcome = (Vec<(usize, bool, Phase)>, BTreeMap<(usize, bool), f64>);

/// Runs every test: per payload, iceoryx2 then the socket, latency then throughput, each
/// announced to the echo by a control frame on the socket.
fn run_tests(
    ipc: &IpcSide,
    stream: &mut UnixStream,
    payloads: &[Payload],
    m: u64,
    each: &mut dyn FnMut(&Payload),
) -> anyhow::Result<Outcome> {
    let mut tests = Vec::new();
    let mut rates = BTreeMap::new();
    for (i, p) in payloads.iter().enumerate() {
        for over_socket in [false, true] {
            for phase in [Phase::Latency, Phase::Throughput] {
                let test = u32::try_from(tests.len()).context("too many tests")?;
                tests.push((i, over_socket, phase));
                let flags =
                    CONTROL | if over_socket { OVER_SOCKET } else { 0 } | (p.kind.code() << 8);
                let mut control = [0u8; FRAME_HEADER];
                let stamp = Stamp {
                    seq: m,
                    sent_ns: 0,
                    test,
                    flags,
                };
                encode(&stamp, 0, &mut control);
                stream.write_all(&control).context("socket write")?;
                let rate = if over_socket {
                    let mut link = SocketLink {
                        stream: &mut *stream,
                        frame: vec![0u8; FRAME_HEADER + p.bytes()],
                    };
                    run_phase(&mut link, test, phase, m)?
                } else {
                    ipc.run(p, test, phase, m)?
                };
                if phase == Phase::Throughput {
                    rates.insert((i, over_socket), rate);
                }
            }
        }
        each(p);
    }
    Ok((tests, rates))
}

/// Runs the comparison from the launcher's side over run `bus` (whose id the echo joins):
/// spawns `lavatube bench-echo` from `launcher`, sends `weights` as the weight payload, calls
/// `each` after every payload.
pub fn compare(
    bus: &Bus,
    launcher: &Path,
    dir: &Path,
    payloads: &[Payload],
    messages: usize,
    weights: &[f32],
    each: &mut dyn FnMut(&Payload),
) -> anyhow::Result<Vec<TransportRow>> {
    let ipc = IpcSide::new(bus, payloads, weights)?;
    // Socket paths are limited to ~100 bytes: a short one in the temp directory.
    let sock = std::env::temp_dir().join(format!("lavatube-{}.sock", bus.run()));
    let _ = std::fs::remove_file(&sock);
    let listener =
        UnixListener::bind(&sock).with_context(|| format!("cannot bind {}", sock.display()))?;
    let out = dir.join("echo.json");
    let args: Vec<String> = vec![
        "bench-echo".into(),
        "--run-id".into(),
        bus.run().into(),
        "--socket".into(),
        sock.display().to_string(),
        "--out".into(),
        out.display().to_string(),
    ];
    let mut echo = Child::spawn("echo", launcher, &args, dir)?;
    let accepted = accept(&listener, &mut echo);
    let _ = std::fs::remove_file(&sock);
    let mut stream = accepted?;
    // The echo subscribed before connecting; make sure the publishers know.
    ipc.update_connections()?;
    let ran = run_tests(&ipc, &mut stream, payloads, messages as u64, each);
    drop(stream);
    // Closing the socket ends the echo; a test that failed because the echo died says how.
    let finished = echo.wait_for(TIMEOUT)?;
    if let Some(f) = echo.failure() {
        return Err(match ran {
            Err(e) => e.context(f),
            Ok(_) => anyhow::anyhow!(f),
        });
    }
    let (tests, rates) = ran?;
    if !finished {
        bail!(
            "the echo process did not finish; log: {}",
            echo.log.display()
        );
    }
    let latencies: BTreeMap<u32, Latency> = {
        let text = std::fs::read_to_string(&out)
            .with_context(|| format!("cannot read {}", out.display()))?;
        serde_json::from_str(&text).with_context(|| format!("cannot parse {}", out.display()))?
    };

    let mut rows = Vec::new();
    for (i, p) in payloads.iter().enumerate() {
        let link = |over_socket: bool| -> anyhow::Result<LinkResult> {
            let test = tests
                .iter()
                .position(|t| *t == (i, over_socket, Phase::Latency))
                .and_then(|t| u32::try_from(t).ok())
                .context("latency test missing")?;
            let l = latencies
                .get(&test)
                .with_context(|| format!("the echo recorded no latencies for test {test}"))?;
            Ok(LinkResult {
                latency_p50_us: l.p50_us,
                latency_p99_us: l.p99_us,
                messages_per_s: rates
                    .get(&(i, over_socket))
                    .copied()
                    .context("throughput missing")?,
            })
        };
        let (shm, uds) = (link(false)?, link(true)?);
        rows.push(TransportRow {
            payload: p.kind,
            envs: p.envs,
            elements: p.elements,
            bytes: p.bytes(),
            messages,
            iceoryx2: shm,
            uds,
            ratios: Ratios {
                latency_p50_uds_over_iceoryx2: uds.latency_p50_us / shm.latency_p50_us,
                latency_p99_uds_over_iceoryx2: uds.latency_p99_us / shm.latency_p99_us,
                messages_per_s_iceoryx2_over_uds: shm.messages_per_s / uds.messages_per_s,
            },
        });
    }
    Ok(rows)
}

#[derive(Debug, clap::Args)]
pub struct EchoArgs {
    /// The bench run whose `bench/*` services to read.
    #[arg(long, value_parser = common::cli::parse_run_id)]
    pub run_id: String,
    /// The launcher's socket.
    #[arg(long)]
    pub socket: PathBuf,
    /// Where to write the recorded latencies (JSON) when the launcher closes the socket.
    #[arg(long)]
    pub out: PathBuf,
}

/// Receives the `count` messages of iceoryx2 test `test`; the recorded latencies,
/// nanoseconds. Takes no more: the launcher starts the next test on the same service as soon
/// as it has the last acknowledgement, so its first messages may already be waiting.
fn serve_ipc<T: std::fmt::Debug + Copy + ZeroCopySend + 'static>(
    rx: &Receiver<T, Stamp>,
    acks: &Sender<u64, Stamp>,
    test: u32,
    count: u64,
) -> anyhow::Result<Vec<u64>> {
    let mut latencies = Vec::new();
    let (mut got, mut progress) = (0u64, Instant::now());
    while got < count {
        while got < count
            && let Some(s) = rx.try_recv()?
        {
            let now = wire::monotonic_ns();
            let st = *s.user_header();
            drop(s);
            ensure!(
                st.test == test,
                "test {test}: got a message of test {}",
                st.test
            );
            got += 1;
            progress = Instant::now();
            if st.flags & RECORD != 0 {
                latencies.push(now.saturating_sub(st.sent_ns));
            }
            if st.flags & ACK != 0 {
                acks.send(st, &[got])?;
            }
        }
        if got < count {
            if progress.elapsed() > TIMEOUT {
                bail!("test {got}/{count}: nothing arrived over iceoryx2 for {TIMEOUT:?}");
            }
            rx.wait(Duration::from_millis(100))?;
        }
    }
    Ok(latencies)
}

/// Receives `count` frames of one socket test; the recorded latencies, nanoseconds.
fn serve_socket(
    stream: &mut UnixStream,
    buf: &mut Vec<u8>,
    count: u64,
) -> anyhow::Result<Vec<u64>> {
    let mut latencies = Vec::new();
    for got in 1..=count {
        let (st, len) = read_header(stream)?.context("the socket closed mid-test")?;
        buf.resize(len, 0);
        stream.read_exact(buf).context("socket read")?;
        let now = wire::monotonic_ns();
        if st.flags & RECORD != 0 {
            latencies.push(now.saturating_sub(st.sent_ns));
        }
        if st.flags & ACK != 0 {
            stream
                .write_all(&got.to_le_bytes())
                .context("socket write")?;
        }
    }
    Ok(latencies)
}

/// `lavatube bench-echo`: the receiving process of the comparison.
pub fn echo(args: EchoArgs) -> anyhow::Result<ExitCode> {
    let bus = Bus::connect(&args.run_id, "bench-echo")?;
    let tele = bus.receiver::<EnvTick, Stamp>(&TELEMETRY, None)?;
    let rollout = bus.receiver::<Transition, Stamp>(&ROLLOUT, None)?;
    let weights = bus.receiver::<f32, Stamp>(&WEIGHTS, None)?;
    let acks = bus.sender::<u64, Stamp>(&ACKS, None, 1)?;
    // Connecting tells the launcher every subscriber above exists.
    let mut stream = UnixStream::connect(&args.socket)
        .with_context(|| format!("cannot connect to {}", args.socket.display()))?;
    stream
        .set_read_timeout(Some(TIMEOUT))
        .context("socket timeout")?;
    let mut buf = Vec::new();
    let mut results: BTreeMap<u32, Latency> = BTreeMap::new();
    while let Some((control, _)) = read_header(&mut stream)? {
        ensure!(control.flags & CONTROL != 0, "expected a control frame");
        let count = control.seq;
        let mut ns = if control.flags & OVER_SOCKET != 0 {
            serve_socket(&mut stream, &mut buf, count)?
        } else {
            match Kind::from_code((control.flags >> 8) & 0xff)? {
                Kind::Telemetry => serve_ipc(&tele, &acks, control.test, count)?,
                Kind::Rollout => serve_ipc(&rollout, &acks, control.test, count)?,
                Kind::Weights => serve_ipc(&weights, &acks, control.test, count)?,
            }
        };
        ns.sort_unstable();
        if let (Some(p50_us), Some(p99_us)) = (percentile_us(&ns, 0.5), percentile_us(&ns, 0.99)) {
            results.insert(
                control.test,
                Latency {
                    count: ns.len(),
                    p50_us,
                    p99_us,
                },
            );
        }
    }
    std::fs::write(&args.out, serde_json::to_string_pretty(&results)?)
        .with_context(|| format!("cannot write {}", args.out.display()))?;
    Ok(ExitCode::SUCCESS)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::mem::{align_of, offset_of};

    #[test]
    fn stamp_layout() {
        let msg = "layout changed: bump the version in the type name";
        assert_eq!((size_of::<Stamp>(), align_of::<Stamp>()), (24, 8), "{msg}");
        assert_eq!(offset_of!(Stamp, test), 16, "{msg}");
        assert_eq!(offset_of!(Stamp, flags), 20, "{msg}");
    }

    #[test]
    fn a_frame_header_round_trips() {
        let (a, b) = UnixStream::pair().expect("pair");
        let stamp = Stamp {
            seq: 7,
            sent_ns: 1 << 40,
            test: 3,
            flags: CONTROL | OVER_SOCKET | (Kind::Weights.code() << 8),
        };
        let mut h = [0u8; FRAME_HEADER];
        encode(&stamp, 4096, &mut h);
        (&a).write_all(&h).expect("write");
        drop(a);
        let mut b = b;
        assert_eq!(read_header(&mut b).expect("read"), Some((stamp, 4096)));
        assert_eq!(
            read_header(&mut b).expect("eof"),
            None,
            "a closed socket ends the echo"
        );
        assert_eq!(
            Kind::from_code((stamp.flags >> 8) & 0xff).expect("kind"),
            Kind::Weights
        );
    }

    /// Both transports through both phases inside one process: every message acknowledged,
    /// every recorded latency positive.
    #[test]
    fn both_links_deliver_every_message() {
        let run = format!("bt{}", std::process::id());
        let bus = Bus::connect(&run, "test").expect("node");
        let rx = bus.receiver::<f32, Stamp>(&WEIGHTS, None).expect("rx");
        let acks_rx = bus.receiver::<u64, Stamp>(&ACKS, None).expect("acks rx");
        let tx = bus.sender::<f32, Stamp>(&WEIGHTS, None, 64).expect("tx");
        let acks_tx = bus.sender::<u64, Stamp>(&ACKS, None, 1).expect("acks tx");
        let data = vec![0.5f32; 64];
        let (mut a, mut b) = UnixStream::pair().expect("pair");
        let echo = std::thread::spawn(move || {
            let mut buf = Vec::new();
            let lat = serve_socket(&mut b, &mut buf, 100).expect("latency");
            let thr = serve_socket(&mut b, &mut buf, 100).expect("throughput");
            (lat.len(), thr.len())
        });
        let mut link = SocketLink {
            stream: &mut a,
            frame: vec![1u8; FRAME_HEADER + 256],
        };
        assert!(run_phase(&mut link, 0, Phase::Latency, 100).expect("latency") > 0.0);
        assert!(run_phase(&mut link, 1, Phase::Throughput, 100).expect("throughput") > 0.0);
        assert_eq!(
            echo.join().expect("echo"),
            (90, 0),
            "warm-up and throughput unrecorded"
        );

        // iceoryx2 ports hold an Rc: echo and sender interleave on this thread, one
        // latency-phase message at a time.
        let mut link = IpcLink {
            tx: &tx,
            data: &data,
            acks: &acks_rx,
        };
        for seq in 0..3 {
            link.send(Stamp {
                seq,
                sent_ns: wire::monotonic_ns(),
                test: 2,
                flags: RECORD | ACK,
            })
            .expect("send");
            let lat = serve_ipc(&rx, &acks_tx, 2, 1).expect("echo");
            assert_eq!(lat.len(), 1);
            assert_eq!(link.acked().expect("ack"), 1);
        }
        drop((tx, rx, acks_tx, acks_rx, bus));
        common::ipc::remove_run(&run).expect("clean");
    }
}
