//! The slow, obviously correct marching cubes that the fast sweep is tested against.
//!
//! Single-threaded and direct: every grid edge is checked, crossing edges get their vertex in a
//! `BTreeMap` keyed by the fast path's vertex order, then every cell is visited in `[k][j][i]`
//! order, its case read from its eight values and its triangles looked up by edge key. It shares
//! only the case table ([`super::tables`], tested on its own and against `isosurface`) and the
//! crossing formula with the fast path, so equal output means the sweep's bit tricks, ranks,
//! slabs and parallel chunks are right.

use super::mcubes::{crossing, Coords};
use super::tables::{edge_axis, edge_origin, TABLES};
use super::{inside, GridSpec, McError, TriMesh};
use std::collections::{BTreeMap, HashMap};

/// Sort key of a vertex in the fast path's order: `(k, group, j, sub, i)` with x-edges
/// `(k, 0, j, 0, i)`, y-edges `(k, 0, j, 1, i)`, z-edges `(k, 1, j, 0, i)`.
type Key = (usize, u8, usize, u8, usize);

fn key(axis: usize, i: usize, j: usize, k: usize) -> Key {
    match axis {
        0 => (k, 0, j, 0, i),
        1 => (k, 0, j, 1, i),
        _ => (k, 1, j, 0, i),
    }
}

/// Marching cubes on `values` (`[k][j][i]`, x fastest) over `grid`, the slow way.
pub fn marching_cubes_reference(
    values: &[f32],
    grid: &GridSpec,
    iso: f32,
) -> Result<TriMesh, McError> {
    grid.validate()?;
    if !iso.is_finite() {
        return Err(McError::Iso { iso });
    }
    let [nx, ny, nz] = grid.res;
    if values.len() != nx * ny * nz {
        return Err(McError::ValuesLength {
            got: values.len(),
            expected: nx * ny * nz,
            res: grid.res,
        });
    }
    let coords = Coords::new(grid);
    let at = |i: usize, j: usize, k: usize| values[(k * ny + j) * nx + i];
    if let Some(n) = values.iter().position(|v| v.is_nan()) {
        let (i, j, k) = (n % nx, (n / nx) % ny, n / (nx * ny));
        return Err(McError::NanSdf {
            index: [i, j, k],
            position: coords.point(i, j, k),
        });
    }

    let mut verts: BTreeMap<Key, [f32; 3]> = BTreeMap::new();
    for k in 0..nz {
        for j in 0..ny {
            for i in 0..nx {
                let p = [i, j, k];
                for axis in 0..3 {
                    let mut q = p;
                    q[axis] += 1;
                    if q[axis] >= grid.res[axis] {
                        continue;
                    }
                    let (va, vb) = (at(i, j, k), at(q[0], q[1], q[2]));
                    if inside(va, iso) == inside(vb, iso) {
                        continue;
                    }
                    let mut pos = coords.point(i, j, k);
                    let c = &coords.c[axis];
                    pos[axis] = crossing(c[p[axis]], c[p[axis] + 1], va, vb, iso);
                    verts.insert(key(axis, i, j, k), pos);
                }
            }
        }
    }
    let index: HashMap<Key, u32> = verts
        .keys()
        .enumerate()
        .map(|(n, k)| (*k, n as u32))
        .collect();

    let mut faces = Vec::new();
    for k in 0..nz - 1 {
        for j in 0..ny - 1 {
            for i in 0..nx - 1 {
                let mut case = 0;
                for c in 0..8 {
                    let (dx, dy, dz) = (c & 1, (c >> 1) & 1, (c >> 2) & 1);
                    if inside(at(i + dx, j + dy, k + dz), iso) {
                        case |= 1 << c;
                    }
                }
                let t = &TABLES.cases[case];
                for tri in &t.tris[..t.count as usize] {
                    faces.push(tri.map(|e| {
                        let [dx, dy, dz] = edge_origin(e as usize);
                        index[&key(edge_axis(e as usize), i + dx, j + dy, k + dz)]
                    }));
                }
            }
        }
    }
    Ok(TriMesh {
        vertices: verts.into_values().collect(),
        faces,
    })
}
