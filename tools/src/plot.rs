//! Small SVG plotting helpers on `plotters` (SVG backend: no fonts or system libraries).

use anyhow::{anyhow, Result};
use plotters::coord::types::RangedCoordf64;
use plotters::prelude::*;
use std::path::Path;

/// One labelled line.
pub struct Series<'a> {
    /// Legend label.
    pub label: String,
    /// x values.
    pub x: &'a [f64],
    /// y values.
    pub y: &'a [f64],
}

/// Decorations that show a decision: horizontal limit lines, shaded x intervals, a fixed
/// y range (so a small residual is drawn at a visible scale and large curves are clipped).
#[derive(Clone, Debug, Default)]
pub struct Marks {
    /// Horizontal dashed lines: (y, legend label); a label is drawn once per distinct text.
    pub hlines: Vec<(f64, String)>,
    /// Shaded x intervals with a legend label.
    pub shaded_x: Vec<(f64, f64, String)>,
    /// Fixed y range.
    pub y_range: Option<(f64, f64)>,
}

const COLORS: [RGBColor; 6] = [
    BLACK,
    RED,
    BLUE,
    RGBColor(0, 140, 0),
    MAGENTA,
    RGBColor(230, 140, 0),
];

/// Writes a line plot of `series` to `path` (SVG, 1000×600).
pub fn lines(
    path: &Path,
    title: &str,
    x_label: &str,
    y_label: &str,
    series: &[Series],
    log_y: bool,
) -> Result<()> {
    lines_marked(
        path,
        title,
        x_label,
        y_label,
        series,
        log_y,
        &Marks::default(),
    )
}

/// [`lines`] with [`Marks`].
pub fn lines_marked(
    path: &Path,
    title: &str,
    x_label: &str,
    y_label: &str,
    series: &[Series],
    log_y: bool,
    marks: &Marks,
) -> Result<()> {
    let finite = |v: &&f64| v.is_finite() && (!log_y || **v > 0.0);
    let xs = series.iter().flat_map(|s| s.x.iter()).filter(finite);
    let (x0, x1) = xs.fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &v| {
        (a.min(v), b.max(v))
    });
    let ys = series.iter().flat_map(|s| s.y.iter()).filter(finite);
    let (mut y0, mut y1) = ys.fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &v| {
        (a.min(v), b.max(v))
    });
    if !(x0.is_finite() && y0.is_finite()) {
        return Err(anyhow!("nothing finite to plot in {}", path.display()));
    }
    if y1 - y0 < 1e-12 {
        y0 -= 1.0;
        y1 += 1.0;
    }
    let pad = 0.05 * (y1 - y0);
    let (ya, yb) = marks.y_range.unwrap_or((y0 - pad, y1 + pad));
    let root = SVGBackend::new(path, (1000, 600)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| anyhow!("{e}"))?;
    macro_rules! draw {
        ($chart:expr) => {{
            let mut chart = $chart;
            chart
                .configure_mesh()
                .x_desc(x_label)
                .y_desc(y_label)
                .draw()
                .map_err(|e| anyhow!("{e}"))?;
            draw_shaded(&mut chart, &marks.shaded_x, (ya, yb))?;
            draw_lines(&mut chart, series, log_y)?;
            draw_hlines(&mut chart, &marks.hlines, (x0, x1))?;
            chart
                .configure_series_labels()
                .background_style(WHITE.mix(0.8))
                .border_style(BLACK)
                .draw()
                .map_err(|e| anyhow!("{e}"))?;
        }};
    }
    let mut b = ChartBuilder::on(&root);
    b.caption(title, ("sans-serif", 22))
        .margin(15)
        .x_label_area_size(45)
        .y_label_area_size(70);
    if log_y {
        draw!(b
            .build_cartesian_2d(x0..x1, (ya.max(1e-300)..yb * 1.5).log_scale())
            .map_err(|e| anyhow!("{e}"))?);
    } else {
        draw!(b
            .build_cartesian_2d(x0..x1, ya..yb)
            .map_err(|e| anyhow!("{e}"))?);
    }
    root.present().map_err(|e| anyhow!("{e}"))?;
    Ok(())
}

/// A chart with a linear x axis and any f64 y axis (linear or logarithmic).
type Chart<'a, DB, Y> = ChartContext<'a, DB, Cartesian2d<RangedCoordf64, Y>>;

/// The shaded x intervals of [`Marks`], over the y range `y_range`.
fn draw_shaded<DB: DrawingBackend, Y: Ranged<ValueType = f64>>(
    chart: &mut Chart<'_, DB, Y>,
    shaded_x: &[(f64, f64, String)],
    y_range: (f64, f64),
) -> Result<()> {
    let (ya, yb) = y_range;
    for (lo, hi, label) in shaded_x {
        let (lo, hi) = (*lo, *hi);
        let fill = RGBColor(120, 170, 255).mix(0.25);
        chart
            .draw_series(std::iter::once(Rectangle::new(
                [(lo, ya), (hi, yb)],
                fill.filled(),
            )))
            .map_err(|e| anyhow!("{e}"))?
            .label(label.clone())
            .legend(move |(x, y)| Rectangle::new([(x, y - 5), (x + 20, y + 5)], fill.filled()));
    }
    Ok(())
}

/// The series as lines (non-positive values skipped on a logarithmic axis).
fn draw_lines<DB: DrawingBackend, Y: Ranged<ValueType = f64>>(
    chart: &mut Chart<'_, DB, Y>,
    series: &[Series],
    log_y: bool,
) -> Result<()> {
    for (i, s) in series.iter().enumerate() {
        let c = COLORS[i % COLORS.len()];
        chart
            .draw_series(LineSeries::new(
                s.x.iter()
                    .zip(s.y)
                    .filter(|(_, y)| !log_y || **y > 0.0)
                    .map(|(&x, &y)| (x, y)),
                c.stroke_width(2),
            ))
            .map_err(|e| anyhow!("{e}"))?
            .label(s.label.clone())
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], c.stroke_width(2)));
    }
    Ok(())
}

/// The dashed horizontal lines of [`Marks`] across `x_range`, one colour and one legend
/// entry per distinct label.
fn draw_hlines<DB: DrawingBackend, Y: Ranged<ValueType = f64>>(
    chart: &mut Chart<'_, DB, Y>,
    hlines: &[(f64, String)],
    x_range: (f64, f64),
) -> Result<()> {
    let (x0, x1) = x_range;
    let mut seen: Vec<&str> = Vec::new();
    for (y, label) in hlines {
        let c = [
            RGBColor(0, 150, 0),
            RGBColor(200, 0, 200),
            RGBColor(120, 120, 120),
        ][seen.iter().position(|l| *l == label).unwrap_or(seen.len()) % 3];
        let y = *y;
        let dash: Vec<(f64, f64)> = (0..200)
            .filter(|i| i % 2 == 0)
            .flat_map(|i| {
                let a = x0 + (x1 - x0) * i as f64 / 200.0;
                let b = x0 + (x1 - x0) * (i + 1) as f64 / 200.0;
                [(a, y), (b, y)]
            })
            .collect();
        let s = chart
            .draw_series(
                dash.chunks(2)
                    .map(|p| PathElement::new(p.to_vec(), c.stroke_width(2))),
            )
            .map_err(|e| anyhow!("{e}"))?;
        if !seen.contains(&label.as_str()) {
            s.label(label.clone()).legend(move |(x, yy)| {
                PathElement::new(vec![(x, yy), (x + 20, yy)], c.stroke_width(2))
            });
            seen.push(label);
        }
    }
    Ok(())
}
