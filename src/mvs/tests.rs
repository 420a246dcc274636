//! Tests of the stereo on rendered planes, and the test rigs other modules' tests share.

use super::fuse::fuse;
use super::holes::{fill_holes, free_of_others, SurfelCloud};
use super::*;
use crate::scene::camera::{centred_intrinsics, look_at as look_at_up};

/// A camera at `c` looking at `target`, `w×h` pixels, focal `f` pixels, with `+z` up.
pub(crate) fn look_at(c: Vector3<f64>, target: Vector3<f64>, w: u32, h: u32, f: f64) -> Camera {
    look_at_up(c, target, Vector3::z(), centred_intrinsics(f, w, h), w, h)
}

/// A smooth texture on the plane `z = 0`.
fn texture(x: f64, y: f64) -> f64 {
    0.5 + 0.2 * (9.0 * x).sin() * (7.0 * y + 0.3).cos() + 0.15 * (13.0 * x - 5.0 * y).sin()
}

/// The image of the textured plane `z = 0` from `cam` (grey in every channel).
pub(crate) fn render_plane(cam: &Camera) -> RgbImage {
    let mut img = RgbImage::new(cam.width as usize, cam.height as usize);
    for y in 0..cam.height as usize {
        for x in 0..cam.width as usize {
            let (o, d) = cam.ray(x as f64 + 0.5, y as f64 + 0.5);
            let t = -o.z / d.z;
            let p = o + t * d;
            let g = texture(p.x, p.y) as f32;
            img.set(x, y, [g, g, g]);
        }
    }
    img
}

/// The true distance along the ray of `cam` through pixel `(u, v)` to the plane `z = 0`.
pub(crate) fn plane_t(cam: &Camera, u: f64, v: f64) -> f64 {
    let (o, d) = cam.ray(u, v);
    -o.z / d.z
}

/// Five cameras about 1.9 above the plane, looking at the origin.
pub(crate) fn rig() -> (Vec<Camera>, Vec<RgbImage>) {
    let cams: Vec<Camera> = [
        Vector3::new(0.0, -0.4, 1.9),
        Vector3::new(0.5, -0.3, 1.8),
        Vector3::new(-0.5, -0.2, 1.8),
        Vector3::new(0.1, 0.5, 1.8),
        Vector3::new(-0.3, 0.4, 1.85),
    ]
    .into_iter()
    .map(|c| look_at(c, Vector3::zeros(), 96, 80, 90.0))
    .collect();
    let imgs = cams.iter().map(render_plane).collect();
    (cams, imgs)
}

/// The stereo for this coarse rig: one plane step (2 / 128) is about 0.2 px of disparity
/// here, so depths agree to 1 % (`rel_tol`), not the 0.2 % of a 400 × 300 scene, and a
/// depth counts as right within `TOL` (about 0.3 px).
fn rig_cfg() -> MvsConfig {
    MvsConfig {
        rel_tol: 0.01,
        ..Default::default()
    }
}

const TOL: f64 = 0.03;

/// The stereo's view of `img` from `c` (grey = the red channel), every pixel masked.
fn view(c: &Camera, img: &RgbImage) -> View {
    View {
        w: img.width,
        h: img.height,
        grey: img.data.chunks_exact(3).map(|q| q[0]).collect(),
        k: c.k,
        kinv: c.k.try_inverse().unwrap(),
        r: c.r,
        c: c.center,
        mask: vec![true; img.width * img.height],
    }
}

/// The hole fill without the free-space check (every candidate passes).
fn fill_plain(
    cfg: &MvsConfig,
    w: usize,
    h: usize,
    mask: &[bool],
    grey: &[f32],
    z: &[f32],
) -> (Vec<f32>, Vec<bool>) {
    fill_holes(cfg, w, h, mask, grey, z, |_, _| true, |_, _| None)
}

