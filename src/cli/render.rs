//! `termtrace render`: a headless render to PNG (and linear EXR), with a progress bar,
//! Ctrl-C that stops early and still saves, and atomic output files.

use super::args::{FrameArgs, GlobalArgs, ImageArgs};
use crate::common::FrameSettings;
use crate::output::{ImageFile, LinearImage, check_writable, write_exr, write_png};
use crate::render::RenderOptions;
use crate::render::stages;
use crate::render::team::Team;
use crate::render::{Backend, ErrorEstimate};
use crate::scene::load_scene;
use anyhow::Context;
use clap::Args;
use indicatif::{ProgressBar, ProgressStyle};
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

#[derive(Args, Debug)]
pub struct RenderArgs {
    /// Scene file, or the name of a built-in scene (weekend, cornell, …).
    pub scene: String,
    /// Output image: a PNG, or the linear radiance as OpenEXR when the name ends in `.exr`
    /// [default: SCENE.png in the current directory].
    #[arg(short, long, value_name = "FILE")]
    pub output: Option<PathBuf>,
    /// Samples per pixel [default: the scene's `spp`].
    #[arg(long, conflicts_with = "time", value_parser = clap::value_parser!(u32).range(1..))]
    pub spp: Option<u32>,
    /// Render for this many seconds instead of a fixed sample count.
    #[arg(long, value_name = "SECONDS", value_parser = positive_seconds)]
    pub time: Option<f64>,
    #[command(flatten)]
    pub frame: FrameArgs,
    #[command(flatten)]
    pub image: ImageArgs,
    /// Use the generic tracer instead of one specialized for the scene.
    #[arg(long)]
    pub generic: bool,
    /// No light sampling: the brute-force path tracer of the lecture (no next-event
    /// estimation, no multiple importance sampling, no Russian roulette).
    #[arg(long)]
    pub no_nee: bool,
    /// Render one shard of the samples, for `termtrace merge`: `I/K` traces shard I (from 0)
    /// of K, samples ⌊I·spp/K⌋ to ⌊(I+1)·spp/K⌋ of every pixel, and writes their exact sums
    /// to a `.tta` file [default: SCENE-part-I-of-K.tta]. `K` alone takes I from the
    /// scheduler: SLURM_ARRAY_TASK_ID (a Slurm job array, `--array=0-(K-1)`) or
    /// JOB_COMPLETION_INDEX (a Kubernetes Indexed Job).
    #[arg(long, value_name = "I/K", conflicts_with_all = ["time", "target_error"])]
    pub shard: Option<String>,
    /// Stop once the estimated relative RMSE (from the difference of two independent halves
    /// of the samples) falls below this, e.g. 0.01 for 1 %.
    #[arg(long, value_name = "E", value_parser = super::args::positive)]
    pub target_error: Option<f64>,
    /// Write the denoised image (guided by the albedo and normal of the first surfaces the
    /// camera sees; tile by tile the raw image wherever that is estimated better), and beside
    /// it the raw linear image and the guides as OpenEXR: NAME-raw.exr, NAME-albedo.exr,
    /// NAME-normal.exr.
    #[arg(long, conflicts_with = "shard")]
    pub denoise: bool,
    /// The global `-q` (set by `run`).
    #[arg(skip)]
    pub quiet: bool,
}

/// How often `render` reads the image back for its noise estimate: for the progress bar,
/// and (more often) to stop at a target error.
const ESTIMATE_EVERY: Duration = Duration::from_secs(2);
const TARGET_CHECK_EVERY: Duration = Duration::from_millis(500);

fn positive_seconds(s: &str) -> Result<f64, String> {
    match s.parse::<f64>() {
        Ok(x) if x.is_finite() && x > 0.0 => Ok(x),
        _ => Err(format!("`{s}` is not a positive number of seconds")),
    }
}

/// Set by the first Ctrl-C; a second one exits at once.
static INTERRUPTED: AtomicBool = AtomicBool::new(false);

fn install_ctrlc() {
    let _ = ctrlc::set_handler(|| {
        if INTERRUPTED.swap(true, Ordering::SeqCst) {
            eprintln!("\ninterrupted twice: exiting without saving");
            super::leave::exit(130);
        }
    });
}

