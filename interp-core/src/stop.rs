//! The fastest jerk-limited stop from a moving state: what feed hold and
//! abort follow (real time, closed form).
//!
//! From speed `v0 ≥ 0` and tangential acceleration `a0`, jerk `−J` takes the
//! acceleration down to `a1`, it holds there (if `a1 = −A`), and jerk `+J`
//! brings it back to zero exactly as the speed reaches zero:
//!
//! ```text
//! v0 + (a0² − a1²)/(2J) − a1²/(2J) − A·T2 = 0
//! triangle: a1 = −√(J·v0 + a0²/2) (if ≥ −A);   trapezoid: a1 = −A, T2 = (v0 + a0²/(2J) − A²/J)/A
//! ```
//!
//! A state already braking harder than that (`v0 < a0²/(2J)`, `a0 < 0`)
//! eases off at once and rests where the speed reaches zero.

/// A stop profile: up to three phases of constant jerk.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub struct Stop {
    v0: f64,
    a0: f64,
    /// Phase durations, s.
    dur: [f64; 3],
    /// Phase jerks, mm/s³.
    jerk: [f64; 3],
    /// Distance to rest, mm.
    distance: f64,
    /// Time to rest, s.
    duration: f64,
}

/// Position, speed and acceleration after `t` of constant jerk `j`.
#[inline]
fn step(v: f64, a: f64, j: f64, t: f64) -> (f64, f64, f64) {
    (
        v * t + 0.5 * a * t * t + j * t * t * t / 6.0,
        v + a * t + 0.5 * j * t * t,
        a + j * t,
    )
}

impl Stop {
    /// The fastest stop from speed `v0` and acceleration `a0` with
    /// acceleration at most `a_max` and jerk at most `j_max` (both > 0).
    pub fn new(v0: f64, a0: f64, a_max: f64, j_max: f64) -> Stop {
        let (v0, a0) = (v0.max(0.0), a0.clamp(-a_max, a_max));
        let (a, j) = (a_max, j_max);
        let mut dur = [0.0; 3];
        let mut jerk = [-j, 0.0, j];
        if a0 < 0.0 && v0 <= a0 * a0 / (2.0 * j) {
            // Braking harder than needed: ease off now; rest comes where the
            // speed v0 + a0·t + j·t²/2 first reaches zero (a simple root).
            let disc = (a0 * a0 - 2.0 * j * v0).max(0.0);
            dur[2] = (-a0 - libm::sqrt(disc)) / j;
        } else {
            let peak = libm::sqrt(j * v0 + 0.5 * a0 * a0);
            if peak <= a {
                dur[0] = (a0 + peak) / j;
                dur[2] = peak / j;
            } else {
                dur[0] = (a0 + a) / j;
                dur[1] = ((v0 + a0 * a0 / (2.0 * j) - a * a / j) / a).max(0.0);
                dur[2] = a / j;
                jerk[1] = 0.0;
            }
        }
        let mut stop = Stop {
            v0,
            a0,
            dur,
            jerk,
            distance: 0.0,
            duration: 0.0,
        };
        let (mut s, mut v, mut acc, mut t) = (0.0, v0, a0, 0.0);
        for k in 0..3 {
            let d = dur[k];
            if d <= 0.0 {
                continue;
            }
            let (ds, v1, a1) = step(v, acc, jerk[k], d);
            s += ds;
            v = v1;
            acc = a1;
            t += d;
        }
        stop.distance = s;
        stop.duration = t;
        stop
    }

    /// Distance from the start to rest, mm.
    pub fn distance(&self) -> f64 {
        self.distance
    }

    /// Time from the start to rest, s.
    pub fn duration(&self) -> f64 {
        self.duration
    }

    /// Distance covered when the speed peaks (it still rises while a
    /// starting acceleration ramps down; zero when it does not).
    pub fn peak_distance(&self) -> f64 {
        if self.a0 > 0.0 && self.jerk[0] < 0.0 {
            self.at(self.a0 / -self.jerk[0]).0
        } else {
            0.0
        }
    }