fn no_fill() -> MvsConfig {
    MvsConfig {
        fuse_radius: 0.0,
        hole_radius: 0,
        ..rig_cfg()
    }
}

/// A `w × h` camera-`z` map from `f(x, y)`, NaN where `hole(x, y)`.
fn zmap(
    w: usize,
    h: usize,
    f: impl Fn(f64, f64) -> f64,
    hole: impl Fn(usize, usize) -> bool,
) -> Vec<f32> {
    (0..w * h)
        .map(|k| {
            let (x, y) = (k % w, k / w);
            if hole(x, y) {
                f32::NAN
            } else {
                f(x as f64, y as f64) as f32
            }
        })
        .collect()
}

/// Asserts that every pixel `(x, y)` of `xs × ys` in a `w`-wide map was filled (when
/// `must_fill`; otherwise every filled one) and lies within `rel` of `want(x, y)`.
#[allow(clippy::too_many_arguments)]
fn assert_fills(
    w: usize,
    out: &[f32],
    filled: &[bool],
    xs: std::ops::Range<usize>,
    ys: std::ops::Range<usize>,
    want: impl Fn(f64, f64) -> f64,
    rel: f64,
    must_fill: bool,
) {
    for y in ys {
        for x in xs.clone() {
            let k = y * w + x;
            assert!(filled[k] || !must_fill, "({x}, {y}) filled");
            let want = want(x as f64, y as f64);
            assert!(
                !filled[k] || (out[k] as f64 - want).abs() < rel * want,
                "({x}, {y}): {} against {want}",
                out[k]
            );
        }
    }
}

/// The slanted background of [`occluder_scene`] at pixel `(x, y)`.
fn far(x: f64, y: f64) -> f64 {
    1.0 / (0.3 + 0.0005 * x + 0.0002 * y)
}

/// A `40 × 21` map: an occluder at z = 2 left of x = 15; the slanted background [`far`]
/// right of x = 20; the columns 15..=20 between them (just behind the contour) empty.
fn occluder_scene() -> (usize, usize, Vec<f32>) {
    let (w, h) = (40, 21);
    let z = zmap(
        w,
        h,
        |x, y| if x < 15.0 { 2.0 } else { far(x, y) },
        |x, _| (15..=20).contains(&x),
    );
    (w, h, z)
}

#[test]
fn the_hole_fill_takes_the_background_behind_an_occluder() {
    let (w, h, z) = occluder_scene();
    let cfg = MvsConfig::default();
    let (out, filled) = fill_plain(&cfg, w, h, &vec![true; w * h], &vec![0.5; w * h], &z);
    assert_fills(w, &out, &filled, 15..21, 5..16, far, 0.02, true);
    assert!(
        (0..w * h).all(|k| !filled[k] || z[k].is_nan()),
        "only missing pixels are filled"
    );
    assert!((0..w * h)
        .filter(|&k| z[k].is_finite())
        .all(|k| out[k] == z[k]));
}

