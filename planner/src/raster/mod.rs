//! 3-axis raster finishing by slicing the offset triangle mesh (seed `001_…`
//! §4.3–4.6).
//!
//! [`plan_raster`] turns a [`TriMesh`] and a [`Cutter`] into parallel passes
//! of tool-tip (CL) polylines:
//!
//! 1. **Offset** (§4.3, [`offset`]): every face becomes its offset copy, every
//!    edge that is convex seen from above (or a boundary, or non-manifold)
//!    becomes a cylinder-like capsule with its end vertices' spheres; concave
//!    and flat edges are skipped because the faces beside them dominate.
//! 2. **Slice** (§4.4): each pass is a vertical plane; a sorted index finds
//!    the offsets a plane can meet, and each gives one section piece (a
//!    segment for a face, a concave arc for an edge with its end caps).
//! 3. **Trace and envelope** (§4.5–4.6, [`envelope`]): the pieces' upper
//!    envelope along the pass is the CL curve; gaps (the tool off the mesh)
//!    split a pass into several polylines.
//!
//! Passes run in parallel (rayon), one pass per task, each thread with its own
//! scratch memory.

mod envelope;
mod offset;

use std::sync::atomic::{AtomicUsize, Ordering};

use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::cutter::Cutter;
use crate::mesh::{P3, TriMesh};
use envelope::{EnvelopeOptions, EnvelopeScratch, PassGeometry, envelope, run_points};
use offset::{CutterShape, F3, OffsetEdge, OffsetFace, Piece};

/// Settings of a raster finishing path. Serialised kebab-case; every field
/// has the default given in its doc.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case", default, deny_unknown_fields)]
pub struct RasterConfig {
    /// Distance between passes, mm. Default 0.5.
    pub stepover: f64,
    /// Direction of the passes, degrees counter-clockwise from +X. Default 0.
    pub angle_deg: f64,
    /// Reverse every other pass so the tool cuts both ways. Default false.
    pub zigzag: bool,
    /// Largest distance between the exact CL curve and the output polyline, mm.
    /// Default 1e-5.
    pub chord_tolerance: f64,
    /// Width of the cells a pass is first cut into for the envelope, mm.
    /// Default 0.5 (speed only; the result does not depend on it).
    pub cell_width: f64,
    /// Envelope crossings are located to this, mm. Default 1e-7.
    pub crossing_tolerance: f64,
    /// A far corner within this distance (mm) of its neighbour's plane makes
    /// the edge flat (skipped). Default 1e-9.
    pub flat_edge_tolerance: f64,
}

impl Default for RasterConfig {
    fn default() -> Self {
        Self {
            stepover: 0.5,
            angle_deg: 0.0,
            zigzag: false,
            chord_tolerance: 1e-5,
            cell_width: 0.5,
            crossing_tolerance: 1e-7,
            flat_edge_tolerance: 1e-9,
        }
    }
}

/// Two values of one vertex offset held by two capsules agree to this (mm).
const SAME_CURVE_TOLERANCE: f64 = 1e-12;

/// Two curves equal at three points of an interval this short (mm) are one:
/// with curvature up to 1/(0.1 mm) they differ in between by < 2.5e-8 mm.
const SAME_CURVE_WIDTH: f64 = 1e-4;

/// A piece at most this far (mm) above the envelope's lower bound is taken
/// as below it: the path may be this much low, far under the chord
/// tolerance, and tangent meetings stop bisecting at ~1e-4 mm instead of the
/// crossing tolerance.
const PRUNE_TOLERANCE: f64 = 1e-9;

/// Envelope runs and gaps narrower than this (mm) are round-off.
const MIN_RUN_WIDTH: f64 = 1e-9;

/// Offsets wider (across the passes) than this many step-overs plus the
/// cutter diameter go to a list every pass scans, so one huge triangle does
/// not widen every pass's index window.
const WIDE_OFFSET_STEPOVERS: f64 = 16.0;

