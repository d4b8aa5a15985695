//! Error against run time: renders from zero and measures, at log-spaced checkpoints, the
//! error of the image against a reference; summarises runs into curves with a fitted slope
//! and the time to reach an error; writes the CSV and the plot.

pub mod metrics;
pub mod plot;
pub mod reference;

use crate::common::FrameSettings;
use crate::render::Backend;
use crate::render::team::Team;
use crate::render::{RenderOptions, Snapshot};
use crate::scene::Scene;
use metrics::{Errors, errors_against_noisy, log_log_fit, time_to};
use std::io::Write;
use std::path::Path;
use std::time::{Duration, Instant};

/// Why a convergence measurement cannot go on: its reference or its plot.
#[derive(Debug, thiserror::Error)]
pub enum ConvergeError {
    #[error("{} is not a cached termtrace reference of {width}x{height}", path.display())]
    NotCached {
        path: std::path::PathBuf,
        width: u32,
        height: u32,
    },
    #[error("cannot read the reference {}: {source}", path.display())]
    Read {
        path: std::path::PathBuf,
        #[source]
        source: image::ImageError,
    },
    #[error(
        "the reference {} is {}x{}, but the runs render {}x{}: render the reference at the \
         same size, or the runs at {}x{}",
        path.display(), reference.0, reference.1, runs.0, runs.1, reference.0, reference.1
    )]
    Size {
        path: std::path::PathBuf,
        reference: (u32, u32),
        runs: (u32, u32),
    },
    #[error("no checkpoints to plot")]
    NoCheckpoints,
    #[error("cannot draw the plot: {0}")]
    Draw(String),
    #[error(transparent)]
    Output(#[from] crate::output::write::OutputError),
}

/// The first checkpoint, in seconds of rendering.
pub const FIRST_CHECKPOINT: f64 = 0.05;
/// Checkpoints are this factor apart: two per doubling of time.
pub const CHECKPOINT_FACTOR: f64 = std::f64::consts::SQRT_2;
/// Checkpoints with fewer samples per pixel are left out of the slope fit (the first
/// samples' error is dominated by a few pixels)…
pub const FIT_MIN_SPP: u64 = 16;
/// … and so are those before this fraction of the run (there a submission's fixed cost
/// weighs on the time axis, which would steepen the slope).
pub const FIT_MIN_FRACTION: f64 = 0.01;

/// One way of rendering to compare (`--compare '--no-nee'`).
#[derive(Clone, Debug)]
pub struct Variant {
    pub label: String,
    pub options: RenderOptions,
    pub max_bounces: Option<u32>,
    /// Next-event estimation.
    pub nee: bool,
}

impl Default for Variant {
    fn default() -> Self {
        Variant {
            label: "default".into(),
            options: RenderOptions::default(),
            max_bounces: None,
            nee: true,
        }
    }
}

/// The error at one checkpoint of one run.
#[derive(Clone, Debug)]
pub struct Checkpoint {
    pub label: String,
    pub run: u32,
    /// Seconds of rendering (readbacks for measuring are not counted).
    pub seconds: f64,
    /// Fewest samples any pixel has.
    pub spp: u64,
    pub errors: Errors,
    /// The estimate from the image's two halves, without the reference.
    pub estimated_rel_rmse: Option<f64>,
    /// Seconds until the run's first sample per pixel had landed (pipeline build, upload):
    /// the same for every checkpoint of a run. No checkpoint comes before it.
    pub first_sample: f64,
}

pub struct Run {
    pub checkpoints: Vec<Checkpoint>,
    /// With `Setup::denoise`: the denoised image at every checkpoint with a sample in each
    /// half, as checkpoints of the variant `LABEL denoised` whose seconds include the
    /// denoiser's time and the guides' (`denoise_seconds` of each).
    pub denoised: Vec<(Checkpoint, f64)>,
    pub last: Snapshot,
}

