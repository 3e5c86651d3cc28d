//! The POSIX clocks std does not expose: one monotonic clock every process on a host shares
//! (send timestamps that cross process boundaries, unlike `std::time::Instant`), and the CPU
//! time of the process (benchmarks on a machine whose cores are shared).

use std::time::Duration;

fn read(clock: libc::clockid_t) -> Duration {
    let mut ts = libc::timespec {
        tv_sec: 0,
        tv_nsec: 0,
    };
    // SAFETY: clock_gettime(2) writes one timespec through a valid pointer; the two clock
    // ids used here always exist on Linux, so it cannot fail.
    unsafe {
        libc::clock_gettime(clock, &raw mut ts);
    }
    Duration::new(ts.tv_sec as u64, ts.tv_nsec as u32)
}

/// `CLOCK_MONOTONIC` in nanoseconds.
pub fn monotonic_ns() -> u64 {
    u64::try_from(read(libc::CLOCK_MONOTONIC).as_nanos()).unwrap_or(u64::MAX)
}

/// CPU time of the whole process, all threads.
pub fn process_cpu() -> Duration {
    read(libc::CLOCK_PROCESS_CPUTIME_ID)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn clocks_advance_and_cpu_time_counts_work() {
        let (t0, c0) = (monotonic_ns(), process_cpu());
        let mut x = 0u64;
        for i in 0..2_000_000u64 {
            x = std::hint::black_box(x.wrapping_add(i * i));
        }
        assert!(monotonic_ns() > t0 && process_cpu() > c0);
    }
}
