//! Independent jobs on a few scoped threads, results in the order of the jobs.

use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::Mutex;

/// `f(i)` for each `i` in `0..n` on at most `threads` threads, each taking the next index
/// when it is free; `None` where `interrupt` was set before the job started or `f` gave none.
pub fn map<T: Send>(
    n: usize,
    threads: usize,
    interrupt: &AtomicBool,
    f: impl Fn(usize) -> Option<T> + Sync,
) -> Vec<Option<T>> {
    let next = AtomicUsize::new(0);
    let out: Mutex<Vec<Option<T>>> = Mutex::new((0..n).map(|_| None).collect());
    std::thread::scope(|sc| {
        for _ in 0..threads.clamp(1, n.max(1)) {
            sc.spawn(|| loop {
                let i = next.fetch_add(1, Ordering::Relaxed);
                if i >= n || interrupt.load(Ordering::Relaxed) {
                    break;
                }
                let v = f(i);
                if let Ok(mut o) = out.lock() {
                    o[i] = v;
                }
            });
        }
    });
    out.into_inner().unwrap_or_default()
}