/// What every run of a measurement shares.
pub struct Setup<'a> {
    /// The devices that share each run (`render::team`).
    pub backends: &'a [Backend],
    pub scene: &'a Scene,
    pub settings: FrameSettings,
    pub reference: &'a crate::output::LinearImage,
    /// The reference's own per-pixel variance, when it is a rendered one: taken out of the
    /// measured errors ([`metrics::errors_against_noisy`]).
    pub reference_variance: Option<&'a [[f32; 3]]>,
    /// Also measure the denoised image (`denoise`) at every checkpoint.
    pub denoise: bool,
}

/// Renders `variant` from zero for `time` seconds of rendering and measures it against the
/// reference at every checkpoint; `progress(seconds, spp)` after every step.
pub fn run_once(
    setup: &Setup<'_>,
    variant: &Variant,
    run: u32,
    time: Duration,
    mut progress: impl FnMut(f64, u32),
) -> Run {
    let s = FrameSettings {
        max_bounces: variant.max_bounces.unwrap_or(setup.settings.max_bounces),
        seed: setup.settings.seed.wrapping_add(run),
        nee: variant.nee,
        ..setup.settings
    };
    // The samples are claimed up to the next checkpoint's count, so that a checkpoint at
    // 1, 2, 4, … spp holds just that many; time checkpoints stop the devices at a deadline.
    // The time axis is the devices' tracing: the checkpoints' own work (reading back,
    // measuring, denoising) is left out.
    let team = Team::new(setup.backends, setup.scene, s, variant.options, 0..1);
    let total = time.as_secs_f64();
    let mut next = FIRST_CHECKPOINT.min(total);
    // Checkpoints also come at 1, 2, 4, … samples per pixel, whichever is due first: on a
    // fast GPU the first time checkpoint would already hold hundreds of samples, leaving the
    // early curve (and the time to 5 %) unmeasured.
    let mut next_spp = 1u32;
    let mut seconds = 0.0;
    let mut first_sample = None;
    let mut checkpoints = Vec::new();
    let mut denoised = Vec::new();
    // Time the denoiser has taken so far in this run (the guides' included): the denoised
    // curve's time axis is the tracer's plus this.
    let mut denoise_total = 0.0;
    loop {
        let left = (next - seconds).max(0.0);
        let start = Instant::now();
        team.run(
            Duration::from_millis(250),
            Some(start + Duration::from_secs_f64(left)),
            |_| true,
        );
        seconds += start.elapsed().as_secs_f64();
        let samples = team.samples().min(u32::MAX as u64) as u32;
        progress(seconds, samples);
        if samples == 0 && seconds < total {
            // The image before any sample is no measurement of the tracer's error.
            continue;
        }
        let first = *first_sample.get_or_insert(seconds);
        if seconds + 1e-9 < next && samples < next_spp {
            continue;
        }
        let snap = team.snapshot();
        if snap.min_samples() > 0 {
            checkpoints.push(Checkpoint {
                label: variant.label.clone(),
                run,
                seconds,
                spp: snap.min_samples(),
                errors: errors_against_noisy(
                    &snap.image(),
                    setup.reference,
                    setup.reference_variance,
                ),
                estimated_rel_rmse: snap.noise_estimate(),
                first_sample: first,
            });
        }
        if setup.denoise && snap.min_samples() >= 2 {
            let start = std::time::Instant::now();
            let d = crate::denoise::denoise(&snap.data.even, &snap.data.odd, team.first().guides());
            let shown = crate::output::LinearImage {
                width: s.width,
                height: s.height,
                pixels: d.shown(),
            };
            let took = start.elapsed().as_secs_f64();
            denoise_total += took;
            denoised.push((
                Checkpoint {
                    label: format!("{} denoised", variant.label),
                    run,
                    seconds: seconds + denoise_total,
                    spp: snap.min_samples(),
                    errors: errors_against_noisy(&shown, setup.reference, setup.reference_variance),
                    estimated_rel_rmse: Some(d.rel_rmse(d.shown_sums())),
                    first_sample: first,
                },
                took,
            ));
        }
        if seconds >= total {
            return Run {
                checkpoints,
                denoised,
                last: snap,
            };
        }
        while next <= seconds {
            next *= CHECKPOINT_FACTOR;
        }
        next = next.min(total);
        while next_spp <= samples {
            next_spp = next_spp.saturating_mul(2);
        }
        team.extend(next_spp);
    }
}