#[test]
fn the_free_space_check_passes_over_the_background_and_marches_when_all_fail() {
    // The check refuses every depth beyond 2.5 (the background), as other views seeing
    // past it would.
    let (w, h, z) = occluder_scene();
    let cfg = MvsConfig::default();
    let (mask, grey) = (vec![true; w * h], vec![0.5; w * h]);
    let near_only = |_: usize, zz: f64| zz < 2.5;
    let (out, filled) = fill_holes(&cfg, w, h, &mask, &grey, &z, near_only, |_, _| None);
    // Where the occluder's group was found too, it is the next candidate.
    assert!(filled.iter().filter(|&&f| f).count() > 20, "some filled");
    assert!((0..w * h)
        .filter(|&k| filled[k])
        .all(|k| (out[k] - 2.0).abs() < 1e-4));
    // With every candidate refused, the march is asked from the preferred one's depth
    // (the background's, > 2.5) and its answer taken.
    let asked = std::sync::Mutex::new(Vec::new());
    let cast = |k: usize, z0: f64| {
        asked.lock().unwrap().push((k, z0));
        Some(7.0)
    };
    let (out, filled) = fill_holes(&cfg, w, h, &mask, &grey, &z, |_, _| false, cast);
    let asked = asked.into_inner().unwrap();
    assert_eq!(asked.len(), filled.iter().filter(|&&f| f).count());
    assert!(asked
        .iter()
        .all(|&(k, z0)| filled[k] && out[k] == 7.0 && z0 > 2.5));
    assert!(
        asked.len() >= 6 * 11,
        "every pixel between the contours: {}",
        asked.len()
    );
    // A march that finds nothing leaves the pixel empty.
    let (out, filled) = fill_holes(&cfg, w, h, &mask, &grey, &z, |_, _| false, |_, _| None);
    assert!(!filled.iter().any(|&f| f));
    assert_eq!(
        out.iter().filter(|v| v.is_nan()).count(),
        z.iter().filter(|v| v.is_nan()).count()
    );
}

/// Per view, the camera-`z` map of the plane `z = 0` (NaN where `gap` holds at the hit).
fn plane_z(views: &[View], gap: impl Fn(&Vector3<f64>) -> bool) -> Vec<Vec<f32>> {
    views
        .iter()
        .map(|v| {
            (0..v.w * v.h)
                .map(|k| {
                    let d = v.dir((k % v.w) as f64 + 0.5, (k / v.w) as f64 + 0.5);
                    let z = -v.c.z / d.z;
                    if gap(&(v.c + d * z)) {
                        f32::NAN
                    } else {
                        z as f32
                    }
                })
                .collect()
        })
        .collect()
}

fn rig_views() -> Vec<View> {
    let (cams, imgs) = rig();
    cams.iter().zip(&imgs).map(|(c, i)| view(c, i)).collect()
}

#[test]
fn the_free_space_check_refuses_a_point_other_views_see_past() {
    let views = rig_views();
    let ev = plane_z(&views, |_| false);
    let cfg = MvsConfig::default();
    let at = |h: f64| Vector3::new(0.1, -0.05, h);
    assert!(
        free_of_others(&cfg, &views, &ev, 0, &at(0.0)),
        "on the plane"
    );
    assert!(
        free_of_others(&cfg, &views, &ev, 0, &at(0.01)),
        "within free_tol"
    );
    assert!(!free_of_others(&cfg, &views, &ev, 0, &at(0.3)), "in front");
    assert!(
        free_of_others(&cfg, &views, &ev, 0, &at(-0.3)),
        "hidden behind"
    );
    // With depths in one other view only, two views cannot see past it; one may be enough.
    let mut one = ev.clone();
    for m in &mut one[2..] {
        m.fill(f32::NAN);
    }
    assert!(free_of_others(&cfg, &views, &one, 0, &at(0.3)));
    let cfg1 = MvsConfig {
        free_views: 1,
        ..cfg
    };
    assert!(!free_of_others(&cfg1, &views, &one, 0, &at(0.3)));
    // The view's own depths are not evidence.
    for m in &mut one[1..] {
        m.fill(f32::NAN);
    }
    assert!(free_of_others(&cfg1, &views, &one, 0, &at(0.3)));
}

