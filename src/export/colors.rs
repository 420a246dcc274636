//! The colour network queried at surface points, as the held-out renders query it.
//!
//! Per point `x` (normalised space) with `active` hash-grid levels:
//! 1. the SDF network at `x` (all outputs: the SDF and the features, the colour network's first
//!    input) and at the six taps `x ± ε·e_a` (clamped to the box, `ε` = one cell of the finest
//!    active level), the renderer's central differences: `g_a = (f(x+ε e_a) − f(x−ε e_a))/(2ε)`,
//!    `n = g/|g|`;
//! 2. the colour network on `[features, SH₄(d), n, Emb(identity), p = 0, colour grid]` with a
//!    view direction `d` ([`ViewDirection`]): head-on (`d = −n`, a camera looking straight
//!    along the inward normal), or, by default, the training cameras' directions to the point
//!    weighted towards the most head-on.
//!
//! nerfstudio's `exporter/texture_utils.py` (and sdfstudio's copy) casts a short ray from just
//! outside the surface along `−n` and volume-renders it. With a converged NeuS field (`inv_s`
//! in the hundreds or more) the rendering weights concentrate on the surface crossing, so that
//! ray's colour is the colour network's at the surface point with `d = −n`: this module queries
//! that point directly, one network evaluation instead of a ray's worth. Head-on is the default
//! there; here it is an option, because on DTU-style rigs (a cap of cameras on one side) `−n`
//! is for much of the surface a direction no training ray came from, and the colour network's
//! answer there is an extrapolation. On `reconstruct blob --preset quick --seed 0`, rendered at
//! its three held-out cameras (`neus-aug export RUN --check`, PSNR against the truth): network
//! 34.41 dB, vertex colours head-on 32.41 dB, camera-weighted 34.68 dB, and the mesh coloured
//! along each pixel's own ray 34.68 dB (the check's bound); away from the silhouette head-on
//! loses 5–9 dB to the network, the camera-weighted colours nothing.
//!
//! A point whose gradient is not finite or vanishes (|g| < 1e-12) gets the caller's fallback
//! normal; a colour that is not finite gets mid-grey. Both are counted
//! ([`SurfaceShading::fallbacks`]), never passed on as NaN.

// Numeric kernels index several parallel arrays with one loop variable.
#![allow(clippy::needless_range_loop)]

use crate::field::mlp::MlpTape;
use crate::field::sh::{sh4, SH_DIM};
use crate::field::sigmoid;
use crate::render::model::{ModelError, NeusModel};
use crate::render::Schedule;
use dtu_eval::mesh::TriMesh;
use rayon::prelude::*;

/// Points per parallel job: its buffers (7 encodings per point) stay small.
const CHUNK: usize = 512;

/// The trained field's colour and normal query ([`SurfaceField::shade`]).
pub struct SurfaceField<'a> {
    model: &'a NeusModel,
    params: &'a [f32],
    /// Active hash-grid levels (the inference schedule's).
    active: usize,
    /// Scale of the SH degrees 1–3 (`RenderConfig::view_dependence` at the schedule's step).
    view_dependence: f32,
    /// Training camera centres (normalised space) for [`ViewDirection::Cameras`]; empty: head-on.
    cameras: Vec<[f32; 3]>,
}

/// The view direction the colour network is queried with at a surface point `x` with normal
/// `n` (config `export.view_direction`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ViewDirection {
    /// `d = −n`: a camera looking straight along the inward normal (nerfstudio's
    /// `texture_utils.py`, sdfstudio). Where no training camera looked from near the normal (the
    /// far and under sides of a DTU-style cap of cameras) the SH input is one the network never
    /// saw, and its colour is an extrapolation.
    HeadOn,
    /// `d = normalize(Σ_j w_j d_j)`, `d_j` the ray direction from training camera `j` to `x`,
    /// `w_j = max(0, −d_j·n)⁸`: the directions the training cameras saw `x` from, weighted
    /// towards the most head-on; `−n` where no camera faces the point. Smooth in `x` and `n`,
    /// and inside the directions the network was trained on.
    #[default]
    Cameras,
}

/// Colours and normals of a batch of points.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct SurfaceShading {
    /// `[n][3]` colours in `[0, 1]` (sRGB as the training images are).
    pub rgb: Vec<[f32; 3]>,
    /// `[n][3]` unit normals (outward, `∇f/|∇f|`), normalised space (the same directions as
    /// the world frame: the normalisation is a similarity without rotation).
    pub normal: Vec<[f32; 3]>,
    /// Points whose normal or colour was not finite and took the fallback.
    pub fallbacks: usize,
}

