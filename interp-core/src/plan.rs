//! Feed scheduling (non-RT): a speed-limit profile on a global arc-length
//! grid, and the look-ahead pass under the tangential acceleration limit.
//!
//! The grid has spacing `h` and is anchored at arc length 0 of the run, not at
//! block boundaries, so where a curve is cut into blocks or segments does not
//! change the schedule (a split curve gives the same setpoints as the whole).
//! Interval `g` covers `[g·h, (g+1)·h]`; its `cap` is the minimum of the feed
//! laws over `law_samples_per_interval + 1` points evenly spaced in arc length.
//! Node `g` (at `g·h`) gets `min(cap[g−1], cap[g])`, then the backward pass
//! lowers node limits so the machine can brake, at every node, to every later
//! limit and to rest at each stop (corner, end of the queue). The RT tick only
//! reads these numbers.

use crate::path::{MrrParams, Path};

/// Grid intervals the profile ring holds (look-ahead distance = this × `h`).
pub const MAX_PROFILE: usize = 4096;

/// A piece of a block in the RT queue.
#[derive(Clone, Copy, Debug)]
pub struct Segment {
    /// Geometry.
    pub path: Path,
    /// Id of the block this piece belongs to.
    pub block_id: u32,
    /// Programmed feed, mm/s.
    pub feed: f64,
    /// MRR law parameters of the block.
    pub mrr: Option<MrrParams>,
    /// Arc length of the run at the start of this segment, mm.
    pub s0: f64,
    /// Arc length of this segment, mm.
    pub length: f64,
    /// The path must come to rest at the end of this segment (a corner, or
    /// the end of what is queued).
    pub stop_at_end: bool,
}

impl Segment {
    /// Arc length of the run at the end of this segment, mm.
    #[inline]
    pub fn s1(&self) -> f64 {
        self.s0 + self.length
    }
}

/// Fixed-capacity ring of grid intervals.
///
/// Per interval it holds the raw limits sampled from the feed laws (`raw`:
/// machine, chord-error, centripetal and per-axis laws; `raw_feed`: the
/// programmed feed and the MRR law, which the feed override scales), the same
/// two limits eroded for the jerk filter (`cap`, `feed_cap`, see
/// [`Profile::erode`]), the planned node limit at the interval's start (`v`,
/// from the backward pass) and whether a full stop lies inside it.
#[derive(Clone, Debug)]
pub struct Profile {
    h: f64,
    /// Grid index of the first interval held.
    base: i64,
    head: usize,
    len: usize,
    raw: [f64; MAX_PROFILE],
    raw_feed: [f64; MAX_PROFILE],
    cap: [f64; MAX_PROFILE],
    feed_cap: [f64; MAX_PROFILE],
    v: [f64; MAX_PROFILE],
    stop: [bool; MAX_PROFILE],
    /// Scratch space of `erode`: candidate indices and values, right-side results.
    scratch_q: [i64; MAX_PROFILE + 1],
    scratch_c: [f64; MAX_PROFILE + 1],
    scratch_val: [f64; MAX_PROFILE],
}

/// How [`Profile::erode`] shapes the limits around each interval.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Erosion {
    /// Speed allowed per interval of distance from a lower limit, mm/s: `h/T`
    /// for a filter window `T` (infinite: no erosion).
    pub slope: f64,
    /// The same for the override-scaled feed limit: `h/(T·max_override)`.
    pub feed_slope: f64,
    /// Intervals from this one on are unknown yet (the queue may grow): they
    /// count as a zero limit. `None` once the program is finished.
    pub cone_from: Option<i64>,
    /// An upper bound on every raw limit held (the machine's top speed): no
    /// candidate farther than `top/slope` intervals can be the minimum, so
    /// erosion looks no farther back. Infinite: scan the ring for it (linear
    /// in what is queued, not in what changed).
    pub top: f64,
}

