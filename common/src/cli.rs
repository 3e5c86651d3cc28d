//! Command-line pieces every binary shares: argument parsing and errors with lavatube's exit
//! codes, the run-id value parser, the arguments with which the launcher starts a process,
//! and the check that every argument is documented.

use std::ffi::OsString;
use std::path::PathBuf;
use std::process::ExitCode;

/// A count argument: an integer in `lo ..= hi`; `what` names it in the errors ("window").
pub fn parse_count(s: &str, what: &str, (lo, hi): (u64, u64)) -> Result<usize, String> {
    let n: u64 = s
        .trim()
        .parse()
        .map_err(|_| format!("`{s}` is not a {what} (an integer)"))?;
    if (lo..=hi).contains(&n) {
        usize::try_from(n).map_err(|_| format!("{what} {n} is too large"))
    } else {
        Err(format!("{what} {n} is out of range {lo}..={hi}"))
    }
}

/// Exit code of user errors: bad arguments, config or input files.
pub const EXIT_USER: u8 = 1;

/// Parses `args` as `C`. Usage errors print clap's message and give exit code 1 (a user
/// error); `--help` and `--version` print and give 0.
pub fn parse<C: clap::Parser>(args: impl IntoIterator<Item = OsString>) -> Result<C, ExitCode> {
    C::try_parse_from(args).map_err(|e| {
        let _ = e.print();
        if e.use_stderr() {
            ExitCode::from(EXIT_USER)
        } else {
            ExitCode::SUCCESS
        }
    })
}

/// What a process's `main` returns for `result`: success, or the error on one line and
/// [`EXIT_USER`] when its chain holds an `E` that `is_user` calls the user's to fix (a bad
/// config or input file), else 2 (anything unexpected).
pub fn exit<E>(result: anyhow::Result<()>, is_user: fn(&E) -> bool) -> ExitCode
where
    E: std::error::Error + Send + Sync + 'static,
{
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            let user = e
                .chain()
                .any(|c| c.downcast_ref::<E>().is_some_and(is_user));
            ExitCode::from(if user { EXIT_USER } else { 2 })
        }
    }
}

/// clap's own consistency checks on `cmd`, then a panic naming the first argument of its
/// subcommands without help text: each binary's command-line test.
pub fn assert_documented(cmd: &clap::Command) {
    cmd.clone().debug_assert();
    for sub in cmd.get_subcommands() {
        for arg in sub.get_arguments() {
            let id = arg.get_id().as_str();
            assert!(
                id == "help" || id == "version" || arg.get_help().is_some(),
                "{} --{id} has no help",
                sub.get_name()
            );
        }
    }
}

/// clap value parser for a run id (see [`crate::ipc::validate_run_id`]).
pub fn parse_run_id(s: &str) -> Result<String, String> {
    crate::ipc::validate_run_id(s).map(|()| s.to_string())
}

/// clap value parser for a Zenoh endpoint of a run across hosts, `tcp/HOST:PORT`.
pub fn parse_endpoint(endpoint: &str) -> Result<String, String> {
    let ok = endpoint
        .strip_prefix("tcp/")
        .and_then(|rest| rest.rsplit_once(':'))
        .is_some_and(|(host, port)| !host.is_empty() && port.parse::<u16>().is_ok());
    if ok {
        Ok(endpoint.to_string())
    } else {
        Err(format!(
            "endpoint `{endpoint}` is not tcp/HOST:PORT (e.g. tcp/0.0.0.0:7447)"
        ))
    }
}

/// How the launcher starts a process in a run.
#[derive(Debug, Clone, clap::Args)]
pub struct JoinArgs {
    /// The run's resolved config (TOML).
    #[arg(long)]
    pub config: PathBuf,
    /// The run to join over shared memory.
    #[arg(long, value_parser = parse_run_id)]
    pub run_id: String,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn counts_are_integers_within_their_bounds() {
        assert_eq!(parse_count(" 70 ", "window size", (2, 100)), Ok(70));
        assert_eq!(
            parse_count("1", "window size", (2, 100)),
            Err("window size 1 is out of range 2..=100".into())
        );
        assert_eq!(
            parse_count("x", "window size", (2, 100)),
            Err("`x` is not a window size (an integer)".into())
        );
    }

    #[test]
    fn endpoints_are_tcp_host_and_port() {
        assert!(parse_endpoint("tcp/127.0.0.1:7447").is_ok());
        assert!(parse_endpoint("tcp/[::1]:7447").is_ok());
        for bad in [
            "127.0.0.1:7447",
            "tcp/host",
            "tcp/:1",
            "udp/1.2.3.4:5",
            "tcp/h:99999",
        ] {
            let e = parse_endpoint(bad).expect_err(bad);
            assert!(e.contains(bad), "{e}");
        }
    }
}
