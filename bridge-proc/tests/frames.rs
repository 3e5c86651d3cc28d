//! A learner host's bridge, run as its real process, against what reaches it (DESIGN §9): a
//! connection without the run's credentials is not let in; from one with them, frames with a
//! wrong key, of another kind, of other message types, with non-finite numbers, sealed for
//! another start of the run, sent again, under another source, or past a source's share of a second
//! are refused and counted, and a genuine chunk sent among them still reaches the learner
//! host's shared memory, bit for bit, once.

use bridge_proc::frame::{Key, Kind, Sealer};
use bridge_proc::link;
use common::ipc::{self, Bus};
use common::wire::{PolicyHeader, RolloutHeader};
use common::{Config, Transition};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};
use zenoh::Wait;
use zenoh::qos::CongestionControl;

const SECRET: &[u8] = b"the shared key of this test's run, 32+ bytes";

/// Fails the test after `limit` instead of hanging.
fn until(limit: Duration, what: &str, mut done: impl FnMut() -> bool) {
    let started = Instant::now();
    while !done() {
        assert!(started.elapsed() < limit, "{what}: not within {limit:?}");
        std::thread::sleep(Duration::from_millis(20));
    }
}

/// A publisher of source `source`'s rollout frames, once the bridge subscribes to it.
fn rollout_publisher(net: &zenoh::Session, source: u32) -> zenoh::pubsub::Publisher<'static> {
    let publisher = net
        .declare_publisher(link::rollout_key(source))
        .congestion_control(CongestionControl::Block)
        .wait()
        .expect("publisher");
    until(Duration::from_secs(30), "the bridge subscribed", || {
        publisher
            .matching_status()
            .wait()
            .is_ok_and(|m| m.matching())
    });
    publisher
}

