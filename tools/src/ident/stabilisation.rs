//! Stabilisation diagram over model orders and automatic selection of the stable modes.
//!
//! A pole at order n is *stable* when a pole of order n−1 (the previous order computed) lies
//! within `df_rel` in frequency and `dzeta_rel` in damping (defaults 1 % and 5 %, the usual
//! PolyMAX/sdypy-EMA criteria). Poles stable at least in frequency are clustered (within
//! `df_rel` of the cluster's running median; damping estimates from noisy data wander more
//! than 5 % between orders, so requiring damping stability too loses real modes); a cluster
//! is a mode when it holds poles from at least `min_fraction` of the orders. The mode's estimate is the median of its poles, and its 1-σ
//! uncertainty the spread (1.4826 × MAD) of its poles across model orders.

use super::poles::Pole;
use super::std_dev;
use crate::numeric::stats::median;
use anyhow::{anyhow, Result};
use plotters::prelude::*;
use serde::Serialize;

/// Stability of a pole relative to the previous order.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub enum Stability {
    /// New (no match in frequency).
    New,
    /// Frequency stable.
    Freq,
    /// Frequency and damping stable.
    Stable,
}

/// Criteria.
#[derive(Clone, Debug, Serialize)]
pub struct StabCriteria {
    /// Relative frequency tolerance.
    pub df_rel: f64,
    /// Relative damping tolerance.
    pub dzeta_rel: f64,
    /// Fraction of orders a mode must be stable in.
    pub min_fraction: f64,
}

impl Default for StabCriteria {
    fn default() -> Self {
        StabCriteria {
            df_rel: 0.01,
            dzeta_rel: 0.05,
            min_fraction: 0.3,
        }
    }
}

/// One order's poles with their stability.
#[derive(Clone, Debug, Serialize)]
pub struct OrderPoles {
    /// Model order.
    pub order: usize,
    /// Poles and their stability labels.
    pub poles: Vec<(Pole, Stability)>,
}

/// A mode selected from the diagram.
#[derive(Clone, Debug, Serialize)]
pub struct StableMode {
    /// Median frequency (Hz).
    pub freq_hz: f64,
    /// Median damping ratio.
    pub zeta: f64,
    /// 1-σ spread of the frequency across orders (Hz).
    pub freq_hz_std: f64,
    /// 1-σ spread of the damping across orders.
    pub zeta_std: f64,
    /// Number of stable poles in the cluster.
    pub count: usize,
}

/// A stabilisation diagram.
#[derive(Clone, Debug, Serialize)]
pub struct Diagram {
    /// Estimator name.
    pub method: String,
    /// Poles per order, ascending order.
    pub orders: Vec<OrderPoles>,
    /// Modes selected.
    pub modes: Vec<StableMode>,
}

/// Labels poles of consecutive orders (`raw` ascending by order).
pub fn label(raw: Vec<(usize, Vec<Pole>)>, c: &StabCriteria) -> Vec<OrderPoles> {
    let mut out: Vec<OrderPoles> = Vec::with_capacity(raw.len());
    for (order, poles) in raw {
        let prev = out
            .last()
            .map(|o| o.poles.iter().map(|p| p.0).collect::<Vec<_>>())
            .unwrap_or_default();
        let lab = poles
            .into_iter()
            .map(|p| {
                let best = prev
                    .iter()
                    .filter(|q| (q.freq_hz / p.freq_hz - 1.0).abs() < c.df_rel)
                    .min_by(|a, b| {
                        (a.freq_hz - p.freq_hz)
                            .abs()
                            .total_cmp(&(b.freq_hz - p.freq_hz).abs())
                    });
                let s = match best {
                    None => Stability::New,
                    Some(q) if (q.zeta / p.zeta - 1.0).abs() < c.dzeta_rel => Stability::Stable,
                    Some(_) => Stability::Freq,
                };
                (p, s)
            })
            .collect();
        out.push(OrderPoles { order, poles: lab });
    }
    out
}

