//! PNG plots of a study (plotters' bitmap backend into memory, PNG-encoded with `image`).
//!
//! Text uses the bundled DejaVu Sans subset (`assets/fonts/`, Bitstream Vera licence) through
//! plotters' `ab_glyph` backend, so plots look the same on every machine and need no system
//! font. Rendering and encoding are deterministic: the same data give the same bytes.

use super::StudyError;
use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::FontStyle;
use std::path::PathBuf;
use std::sync::Once;

/// Image size, pixels.
pub const WIDTH: u32 = 1000;
pub const HEIGHT: u32 = 600;
const FONT: &str = "sans-serif";
const FONT_BYTES: &[u8] = include_bytes!("../../assets/fonts/DejaVuSans-subset.ttf");

/// Series colours (colour-blind-safe muted palette), in arm order.
const COLOURS: [RGBColor; 6] = [
    RGBColor(0x4c, 0x72, 0xb0),
    RGBColor(0xdd, 0x84, 0x52),
    RGBColor(0x55, 0xa8, 0x68),
    RGBColor(0xc4, 0x4e, 0x52),
    RGBColor(0x81, 0x72, 0xb3),
    RGBColor(0x93, 0x78, 0x60),
];

fn colour(i: usize) -> RGBColor {
    COLOURS[i % COLOURS.len()]
}

fn ensure_font() {
    static ONCE: Once = Once::new();
    ONCE.call_once(|| {
        // The font is compiled in; a failure here would show as a drawing error below.
        let _ = plotters::style::register_font(FONT, FontStyle::Normal, FONT_BYTES);
    });
}

type Area<'a> = DrawingArea<BitMapBackend<'a>, Shift>;

/// Draws with `f` on a white `WIDTH × HEIGHT` canvas and returns the PNG bytes.
fn render(
    name: &str,
    f: impl FnOnce(&Area<'_>) -> Result<(), String>,
) -> Result<Vec<u8>, StudyError> {
    ensure_font();
    let err = |message: String| StudyError::Plot {
        path: PathBuf::from(name),
        message,
    };
    let mut buf = vec![255u8; (WIDTH * HEIGHT * 3) as usize];
    {
        let root = BitMapBackend::with_buffer(&mut buf, (WIDTH, HEIGHT)).into_drawing_area();
        root.fill(&WHITE).map_err(|e| err(e.to_string()))?;
        f(&root).map_err(err)?;
        root.present().map_err(|e| err(e.to_string()))?;
    }
    let mut png = Vec::new();
    use image::ImageEncoder;
    image::codecs::png::PngEncoder::new(&mut png)
        .write_image(&buf, WIDTH, HEIGHT, image::ExtendedColorType::Rgb8)
        .map_err(|e| err(e.to_string()))?;
    Ok(png)
}

fn s<E: std::fmt::Display>(e: E) -> String {
    e.to_string()
}

/// The series legend every chart here uses: upper right, framed, on a translucent white box.
fn legend<'a, CT: CoordTranslate>(
    chart: &mut ChartContext<'a, BitMapBackend<'a>, CT>,
) -> Result<(), String> {
    chart
        .configure_series_labels()
        .position(SeriesLabelPosition::UpperRight)
        .label_font((FONT, 15))
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .draw()
        .map_err(s)
}

/// Grouped bars with error bars: `values[group][series] = Some((mean, half-height))`.
pub struct Bars {
    pub title: String,
    pub y_label: String,
    pub groups: Vec<String>,
    pub series: Vec<String>,
    pub values: Vec<Vec<Option<(f64, f64)>>>,
}

