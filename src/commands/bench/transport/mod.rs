//! The same bytes between the same two processes over iceoryx2 (the
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

mod echo;
mod link;
mod protocol;

pub use echo::{EchoArgs, echo};
pub use protocol::Kind;

use super::files::read_json;
use crate::runtime::{Child, Output, Role};
use anyhow::{Context, bail};
use common::Transition;
use common::ipc::{Bus, Receiver, Sender};
use common::wire::{self, EnvTick};
use link::{FRAME_HEADER, IpcLink, Link, SocketLink, encode};
use protocol::{
    ACK, ACK_EVERY, ACKS, CONTROL, Latency, OVER_SOCKET, RECORD, ROLLOUT, Stamp, TELEMETRY,
    TIMEOUT, WEIGHTS, WINDOW,
};
use serde::Serialize;
use std::collections::BTreeMap;
use std::io::{ErrorKind, Write};
use std::os::unix::net::{UnixListener, UnixStream};
use std::path::Path;
use std::time::{Duration, Instant};

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
        if echo.poll()?.is_some() {
            bail!(
                "the echo process exited before connecting; log: {}",
                echo.log().display()
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
    let out = dir.join("echo.json");
    let (mut echo, mut stream) = start_echo(bus, launcher, dir, &out)?;
    // The echo subscribed before connecting; make sure the publishers know.
    ipc.update_connections()?;
    let ran = run_tests(&ipc, &mut stream, payloads, messages as u64, each);
    drop(stream);
    let outcome = echo_finished(&mut echo, ran)?;
    let latencies: BTreeMap<u32, Latency> = read_json(&out)?;
    payloads
        .iter()
        .enumerate()
        .map(|(i, p)| {
            let (shm, uds) = (
                link_result(i, false, &outcome, &latencies)?,
                link_result(i, true, &outcome, &latencies)?,
            );
            Ok(TransportRow {
                payload: p.kind,
                envs: p.envs,
                elements: p.elements,
                bytes: p.bytes(),
                messages,
                iceoryx2: shm,
                uds,
                ratios: Ratios::of(shm, uds),
            })
        })
        .collect()
}

/// Spawns `lavatube bench-echo` from `launcher` on run `bus`, its latencies to go to `out`,
/// and accepts its connection on a socket of its own; the echo and the connection.
fn start_echo(
    bus: &Bus,
    launcher: &Path,
    dir: &Path,
    out: &Path,
) -> anyhow::Result<(Child, UnixStream)> {
    // Socket paths are limited to ~100 bytes: a short one in the temp directory.
    let sock = std::env::temp_dir().join(format!("lavatube-{}.sock", bus.run()));
    let _ = std::fs::remove_file(&sock);
    let listener =
        UnixListener::bind(&sock).with_context(|| format!("cannot bind {}", sock.display()))?;
    let args: Vec<String> = vec![
        "bench-echo".into(),
        "--run-id".into(),
        bus.run().into(),
        "--socket".into(),
        sock.display().to_string(),
        "--out".into(),
        out.display().to_string(),
    ];
    let mut echo = Child::spawn(Role::Echo.name(), launcher, &args, dir, Output::File)?;
    let accepted = accept(&listener, &mut echo);
    let _ = std::fs::remove_file(&sock);
    Ok((echo, accepted?))
}

/// Waits for the echo to end, which closing the socket asks of it; the tests' outcome. A
/// test that failed because the echo died says how.
fn echo_finished(echo: &mut Child, ran: anyhow::Result<Outcome>) -> anyhow::Result<Outcome> {
    let finished = echo.wait_for(TIMEOUT)?;
    if let Some(f) = echo.failure() {
        return Err(match ran {
            Err(e) => e.context(f),
            Ok(_) => anyhow::anyhow!(f),
        });
    }
    let outcome = ran?;
    if !finished {
        bail!(
            "the echo process did not finish; log: {}",
            echo.log().display()
        );
    }
    Ok(outcome)
}

/// Payload `i`'s numbers over one transport: the latencies the echo recorded in its latency
/// test, the throughput measured here.
fn link_result(
    i: usize,
    over_socket: bool,
    (tests, rates): &Outcome,
    latencies: &BTreeMap<u32, Latency>,
) -> anyhow::Result<LinkResult> {
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
}

impl Ratios {
    /// How `uds` compares with `shm` (iceoryx2) for one payload.
    fn of(shm: LinkResult, uds: LinkResult) -> Self {
        Self {
            latency_p50_uds_over_iceoryx2: uds.latency_p50_us / shm.latency_p50_us,
            latency_p99_uds_over_iceoryx2: uds.latency_p99_us / shm.latency_p99_us,
            messages_per_s_iceoryx2_over_uds: shm.messages_per_s / uds.messages_per_s,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::echo::{serve_ipc, serve_socket};
    use super::link::read_header;
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
