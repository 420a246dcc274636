//! DTU ground-truth files: where they live, and the MATLAB v5 `.mat` files that hold the
//! observation mask and the ground plane.
//!
//! Layout under a ground-truth root (DTU's "SampleSet/MVS Data", as jzhangbs/DTUeval-python
//! `eval.py` reads it):
//! - `Points/stl/stl{scan:03}_total.ply`: the structured-light reference points (mm);
//! - `ObsMask/ObsMask{scan}_10.mat`: `ObsMask` (logical, 3-D, MATLAB column-major), `BB` (2×3:
//!   the box's min and max corners, mm) and `Res` (voxel edge, mm);
//! - `ObsMask/Plane{scan}.mat`: `P`, the ground plane as a 4-vector with `[x, y, z, 1]·P > 0`
//!   above it.
//!
//! Reading goes through the `matfile` crate (compressed or not). Writing (the simulator's need) is
//! a small hand-written MATLAB v5 writer: no crate writes v5 files. Each variable is stored as a
//! zlib-compressed `miMATRIX` element, as MATLAB's `save -v7` does; `scipy.io.loadmat` and
//! `matfile` read the result (tests and `scripts/` check both).

use flate2::write::ZlibEncoder;
use flate2::Compression;
use std::io::Write;
use std::path::{Path, PathBuf};

/// Errors of ground-truth input/output. Every variant names the file.
#[derive(Debug, thiserror::Error)]
pub enum GtError {
    /// The file could not be read or written.
    #[error("cannot access {path}")]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    /// The file is not a MATLAB v5 file `matfile` can parse.
    #[error("{path} is not a readable MATLAB v5 .mat file: {message}")]
    Parse { path: PathBuf, message: String },
    /// A variable is missing or has the wrong shape or type.
    #[error("{path}: variable '{name}' {problem}")]
    Variable {
        path: PathBuf,
        name: String,
        problem: String,
    },
}

/// The paths of one scan's ground truth under a DTU ground-truth root.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct GtPaths {
    /// `Points/stl/stl{scan:03}_total.ply`.
    pub points: PathBuf,
    /// `ObsMask/ObsMask{scan}_10.mat`.
    pub obs_mask: PathBuf,
    /// `ObsMask/Plane{scan}.mat`.
    pub plane: PathBuf,
}

impl GtPaths {
    /// The DTU file names for `scan` under `root`.
    pub fn new(root: &Path, scan: u32) -> Self {
        Self {
            points: root.join(format!("Points/stl/stl{scan:03}_total.ply")),
            obs_mask: root.join(format!("ObsMask/ObsMask{scan}_10.mat")),
            plane: root.join(format!("ObsMask/Plane{scan}.mat")),
        }
    }
}

/// DTU's observation mask: the voxels of a box that some camera observed.
#[derive(Clone, Debug, PartialEq)]
pub struct ObsMask {
    /// Voxel counts along x, y, z (MATLAB's `size(ObsMask)`).
    pub dims: [usize; 3],
    /// `dims[0]·dims[1]·dims[2]` flags in MATLAB column-major order: voxel `(i, j, k)` is at
    /// `i + dims[0]·(j + dims[1]·k)`.
    pub data: Vec<bool>,
    /// `BB`: row 0 the box's minimum corner, row 1 its maximum corner (world mm).
    pub bb: [[f64; 3]; 2],
    /// `Res`: the voxel edge length (mm).
    pub res: f64,
}

impl ObsMask {
    /// The flag of voxel `(i, j, k)`; `false` outside the grid.
    pub fn get(&self, i: i64, j: i64, k: i64) -> bool {
        let [nx, ny, nz] = self.dims.map(|d| d as i64);
        if i < 0 || j < 0 || k < 0 || i >= nx || j >= ny || k >= nz {
            return false;
        }
        self.data[(i + nx * (j + ny * k)) as usize]
    }

