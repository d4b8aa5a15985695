//! Statistical tests: the image mean must lie within a stated number of standard errors of
//! an analytic value. Pixels are independently scrambled, and a pixel's N samples are
//! stratified (scrambled Sobol points: src/cpu/rng.rs), whose mean varies no more than that of
//! N independent samples, so the image mean over P pixels has a standard error of at most
//! σ / √(P·N) for a per-sample standard deviation σ; where the test measures the spread of
//! the pixel means, it uses that spread / √P.

mod common;
use common::*;

/// Allowed deviation, in standard errors: two-sided p ≈ 6e-5 per check.
const Z: f64 = 4.0;

fn channel_mean(img: &termtrace::output::LinearImage, c: usize) -> f64 {
    img.pixels.iter().map(|p| p[c] as f64).sum::<f64>() / img.pixels.len() as f64
}

/// Sample variance of the pixel means of channel `c`.
fn pixel_variance(img: &termtrace::output::LinearImage, c: usize) -> f64 {
    let m = channel_mean(img, c);
    img.pixels
        .iter()
        .map(|p| (p[c] as f64 - m).powi(2))
        .sum::<f64>()
        / (img.pixels.len() - 1) as f64
}

#[test]
fn lambertian_plane_under_a_gradient_sky() {
    // A cosine-distributed bounce (normalize(n + unit vector)) off a plane with normal +y sees
    // t = 0.5 (1 + cos θ) with E[cos θ] = 2/3 and Var[cos θ] = 1/2 - 4/9 = 1/18, so a pixel of
    // albedo ρ has mean ρ·(B + (T - B)·5/6) and standard deviation ρ·0.5·|T - B|·√(1/18).
    let (b, t) = ([0.1, 0.2, 0.0], [0.9, 0.5, 1.0]);
    let toml = "[camera]\nlook_from = [0, 1, 0]\nlook_at = [0, 0, -0.5]\nvfov = 40\n\
                [sky]\nbottom = [0.1, 0.2, 0.0]\ntop = [0.9, 0.5, 1.0]\n\
                [[quad]]\nq = [-1000, 0, 1000]\nu = [2000, 0, 0]\nv = [0, 0, -2000]\ncolor = [0.5, 0.5, 0.5]\n";
    let (w, h, spp) = (64u32, 64u32, 64u32);
    let img = render(toml, w, h, spp, 4);
    for c in 0..3 {
        let expected = 0.5 * (b[c] + (t[c] - b[c]) * 5.0 / 6.0);
        let sigma = 0.5 * 0.5 * (t[c] - b[c]) * (1.0f64 / 18.0).sqrt();
        let mean = channel_mean(&img, c);
        // The pixel means' spread: below σ²/N, as the samples are stratified (0.03 σ²/N here;
        // independent samples would give 1 ± 0.1 with χ² of 4095 dof at > 6σ).
        let var = pixel_variance(&img, c);
        let ratio = var / (sigma * sigma / spp as f64);
        assert!(ratio < 0.25, "channel {c}: pixel variance ratio {ratio}");
        let se = (var / (w * h) as f64).sqrt();
        eprintln!(
            "channel {c}: mean {mean:.6}, expected {expected:.6}, {:.2} SE, variance ratio {ratio:.3}",
            (mean - expected) / se
        );
        assert!(
            (mean - expected).abs() <= Z * se,
            "channel {c}: {mean} vs {expected} ± {se}"
        );
    }
}

/// Schlick reflectance of MODEL.md.
fn schlick(cos: f64, ratio: f64) -> f64 {
    let r0 = ((1.0 - ratio) / (1.0 + ratio)).powi(2);
    r0 + (1.0 - r0) * (1.0 - cos).powi(5)
}

