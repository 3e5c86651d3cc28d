//! `lavatube bench-echo`: the receiving process of the transport comparison. It reads
//! every message of each test from iceoryx2 or the socket, acknowledges as asked, and writes
//! the one-way latencies it recorded when the launcher closes the socket.

use super::link::read_header;
use super::protocol::{
    ACK, ACKS, CONTROL, Kind, Latency, OVER_SOCKET, RECORD, ROLLOUT, Stamp, TELEMETRY, TIMEOUT,
    WEIGHTS,
};
use crate::commands::bench::reader::percentile_us;
use anyhow::{Context, bail, ensure};
use common::Transition;
use common::ipc::{Bus, Receiver, Sender};
use common::wire::{self, EnvTick};
use iceoryx2::prelude::ZeroCopySend;
use std::collections::BTreeMap;
use std::io::{Read, Write};
use std::os::unix::net::UnixStream;
use std::path::PathBuf;
use std::process::ExitCode;
use std::time::{Duration, Instant};

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
pub(super) fn serve_ipc<T: std::fmt::Debug + Copy + ZeroCopySend + 'static>(
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
pub(super) fn serve_socket(
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
