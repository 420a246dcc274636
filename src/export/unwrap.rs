//! UV unwrapping: charts, their flattening and their packing into one square atlas, with the
//! `uvunwrap` crate (pure Rust: segmentation by normal cones, LSCM + ARAP flattening, shape
//! packing; modelled on xatlas, which nerfstudio's `exporter/texture_utils.py` calls).
//!
//! Why `uvunwrap` 0.3 and not an xatlas binding: the one binding on crates.io, `xatlas-rs` 0.1.3
//! (2019, with the xatlas of 2019), does not link on Linux: its pre-generated bindings carry
//! MSVC-mangled symbol names (`?Create@xatlas@@YAPEAUAtlas@1@XZ`), and regenerating them needs
//! bindgen 0.49 and libclang. Against xatlas itself (its PyPI binding 0.0.11, the library
//! nerfstudio unwraps with; `python3 scripts/unwrap_compare.py RUN/mesh.ply`) on the mesh of
//! `reconstruct blob --preset quick --seed 0` (151 461 vertices, 301 071 faces), 1024² asked,
//! on 2 shared cores (a study and other builds running, so the times are loose):
//!
//! | | time | charts | UV vertices / vertex | atlas |
//! |---|---|---|---|---|
//! | uvunwrap 0.3.0 (padding 2) | 9.7 s | 46 | 1.022 | 1024 × 1022, 63 % used |
//! | uvunwrap 0.3.0 without `direct-solver` (padding 4) | 440 s | 42 | 1.018 | 57 % used |
//! | xatlas 0.0.11 (defaults, padding 2) | 2346 s | 9 565 | 1.399 | grew to 1471², 82 % by its measure, 37 % of texel centres covered |
//!
//! uvunwrap makes 200 times fewer charts (fewer seams to bleed) two orders of magnitude faster.
//! Its default `direct-solver` feature (`faer`) stays on: the iterative solver alone took 45
//! times longer. With `faer` the crate documents its output as identical at every thread
//! count, but possibly different between CPU architectures (runtime SIMD dispatch): the UVs of
//! an x86-64 run may differ in the last bits from an ARM run's; the geometry, the vertex colours
//! and `mesh.ply` do not depend on it.
//!
//! Conventions of the result ([`UvMesh`]): `uv` in `[0, 1]` of the square texture, `(0, 0)` the
//! top-left corner of texel row 0, `v` growing with the image row (glTF's convention; OBJ
//! writes `1 − v`). Vertices are split on chart seams: `xref` maps each UV vertex to its
//! geometry vertex, so positions, normals and faces of the input are kept as they are.

use super::ExportError;
use dtu_eval::mesh::TriMesh;
use std::time::Instant;

/// The unwrapped mesh: the input's geometry plus a second index stream for the texture
/// coordinates.
#[derive(Clone, Debug, PartialEq)]
pub struct UvMesh {
    /// `[n][3]` positions (world mm), the input's.
    pub positions: Vec<[f32; 3]>,
    /// `[n][3]` unit normals (world frame), the input's.
    pub normals: Vec<[f32; 3]>,
    /// `[f][3]` faces into `positions`, the input's, in its order.
    pub faces: Vec<[u32; 3]>,
    /// `[m][2]` texture coordinates (see the module docs), `m ≥ n`.
    pub uv: Vec<[f32; 2]>,
    /// `[m]` the geometry vertex of each UV vertex.
    pub xref: Vec<u32>,
    /// `[f][3]` faces into `uv` (same faces, same corner order).
    pub uv_faces: Vec<[u32; 3]>,
    pub stats: UvStats,
}

/// What the unwrap produced, for the report.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize)]
pub struct UvStats {
    pub charts: u32,
    /// Share of the atlas covered by charts (uvunwrap's measure, over the cropped page).
    pub utilization: f32,
    /// UV vertices over geometry vertices (1 = no seams).
    pub vertex_ratio: f64,
    /// Padding between charts and to the border, texels.
    pub padding: u32,
    pub seconds: f64,
}

/// Padding (texels) around each chart at texture side `size`: 2 up to 511, 4 at 1024, 8 from
/// 2048. The bake dilates the texture by as many texels past each chart's border.
pub fn padding_for(size: u32) -> u32 {
    (size / 256).clamp(2, 8)
}

