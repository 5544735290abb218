//! The machine's spare cores, lent to work that can run beside the thread that needs it.
//!
//! A diagnosis runs on one thread, but the columns of a finite-difference Jacobian are
//! independent model evaluations that a free core can share
//! ([`crate::diagnose::fit::Problem::whitened_batch`]). The pool holds
//! `available_parallelism − 1` tokens; whoever holds one may run one more thread. Work that
//! gets none runs on its own thread: the results are the same either way, only the time differs,
//! so an answer never depends on the machine or its load.

use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::OnceLock;

/// Tokens lent out now.
static LENT: AtomicUsize = AtomicUsize::new(0);

/// The cores besides the calling thread's: `available_parallelism − 1` (0 when unknown).
fn spare_total() -> usize {
    static TOTAL: OnceLock<usize> = OnceLock::new();
    *TOTAL.get_or_init(|| {
        std::thread::available_parallelism()
            .map_or(1, |n| n.get())
            .saturating_sub(1)
    })
}

/// A spare core lent to its holder; returned to the pool when dropped.
#[derive(Debug)]
pub struct SpareCore(());

impl Drop for SpareCore {
    fn drop(&mut self) {
        LENT.fetch_sub(1, Ordering::AcqRel);
    }
}

/// A spare core if one is free now, `None` otherwise.
pub fn take() -> Option<SpareCore> {
    LENT.fetch_update(Ordering::AcqRel, Ordering::Acquire, |n| {
        (n < spare_total()).then_some(n + 1)
    })
    .ok()
    .map(|_| SpareCore(()))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn no_more_cores_are_lent_than_the_machine_has_spare() {
        let held: Vec<SpareCore> = std::iter::from_fn(take).take(1024).collect();
        assert!(
            held.len() <= spare_total(),
            "{} > {}",
            held.len(),
            spare_total()
        );
        drop(held);
        // other tests may hold tokens now; at least none of ours is still counted
        assert!(LENT.load(Ordering::Acquire) <= spare_total());
    }
}
