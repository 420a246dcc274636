//! The fast marching cubes: plane by plane, bit-parallel classification, rank-addressed vertices.
//!
//! The grid is swept along z. For the two z-planes `k` and `k + 1` around the current layer of
//! cells it keeps, per row of `nx` points, 64-bit words of
//! - `inside` bits (`v <= iso`),
//! - crossing bits of the x-edges of the row, of the y-edges to the next row and of the z-edges to
//!   the next plane (an XOR of inside bits), with per-word prefix popcounts.
//!
//! A vertex is identified by its grid edge and numbered in a fixed order (plane `k`: for each row,
//! its x-edges then its y-edges; then the z-edges from plane `k` to `k + 1`, row by row; then plane
//! `k + 1` …). A cell finds the index of the vertex on one of its edges as the row's first index
//! plus the rank (popcount below) of the edge's bit: no hash map, no per-cell search, one vertex
//! per edge whichever cell asks. Active cells (not all eight corners on one side) are found 64 at
//! a time with OR/AND of four rows. Rows of a plane are processed in parallel (rayon) in chunks of
//! a fixed size, and the results are concatenated in row order, so the output is the same bytes
//! for any thread count. Only two planes of bits and one slab of SDF values are held at a time.

use super::closing;
use super::tables::{edge_axis, edge_origin, TABLES};
use super::{inside, GridSpec, McError, McOptions, TriMesh};
use rayon::prelude::*;
use std::collections::VecDeque;

/// Rows per parallel task (fixed, so that results do not depend on the thread count).
const ROWS_PER_TASK: usize = 8;

/// Samples `sdf` on every point of `grid`, in parallel batches of `opts.batch_points`.
///
/// Returns values laid out `[k][j][i]` (x fastest), `grid.n_points()` of them. Meant for small
/// grids, tests and benchmarks; [`marching_cubes`] never holds the whole grid.
pub fn sample_grid<F>(sdf: &F, grid: &GridSpec, opts: &McOptions) -> Result<Vec<f32>, McError>
where
    F: Fn(&[[f32; 3]]) -> Vec<f32> + Sync,
{
    grid.validate()?;
    let coords = Coords::new(grid);
    let mut values = vec![0.0f32; grid.n_points()];
    evaluate_planes(sdf, &coords, 0, &mut values, opts.batch_points)?;
    Ok(values)
}

/// Marching cubes on the SDF `sdf` sampled over `grid` (normalised space).
///
/// With `opts.close_radius > 0` the values are closed ([`super::closing`]) before extraction,
/// still streamed: about `2·(2r + 1) + 2` planes beyond the slab are held.
///
/// `sdf` receives batches of points (`[n][3]`, normalised space) and returns one value per point,
/// negative inside. The grid is evaluated slab by slab (about `opts.slab_points` values at a time)
/// with the batches of a slab running in parallel; extraction then sweeps the slab plane by plane.
/// An SDF that never changes sign gives an empty mesh. Errors: invalid grid or iso level, a batch
/// answered with the wrong length, a NaN value (the first in `[k][j][i]` order is named).
pub fn marching_cubes<F>(sdf: &F, grid: &GridSpec, opts: &McOptions) -> Result<TriMesh, McError>
where
    F: Fn(&[[f32; 3]]) -> Vec<f32> + Sync,
{
    grid.validate()?;
    check_iso(opts.iso)?;
    let coords = Coords::new(grid);
    let plane = grid.res[0] * grid.res[1];
    let slab_planes = (opts.slab_points / plane).max(1);
    let mut source = SdfSlabs {
        sdf,
        coords: &coords,
        batch: opts.batch_points.max(1),
        slab_planes,
        base: 0,
        n_planes: 0,
        buf: Vec::new(),
    };
    if opts.close_radius > 0 {
        let mut closed = ClosedSlabs::new(source, opts.close_radius);
        return sweep(&coords, opts.iso, &mut closed);
    }
    sweep(&coords, opts.iso, &mut source)
}