    /// Reads `ObsMask`, `BB` and `Res` from a `.mat` file.
    pub fn read(path: &Path) -> Result<Self, GtError> {
        let mat = parse(path)?;
        let mask = find(&mat, path, "ObsMask")?;
        if mask.size().len() != 3 {
            return Err(var_err(
                path,
                "ObsMask",
                format!("has shape {:?}, not 3-D", mask.size()),
            ));
        }
        let dims = [mask.size()[0], mask.size()[1], mask.size()[2]];
        let data = match mask.data() {
            matfile::NumericData::UInt8 { real, .. } => real.iter().map(|&v| v != 0).collect(),
            other => to_f64(other).into_iter().map(|v| v != 0.0).collect(),
        };
        let bb = to_f64(find(&mat, path, "BB")?.data());
        let bb_arr = find(&mat, path, "BB")?;
        if bb_arr.size() != &vec![2, 3] {
            return Err(var_err(
                path,
                "BB",
                format!("has shape {:?}, not 2×3", bb_arr.size()),
            ));
        }
        // Column-major 2×3: element (r, c) at r + 2c.
        let bb = [[bb[0], bb[2], bb[4]], [bb[1], bb[3], bb[5]]];
        let res = to_f64(find(&mat, path, "Res")?.data());
        let res = match res.as_slice() {
            [r] if r.is_finite() && *r > 0.0 => *r,
            _ => {
                return Err(var_err(
                    path,
                    "Res",
                    format!("is {res:?}, not one positive number"),
                ))
            }
        };
        Ok(Self {
            dims,
            data,
            bb,
            res,
        })
    }

    /// Writes `ObsMask` (logical), `BB` (double 2×3) and `Res` (double) to a `.mat` file.
    pub fn write(&self, path: &Path) -> Result<(), GtError> {
        assert_eq!(self.data.len(), self.dims.iter().product::<usize>());
        let bytes: Vec<u8> = self.data.iter().map(|&b| b as u8).collect();
        let bb = [
            self.bb[0][0],
            self.bb[1][0],
            self.bb[0][1],
            self.bb[1][1],
            self.bb[0][2],
            self.bb[1][2],
        ];
        write_mat(
            path,
            &[
                MatVar::logical("ObsMask", &self.dims, &bytes),
                MatVar::double("BB", &[2, 3], &bb),
                MatVar::double("Res", &[1, 1], &[self.res]),
            ],
        )
    }
}

/// A ground plane `P` (4-vector): a point `x` is above it when `[x, y, z, 1]·P > 0`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Plane(pub [f64; 4]);

impl Plane {
    /// Signed value `[x, y, z, 1]·P` (positive above the plane).
    pub fn eval(&self, p: [f64; 3]) -> f64 {
        p[0] * self.0[0] + p[1] * self.0[1] + p[2] * self.0[2] + self.0[3]
    }

    /// Reads `P` from a `.mat` file (any 4-element shape).
    pub fn read(path: &Path) -> Result<Self, GtError> {
        let mat = parse(path)?;
        let p = to_f64(find(&mat, path, "P")?.data());
        match p.as_slice() {
            [a, b, c, d] if p.iter().all(|v| v.is_finite()) => Ok(Plane([*a, *b, *c, *d])),
            _ => Err(var_err(
                path,
                "P",
                format!("is {p:?}, not 4 finite numbers"),
            )),
        }
    }

    /// Writes `P` as a double 4×1 column, as DTU's files hold it.
    pub fn write(&self, path: &Path) -> Result<(), GtError> {
        write_mat(path, &[MatVar::double("P", &[4, 1], &self.0)])
    }
}

fn parse(path: &Path) -> Result<matfile::MatFile, GtError> {
    let bytes = std::fs::read(path).map_err(|source| GtError::Io {
        path: path.into(),
        source,
    })?;
    let parse_err = |message: String| GtError::Parse {
        path: path.into(),
        message,
    };
    if let Some(why) = header_problem(&bytes) {
        return Err(parse_err(why));
    }
    matfile::MatFile::parse(bytes.as_slice()).map_err(|e| {
        parse_err(match truncation(&bytes) {
            Some(why) => format!("the file is truncated ({why}); copy it again"),
            // matfile's Debug form dumps the bytes it stopped at; its Display form says what
            // kind of failure it was.
            None => format!("its data elements do not parse ({e}); the file is damaged"),
        })
    })
}

