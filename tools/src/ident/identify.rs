//! The one identification entry point: [`identify`] takes any recording — a sweep or other
//! broadband input/output recording, a free decay, or moves followed by a ring-down — and
//! returns the modes (natural frequency Hz, damping ratio, both with 1-σ), the path it took
//! and why, the modes it rejected and why, and warnings. It prints nothing; it reports its
//! stages through a callback (the CLI draws the progress).
//!
//! Steps:
//! 1. **Gaps** ([`gap_threshold_s`]): time steps longer than max(5 median steps, a tenth of
//!    the dominant period) split the recording; the longest clean segment is used, with a
//!    warning (interpolating across a gap biases the decay: docs/ident.md, "Numbers behind
//!    the design choices").
//! 2. **Base stillness** ([`base_motion`]): the base's noise is measured where it ends
//!    (1.4826 × MAD of the last 10 % of the recording); the base is still from the last
//!    sample that leaves ±6 σ of its final position. A servo dithering by ±2 µm is still.
//! 3. **Path** ([`choose_path`]): no input channel, or a base that never leaves its noise
//!    band → free decay of the tip; a base that oscillates (≥ 6 reversals beyond its noise)
//!    → FRF path (Welch H1, LSCF/LSCE stabilised over orders, ML refinement, paper §5.2);
//!    moves (fewer reversals) followed by ≥ 3 s of stillness → free decay of the tip
//!    deflection after the last move (log decrement eqs. 28–29 + damped-sinusoid fits). A base
//!    that keeps creeping after its move (still for less than 3 s) is judged by what the tip's
//!    dominant mode sees of it instead ([`super::quiet`]: its increments' excitation and its
//!    quasi-static deflection against the decay the tip shows; the bound widens the σ).
//! 4. **Only physical modes** ([`screen_modes`], FRF path): a mode must be stable at ≥ 25 %
//!    of the model orders, show a peak in the output auto-spectrum ≥ 13 dB over its local
//!    noise floor where the input has energy (within 40 dB of its in-band maximum), and have
//!    a plausible damping ratio (10⁻⁴ ≤ ζ < `zeta_max`, 1-σ below ζ); of two modes within
//!    5 % the one stable at fewer orders is a split peak.
//!    The maximum-likelihood refinement then runs on the kept modes only.
//! 5. **Long recordings** ([`super::longrec`]): the FRF path decimates to 4 × the band's top
//!    (anti-aliased FIR) and takes its Welch segments from resolution (the lowest mode's
//!    half-power band in 16 lines, after an exploring pass at the band's resolution), never
//!    longer than [`IdentifyOptions::max_segment`] samples (bounded memory).

use super::freedecay::identify_free_decay;
use super::frf::{Frf, InputChannel, Window};
use super::identify_paths::{base_channel, identify_spectrum_file, tip_signal};
use super::identify_types::rayleigh;
pub use super::identify_types::{
    BaseMotion, IdentPath, Identification, IdentifyOptions, PathChoice, RejectedMode, Stage,
};
pub use super::longrec::MAX_FULL_RATE_SAMPLES;
use super::longrec::{
    explore_resolution_hz, half_power_resolution_hz, input_band_top_hz, resolution_note,
    segment_for_resolution, segmented,
};
use super::mlfit::refine_estimates;
use super::pipeline::{
    estimate_on_frf, frf_band, frf_with_options, IdentOptions, IdentResult, Method,
};
use super::spectrum::{amplitude_spectrum, peaks};
use super::ModeEstimate;
use crate::recording::{check_time_unit, find_gaps, fmt_sig, split_at_gaps, Recording, F_MIN_HZ};
use anyhow::{bail, Result};
use std::borrow::Cow;

/// Reads the file at `path` ([`Recording::read_any_with`] with `opts.read`: CSV, `.npy`; or a LabVIEW `.lvm`
/// magnitude spectrum) and identifies it ([`identify`]; a spectrum by [`super::magspec`] in
/// `opts.decay`'s band, at most 6 peaks ≥ 10 dB prominent).
pub fn identify_file(
    path: &std::path::Path,
    opts: &IdentifyOptions,
    progress: &mut dyn FnMut(Stage),
) -> Result<Identification> {
    let is_lvm = path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("lvm"));
    if is_lvm {
        return identify_spectrum_file(path, opts);
    }
    if crate::recording::rawpsd::is_raw_file(path) {
        if let Some(id) = super::klipper_raw::identify_klipper_raw(path, opts)? {
            return Ok(id);
        }
    }
    let rec = Recording::read_any_with(path, &opts.read, &mut |n| progress(Stage::Reading(n)))?;
    let id = identify(&rec, opts, progress).map_err(|e| {
        // what reading noted (the columns read, a row-wise log, a staircase, …) follows the error
        let notes: String = rec.notes.iter().map(|n| format!("\n  note: {n}")).collect();
        anyhow::anyhow!("{}: {e:#}{notes}", path.display())
    });
    if let (Err(e), PathChoice::Auto) = (&id, opts.path) {
        // a Klipper raw file whose time-domain paths found nothing: its PSD's peaks
        if crate::recording::rawpsd::is_raw_file(path) {
            let why = format!("the time-domain paths found no mode ({e:#})");
            if let Ok(Some(s)) = super::klipper_raw::spectrum_path(path, opts, Some(&why)) {
                return Ok(s);
            }
        }
    }
    let mut id = id?;
    // what reading noted or mended (ignored columns, blank cells filled, …) heads the warnings
    id.warnings.splice(0..0, rec.notes.iter().cloned());
    Ok(id)
}