/// Marching cubes on grid values already in memory, laid out `[k][j][i]` (x fastest).
pub fn marching_cubes_values(
    values: &[f32],
    grid: &GridSpec,
    iso: f32,
) -> Result<TriMesh, McError> {
    grid.validate()?;
    check_iso(iso)?;
    if values.len() != grid.n_points() {
        return Err(McError::ValuesLength {
            got: values.len(),
            expected: grid.n_points(),
            res: grid.res,
        });
    }
    let coords = Coords::new(grid);
    sweep(
        &coords,
        iso,
        &mut InMemory {
            values,
            coords: &coords,
        },
    )
}

fn check_iso(iso: f32) -> Result<(), McError> {
    if iso.is_finite() {
        Ok(())
    } else {
        Err(McError::Iso { iso })
    }
}

/// Grid point coordinates per axis (f64 holding f32-rounded values).
pub(crate) struct Coords {
    pub(crate) n: [usize; 3],
    pub(crate) c: [Vec<f64>; 3],
}

impl Coords {
    pub(crate) fn new(grid: &GridSpec) -> Self {
        Self {
            n: grid.res,
            c: [grid.coords(0), grid.coords(1), grid.coords(2)],
        }
    }

    pub(crate) fn point(&self, i: usize, j: usize, k: usize) -> [f32; 3] {
        [
            self.c[0][i] as f32,
            self.c[1][j] as f32,
            self.c[2][k] as f32,
        ]
    }
}

/// Position of the iso crossing on the edge from `a` (value `va`) to `b` (value `vb`), which lie on
/// different sides of `iso` and are not NaN. Linear interpolation in f64; an infinite end value
/// puts the crossing on the other (finite) end, two infinite ends at the midpoint.
#[inline]
pub(crate) fn crossing(a: f64, b: f64, va: f32, vb: f32, iso: f32) -> f32 {
    let t = match (va.is_infinite(), vb.is_infinite()) {
        (false, false) => {
            let (va, vb, iso) = (va as f64, vb as f64, iso as f64);
            ((iso - va) / (vb - va)).clamp(0.0, 1.0)
        }
        (true, true) => 0.5,
        (true, false) => 1.0,
        (false, true) => 0.0,
    };
    (a + t * (b - a)) as f32
}

/// Where the sweep gets its z-planes of values from.
trait PlaneSource {
    /// Makes planes `k − 1` (when `k > 0`) and `k` available.
    fn prepare(&mut self, k: usize) -> Result<(), McError>;
    /// Values of plane `k` (`[j][i]`), after `prepare(k)` or `prepare(k + 1)`.
    fn plane(&self, k: usize) -> &[f32];
}

struct InMemory<'a> {
    values: &'a [f32],
    coords: &'a Coords,
}

impl PlaneSource for InMemory<'_> {
    fn prepare(&mut self, _k: usize) -> Result<(), McError> {
        Ok(())
    }
    fn plane(&self, k: usize) -> &[f32] {
        let n = self.coords.n[0] * self.coords.n[1];
        &self.values[k * n..(k + 1) * n]
    }
}

struct SdfSlabs<'a, F> {
    sdf: &'a F,
    coords: &'a Coords,
    batch: usize,
    slab_planes: usize,
    /// First plane held in `buf`.
    base: usize,
    /// Planes held in `buf`.
    n_planes: usize,
    buf: Vec<f32>,
}

impl<F> PlaneSource for SdfSlabs<'_, F>
where
    F: Fn(&[[f32; 3]]) -> Vec<f32> + Sync,
{
    fn prepare(&mut self, k: usize) -> Result<(), McError> {
        if k < self.base + self.n_planes {
            return Ok(());
        }
        let plane = self.coords.n[0] * self.coords.n[1];
        let nz = self.coords.n[2];
        // Keep plane k − 1, evaluate up to `slab_planes` new planes starting at k.
        let keep = usize::from(k > 0);
        let new = self.slab_planes.min(nz - k);
        if keep == 1 {
            let src = (k - 1 - self.base) * plane;
            self.buf.copy_within(src..src + plane, 0);
        }
        self.buf.resize((keep + new) * plane, 0.0);
        evaluate_planes(
            self.sdf,
            self.coords,
            k,
            &mut self.buf[keep * plane..],
            self.batch,
        )?;
        self.base = k - keep;
        self.n_planes = keep + new;
        Ok(())
    }

    fn plane(&self, k: usize) -> &[f32] {
        let n = self.coords.n[0] * self.coords.n[1];
        let o = (k - self.base) * n;
        &self.buf[o..o + n]
    }
}

