//! COLMAP's binary model files (`cameras.bin`, `images.bin`, `points3D.bin`): reading and
//! writing. Layout (little endian; COLMAP `scripts/python/read_write_model.py`): see the
//! [`colmap`](super::colmap) module doc.

use super::colmap_model::{
    parse_err, supported_hint, ColmapCamera, ColmapImage, ColmapModel, ColmapPoint, MODELS,
};
use super::{io_err, ImportError};
use std::collections::BTreeMap;
use std::path::Path;

/// A little-endian cursor over a binary model file; errors name the file and offset.
struct Reader<'a> {
    file: &'a Path,
    bytes: &'a [u8],
    pos: usize,
}

impl<'a> Reader<'a> {
    fn take<const N: usize>(&mut self, what: &str) -> Result<[u8; N], ImportError> {
        let end = self.pos + N;
        if end > self.bytes.len() {
            return Err(parse_err(
                self.file,
                format!("truncated at byte {} while reading {what}", self.pos),
            ));
        }
        let out = self.bytes[self.pos..end].try_into().expect("N bytes");
        self.pos = end;
        Ok(out)
    }
    fn u64(&mut self, what: &str) -> Result<u64, ImportError> {
        Ok(u64::from_le_bytes(self.take(what)?))
    }
    fn i64(&mut self, what: &str) -> Result<i64, ImportError> {
        Ok(i64::from_le_bytes(self.take(what)?))
    }
    fn i32(&mut self, what: &str) -> Result<i32, ImportError> {
        Ok(i32::from_le_bytes(self.take(what)?))
    }
    fn f64(&mut self, what: &str) -> Result<f64, ImportError> {
        Ok(f64::from_le_bytes(self.take(what)?))
    }
    fn u8(&mut self, what: &str) -> Result<u8, ImportError> {
        Ok(self.take::<1>(what)?[0])
    }
    /// A count, refused when it cannot fit in the rest of the file (`min_size` bytes each).
    fn count(&mut self, what: &str, min_size: usize) -> Result<usize, ImportError> {
        let n = self.u64(what)?;
        let left = (self.bytes.len() - self.pos) as u64;
        if n.saturating_mul(min_size as u64) > left {
            return Err(parse_err(
                self.file,
                format!("{what} {n} at byte {} exceeds the file size", self.pos - 8),
            ));
        }
        Ok(n as usize)
    }
    fn id32(&mut self, what: &str) -> Result<u32, ImportError> {
        let v = self.i32(what)?;
        u32::try_from(v).map_err(|_| {
            parse_err(
                self.file,
                format!("negative {what} {v} at byte {}", self.pos - 4),
            )
        })
    }
}

pub(crate) fn parse_cameras_bin(
    file: &Path,
    bytes: &[u8],
) -> Result<BTreeMap<u32, ColmapCamera>, ImportError> {
    let mut r = Reader {
        file,
        bytes,
        pos: 0,
    };
    let n = r.count("number of cameras", 24)?;
    let mut cams = BTreeMap::new();
    for _ in 0..n {
        let id = r.id32("camera id")?;
        let model_id = r.i32("model id")?;
        let Some(&(model, _, n_params)) = MODELS.iter().find(|m| m.1 == model_id) else {
            return Err(ImportError::UnsupportedModel {
                file: file.into(),
                camera_id: id as u64,
                model: format!("unknown (model id {model_id})"),
                hint: supported_hint(),
            });
        };
        let width = r.u64("width")?;
        let height = r.u64("height")?;
        let params = (0..n_params)
            .map(|_| r.f64("camera parameter"))
            .collect::<Result<_, _>>()?;
        cams.insert(
            id,
            ColmapCamera {
                id,
                model: model.into(),
                width,
                height,
                params,
            },
        );
    }
    Ok(cams)
}

pub(crate) fn parse_images_bin(file: &Path, bytes: &[u8]) -> Result<Vec<ColmapImage>, ImportError> {
    let mut r = Reader {
        file,
        bytes,
        pos: 0,
    };
    let n = r.count("number of images", 64)?;
    let mut images = Vec::with_capacity(n);
    for _ in 0..n {
        let id = r.id32("image id")?;
        let mut qvec = [0.0; 4];
        for q in &mut qvec {
            *q = r.f64("qvec")?;
        }
        let mut tvec = [0.0; 3];
        for t in &mut tvec {
            *t = r.f64("tvec")?;
        }
        let camera_id = r.id32("camera id")?;
        let start = r.pos;
        let len = bytes[start..].iter().position(|&b| b == 0).ok_or_else(|| {
            parse_err(
                file,
                format!("image name at byte {start} is not NUL-terminated"),
            )
        })?;
        let name = String::from_utf8(bytes[start..start + len].to_vec())
            .map_err(|_| parse_err(file, format!("image name at byte {start} is not UTF-8")))?;
        r.pos = start + len + 1;
        let np = r.count("number of 2-D points", 24)?;
        let mut points2d = Vec::with_capacity(np);
        for _ in 0..np {
            points2d.push((r.f64("x")?, r.f64("y")?, r.i64("point3D id")?));
        }
        images.push(ColmapImage {
            id,
            qvec,
            tvec,
            camera_id,
            name,
            points2d,
        });
    }
    Ok(images)
}

