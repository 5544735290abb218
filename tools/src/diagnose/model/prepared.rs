//! One recording prepared for simulation ([`Prepared`]): uniform dt, the command (or the measured
//! base when no command was recorded), the drive with its measurement noise removed
//! ([`drive_of`]) and the measured channels with their rails and gaps.

use anyhow::{bail, Result};

/// One recording prepared for simulation: uniform dt, the command (or the measured base when
/// no command was recorded) and the measured channels.
#[derive(Clone, Debug)]
pub struct Prepared {
    /// Name (file).
    pub name: String,
    /// Sample interval (s).
    pub dt: f64,
    /// Time (s).
    pub time_s: Vec<f64>,
    /// Base command (m), as the model's input (at a working rate below the recording's,
    /// emphasised against its piecewise-linear interpolation, [`crate::diagnose::rate`]).
    pub cmd_m: Vec<f64>,
    /// The command as recorded (filtered, not emphasised) when `cmd_m` is emphasised: the
    /// predicted base of a model without a servo loop; `None` = `cmd_m`.
    pub cmd_identity_m: Option<Vec<f64>>,
    /// Measured base position (m), if recorded *and* a command exists.
    pub base_m: Option<Vec<f64>>,
    /// Measured base used to drive the beam (= `base_m`, or the base when it is the only one).
    pub drive_m: Option<Vec<f64>>,
    /// `drive_m` as sampled (not emphasised) when `drive_m` is emphasised; `None` = `drive_m`.
    pub drive_identity_m: Option<Vec<f64>>,
    /// Tip position (m).
    pub tip_m: Option<Vec<f64>>,
    /// Force (N).
    pub force_n: Option<Vec<f64>>,
    /// Samples held at a sensor's rail, per compared channel (base, tip, force): left out of
    /// every residual ([`crate::diagnose::saturation`]; the base, which also drives the model, has none).
    pub rails: [crate::diagnose::saturation::Rails; 3],
    /// Runs where a compared channel had no reading (base, tip, force; a sensor that lost its
    /// target for longer than the loader fills, bridged by a straight line): left out of every
    /// residual as the rails are ([`Prepared::with_gaps`]; the base, which drives the model,
    /// has none). The `values` of each are empty.
    pub gaps: [crate::diagnose::saturation::Rails; 3],
    /// The recording does not start at rest (a logger started mid-motion, or while the beam
    /// still rang: [`crate::recording::zero::starts_at_rest`]): the prediction adds the beam
    /// modes' free response from an unknown initial state ([`add_free_response`]).
    pub free_start: bool,
}

impl Prepared {
    /// Prepares a validated recording; finds the rails of its tip and force channels
    /// ([`crate::diagnose::saturation`]). Errors: no `base_cmd_m` and no `base_pos_m`, no channel to
    /// compare with, a channel more than [`crate::diagnose::saturation::MAX_RAIL_FRACTION`] at its rails.
    pub fn new(name: &str, rec: &crate::recording::Recording) -> Result<Prepared> {
        rec.validate()?;
        let (cmd, base, drive) = match (&rec.base_cmd_m, &rec.base_pos_m) {
            (Some(c), b) => (c.clone(), b.clone(), b.as_ref().map(|b| drive_of(c, b))),
            (None, Some(b)) => (b.clone(), None, Some(b.clone())),
            (None, None) => bail!("{name}: needs `base_cmd_m` or `base_pos_m` (the base motion that drives the model)"),
        };
        if base.is_none() && rec.tip_pos_m.is_none() && rec.force_n.is_none() {
            bail!("{name}: nothing to compare: record at least one of `base_pos_m` (with `base_cmd_m`), `tip_pos_m`, `force_n`");
        }
        let rails_of = |c: &Option<Vec<f64>>,
                        channel: &str|
         -> Result<crate::diagnose::saturation::Rails> {
            let Some(y) = c else {
                return Ok(Default::default());
            };
            let r = crate::diagnose::saturation::rails(y);
            let share = r.samples() as f64 / y.len().max(1) as f64;
            if share > crate::diagnose::saturation::MAX_RAIL_FRACTION {
                bail!(
                    "{name}: {channel} sits at its sensor's rail ({}) on {:.0} % of the samples: too little of the motion was recorded; reduce the amplitude or widen the sensor's range",
                    r.values_words(),
                    100.0 * share
                );
            }
            Ok(r)
        };
        let rails = [
            Default::default(),
            rails_of(&rec.tip_pos_m, "tip_pos_m")?,
            rails_of(&rec.force_n, "force_n")?,
        ];
        Ok(Prepared {
            name: name.to_string(),
            dt: rec.sample_interval_s(),
            time_s: rec.time_s.clone(),
            cmd_m: cmd,
            cmd_identity_m: None,
            base_m: base,
            drive_m: drive,
            drive_identity_m: None,
            tip_m: rec.tip_pos_m.clone(),
            force_n: rec.force_n.clone(),
            rails,
            gaps: Default::default(),
            free_start: false,
        })
    }

