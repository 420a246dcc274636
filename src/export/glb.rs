//! The textured mesh as binary glTF 2.0 (`.glb`): the JSON built with `gltf-json` (typed, and
//! checked with its validator in the tests), the container written here (glTF 2.0 §4.4 "Binary
//! glTF Layout": a 12-byte header, a JSON chunk padded with spaces, a BIN chunk padded with
//! zeros, each chunk 4-byte aligned).
//!
//! Contents: one mesh of one triangle primitive (`POSITION` f32×3 with its `min`/`max`,
//! `NORMAL` f32×3, `TEXCOORD_0` f32×2, `u32` indices; vertices split on UV seams, positions
//! copied through `xref`), one material (`baseColorTexture`, metallic 0, roughness 1; the
//! colours are sRGB as glTF's base colour texture is, §3.9.2), the PNG embedded in the buffer
//! (§3.8.4 images from a buffer view), a linear sampler with clamped edges.
//!
//! Units and axes (§3.4: metres, +Y up): the positions stay in world millimetres, bit for bit the
//! mesh's, and the node's `matrix` carries the change: scale 1e-3, a rotation taking the scene's
//! up direction ([`super::scene_up`]) to +Y, and a translation putting the scene's normalisation
//! centre at the origin. Texture coordinates have `v` down (§3.7.2.1: origin at the image's
//! top-left), as [`UvMesh`] stores them.

// Numeric kernels index several parallel arrays with one loop variable.
#![allow(clippy::needless_range_loop)]

use super::unwrap::UvMesh;
use gltf_json as json;
use json::validation::Checked::Valid;
use json::validation::USize64;
use std::collections::BTreeMap;

/// Column-major 4×4 node matrix: `x_m = 1e-3 · R · (x_mm − c)`, `R` the smallest rotation
/// taking unit `up` to +Y (a half turn about +X when `up` is −Y).
pub fn node_matrix(up: [f64; 3], center_mm: [f64; 3]) -> [f32; 16] {
    let r = rotation_to_y(up);
    let s = 1e-3;
    let mut m = [0f32; 16];
    for col in 0..3 {
        for row in 0..3 {
            m[col * 4 + row] = (s * r[row][col]) as f32;
        }
    }
    for row in 0..3 {
        let t: f64 = (0..3).map(|k| r[row][k] * center_mm[k]).sum();
        m[12 + row] = (-s * t) as f32;
    }
    m[15] = 1.0;
    m
}

/// Row-major rotation taking unit `u` to `(0, 1, 0)` (Rodrigues about `u × y`).
pub fn rotation_to_y(u: [f64; 3]) -> [[f64; 3]; 3] {
    let l = (u[0] * u[0] + u[1] * u[1] + u[2] * u[2]).sqrt();
    let u = if l > 0.0 && l.is_finite() {
        u.map(|v| v / l)
    } else {
        [0.0, 1.0, 0.0]
    };
    let c = u[1];
    // Axis k = u × y = (−u_z, 0, u_x), |k| = sin.
    let k = [-u[2], 0.0, u[0]];
    let s2 = k[0] * k[0] + k[2] * k[2];
    if s2 < 1e-24 {
        return if c > 0.0 {
            [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]
        } else {
            [[1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, -1.0]]
        };
    }
    // R = I + [k]× + [k]×² · (1 − c)/s².
    let kx = [[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]];
    let f = (1.0 - c) / s2;
    let mut r = [[0.0; 3]; 3];
    for i in 0..3 {
        for j in 0..3 {
            let kk: f64 = (0..3).map(|m| kx[i][m] * kx[m][j]).sum();
            r[i][j] = f64::from(u8::from(i == j)) + kx[i][j] + f * kk;
        }
    }
    r
}

/// Appends `bytes` to `bin` at a 4-byte boundary; returns `(offset, length)`.
fn append(bin: &mut Vec<u8>, bytes: &[u8]) -> (usize, usize) {
    while !bin.len().is_multiple_of(4) {
        bin.push(0);
    }
    let off = bin.len();
    bin.extend_from_slice(bytes);
    (off, bytes.len())
}

