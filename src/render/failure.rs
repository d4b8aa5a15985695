//! A device's failure contained: a device lost mid-render (the driver gone, the GPU reset)
//! panics in the code that waits on it; on a team of devices (`multi`, the preview's
//! helpers) that panic is caught on the device's own thread, its samples are given back to
//! the others (`Claims::release`), and the render goes on.

use std::cell::Cell;
use std::panic::{AssertUnwindSafe, catch_unwind};

crate::message_error!(
    /// A device's failure: the message of the panic that ended its work.
    DeviceFailure
);

thread_local! {
    static CONTAINED: Cell<bool> = const { Cell::new(false) };
}

/// Runs `f`, catching a panic as its message. While it runs, `containing()` is true on this
/// thread, so that a panic hook leaves the process as it is (the preview's restores the
/// terminal only for a panic that ends the program).
pub fn contained<T>(f: impl FnOnce() -> T) -> Result<T, DeviceFailure> {
    let outer = CONTAINED.with(|c| c.replace(true));
    // The device's state is dropped with its failure; nothing that outlives `f` is left
    // half-changed but the claims, which `release` mends.
    let result = catch_unwind(AssertUnwindSafe(f));
    CONTAINED.with(|c| c.set(outer));
    result.map_err(|payload| {
        payload
            .downcast_ref::<&str>()
            .map(|s| s.to_string())
            .or_else(|| payload.downcast_ref::<String>().cloned())
            .map_or_else(|| "a panic without a message".into(), DeviceFailure)
    })
}

/// Whether this thread is running in `contained` (its panics are caught).
pub fn containing() -> bool {
    CONTAINED.with(Cell::get)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_panic_is_caught_with_its_message() {
        assert_eq!(contained(|| 7), Ok(7));
        let r: Result<(), DeviceFailure> = contained(|| panic!("lost {}", 3));
        let s: Result<(), DeviceFailure> = contained(|| {
            assert!(containing());
            panic!("gone")
        });
        assert_eq!(r, Err("lost 3".into()));
        assert_eq!(s, Err("gone".into()));
        assert!(!containing());
    }
}