/// Identifies the modes of `rec` (any recording: uniform or not, with gaps) along the path
/// chosen by `opts.path`; `progress` is told each stage.
///
/// Errors: invalid recording (NaN, non-increasing time, a time base in ms), too short, no
/// physical mode found on the path taken (the message names the path and why).
pub fn identify(
    rec: &Recording,
    opts: &IdentifyOptions,
    progress: &mut dyn FnMut(Stage),
) -> Result<Identification> {
    if opts.path == PathChoice::Spectrum {
        bail!("the spectrum path (--path spectrum) reads Klipper's raw accelerometer file (header `#time,accel_x,accel_y,accel_z`); this recording is not one");
    }
    rec.validate_gapped()?;
    check_time_unit(rec)?;
    let mut warnings: Vec<String> = Vec::new();
    progress(Stage::Gaps);
    let mut seg = clean_segment(rec, &mut warnings);
    if seg.len() < 64 {
        bail!(
            "the longest clean stretch of the recording has {} samples; identification needs at least 64",
            seg.len()
        );
    }
    progress(Stage::Excitation);
    let mut base = base_channel(&seg).map(base_motion);
    if let Some(b) = base.as_mut() {
        quiet_base(&seg, b);
    }
    let (path, reason) = choose_path(&seg, base.as_ref(), opts);
    decimate_for_path(&mut seg, &mut base, path, opts, &mut warnings, progress);
    let rate = seg.sample_rate_hz();
    let span = (seg.time_s[0], seg.time_s[seg.len() - 1]);
    let mut out = Identification {
        modes: vec![],
        path,
        reason,
        rayleigh: None,
        rejected: vec![],
        warnings,
        span_s: span,
        sample_rate_hz: rate,
        base,
        frf_result: None,
        decay_result: None,
    };
    match path {
        IdentPath::Frf => frf_path(&seg, opts, &mut out, progress)?,
        IdentPath::FreeDecay
        | IdentPath::RingDown
        | IdentPath::Spectrum
        | IdentPath::KlipperPsd => decay_path(&seg, opts, &mut out, progress)?,
        IdentPath::OutputOnly => {
            super::identify_paths::output_only_path(&seg, opts, &mut out, progress)?
        }
        IdentPath::RingDowns => {
            super::identify_paths::ringdowns_path(&seg, opts, &mut out, progress)?
        }
    }
    if out.modes.is_empty() {
        bail!(
            "no physical mode found on the {} path ({}){}",
            out.path,
            out.reason,
            rejected_text(&out.rejected)
        );
    }
    out.rayleigh = rayleigh(&out.modes, &mut out.warnings);
    Ok(out)
}

/// `; rejected: f Hz (why); …`, or nothing.
fn rejected_text(rejected: &[RejectedMode]) -> String {
    if rejected.is_empty() {
        return String::new();
    }
    let list: Vec<String> = rejected
        .iter()
        .map(|r| format!("{} Hz ({})", fmt_sig(r.mode.freq_hz, 4), r.reason))
        .collect();
    format!("; rejected: {}", list.join("; "))
}

/// Anti-aliased decimation of `seg` by [`decimation_factor`] for `path` (with a warning),
/// keeping `base.still_from` at the same time.
fn decimate_for_path(
    seg: &mut Cow<'_, Recording>,
    base: &mut Option<BaseMotion>,
    path: IdentPath,
    opts: &IdentifyOptions,
    warnings: &mut Vec<String>,
    progress: &mut dyn FnMut(Stage),
) {
    let q = decimation_factor(seg, path, opts);
    if q > 1 {
        progress(Stage::Decimating(q));
    }
    if q <= 1 {
        return;
    }
    let from_s = base
        .as_ref()
        .map(|b| seg.time_s[b.still_from.min(seg.len() - 1)]);
    let d = seg.decimated(q);
    warnings.push(format!(
        "long recording ({} samples at {} Hz): decimated by {q} to {} Hz (anti-aliased, FIR) before the {path} path",
        seg.len(),
        fmt_sig(seg.sample_rate_hz(), 5),
        fmt_sig(d.sample_rate_hz(), 5)
    ));
    if let (Some(b), Some(t0)) = (base.as_mut(), from_s) {
        b.still_from = d.time_s.partition_point(|t| *t < t0);
    }
    *seg = Cow::Owned(d);
}