fn f32_bytes<const N: usize>(v: impl Iterator<Item = [f32; N]>) -> Vec<u8> {
    v.flat_map(|a| a.into_iter().flat_map(f32::to_le_bytes))
        .collect()
}

/// The glTF document (JSON) and its binary buffer for `m` with the PNG `png` and the node
/// matrix `matrix`.
pub fn gltf_document(m: &UvMesh, png: &[u8], matrix: &[f32; 16]) -> (json::Root, Vec<u8>) {
    let pos: Vec<[f32; 3]> = m.xref.iter().map(|&i| m.positions[i as usize]).collect();
    let nrm: Vec<[f32; 3]> = m.xref.iter().map(|&i| m.normals[i as usize]).collect();
    let mut lo = [f32::INFINITY; 3];
    let mut hi = [f32::NEG_INFINITY; 3];
    for p in &pos {
        for a in 0..3 {
            lo[a] = lo[a].min(p[a]);
            hi[a] = hi[a].max(p[a]);
        }
    }
    let mut bin = Vec::new();
    let sections = [
        append(&mut bin, &f32_bytes(pos.iter().copied())),
        append(&mut bin, &f32_bytes(nrm.iter().copied())),
        append(&mut bin, &f32_bytes(m.uv.iter().copied())),
        append(
            &mut bin,
            &m.uv_faces
                .iter()
                .flatten()
                .flat_map(|i| i.to_le_bytes())
                .collect::<Vec<u8>>(),
        ),
        append(&mut bin, png),
    ];
    while !bin.len().is_multiple_of(4) {
        bin.push(0);
    }
    let mut root = json::Root {
        asset: json::Asset {
            copyright: None,
            extensions: Default::default(),
            extras: Default::default(),
            generator: Some(format!("neus-aug {}", env!("CARGO_PKG_VERSION"))),
            min_version: None,
            version: "2.0".into(),
        },
        ..Default::default()
    };
    let buffer = root.push(json::Buffer {
        byte_length: USize64::from(bin.len()),
        extensions: Default::default(),
        extras: Default::default(),
        name: None,
        uri: None,
    });
    let targets = [
        Some(json::buffer::Target::ArrayBuffer),
        Some(json::buffer::Target::ArrayBuffer),
        Some(json::buffer::Target::ArrayBuffer),
        Some(json::buffer::Target::ElementArrayBuffer),
        None,
    ];
    let views: Vec<json::Index<json::buffer::View>> = sections
        .iter()
        .zip(targets)
        .map(|(&(off, len), target)| {
            root.push(json::buffer::View {
                buffer,
                byte_length: USize64::from(len),
                byte_offset: Some(USize64::from(off)),
                byte_stride: None,
                extensions: Default::default(),
                extras: Default::default(),
                name: None,
                target: target.map(Valid),
            })
        })
        .collect();
    let mut accessor = |view: usize,
                        count: usize,
                        ct: json::accessor::ComponentType,
                        ty: json::accessor::Type,
                        bounds: Option<([f32; 3], [f32; 3])>| {
        root.push(json::Accessor {
            buffer_view: Some(views[view]),
            byte_offset: Some(USize64(0)),
            count: USize64::from(count),
            component_type: Valid(json::accessor::GenericComponentType(ct)),
            extensions: Default::default(),
            extras: Default::default(),
            type_: Valid(ty),
            min: bounds.map(|b| json::Value::from(b.0.to_vec())),
            max: bounds.map(|b| json::Value::from(b.1.to_vec())),
            name: None,
            normalized: false,
            sparse: None,
        })
    };
    use json::accessor::{ComponentType as C, Type as T};
    let a_pos = accessor(0, pos.len(), C::F32, T::Vec3, Some((lo, hi)));
    let a_nrm = accessor(1, nrm.len(), C::F32, T::Vec3, None);
    let a_uv = accessor(2, m.uv.len(), C::F32, T::Vec2, None);
    let a_idx = accessor(3, 3 * m.uv_faces.len(), C::U32, T::Scalar, None);
    let image = root.push(json::Image {
        buffer_view: Some(views[4]),
        mime_type: Some(json::image::MimeType("image/png".into())),
        name: Some("baked colour".into()),
        uri: None,
        extensions: Default::default(),
        extras: Default::default(),
    });
    let sampler = root.push(json::texture::Sampler {
        mag_filter: Some(Valid(json::texture::MagFilter::Linear)),
        min_filter: Some(Valid(json::texture::MinFilter::LinearMipmapLinear)),
        wrap_s: Valid(json::texture::WrappingMode::ClampToEdge),
        wrap_t: Valid(json::texture::WrappingMode::ClampToEdge),
        ..Default::default()
    });
    let texture = root.push(json::Texture {
        name: None,
        sampler: Some(sampler),
        source: image,
        extensions: Default::default(),
        extras: Default::default(),
    });
    let material = root.push(json::Material {
        name: Some("neus-aug".into()),
        pbr_metallic_roughness: json::material::PbrMetallicRoughness {
            base_color_texture: Some(json::texture::Info {
                index: texture,
                tex_coord: 0,
                extensions: Default::default(),
                extras: Default::default(),
            }),
            metallic_factor: json::material::StrengthFactor(0.0),
            roughness_factor: json::material::StrengthFactor(1.0),
            ..Default::default()
        },
        double_sided: true,
        ..Default::default()
    });
    let attributes = BTreeMap::from([
        (Valid(json::mesh::Semantic::Positions), a_pos),
        (Valid(json::mesh::Semantic::Normals), a_nrm),
        (Valid(json::mesh::Semantic::TexCoords(0)), a_uv),
    ]);
    let mesh = root.push(json::Mesh {
        extensions: Default::default(),
        extras: Default::default(),
        name: Some("neus-aug surface".into()),
        primitives: vec![json::mesh::Primitive {
            attributes,
            extensions: Default::default(),
            extras: Default::default(),
            indices: Some(a_idx),
            material: Some(material),
            mode: Valid(json::mesh::Mode::Triangles),
            targets: None,
        }],
        weights: None,
    });
    let node = root.push(json::Node {
        mesh: Some(mesh),
        matrix: Some(*matrix),
        name: Some("world mm → metres, scene up → +Y".into()),
        ..Default::default()
    });
    let scene = root.push(json::Scene {
        extensions: Default::default(),
        extras: Default::default(),
        name: None,
        nodes: vec![node],
    });
    root.scene = Some(scene);
    (root, bin)
}

