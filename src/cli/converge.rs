//! `termtrace converge`: how fast the noise falls, measured against a reference, for one or
//! several ways of rendering the same scene.

use super::args::GlobalArgs;
use crate::converge::{self, Variant, metrics, plot, reference};
use crate::output::{Transfer, write_exr, write_png};
use crate::render::Backend;
use crate::render::RenderOptions;
use crate::scene::load_scene;
use anyhow::Context;
use clap::{Args, Parser};
use indicatif::{ProgressBar, ProgressStyle};
use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Duration;

#[derive(Args, Debug)]
pub struct ConvergeArgs {
    /// Scene file or built-in scene name.
    pub scene: String,
    /// Seconds of rendering per run.
    #[arg(long, default_value_t = 10.0, value_parser = super::args::positive)]
    pub time: f64,
    /// Directory for convergence.csv, convergence.png, final.png and reference.exr.
    #[arg(long, value_name = "DIR")]
    pub out: PathBuf,
    /// Measure against this linear EXR, or a cached rendered reference (`reference-….bin`,
    /// which keeps its own noise for the bias check), of the same size as the runs.
    #[arg(long, value_name = "FILE", conflicts_with = "reference_spp")]
    pub reference: Option<PathBuf>,
    /// Render the reference with this many samples per pixel (cached for later runs).
    #[arg(long, value_name = "N", default_value_t = 4096)]
    pub reference_spp: u32,
    /// Where rendered references are cached [default: ~/.cache/termtrace].
    #[arg(long, value_name = "DIR")]
    pub cache_dir: Option<PathBuf>,
    /// Do not read or write the reference cache.
    #[arg(long)]
    pub no_cache: bool,
    /// Render the reference without light sampling (brute force), to check that light
    /// sampling converges to the same image (with --bias-check).
    #[arg(long)]
    pub reference_no_nee: bool,
    /// Independent runs per variant (different seeds): the mean curve and its spread.
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u32).range(1..))]
    pub runs: u32,
    /// A variant to compare, as a quoted set of options; repeat for each variant, e.g.
    /// --compare '' --compare '--no-nee' (options: --generic, --no-bvh, --no-nee,
    /// --max-bounces N; '' is the default).
    #[arg(long, value_name = "'OPTIONS'", allow_hyphen_values = true, action = clap::ArgAction::Append)]
    pub compare: Vec<String>,
    /// Test every variant's final image against the reference, tile by tile (Welch t-test).
    #[arg(long)]
    pub bias_check: bool,
    /// Significance of the bias check, before the Bonferroni correction over tiles.
    #[arg(long, default_value_t = 0.01)]
    pub alpha: f64,
    /// Tile size of the bias check, in pixels.
    #[arg(long, default_value_t = 16, value_parser = clap::value_parser!(u32).range(1..))]
    pub tile: u32,
    #[command(flatten)]
    pub frame: super::args::FrameArgs,
    /// Also denoise the image at every checkpoint (`denoise`): a second curve per variant,
    /// `LABEL denoised`, its time including the denoiser's, and its estimated error beside the
    /// true one.
    #[arg(long)]
    pub denoise: bool,
    /// The global `-q` (set by `run`).
    #[arg(skip)]
    pub quiet: bool,
}

/// The options a `--compare` variant may set.
#[derive(Parser, Debug)]
#[command(no_binary_name = true, name = "--compare variant")]
struct VariantArgs {
    #[arg(long)]
    generic: bool,
    #[arg(long)]
    no_bvh: bool,
    #[arg(long)]
    no_nee: bool,
    #[arg(long)]
    max_bounces: Option<u32>,
}

fn variant(spec: &str) -> anyhow::Result<Variant> {
    let words = shlex::split(spec).with_context(|| format!("cannot split `{spec}` into words"))?;
    let a = VariantArgs::try_parse_from(&words)
        .map_err(|e| anyhow::anyhow!("in --compare '{spec}': {e}"))?;
    Ok(Variant {
        label: if spec.trim().is_empty() {
            "default".into()
        } else {
            spec.trim().to_string()
        },
        options: RenderOptions {
            generic: a.generic,
            no_bvh: a.no_bvh,
            ..Default::default()
        },
        max_bounces: a.max_bounces,
        nee: !a.no_nee,
    })
}

