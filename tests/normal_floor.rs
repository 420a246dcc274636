//! `scripts/normal_floor.py`, the normal error a surface smooth at a scale r would score, on
//! meshes whose answer is known: a finely tessellated sphere has almost no normal variation
//! below a few mm, a cube's sharp edges have a lot, growing with r; a mesh without faces is
//! refused.

use std::fmt::Write;
use std::path::Path;
use std::process::Command;

/// An ASCII PLY of `vertices` and triangles `faces`.
fn write_ply(path: &Path, vertices: &[[f64; 3]], faces: &[[usize; 3]]) {
    let mut s = format!(
        "ply\nformat ascii 1.0\nelement vertex {}\nproperty float x\nproperty float y\n\
         property float z\nelement face {}\nproperty list uchar int vertex_indices\nend_header\n",
        vertices.len(),
        faces.len()
    );
    for v in vertices {
        writeln!(s, "{} {} {}", v[0], v[1], v[2]).unwrap();
    }
    for f in faces {
        writeln!(s, "3 {} {} {}", f[0], f[1], f[2]).unwrap();
    }
    std::fs::write(path, s).unwrap();
}

/// A cube of side `a` mm about the origin, faces outward.
fn cube(a: f64) -> (Vec<[f64; 3]>, Vec<[usize; 3]>) {
    let h = a / 2.0;
    let v: Vec<[f64; 3]> = (0..8)
        .map(|i| [i & 1, (i >> 1) & 1, (i >> 2) & 1].map(|b| if b == 1 { h } else { -h }))
        .collect();
    let quads = [
        [0, 2, 3, 1],
        [4, 5, 7, 6],
        [0, 1, 5, 4],
        [2, 6, 7, 3],
        [0, 4, 6, 2],
        [1, 3, 7, 5],
    ];
    let f = quads
        .iter()
        .flat_map(|q| [[q[0], q[1], q[2]], [q[0], q[2], q[3]]])
        .collect();
    (v, f)
}

/// A UV sphere of radius `r` mm, `n` rings and `2n` segments.
fn sphere(r: f64, n: usize) -> (Vec<[f64; 3]>, Vec<[usize; 3]>) {
    let m = 2 * n;
    let mut v = vec![[0.0, 0.0, r]];
    for i in 1..n {
        let th = std::f64::consts::PI * i as f64 / n as f64;
        for j in 0..m {
            let ph = 2.0 * std::f64::consts::PI * j as f64 / m as f64;
            v.push([
                r * th.sin() * ph.cos(),
                r * th.sin() * ph.sin(),
                r * th.cos(),
            ]);
        }
    }
    v.push([0.0, 0.0, -r]);
    let at = |i: usize, j: usize| 1 + (i - 1) * m + j % m;
    let mut f = Vec::new();
    for j in 0..m {
        f.push([0, at(1, j), at(1, j + 1)]);
        f.push([v.len() - 1, at(n - 1, j + 1), at(n - 1, j)]);
    }
    for i in 1..n - 1 {
        for j in 0..m {
            f.push([at(i, j), at(i + 1, j), at(i + 1, j + 1)]);
            f.push([at(i, j), at(i + 1, j + 1), at(i, j + 1)]);
        }
    }
    (v, f)
}

/// The script's table row of `name`: the angles in degrees, one per radius.
fn row(out: &str, name: &str) -> Vec<f64> {
    let line = out
        .lines()
        .find(|l| l.starts_with(&format!("| {name} |")))
        .unwrap_or_else(|| panic!("no row for {name} in:\n{out}"));
    line.split('|')
        .skip(4)
        .filter_map(|c| c.trim().trim_end_matches('°').parse().ok())
        .collect()
}

#[test]
fn a_sphere_is_smooth_a_cubes_edges_are_not_and_an_empty_mesh_is_refused() {
    if Command::new("python3").arg("--version").output().is_err() {
        eprintln!("SKIPPED normal_floor.py: python3 is not installed");
        return;
    }
    let tmp = tempfile::tempdir().unwrap();
    let (cv, cf) = cube(20.0);
    write_ply(&tmp.path().join("cube.ply"), &cv, &cf);
    let (sv, sf) = sphere(20.0, 64);
    write_ply(&tmp.path().join("sphere.ply"), &sv, &sf);
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("scripts/normal_floor.py");
    let out = Command::new("python3")
        .arg(&script)
        .args([
            "cube.ply",
            "sphere.ply",
            "--radii",
            "0.5,2",
            "--samples",
            "40000",
        ])
        .args(["--queries", "3000"])
        .current_dir(tmp.path())
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{text}\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let (c, s) = (row(&text, "cube.ply"), row(&text, "sphere.ply"));
    assert_eq!((c.len(), s.len()), (2, 2), "{text}");
    // The sphere's normal turns by r/R radians over a ball of radius r: under 6° at 2 mm.
    assert!(s.iter().all(|&a| a < 3.0), "sphere {s:?}");
    // The cube: flat faces, so only points within r of an edge count; more of them at 2 mm.
    assert!(c[1] > c[0] && c[1] > 2.0, "cube {c:?}");
    assert!(c[1] > 3.0 * s[1], "cube {c:?} against sphere {s:?}");

    write_ply(&tmp.path().join("empty.ply"), &cv, &[]);
    let out = Command::new("python3")
        .arg(&script)
        .arg("empty.ply")
        .current_dir(tmp.path())
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("no faces"));
}