#[test]
fn the_march_crosses_the_plane_across_a_gap_narrower_than_its_radius() {
    let views = rig_views();
    let v = &views[0];
    // The centre pixel looks at the origin (the rig's target).
    let k = (v.h / 2) * v.w + v.w / 2;
    let d = v.dir((k % v.w) as f64 + 0.5, (k / v.w) as f64 + 0.5);
    let truth = -v.c.z / d.z;
    let gap = |r: f64| move |p: &Vector3<f64>| p.x.hypot(p.y) < r;
    let cloud = SurfelCloud::new(&views, &plane_z(&views, gap(0.1)), 0.25);
    let got = cloud
        .cast(v, k, 0.5 * truth, &|_| true)
        .expect("a crossing");
    assert!((got - truth).abs() < 1e-3 * truth, "{got} against {truth}");
    // What `ok` refuses is passed over; nothing lies beyond the plane.
    assert_eq!(cloud.cast(v, k, 0.5 * truth, &|_| false), None);
    assert_eq!(cloud.cast(v, k, 1.1 * truth, &|_| true), None);
    // A gap wider than the radius is left alone.
    let wide = SurfelCloud::new(&views, &plane_z(&views, gap(0.5)), 0.25);
    assert_eq!(wide.cast(v, k, 0.5 * truth, &|_| true), None);
    // Surfels seen only from the other side of the plane are not this ray's surface.
    let (cams, imgs) = rig();
    let below: Vec<View> = cams
        .iter()
        .zip(&imgs)
        .map(|(c, i)| {
            let m = Vector3::new(c.center.x, c.center.y, -c.center.z);
            view(&look_at(m, Vector3::zeros(), 96, 80, 90.0), i)
        })
        .collect();
    let under = SurfelCloud::new(&below, &plane_z(&below, |_| false), 0.25);
    assert!(under.p.len() > 100, "{} surfels", under.p.len());
    assert_eq!(under.cast(v, k, 0.5 * truth, &|_| true), None);
}

#[test]
fn the_refit_extends_a_receding_background_to_the_occluder() {
    // A background whose depth grows upwards (smaller y) above an occluder (z = 1.5, rows
    // 25 and below); rows 18..=24 have no depth. From (20, 22) the background is found
    // only along the three upward directions, all at row 17: collinear, so the group
    // gives row 17's depth, farther than the truth. The refit fits the window's rows
    // 12..=17 instead and continues the plane down to row 22.
    let (w, h) = (40, 40);
    let far = |_: f64, y: f64| 1.0 / (0.25 + 0.002 * y);
    let z = zmap(
        w,
        h,
        |x, y| if y >= 25.0 { 1.5 } else { far(x, y) },
        |_, y| (18..=24).contains(&y),
    );
    let (mask, grey) = (vec![true; w * h], vec![0.5; w * h]);
    let k = 22 * w + 20;
    let want = far(20.0, 22.0);
    let plain = MvsConfig {
        hole_refine: 0,
        ..MvsConfig::default()
    };
    let (group, f0) = fill_plain(&plain, w, h, &mask, &grey, &z);
    assert!(f0[k]);
    assert!(
        (group[k] as f64 - far(20.0, 17.0)).abs() < 1e-5 * want,
        "without the refit, row 17's depth: {} against {}",
        group[k],
        far(20.0, 17.0)
    );
    assert!(
        (group[k] as f64 - want) > 0.03 * want,
        "and behind the truth"
    );
    let cfg = MvsConfig::default();
    assert_eq!(cfg.hole_refine, 2, "the refit is the default");
    let (out, filled) = fill_plain(&cfg, w, h, &mask, &grey, &z);
    assert!(filled[k]);
    assert!(
        (out[k] as f64 - want).abs() < 1e-5 * want,
        "with the refit: {} against {want}",
        out[k]
    );
    // Every filled pixel of the band lies on the background's plane.
    assert_fills(w, &out, &filled, 5..35, 18..25, far, 1e-4, false);
}