fn bar(quiet: bool, len: u64, template: &str) -> ProgressBar {
    if quiet {
        return ProgressBar::hidden();
    }
    let pb = ProgressBar::new(len);
    pb.set_style(
        ProgressStyle::with_template(template)
            .expect("valid template")
            .progress_chars("=> "),
    );
    pb
}

pub fn run(mut a: ConvergeArgs, g: &GlobalArgs) -> anyhow::Result<ExitCode> {
    a.quiet |= g.quiet;
    let scene = load_scene(&a.scene, g.camera.as_deref(), g.sky.as_deref())?;
    let settings = a.frame.settings(&scene);
    let variants = if a.compare.is_empty() {
        vec![Variant::default()]
    } else {
        a.compare
            .iter()
            .map(|s| variant(s))
            .collect::<anyhow::Result<_>>()?
    };
    std::fs::create_dir_all(&a.out)
        .with_context(|| format!("cannot create the output directory {}", a.out.display()))?;
    crate::output::check_writable(&a.out.join("convergence.csv"))?;
    let backends = Backend::open_all(g.adapter.as_deref())?;
    for b in &backends {
        b.check_fits(&scene)?;
    }
    let devices: Vec<String> = backends.iter().map(Backend::describe).collect();
    eprintln!(
        "converge: {} at {}x{} on {}",
        scene.origin,
        settings.width,
        settings.height,
        devices.join(" + ")
    );
    let reference = obtain_reference(&a, &backends, &scene, settings)?;
    let reference_variance = reference
        .snapshot
        .as_ref()
        .map(converge::metrics::mean_variance);
    let setup = converge::Setup {
        reference_variance: reference_variance.as_deref(),
        backends: &backends,
        scene: &scene,
        settings,
        reference: &reference.image,
        denoise: a.denoise,
    };
    let (all, summaries, finals) = run_variants(&a, &setup, &variants);
    let rows: Vec<&converge::Checkpoint> =
        all.iter().flatten().flat_map(|r| &r.checkpoints).collect();
    print_results(&all, &rows, &summaries);
    write_outputs(&a, &scene, settings, &rows, &summaries, &finals)?;
    let biased = a.bias_check && bias_check(&a, &variants, &finals, &reference);
    Ok(if biased {
        ExitCode::FAILURE
    } else {
        ExitCode::SUCCESS
    })
}

/// The reference the runs are measured against: the file given, else rendered (or taken
/// from the cache) and written beside the results.
fn obtain_reference(
    a: &ConvergeArgs,
    backends: &[Backend],
    scene: &crate::scene::Scene,
    settings: crate::common::FrameSettings,
) -> anyhow::Result<reference::Reference> {
    let reference = match &a.reference {
        Some(p) => reference::from_file(p, settings.width, settings.height)?,
        None => {
            let cache = if a.no_cache {
                None
            } else {
                Some(
                    a.cache_dir
                        .clone()
                        .unwrap_or_else(reference::default_cache_dir),
                )
            };
            let pb = bar(
                a.quiet,
                a.reference_spp as u64,
                "reference {elapsed_precise} [{wide_bar}] {pos}/{len} spp  ETA {eta}",
            );
            let ref_settings = crate::common::FrameSettings {
                nee: !a.reference_no_nee,
                ..settings
            };
            let r = reference::rendered(
                backends,
                scene,
                ref_settings,
                a.reference_spp,
                cache.as_deref(),
                |done, _| pb.set_position(done as u64),
            );
            pb.finish_and_clear();
            write_exr(&a.out.join("reference.exr"), &r.image)?;
            r
        }
    };
    eprintln!(
        "reference: {}{}",
        reference.source,
        reference.noise().map_or(String::new(), |n| format!(
            "; its own relative RMSE ≈ {:.3}%, taken out of the errors below (MAE excepted)",
            n * 100.0
        ))
    );

    Ok(reference)
}