/// Reusable buffers of one job.
#[derive(Default)]
struct Scratch {
    xs: Vec<[f32; 3]>,
    enc: Vec<f32>,
    tap_sdf: Vec<f32>,
    feat: Vec<f32>,
    color_in: Vec<f32>,
    logits: Vec<f32>,
    sdf_tape: MlpTape<f32>,
    color_tape: MlpTape<f32>,
}

impl<'a> SurfaceField<'a> {
    /// The query on `params` (the model's layout) under `sched` (normally
    /// [`crate::render::ModelConfig::inference_schedule`] at the run's last step).
    pub fn new(
        model: &'a NeusModel,
        params: &'a [f32],
        sched: Schedule,
    ) -> Result<Self, ModelError> {
        if params.len() != model.n_params() {
            return Err(ModelError::ParamLen {
                expected: model.n_params(),
                got: params.len(),
            });
        }
        Ok(Self {
            model,
            params,
            active: sched.active_levels,
            view_dependence: sched.view_dependence,
            cameras: Vec::new(),
        })
    }

    /// The query with view direction `how`; `cameras` are the training cameras' centres
    /// (normalised space), used by [`ViewDirection::Cameras`] (none: head-on everywhere).
    pub fn with_view(mut self, how: ViewDirection, cameras: &[[f32; 3]]) -> Self {
        self.cameras = match how {
            ViewDirection::HeadOn => Vec::new(),
            ViewDirection::Cameras => cameras.to_vec(),
        };
        self
    }

    /// The view direction at `x` with unit normal `n` (see [`ViewDirection`]).
    fn view_dir(&self, x: [f32; 3], n: [f32; 3]) -> [f32; 3] {
        let mut acc = [0f64; 3];
        for c in &self.cameras {
            let d = [0, 1, 2].map(|a| (x[a] - c[a]) as f64);
            let l = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
            if l.is_nan() || l <= 0.0 {
                continue;
            }
            let cos = -(d[0] * n[0] as f64 + d[1] * n[1] as f64 + d[2] * n[2] as f64) / l;
            if cos > 0.0 {
                let w = cos.powi(8) / l;
                for a in 0..3 {
                    acc[a] += w * d[a];
                }
            }
        }
        let l = (acc[0] * acc[0] + acc[1] * acc[1] + acc[2] * acc[2]).sqrt();
        if l > 0.0 && l.is_finite() {
            acc.map(|v| (v / l) as f32)
        } else {
            [-n[0], -n[1], -n[2]]
        }
    }

