//! The valid range of every numeric command-line value, one home for each:
//! `cli.rs` parses each flag through its range (clap then names the flag and
//! the range in its error, before anything runs), and the library's
//! commands check their option structs against the same ranges (a caller
//! that builds the options itself gets the same refusal). NaN and ±∞ are
//! outside every range. The bounds refuse what no machine or part asks for
//! (a typo, `1e308`), never a real value: `docs/daemon.md` › Numeric flags
//! lists them.

use core::fmt;

/// A closed or half-open interval of a flag's values, with its unit.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Range {
    /// Lower bound.
    pub min: f64,
    /// Whether `min` itself is refused (`(min, max]`).
    pub min_open: bool,
    /// Upper bound (included).
    pub max: f64,
    /// Unit, as the help and the errors print it.
    pub unit: &'static str,
}

/// A value outside its [`Range`].
#[derive(Clone, Debug, PartialEq)]
pub struct OutOfRange {
    /// The flag (`--feed`) or configuration key.
    pub flag: String,
    /// The value given.
    pub value: f64,
    /// Its range.
    pub range: Range,
}

impl fmt::Display for OutOfRange {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "{} {} is out of range: it must be a number in {}",
            self.flag,
            Show(self.value),
            self.range
        )
    }
}

impl std::error::Error for OutOfRange {}

/// A number as a person wrote it: plain in the usual magnitudes, with an
/// exponent beyond (`1e308`, not 309 digits).
struct Show(f64);

impl fmt::Display for Show {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let a = self.0.abs();
        if a == 0.0 || !a.is_finite() || (1e-4..1e12).contains(&a) {
            write!(f, "{}", self.0)
        } else {
            write!(f, "{:e}", self.0)
        }
    }
}

impl fmt::Display for Range {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let open = if self.min_open { '(' } else { '[' };
        write!(
            f,
            "{open}{}, {}] {}",
            Show(self.min),
            Show(self.max),
            self.unit
        )
    }
}

impl Range {
    /// `(min, max]`.
    pub const fn above(min: f64, max: f64, unit: &'static str) -> Range {
        Range {
            min,
            min_open: true,
            max,
            unit,
        }
    }

    /// `[min, max]`.
    pub const fn within(min: f64, max: f64, unit: &'static str) -> Range {
        Range {
            min,
            min_open: false,
            max,
            unit,
        }
    }

    /// Whether `v` is in the range (never NaN or ±∞).
    pub fn contains(&self, v: f64) -> bool {
        let low = if self.min_open {
            v > self.min
        } else {
            v >= self.min
        };
        v.is_finite() && low && v <= self.max
    }

    /// `v` if it is in the range, else an error naming `flag`.
    pub fn check(&self, flag: &str, v: f64) -> Result<f64, OutOfRange> {
        if self.contains(v) {
            Ok(v)
        } else {
            Err(OutOfRange {
                flag: flag.to_owned(),
                value: v,
                range: *self,
            })
        }
    }

    /// A clap value parser for a flag of this range (clap names the flag).
    pub fn parser(&'static self) -> impl Fn(&str) -> Result<f64, String> + Clone + Send + Sync {
        move |s: &str| {
            let v: f64 = s
                .trim()
                .parse()
                .map_err(|_| format!("`{s}` is not a number (expected one in {self})"))?;
            if self.contains(v) {
                Ok(v)
            } else {
                Err(format!("{} is outside {self}", s.trim()))
            }
        }
    }
}