/// Why a raster path could not be planned.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum RasterError {
    /// A config value is out of range.
    #[error("raster config: {field} = {value} must be {rule}")]
    Config {
        /// Kebab-case field name.
        field: &'static str,
        /// The value given.
        value: f64,
        /// What it must be.
        rule: &'static str,
    },
    /// So many passes would be needed that the step-over is surely wrong.
    #[error(
        "{passes} passes for a {width} mm wide part at step-over {stepover} mm (limit {limit})"
    )]
    TooManyPasses {
        /// Passes needed.
        passes: f64,
        /// Part width across the passes, mm.
        width: f64,
        /// The step-over, mm.
        stepover: f64,
        /// The limit.
        limit: usize,
    },
    /// The path would hold more CL points than the limit: the chord
    /// tolerance (or the step-over) is far finer than any machine needs, and
    /// the program written from it would exhaust memory.
    #[error(
        "more than {limit} CL points (at least {points}) at chord-tolerance {chord_tolerance} mm \
         and stepover {stepover} mm: raise either"
    )]
    TooManyPoints {
        /// Points made before planning stopped (a lower bound).
        points: usize,
        /// The chord tolerance, mm.
        chord_tolerance: f64,
        /// The step-over, mm.
        stepover: f64,
        /// The limit.
        limit: usize,
    },
}

/// Upper limit on the number of passes (10 m at 0.1 µm would be absurd).
pub const MAX_PASSES: usize = 10_000_000;

/// Upper limit on the CL points of a path. Ten million points is a large
/// mould finished at a fine step-over (about 0.5 GB of G-code); a chord
/// tolerance near what f64 resolves asks for far more (a 20 mm plate at
/// 1e-11 mm: 65 million points, a 3 GB program built in 23 GB of memory).
/// Planning stops soon after the limit is passed, so memory stays bounded.
pub const MAX_POINTS: usize = 10_000_000;

/// One pass: its index from the first pass and its polylines in cutting
/// order (several when the tool leaves the mesh in between).
#[derive(Debug, Clone, PartialEq)]
pub struct RasterPass {
    /// 0 for the pass at the lowest cross coordinate.
    pub index: usize,
    /// Tool-tip points, mm, in machine XYZ.
    pub polylines: Vec<Vec<P3>>,
}

/// A raster finishing path: passes of tool-tip (CL) polylines.
#[derive(Debug, Clone, PartialEq)]
pub struct RasterPath {
    /// The cutter the path is for.
    pub cutter: Cutter,
    /// The settings used.
    pub config: RasterConfig,
    /// Passes in machining order.
    pub passes: Vec<RasterPass>,
    /// Counts from the planning run.
    pub stats: RasterStats,
}

/// Counts from a planning run.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize)]
#[serde(rename_all = "kebab-case")]
pub struct RasterStats {
    /// Triangles in the mesh.
    pub triangles: usize,
    /// Edges in the mesh.
    pub edges: usize,
    /// Edges offset as capsules (convex from above, boundary, non-manifold).
    pub offset_edges: usize,
    /// Boundary edges (gaps, open borders).
    pub boundary_edges: usize,
    /// Edges with three or more triangles or inconsistent orientation.
    pub non_manifold_edges: usize,
    /// Sliver triangles.
    pub slivers: usize,
    /// Section pieces over all passes.
    pub pieces: usize,
    /// Output points over all passes.
    pub points: usize,
}

impl RasterPath {
    /// Total number of CL points.
    pub fn point_count(&self) -> usize {
        self.passes
            .iter()
            .flat_map(|p| &p.polylines)
            .map(Vec::len)
            .sum()
    }
}

impl RasterConfig {
    /// Checks the values.
    pub fn validate(&self) -> Result<(), RasterError> {
        let pos = |field, value: f64| {
            if value.is_finite() && value > 0.0 {
                Ok(())
            } else {
                Err(RasterError::Config {
                    field,
                    value,
                    rule: "finite and > 0",
                })
            }
        };
        pos("stepover", self.stepover)?;
        pos("chord-tolerance", self.chord_tolerance)?;
        pos("cell-width", self.cell_width)?;
        pos("crossing-tolerance", self.crossing_tolerance)?;
        if !(self.flat_edge_tolerance.is_finite() && self.flat_edge_tolerance >= 0.0) {
            return Err(RasterError::Config {
                field: "flat-edge-tolerance",
                value: self.flat_edge_tolerance,
                rule: "finite and >= 0",
            });
        }
        if !self.angle_deg.is_finite() {
            return Err(RasterError::Config {
                field: "angle-deg",
                value: self.angle_deg,
                rule: "finite",
            });
        }
        Ok(())
    }
}

/// The pass frame: `u = x cos θ + y sin θ`, `w = −x sin θ + y cos θ`.
#[derive(Debug, Clone, Copy)]
struct Frame {
    c: f64,
    s: f64,
}