    fn group(&self, name: &str) -> &'a [f32] {
        let g = self
            .model
            .layout
            .group(name)
            .unwrap_or_else(|| panic!("the layout has the group {name}"));
        &self.params[g.range()]
    }

    /// Colours and normals at `points` (`[n][3]`, normalised space). `fallback_normals`
    /// (`[n][3]` unit, or empty for `+z`) replace a normal that cannot be computed. Parallel over
    /// fixed chunks; the result does not depend on the thread count.
    pub fn shade(&self, points: &[[f32; 3]], fallback_normals: &[[f32; 3]]) -> SurfaceShading {
        self.shade_along(points, fallback_normals, &[])
    }

    /// [`shade`](Self::shade) with the view direction of each point given (`dirs`, `[n][3]`
    /// unit ray directions, camera → point), or chosen by the field's [`ViewDirection`] when
    /// `dirs` is empty.
    pub fn shade_along(
        &self,
        points: &[[f32; 3]],
        fallback_normals: &[[f32; 3]],
        dirs: &[[f32; 3]],
    ) -> SurfaceShading {
        assert!(
            dirs.is_empty() || dirs.len() == points.len(),
            "one direction per point"
        );
        assert!(
            fallback_normals.is_empty() || fallback_normals.len() == points.len(),
            "one fallback normal per point"
        );
        let n = points.len();
        let mut rgb = vec![[0f32; 3]; n];
        let mut normal = vec![[0f32; 3]; n];
        let fallbacks: usize = rgb
            .par_chunks_mut(CHUNK)
            .zip(normal.par_chunks_mut(CHUNK))
            .enumerate()
            .map_init(Scratch::default, |sc, (c, (rgb, nrm))| {
                let r0 = c * CHUNK;
                let pts = &points[r0..r0 + rgb.len()];
                let part = |v: &'_ [[f32; 3]]| -> Vec<[f32; 3]> {
                    if v.is_empty() {
                        Vec::new()
                    } else {
                        v[r0..r0 + pts.len()].to_vec()
                    }
                };
                self.shade_chunk(pts, &part(fallback_normals), &part(dirs), rgb, nrm, sc)
            })
            .sum();
        SurfaceShading {
            rgb,
            normal,
            fallbacks,
        }
    }

    /// One chunk of [`shade`](Self::shade); returns its fallback count.
    fn shade_chunk(
        &self,
        pts: &[[f32; 3]],
        fallback: &[[f32; 3]],
        dirs: &[[f32; 3]],
        rgb: &mut [[f32; 3]],
        nrm: &mut [[f32; 3]],
        sc: &mut Scratch,
    ) -> usize {
        let m = self.model;
        let n = pts.len();
        let r = m.config.render.radius;
        let eps = m.fd_eps(self.active) as f32;
        let d = m.grid.output_dim();
        let fdim = m.config.field.sdf.feature_dim;
        let wh = m.sdf_mlp.last_hidden_dim();
        let dc = m.config.field.color_input_dim();
        let (hash, sdf, color) = (
            self.group("hash_grid"),
            self.group("sdf_mlp"),
            self.group("color_mlp"),
        );
        // Centres first, then six taps per centre: (+x, −x, +y, −y, +z, −z), as the renderer's.
        sc.xs.clear();
        sc.xs.extend_from_slice(pts);
        for p in pts {
            for a in 0..3 {
                for s in [1.0f32, -1.0] {
                    let mut t = *p;
                    t[a] = (p[a] + s * eps).clamp(-r, r);
                    sc.xs.push(t);
                }
            }
        }
        let rows = sc.xs.len();
        sc.enc.resize(rows * d, 0.0);
        m.grid
            .encode_batch(hash, &sc.xs, r, self.active, &mut sc.enc, d);
        sc.tap_sdf.resize(6 * n, 0.0);
        {
            let tap_sdf = &mut sc.tap_sdf;
            m.sdf_mlp
                .forward_hidden_with(sdf, &sc.enc, rows, &mut sc.sdf_tape, |i, h| {
                    if i >= n {
                        tap_sdf[i - n] = m.sdf_mlp.output_channel(sdf, 0, h);
                    }
                });
        }
        sc.feat.resize(n * fdim, 0.0);
        let h = sc.sdf_tape.acts.last().expect("a hidden layer");
        m.sdf_mlp
            .forward_last(sdf, &h[..n * wh], n, fdim, &mut sc.feat);

        let mut fallbacks = 0usize;
        let inv_2eps = 1.0 / (eps + eps);
        let app = &m.config.field.appearance;
        let codes = self.group("appearance");
        sc.color_in.resize(n * dc, 0.0);
        let mut bad_normal = vec![false; n];
        for i in 0..n {
            let t = &sc.tap_sdf[6 * i..6 * i + 6];
            let g = [0, 1, 2].map(|a| (t[2 * a] - t[2 * a + 1]) * inv_2eps);
            let len = (g[0] * g[0] + g[1] * g[1] + g[2] * g[2]).sqrt();
            let nr = if len.is_finite() && len >= 1e-12 {
                g.map(|v| v / len)
            } else {
                bad_normal[i] = true;
                fallback.get(i).copied().unwrap_or([0.0, 0.0, 1.0])
            };
            nrm[i] = nr;
            let row = &mut sc.color_in[i * dc..(i + 1) * dc];
            row[..fdim].copy_from_slice(&sc.feat[i * fdim..(i + 1) * fdim]);
            let d = match dirs.get(i) {
                Some(d) => *d,
                None => self.view_dir(pts[i], nr),
            };
            sh4(d, &mut row[fdim..fdim + SH_DIM]);
            if self.view_dependence != 1.0 {
                for v in &mut row[fdim + 1..fdim + SH_DIM] {
                    *v *= self.view_dependence;
                }
            }
            row[fdim + SH_DIM..fdim + SH_DIM + 3].copy_from_slice(&nr);
            if app.n_codes > 0 {
                // Code 0: the identity manipulation; `p = 0` (DIA's scalar).
                let a0 = fdim + SH_DIM + 3;
                row[a0..a0 + app.code_dim].copy_from_slice(&codes[..app.code_dim]);
                if app.with_scalar {
                    row[a0 + app.code_dim] = 0.0;
                }
            }
        }
        m.color_mlp
            .forward_hidden(color, &sc.color_in, n, &mut sc.color_tape);
        sc.logits.resize(n * 3, 0.0);
        let hc = sc.color_tape.acts.last().expect("a hidden layer");
        m.color_mlp.forward_last(color, hc, n, 3, &mut sc.logits);
        for i in 0..n {
            let c = [0, 1, 2].map(|k| sigmoid(sc.logits[3 * i + k]));
            let ok = c.iter().all(|v| v.is_finite());
            rgb[i] = if ok { c } else { [0.5; 3] };
            if !ok || bad_normal[i] {
                fallbacks += 1;
            }
        }
        fallbacks
    }
}