fn robust_std(v: &[f64]) -> f64 {
    if v.len() < 3 {
        return std_dev(v);
    }
    let m = median(v);
    let d: Vec<f64> = v.iter().map(|x| (x - m).abs()).collect();
    1.4826 * median(&d)
}

/// Selects the modes (clusters of stable poles), sorted by frequency.
pub fn select(orders: &[OrderPoles], c: &StabCriteria) -> Vec<StableMode> {
    let mut stable: Vec<Pole> = orders
        .iter()
        .flat_map(|o| {
            o.poles
                .iter()
                .filter(|p| p.1 != Stability::New)
                .map(|p| p.0)
        })
        .collect();
    stable.sort_by(|a, b| a.freq_hz.total_cmp(&b.freq_hz));
    let mut clusters: Vec<Vec<Pole>> = Vec::new();
    for p in stable {
        match clusters.last_mut() {
            Some(cl)
                if {
                    let f: Vec<f64> = cl.iter().map(|q| q.freq_hz).collect();
                    (p.freq_hz / median(&f) - 1.0).abs() < c.df_rel
                } =>
            {
                cl.push(p)
            }
            _ => clusters.push(vec![p]),
        }
    }
    let need = ((c.min_fraction * orders.len() as f64).ceil() as usize).max(2);
    clusters
        .into_iter()
        .filter(|cl| cl.len() >= need)
        .map(|cl| {
            let f: Vec<f64> = cl.iter().map(|p| p.freq_hz).collect();
            let z: Vec<f64> = cl.iter().map(|p| p.zeta).collect();
            let (fs, zs) = (robust_std(&f), robust_std(&z));
            StableMode {
                freq_hz: median(&f),
                zeta: median(&z),
                freq_hz_std: fs,
                zeta_std: zs,
                count: cl.len(),
            }
        })
        .collect()
}

/// Runs `estimate(order)` for every order, labels, selects. Errors of single orders are
/// skipped (an order too high for the data); at least one order must succeed. The orders are
/// independent: with a spare core ([`crate::numeric::cores`]) two threads take them from one
/// queue, highest (costliest) first — the longest-processing-time rule (Graham 1969), which
/// keeps the two threads' loads within one order of each other without a cost model — and the
/// results are kept in order (the same answer either way). `progress` advances once per order.
pub fn diagram(
    method: &str,
    orders: impl IntoIterator<Item = usize>,
    c: &StabCriteria,
    estimate: impl Fn(usize) -> Result<Vec<Pole>> + Sync,
    progress: &mut dyn crate::progress::Progress,
) -> Result<Diagram> {
    let orders: Vec<usize> = orders.into_iter().collect();
    progress.stage(method);
    let results = run_orders(&orders, &estimate, progress);
    let mut raw = Vec::new();
    let mut last_err = None;
    for (n, r) in results {
        match r {
            Ok(p) => raw.push((n, p)),
            Err(e) => last_err = Some(e),
        }
    }
    if raw.is_empty() {
        return Err(last_err.unwrap_or_else(|| anyhow!("{method}: no model orders")));
    }
    let labelled = label(raw, c);
    let modes = select(&labelled, c);
    Ok(Diagram {
        method: method.to_string(),
        orders: labelled,
        modes,
    })
}