/// A grouped bar chart (PNG bytes).
pub fn bar_chart(name: &str, b: &Bars) -> Result<Vec<u8>, StudyError> {
    render(name, |root| {
        let ng = b.groups.len().max(1);
        let ns = b.series.len().max(1);
        let top = b
            .values
            .iter()
            .flatten()
            .flatten()
            .map(|(m, e)| m + e.max(0.0))
            .fold(0.0f64, f64::max);
        let top = if top > 0.0 { top * 1.18 } else { 1.0 };
        // Group names that do not fit their slot side by side are drawn upright (reading bottom
        // to top), with a label band as deep as the longest name.
        let label_font = (FONT, 14).into_font();
        let measure = TextStyle::from(label_font.clone());
        let sizes = b
            .groups
            .iter()
            .map(|g| root.estimate_text_size(g, &measure).map_err(s))
            .collect::<Result<Vec<(u32, u32)>, String>>()?;
        let widest = sizes.iter().map(|z| z.0).max().unwrap_or(0);
        let slot = (WIDTH - 70 - 2 * 16) as f64 / ng as f64;
        let upright = widest as f64 > 0.95 * slot;
        let label_band = if upright {
            (widest + 16).min(HEIGHT / 3)
        } else {
            44
        };
        let mut chart = ChartBuilder::on(root)
            .caption(&b.title, (FONT, 22))
            .margin(16)
            .x_label_area_size(label_band)
            .y_label_area_size(70)
            .build_cartesian_2d(-0.5f64..(ng as f64 - 0.5), 0f64..top)
            .map_err(s)?;
        chart
            .configure_mesh()
            .disable_x_mesh()
            .x_labels(0)
            .y_desc(b.y_label.as_str())
            .axis_desc_style((FONT, 16))
            .label_style((FONT, 14))
            .draw()
            .map_err(s)?;
        let w = 0.8 / ns as f64;
        for (k, name) in b.series.iter().enumerate() {
            let c = colour(k);
            let bars: Vec<Rectangle<(f64, f64)>> = b
                .values
                .iter()
                .enumerate()
                .filter_map(|(g, row)| {
                    let (m, _) = (*row.get(k)?)?;
                    let x0 = g as f64 - 0.4 + k as f64 * w;
                    Some(Rectangle::new(
                        [(x0 + 0.05 * w, 0.0), (x0 + 0.95 * w, m)],
                        c.filled(),
                    ))
                })
                .collect();
            chart
                .draw_series(bars)
                .map_err(s)?
                .label(name.as_str())
                .legend(move |(x, y)| Rectangle::new([(x, y - 6), (x + 14, y + 6)], c.filled()));
            let mut whiskers = Vec::new();
            for (g, row) in b.values.iter().enumerate() {
                if let Some(Some((m, e))) = row.get(k) {
                    if *e > 0.0 {
                        let x = g as f64 - 0.4 + (k as f64 + 0.5) * w;
                        let cap = 0.2 * w;
                        whiskers.push(PathElement::new(
                            vec![(x, m - e), (x, m + e)],
                            BLACK.stroke_width(1),
                        ));
                        whiskers.push(PathElement::new(
                            vec![(x - cap, m + e), (x + cap, m + e)],
                            BLACK.stroke_width(1),
                        ));
                        whiskers.push(PathElement::new(
                            vec![(x - cap, m - e), (x + cap, m - e)],
                            BLACK.stroke_width(1),
                        ));
                    }
                }
            }
            chart.draw_series(whiskers).map_err(s)?;
        }
        legend(&mut chart)?;
        // Group names under the axis, centred on their groups.
        use plotters::style::text_anchor::{HPos, Pos, VPos};
        let flat = TextStyle::from(label_font.clone())
            .color(&BLACK)
            .pos(Pos::new(HPos::Center, VPos::Top));
        // Rotate270 maps the glyph's (x, y) to (y, -x) about the anchor: the text runs upwards
        // from the anchor and lies to its right, so the anchor is the name's lower left corner.
        let turned = TextStyle::from(label_font.transform(FontTransform::Rotate270))
            .color(&BLACK)
            .pos(Pos::new(HPos::Left, VPos::Top));
        for (g, (label, &(w, h))) in b.groups.iter().zip(&sizes).enumerate() {
            let (px, py) = chart.backend_coord(&(g as f64, 0.0));
            if upright {
                let at = (px - h as i32 / 2, py + 8 + w as i32);
                root.draw(&Text::new(label.as_str(), at, turned.clone()))
                    .map_err(s)?;
            } else {
                root.draw(&Text::new(label.as_str(), (px, py + 8), flat.clone()))
                    .map_err(s)?;
            }
        }
        Ok(())
    })
}

/// One line: its name and `(x, mean, half-height of the error bar)` points.
pub type Series = (String, Vec<(f64, f64, f64)>);

/// Lines with points and error bars.
pub struct Lines {
    pub title: String,
    pub x_label: String,
    pub y_label: String,
    pub series: Vec<Series>,
}

