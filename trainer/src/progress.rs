//! How far the trainer's current run is, for a front end that draws its own progress display (the
//! Python package's notebook bar); the command line draws with indicatif itself. One run at a time
//! is reported: a process that runs several reads the last one started.

use std::sync::atomic::{AtomicU64, Ordering};

static DONE: AtomicU64 = AtomicU64::new(0);
static TOTAL: AtomicU64 = AtomicU64::new(0);

/// A run of `total` units (steps, images) starts, `done` of them already behind it (a resumed fit).
pub fn start(done: u64, total: u64) {
    TOTAL.store(total, Ordering::Relaxed);
    DONE.store(done, Ordering::Relaxed);
}

/// `done` units are behind the run.
pub fn set(done: u64) {
    DONE.store(done, Ordering::Relaxed);
}

/// One more unit is done.
pub fn advance() {
    DONE.fetch_add(1, Ordering::Relaxed);
}

/// `(done, total)` of the run last started.
pub fn get() -> (u64, u64) {
    (DONE.load(Ordering::Relaxed), TOTAL.load(Ordering::Relaxed))
}
