//! Milling cutters: ball, flat and bull (toroidal) end mills.
//!
//! Sizes follow tool catalogues and OpenCAMLib: the number given is the
//! **diameter**. On the command line a cutter is `ball:D`, `flat:D` or
//! `bull:D:r` (corner radius `r`), in mm; e.g. `ball:6` is a 6 mm ball end
//! mill of radius 3 mm.

use std::fmt;
use std::str::FromStr;

/// A cutter's shape. The tool tip (the point a CL path gives) is the lowest
/// point of the cutter on its axis.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Cutter {
    /// Ball end mill of the given diameter, mm.
    Ball {
        /// Diameter, mm.
        diameter: f64,
    },
    /// Flat end mill of the given diameter, mm.
    Flat {
        /// Diameter, mm.
        diameter: f64,
    },
    /// Bull-nose (toroidal, fillet) end mill.
    Bull {
        /// Diameter, mm.
        diameter: f64,
        /// Corner (fillet) radius, mm; `0 < corner_radius < diameter / 2`.
        corner_radius: f64,
    },
}

/// Why a cutter description was refused.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum CutterError {
    /// Not `ball:D`, `flat:D` or `bull:D:r`.
    #[error("cutter `{0}`: expected ball:D, flat:D or bull:D:r (mm, D the diameter)")]
    Syntax(String),
    /// A size is not a finite positive number, or the corner radius does not fit.
    #[error("cutter `{0}`: sizes must be finite and > 0, and a bull corner radius < D/2")]
    Size(String),
}

impl Cutter {
    /// Checks the sizes.
    pub fn validated(self) -> Result<Self, CutterError> {
        let ok = |v: f64| v.is_finite() && v > 0.0;
        let valid = match self {
            Cutter::Ball { diameter } | Cutter::Flat { diameter } => ok(diameter),
            Cutter::Bull {
                diameter,
                corner_radius,
            } => ok(diameter) && ok(corner_radius) && corner_radius < diameter / 2.0,
        };
        if valid {
            Ok(self)
        } else {
            Err(CutterError::Size(self.to_string()))
        }
    }

    /// Radius of the cutter's cylinder, mm.
    pub fn radius(&self) -> f64 {
        match *self {
            Cutter::Ball { diameter }
            | Cutter::Flat { diameter }
            | Cutter::Bull { diameter, .. } => diameter / 2.0,
        }
    }

    /// Corner radius: the full radius for a ball, 0 for a flat end mill.
    pub fn corner_radius(&self) -> f64 {
        match *self {
            Cutter::Ball { diameter } => diameter / 2.0,
            Cutter::Flat { .. } => 0.0,
            Cutter::Bull { corner_radius, .. } => corner_radius,
        }
    }
}

impl fmt::Display for Cutter {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            Cutter::Ball { diameter } => write!(f, "ball:{diameter}"),
            Cutter::Flat { diameter } => write!(f, "flat:{diameter}"),
            Cutter::Bull {
                diameter,
                corner_radius,
            } => write!(f, "bull:{diameter}:{corner_radius}"),
        }
    }
}

impl FromStr for Cutter {
    type Err = CutterError;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        let syntax = || CutterError::Syntax(s.to_string());
        let num = |t: &str| t.trim().parse::<f64>().map_err(|_| syntax());
        let parts: Vec<&str> = s.split(':').collect();
        let cutter = match parts.as_slice() {
            [kind, d] if kind.eq_ignore_ascii_case("ball") => Cutter::Ball { diameter: num(d)? },
            [kind, d] if kind.eq_ignore_ascii_case("flat") => Cutter::Flat { diameter: num(d)? },
            [kind, d, r] if kind.eq_ignore_ascii_case("bull") => Cutter::Bull {
                diameter: num(d)?,
                corner_radius: num(r)?,
            },
            _ => return Err(syntax()),
        };
        cutter
            .validated()
            .map_err(|_| CutterError::Size(s.to_string()))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_catalogue_notation_as_diameters() {
        let ball: Cutter = "ball:6".parse().unwrap();
        assert_eq!(ball.radius(), 3.0);
        assert_eq!(ball.corner_radius(), 3.0);
        let flat: Cutter = "FLAT:10".parse().unwrap();
        assert_eq!((flat.radius(), flat.corner_radius()), (5.0, 0.0));
        let bull: Cutter = "bull:10:2".parse().unwrap();
        assert_eq!((bull.radius(), bull.corner_radius()), (5.0, 2.0));
        assert_eq!(bull.to_string().parse::<Cutter>().unwrap(), bull);
    }

    #[test]
    fn refuses_bad_sizes_and_syntax() {
        for bad in [
            "ball",
            "ball:x",
            "cone:6",
            "ball:-1",
            "ball:NaN",
            "bull:10:5",
            "bull:10:0",
            "flat:6:1",
        ] {
            assert!(bad.parse::<Cutter>().is_err(), "{bad} accepted");
        }
    }
}
