//! The Zenoh side of a bridge: the connection each side opens, and the key expressions of a
//! run across hosts (DESIGN §9). The learner host's bridge is a Zenoh router listening on the
//! run's endpoint; each sim host's bridge is a peer that connects to it, and that Zenoh
//! reconnects by itself when the learner host comes back. Both take only connections that
//! prove they hold the run's credentials (Zenoh's user-password authentication, a challenge and
//! an HMAC of it, with a password derived from the run's key): a connection without them is
//! closed in its handshake, before it can subscribe, query, publish or declare a token.

use anyhow::Context;
use zenoh::handlers::{FifoChannel, FifoChannelHandler};
use zenoh::pubsub::Subscriber;
use zenoh::sample::Sample;
use zenoh::{Config, Wait};

/// An open Zenoh connection to the run's other hosts, as `zenoh::open` returns it.
pub type Net = zenoh::Session;

/// Rollout chunks of sim host `source`.
pub fn rollout_key(source: u32) -> String {
    format!("lavatube/rollout/{source}")
}
/// Every sim host's rollout chunks.
pub const ROLLOUT_ALL: &str = "lavatube/rollout/*";
/// The policies of slot `slot` (`general`, `flat`, `rough`).
pub fn policy_key(slot: &str) -> String {
    format!("lavatube/policy/{slot}")
}
/// Every slot's policies; also the query a sim host sends for the newest ones.
pub const POLICY_ALL: &str = "lavatube/policy/*";
/// A sim host's liveliness token.
pub fn sim_token(source: u32) -> String {
    format!("lavatube/sim/{source}")
}
/// Every sim host's liveliness token.
pub const SIM_ALL: &str = "lavatube/sim/*";
/// The learner host's liveliness token, naming this start of its bridge (a random id): a
/// sim host adopts the start and asks for policies again when it appears.
pub fn learner_token(start: u64) -> String {
    format!("lavatube/learner/{start:016x}")
}
/// Every learner host token.
pub const LEARNER_ALL: &str = "lavatube/learner/*";

/// The start in a learner host's token key, `lavatube/learner/<start>`.
pub fn token_start(key: &str) -> Option<u64> {
    u64::from_str_radix(key.strip_prefix("lavatube/learner/")?, 16).ok()
}

/// A Zenoh error as one line saying what failed.
pub fn zerr(what: &'static str) -> impl Fn(zenoh::Error) -> anyhow::Error {
    move |e| anyhow::anyhow!("{what}: {e}")
}

/// What a bridge reads from Zenoh: samples queued in a bounded channel, drained by its loop.
pub type Inbox = Subscriber<FifoChannelHandler<Sample>>;

/// A subscriber on `key` that queues up to `capacity` samples.
pub fn subscribe(net: &Net, key: &str, capacity: usize) -> anyhow::Result<Inbox> {
    net.declare_subscriber(key.to_string())
        .with(FifoChannel::new(capacity))
        .wait()
        .map_err(zerr("subscriber"))
}

/// The liveliness tokens on `key`, those alive now first (as joins), then every join and
/// leave.
pub fn watch_tokens(net: &Net, key: &str, capacity: usize) -> anyhow::Result<Inbox> {
    net.liveliness()
        .declare_subscriber(key.to_string())
        .history(true)
        .with(FifoChannel::new(capacity))
        .wait()
        .map_err(zerr("liveliness subscriber"))
}

/// The source id in a sim token's key, `lavatube/sim/<source>`.
pub fn token_source(key: &str) -> Option<u32> {
    key.strip_prefix("lavatube/sim/")?.parse().ok()
}

/// The run's connection credentials, derived from its secret: what a connection shows (an HMAC of
/// the listener's challenge under the password) to be let in.
pub struct Credentials {
    user: &'static str,
    password: String,
}

/// BLAKE3's key-derivation context for the connection password.
const PASSWORD_CONTEXT: &str = "lavatube 2026 Zenoh connection password, version 1";

impl Credentials {
    pub fn new(secret: &[u8]) -> Self {
        let password = blake3::derive_key(PASSWORD_CONTEXT, secret)
            .iter()
            .map(|b| format!("{b:02x}"))
            .collect();
        Self {
            user: "lavatube",
            password,
        }
    }

