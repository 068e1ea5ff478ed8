//! Cooperative cancellation of the trainer's long work (`synth`, `fit`, `study`) by the process that
//! embeds it: the Python package's Ctrl-C or a notebook's interrupt. The work checks the flag between
//! steps, images and jobs and stops with [`Error::Interrupted`]; what it staged is dropped, so its
//! output folder is left as it was. The command line needs none of this (a signal ends it;
//! [`crate::staging`] cleans up).

use std::sync::atomic::{AtomicBool, Ordering};

use crate::Error;

static REQUESTED: AtomicBool = AtomicBool::new(false);

/// Asks every run of the trainer in this process to stop at its next check.
pub fn request() {
    REQUESTED.store(true, Ordering::SeqCst);
}

/// Withdraws the request, once the interrupted work has returned.
pub fn clear() {
    REQUESTED.store(false, Ordering::SeqCst);
}

/// `Err(Error::Interrupted)` once a stop was requested.
pub fn check() -> Result<(), Error> {
    if REQUESTED.load(Ordering::SeqCst) {
        Err(Error::Interrupted)
    } else {
        Ok(())
    }
}

/// [`check`] for the data-set code, whose errors are the core's.
pub fn check_core() -> Result<(), nbrdf::Error> {
    check().map_err(|_| nbrdf::Error::io("the run", &std::io::Error::new(std::io::ErrorKind::Interrupted, "interrupted")))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_request_stops_the_next_check_until_cleared() {
        assert!(check().is_ok());
        request();
        assert!(matches!(check(), Err(Error::Interrupted)));
        assert!(check_core().is_err());
        clear();
        assert!(check().is_ok());
    }
}