/// The FRF path, into `out`: Welch segments from resolution ([`frf_by_resolution`]), the
/// estimators without refinement, [`screen_modes`], then the maximum-likelihood refinement of
/// the kept modes (LSCF, LSCE primary).
fn frf_path(
    seg: &Recording,
    opts: &IdentifyOptions,
    out: &mut Identification,
    progress: &mut dyn FnMut(Stage),
) -> Result<()> {
    progress(Stage::Estimating(out.path, seg.len()));
    let mut fo = frf_options(seg, opts);
    // The ML refinement runs on the screened modes only (faster, and a spurious
    // estimate cannot pull a physical one).
    let ml = std::mem::replace(&mut fo.ml_refine, false);
    let FrfPass {
        r,
        frf,
        mut kept,
        rejected,
    } = frf_by_resolution(seg, &fo, opts.max_segment, out, progress)?;
    out.warnings.extend(r.warnings.iter().cloned());
    let primary = r.methods.first().map(|m| m.method);
    if ml && matches!(primary, Some(Method::Lscf | Method::Lsce)) {
        progress(Stage::Refining(kept.len()));
        refine_estimates(&frf, r.band_hz, &mut kept, "FRF", &mut out.warnings);
    }
    let mut rejected = rejected;
    // the refinement is held to the same damping rule as the screening (step 4)
    let (kept, implausible): (Vec<_>, Vec<_>) = kept
        .into_iter()
        .partition(|m| m.zeta >= 1e-4 && m.zeta < fo.zeta_max && m.zeta_std < m.zeta);
    rejected.extend(implausible.into_iter().map(|m| RejectedMode {
        reason: format!(
            "after the maximum-likelihood refinement the damping is not determined (ζ = {} ± {})",
            fmt_sig(m.zeta, 3),
            fmt_sig(m.zeta_std, 3)
        ),
        mode: m,
    }));
    out.modes = kept;
    out.rejected = rejected;
    out.reason = format!("{}; FRF {} -> {}", out.reason, r.input, r.output);
    out.frf_result = Some((r, frf));
    Ok(())
}

/// One FRF and its screened estimates.
struct FrfPass {
    r: IdentResult,
    frf: Frf,
    kept: Vec<ModeEstimate>,
    rejected: Vec<RejectedMode>,
}

/// Welch FRF of `seg` with `fo`, the estimators (no refinement) and [`screen_modes`].
fn frf_pass(
    seg: &Recording,
    fo: &IdentOptions,
    progress: &mut dyn FnMut(Stage),
) -> Result<FrfPass> {
    if seg.len() < 256 {
        bail!(
            "the recording has {} samples; identification needs at least 256",
            seg.len()
        );
    }
    progress(Stage::Welch(fo.welch.nperseg.unwrap_or(seg.len())));
    let (frf, warnings) = frf_with_options(seg, fo)?;
    let lines = frf_band(&frf, fo).map_or(0, |b| frf.band(b.0, b.1).len());
    progress(Stage::Estimators(lines));
    let r = estimate_on_frf(seg, &frf, warnings, fo, &mut crate::progress::Silent)?;
    progress(Stage::Screening);
    let (kept, rejected) = screen_modes(&r, &frf, fo);
    Ok(FrfPass {
        r,
        frf,
        kept,
        rejected,
    })
}

