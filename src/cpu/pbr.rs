//! glTF 2.0's metallic-roughness BRDF (its Appendix B) on the CPU: shaders/common/pbr.wgsl in
//! Rust, term for term (its comments give the sources): GGX with α = roughness², the
//! height-correlated Smith visibility, Schlick's Fresnel mixed by metallic, sampled by visible
//! normals (Heitz 2018) mixed with the cosine lobe.

use super::rng::Rng;
use super::sampling::{PI, basis, normalize_or, sin_cos_turns};
use super::scene::Material;
use glam::Vec3A;

/// Below this α the specular lobe is a perfect mirror.
pub const ALPHA_MIN: f32 = 1e-4;
const LUMINANCE: Vec3A = Vec3A::new(0.2126, 0.7152, 0.0722);

/// A pbr material at a hit, seen from `wo` over the shading normal `n` (pbr.wgsl: PbrLobe).
#[derive(Clone, Copy, Debug)]
pub struct Lobe {
    pub base: Vec3A,
    pub metallic: f32,
    pub n: Vec3A,
    pub alpha: f32,
    pub wo: Vec3A,
    /// KHR_materials_specular's specularFactor (1 without it).
    pub weight: f32,
    /// The dielectric's f0, times the extension's colour, at most 1.
    pub f0: Vec3A,
    pub p_spec: f32,
}

/// A drawn direction, its throughput factor f·cos/pdf and its density (0: the mirror).
#[derive(Clone, Copy, Debug)]
pub struct Sample {
    pub dir: Vec3A,
    pub weight: Vec3A,
    pub pdf: f32,
    pub ok: bool,
}

#[inline(always)]
fn pow5(x: f32) -> f32 {
    let x2 = x * x;
    x2 * x2 * x
}

/// Schlick's Fresnel of reflectance `f0` at the angle whose (1 − cos)⁵ is `x5`: the metal's
/// and the dielectric's, one x5 for both (pbr.wgsl: pbr_fresnel).
#[inline(always)]
fn fresnel(f0: Vec3A, x5: f32) -> Vec3A {
    f0 + (Vec3A::ONE - f0) * x5
}

/// (1 − cos)⁵ of Schlick's approximation (pbr.wgsl: pbr_schlick_x5).
#[inline(always)]
fn schlick_x5(cos: f32) -> f32 {
    pow5(1.0 - cos.clamp(0.0, 1.0))
}

#[inline(always)]
fn max3(v: Vec3A) -> f32 {
    v.x.max(v.y.max(v.z))
}

/// The lobe of material `m` towards `wo` over `n` (pbr.wgsl: pbr_lobe, with
/// KHR_materials_specular's fresnel_mix).
pub fn lobe(m: &Material, wo: Vec3A, n: Vec3A) -> Lobe {
    let r = (m.ior - 1.0) / (m.ior + 1.0);
    let f0 = (Vec3A::splat(r * r) * m.specular_color).min(Vec3A::ONE);
    let fd = m.specular * max3(fresnel(f0, schlick_x5(n.dot(wo))));
    let spec_w = m.metallic + (1.0 - m.metallic) * fd;
    let diff_w = (1.0 - m.metallic) * (1.0 - fd) * m.color.dot(LUMINANCE);
    let total = spec_w + diff_w;
    let p_spec = if total > 0.0 { spec_w / total } else { 1.0 };
    Lobe {
        base: m.color,
        metallic: m.metallic,
        n,
        alpha: m.roughness * m.roughness,
        wo,
        weight: m.specular,
        f0,
        p_spec,
    }
}

/// Trowbridge-Reitz (GGX) normal distribution, from cos and sin² of the half vector's angle:
/// its denominator written as sin² + cos²·α² rather than cos²(α² − 1) + 1, which cancels to
/// 0 in f32 for α below about 2.4·10⁻⁴ (1 − α² rounds to 1) and made D infinite.
#[inline(always)]
pub fn d(n_dot_h: f32, sin2_h: f32, alpha: f32) -> f32 {
    let a2 = alpha * alpha;
    let k = sin2_h + n_dot_h * n_dot_h * a2;
    a2 / (PI * k * k)
}

