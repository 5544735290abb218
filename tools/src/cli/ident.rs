//! `identify`, `sweep` and `frf`: arguments, printing and files of the identification commands
//! over [`crate::ident`].

use crate::ident::freedecay::FreeDecayOptions;
use crate::ident::frf::{
    frf_of_recording, Detrend, InputChannel, OutputChannel, WelchOptions, Window,
};
use crate::ident::report;
use crate::ident::sweep::{
    design_sweep, tip_modes_of_model, uniform_tip_modes, SweepDesign, SweepKind, SweepSpec,
};
use crate::ident::{IdentOptions, IdentifyOptions, Method, PathChoice, Stage};
use crate::recording::Recording;
use anyhow::{bail, Context, Result};
use clap::Args;
use std::path::{Path, PathBuf};

/// `identify` arguments.
#[derive(Args, Debug)]
pub struct IdentifyArgs {
    /// Recording: `.npy` (2, N) [time_s; signal] or recording CSV (uses the tip deflection
    /// tip_pos_m − base_pos_m after the base last moved), or a LabVIEW `.lvm` magnitude
    /// spectrum (frequency Hz, dB) of an impact test.
    pub recording: PathBuf,
    /// Lowest frequency considered (Hz).
    #[arg(long, default_value_t = 0.2)]
    pub f_min_hz: f64,
    /// Highest frequency considered (Hz).
    #[arg(long, default_value_t = 500.0)]
    pub f_max_hz: f64,
    /// Write the result as JSON here.
    #[arg(long)]
    pub json: Option<PathBuf>,
    /// Methods for an input/output recording: lscf (default, the most robust), lsce (the
    /// paper's), peak, logdec (free decays after each move), all; comma-separated, the first
    /// is primary. A `.npy` or a recording without an input channel is a free decay.
    #[arg(long, default_value = "lscf")]
    pub method: String,
    /// FRF input: accel (base acceleration from base_pos_m), force (force_n), pos.
    #[arg(long, default_value = "accel")]
    pub input: String,
    /// FRF output: deflection (tip_pos_m - base_pos_m) or tip (absolute).
    #[arg(long, default_value = "deflection")]
    pub output: String,
    /// Band for the FRF methods (Hz), e.g. `0.3,8`; default: where the input has energy.
    #[arg(long)]
    pub band: Option<String>,
    /// Keep the N best-supported modes.
    #[arg(long)]
    pub modes: Option<usize>,
    /// Highest model order (LSCF) / number of poles (LSCE).
    #[arg(long, default_value_t = 32)]
    pub max_order: usize,
    /// FRF window: rect (default: one segment, a sweep from rest to rest), hamming, hann, exp.
    #[arg(long, default_value = "rect")]
    pub window: String,
    /// Welch segment length (samples); default the whole record.
    #[arg(long)]
    pub nperseg: Option<usize>,
    /// No sweep-tracking filter on the input.
    #[arg(long)]
    pub no_track: bool,
    /// Sanathanan–Koerner iterations of LSCF (removes output-noise damping bias).
    #[arg(long, default_value_t = 1)]
    pub sk: usize,
    /// No maximum-likelihood (output-error) refinement of the primary method's modes.
    #[arg(long)]
    pub no_ml: bool,
    /// Write the stabilisation diagram (SVG) here.
    #[arg(long)]
    pub stab_plot: Option<PathBuf>,
    /// Write the FRF plot (SVG) here (and `<name>-coherence.svg`).
    #[arg(long)]
    pub frf_plot: Option<PathBuf>,
    /// Identification path: auto (decided from the recording and reported), frf (input/output
    /// FRF), decay (free decay of the tip, after the base's last move), output-only (SSI-cov),
    /// spectrum (peaks of Klipper's PSD of a raw accelerometer file; auto takes it for a
    /// resonance test's sweep).
    #[arg(long, default_value = "auto")]
    pub path: String,
    /// How the recording is read (`--columns`, `--axis`).
    #[command(flatten)]
    pub read: super::read::ReadArgs,
    /// Benchmark: wall time per stage, peak RSS (VmHWM), and the peer's run (--peer-python).
    #[arg(long)]
    pub bench: bool,
    /// With --bench: a Python with numpy, scipy and sdypy-EMA to run the peer
    /// (bench/identify_peer.py: scipy csd/welch H1 + sdypy-EMA LSCF) on the same file.
    #[arg(long, requires = "bench")]
    pub peer_python: Option<PathBuf>,
    /// With --bench: the peer's script (default: bench/identify_peer.py of this checkout).
    #[arg(long, requires = "bench")]
    pub peer_script: Option<PathBuf>,
}