/// The FRF pass with Welch segments set by resolution ([`super::longrec`]), not by the
/// record's length: asked segments (`fo.welch.nperseg`) are used as they are (at most
/// `max_segment`). Otherwise, when the band's exploring resolution needs segments of at most
/// half the record, a first pass at that resolution finds the lowest physical mode, whose
/// half-power band then sets the final segment (no second pass when the first was fine
/// enough). A record shorter than twice its segment is one segment with `fo`'s window (at most
/// `max_segment` samples: longer ones are Hamming segments of that length, bounded memory).
fn frf_by_resolution(
    seg: &Recording,
    fo: &IdentOptions,
    max_segment: usize,
    out: &mut Identification,
    progress: &mut dyn FnMut(Stage),
) -> Result<FrfPass> {
    let (n, rate) = (seg.len(), seg.sample_rate_hz());
    if let Some(l) = fo.welch.nperseg {
        let mut o = fo.clone();
        if l > max_segment {
            o.welch.nperseg = Some(max_segment);
            o.welch.window = Window::Hamming;
            out.warnings.push(format!(
                "long recording ({n} samples): FRF averaged over Hamming-windowed segments of {max_segment} samples (50 % overlap)"
            ));
        }
        return frf_pass(seg, &o, progress);
    }
    let top = fo.band_hz.map(|b| b.1).or_else(|| input_band_top_hz(seg));
    let l1 = top.map(|t| segment_for_resolution(rate, explore_resolution_hz(t), max_segment));
    let Some(l1) = l1.filter(|l| 2 * l <= n) else {
        return frf_pass(
            seg,
            &segmented(fo, n, n, max_segment, &mut out.warnings),
            progress,
        );
    };
    let first = frf_pass(
        seg,
        &segmented(fo, l1, n, max_segment, &mut Vec::new()),
        progress,
    );
    let lowest = first.as_ref().ok().and_then(|p| p.kept.first().cloned());
    let l2 = lowest.as_ref().map_or(n, |m| {
        segment_for_resolution(rate, half_power_resolution_hz(m.freq_hz, m.zeta), n)
    });
    if let (Ok(p), true) = (&first, l2 <= l1) {
        out.warnings
            .push(resolution_note(lowest.as_ref(), p.frf.nperseg, rate));
        return first;
    }
    let p = frf_pass(
        seg,
        &segmented(fo, l2, n, max_segment, &mut out.warnings),
        progress,
    )?;
    out.warnings
        .push(resolution_note(lowest.as_ref(), p.frf.nperseg, rate));
    Ok(p)
}

/// The free-decay paths: [`identify_free_decay`] of the tip signal (from where the base is
/// still on the ring-down path), into `out`.
fn decay_path(
    seg: &Recording,
    opts: &IdentifyOptions,
    out: &mut Identification,
    progress: &mut dyn FnMut(Stage),
) -> Result<()> {
    let from = match (out.path, &out.base) {
        (IdentPath::RingDown, Some(b)) => b.still_from,
        _ => 0,
    };
    let (t, x) = tip_signal(seg, from);
    progress(Stage::Estimating(out.path, t.len()));
    let r = identify_free_decay(&t, &x, &opts.decay)?;
    out.modes = r.modes.clone();
    if let (IdentPath::RingDown, Some(q)) =
        (out.path, out.base.as_ref().and_then(|b| b.quiet.as_ref()))
    {
        super::quiet::widen_for_excitation(&mut out.modes, q);
    }
    out.warnings.extend(r.warnings.iter().cloned());
    out.span_s = (t[0], t[t.len() - 1]);
    out.decay_result = Some(r);
    Ok(())
}

/// The free-decay part of `rec` as (time s, signal, description): the longest clean segment
/// (split at gaps, jitter resampled), from where the base is still within its noise band
/// ([`base_motion`]) when it moves, tip − base (or the tip alone). For callers that run
/// their own free-decay analysis (the diagnosis).
///
/// Errors: invalid recording, no tip channel, fewer than 64 samples after the base is still.
pub fn free_decay_signal(rec: &Recording) -> Result<(Vec<f64>, Vec<f64>, String)> {
    rec.validate_gapped()?;
    check_time_unit(rec)?;
    if rec.tip_pos_m.is_none() {
        bail!("no tip_pos_m column to identify from");
    }
    let mut warnings = Vec::new();
    let seg = clean_segment(rec, &mut warnings);
    let mut base = base_channel(&seg).map(base_motion);
    if let Some(b) = base.as_mut() {
        quiet_base(&seg, b);
    }
    let from = base.as_ref().map_or(0, |b| b.still_from);
    let (t, x) = tip_signal(&seg, from);
    if t.len() < 64 {
        bail!(
            "only {} samples after the base is still (within ±{} µm of its final position); a free decay needs at least 64",
            t.len(),
            fmt_sig(base.map_or(0.0, |b| b.still_band_m) * 1e6, 3)
        );
    }
    let mut what = match &base {
        Some(b) => format!(
            "tip deflection from t = {} s (base still within ±{} µm)",
            fmt_sig(t[0], 4),
            fmt_sig(b.still_band_m * 1e6, 3)
        ),
        None => "the tip signal".to_string(),
    };
    for w in warnings {
        what += &format!("; {w}");
    }
    Ok((t, x, what))
}

/// The free-decay part of a recording file (CSV, `.npy`, [`Recording::read_any`]):
/// [`free_decay_signal`] (gaps split, base still within its noise band). Returns (time (s),
/// signal, description naming the file).
///
/// Errors: the file cannot be read, or those of [`free_decay_signal`] (prefixed by the path).
pub fn free_decay_of(path: &std::path::Path) -> Result<(Vec<f64>, Vec<f64>, String)> {
    let rec = Recording::read_any(path, &mut |_| {})?;
    let (t, x, what) =
        free_decay_signal(&rec).map_err(|e| anyhow::anyhow!("{}: {e:#}", path.display()))?;
    Ok((t, x, format!("{}: {what}", path.display())))
}

