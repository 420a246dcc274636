//! The objects: procedural triangle meshes of the built-in catalog, and user meshes read from
//! `.ply` / `.obj` files, all placed in the rig frame (mm, `+z` up; see [`super::rig`]).
//!
//! Every procedural mesh is a union of closed, consistently oriented (outward, counter-clockwise
//! seen from outside) components built parametrically, so the mesh *is* the exact ground-truth
//! surface; components may interpenetrate (their hidden parts are never visible, so they never
//! enter the ground truth). Triangle counts stay below ~100k.

use super::desc::{Shape, UpAxis};
use super::SimError;
use std::collections::HashMap;
use std::f64::consts::PI;
use std::path::Path;

/// A triangle mesh in f64 (rig frame while building): `vertices` `[n][3]` mm, `faces` `[m][3]`
/// counter-clockwise seen from outside.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Mesh {
    /// Vertex positions.
    pub vertices: Vec<[f64; 3]>,
    /// Triangles as indices into `vertices`.
    pub faces: Vec<[u32; 3]>,
}

type V3 = [f64; 3];

fn sub(a: V3, b: V3) -> V3 {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}
fn add(a: V3, b: V3) -> V3 {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}
fn scale(a: V3, s: f64) -> V3 {
    [a[0] * s, a[1] * s, a[2] * s]
}
fn cross(a: V3, b: V3) -> V3 {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}
fn dot(a: V3, b: V3) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}
fn norm(a: V3) -> f64 {
    dot(a, a).sqrt()
}
fn normalize(a: V3) -> V3 {
    scale(a, 1.0 / norm(a))
}

/// Rotation about the x axis by `deg` degrees (right-handed: `+z` turns towards `−y`).
fn rot_x(p: V3, deg: f64) -> V3 {
    let (s, c) = deg.to_radians().sin_cos();
    [p[0], c * p[1] - s * p[2], s * p[1] + c * p[2]]
}
/// Rotation about the z axis by `deg` degrees.
fn rot_z(p: V3, deg: f64) -> V3 {
    let (s, c) = deg.to_radians().sin_cos();
    [c * p[0] - s * p[1], s * p[0] + c * p[1], p[2]]
}

impl Mesh {
    /// Six times the signed volume enclosed (positive for outward-oriented closed meshes).
    pub fn signed_volume6(&self) -> f64 {
        self.faces
            .iter()
            .map(|f| {
                let [a, b, c] = f.map(|i| self.vertices[i as usize]);
                dot(a, cross(b, c))
            })
            .sum()
    }

    /// The total area of the faces (the mesh's unit squared).
    pub fn area(&self) -> f64 {
        self.faces
            .iter()
            .map(|f| {
                let [a, b, c] = f.map(|i| self.vertices[i as usize]);
                0.5 * norm(cross(sub(b, a), sub(c, a)))
            })
            .sum()
    }

    /// The vertex farthest from the per-axis median of the vertices, with its distance to it:
    /// the likeliest stray vertex when one stretches the bounding box (a median ignores it, the
    /// box's centre does not). `None` without vertices.
    pub fn farthest_from_median(&self) -> Option<(usize, f64)> {
        let n = self.vertices.len();
        if n == 0 {
            return None;
        }
        let median: V3 = std::array::from_fn(|k| {
            let mut axis: Vec<f64> = self.vertices.iter().map(|v| v[k]).collect();
            axis.sort_by(f64::total_cmp);
            axis[n / 2]
        });
        (0..n)
            .map(|i| (i, norm(sub(self.vertices[i], median))))
            .reduce(|best, x| if x.1 > best.1 { x } else { best })
    }

    /// Appends `other`, first flipping it if it is oriented inwards (each component is closed).
    fn append_component(&mut self, other: Mesh) {
        let other = other.outward();
        let base = self.vertices.len() as u32;
        self.vertices.extend(other.vertices);
        self.faces
            .extend(other.faces.iter().map(|f| f.map(|i| i + base)));
    }

    /// Flips every face when the mesh encloses a negative volume (closed, one orientation).
    fn outward(mut self) -> Self {
        if self.signed_volume6() < 0.0 {
            for f in &mut self.faces {
                f.swap(1, 2);
            }
        }
        self
    }

    fn map(mut self, f: impl Fn(V3) -> V3) -> Self {
        for v in &mut self.vertices {
            *v = f(*v);
        }
        self
    }

