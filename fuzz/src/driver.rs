//! The mutational driver: a target's seeds, then mutations of them, each input under a time
//! bound. A panic (also one a loader catches around a third-party decoder: the panic hook sees
//! it) is a failure, its input saved; an input that runs past the bound (CPU time of the
//! process, or 12 times the bound in wall time) is a hang: the input is saved and the process
//! exits (a stuck thread cannot be stopped), naming the file.
//!
//! libFuzzer (`fuzz_targets/`) is the coverage-guided fuzzer; this driver is what runs without
//! instrumentation: CI's smoke test, and long runs where the instrumented build is not wanted.

use std::panic::AssertUnwindSafe;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex, Once};
use std::time::{Duration, Instant};

use crate::rng::Rng;
use crate::seeds::Seed;
use crate::{mutate, Target};

/// How a run goes.
#[derive(Clone, Debug)]
pub struct Options {
    /// Executions after the seeds (each a mutation of a random seed).
    pub mutations: u64,
    /// Stop mutating after this long (whatever the count).
    pub max_time: Duration,
    /// The longest one input may run.
    pub time_bound: Duration,
    /// Where failing inputs are written.
    pub failures: PathBuf,
    /// Seed of the mutations (same seed, same inputs).
    pub seed: u64,
    /// Print a progress line to stderr every this many executions (0: never).
    pub progress_every: u64,
}

/// What a run saw.
#[derive(Clone, Debug, Default)]
pub struct Report {
    pub executions: u64,
    pub elapsed: Duration,
    /// Inputs that panicked, saved under [`Options::failures`], with the panic message.
    pub panics: Vec<(PathBuf, String)>,
    /// The slowest input's time.
    pub slowest: Duration,
    /// The process's peak resident memory so far (KiB, from /proc; 0 where unknown).
    pub peak_rss_kib: u64,
}

impl Report {
    pub fn execs_per_second(&self) -> f64 {
        self.executions as f64 / self.elapsed.as_secs_f64().max(1e-9)
    }
}

/// Panics seen by the hook since the process started, and the last message.
static PANICS: AtomicU64 = AtomicU64::new(0);
static LAST_PANIC: Mutex<String> = Mutex::new(String::new());

/// Whether an input is running (on any thread): panics outside one are the driver's own.
static IN_INPUT: AtomicBool = AtomicBool::new(false);

/// Installs (once) a panic hook that counts panics on any thread and keeps the message. A panic
/// while no input runs (in the driver or a mutator) also goes to the default hook, so that it is
/// printed: it ends the run, and a run that ends without a report must say why.
fn install_panic_hook() {
    static ONCE: Once = Once::new();
    ONCE.call_once(|| {
        let default = std::panic::take_hook();
        std::panic::set_hook(Box::new(move |info| {
            if !IN_INPUT.load(Ordering::SeqCst) {
                eprintln!("the fuzz driver itself panicked (no input was running):");
                default(info);
                return;
            }
            PANICS.fetch_add(1, Ordering::SeqCst);
            if let Ok(mut last) = LAST_PANIC.lock() {
                *last = info.to_string();
            }
        }));
    });
}

/// The input being run and when it started, for the watchdog.
struct Current {
    input: Mutex<Vec<u8>>,
    /// Milliseconds since `epoch` when the input started; 0 when none is running.
    started_ms: AtomicU64,
    /// The process's CPU time (ms, all threads) when the input started.
    started_cpu_ms: AtomicU64,
    epoch: Instant,
}

/// How many times the time bound an input may take in wall-clock time (when it is blocked, or
/// starved of CPU) before it is a hang; the bound itself applies to the CPU time it spends.
const WALL_FACTOR: u64 = 12;

/// CPU time of this process, all threads (ms, from `/proc/self/stat`; 0 elsewhere).
pub fn process_cpu_ms() -> u64 {
    let Ok(stat) = std::fs::read_to_string("/proc/self/stat") else { return 0 };
    // Fields after the command name (which may hold spaces): state is the first, utime the
    // 12th and stime the 13th, in clock ticks (100 per second on Linux).
    let fields: Vec<&str> = stat.rsplit_once(')').map_or("", |(_, rest)| rest).split_whitespace().collect();
    let ticks = |i: usize| fields.get(i).and_then(|f| f.parse::<u64>().ok()).unwrap_or(0);
    (ticks(11) + ticks(12)) * 10
}