/// Why `bytes` do not start like a MATLAB v5 file, if they do not: the 128-byte header ends
/// with the version and the endian indicator `IM` (little endian) or `MI` (big endian)
/// ("MAT-File Format", MathWorks, 2023: "MAT-File Header Format"). A short file whose text
/// begins "MATLAB" is a truncated one; a version 7.3 file is HDF5, which `matfile` does not read.
fn header_problem(bytes: &[u8]) -> Option<String> {
    let looks_matlab = bytes.starts_with(b"MATLAB");
    if bytes.len() < 128 {
        return Some(if looks_matlab {
            format!(
                "the file is truncated ({} bytes, less than the 128-byte header); copy it again",
                bytes.len()
            )
        } else {
            format!(
                "{} bytes, less than the 128-byte MATLAB header, and not starting with 'MATLAB': \
                 not a .mat file",
                bytes.len()
            )
        });
    }
    if bytes.starts_with(b"MATLAB 7.3") {
        return Some(
            "it is a MATLAB 7.3 file (HDF5), which cannot be read; save it again with \
             `save(..., '-v7')`"
                .into(),
        );
    }
    let indicator = &bytes[126..128];
    if indicator != b"IM" && indicator != b"MI" {
        return Some(format!(
            "no MATLAB v5 header: bytes 126-127 are {:#04x} {:#04x}, not the endian indicator \
             'IM' or 'MI'{}",
            indicator[0],
            indicator[1],
            if looks_matlab {
                ""
            } else {
                ", and the file does not start with 'MATLAB'"
            }
        ));
    }
    None
}

fn find<'a>(
    mat: &'a matfile::MatFile,
    path: &Path,
    name: &str,
) -> Result<&'a matfile::Array, GtError> {
    mat.find_by_name(name).ok_or_else(|| {
        match std::fs::read(path).ok().and_then(|b| truncation(&b)) {
            // matfile stops quietly at a cut-off element, so a truncated file looks like one whose
            // variables are missing; say what is really wrong.
            Some(why) => GtError::Parse {
                path: path.into(),
                message: format!("the file is truncated ({why}); copy it again"),
            },
            None => var_err(path, name, "is missing".into()),
        }
    })
}

/// Why a MATLAB v5 file is cut short, if it is: walks the top-level data elements (8-byte tag:
/// type and byte count, little- or big-endian per the header's `IM`/`MI` indicator; elements are
/// padded to 8 bytes except `miCOMPRESSED`, type 15) and reports the first one whose declared
/// size runs past the end of the file.
fn truncation(bytes: &[u8]) -> Option<String> {
    if bytes.len() < 128 {
        return Some(format!(
            "{} bytes, less than the 128-byte header",
            bytes.len()
        ));
    }
    let big = &bytes[126..128] == b"MI";
    let word = |at: usize| -> u32 {
        let b = [bytes[at], bytes[at + 1], bytes[at + 2], bytes[at + 3]];
        if big {
            u32::from_be_bytes(b)
        } else {
            u32::from_le_bytes(b)
        }
    };
    let mut at = 128usize;
    while at < bytes.len() {
        if at + 8 > bytes.len() {
            return Some(format!("a data element tag at byte {at} is cut off"));
        }
        let (ty, n) = (word(at), word(at + 4) as usize);
        if ty >> 16 != 0 {
            at += 8; // small data element: tag and data in 8 bytes
            continue;
        }
        let end = at + 8 + n;
        if end > bytes.len() {
            return Some(format!(
                "the data element at byte {at} declares {n} bytes, only {} remain",
                bytes.len() - at - 8
            ));
        }
        at = if ty == 15 { end } else { end.div_ceil(8) * 8 };
    }
    None
}

fn var_err(path: &Path, name: &str, problem: String) -> GtError {
    GtError::Variable {
        path: path.into(),
        name: name.into(),
        problem,
    }
}

fn to_f64(data: &matfile::NumericData) -> Vec<f64> {
    use matfile::NumericData as N;
    match data {
        N::Int8 { real, .. } => real.iter().map(|&v| v as f64).collect(),
        N::UInt8 { real, .. } => real.iter().map(|&v| v as f64).collect(),
        N::Int16 { real, .. } => real.iter().map(|&v| v as f64).collect(),
        N::UInt16 { real, .. } => real.iter().map(|&v| v as f64).collect(),
        N::Int32 { real, .. } => real.iter().map(|&v| v as f64).collect(),
        N::UInt32 { real, .. } => real.iter().map(|&v| v as f64).collect(),
        N::Int64 { real, .. } => real.iter().map(|&v| v as f64).collect(),
        N::UInt64 { real, .. } => real.iter().map(|&v| v as f64).collect(),
        N::Single { real, .. } => real.iter().map(|&v| v as f64).collect(),
        N::Double { real, .. } => real.clone(),
    }
}

// MATLAB v5 constants ("MAT-File Format", MathWorks, 2023: tables 1-2 and 1-3).
const MI_INT8: u32 = 1;
const MI_UINT8: u32 = 2;
const MI_INT32: u32 = 5;
const MI_UINT32: u32 = 6;
const MI_DOUBLE: u32 = 9;
const MI_MATRIX: u32 = 14;
const MI_COMPRESSED: u32 = 15;
const MX_DOUBLE_CLASS: u32 = 6;
const MX_UINT8_CLASS: u32 = 9;
const FLAG_LOGICAL: u32 = 0x02;

