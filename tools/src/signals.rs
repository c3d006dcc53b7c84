//! SIGINT, SIGTERM and SIGHUP, taken by one thread with `sigwait` rather than by a handler.
//!
//! Why not a handler (the `ctrlc` crate, until this was found): METIS, which orders the sparse
//! factorizations, installs its own SIGTERM handler around every call (GKlib's error.c,
//! `gk_sigtrap`: its internal errors raise SIGTERM and longjmp back into METIS), and restores
//! the previous one afterwards as a one-shot handler. A SIGTERM that arrived during an ordering
//! was taken by METIS, which then failed over to our own ordering, and the run never heard of
//! it: `remesh_one_layer_quick`, signalled in its third frame, went on in 3 runs of 6. Had the
//! signal reached a thread other than METIS's, its handler would have jumped to a buffer that
//! thread never set.
//!
//! [`take_over`] blocks the three signals in the calling thread, so in every thread started
//! after it, and starts one thread that waits for them. A blocked signal stays pending until
//! that thread takes it, whatever handler is installed meanwhile. Children started with
//! `std::process::Command` get an empty signal mask back.
//!
//! Elsewhere than on Unix, Ctrl-C goes through the `ctrlc` crate.

#[cfg(unix)]
use nix::sys::signal::{self, SigHandler, SigSet, SigmaskHow, Signal};
use std::sync::Mutex;

/// What a signal does once [`take_over`] has run: `None` is the default action (the process
/// ends as the signal's own default would end it).
type Action = Box<dyn Fn() + Send>;
static ACTION: Mutex<Option<Action>> = Mutex::new(None);

fn action() -> std::sync::MutexGuard<'static, Option<Action>> {
    ACTION.lock().unwrap_or_else(std::sync::PoisonError::into_inner)
}

#[cfg(unix)]
fn the_three() -> SigSet {
    let mut set = SigSet::empty();
    for s in [Signal::SIGINT, Signal::SIGTERM, Signal::SIGHUP] {
        set.add(s);
    }
    set
}

/// Block SIGINT, SIGTERM and SIGHUP here and in every thread started afterwards, and take them
/// in a thread of their own. Call it first thing in `main`, before any thread is started.
#[cfg(unix)]
pub fn take_over() -> std::io::Result<()> {
    let set = the_three();
    set.thread_block().map_err(std::io::Error::from)?;
    std::thread::Builder::new().name("signals".into()).spawn(move || loop {
        let Ok(sig) = set.wait() else { continue };
        match action().as_ref() {
            Some(act) => act(),
            None => default_action(sig),
        }
    })?;
    Ok(())
}

/// Ctrl-C through the `ctrlc` crate's handler.
#[cfg(not(unix))]
pub fn take_over() -> std::io::Result<()> {
    ctrlc::set_handler(|| match action().as_ref() {
        Some(act) => act(),
        None => std::process::exit(130),
    })
    .map_err(std::io::Error::other)
}

/// From now on a signal calls `act` (on the signals' thread) instead of ending the process.
pub fn on_signal(act: impl Fn() + Send + 'static) {
    *action() = Some(Box::new(act));
}

/// End the process as `sig`'s default disposition would: restore it, unblock it in this thread
/// and send it to this thread.
#[cfg(unix)]
fn default_action(sig: Signal) {
    // SAFETY: SIG_DFL installs no Rust code as a handler.
    let _ = unsafe { signal::signal(sig, SigHandler::SigDfl) };
    let mut one = SigSet::empty();
    one.add(sig);
    let _ = signal::pthread_sigmask(SigmaskHow::SIG_UNBLOCK, Some(&one), None);
    let _ = signal::raise(sig);
    // Only reached if the default was not to end the process.
    std::process::exit(128 + sig as i32);
}
