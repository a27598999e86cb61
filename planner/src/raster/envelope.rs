//! Upper envelope of the section pieces along one pass (seed `001_…` §4.6).
//!
//! The seed orders the traced curves along the pass, splits them into
//! monotone chains, cuts them at their intersections and keeps the highest
//! chain. Every piece here is already monotone in `u` (a function `z(u)` on
//! one interval) and concave, which allows an exact branch-and-bound instead
//! of pairwise curve intersection:
//!
//! * on an interval `[s, t]` that every candidate covers, a concave piece is
//!   at least `min(z(s), z(t))` and at most the extension of its secants
//!   through `s, m, t` (`m` the midpoint);
//! * a candidate whose upper bound is below another's lower bound is not on
//!   the envelope there and is dropped;
//! * the rest is split at `m` until one candidate is left, which then *is*
//!   the envelope on that interval. Crossings are so located to
//!   [`EnvelopeOptions::min_split`]; copies of one vertex offset held by
//!   several capsules are merged by feature id.
//!
//! The result is a list of runs `(piece, s, t)`; each run is one concave
//! curve, turned into points by midpoint-deviation subdivision (for a concave
//! curve the chord error is at most twice the midpoint deviation).

use super::offset::{CutterShape, Feature, OffsetEdge, Piece, PieceKind};

/// Tolerances of the envelope step.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct EnvelopeOptions {
    /// Width of the cells the pass is first cut into, mm.
    pub cell_width: f64,
    /// Intervals narrower than this (mm) are not split further: the highest
    /// candidate at the midpoint wins.
    pub min_split: f64,
    /// Two candidates whose values agree this closely (mm) at the sample
    /// points may be one curve (see `same_curve_width`).
    pub same_value: f64,
    /// Below this interval width (mm) two curves equal at three points are
    /// taken as one.
    pub same_curve_width: f64,
    /// Chord tolerance of the output polyline, mm.
    pub chord_tolerance: f64,
    /// A piece whose upper bound is above the envelope's lower bound by no
    /// more than this (mm) is dropped: the envelope may be that much low.
    pub prune_tolerance: f64,
}

/// Pieces of one pass and what they need for evaluation.
pub(crate) struct PassGeometry<'a> {
    pub pieces: &'a [Piece],
    pub edges: &'a [OffsetEdge],
    pub shape: &'a CutterShape,
    pub w: f64,
}

impl PassGeometry<'_> {
    /// Value and feature of piece `i` at `u` (clamped into its interval).
    #[inline]
    pub(crate) fn eval(&self, i: u32, u: f64) -> (f64, Feature) {
        let p = &self.pieces[i as usize];
        let u = u.clamp(p.u0, p.u1);
        match p.kind {
            PieceKind::Line { z0, z1, face } => {
                let l = (u - p.u0) / (p.u1 - p.u0);
                (z0 + l * (z1 - z0), Feature::Face(face))
            }
            PieceKind::Capsule { edge } => {
                self.edges[edge as usize].drop_at(u, self.w, self.shape, edge)
            }
        }
    }
}

/// One stretch of the envelope: piece `piece` from `s` to `t`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Run {
    pub piece: u32,
    pub s: f64,
    pub t: f64,
}

/// Scratch memory reused across the passes one thread computes.
#[derive(Debug, Default)]
pub(crate) struct EnvelopeScratch {
    order: Vec<u32>,
    active: Vec<u32>,
    cands: Vec<u32>,
    stack: Vec<Vec<u32>>,
    pub runs: Vec<Run>,
}

/// Computes the envelope runs of `geo` into `scratch.runs`.
pub(crate) fn envelope(
    geo: &PassGeometry<'_>,
    opt: &EnvelopeOptions,
    scratch: &mut EnvelopeScratch,
) {
    scratch.runs.clear();
    let n = geo.pieces.len();
    if n == 0 {
        return;
    }
    scratch.order.clear();
    scratch.order.extend(0..n as u32);
    let pieces = geo.pieces;
    scratch
        .order
        .sort_unstable_by(|&a, &b| pieces[a as usize].u0.total_cmp(&pieces[b as usize].u0));
    let umin = pieces[scratch.order[0] as usize].u0;
    let umax = pieces
        .iter()
        .map(|p| p.u1)
        .fold(f64::NEG_INFINITY, f64::max);
    let cells = (((umax - umin) / opt.cell_width).ceil() as usize).max(1);
    let width = (umax - umin) / cells as f64;
    let mut next = 0;
    scratch.active.clear();
    for c in 0..cells {
        // Both ends from one formula, so neighbouring cells meet exactly.
        let s = umin + c as f64 * width;
        let t = if c + 1 == cells {
            umax
        } else {
            umin + (c + 1) as f64 * width
        };
        while next < n && pieces[scratch.order[next] as usize].u0 < t {
            scratch.active.push(scratch.order[next]);
            next += 1;
        }
        scratch.active.retain(|&i| pieces[i as usize].u1 > s);
        scratch.cands.clear();
        scratch.cands.extend_from_slice(&scratch.active);
        let cands = std::mem::take(&mut scratch.cands);
        resolve(geo, opt, &cands, s, t, 0, scratch);
        scratch.cands = cands;
    }
    // Join neighbouring runs of the same piece.
    let mut joined: Vec<Run> = Vec::with_capacity(scratch.runs.len());
    for r in scratch.runs.drain(..) {
        if let Some(last) = joined.last_mut()
            && last.piece == r.piece
            && last.t == r.s
        {
            last.t = r.t;
            continue;
        }
        joined.push(r);
    }
    scratch.runs = joined;
}

