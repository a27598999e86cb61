//! Planning a block off the RT path, and committing it on the RT path.
//!
//! [`Interpolator::push`](crate::Interpolator::push) is two halves:
//!
//! 1. **Planning** ([`BlockPlanner::plan`]): cut the block at tangent breaks,
//!    measure the pieces, sample the feed laws onto the global arc-length grid
//!    and price the corners inside the block. This is the costly part
//!    (milliseconds for a long NURBS) and depends only on the block, the
//!    configuration and where the queue ends (point and arc length), so it can
//!    run on any thread ahead of time.
//! 2. **Commit** ([`Interpolator::commit`](crate::Interpolator::commit)): merge
//!    the planned limits into the profile (a minimum per interval), price the
//!    junction with what is queued, erode and run the backward pass. Linear in
//!    the block's intervals, a few microseconds, no allocation: the RT thread
//!    can do it between ticks.
//!
//! `push` is exactly `plan` then `commit`, so a daemon that plans on one
//! thread and commits on another gives bit-identical setpoints to `simulate`.
//! A plan made against another queue end (after an abort) is refused with
//! [`PushError::Stale`].

use crate::config::{ConfigError, InterpConfig};
use crate::feed::{feed_limit, junction_speed, machine_limit, stationary_offset};
use crate::geom::{Curve, Derivs, Vec3, golden_section_min};
use crate::interp::{JOIN_TOLERANCE, MAX_PIECES, PushError, grid_multiple};
use crate::nurbs::Side;
use crate::path::{Block, Path};
use crate::plan::{MAX_PROFILE, Segment};

/// Grid intervals one planned block can cover: the whole profile ring and
/// the interval on each side that law samples on a node and corner pricing touch.
pub const PLAN_INTERVALS: usize = MAX_PROFILE + 3;

/// Grid index of the interval containing arc length `s` on a grid of spacing `h`
/// (the same formula as [`Profile::index_of`](crate::plan::Profile::index_of)).
#[inline]
fn index_of(s: f64, h: f64) -> i64 {
    libm::floor(s / h) as i64
}

/// A block planned by [`BlockPlanner::plan`], ready for
/// [`Interpolator::commit`](crate::Interpolator::commit).
///
/// About 110 KiB: keep it in a reused buffer (a `Box` recycled through a
/// queue in the daemon), not on a small stack.
#[derive(Clone, Debug)]
pub struct PlannedBlock {
    /// Grid spacing it was planned on, mm.
    pub(crate) h: f64,
    /// The block's id.
    pub(crate) id: u32,
    /// End of the queue it was planned against (where it starts), and the
    /// run's arc length there.
    pub(crate) tail: Vec3,
    pub(crate) s0: f64,
    /// Arc length of the run at its end.
    pub(crate) s1: f64,
    /// Its end point.
    pub(crate) end: Vec3,
    /// Derivatives (order 3) at its start and end, for junction pricing.
    pub(crate) entry: Derivs,
    pub(crate) exit: Derivs,
    /// The block asks to come to rest at its end (G61.1).
    pub(crate) exact_stop: bool,
    /// Pieces (cut at tangent breaks), with their arc lengths in the run.
    pub(crate) segments: [Option<Segment>; MAX_PIECES],
    pub(crate) n_segments: usize,
    /// `corner[k]`: junction speed between piece `k − 1` and piece `k`.
    pub(crate) corner: [f64; MAX_PIECES],
    /// Raw limits of grid intervals `g0 ..g0 + n_caps` (machine laws; feed laws at 100 %).
    pub(crate) g0: i64,
    pub(crate) n_caps: usize,
    pub(crate) raw: [f64; PLAN_INTERVALS],
    pub(crate) raw_feed: [f64; PLAN_INTERVALS],
}

impl Default for PlannedBlock {
    fn default() -> Self {
        Self::new()
    }
}