pub fn run(mut a: RenderArgs, g: &GlobalArgs) -> anyhow::Result<ExitCode> {
    a.quiet |= g.quiet;
    let scene = load_scene(&a.scene, g.camera.as_deref(), g.sky.as_deref())?;
    let to_tta = a
        .output
        .as_deref()
        .is_some_and(crate::render::shard::is_part_file);
    if a.shard.is_some() || to_tta {
        return run_shard(&a, g, &scene);
    }
    let out = a
        .output
        .clone()
        .unwrap_or_else(|| PathBuf::from(format!("{}.png", scene.short_name())));
    let kind = ImageFile::of(&out)?;
    check_writable(&out)?;
    a.image.check(&out, kind)?;
    let settings = FrameSettings {
        nee: !a.no_nee,
        ..a.frame.settings(&scene)
    };
    let backends = Backend::open_all(g.adapter.as_deref())?;
    for b in &backends {
        b.check_fits(&scene)?;
    }
    let options = RenderOptions {
        generic: a.generic,
        ..Default::default()
    };
    let time_limit = a.time.map(Duration::from_secs_f64);
    // A target error alone renders until it is reached; with --spp or --time, whichever
    // comes first.
    let spp = match (time_limit, a.target_error, a.spp) {
        (Some(_), _, _) => u32::MAX,
        (None, Some(_), None) => u32::MAX,
        (None, _, s) => s.unwrap_or(scene.render.spp),
    };
    let team = Team::new(
        &backends,
        &scene,
        settings,
        options,
        0..stages::first_end(a.target_error, spp),
    );
    install_ctrlc();
    if !a.quiet {
        announce(&a, &scene, settings, spp, &team);
    }
    let start = Instant::now();
    let ended = accumulate(&a, &scene, settings, spp, &team, start);
    let elapsed = start.elapsed();
    let paths = team.paths();
    let snap = team.snapshot();
    let mut image = snap.image();
    let estimate = snap.error_estimate();
    let (mut extra, mut denoised_text) = (Vec::new(), String::new());
    if a.denoise {
        let rough = estimate.is_some_and(|e| e.doubt.is_some());
        (image, extra, denoised_text) = denoised(&out, &team, &snap, image, rough)?;
    }
    let written = match kind {
        ImageFile::Png => save(&out, &image, |p| {
            write_png(p, &image, a.image.transfer, a.image.png16)
        })?,
        ImageFile::Exr => save(&out, &image, |p| write_exr(p, &image))?,
    };
    let mut outputs = vec![written.display().to_string()];
    outputs.extend(extra);
    if let Some(exr) = &a.image.exr {
        outputs.push(
            save(exr, &image, |p| write_exr(p, &image))?
                .display()
                .to_string(),
        );
    }
    let rate = paths as f64 / elapsed.as_secs_f64().max(1e-9);
    eprintln!(
        "{}{} ({}x{}, {} spp, {:.1} s, {} on {}, estimated error {}{denoised_text}, {} invalid samples)",
        match ended {
            Ended::Interrupted => "interrupted; wrote ",
            Ended::Reached => "target error reached; wrote ",
            Ended::Done => "wrote ",
        },
        outputs.join(" and "),
        settings.width,
        settings.height,
        snap.min_samples(),
        elapsed.as_secs_f64(),
        rate_text(rate),
        team.describe(),
        estimate.map_or("–".into(), |e| e.text()),
        snap.invalid_samples(),
    );
    report_shares(&team);
    Ok(ExitCode::SUCCESS)
}

/// Why a render stopped.
enum Ended {
    /// Its samples or its time were done.
    Done,
    /// The estimated error reached the target.
    Reached,
    /// Ctrl-C.
    Interrupted,
}

/// The line that says what is rendered, how far and on what.
fn announce(
    a: &RenderArgs,
    scene: &crate::scene::Scene,
    settings: FrameSettings,
    spp: u32,
    team: &Team,
) {
    let until = a
        .target_error
        .map(|e| format!("until the estimated error is below {}%", e * 100.0));
    let what = match (a.time, spp, until) {
        (None, u32::MAX, Some(u)) => u,
        (Some(t), _, u) => format!(
            "for {t} s{}",
            u.map_or(String::new(), |u| format!(" or {u}"))
        ),
        (None, n, u) => format!(
            "to {n} spp{}",
            u.map_or(String::new(), |u| format!(" or {u}"))
        ),
    };
    eprintln!(
        "rendering {} at {}x{} {what} on {} (Ctrl-C stops and saves)",
        scene.origin,
        settings.width,
        settings.height,
        team.describe()
    );
}