pub(crate) fn parse_points_bin(file: &Path, bytes: &[u8]) -> Result<Vec<ColmapPoint>, ImportError> {
    let mut r = Reader {
        file,
        bytes,
        pos: 0,
    };
    let n = r.count("number of points", 43)?;
    let mut points = Vec::with_capacity(n);
    for _ in 0..n {
        let id = r.u64("point id")?;
        let xyz = [r.f64("x")?, r.f64("y")?, r.f64("z")?];
        let rgb = [r.u8("r")?, r.u8("g")?, r.u8("b")?];
        let error = r.f64("error")?;
        let nt = r.count("track length", 8)?;
        let mut track = Vec::with_capacity(nt);
        for _ in 0..nt {
            track.push((r.id32("track image id")?, r.id32("track 2-D point index")?));
        }
        points.push(ColmapPoint {
            id,
            xyz,
            rgb,
            error,
            track,
        });
    }
    Ok(points)
}

/// Writes the model as `cameras.bin`, `images.bin`, `points3D.bin` in `dir` (created), in
/// COLMAP's binary layout (module doc). Cameras must use one of COLMAP's model names.
pub fn write_binary(model: &ColmapModel, dir: &Path) -> Result<(), ImportError> {
    std::fs::create_dir_all(dir).map_err(io_err(dir))?;
    let mut cams = Vec::new();
    cams.extend((model.cameras.len() as u64).to_le_bytes());
    for c in model.cameras.values() {
        let Some(&(_, model_id, n)) = MODELS.iter().find(|m| m.0 == c.model) else {
            return Err(ImportError::Export(format!(
                "camera {} has model '{}', which has no COLMAP id",
                c.id, c.model
            )));
        };
        if c.params.len() != n {
            return Err(ImportError::Export(format!(
                "camera {} ({}) has {} parameters, expected {n}",
                c.id,
                c.model,
                c.params.len()
            )));
        }
        cams.extend((c.id as i32).to_le_bytes());
        cams.extend(model_id.to_le_bytes());
        cams.extend(c.width.to_le_bytes());
        cams.extend(c.height.to_le_bytes());
        c.params.iter().for_each(|p| cams.extend(p.to_le_bytes()));
    }
    let mut imgs = Vec::new();
    imgs.extend((model.images.len() as u64).to_le_bytes());
    for im in &model.images {
        imgs.extend((im.id as i32).to_le_bytes());
        im.qvec.iter().for_each(|v| imgs.extend(v.to_le_bytes()));
        im.tvec.iter().for_each(|v| imgs.extend(v.to_le_bytes()));
        imgs.extend((im.camera_id as i32).to_le_bytes());
        imgs.extend(im.name.as_bytes());
        imgs.push(0);
        imgs.extend((im.points2d.len() as u64).to_le_bytes());
        for (x, y, id) in &im.points2d {
            imgs.extend(x.to_le_bytes());
            imgs.extend(y.to_le_bytes());
            imgs.extend(id.to_le_bytes());
        }
    }
    let mut pts = Vec::new();
    pts.extend((model.points.len() as u64).to_le_bytes());
    for p in &model.points {
        pts.extend(p.id.to_le_bytes());
        p.xyz.iter().for_each(|v| pts.extend(v.to_le_bytes()));
        pts.extend(p.rgb);
        pts.extend(p.error.to_le_bytes());
        pts.extend((p.track.len() as u64).to_le_bytes());
        for (i, k) in &p.track {
            pts.extend((*i as i32).to_le_bytes());
            pts.extend((*k as i32).to_le_bytes());
        }
    }
    for (name, bytes) in [
        ("cameras.bin", cams),
        ("images.bin", imgs),
        ("points3D.bin", pts),
    ] {
        let path = dir.join(name);
        std::fs::write(&path, bytes).map_err(io_err(&path))?;
    }
    Ok(())
}