/// The raw planes of an [`SdfSlabs`] closed on the fly ([`super::closing`]): each raw plane is
/// checked for NaN, filtered in-plane (minimum), and the z-minimum over `2r + 1` of those gives a
/// dilated plane; the same with maxima gives the closed plane. Planes leave the queues as soon as
/// no later plane needs them.
struct ClosedSlabs<'a, F> {
    raw: SdfSlabs<'a, F>,
    r: usize,
    /// In-plane minima of raw planes, by plane index (oldest first).
    dil: VecDeque<(usize, Vec<f32>)>,
    /// Dilated planes after their in-plane maxima, by plane index.
    ero: VecDeque<(usize, Vec<f32>)>,
    /// The last closed planes (at most two), by plane index.
    out: VecDeque<(usize, Vec<f32>)>,
    line: Vec<f32>,
}

impl<'a, F> ClosedSlabs<'a, F>
where
    F: Fn(&[[f32; 3]]) -> Vec<f32> + Sync,
{
    fn new(raw: SdfSlabs<'a, F>, r: usize) -> Self {
        Self {
            raw,
            r,
            dil: VecDeque::new(),
            ero: VecDeque::new(),
            out: VecDeque::new(),
            line: Vec::new(),
        }
    }

    fn dims(&self) -> (usize, usize, usize) {
        let [nx, ny, nz] = self.raw.coords.n;
        (nx, ny, nz)
    }

    /// In-plane minima of raw planes up to `k`.
    fn fill_dil(&mut self, k: usize) -> Result<(), McError> {
        let (nx, ny, _) = self.dims();
        let mut next = self.dil.back().map_or(0, |(q, _)| q + 1);
        while next <= k {
            self.raw.prepare(next)?;
            let mut p = self.raw.plane(next).to_vec();
            if let Some(at) = p.iter().position(|v| v.is_nan()) {
                return Err(nan_error(self.raw.coords, next, (at / nx, at % nx)));
            }
            closing::filter_plane(&mut p, nx, ny, self.r, false, &mut self.line);
            self.dil.push_back((next, p));
            next += 1;
        }
        Ok(())
    }

    /// Dilated, in-plane-maximised planes up to `k`.
    fn fill_ero(&mut self, k: usize) -> Result<(), McError> {
        let (nx, ny, nz) = self.dims();
        let mut next = self.ero.back().map_or(0, |(q, _)| q + 1);
        while next <= k {
            self.fill_dil((next + self.r).min(nz - 1))?;
            let mut p = z_combine(&mut self.dil, next, self.r, nz, false);
            closing::filter_plane(&mut p, nx, ny, self.r, true, &mut self.line);
            self.ero.push_back((next, p));
            next += 1;
        }
        Ok(())
    }
}

/// The element-wise minimum (`max = false`) or maximum of the planes `next − r ..= next + r`
/// (clipped to `0..nz`) of `queue`, which must hold them; then the planes that no later index
/// needs leave the queue.
fn z_combine(
    queue: &mut VecDeque<(usize, Vec<f32>)>,
    next: usize,
    r: usize,
    nz: usize,
    max: bool,
) -> Vec<f32> {
    let (lo, hi) = (next.saturating_sub(r), (next + r).min(nz - 1));
    let mut window = queue
        .iter()
        .filter(|(q, _)| (lo..=hi).contains(q))
        .map(|(_, p)| p.as_slice())
        .peekable();
    let mut out = vec![0.0; window.peek().map_or(0, |p| p.len())];
    closing::combine_planes(&mut out, window, max);
    while queue.front().is_some_and(|(q, _)| q + r <= next) {
        queue.pop_front();
    }
    out
}