/// The `.glb` bytes of [`gltf_document`].
pub fn glb_bytes(m: &UvMesh, png: &[u8], matrix: &[f32; 16]) -> Vec<u8> {
    let (root, bin) = gltf_document(m, png, matrix);
    let mut js = json::serialize::to_vec(&root).expect("the document serialises");
    while js.len() % 4 != 0 {
        js.push(b' ');
    }
    let total = 12 + 8 + js.len() + 8 + bin.len();
    let mut out = Vec::with_capacity(total);
    out.extend_from_slice(b"glTF");
    out.extend_from_slice(&2u32.to_le_bytes());
    out.extend_from_slice(&(total as u32).to_le_bytes());
    out.extend_from_slice(&(js.len() as u32).to_le_bytes());
    out.extend_from_slice(b"JSON");
    out.extend_from_slice(&js);
    out.extend_from_slice(&(bin.len() as u32).to_le_bytes());
    out.extend_from_slice(b"BIN\0");
    out.extend_from_slice(&bin);
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tri() -> UvMesh {
        UvMesh {
            positions: vec![[0.0, 0.0, 600.0], [10.0, 0.0, 600.0], [0.0, 10.0, 601.5]],
            normals: vec![[0.0, 0.0, 1.0]; 3],
            faces: vec![[0, 1, 2]],
            uv: vec![[0.1, 0.1], [0.9, 0.1], [0.1, 0.9], [0.5, 0.5]],
            xref: vec![0, 1, 2, 2],
            uv_faces: vec![[0, 1, 3]],
            stats: Default::default(),
        }
    }

    /// The container parses back (header, chunk types, lengths, padding), the JSON passes
    /// gltf-json's validator, and the buffer holds the positions and the PNG where the views
    /// say.
    #[test]
    fn glb_container_and_document_are_valid() {
        let png = b"\x89PNG fake image bytes";
        let m = tri();
        let bytes = glb_bytes(&m, png, &node_matrix([0.0, 0.0, 1.0], [0.0, 0.0, 600.0]));
        let u32_at = |o: usize| u32::from_le_bytes(bytes[o..o + 4].try_into().unwrap()) as usize;
        assert_eq!(&bytes[0..4], b"glTF");
        assert_eq!(u32_at(4), 2);
        assert_eq!(u32_at(8), bytes.len());
        let jl = u32_at(12);
        assert_eq!(&bytes[16..20], b"JSON");
        assert_eq!(jl % 4, 0);
        let js = &bytes[20..20 + jl];
        let bl = u32_at(20 + jl);
        assert_eq!(&bytes[24 + jl..28 + jl], b"BIN\0");
        assert_eq!(28 + jl + bl, bytes.len());
        assert_eq!(bl % 4, 0);
        let bin = &bytes[28 + jl..];
        let root: json::Root = json::deserialize::from_slice(js).unwrap();
        let mut errors = Vec::new();
        use json::validation::Validate;
        root.validate(&root, json::Path::new, &mut |p, e| {
            errors.push(format!("{}: {e:?}", p()))
        });
        assert!(errors.is_empty(), "{errors:?}");
        assert_eq!(root.buffers[0].byte_length.0 as usize, bl);
        // Positions: the fourth UV vertex copies geometry vertex 2.
        let v = &root.buffer_views[0];
        let off = v.byte_offset.unwrap().0 as usize;
        let f =
            |k: usize| f32::from_le_bytes(bin[off + 4 * k..off + 4 * k + 4].try_into().unwrap());
        assert_eq!([f(9), f(10), f(11)], [0.0, 10.0, 601.5]);
        let acc = &root.accessors[0];
        assert_eq!(acc.min, Some(json::Value::from(vec![0.0f32, 0.0, 600.0])));
        let iv = &root.buffer_views[4];
        let o = iv.byte_offset.unwrap().0 as usize;
        assert_eq!(&bin[o..o + png.len()], png);
        assert_eq!(root.images[0].mime_type.as_ref().unwrap().0, "image/png");
    }

    /// The node matrix maps the centre to the origin, the up direction to +Y and a millimetre
    /// to 1e-3.
    #[test]
    fn node_matrix_scales_rotates_and_centres() {
        for up in [
            [0.0, 0.0, 1.0],
            [0.0, -1.0, 0.0],
            [0.6, 0.0, -0.8],
            [0.0, 1.0, 0.0],
        ] {
            let c = [10.0, -20.0, 600.0];
            let m = node_matrix(up, c);
            let apply = |x: [f64; 3]| {
                [0, 1, 2].map(|r| {
                    (0..3).map(|k| m[k * 4 + r] as f64 * x[k]).sum::<f64>() + m[12 + r] as f64
                })
            };
            let o = apply(c);
            assert!(o.iter().all(|v| v.abs() < 1e-6), "{up:?}: {o:?}");
            let top = apply([0, 1, 2].map(|k| c[k] + 1000.0 * up[k]));
            assert!((top[1] - 1.0).abs() < 1e-5 && top[0].abs() < 1e-5 && top[2].abs() < 1e-5);
            let r = rotation_to_y(up);
            let det = r[0][0] * (r[1][1] * r[2][2] - r[1][2] * r[2][1])
                - r[0][1] * (r[1][0] * r[2][2] - r[1][2] * r[2][0])
                + r[0][2] * (r[1][0] * r[2][1] - r[1][1] * r[2][0]);
            assert!((det - 1.0).abs() < 1e-12, "a rotation: det {det}");
        }
    }
}
