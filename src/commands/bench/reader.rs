//! `lavatube bench-reader` (hidden): the subscriber process of stages c–f. It reads every
//! telemetry tick and rollout chunk of a run, event-woken like the runtime's own readers,
//! and reports what arrived, what was missed, the sim's stepping rate from the ticks' send
//! timestamps, and the transport latency per tick.

use anyhow::Context;
use common::Transition;
use common::ipc::{self, Bus, Receiver};
use common::wire::{self, EnvTick, RolloutHeader, TickHeader};
use serde::{Deserialize, Serialize};
use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Duration;

#[derive(Debug, clap::Args)]
pub struct ReaderArgs {
    /// The run to read.
    #[arg(long, value_parser = common::cli::parse_run_id)]
    pub run_id: String,
    /// Where to write the result (JSON) once a shutdown is requested.
    #[arg(long)]
    pub out: PathBuf,
    /// Created once subscribed, so the bench starts the sim only when no tick can be missed.
    #[arg(long)]
    pub ready: PathBuf,
}

/// What the reader saw.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct ReaderResult {
    /// Telemetry ticks and rollout chunks read (the bench compares them with what the sim
    /// sent), and the transitions in those chunks.
    pub ticks: u64,
    pub chunks: u64,
    pub transitions: u64,
    /// Episode ends seen in the telemetry (proof every env's entry was read).
    pub episode_ends: u64,
    /// Env steps over which the rate below was taken, and the rate: from the first tick of
    /// the first chunk to the first tick of the last, i.e. whole chunk cycles (in sync mode
    /// each includes one wait for the learner), by the sim's own send timestamps.
    pub measured_env_steps: u64,
    pub decision_steps_per_s: Option<f64>,
    pub latency_p50_us: Option<f64>,
    pub latency_p99_us: Option<f64>,
    pub latency_max_us: Option<f64>,
}

/// Nearest-rank percentile `q` (0–1) of sorted nanoseconds, in microseconds.
pub fn percentile_us(sorted_ns: &[u64], q: f64) -> Option<f64> {
    if sorted_ns.is_empty() {
        return None;
    }
    let rank = ((q * sorted_ns.len() as f64).ceil() as usize).clamp(1, sorted_ns.len());
    Some(sorted_ns[rank - 1] as f64 / 1e3)
}

/// Running tallies of the reader.
#[derive(Debug, Default)]
struct Tally {
    result: ReaderResult,
    /// Per tick received: (tick, env steps, send time).
    sent: Vec<(u64, u64, u64)>,
    latencies_ns: Vec<u64>,
    rollout_steps: Option<u64>,
}

impl Tally {
    fn tick(&mut self, h: &TickHeader, envs: &[EnvTick], received_ns: u64) {
        let r = &mut self.result;
        r.ticks += 1;
        let ends = wire::EVENT_TERMINATED | wire::EVENT_TRUNCATED;
        r.episode_ends += envs.iter().filter(|t| t.events & ends != 0).count() as u64;
        self.latencies_ns
            .push(received_ns.saturating_sub(h.sent_ns));
        self.sent.push((h.tick, h.env_steps, h.sent_ns));
    }

    fn chunk(&mut self, h: &RolloutHeader, len: usize) {
        let r = &mut self.result;
        self.rollout_steps = Some(u64::from(h.steps));
        r.chunks += 1;
        r.transitions += len as u64;
    }

    /// Reads everything buffered; whether anything was.
    fn drain(
        &mut self,
        tele: &Receiver<EnvTick, TickHeader>,
        rollout: &Receiver<Transition, RolloutHeader>,
    ) -> anyhow::Result<bool> {
        let mut got = false;
        while let Some(s) = tele.try_recv()? {
            got = true;
            self.tick(s.user_header(), s.payload(), wire::monotonic_ns());
        }
        let mut chunks = false;
        while let Some(s) = rollout.try_recv()? {
            chunks = true;
            self.chunk(s.user_header(), s.payload().len());
        }
        if chunks {
            // Chunks are found on telemetry's wake-ups; their own are only cleared.
            rollout
                .listener()
                .try_wait(|_| {})
                .map_err(|e| anyhow::anyhow!("rollout events: {e:?}"))?;
        }
        Ok(got || chunks)
    }