/// Traces until the samples, the time or the target error are reached, or Ctrl-C, showing
/// progress and the estimated error.
fn accumulate(
    a: &RenderArgs,
    scene: &crate::scene::Scene,
    settings: FrameSettings,
    spp: u32,
    team: &Team,
    start: Instant,
) -> Ended {
    let time_limit = a.time.map(Duration::from_secs_f64);
    let pb = progress_bar(
        a.quiet,
        time_limit.or((spp == u32::MAX).then_some(Duration::ZERO)),
        spp,
    );
    pb.set_prefix(format!(
        "{} {}x{}",
        scene.short_name(),
        settings.width,
        settings.height
    ));
    let mut state = StageState {
        estimate: None,
        last_estimate: Instant::now(),
        reached: false,
        interrupted: false,
    };
    let every = if a.target_error.is_some() {
        TARGET_CHECK_EVERY
    } else {
        ESTIMATE_EVERY
    };
    let deadline = time_limit.map(|t| start + t);
    // With a target error, in stages (`render::stages`): each stage's samples are traced to
    // the end, the error is estimated, and the next stage aims at the target.
    let mut end = stages::first_end(a.target_error, spp);
    loop {
        run_stage(
            a,
            team,
            start,
            (time_limit, deadline, spp),
            &pb,
            every,
            &mut state,
        );
        let Some(target) = a.target_error else {
            break;
        };
        if state.reached || state.interrupted || deadline.is_some_and(|d| Instant::now() >= d) {
            break;
        }
        let traced = team.samples().min(u32::MAX as u64) as u32;
        if traced < end {
            break; // every device failed or stopped short
        }
        state.estimate = team.snapshot().error_estimate();
        state.last_estimate = Instant::now();
        match stages::next(end, state.estimate.map(|e| e.rel_rmse), target, spp) {
            stages::Next::Reached => {
                state.reached = true;
                break;
            }
            stages::Next::Exhausted => break,
            stages::Next::To(e) => end = e,
        }
        team.extend(end);
    }
    pb.finish_and_clear();
    if state.interrupted {
        Ended::Interrupted
    } else if state.reached {
        Ended::Reached
    } else {
        Ended::Done
    }
}

/// What `accumulate`'s stages share: the last estimate and when it was made, and how the
/// render ended.
struct StageState {
    /// The last estimate of the error (the progress line says whether it is rough).
    estimate: Option<ErrorEstimate>,
    last_estimate: Instant,
    reached: bool,
    interrupted: bool,
}

/// Traces until the team's claimed samples are traced, the deadline passes, the target error
/// is reached or Ctrl-C, showing progress.
fn run_stage(
    a: &RenderArgs,
    team: &Team,
    start: Instant,
    (time_limit, deadline, spp): (Option<Duration>, Option<Instant>, u32),
    pb: &indicatif::ProgressBar,
    every: Duration,
    state: &mut StageState,
) {
    let StageState {
        estimate,
        last_estimate,
        reached,
        interrupted,
    } = state;
    team.run(Duration::from_millis(250), deadline, |team| {
        let rate = team.paths() as f64 / start.elapsed().as_secs_f64().max(1e-9);
        if last_estimate.elapsed() >= every {
            *estimate = team.snapshot().error_estimate();
            *last_estimate = Instant::now();
            if let (Some(e), Some(target)) = (*estimate, a.target_error)
                && e.rel_rmse <= target
            {
                *reached = true;
            }
        }
        // A rough figure as the summary says it; a sure one with two decimals.
        let noise_text = match *estimate {
            Some(e) if e.doubt.is_some() => format!("  noise {}", e.text()),
            Some(e) => format!("  noise {:.2}%", e.rel_rmse * 100.0),
            None => String::new(),
        };
        let samples = team.samples();
        match time_limit {
            Some(t) => {
                pb.set_message(format!("{samples} spp  {}{noise_text}", rate_text(rate)));
                pb.set_position(start.elapsed().min(t).as_millis() as u64);
            }
            None if spp == u32::MAX => {
                pb.set_message(format!("{samples} spp  {}{noise_text}", rate_text(rate)));
            }
            None => {
                pb.set_message(format!("{}{noise_text}", rate_text(rate)));
                pb.set_position(samples);
            }
        }
        *interrupted = INTERRUPTED.load(Ordering::SeqCst);
        !*reached && !*interrupted
    });
}