/// `estimate(n)` for every order of `orders`, in that order; the work is shared with a spare
/// core when one is free (see [`diagram`]).
fn run_orders(
    orders: &[usize],
    estimate: &(impl Fn(usize) -> Result<Vec<Pole>> + Sync),
    progress: &mut dyn crate::progress::Progress,
) -> Vec<(usize, Result<Vec<Pole>>)> {
    use std::sync::atomic::{AtomicUsize, Ordering};
    let total = orders.len() as u64;
    // Queue positions in descending order of the model order.
    let mut queue: Vec<usize> = (0..orders.len()).collect();
    queue.sort_by(|&a, &b| orders[b].cmp(&orders[a]));
    let next = AtomicUsize::new(0);
    let work = || {
        let mut done = Vec::new();
        while let Some(&i) = queue.get(next.fetch_add(1, Ordering::Relaxed)) {
            done.push((i, estimate(orders[i])));
        }
        done
    };
    let mut results: Vec<Option<Result<Vec<Pole>>>> = orders.iter().map(|_| None).collect();
    std::thread::scope(|scope| {
        let beside = crate::numeric::cores::take().map(|core| {
            scope.spawn(|| {
                let _held = core;
                work()
            })
        });
        let mut mine = 0u64;
        while let Some(&i) = queue.get(next.fetch_add(1, Ordering::Relaxed)) {
            results[i] = Some(estimate(orders[i]));
            mine += 1;
            progress.advance(mine, total);
        }
        if let Some(Ok(theirs)) = beside.map(|h| h.join()) {
            for (i, r) in theirs {
                results[i] = Some(r);
            }
        }
    });
    progress.advance(total, total);
    orders
        .iter()
        .zip(results)
        .map(|(&n, r)| {
            // An order whose thread died is computed here (the result is the same).
            (n, r.unwrap_or_else(|| estimate(n)))
        })
        .collect()
}

impl Diagram {
    /// Text diagram: one line per order, a character per frequency bin of the band
    /// (`o` new, `f` frequency-stable, `s` stable), the selected modes marked below.
    pub fn text(&self, f_lo: f64, f_hi: f64, width: usize) -> String {
        let col = |f: f64| {
            (((f - f_lo) / (f_hi - f_lo)) * (width - 1) as f64)
                .round()
                .clamp(0.0, (width - 1) as f64) as usize
        };
        let mut s = format!(
            "stabilisation diagram ({}), {:.2}..{:.2} Hz; o new, f freq-stable, s stable\n",
            self.method, f_lo, f_hi
        );
        for o in &self.orders {
            let mut line = vec![' '; width];
            for (p, st) in &o.poles {
                let c = col(p.freq_hz);
                let ch = match st {
                    Stability::New => 'o',
                    Stability::Freq => 'f',
                    Stability::Stable => 's',
                };
                if line[c] != 's' {
                    line[c] = ch;
                }
            }
            s += &format!("{:>4} |{}|\n", o.order, line.iter().collect::<String>());
        }
        let mut mark = vec![' '; width];
        for m in &self.modes {
            mark[col(m.freq_hz)] = '^';
        }
        s += &format!("mode |{}|\n", mark.iter().collect::<String>());
        for m in &self.modes {
            s += &format!(
                "     {:.4} Hz  zeta {:.5}  ({} stable poles)\n",
                m.freq_hz, m.zeta, m.count
            );
        }
        s
    }

    /// (frequency Hz, order) of the poles labelled `st` in `f_lo..=f_hi`.
    fn points(&self, st: Stability, f_lo: f64, f_hi: f64) -> Vec<(f64, f64)> {
        self.orders
            .iter()
            .flat_map(|o| {
                o.poles
                    .iter()
                    .filter(move |p| p.1 == st && p.0.freq_hz >= f_lo && p.0.freq_hz <= f_hi)
                    .map(move |p| (p.0.freq_hz, o.order as f64))
            })
            .collect()
    }

