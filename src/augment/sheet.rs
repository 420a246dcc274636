//! A contact sheet: one view under every manipulation and degradation, to look at before training.

use super::{AugmentConfig, AugmentError, Degradation, DegradationKind, ImageOp, Manipulation};
use crate::scene::image::RgbImage;
use rand::SeedableRng;
use rand_pcg::Pcg64Mcg;

/// Gap between cells, pixels.
const GAP: usize = 4;
/// Background (gap) gray level.
const BACKGROUND: f32 = 0.2;
/// Cells per row.
const COLUMNS: usize = 6;

/// The sheet image and a legend naming each cell.
#[derive(Clone, Debug)]
pub struct ContactSheet {
    /// The grid, `rows × 6` cells of the view's size separated by 4-pixel gaps.
    pub image: RgbImage,
    /// `(row, column, spec, note)` per cell, row-major; `spec` parses as an [`ImageOp`].
    pub cells: Vec<(usize, usize, String, String)>,
}

impl ContactSheet {
    /// The legend as text, one line per cell, with a header explaining the layout.
    pub fn legend(&self) -> String {
        let mut s = String::from(
            "# neus-aug augment contact sheet: rows top to bottom, columns left to right.\n\
             # Rows 0-4: one manipulation each at p = -w/2, -w/4, 0, +w/4, +w/2 (the DIA range)\n\
             # and the SIA intensity p_i. Row 5: degradations at the paper's default q; row 6: at\n\
             # its milder q (column 0 of rows 5-6: the original).\n",
        );
        for (r, c, spec, note) in &self.cells {
            s.push_str(&format!("row {r} col {c}: {spec:<22} {note}\n"));
        }
        s
    }
}

/// Builds the contact sheet of `view` (`[h][w][3]` in `[0, 1]`) under `cfg`'s DIA widths and SIA
/// intensities; random degradations use streams seeded from `seed` (one per cell).
pub fn contact_sheet(
    view: &RgbImage,
    cfg: &AugmentConfig,
    seed: u64,
) -> Result<ContactSheet, AugmentError> {
    cfg.validate()?;
    if view.is_empty() {
        return Err(AugmentError::NoImages {
            reason: "the contact sheet's view has no pixels".into(),
        });
    }
    let mut grid: Vec<(ImageOp, String)> = Vec::new();
    for m in Manipulation::NON_IDENTITY {
        let w = cfg.dia_width.get(m);
        for (k, note) in [
            (-0.5, "DIA lower end"),
            (-0.25, ""),
            (0.0, "original"),
            (0.25, ""),
            (0.5, "DIA upper end"),
        ] {
            grid.push((ImageOp::Manipulate(m, k * w), note.to_string()));
        }
        grid.push((
            ImageOp::Manipulate(m, cfg.sia_p.get(m)),
            "SIA replica".to_string(),
        ));
    }
    for (mild, note) in [(false, "default q"), (true, "mild q")] {
        grid.push((
            ImageOp::Manipulate(Manipulation::Identity, 0.0),
            "original".into(),
        ));
        for kind in DegradationKind::ALL {
            let q = if mild {
                kind.mild_q()
            } else {
                kind.default_q()
            };
            let d = Degradation::new(kind, q)?;
            grid.push((ImageOp::Degrade(d), note.to_string()));
        }
    }

    let rows = grid.len() / COLUMNS;
    let (cw, ch) = (view.width, view.height);
    let mut image = RgbImage::from_fn(
        COLUMNS * cw + (COLUMNS + 1) * GAP,
        rows * ch + (rows + 1) * GAP,
        |_, _| [BACKGROUND; 3],
    );
    let mut cells = Vec::with_capacity(grid.len());
    for (i, (op, note)) in grid.iter().enumerate() {
        let (r, c) = (i / COLUMNS, i % COLUMNS);
        let mut rng = Pcg64Mcg::seed_from_u64(seed.wrapping_add(i as u64));
        let cell = op.apply(view, &mut rng);
        let (x0, y0) = (GAP + c * (cw + GAP), GAP + r * (ch + GAP));
        for y in 0..ch {
            for x in 0..cw {
                image.set(x0 + x, y0 + y, cell.get(x, y));
            }
        }
        cells.push((r, c, op.to_string(), note.clone()));
    }
    Ok(ContactSheet { image, cells })
}

/// Shrinks `img` by the smallest integer factor that makes both sides `≤ max_side` (box average
/// of `factor × factor` blocks; trailing rows/columns that do not fill a block are dropped).
/// Returns a copy when it already fits. `max_side` must be at least 1.
pub fn downscale_to_fit(img: &RgbImage, max_side: usize) -> RgbImage {
    let max_side = max_side.max(1);
    let factor = img.width.max(img.height).div_ceil(max_side);
    if factor <= 1 {
        return img.clone();
    }
    let (w, h) = ((img.width / factor).max(1), (img.height / factor).max(1));
    RgbImage::from_fn(w, h, |x, y| {
        let mut acc = [0.0f32; 3];
        let mut n = 0.0f32;
        for yy in y * factor..((y + 1) * factor).min(img.height) {
            for xx in x * factor..((x + 1) * factor).min(img.width) {
                let c = img.get(xx, yy);
                for ch in 0..3 {
                    acc[ch] += c[ch];
                }
                n += 1.0;
            }
        }
        acc.map(|a| a / n)
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sheet_layout_cells_and_contents() {
        let view = RgbImage::from_fn(10, 8, |x, y| [x as f32 / 10.0, y as f32 / 8.0, 0.6]);
        let cfg = AugmentConfig::default();
        let sheet = contact_sheet(&view, &cfg, 1).unwrap();
        assert_eq!(sheet.cells.len(), 42);
        assert_eq!(sheet.image.width, 6 * 10 + 7 * GAP);
        assert_eq!(sheet.image.height, 7 * 8 + 8 * GAP);
        // Every spec parses back, and each cell holds exactly what its spec produces.
        for (i, (r, c, spec, _)) in sheet.cells.iter().enumerate() {
            let op: ImageOp = spec.parse().unwrap_or_else(|e| panic!("{spec}: {e}"));
            let mut rng = Pcg64Mcg::seed_from_u64(1 + i as u64);
            let expect = op.apply(&view, &mut rng);
            let (x0, y0) = (GAP + c * (10 + GAP), GAP + r * (8 + GAP));
            for y in 0..8 {
                for x in 0..10 {
                    assert_eq!(
                        sheet.image.get(x0 + x, y0 + y),
                        expect.get(x, y),
                        "cell {spec}"
                    );
                }
            }
        }
        // Column 2 of the manipulation rows is the original (p = 0).
        assert_eq!(sheet.cells[2].2, "brightness:0");
        assert!(sheet.legend().contains("row 5 col 1: gaussian:0.1"));
        assert!(sheet.legend().contains("row 6 col 3: poisson:100"));
    }

    #[test]
    fn downscale_averages_blocks() {
        let img = RgbImage::from_fn(8, 4, |x, _| [x as f32 / 8.0, 0.0, 1.0]);
        let small = downscale_to_fit(&img, 4);
        assert_eq!((small.width, small.height), (4, 2));
        assert!((small.get(1, 0)[0] - 2.5 / 8.0).abs() < 1e-6);
        assert_eq!(downscale_to_fit(&img, 8), img);
    }
}