impl PlannedBlock {
    /// An empty plan (a buffer for [`BlockPlanner::plan`]).
    pub fn new() -> Self {
        PlannedBlock {
            h: 0.0,
            id: 0,
            tail: Vec3::zeros(),
            s0: 0.0,
            s1: 0.0,
            end: Vec3::zeros(),
            entry: Derivs::ZERO,
            exit: Derivs::ZERO,
            exact_stop: false,
            segments: [None; MAX_PIECES],
            n_segments: 0,
            corner: [f64::INFINITY; MAX_PIECES],
            g0: 0,
            n_caps: 0,
            raw: [f64::INFINITY; PLAN_INTERVALS],
            raw_feed: [f64::INFINITY; PLAN_INTERVALS],
        }
    }
    /// Id of the planned block.
    pub fn id(&self) -> u32 {
        self.id
    }
    /// Segments (pieces) it becomes in the queue.
    pub fn segments(&self) -> usize {
        self.n_segments
    }
    /// Arc length of the run at its start and end, mm.
    pub fn arc_range(&self) -> (f64, f64) {
        (self.s0, self.s1)
    }
    /// Grid intervals whose limits it sets.
    pub fn intervals(&self) -> usize {
        self.n_caps
    }
    /// The pieces, in order.
    pub(crate) fn pieces(&self) -> impl Iterator<Item = &Segment> {
        self.segments[..self.n_segments].iter().flatten()
    }
    #[inline]
    fn slot(&self, g: i64) -> Option<usize> {
        let i = g - self.g0;
        (i >= 0 && (i as usize) < self.n_caps).then_some(i as usize)
    }
    /// Lower the raw machine-law limit of interval `g`.
    #[inline]
    fn lower_cap(&mut self, g: i64, c: f64) {
        if let Some(k) = self.slot(g)
            && c < self.raw[k]
        {
            self.raw[k] = c;
        }
    }
    /// Lower the raw feed limit (100 % override) of interval `g`.
    #[inline]
    fn lower_feed_cap(&mut self, g: i64, c: f64) {
        if let Some(k) = self.slot(g)
            && c < self.raw_feed[k]
        {
            self.raw_feed[k] = c;
        }
    }
    #[inline]
    fn h(&self) -> f64 {
        self.h
    }
    #[inline]
    fn index_of(&self, s: f64) -> i64 {
        index_of(s, self.h)
    }
}

/// Room the caller has for a plan: refuse early (before any sampling) when
/// the block cannot be committed now anyway.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Room {
    /// Free segment slots.
    pub segments: usize,
    /// Last grid interval the profile can hold.
    pub last_interval: i64,
}

/// The planning half of `push`: tracks where the queue will end and plans
/// each block against it. Cheap to copy; runs on any thread.
#[derive(Clone, Copy, Debug)]
pub struct BlockPlanner {
    cfg: InterpConfig,
    h: f64,
    tail: Vec3,
    tail_s: f64,
}

impl BlockPlanner {
    /// A planner for a queue that ends at `tail` (X Y Z), arc length `tail_s`
    /// of the run (0 for a fresh interpolator, else
    /// [`Interpolator::planner`](crate::Interpolator::planner) or the last setpoint's `s`).
    pub fn new(cfg: InterpConfig, tail: Vec3, tail_s: f64) -> Result<Self, ConfigError> {
        cfg.validate()?;
        if !(tail.iter().all(|c| c.is_finite()) && tail_s.is_finite()) {
            return Err(ConfigError::OutOfRange("position"));
        }
        Ok(BlockPlanner {
            cfg,
            h: crate::Interpolator::<1>::grid_step(&cfg),
            tail,
            tail_s,
        })
    }
    pub(crate) fn from_parts(cfg: InterpConfig, h: f64, tail: Vec3, tail_s: f64) -> Self {
        BlockPlanner {
            cfg,
            h,
            tail,
            tail_s,
        }
    }
    /// Where the next block must start.
    pub fn tail(&self) -> Vec3 {
        self.tail
    }
    /// Arc length of the run where the next block starts, mm.
    pub fn tail_s(&self) -> f64 {
        self.tail_s
    }
    /// Move the queue end (after an abort: where the machine stopped, the
    /// last setpoint's X Y Z and `s`).
    pub fn resync(&mut self, tail: Vec3, tail_s: f64) {
        self.tail = tail;
        self.tail_s = tail_s;
    }

    /// Plan `block` into `out` against the current queue end and move the end
    /// past it. On error `out` is unspecified and the end has not moved.
    pub fn plan(&mut self, block: &Block, out: &mut PlannedBlock) -> Result<(), PushError> {
        self.plan_within(block, out, None)
    }