/// The denoised image, the side images written beside `out` (raw, albedo, normal) and the
/// words that report the denoiser.
fn denoised(
    out: &std::path::Path,
    team: &Team,
    snap: &crate::render::Snapshot,
    image: LinearImage,
    rough: bool,
) -> anyhow::Result<(LinearImage, Vec<String>, String)> {
    let guides = team.first().guides().clone();
    let d = crate::denoise::denoise(&snap.data.even, &snap.data.odd, &guides);
    let side = |suffix: &str| {
        let stem = out.file_stem().unwrap_or_default().to_string_lossy();
        out.with_file_name(format!("{stem}-{suffix}.exr"))
    };
    let as_image = |pixels: Vec<[f32; 3]>| LinearImage {
        width: snap.width,
        height: snap.height,
        pixels,
    };
    let n = d.tiles.iter().filter(|&&t| t).count();
    let shown = d.shown_estimate();
    let denoised_text = format!(
        ", denoised {} in {n} of {} tiles",
        if rough {
            shown.rough_text()
        } else {
            shown.text()
        },
        d.tiles.len()
    );
    let mut extra = Vec::new();
    for (suffix, img) in [
        ("raw", image),
        ("albedo", as_image(guides.albedo.clone())),
        ("normal", as_image(guides.normal.clone())),
    ] {
        let path = side(suffix);
        extra.push(
            save(&path, &img, |p| write_exr(p, &img))?
                .display()
                .to_string(),
        );
    }
    Ok((as_image(d.shown()), extra, denoised_text))
}

/// With several devices, what each traced: its share of the samples and its rate.
pub(crate) fn report_shares(team: &Team) {
    if team.len() < 2 {
        return;
    }
    let total = team.paths().max(1) as f64;
    for s in team.shares() {
        if let Some(why) = &s.failed {
            eprintln!(
                "  failed: {} ({why}); what it had claimed was traced by the others",
                s.device
            );
            continue;
        }
        eprintln!(
            "  {:5.1}% of the samples ({} spp in {} claims, {}) on {}",
            100.0 * s.paths as f64 / total,
            s.samples,
            s.ranges.len(),
            rate_text(s.paths as f64 / s.seconds.max(1e-9)),
            s.device
        );
    }
}

/// Writes with `write`; if that fails, saves the image to the temporary directory instead so
/// that the render is not lost, and reports both.
fn save(
    path: &Path,
    image: &LinearImage,
    write: impl Fn(&Path) -> Result<(), crate::output::OutputError>,
) -> anyhow::Result<PathBuf> {
    match write(path) {
        Ok(()) => Ok(path.to_path_buf()),
        Err(e) => {
            let name = path
                .file_name()
                .map(|n| n.to_string_lossy().into_owned())
                .unwrap_or_else(|| "render.png".into());
            let rescue = std::env::temp_dir().join(format!("termtrace-rescued-{name}"));
            write(&rescue).with_context(|| {
                format!(
                    "{e}; saving the {}x{} image elsewhere failed too",
                    image.width, image.height
                )
            })?;
            eprintln!(
                "error: {e}; the image was saved to {} instead",
                rescue.display()
            );
            Ok(rescue)
        }
    }
}

fn progress_bar(quiet: bool, time: Option<Duration>, spp: u32) -> ProgressBar {
    if quiet {
        return ProgressBar::hidden();
    }
    let (len, template) = match time {
        // No bound known in advance: a spinner.
        Some(t) if t.is_zero() => (0, "{prefix} {spinner} {elapsed_precise} {msg}"),
        Some(t) => (
            t.as_millis() as u64,
            "{prefix} {elapsed_precise} [{wide_bar:.cyan/blue}] {msg}  ETA {eta}",
        ),
        None => (
            spp as u64,
            "{prefix} {elapsed_precise} [{wide_bar:.cyan/blue}] {pos}/{len} spp  {msg}  ETA {eta}",
        ),
    };
    let pb = ProgressBar::new(len);
    pb.set_style(
        ProgressStyle::with_template(template)
            .expect("valid progress template")
            .progress_chars("=> "),
    );
    pb.enable_steady_tick(Duration::from_millis(200));
    pb
}

/// `12.3 Msamples/s`.
pub(crate) fn rate_text(samples_per_second: f64) -> String {
    let (v, unit) = if samples_per_second >= 1e9 {
        (samples_per_second / 1e9, "G")
    } else if samples_per_second >= 1e6 {
        (samples_per_second / 1e6, "M")
    } else if samples_per_second >= 1e3 {
        (samples_per_second / 1e3, "k")
    } else {
        (samples_per_second, "")
    };
    format!("{v:.2} {unit}samples/s")
}