impl<F> PlaneSource for ClosedSlabs<'_, F>
where
    F: Fn(&[[f32; 3]]) -> Vec<f32> + Sync,
{
    fn prepare(&mut self, k: usize) -> Result<(), McError> {
        let (_, _, nz) = self.dims();
        let mut next = self.out.back().map_or(0, |(q, _)| q + 1);
        while next <= k {
            self.fill_ero((next + self.r).min(nz - 1))?;
            let p = z_combine(&mut self.ero, next, self.r, nz, true);
            self.out.push_back((next, p));
            if self.out.len() > 2 {
                self.out.pop_front();
            }
            next += 1;
        }
        Ok(())
    }

    fn plane(&self, k: usize) -> &[f32] {
        let (_, p) = self
            .out
            .iter()
            .find(|(q, _)| *q == k)
            .expect("plane prepared");
        p
    }
}

/// Fills `out` (whole planes starting at plane `k0`) with SDF values, batch by batch in parallel.
fn evaluate_planes<F>(
    sdf: &F,
    coords: &Coords,
    k0: usize,
    out: &mut [f32],
    batch: usize,
) -> Result<(), McError>
where
    F: Fn(&[[f32; 3]]) -> Vec<f32> + Sync,
{
    let [nx, ny, _] = coords.n;
    let batch = batch.max(1);
    let xs: Vec<f32> = coords.c[0].iter().map(|&x| x as f32).collect();
    out.par_chunks_mut(batch).enumerate().try_for_each_init(
        Vec::new,
        |pts: &mut Vec<[f32; 3]>, (b, chunk)| {
            pts.clear();
            // Row by row: y and z are constant along a row, x comes from the coordinate table.
            let (mut n, end) = (b * batch, b * batch + chunk.len());
            while n < end {
                let (i0, row) = (n % nx, n / nx);
                let (j, k) = (row % ny, k0 + row / ny);
                let i1 = nx.min(i0 + end - n);
                let (y, z) = (coords.c[1][j] as f32, coords.c[2][k] as f32);
                pts.extend(xs[i0..i1].iter().map(|&x| [x, y, z]));
                n += i1 - i0;
            }
            let vals = sdf(pts);
            if vals.len() != chunk.len() {
                return Err(McError::SdfLength {
                    expected: chunk.len(),
                    got: vals.len(),
                });
            }
            chunk.copy_from_slice(&vals);
            Ok(())
        },
    )
}

/// Crossing bits of one kind of edge for every row of a plane, with ranks and first indices.
#[derive(Default)]
struct Mask {
    /// `[ny][words]`: bit `i` of row `j` set when the edge starting at point `(i, j)` crosses.
    bits: Vec<u64>,
    /// `[ny][words]`: set bits in the words before this one, within the row.
    prefix: Vec<u32>,
    /// `[ny]`: set bits in the row.
    count: Vec<u32>,
    /// `[ny]`: global index of the row's first vertex.
    offset: Vec<u32>,
}

impl Mask {
    fn new(ny: usize, words: usize) -> Self {
        Self {
            bits: vec![0; ny * words],
            prefix: vec![0; ny * words],
            count: vec![0; ny],
            offset: vec![0; ny],
        }
    }

    /// Global index of the vertex on the edge starting at point `(i, j)` (which must cross).
    #[inline(always)]
    fn index(&self, words: usize, j: usize, i: usize) -> u32 {
        let w = j * words + (i >> 6);
        let below = self.bits[w] & ((1u64 << (i & 63)) - 1);
        self.offset[j] + self.prefix[w] + below.count_ones()
    }

    /// Recomputes bits (with `f(j, row_words)`), prefixes and counts of every row.
    fn fill(&mut self, words: usize, f: impl Fn(usize, &mut [u64])) {
        for (j, (bits, prefix)) in self
            .bits
            .chunks_mut(words)
            .zip(self.prefix.chunks_mut(words))
            .enumerate()
        {
            f(j, bits);
            let mut acc = 0;
            for (p, b) in prefix.iter_mut().zip(bits.iter()) {
                *p = acc;
                acc += b.count_ones();
            }
            self.count[j] = acc;
        }
    }
}

/// Bits of one z-plane.
struct Plane {
    /// `[ny][words]` inside bits (`v <= iso`); bits at `i >= nx` are zero.
    inside: Vec<u64>,
    /// x-edges `(i, j) – (i + 1, j)`.
    x: Mask,
    /// y-edges `(i, j) – (i, j + 1)`.
    y: Mask,
    /// z-edges from this plane to the next.
    z: Mask,
}