/// Unwraps `mesh` (faces required) for a `size × size` texture. `normals` are carried along.
pub fn unwrap_mesh(mesh: &TriMesh, normals: &[[f32; 3]], size: u32) -> Result<UvMesh, ExportError> {
    assert_eq!(normals.len(), mesh.vertices.len(), "one normal per vertex");
    let t0 = Instant::now();
    let err = |why: String| ExportError::Unwrap {
        what: format!(
            "a mesh of {} vertices and {} faces",
            mesh.vertices.len(),
            mesh.faces.len()
        ),
        why,
    };
    let indices: Vec<u32> = mesh.faces.iter().flatten().copied().collect();
    let padding = padding_for(size);
    let opts = uvunwrap::Options {
        density: uvunwrap::Density::Auto { page_size: size },
        padding,
        ..Default::default()
    };
    let atlas = uvunwrap::generate(&[uvunwrap::MeshInput::new(&mesh.vertices, &indices)], &opts)
        .map_err(|e| err(e.to_string()))?;
    if atlas.page_count != 1 {
        return Err(err(format!(
            "the charts need {} atlas pages of {size}²; use a larger texture size",
            atlas.page_count
        )));
    }
    let out = &atlas.meshes[0];
    // A cropped page: v in [0, 1] of `height` rows, which are the top rows of the square.
    let (sx, sy) = (
        atlas.width as f32 / size as f32,
        atlas.height as f32 / size as f32,
    );
    let uv: Vec<[f32; 2]> = out
        .vertices
        .iter()
        .map(|v| [v.uv[0] * sx, v.uv[1] * sy])
        .collect();
    let xref: Vec<u32> = out.vertices.iter().map(|v| v.xref).collect();
    let uv_faces: Vec<[u32; 3]> = out
        .indices
        .chunks_exact(3)
        .map(|c| [c[0], c[1], c[2]])
        .collect();
    if uv_faces.len() != mesh.faces.len()
        || uv_faces
            .iter()
            .zip(&mesh.faces)
            .any(|(t, f)| (0..3).any(|k| xref[t[k] as usize] != f[k]))
    {
        return Err(err("the output's faces do not follow the input's".into()));
    }
    let stats = UvStats {
        charts: atlas.chart_count,
        utilization: atlas.utilization * sy.min(1.0) * sx.min(1.0),
        vertex_ratio: uv.len() as f64 / mesh.vertices.len().max(1) as f64,
        padding,
        seconds: t0.elapsed().as_secs_f64(),
    };
    Ok(UvMesh {
        positions: mesh.vertices.clone(),
        normals: normals.to_vec(),
        faces: mesh.faces.clone(),
        uv,
        xref,
        uv_faces,
        stats,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A closed box (12 triangles): every corner maps into the texture, the faces follow the
    /// input, seams split vertices, and no two triangles overlap in UV space.
    #[test]
    fn a_cube_unwraps_into_the_square_without_overlap() {
        let v: Vec<[f32; 3]> = (0..8)
            .map(|i| [(i & 1) as f32, ((i >> 1) & 1) as f32, ((i >> 2) & 1) as f32])
            .collect();
        let faces = vec![
            [0, 2, 1],
            [1, 2, 3],
            [4, 5, 6],
            [5, 7, 6],
            [0, 1, 4],
            [1, 5, 4],
            [2, 6, 3],
            [3, 6, 7],
            [0, 4, 2],
            [2, 4, 6],
            [1, 3, 5],
            [3, 7, 5],
        ];
        let mesh = TriMesh { vertices: v, faces };
        let n = vec![[0.0, 0.0, 1.0]; 8];
        let u = unwrap_mesh(&mesh, &n, 64).unwrap();
        assert_eq!(u.faces, mesh.faces);
        assert!(u.uv.iter().flatten().all(|c| (0.0..=1.0).contains(c)));
        assert!(u.uv.len() > 8, "a cube cannot be flattened without seams");
        assert!(u.stats.charts >= 2);
        // No overlap: rasterise every triangle at 256² and count texels hit twice.
        let res = 256usize;
        let mut hits = vec![0u8; res * res];
        for t in &u.uv_faces {
            let p = t.map(|i| u.uv[i as usize].map(|c| c * res as f32));
            super::super::bake::raster_triangle(p, res, res, |x, y, _| hits[y * res + x] += 1);
        }
        assert_eq!(hits.iter().filter(|&&h| h > 1).count(), 0);
        assert!(hits.iter().filter(|&&h| h == 1).count() > res * res / 10);
    }

    #[test]
    fn padding_grows_with_the_texture() {
        assert_eq!(padding_for(16), 2);
        assert_eq!(padding_for(1024), 4);
        assert_eq!(padding_for(16384), 8);
    }
}