/// One variable to write: a real numeric array, column-major.
struct MatVar<'a> {
    name: &'a str,
    dims: Vec<usize>,
    class: u32,
    flags: u32,
    data_type: u32,
    data: Vec<u8>,
}

impl<'a> MatVar<'a> {
    fn double(name: &'a str, dims: &[usize], values: &[f64]) -> Self {
        Self {
            name,
            dims: dims.to_vec(),
            class: MX_DOUBLE_CLASS,
            flags: 0,
            data_type: MI_DOUBLE,
            data: values.iter().flat_map(|v| v.to_le_bytes()).collect(),
        }
    }

    fn logical(name: &'a str, dims: &[usize], values: &[u8]) -> Self {
        Self {
            name,
            dims: dims.to_vec(),
            class: MX_UINT8_CLASS,
            flags: FLAG_LOGICAL,
            data_type: MI_UINT8,
            data: values.to_vec(),
        }
    }

    /// The uncompressed `miMATRIX` element (tag included).
    fn matrix_element(&self) -> Vec<u8> {
        let mut body = Vec::new();
        // Array flags: class in the low byte, flags in the second byte; nzmax unused.
        let flags = (self.flags << 8) | self.class;
        sub_element(
            &mut body,
            MI_UINT32,
            &[flags.to_le_bytes(), 0u32.to_le_bytes()].concat(),
        );
        let dims: Vec<u8> = self
            .dims
            .iter()
            .flat_map(|&d| (d as i32).to_le_bytes())
            .collect();
        sub_element(&mut body, MI_INT32, &dims);
        sub_element(&mut body, MI_INT8, self.name.as_bytes());
        sub_element(&mut body, self.data_type, &self.data);
        let mut out = Vec::with_capacity(body.len() + 8);
        out.extend_from_slice(&MI_MATRIX.to_le_bytes());
        out.extend_from_slice(&(body.len() as u32).to_le_bytes());
        out.extend_from_slice(&body);
        out
    }
}

/// Appends a tagged sub-element padded to 8 bytes.
fn sub_element(out: &mut Vec<u8>, data_type: u32, data: &[u8]) {
    out.extend_from_slice(&data_type.to_le_bytes());
    out.extend_from_slice(&(data.len() as u32).to_le_bytes());
    out.extend_from_slice(data);
    out.resize(out.len().next_multiple_of(8), 0);
}