impl Plane {
    fn new(ny: usize, words: usize) -> Self {
        Self {
            inside: vec![0; ny * words],
            x: Mask::new(ny, words),
            y: Mask::new(ny, words),
            z: Mask::new(ny, words),
        }
    }
}

/// Geometry and bookkeeping shared by the passes of the sweep.
struct Layout<'a> {
    coords: &'a Coords,
    nx: usize,
    ny: usize,
    words: usize,
    iso: f32,
    /// Per word: bits of valid x-edges / cells (`i < nx − 1`).
    edge_valid: Vec<u64>,
}

impl Layout<'_> {
    /// Inside bits of every row of `vals`; the first NaN (row-major) is returned as `(j, i)`.
    fn classify(&self, vals: &[f32], out: &mut [u64]) -> Option<(usize, usize)> {
        let (nx, words, iso) = (self.nx, self.words, self.iso);
        let nan_rows: Vec<Option<(usize, usize)>> = out
            .par_chunks_mut(words * ROWS_PER_TASK)
            .enumerate()
            .map(|(t, rows)| {
                let mut first_nan = None;
                for (r, row) in rows.chunks_mut(words).enumerate() {
                    let j = t * ROWS_PER_TASK + r;
                    let v = &vals[j * nx..(j + 1) * nx];
                    let mut nan = false;
                    for (w, word) in row.iter_mut().enumerate() {
                        let chunk = &v[w * 64..((w + 1) * 64).min(nx)];
                        let mut m = 0u64;
                        for (b, &x) in chunk.iter().enumerate() {
                            m |= (inside(x, iso) as u64) << b;
                            nan |= x.is_nan();
                        }
                        *word = m;
                    }
                    if nan && first_nan.is_none() {
                        first_nan = Some((j, v.iter().position(|x| x.is_nan()).unwrap_or(0)));
                    }
                }
                first_nan
            })
            .collect();
        nan_rows.into_iter().flatten().next()
    }

    /// x- and y-edge masks of a plane from its inside bits.
    fn xy_masks(&self, p: &mut Plane) {
        let words = self.words;
        let (inside, ev, ny) = (&p.inside, &self.edge_valid, self.ny);
        p.x.fill(words, |j, out| {
            let r = &inside[j * words..(j + 1) * words];
            for w in 0..words {
                let next = if w + 1 < words { r[w + 1] } else { 0 };
                out[w] = (r[w] ^ ((r[w] >> 1) | (next << 63))) & ev[w];
            }
        });
        p.y.fill(words, |j, out| {
            if j + 1 == ny {
                out.fill(0);
                return;
            }
            let a = &inside[j * words..(j + 1) * words];
            let b = &inside[(j + 1) * words..(j + 2) * words];
            for w in 0..words {
                out[w] = a[w] ^ b[w];
            }
        });
    }

    /// Positions of the vertices on the x- and y-edges of plane `k`, in index order.
    fn xy_vertices(&self, p: &Plane, vals: &[f32], k: usize) -> Vec<[f32; 3]> {
        let (nx, words, iso) = (self.nx, self.words, self.iso);
        let [cx, cy, cz] = &self.coords.c;
        let z = cz[k] as f32;
        let chunks: Vec<Vec<[f32; 3]>> = (0..self.ny.div_ceil(ROWS_PER_TASK))
            .into_par_iter()
            .map(|t| {
                let mut out = Vec::new();
                for j in t * ROWS_PER_TASK..((t + 1) * ROWS_PER_TASK).min(self.ny) {
                    let y = cy[j] as f32;
                    for_each_bit(&p.x.bits[j * words..(j + 1) * words], |i| {
                        let (va, vb) = (vals[j * nx + i], vals[j * nx + i + 1]);
                        out.push([crossing(cx[i], cx[i + 1], va, vb, iso), y, z]);
                    });
                    for_each_bit(&p.y.bits[j * words..(j + 1) * words], |i| {
                        let (va, vb) = (vals[j * nx + i], vals[(j + 1) * nx + i]);
                        out.push([cx[i] as f32, crossing(cy[j], cy[j + 1], va, vb, iso), z]);
                    });
                }
                out
            })
            .collect();
        chunks.concat()
    }

    /// Positions of the vertices on the z-edges from plane `k` to `k + 1`, in index order.
    fn z_vertices(&self, p0: &Plane, v0: &[f32], v1: &[f32], k: usize) -> Vec<[f32; 3]> {
        let (nx, words, iso) = (self.nx, self.words, self.iso);
        let [cx, cy, cz] = &self.coords.c;
        let chunks: Vec<Vec<[f32; 3]>> = (0..self.ny.div_ceil(ROWS_PER_TASK))
            .into_par_iter()
            .map(|t| {
                let mut out = Vec::new();
                for j in t * ROWS_PER_TASK..((t + 1) * ROWS_PER_TASK).min(self.ny) {
                    let y = cy[j] as f32;
                    for_each_bit(&p0.z.bits[j * words..(j + 1) * words], |i| {
                        let (va, vb) = (v0[j * nx + i], v1[j * nx + i]);
                        out.push([cx[i] as f32, y, crossing(cz[k], cz[k + 1], va, vb, iso)]);
                    });
                }
                out
            })
            .collect();
        chunks.concat()
    }

    /// Triangles of the layer of cells between planes `p0` (z = k) and `p1` (z = k + 1).
    fn faces(&self, p0: &Plane, p1: &Plane) -> Vec<[u32; 3]> {
        let n_cell_rows = self.ny - 1;
        let chunks: Vec<Vec<[u32; 3]>> = (0..n_cell_rows.div_ceil(ROWS_PER_TASK))
            .into_par_iter()
            .map(|t| {
                let mut out = Vec::new();
                for j in t * ROWS_PER_TASK..((t + 1) * ROWS_PER_TASK).min(n_cell_rows) {
                    self.cell_row(p0, p1, j, &mut out);
                }
                out
            })
            .collect();
        chunks.concat()
    }

    fn cell_row(&self, p0: &Plane, p1: &Plane, j: usize, out: &mut Vec<[u32; 3]>) {
        let words = self.words;
        let r = |jj: usize| jj * words..(jj + 1) * words;
        // Corner bit dx | dy << 1 | dz << 2 comes from row (dy, dz), point i + dx.
        let rows = [
            &p0.inside[r(j)],
            &p0.inside[r(j + 1)],
            &p1.inside[r(j)],
            &p1.inside[r(j + 1)],
        ];
        let word = |w: usize| -> (u64, u64) {
            let (mut o, mut a) = (0u64, !0u64);
            for r in &rows {
                o |= r[w];
                a &= r[w];
            }
            (o, a)
        };
        let (mut o, mut a) = word(0);
        for w in 0..words {
            let (on, an) = if w + 1 < words { word(w + 1) } else { (0, 0) };
            let mixed = o ^ a;
            let mixed_next = (mixed >> 1) | ((on ^ an) << 63);
            let a_next = (a >> 1) | (an << 63);
            let active = (mixed | mixed_next | (a ^ a_next)) & self.edge_valid[w];
            for_each_bit_word(active, w, |i| {
                let mut case = 0usize;
                for (s, r) in rows.iter().enumerate() {
                    case |= pair(r, i) << (2 * s);
                }
                let t = &TABLES.cases[case];
                for tri in &t.tris[..t.count as usize] {
                    out.push(tri.map(|e| self.edge_index(p0, p1, e as usize, i, j)));
                }
            });
            (o, a) = (on, an);
        }
    }

    /// Global vertex index of edge `e` of the cell at `(i, j)` between planes `p0` and `p1`.
    #[inline(always)]
    fn edge_index(&self, p0: &Plane, p1: &Plane, e: usize, i: usize, j: usize) -> u32 {
        let [dx, dy, dz] = edge_origin(e);
        let pz = if dz == 0 { p0 } else { p1 };
        match edge_axis(e) {
            0 => pz.x.index(self.words, j + dy, i),
            1 => pz.y.index(self.words, j, i + dx),
            _ => p0.z.index(self.words, j + dy, i + dx),
        }
    }
}