#[test]
fn with_a_grey_tolerance_the_hole_fill_keeps_a_thin_part_in_front() {
    // A bar (z = 2, grey 0.8) over x = 17..=22 in front of a background (z = 3, grey 0.2);
    // the bar's right edge, x = 20..=22, has no depth.
    let (w, h) = (40, 21);
    let bar = |x: usize| (17..=22).contains(&x);
    let z = zmap(
        w,
        h,
        |x, _| if bar(x as usize) { 2.0 } else { 3.0 },
        |x, _| (20..=22).contains(&x),
    );
    let grey: Vec<f32> = (0..w * h)
        .map(|k| if bar(k % w) { 0.8 } else { 0.2 })
        .collect();
    let mask = vec![true; w * h];
    let k = 10 * w + 21;
    let plain_cfg = MvsConfig {
        hole_grey_tol: 0.0,
        ..MvsConfig::default()
    };
    let (plain, _) = fill_plain(&plain_cfg, w, h, &mask, &grey, &z);
    assert!(
        (plain[k] - 3.0).abs() < 1e-6,
        "background rule: {}",
        plain[k]
    );
    let cfg = MvsConfig::default();
    assert_eq!(cfg.hole_grey_tol, 0.1, "the grey rule is the default");
    let (out, filled) = fill_plain(&cfg, w, h, &mask, &grey, &z);
    assert!(
        filled[k] && (out[k] - 2.0).abs() < 1e-6,
        "grey rule: {}",
        out[k]
    );
    // A grey that matches no group leaves the pixel empty.
    let mut odd = grey.clone();
    odd[k] = 0.5;
    let (none, f) = fill_plain(&cfg, w, h, &mask, &odd, &z);
    assert!(none[k].is_nan() && !f[k]);
}

#[test]
fn the_hole_fill_recovers_a_slanted_plane_inside_a_patch() {
    // 1/z affine in the pixel coordinates is a plane in the camera frame.
    let (w, h) = (40, 40);
    let plane = |x: f64, y: f64| 1.0 / (0.3 + 0.0002 * x - 0.0001 * y);
    let z = zmap(w, h, plane, |x, y| {
        (17..24).contains(&x) && (17..24).contains(&y)
    });
    let (out, filled) = fill_plain(
        &MvsConfig::default(),
        w,
        h,
        &vec![true; w * h],
        &vec![0.5; w * h],
        &z,
    );
    assert_fills(w, &out, &filled, 17..24, 17..24, plane, 1e-5, true);
}

#[test]
fn the_hole_fill_leaves_what_it_cannot_reach_and_stays_in_the_mask() {
    let (w, h) = (40, 40);
    let cfg = MvsConfig {
        hole_radius: 5,
        ..MvsConfig::default()
    };
    // A 20 × 20 hole: its centre is more than 5 px from every depth.
    let z = zmap(
        w,
        h,
        |_, _| 3.0,
        |x, y| (10..30).contains(&x) && (10..30).contains(&y),
    );
    // The right half is outside the mask: nothing there is filled, and nothing is
    // looked for across it.
    let mask: Vec<bool> = (0..w * h).map(|k| k % w < 20).collect();
    let (out, filled) = fill_plain(&cfg, w, h, &mask, &vec![0.5; w * h], &z);
    assert!(
        out[20 * w + 19].is_nan() && !filled[20 * w + 19],
        "beyond reach"
    );
    assert!(filled[11 * w + 11] && (out[11 * w + 11] - 3.0).abs() < 1e-6);
    assert!((0..w * h).all(|k| mask[k] || !filled[k]));
    // One direction alone is not enough: a pixel whose only depth within reach lies
    // in one direction stays empty.
    let z1 = zmap(w, h, |_, _| 3.0, |x, _| x >= 1);
    let (out1, _) = fill_plain(&cfg, w, h, &vec![true; w * h], &vec![0.5; w * h], &z1);
    assert!(
        out1[20 * w + 3].is_finite(),
        "left, up-left and down-left reach x = 0"
    );
    let z2 = zmap(w, h, |_, _| 3.0, |x, y| !(x == 0 && y == 20));
    let (out2, _) = fill_plain(&cfg, w, h, &vec![true; w * h], &vec![0.5; w * h], &z2);
    assert!(out2[20 * w + 3].is_nan(), "one depth in one direction");
    assert!(
        fill_plain(
            &cfg,
            w,
            h,
            &vec![true; w * h],
            &vec![0.5; w * h],
            &vec![f32::NAN; w * h]
        )
        .1
        .iter()
        .all(|f| !f),
        "no depth anywhere: nothing filled"
    );
}

