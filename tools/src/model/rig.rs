//! The rig file (TOML): beam geometry and material, carriage mass, damping ratios, sensors.
//!
//! ```toml
//! [beam]
//! length_m = 0.9
//! density_kg_m3 = 8190.0
//! youngs_modulus_pa = 1.9e11
//! stations = [ { x_m = 0.0, width_m = 0.025, thickness_m = 0.00115 },
//!              { x_m = 0.9, width_m = 0.025, thickness_m = 0.00115 } ]
//! # or a tabulated profile instead of stations:
//! # profile = [ { x_m = 0.0, area_m2 = 2.9e-5, inertia_m4 = 3.2e-12 }, … ]
//! [base]
//! mass_kg = 2.5
//! [damping]
//! ratios = [0.0074, 0.0074]
//! [sensors]
//! sample_rate_hz = 100.0
//! ```
//! Rectangular sections give A = b·h and I = b·h³/12, linear in x between stations.
//! A rig without `[beam]` is a carriage-only rig.

use anyhow::{bail, Context, Result};
use serde::Deserialize;
use std::path::Path;

/// One rectangular station.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Station {
    /// Position from the clamped root (m).
    pub x_m: f64,
    /// Width b (m).
    pub width_m: f64,
    /// Thickness h (m), in the bending direction.
    pub thickness_m: f64,
}

/// One tabulated station.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct ProfilePoint {
    /// Position from the clamped root (m).
    pub x_m: f64,
    /// Cross-section area A (m²).
    pub area_m2: f64,
    /// Second moment of area I (m⁴).
    pub inertia_m4: f64,
}

/// `[beam]`.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct BeamSection {
    /// Free length l (m).
    pub length_m: f64,
    /// Density ρ (kg/m³).
    pub density_kg_m3: f64,
    /// Young's modulus E (Pa).
    pub youngs_modulus_pa: f64,
    /// Rectangular stations (root to tip).
    #[serde(default)]
    pub stations: Vec<Station>,
    /// Tabulated A(x), I(x) (root to tip), instead of `stations`.
    #[serde(default)]
    pub profile: Vec<ProfilePoint>,
}

/// `[base]`.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct BaseSection {
    /// Carriage mass m without the beam (kg).
    pub mass_kg: f64,
}

/// `[damping]`.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct DampingSection {
    /// Damping ratios of modes 1, 2, … in order (one or more). Modes 1 and 2 set Rayleigh's
    /// α1, α2 (eq. 22) for the model; the diagnosis starts each mode's ratio from its entry
    /// (the last repeated for higher modes).
    pub ratios: Vec<f64>,
}

/// `[sensors]`.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct SensorSection {
    /// Sample rate of recordings (Hz).
    pub sample_rate_hz: f64,
}

/// A whole rig file.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Rig {
    /// The beam (absent for a carriage-only rig).
    pub beam: Option<BeamSection>,
    /// The carriage.
    pub base: BaseSection,
    /// Damping ratios.
    pub damping: Option<DampingSection>,
    /// Sensors.
    pub sensors: Option<SensorSection>,
}

/// A(x) and I(x) of a beam. From `stations` (a rectangular section of width b and thickness
/// h at each) the *dimensions* are linear in x between stations, as a machined or rolled taper
/// is, and A = b h, I = b h³ / 12 follow from them (a thickness taper makes I a cubic in x;
/// interpolating I itself linearly overstates it between the stations, by 1.4 % at the middle
/// of a 15 % thickness taper, and the first natural frequency by about 0.5 %). From a
/// tabulated `profile`, A and I are linear in x between its entries.
#[derive(Clone, Debug, PartialEq)]
pub struct SectionProfile {
    /// Station positions (m), increasing from 0 to l.
    pub x_m: Vec<f64>,
    /// Areas (m²) at the stations.
    pub area_m2: Vec<f64>,
    /// Second moments (m⁴) at the stations.
    pub inertia_m4: Vec<f64>,
    /// Width and thickness (m) at the stations of a rectangular section (`None`: a tabulated
    /// profile).
    pub rectangle_m: Option<Vec<(f64, f64)>>,
}

impl SectionProfile {
    /// The segment holding `x` and the fraction of the way along it (clamped to the ends).
    fn locate(&self, x: f64) -> (usize, f64) {
        let n = self.x_m.len();
        if x <= self.x_m[0] {
            return (1, 0.0);
        }
        for k in 1..n {
            if x <= self.x_m[k] {
                return (k, (x - self.x_m[k - 1]) / (self.x_m[k] - self.x_m[k - 1]));
            }
        }
        (n - 1, 1.0)
    }

    fn interp(&self, v: &[f64], x: f64) -> f64 {
        let (k, a) = self.locate(x);
        v[k - 1] + a * (v[k] - v[k - 1])
    }

    /// Width and thickness (m) at `x` of a rectangular section, linear between stations.
    fn rectangle_at(&self, x: f64) -> Option<(f64, f64)> {
        let r = self.rectangle_m.as_ref()?;
        let (k, a) = self.locate(x);
        let lerp = |p: f64, q: f64| p + a * (q - p);
        Some((lerp(r[k - 1].0, r[k].0), lerp(r[k - 1].1, r[k].1)))
    }

    /// A(x) (m²).
    pub fn area(&self, x: f64) -> f64 {
        match self.rectangle_at(x) {
            Some((b, h)) => b * h,
            None => self.interp(&self.area_m2, x),
        }
    }