    /// True when every directed edge `(a, b)` occurs exactly once and its reverse `(b, a)` exactly
    /// once: the mesh is closed (watertight by index) and consistently oriented. Together with a
    /// positive [`Mesh::signed_volume6`], normals point outwards, so a surface point whose
    /// triangle faces away from a camera cannot be seen by it.
    pub fn is_closed_oriented(&self) -> bool {
        // Directed edges as sorted `a << 32 | b` keys: a duplicate means an edge used twice in
        // the same direction; a missing reverse means a border or a flipped neighbour.
        let mut edges: Vec<u64> = Vec::with_capacity(self.faces.len() * 3);
        for f in &self.faces {
            for k in 0..3 {
                let (a, b) = (f[k], f[(k + 1) % 3]);
                if a == b {
                    return false;
                }
                edges.push((a as u64) << 32 | b as u64);
            }
        }
        edges.sort_unstable();
        if edges.windows(2).any(|w| w[0] == w[1]) {
            return false;
        }
        edges
            .iter()
            .all(|&e| edges.binary_search(&e.rotate_right(32)).is_ok())
    }

    /// The axis-aligned bounding box `(min, max)`.
    pub fn bounds(&self) -> (V3, V3) {
        let mut lo = [f64::INFINITY; 3];
        let mut hi = [f64::NEG_INFINITY; 3];
        for v in &self.vertices {
            for k in 0..3 {
                lo[k] = lo[k].min(v[k]);
                hi[k] = hi[k].max(v[k]);
            }
        }
        (lo, hi)
    }

    /// Moves the bounding-box centre to the origin and scales so the largest vertex distance
    /// from it is `radius`.
    pub fn centre_and_scale(self, radius: f64) -> Result<Self, String> {
        let (lo, hi) = self.bounds();
        let c = scale(add(lo, hi), 0.5);
        let r = self
            .vertices
            .iter()
            .map(|v| norm(sub(*v, c)))
            .fold(0.0, f64::max);
        if !(r.is_finite() && r > 0.0) {
            return Err(format!("has zero extent (bounding radius {r})"));
        }
        let s = radius / r;
        Ok(self.map(|v| scale(sub(v, c), s)))
    }
}

