//! Two pieces of work side by side where the caller can run them so (rayon's `join`, lent as
//! the room is): the host runs the second on another core, the chip one after the other. The
//! solver splits its per-sphere work in two with it (`solve::Workspace::helper`); the results
//! do not depend on how the caller runs them.

/// Runs two pieces of work; both have returned when [`Fork::join`] returns.
pub trait Fork: Sync + core::fmt::Debug {
    /// Run `a` and `b`, side by side or one after the other.
    fn join(&self, a: &mut dyn FnMut(), b: &mut (dyn FnMut() + Send));
}

/// One after the other, on the caller's thread.
#[derive(Debug, Clone, Copy, Default)]
pub struct InTurn;

impl Fork for InTurn {
    fn join(&self, a: &mut dyn FnMut(), b: &mut (dyn FnMut() + Send)) {
        a();
        b();
    }
}

#[cfg(test)]
mod tests {
    use super::{Fork, InTurn};

    #[test]
    fn in_turn_runs_both_one_after_the_other() {
        let (mut a, mut b) = (0u8, 0u8);
        let order = core::sync::atomic::AtomicU8::new(0);
        InTurn.join(
            &mut || a = order.fetch_add(1, core::sync::atomic::Ordering::Relaxed) + 1,
            &mut || b = order.fetch_add(1, core::sync::atomic::Ordering::Relaxed) + 1,
        );
        assert_eq!((a, b), (1, 2));
    }
}