/// Every variant's runs (and, with the denoiser, their denoised images as a variant of
/// their own), each variant's summary, and the last snapshot of each variant's first run.
fn run_variants(
    a: &ConvergeArgs,
    setup: &converge::Setup<'_>,
    variants: &[Variant],
) -> (
    Vec<Vec<converge::Run>>,
    Vec<converge::Summary>,
    Vec<crate::render::Snapshot>,
) {
    let time = Duration::from_secs_f64(a.time);
    let mut all = Vec::new();
    let mut summaries = Vec::new();
    let mut finals = Vec::new();
    for v in variants {
        let mut runs = Vec::new();
        for run in 0..a.runs {
            let pb = bar(
                a.quiet,
                (a.time * 1000.0) as u64,
                &format!(
                    "{} run {}/{} {{elapsed_precise}} [{{wide_bar}}] {{msg}}",
                    v.label,
                    run + 1,
                    a.runs
                ),
            );
            let r = converge::run_once(setup, v, run, time, |secs, spp| {
                pb.set_position((secs * 1000.0) as u64);
                pb.set_message(format!("{spp} spp"));
            });
            pb.finish_and_clear();
            runs.push(r);
        }
        summaries.push(converge::summarize(&v.label, &runs));
        finals.push(runs[0].last.clone());
        if a.denoise {
            // The denoised images as a variant of their own.
            let denoised: Vec<converge::Run> = runs
                .iter()
                .map(|r| converge::Run {
                    checkpoints: r.denoised.iter().map(|d| d.0.clone()).collect(),
                    denoised: Vec::new(),
                    last: r.last.clone(),
                })
                .collect();
            for r in &runs {
                if let Some(worst) = r.denoised.iter().map(|d| d.1).reduce(f64::max) {
                    let n = r.denoised.len() as f64;
                    let mean = r.denoised.iter().map(|d| d.1).sum::<f64>() / n;
                    println!(
                        "{} run {}: the denoiser took {:.2} ms a frame on average, {:.2} ms at most (guides included in the first)",
                        v.label,
                        r.checkpoints.first().map_or(0, |c| c.run),
                        mean * 1e3,
                        worst * 1e3
                    );
                }
            }
            summaries.push(converge::summarize(
                &format!("{} denoised", v.label),
                &denoised,
            ));
            all.push(runs);
            all.push(denoised);
        } else {
            all.push(runs);
        }
    }

    (all, summaries, finals)
}

/// The time to each variant's first sample, the table of checkpoints and each variant's
/// slope and times to 5% and 1%.
fn print_results(
    all: &[Vec<converge::Run>],
    rows: &[&converge::Checkpoint],
    summaries: &[converge::Summary],
) {
    // The time to a first sample (pipeline build, upload) once, not as error rows.
    for runs in all {
        if let Some(c) = runs.iter().find_map(|r| r.checkpoints.first()) {
            let firsts: Vec<String> = runs
                .iter()
                .filter_map(|r| r.checkpoints.first())
                .map(|c| format!("{:.3} s", c.first_sample))
                .collect();
            println!(
                "{}: first sample per pixel after {} (pipeline build and upload; checkpoints start there)",
                c.label,
                firsts.join(", ")
            );
        }
    }
    // Table.
    // The estimate beside the true relative RMSE, and their ratio: how far the status line's
    // figure (or, for a denoised variant, the shown image's) is from the truth in this run.
    println!(
        "{:<16} {:>4} {:>9} {:>7} {:>11} {:>11} {:>9} {:>11} {:>9} {:>8}",
        "variant",
        "run",
        "seconds",
        "spp",
        "RMSE",
        "relMSE",
        "rel RMSE",
        "MAE",
        "estimate",
        "est÷true"
    );
    for c in rows {
        let true_rel = c.errors.rel_rmse();
        println!(
            "{:<16} {:>4} {:>9.3} {:>7} {:>11.4e} {:>11.4e} {:>8.3}% {:>11.4e} {:>8} {:>8}",
            c.label,
            c.run,
            c.seconds,
            c.spp,
            c.errors.rmse,
            c.errors.relmse,
            c.errors.rel_rmse() * 100.0,
            c.errors.mae,
            c.estimated_rel_rmse
                .map_or("–".into(), |e| format!("{:.3}%", e * 100.0)),
            c.estimated_rel_rmse
                .filter(|_| true_rel > 0.0)
                .map_or("–".into(), |e| format!("{:.2}", e / true_rel))
        );
    }
    println!();
    for s in summaries {
        println!(
            "{}: slope {} (log-log fit of relative RMSE against time, spp ≥ {}, from {}% of the run); 5% in {}, 1% in {}",
            s.label,
            s.slope.map_or("–".into(), |x| format!("{x:.3}")),
            converge::FIT_MIN_SPP,
            converge::FIT_MIN_FRACTION * 100.0,
            converge::fmt_time_to(s.to_5),
            converge::fmt_time_to(s.to_1)
        );
    }
}

