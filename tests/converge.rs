//! Error against run time: the error metrics against analytic values, the bias check, and
//! the files `converge` writes (the live noise estimate against the true error on every
//! shipped scene is tests/estimate.rs). The estimators are tested on images of the native CPU
//! tracer (the fastest backend here).

mod common;
use common::*;
use termtrace::converge::metrics;
use termtrace::output::LinearImage;
use termtrace::render::{Backend, RenderOptions, Renderer};

/// The Lambertian plane under a gradient sky (see tests/statistical.rs): every pixel's mean
/// is ρ·(B + (T - B)·5/6) and its per-sample standard deviation ρ·0.5·|T - B|·√(1/18).
const PLANE: &str = "[camera]\nlook_from = [0, 1, 0]\nlook_at = [0, 0, -0.5]\nvfov = 40\n\
    [sky]\nbottom = [0.1, 0.2, 0.0]\ntop = [0.9, 0.5, 1.0]\n\
    [[quad]]\nq = [-1000, 0, 1000]\nu = [2000, 0, 0]\nv = [0, 0, -2000]\ncolor = [0.5, 0.5, 0.5]\n";
const B: [f64; 3] = [0.1, 0.2, 0.0];
const T: [f64; 3] = [0.9, 0.5, 1.0];

#[test]
fn stratified_samples_beat_sigma_over_root_n_without_bias() {
    // A sky-lit diffuse plane: every pixel's exact value is known, and a pixel's samples
    // differ only by their first bounce's direction (one 2D draw). With independent samples
    // the RMSE at N spp would be σ/√N; the scrambled Sobol points must do better at every N
    // and fall faster than N^-3/4 from 4 to 256 spp (Owen, "Scrambled net variance for
    // integrals of smooth functions", Ann. Stat. 1997: O(N^-3/2) for smooth integrands),
    // while the mean error over the 4096 pixels, independently scrambled, stays within 4
    // standard errors of zero (no bias).
    let (w, h) = (64, 64);
    let exact = LinearImage {
        width: w,
        height: h,
        pixels: vec![
            std::array::from_fn(|c| (0.5 * (B[c] + (T[c] - B[c]) * 5.0 / 6.0)) as f32);
            (w * h) as usize
        ],
    };
    let sigma2: f64 = (0..3)
        .map(|c| (0.25 * (T[c] - B[c])).powi(2) / 18.0)
        .sum::<f64>()
        / 3.0;
    let mut r = Renderer::new(
        Backend::Cpu,
        &scene(PLANE),
        settings(w, h, 4),
        RenderOptions::default(),
    );
    let mut rmse = Vec::new();
    for n in [4u32, 16, 64, 256] {
        r.render_spp(n);
        let image = r.snapshot().image();
        let e = metrics::errors(&image, &exact);
        let independent = (sigma2 / n as f64).sqrt();
        let mean_error = image
            .pixels
            .iter()
            .zip(&exact.pixels)
            .map(|(v, x)| (0..3).map(|c| (v[c] - x[c]) as f64).sum::<f64>() / 3.0)
            .sum::<f64>()
            / (w * h) as f64;
        eprintln!(
            "{n} spp: RMSE {:.5e}, σ/√N {independent:.5e}, mean error {mean_error:.3e}",
            e.rmse
        );
        assert!(
            e.rmse < 0.75 * independent,
            "{n} spp: {} vs {independent}",
            e.rmse
        );
        let standard_error = e.rmse / ((w * h) as f64).sqrt();
        assert!(
            mean_error.abs() < 4.0 * standard_error,
            "{n} spp: mean error {mean_error} ({standard_error} standard error)"
        );
        rmse.push(e.rmse);
    }
    let slope = (rmse[3] / rmse[0]).ln() / 64f64.ln();
    eprintln!("slope {slope:.3}");
    assert!(slope < -0.75, "RMSE falls as N^{slope}");
}