    pub(crate) fn plan_within(
        &mut self,
        block: &Block,
        out: &mut PlannedBlock,
        room: Option<Room>,
    ) -> Result<(), PushError> {
        let cfg = self.cfg;
        if !(block.feed.is_finite() && block.feed > 0.0) {
            return Err(PushError::Feed);
        }
        let gap = (block.path.start_point() - self.tail).norm();
        if !(gap <= JOIN_TOLERANCE) {
            return Err(PushError::Discontinuous { gap });
        }
        let mut pieces = [block.path; MAX_PIECES];
        let mut singular = [false; MAX_PIECES + 1];
        let n_pieces = split_at_tangent_breaks(
            &block.path,
            &mut pieces,
            cfg.tangent_tolerance,
            cfg.chord_tolerance,
            &mut singular,
        )?;
        if let Some(r) = room
            && n_pieces > r.segments
        {
            return Err(PushError::Full {
                needed: n_pieces,
                free: r.segments,
            });
        }
        let mut total = 0.0;
        let mut lengths = [0.0; MAX_PIECES];
        for (len, piece) in lengths.iter_mut().zip(&pieces[..n_pieces]) {
            *len = piece.length();
            if !(*len > 0.0 && len.is_finite()) {
                return Err(PushError::Empty);
            }
            total += *len;
        }
        // Where a piece starts or ends at a stationary point (C' = 0), its laws
        // are taken a tick's distance inside (feed::stationary_offset).
        let mut windows = [(0.0, 0.0); MAX_PIECES];
        for (k, w) in windows.iter_mut().enumerate().take(n_pieces) {
            *w = law_window(
                &pieces[k],
                lengths[k],
                (singular[k], singular[k + 1]),
                block,
                &cfg,
            );
        }
        let h = self.h;
        let g_first = index_of(self.tail_s, h) - 1;
        let g_last = index_of(self.tail_s + total, h);
        if let Some(r) = room
            && g_last > r.last_interval
        {
            return Err(PushError::ProfileFull);
        }
        let n_caps = (g_last + 2 - g_first) as usize;
        if n_caps > PLAN_INTERVALS {
            return Err(PushError::TooLong);
        }
        // From here on nothing can fail.
        out.h = h;
        out.id = block.id;
        out.tail = self.tail;
        out.s0 = self.tail_s;
        out.g0 = g_first;
        out.n_caps = n_caps;
        out.raw[..n_caps].fill(f64::INFINITY);
        out.raw_feed[..n_caps].fill(f64::INFINITY);
        out.entry = block.path.eval(windows[0].0, 3);
        out.n_segments = n_pieces;
        let mut s = self.tail_s;
        for (k, piece) in pieces[..n_pieces].iter().enumerate() {
            let seg = Segment {
                path: *piece,
                block_id: block.id,
                feed: block.feed,
                mrr: block.mrr,
                s0: s,
                length: lengths[k],
                // Set at commit: corners and the end of the queue.
                stop_at_end: true,
            };
            out.corner[k] = if k > 0 {
                // A tangent break inside the block.
                let left = pieces[k - 1].eval(windows[k - 1].1, 3);
                let right = piece.eval(windows[k].0, 3);
                junction_speed(&left, &right, &cfg)
            } else {
                f64::INFINITY
            };
            sample_laws(&seg, windows[k], &cfg, out);
            s += seg.length;
            out.segments[k] = Some(seg);
        }
        let last = &pieces[n_pieces - 1];
        out.exit = last.eval(windows[n_pieces - 1].1, 3);
        out.exact_stop = block.blending == crate::path::Blending::ExactStop;
        out.end = block.path.end_point();
        out.s1 = s;
        self.tail = out.end;
        self.tail_s = s;
        Ok(())
    }
}

