//! Pearson's chi-square of directions drawn against the density their sampler reports
//! (Mitsuba 3's `chi2` tests are the model): the directions over the sphere about +z binned
//! in (μ = cos θ, φ),
//! against the counts the density integrates to per bin (a midpoint rule on a finer grid
//! inside each bin), bins expecting fewer than 5 pooled into one. Both tracers' pbr samplers
//! are tested with it (`cpu::pbr`'s tests, tests/pbr.rs for the WGSL one).

use statrs::distribution::{ChiSquared, ContinuousCDF};
use std::f64::consts::PI;

/// Bins in μ (over −1 … 1) and in φ, and the midpoint rule's sub-steps per bin and axis.
const MU_BINS: usize = 32;
const PHI_BINS: usize = 32;
const SUB: usize = 12;

/// The pbr lobes both samplers are tested on: (metallic, roughness, cos θ of the viewer).
pub const PBR_CASES: [(f32, f32, f32); 6] = [
    (0.0, 0.3, 0.5),
    (0.0, 0.8, 0.9),
    (0.5, 0.5, 0.3),
    (1.0, 0.3, 0.7),
    (1.0, 0.6, 0.15),
    (1.0, 1.0, 0.5),
];

/// The transmission lobes both samplers are tested on: (roughness, cos θ of the viewer,
/// η), of a material of transmission 0.8, metallic 0, ior 1.5: η 0 a thin wall, 1/1.5 a
/// volume entered, 1.5 one left (where total internal reflection refuses some normals).
pub const PBR_THROUGH_CASES: [(f32, f32, f32); 6] = [
    (0.3, 0.6, 0.0),
    (0.7, 0.2, 0.0),
    (0.3, 0.5, 1.0 / 1.5),
    (0.8, 0.9, 1.0 / 1.5),
    (0.3, 0.7, 1.5),
    (0.6, 0.3, 1.5),
];

/// The clear-coated lobes both samplers are tested on: (metallic, roughness, clearcoat
/// roughness, cos θ of the viewer), of clearcoat 1 over an orange base.
/// (Coats of α ≥ 0.1, as the other cases: the bins' midpoint rule cannot integrate a narrower
/// lobe; the polished coat has known answers in tests/pbr.rs.)
pub const PBR_COAT_CASES: [(f32, f32, f32, f32); 4] = [
    (0.0, 0.8, 0.35, 0.6),
    (1.0, 0.6, 0.4, 0.3),
    (0.0, 0.3, 0.6, 0.9),
    (0.5, 1.0, 0.35, 0.2),
];

/// Draws per case.
pub const PBR_DRAWS: u32 = 400_000;

/// The statistic, its degrees of freedom and its p-value.
#[derive(Clone, Copy, Debug)]
pub struct ChiSquare {
    pub chi2: f64,
    pub bins: usize,
    pub p: f64,
}

/// Tests `draws` draws (`None`: a draw the sampler refused, which counts toward the total
/// but in no bin) against `pdf`, the density over the sphere (per steradian).
pub fn test(
    draws: impl IntoIterator<Item = Option<[f32; 3]>>,
    pdf: impl Fn([f32; 3]) -> f64,
) -> ChiSquare {
    let mut observed = vec![0f64; MU_BINS * PHI_BINS];
    let mut total = 0usize;
    for d in draws {
        total += 1;
        let Some([x, y, z]) = d else { continue };
        let mu = z.clamp(-1.0, 0.999_999) as f64;
        let phi = (y as f64).atan2(x as f64).rem_euclid(2.0 * PI);
        let i = (((mu + 1.0) * 0.5 * MU_BINS as f64) as usize).min(MU_BINS - 1);
        let j = ((phi / (2.0 * PI) * PHI_BINS as f64) as usize).min(PHI_BINS - 1);
        observed[i * PHI_BINS + j] += 1.0;
    }
    let dw = (2.0 / (MU_BINS * SUB) as f64) * (2.0 * PI / (PHI_BINS * SUB) as f64);
    let (mut chi2, mut bins, mut pool_o, mut pool_e) = (0.0, 0usize, 0.0, 0.0);
    for (b, o) in observed.iter().enumerate() {
        let (bi, bj) = (b / PHI_BINS, b % PHI_BINS);
        let mut sum = 0.0;
        for si in 0..SUB {
            for sj in 0..SUB {
                let mu = -1.0 + 2.0 * (bi as f64 + (si as f64 + 0.5) / SUB as f64) / MU_BINS as f64;
                let phi = 2.0 * PI * (bj as f64 + (sj as f64 + 0.5) / SUB as f64) / PHI_BINS as f64;
                let s = (1.0 - mu * mu).max(0.0).sqrt();
                let dir = [(s * phi.cos()) as f32, (s * phi.sin()) as f32, mu as f32];
                sum += pdf(dir);
            }
        }
        let e = sum * dw * total as f64;
        if e < 5.0 {
            pool_o += o;
            pool_e += e;
        } else {
            chi2 += (o - e).powi(2) / e;
            bins += 1;
        }
    }
    if pool_e >= 5.0 {
        chi2 += (pool_o - pool_e).powi(2) / pool_e;
        bins += 1;
    }
    let p = 1.0 - ChiSquared::new((bins.max(2) - 1) as f64).unwrap().cdf(chi2);
    ChiSquare { chi2, bins, p }
}
