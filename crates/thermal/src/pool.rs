//! A fixed pool of worker threads for the step, created once per process (on the first
//! step big enough to split) and shared by every simulation; one simulation uses it at a
//! time (another one meanwhile steps on its own thread). Per step the caller publishes the
//! kernel and cuts the slot range into chunks; the caller and the workers claim chunks
//! until none is left, and the caller waits until every chunk is done: one barrier per
//! step. Chunks are claimed, not assigned, so a worker the OS has not scheduled (other
//! processes on the cores) delays nothing: the caller steps its chunks. A worker preempted
//! while it holds a chunk does delay the step; after such a stall (> 0.3 ms) steps run on
//! the caller's thread alone for 0.5 s, doubling (up to 16 s) while stalls keep coming
//! within 30 s of each other, so an oversubscribed machine costs little. Idle workers spin
//! ~50 µs, then sleep on a condition variable.

use std::cell::UnsafeCell;
use std::sync::atomic::{AtomicBool, AtomicU64, AtomicUsize, Ordering};
use std::sync::{Condvar, Mutex, OnceLock};
use std::time::{Duration, Instant};

use crate::kernel::Kernel;

/// Chunks per thread of one step (more: better balance, more atomics).
const CHUNKS_PER_THREAD: usize = 4;

struct Job {
    kernel: Option<Kernel>,
    lo: usize,
    hi: usize,
    chunks: usize,
}

struct Shared {
    /// epoch << 32 | first unclaimed chunk << 16 | last unclaimed chunk + 1.
    claim: AtomicU64,
    finished: AtomicUsize,
    sleepers: AtomicUsize,
    lock: Mutex<()>,
    wake: Condvar,
    job: UnsafeCell<Job>,
}

// SAFETY: `job` is written only by the pool's owner while no chunk is claimed and
// unfinished, and read only by a thread holding a claimed, unfinished chunk.
unsafe impl Sync for Shared {}

impl Shared {
    /// Claims and steps chunks of `epoch` until none is left: the caller from the
    /// front, the workers from the back, so that with two threads each one mostly
    /// steps the same half of the slots every step (it stays in its core's cache).
    fn work(&self, epoch: u64, front: bool) {
        let mut cur = self.claim.load(Ordering::Acquire);
        loop {
            let (e, lo, hi) = (cur >> 32, (cur >> 16) & 0xffff, cur & 0xffff);
            if e != epoch || lo >= hi {
                return;
            }
            let (chunk, new) = if front {
                (lo, cur + (1 << 16))
            } else {
                (hi - 1, cur - 1)
            };
            match self
                .claim
                .compare_exchange_weak(cur, new, Ordering::AcqRel, Ordering::Acquire)
            {
                Ok(_) => {
                    // SAFETY: this chunk of this epoch is ours and unfinished, so the
                    // job is this epoch's and stays as it is.
                    unsafe {
                        let job = &*self.job.get();
                        let (a, b) = cut(job.lo, job.hi, chunk as usize, job.chunks);
                        if let Some(k) = &job.kernel {
                            k.run(a, b);
                        }
                    }
                    self.finished.fetch_add(1, Ordering::Release);
                    cur = self.claim.load(Ordering::Acquire);
                }
                Err(now) => cur = now,
            }
        }
    }
}

/// Slots of chunk `c` of `chunks` over `lo..hi`, cut at multiples of 8 slots (the
/// 64-byte lines of the output).
fn cut(lo: usize, hi: usize, c: usize, chunks: usize) -> (usize, usize) {
    let at = |c: usize| {
        if c == 0 {
            lo
        } else if c == chunks {
            hi
        } else {
            ((lo + (hi - lo) * c / chunks) & !7).clamp(lo, hi)
        }
    };
    (at(c), at(c + 1))
}

pub struct Pool {
    shared: &'static Shared,
    workers: usize,
    busy: AtomicBool,
    epoch: AtomicU64,
    /// Steps run on the caller's thread alone until this time ([`clock_ns`]).
    backoff_until: AtomicU64,
    /// Length of the last back-off, ns.
    backoff: AtomicU64,
    /// Start of the current [`WINDOW`] and the time stalls cost in it, ns.
    window_start: AtomicU64,
    window_stalls: AtomicU64,
    /// Time of the last back-off ([`clock_ns`]).
    last_backoff: AtomicU64,
}

/// A wait this long for the workers' chunks means a worker was preempted mid-chunk.
const STALL: Duration = Duration::from_micros(300);
/// Stalls that cost more than a tenth of such a window mean the cores are
/// oversubscribed (other processes want them too). A few short stalls are the jitter of
/// a virtual machine's idle cores (seen twice a second on a 2-vCPU VM, 0.3 ms each):
/// they cost less than stepping alone would.
const WINDOW: Duration = Duration::from_millis(250);
/// After stalls cost too much, steps run single-threaded this long; twice as long after
/// each back-off that follows the last one within [`QUIET`], up to [`MAX_BACKOFF`].
const BACKOFF: Duration = Duration::from_millis(500);
const MAX_BACKOFF: Duration = Duration::from_secs(16);
const QUIET: Duration = Duration::from_secs(30);

/// Nanoseconds since the pool's first use.
fn clock_ns() -> u64 {
    static START: OnceLock<Instant> = OnceLock::new();
    START.get_or_init(Instant::now).elapsed().as_nanos() as u64
}

static POOL: OnceLock<Pool> = OnceLock::new();

