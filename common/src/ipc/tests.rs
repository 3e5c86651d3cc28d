//! Channels, control and cleanup against real iceoryx2 services of throwaway runs.

use super::*;
use crate::wire::TickHeader;
use iceoryx2::prelude::ZeroCopySend;
use std::fmt::Debug;
use std::time::Duration;

/// Bare numbers under a tick header, on a service of their own, sized like [`TELEMETRY`]
/// (which carries `EnvTick`s).
const TICKS: Channel<u32, TickHeader> = Channel::new("test/ticks", TELEMETRY.capacity);

#[test]
fn run_ids_are_checked() {
    assert!(validate_run_id("run-1a").is_ok());
    assert!(validate_run_id("run_1").is_err());
    assert!(validate_run_id("").is_err());
    assert!(validate_run_id("a/b").is_err());
    assert!(validate_run_id(&"x".repeat(33)).is_err());
}

#[test]
fn a_shutdown_request_reaches_a_listener() {
    let run = format!("c{}", std::process::id());
    let bus = Bus::connect(&run, "test").expect("node");
    // The launcher's notifier exists before the processes' listeners.
    let notifier = bus.control_notifier().expect("notifier");
    let listener = bus.control_listener().expect("listener");
    assert!(!bus.stop_requested(&listener));
    request_shutdown(&notifier).expect("notify");
    assert!(bus.stop_requested(&listener));
    drop((notifier, listener, bus));
    remove_run(&run).expect("clean");
}

#[test]
fn a_late_subscriber_gets_the_last_policy_once_the_publisher_updates() {
    let run = format!("h{}", std::process::id());
    let bus = Bus::connect(&run, "test").expect("node");
    let tx: Sender<f32, crate::wire::PolicyHeader> =
        bus.sender(&POLICY, Some("general"), 3).expect("sender");
    let header = crate::wire::PolicyHeader {
        version: 4,
        ..Default::default()
    };
    tx.send(header, &[1.0, 2.0, 3.0]).expect("send");
    // The sim connects after the learner published, then the learner idles.
    let rx: Receiver<f32, crate::wire::PolicyHeader> =
        bus.receiver(&POLICY, Some("general")).expect("receiver");
    tx.update_connections().expect("update");
    let s = rx
        .latest()
        .expect("receive")
        .expect("history delivers the last policy");
    assert_eq!(
        (s.user_header().version, s.payload()),
        (4, &[1.0f32, 2.0, 3.0][..])
    );
    drop((s, rx, tx, bus));
    remove_run(&run).expect("clean");
}

#[test]
fn a_slice_with_its_header_crosses_a_channel() {
    let run = format!("t{}", std::process::id());
    let bus = Bus::connect(&run, "test").expect("node");
    let rx: Receiver<u32, TickHeader> = bus.receiver(&TICKS, None).expect("receiver");
    let tx: Sender<u32, TickHeader> = bus.sender(&TICKS, None, 4).expect("sender");
    let header = TickHeader {
        tick: 7,
        envs: 3,
        ..Default::default()
    };
    tx.send(header, &[1, 2, 3]).expect("send");
    rx.wait(Duration::from_secs(1)).expect("wait");
    let s = rx.try_recv().expect("receive").expect("a sample");
    assert_eq!((s.user_header().tick, s.payload()), (7, &[1u32, 2, 3][..]));
    // Longer than the initial max: the publisher grows its segment.
    tx.send(header, &[9; 100]).expect("send grown");
    assert_eq!(
        rx.latest()
            .expect("receive")
            .expect("a sample")
            .payload()
            .len(),
        100
    );
    drop(s);
    let nodes = list_nodes(&run).expect("list");
    assert_eq!(nodes.len(), 1);
    assert!(nodes[0].alive && nodes[0].name == "test");
    assert!(remove_run(&run).is_err(), "refuses while a node is alive");
    drop((tx, rx, bus));
    assert!(
        !run_files(&run).is_empty(),
        "iceoryx2 keeps its global segment"
    );
    assert!(runs_with_files().contains(&run));
    remove_run(&run).expect("clean");
    assert!(run_files(&run).is_empty(), "{:?}", run_files(&run));
}

/// Wake-ups the listener has pending (drains them).
fn wakeups<T, H>(rx: &Receiver<T, H>) -> usize
where
    T: Debug + Copy + ZeroCopySend + 'static,
    H: Debug + Copy + ZeroCopySend + 'static,
{
    let mut n = 0;
    rx.listener().try_wait(|_| n += 1).expect("try_wait");
    n
}

#[test]
fn a_wake_interval_batches_wakeups_but_delivers_every_sample() {
    let run = format!("w{}", std::process::id());
    let bus = Bus::connect(&run, "test").expect("node");
    let rx: Receiver<u32, TickHeader> = bus.receiver(&TICKS, None).expect("receiver");
    let interval = Duration::from_millis(200);
    let tx: Sender<u32, TickHeader> = bus
        .sender(&TICKS, None, 1)
        .expect("sender")
        .with_wake_interval(interval);
    let send = |tick| {
        let h = TickHeader {
            tick,
            ..Default::default()
        };
        tx.send(h, &[tick as u32]).expect("send");
    };
    send(0);
    assert_eq!(wakeups(&rx), 1, "the first send wakes");
    send(1);
    send(2);
    assert_eq!(wakeups(&rx), 0, "sends within the interval do not");
    tx.flush().expect("flush");
    assert_eq!(wakeups(&rx), 1, "flush wakes for the pending sends");
    tx.flush().expect("flush");
    assert_eq!(wakeups(&rx), 0, "nothing pending, no wake-up");
    std::thread::sleep(interval);
    send(3);
    assert_eq!(wakeups(&rx), 1, "a send after the interval wakes");
    let mut ticks = Vec::new();
    while let Some(s) = rx.try_recv().expect("receive") {
        ticks.push(s.user_header().tick);
    }
    assert_eq!(ticks, [0, 1, 2, 3]);
    drop((tx, rx, bus));
    remove_run(&run).expect("clean");
}