impl Frame {
    fn new(angle_deg: f64) -> Self {
        let (s, c) = angle_deg.to_radians().sin_cos();
        Self { c, s }
    }
    fn to_frame(self, p: &P3) -> F3 {
        [
            p.x * self.c + p.y * self.s,
            -p.x * self.s + p.y * self.c,
            p.z,
        ]
    }
    fn to_world(self, u: f64, w: f64, z: f64) -> P3 {
        P3::new(u * self.c - w * self.s, u * self.s + w * self.c, z)
    }
}

/// Offsets sorted by the low end of their `w` range, for a pass to find the
/// ones it meets.
struct PassIndex {
    /// `(w_lo, w_hi, id)`, sorted by `w_lo`; ids `< faces` are faces, the rest edges.
    narrow: Vec<(f64, f64, u32)>,
    widest_narrow: f64,
    wide: Vec<(f64, f64, u32)>,
}

impl PassIndex {
    fn new(mut ranges: Vec<(f64, f64, u32)>, wide_limit: f64) -> Self {
        let (mut wide, mut narrow) = (Vec::new(), Vec::with_capacity(ranges.len()));
        for r in ranges.drain(..) {
            if r.1 - r.0 > wide_limit {
                wide.push(r);
            } else {
                narrow.push(r);
            }
        }
        narrow.par_sort_unstable_by(|a, b| a.0.total_cmp(&b.0));
        let widest_narrow = narrow.iter().map(|r| r.1 - r.0).fold(0.0, f64::max);
        Self {
            narrow,
            widest_narrow,
            wide,
        }
    }

    fn for_each_at(&self, w: f64, mut f: impl FnMut(u32)) {
        let start = self
            .narrow
            .partition_point(|r| r.0 < w - self.widest_narrow);
        for r in &self.narrow[start..] {
            if r.0 > w {
                break;
            }
            if r.1 >= w {
                f(r.2);
            }
        }
        for r in &self.wide {
            if r.0 <= w && r.1 >= w {
                f(r.2);
            }
        }
    }
}

/// Plans a raster finishing path over `mesh` for `cutter`.
pub fn plan_raster(
    mesh: &TriMesh,
    cutter: &Cutter,
    config: &RasterConfig,
) -> Result<RasterPath, RasterError> {
    plan_raster_with_progress(mesh, cutter, config, &|_, _| {})
}

/// [`plan_raster`] calling `progress(done, total)` as passes finish (from
/// worker threads).
pub fn plan_raster_with_progress(
    mesh: &TriMesh,
    cutter: &Cutter,
    config: &RasterConfig,
    progress: &(dyn Fn(usize, usize) + Sync),
) -> Result<RasterPath, RasterError> {
    plan_raster_limited(mesh, cutter, config, progress, MAX_POINTS)
}