fn schlick_at(theta_deg: f64) {
    // A near-orthographic camera looks at a glass quad (normal +y, ior 1.5) at θ from its
    // normal, under the sky t = 0.5 (dir.y + 1) (bottom black, top white). A reflected ray has
    // dir.y = cos θ, a refracted one dir.y = -cos θt (Snell), each then seen against the sky,
    // so the mean is R·a + (1 - R)·b with Bernoulli variance R(1 - R)(a - b)².
    let th = theta_deg.to_radians();
    let look_from = [0.0, 1000.0 * th.cos(), 1000.0 * th.sin()];
    let toml = format!(
        "[camera]\nlook_from = [{}, {}, {}]\nlook_at = [0, 0, 0]\nvfov = 0.02\n\
         [sky]\nbottom = [0, 0, 0]\ntop = [1, 1, 1]\n\
         [[quad]]\nq = [-10, 0, -10]\nu = [0, 0, 20]\nv = [20, 0, 0]\nsmoothness = -1\nior = 1.5\n",
        look_from[0], look_from[1], look_from[2]
    );
    let (w, h, spp) = (64u32, 64u32, 64u32);
    let img = render(&toml, w, h, spp, 1);
    let r = schlick(th.cos(), 1.0 / 1.5);
    let cos_t = (1.0 - (th.sin() / 1.5).powi(2)).sqrt();
    let (a, b) = (0.5 * (1.0 + th.cos()), 0.5 * (1.0 - cos_t));
    let expected = r * a + (1.0 - r) * b;
    let se = (r * (1.0 - r)).sqrt() * (a - b) / ((w * h * spp) as f64).sqrt();
    let mean = channel_mean(&img, 0);
    let measured_r = (mean - b) / (a - b);
    eprintln!(
        "Schlick at {theta_deg}°: R = {measured_r:.5} measured, {r:.5} expected ({:.2} SE)",
        (mean - expected) / se
    );
    assert!(
        (mean - expected).abs() <= Z * se,
        "{mean} vs {expected} ± {se}"
    );
}

#[test]
fn schlick_reflectance_of_a_glass_plane_at_60_degrees() {
    schlick_at(60.0);
}

#[test]
fn schlick_reflectance_of_a_glass_plane_at_80_degrees() {
    schlick_at(80.0);
}

/// E[f(normalize(r + a·u))] and E[f²] for u uniform on the unit sphere, by the midpoint rule
/// on (z, φ) (z uniform in [-1, 1] makes the measure uniform), n × 2n cells.
fn sphere_expectation(r: [f64; 3], a: f64, f: impl Fn([f64; 3]) -> f64, n: usize) -> (f64, f64) {
    let (mut s1, mut s2) = (0.0, 0.0);
    for i in 0..n {
        let z = -1.0 + (i as f64 + 0.5) * 2.0 / n as f64;
        let rho = (1.0 - z * z).sqrt();
        for j in 0..2 * n {
            let phi = (j as f64 + 0.5) * std::f64::consts::PI / n as f64;
            let u = [rho * phi.cos(), rho * phi.sin(), z];
            let v = [r[0] + a * u[0], r[1] + a * u[1], r[2] + a * u[2]];
            let l = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
            let x = f([v[0] / l, v[1] / l, v[2] / l]);
            s1 += x;
            s2 += x * x;
        }
    }
    let cells = (2 * n * n) as f64;
    (s1 / cells, s2 / cells)
}

#[test]
fn mean_of_fuzzed_mirror_directions() {
    // A white mirror plane with absorption (fuzz) 0.5, seen at 70° from its normal: the
    // reflected direction r is pushed by 0.5 × a uniform unit vector and renormalized; a
    // direction below the plane is absorbed (0). Under the sky t = 0.5 (dir.y + 1) the pixel
    // mean is E[t · 1{dir.y > 0}], integrated on the host.
    let th: f64 = 70f64.to_radians();
    let toml = format!(
        "[camera]\nlook_from = [0, {}, {}]\nlook_at = [0, 0, 0]\nvfov = 0.02\n\
         [sky]\nbottom = [0, 0, 0]\ntop = [1, 1, 1]\n\
         [[quad]]\nq = [-10, 0, -10]\nu = [0, 0, 20]\nv = [20, 0, 0]\ncolor = [1, 1, 1]\nsmoothness = 1\nabsorption = 0.5\n",
        1000.0 * th.cos(),
        1000.0 * th.sin()
    );
    let r = [0.0, th.cos(), -th.sin()];
    let f = |d: [f64; 3]| if d[1] > 0.0 { 0.5 * (1.0 + d[1]) } else { 0.0 };
    let (m1, m2) = sphere_expectation(r, 0.5, f, 1500);
    let sigma = (m2 - m1 * m1).sqrt();
    let (w, h, spp) = (64u32, 64u32, 64u32);
    let img = render(&toml, w, h, spp, 1);
    let mean = channel_mean(&img, 0);
    let se = sigma / ((w * h * spp) as f64).sqrt();
    eprintln!(
        "fuzz: mean {mean:.6}, expected {m1:.6} ({:.2} SE)",
        (mean - m1) / se
    );
    assert!((mean - m1).abs() <= Z * se, "{mean} vs {m1} ± {se}");
}