/// The height-correlated Smith visibility (glTF's V_GGX).
#[inline(always)]
pub fn v(n_dot_l: f32, n_dot_v: f32, alpha: f32) -> f32 {
    let a2 = alpha * alpha;
    let gv = n_dot_l * (n_dot_v * n_dot_v * (1.0 - a2) + a2).sqrt();
    let gl = n_dot_v * (n_dot_l * n_dot_l * (1.0 - a2) + a2).sqrt();
    0.5 / (gv + gl)
}

/// Smith's masking of one direction.
#[inline(always)]
pub fn g1(n_dot_v: f32, alpha: f32) -> f32 {
    let a2 = alpha * alpha;
    2.0 * n_dot_v / (n_dot_v + (a2 + (1.0 - a2) * n_dot_v * n_dot_v).sqrt())
}

/// f·cos towards `wi`, and the density with which [`sample`] draws it (pbr.wgsl: pbr_eval).
pub fn eval(l: &Lobe, wi: Vec3A) -> (Vec3A, f32) {
    let nl = l.n.dot(wi);
    let nv = l.n.dot(l.wo);
    if nl <= 0.0 || nv <= 0.0 {
        return (Vec3A::ZERO, 0.0);
    }
    let h = (l.wo + wi).normalize();
    let x5 = schlick_x5(l.wo.dot(h));
    let (fd, fm) = (fresnel(l.f0, x5), fresnel(l.base, x5));
    let mut f = (1.0 - l.metallic) * (1.0 - l.weight * max3(fd)) * l.base / PI;
    let mut pdf = (1.0 - l.p_spec) * nl / PI;
    if l.alpha >= ALPHA_MIN {
        let nh = l.n.dot(h).clamp(0.0, 1.0);
        let dh = d(nh, l.n.cross(h).length_squared(), l.alpha);
        f += ((1.0 - l.metallic) * l.weight * fd + l.metallic * fm) * (dh * v(nl, nv, l.alpha));
        pdf += l.p_spec * dh * g1(nv, l.alpha) / (4.0 * nv);
    }
    (f * nl, pdf)
}

/// A visible normal of GGX seen from `wo` (local frame): Heitz 2018, listing 1.
pub fn visible_normal(wo: Vec3A, alpha: f32, (u1, u2): (f32, f32)) -> Vec3A {
    let vh = Vec3A::new(alpha * wo.x, alpha * wo.y, wo.z).normalize();
    let len2 = vh.x * vh.x + vh.y * vh.y;
    let t1 = if len2 > 0.0 {
        Vec3A::new(-vh.y, vh.x, 0.0) / len2.sqrt()
    } else {
        Vec3A::X
    };
    let t2 = vh.cross(t1);
    let r = u1.sqrt();
    let (s_phi, c_phi) = sin_cos_turns(u2);
    let p1 = r * c_phi;
    let s = 0.5 * (1.0 + vh.z);
    let p2 = (1.0 - s) * (1.0 - p1 * p1).max(0.0).sqrt() + s * r * s_phi;
    let nh = p1 * t1 + p2 * t2 + (1.0 - p1 * p1 - p2 * p2).max(0.0).sqrt() * vh;
    Vec3A::new(alpha * nh.x, alpha * nh.y, nh.z.max(0.0)).normalize()
}

