//! A fixed set of worker threads, created once and woken for every fleet step.
//!
//! Spawning the threads anew each decision step cost a third of the CPU time at 2 envs on
//! 2 threads (3,600 against 5,300 decision steps per CPU-second here) and a sixth at 8 envs.
//! These workers wait between steps instead: first spinning briefly, because a round's two
//! hand-offs cost 60–160 µs on this VM between threads asleep on a condition variable (a
//! fifth of a step at 4 envs per thread) and under 25 µs between threads still spinning;
//! then sleeping, so a pool waiting on a learner costs no CPU. A spinning thread yields its
//! core at every turn: where the learner and the estimator share the cores with the sim, the
//! spin would otherwise burn time they are waiting for.
//!
//! A job is a borrowed closure called once per part index: part `k` always runs on worker `k`
//! (the caller takes the last part), so which thread runs what never depends on timing.

use std::panic::{self, AssertUnwindSafe};
use std::sync::atomic::{AtomicU64, AtomicUsize, Ordering};
use std::sync::{Arc, Condvar, Mutex, MutexGuard, PoisonError};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

/// How long a thread spins on a round's start or end before it sleeps: longer than the gap
/// between two fleet steps (the controller acting) and than the other thread's last env
/// step, far shorter than a wait on the learner. At 50 µs the threads of a training run
/// slept on most rounds and waited out the wake-ups with both cores idle: 6 % fewer env
/// steps per second than at 300 µs (1 ms gains nothing more).
const SPIN: Duration = Duration::from_micros(300);

/// The job of the current round. `'static` only in name: [`Pool::run`] does not return while
/// any worker may still call it.
type Job = &'static (dyn Fn(usize) + Sync);

#[derive(Default)]
struct State {
    job: Option<Job>,
    panicked: bool,
    shutdown: bool,
}

/// Round counters are atomics so spinning threads can watch them without the lock; they
/// change only under the lock, so a sleeper that checks them under it never misses a wake-up.
#[derive(Default)]
struct Shared {
    /// Bumped for each round, so a worker runs each job exactly once.
    round: AtomicU64,
    /// Workers that have not finished the current round.
    pending: AtomicUsize,
    state: Mutex<State>,
    start: Condvar,
    done: Condvar,
}

impl Shared {
    /// The state lock; a panic never happens while it is held, so poisoning carries no meaning.
    fn lock(&self) -> MutexGuard<'_, State> {
        self.state.lock().unwrap_or_else(PoisonError::into_inner)
    }
}

/// Spins while `waiting()` holds, for at most [`SPIN`], yielding the core to any other
/// runnable thread at every turn.
fn spin_while(waiting: impl Fn() -> bool) {
    let deadline = Instant::now() + SPIN;
    while waiting() && Instant::now() < deadline {
        std::thread::yield_now();
    }
}

/// `parts - 1` worker threads plus the calling thread.
pub struct Pool {
    shared: Arc<Shared>,
    workers: Vec<JoinHandle<()>>,
}

impl Pool {
    /// A pool that runs `parts` (at least 1) parts of each job at once.
    pub fn new(parts: usize) -> Self {
        let shared = Arc::new(Shared::default());
        let workers = (0..parts.max(1) - 1)
            .map(|index| {
                let shared = Arc::clone(&shared);
                std::thread::Builder::new()
                    .name(format!("sim-worker-{index}"))
                    .spawn(move || work(&shared, index))
                    .expect("spawning a sim worker thread")
            })
            .collect();
        Self { shared, workers }
    }

