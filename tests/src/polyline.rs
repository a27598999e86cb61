//! How far setpoints stray from a programmed polyline: an independent check
//! of the `G64 P` stage, from the program's own vertices (never from what
//! the stage made of them).
//!
//! Segments go into a uniform grid of cubes; a point's distance is the
//! smallest over the segments in its cube and the 26 around it, exact for
//! every distance below the cube's size (larger ones are reported as the
//! cube size, which fails any tolerance it could be compared with). A chord
//! between two setpoints is bounded by `min_s max(d(A, s), d(B, s))` over the
//! segments `s` near either end (the distance to one segment is convex, so
//! the whole chord is within that of `s`); where that bound is not within
//! [`RESOLUTION`] of the larger end distance (a chord across a vertex), the
//! chord is halved, down to halves of [`RESOLUTION`], where
//! `max(d(A), d(B)) + |AB|/2` bounds it. So the chord bound exceeds the true
//! largest distance by at most [`RESOLUTION`].

use std::collections::HashMap;

use interp_core::Vec3;

/// Cube size of the grid, mm: the largest distance measured exactly.
pub const CELL: f64 = 0.5;

/// How much a chord bound may exceed the chord's true largest distance, mm.
pub const RESOLUTION: f64 = 2e-5;

/// A programmed polyline (or several: a path with jumps is several
/// polylines, whose segments all count).
#[derive(Debug)]
pub struct Polyline {
    segs: Vec<(Vec3, Vec3)>,
    grid: HashMap<(i64, i64, i64), Vec<u32>>,
}

fn cell(p: &Vec3) -> (i64, i64, i64) {
    (
        (p.x / CELL).floor() as i64,
        (p.y / CELL).floor() as i64,
        (p.z / CELL).floor() as i64,
    )
}

/// Distance from `x` to the segment `a b`.
pub fn seg_dist(x: &Vec3, a: &Vec3, b: &Vec3) -> f64 {
    let ab = b - a;
    let l2 = ab.norm_squared();
    let t = if l2 > 0.0 {
        ((x - a).dot(&ab) / l2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    (x - (a + ab * t)).norm()
}

impl Polyline {
    /// The segments between consecutive `vertices`.
    pub fn new(vertices: &[Vec3]) -> Self {
        Self::from_segments(vertices.windows(2).map(|w| (w[0], w[1])))
    }

    /// Any set of segments.
    pub fn from_segments(segs: impl IntoIterator<Item = (Vec3, Vec3)>) -> Self {
        let segs: Vec<(Vec3, Vec3)> = segs.into_iter().collect();
        let mut grid: HashMap<(i64, i64, i64), Vec<u32>> = HashMap::new();
        for (i, (a, b)) in segs.iter().enumerate() {
            let (ca, cb) = (cell(a), cell(b));
            let lo = (ca.0.min(cb.0), ca.1.min(cb.1), ca.2.min(cb.2));
            let hi = (ca.0.max(cb.0), ca.1.max(cb.1), ca.2.max(cb.2));
            for x in lo.0..=hi.0 {
                for y in lo.1..=hi.1 {
                    for z in lo.2..=hi.2 {
                        grid.entry((x, y, z)).or_default().push(i as u32);
                    }
                }
            }
        }
        Polyline { segs, grid }
    }

    fn near(&self, p: &Vec3) -> impl Iterator<Item = u32> + '_ {
        let c = cell(p);
        (-1..=1).flat_map(move |dx| {
            (-1..=1).flat_map(move |dy| {
                (-1..=1).flat_map(move |dz| {
                    self.grid
                        .get(&(c.0 + dx, c.1 + dy, c.2 + dz))
                        .into_iter()
                        .flatten()
                        .copied()
                })
            })
        })
    }

    /// Distance from `p` to the polyline (capped at [`CELL`]).
    pub fn distance(&self, p: &Vec3) -> f64 {
        self.near(p)
            .map(|i| {
                let (a, b) = &self.segs[i as usize];
                seg_dist(p, a, b)
            })
            .fold(CELL, f64::min)
    }

    /// A bound on the distance of every point of the chord `a b`, at most
    /// [`RESOLUTION`] above the true largest one (capped at [`CELL`]).
    pub fn chord_distance(&self, a: &Vec3, b: &Vec3) -> f64 {
        self.chord_bound(a, b, self.distance(a), self.distance(b), 0)
    }

    fn chord_bound(&self, a: &Vec3, b: &Vec3, da: f64, db: f64, depth: u32) -> f64 {
        let one = self
            .near(a)
            .chain(self.near(b))
            .map(|i| {
                let (s0, s1) = &self.segs[i as usize];
                seg_dist(a, s0, s1).max(seg_dist(b, s0, s1))
            })
            .fold(CELL, f64::min);
        let ends = da.max(db);
        let half = 0.5 * (b - a).norm();
        if one - ends <= RESOLUTION || depth >= 40 {
            return one;
        }
        if half <= RESOLUTION {
            return (ends + half).min(one);
        }
        let m = (a + b) * 0.5;
        let dm = self.distance(&m);
        self.chord_bound(a, &m, da, dm, depth + 1)
            .max(self.chord_bound(&m, b, dm, db, depth + 1))
    }

    /// The largest distance of the points and of the chords between
    /// consecutive points: `(points, chords)`.
    pub fn deviation(&self, pts: &[Vec3]) -> (f64, f64) {
        let p = pts.iter().map(|x| self.distance(x)).fold(0.0, f64::max);
        let c = pts
            .windows(2)
            .map(|w| self.chord_distance(&w[0], &w[1]))
            .fold(0.0, f64::max);
        (p, c)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn distances_match_brute_force() {
        let v: Vec<Vec3> = (0..50)
            .map(|i| {
                let t = i as f64 * 0.3;
                Vec3::new(t.cos() * 3.0, t.sin() * 2.0, 0.1 * t)
            })
            .collect();
        let pl = Polyline::new(&v);
        for k in 0..200 {
            let t = k as f64 * 0.071;
            let p = Vec3::new(t.cos() * 3.1, t.sin() * 1.9, 0.1 * t + 0.05);
            let brute = v
                .windows(2)
                .map(|w| seg_dist(&p, &w[0], &w[1]))
                .fold(f64::INFINITY, f64::min);
            assert_eq!(pl.distance(&p), brute.min(CELL));
        }
        // A chord cutting a corner: its midpoint is 0.05 off both lines, its ends on them.
        let sq = Polyline::new(&[
            Vec3::new(0.0, 0.0, 0.0),
            Vec3::new(1.0, 0.0, 0.0),
            Vec3::new(1.0, 1.0, 0.0),
        ]);
        let (a, b) = (Vec3::new(0.9, 0.0, 0.0), Vec3::new(1.0, 0.1, 0.0));
        assert_eq!(sq.distance(&a), 0.0);
        let d = sq.chord_distance(&a, &b);
        let truth = 0.05;
        assert!(d >= truth - 1e-15 && d <= truth + RESOLUTION, "{d}");
        // A chord along the polyline across a small turn is close to it.
        let bend = Polyline::new(&[
            Vec3::new(0.0, 0.0, 0.0),
            Vec3::new(1.0, 0.0, 0.0),
            Vec3::new(2.0, 0.01, 0.0),
        ]);
        let d = bend.chord_distance(&Vec3::new(0.95, 0.0, 0.0), &Vec3::new(1.05, 0.0005, 0.0));
        assert!(d < 3e-4 + RESOLUTION, "{d}");
    }
}
