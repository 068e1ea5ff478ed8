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
    check_flag(&REQUESTED)
}

fn check_flag(flag: &AtomicBool) -> Result<(), Error> {
    if flag.load(Ordering::SeqCst) {
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

    // On a flag of its own: the process-wide one would stop the fits other tests run meanwhile.
    #[test]
    fn a_raised_flag_stops_the_next_check_with_interrupted() {
        let flag = AtomicBool::new(false);
        assert!(check_flag(&flag).is_ok());
        flag.store(true, Ordering::SeqCst);
        assert!(matches!(check_flag(&flag), Err(Error::Interrupted)));
        assert!(check().is_ok(), "the process-wide flag is untouched");
    }
}