fn parse_band(s: &str) -> Result<(f64, f64)> {
    let v: Vec<&str> = s.split(',').collect();
    if v.len() != 2 {
        bail!("--band wants `f_lo,f_hi` in Hz (got `{s}`)");
    }
    let p = |x: &str| {
        x.trim()
            .parse::<f64>()
            .with_context(|| format!("--band: `{x}` is not a number"))
    };
    Ok((p(v[0])?, p(v[1])?))
}

/// The [`IdentOptions`] of the `identify`/`frf` arguments.
pub fn options_of(a: &IdentifyArgs) -> Result<IdentOptions> {
    let mut o = IdentOptions {
        methods: Method::parse_list(&a.method)?,
        input: InputChannel::from_name(&a.input)?,
        output: OutputChannel::from_name(&a.output)?,
        band_hz: a.band.as_deref().map(parse_band).transpose()?,
        n_modes: a.modes,
        max_order: a.max_order,
        track_input: !a.no_track,
        sk_iterations: a.sk,
        ml_refine: !a.no_ml,
        ..Default::default()
    };
    o.welch.window = Window::from_name(&a.window)?;
    o.welch.nperseg = a.nperseg;
    Ok(o)
}

/// `beamtool identify` on a magnitude spectrum (`.lvm`): [`crate::ident::magspec`], at most
/// `--modes` (default 6) peaks ≥ 10 dB above their neighbourhood in `--f-min-hz..--f-max-hz`.
fn identify_spectrum(a: &IdentifyArgs) -> Result<()> {
    let s = crate::ident::magspec::read_lvm(&a.recording)?;
    let df = s.freq_hz[1] - s.freq_hz[0];
    let modes = crate::ident::magspec::identify_magnitude_spectrum(
        &s,
        a.f_min_hz,
        a.f_max_hz,
        10.0,
        a.modes.unwrap_or(6),
    )?;
    println!(
        "{}: magnitude spectrum (dB re 1 {}), {} lines, df = {:.4} Hz (record {:.2} s); single-mode accelerance fits",
        a.recording.display(),
        if s.unit.is_empty() { "?" } else { s.unit.as_str() },
        s.freq_hz.len(),
        df,
        1.0 / df
    );
    println!(
        "  {:>4} {:>11} {:>9} {:>10} {:>9} {:>12} {:>10} {:>9}",
        "mode", "f (Hz)", "+-1sd", "zeta", "+-1sd", "prominence", "half-pwr", "misfit"
    );
    for (i, m) in modes.iter().enumerate() {
        println!(
            "  {:>4} {:>11.4} {:>9.4} {:>10} {:>9.5} {:>9.1} dB {:>6.1} ln {:>6.2} dB",
            i + 1,
            m.freq_hz,
            m.freq_hz_std,
            if m.resolution_limited {
                format!("<={:.5}", m.zeta)
            } else {
                format!("{:.5}", m.zeta)
            },
            m.zeta_std,
            m.prominence_db,
            m.half_power_lines,
            m.rms_misfit_db
        );
    }
    if modes.iter().any(|m| m.resolution_limited) {
        println!("  <= : the half-power band spans fewer than {} lines; without phase or a time record the damping is an upper bound (record longer)", crate::ident::magspec::RESOLVED_LINES);
    }
    if modes.len() >= 2 {
        let f1 = modes[0].freq_hz;
        let ratios: Vec<String> = modes[1..]
            .iter()
            .map(|m| format!("{:.3}", m.freq_hz / f1))
            .collect();
        println!("  frequency ratios to mode 1: {} (uniform clamped-free beam: 6.267, 17.547, 34.386, 56.842)", ratios.join(", "));
    }
    if let Some(j) = &a.json {
        std::fs::write(j, serde_json::to_string_pretty(&modes)?)
            .with_context(|| format!("cannot write {}", j.display()))?;
        println!("JSON -> {}", j.display());
    }
    Ok(())
}

/// The [`IdentifyOptions`] of the `identify` arguments.
pub fn identify_options_of(a: &IdentifyArgs) -> Result<IdentifyOptions> {
    for (name, v) in [("--f-min-hz", a.f_min_hz), ("--f-max-hz", a.f_max_hz)] {
        if !v.is_finite() || v < 0.0 {
            bail!("{name} {v}: want a finite frequency >= 0 Hz");
        }
    }
    if a.f_max_hz <= a.f_min_hz {
        bail!(
            "--f-max-hz {} must exceed --f-min-hz {}",
            a.f_max_hz,
            a.f_min_hz
        );
    }
    let frf = options_of(a)?;
    Ok(IdentifyOptions {
        path: PathChoice::from_name(&a.path)?,
        frf,
        decay: FreeDecayOptions {
            f_min_hz: a.f_min_hz,
            f_max_hz: a.f_max_hz,
            ..Default::default()
        },
        read: a.read.options(),
        ..Default::default()
    })
}

