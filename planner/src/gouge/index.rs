//! A uniform grid over XY: the spatial index that makes detection cost grow with
//! the path, not with path × surface (the "detection range" of §2.1).
//!
//! Items are stored once per cell they overlap, in one flat array sorted by
//! cell (CSR layout), so a query touches only the cells of its rectangle.

/// Cell counts above this are refused; the cell size grows instead, so a
/// huge or degenerate extent can never exhaust memory.
const MAX_CELLS: usize = 1 << 22;

/// Uniform XY grid of item ids.
#[derive(Debug, Clone)]
pub struct Grid2 {
    origin: [f64; 2],
    cell: f64,
    dims: [usize; 2],
    starts: Vec<u32>,
    items: Vec<u32>,
}

impl Grid2 {
    /// Builds the grid over `boxes` (`[xmin, ymin, xmax, ymax]` per item), with
    /// cells of about `cell` mm.
    pub fn build(boxes: &[[f64; 4]], cell: f64) -> Self {
        let mut lo = [f64::INFINITY; 2];
        let mut hi = [f64::NEG_INFINITY; 2];
        for b in boxes {
            lo = [lo[0].min(b[0]), lo[1].min(b[1])];
            hi = [hi[0].max(b[2]), hi[1].max(b[3])];
        }
        if boxes.is_empty() {
            lo = [0.0; 2];
            hi = [0.0; 2];
        }
        let mut cell = if cell.is_finite() && cell > 0.0 {
            cell
        } else {
            1.0
        };
        let span = |c: f64| {
            [
                (((hi[0] - lo[0]) / c).floor() as usize + 1).max(1),
                (((hi[1] - lo[1]) / c).floor() as usize + 1).max(1),
            ]
        };
        let mut dims = span(cell);
        while dims[0].saturating_mul(dims[1]) > MAX_CELLS {
            cell *= 2.0;
            dims = span(cell);
        }
        let mut grid = Grid2 {
            origin: lo,
            cell,
            dims,
            starts: vec![0; dims[0] * dims[1] + 1],
            items: Vec::new(),
        };
        // Count, prefix-sum, fill.
        for b in boxes {
            let (ix, iy) = grid.range(b);
            for y in iy.0..=iy.1 {
                for x in ix.0..=ix.1 {
                    grid.starts[y * dims[0] + x + 1] += 1;
                }
            }
        }
        for i in 1..grid.starts.len() {
            grid.starts[i] += grid.starts[i - 1];
        }
        let mut fill = grid.starts.clone();
        grid.items = vec![0; *grid.starts.last().unwrap_or(&0) as usize];
        for (id, b) in boxes.iter().enumerate() {
            let (ix, iy) = grid.range(b);
            for y in iy.0..=iy.1 {
                for x in ix.0..=ix.1 {
                    let c = y * dims[0] + x;
                    grid.items[fill[c] as usize] = id as u32;
                    fill[c] += 1;
                }
            }
        }
        grid
    }

    /// Builds the grid over points (a box of zero size each).
    pub fn of_points(points: impl Iterator<Item = [f64; 2]>, cell: f64) -> Self {
        let boxes: Vec<[f64; 4]> = points.map(|p| [p[0], p[1], p[0], p[1]]).collect();
        Self::build(&boxes, cell)
    }

    fn clamp_index(&self, v: f64, axis: usize) -> usize {
        let i = ((v - self.origin[axis]) / self.cell).floor();
        if i.is_nan() || i < 0.0 {
            0
        } else {
            (i as usize).min(self.dims[axis] - 1)
        }
    }

    fn range(&self, b: &[f64; 4]) -> ((usize, usize), (usize, usize)) {
        (
            (self.clamp_index(b[0], 0), self.clamp_index(b[2], 0)),
            (self.clamp_index(b[1], 1), self.clamp_index(b[3], 1)),
        )
    }

    /// Calls `visit` with every item id stored in a cell that overlaps the
    /// rectangle (an item may come more than once if it spans several cells).
    pub fn query(&self, rect: [f64; 4], mut visit: impl FnMut(u32)) {
        let max = [
            self.origin[0] + self.cell * self.dims[0] as f64,
            self.origin[1] + self.cell * self.dims[1] as f64,
        ];
        if rect[2] < self.origin[0]
            || rect[3] < self.origin[1]
            || rect[0] > max[0]
            || rect[1] > max[1]
        {
            return;
        }
        let (ix, iy) = self.range(&rect);
        for y in iy.0..=iy.1 {
            let row = y * self.dims[0];
            let (s, e) = (
                self.starts[row + ix.0] as usize,
                self.starts[row + ix.1 + 1] as usize,
            );
            for &id in &self.items[s..e] {
                visit(id);
            }
        }
    }
}

impl Grid2 {
    /// Number of cells.
    pub fn cell_count(&self) -> usize {
        self.dims[0] * self.dims[1]
    }

    /// The item ids stored in cell `c`.
    pub fn cell_items(&self, c: usize) -> &[u32] {
        &self.items[self.starts[c] as usize..self.starts[c + 1] as usize]
    }

    /// Calls `visit(cell, cell_rect, ids)` for every non-empty cell overlapping
    /// the rectangle, so a caller can skip whole cells with a bound.
    pub fn query_cells(&self, rect: [f64; 4], mut visit: impl FnMut(usize, [f64; 4], &[u32])) {
        let max = [
            self.origin[0] + self.cell * self.dims[0] as f64,
            self.origin[1] + self.cell * self.dims[1] as f64,
        ];
        if rect[2] < self.origin[0]
            || rect[3] < self.origin[1]
            || rect[0] > max[0]
            || rect[1] > max[1]
        {
            return;
        }
        let (ix, iy) = self.range(&rect);
        for y in iy.0..=iy.1 {
            for x in ix.0..=ix.1 {
                let c = y * self.dims[0] + x;
                let ids = self.cell_items(c);
                if ids.is_empty() {
                    continue;
                }
                let x0 = self.origin[0] + self.cell * x as f64;
                let y0 = self.origin[1] + self.cell * y as f64;
                visit(c, [x0, y0, x0 + self.cell, y0 + self.cell], ids);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn query_finds_exactly_what_brute_force_finds() {
        let pts: Vec<[f64; 2]> = (0..500)
            .map(|i| {
                let a = i as f64 * 0.7;
                [a.sin() * 30.0 + 0.01 * i as f64, (a * 1.3).cos() * 20.0]
            })
            .collect();
        let grid = Grid2::of_points(pts.iter().copied(), 2.5);
        for rect in [
            [-5.0, -5.0, 5.0, 5.0],
            [10.0, -30.0, 40.0, 0.0],
            [-100.0, -100.0, 100.0, 100.0],
            [50.0, 50.0, 60.0, 60.0],
        ] {
            let mut got = Vec::new();
            grid.query(rect, |i| {
                let p = pts[i as usize];
                if p[0] >= rect[0] && p[0] <= rect[2] && p[1] >= rect[1] && p[1] <= rect[3] {
                    got.push(i)
                }
            });
            got.sort();
            let want: Vec<u32> = (0..pts.len() as u32)
                .filter(|&i| {
                    let p = pts[i as usize];
                    p[0] >= rect[0] && p[0] <= rect[2] && p[1] >= rect[1] && p[1] <= rect[3]
                })
                .collect();
            assert_eq!(got, want, "{rect:?}");
        }
    }
}
