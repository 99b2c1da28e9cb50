//! Independent fits on every core: diagnose's candidates of one round do
//! not depend on each other, and each is a whole refit.

use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Mutex;

/// `f` applied to each of `items`, the results in `items`' order, on as
/// many threads as the machine has cores (at most one per item). A worker
/// takes the next item when it is done with one, so a long fit does not
/// hold back the others. The same results as a sequential `map`: each call
/// sees only its item and what `f` borrows.
pub(super) fn map<T: Sync, R: Send>(items: &[T], f: impl Fn(&T) -> R + Sync) -> Vec<R> {
    let workers = std::thread::available_parallelism()
        .map_or(1, usize::from)
        .min(items.len());
    if workers <= 1 {
        return items.iter().map(f).collect();
    }
    let next = AtomicUsize::new(0);
    let done: Mutex<Vec<(usize, R)>> = Mutex::new(Vec::with_capacity(items.len()));
    std::thread::scope(|scope| {
        for _ in 0..workers {
            scope.spawn(|| loop {
                let i = next.fetch_add(1, Ordering::Relaxed);
                let Some(item) = items.get(i) else { break };
                let r = f(item);
                // A poisoned lock means another worker panicked: scope
                // re-raises that panic when it joins.
                if let Ok(mut d) = done.lock() {
                    d.push((i, r));
                }
            });
        }
    });
    let mut done = done.into_inner().unwrap_or_else(|e| e.into_inner());
    done.sort_by_key(|(i, _)| *i);
    done.into_iter().map(|(_, r)| r).collect()
}

/// What a scoped thread returned (its panic, should it panic, raised
/// again here).
pub(super) fn joined<T>(handle: std::thread::ScopedJoinHandle<'_, T>) -> T {
    handle
        .join()
        .unwrap_or_else(|e| std::panic::resume_unwind(e))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_results_keep_the_items_order() {
        // Uneven work, so that the workers finish out of order.
        let work = |&n: &u64| {
            let mut x = n;
            for _ in 0..(37 - n) * 1000 {
                x = x.wrapping_mul(6364136223846793005).wrapping_add(1);
            }
            (n, x)
        };
        let items: Vec<u64> = (0..37).collect();
        let want: Vec<(u64, u64)> = items.iter().map(work).collect();
        assert_eq!(map(&items, work), want);
    }

    #[test]
    fn no_items_give_no_results() {
        let got: Vec<u8> = map(&[] as &[u8], |&x| x);
        assert!(got.is_empty());
    }
}