/// Draws a direction from the lobe (pbr.wgsl: pbr_sample); three draws either way.
pub fn sample(l: &Lobe, rng: &mut Rng) -> Sample {
    let pick = rng.rand();
    let u = rng.rand2();
    let nv = l.n.dot(l.wo);
    let none = |dir| Sample {
        dir,
        weight: Vec3A::ZERO,
        pdf: 0.0,
        ok: false,
    };
    if nv <= 0.0 {
        return none(l.n);
    }
    let wi = if pick < l.p_spec {
        if l.alpha < ALPHA_MIN {
            let x5 = schlick_x5(nv);
            let (fd, fm) = (fresnel(l.f0, x5), fresnel(l.base, x5));
            return Sample {
                dir: reflect(-l.wo, l.n),
                weight: ((1.0 - l.metallic) * l.weight * fd + l.metallic * fm) / l.p_spec,
                pdf: 0.0,
                ok: true,
            };
        }
        let [t, b, n] = basis(l.n);
        let local = Vec3A::new(t.dot(l.wo), b.dot(l.wo), nv);
        let m = visible_normal(local, l.alpha, u);
        let h = t * m.x + b * m.y + n * m.z;
        reflect(-l.wo, h)
    } else {
        let z = 1.0 - 2.0 * u.0;
        let r = (1.0 - z * z).max(0.0).sqrt();
        let (s, c) = sin_cos_turns(u.1);
        normalize_or(l.n + Vec3A::new(r * c, r * s, z), l.n)
    };
    let (f, pdf) = eval(l, wi);
    if pdf <= 0.0 {
        return none(wi);
    }
    Sample {
        dir: wi,
        weight: f / pdf,
        pdf,
        ok: true,
    }
}

#[inline(always)]
fn reflect(d: Vec3A, n: Vec3A) -> Vec3A {
    d - 2.0 * d.dot(n) * n
}

#[cfg(test)]
mod tests {
    use super::*;

    fn material(base: f32, metallic: f32, roughness: f32) -> Material {
        Material {
            color: Vec3A::new(base, 0.5 * base, 0.25 * base),
            specular_color: Vec3A::ONE,
            smoothness: 0.0,
            absorption: 0.0,
            specular: 1.0,
            light: 0.0,
            ior: 1.5,
            light_slot: 0,
            metallic,
            roughness,
            pbr: true,
        }
    }

    /// The lobe over n = +z, seen from a direction at `cos_theta` from it.
    fn lobe_at(m: &Material, cos_theta: f32) -> Lobe {
        let s = (1.0 - cos_theta * cos_theta).sqrt();
        lobe(m, Vec3A::new(s, 0.0, cos_theta), Vec3A::Z)
    }

    /// The direction at (μ = cos θ, φ) over +z.
    fn dir(mu: f32, phi: f32) -> Vec3A {
        let s = (1.0 - mu * mu).max(0.0).sqrt();
        Vec3A::new(s * phi.cos(), s * phi.sin(), mu)
    }

    /// ∫ f·cos dω and ∫ pdf dω over the hemisphere, by the midpoint rule in (μ, φ)
    /// (dω = dμ dφ), on a grid fine enough for α ≥ 0.1.
    fn quadrature(l: &Lobe) -> (Vec3A, f64) {
        let (nm, np) = (600, 600);
        let dw = (1.0 / nm as f64) * (2.0 * std::f64::consts::PI / np as f64);
        let (mut albedo, mut mass) = (glam::DVec3::ZERO, 0.0);
        for i in 0..nm {
            for j in 0..np {
                let mu = (i as f32 + 0.5) / nm as f32;
                let phi = 2.0 * PI * (j as f32 + 0.5) / np as f32;
                let (f, pdf) = eval(l, dir(mu, phi));
                albedo += f.as_dvec3() * dw;
                mass += pdf as f64 * dw;
            }
        }
        (albedo.as_vec3a(), mass)
    }

    /// The mean of the sampling routine's weights over `n` draws: the directional albedo.
    fn sampled(l: &Lobe, n: u32) -> Vec3A {
        let mut sum = glam::DVec3::ZERO;
        for i in 0..n {
            let mut rng = Rng::new(3, i, 11);
            let s = sample(l, &mut rng);
            assert!(s.weight.is_finite() && s.pdf.is_finite(), "{s:?}");
            if s.ok {
                sum += s.weight.as_dvec3();
            }
        }
        (sum / n as f64).as_vec3a()
    }