    fn finish(mut self) -> ReaderResult {
        self.latencies_ns.sort_unstable();
        let r = &mut self.result;
        r.latency_p50_us = percentile_us(&self.latencies_ns, 0.50);
        r.latency_p99_us = percentile_us(&self.latencies_ns, 0.99);
        r.latency_max_us = percentile_us(&self.latencies_ns, 1.0);
        // Whole chunk cycles when there are two chunk starts; else first to last tick.
        let starts: Vec<(u64, u64, u64)> = match self.rollout_steps {
            Some(t) if t > 0 => self.sent.iter().copied().filter(|s| s.0 % t == 0).collect(),
            _ => Vec::new(),
        };
        let ends = if starts.len() >= 2 {
            &starts
        } else {
            &self.sent
        };
        let span = ends.first().zip(ends.last());
        if let Some((a, b)) = span
            && b.2 > a.2
        {
            r.measured_env_steps = b.1 - a.1;
            r.decision_steps_per_s = Some((b.1 - a.1) as f64 / ((b.2 - a.2) as f64 * 1e-9));
        }
        self.result
    }
}

pub fn reader(args: ReaderArgs) -> anyhow::Result<ExitCode> {
    let bus = Bus::connect(&args.run_id, "bench-reader")?;
    let control = bus.control_listener()?;
    let tele = bus.receiver::<EnvTick, TickHeader>(&ipc::TELEMETRY, None)?;
    let rollout = bus.receiver::<Transition, RolloutHeader>(&ipc::ROLLOUT, None)?;
    std::fs::write(&args.ready, b"")
        .with_context(|| format!("cannot write {}", args.ready.display()))?;
    let mut tally = Tally::default();
    loop {
        // Telemetry comes every tick and each chunk right after its last tick, so waking on
        // telemetry alone finds every chunk.
        tele.wait(Duration::from_millis(50))?;
        // The shutdown request comes once the sim is done, so it is looked for only when
        // nothing arrived: that costs no syscalls per tick, which stage c would pay for.
        if !tally.drain(&tele, &rollout)? && bus.stop_requested(&control) {
            tally.drain(&tele, &rollout)?;
            break;
        }
    }
    let result = tally.finish();
    std::fs::write(&args.out, serde_json::to_string_pretty(&result)?)
        .with_context(|| format!("cannot write {}", args.out.display()))?;
    Ok(ExitCode::SUCCESS)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn percentiles_are_nearest_rank() {
        let v: Vec<u64> = (1..=100).map(|i| i * 1000).collect();
        assert_eq!(percentile_us(&v, 0.5), Some(50.0));
        assert_eq!(percentile_us(&v, 0.99), Some(99.0));
        assert_eq!(percentile_us(&v, 1.0), Some(100.0));
        assert_eq!(percentile_us(&[7000], 0.99), Some(7.0));
        assert_eq!(percentile_us(&[], 0.5), None);
    }

    #[test]
    fn the_rate_spans_whole_chunk_cycles() {
        let mut t = Tally::default();
        let tick = |tick: u64, sent_ns| TickHeader {
            tick,
            env_steps: (tick + 1) * 2,
            sent_ns,
            ..TickHeader::default()
        };
        // 2 envs, 4 ticks per chunk; chunk 0 at 1 ms per tick, then a 10 ms learner wait.
        for (k, sent) in [(0, 0), (1, 1), (2, 2), (3, 3), (4, 14), (5, 15), (7, 17)] {
            t.tick(
                &tick(k, sent * 1_000_000),
                &[EnvTick::default(); 2],
                sent * 1_000_000 + 5000,
            );
        }
        let chunk = |chunk| RolloutHeader {
            chunk,
            steps: 4,
            envs: 2,
            ..RolloutHeader::default()
        };
        t.chunk(&chunk(0), 10);
        t.chunk(&chunk(1), 10);
        let r = t.finish();
        assert_eq!((r.ticks, r.chunks, r.transitions), (7, 2, 20));
        // Ticks 0 and 4 start chunks: 8 env steps in 14 ms.
        assert_eq!(r.measured_env_steps, 8);
        let rate = r.decision_steps_per_s.expect("rate");
        assert!((rate - 8.0 / 0.014).abs() < 1e-6, "{rate}");
        assert_eq!(r.latency_p50_us, Some(5.0));
    }
}