/// Decimation factor of `rec` before `path` ([`super::longrec::decimation_factor`]: the FRF
/// path keeps ≥ 4 × the top of `opts.frf.band_hz` or of the input's band; free-decay paths
/// decimate only above [`MAX_FULL_RATE_SAMPLES`] samples, to `opts.decay.f_max_hz`).
pub fn decimation_factor(rec: &Recording, path: IdentPath, opts: &IdentifyOptions) -> usize {
    super::longrec::decimation_factor(
        rec,
        path == IdentPath::Frf,
        opts.frf.band_hz,
        opts.decay.f_max_hz,
    )
}

/// Gap threshold (s): max(5 × the median step, a tenth of the period of the strongest
/// spectral peak of the tip signal), so that the jitter of a real logger (steps of up to 30 ×
/// the median, a small fraction of a period) is interpolated and a gap that loses phase is
/// not. `None` when no step exceeds 5 × the median (no spectrum is computed then).
pub fn gap_threshold_s(rec: &Recording) -> Option<f64> {
    let dt = rec.sample_interval_s();
    let longest = rec
        .time_s
        .windows(2)
        .map(|w| w[1] - w[0])
        .fold(0.0, f64::max);
    if longest <= 5.0 * dt {
        return None;
    }
    let (t, x) = tip_signal(rec, 0);
    let rate = 1.0 / dt;
    let (_, xu, _) = crate::recording::resample_uniform(&t, &x, rate);
    let (f, mag) = amplitude_spectrum(&xu, rate);
    let f_dom = peaks(&f, &mag, F_MIN_HZ, 0.45 * rate)
        .first()
        .map_or(F_MIN_HZ, |p| p.0);
    Some((5.0 * dt).max(0.1 / f_dom))
}

/// The longest clean (gap-free) segment of `rec`, resampled if its steps jitter; warns.
fn clean_segment<'a>(rec: &'a Recording, warnings: &mut Vec<String>) -> Cow<'a, Recording> {
    let gaps = gap_threshold_s(rec).map_or(vec![], |th| find_gaps(&rec.time_s, th));
    let seg = if gaps.is_empty() {
        Cow::Borrowed(rec)
    } else {
        let segs = split_at_gaps(rec, &gaps);
        let longest = segs
            .iter()
            .enumerate()
            .max_by_key(|(_, s)| s.len())
            .map(|(i, _)| i)
            .unwrap_or(0);
        let g = gaps
            .iter()
            .max_by(|a, b| a.length_s.total_cmp(&b.length_s))
            .expect("non-empty");
        let s = &segs[longest];
        warnings.push(format!(
            "{} logging gap(s) (longest {} s at t = {} s): split into {} clean segments; identified on the longest, {}..{} s ({} samples)",
            gaps.len(),
            fmt_sig(g.length_s, 3),
            fmt_sig(g.start_s, 4),
            segs.len(),
            fmt_sig(s.time_s[0], 4),
            fmt_sig(s.time_s[s.len() - 1], 4),
            s.len()
        ));
        Cow::Owned(segs[longest].clone())
    };
    if seg.len() >= 2 && !seg.is_uniform() {
        let dt = seg.sample_interval_s();
        let longest = seg
            .time_s
            .windows(2)
            .map(|w| w[1] - w[0])
            .fold(0.0, f64::max);
        warnings.push(format!(
            "non-uniform time base (median step {} s, longest {} ms): resampled to {} Hz by linear interpolation",
            fmt_sig(dt, 4),
            fmt_sig(longest * 1e3, 3),
            fmt_sig(1.0 / dt, 5)
        ));
        return Cow::Owned(seg.resampled_uniform());
    }
    seg
}

fn median(v: &mut [f64]) -> f64 {
    v.sort_by(|a, b| a.total_cmp(b));
    v[v.len() / 2]
}

