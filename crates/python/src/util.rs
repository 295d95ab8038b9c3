//! Argument helpers shared by the binding modules: errors name the argument and the value,
//! and are raised as the classes of `piezohyst.errors` (each also a builtin
//! `ValueError`), so Python callers see one vocabulary whichever layer refused.
use numpy::PyReadonlyArray1;
use piezohyst_core::ModelError;
use pyo3::prelude::*;

pyo3::import_exception!(piezohyst.errors, ParameterError);
pyo3::import_exception!(piezohyst.errors, NotInvertibleError);
pyo3::import_exception!(piezohyst.errors, UnreachableError);

/// What a core error is about: `(parameter, index, value)`, each `None` where it does not
/// apply. Raised errors carry them as the attributes `.parameter`, `.index`, `.value`.
pub fn subject(e: &ModelError) -> (Option<&'static str>, Option<usize>, Option<f64>) {
    let at = |i: usize| if i == usize::MAX { None } else { Some(i) };
    match *e {
        ModelError::NotFinite(n, i, v)
        | ModelError::Negative(n, i, v)
        | ModelError::NotPositive(n, i, v)
        | ModelError::NotIncreasing(n, i, v)
        | ModelError::OutOfRange(n, i, v, _, _) => (Some(n), at(i), Some(v)),
        ModelError::Length(n, _, got) => (Some(n), None, Some(got as f64)),
        ModelError::Structure(n, v) => (Some(n), None, Some(v as f64)),
        ModelError::NotInvertible(i, s) => (Some("weights"), Some(i), Some(s)),
        ModelError::Unreachable(k, y) => (Some("desired"), Some(k), Some(y)),
        ModelError::EnvelopeNotMonotone(n, v, _) => (Some(n), None, Some(v)),
        ModelError::EnvelopesCross(v, i) => (Some("thresholds"), Some(i), Some(v)),
        ModelError::NoAnalyticInverse(_) => (None, None, None),
    }
}

/// A core error as the matching `piezohyst.errors` class, with `.parameter`, `.index` and
/// `.value` set from the error (see [`subject`]); `context` (if not empty) prefixes the
/// message.
pub fn err_in(context: &str, e: ModelError) -> PyErr {
    let msg = if context.is_empty() { e.to_string() } else { format!("{context}: {e}") };
    let raised = match e {
        ModelError::NotInvertible(..) => NotInvertibleError::new_err(msg),
        ModelError::Unreachable(..) => UnreachableError::new_err(msg),
        _ => ParameterError::new_err(msg),
    };
    let (parameter, index, value) = subject(&e);
    Python::attach(|py| {
        let v = raised.value(py);
        // plain attributes of a Python exception instance: setting them cannot fail
        let _ = v.setattr("parameter", parameter);
        let _ = v.setattr("index", index);
        let _ = v.setattr("value", value);
    });
    raised
}

/// A core error as the matching `piezohyst.errors` class (see [`err_in`]).
pub fn err(e: ModelError) -> PyErr {
    err_in("", e)
}

/// A bad argument (`piezohyst.errors.ParameterError`, a `ValueError`).
pub fn bad_arg(msg: String) -> PyErr {
    ParameterError::new_err(msg)
}

/// The array's data, which must be contiguous.
pub fn slice<'a>(a: &'a PyReadonlyArray1<'_, f64>, name: &str) -> PyResult<&'a [f64]> {
    a.as_slice().map_err(|_| bad_arg(format!("{name} must be a contiguous float64 array")))
}

/// Every value finite, else an error naming the first offender.
pub fn check_finite(name: &str, xs: &[f64]) -> PyResult<()> {
    match xs.iter().position(|x| !x.is_finite()) {
        Some(k) => Err(bad_arg(format!("{name}[{k}] = {} is not finite", xs[k]))),
        None => Ok(()),
    }
}

// ---------------------------------------------------------------------------------------
// the last line of defence, resource bounds, interrupts (issue 20)

pyo3::import_exception!(piezohyst.errors, InternalError);
pyo3::import_exception!(piezohyst.errors, ResourceLimitError);

/// Run an entry point's body and turn a panic (a bug: every argument and state is
/// validated first) into `piezohyst.errors.InternalError` — a `PiezohystError`, so
/// `except PiezohystError` / `except Exception` catch it, unlike PyO3's `PanicException`
/// (a `BaseException`). A panic on a rayon worker reaches here too (rayon resumes it on
/// the calling thread).
pub fn guarded<T>(f: impl FnOnce() -> PyResult<T>) -> PyResult<T> {
    match std::panic::catch_unwind(std::panic::AssertUnwindSafe(f)) {
        Ok(r) => r,
        Err(payload) => {
            let text = payload
                .downcast_ref::<&str>()
                .copied()
                .or_else(|| payload.downcast_ref::<String>().map(String::as_str))
                .unwrap_or("(no message)");
            Err(InternalError::new_err(format!("internal error (a bug in piezohyst; please report it): {text}")))
        }
    }
}

/// The environment variable that sets [`max_alloc_bytes`].
pub const MAX_ALLOC_ENV: &str = "PIEZOHYST_MAX_ALLOC_BYTES";
/// Default of [`max_alloc_bytes`]: 2 GiB.
pub const DEFAULT_MAX_ALLOC_BYTES: u64 = 2 << 30;

