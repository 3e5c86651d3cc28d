//! Shared-memory round trip: publish a message through `common::ipc` (loan, copy in, send,
//! event notify) and receive it on a subscriber in the same process, for the three payloads
//! the runtime moves: a telemetry tick (8 envs), a rollout chunk (2048 + 8 transitions) and
//! a policy (the default 128-128 actor). This is the per-message cost the simulator pays on
//! its hot path; `lavatube bench` measures the same between two processes and against a Unix
//! socket.

use common::ipc::{self, Bus, Channel};
use common::wire::EnvTick;
use common::{ACT_DIM, OBS_DIM, PolicyLayout, Transition};
use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use iceoryx2::prelude::ZeroCopySend;
use std::fmt::Debug;
use std::hint::black_box;

fn round_trip<T, H>(c: &mut Criterion, bus: &Bus, name: &str, channel: &Channel<T, H>, data: &[T])
where
    T: Debug + Copy + Default + ZeroCopySend + 'static,
    H: Debug + Copy + Default + ZeroCopySend + 'static,
{
    let rx = bus.receiver(channel, None).expect("receiver");
    let tx = bus.sender(channel, None, data.len()).expect("sender");
    let bytes = std::mem::size_of_val(data) as u64;
    let mut g = c.benchmark_group("shm_round_trip");
    g.throughput(Throughput::Bytes(bytes));
    g.bench_function(format!("{name} ({bytes} B)"), |b| {
        b.iter(|| {
            tx.send(H::default(), black_box(data)).expect("send");
            let s = rx.try_recv().expect("receive").expect("a sample");
            black_box(s.payload().len());
        });
    });
    g.finish();
}

fn bench(c: &mut Criterion) {
    let run = format!("benchipc-{}", std::process::id());
    let bus = Bus::connect(&run, "bench").expect("node");
    let ticks = [EnvTick::default(); 8];
    round_trip(c, &bus, "telemetry tick", &ipc::TELEMETRY, &ticks);
    let chunk = vec![Transition::default(); 2048 + 8];
    round_trip(c, &bus, "rollout chunk", &ipc::ROLLOUT, &chunk);
    let policy = vec![0.5f32; PolicyLayout::new(OBS_DIM, &[128, 128], ACT_DIM).len()];
    round_trip(c, &bus, "policy", &ipc::POLICY, &policy);
    drop(bus);
    if let Err(e) = ipc::remove_run(&run) {
        eprintln!("cannot clean up {run}: {e}");
    }
}

criterion_group!(benches, bench);
criterion_main!(benches);