    /// This recording with the runs `gaps` of its tip and force channels (as read by
    /// [`crate::recording::regular::regularise_leaving_gaps`]) left out of every residual.
    /// Errors: a gap in `base_pos_m` or `base_cmd_m` (they drive the model), or more than
    /// [`crate::diagnose::saturation::MAX_RAIL_FRACTION`] of a channel at its rails or in gaps.
    pub fn with_gaps(mut self, gaps: &crate::recording::regular::Gaps) -> Result<Prepared> {
        for (name, runs) in &gaps.runs {
            let c = match *name {
                "tip_pos_m" => 1,
                "force_n" => 2,
                _ => bail!("{}: {name} has no reading for a while: the base motion drives the model and cannot be left out; cut the recording there", self.name),
            };
            let len = self.cmd_m.len();
            let share = (self.rails[c].samples() + runs.iter().map(|(a, b)| b - a).sum::<usize>())
                as f64
                / len.max(1) as f64;
            if share > crate::diagnose::saturation::MAX_RAIL_FRACTION {
                bail!(
                    "{}: {name} has no usable reading (at a rail or missing) on {:.0} % of the samples: too little of the motion was recorded",
                    self.name,
                    100.0 * share
                );
            }
            self.gaps[c] = crate::diagnose::saturation::Rails {
                values: Vec::new(),
                runs: runs.clone(),
            };
        }
        Ok(self)
    }
}

impl Prepared {
    /// The command as recorded (at the working rate, not [emphasised](crate::diagnose::rate::emphasise)).
    pub fn cmd_as_sampled(&self) -> &[f64] {
        self.cmd_identity_m.as_deref().unwrap_or(&self.cmd_m)
    }

    /// The measured drive, else the command, as sampled (not emphasised): what a yardstick
    /// built from the recordings (the physics-free correction) may use. The emphasised inputs
    /// differ from these by ≈ (π²/3) dt² × their second derivative, a derivative of the motion
    /// that the model's own physics (a servo loop, an inertia) should have to earn.
    pub fn drive_as_sampled(&self) -> &[f64] {
        match &self.drive_m {
            Some(m) => self.drive_identity_m.as_deref().unwrap_or(m),
            None => self.cmd_as_sampled(),
        }
    }

    /// The largest tip deflection relative to the drive as sampled, max |tip − drive| (m);
    /// `None` without a tip channel.
    pub fn peak_deflection_m(&self) -> Option<f64> {
        let tip = self.tip_m.as_ref()?;
        Some(
            tip.iter()
                .zip(self.drive_as_sampled())
                .map(|(a, b)| (a - b).abs())
                .fold(0.0, f64::max),
        )
    }
}

/// The base motion that drives the model when `base_pos_m` (`base`) is recorded with its
/// command `cmd`: the command plus the measured following error (base − command) with its white
/// measurement noise removed ([`wiener_denoise`](crate::numeric::stats::wiener_denoise)). The
/// model differentiates its drive twice (the carriage's inertia on `force_n`, the beam root's
/// acceleration); a position sensor's noise σ becomes an acceleration noise of about
/// √6 σ / dt², which at high sample rates outweighs the motion's own acceleration — the force
/// calibration then fits a carriage without mass (errors in the input variable). The
/// following error's own content above the noise floor (the loop's lag and ripple) is kept.
pub fn drive_of(cmd: &[f64], base: &[f64]) -> Vec<f64> {
    let e: Vec<f64> = base.iter().zip(cmd).map(|(b, c)| b - c).collect();
    crate::numeric::stats::wiener_denoise(&e)
        .iter()
        .zip(cmd)
        .map(|(e, c)| c + e)
        .collect()
}