impl Profile {
    /// An empty profile with grid spacing `h` (mm).
    pub fn new(h: f64) -> Self {
        Profile {
            h,
            base: 0,
            head: 0,
            len: 0,
            raw: [f64::INFINITY; MAX_PROFILE],
            raw_feed: [f64::INFINITY; MAX_PROFILE],
            cap: [f64::INFINITY; MAX_PROFILE],
            feed_cap: [f64::INFINITY; MAX_PROFILE],
            v: [0.0; MAX_PROFILE],
            stop: [false; MAX_PROFILE],
            scratch_q: [0; MAX_PROFILE + 1],
            scratch_c: [0.0; MAX_PROFILE + 1],
            scratch_val: [0.0; MAX_PROFILE],
        }
    }
    /// Grid spacing, mm.
    #[inline]
    pub fn h(&self) -> f64 {
        self.h
    }
    /// Grid index of the interval containing arc length `s`.
    #[inline]
    pub fn index_of(&self, s: f64) -> i64 {
        libm::floor(s / self.h) as i64
    }
    /// First grid index held.
    #[inline]
    pub fn base(&self) -> i64 {
        self.base
    }
    /// One past the last grid index held.
    #[inline]
    pub fn end(&self) -> i64 {
        self.base + self.len as i64
    }
    #[inline]
    fn held(&self, g: i64) -> bool {
        g >= self.base && g < self.end()
    }
    #[inline]
    fn slot(&self, g: i64) -> usize {
        debug_assert!(self.held(g));
        (self.head + (g - self.base) as usize) % MAX_PROFILE
    }
    /// Eroded machine-law limit of interval `g` (mm/s); infinity outside what is held.
    #[inline]
    pub fn cap(&self, g: i64) -> f64 {
        if self.held(g) {
            self.cap[self.slot(g)]
        } else {
            f64::INFINITY
        }
    }
    /// Eroded feed limit of interval `g` at 100 % override (mm/s).
    #[inline]
    pub fn feed_cap(&self, g: i64) -> f64 {
        if self.held(g) {
            self.feed_cap[self.slot(g)]
        } else {
            f64::INFINITY
        }
    }
    /// Raw (sampled, not eroded) machine-law limit of interval `g`.
    #[inline]
    pub fn raw_cap(&self, g: i64) -> f64 {
        if self.held(g) {
            self.raw[self.slot(g)]
        } else {
            f64::INFINITY
        }
    }
    /// The limit of interval `g` at feed override `ovr`.
    #[inline]
    pub fn limit(&self, g: i64, ovr: f64) -> f64 {
        self.cap(g).min(ovr * self.feed_cap(g))
    }
    /// Planned limit at node `g` (mm/s); zero outside what is held.
    #[inline]
    pub fn node(&self, g: i64) -> f64 {
        if self.held(g) {
            self.v[self.slot(g)]
        } else {
            0.0
        }
    }
    /// Does a full stop lie inside interval `g`?
    #[inline]
    pub fn has_stop(&self, g: i64) -> bool {
        self.held(g) && self.stop[self.slot(g)]
    }
    /// Room to extend the ring up to and including interval `g`?
    pub fn can_extend_to(&self, g: i64) -> bool {
        g < self.base + MAX_PROFILE as i64
    }
    /// Make intervals up to and including `g` present (new ones uncapped).
    /// Returns false (changing nothing) when the ring is too small.
    pub fn extend_to(&mut self, g: i64) -> bool {
        if !self.can_extend_to(g) {
            return false;
        }
        while self.end() <= g {
            let slot = (self.head + self.len) % MAX_PROFILE;
            self.raw[slot] = f64::INFINITY;
            self.raw_feed[slot] = f64::INFINITY;
            self.cap[slot] = f64::INFINITY;
            self.feed_cap[slot] = f64::INFINITY;
            self.v[slot] = 0.0;
            self.stop[slot] = false;
            self.len += 1;
        }
        true
    }
    /// Restart an empty ring at grid index `g`.
    pub fn reset_at(&mut self, g: i64) {
        self.base = g;
        self.head = 0;
        self.len = 0;
    }
    /// Lower the raw machine-law limit of interval `g` to `c`.
    #[inline]
    pub fn lower_cap(&mut self, g: i64, c: f64) {
        if self.held(g) {
            let k = self.slot(g);
            if c < self.raw[k] {
                self.raw[k] = c;
            }
        }
    }
    /// Lower the raw feed limit (100 % override) of interval `g` to `c`.
    #[inline]
    pub fn lower_feed_cap(&mut self, g: i64, c: f64) {
        if self.held(g) {
            let k = self.slot(g);
            if c < self.raw_feed[k] {
                self.raw_feed[k] = c;
            }
        }
    }
    /// Mark a full stop inside interval `g`.
    #[inline]
    pub fn mark_stop(&mut self, g: i64) {
        if self.held(g) {
            let k = self.slot(g);
            self.stop[k] = true;
        }
    }
    /// Set node `g`'s limit.
    #[inline]
    pub fn set_node(&mut self, g: i64, v: f64) {
        if self.held(g) {
            let k = self.slot(g);
            self.v[k] = v;
        }
    }
    /// A node's limit before look-ahead: the smaller limit of its two
    /// intervals, with the feed limit at override `ovr`.
    #[inline]
    pub fn raw_node(&self, g: i64, ovr: f64) -> f64 {
        let left = if g > self.base {
            self.limit(g - 1, ovr)
        } else {
            f64::INFINITY
        };
        left.min(self.limit(g, ovr))
    }
    /// Drop intervals before `g` (the machine has passed them). O(1) per interval.
    #[inline]
    pub fn drop_before(&mut self, g: i64) {
        while self.len > 0 && self.base < g {
            self.head = (self.head + 1) % MAX_PROFILE;
            self.base += 1;
            self.len -= 1;
        }
    }