/// Bits `i` and `i + 1` of a row (`i + 1 < nx`).
#[inline(always)]
fn pair(r: &[u64], i: usize) -> usize {
    let (w, b) = (i >> 6, i & 63);
    if b < 63 {
        ((r[w] >> b) & 3) as usize
    } else {
        ((r[w] >> 63) | ((r[w + 1] & 1) << 1)) as usize
    }
}

#[inline(always)]
fn for_each_bit_word(mut m: u64, w: usize, mut f: impl FnMut(usize)) {
    while m != 0 {
        let b = m.trailing_zeros() as usize;
        m &= m - 1;
        f(w * 64 + b);
    }
}

#[inline(always)]
fn for_each_bit(row: &[u64], mut f: impl FnMut(usize)) {
    for (w, &m) in row.iter().enumerate() {
        for_each_bit_word(m, w, &mut f);
    }
}

/// Assigns global first indices: z-edges of `p0` rows, then x/y-edges of `p1` rows.
fn assign_offsets(
    start: usize,
    z_of: Option<&mut Mask>,
    xy_of: &mut Plane,
) -> Result<usize, McError> {
    let mut next = start as u64;
    if let Some(z) = z_of {
        for (o, c) in z.offset.iter_mut().zip(&z.count) {
            *o = next as u32;
            next += *c as u64;
        }
    }
    for j in 0..xy_of.x.count.len() {
        xy_of.x.offset[j] = next as u32;
        next += xy_of.x.count[j] as u64;
        xy_of.y.offset[j] = next as u32;
        next += xy_of.y.count[j] as u64;
    }
    if next > u32::MAX as u64 {
        return Err(McError::TooManyVertices);
    }
    Ok(next as usize)
}