/// The base's noise, stillness and reversals. The noise is measured on the last 10 % of the
/// recording (1.4826 × MAD about its median): a servo holding position dithers there by its
/// encoder quantisation and the beam's reaction.
pub fn base_motion(b: &[f64]) -> BaseMotion {
    let n = b.len();
    let tail_n = (n / 10).max(8).min(n);
    let mut tail: Vec<f64> = b[n - tail_n..].to_vec();
    let fin = median(&mut tail);
    let mut dev: Vec<f64> = b[n - tail_n..].iter().map(|v| (v - fin).abs()).collect();
    let noise = 1.4826 * median(&mut dev);
    let (lo, hi) = b
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), v| {
            (l.min(*v), h.max(*v))
        });
    let range = hi - lo;
    let band = (6.0 * noise).max(1e-7 * range).max(1e-12);
    let still_from = b
        .iter()
        .rposition(|v| (v - fin).abs() > band)
        .map_or(0, |k| k + 1);
    // Reversals of direction with hysteresis: the base must travel `hyst` back.
    let hyst = band.max(0.005 * range);
    let (mut reversals, mut dir, mut ext) = (0usize, 0i8, b[0]);
    for &v in &b[..still_from] {
        match dir {
            0 if (v - ext).abs() > hyst => {
                dir = if v > ext { 1 } else { -1 };
                ext = v;
            }
            0 => {}
            1 if v > ext => ext = v,
            -1 if v < ext => ext = v,
            d if (v - ext).abs() > hyst => {
                reversals += 1;
                dir = -d;
                ext = v;
            }
            _ => {}
        }
    }
    // Sample-to-sample noise: 1.4826 × MAD of the second differences / √6 (white noise).
    let noise_hf = if b.len() < 3 {
        0.0
    } else {
        crate::numeric::stats::second_difference_noise(b)
    };
    let moves = range > 20.0 * noise_hf && range > 0.0;
    BaseMotion {
        noise_m: noise,
        still_band_m: band,
        range_m: range,
        still_from: if moves { still_from } else { 0 },
        reversals,
        ends_still: !moves || noise < 0.05 * range,
        quiet: None,
    }
}

/// The shortest ring-down (s) the ring-down path takes.
const RING_DOWN_MIN_S: f64 = 3.0;

/// The first sample of `rec`'s ring-down when its base moves, stops and then no longer
/// excites the tip's dominant mode before it settles within its still band
/// ([`super::quiet::quiet_start`]); `None` otherwise (no base or tip position, a base that
/// never moves or oscillates, or no such start). For the model-free check of `tune`, which
/// applies the shaper to the free vibration from there.
pub fn quiet_ring_down_start(rec: &Recording) -> Option<usize> {
    let mut b = base_motion(base_channel(rec)?);
    quiet_base(rec, &mut b);
    b.quiet.map(|q| q.from)
}

/// Moves the ring-down's start of a moving base `b` (fewer than 6 reversals, ending still)
/// to where its motion stops exciting the tip's dominant mode ([`super::quiet::quiet_start`]),
/// when its still band leaves less than [`RING_DOWN_MIN_S`] of ring-down (a base that keeps
/// creeping after its move) and that start is earlier.
fn quiet_base(seg: &Recording, b: &mut BaseMotion) {
    if b.still_from == 0 || !b.ends_still || b.reversals >= 6 || seg.tip_pos_m.is_none() {
        return;
    }
    let Some(x) = base_channel(seg) else {
        return;
    };
    let n = x.len();
    let mut tail = x[n - (n / 10).max(8).min(n)..].to_vec();
    let fin = median(&mut tail);
    // the still band decides when it leaves a ring-down of RING_DOWN_MIN_S
    let rate = seg.sample_rate_hz();
    if (n - b.still_from) as f64 / rate >= RING_DOWN_MIN_S {
        return;
    }
    let (_, y) = tip_signal(seg, 0);
    let q = super::quiet::quiet_start(x, &y, rate, fin, b.range_m);
    if let Some(q) = q.filter(|q| q.from < b.still_from) {
        b.still_from = q.from;
        b.quiet = Some(q);
    }
}

/// The path the user asked for (`None` for `auto`), with its reason: a ring-down when the base
/// moved (`ring_s` of it), else a free decay.
fn asked_path(choice: PathChoice, moves: bool, ring_s: f64) -> Option<(IdentPath, String)> {
    match choice {
        PathChoice::Frf => Some((IdentPath::Frf, "FRF path asked for".into())),
        PathChoice::Decay if moves => Some((
            IdentPath::RingDown,
            format!("free decay asked for: tip deflection after the base's last move ({} s of ring-down)", fmt_sig(ring_s, 3)),
        )),
        PathChoice::Decay => Some((IdentPath::FreeDecay, "free decay asked for".into())),
        PathChoice::OutputOnly => Some((
            IdentPath::OutputOnly,
            "output-only asked for: SSI-cov of the tip response".into(),
        )),
        PathChoice::Auto | PathChoice::Spectrum => None,
    }
}

/// The path for `rec` and the reason: [`choose_path_io`], except that a base that steps
/// between levels ([`super::ringdowns::step_excited`]: a square-wave reference under
/// feedback, moves with rests) takes the pooled ring-downs instead of the FRF.
pub fn choose_path(
    rec: &Recording,
    base: Option<&BaseMotion>,
    opts: &IdentifyOptions,
) -> (IdentPath, String) {
    let (path, reason) = choose_path_io(rec, base, opts);
    if path == IdentPath::Frf && opts.path == PathChoice::Auto {
        if let (Some(b), Some(_)) = (base_channel(rec), rec.tip_pos_m.as_ref()) {
            if let Some(why) = super::ringdowns::step_excited(b) {
                return (
                    IdentPath::RingDowns,
                    format!("{why}: the tip rings after each step; pooled ring-downs with the measured base as input (the structure's mode, not the loop's poles)"),
                );
            }
        }
    }
    (path, reason)
}