/// Progress of [`crate::ident::identify()`] as one line per stage on stderr (reading: every 2²⁰ rows).
pub fn progress_line(stage: Stage) {
    eprintln!("  .. {stage}");
}

/// `beamtool identify`: [`crate::ident::identify::identify_file`], then the table, the stabilisation
/// diagram (FRF path), plots and JSON.
pub fn identify(a: IdentifyArgs) -> Result<()> {
    let opts = identify_options_of(&a)?;
    if a.recording
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("lvm"))
    {
        return identify_spectrum(&a);
    }
    let mut clock = super::identbench::StageClock::start();
    let id = crate::ident::identify::identify_file(&a.recording, &opts, &mut |s| {
        clock.mark(&s);
        progress_line(s)
    })?;
    let end = std::time::Instant::now();
    println!("{}:", a.recording.display());
    print!("{}", report::identification_table(&id));
    if let Some((r, frf)) = &id.frf_result {
        for mr in &r.methods {
            if let Some(d) = &mr.diagram {
                print!("{}", d.text(r.band_hz.0, r.band_hz.1, 72));
            }
        }
        if let Some(p) = &a.stab_plot {
            if let Some(d) = r.methods.iter().find_map(|m| m.diagram.as_ref()) {
                let mag: Vec<f64> = frf.h1.iter().map(|c| c.norm()).collect();
                write_file(p, &d.svg(&frf.freq_hz, &mag, r.band_hz.0, r.band_hz.1)?)?;
                println!("stabilisation diagram -> {}", p.display());
            }
        }
        if let Some(p) = &a.frf_plot {
            write_frf_plots(p, frf, r.band_hz.0, r.band_hz.1)?;
            println!("FRF plot -> {}", p.display());
        }
    }
    if let Some(r) = &id.decay_result {
        println!(
            "  mode 1 log decrement (eqs. 28-29, {} peaks): f = {:.4} Hz, zeta = {:.5}; damped-sinusoid fit: f = {:.4} Hz, zeta = {:.5}; decay {:.3}..{:.3} s",
            r.log_decrement.2, r.log_decrement.0, r.log_decrement.1, r.sinusoid_fit.0, r.sinusoid_fit.1, r.segment_s.0, r.segment_s.1
        );
    }
    if let Some(j) = &a.json {
        std::fs::write(j, serde_json::to_string_pretty(&id)?)
            .with_context(|| format!("cannot write {}", j.display()))?;
        println!("JSON -> {}", j.display());
    }
    if a.bench {
        let b = super::identbench::BenchArgs {
            file: &a.recording,
            python: a.peer_python.as_deref(),
            script: a.peer_script.as_deref(),
            window: opts.frf.welch.window,
            max_order: opts.frf.max_order,
        };
        super::identbench::print_bench(&b, &id, &clock, end);
    }
    Ok(())
}

/// `sweep` arguments.
#[derive(Args, Debug)]
pub struct SweepArgs {
    /// linear (rate in Hz/s, eq. 33) or exponential (octaves/min, eq. 34).
    #[arg(long, default_value = "exponential")]
    pub kind: String,
    /// Sweep rate beta; negative sweeps down from f_b.
    #[arg(long, allow_hyphen_values = true, default_value_t = 3.0)]
    pub rate: f64,
    /// Lower frequency f_a (Hz).
    #[arg(long, default_value_t = 0.1)]
    pub f_a_hz: f64,
    /// Upper frequency f_b (Hz).
    #[arg(long, default_value_t = 8.0)]
    pub f_b_hz: f64,
    /// Command sample rate (Hz).
    #[arg(long, default_value_t = 1000.0)]
    pub rate_hz: f64,
    /// Peak base stroke (mm).
    #[arg(long, default_value_t = 20.0)]
    pub stroke_mm: f64,
    /// Peak base acceleration (m/s²).
    #[arg(long, default_value_t = 2.0)]
    pub accel_max: f64,
    /// Peak tip deflection (mm), from the rig model's modes (--rig) or --mode.
    #[arg(long)]
    pub tip_max_mm: Option<f64>,
    /// Rig file for the tip-deflection limit and the check simulation.
    #[arg(long)]
    pub rig: Option<PathBuf>,
    /// A mode `f_hz:zeta` (repeatable; uniform-cantilever participation) for the tip limit.
    #[arg(long)]
    pub mode: Vec<String>,
    /// Fade in/out (s).
    #[arg(long, default_value_t = 2.0)]
    pub fade_s: f64,
    /// Rest before (s).
    #[arg(long, default_value_t = 1.0)]
    pub lead_s: f64,
    /// Rest after, for the ring-down (s).
    #[arg(long, default_value_t = 20.0)]
    pub tail_s: f64,
    /// Output command CSV (time_s, base_cmd_m).
    #[arg(long, default_value = "sweep.csv")]
    pub out: PathBuf,
}