    /// I(x) (m⁴).
    pub fn inertia(&self, x: f64) -> f64 {
        match self.rectangle_at(x) {
            Some((b, h)) => b * h * h * h / 12.0,
            None => self.interp(&self.inertia_m4, x),
        }
    }
}

fn positive(v: f64, key: &str) -> Result<()> {
    if !(v.is_finite() && v > 0.0) {
        bail!("`{key}` must be a finite number > 0 (got {v})");
    }
    Ok(())
}

impl Rig {
    /// Parses and validates a rig file. Errors name the offending key.
    pub fn from_toml_file(path: impl AsRef<Path>) -> Result<Rig> {
        let path = path.as_ref();
        let text = std::fs::read_to_string(path)
            .with_context(|| format!("cannot read rig file {}", path.display()))?;
        Rig::from_toml_str(&text).with_context(|| format!("rig file {}", path.display()))
    }

    /// Parses and validates a rig from TOML text.
    pub fn from_toml_str(text: &str) -> Result<Rig> {
        let rig: Rig =
            toml::from_str(text).map_err(|e| anyhow::anyhow!("{}", e.to_string().trim_end()))?;
        rig.validate()?;
        Ok(rig)
    }

    /// Checks sizes, ordering and ranges.
    pub fn validate(&self) -> Result<()> {
        positive(self.base.mass_kg, "base.mass_kg")?;
        if let Some(s) = &self.sensors {
            positive(s.sample_rate_hz, "sensors.sample_rate_hz")?;
        }
        if let Some(d) = &self.damping {
            if d.ratios.is_empty() {
                bail!("`damping.ratios` needs at least one damping ratio (mode 1, then 2, …)");
            }
            for (i, z) in d.ratios.iter().enumerate() {
                if !(z.is_finite() && *z >= 0.0 && *z < 1.0) {
                    bail!("`damping.ratios[{i}]` must be in [0, 1) (got {z})");
                }
            }
        }
        if let Some(b) = &self.beam {
            positive(b.length_m, "beam.length_m")?;
            positive(b.density_kg_m3, "beam.density_kg_m3")?;
            positive(b.youngs_modulus_pa, "beam.youngs_modulus_pa")?;
            self.profile()?;
        }
        Ok(())
    }

    /// The beam's A(x), I(x). Errors: no or both of `stations`/`profile`, fewer than 2
    /// stations, non-positive sizes, unsorted stations, a profile not spanning [0, l].
    pub fn profile(&self) -> Result<SectionProfile> {
        let b = self
            .beam
            .as_ref()
            .context("the rig has no [beam] section")?;
        let p = match (b.stations.is_empty(), b.profile.is_empty()) {
            (false, true) => {
                for (i, s) in b.stations.iter().enumerate() {
                    positive(s.width_m, &format!("beam.stations[{i}].width_m"))?;
                    positive(s.thickness_m, &format!("beam.stations[{i}].thickness_m"))?;
                }
                SectionProfile {
                    x_m: b.stations.iter().map(|s| s.x_m).collect(),
                    area_m2: b
                        .stations
                        .iter()
                        .map(|s| s.width_m * s.thickness_m)
                        .collect(),
                    inertia_m4: b
                        .stations
                        .iter()
                        .map(|s| s.width_m * s.thickness_m.powi(3) / 12.0)
                        .collect(),
                    rectangle_m: Some(
                        b.stations
                            .iter()
                            .map(|s| (s.width_m, s.thickness_m))
                            .collect(),
                    ),
                }
            }
            (true, false) => {
                for (i, s) in b.profile.iter().enumerate() {
                    positive(s.area_m2, &format!("beam.profile[{i}].area_m2"))?;
                    positive(s.inertia_m4, &format!("beam.profile[{i}].inertia_m4"))?;
                }
                SectionProfile {
                    x_m: b.profile.iter().map(|s| s.x_m).collect(),
                    area_m2: b.profile.iter().map(|s| s.area_m2).collect(),
                    inertia_m4: b.profile.iter().map(|s| s.inertia_m4).collect(),
                    rectangle_m: None,
                }
            }
            (true, true) => {
                bail!("`beam` needs `stations` (rectangular) or `profile` (tabulated A, I)")
            }
            (false, false) => bail!("`beam` has both `stations` and `profile`; give one"),
        };
        let key = if b.stations.is_empty() {
            "beam.profile"
        } else {
            "beam.stations"
        };
        if p.x_m.len() < 2 {
            bail!("`{key}` needs at least 2 entries (root and tip)");
        }
        if p.x_m.windows(2).any(|w| !(w[1] > w[0])) {
            bail!("`{key}` must be sorted by strictly increasing x_m");
        }
        if p.x_m[0].abs() > 1e-9
            || (p.x_m[p.x_m.len() - 1] - b.length_m).abs() > 1e-9 * b.length_m.max(1.0)
        {
            bail!(
                "`{key}` must run from x_m = 0 to x_m = beam.length_m = {}",
                b.length_m
            );
        }
        Ok(p)
    }

    /// Damping ratios of modes 1 and 2 (one value is used for both; entries for higher modes
    /// are not Rayleigh's; default 0.0074, the paper's eq. 35).
    pub fn damping_ratios(&self) -> (f64, f64) {
        match self.damping.as_ref().map(|d| d.ratios.as_slice()) {
            Some([z]) => (*z, *z),
            Some([z1, z2, ..]) => (*z1, *z2),
            _ => (0.0074, 0.0074),
        }
    }

    /// Sample rate of recordings (Hz; default 100, the paper's camera).
    pub fn sample_rate_hz(&self) -> f64 {
        self.sensors.as_ref().map_or(100.0, |s| s.sample_rate_hz)
    }
}
