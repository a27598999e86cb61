//! Thread stack sizes, in one place. The interpolator keeps its look-ahead
//! in fixed-capacity arrays (no allocation on the RT path) and is built on
//! a thread's stack before it is boxed; an unoptimised build copies it
//! several times on the way. Only the pages a thread touches are committed,
//! so these are reservations, not memory spent.

/// A thread that builds an [`crate::Run`] or its executor and driver: the
/// service's RT and planning threads and the thread every `interpd`
/// command runs on (an unoptimised `interpd simulate` needs 12–14 MiB).
pub const RT_STACK_BYTES: usize = 32 << 20;

/// The service's control-plane thread: a program's pipeline builds its
/// `G64 P` stage (`interp_core::Smoother`, 420 KB) on it before boxing it
/// (2 MiB, the default, overflowed in unoptimised builds).
pub const CONTROL_STACK_BYTES: usize = 16 << 20;

/// A thread that owns an `Interpolator<1024>` (about 7.2 MB) or runs a
/// bench's planned programs: the tests' path-time runs, the examples, the
/// benches.
pub const INTERPOLATOR_STACK_BYTES: usize = 64 << 20;

/// Runs `f` on a thread of [`INTERPOLATOR_STACK_BYTES`] and returns what it
/// returns (a bench's or an example's whole run: a panic in `f` is passed
/// on).
pub fn on_interpolator_stack<T: Send + 'static>(f: impl FnOnce() -> T + Send + 'static) -> T {
    let thread = std::thread::Builder::new()
        .stack_size(INTERPOLATOR_STACK_BYTES)
        .spawn(f)
        .expect("a thread with the interpolator's stack");
    thread
        .join()
        .unwrap_or_else(|panic| std::panic::resume_unwind(panic))
}

/// Every test thread's stack: `RUST_MIN_STACK` in `.cargo/config.toml`
/// (which cannot name this constant; a test holds the two equal), enough to
/// build an `Interpolator` with the default look-ahead in an unoptimised
/// build (16 MiB overflowed in a five-axis test once one linear program
/// held 1,024 pieces).
pub const TEST_STACK_BYTES: usize = 64 << 20;

#[cfg(test)]
mod tests {
    /// `.cargo/config.toml` sets `RUST_MIN_STACK` for every process cargo
    /// runs; it must be [`super::TEST_STACK_BYTES`]. (A test binary run
    /// by hand, without cargo, has no such variable: nothing to compare.)
    #[test]
    fn cargo_config_sets_the_test_stack() {
        if let Ok(v) = std::env::var("RUST_MIN_STACK") {
            assert_eq!(v.parse::<usize>(), Ok(super::TEST_STACK_BYTES), "{v}");
        }
    }
}