#[test]
fn frames_from_outside_the_run_are_refused_and_counted_while_genuine_ones_get_through() {
    let dir = tempfile::tempdir().expect("tempdir");
    let key_file = dir.path().join("run.key");
    std::fs::write(&key_file, SECRET).expect("key");
    let config = dir.path().join("config.toml");
    std::fs::write(
        &config,
        format!("[net]\nkey-file = {:?}\n", key_file.display().to_string()),
    )
    .expect("config");
    let cfg = Config::load(&config).expect("config");
    let port = std::net::TcpListener::bind("127.0.0.1:0")
        .and_then(|l| l.local_addr())
        .expect("a free port")
        .port();
    let endpoint = format!("tcp/127.0.0.1:{port}");
    let run = format!("frames-{}", std::process::id());

    let bus = Bus::connect(&run, "test").expect("node");
    let chunks = bus.receiver(&ipc::ROLLOUT, None).expect("rollout receiver");
    let control = bus.control_notifier().expect("control");
    let log_path = dir.path().join("bridge.log");
    let log = std::fs::File::create(&log_path).expect("log");
    let mut bridge = Command::new(env!("CARGO_BIN_EXE_bridge-proc"))
        .args([
            "learner",
            "--config",
            &config.display().to_string(),
            "--run-id",
            &run,
        ])
        .args(["--listen", &endpoint])
        .stdout(Stdio::null())
        .stderr(Stdio::from(log))
        .spawn()
        .expect("bridge-proc starts");

    // Without the run's credentials, or with another run's, no connection opens.
    for (who, password) in [("no", None), ("wrong", Some("another run's password"))] {
        let mut outsider = zenoh::Config::default();
        let mut settings = vec![
            ("mode", "\"client\"".to_string()),
            ("connect/endpoints", format!("[\"{endpoint}\"]")),
            ("connect/timeout_ms", "3000".to_string()),
            ("scouting/multicast/enabled", "false".to_string()),
        ];
        if let Some(p) = password {
            settings.push((
                "transport/auth/usrpwd",
                format!("{{user: \"lavatube\", password: \"{p}\"}}"),
            ));
        }
        for (k, v) in settings {
            outsider.insert_json5(k, &v).expect("outsider config");
        }
        assert!(
            zenoh::open(outsider).wait().is_err(),
            "a connection with {who} credentials was let in"
        );
    }

    let net = link::connect(&endpoint, &link::Credentials::new(SECRET)).expect("net");
    let learner = link::watch_tokens(&net, link::LEARNER_ALL, 8).expect("tokens");
    let mut start = None;
    until(Duration::from_secs(30), "the learner host's start", || {
        if let Ok(Some(s)) = learner.try_recv() {
            start = link::token_start(s.key_expr().as_str());
        }
        start.is_some()
    });
    let start = start.expect("a start");
    let publisher = rollout_publisher(&net, 1);

    let n = cfg.sim.num_envs();
    let t = cfg.ppo.rollout_steps(n);
    let header = RolloutHeader {
        chunk: 0,
        env_steps: (t * n) as u64,
        steps: t as u32,
        envs: n as u32,
        source: 1,
        _reserved: 0,
    };
    let good: Vec<Transition> = (0..t * n + n)
        .map(|i| Transition {
            env: (i % n) as u32,
            reward: i as f32 * 1e-3,
            ..Transition::default()
        })
        .collect();
    let mut nan = good.clone();
    nan[3].reward = f32::NAN;
    let ours = Key::new(SECRET);
    let mut sealer = Sealer::new(&ours, Kind::Rollout, 1);
    let (nan_frame, genuine) = (
        sealer.seal(start, &header, &nan),
        sealer.seal(start, &header, &good),
    );
    // The next chunk of the stream closes the test's frames: once it is through, the bridge
    // has read every frame sent before it on this key.
    let last = RolloutHeader {
        chunk: 1,
        env_steps: 2 * header.env_steps,
        ..header
    };
    let closing = sealer.seal(start, &last, &good);
    let frames = [
        Sealer::new(&Key::new(&[9u8; 32]), Kind::Rollout, 1).seal(start, &header, &good),
        Sealer::new(&ours, Kind::Policy, 1).seal(start, &header, &good),
        Sealer::new(&ours, Kind::Rollout, 1).seal(start, &PolicyHeader::default(), &[0.5f32; 8]),
        Sealer::new(&ours, Kind::Rollout, 1).seal(start ^ 1, &header, &good),
        // The NaN chunk is frame 0 of its sender's stream, so the genuine chunk's 1 follows
        // it and no frame counts as lost; both again, as a recorder of the link would send them.
        nan_frame.clone(),
        genuine.clone(),
        genuine.clone(),
        nan_frame,
        closing,
    ];
    // First the genuine frame under another sim host's key expression.
    let elsewhere = rollout_publisher(&net, 2);
    elsewhere.put(genuine.clone()).wait().expect("put");
    // A flood from one source is read no further than its share (`net.source-frames-per-s`,
    // 200) per second.
    let flood = net
        .declare_publisher(link::rollout_key(3))
        .congestion_control(CongestionControl::Block)
        .wait()
        .expect("publisher");
    for i in 0..1000u32 {
        flood.put(i.to_le_bytes().to_vec()).wait().expect("put");
    }
    for f in frames {
        publisher.put(f).wait().expect("put");
    }

    let mut received = Vec::new();
    until(
        Duration::from_secs(30),
        "the genuine and the closing chunk arrived",
        || {
            let _ = chunks.wait(Duration::from_millis(10));
            while let Some(s) = chunks.try_recv().expect("receive") {
                received.push((*s.user_header(), s.payload().to_vec()));
            }
            received.len() >= 2
        },
    );
    let heads: Vec<RolloutHeader> = received.iter().map(|(h, _)| *h).collect();
    assert_eq!(
        heads,
        [header, last],
        "only the genuine chunk, once, then the closing one"
    );
    assert!(
        received[0]
            .1
            .iter()
            .zip(&good)
            .all(|(a, b)| a.reward.to_bits() == b.reward.to_bits() && a.env == b.env)
    );
    assert!(
        chunks.try_recv().expect("receive").is_none(),
        "nothing after the closing chunk"
    );

    ipc::request_shutdown(&control).expect("shutdown");
    until(Duration::from_secs(30), "the bridge stopped", || {
        bridge.try_wait().expect("poll").is_some()
    });
    let status = bridge.wait().expect("status");
    let said = std::fs::read_to_string(&log_path).expect("log");
    assert!(status.success(), "{status}\n{said}");
    for counted in [
        "wrong key: 1",
        "wrong kind: 1",
        "different message types: 1",
        "other start: 1",
        "non-finite value: 1",
        "replayed: 2",
        "source mismatch: 1",
        "over the source's rate: ",
    ] {
        assert!(said.contains(counted), "`{counted}` missing from:\n{said}");
    }
    assert!(
        said.contains("lost=0"),
        "no frame of source 1 went missing:\n{said}"
    );
}