/// A line chart (PNG bytes).
pub fn line_chart(name: &str, l: &Lines) -> Result<Vec<u8>, StudyError> {
    render(name, |root| {
        let pts = l.series.iter().flat_map(|(_, p)| p.iter());
        let (mut x0, mut x1, mut y1) = (f64::INFINITY, f64::NEG_INFINITY, 0.0f64);
        for &(x, m, e) in pts {
            x0 = x0.min(x);
            x1 = x1.max(x);
            y1 = y1.max(m + e.max(0.0));
        }
        if !x0.is_finite() {
            (x0, x1) = (0.0, 1.0);
        }
        let pad = ((x1 - x0) * 0.06).max(1e-3);
        let y1 = if y1 > 0.0 { y1 * 1.15 } else { 1.0 };
        let mut chart = ChartBuilder::on(root)
            .caption(&l.title, (FONT, 22))
            .margin(16)
            .x_label_area_size(50)
            .y_label_area_size(70)
            .build_cartesian_2d((x0 - pad)..(x1 + pad), 0f64..y1)
            .map_err(s)?;
        chart
            .configure_mesh()
            .x_desc(l.x_label.as_str())
            .y_desc(l.y_label.as_str())
            .axis_desc_style((FONT, 16))
            .label_style((FONT, 14))
            .draw()
            .map_err(s)?;
        // Series are nudged sideways by a small fraction of the x range so their error bars do
        // not hide each other.
        let ns = l.series.len().max(1) as f64;
        let dodge = |k: usize| (k as f64 - (ns - 1.0) / 2.0) * 0.012 * (x1 - x0 + 2.0 * pad);
        let cap = 0.006 * (x1 - x0 + 2.0 * pad);
        for (k, (name, p)) in l.series.iter().enumerate() {
            let c = colour(k);
            let dx = dodge(k);
            chart
                .draw_series(LineSeries::new(
                    p.iter().map(|&(x, m, _)| (x + dx, m)),
                    c.stroke_width(2),
                ))
                .map_err(s)?
                .label(name.as_str())
                .legend(move |(x, y)| {
                    PathElement::new(vec![(x, y), (x + 18, y)], c.stroke_width(2))
                });
            chart
                .draw_series(
                    p.iter()
                        .map(|&(x, m, _)| Circle::new((x + dx, m), 4, c.filled())),
                )
                .map_err(s)?;
            let mut bars: Vec<PathElement<(f64, f64)>> = Vec::new();
            for &(x, m, e) in p.iter().filter(|(_, _, e)| *e > 0.0) {
                let x = x + dx;
                bars.push(PathElement::new(
                    vec![(x, m - e), (x, m + e)],
                    c.stroke_width(1),
                ));
                for y in [m - e, m + e] {
                    bars.push(PathElement::new(
                        vec![(x - cap, y), (x + cap, y)],
                        c.stroke_width(1),
                    ));
                }
            }
            chart.draw_series(bars).map_err(s)?;
        }
        legend(&mut chart)?;
        Ok(())
    })
}

/// A point of the accuracy-against-time plot.
pub struct ParetoPoint {
    /// Seconds (log axis).
    pub time: f64,
    /// mm.
    pub chamfer: f64,
    pub label: String,
    /// A preset (drawn large, in red).
    pub preset: bool,
    pub on_front: bool,
}

/// Another study's Pareto front drawn beside this one's (`study collect --reference-front`):
/// an older build, another machine, another recipe.
#[derive(Clone, Debug)]
pub struct ReferenceFront {
    /// Legend entry.
    pub label: String,
    /// Every point of the reference study, (time to mesh in s, Chamfer in mm).
    pub points: Vec<(f64, f64)>,
    /// Which of `points` are on its front (same length as `points`).
    pub on_front: Vec<bool>,
}

/// The staircase through a front's points: sorted by time, each step holding the previous
/// point's error until the next point's time.
fn staircase(mut front: Vec<(f64, f64)>) -> Vec<(f64, f64)> {
    front.sort_by(|a, b| a.0.total_cmp(&b.0));
    let mut stair = Vec::new();
    for (i, &(t, c)) in front.iter().enumerate() {
        if i > 0 {
            stair.push((t, front[i - 1].1));
        }
        stair.push((t, c));
    }
    stair
}