/// Area-weighted vertex normals of a mesh (`[n_vertices][3]`, unit; `+z` for a vertex of
/// degenerate faces only): the fallback where the field's gradient is unusable.
pub fn area_weighted_normals(mesh: &TriMesh) -> Vec<[f32; 3]> {
    let mut acc = vec![[0f64; 3]; mesh.vertices.len()];
    for f in &mesh.faces {
        let p = f.map(|i| mesh.vertices[i as usize].map(|v| v as f64));
        let e1 = [0, 1, 2].map(|a| p[1][a] - p[0][a]);
        let e2 = [0, 1, 2].map(|a| p[2][a] - p[0][a]);
        // |e1 × e2| = twice the area: the cross product is the area-weighted normal.
        let c = [
            e1[1] * e2[2] - e1[2] * e2[1],
            e1[2] * e2[0] - e1[0] * e2[2],
            e1[0] * e2[1] - e1[1] * e2[0],
        ];
        for &i in f {
            for a in 0..3 {
                acc[i as usize][a] += c[a];
            }
        }
    }
    acc.iter()
        .map(|c| {
            let l = (c[0] * c[0] + c[1] * c[1] + c[2] * c[2]).sqrt();
            if l > 0.0 && l.is_finite() {
                c.map(|v| (v / l) as f32)
            } else {
                [0.0, 0.0, 1.0]
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::ModelConfig;

    /// The sphere-initialised network: the normals of its SDF at points on the init sphere
    /// point outwards, and the colours are finite, in `[0, 1]` and the same at any thread count.
    #[test]
    fn normals_of_the_sphere_init_point_outwards() {
        let model = NeusModel::new(ModelConfig::default()).unwrap();
        let p = model.init_params(7);
        let sched = model.config.inference_schedule(0);
        let f = SurfaceField::new(&model, &p, sched).unwrap();
        let r0 = model.config.field.sdf.sphere_init_radius;
        let pts: Vec<[f32; 3]> = (0..1000)
            .map(|i| {
                let t = i as f32 * 0.618_034 * std::f32::consts::TAU;
                let z = 1.0 - 2.0 * (i as f32 + 0.5) / 1000.0;
                let s = (1.0 - z * z).sqrt();
                [r0 * s * t.cos(), r0 * s * t.sin(), r0 * z]
            })
            .collect();
        let s = f.shade(&pts, &[]);
        assert_eq!(s.fallbacks, 0);
        // The geometric init is a sphere up to the hash grid's ±1e-4 start: outward everywhere,
        // close to radial on average.
        let cos: Vec<f32> = pts
            .iter()
            .zip(&s.normal)
            .map(|(x, n)| (x[0] * n[0] + x[1] * n[1] + x[2] * n[2]) / r0)
            .collect();
        let min = cos.iter().copied().fold(1.0f32, f32::min);
        let mean = cos.iter().sum::<f32>() / cos.len() as f32;
        assert!(
            min > 0.3 && mean > 0.9,
            "cos to the radius: min {min}, mean {mean}"
        );
        assert!(s.rgb.iter().flatten().all(|v| (0.0..=1.0).contains(v)));
        let one = rayon::ThreadPoolBuilder::new()
            .num_threads(1)
            .build()
            .unwrap()
            .install(|| f.shade(&pts, &[]));
        assert_eq!(one, s, "thread count does not change the result");
    }

    /// A non-finite parameter makes every query fall back, counted, with no NaN out.
    #[test]
    fn non_finite_queries_fall_back_and_are_counted() {
        let model = NeusModel::new(ModelConfig::default()).unwrap();
        let mut p = model.init_params(7);
        for v in &mut p[model.layout.group("sdf_mlp").unwrap().range()] {
            *v = f32::NAN;
        }
        let f = SurfaceField::new(&model, &p, model.config.inference_schedule(0)).unwrap();
        let pts = vec![[0.1, 0.2, 0.3]; 5];
        let fb = vec![[1.0, 0.0, 0.0]; 5];
        let s = f.shade(&pts, &fb);
        assert_eq!(s.fallbacks, 5);
        assert!(s.normal.iter().all(|n| *n == [1.0, 0.0, 0.0]));
        assert!(s.rgb.iter().all(|c| *c == [0.5; 3]));
    }

    #[test]
    fn area_weighted_normals_of_a_tetrahedron_point_outwards() {
        let m = TriMesh {
            vertices: vec![
                [1.0, 1.0, 1.0],
                [1.0, -1.0, -1.0],
                [-1.0, 1.0, -1.0],
                [-1.0, -1.0, 1.0],
            ],
            faces: vec![[0, 1, 2], [0, 3, 1], [0, 2, 3], [1, 3, 2]],
        };
        for (v, n) in m.vertices.iter().zip(area_weighted_normals(&m)) {
            let cos = (v[0] * n[0] + v[1] * n[1] + v[2] * n[2]) / 3f32.sqrt();
            assert!((cos - 1.0).abs() < 1e-5, "{v:?} {n:?}");
        }
    }
}