    /// Calls `job(k)` for every part `k` in `0..parts` (`Pool::new`'s, one per thread) in
    /// parallel and returns when all have returned. A panic in any part is re-raised here,
    /// after every part has finished.
    pub fn run(&self, job: &(dyn Fn(usize) + Sync)) {
        let last = self.workers.len();
        if last == 0 {
            job(0);
            return;
        }
        let shared = &*self.shared;
        // SAFETY: only the lifetime is extended. Workers call the job between the round start
        // below and their `pending` decrement, and this function waits for `pending == 0`
        // (a worker catches its own panic before decrementing) and clears the job before
        // returning or unwinding, so no worker can reach `job` once its borrow ends.
        let erased: Job = unsafe { std::mem::transmute::<&(dyn Fn(usize) + Sync), Job>(job) };
        {
            let mut s = shared.lock();
            s.job = Some(erased);
            shared.pending.store(last, Ordering::Relaxed);
            shared.round.fetch_add(1, Ordering::Release);
        }
        shared.start.notify_all();
        let mine = panic::catch_unwind(AssertUnwindSafe(|| job(last)));
        spin_while(|| shared.pending.load(Ordering::Acquire) > 0);
        let worker_panicked = {
            let mut s = shared.lock();
            while shared.pending.load(Ordering::Acquire) > 0 {
                s = shared.done.wait(s).unwrap_or_else(PoisonError::into_inner);
            }
            s.job = None;
            std::mem::take(&mut s.panicked)
        };
        if let Err(payload) = mine {
            panic::resume_unwind(payload);
        }
        assert!(!worker_panicked, "a sim worker thread panicked");
    }
}

/// A worker's life: wait for a round, run part `index` of its job, report, repeat.
fn work(shared: &Shared, index: usize) {
    let mut seen = 0;
    loop {
        let ok = {
            spin_while(|| shared.round.load(Ordering::Acquire) == seen);
            let job = {
                let mut s = shared.lock();
                while shared.round.load(Ordering::Acquire) == seen && !s.shutdown {
                    s = shared.start.wait(s).unwrap_or_else(PoisonError::into_inner);
                }
                if s.shutdown {
                    return;
                }
                seen = shared.round.load(Ordering::Acquire);
                s.job
            };
            // `job` ends with this block, before the decrement below lets `run` return.
            job.is_none_or(|job| panic::catch_unwind(AssertUnwindSafe(|| job(index))).is_ok())
        };
        let mut s = shared.lock();
        s.panicked |= !ok;
        if shared.pending.fetch_sub(1, Ordering::AcqRel) == 1 {
            shared.done.notify_one();
        }
    }
}

impl Drop for Pool {
    fn drop(&mut self) {
        self.shared.lock().shutdown = true;
        self.shared.start.notify_all();
        for w in self.workers.drain(..) {
            // A worker never panics outside `catch_unwind`, so join cannot fail.
            let _ = w.join();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_part_runs_once_per_round_on_its_own_thread() {
        let pool = Pool::new(3);
        let counts: Vec<AtomicUsize> = (0..3).map(|_| AtomicUsize::new(0)).collect();
        let names = Mutex::new(vec![String::new(); 3]);
        for _ in 0..100 {
            pool.run(&|k| {
                counts[k].fetch_add(1, Ordering::Relaxed);
                let name = std::thread::current().name().unwrap_or("").to_owned();
                names.lock().expect("names")[k] = name;
            });
        }
        assert!(counts.iter().all(|c| c.load(Ordering::Relaxed) == 100));
        let names = names.into_inner().expect("names");
        assert_eq!(names[..2], ["sim-worker-0", "sim-worker-1"]);
        assert_ne!(names[2], "sim-worker-2", "the caller runs the last part");
    }

    #[test]
    fn a_panicking_part_reaches_the_caller_and_the_pool_survives() {
        let pool = Pool::new(2);
        let hit = panic::catch_unwind(AssertUnwindSafe(|| {
            pool.run(&|k| assert_ne!(k, 0, "part 0 fails"));
        }));
        assert!(hit.is_err());
        let ran = AtomicUsize::new(0);
        pool.run(&|_| {
            ran.fetch_add(1, Ordering::Relaxed);
        });
        assert_eq!(ran.load(Ordering::Relaxed), 2);
    }

    #[test]
    fn rounds_after_a_long_idle_still_run() {
        // Longer than `SPIN`: the workers have gone to sleep and must be woken.
        let pool = Pool::new(2);
        let ran = AtomicUsize::new(0);
        for _ in 0..3 {
            std::thread::sleep(SPIN * 4);
            pool.run(&|_| {
                ran.fetch_add(1, Ordering::Relaxed);
            });
        }
        assert_eq!(ran.load(Ordering::Relaxed), 6);
    }
}
