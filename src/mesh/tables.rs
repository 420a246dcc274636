//! Marching-cubes case tables, derived at start-up from one rule instead of typed in.
//!
//! Numbering used throughout `mesh`:
//! - corner `c = dx | dy << 1 | dz << 2` of a cell whose lowest corner is grid point `(i, j, k)`
//!   sits at `(i + dx, j + dy, k + dz)`;
//! - a cell's case has bit `c` set when corner `c` is **inside** (`value <= iso`, see
//!   [`super::inside`]);
//! - edge `e = 4·axis + (u | w << 1)` runs along `axis` (0 = x, 1 = y, 2 = z) from the corner with
//!   coordinate 0 on that axis to the one with 1; `(u, w)` are the offsets on the two other axes in
//!   increasing axis order (x-edges: `(dy, dz)`, y-edges: `(dx, dz)`, z-edges: `(dx, dy)`).
//!
//! The rule (the classic Lorensen–Cline / Bourke table follows it, and PyMCubes and
//! `isosurface` 0.1.0-alpha.0 use that table; checked case by case in the tests):
//! 1. one vertex on every cell edge whose two corners are on different sides;
//! 2. on each cell face the contour joins those vertices by segments; on an *ambiguous* face (two
//!    inside corners on one diagonal, two outside on the other) every inside corner is cut off by
//!    its own segment, i.e. inside corners are never joined across a face. The choice depends on the
//!    face alone, so the two cells sharing a face agree and the surface is closed;
//! 3. the segments of a cell form closed loops, each triangulated as a fan (`n` vertices give
//!    `n − 2` triangles). The apex is picked so that no diagonal joins two vertices on one cell
//!    face, which keeps every mesh edge shared by exactly two triangles;
//! 4. loops are oriented counter-clockwise seen from outside (the side where values exceed `iso`),
//!    so triangle normals point outward for an SDF that is negative inside.
//!
//! Scikit-image's `method="lorensen"` applies the opposite choice on ambiguous faces (it joins the
//! corners with values `<= level`), and its default Lewiner method resolves them with the
//! asymptotic decider; both agree with this table wherever no face is ambiguous.

use std::sync::LazyLock;

/// The two corners of each edge: `[lower, upper]` along the edge's axis.
pub const EDGE_CORNERS: [[u8; 2]; 12] = edge_corners();

/// Axis (0 = x, 1 = y, 2 = z) of each edge.
pub const fn edge_axis(e: usize) -> usize {
    e / 4
}

/// Offset `(dx, dy, dz)` of an edge's lower corner relative to the cell's lowest corner.
pub const fn edge_origin(e: usize) -> [usize; 3] {
    let c = EDGE_CORNERS[e][0] as usize;
    [c & 1, (c >> 1) & 1, (c >> 2) & 1]
}

const fn edge_corners() -> [[u8; 2]; 12] {
    let mut out = [[0u8; 2]; 12];
    let mut e = 0;
    while e < 12 {
        let axis = e / 4;
        let u = e & 1;
        let w = (e >> 1) & 1;
        // The two other axes in increasing order carry u and w.
        let (a1, a2) = match axis {
            0 => (1, 2),
            1 => (0, 2),
            _ => (0, 1),
        };
        let base = (u << a1) | (w << a2);
        out[e] = [base as u8, (base | (1 << axis)) as u8];
        e += 1;
    }
    out
}

/// Triangles of one case: `count` triangles, each three edge ids, counter-clockwise from outside.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct CaseTriangles {
    /// Number of valid entries in `tris` (0..=5 for the classic rule; 6 slots for safety).
    pub count: u8,
    /// Edge ids of each triangle.
    pub tris: [[u8; 3]; 6],
}

/// The full table: per case the triangles and the 12-bit mask of edges that carry a vertex.
pub struct Tables {
    /// `cases[case]`: triangles of that case.
    pub cases: [CaseTriangles; 256],
    /// `edge_mask[case]`: bit `e` set when edge `e` has one inside and one outside corner.
    pub edge_mask: [u16; 256],
}

/// The tables, built on first use (a few microseconds).
pub static TABLES: LazyLock<Tables> = LazyLock::new(build_tables);