/// Runs `run` on every seed and then on `options.mutations` mutated inputs of `target`.
pub fn run(target: Target, seeds: &[Seed], options: &Options, run: &mut dyn FnMut(&[u8])) -> Report {
    install_panic_hook();
    let current = Arc::new(Current {
        input: Mutex::new(Vec::new()),
        started_ms: AtomicU64::new(0),
        started_cpu_ms: AtomicU64::new(0),
        epoch: Instant::now(),
    });
    let watchdog = spawn_watchdog(target, Arc::clone(&current), options.time_bound, options.failures.clone());
    let mut report = Report::default();
    let start = Instant::now();
    let mut rng = Rng::new(options.seed);
    let mut execute = |input: &[u8], report: &mut Report| {
        *current.input.lock().unwrap_or_else(|e| e.into_inner()) = input.to_vec();
        let before = PANICS.load(Ordering::SeqCst);
        let t0 = Instant::now();
        current.started_cpu_ms.store(process_cpu_ms(), Ordering::SeqCst);
        current.started_ms.store(current.epoch.elapsed().as_millis() as u64 + 1, Ordering::SeqCst);
        IN_INPUT.store(true, Ordering::SeqCst);
        let escaped = std::panic::catch_unwind(AssertUnwindSafe(|| run(input))).is_err();
        IN_INPUT.store(false, Ordering::SeqCst);
        current.started_ms.store(0, Ordering::SeqCst);
        report.slowest = report.slowest.max(t0.elapsed());
        report.executions += 1;
        if options.progress_every > 0 && report.executions.is_multiple_of(options.progress_every) {
            let seconds = start.elapsed().as_secs_f64();
            eprintln!(
                "progress: {} executions in {seconds:.0} s ({:.0}/s), peak RSS {} MiB",
                report.executions,
                report.executions as f64 / seconds.max(1e-9),
                peak_rss_kib() / 1024
            );
        }
        if escaped || PANICS.load(Ordering::SeqCst) != before {
            let message = LAST_PANIC.lock().map(|m| m.clone()).unwrap_or_default();
            let path = save(&options.failures, target, "panic", input);
            report.panics.push((path, message));
        }
    };
    for (_, seed) in seeds {
        execute(seed, &mut report);
    }
    if !seeds.is_empty() {
        for _ in 0..options.mutations {
            if start.elapsed() > options.max_time {
                break;
            }
            let input = mutated(target, seeds, &mut rng);
            execute(&input, &mut report);
        }
    }
    report.elapsed = start.elapsed();
    report.peak_rss_kib = peak_rss_kib();
    drop(watchdog);
    report
}

/// The inputs a run with mutation seed `seed` executes, in order: the seeds, then the
/// mutations (the same as [`run`]'s: they depend on nothing but the seed list and `seed`). For
/// finding which input a run that died (killed, aborted) was executing.
pub fn inputs<'a>(target: Target, seeds: &'a [Seed], seed: u64) -> impl Iterator<Item = Vec<u8>> + 'a {
    let mut rng = Rng::new(seed);
    let mutations = std::iter::from_fn(move || (!seeds.is_empty()).then(|| mutated(target, seeds, &mut rng)));
    seeds.iter().map(|(_, s)| s.clone()).chain(mutations)
}

/// A mutation of a random seed: structure-aware half of the time where the target has one,
/// then byte-level ones with a second seed to splice from; sometimes stacked.
pub fn mutated(target: Target, seeds: &[Seed], rng: &mut Rng) -> Vec<u8> {
    let mut input = seeds[rng.below(seeds.len())].1.clone();
    for _ in 0..1 + rng.below(3) {
        let structured = if rng.one_in(2) { mutate::structured(target, &input, rng) } else { None };
        match structured {
            Some(m) => input = m,
            None => {
                let other = &seeds[rng.below(seeds.len())].1;
                mutate::bytes(&mut input, rng, other, target.max_len());
            }
        }
    }
    input.truncate(target.max_len());
    input
}

/// Writes a failing input as `<dir>/<target>-<kind>-<hash>` and returns the path.
pub fn save(dir: &Path, target: Target, kind: &str, input: &[u8]) -> PathBuf {
    let _ = std::fs::create_dir_all(dir);
    let hash = input.iter().fold(0xcbf2_9ce4_8422_2325u64, |h, &b| (h ^ b as u64).wrapping_mul(0x0100_0000_01b3));
    let path = dir.join(format!("{}-{kind}-{hash:016x}", target.name()));
    let _ = std::fs::write(&path, input);
    path
}

/// Stops the watchdog thread when dropped.
struct Watchdog(Arc<AtomicU64>);

impl Drop for Watchdog {
    fn drop(&mut self) {
        self.0.store(1, Ordering::SeqCst);
    }
}

fn spawn_watchdog(target: Target, current: Arc<Current>, bound: Duration, failures: PathBuf) -> Watchdog {
    let stop = Arc::new(AtomicU64::new(0));
    let stopped = Arc::clone(&stop);
    std::thread::spawn(move || {
        while stopped.load(Ordering::SeqCst) == 0 {
            std::thread::sleep(Duration::from_millis(50));
            let started = current.started_ms.load(Ordering::SeqCst);
            if started == 0 {
                continue;
            }
            let wall = (current.epoch.elapsed().as_millis() as u64 + 1).saturating_sub(started);
            let cpu = process_cpu_ms().saturating_sub(current.started_cpu_ms.load(Ordering::SeqCst));
            let bound_ms = bound.as_millis() as u64;
            // CPU time, so that a run starved by other work (nice 19 on a shared machine) does
            // not report slow inputs as hangs; wall time too, for an input that blocks.
            if cpu > bound_ms || wall > bound_ms * WALL_FACTOR {
                let input = current.input.lock().map(|i| i.clone()).unwrap_or_default();
                let path = save(&failures, target, "hang", &input);
                eprintln!(
                    "HANG: a {} input ran for more than {bound:?} of CPU time ({cpu} ms CPU, {wall} ms wall); it is \
                     saved at {}",
                    target.name(),
                    path.display()
                );
                std::process::exit(3);
            }
        }
    });
    Watchdog(stop)
}

/// Peak resident memory of this process (KiB), from `/proc/self/status` (0 elsewhere).
pub fn peak_rss_kib() -> u64 {
    std::fs::read_to_string("/proc/self/status")
        .ok()
        .and_then(|s| {
            s.lines().find_map(|l| l.strip_prefix("VmHWM:").map(|v| v.trim().trim_end_matches(" kB").trim().to_owned()))
        })
        .and_then(|v| v.parse().ok())
        .unwrap_or(0)
}
