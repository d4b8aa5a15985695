//! Environment maps (issue 29, first part): the loader's checks, and the importance-sampling
//! distribution both tracers will share, tested as Mitsuba tests its samplers: a chi-square
//! test of sampled directions against the distribution's own integral over each texel, and
//! the density a sample reports against the density of its direction.

use glam::Vec3;
use statrs::distribution::{ChiSquared, ContinuousCDF};
use termtrace::common::envmap::{Distribution, coordinates, direction, luminance};
use termtrace::scene::envmap::EnvMap;

/// A small map with a bright "sun" texel, a black row and smooth variation elsewhere.
fn test_map() -> (u32, u32, Vec<[f32; 3]>) {
    let (w, h) = (16u32, 8u32);
    let mut t = Vec::new();
    for y in 0..h {
        for x in 0..w {
            let v = if y == 5 {
                0.0
            } else {
                0.2 + 0.1 * ((x * 7 + y * 3) % 5) as f32
            };
            t.push([v, v * 0.5, v * 2.0]);
        }
    }
    t[(2 * w + 11) as usize] = [200.0, 180.0, 150.0];
    (w, h, t)
}

/// A deterministic low-discrepancy-free stream of uniform numbers (SplitMix64).
struct Stream(u64);
impl Stream {
    fn next(&mut self) -> f32 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^= z >> 31;
        (z >> 40) as f32 / (1u64 << 24) as f32
    }
}

#[test]
fn sampled_directions_follow_the_map_by_a_chi_square_test() {
    // 400 000 samples binned by the texel their direction falls in (found again from the
    // direction, so that the mapping is tested too), against the expected count: N × the
    // texel's weight (luminance × sin θ at its row's centre) over the sum of weights. Cells
    // expected below 5 are pooled. The test fails at p < 0.001.
    let (w, h, t) = test_map();
    let rotation = 0.7;
    let d = Distribution::new(w, h, &t);
    let n = 400_000usize;
    let mut counts = vec![0f64; (w * h) as usize];
    let mut s = Stream(29);
    for _ in 0..n {
        let smp = d.sample(s.next(), s.next(), rotation);
        let (u, v) = coordinates(smp.dir, rotation);
        let x = ((u * w as f32) as u32).min(w - 1);
        let y = ((v * h as f32) as u32).min(h - 1);
        counts[(y * w + x) as usize] += 1.0;
    }
    let weight = |x: u32, y: u32| {
        let sin_t = (std::f64::consts::PI * (y as f64 + 0.5) / h as f64).sin();
        luminance(t[(y * w + x) as usize]) as f64 * sin_t
    };
    let total: f64 = (0..h)
        .flat_map(|y| (0..w).map(move |x| (x, y)))
        .map(|(x, y)| weight(x, y))
        .sum();
    let (mut chi2, mut cells, mut pool_e, mut pool_o) = (0.0, 0usize, 0.0, 0.0);
    for y in 0..h {
        for x in 0..w {
            let e = n as f64 * weight(x, y) / total;
            let o = counts[(y * w + x) as usize];
            if e == 0.0 {
                assert_eq!(o, 0.0, "a black texel ({x}, {y}) was sampled");
                continue;
            }
            if e < 5.0 {
                pool_e += e;
                pool_o += o;
                continue;
            }
            chi2 += (o - e) * (o - e) / e;
            cells += 1;
        }
    }
    if pool_e > 0.0 {
        chi2 += (pool_o - pool_e) * (pool_o - pool_e) / pool_e;
        cells += 1;
    }
    let p = 1.0 - ChiSquared::new((cells - 1) as f64).unwrap().cdf(chi2);
    assert!(p > 1e-3, "chi² {chi2} over {cells} cells: p = {p}");
    // The sun texel (one of 128) takes its share: its weight over the total, within 4σ of
    // a binomial count.
    let share = weight(11, 2) / total;
    let seen = counts[(2 * w + 11) as usize] / n as f64;
    let sigma = (share * (1.0 - share) / n as f64).sqrt();
    assert!(share > 0.8, "the sun's weight {share}");
    assert!(
        (seen - share).abs() < 4.0 * sigma,
        "the sun's share {seen} against {share}"
    );
}