    /// Recompute the eroded limits of intervals `from..end()`.
    ///
    /// The jerk filter outputs the mean of the last `N` reference positions,
    /// so its speed is the mean reference speed over a window `T = N·Ts` that
    /// reaches both sides of where the machine is. With the reference held to
    /// `e(x) = min_y max(c(y), |y − x|/T)`, the filtered speed never exceeds
    /// `c` where the machine is: a window longer than `T·c(x)` would take the
    /// reference longer than `T` to cross. On the grid, distance counts whole
    /// intervals between (`(|g − g'| − 1)·h`, one interval of slack). Full
    /// stops bound the window (the reference waits at a stop until the filter
    /// has drained), and intervals from `cone_from` on count as zero so that
    /// blocks arriving later can only raise limits already in use.
    pub fn erode(&mut self, from: i64, e: Erosion) {
        let from = from.max(self.base);
        let end = self.end();
        if from >= end {
            return;
        }
        for which in 0..2 {
            let slope = if which == 0 { e.slope } else { e.feed_slope };
            let val = |p: &Profile, q: i64| -> f64 {
                if e.cone_from.is_some_and(|c| q >= c) {
                    0.0
                } else if which == 0 {
                    p.raw[p.slot(q)]
                } else {
                    p.raw_feed[p.slot(q)]
                }
            };
            if !(slope.is_finite() && slope > 0.0) {
                for g in from..end {
                    let v = val(self, g);
                    self.store(which, g, v);
                }
                continue;
            }
            // Right side (candidates q > g), g from the end down; results in `scratch_val`.
            let mut stack = Hull::new();
            for g in (from..end).rev() {
                let q = g + 1;
                if q < end {
                    stack.insert(self, q, val(self, q), self.has_stop(q));
                } else if e.cone_from.is_some() {
                    // Unknown intervals past the end: only the nearest zero matters.
                    stack.insert(self, q, 0.0, false);
                }
                self.scratch_val[(g - from) as usize] = stack.best(self, g, slope, 1);
            }
            // Left side (candidates q < g), g upwards from where the cone of the
            // highest limit can still reach `from`.
            let top = if e.top.is_finite() {
                e.top
            } else {
                self.raw_top(which)
            };
            let reach = if top.is_finite() {
                (libm::ceil(top / slope) as i64).saturating_add(2)
            } else {
                MAX_PROFILE as i64
            };
            let lo = (from - reach).max(self.base);
            let mut stack = Hull::new();
            for g in lo..end {
                let q = g - 1;
                if q >= self.base {
                    stack.insert(self, q, val(self, q), self.has_stop(q));
                }
                if g >= from {
                    let left = stack.best(self, g, slope, -1);
                    let right = self.scratch_val[(g - from) as usize];
                    let v = val(self, g).min(left).min(right);
                    self.store(which, g, v);
                }
            }
        }
    }

    #[inline]
    fn store(&mut self, which: usize, g: i64, v: f64) {
        let k = self.slot(g);
        if which == 0 {
            self.cap[k] = v;
        } else {
            self.feed_cap[k] = v;
        }
    }