/// Second moment Σ I·r² / Σ I of an image about its intensity centroid (pixel centres).
fn second_moment(img: &termtrace::output::LinearImage) -> f64 {
    let (mut s, mut sx, mut sy) = (0.0, 0.0, 0.0);
    for y in 0..img.height {
        for x in 0..img.width {
            let i = img.get(x, y)[0] as f64;
            s += i;
            sx += i * (x as f64 + 0.5);
            sy += i * (y as f64 + 0.5);
        }
    }
    let (cx, cy) = (sx / s, sy / s);
    let mut m = 0.0;
    for y in 0..img.height {
        for x in 0..img.width {
            let i = img.get(x, y)[0] as f64;
            m += i * ((x as f64 + 0.5 - cx).powi(2) + (y as f64 + 0.5 - cy).powi(2));
        }
    }
    m / s
}

/// Second moment of a uniform square of side `side` px centred on a pixel corner at the
/// image centre, binned into pixels as the tracer's pixel filter bins it (exact coverage).
fn binned_square_moment(side: f64, w: u32) -> f64 {
    let c = w as f64 / 2.0;
    let overlap =
        |x: u32| ((x as f64 + 1.0).min(c + side / 2.0) - (x as f64).max(c - side / 2.0)).max(0.0);
    let (mut s, mut m) = (0.0, 0.0);
    for y in 0..w {
        for x in 0..w {
            let i = overlap(x) * overlap(y);
            s += i;
            m += i * ((x as f64 + 0.5 - c).powi(2) + (y as f64 + 0.5 - c).powi(2));
        }
    }
    m / s
}

#[test]
fn thin_lens_blur_width() {
    // A small square emitter facing the camera at distance d, the lens focused at f. For a
    // plane at one depth the thin lens convolves the sharp image with a uniform disk of radius
    // R = (aperture/2)·|1 - f/d| on the focus plane, and second moments add under
    // convolution: moment(blurred) - moment(in focus) = R²/2. In focus, the image is the
    // square binned into pixels, whose moment is computed exactly on the host.
    // Tolerances: 3 % blurred (the spread over seeds is 0.6 %), 0.1 px² in focus.
    let (size, d, f, aperture, vfov) = (0.1f64, 4.0f64, 2.0f64, 0.4f64, 20.0f64);
    let (w, spp) = (128u32, 256u32);
    let px_per_unit = w as f64 / (2.0 * f * (vfov.to_radians() / 2.0).tan());
    let r = aperture / 2.0 * (1.0 - f / d).abs() * px_per_unit;
    let scene_at = |focus: f64| {
        format!(
            "[camera]\nlook_from = [0, 0, 0]\nlook_at = [0, 0, -1]\nvfov = {vfov}\naperture = {aperture}\nfocus_distance = {focus}\n\
             [sky]\nuniform = [0, 0, 0]\n\
             [[quad]]\nq = [{q}, {q}, -{d}]\nu = [{size}, 0, 0]\nv = [0, {size}, 0]\ncolor = [1, 1, 1]\nlight = 1\n",
            q = -size / 2.0
        )
    };
    let sharp = second_moment(&render(&scene_at(d), w, w, 64, 1));
    // The square's image is size·f/d wide in pixels of the plane focused at f (the same in
    // pixels whatever the focus distance: the viewport scales with it).
    let side = size * f / d * px_per_unit;
    let sharp_expected = binned_square_moment(side, w);
    eprintln!("in focus: second moment {sharp:.3} px², expected {sharp_expected:.3}");
    assert!(
        (sharp - sharp_expected).abs() < 0.1,
        "{sharp} vs {sharp_expected}"
    );
    let blurred = second_moment(&render(&scene_at(f), w, w, spp, 1));
    let added = blurred - sharp_expected;
    eprintln!(
        "thin lens: blur adds {added:.2} px², expected R²/2 = {:.2} (R = {r:.2} px)",
        r * r / 2.0
    );
    assert!(
        (added / (r * r / 2.0) - 1.0).abs() < 0.03,
        "{added} vs {}",
        r * r / 2.0
    );
}