    /// Zenoh's `transport/auth/usrpwd`: what this side shows, and the dictionary (a file
    /// only this user may read, `user:password`) of what it takes from the other side.
    fn usrpwd(&self) -> anyhow::Result<(String, tempfile::NamedTempFile)> {
        use std::io::Write;
        let mut dictionary = tempfile::Builder::new()
            .prefix("lavatube-usrpwd-")
            .tempfile()
            .context("cannot write the password dictionary")?;
        writeln!(dictionary, "{}:{}", self.user, self.password)
            .context("cannot write the password dictionary")?;
        let path = dictionary.path().display().to_string();
        let value = format!(
            "{{user: {:?}, password: {:?}, dictionary_file: {path:?}}}",
            self.user, self.password
        );
        Ok((value, dictionary))
    }
}

/// A Zenoh config that stays on the endpoints given (no multicast scouting, no gossip) and
/// takes only connections with `credentials`; the dictionary file must live until the Zenoh
/// node is
/// open.
fn config(
    mode: &str,
    listen: &[&str],
    connect: &[&str],
    credentials: &Credentials,
) -> anyhow::Result<(Config, tempfile::NamedTempFile)> {
    let list = |v: &[&str]| {
        let quoted: Vec<String> = v.iter().map(|e| format!("{e:?}")).collect();
        format!("[{}]", quoted.join(","))
    };
    let mut c = Config::default();
    let (usrpwd, dictionary) = credentials.usrpwd()?;
    for (key, value) in [
        ("transport/auth/usrpwd", usrpwd),
        ("mode", format!("{mode:?}")),
        ("listen/endpoints", list(listen)),
        ("connect/endpoints", list(connect)),
        ("scouting/multicast/enabled", "false".into()),
        ("scouting/gossip/enabled", "false".into()),
        // Return from opening at once: a peer connecting to a router otherwise waits out the
        // scouting delay (half a second). The bridges learn that the other side is there
        // from its liveliness token, not from the open returning.
        ("open/return_conditions/connect_scouted", "false".into()),
        // Retry the learner host quickly: a sim host that (re)joins should have the newest
        // policy within a second of the learner host being reachable.
        (
            "connect/retry",
            "{period_init_ms: 100, period_max_ms: 1000, period_increase_factor: 2}".into(),
        ),
    ] {
        // The password is a secret: never in an error message.
        let shown = if key.starts_with("transport/auth") {
            "(the run's credentials)"
        } else {
            &value
        };
        c.insert_json5(key, &value)
            .map_err(|e| anyhow::anyhow!("zenoh config `{key}` = {shown}: {e}"))?;
    }
    Ok((c, dictionary))
}

fn open((c, _dictionary): (Config, tempfile::NamedTempFile), what: &str) -> anyhow::Result<Net> {
    zenoh::open(c)
        .wait()
        .map_err(|e| anyhow::anyhow!("{e}"))
        .with_context(|| format!("cannot open the Zenoh connection {what}"))
}

/// The learner host's connection: a router listening on `endpoint` (e.g. `tcp/0.0.0.0:7447`).
pub fn listen(endpoint: &str, credentials: &Credentials) -> anyhow::Result<Net> {
    open(
        config("router", &[endpoint], &[], credentials)?,
        &format!("listening on {endpoint}"),
    )
}

/// A sim host's connection: a peer that connects to the learner host at `endpoint`, retrying
/// until it answers, and again whenever the connection is lost. It listens on an ephemeral
/// loopback port only, so it is reachable from nowhere else.
pub fn connect(endpoint: &str, credentials: &Credentials) -> anyhow::Result<Net> {
    open(
        config("peer", &["tcp/127.0.0.1:0"], &[endpoint], credentials)?,
        &format!("to {endpoint}"),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_sim_token_names_its_source() {
        assert_eq!(token_source(&sim_token(12)), Some(12));
        assert_eq!(token_source("lavatube/sim/x"), None);
        assert_eq!(rollout_key(3), "lavatube/rollout/3");
        assert_eq!(token_start(&learner_token(0xabc)), Some(0xabc));
        assert_eq!(token_start("lavatube/learner"), None);
    }
}