fn nan_error(coords: &Coords, k: usize, (j, i): (usize, usize)) -> McError {
    McError::NanSdf {
        index: [i, j, k],
        position: coords.point(i, j, k),
    }
}

fn sweep(coords: &Coords, iso: f32, src: &mut impl PlaneSource) -> Result<TriMesh, McError> {
    let [nx, ny, nz] = coords.n;
    let words = nx.div_ceil(64);
    let edge_valid = (0..words)
        .map(|w| {
            let lo = w * 64;
            let valid = (nx - 1).saturating_sub(lo).min(64);
            if valid == 64 {
                !0
            } else {
                (1u64 << valid) - 1
            }
        })
        .collect();
    let lay = Layout {
        coords,
        nx,
        ny,
        words,
        iso,
        edge_valid,
    };
    let mut mesh = TriMesh::default();
    let mut p0 = Plane::new(ny, words);
    let mut p1 = Plane::new(ny, words);

    src.prepare(0)?;
    if let Some(at) = lay.classify(src.plane(0), &mut p0.inside) {
        return Err(nan_error(coords, 0, at));
    }
    lay.xy_masks(&mut p0);
    let n = assign_offsets(0, None, &mut p0)?;
    mesh.vertices = lay.xy_vertices(&p0, src.plane(0), 0);
    debug_assert_eq!(mesh.vertices.len(), n);

    for k in 0..nz - 1 {
        src.prepare(k + 1)?;
        let (v0, v1) = (src.plane(k), src.plane(k + 1));
        if let Some(at) = lay.classify(v1, &mut p1.inside) {
            return Err(nan_error(coords, k + 1, at));
        }
        lay.xy_masks(&mut p1);
        {
            let (a, b) = (&p0.inside, &p1.inside);
            p0.z.fill(words, |j, out| {
                for w in 0..words {
                    out[w] = a[j * words + w] ^ b[j * words + w];
                }
            });
        }
        let n = assign_offsets(mesh.vertices.len(), Some(&mut p0.z), &mut p1)?;
        let (zv, (xyv, faces)) = rayon::join(
            || lay.z_vertices(&p0, v0, v1, k),
            || rayon::join(|| lay.xy_vertices(&p1, v1, k + 1), || lay.faces(&p0, &p1)),
        );
        mesh.vertices.extend_from_slice(&zv);
        mesh.vertices.extend_from_slice(&xyv);
        debug_assert_eq!(mesh.vertices.len(), n);
        mesh.faces.extend_from_slice(&faces);
        std::mem::swap(&mut p0, &mut p1);
    }
    Ok(mesh)
}
