//! Klipper's raw accelerometer CSV (`ACCELEROMETER_MEASURE`, `TEST_RESONANCES … OUTPUT=raw_data`:
//! files `adxl345-*.csv`, `raw_data_*.csv`).
//!
//! Format (Klipper's documentation, "Measuring Resonances"): a header line
//! `#time,accel_x,accel_y,accel_z` (possibly after `##` status lines), then one row per sample:
//! time (s, the printer's clock) and the three accelerations (mm/s², the chip's axes). The
//! sample rate is the chip's (ADXL345: 3.2 kHz nominal) with time stamps estimated from its
//! clock, so the steps jitter slightly and the queries leave gaps.
//!
//! One axis is read as the project's `tip_acc_m_s2` (converted to m/s²): `--axis x|y|z`, or by
//! default the axis with the most energy (the largest variance about its mean; gravity's
//! constant share is removed with the mean). The time base is then mended onto a uniform grid
//! by [`super::regular`] where it allows (jitter, dropped samples), with a note; a gap too long
//! to fill is kept, and `identify` splits the recording there.

use super::columns::Axis;
use super::fmt_sig;

/// The header fields of Klipper's raw accelerometer CSV.
pub const HEADER: [&str; 4] = ["time", "accel_x", "accel_y", "accel_z"];

/// mm/s² → m/s².
pub const MM_S2_TO_M_S2: f64 = 1e-3;

/// True when the header `names` is Klipper's raw accelerometer header.
pub fn is_klipper_header(names: &[&str]) -> bool {
    names == HEADER
}

/// Variance of `x` about its mean (NaN values skipped); 0 for fewer than 2 values.
fn variance(x: &[f64]) -> f64 {
    let v: Vec<f64> = x.iter().copied().filter(|v| v.is_finite()).collect();
    if v.len() < 2 {
        return 0.0;
    }
    let mean = v.iter().sum::<f64>() / v.len() as f64;
    v.iter().map(|a| (a - mean) * (a - mean)).sum::<f64>() / (v.len() - 1) as f64
}

/// The axis to read from the three accelerations `xyz` (m/s²): `chosen`, or the one
/// with the largest variance about its mean. Returns the axis and the note saying why.
pub fn choose_axis(xyz: [&[f64]; 3], chosen: Option<Axis>) -> (Axis, String) {
    let rms: Vec<f64> = xyz.iter().map(|c| variance(c).sqrt()).collect();
    let list = format!(
        "x {}, y {}, z {} m/s²",
        fmt_sig(rms[0], 3),
        fmt_sig(rms[1], 3),
        fmt_sig(rms[2], 3)
    );
    match chosen {
        Some(a) => (
            a,
            format!(
                "Klipper raw accelerometer CSV (time s, mm/s²): axis {} (--axis) read as tip_acc_m_s2 in m/s² (RMS about the mean: {list})",
                a.name()
            ),
        ),
        None => {
            let k = (0..3)
                .max_by(|&i, &j| rms[i].total_cmp(&rms[j]))
                .expect("three axes");
            let a = [Axis::X, Axis::Y, Axis::Z][k];
            (
                a,
                format!(
                    "Klipper raw accelerometer CSV (time s, mm/s²): axis {} read as tip_acc_m_s2 in m/s², the axis with the most energy (RMS about the mean: {list}; choose another with --axis)",
                    a.name()
                ),
            )
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_axis_with_the_most_energy_about_its_mean_is_chosen() {
        // z holds gravity (a large mean, little motion); y moves most
        let x: Vec<f64> = (0..100).map(|k| (k as f64 * 0.3).sin() * 10.0).collect();
        let y: Vec<f64> = (0..100).map(|k| (k as f64 * 0.3).cos() * 300.0).collect();
        let z: Vec<f64> = (0..100).map(|k| 9806.0 + (k % 2) as f64).collect();
        let (a, note) = choose_axis([&x, &y, &z], None);
        assert_eq!(a, Axis::Y);
        assert!(note.contains("axis y read as tip_acc_m_s2"), "{note}");
        assert_eq!(choose_axis([&x, &y, &z], Some(Axis::Z)).0, Axis::Z);
    }
}