/// The path for `rec` and the reason, among free decay, ring-down, output-only and FRF.
pub fn choose_path_io(
    rec: &Recording,
    base: Option<&BaseMotion>,
    opts: &IdentifyOptions,
) -> (IdentPath, String) {
    let rate = rec.sample_rate_hz();
    let force = rec.force_n.is_some();
    let moves = base.is_some_and(|b| b.still_from > 0);
    let ring_s = base.map_or(0.0, |b| (rec.len() - b.still_from) as f64 / rate);
    if let Some(asked) = asked_path(opts.path, moves, ring_s) {
        return asked;
    }
    let Some(b) = base else {
        return no_base_path(rec, opts, force);
    };
    let still = still_band_text(b);
    if !b.ends_still {
        return (
            IdentPath::Frf,
            format!(
                "the base moves until the end of the recording (noise of its last 10 % is {} % of its range): input/output FRF",
                fmt_sig(100.0 * b.noise_m / b.range_m, 2)
            ),
        );
    }
    if !moves {
        if let Ok(why) = super::identify_paths::output_only_reason(rec, opts) {
            return (
                IdentPath::OutputOnly,
                format!("the base never leaves {still} (range {} µm, within its noise: no usable input), and the tip deflection is {why}: output-only SSI-cov", fmt_sig(b.range_m * 1e6, 3)),
            );
        }
        return (
            IdentPath::FreeDecay,
            format!("the base never leaves {still} (range {} µm, within its noise): the tip deflection is a free decay", fmt_sig(b.range_m * 1e6, 3)),
        );
    }
    if b.reversals >= 6 {
        return (
            IdentPath::Frf,
            format!(
                "the base oscillates ({} reversals, a sweep or other broadband input): input/output FRF",
                b.reversals
            ),
        );
    }
    if ring_s >= RING_DOWN_MIN_S && rec.len() - b.still_from >= 64 {
        if let Some(q) = &b.quiet {
            return (
                IdentPath::RingDown,
                q.describe(rec.time_s[b.still_from] - rec.time_s[0]),
            );
        }
        return (
            IdentPath::RingDown,
            format!(
                "the base moves ({} reversals: moves, not a sweep), then stays within {still} for {} s from t = {} s: free decay of the tip deflection",
                b.reversals,
                fmt_sig(ring_s, 3),
                fmt_sig(rec.time_s[b.still_from], 4)
            ),
        );
    }
    (
        IdentPath::Frf,
        format!(
            "the base moves and is still for only {} s at the end (a ring-down needs 3 s): input/output FRF",
            fmt_sig(ring_s, 3)
        ),
    )
}

/// The path when there is no base channel: the FRF of a force input, output-only SSI-cov
/// of a stationary tip response, or the tip's free decay.
fn no_base_path(rec: &Recording, opts: &IdentifyOptions, force: bool) -> (IdentPath, String) {
    if force {
        (
            IdentPath::Frf,
            "force input, no base channel: FRF of force -> tip".into(),
        )
    } else {
        match super::identify_paths::output_only_reason(rec, opts) {
            Ok(why) => (
                IdentPath::OutputOnly,
                format!(
                    "no base or force channel, and the tip signal is {why}: output-only SSI-cov"
                ),
            ),
            Err(_) => (
                IdentPath::FreeDecay,
                "no base or force channel: the tip signal is a free decay".into(),
            ),
        }
    }
}

/// The still band of base motion `b` as the path's reason says it: 6 × its noise, or the
/// resolution floor (10⁻⁷ of its range) when its end does not move at all.
fn still_band_text(b: &BaseMotion) -> String {
    if b.still_band_m > 6.0 * b.noise_m {
        // the floor: a base that does not move at all at the recording's resolution
        format!(
            "±{} µm (10⁻⁷ of its range: its last 10 % does not move at the recording's resolution, noise {} µm)",
            fmt_sig(b.still_band_m * 1e6, 3),
            fmt_sig(b.noise_m * 1e6, 3)
        )
    } else {
        format!(
            "±{} µm (6 × its noise {} µm, 1.4826 × MAD of the last 10 %)",
            fmt_sig(b.still_band_m * 1e6, 3),
            fmt_sig(b.noise_m * 1e6, 3)
        )
    }
}

/// The FRF options for `rec`: force input when there is no base.
fn frf_options(rec: &Recording, opts: &IdentifyOptions) -> IdentOptions {
    let mut fo = opts.frf.clone();
    if base_channel(rec).is_none() && rec.force_n.is_some() {
        fo.input = InputChannel::Force;
    }
    fo
}