impl SweepArgs {
    /// The (f_hz, ζ) of every `--mode f_hz:zeta`.
    fn modes(&self) -> Result<Vec<(f64, f64)>> {
        self.mode
            .iter()
            .map(|s| {
                let v: Vec<&str> = s.split(':').collect();
                let p = |x: &str| {
                    x.trim()
                        .parse::<f64>()
                        .with_context(|| format!("--mode `{s}`: want f_hz:zeta"))
                };
                if v.len() != 2 {
                    bail!("--mode `{s}`: want f_hz:zeta");
                }
                Ok((p(v[0])?, p(v[1])?))
            })
            .collect()
    }

    /// The sweep specification of these arguments, without tip modes.
    ///
    /// Errors: an unknown `--kind`.
    pub fn spec(&self) -> Result<SweepSpec> {
        Ok(SweepSpec {
            kind: SweepKind::from_name(&self.kind)?,
            f_a_hz: self.f_a_hz,
            f_b_hz: self.f_b_hz,
            rate: self.rate,
            sample_rate_hz: self.rate_hz,
            stroke_max_m: self.stroke_mm * 1e-3,
            accel_max_m_s2: self.accel_max,
            tip_max_m: self.tip_max_mm.map(|v| v * 1e-3),
            tip_modes: vec![],
            fade_s: self.fade_s,
            lead_s: self.lead_s,
            tail_s: self.tail_s,
        })
    }
}

/// `beamtool sweep`: [`design_sweep`] with the modes of `--rig` and `--mode`, written as a
/// command CSV.
pub fn sweep(a: SweepArgs) -> Result<()> {
    let mut spec = a.spec()?;
    let model = match &a.rig {
        Some(r) => {
            let rig = crate::model::Rig::from_toml_file(r)?;
            let opts = crate::model::ModelOptions::default();
            Some(crate::model::BeamModel::new(&rig, &opts)?)
        }
        None => None,
    };
    if let Some(m) = &model {
        spec.tip_modes = tip_modes_of_model(m)?;
    }
    spec.tip_modes
        .extend(uniform_tip_modes(&a.modes()?).context("--mode")?);
    let d = design_sweep(&spec, model.as_ref())?;
    let rec = Recording {
        time_s: d.sweep.time_s.clone(),
        base_cmd_m: Some(d.sweep.base_cmd_m.clone()),
        ..Default::default()
    };
    rec.write_csv(&a.out)?;
    print_sweep(&a, &d);
    Ok(())
}

fn print_sweep(a: &SweepArgs, d: &SweepDesign) {
    let (spec, s) = (&d.spec, &d.sweep);
    println!("{:?} sweep {}..{} Hz, beta = {} ({}), T = {:.2} s (+{} s lead, {} s tail), {} samples at {} Hz -> {}",
        spec.kind, spec.f_a_hz, spec.f_b_hz, spec.rate, if spec.kind == SweepKind::Linear { "Hz/s" } else { "octaves/min" },
        s.duration_s, spec.lead_s, spec.tail_s, s.time_s.len(), spec.sample_rate_hz, a.out.display());
    println!(
        "peak stroke {:.3} mm (limit {}), peak acceleration {:.3} m/s^2 (limit {})",
        s.peak_stroke_m * 1e3,
        a.stroke_mm,
        s.peak_accel_m_s2,
        a.accel_max
    );
    if let Some(peak) = d.simulated_peak_tip_m {
        println!(
            "simulated on the rig: peak tip deflection {:.3} mm{}",
            peak * 1e3,
            a.tip_max_mm.map_or(String::new(), |l| format!(
                " (limit {l} mm; envelope limit tightened to {:.2} mm steady state)",
                spec.tip_max_m.unwrap_or(0.0) * 1e3
            ))
        );
    }
}