/// Writes a little-endian MATLAB v5 file with each variable zlib-compressed, atomically.
fn write_mat(path: &Path, vars: &[MatVar]) -> Result<(), GtError> {
    let io_err = |source| GtError::Io {
        path: path.into(),
        source,
    };
    let mut bytes = Vec::new();
    let mut text = format!(
        "MATLAB 5.0 MAT-file, Platform: neus-aug, Created by: dtu_eval {}",
        env!("CARGO_PKG_VERSION")
    )
    .into_bytes();
    text.resize(116, b' ');
    bytes.extend_from_slice(&text);
    bytes.extend_from_slice(&[0u8; 8]); // subsystem data offset: none
    bytes.extend_from_slice(&0x0100u16.to_le_bytes()); // version
    bytes.extend_from_slice(b"IM"); // 'MI' written little-endian
    for var in vars {
        let mut enc = ZlibEncoder::new(Vec::new(), Compression::default());
        enc.write_all(&var.matrix_element()).map_err(io_err)?;
        let z = enc.finish().map_err(io_err)?;
        bytes.extend_from_slice(&MI_COMPRESSED.to_le_bytes());
        bytes.extend_from_slice(&(z.len() as u32).to_le_bytes());
        bytes.extend_from_slice(&z);
    }
    if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).map_err(io_err)?;
    }
    crate::atomic::write_atomic(path, &bytes).map_err(io_err)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn obs_mask_round_trip_keeps_column_major_order() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("ObsMask/ObsMask7_10.mat");
        let dims = [3, 4, 5];
        let data: Vec<bool> = (0..60).map(|i| (i * 7) % 3 == 0 || i == 59).collect();
        let mask = ObsMask {
            dims,
            data,
            bb: [[-10.5, 0.0, 3.25], [20.0, 40.0, 53.25]],
            res: 10.0,
        };
        mask.write(&path).unwrap();
        let back = ObsMask::read(&path).unwrap();
        assert_eq!(back, mask);
        // (i, j, k) = (2, 3, 4) is the last voxel in column-major order.
        assert!(back.get(2, 3, 4));
        assert_eq!(back.get(1, 0, 0), mask.data[1]);
        assert_eq!(back.get(0, 1, 0), mask.data[3]);
        assert_eq!(back.get(0, 0, 1), mask.data[12]);
        assert!(!back.get(-1, 0, 0) && !back.get(3, 0, 0));
    }

    #[test]
    fn plane_round_trip() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("Plane7.mat");
        let plane = Plane([0.1, -0.2, 0.97, -512.25]);
        plane.write(&path).unwrap();
        assert_eq!(Plane::read(&path).unwrap(), plane);
        assert!(plane.eval([0.0, 0.0, 1000.0]) > 0.0);
    }

    #[test]
    fn missing_and_wrong_variables_are_named() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("Plane1.mat");
        write_mat(&path, &[MatVar::double("Q", &[4, 1], &[0.0; 4])]).unwrap();
        let err = Plane::read(&path).unwrap_err().to_string();
        assert!(err.contains("'P'") && err.contains("Plane1.mat"), "{err}");
        let err = ObsMask::read(&path).unwrap_err().to_string();
        assert!(err.contains("'ObsMask'"), "{err}");
        let err = ObsMask::read(&dir.path().join("nope.mat"))
            .unwrap_err()
            .to_string();
        assert!(err.contains("nope.mat"), "{err}");
        std::fs::write(&path, b"garbage").unwrap();
        assert!(matches!(Plane::read(&path), Err(GtError::Parse { .. })));
    }

    #[test]
    fn a_truncated_mat_file_says_truncated_not_missing() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("ObsMask3_10.mat");
        let mask = ObsMask {
            dims: [4, 3, 2],
            data: (0..24).map(|i| i % 3 == 0).collect(),
            bb: [[0.0, 0.0, 0.0], [4.0, 3.0, 2.0]],
            res: 1.0,
        };
        mask.write(&path).unwrap();
        let bytes = std::fs::read(&path).unwrap();
        assert!(
            truncation(&bytes).is_none(),
            "a whole file is not truncated"
        );
        for cut in [bytes.len() - 3, bytes.len() / 2, 150, 100] {
            std::fs::write(&path, &bytes[..cut]).unwrap();
            let err = ObsMask::read(&path).unwrap_err().to_string();
            assert!(
                err.contains("truncated") && !err.contains("missing"),
                "cut at {cut}: {err}"
            );
        }
    }

    #[test]
    fn random_bytes_and_other_formats_say_what_is_wrong_without_parser_dumps() {
        use rand::{Rng, SeedableRng};
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("Plane24.mat");
        let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(3);
        let random: Vec<u8> = (0..3000).map(|_| rng.random()).collect();
        let mut v73 = b"MATLAB 7.3 MAT-file, Platform: GLNXA64, Created on: ...".to_vec();
        v73.resize(512, b' ');
        v73.extend_from_slice(b"\x89HDF\r\n\x1a\n");
        // A valid header over random data elements.
        let mut damaged = std::fs::read({
            Plane([0.0, 0.0, 1.0, -1.0]).write(&path).unwrap();
            &path
        })
        .unwrap();
        damaged.truncate(128);
        damaged.extend_from_slice(&[14, 0, 0, 0, 24, 0, 0, 0]);
        damaged.extend_from_slice(&random[..24]);
        for (bytes, expect) in [
            (random.clone(), "bytes 126-127"),
            (random[..100].to_vec(), "not a .mat file"),
            (v73, "MATLAB 7.3"),
            (damaged, "do not parse"),
        ] {
            std::fs::write(&path, &bytes).unwrap();
            let err = crate::error::error_chain(&Plane::read(&path).unwrap_err());
            assert!(
                err.contains("Plane24.mat") && err.contains(expect),
                "{expect}: {err}"
            );
            for raw in ["ParseError", "input:", "code:"] {
                assert!(!err.contains(raw), "a parser dump in {err}");
            }
            assert!(err.len() < 300, "{err}");
        }
    }

    #[test]
    fn dtu_paths() {
        let p = GtPaths::new(Path::new("/gt"), 24);
        assert_eq!(p.points, Path::new("/gt/Points/stl/stl024_total.ply"));
        assert_eq!(p.obs_mask, Path::new("/gt/ObsMask/ObsMask24_10.mat"));
        assert_eq!(p.plane, Path::new("/gt/ObsMask/Plane24.mat"));
    }
}