    /// Highest finite raw limit held (bounds how far erosion reaches).
    fn raw_top(&self, which: usize) -> f64 {
        let mut top: f64 = 0.0;
        for g in self.base..self.end() {
            let k = self.slot(g);
            let v = if which == 0 {
                self.raw[k]
            } else {
                self.raw_feed[k]
            };
            if v.is_finite() {
                top = top.max(v);
            } else {
                return f64::INFINITY;
            }
        }
        top
    }
}

/// Candidates for `min_q max(c_q, slope·(|q − g| − 1))` on one side of `g`,
/// as `g` moves away from them: a stack, nearest on top, whose values rise
/// towards the top (a nearer candidate with a value no higher hides every
/// farther one for good). Along the stack `max(c, slope·d)` falls and then
/// rises, and its minimum only moves towards the top as `g` moves on, so one
/// pointer finds it in amortised O(1) per interval.
struct Hull {
    len: usize,
    ptr: usize,
}

impl Hull {
    fn new() -> Self {
        Hull { len: 0, ptr: 0 }
    }

    /// Add the new nearest candidate `q` with value `c`; a stop drops every
    /// farther candidate (the window does not reach past a stop).
    #[inline]
    fn insert(&mut self, p: &mut Profile, q: i64, c: f64, stop: bool) {
        if stop {
            self.len = 0;
        }
        while self.len > 0 && p.scratch_c[self.len - 1] >= c {
            self.len -= 1;
        }
        p.scratch_q[self.len] = q;
        p.scratch_c[self.len] = c;
        self.len += 1;
        if self.ptr >= self.len {
            self.ptr = self.len - 1;
        }
    }

    /// The minimum for interval `g` (`side` = +1: candidates after `g`, −1: before).
    #[inline]
    fn best(&mut self, p: &Profile, g: i64, slope: f64, side: i64) -> f64 {
        if self.len == 0 {
            return f64::INFINITY;
        }
        let f = |i: usize| {
            let d = ((p.scratch_q[i] - g) * side - 1).max(0) as f64;
            p.scratch_c[i].max(slope * d)
        };
        while self.ptr + 1 < self.len && f(self.ptr + 1) <= f(self.ptr) {
            self.ptr += 1;
        }
        f(self.ptr)
    }
}

/// Discrete braking: the largest step `Δ` (mm per tick) such that stepping
/// `Δ, Δ−a, Δ−2a, …`, every step longer than `w` ends within `r` of here.
///
/// This is the exact discrete form of `v² ≤ w² + 2·A·r`: a continuous braking
/// curve sampled once per tick would brake harder than `A`. The feasible set
/// is `[0, Δ*]`, and once `Δ` was feasible, `Δ − a` is feasible one tick
/// later, which is why the tick never needs to decelerate harder than `a`.
#[inline]
pub fn brake_step(r: f64, w: f64, a: f64) -> f64 {
    if r <= w {
        // Not even one step longer than w fits before the node.
        return w;
    }
    // Largest n with n·w + a·n(n−1)/2 < r (the distance at which n steps
    // just above w end).
    let b = w - 0.5 * a;
    let root = (-b + libm::sqrt(b * b + 2.0 * a * r)) / a;
    let mut n = libm::ceil(root) - 1.0;
    if n < 1.0 {
        n = 1.0;
    }
    let band_start = |n: f64| n * w + 0.5 * a * n * (n - 1.0);
    // Guard against round-off in the root.
    while n > 1.0 && band_start(n) >= r {
        n -= 1.0;
    }
    while band_start(n + 1.0) < r {
        n += 1.0;
    }
    (w + n * a).min((r + 0.5 * a * n * (n - 1.0)) / n)
}

/// Distance needed to come to rest from step `d` braking by `a` per tick
/// (all steps, including this one): `n·d − a·n(n−1)/2` with `n = ⌈d/a⌉`.
#[inline]
pub fn stop_distance(d: f64, a: f64) -> f64 {
    if d <= 0.0 {
        return 0.0;
    }
    let n = libm::ceil(d / a);
    n * d - 0.5 * a * n * (n - 1.0)
}

#[cfg(test)]
mod tests {
    extern crate alloc;
    use super::*;
    use alloc::vec::Vec;