/// Sample the feed laws of `seg` onto the global grid: sample `k` sits at
/// arc length `k·h/M` and feeds interval `⌊k/M⌋` (and the one before when it
/// is on a node). A curvature peak can fall between samples, so every local
/// minimum of the sampled law is refined by a golden-section search between
/// its neighbours, and the refined value lowers the intervals it may lie in.
///
/// The laws are evaluated with the parameter clamped into `window` (see
/// [`law_window`]).
fn sample_laws(seg: &Segment, window: (f64, f64), cfg: &InterpConfig, profile: &mut PlannedBlock) {
    let (u_lo, u_hi) = window;
    // Law samples stay `profile_step / law_samples_per_interval` apart however
    // long the period (a long period only widens the grid), so no feature of
    // the curve hides between samples.
    let m = cfg.law_samples_per_interval as i64 * grid_multiple(cfg);
    let hs = profile.h() / m as f64;
    let path = &seg.path;
    // The machine laws (index 0) and the override-scaled feed laws (index 1).
    let law = |u: f64, which: usize| {
        let d = path.eval(u.clamp(u_lo, u_hi), 3);
        if which == 0 {
            machine_limit(&d, cfg, 1.0)
        } else {
            feed_limit(&d, seg.feed, seg.mrr.as_ref(), cfg)
        }
    };
    let lower = |profile: &mut PlannedBlock, g: i64, which: usize, v: f64| {
        if which == 0 {
            profile.lower_cap(g, v);
        } else {
            profile.lower_feed_cap(g, v);
        }
    };
    // Lines and arcs have constant curvature: nothing to refine.
    let refine = matches!(path, Path::Nurbs(_));
    let (g_first, g_last) = (profile.index_of(seg.s0), profile.index_of(seg.s1()));
    let feed_top = seg.feed.min(cfg.max_path_speed);
    for g in g_first..=g_last {
        profile.lower_feed_cap(g, feed_top);
    }
    let k0 = libm::ceil(seg.s0 / hs) as i64;
    let k1 = libm::floor(seg.s1() / hs) as i64;
    let (mut u_prev, mut x_prev) = (path.u_start(), seg.s0);
    // Per law, the last two samples: (k, u, value).
    let mut w1: [Option<(i64, f64, f64)>; 2] = [None; 2];
    let mut w2: [Option<(i64, f64, f64)>; 2] = [None; 2];
    for k in k0..=k1 {
        let x = k as f64 * hs;
        let u = path.param_at_arc_length(u_prev, x - x_prev);
        let g = k.div_euclid(m);
        // One evaluation for both laws at the sample.
        let d = path.eval(u.clamp(u_lo, u_hi), 3);
        let both = [
            machine_limit(&d, cfg, 1.0),
            feed_limit(&d, seg.feed, seg.mrr.as_ref(), cfg),
        ];
        for which in 0..2 {
            let v = both[which];
            lower(profile, g, which, v);
            if k.rem_euclid(m) == 0 {
                lower(profile, g - 1, which, v);
            }
            // w2, w1, this: a local minimum at w1 is refined between w2 and this sample.
            if let (true, Some((ka, ua, va)), Some((_, _, vb))) = (refine, w2[which], w1[which])
                && vb < va
                && vb <= v
            {
                let vmin = golden_section_min(|u| law(u, which), ua, u, GOLDEN_ITERS, 0.0).min(vb);
                for gi in ka.div_euclid(m)..=k.div_euclid(m) {
                    lower(profile, gi, which, vmin);
                }
            }
            w2[which] = w1[which];
            w1[which] = Some((k, u, v));
        }
        u_prev = u;
        x_prev = x;
    }
    // Knots where the curvature may jump (continuity C1 or less): price them
    // as junctions. Tangent breaks were cut into separate segments already.
    if let Path::Nurbs(n) = path {
        let p = n.degree();
        let knots = n.knots();
        let (ua, ub) = (n.u_start(), n.u_end());
        let mut i = p + 1;
        let mut prev = ua;
        while i < knots.len() - p - 1 {
            let u = knots[i];
            let mut mult = 1;
            while i + mult < knots.len() && knots[i + mult] == u {
                mult += 1;
            }
            if u > ua && u < ub && mult + 1 >= p {
                let left = n.eval(u - (u - prev) * 1e-9, 3);
                let right = n.eval(u, 3);
                let v = junction_speed(&left, &right, cfg);
                let g = profile.index_of(seg.s0 + path.arc_length(ua, u));
                profile.lower_cap(g, v);
                profile.lower_cap(g - 1, v);
                profile.lower_cap(g + 1, v);
            }
            if u > ua {
                prev = u;
            }
            i += mult;
        }
    }
}

/// Golden-section steps refining a sampled law minimum (bracket shrinks by 0.618 each).
const GOLDEN_ITERS: usize = 40;