/// Most bytes one call may allocate for its result and work buffers: `PIEZOHYST_MAX_ALLOC_BYTES`
/// (a whole number of bytes) or 2 GiB. Read at each call, so a test or a session can raise it.
pub fn max_alloc_bytes() -> PyResult<u64> {
    match std::env::var(MAX_ALLOC_ENV) {
        Err(_) => Ok(DEFAULT_MAX_ALLOC_BYTES),
        Ok(s) => s.trim().parse::<u64>().map_err(|_| {
            bad_arg(format!("{MAX_ALLOC_ENV} = {s:?} is not a whole number of bytes (unset it for the default, 2 GiB)"))
        }),
    }
}

fn human(bytes: f64) -> String {
    const UNITS: [&str; 5] = ["B", "KiB", "MiB", "GiB", "TiB"];
    let mut x = bytes;
    let mut u = 0;
    while x >= 1024.0 && u + 1 < UNITS.len() {
        x /= 1024.0;
        u += 1;
    }
    format!("{x:.1} {}", UNITS[u])
}

/// Refuse a request before allocating: `what` needs `factors` (multiplied) `f64` values.
/// Raises `piezohyst.errors.ResourceLimitError` (a `MemoryError`) naming the size, the
/// limit and how to raise it.
pub fn check_alloc(what: &str, factors: &[usize]) -> PyResult<()> {
    let limit = max_alloc_bytes()?;
    let values = factors.iter().try_fold(1u64, |acc, &f| acc.checked_mul(f as u64));
    let bytes = values.and_then(|v| v.checked_mul(8));
    let shape = factors.iter().map(|f| f.to_string()).collect::<Vec<_>>().join(" x ");
    match bytes {
        Some(b) if b <= limit => Ok(()),
        _ => {
            let need = factors.iter().fold(8.0, |acc, &f| acc * f as f64);
            Err(ResourceLimitError::new_err(format!(
                "{what} needs {} ({shape} float64 values), above the limit of {} ({limit} bytes); raise it with the \
                 environment variable {MAX_ALLOC_ENV} (bytes) if the machine has the memory",
                human(need),
                human(limit as f64),
            )))
        }
    }
}

/// A stop request seen by long loops: set when the calling thread found a pending signal.
#[derive(Debug, Default)]
pub struct Stop(std::sync::atomic::AtomicBool);

impl Stop {
    /// Whether the work should stop now (its result will be discarded).
    #[inline]
    pub fn stopped(&self) -> bool {
        self.0.load(std::sync::atomic::Ordering::Relaxed)
    }
}

/// How often a waiting caller checks for signals (Ctrl-C stops within about this, plus one
/// chunk of work).
const POLL: std::time::Duration = std::time::Duration::from_millis(50);

/// Run `work` (which may use rayon) on a helper thread while the calling thread, with the
/// GIL released, checks for signals every 50 ms: on a pending signal (Ctrl-C) the stop flag
/// is set, `work` (which polls it between rows and every few thousand samples) returns
/// early, and the signal handler's exception (`KeyboardInterrupt`) is raised. A panic in
/// `work` is resumed on the calling thread (see [`guarded`]).
pub fn interruptible<T: Send>(py: Python<'_>, work: impl FnOnce(&Stop) -> T + Send) -> PyResult<T> {
    use std::sync::{Condvar, Mutex};
    let stop = Stop::default();
    let done = (Mutex::new(false), Condvar::new());
    let mut interrupted = None;
    let result = std::thread::scope(|s| {
        let (stop, done) = (&stop, &done);
        let handle = s.spawn(move || {
            let r = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| work(stop)));
            *done.0.lock().unwrap_or_else(|e| e.into_inner()) = true;
            done.1.notify_all();
            r
        });
        // wait until the work is done, looking for signals every POLL
        let finished = || {
            let g = done.0.lock().unwrap_or_else(|e| e.into_inner());
            let (g, _) = done.1.wait_timeout_while(g, POLL, |d| !*d).unwrap_or_else(|e| e.into_inner());
            *g
        };
        while !py.detach(finished) {
            if let Err(e) = py.check_signals() {
                stop.0.store(true, std::sync::atomic::Ordering::Relaxed);
                interrupted = Some(e);
                break;
            }
        }
        py.detach(|| handle.join())
    });
    match result {
        Ok(Ok(r)) => match interrupted {
            Some(e) => Err(e),
            None => Ok(r),
        },
        Ok(Err(payload)) | Err(payload) => std::panic::resume_unwind(payload),
    }
}

/// Work (in model steps x state slots) above which a single-threaded call goes through
/// [`interruptible`]; below it, the thread hand-off would cost more than the call.
pub const INTERRUPTIBLE_WORK: usize = 1 << 22;

/// Whether the hot loops take their AVX2 path: the CPU has AVX2 and `PIEZOHYST_NO_AVX2` is not
/// set (read once; the benchmark sets it to check that both paths give the same bits).
#[cfg(target_arch = "x86_64")]
pub fn use_avx2() -> bool {
    static USE: std::sync::OnceLock<bool> = std::sync::OnceLock::new();
    *USE.get_or_init(|| std::is_x86_feature_detected!("avx2") && std::env::var_os("PIEZOHYST_NO_AVX2").is_none())
}