#[test]
fn a_sample_reports_the_density_of_its_direction_and_the_density_integrates_to_one() {
    let (w, h, t) = test_map();
    let d = Distribution::new(w, h, &t);
    let mut s = Stream(7);
    for _ in 0..2000 {
        let smp = d.sample(s.next(), s.next(), -1.3);
        let again = d.pdf(smp.dir, -1.3);
        assert!(
            (smp.pdf - again).abs() <= 1e-3 * smp.pdf.max(again),
            "{} against {again}",
            smp.pdf
        );
    }
    // ∫ pdf dω over the sphere, by uniform sphere sampling: 1 within its 4σ.
    let n = 400_000;
    let (mut sum, mut sum2) = (0f64, 0f64);
    for _ in 0..n {
        let z = 1.0 - 2.0 * s.next();
        let phi = 2.0 * std::f32::consts::PI * s.next();
        let r = (1.0 - z * z).max(0.0).sqrt();
        let dir = Vec3::new(r * phi.cos(), z, r * phi.sin());
        let f = d.pdf(dir, -1.3) as f64 * 4.0 * std::f64::consts::PI;
        sum += f;
        sum2 += f * f;
    }
    let mean = sum / n as f64;
    let sigma = ((sum2 / n as f64 - mean * mean) / n as f64).sqrt();
    assert!((mean - 1.0).abs() < 4.0 * sigma, "∫pdf = {mean} ± {sigma}");
}

#[test]
fn a_constant_map_has_about_the_uniform_density_and_exactly_its_rows() {
    let d = Distribution::new(8, 4, &[[1.0, 1.0, 1.0]; 32]);
    let mut s = Stream(3);
    for _ in 0..1000 {
        let smp = d.sample(s.next(), s.next(), 0.0);
        let (_, v) = coordinates(smp.dir, 0.0);
        // Each texel's weight is sin θ at its row's centre, over the sphere's 2π² sin θ at
        // the point: about 1/4π, exactly this.
        let row = (v * 4.0).floor().min(3.0);
        let centre = (std::f32::consts::PI * (row + 0.5) / 4.0).sin();
        let one_row_integral: f32 = (0..4)
            .map(|r| (std::f32::consts::PI * (r as f32 + 0.5) / 4.0).sin())
            .sum::<f32>()
            / 4.0;
        let exact = centre
            / one_row_integral
            / (2.0 * std::f32::consts::PI.powi(2) * (std::f32::consts::PI * v).sin());
        // (v found again from the direction by acos: f32 loses digits near the poles.)
        assert!(
            (smp.pdf - exact).abs() <= 5e-3 * exact,
            "{} against {exact}",
            smp.pdf
        );
    }
    assert!(direction(0.5, 0.5, 0.0).abs_diff_eq(Vec3::NEG_Z, 1e-6));
}

#[test]
fn maps_load_from_radiance_hdr_and_broken_texels_are_refused_by_position() {
    let dir = tempfile::tempdir().unwrap();
    // A 4 × 2 Radiance HDR with a bright texel.
    let mut img = image::Rgb32FImage::from_pixel(4, 2, image::Rgb([0.5, 0.25, 1.0]));
    img.put_pixel(3, 1, image::Rgb([1000.0, 900.0, 800.0]));
    let path = dir.path().join("sky.hdr");
    image::DynamicImage::ImageRgb32F(img.clone())
        .save(&path)
        .unwrap();
    let m = EnvMap::load(&path).unwrap();
    // RGBE texels (4 bytes each) and the CDFs (3 + 2 × 5 f32).
    assert_eq!((m.width, m.height, m.bytes()), (4, 2, 8 * 4 + 13 * 4));
    // RGBE keeps 8 bits of mantissa per channel: within 1 %.
    let [r, g, b] = m.texel(3, 1);
    assert!(
        (r / 1000.0 - 1.0).abs() < 0.01
            && (g / 900.0 - 1.0).abs() < 0.01
            && (b / 800.0 - 1.0).abs() < 0.01
    );
    // NaN and negative texels, by position (column, row from the top).
    for (bad, what) in [(f32::NAN, "NaN"), (-1.0, "-1"), (f32::INFINITY, "inf")] {
        let mut broken = img.clone();
        broken.put_pixel(2, 1, image::Rgb([0.1, bad, 0.1]));
        let e = EnvMap::from_image(broken, "broken.exr".into()).unwrap_err();
        assert!(
            e.contains("broken.exr: texel (2, 1)") && e.contains(what),
            "{e}"
        );
    }
    // A 1 × 1 map is a constant sky: it loads, and its distribution is uniform.
    let one = EnvMap::from_image(
        image::Rgb32FImage::from_pixel(1, 1, image::Rgb([2.0; 3])),
        "one".into(),
    )
    .unwrap();
    let d = &one.distribution;
    assert!(
        (d.sample(0.25, 0.5, 0.0).pdf - 1.0 / (2.0 * std::f32::consts::PI.powi(2))).abs() < 1e-6
    );
    // Not an image.
    let junk = dir.path().join("junk.hdr");
    std::fs::write(&junk, b"#?RADIANCE\nbroken").unwrap();
    assert!(EnvMap::load(&junk).unwrap_err().contains("junk.hdr"));
}