    #[test]
    fn the_sampled_albedo_is_the_integral_of_the_brdf() {
        // Directional albedo ∫ f·cos dω: drawn by the sampling routine (its mean weight)
        // against the midpoint rule on the same formulas, at several (metallic, α, cos θ):
        // within 1 % (plus 0.002 for the draws' noise at 2·10⁵ samples).
        for metallic in [0.0, 0.5, 1.0] {
            for roughness in [0.4, 0.7, 1.0] {
                for cos_theta in [0.2, 0.6, 0.95] {
                    let l = lobe_at(&material(0.9, metallic, roughness), cos_theta);
                    let (exact, _) = quadrature(&l);
                    let drawn = sampled(&l, 200_000);
                    for c in 0..3 {
                        assert!(
                            (drawn[c] - exact[c]).abs() <= 0.01 * exact[c] + 0.002,
                            "metallic {metallic} roughness {roughness} cos {cos_theta}: \
                             channel {c} drawn {} integrated {}",
                            drawn[c],
                            exact[c]
                        );
                    }
                    // A metal never returns more than it receives.
                    if metallic == 1.0 {
                        assert!(exact.max_element() <= 1.0, "{exact}");
                    }
                }
            }
        }
    }

    #[test]
    fn the_sampler_draws_from_the_density_it_reports() {
        use crate::stability::chi2::{PBR_CASES, PBR_DRAWS};
        // Pearson's chi-square (`stability::chi2`): the directions drawn against the density
        // the sampler reports. Each case must pass at 1e-3 / cases. tests/pbr.rs runs the
        // same cases on the WGSL sampler.
        for (metallic, roughness, cos_theta) in PBR_CASES {
            let l = lobe_at(&material(0.8, metallic, roughness), cos_theta);
            let draws = (0..PBR_DRAWS).map(|i| {
                let s = sample(&l, &mut Rng::new(5, i, 3));
                s.ok.then(|| s.dir.to_array())
            });
            let r = crate::stability::chi2::test(draws, |d| eval(&l, Vec3A::from(d)).1 as f64);
            assert!(
                r.p > 1e-3 / PBR_CASES.len() as f64,
                "metallic {metallic} roughness {roughness} cos {cos_theta}: {r:?}"
            );
        }
    }

    #[test]
    fn the_brdf_is_reciprocal() {
        let m = material(0.7, 0.4, 0.5);
        for (a, b) in [(0.3, 0.8), (0.9, 0.2), (0.5, 0.55)] {
            let (wo, wi) = (dir(a, 0.3), dir(b, 2.1));
            let f1 = eval(&lobe(&m, wo, Vec3A::Z), wi).0 / wi.z;
            let f2 = eval(&lobe(&m, wi, Vec3A::Z), wo).0 / wo.z;
            assert!(
                (f1 - f2).abs().max_element() <= 1e-5 * f1.max_element(),
                "{f1} {f2}"
            );
        }
    }

    #[test]
    fn roughness_to_zero_is_a_mirror_without_nan() {
        // A white metal: the mirror's weight is exactly 1; just above the mirror's α the
        // microfacet lobe returns G2/G1 ≈ 1; no weight is NaN or infinite on the way.
        let white = |roughness| Material {
            color: Vec3A::ONE,
            ..material(1.0, 1.0, roughness)
        };
        let l = lobe_at(&white(0.0), 0.5);
        let s = sample(&l, &mut Rng::new(0, 0, 1));
        assert_eq!((s.weight, s.pdf), (Vec3A::ONE, 0.0));
        assert_eq!(s.dir, Vec3A::new(-(0.75f32).sqrt(), 0.0, 0.5));
        for roughness in [0.0101, 0.02, 0.05] {
            let w = sampled(&lobe_at(&white(roughness), 0.5), 20_000);
            assert!(
                (w - Vec3A::ONE).abs().max_element() < 2e-3,
                "{roughness}: {w}"
            );
        }
    }
}