fn corner_pos2(c: usize) -> [i32; 3] {
    // Doubled integer coordinates: a corner is at 0 or 2 on each axis.
    [
        2 * (c & 1) as i32,
        2 * ((c >> 1) & 1) as i32,
        2 * ((c >> 2) & 1) as i32,
    ]
}

fn edge_mid2(e: usize) -> [i32; 3] {
    let [a, b] = EDGE_CORNERS[e];
    let pa = corner_pos2(a as usize);
    let pb = corner_pos2(b as usize);
    [
        (pa[0] + pb[0]) / 2,
        (pa[1] + pb[1]) / 2,
        (pa[2] + pb[2]) / 2,
    ]
}

fn sub(a: [i32; 3], b: [i32; 3]) -> [i32; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

fn cross(a: [i32; 3], b: [i32; 3]) -> [i32; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

fn dot(a: [i32; 3], b: [i32; 3]) -> i32 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// The edge joining corners `a` and `b` (which must differ in exactly one bit).
fn edge_between(a: usize, b: usize) -> usize {
    (0..12)
        .find(|&e| {
            let [p, q] = EDGE_CORNERS[e];
            (p as usize, q as usize) == (a, b) || (p as usize, q as usize) == (b, a)
        })
        .expect("corners of a face edge differ in one bit")
}

/// The six faces as `(axis, side, corners in cyclic order)`.
pub fn faces() -> [(usize, usize, [usize; 4]); 6] {
    let mut out = [(0, 0, [0; 4]); 6];
    for axis in 0..3 {
        let (a1, a2) = match axis {
            0 => (1, 2),
            1 => (0, 2),
            _ => (0, 1),
        };
        for side in 0..2 {
            let base = side << axis;
            let cyc = [
                base,
                base | (1 << a1),
                base | (1 << a1) | (1 << a2),
                base | (1 << a2),
            ];
            out[axis * 2 + side] = (axis, side, cyc);
        }
    }
    out
}

/// Whether edges `e` and `f` lie on a common cell face.
pub fn share_face(e: usize, f: usize) -> bool {
    faces().iter().any(|(_, _, cyc)| {
        let on = |x: usize| {
            let [a, b] = EDGE_CORNERS[x];
            cyc.contains(&(a as usize)) && cyc.contains(&(b as usize))
        };
        on(e) && on(f)
    })
}

/// Oriented contour segments `(from_edge, to_edge)` of `case` on every face (rule 2 and 4).
pub fn face_segments(case: usize) -> Vec<(usize, usize)> {
    let inside = |c: usize| (case >> c) & 1 == 1;
    let mut segs = Vec::new();
    for (axis, side, cyc) in faces() {
        let mut normal = [0i32; 3];
        normal[axis] = if side == 0 { -1 } else { 1 };
        let face_edge = |m: usize| edge_between(cyc[m % 4], cyc[(m + 1) % 4]);
        let crossing: Vec<usize> = (0..4)
            .filter(|&m| inside(cyc[m]) != inside(cyc[(m + 1) % 4]))
            .collect();
        // Each entry: two edges, the sum of the inside corners (doubled coordinates) that the
        // segment bounds on this face, and their count.
        let mut raw: Vec<(usize, usize, [i32; 3], i32)> = Vec::new();
        match crossing.len() {
            0 => {}
            2 => {
                let mut sum = [0i32; 3];
                let mut n = 0;
                for &c in cyc.iter().filter(|&&c| inside(c)) {
                    let q = corner_pos2(c);
                    for k in 0..3 {
                        sum[k] += q[k];
                    }
                    n += 1;
                }
                raw.push((face_edge(crossing[0]), face_edge(crossing[1]), sum, n));
            }
            4 => {
                for (m, &c) in cyc.iter().enumerate() {
                    if inside(c) {
                        raw.push((face_edge(m + 3), face_edge(m), corner_pos2(c), 1));
                    }
                }
            }
            n => unreachable!("a square face has an even number of sign changes, got {n}"),
        }
        for (a, b, sum, n) in raw {
            // w = 2·n·(centroid of the inside corners − segment midpoint), in doubled coordinates.
            let ma = edge_mid2(a);
            let mb = edge_mid2(b);
            let d = sub(mb, ma);
            let w = sub(
                [2 * sum[0], 2 * sum[1], 2 * sum[2]],
                [
                    n * (ma[0] + mb[0]),
                    n * (ma[1] + mb[1]),
                    n * (ma[2] + mb[2]),
                ],
            );
            let s = dot(cross(d, w), normal);
            assert!(s != 0, "degenerate segment orientation in case {case}");
            // Seen from outside the cell the inside part lies to the right of the segment.
            segs.push(if s < 0 { (a, b) } else { (b, a) });
        }
    }
    segs
}

fn case_triangles(case: usize) -> CaseTriangles {
    let segs = face_segments(case);
    let mut next = [usize::MAX; 12];
    for &(a, b) in &segs {
        assert!(
            next[a] == usize::MAX,
            "edge {a} starts two segments in case {case}"
        );
        next[a] = b;
    }
    let mut visited = [false; 12];
    let mut out = CaseTriangles::default();
    for start in 0..12 {
        if next[start] == usize::MAX || visited[start] {
            continue;
        }
        let mut lp = Vec::new();
        let mut e = start;
        while !visited[e] {
            visited[e] = true;
            lp.push(e);
            e = next[e];
        }
        assert!(e == start, "open contour in case {case}");
        let n = lp.len();
        // Pick the first apex whose fan has no diagonal between two vertices on one face.
        let apex = (0..n)
            .find(|&r| (2..n - 1).all(|i| !share_face(lp[r], lp[(r + i) % n])))
            .unwrap_or(0);
        for i in 1..n - 1 {
            let t = [lp[apex], lp[(apex + i) % n], lp[(apex + i + 1) % n]];
            out.tris[out.count as usize] = [t[0] as u8, t[1] as u8, t[2] as u8];
            out.count += 1;
        }
    }
    out
}

fn build_tables() -> Tables {
    let mut cases = [CaseTriangles::default(); 256];
    let mut edge_mask = [0u16; 256];
    for case in 0..256 {
        cases[case] = case_triangles(case);
        for (e, [a, b]) in EDGE_CORNERS.iter().enumerate() {
            if ((case >> a) ^ (case >> b)) & 1 == 1 {
                edge_mask[case] |= 1 << e;
            }
        }
    }
    Tables { cases, edge_mask }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn edges_join_corners_one_step_apart_along_their_axis() {
        for (e, &[a, b]) in EDGE_CORNERS.iter().enumerate() {
            assert_eq!(b ^ a, 1 << edge_axis(e), "edge {e}");
            assert!(a < b);
            let o = edge_origin(e);
            assert_eq!(o[0] | o[1] << 1 | o[2] << 2, a as usize);
        }
    }

    #[test]
    fn every_crossing_edge_is_used_and_no_other() {
        for case in 0..256 {
            let t = &TABLES.cases[case];
            let mut used = 0u16;
            for tri in &t.tris[..t.count as usize] {
                for &e in tri {
                    used |= 1 << e;
                }
                assert!(tri[0] != tri[1] && tri[1] != tri[2] && tri[0] != tri[2]);
            }
            assert_eq!(used, TABLES.edge_mask[case], "case {case:#010b}");
        }
        assert_eq!(TABLES.cases[0].count, 0);
        assert_eq!(TABLES.cases[255].count, 0);
    }

    #[test]
    fn total_triangle_count_matches_the_classic_table() {
        // 820 triangles over the 256 cases: the sum PyMCubes gives on the 256 one-cell grids
        // (measured while writing this module); `every_case_matches_the_oracle` in
        // tests/mesh_mcubes.rs compares each case with isosurface 0.1.0-alpha.0.
        let total: usize = TABLES.cases.iter().map(|c| c.count as usize).sum();
        assert_eq!(total, 820);
    }

    #[test]
    fn inside_corners_are_never_joined_across_an_ambiguous_face() {
        let mut ambiguous = 0;
        for case in 0..256usize {
            let segs = face_segments(case);
            for (_, _, cyc) in faces() {
                let ins: Vec<bool> = cyc.iter().map(|&c| (case >> c) & 1 == 1).collect();
                if ins == [true, false, true, false] || ins == [false, true, false, true] {
                    ambiguous += 1;
                    for m in 0..4 {
                        if ins[m] {
                            let e1 = edge_between(cyc[(m + 3) % 4], cyc[m]);
                            let e2 = edge_between(cyc[m], cyc[(m + 1) % 4]);
                            assert!(
                                segs.contains(&(e1, e2)) || segs.contains(&(e2, e1)),
                                "case {case}: inside corner {} not cut off",
                                cyc[m]
                            );
                        }
                    }
                }
            }
        }
        // 6 faces × 2 diagonal patterns × 16 states of the other four corners.
        assert_eq!(ambiguous, 192);
    }

    #[test]
    fn no_fan_diagonal_lies_on_a_face() {
        for case in 0..256 {
            let t = &TABLES.cases[case];
            let segs = face_segments(case);
            let mut edges: std::collections::HashMap<(u8, u8), i32> = Default::default();
            for tri in &t.tris[..t.count as usize] {
                for k in 0..3 {
                    let (a, b) = (tri[k], tri[(k + 1) % 3]);
                    *edges.entry((a.min(b), a.max(b))).or_default() += 1;
                }
            }
            for (&(a, b), &n) in &edges {
                let is_seg = segs
                    .iter()
                    .any(|&(p, q)| (p.min(q), p.max(q)) == (a as usize, b as usize));
                if is_seg {
                    assert_eq!(n, 1, "case {case}: boundary segment {a}-{b} used {n} times");
                } else {
                    assert_eq!(n, 2, "case {case}: diagonal {a}-{b} used {n} times");
                    assert!(
                        !share_face(a as usize, b as usize),
                        "case {case}: diagonal {a}-{b} lies on a face"
                    );
                }
            }
        }
    }

    /// With corner values −1 (inside) and +1 (outside), vertices sit at edge midpoints. Every
    /// triangle's normal must point from an inside corner towards the outside: checked against the
    /// gradient of the trilinear interpolant at the triangle's centroid.
    #[test]
    fn triangles_face_outward() {
        for case in 1..255usize {
            let val = |c: usize| if (case >> c) & 1 == 1 { -1.0f64 } else { 1.0 };
            let t = &TABLES.cases[case];
            for tri in &t.tris[..t.count as usize] {
                let p: Vec<[f64; 3]> = tri
                    .iter()
                    .map(|&e| {
                        let m = edge_mid2(e as usize);
                        [m[0] as f64 / 2.0, m[1] as f64 / 2.0, m[2] as f64 / 2.0]
                    })
                    .collect();
                let u = [p[1][0] - p[0][0], p[1][1] - p[0][1], p[1][2] - p[0][2]];
                let v = [p[2][0] - p[0][0], p[2][1] - p[0][1], p[2][2] - p[0][2]];
                let n = [
                    u[1] * v[2] - u[2] * v[1],
                    u[2] * v[0] - u[0] * v[2],
                    u[0] * v[1] - u[1] * v[0],
                ];
                let c = [
                    (p[0][0] + p[1][0] + p[2][0]) / 3.0,
                    (p[0][1] + p[1][1] + p[2][1]) / 3.0,
                    (p[0][2] + p[1][2] + p[2][2]) / 3.0,
                ];
                // Gradient of the trilinear interpolant of the corner values at c.
                let mut g = [0.0f64; 3];
                for corner in 0..8 {
                    let b = [corner & 1, (corner >> 1) & 1, (corner >> 2) & 1];
                    for axis in 0..3 {
                        let mut w = if b[axis] == 1 { 1.0 } else { -1.0 };
                        for other in 0..3 {
                            if other != axis {
                                w *= if b[other] == 1 {
                                    c[other]
                                } else {
                                    1.0 - c[other]
                                };
                            }
                        }
                        g[axis] += w * val(corner);
                    }
                }
                let d = n[0] * g[0] + n[1] * g[1] + n[2] * g[2];
                assert!(
                    d > 0.0,
                    "case {case:#010b}: triangle {tri:?} faces inward ({d})"
                );
            }
        }
    }
}