/// Depth limit of the bisection (2^-60 of a cell is below f64 resolution).
const MAX_DEPTH: usize = 60;

fn resolve(
    geo: &PassGeometry<'_>,
    opt: &EnvelopeOptions,
    cands: &[u32],
    s: f64,
    t: f64,
    depth: usize,
    scratch: &mut EnvelopeScratch,
) {
    if cands.is_empty() || !(t > s) {
        return;
    }
    let pieces = geo.pieces;
    let m = 0.5 * (s + t);
    // Bounds of each candidate on the part [a, b] of [s, t] it covers: at
    // least min(z(a), z(b)) (concavity), at most its secants extended.
    struct Bound {
        piece: u32,
        full: bool,
        ub: f64,
        z: [f64; 3],
        line: bool,
        vertex: Option<u32>,
    }
    let mut bounds: Vec<Bound> = Vec::with_capacity(cands.len());
    let mut lower = f64::NEG_INFINITY;
    // Faces first: their values are cheap and give `lower`, which then
    // drops most capsules by a bound that needs no contact solve.
    let faces = cands
        .iter()
        .filter(|&&i| matches!(pieces[i as usize].kind, PieceKind::Line { .. }));
    let capsules = cands
        .iter()
        .filter(|&&i| matches!(pieces[i as usize].kind, PieceKind::Capsule { .. }));
    for &i in faces.chain(capsules) {
        let p = &pieces[i as usize];
        let (a, b) = (p.u0.max(s), p.u1.min(t));
        if !(b > a) {
            continue;
        }
        if let PieceKind::Capsule { edge } = p.kind
            && geo.edges[edge as usize].upper_bound(a, b, geo.w, geo.shape) < lower
        {
            continue;
        }
        let c = 0.5 * (a + b);
        let (za, fa) = geo.eval(i, a);
        let (zc, fc) = geo.eval(i, c);
        let (zb, fb) = geo.eval(i, b);
        // One vertex offset touched at both ends and the middle: the piece
        // is that vertex's offset on the whole interval (the points whose
        // contact is a given end of an edge form a convex set, so an
        // interval of the pass), whichever capsule holds it.
        let vertex = match (fa, fc, fb) {
            (Feature::Vertex(x), Feature::Vertex(y), Feature::Vertex(z)) if x == y && y == z => {
                Some(x)
            }
            _ => None,
        };
        let full = a == s && b == t;
        if full {
            lower = lower.max(za.min(zb));
        }
        let ub = zc.max(2.0 * zc - za).max(2.0 * zc - zb);
        bounds.push(Bound {
            piece: i,
            full,
            ub,
            z: [za, zc, zb],
            // A concave curve through the midpoint of its chord is straight
            // on the interval (it is above the chord and concave).
            line: matches!(p.kind, PieceKind::Line { .. })
                || (za + zb - 2.0 * zc).abs() <= opt.same_value,
            vertex,
        });
    }
    // Linear lower bounds of the envelope: the chords of the full candidates
    // highest at s, at m and at t (a concave curve is above its chords).
    let mut refs = [None::<usize>; 3];
    for (k, b) in bounds.iter().enumerate() {
        if b.full {
            for q in 0..3 {
                if refs[q].is_none_or(|r| b.z[q] > bounds[r].z[q]) {
                    refs[q] = Some(k);
                }
            }
        }
    }
    // A candidate is below the envelope on [s, m] if its upper line there
    // (the secant through m and t, extended) is below some chord at both ends;
    // likewise on [m, t].
    // Within `prune_tolerance` counts as below: where a piece meets the
    // envelope tangentially (a face's offset running into its edge's
    // cylinder) the secant bounds close in only quadratically, and without
    // the slack the bisection would go down to `min_split`. The references
    // themselves are never pruned, so the envelope is never left empty.
    let eps = opt.prune_tolerance;
    let below = |k: usize, b: &Bound| {
        if !b.full || refs.contains(&Some(k)) {
            return false;
        }
        let left = [2.0 * b.z[1] - b.z[2], b.z[1]];
        let right = [b.z[1], 2.0 * b.z[1] - b.z[0]];
        let under = |r: &Bound, ends: [f64; 2], i: usize| {
            ends[0] < r.z[i] + eps && ends[1] < r.z[i + 1] + eps
        };
        refs.iter().flatten().any(|&r| under(&bounds[r], left, 0))
            && refs.iter().flatten().any(|&r| under(&bounds[r], right, 1))
    };
    let mut keep = scratch.stack.pop().unwrap_or_default();
    keep.clear();
    let mut kept: Vec<usize> = Vec::new();
    let mut best: Option<usize> = None;
    for (k, b) in bounds.iter().enumerate() {
        if !(b.ub >= lower) || below(k, b) {
            continue;
        }
        // The same curve held twice: a straight piece and a concave curve
        // equal at three points are equal throughout; two curves equal at three points
        // of a very short interval (one vertex offset in two capsules) differ
        // in between by far less than the tolerances.
        let dup = b.full
            && kept.iter().any(|&j| {
                let o = &bounds[j];
                o.full
                    && (o.line
                        || b.line
                        || t - s <= opt.same_curve_width
                        || (o.vertex.is_some() && o.vertex == b.vertex))
                    && (0..3).all(|q| (o.z[q] - b.z[q]).abs() <= opt.same_value)
            });
        if dup {
            continue;
        }
        if b.full && best.is_none_or(|x| b.z[1] > bounds[x].z[1]) {
            best = Some(k);
        }
        kept.push(k);
        keep.push(b.piece);
    }
    // Split at a survivor's end inside (s, t) so that the survivors then
    // cover whole intervals.
    let mut split = None::<f64>;
    for &i in keep.iter() {
        let p = &pieces[i as usize];
        for e in [p.u0, p.u1] {
            if e > s && e < t && split.is_none_or(|x: f64| (e - m).abs() < (x - m).abs()) {
                split = Some(e);
            }
        }
    }
    if let Some(x) = split
        && depth < MAX_DEPTH
    {
        let mut part = scratch.stack.pop().unwrap_or_default();
        part.clear();
        part.extend(keep.iter().copied().filter(|&i| pieces[i as usize].u0 < x));
        resolve(geo, opt, &part, s, x, depth + 1, scratch);
        part.clear();
        part.extend(keep.iter().copied().filter(|&i| pieces[i as usize].u1 > x));
        resolve(geo, opt, &part, x, t, depth + 1, scratch);
        scratch.stack.push(part);
    } else if keep.len() == 1 || t - s <= opt.min_split || depth >= MAX_DEPTH {
        let piece = match best {
            Some(k) => bounds[k].piece,
            None => keep.first().copied().unwrap_or(cands[0]),
        };
        scratch.runs.push(Run { piece, s, t });
    } else if !keep.is_empty() {
        resolve(geo, opt, &keep, s, m, depth + 1, scratch);
        resolve(geo, opt, &keep, m, t, depth + 1, scratch);
    }
    scratch.stack.push(keep);
}