/// Splits the FRF path's modes into physical ones and rejected ones (module doc, step 4).
pub fn screen_modes(
    r: &IdentResult,
    frf: &Frf,
    fo: &IdentOptions,
) -> (Vec<ModeEstimate>, Vec<RejectedMode>) {
    let diagram = r.methods.first().and_then(|m| m.diagram.as_ref());
    let n_orders = diagram.map_or(0, |d| d.orders.len());
    let band = frf.band(r.band_hz.0, r.band_hz.1);
    let sxx_max = frf.sxx[band.clone()].iter().cloned().fold(0.0, f64::max);
    let mut kept = Vec::new();
    let mut rejected = Vec::new();
    for m in &r.modes {
        let count = diagram.and_then(|d| {
            d.modes
                .iter()
                .min_by(|a, b| {
                    (a.freq_hz - m.freq_hz)
                        .abs()
                        .total_cmp(&(b.freq_hz - m.freq_hz).abs())
                })
                .filter(|s| (s.freq_hz / m.freq_hz - 1.0).abs() < 0.02)
                .map(|s| s.count)
        });
        let reason = if let Some(c) = count.filter(|c| 4 * c < n_orders) {
            Some(format!("stable at only {c} of {n_orders} model orders"))
        } else if !(m.zeta >= 1e-4 && m.zeta < fo.zeta_max) {
            Some(format!(
                "implausible damping ratio {} (expected 1e-4..{})",
                fmt_sig(m.zeta, 3),
                fo.zeta_max
            ))
        } else if m.zeta_std >= m.zeta {
            Some(format!(
                "damping not determined (ζ = {} ± {})",
                fmt_sig(m.zeta, 3),
                fmt_sig(m.zeta_std, 3)
            ))
        } else {
            signal_reason(frf, m, sxx_max)
        };
        match reason {
            Some(reason) => rejected.push(RejectedMode {
                mode: m.clone(),
                reason,
            }),
            None => kept.push((m.clone(), count.unwrap_or(0))),
        }
    }
    // A planar beam's bending modes are far apart (ratio ≥ 2.8): of two kept modes within 5 %
    // the one with fewer stable poles is a split of the other's peak.
    let mut out: Vec<ModeEstimate> = Vec::new();
    for (i, (m, c)) in kept.iter().enumerate() {
        let better = kept.iter().enumerate().find(|(j, (o, oc))| {
            *j != i && (o.freq_hz / m.freq_hz - 1.0).abs() < 0.05 && (oc > c || (oc == c && *j < i))
        });
        match better {
            Some((_, (o, oc))) => rejected.push(RejectedMode {
                mode: m.clone(),
                reason: format!(
                    "within 5 % of the better-supported {} Hz mode ({oc} stable poles against {c}): a split peak",
                    fmt_sig(o.freq_hz, 5)
                ),
            }),
            None => out.push(m.clone()),
        }
    }
    (out, rejected)
}

/// `None` when the output auto-spectrum peaks at the mode ≥ 13 dB (×20) over its local floor
/// (median over 0.8–1.25 f outside the peak) and the input has energy there (≥ 10⁻⁴ of its
/// in-band maximum); else the reason.
fn signal_reason(frf: &Frf, m: &ModeEstimate, sxx_max: f64) -> Option<String> {
    let df = frf.df_hz();
    let idx = |f: f64| ((f / df).round().max(0.0) as usize).min(frf.freq_hz.len() - 1);
    let half = (3.0 * df).max(2.0 * m.zeta * m.freq_hz);
    let (a, b) = (idx(m.freq_hz - half), idx(m.freq_hz + half));
    let peak = frf.syy[a..=b].iter().cloned().fold(0.0, f64::max);
    let (la, lb) = (idx(0.8 * m.freq_hz), idx(1.25 * m.freq_hz));
    let excl = 2.0 * half;
    let mut floor: Vec<f64> = (la..=lb)
        .filter(|&k| (frf.freq_hz[k] - m.freq_hz).abs() > excl)
        .map(|k| frf.syy[k])
        .collect();
    if floor.len() >= 5 {
        let fl = median(&mut floor);
        if peak < 20.0 * fl {
            return Some(format!(
                "no resonance in the output spectrum ({} dB over its local floor; 13 dB needed)",
                fmt_sig(10.0 * (peak / fl).log10(), 2)
            ));
        }
    }
    let sxx = frf.sxx[a..=b].iter().sum::<f64>() / (b - a + 1) as f64;
    if sxx < 1e-4 * sxx_max {
        return Some(format!(
            "the input has no energy there ({} dB below its in-band maximum)",
            fmt_sig(-10.0 * (sxx / sxx_max).log10(), 2)
        ));
    }
    None
}