/// The parameters between which the laws of `path` (of length `len`, a piece
/// of `block`) are evaluated: its whole range, narrowed by [`stationary_offset`]
/// at an end that is `singular` (the curve stops or turns back there: the
/// curvature is in general infinite, or as good as, and no tick sees it).
fn law_window(
    path: &Path,
    len: f64,
    singular: (bool, bool),
    block: &Block,
    cfg: &InterpConfig,
) -> (f64, f64) {
    let (ua, ub) = (path.u_start(), path.u_end());
    let limit = |u: f64| {
        let d = path.eval(u, 3);
        machine_limit(&d, cfg, 1.0).min(feed_limit(&d, block.feed, block.mrr.as_ref(), cfg))
    };
    let lo = if singular.0 {
        let d = stationary_offset(cfg, 0.5 * len, |x| limit(path.param_at_arc_length(ua, x)));
        path.param_at_arc_length(ua, d)
    } else {
        ua
    };
    let hi = if singular.1 {
        let d = stationary_offset(cfg, 0.5 * len, |x| {
            limit(path.param_at_arc_length(ua, len - x))
        });
        path.param_at_arc_length(ua, len - d)
    } else {
        ub
    };
    (lo, hi)
}

/// Cut a NURBS where the tangent breaks: at interior knots of full
/// multiplicity where it turns by more than `tol` (a corner inside one
/// block), and where the curve stops or turns back
/// ([`Nurbs::for_each_stationary`]: C' = 0, a cusp where the tangent reverses,
/// a corner, or a point where the curvature blows up; or a hairpin that is a
/// cusp to within `near`). Those are marked in `singular` (one flag per piece
/// boundary, the block's ends included, which are marked where the curve is
/// stationary): the pieces' laws are taken a tick inside them
/// ([`law_window`]) and their junction is priced like a corner's. Lines and
/// arcs are one piece. Returns the number of pieces written.
pub(crate) fn split_at_tangent_breaks(
    path: &Path,
    out: &mut [Path; MAX_PIECES],
    tol: f64,
    near: f64,
    singular: &mut [bool; MAX_PIECES + 1],
) -> Result<usize, PushError> {
    out[0] = *path;
    singular.fill(false);
    let Path::Nurbs(n) = path else {
        return Ok(1);
    };
    let (ua, ub) = (n.u_start(), n.u_end());
    singular[0] = n.is_stationary(ua, Side::After);
    // Cut parameters and whether each stops or turns the curve back (more than
    // MAX_PIECES - 1 is an error either way).
    let mut cuts = [(0.0f64, false); 2 * MAX_PIECES];
    let mut n_cuts = 0;
    let mut add = |u: f64, stops: bool| {
        if n_cuts < cuts.len() {
            cuts[n_cuts] = (u, stops);
        }
        n_cuts += 1;
    };
    let p = n.degree();
    let knots = n.knots();
    let mut i = p + 1;
    while i < knots.len() - p - 1 {
        let u = knots[i];
        let mut mult = 1;
        while i + mult < knots.len() && knots[i + mult] == u {
            mult += 1;
        }
        if u > ua && u < ub && mult >= p {
            // The one-sided tangents at a C0 knot.
            let left = n.tangent(u, Side::Before);
            let right = n.tangent(u, Side::After);
            if !(left.dot(&right) >= libm::cos(tol)) {
                add(u, false);
            }
        }
        i += mult;
    }
    n.for_each_stationary(near, |u| add(u, true));
    if n_cuts > cuts.len() {
        return Err(PushError::TooManyCorners);
    }
    let cuts = &mut cuts[..n_cuts];
    cuts.sort_unstable_by(|a, b| a.0.total_cmp(&b.0));
    let mut count = 1;
    let mut last = ua;
    for &(u, stops) in cuts.iter() {
        if u <= last {
            // A stationary corner knot, found twice.
            singular[count - 1] |= stops;
            continue;
        }
        if count >= MAX_PIECES {
            return Err(PushError::TooManyCorners);
        }
        let (a, b) = out[count - 1].split_at(u).map_err(PushError::Split)?;
        out[count - 1] = a;
        out[count] = b;
        singular[count] = stops;
        count += 1;
        last = u;
    }
    singular[count] = n.is_stationary(ub, Side::Before);
    Ok(count)
}
