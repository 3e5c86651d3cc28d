//! A run across hosts against connections from outside it (DESIGN §9): one with no credentials
//! and one with another run's. While a sim host feeds a learner host, each listens on every
//! key for five seconds, asks for every key of the run, declares a sim host's and a learner
//! host's liveliness token, and publishes forged frames and a flood of 10,000 messages a
//! second on the rollout key. Neither receives a byte of the run, `lavatube status` never
//! lists its token, the learner host counts its refused connections by kind, the honest
//! host's every chunk is trained on, and the learner updates at least 80 % as often as in
//! the same run without outsiders.

use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};
use zenoh::Wait;

mod support;

const CONFIG: &str = "tests/fixtures/outsiders.toml";

/// A peer dialling `endpoint` with `password` for user `lavatube`, or with none:
/// it opens locally and keeps retrying the learner host in the background.
fn outsider(endpoint: &str, password: Option<&str>) -> zenoh::Session {
    let mut c = zenoh::Config::default();
    let mut settings = vec![
        ("mode", "\"peer\"".to_string()),
        ("connect/endpoints", format!("[\"{endpoint}\"]")),
        ("listen/endpoints", "[\"tcp/127.0.0.1:0\"]".to_string()),
        ("scouting/multicast/enabled", "false".to_string()),
        (
            "connect/retry",
            "{period_init_ms: 100, period_max_ms: 200, period_increase_factor: 1}".to_string(),
        ),
    ];
    if let Some(p) = password {
        settings.push((
            "transport/auth/usrpwd",
            format!("{{user: \"lavatube\", password: \"{p}\"}}"),
        ));
    }
    for (k, v) in settings {
        c.insert_json5(k, &v).expect("outsider config");
    }
    zenoh::open(c).wait().expect("a peer opens locally")
}

/// What one outside peer got of the run, in bytes, while it listened, asked, declared
/// tokens, forged and flooded for `listen`.
fn intrude(net: &zenoh::Session, listen: Duration) -> u64 {
    let got = Arc::new(AtomicU64::new(0));
    let counter = got.clone();
    // What comes from elsewhere: the peer's own flood is delivered to it locally.
    let _all = net
        .declare_subscriber("**")
        .allowed_origin(zenoh::sample::Locality::Remote)
        .callback(move |s| {
            counter.fetch_add(s.payload().len() as u64 + 1, Ordering::Relaxed);
        })
        .wait()
        .expect("subscriber");
    let _tokens = ["lavatube/sim/7", "lavatube/learner/0000000000000007"].map(|k| {
        net.liveliness()
            .declare_token(k)
            .wait()
            .expect("liveliness token")
    });
    let rollouts = net
        .declare_publisher("lavatube/rollout/1")
        .wait()
        .expect("publisher");
    let started = Instant::now();
    let mut sent = 0u64;
    let forged = vec![0x4cu8; 4096];
    while started.elapsed() < listen {
        // 10,000 small messages a second, with a forged frame-sized one every hundredth.
        for i in 0..100 {
            let msg = if i == 0 {
                forged.clone()
            } else {
                vec![i as u8; 64]
            };
            rollouts.put(msg).wait().expect("put");
            sent += 1;
        }
        let due = Duration::from_micros(sent * 100);
        if let Some(wait) = due.checked_sub(started.elapsed()) {
            std::thread::sleep(wait);
        }
    }
    let replies = net
        .get("lavatube/**")
        .allowed_destination(zenoh::sample::Locality::Remote)
        .timeout(Duration::from_secs(1))
        .wait()
        .expect("query");
    while let Ok(reply) = replies.recv() {
        if let Ok(s) = reply.result() {
            got.fetch_add(s.payload().len() as u64 + 1, Ordering::Relaxed);
        }
    }
    assert!(sent >= 40_000, "the flood sent {sent} messages");
    got.load(Ordering::Relaxed)
}

