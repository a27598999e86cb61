//! The fixed-period loop's clock: `CLOCK_MONOTONIC` in nanoseconds and a
//! sleep until an absolute deadline (`clock_nanosleep(TIMER_ABSTIME)`), so
//! that periods never drift and lateness is measured against the deadline.

/// Nanoseconds per second.
pub const NS_PER_S: i64 = 1_000_000_000;

/// Now on `CLOCK_MONOTONIC`, ns.
#[cfg(target_os = "linux")]
#[allow(clippy::unnecessary_cast)] // `time_t` / `c_long` are i32 on some targets
pub fn now_ns() -> i64 {
    let mut ts = libc::timespec {
        tv_sec: 0,
        tv_nsec: 0,
    };
    // SAFETY: `ts` is a valid, writable `timespec`; CLOCK_MONOTONIC always exists on
    // Linux, so the call cannot fail.
    unsafe { libc::clock_gettime(libc::CLOCK_MONOTONIC, &mut ts) };
    ts.tv_sec as i64 * NS_PER_S + ts.tv_nsec as i64
}

/// Sleeps until `deadline` (ns on `CLOCK_MONOTONIC`); returns at once if it has passed.
/// Never wakes early: interrupted sleeps are resumed.
#[cfg(target_os = "linux")]
#[allow(clippy::unnecessary_cast)]
pub fn sleep_until_ns(deadline: i64) {
    let ts = libc::timespec {
        tv_sec: deadline.div_euclid(NS_PER_S) as libc::time_t,
        tv_nsec: deadline.rem_euclid(NS_PER_S) as libc::c_long,
    };
    loop {
        // SAFETY: `ts` is a valid `timespec`; with TIMER_ABSTIME the remainder
        // pointer is unused and may be null.
        let rc = unsafe {
            libc::clock_nanosleep(
                libc::CLOCK_MONOTONIC,
                libc::TIMER_ABSTIME,
                &ts,
                core::ptr::null_mut(),
            )
        };
        if rc != libc::EINTR {
            return;
        }
    }
}

/// Waits until `deadline` (ns on the monotonic clock): sleeps until `spin_ns`
/// before it, then spins on the clock. Spinning keeps the core from idling
/// just before the deadline, so that waking from idle (and, in a VM, the host
/// rescheduling the virtual CPU) is paid before the deadline, not after it.
/// Never returns before the deadline.
pub fn wait_until_ns(deadline: i64, spin_ns: i64) {
    if spin_ns <= 0 {
        sleep_until_ns(deadline);
        return;
    }
    sleep_until_ns(deadline - spin_ns);
    while now_ns() < deadline {
        core::hint::spin_loop();
    }
}

/// Asks for the smallest timer slack (1 ns) on the calling thread, so that
/// absolute sleeps are not rounded up by the default 50 µs of a normal-priority
/// thread. Unprivileged; returns whether it took effect.
#[cfg(target_os = "linux")]
pub fn minimise_timer_slack() -> bool {
    let one: libc::c_ulong = 1;
    // SAFETY: PR_SET_TIMERSLACK takes one unsigned long and touches no memory.
    unsafe { libc::prctl(libc::PR_SET_TIMERSLACK, one) == 0 }
}

/// No timer slack control off Linux.
#[cfg(not(target_os = "linux"))]
pub fn minimise_timer_slack() -> bool {
    false
}

#[cfg(not(target_os = "linux"))]
fn epoch() -> std::time::Instant {
    static EPOCH: std::sync::OnceLock<std::time::Instant> = std::sync::OnceLock::new();
    *EPOCH.get_or_init(std::time::Instant::now)
}

/// Now on the monotonic clock, ns (from a process-wide epoch off Linux).
#[cfg(not(target_os = "linux"))]
pub fn now_ns() -> i64 {
    i64::try_from(epoch().elapsed().as_nanos()).unwrap_or(i64::MAX)
}

/// Sleeps until `deadline` (ns, see [`now_ns`]) with `std::thread::sleep`.
#[cfg(not(target_os = "linux"))]
pub fn sleep_until_ns(deadline: i64) {
    let left = deadline - now_ns();
    if left > 0 {
        std::thread::sleep(core::time::Duration::from_nanos(left as u64));
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sleeps_until_the_deadline_and_not_before() {
        let t0 = now_ns();
        let deadline = t0 + 2_000_000;
        sleep_until_ns(deadline);
        assert!(now_ns() >= deadline);
        // A past deadline returns at once.
        sleep_until_ns(t0);
        assert!(now_ns() >= t0);
    }

    #[test]
    fn a_spinning_wait_returns_at_the_deadline_and_not_before() {
        for spin_ns in [0, 300_000, 5_000_000] {
            let deadline = now_ns() + 1_000_000;
            wait_until_ns(deadline, spin_ns);
            let woke = now_ns();
            assert!(
                woke >= deadline,
                "spin {spin_ns} ns woke {} ns early",
                deadline - woke
            );
        }
    }
}
