//! Every SIGTERM reaches the run, also one that comes while METIS orders a matrix (METIS
//! installs its own SIGTERM handler around each call: `skinsim_tools::signals`).
//!
//! Its own test binary without libtest's harness: signal masks are per thread and inherited,
//! so `take_over` must run on the main thread before any other thread starts.

use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

#[cfg(unix)]
/// The lower triangle (CSC) of a 5-point grid's matrix: `side`² unknowns.
fn grid(side: u32) -> (Vec<u32>, Vec<u32>) {
    let (mut col_ptr, mut row_idx) = (vec![0u32], Vec::new());
    for c in 0..side * side {
        row_idx.push(c);
        if c % side + 1 < side {
            row_idx.push(c + 1);
        }
        if c + side < side * side {
            row_idx.push(c + side);
        }
        col_ptr.push(row_idx.len() as u32);
    }
    (col_ptr, row_idx)
}

#[cfg(unix)]
fn main() {
    skinsim_tools::signals::take_over().expect("take over the signals");
    let taken = Arc::new(AtomicUsize::new(0));
    let counter = taken.clone();
    skinsim_tools::signals::on_signal(move || {
        counter.fetch_add(1, Ordering::SeqCst);
    });
    // One thread orders all the time; the other sends signals, each waited for before the next.
    let stop = Arc::new(AtomicBool::new(false));
    let (halt, orderings) = (stop.clone(), Arc::new(AtomicUsize::new(0)));
    let done = orderings.clone();
    let (col_ptr, row_idx) = grid(60);
    let orderer = std::thread::spawn(move || {
        while !halt.load(Ordering::SeqCst) {
            let order = skinsim::solve::ordering::metis_nested_dissection(&col_ptr, &row_idx);
            assert!(order.is_some(), "METIS failed: a signal reached it");
            done.fetch_add(1, Ordering::SeqCst);
        }
    });
    while orderings.load(Ordering::SeqCst) == 0 {
        std::thread::sleep(Duration::from_millis(1));
    }
    // At least 200 signals, and on until 50 orderings have run meanwhile.
    let mut k = 0;
    while k < 200 || orderings.load(Ordering::SeqCst) < 50 {
        // To the process, as kill(1) sends it (raise would send it to this thread alone).
        let me = nix::unistd::Pid::from_raw(std::process::id() as i32);
        nix::sys::signal::kill(me, nix::sys::signal::Signal::SIGTERM).expect("kill");
        let sent = Instant::now();
        while taken.load(Ordering::SeqCst) <= k {
            assert!(sent.elapsed() < Duration::from_secs(10), "signal {} was lost", k + 1);
            std::thread::sleep(Duration::from_micros(200));
        }
        std::thread::sleep(Duration::from_micros(300 + 37 * (k as u64 % 11)));
        k += 1;
    }
    stop.store(true, Ordering::SeqCst);
    orderer.join().expect("the ordering thread");
    let n = orderings.load(Ordering::SeqCst);
    assert_eq!(taken.load(Ordering::SeqCst), k, "more signals taken than sent");
    println!("signals: {k} sent and taken, during {n} METIS orderings");
}

#[cfg(not(unix))]
fn main() {}