/// Appends the points of run `r` (excluding its start) to `out` as `(u, z)`,
/// subdividing curved pieces until the chord error is within tolerance.
pub(crate) fn run_points(
    geo: &PassGeometry<'_>,
    opt: &EnvelopeOptions,
    r: &Run,
    zs: f64,
    zt: f64,
    out: &mut Vec<[f64; 2]>,
) {
    match geo.pieces[r.piece as usize].kind {
        PieceKind::Line { .. } => out.push([r.t, zt]),
        PieceKind::Capsule { .. } => subdivide(geo, opt, r.piece, r.s, zs, r.t, zt, 0, out),
    }
}

/// Depth limit of the chord subdivision.
const MAX_CHORD_DEPTH: usize = 30;

#[allow(clippy::too_many_arguments)]
fn subdivide(
    geo: &PassGeometry<'_>,
    opt: &EnvelopeOptions,
    piece: u32,
    s: f64,
    zs: f64,
    t: f64,
    zt: f64,
    depth: usize,
    out: &mut Vec<[f64; 2]>,
) {
    let m = 0.5 * (s + t);
    let (zm, _) = geo.eval(piece, m);
    if zm.is_finite()
        && zs.is_finite()
        && zt.is_finite()
        && depth < MAX_CHORD_DEPTH
        && (zm - 0.5 * (zs + zt)).abs() > 0.5 * opt.chord_tolerance
    {
        subdivide(geo, opt, piece, s, zs, m, zm, depth + 1, out);
        subdivide(geo, opt, piece, m, zm, t, zt, depth + 1, out);
    } else {
        out.push([t, zt]);
    }
}
