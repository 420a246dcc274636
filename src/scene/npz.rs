//! `.npz` archives of float matrices (the `cameras_sphere.npz` of NeuS / IDR).
//!
//! An `.npz` is a zip of `.npy` files; we read the zip with `zip` (stored or deflate, as
//! `np.savez` / `np.savez_compressed` write it) and each entry with `npyz`. Values are returned
//! as f64 in row-major (C) order whatever the stored dtype (`<f8`, `<f4`, integers) and order.

use std::collections::BTreeMap;
use std::io::{Read, Write};
use std::path::{Path, PathBuf};

/// Errors of `.npz` input/output, naming the file and, where it applies, the key.
#[derive(Debug, thiserror::Error)]
pub enum NpzError {
    /// The file could not be opened or written.
    #[error("cannot access {path}: {source}")]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    /// The file or one of its entries is not a valid npz / npy.
    #[error("{path} is not a valid .npz archive ({key}): {message}")]
    Format {
        path: PathBuf,
        key: String,
        message: String,
    },
}

/// One array of an archive: its shape and its values in row-major order.
#[derive(Clone, Debug, PartialEq)]
pub struct NpArray {
    /// Dimensions, outermost first.
    pub shape: Vec<usize>,
    /// `shape.iter().product()` values, row-major.
    pub data: Vec<f64>,
}

/// Reads every array of an `.npz` file, keyed by array name (the entry name without `.npy`).
pub fn read(path: &Path) -> Result<BTreeMap<String, NpArray>, NpzError> {
    let fmt = |key: &str, message: String| NpzError::Format {
        path: path.into(),
        key: key.into(),
        message,
    };
    let file = std::fs::File::open(path).map_err(|source| NpzError::Io {
        path: path.into(),
        source,
    })?;
    let mut zip = zip::ZipArchive::new(std::io::BufReader::new(file))
        .map_err(|e| fmt("archive", e.to_string()))?;
    let mut out = BTreeMap::new();
    for i in 0..zip.len() {
        let mut entry = zip.by_index(i).map_err(|e| fmt("archive", e.to_string()))?;
        let name = entry.name().to_string();
        let Some(key) = name.strip_suffix(".npy") else {
            continue;
        };
        let mut bytes = Vec::with_capacity(entry.size() as usize);
        entry
            .read_to_end(&mut bytes)
            .map_err(|e| fmt(key, e.to_string()))?;
        let npy = npyz::NpyFile::new(&bytes[..]).map_err(|e| fmt(key, e.to_string()))?;
        let shape: Vec<usize> = npy.shape().iter().map(|&d| d as usize).collect();
        let order = npy.order();
        let descr = npy.dtype().descr();
        let data: Vec<f64> = match descr
            .trim_matches('\'')
            .trim_start_matches(['<', '>', '|', '='])
        {
            "f8" => npy.into_vec::<f64>(),
            "f4" => npy
                .into_vec::<f32>()
                .map(|v| v.into_iter().map(f64::from).collect()),
            "i8" => npy
                .into_vec::<i64>()
                .map(|v| v.into_iter().map(|x| x as f64).collect()),
            "i4" => npy
                .into_vec::<i32>()
                .map(|v| v.into_iter().map(f64::from).collect()),
            other => {
                return Err(fmt(
                    key,
                    format!("unsupported dtype '{other}' (want float)"),
                ))
            }
        }
        .map_err(|e| fmt(key, e.to_string()))?;
        let data = if order == npyz::Order::Fortran && shape.len() == 2 {
            let (r, c) = (shape[0], shape[1]);
            (0..r * c).map(|i| data[(i % c) * r + i / c]).collect()
        } else {
            data
        };
        out.insert(key.to_string(), NpArray { shape, data });
    }
    Ok(out)
}

/// Writes `(name, shape, row-major values)` arrays as an uncompressed `.npz` of `<f8` arrays
/// (what `np.savez` writes), atomically ([`dtu_eval::atomic::write_atomic`]).
pub fn write(path: &Path, arrays: &[(String, Vec<usize>, Vec<f64>)]) -> Result<(), NpzError> {
    let io = |source| NpzError::Io {
        path: path.into(),
        source,
    };
    let result = (|| -> std::io::Result<()> {
        // Built in memory (a zip needs to seek back), then written with the workspace's one
        // atomic writer.
        let mut zip = zip::ZipWriter::new(std::io::Cursor::new(Vec::new()));
        let opts = zip::write::SimpleFileOptions::default()
            .compression_method(zip::CompressionMethod::Stored);
        for (name, shape, data) in arrays {
            assert_eq!(shape.iter().product::<usize>(), data.len(), "array {name}");
            zip.start_file(format!("{name}.npy"), opts)
                .map_err(std::io::Error::other)?;
            let shape: Vec<u64> = shape.iter().map(|&d| d as u64).collect();
            let mut buf = Vec::new();
            {
                use npyz::WriterBuilder;
                let mut w = npyz::WriteOptions::new()
                    .default_dtype()
                    .shape(&shape)
                    .writer(&mut buf)
                    .begin_nd()?;
                w.extend(data.iter().copied())?;
                w.finish()?;
            }
            zip.write_all(&buf)?;
        }
        let bytes = zip.finish().map_err(std::io::Error::other)?.into_inner();
        dtu_eval::atomic::write_atomic(path, &bytes)
    })();
    result.map_err(io)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trip_keeps_shapes_and_values() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("c.npz");
        let a: Vec<f64> = (0..16).map(|i| i as f64 * 0.1 - 0.3).collect();
        write(
            &path,
            &[
                ("world_mat_0".into(), vec![4, 4], a.clone()),
                ("v".into(), vec![3], vec![1.0, 2.0, 3.0]),
            ],
        )
        .unwrap();
        let back = read(&path).unwrap();
        assert_eq!(back["world_mat_0"].shape, vec![4, 4]);
        assert_eq!(back["world_mat_0"].data, a);
        assert_eq!(back["v"].data, vec![1.0, 2.0, 3.0]);
    }

    #[test]
    fn not_a_zip_is_an_error_naming_the_file() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("cameras_sphere.npz");
        std::fs::write(&path, b"nope").unwrap();
        let err = read(&path).unwrap_err().to_string();
        assert!(err.contains("cameras_sphere.npz"), "{err}");
    }
}