/// `(pixels with a depth, of them within tol of the plane)` in view `v`.
fn score(maps: &DepthMaps, cams: &[Camera], v: usize, tol: f64) -> (usize, usize) {
    let c = &cams[v];
    let (mut n, mut good) = (0, 0);
    for y in 0..c.height {
        for x in 0..c.width {
            if let Some(t) = maps.get(v, x, y) {
                n += 1;
                if (t - plane_t(c, x as f64 + 0.5, y as f64 + 0.5)).abs() < tol {
                    good += 1;
                }
            }
        }
    }
    (n, good)
}

#[test]
fn the_sweep_finds_the_plane_in_every_view() {
    let (cams, imgs) = rig();
    let maps = depth_maps(&no_fill(), &cams, &imgs, None);
    // A plane step is 2 / 128 ≈ 0.016; the parabola refines within it.
    for v in 0..cams.len() {
        let (n, good) = score(&maps, &cams, v, TOL);
        assert!(n > 96 * 80 / 2, "view {v}: {n} depths");
        assert!(
            good as f64 > 0.95 * n as f64,
            "view {v}: {good} of {n} within {TOL}"
        );
    }
    assert_eq!(maps.considered, 5 * 96 * 80);
    assert_eq!(maps.counts().1, 0, "no fill asked");
}

/// Five cameras low over the plane (about 25° above it, so their rays meet it at about 65°
/// from its normal), masked to where the plane lies within 0.8 of the origin.
pub(crate) fn grazing_rig() -> (Vec<Camera>, Vec<RgbImage>, Vec<GrayImage>) {
    let cams: Vec<Camera> = [-0.3f64, -0.15, 0.0, 0.15, 0.3]
        .into_iter()
        .map(|a| {
            let c = Vector3::new(1.9 * a.sin(), -1.9 * a.cos(), 0.9);
            look_at(c, Vector3::zeros(), 96, 80, 90.0)
        })
        .collect();
    let imgs = cams.iter().map(render_plane).collect();
    let masks = cams
        .iter()
        .map(|c| {
            let mut m = GrayImage::new(c.width as usize, c.height as usize);
            for y in 0..c.height as usize {
                for x in 0..c.width as usize {
                    let (o, d) = c.ray(x as f64 + 0.5, y as f64 + 0.5);
                    let t = plane_t(c, x as f64 + 0.5, y as f64 + 0.5);
                    let p = o + t * d;
                    let inside = t > 0.0 && p.x.hypot(p.y) < 0.8;
                    m.data[y * c.width as usize + x] = if inside { 1.0 } else { 0.0 };
                }
            }
            m
        })
        .collect();
    (cams, imgs, masks)
}

#[test]
fn slanted_windows_find_more_of_a_plane_seen_at_grazing_incidence() {
    let (cams, imgs, masks) = grazing_rig();
    let flat_cfg = MvsConfig {
        slant_iters: 0,
        ..no_fill()
    };
    let flat = depth_maps(&flat_cfg, &cams, &imgs, Some(&masks));
    let slanted = depth_maps(&no_fill(), &cams, &imgs, Some(&masks));
    assert_eq!(no_fill().slant_iters, 3, "the default");
    // Measured: the sweep keeps about 1 100 depths per view, 35–40 % of them within TOL;
    // the slanted windows about 1 870, all within TOL.
    for v in 0..cams.len() {
        let (n0, g0) = score(&flat, &cams, v, TOL);
        let (n1, g1) = score(&slanted, &cams, v, TOL);
        assert!(
            (g0 as f64) < 0.6 * n0 as f64,
            "view {v}: the sweep alone already finds {g0} of {n0}"
        );
        assert!(
            g1 as f64 > 0.95 * n1 as f64 && g1 > 2 * g0,
            "view {v}: slanted {g1} of {n1} within {TOL}, fronto-parallel {g0} of {n0}"
        );
    }
}