/// `frf` arguments.
#[derive(Args, Debug)]
pub struct FrfArgs {
    /// Recording CSV.
    pub recording: PathBuf,
    /// Input: force, accel, pos.
    #[arg(long, default_value = "accel")]
    pub input: String,
    /// Output: deflection, tip.
    #[arg(long, default_value = "deflection")]
    pub output: String,
    /// Window: hamming (paper), hann, rect, exp, exp:<end>.
    #[arg(long, default_value = "hamming")]
    pub window: String,
    /// Segment length (samples); default a quarter of the record.
    #[arg(long)]
    pub nperseg: Option<usize>,
    /// Overlap fraction.
    #[arg(long, default_value_t = 0.5)]
    pub overlap: f64,
    /// Detrend: none, mean, linear.
    #[arg(long, default_value = "mean")]
    pub detrend: String,
    /// Band to write and plot (Hz), `f_lo,f_hi`; default 0..Nyquist.
    #[arg(long)]
    pub band: Option<String>,
    /// Output CSV: freq_hz, h1_re, h1_im, h2_re, h2_im, coherence.
    #[arg(long, default_value = "frf.csv")]
    pub out: PathBuf,
    /// Plot (SVG).
    #[arg(long)]
    pub plot: Option<PathBuf>,
    /// JSON of the whole estimate.
    #[arg(long)]
    pub json: Option<PathBuf>,
    /// How the recording is read (`--columns`, `--axis`).
    #[command(flatten)]
    pub read: super::read::ReadArgs,
}

/// `beamtool frf`.
pub fn frf(a: FrfArgs) -> Result<()> {
    let rec = super::read_recording_with(&a.recording, &a.read.options())?;
    let opts = WelchOptions {
        nperseg: Some(a.nperseg.unwrap_or(rec.len() / 4)),
        overlap: a.overlap,
        window: Window::from_name(&a.window)?,
        detrend: Detrend::from_name(&a.detrend)?,
        pad: 1,
    };
    let (f, warnings) = frf_of_recording(
        &rec,
        InputChannel::from_name(&a.input)?,
        OutputChannel::from_name(&a.output)?,
        &opts,
    )?;
    for w in &warnings {
        println!("warning: {w}");
    }
    let nyq = 0.5 * f.sample_rate_hz;
    let (lo, hi) = a
        .band
        .as_deref()
        .map(parse_band)
        .transpose()?
        .unwrap_or((0.0, nyq));
    if hi > nyq * (1.0 + 1e-9) {
        bail!("--band upper limit {hi} Hz is beyond the Nyquist frequency {nyq} Hz");
    }
    let mut w = csv::Writer::from_path(&a.out)
        .with_context(|| format!("cannot write {}", a.out.display()))?;
    w.write_record(["freq_hz", "h1_re", "h1_im", "h2_re", "h2_im", "coherence"])?;
    for k in f.band(lo, hi) {
        w.write_record(
            [
                f.freq_hz[k],
                f.h1[k].re,
                f.h1[k].im,
                f.h2[k].re,
                f.h2[k].im,
                f.coherence[k],
            ]
            .iter()
            .map(|v| format!("{v:.9e}")),
        )?;
    }
    w.flush()?;
    println!("FRF {} -> {}: {} averages of {} samples ({:?} window, {:.0} % overlap), df = {:.4} Hz -> {}", f.input, f.output, f.n_averages, f.nperseg, opts.window, 100.0 * opts.overlap, f.df_hz(), a.out.display());
    if let Some(p) = &a.plot {
        write_frf_plots(p, &f, lo.max(f.df_hz()), hi)?;
        println!("plot -> {}", p.display());
    }
    if let Some(j) = &a.json {
        std::fs::write(j, serde_json::to_string(&f)?)
            .with_context(|| format!("cannot write {}", j.display()))?;
        println!("JSON -> {}", j.display());
    }
    Ok(())
}

/// Writes `text` to `path`.
fn write_file(path: &Path, text: &str) -> Result<()> {
    std::fs::write(path, text).with_context(|| format!("cannot write {}", path.display()))
}

/// [`report::frf_svgs`] written to `path` and `<stem>-coherence.svg` beside it.
fn write_frf_plots(path: &Path, frf: &crate::ident::frf::Frf, f_lo: f64, f_hi: f64) -> Result<()> {
    let (h, coh) = report::frf_svgs(frf, f_lo, f_hi)?;
    write_file(path, &h)?;
    let stem = path
        .file_stem()
        .map(|s| s.to_string_lossy().to_string())
        .unwrap_or_default();
    write_file(&path.with_file_name(format!("{stem}-coherence.svg")), &coh)
}
