use super::*;

#[test]
fn every_procedural_shape_is_closed_outward_and_moderate() {
    for shape in Shape::ALL {
        let m = procedural(shape);
        assert!(m.is_closed_oriented(), "{shape:?} is not closed/oriented");
        assert!(m.signed_volume6() > 0.0, "{shape:?} points inwards");
        assert!(
            m.faces.len() <= 200_000,
            "{shape:?}: {} faces",
            m.faces.len()
        );
        assert!(m.vertices.iter().flatten().all(|c| c.is_finite()));
        // No degenerate triangle.
        let min_area = m
            .faces
            .iter()
            .map(|f| {
                let [a, b, c] = f.map(|i| m.vertices[i as usize]);
                norm(cross(sub(b, a), sub(c, a)))
            })
            .fold(f64::INFINITY, f64::min);
        assert!(min_area > 1e-6, "{shape:?}: degenerate triangle {min_area}");
    }
}

#[test]
fn genus_follows_euler_characteristic() {
    // For a closed orientable surface, V − E + F = 2 − 2g (per component).
    let genus = |m: &Mesh| {
        let e = m.faces.len() * 3 / 2;
        let chi = m.vertices.len() as i64 - e as i64 + m.faces.len() as i64;
        (2 - chi) / 2
    };
    assert_eq!(genus(&procedural(Shape::Blob)), 0);
    assert_eq!(genus(&procedural(Shape::Torus)), 1);
    assert_eq!(genus(&procedural(Shape::Cup)), 0);
    assert_eq!(genus(&procedural(Shape::Relief)), 0);
    assert_eq!(genus(&procedural(Shape::DoubleTorus)), 2);
    assert_eq!(genus(&procedural(Shape::Plate)), 0);
    assert_eq!(genus(&procedural(Shape::Rods)), 5);
}

#[test]
fn thin_structures_are_about_one_and_a_half_percent_of_the_size() {
    let m = procedural(Shape::Thin).centre_and_scale(100.0).unwrap();
    let (lo, hi) = m.bounds();
    let size = (0..3).map(|k| hi[k] - lo[k]).fold(0.0, f64::max);
    // Rod radius 1.5 mm before scaling; the scale factor is 100 / bounding radius.
    let raw = procedural(Shape::Thin);
    let (rlo, rhi) = raw.bounds();
    let c = scale(add(rlo, rhi), 0.5);
    let r = raw
        .vertices
        .iter()
        .map(|v| norm(sub(*v, c)))
        .fold(0.0, f64::max);
    let diameter = 3.0 * 100.0 / r;
    let frac = diameter / size;
    assert!(
        (0.01..=0.02).contains(&frac),
        "rod diameter {diameter} mm / size {size} mm"
    );
}

#[test]
fn obj_reader_handles_slashes_negatives_and_polygons() {
    let m = parse_obj("# c\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1/1/1 2//2 3 -1\n").unwrap();
    assert_eq!(m.faces, vec![[0, 1, 2], [0, 2, 3]]);
    assert!(parse_obj("v 0 0 0\nf 1 2 3\n")
        .unwrap_err()
        .contains("line 2"));
    assert!(parse_obj("v 0 x 0\n").unwrap_err().contains("'x'"));
}
