//! Small SVG plotting helpers on `plotters` (SVG backend: no fonts or system libraries).

use anyhow::{anyhow, Result};
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
                    .legend(move |(x, y)| {
                        PathElement::new(vec![(x, y), (x + 20, y)], c.stroke_width(2))
                    });
            }
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
            .build_cartesian_2d(x0..x1, (y0.max(1e-300)..y1 * 1.5).log_scale())
            .map_err(|e| anyhow!("{e}"))?);
    } else {
        draw!(b
            .build_cartesian_2d(x0..x1, (y0 - pad)..(y1 + pad))
            .map_err(|e| anyhow!("{e}"))?);
    }
    root.present().map_err(|e| anyhow!("{e}"))?;
    Ok(())
}