/// A programmed feed (`plan raster --feed`, `--plunge-feed`, `demo --feed`,
/// `watch --check-feed`), mm/min: up to 120 m/min, beyond the fastest
/// linear-motor machines.
pub const FEED: Range = Range::above(0.0, 120_000.0, "mm/min");
/// A speed limit (`simulate --max-speed`, `interp.max-path-speed`,
/// `interp.axis-max-velocity`), mm/s: the feed's bound, 120 m/min.
pub const PATH_SPEED: Range = Range::above(0.0, 2_000.0, "mm/s");
/// An acceleration limit (`demo --accel`, `simulate --max-accel`,
/// `interp.max-path-accel`, `interp.max-centripetal-accel`,
/// `interp.axis-max-accel`), mm/s²: up to 100 g.
pub const ACCEL: Range = Range::above(0.0, 1.0e6, "mm/s²");
/// A jerk limit (`interp.max-path-jerk`, `interp.axis-max-jerk`), mm/s³.
pub const JERK: Range = Range::above(0.0, 1.0e9, "mm/s³");
/// A rotary joint's velocity limit (`interp.rotary-max-velocity`), deg/s:
/// up to 100 turns a second.
pub const ROTARY_SPEED: Range = Range::above(0.0, 36_000.0, "deg/s");
/// A rotary joint's acceleration limit (`interp.rotary-max-accel`), deg/s².
pub const ROTARY_ACCEL: Range = Range::above(0.0, 3.6e7, "deg/s²");
/// A rotary joint's jerk limit (`interp.rotary-max-jerk`), deg/s³.
pub const ROTARY_JERK: Range = Range::above(0.0, 3.6e10, "deg/s³");
/// A length of the interpolator's configuration (`interp.profile-step`,
/// `interp.compress-max-move`, `interp.default-blend-tolerance`), mm.
pub const CONFIG_LENGTH: Range = Range::above(0.0, 1_000.0, "mm");
/// A chord tolerance of the interpolator (`demo --chord-tolerance-mm`,
/// `simulate --chord-tolerance-mm`), mm: at most a millimetre.
pub const CHORD_TOLERANCE: Range = Range::above(0.0, 1.0, "mm");
/// The interpolation period of `simulate --period-us`, µs: what `serve`
/// accepts, widened to 1 µs ..= 1 s for offline studies.
pub const SIM_PERIOD_US: Range = Range::within(1.0, 1.0e6, "µs");
/// A distance in a part's frame (`serve --position` X Y Z), mm: a kilometre
/// each way.
pub const POSITION: Range = Range::within(-1.0e6, 1.0e6, "mm");
/// A rotary position (`serve --position` A B C), degrees: a hundred turns
/// each way.
pub const ANGLE_POSITION: Range = Range::within(-36_000.0, 36_000.0, "degrees");
/// A duration of a run (`watch --seconds`, `jitter --seconds`), s: up to a day.
pub const SECONDS: Range = Range::above(0.0, 86_400.0, "s");
/// `watch --liveness`, s: up to an hour without a sample.
pub const LIVENESS: Range = Range::above(0.0, 3_600.0, "s");
/// A planner's stepover or sampling step (`plan raster --stepover`, `plan
/// gouge --sample-spacing`, `--grid-step`), mm.
pub const STEP: Range = Range::above(0.0, 1_000.0, "mm");
/// A planner's tolerance (`plan raster --chord-tolerance`, `plan gouge
/// --tol`, `plan fit --tol`), mm: at most 10 mm (a part's own size decides
/// the lower end, below which f64 cannot resolve it).
pub const PLAN_TOLERANCE: Range = Range::above(0.0, 10.0, "mm");
/// A tolerance that may be zero (`plan raster --blend-tolerance` (0: no
/// G64), `--weld-tolerance`, `plan fit --gouge-tol`), mm.
pub const PLAN_TOLERANCE_OR_ZERO: Range = Range::within(0.0, 10.0, "mm");
/// `plan raster --clearance`, mm above the part's top: up to a metre.
pub const CLEARANCE: Range = Range::within(0.0, 1_000.0, "mm");
/// `plan raster --angle`, degrees counter-clockwise from +X.
pub const PASS_ANGLE: Range = Range::within(-360.0, 360.0, "degrees");

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ranges_refuse_nan_infinities_and_their_ends() {
        for r in [FEED, CLEARANCE] {
            for bad in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY, 1e308, -1.0] {
                assert!(!r.contains(bad), "{r} holds {bad}");
            }
            assert!(r.contains(r.max));
        }
        assert!(!FEED.contains(0.0) && CLEARANCE.contains(0.0));
        let e = FEED.check("--feed", 1e308).unwrap_err();
        assert_eq!(
            e.to_string(),
            "--feed 1e308 is out of range: it must be a number in (0, 120000] mm/min"
        );
        let p = FEED.parser();
        assert_eq!(p("6000"), Ok(6000.0));
        assert_eq!(
            p("1e308").unwrap_err(),
            "1e308 is outside (0, 120000] mm/min"
        );
        assert!(p("nan").is_err() && p("fast").is_err());
    }
}