/// A unit icosphere: the icosahedron subdivided `level` times (`20·4^level` faces), outward.
pub fn icosphere(level: u32) -> Mesh {
    let t = (1.0 + 5f64.sqrt()) / 2.0;
    let mut vertices: Vec<V3> = [
        [-1.0, t, 0.0],
        [1.0, t, 0.0],
        [-1.0, -t, 0.0],
        [1.0, -t, 0.0],
        [0.0, -1.0, t],
        [0.0, 1.0, t],
        [0.0, -1.0, -t],
        [0.0, 1.0, -t],
        [t, 0.0, -1.0],
        [t, 0.0, 1.0],
        [-t, 0.0, -1.0],
        [-t, 0.0, 1.0],
    ]
    .iter()
    .map(|&v| normalize(v))
    .collect();
    let mut faces: Vec<[u32; 3]> = vec![
        [0, 11, 5],
        [0, 5, 1],
        [0, 1, 7],
        [0, 7, 10],
        [0, 10, 11],
        [1, 5, 9],
        [5, 11, 4],
        [11, 10, 2],
        [10, 7, 6],
        [7, 1, 8],
        [3, 9, 4],
        [3, 4, 2],
        [3, 2, 6],
        [3, 6, 8],
        [3, 8, 9],
        [4, 9, 5],
        [2, 4, 11],
        [6, 2, 10],
        [8, 6, 7],
        [9, 8, 1],
    ];
    for _ in 0..level {
        let mut mid: HashMap<(u32, u32), u32> = HashMap::new();
        let mut midpoint = |a: u32, b: u32, vertices: &mut Vec<V3>| -> u32 {
            let key = (a.min(b), a.max(b));
            *mid.entry(key).or_insert_with(|| {
                let m = normalize(scale(add(vertices[a as usize], vertices[b as usize]), 0.5));
                vertices.push(m);
                (vertices.len() - 1) as u32
            })
        };
        let mut next = Vec::with_capacity(faces.len() * 4);
        for [a, b, c] in faces {
            let ab = midpoint(a, b, &mut vertices);
            let bc = midpoint(b, c, &mut vertices);
            let ca = midpoint(c, a, &mut vertices);
            next.extend([[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]);
        }
        faces = next;
    }
    Mesh { vertices, faces }.outward()
}

/// A closed grid surface: `rows × cols` vertices from `f(i, j)`, wrapping in `j` (and in `i` when
/// `wrap_i`); without `wrap_i`, rows 0 and `rows−1` are closed by pole vertices `poles`.
fn revolve_grid(
    rows: usize,
    cols: usize,
    wrap_i: bool,
    poles: Option<(V3, V3)>,
    f: impl Fn(usize, usize) -> V3,
) -> Mesh {
    let mut m = Mesh::default();
    for i in 0..rows {
        for j in 0..cols {
            m.vertices.push(f(i, j));
        }
    }
    let id = |i: usize, j: usize| ((i % rows) * cols + (j % cols)) as u32;
    let row_pairs = if wrap_i { rows } else { rows - 1 };
    for i in 0..row_pairs {
        for j in 0..cols {
            let (a, b, c, d) = (id(i, j), id(i, j + 1), id(i + 1, j + 1), id(i + 1, j));
            m.faces.push([a, b, c]);
            m.faces.push([a, c, d]);
        }
    }
    if let Some((p0, p1)) = poles {
        let s = m.vertices.len() as u32;
        m.vertices.push(p0);
        m.vertices.push(p1);
        for j in 0..cols {
            m.faces.push([s, id(0, j + 1), id(0, j)]);
            m.faces.push([s + 1, id(rows - 1, j), id(rows - 1, j + 1)]);
        }
    }
    m
}

/// The smooth genus-0 default: an icosphere (81,920 faces) stretched and deformed by a few
/// low-frequency lobes; star-shaped about the origin, so it is a closed genus-0 surface.
fn blob() -> Mesh {
    icosphere(6).map(|d| {
        let [x, y, z] = d;
        let lobes = 0.11 * (2.0 * x + 1.0).sin() * (3.0 * y).cos()
            + 0.09 * (3.0 * z + 0.5).sin()
            + 0.12 * x * z
            + 0.06 * (4.0 * y + 2.0 * z).cos();
        let r = 80.0 * (1.0 + lobes);
        [x * r * 1.05, y * r * 0.9, z * r * 1.1]
    })
}

/// A torus (major radius 70, tube 22 mm) leaning 55° towards the cameras so they see through
/// its hole; 24,576 faces.
fn torus() -> Mesh {
    let (big, small) = (70.0, 22.0);
    let (nu, nv) = (192, 64);
    revolve_grid(nu, nv, true, None, |i, j| {
        let u = 2.0 * PI * i as f64 / nu as f64;
        let v = 2.0 * PI * j as f64 / nv as f64;
        let p = [
            (big + small * v.cos()) * u.cos(),
            (big + small * v.cos()) * u.sin(),
            small * v.sin(),
        ];
        rot_x(p, 55.0)
    })
    .outward()
}

/// A capped cylinder of radius `r` from `p0` to `p1`, `seg` facets around, rings every ~4 mm.
fn rod(p0: V3, p1: V3, r: f64, seg: usize) -> Mesh {
    let axis = sub(p1, p0);
    let len = norm(axis);
    let a = scale(axis, 1.0 / len);
    let helper = if a[2].abs() < 0.9 {
        [0.0, 0.0, 1.0]
    } else {
        [1.0, 0.0, 0.0]
    };
    let u = normalize(cross(a, helper));
    let w = cross(a, u);
    let rings = ((len / 4.0).ceil() as usize).max(1) + 1;
    revolve_grid(rings, seg, false, Some((p0, p1)), |i, j| {
        let t = len * i as f64 / (rings - 1) as f64;
        let ang = 2.0 * PI * j as f64 / seg as f64;
        add(
            add(p0, scale(a, t)),
            add(scale(u, r * ang.cos()), scale(w, r * ang.sin())),
        )
    })
}

/// An axis-aligned box `[lo, hi]` (8 vertices, 12 faces), then `f` applied to its vertices.
fn cuboid(lo: V3, hi: V3, f: impl Fn(V3) -> V3) -> Mesh {
    let vertices: Vec<V3> = (0..8)
        .map(|i| {
            f([
                if i & 1 == 0 { lo[0] } else { hi[0] },
                if i & 2 == 0 { lo[1] } else { hi[1] },
                if i & 4 == 0 { lo[2] } else { hi[2] },
            ])
        })
        .collect();
    // Quads (outward, counter-clockwise), split in two.
    let quads = [
        [0, 2, 3, 1], // z = lo
        [4, 5, 7, 6], // z = hi
        [0, 1, 5, 4], // y = lo
        [2, 6, 7, 3], // y = hi
        [0, 4, 6, 2], // x = lo
        [1, 3, 7, 5], // x = hi
    ];
    let faces = quads
        .iter()
        .flat_map(|q| [[q[0], q[1], q[2]], [q[0], q[2], q[3]]])
        .collect();
    Mesh { vertices, faces }
}

/// A thin-structure object: a round body with seven rods of radius 1.5 mm (diameter ≈ 1.5 % of
/// the object's 200 mm size) and a 2.5 mm fin.
fn thin() -> Mesh {
    let mut m = Mesh::default();
    m.append_component(icosphere(5).map(|d| [d[0] * 42.0, d[1] * 42.0, d[2] * 38.0 - 40.0]));
    let body = [0.0, 0.0, -40.0];
    let tips: [V3; 7] = [
        [0.0, -5.0, 95.0],
        [-45.0, -20.0, 75.0],
        [50.0, -25.0, 65.0],
        [-70.0, 10.0, 30.0],
        [25.0, 35.0, 85.0],
        [-20.0, -55.0, 55.0],
        [75.0, 5.0, 20.0],
    ];
    for tip in tips {
        let dir = normalize(sub(tip, body));
        // Start inside the body so the rod's cap is hidden.
        let start = add(body, scale(dir, 25.0));
        m.append_component(rod(start, tip, 1.5, 20));
    }
    m.append_component(cuboid([-82.0, -1.25, -70.0], [-30.0, 1.25, -20.0], |p| {
        rot_z(p, 20.0)
    }));
    m
}

/// Planar faces and sharp edges: a slab, a rotated cube, a pyramid and a prism.
fn blocks() -> Mesh {
    let mut m = Mesh::default();
    m.append_component(cuboid([-80.0, -60.0, 0.0], [80.0, 60.0, 25.0], |p| p));
    // The cube sinks 1 mm into the slab, so no coplanar faces touch.
    m.append_component(cuboid([-30.0, -30.0, -30.0], [30.0, 30.0, 30.0], |p| {
        add(rot_z(p, 25.0), [-35.0, 10.0, 54.0])
    }));
    let pyramid = Mesh {
        vertices: vec![
            [20.0, -10.0, 24.0],
            [70.0, -10.0, 24.0],
            [70.0, 40.0, 24.0],
            [20.0, 40.0, 24.0],
            [45.0, 15.0, 95.0],
        ],
        faces: vec![
            [0, 2, 1],
            [0, 3, 2],
            [0, 1, 4],
            [1, 2, 4],
            [2, 3, 4],
            [3, 0, 4],
        ],
    };
    m.append_component(pyramid);
    let prism = Mesh {
        vertices: vec![
            [-70.0, -55.0, 24.0],
            [-70.0, -25.0, 24.0],
            [-70.0, -40.0, 50.0],
            [10.0, -55.0, 24.0],
            [10.0, -25.0, 24.0],
            [10.0, -40.0, 50.0],
        ],
        faces: vec![
            [0, 2, 1],
            [3, 4, 5],
            [0, 1, 4],
            [0, 4, 3],
            [1, 2, 5],
            [1, 5, 4],
            [2, 0, 3],
            [2, 3, 5],
        ],
    };
    m.append_component(prism);
    m
}

/// A polyline `(r, z)` from `a` to `b` with points about `step` mm apart (`a` excluded).
fn segment(a: (f64, f64), b: (f64, f64), step: f64) -> Vec<(f64, f64)> {
    let len = ((b.0 - a.0).powi(2) + (b.1 - a.1).powi(2)).sqrt();
    let n = ((len / step).ceil() as usize).max(1);
    (1..=n)
        .map(|i| {
            let t = i as f64 / n as f64;
            (a.0 + (b.0 - a.0) * t, a.1 + (b.1 - a.1) * t)
        })
        .collect()
}

/// An arc of centre `c`, radius `r`, from angle `t0` to `t1` (radians; `t0` excluded).
fn arc(c: (f64, f64), r: f64, t0: f64, t1: f64, n: usize) -> Vec<(f64, f64)> {
    (1..=n)
        .map(|i| {
            let t = t0 + (t1 - t0) * i as f64 / n as f64;
            (c.0 + r * t.cos(), c.1 + r * t.sin())
        })
        .collect()
}

/// A deep cup: a surface of revolution (outer radius 60, height 130, wall 5, bottom 8 mm, with
/// rounded rim and fillets), 128 facets around; 122 mm of inner depth.
fn cup() -> Mesh {
    let (ro, h, t, tb) = (60.0, 130.0, 5.0, 8.0);
    let ri = ro - t;
    let mut prof: Vec<(f64, f64)> = Vec::new();
    prof.extend(segment((0.0, 0.0), (ro - 4.0, 0.0), 4.0));
    prof.extend(arc((ro - 4.0, 4.0), 4.0, -PI / 2.0, 0.0, 6));
    prof.extend(segment((ro, 4.0), (ro, h), 4.0));
    prof.extend(arc((ro - t / 2.0, h), t / 2.0, 0.0, PI, 10));
    prof.extend(segment((ri, h), (ri, tb + 6.0), 4.0));
    prof.extend(arc((ri - 6.0, tb + 6.0), 6.0, 0.0, -PI / 2.0, 8));
    prof.extend(segment((ri - 6.0, tb), (0.0, tb), 4.0));
    // The last point is on the axis: it becomes the inner pole.
    let inner_pole = prof.pop().expect("profile is not empty");
    let n = 128;
    let rows = prof.len();
    revolve_grid(
        rows,
        n,
        false,
        Some(([0.0, 0.0, 0.0], [0.0, 0.0, inner_pole.1])),
        |i, j| {
            let a = 2.0 * PI * j as f64 / n as f64;
            let (r, z) = prof[i];
            [r * a.cos(), r * a.sin(), z]
        },
    )
    .outward()
}

/// The relief height (mm) at plaque coordinates `(x, y)`: ripples, domes, engraved strokes and
/// a gentle undulation, faded to zero near the plaque's border.
pub fn relief_height(x: f64, y: f64) -> f64 {
    let smooth = |e0: f64, e1: f64, v: f64| {
        let t = ((v - e0) / (e1 - e0)).clamp(0.0, 1.0);
        t * t * (3.0 - 2.0 * t)
    };
    let mut h = 1.2 * (x / 23.0).sin() * (y / 19.0).cos();
    // Ripples around (−40, 15).
    let r = ((x + 40.0).powi(2) + (y - 15.0).powi(2)).sqrt();
    h += 0.6 * (2.0 * PI * r / 6.0).cos() * (1.0 - smooth(25.0, 35.0, r));
    // Domes on a 16 mm grid, right half.
    if x > 5.0 {
        let gx = (x - 5.0).rem_euclid(16.0) - 8.0;
        let gy = (y + 200.0).rem_euclid(16.0) - 8.0;
        let d2 = (gx * gx + gy * gy) / 25.0;
        if d2 < 1.0 {
            h += 2.2 * (1.0 - d2).powi(2);
        }
    }
    // Engraved zig-zag strokes in the lower left: depth 1.2 mm, half-width 1.5 mm.
    let strokes: [((f64, f64), (f64, f64)); 4] = [
        ((-70.0, -50.0), (-55.0, -20.0)),
        ((-55.0, -20.0), (-40.0, -50.0)),
        ((-40.0, -50.0), (-25.0, -20.0)),
        ((-25.0, -20.0), (-10.0, -50.0)),
    ];
    let mut groove: f64 = 0.0;
    for (a, b) in strokes {
        let (dx, dy) = (b.0 - a.0, b.1 - a.1);
        let t = (((x - a.0) * dx + (y - a.1) * dy) / (dx * dx + dy * dy)).clamp(0.0, 1.0);
        let d = ((x - a.0 - t * dx).powi(2) + (y - a.1 - t * dy).powi(2)).sqrt();
        if d < 1.5 {
            groove = groove.max((PI * d / 3.0).cos().powi(2));
        }
    }
    h -= 1.2 * groove;
    let edge = (85.0 - x.abs()).min(65.0 - y.abs());
    h * smooth(2.0, 10.0, edge)
}

/// A 170 × 130 × 16 mm plaque whose top carries [`relief_height`] on a 0.71 mm grid, leaning
/// 50° back so its face looks at the rig; 88k faces.
fn relief() -> Mesh {
    let (hx, hy, th) = (85.0, 65.0, 16.0);
    let (nx, ny) = (241usize, 185usize);
    let mut m = Mesh::default();
    let gx = |i: usize| -hx + 2.0 * hx * i as f64 / (nx - 1) as f64;
    let gy = |j: usize| -hy + 2.0 * hy * j as f64 / (ny - 1) as f64;
    for j in 0..ny {
        for i in 0..nx {
            let (x, y) = (gx(i), gy(j));
            m.vertices.push([x, y, th + relief_height(x, y)]);
        }
    }
    let top = |i: usize, j: usize| (j * nx + i) as u32;
    for j in 0..ny - 1 {
        for i in 0..nx - 1 {
            let (a, b, c, d) = (top(i, j), top(i + 1, j), top(i + 1, j + 1), top(i, j + 1));
            m.faces.push([a, b, c]);
            m.faces.push([a, c, d]);
        }
    }
    // The top's border loop, counter-clockwise seen from above.
    let mut border: Vec<(usize, usize)> = Vec::new();
    border.extend((0..nx - 1).map(|i| (i, 0)));
    border.extend((0..ny - 1).map(|j| (nx - 1, j)));
    border.extend((1..nx).rev().map(|i| (i, ny - 1)));
    border.extend((1..ny).rev().map(|j| (0, j)));
    let base = m.vertices.len() as u32;
    for &(i, j) in &border {
        m.vertices.push([gx(i), gy(j), 0.0]);
    }
    let centre = m.vertices.len() as u32;
    m.vertices.push([0.0, 0.0, 0.0]);
    let n = border.len();
    for k in 0..n {
        let k1 = (k + 1) % n;
        let (t0, t1) = (
            top(border[k].0, border[k].1),
            top(border[k1].0, border[k1].1),
        );
        let (b0, b1) = (base + k as u32, base + k1 as u32);
        // Walls face outwards; the bottom faces down.
        m.faces.push([b0, b1, t1]);
        m.faces.push([b0, t1, t0]);
        m.faces.push([centre, b1, b0]);
    }
    m.outward().map(|p| rot_x(p, 50.0))
}

/// The zero level set of `f` (negative inside, mm) over the box `[lo, hi]` by marching cubes
/// (`crate::mesh`) with cells of about `cell` mm. Grid values closer to 0 than 5 % of a cell are
/// pushed to ±5 % (sign kept), so no mesh vertex lands within 5 % of a cell of a grid point and no
/// triangle degenerates; the surface moves by at most that much, and the mesh *is* the ground
/// truth, so nothing downstream sees the difference. The box must enclose the surface.
fn implicit(f: impl Fn(V3) -> f64 + Sync, lo: V3, hi: V3, cell: f64) -> Mesh {
    use crate::mesh::{marching_cubes_values, GridSpec};
    use rayon::prelude::*;
    let res: [usize; 3] = std::array::from_fn(|a| ((hi[a] - lo[a]) / cell).ceil() as usize + 1);
    let h: [f64; 3] = std::array::from_fn(|a| (hi[a] - lo[a]) / (res[a] - 1) as f64);
    let eps = 0.05 * cell;
    let values: Vec<f32> = (0..res[0] * res[1] * res[2])
        .into_par_iter()
        .map(|n| {
            let (i, j, k) = (n % res[0], (n / res[0]) % res[1], n / (res[0] * res[1]));
            let p = [
                lo[0] + i as f64 * h[0],
                lo[1] + j as f64 * h[1],
                lo[2] + k as f64 * h[2],
            ];
            let v = f(p);
            (if v.abs() < eps { eps.copysign(v) } else { v }) as f32
        })
        .collect();
    let grid = GridSpec {
        min: lo.map(|x| x as f32),
        max: hi.map(|x| x as f32),
        res,
    };
    let m = marching_cubes_values(&values, &grid, 0.0).expect("finite grid on a valid box");
    // Vertices in f64 from the grid (f32 positions are exact to ~1e-5 mm here).
    Mesh {
        vertices: m.vertices.iter().map(|v| v.map(|x| x as f64)).collect(),
        faces: m.faces,
    }
    .outward()
}

/// Exact SDF of a torus in the `xy` plane around `c`: ring radius `big`, tube radius `small`.
fn torus_sdf(p: V3, c: V3, big: f64, small: f64) -> f64 {
    let q = sub(p, c);
    let ring = (q[0] * q[0] + q[1] * q[1]).sqrt() - big;
    (ring * ring + q[2] * q[2]).sqrt() - small
}

/// Polynomial smooth minimum (blend width `k` mm), as in Quílez's "smooth minimum" article.
fn smin(a: f64, b: f64, k: f64) -> f64 {
    let h = (0.5 + 0.5 * (b - a) / k).clamp(0.0, 1.0);
    b + (a - b) * h - k * h * (1.0 - h)
}

/// Exact SDF of the capsule (segment `a`–`b`, radius `r`).
fn capsule_sdf(p: V3, a: V3, b: V3, r: f64) -> f64 {
    let (pa, ba) = (sub(p, a), sub(b, a));
    let t = (dot(pa, ba) / dot(ba, ba)).clamp(0.0, 1.0);
    norm(sub(pa, scale(ba, t))) - r
}

/// Genus 2: two tori (ring 45, tube 15 mm) fused side by side into a figure of eight, leaning
/// 55° like [`torus`] so the cameras see through both holes (each 60 mm across).
fn double_torus() -> Mesh {
    let f = |p: V3| {
        let q = rot_x(p, -55.0);
        smin(
            torus_sdf(q, [-47.0, 0.0, 0.0], 45.0, 15.0),
            torus_sdf(q, [47.0, 0.0, 0.0], 45.0, 15.0),
            6.0,
        )
    };
    implicit(f, [-110.0, -65.0, -65.0], [110.0, 65.0, 65.0], 1.1)
}

/// A thin sheet: a 160 × 110 mm plate 3 mm thick (rounded rims), bent into a shallow wave
/// (amplitude 10 mm) and tilted 40° so the cameras see its upper face and its rim.
fn plate() -> Mesh {
    let (hx, hy, ht) = (80.0, 55.0, 1.5);
    let f = |p: V3| {
        let q = rot_x(p, -40.0);
        // Distance to the bent mid-surface, measured vertically (close to exact: slope ≤ 0.4).
        let z = q[2] - 10.0 * (q[0] / 35.0).sin();
        let d = [(q[0].abs() - hx).max(0.0), (q[1].abs() - hy).max(0.0)];
        let inside = (q[0].abs() - hx).max(q[1].abs() - hy).min(0.0);
        (d[0] * d[0] + d[1] * d[1] + z * z).sqrt() + inside - ht
    };
    implicit(f, [-90.0, -70.0, -70.0], [90.0, 70.0, 70.0], 0.95)
}

/// Thin rods: the twelve edges of a 130 mm cube frame, rods 4 mm across (3 % of the size),
/// turned so no edge is axis-aligned to the cameras. Genus 5 (`E − V + 1` of the cube graph).
fn rods() -> Mesh {
    let h = 65.0;
    let corners: Vec<V3> = (0..8)
        .map(|i| {
            let c = [
                if i & 1 == 0 { -h } else { h },
                if i & 2 == 0 { -h } else { h },
                if i & 4 == 0 { -h } else { h },
            ];
            rot_x(rot_z(c, 30.0), 25.0)
        })
        .collect();
    let edges: Vec<(usize, usize)> = (0..8)
        .flat_map(|i| [1, 2, 4].map(move |b| (i, i ^ b)))
        .filter(|(i, j)| i < j)
        .collect();
    let f = |p: V3| {
        edges
            .iter()
            .map(|&(i, j)| capsule_sdf(p, corners[i], corners[j], 2.0))
            .fold(f64::INFINITY, f64::min)
    };
    implicit(f, [-120.0; 3], [120.0; 3], 0.7)
}

/// The procedural mesh of a built-in shape, before centring and scaling.
pub fn procedural(shape: Shape) -> Mesh {
    match shape {
        Shape::Blob => blob(),
        Shape::Torus => torus(),
        Shape::Thin => thin(),
        Shape::Blocks => blocks(),
        Shape::Cup => cup(),
        Shape::Relief => relief(),
        Shape::DoubleTorus => double_torus(),
        Shape::Plate => plate(),
        Shape::Rods => rods(),
    }
}

/// Reads a `.ply` or `.obj` mesh and turns its `up` axis into the rig's `+z` (a proper rotation).
/// Errors: unreadable or malformed file, no faces, non-finite vertices, indices out of range.
pub fn load_mesh(path: &Path, up: UpAxis) -> Result<Mesh, SimError> {
    let bad = |problem: String| SimError::BadMesh {
        path: path.into(),
        problem,
    };
    let ext = path
        .extension()
        .map(|e| e.to_string_lossy().to_ascii_lowercase())
        .unwrap_or_default();
    let tri = match ext.as_str() {
        "ply" => {
            dtu_eval::ply::read_mesh(path).map_err(|e| bad(dtu_eval::error::error_chain(&e)))?
        }
        "obj" => {
            let bytes = std::fs::read(path).map_err(|source| SimError::Io {
                path: path.into(),
                source,
            })?;
            let text = String::from_utf8(bytes).map_err(|e| {
                bad(format!(
                    "is not a text OBJ file: byte {} is not UTF-8 text (a binary file, or another \
                     format named .obj?)",
                    e.utf8_error().valid_up_to()
                ))
            })?;
            parse_obj(&text).map_err(bad)?
        }
        _ => {
            return Err(bad(format!(
                "unsupported extension '{ext}' (expected .ply or .obj)"
            )))
        }
    };
    tri.validate().map_err(|e| bad(e.to_string()))?;
    if tri.faces.is_empty() {
        return Err(bad("has no faces (a point cloud cannot be rendered)".into()));
    }
    let rotate = |[x, y, z]: V3| -> V3 {
        match up {
            UpAxis::PosZ => [x, y, z],
            UpAxis::NegZ => [x, -y, -z],
            UpAxis::PosY => [x, -z, y],
            UpAxis::NegY => [x, z, -y],
            UpAxis::PosX => [-z, y, x],
            UpAxis::NegX => [z, y, -x],
        }
    };
    Ok(Mesh {
        vertices: tri
            .vertices
            .iter()
            .map(|v| rotate(v.map(|c| c as f64)))
            .collect(),
        faces: tri.faces,
    })
}

/// A minimal Wavefront OBJ reader: `v x y z` and `f a b c ...` lines (indices 1-based or
/// negative-relative, `a/b/c` forms accepted, polygons fan-split); other lines are ignored.
fn parse_obj(text: &str) -> Result<dtu_eval::TriMesh, String> {
    let mut mesh = dtu_eval::TriMesh::default();
    for (ln, line) in text.lines().enumerate() {
        let mut it = line.split_whitespace();
        match it.next() {
            Some("v") => {
                let mut xyz = [0f32; 3];
                for c in &mut xyz {
                    let tok = it.next().ok_or_else(|| {
                        format!("line {}: vertex has fewer than 3 coordinates", ln + 1)
                    })?;
                    *c = tok
                        .parse()
                        .map_err(|_| format!("line {}: '{tok}' is not a number", ln + 1))?;
                }
                mesh.vertices.push(xyz);
            }
            Some("f") => {
                let n = mesh.vertices.len() as i64;
                let idx = it
                    .map(|tok| {
                        let first = tok.split('/').next().unwrap_or("");
                        let i: i64 = first
                            .parse()
                            .map_err(|_| format!("line {}: bad face index '{tok}'", ln + 1))?;
                        let zero_based = if i < 0 { n + i } else { i - 1 };
                        if i == 0 || zero_based < 0 || zero_based >= n {
                            return Err(format!(
                                "line {}: face index {i} is out of range ({n} vertices so far)",
                                ln + 1
                            ));
                        }
                        Ok(zero_based as u32)
                    })
                    .collect::<Result<Vec<u32>, String>>()?;
                if idx.len() < 3 {
                    return Err(format!("line {}: face has fewer than 3 vertices", ln + 1));
                }
                for k in 1..idx.len() - 1 {
                    mesh.faces.push([idx[0], idx[k], idx[k + 1]]);
                }
            }
            _ => {}
        }
    }
    Ok(mesh)
}

#[cfg(test)]
mod tests;