/// [`plan_raster_with_progress`] refusing a path of more than `max_points`
/// CL points: passes not yet started once the limit is passed are skipped.
fn plan_raster_limited(
    mesh: &TriMesh,
    cutter: &Cutter,
    config: &RasterConfig,
    progress: &(dyn Fn(usize, usize) + Sync),
    max_points: usize,
) -> Result<RasterPath, RasterError> {
    config.validate()?;
    let cutter = cutter.validated().map_err(|_| RasterError::Config {
        field: "cutter",
        value: cutter.radius(),
        rule: "a valid cutter",
    })?;
    let shape = CutterShape::new(&cutter);
    let frame = Frame::new(config.angle_deg);
    let verts: Vec<F3> = mesh
        .vertices
        .par_iter()
        .map(|p| frame.to_frame(p))
        .collect();
    let topo = mesh.topology(crate::mesh::TopologyOptions {
        flat_tolerance: config.flat_edge_tolerance,
        ..Default::default()
    });

    // Normals flipped to point up: a cutter from above meets the upper side
    // of every triangle whatever the file's orientation (as OpenCAMLib does).
    let up: Vec<[f64; 3]> = mesh
        .normals
        .iter()
        .map(|n| {
            let n = frame.to_frame(&P3::from(*n));
            if n[2] < 0.0 { n.map(|c| -c) } else { n }
        })
        .collect();
    let faces: Vec<OffsetFace> = mesh
        .triangles
        .par_iter()
        .enumerate()
        .map(|(t, tri)| OffsetFace::new(tri.map(|v| verts[v as usize]), up[t], &shape, t as u32))
        .collect();
    let edges: Vec<OffsetEdge> = topo
        .edges
        .par_iter()
        .filter(|e| keep_edge(mesh, &verts, &up, e, config.flat_edge_tolerance))
        .map(|e| OffsetEdge {
            p0: verts[e.vertices[0] as usize],
            p1: verts[e.vertices[1] as usize],
            v0: e.vertices[0],
            v1: e.vertices[1],
        })
        .collect();

    let nf = faces.len() as u32;
    let mut ranges: Vec<(f64, f64, u32)> = Vec::with_capacity(faces.len() + edges.len());
    ranges.extend(faces.iter().enumerate().map(|(i, f)| {
        let (a, b) = f.w_range();
        (a, b, i as u32)
    }));
    ranges.extend(edges.iter().enumerate().map(|(i, e)| {
        let (a, b) = e.w_range(&shape);
        (a, b, nf + i as u32)
    }));
    let index = PassIndex::new(
        ranges,
        WIDE_OFFSET_STEPOVERS * config.stepover + 2.0 * shape.radius,
    );

    let (wmin, wmax) = verts
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
            (a.min(v[1]), b.max(v[1]))
        });
    let width = wmax - wmin;
    let count = (width / config.stepover).floor() + 1.0;
    if !(count <= MAX_PASSES as f64) {
        return Err(RasterError::TooManyPasses {
            passes: count,
            width,
            stepover: config.stepover,
            limit: MAX_PASSES,
        });
    }
    let count = count as usize;
    let opt = EnvelopeOptions {
        cell_width: config.cell_width,
        min_split: config.crossing_tolerance,
        same_value: SAME_CURVE_TOLERANCE,
        same_curve_width: SAME_CURVE_WIDTH,
        chord_tolerance: config.chord_tolerance,
        prune_tolerance: PRUNE_TOLERANCE,
    };
    let done = AtomicUsize::new(0);
    let points = AtomicUsize::new(0);
    let results: Vec<(RasterPass, usize)> = (0..count)
        .into_par_iter()
        .map_init(
            || (Vec::<Piece>::new(), EnvelopeScratch::default()),
            |(pieces, scratch), k| {
                if points.load(Ordering::Relaxed) > max_points {
                    let polylines = Vec::new();
                    return (
                        RasterPass {
                            index: k,
                            polylines,
                        },
                        0,
                    );
                }
                let w = wmin + k as f64 * config.stepover;
                pieces.clear();
                index.for_each_at(w, |id| {
                    let piece = if id < nf {
                        faces[id as usize].slice(w)
                    } else {
                        let e = id - nf;
                        edges[e as usize].slice(w, &shape, e)
                    };
                    pieces.extend(piece);
                });
                let geo = PassGeometry {
                    pieces,
                    edges: &edges,
                    shape: &shape,
                    w,
                };
                envelope(&geo, &opt, scratch);
                let mut polylines = trace_runs(&geo, &opt, &scratch.runs, &frame);
                if config.zigzag && k % 2 == 1 {
                    polylines.reverse();
                    for p in &mut polylines {
                        p.reverse();
                    }
                }
                let made: usize = polylines.iter().map(Vec::len).sum();
                points.fetch_add(made, Ordering::Relaxed);
                let n = done.fetch_add(1, Ordering::Relaxed) + 1;
                progress(n, count);
                (
                    RasterPass {
                        index: k,
                        polylines,
                    },
                    pieces.len(),
                )
            },
        )
        .collect();
    let made = points.into_inner();
    if made > max_points {
        return Err(RasterError::TooManyPoints {
            points: made,
            chord_tolerance: config.chord_tolerance,
            stepover: config.stepover,
            limit: max_points,
        });
    }
    let mut stats = RasterStats {
        triangles: mesh.triangles.len(),
        edges: topo.edges.len(),
        offset_edges: edges.len(),
        boundary_edges: topo.boundary_edges,
        non_manifold_edges: topo.non_manifold_edges,
        slivers: topo.slivers,
        ..Default::default()
    };
    let mut passes = Vec::with_capacity(results.len());
    for (p, n) in results {
        stats.pieces += n;
        passes.push(p);
    }
    let mut path = RasterPath {
        cutter,
        config: *config,
        passes,
        stats,
    };
    path.stats.points = path.point_count();
    Ok(path)
}