    /// The highest speed over the stretch `[d0, d1]` of the stop.
    pub fn top_speed_over(&self, d0: f64, d1: f64) -> f64 {
        let peak = self.peak_distance();
        if d0 < peak {
            self.speed_after(d1.min(peak))
        } else {
            self.speed_after(d0)
        }
    }

    /// Speed once the stop has covered distance `d` (zero past its end).
    pub fn speed_after(&self, d: f64) -> f64 {
        if d <= 0.0 {
            return self.v0;
        }
        if d >= self.distance {
            return 0.0;
        }
        // The distance covered grows with time: bisect on it.
        let (mut lo, mut hi) = (0.0, self.duration);
        for _ in 0..60 {
            let m = 0.5 * (lo + hi);
            if self.at(m).0 < d {
                lo = m;
            } else {
                hi = m;
            }
        }
        self.at(hi).1
    }

    /// Distance travelled, speed and acceleration `t` after the start
    /// (at rest on the stop point after [`Self::duration`]).
    pub fn at(&self, t: f64) -> (f64, f64, f64) {
        if t >= self.duration {
            return (self.distance, 0.0, 0.0);
        }
        let (mut s, mut v, mut a, mut left) = (0.0, self.v0, self.a0, t);
        for k in 0..3 {
            let d = self.dur[k].min(left);
            if d <= 0.0 {
                continue;
            }
            let (ds, v1, a1) = step(v, a, self.jerk[k], d);
            s += ds;
            v = v1;
            a = a1;
            left -= d;
            if left <= 0.0 {
                break;
            }
        }
        (s.min(self.distance), v.max(0.0), a)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Integrate the profile finely and check it against the closed forms.
    #[test]
    fn stops_keep_their_limits_and_end_at_rest() {
        let (a, j) = (2000.0, 1e5);
        for &(v0, a0) in &[
            (100.0, 0.0),
            (100.0, 1500.0),
            (100.0, -2000.0),
            (5.0, 0.0),
            (5.0, 1000.0),
            (0.5, -800.0),
            (250.0, -100.0),
            (0.0, 0.0),
        ] {
            let stop = Stop::new(v0, a0, a, j);
            let n = 100_000;
            let dt = stop.duration() / n as f64;
            let (mut prev_a, mut max_j, mut max_a) = (a0, 0.0f64, 0.0f64);
            let mut prev_s = 0.0;
            // A state braking harder than a jerk-limited stop needs rests
            // before its acceleration is back to zero: the last step is a jump.
            let eases_off = a0 < 0.0 && v0 <= a0 * a0 / (2.0 * j);
            let last = if eases_off { n - 1 } else { n };
            if eases_off {
                let (_, _, a_end) = stop.at(stop.duration() * (1.0 - 1e-12));
                assert!(a_end.abs() <= a0.abs(), "{v0} {a0}: ends at {a_end}");
            }
            for k in 1..=last {
                let (s, v, acc) = stop.at(k as f64 * dt);
                assert!(s >= prev_s - 1e-12, "moves backwards {v0} {a0}");
                assert!(v >= 0.0);
                max_a = max_a.max(acc.abs());
                if dt > 0.0 {
                    max_j = max_j.max((acc - prev_a).abs() / dt);
                }
                prev_a = acc;
                prev_s = s;
            }
            assert!(max_a <= a * (1.0 + 1e-9), "{v0} {a0}: accel {max_a}");
            assert!(max_j <= j * (1.0 + 1e-6), "{v0} {a0}: jerk {max_j}");
            let (s, v, acc) = stop.at(stop.duration());
            assert_eq!((v, acc), (0.0, 0.0));
            assert!((s - stop.distance()).abs() < 1e-12);
        }
    }

    #[test]
    fn the_stop_is_no_longer_than_a_constant_deceleration_bound() {
        // From cruise, the distance is v²/(2A) + v·A/(2J) for the trapezoid.
        let (a, j, v) = (2000.0, 1e5, 100.0);
        let stop = Stop::new(v, 0.0, a, j);
        let want = v * v / (2.0 * a) + v * a / (2.0 * j);
        assert!((stop.distance() - want).abs() < 1e-9, "{}", stop.distance());
        assert!((stop.duration() - (v / a + a / j)).abs() < 1e-12);
    }
}