/// `--shard I/K` or `--shard K` (I from the scheduler's environment, `env`) as (I, K).
pub(crate) fn shard_spec(
    spec: &str,
    env: impl Fn(&str) -> Option<String>,
) -> anyhow::Result<(u32, u32)> {
    let number = |s: &str, what: &str| -> anyhow::Result<u32> {
        s.trim()
            .parse::<u32>()
            .map_err(|_| anyhow::anyhow!("--shard {spec}: {what} `{s}` is not a whole number"))
    };
    let (i, k) = match spec.split_once('/') {
        Some((i, k)) => (number(i, "the shard")?, number(k, "the count")?),
        None => {
            let k = number(spec, "the count")?;
            let (var, value) = ["SLURM_ARRAY_TASK_ID", "JOB_COMPLETION_INDEX"]
                .iter()
                .find_map(|v| env(v).map(|x| (*v, x)))
                .ok_or_else(|| {
                    anyhow::anyhow!(
                        "--shard {spec} takes the shard from SLURM_ARRAY_TASK_ID or \
                         JOB_COMPLETION_INDEX, and neither is set; give it as --shard I/{spec}"
                    )
                })?;
            let i = value.trim().parse::<u32>().map_err(|_| {
                anyhow::anyhow!("--shard {spec}: {var} is `{value}`, not a whole number")
            })?;
            if i >= k {
                anyhow::bail!(
                    "--shard {spec}: {var} is {i}, and the shards are 0 to {} (a Slurm array \
                     --array=0-{})",
                    k.saturating_sub(1),
                    k.saturating_sub(1)
                );
            }
            (i, k)
        }
    };
    anyhow::ensure!(k >= 1, "--shard {spec}: the count must be at least 1");
    anyhow::ensure!(i < k, "--shard {spec}: shards are numbered 0 to {}", k - 1);
    Ok((i, k))
}

/// `render --shard I/K` (or `-o part.tta`): traces the shard's samples and writes their exact
/// sums (`render::shard`). An interrupted shard writes nothing: a part without all its
/// samples could not be merged.
fn run_shard(
    a: &RenderArgs,
    g: &GlobalArgs,
    scene: &crate::scene::Scene,
) -> anyhow::Result<ExitCode> {
    use crate::render::shard::{Header, Part, write};
    let (i, k) = match &a.shard {
        Some(spec) => shard_spec(spec, |v| std::env::var(v).ok())?,
        None => (0, 1),
    };
    let spp = a.spp.unwrap_or(scene.render.spp);
    anyhow::ensure!(
        k <= spp,
        "--shard {i}/{k}: {k} shards of {spp} samples per pixel leave some empty; use at most {spp}"
    );
    let out = a
        .output
        .clone()
        .unwrap_or_else(|| PathBuf::from(format!("{}-part-{i}-of-{k}.tta", scene.short_name())));
    anyhow::ensure!(
        crate::render::shard::is_part_file(&out),
        "{}: a shard is written as exact sums to a .tta file (`termtrace merge` makes the image)",
        out.display()
    );
    anyhow::ensure!(
        a.image.exr.is_none() && !a.image.png16,
        "--exr and --png16 are options of the image; `termtrace merge` writes it from the shards"
    );
    check_writable(&out)?;
    let settings = FrameSettings {
        nee: !a.no_nee,
        ..a.frame.settings(scene)
    };
    let (first, end) = Header::range(i, k, spp);
    let backends = Backend::open_all(g.adapter.as_deref())?;
    for b in &backends {
        b.check_fits(scene)?;
    }
    let options = RenderOptions {
        generic: a.generic,
        ..Default::default()
    };
    let team = Team::new(&backends, scene, settings, options, first..end);
    install_ctrlc();
    if !a.quiet {
        eprintln!(
            "rendering shard {i} of {k} of {} at {}x{}: samples {first}..{end} of {spp} on {}",
            scene.origin,
            settings.width,
            settings.height,
            team.describe()
        );
    }
    let n = end - first;
    let pb = progress_bar(a.quiet, None, n);
    let start = Instant::now();
    team.run(Duration::from_millis(250), None, |team| {
        pb.set_position(team.samples());
        !INTERRUPTED.load(Ordering::SeqCst)
    });
    pb.finish_and_clear();
    if team.samples() < n as u64 {
        eprintln!(
            "interrupted: shard {i} of {k} has {} of its {n} samples; nothing written \
             (render it again)",
            team.samples()
        );
        return Ok(ExitCode::from(130));
    }
    let crate::common::accum::Sums { even, odd, invalid } = team.exact_sums();
    let part = Part {
        header: Header::new(scene, &settings, spp, (i, k), invalid),
        even,
        odd,
    };
    write(&out, &part)?;
    eprintln!(
        "wrote {} (shard {i} of {k}: samples {first}..{end}, {:.1} s, {} bytes)",
        out.display(),
        start.elapsed().as_secs_f64(),
        std::fs::metadata(&out).map(|m| m.len()).unwrap_or(0)
    );
    report_shares(&team);
    Ok(ExitCode::SUCCESS)
}