/// The CSV, the plot and the final image.
fn write_outputs(
    a: &ConvergeArgs,
    scene: &crate::scene::Scene,
    settings: crate::common::FrameSettings,
    rows: &[&converge::Checkpoint],
    summaries: &[converge::Summary],
    finals: &[crate::render::Snapshot],
) -> anyhow::Result<()> {
    converge::write_csv(&a.out.join("convergence.csv"), rows)
        .with_context(|| format!("cannot write {}", a.out.join("convergence.csv").display()))?;
    let curves: Vec<plot::Curve> = summaries
        .iter()
        .map(|s| plot::Curve {
            label: s.label.clone(),
            points: s.points.iter().map(|p| (p.0, p.1, p.2, p.3)).collect(),
            slope: s.slope,
        })
        .collect();
    plot::plot(
        &a.out.join("convergence.png"),
        &format!(
            "{} at {}x{}: relative RMSE against time",
            scene.short_name(),
            settings.width,
            settings.height
        ),
        &curves,
    )?;
    write_png(
        &a.out.join("final.png"),
        &finals[0].image(),
        Transfer::Srgb,
        false,
    )?;
    eprintln!(
        "wrote {}/convergence.csv, convergence.png, final.png{}",
        a.out.display(),
        if a.reference.is_none() {
            ", reference.exr"
        } else {
            ""
        }
    );

    Ok(())
}

/// Compares each variant's last image with the reference tile by tile; whether any tile
/// differs significantly.
fn bias_check(
    a: &ConvergeArgs,
    variants: &[Variant],
    finals: &[crate::render::Snapshot],
    reference: &reference::Reference,
) -> bool {
    let mut biased = false;
    let exact = reference.snapshot.is_none();
    let ref_snap = match &reference.snapshot {
        Some(s) => s.clone(),
        None => pseudo_snapshot(&reference.image),
    };
    for (v, last) in variants.iter().zip(finals) {
        let r = metrics::bias_check(last, &ref_snap, exact, a.tile, a.alpha);
        if r.significant.is_empty() {
            println!(
                "bias check {}: no tile of {} differs from the reference (alpha {} over {} tiles; smallest p {:.2e})",
                v.label, r.tiles, r.alpha, r.tiles, r.min_p
            );
        } else {
            biased = true;
            println!(
                "bias check {}: {} of {} tiles differ significantly from the reference (p < {:.1e}):",
                v.label,
                r.significant.len(),
                r.tiles,
                r.alpha / r.tiles as f64
            );
            for t in r.significant.iter().take(20) {
                println!(
                    "  tile ({}, {}) at pixels ({}, {}): mean {:.5} vs reference {:.5}, t = {:.1}, p = {:.1e}",
                    t.x,
                    t.y,
                    t.x * a.tile,
                    t.y * a.tile,
                    t.mean,
                    t.reference,
                    t.t,
                    t.p
                );
            }
        }
    }
    biased
}

/// A snapshot holding an exact image (a reference read from a file), for the bias check:
/// both halves equal the image, with one sample each.
fn pseudo_snapshot(img: &crate::output::LinearImage) -> crate::render::Snapshot {
    let px: Vec<[f32; 4]> = img.pixels.iter().map(|p| [p[0], p[1], p[2], 1.0]).collect();
    crate::render::Snapshot {
        width: img.width,
        height: img.height,
        samples: 2,
        data: crate::common::AccumData::from_halves(px.clone(), px),
    }
}