/// Chamfer against time to mesh, log time axis, the Pareto front as a staircase, presets
/// marked, and optionally a reference study's front beside it (hollow points, its own colour)
/// (PNG bytes).
pub fn pareto_chart(
    title: &str,
    pts: &[ParetoPoint],
    reference: Option<&ReferenceFront>,
) -> Result<Vec<u8>, StudyError> {
    render("pareto.png", |root| {
        let (mut t0, mut t1, mut c1) = (f64::INFINITY, 0.0f64, 0.0f64);
        let all = pts
            .iter()
            .map(|p| (p.time, p.chamfer))
            .chain(reference.iter().flat_map(|r| r.points.iter().copied()));
        for (t, c) in all {
            t0 = t0.min(t);
            t1 = t1.max(t);
            c1 = c1.max(c);
        }
        if !t0.is_finite() || t0 <= 0.0 {
            (t0, t1) = (1.0, 10.0);
        }
        let (t0, t1) = (t0 / 1.4, t1 * 1.4);
        let c1 = if c1 > 0.0 { c1 * 1.15 } else { 1.0 };
        let mut chart = ChartBuilder::on(root)
            .caption(title, (FONT, 22))
            .margin(16)
            .x_label_area_size(50)
            .y_label_area_size(70)
            .build_cartesian_2d((t0..t1).log_scale(), 0f64..c1)
            .map_err(s)?;
        chart
            .configure_mesh()
            .x_desc("time to mesh: load + train + extraction (s, log scale)")
            .y_desc("Chamfer acc + comp (mm)")
            .axis_desc_style((FONT, 16))
            .label_style((FONT, 14))
            .draw()
            .map_err(s)?;
        if let Some(r) = reference {
            let orange = colour(1);
            let front = r
                .points
                .iter()
                .zip(&r.on_front)
                .filter(|(_, &f)| f)
                .map(|(&p, _)| p)
                .collect();
            chart
                .draw_series(LineSeries::new(staircase(front), orange.stroke_width(2)))
                .map_err(s)?
                .label(format!("{} front", r.label))
                .legend(move |(x, y)| {
                    PathElement::new(vec![(x, y), (x + 18, y)], orange.stroke_width(2))
                });
            chart
                .draw_series(
                    r.points
                        .iter()
                        .map(|&p| Circle::new(p, 5, orange.stroke_width(2))),
                )
                .map_err(s)?
                .label(format!("{} points", r.label))
                .legend(move |(x, y)| Circle::new((x + 8, y), 5, orange.stroke_width(2)));
        }
        let stair = staircase(
            pts.iter()
                .filter(|p| p.on_front)
                .map(|p| (p.time, p.chamfer))
                .collect(),
        );
        let grey = RGBColor(0x88, 0x88, 0x88);
        chart
            .draw_series(LineSeries::new(stair, grey.stroke_width(2)))
            .map_err(s)?
            .label("Pareto front")
            .legend(move |(x, y)| {
                PathElement::new(vec![(x, y), (x + 18, y)], grey.stroke_width(2))
            });
        let blue = colour(0);
        let red = colour(3);
        chart
            .draw_series(
                pts.iter()
                    .filter(|p| !p.preset)
                    .map(|p| Circle::new((p.time, p.chamfer), 5, blue.filled())),
            )
            .map_err(s)?
            .label("one factor changed")
            .legend(move |(x, y)| Circle::new((x + 8, y), 5, blue.filled()));
        chart
            .draw_series(
                pts.iter()
                    .filter(|p| p.preset)
                    .map(|p| TriangleMarker::new((p.time, p.chamfer), 9, red.filled())),
            )
            .map_err(s)?
            .label("preset")
            .legend(move |(x, y)| TriangleMarker::new((x + 8, y), 7, red.filled()));
        // Labels beside their points, moved to the first free side when they would overlap an
        // earlier label (a greedy placement; good enough for a dozen points).
        let text = TextStyle::from((FONT, 13).into_font()).color(&BLACK);
        let mut placed: Vec<(i32, i32, i32, i32)> = Vec::new();
        let (area_x, area_y) = chart.plotting_area().get_pixel_range();
        for p in pts {
            let (px, py) = chart.backend_coord(&(p.time, p.chamfer));
            let w = 7 * p.label.chars().count() as i32;
            let h = 14;
            let candidates = [
                (9, -17),
                (9, 3),
                (-w - 9, -17),
                (-w - 9, 3),
                (9, -31),
                (9, 17),
            ];
            let free = |(dx, dy): (i32, i32)| {
                let (x, y) = (px + dx, py + dy);
                let inside = x >= area_x.start
                    && x + w <= area_x.end
                    && y >= area_y.start
                    && y + h <= area_y.end;
                inside
                    && !placed
                        .iter()
                        .any(|&(a, b, c, d)| x < a + c && a < x + w && y < b + d && b < y + h)
            };
            let (dx, dy) = candidates
                .into_iter()
                .find(|&c| free(c))
                .unwrap_or(candidates[0]);
            placed.push((px + dx, py + dy, w, h));
            root.draw(&Text::new(
                p.label.as_str(),
                (px + dx, py + dy),
                text.clone(),
            ))
            .map_err(s)?;
        }
        legend(&mut chart)?;
        Ok(())
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn decode(png: &[u8]) -> image::RgbImage {
        image::load_from_memory(png).unwrap().to_rgb8()
    }

    #[test]
    fn bars_draw_the_same_bytes_twice_and_scale_with_the_data() {
        let b = |v: f64| Bars {
            title: "t".into(),
            y_label: "mm".into(),
            groups: vec!["blob".into(), "torus".into()],
            series: vec!["baseline".into(), "SIA".into()],
            values: vec![
                vec![Some((v, 0.1)), Some((1.0, 0.0))],
                vec![None, Some((2.0, 0.3))],
            ],
        };
        let a = bar_chart("a.png", &b(1.5)).unwrap();
        assert_eq!(a, bar_chart("a.png", &b(1.5)).unwrap(), "deterministic");
        assert_ne!(a, bar_chart("a.png", &b(0.5)).unwrap());
        let img = decode(&a);
        assert_eq!(img.dimensions(), (WIDTH, HEIGHT));
        // The first series' colour is present (bars were drawn), and text pixels exist (dark
        // anti-aliased glyphs) in the caption band.
        let c = colour(0);
        assert!(img.pixels().any(|p| p.0 == [c.0, c.1, c.2]));
        let dark_in_caption = dark_rows(&img, 0..40);
        assert!(dark_in_caption > 5, "the caption was not drawn");
    }

    /// Dark pixels (text) in the band `rows` of the image.
    fn dark_rows(img: &image::RgbImage, rows: std::ops::Range<u32>) -> usize {
        (0..WIDTH)
            .flat_map(|x| rows.clone().map(move |y| (x, y)))
            .filter(|&(x, y)| img.get_pixel(x, y).0.iter().all(|&v| v < 100))
            .count()
    }

    #[test]
    fn group_names_too_wide_for_their_slot_are_drawn_upright() {
        let b = |groups: Vec<String>| Bars {
            title: "t".into(),
            y_label: "mm".into(),
            values: vec![vec![Some((1.0, 0.1))]; groups.len()],
            groups,
            series: vec!["baseline".into()],
        };
        let short = decode(&bar_chart("s.png", &b(vec!["a".into(), "b".into()])).unwrap());
        let long: Vec<String> = (0..20)
            .map(|i| format!("salt-pepper:0.05 · scene{i}"))
            .collect();
        let long = decode(&bar_chart("l.png", &b(long)).unwrap());
        // Short names sit in one line just under the axis and leave the bottom of the image
        // white; long ones run upright from the bottom margin up to the axis.
        let bottom = HEIGHT - 34..HEIGHT - 16;
        assert_eq!(dark_rows(&short, bottom.clone()), 0);
        assert!(dark_rows(&long, bottom) > 20);
        // Upright, the twenty names stand apart: a column between two of them is white.
        let img = &long;
        let gaps = (70..WIDTH - 16)
            .filter(|&x| (HEIGHT - 100..HEIGHT - 20).all(|y| img.get_pixel(x, y).0[0] > 200))
            .count();
        assert!(gaps > 400, "{gaps} white columns under the axis");
    }

    #[test]
    fn lines_and_pareto_render() {
        let l = Lines {
            title: "r".into(),
            x_label: "views (%)".into(),
            y_label: "mm".into(),
            series: vec![
                ("baseline".into(), vec![(10.0, 3.0, 0.2), (50.0, 2.0, 0.1)]),
                ("SIA".into(), vec![(10.0, 2.5, 0.0), (50.0, 1.8, 0.1)]),
            ],
        };
        decode(&line_chart("l.png", &l).unwrap());
        let pts = vec![
            ParetoPoint {
                time: 100.0,
                chamfer: 3.0,
                label: "iterations=250".into(),
                preset: false,
                on_front: true,
            },
            ParetoPoint {
                time: 800.0,
                chamfer: 1.5,
                label: "fast (preset)".into(),
                preset: true,
                on_front: true,
            },
            ParetoPoint {
                time: 900.0,
                chamfer: 2.0,
                label: "samples=128".into(),
                preset: false,
                on_front: false,
            },
        ];
        let p = pareto_chart("p", &pts, None).unwrap();
        let img = decode(&p);
        let red = colour(3);
        assert!(
            img.pixels().any(|q| q.0 == [red.0, red.1, red.2]),
            "preset marker drawn"
        );
        // Degenerate input still draws (empty data).
        pareto_chart("e", &[], None).unwrap();
        // A reference front adds its own colour, outside this study's points.
        let reference = ReferenceFront {
            label: "old build".into(),
            points: vec![(2000.0, 2.5), (3000.0, 2.8)],
            on_front: vec![true, false],
        };
        let orange = colour(1);
        let is_orange = |q: &image::Rgb<u8>| q.0 == [orange.0, orange.1, orange.2];
        assert!(!img.pixels().any(is_orange), "no reference, no orange");
        let with = decode(&pareto_chart("p", &pts, Some(&reference)).unwrap());
        assert!(with.pixels().any(is_orange), "the reference front is drawn");
    }
}