/// A variant's runs, summarised.
pub struct Summary {
    pub label: String,
    /// Per checkpoint index: (mean seconds, √(mean relMSE), lowest and highest relative RMSE
    /// of the runs, fewest spp).
    pub points: Vec<(f64, f64, f64, f64, u64)>,
    pub slope: Option<f64>,
    /// Seconds to reach 5 % and 1 % relative RMSE, and whether each was extrapolated.
    pub to_5: Option<(f64, bool)>,
    pub to_1: Option<(f64, bool)>,
}

pub fn summarize(label: &str, runs: &[Run]) -> Summary {
    let n = runs.iter().map(|r| r.checkpoints.len()).min().unwrap_or(0);
    let points: Vec<_> = (0..n)
        .map(|k| {
            let cs: Vec<&Checkpoint> = runs.iter().map(|r| &r.checkpoints[k]).collect();
            let m = cs.len() as f64;
            let secs = cs.iter().map(|c| c.seconds).sum::<f64>() / m;
            let rel = (cs.iter().map(|c| c.errors.relmse).sum::<f64>() / m).sqrt();
            let lo = cs
                .iter()
                .map(|c| c.errors.rel_rmse())
                .fold(f64::MAX, f64::min);
            let hi = cs.iter().map(|c| c.errors.rel_rmse()).fold(0.0, f64::max);
            let spp = cs.iter().map(|c| c.spp).min().unwrap_or(0);
            (secs, rel, lo, hi, spp)
        })
        .collect();
    let curve: Vec<(f64, f64)> = points.iter().map(|p| (p.0, p.1)).collect();
    let end = points.last().map_or(0.0, |p| p.0);
    let fit: Vec<(f64, f64)> = points
        .iter()
        .filter(|p| p.4 >= FIT_MIN_SPP && p.0 >= FIT_MIN_FRACTION * end)
        .map(|p| (p.0, p.1))
        .collect();
    Summary {
        label: label.to_string(),
        slope: log_log_fit(&fit).map(|f| f.0),
        to_5: time_to(&curve, 0.05),
        to_1: time_to(&curve, 0.01),
        points,
    }
}

/// The CSV header, one row per checkpoint of every run.
pub const CSV_HEADER: &str =
    "variant,run,seconds,spp,rmse,relmse,rel_rmse,mae,estimated_rel_rmse,first_sample_seconds";

pub fn write_csv(path: &Path, rows: &[&Checkpoint]) -> std::io::Result<()> {
    let mut s = String::from(CSV_HEADER);
    s.push('\n');
    for c in rows {
        s.push_str(&format!(
            "\"{}\",{},{:.6},{},{:.6e},{:.6e},{:.6e},{:.6e},{},{:.6}\n",
            c.label.replace('"', "\"\""),
            c.run,
            c.seconds,
            c.spp,
            c.errors.rmse,
            c.errors.relmse,
            c.errors.rel_rmse(),
            c.errors.mae,
            c.estimated_rel_rmse
                .map_or(String::new(), |e| format!("{e:.6e}")),
            c.first_sample
        ));
    }
    let mut f = std::fs::File::create(path)?;
    f.write_all(s.as_bytes())
}

/// `12.3 s`, or `~12.3 s (extrapolated)`.
pub fn fmt_time_to(t: Option<(f64, bool)>) -> String {
    match t {
        None => "–".into(),
        Some((s, false)) => format!("{s:.3} s"),
        Some((s, true)) => format!("~{s:.3} s (extrapolated)"),
    }
}