/// One learner host and one sim host of the fixture's run, tagged `tag`, with `during`
/// acting while they run; the learner host's run directory once both have ended well.
fn across_hosts(
    tag: &str,
    during: impl FnOnce(&support::AcrossHosts, &str, &mut support::Launched),
) -> std::path::PathBuf {
    let pid = std::process::id();
    let hosts = support::AcrossHosts::new(CONFIG, &format!("{tag}-{pid}"), 1);
    let learner_run = format!("{tag}-l-{pid}");
    let mut learner = hosts.learner_host(&learner_run);
    let sim = hosts.sim_host(&format!("{tag}-s-{pid}"), 1);
    during(&hosts, &learner_run, &mut learner);
    let (code, said) = sim.wait();
    assert_eq!(code, 0, "the sim host failed:\n{said}");
    let (code, said) = learner.wait();
    assert_eq!(code, 0, "the learner host failed:\n{said}");
    let dir = support::root().join("target/e2e-runs").join(&learner_run);
    let log =
        std::fs::read_to_string(common::run_dir::log_file(&dir, "learner")).expect("learner log");
    // The fixture's steps in chunks of 1024 transitions: every one trained on.
    assert!(log.contains("source 1: 100 chunks (0 missed)"), "{log}");
    dir
}

/// The learner's policy updates per second of wall time, from a run's summary.
fn updates_per_second(run_dir: &std::path::Path) -> f64 {
    let text = std::fs::read_to_string(run_dir.join("summary.json")).expect("summary.json");
    let summary: serde_json::Value = serde_json::from_str(&text).expect("summary is JSON");
    let number = |k: &str| {
        summary[k]
            .as_f64()
            .unwrap_or_else(|| panic!("{k} in {text}"))
    };
    number("policy_version") / number("wall_seconds")
}

#[test]
fn outside_peers_neither_read_nor_join_nor_starve_a_run_across_hosts() {
    let calm = updates_per_second(&across_hosts("calm", |_, _, _| {}));
    let dir = across_hosts("out", |hosts, run, learner| {
        // Watch `lavatube status` all along for the outsiders' tokens.
        let seen = Arc::new(Mutex::new(String::new()));
        let done = Arc::new(AtomicBool::new(false));
        let watcher = {
            let (seen, done, run) = (seen.clone(), done.clone(), run.to_string());
            std::thread::spawn(move || {
                while !done.load(Ordering::Relaxed) {
                    let s = support::status_of(&run);
                    if s.contains("source 7") {
                        *seen.lock().expect("status") = s;
                    }
                    std::thread::sleep(Duration::from_millis(300));
                }
            })
        };
        for (who, password) in [
            ("no", None),
            ("another run's", Some("not this run's password")),
        ] {
            let net = outsider(&hosts.endpoint, password);
            let got = intrude(&net, Duration::from_secs(5));
            assert_eq!(
                got, 0,
                "a peer with {who} credentials received {got} bytes of the run"
            );
            assert!(
                net.info().routers_zid().wait().next().is_none()
                    && net.info().peers_zid().wait().next().is_none(),
                "a peer with {who} credentials got connected"
            );
            net.close().wait().expect("close");
            assert!(
                learner.child.try_wait().expect("learner host").is_none(),
                "the run ended before the peer with {who} credentials was done: lengthen it"
            );
        }
        done.store(true, Ordering::Relaxed);
        watcher.join().expect("status watcher");
        let listed = seen.lock().expect("status").clone();
        assert!(
            listed.is_empty(),
            "an outsider's token counted as a sim host:\n{listed}"
        );
    });
    let flooded = updates_per_second(&dir);
    assert!(
        flooded >= 0.8 * calm,
        "the learner made {flooded:.2} updates/s under the outsiders, {calm:.2} without them"
    );
    let bridge =
        std::fs::read_to_string(common::run_dir::log_file(&dir, "bridge")).expect("bridge log");
    assert!(
        bridge.contains("refused=none"),
        "no outsider's message reached the learner host's bridge as a frame:\n{bridge}"
    );
    for kind in ["without credentials: ", "with another run's credentials: "] {
        assert!(
            bridge.contains(kind),
            "the connections {kind}were not counted:\n{bridge}"
        );
    }
}