    /// Distance covered by the steps longer than `w` when braking from `d`.
    fn braking_distance(mut d: f64, w: f64, a: f64) -> f64 {
        let mut pos = 0.0;
        while d > w {
            pos += d;
            d -= a;
        }
        pos
    }

    #[test]
    fn brake_step_is_the_largest_feasible_step() {
        for &(r, w, a) in &[
            (10.0, 0.0, 0.002),
            (1.0, 0.05, 0.002),
            (0.003, 0.0, 0.002),
            (0.0005, 0.0, 0.002),
            (5.0, 0.1, 0.01),
            (0.25, 0.01, 0.001),
        ] {
            let d = brake_step(r, w, a);
            assert!(
                braking_distance(d, w, a) <= r * (1.0 + 1e-12),
                "r={r} w={w} d={d}"
            );
            let more = d * (1.0 + 1e-9) + 1e-15;
            assert!(
                braking_distance(more, w, a) > r,
                "not maximal: r={r} w={w} d={d}"
            );
        }
    }

    #[test]
    fn brake_step_then_minus_a_stays_feasible() {
        // The invariant the tick relies on.
        let a = 0.002;
        for i in 1..400 {
            let r = i as f64 * 0.0137;
            for &w in &[0.0, 0.01, 0.05] {
                let d = brake_step(r, w, a);
                if d > w {
                    let d2 = brake_step(r - d, w, a);
                    assert!(d2 >= d - a - 1e-15, "r={r} w={w} d={d} d2={d2}");
                }
            }
        }
    }

    #[test]
    fn stop_distance_matches_brake_step() {
        let a = 0.003;
        for i in 1..100 {
            let r = i as f64 * 0.05;
            let d = brake_step(r, 0.0, a);
            assert!(stop_distance(d, a) <= r * (1.0 + 1e-12));
            assert!((stop_distance(d, a) - braking_distance(d, 0.0, a)).abs() < 1e-12);
        }
    }

    #[test]
    fn profile_ring_wraps_and_refuses_overflow() {
        let mut p = Profile::new(0.5);
        assert!(p.extend_to(10));
        p.lower_cap(3, 7.0);
        assert_eq!(p.raw_cap(3), 7.0);
        assert_eq!(p.raw_cap(4), f64::INFINITY);
        p.drop_before(5);
        assert_eq!(p.base(), 5);
        assert!(!p.can_extend_to(5 + MAX_PROFILE as i64));
        assert!(p.extend_to(4 + MAX_PROFILE as i64));
        p.lower_cap(4 + MAX_PROFILE as i64, 1.0);
        assert_eq!(p.raw_cap(4 + MAX_PROFILE as i64), 1.0);
        assert!(!p.extend_to(5 + MAX_PROFILE as i64));
    }

    /// Brute force of `e(g) = min over g' of max(c(g'), slope·(|g − g'| − 1)⁺)`,
    /// not past a stop, intervals from `cone` on (and one past the end) zero.
    fn eroded(raw: &[f64], g: usize, slope: f64, stops: &[usize], cone: Option<usize>) -> f64 {
        let val = |q: usize| {
            if cone.is_some_and(|c| q >= c) {
                0.0
            } else {
                raw[q]
            }
        };
        let n = raw.len() + usize::from(cone.is_some());
        let mut best = f64::INFINITY;
        for q in 0..n {
            let c = if q == raw.len() { 0.0 } else { val(q) };
            let (lo, hi) = (g.min(q), g.max(q));
            // A stop strictly between g and q bounds the window.
            if stops.iter().any(|&st| st > lo && st < hi) {
                continue;
            }
            let d = (hi - lo) as f64;
            best = best.min(c.max(slope * (d - 1.0).max(0.0)));
        }
        best
    }