    /// The diagram as an SVG document: the poles over (frequency, order), on top of the
    /// normalised |H| (`mag` at `freq_hz`) in `f_lo..=f_hi`.
    pub fn svg(&self, freq_hz: &[f64], mag: &[f64], f_lo: f64, f_hi: f64) -> Result<String> {
        let max_order = self.orders.iter().map(|o| o.order).max().unwrap_or(1) as f64;
        let mut svg = String::new();
        {
            let root = SVGBackend::with_string(&mut svg, (1000, 600)).into_drawing_area();
            root.fill(&WHITE).map_err(|e| anyhow!("{e}"))?;
            let mut chart = ChartBuilder::on(&root)
                .caption(
                    format!("Stabilisation diagram ({})", self.method),
                    ("sans-serif", 22),
                )
                .margin(15)
                .x_label_area_size(45)
                .y_label_area_size(60)
                .build_cartesian_2d(f_lo..f_hi, 0.0..max_order + 1.0)
                .map_err(|e| anyhow!("{e}"))?;
            chart
                .configure_mesh()
                .x_desc("frequency (Hz)")
                .y_desc("model order")
                .draw()
                .map_err(|e| anyhow!("{e}"))?;
            let trace = magnitude_trace(freq_hz, mag, (f_lo, f_hi), max_order);
            if !trace.is_empty() {
                chart
                    .draw_series(LineSeries::new(
                        trace,
                        RGBColor(150, 150, 150).stroke_width(1),
                    ))
                    .map_err(|e| anyhow!("{e}"))?
                    .label("|H| (dB, scaled)")
                    .legend(|(x, y)| {
                        PathElement::new(vec![(x, y), (x + 20, y)], RGBColor(150, 150, 150))
                    });
            }
            for (st, color, name) in [
                (Stability::New, RGBColor(200, 200, 200), "new"),
                (Stability::Freq, BLUE, "frequency stable"),
                (Stability::Stable, RED, "stable"),
            ] {
                let pts = self.points(st, f_lo, f_hi);
                chart
                    .draw_series(pts.iter().map(|&p| Circle::new(p, 3, color.filled())))
                    .map_err(|e| anyhow!("{e}"))?
                    .label(name)
                    .legend(move |(x, y)| Circle::new((x + 10, y), 3, color.filled()));
            }
            for m in &self.modes {
                chart
                    .draw_series(LineSeries::new(
                        vec![(m.freq_hz, 0.0), (m.freq_hz, max_order + 1.0)],
                        BLACK.stroke_width(1),
                    ))
                    .map_err(|e| anyhow!("{e}"))?;
            }
            chart
                .configure_series_labels()
                .background_style(WHITE.mix(0.8))
                .border_style(BLACK)
                .draw()
                .map_err(|e| anyhow!("{e}"))?;
            root.present().map_err(|e| anyhow!("{e}"))?;
        }
        Ok(svg)
    }
}

/// |H| (`mag`) in dB within `band_hz`, scaled onto the order axis 0.5..0.5 + `max_order`.
fn magnitude_trace(
    freq_hz: &[f64],
    mag: &[f64],
    band_hz: (f64, f64),
    max_order: f64,
) -> Vec<(f64, f64)> {
    let band: Vec<(f64, f64)> = freq_hz
        .iter()
        .zip(mag)
        .filter(|(f, m)| **f >= band_hz.0 && **f <= band_hz.1 && **m > 0.0)
        .map(|(&f, &m)| (f, 20.0 * m.log10()))
        .collect();
    let (lo, hi) = band
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), p| {
            (a.min(p.1), b.max(p.1))
        });
    let sc = |v: f64| 0.5 + max_order * (v - lo) / (hi - lo).max(1e-9);
    band.iter().map(|&(f, v)| (f, sc(v))).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn selects_the_cluster_present_at_most_orders() {
        let c = StabCriteria::default();
        let raw: Vec<(usize, Vec<Pole>)> = (2..12)
            .map(|n| {
                let mut v = vec![Pole {
                    freq_hz: 1.1 + 1e-4 * n as f64,
                    zeta: 0.0074,
                }];
                // A spurious pole wandering around.
                v.push(Pole {
                    freq_hz: 3.0 + 0.3 * n as f64,
                    zeta: 0.05,
                });
                (n, v)
            })
            .collect();
        let l = label(raw, &c);
        let m = select(&l, &c);
        assert_eq!(m.len(), 1, "{m:?}");
        assert!((m[0].freq_hz - 1.1007).abs() < 1e-3 && m[0].freq_hz_std > 0.0);
        let d = Diagram {
            method: "t".into(),
            orders: l,
            modes: m,
        };
        assert!(d.text(0.5, 8.0, 60).contains('s'));
    }
}