#[test]
fn the_bias_check_finds_a_biased_image_and_passes_an_unbiased_one() {
    let s = scene(PLANE);
    let fs = settings(64, 64, 4);
    let reference = cpu_snapshot(&s, FrameSettingsWith::seed(fs, 77), 256);
    let fair = cpu_snapshot(&s, fs, 64);
    let r = metrics::bias_check(&fair, &reference, false, 16, 0.01);
    assert_eq!(r.tiles, 16);
    assert!(
        r.significant.is_empty(),
        "an unbiased image failed: {:?}",
        r.significant
    );
    // The same plane 3 % darker: a renderer that converges to the wrong answer.
    let biased_scene =
        scene(&PLANE.replace("color = [0.5, 0.5, 0.5]", "color = [0.485, 0.485, 0.485]"));
    let biased = cpu_snapshot(&biased_scene, fs, 64);
    let r = metrics::bias_check(&biased, &reference, false, 16, 0.01);
    assert!(
        r.significant.len() >= 12,
        "only {} of 16 tiles caught a 3 % bias",
        r.significant.len()
    );
}

/// Settings with another seed.
struct FrameSettingsWith;
impl FrameSettingsWith {
    fn seed(
        mut s: termtrace::common::FrameSettings,
        seed: u32,
    ) -> termtrace::common::FrameSettings {
        s.seed = seed;
        s
    }
}

fn termtrace() -> std::process::Command {
    std::process::Command::new(env!("CARGO_BIN_EXE_termtrace"))
}

#[test]
fn converge_writes_a_wellformed_csv_a_plot_and_the_images() {
    let dir = tempfile::tempdir().unwrap();
    let out = termtrace()
        .args([
            "converge",
            "basic",
            "--time",
            "1",
            "--reference-spp",
            "64",
            "--width",
            "32",
            "--height",
            "18",
            "--no-cache",
            "-q",
            "--runs",
            "2",
            "--bias-check",
            "--out",
        ])
        .arg(dir.path())
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{err}");
    let csv = std::fs::read_to_string(dir.path().join("convergence.csv")).unwrap();
    let mut lines = csv.lines();
    assert_eq!(lines.next(), Some(termtrace::converge::CSV_HEADER));
    let mut last_seconds = [0.0f64; 2];
    let mut rows = 0;
    for line in lines {
        let f: Vec<&str> = line.split(',').collect();
        assert_eq!(f.len(), 10, "{line}");
        assert_eq!(f[0], "\"default\"");
        let run: usize = f[1].parse().unwrap();
        let seconds: f64 = f[2].parse().unwrap();
        assert!(
            seconds > last_seconds[run],
            "checkpoints must follow each other in time: {line}"
        );
        last_seconds[run] = seconds;
        let spp: u64 = f[3].parse().unwrap();
        assert!(spp >= 1, "a checkpoint before any sample landed: {line}");
        let first: f64 = f[9].parse().unwrap();
        assert!(first > 0.0 && first <= seconds, "{line}");
        for v in &f[4..8] {
            let x: f64 = v.parse().unwrap();
            assert!(x.is_finite() && x >= 0.0, "{line}");
        }
        rows += 1;
    }
    assert!(rows >= 10, "only {rows} checkpoints");
    let plot = image::open(dir.path().join("convergence.png")).unwrap();
    assert_eq!((plot.width(), plot.height()), (900, 600));
    for f in ["final.png", "reference.exr"] {
        assert!(dir.path().join(f).exists(), "{f} missing");
    }
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        stdout.contains("slope") && stdout.contains("bias check default: no tile"),
        "{stdout}"
    );
}

#[test]
fn a_reference_of_the_wrong_size_is_a_clear_error() {
    let dir = tempfile::tempdir().unwrap();
    let exr = dir.path().join("ref.exr");
    termtrace::output::write_exr(&exr, &LinearImage::new(32, 18)).unwrap();
    let out = termtrace()
        .args([
            "converge",
            "basic",
            "--time",
            "1",
            "--width",
            "40",
            "--height",
            "18",
            "--reference",
        ])
        .arg(&exr)
        .arg("--out")
        .arg(dir.path())
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert!(err.contains("is 32x18, but the runs render 40x18"), "{err}");
}