    #[test]
    fn erosion_matches_brute_force_on_random_profiles() {
        let mut seed = 0x2545_f491_4f6c_dd1du64;
        let mut rnd = || {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            (seed >> 11) as f64 / (1u64 << 53) as f64
        };
        for case in 0..300 {
            let n = 5 + (rnd() * 120.0) as usize;
            let raw: Vec<f64> = (0..n)
                .map(|_| {
                    if rnd() < 0.2 {
                        rnd() * 2.0
                    } else {
                        5.0 + rnd() * 60.0
                    }
                })
                .collect();
            let feed: Vec<f64> = (0..n).map(|_| 1.0 + rnd() * 80.0).collect();
            let stops: Vec<usize> = (0..(rnd() * 4.0) as usize)
                .map(|_| (rnd() * n as f64) as usize)
                .collect();
            let cone = (rnd() < 0.5).then(|| (rnd() * n as f64) as usize);
            let (slope, feed_slope) = (0.3 + rnd() * 8.0, 0.3 + rnd() * 8.0);
            let mut p = Profile::new(0.25);
            // Start the ring at a random offset so it wraps.
            p.reset_at(1000 + case);
            p.head = (rnd() * MAX_PROFILE as f64) as usize;
            let base = p.base();
            p.extend_to(base + n as i64 - 1);
            for g in 0..n {
                p.lower_cap(base + g as i64, raw[g]);
                p.lower_feed_cap(base + g as i64, feed[g]);
            }
            for &st in &stops {
                p.mark_stop(base + st as i64);
            }
            let from = (rnd() * n as f64) as i64;
            // With the ring scanned for the top, and with a bound given.
            let mut bounded = p.clone();
            let e = Erosion {
                slope,
                feed_slope,
                cone_from: cone.map(|c| base + c as i64),
                top: f64::INFINITY,
            };
            p.erode(base + from, e);
            let top = raw.iter().chain(&feed).fold(0.0f64, |a, &b| a.max(b)) * (1.0 + rnd());
            bounded.erode(base + from, Erosion { top, ..e });
            for g in from..n as i64 {
                assert_eq!(
                    bounded.cap(base + g),
                    p.cap(base + g),
                    "case {case} g={g} (top {top})"
                );
                assert_eq!(
                    bounded.feed_cap(base + g),
                    p.feed_cap(base + g),
                    "case {case} g={g} (top {top})"
                );
            }
            for g in from as usize..n {
                let gi = base + g as i64;
                assert_eq!(
                    p.cap(gi),
                    eroded(&raw, g, slope, &stops, cone),
                    "case {case} g={g}"
                );
                assert_eq!(
                    p.feed_cap(gi),
                    eroded(&feed, g, feed_slope, &stops, cone),
                    "case {case} g={g} (feed)"
                );
            }
        }
    }

    #[test]
    fn erosion_matches_brute_force_and_respects_stops_and_the_cone() {
        let raw: Vec<f64> = (0..60)
            .map(|i| {
                if i == 25 {
                    1.0
                } else {
                    20.0 + 15.0 * ((i as f64) * 0.37).sin()
                }
            })
            .collect();
        for &(slope, stop) in &[(2.0, None), (0.7, Some(30usize)), (5.0, Some(10))] {
            let mut p = Profile::new(0.5);
            p.extend_to(raw.len() as i64 - 1);
            for (g, &c) in raw.iter().enumerate() {
                p.lower_cap(g as i64, c);
                p.lower_feed_cap(g as i64, c * 2.0);
            }
            if let Some(st) = stop {
                p.mark_stop(st as i64);
            }
            let e = Erosion {
                slope,
                feed_slope: slope,
                cone_from: None,
                top: f64::INFINITY,
            };
            p.erode(0, e);
            let stops: Vec<usize> = stop.into_iter().collect();
            for g in 0..raw.len() {
                let want = eroded(&raw, g, slope, &stops, None);
                assert_eq!(p.cap(g as i64), want, "g={g} slope={slope}");
                let raw2: Vec<f64> = raw.iter().map(|c| c * 2.0).collect();
                assert_eq!(p.feed_cap(g as i64), eroded(&raw2, g, slope, &stops, None));
                assert!(p.cap(g as i64) <= raw[g]);
            }
            // With the cone, limits fall to zero towards it and are never
            // above the finished profile's.
            let finished: Vec<f64> = (0..raw.len() as i64).map(|g| p.cap(g)).collect();
            p.erode(
                0,
                Erosion {
                    cone_from: Some(50),
                    ..e
                },
            );
            for g in 0..raw.len() as i64 {
                assert!(p.cap(g) <= finished[g as usize]);
                if g >= 50 {
                    assert_eq!(p.cap(g), 0.0);
                } else if stop.is_none_or(|st| st as i64 <= g) {
                    assert!(p.cap(g) <= slope * (50 - g - 1) as f64, "g={g}");
                }
            }
        }
    }
}
