//! The stop ladder, the one way the launcher ends its children: a stop request, then SIGTERM
//! after a grace period, then SIGKILL after another. Every child is reaped before it returns.

use super::Child;
use std::time::{Duration, Instant};

/// How often the ladder polls its children and repeats the stop request.
const REQUEST_EVERY: Duration = Duration::from_millis(100);
const POLL: Duration = Duration::from_millis(20);

/// Stops `children`: `request` (a shutdown event; repeated every 100 ms, since an event sent
/// before a child has connected is not delivered to it), SIGTERM after `grace`, SIGKILL after
/// `grace` again.
pub fn stop(children: &mut [&mut Child], request: &dyn Fn(), grace: Duration) {
    if !wait_all(children, grace, request) {
        for c in children.iter_mut().filter(|c| c.status().is_none()) {
            eprintln!(
                "lavatube: {} (pid {}) did not stop on request: SIGTERM",
                c.name,
                c.pid()
            );
            c.signal(libc::SIGTERM);
        }
        if !wait_all(children, grace, &|| {}) {
            for c in children.iter_mut().filter(|c| c.status().is_none()) {
                eprintln!(
                    "lavatube: {} (pid {}) ignored SIGTERM: SIGKILL",
                    c.name,
                    c.pid()
                );
                c.signal(libc::SIGKILL);
            }
        }
    }
    for c in children.iter_mut() {
        c.reap();
    }
}

/// Stops one child by SIGTERM first (every process treats it as a stop request: a learner
/// checkpoints and exits), then the rest of the ladder.
pub fn terminate(child: &mut Child, grace: Duration) {
    child.signal(libc::SIGTERM);
    stop(&mut [child], &|| {}, grace);
}

/// Waits until every child has exited or `timeout` passes, calling `request` every 100 ms
/// meanwhile; whether all exited.
fn wait_all(children: &mut [&mut Child], timeout: Duration, request: &dyn Fn()) -> bool {
    let until = Instant::now() + timeout;
    let mut next_request = Instant::now();
    loop {
        let mut all = true;
        for c in children.iter_mut() {
            match c.poll() {
                Ok(status) => all &= status.is_some(),
                Err(e) => {
                    eprintln!("lavatube: {e:#}");
                    all = false;
                }
            }
        }
        if all {
            return true;
        }
        let now = Instant::now();
        if now >= until {
            return false;
        }
        if now >= next_request {
            request();
            next_request = now + REQUEST_EVERY;
        }
        std::thread::sleep(POLL);
    }
}
