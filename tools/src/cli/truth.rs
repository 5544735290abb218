//! `truth` subcommand: write one concealed-effect case (rig + recordings + truth.json).

use crate::truth::{generate, TruthOptions};
use anyhow::Result;
use clap::Args;
use std::path::PathBuf;

/// `truth` arguments.
#[derive(Args, Debug)]
pub struct TruthArgs {
    /// Effect to hide: none, base_friction, servo_lag, tip_mass, root_compliance,
    /// quadratic_damping, sensor_delay, gravity_axial_load, mount_resonance, cogging_ripple,
    /// sensor_gain, backlash, cubic_stiffness; several joined by `+` (e.g. backlash+servo_lag).
    #[arg(long, default_value = "none")]
    pub effect: String,
    /// Random seed (geometry, damping, noise, channels, strength, profiles).
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Duration of each recording (s).
    #[arg(long, default_value_t = 60.0)]
    pub duration_s: f64,
    /// Number of fit recordings.
    #[arg(long, default_value_t = 2)]
    pub n_fit: usize,
    /// Physics outside the diagnosis catalogue to switch on (off by default).
    #[arg(long, value_enum)]
    pub unmodelled: Option<crate::truth::unmodelled::Unmodelled>,
    /// Output sample rate (Hz).
    #[arg(long, default_value_t = 100.0)]
    pub rate_hz: f64,
    /// Record no `base_pos_m` (default: drawn from the seed).
    #[arg(long)]
    pub no_base: bool,
    /// Record no `force_n` (default: drawn from the seed).
    #[arg(long)]
    pub no_force: bool,
    /// Multiply every sensor-noise σ by this.
    #[arg(long, default_value_t = 1.0)]
    pub noise_scale: f64,
    /// Output directory.
    #[arg(long, default_value = "truth-case")]
    pub out: PathBuf,
}

/// Runs `truth`.
pub fn truth(a: TruthArgs) -> Result<()> {
    let opts = TruthOptions {
        duration_s: a.duration_s,
        n_fit: a.n_fit.max(1),
        rate_hz: a.rate_hz,
        unmodelled: a.unmodelled,
        base_pos: a.no_base.then_some(false),
        force: a.no_force.then_some(false),
        noise_scale: a.noise_scale,
    };
    let case = generate(&a.effect, a.seed, &opts)?;
    case.write(&a.out)?;
    println!(
        "wrote {} (rig.toml, {} fit recordings, validate.csv, truth.json); hidden effect: {}{}",
        a.out.display(),
        case.fit.len(),
        a.effect,
        a.unmodelled
            .map_or(String::new(), |u| format!(" + unmodelled {}", u.id()))
    );
    Ok(())
}