/// The exclusive use of the pool until dropped.
pub struct Guard(&'static Pool, usize);

impl Drop for Guard {
    fn drop(&mut self) {
        self.0.busy.store(false, Ordering::Release);
    }
}

impl Pool {
    /// The pool for a step on `threads` threads (caller included), if it is free.
    pub fn acquire(threads: usize) -> Option<Guard> {
        let pool = POOL.get_or_init(|| {
            let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
            Pool::spawn(cores.saturating_sub(1).max(1))
        });
        if pool.backoff_until.load(Ordering::Relaxed) > clock_ns()
            || pool.busy.swap(true, Ordering::Acquire)
        {
            return None;
        }
        Some(Guard(pool, threads.min(pool.workers + 1)))
    }

    fn spawn(workers: usize) -> Pool {
        let shared: &'static Shared = Box::leak(Box::new(Shared {
            claim: AtomicU64::new(0),
            finished: AtomicUsize::new(0),
            sleepers: AtomicUsize::new(0),
            lock: Mutex::new(()),
            wake: Condvar::new(),
            job: UnsafeCell::new(Job {
                kernel: None,
                lo: 0,
                hi: 0,
                chunks: 0,
            }),
        }));
        for w in 0..workers {
            std::thread::Builder::new()
                .name(format!("thermal-{w}"))
                .spawn(move || worker(shared))
                .expect("cannot start a simulator thread");
        }
        Pool {
            shared,
            workers,
            busy: AtomicBool::new(false),
            epoch: AtomicU64::new(0),
            backoff_until: AtomicU64::new(0),
            backoff: AtomicU64::new(0),
            window_start: AtomicU64::new(0),
            window_stalls: AtomicU64::new(0),
            last_backoff: AtomicU64::new(0),
        }
    }
}

impl Guard {
    /// Steps slots `lo..hi` on the pool's threads and this one.
    pub fn run(&self, kernel: &Kernel, lo: usize, hi: usize) {
        let (pool, threads) = (self.0, self.1);
        let shared = pool.shared;
        let chunks = (threads * CHUNKS_PER_THREAD).min(0xffff);
        // SAFETY: no chunk is claimed and unfinished (the last `run` waited for all).
        unsafe {
            *shared.job.get() = Job {
                kernel: Some(*kernel),
                lo,
                hi,
                chunks,
            };
        }
        let epoch = (pool.epoch.fetch_add(1, Ordering::Relaxed) + 1) & 0xffff_ffff;
        shared.finished.store(0, Ordering::Relaxed);
        shared
            .claim
            .store(epoch << 32 | chunks as u64, Ordering::SeqCst);
        if shared.sleepers.load(Ordering::SeqCst) > 0 {
            let _g = shared.lock.lock().unwrap_or_else(|e| e.into_inner());
            shared.wake.notify_all();
        }
        shared.work(epoch, true);
        // Spin, never yield: the chunks left are being stepped right now, and a yield
        // on a busy machine hands the core to another process for a whole time slice.
        let mut spins = 0u32;
        let mut waiting: Option<Instant> = None;
        while shared.finished.load(Ordering::Acquire) < chunks {
            std::hint::spin_loop();
            spins += 1;
            if spins % 1024 == 0 {
                waiting.get_or_insert_with(Instant::now);
            }
        }
        // A long wait for the workers' chunks: a worker holding one lost its core.
        if let Some(waited) = waiting.map(|w| w.elapsed()).filter(|&w| w > STALL) {
            pool.stalled(waited);
        }
    }
}

impl Pool {
    /// Counts a stall; when stalls cost more than a tenth of the current window,
    /// stepping alone is faster for a while, the longer the more often it happens.
    fn stalled(&self, waited: Duration) {
        let now = clock_ns();
        let window = WINDOW.as_nanos() as u64;
        if now.saturating_sub(self.window_start.load(Ordering::Relaxed)) > window {
            self.window_start.store(now, Ordering::Relaxed);
            self.window_stalls.store(0, Ordering::Relaxed);
        }
        let cost = self
            .window_stalls
            .fetch_add(waited.as_nanos() as u64, Ordering::Relaxed)
            + waited.as_nanos() as u64;
        if cost <= window / 10 {
            return;
        }
        self.window_stalls.store(0, Ordering::Relaxed);
        let quiet = now.saturating_sub(self.last_backoff.swap(now, Ordering::Relaxed));
        let len = if quiet > QUIET.as_nanos() as u64 {
            BACKOFF.as_nanos() as u64
        } else {
            (self.backoff.load(Ordering::Relaxed) * 2)
                .clamp(BACKOFF.as_nanos() as u64, MAX_BACKOFF.as_nanos() as u64)
        };
        self.backoff.store(len, Ordering::Relaxed);
        self.backoff_until.store(now + len, Ordering::Relaxed);
    }
}

fn worker(shared: &'static Shared) {
    let mut seen = 0u64;
    loop {
        let started = Instant::now();
        let mut spins = 0u32;
        loop {
            let e = shared.claim.load(Ordering::Acquire) >> 32;
            if e != seen {
                seen = e;
                break;
            }
            spins += 1;
            if spins % 256 == 0 && started.elapsed() > Duration::from_micros(50) {
                let mut g = shared.lock.lock().unwrap_or_else(|e| e.into_inner());
                shared.sleepers.fetch_add(1, Ordering::SeqCst);
                while shared.claim.load(Ordering::SeqCst) >> 32 == seen {
                    g = shared.wake.wait(g).unwrap_or_else(|e| e.into_inner());
                }
                shared.sleepers.fetch_sub(1, Ordering::SeqCst);
                drop(g);
            } else {
                std::hint::spin_loop();
            }
        }
        shared.work(seen, false);
    }
}