#[test]
fn consistency_drops_the_depths_of_a_view_with_a_wrong_pose() {
    let (mut cams, imgs) = rig();
    let before = depth_maps(&no_fill(), &cams, &imgs, None);
    let (n0, _) = score(&before, &cams, 0, TOL);
    // View 0's images stay; its camera moves 0.06 sideways (a bad pose estimate).
    cams[0].center.x += 0.06;
    let after = depth_maps(&no_fill(), &cams, &imgs, None);
    let (n1, _) = score(&after, &cams, 0, TOL);
    assert!(n1 * 5 < n0, "view 0 kept {n1} of {n0} depths");
    // The other views drop view 0 as a source (top_k of 4) or lose only what it backed.
    for v in 1..cams.len() {
        let (n, good) = score(&after, &cams, v, TOL);
        assert!(n > 96 * 80 / 3, "view {v}: {n} depths");
        assert!(good as f64 > 0.95 * n as f64, "view {v}: {good} of {n}");
    }
    // Without the check, view 0 keeps a depth at most pixels, mostly wrong.
    let raw = depth_maps(
        &MvsConfig {
            min_consistent: 0,
            ..no_fill()
        },
        &cams,
        &imgs,
        None,
    );
    let (nr, goodr) = score(&raw, &cams, 0, TOL);
    assert!(nr > 2 * n1 && goodr * 2 < nr, "raw: {goodr} of {nr} right");
}

#[test]
fn the_fill_takes_other_views_points_where_the_grey_matches() {
    let (cams, imgs) = rig();
    let cfg = MvsConfig::default();
    let views: Vec<View> = cams.iter().zip(&imgs).map(|(c, i)| view(c, i)).collect();
    // Exact camera depths everywhere, but none in a block of view 0.
    let mut z: Vec<Vec<f32>> = views
        .iter()
        .zip(&cams)
        .map(|(v, c)| {
            (0..v.w * v.h)
                .map(|k| {
                    let (u, vv) = ((k % v.w) as f64 + 0.5, (k / v.w) as f64 + 0.5);
                    (plane_t(c, u, vv) / v.dir(u, vv).norm()) as f32
                })
                .collect()
        })
        .collect();
    let block = |k: usize| (30..50).contains(&(k % 96)) && (30..45).contains(&(k / 96));
    let truth0 = z[0].clone();
    for (k, t) in z[0].iter_mut().enumerate() {
        if block(k) {
            *t = f32::NAN;
        }
    }
    let (out, filled) = fuse(&cfg, &views, &z);
    let nb = (0..96 * 80).filter(|&k| block(k)).count();
    let mut got = 0;
    for k in (0..96 * 80).filter(|&k| block(k)) {
        if filled[0][k] {
            got += 1;
            assert!((out[0][k] - truth0[k]).abs() < 0.01, "pixel {k}");
        }
    }
    assert!(got * 10 > nb * 9, "{got} of {nb} filled");
    assert!(
        (0..96 * 80).all(|k| (!filled[0][k] || block(k)) && !filled[1][k]),
        "only the missing pixels are filled"
    );
    // A pixel whose grey no point shares is left empty.
    let mut views = views;
    for k in (0..96 * 80).filter(|&k| block(k)) {
        views[0].grey[k] = 5.0;
    }
    let (out, filled) = fuse(&cfg, &views, &z);
    assert!((0..96 * 80)
        .filter(|&k| block(k))
        .all(|k| !filled[0][k] && out[0][k].is_nan()));
}