/// Whether an edge's offset can be on the upper envelope: kept unless both
/// triangles' far corners lie on or above the other's plane (a valley or a
/// flat seen from above, with upward normals), where the faces dominate.
fn keep_edge(
    mesh: &TriMesh,
    verts: &[F3],
    up: &[[f64; 3]],
    e: &crate::mesh::MeshEdge,
    tol: f64,
) -> bool {
    use crate::mesh::EdgeConvexity;
    if matches!(
        e.convexity,
        EdgeConvexity::Boundary | EdgeConvexity::NonManifold
    ) {
        return true;
    }
    let [a, b] = e.triangles.map(|t| t as usize);
    let far = |t: usize| {
        let tri = mesh.triangles[t];
        let v = tri
            .iter()
            .copied()
            .find(|&v| v != e.vertices[0] && v != e.vertices[1])
            .unwrap_or(tri[0]);
        verts[v as usize]
    };
    let p = verts[e.vertices[0] as usize];
    let height =
        |q: F3, n: [f64; 3]| (q[0] - p[0]) * n[0] + (q[1] - p[1]) * n[1] + (q[2] - p[2]) * n[2];
    height(far(b), up[a]) < -tol || height(far(a), up[b]) < -tol
}

/// Bisection steps that move a run's end in from a point with no value
/// (2^-60 of the run is below f64 resolution).
const FINITE_END_STEPS: usize = 60;

/// The run with both end values finite (ends moved inwards if needed), or
/// `None` if no part of it has a value.
fn finite_run(geo: &PassGeometry<'_>, r: &envelope::Run) -> Option<(envelope::Run, f64, f64)> {
    let (zs, _) = geo.eval(r.piece, r.s);
    let (zt, _) = geo.eval(r.piece, r.t);
    if zs.is_finite() && zt.is_finite() {
        return Some((*r, zs, zt));
    }
    let m = 0.5 * (r.s + r.t);
    let (zm, _) = geo.eval(r.piece, m);
    if !zm.is_finite() {
        return None;
    }
    // Bisect between a point without a value and `m` (which has one).
    let inward = |mut bad: f64| {
        let mut good = (m, zm);
        for _ in 0..FINITE_END_STEPS {
            let x = 0.5 * (bad + good.0);
            match geo.eval(r.piece, x).0 {
                z if z.is_finite() => good = (x, z),
                _ => bad = x,
            }
        }
        good
    };
    let (s, zs) = if zs.is_finite() {
        (r.s, zs)
    } else {
        inward(r.s)
    };
    let (t, zt) = if zt.is_finite() {
        (r.t, zt)
    } else {
        inward(r.t)
    };
    Some((
        envelope::Run {
            piece: r.piece,
            s,
            t,
        },
        zs,
        zt,
    ))
}

/// Turns envelope runs into polylines in world coordinates, splitting at gaps.
fn trace_runs(
    geo: &PassGeometry<'_>,
    opt: &EnvelopeOptions,
    runs: &[envelope::Run],
    frame: &Frame,
) -> Vec<Vec<P3>> {
    let mut polylines = Vec::new();
    let mut current: Vec<[f64; 2]> = Vec::new();
    let mut last_t = f64::NEG_INFINITY;
    let flush = |current: &mut Vec<[f64; 2]>, polylines: &mut Vec<Vec<P3>>| {
        if current.len() >= 2 {
            polylines.push(
                current
                    .iter()
                    .map(|&[u, z]| frame.to_world(u, geo.w, z))
                    .collect(),
            );
        }
        current.clear();
    };
    for r in runs {
        // Neighbouring faces' sections meet only up to round-off: slivers of
        // runs and gaps narrower than this are round-off, not geometry.
        if r.t - r.s < MIN_RUN_WIDTH && !current.is_empty() {
            continue;
        }
        // A capsule's section ends where the cutter's rim just reaches its
        // edge; round-off can put that end a hair out of reach (no value).
        // Such an end is moved in to the last point that has one.
        let Some((r, zs, zt)) = finite_run(geo, r) else {
            continue;
        };
        if r.s - last_t > MIN_RUN_WIDTH {
            flush(&mut current, &mut polylines);
        }
        match current.last_mut() {
            // Where two runs meet they may give one point twice, its heights
            // within the chord tolerance: one point, at the higher (the
            // envelope is their maximum). Twice, it would be a move of
            // nanometres turning by 90° at both ends, which a controller
            // must stop for. (Heights further apart are a vertical step.)
            Some(last)
                if (r.s - last[0]).abs() <= MIN_RUN_WIDTH
                    && (zs - last[1]).abs() <= opt.chord_tolerance =>
            {
                last[1] = last[1].max(zs)
            }
            _ => current.push([r.s, zs]),
        }
        run_points(geo, opt, &r, zs, zt, &mut current);
        last_t = r.t;
    }
    flush(&mut current, &mut polylines);
    polylines
}

#[cfg(test)]
mod tests;