#[test]
fn the_fill_passes_over_a_nearer_cluster_of_another_grey() {
    // View 0 misses a pixel; nearer points (an occluder another view saw) project onto it
    // with another grey, the plane's points behind with its grey: the plane is taken.
    let (cams, imgs) = rig();
    let cfg = MvsConfig::default();
    let mk = view;
    let views: Vec<View> = vec![mk(&cams[0], &imgs[0]), mk(&cams[0], &imgs[0])];
    let k0 = 40 * 96 + 48;
    let t_plane = plane_t(&cams[0], 48.5, 40.5);
    let dn = views[0].dir(48.5, 40.5).norm();
    let mut z = vec![vec![f32::NAN; 96 * 80]; 2];
    // View 1 (the same pose) holds, at the same pixel, the plane's depth; the occluder is a
    // second copy of the pixel at half the depth with another grey (duplicated for support).
    z[1][k0] = (t_plane / dn) as f32;
    z[1][k0 + 1] = (t_plane / dn) as f32;
    let mut v1 = mk(&cams[0], &imgs[0]);
    v1.grey[k0 + 1] = views[0].grey[k0];
    let mut views = views;
    views[1] = v1;
    let occl = vec![f32::NAN; 96 * 80];
    let mut v2 = mk(&cams[0], &imgs[0]);
    let mut z2 = occl;
    z2[k0] = (0.5 * t_plane / dn) as f32;
    z2[k0 + 1] = (0.5 * t_plane / dn) as f32;
    v2.grey[k0] = views[0].grey[k0] + 0.3;
    v2.grey[k0 + 1] = views[0].grey[k0] + 0.3;
    views.push(v2);
    z.push(z2);
    let cfg = MvsConfig {
        fuse_radius: 1.5,
        fuse_grey_tol: 0.05,
        ..cfg
    };
    let (out, filled) = fuse(&cfg, &views, &z);
    assert!(filled[0][k0], "filled");
    let t = out[0][k0] as f64 * dn;
    assert!(
        (t - t_plane).abs() < 1e-4,
        "{t} against the plane's {t_plane}"
    );
    // With the occluder's grey equal to the pixel's, it is taken instead (nearest first).
    views[2].grey[k0] = views[0].grey[k0];
    views[2].grey[k0 + 1] = views[0].grey[k0];
    let (out, _) = fuse(&cfg, &views, &z);
    assert!((out[0][k0] as f64 * dn - 0.5 * t_plane).abs() < 1e-4);
}

#[test]
fn empty_masks_and_nan_pixels_give_no_depth_there_and_nothing_non_finite() {
    let (cams, mut imgs) = rig();
    let empty: Vec<GrayImage> = cams
        .iter()
        .map(|c| GrayImage::new(c.width as usize, c.height as usize))
        .collect();
    let maps = depth_maps(&MvsConfig::default(), &cams, &imgs, Some(&empty));
    assert_eq!((maps.considered, maps.counts()), (0, (0, 0)));
    // NaN pixels in a block of view 0: no depth within the window of them, depths elsewhere.
    for y in 30..40 {
        for x in 40..50 {
            imgs[0].set(x, y, [f32::NAN; 3]);
        }
    }
    let maps = depth_maps(&no_fill(), &cams, &imgs, None);
    for y in 28..42u32 {
        for x in 38..52u32 {
            assert!(
                maps.get(0, x, y).is_none(),
                "depth next to NaN at ({x}, {y})"
            );
        }
    }
    let (n, good) = score(&maps, &cams, 0, TOL);
    assert!(
        n > 96 * 80 / 3 && good as f64 > 0.95 * n as f64,
        "{good} of {n}"
    );
    assert!(maps
        .t
        .iter()
        .flatten()
        .all(|t| t.is_nan() || (t.is_finite() && *t > 0.0)));
    let filled = depth_maps(&rig_cfg(), &cams, &imgs, None);
    assert!(filled
        .t
        .iter()
        .flatten()
        .all(|t| t.is_nan() || t.is_finite()));
    assert!(
        filled.get(0, 45, 35).is_none(),
        "a NaN pixel is never filled"
    );
}
