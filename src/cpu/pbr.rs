//! glTF 2.0's metallic-roughness BRDF (its Appendix B) on the CPU: shaders/common/pbr.wgsl in
//! Rust, term for term (its comments give the sources): GGX with α = roughness², the
//! height-correlated Smith visibility, Schlick's Fresnel mixed by metallic, sampled by visible
//! normals (Heitz 2018) mixed with the cosine lobe; KHR_materials_transmission's rough
//! dielectric (Walter et al. 2007) where the material transmits; KHR_materials_clearcoat's
//! coat over it all.

use super::rng::Rng;
use super::sampling::{PI, basis, normalize_or, sin_cos_turns};
use super::scene::Material;
use glam::Vec3A;

/// Below this α the specular lobe is a perfect mirror (the scene's `Material::is_mirror`
/// reads the same bound).
pub const ALPHA_MIN: f32 = crate::scene::PBR_MIRROR_ALPHA;
/// The least share of the base a rough transmission lobe is drawn by, however much the
/// macroscopic Fresnel reflects.
const TRANSMISSION_FLOOR: f32 = 0.25;
/// The clear coat's reflectance at normal incidence: ior 1.5, as the extension fixes it.
const COAT_F0: f32 = 0.04;
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
    /// KHR_materials_transmission's share of the dielectric base (0: opaque).
    pub transmission: f32,
    /// The probability of sampling the transmission lobe.
    pub p_trans: f32,
    /// The index ratio η_wo / η_wi across the surface for a refracting (volume) material;
    /// 0 for a thin wall, which transmits without bending (the specification's default).
    pub eta: f32,
    /// KHR_materials_clearcoat's mix weight, clearcoat · Fc(n·v) with Fc Schlick's of f0 0.04;
    /// also the probability of sampling the coat (0: no coat).
    pub coat: f32,
    pub coat_alpha: f32,
}

/// A drawn direction, its throughput factor f·cos/pdf and its density (0: the mirror);
/// `through`: drawn by the transmission lobe, below the surface.
#[derive(Clone, Copy, Debug)]
pub struct Sample {
    pub dir: Vec3A,
    pub weight: Vec3A,
    pub pdf: f32,
    pub ok: bool,
    pub through: bool,
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

/// (1 − cos)⁵ for the dielectric's Fresnel at a microfacet that `wo` meets at `cos`: from
/// inside a refracting material (η > 1) Schlick's approximation takes the angle outside,
/// and total internal reflection reflects everything (pbr.wgsl: pbr_dielectric_x5).
#[inline(always)]
fn dielectric_x5(cos: f32, eta: f32) -> f32 {
    if eta <= 1.0 {
        return schlick_x5(cos);
    }
    let cos_t2 = 1.0 - eta * eta * (1.0 - cos * cos);
    if cos_t2 <= 0.0 {
        return 1.0;
    }
    schlick_x5(cos_t2.sqrt())
}

#[inline(always)]
fn max3(v: Vec3A) -> f32 {
    v.x.max(v.y.max(v.z))
}

/// The lobe of material `m` towards `wo` over `n` (pbr.wgsl: pbr_lobe, with
/// KHR_materials_specular's fresnel_mix and KHR_materials_transmission's split of the base);
/// `front`: `wo` is on the outer side of the geometric surface.
pub fn lobe(m: &Material, wo: Vec3A, n: Vec3A, front: bool) -> Lobe {
    let r = (m.ior - 1.0) / (m.ior + 1.0);
    let f0 = (Vec3A::splat(r * r) * m.specular_color).min(Vec3A::ONE);
    let eta = match (m.transmission > 0.0 && !m.thin, front) {
        (false, _) => 0.0,
        (true, true) => 1.0 / m.ior,
        (true, false) => m.ior,
    };
    let fd = m.specular * max3(fresnel(f0, dielectric_x5(n.dot(wo), eta)));
    let spec_w = m.metallic + (1.0 - m.metallic) * fd;
    let rest = (1.0 - m.metallic) * (1.0 - fd);
    let diff_w = rest * (1.0 - m.transmission) * m.color.dot(LUMINANCE);
    // A rough boundary transmits where the macroscopic normal reflects totally (fd = 1):
    // its lobe keeps a share there, so that the facets that transmit are drawn (`splits`:
    // within the boundary's share, each facet's own Fresnel chooses).
    let rest_t = if m.roughness * m.roughness >= ALPHA_MIN {
        (1.0 - m.metallic) * (1.0 - fd).max(TRANSMISSION_FLOOR)
    } else {
        rest
    };
    let trans_w = rest_t * m.transmission * m.color.dot(LUMINANCE);
    let total = spec_w + diff_w + trans_w;
    let (p_spec, p_trans) = if total > 0.0 {
        (spec_w / total, trans_w / total)
    } else {
        (1.0, 0.0)
    };
    // KHR_materials_clearcoat's fresnel_coat: the coat's Fresnel at n·v (ior 1.5).
    let coat = if m.clearcoat > 0.0 {
        m.clearcoat * (COAT_F0 + (1.0 - COAT_F0) * schlick_x5(n.dot(wo)))
    } else {
        0.0
    };
    Lobe {
        base: m.color,
        metallic: m.metallic,
        n,
        alpha: m.roughness * m.roughness,
        wo,
        weight: m.specular,
        f0,
        p_spec,
        transmission: m.transmission,
        p_trans,
        eta,
        coat,
        coat_alpha: m.clearcoat_roughness * m.clearcoat_roughness,
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

/// f·cos towards `wi`, and the density with which [`sample`] draws it (pbr.wgsl: pbr_eval):
/// the material's, under its clear coat where it has one. KHR_materials_clearcoat's
/// fresnel_coat weighs the material by 1 − coat and adds the coat's GGX lobe (no F: the
/// weight holds it) times coat; the coat is drawn with probability coat, so the material's
/// density is scaled alike.
pub fn eval(l: &Lobe, wi: Vec3A) -> (Vec3A, f32) {
    let (f, pdf) = eval_base(l, wi);
    if l.coat <= 0.0 {
        return (f, pdf);
    }
    let (mut f, mut pdf) = (f * (1.0 - l.coat), pdf * (1.0 - l.coat));
    let (nl, nv) = (l.n.dot(wi), l.n.dot(l.wo));
    if nl > 0.0 && nv > 0.0 && l.coat_alpha >= ALPHA_MIN {
        let h = (l.wo + wi).normalize();
        let nh = l.n.dot(h).clamp(0.0, 1.0);
        let dh = d(nh, l.n.cross(h).length_squared(), l.coat_alpha);
        f += Vec3A::splat(l.coat * dh * v(nl, nv, l.coat_alpha) * nl);
        pdf += l.coat * dh * g1(nv, l.coat_alpha) / (4.0 * nv);
    }
    (f, pdf)
}

/// The material without its coat: f·cos and the density of its lobes (pbr.wgsl:
/// pbr_eval_base).
pub fn eval_base(l: &Lobe, wi: Vec3A) -> (Vec3A, f32) {
    let nl = l.n.dot(wi);
    let nv = l.n.dot(l.wo);
    if nv <= 0.0 {
        return (Vec3A::ZERO, 0.0);
    }
    if nl <= 0.0 {
        if l.transmission > 0.0 && nl < 0.0 {
            return eval_through(l, wi, -nl, nv);
        }
        return (Vec3A::ZERO, 0.0);
    }
    let h = (l.wo + wi).normalize();
    let c = l.wo.dot(h);
    let x5 = schlick_x5(c);
    let xd = if l.eta > 1.0 {
        dielectric_x5(c, l.eta)
    } else {
        x5
    };
    let (fd, fm) = (fresnel(l.f0, xd), fresnel(l.base, x5));
    let mut f =
        (1.0 - l.metallic) * (1.0 - l.weight * max3(fd)) * (1.0 - l.transmission) * l.base / PI;
    let mut pdf = (1.0 - l.p_spec - l.p_trans) * nl / PI;
    if l.alpha >= ALPHA_MIN {
        let nh = l.n.dot(h).clamp(0.0, 1.0);
        let dh = d(nh, l.n.cross(h).length_squared(), l.alpha);
        f += ((1.0 - l.metallic) * l.weight * fd + l.metallic * fm) * (dh * v(nl, nv, l.alpha));
        let p = lobe_shares(l, l.weight * max3(fd)).0;
        pdf += p * dh * g1(nv, l.alpha) / (4.0 * nv);
    }
    (f * nl, pdf)
}

/// The transmission lobe towards `wi` below the surface (|n·wi| = `nl`): f·cos and its
/// density (pbr.wgsl: pbr_eval_through). A thin wall's is the specular lobe mirrored through
/// the surface (KHR_materials_transmission, "thin-walled"); a volume's boundary refracts, by
/// Walter et al., "Microfacet Models for Refraction through Rough Surfaces" (EGSR 2007),
/// eq. 16 and 21, with PBRT 4th ed. §9.7's density. The base colour tints it; radiance's
/// 1/η² across the boundary is left out, as the lecture's glass leaves it out (it cancels
/// on a closed object).
pub fn eval_through(l: &Lobe, wi: Vec3A, nl: f32, nv: f32) -> (Vec3A, f32) {
    if l.alpha < ALPHA_MIN {
        return (Vec3A::ZERO, 0.0);
    }
    let tint = (1.0 - l.metallic) * l.transmission * l.base;
    if l.eta == 0.0 {
        let h = (l.wo + wi + 2.0 * nl * l.n).normalize();
        let fd = fresnel(l.f0, schlick_x5(l.wo.dot(h)));
        let nh = l.n.dot(h).clamp(0.0, 1.0);
        let dh = d(nh, l.n.cross(h).length_squared(), l.alpha);
        let f = tint * (1.0 - l.weight * max3(fd)) * (dh * v(nl, nv, l.alpha));
        let p = lobe_shares(l, l.weight * max3(fd)).1;
        return (f * nl, p * dh * g1(nv, l.alpha) / (4.0 * nv));
    }
    let mut h = normalize_or(l.eta * l.wo + wi, l.n);
    if h.dot(l.n) < 0.0 {
        h = -h;
    }
    let (oh, ih) = (l.wo.dot(h), wi.dot(h));
    if oh <= 0.0 || ih >= 0.0 {
        return (Vec3A::ZERO, 0.0);
    }
    let denom = (ih + l.eta * oh) * (ih + l.eta * oh);
    let fd = fresnel(l.f0, dielectric_x5(oh, l.eta));
    let nh = l.n.dot(h).clamp(0.0, 1.0);
    let dh = d(nh, l.n.cross(h).length_squared(), l.alpha);
    let jacobian = -ih * oh / denom;
    let f = tint * (1.0 - l.weight * max3(fd)) * (4.0 * nl * v(nl, nv, l.alpha) * dh * jacobian);
    let p = lobe_shares(l, l.weight * max3(fd)).1;
    (f, p * g1(nv, l.alpha) / nv * dh * jacobian)
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

/// Draws a direction from the lobe (pbr.wgsl: pbr_sample): the specular lobe with
/// probability p_spec, the transmission lobe with p_trans, else the cosine lobe; a rough
/// boundary that transmits draws the two together, a facet's Fresnel choosing
/// (`sample_facet`). Three draws either way.
pub fn sample(l: &Lobe, rng: &mut Rng) -> Sample {
    let mut pick = rng.rand();
    let u = rng.rand2();
    let nv = l.n.dot(l.wo);
    let none = |dir| Sample {
        dir,
        weight: Vec3A::ZERO,
        pdf: 0.0,
        ok: false,
        through: false,
    };
    if nv <= 0.0 {
        return none(l.n);
    }
    // The coat with probability coat; the material's lobes share the rest of the draw.
    if l.coat > 0.0 {
        if pick < l.coat {
            return sample_coat(l, nv, u);
        }
        pick = (pick - l.coat) / (1.0 - l.coat);
    }
    if splits(l) && pick < l.p_spec + l.p_trans {
        return sample_facet(l, nv, pick / (l.p_spec + l.p_trans), u);
    }
    let through = l.p_trans > 0.0 && pick >= l.p_spec && pick < l.p_spec + l.p_trans;
    let wi = if pick < l.p_spec || through {
        if l.alpha < ALPHA_MIN {
            return mirror(l, nv, through);
        }
        // A rough lobe that transmits is drawn by `sample_facet`: this one reflects.
        reflect(-l.wo, half_vector(l, nv, l.alpha, u))
    } else {
        let z = 1.0 - 2.0 * u.0;
        let r = (1.0 - z * z).max(0.0).sqrt();
        let (s, c) = sin_cos_turns(u.1);
        normalize_or(l.n + Vec3A::new(r * c, r * s, z), l.n)
    };
    drawn(l, wi, through)
}

/// Whether the lobe draws reflection or transmission by the Fresnel of the microfacet it
/// draws (`sample_facet`): a rough boundary that transmits (pbr.wgsl: pbr_splits).
#[inline(always)]
fn splits(l: &Lobe) -> bool {
    l.p_trans > 0.0 && l.alpha >= ALPHA_MIN
}

/// At a microfacet whose dielectric Fresnel is `fd` (specular · max F), the shares of the
/// draw that reflect and that transmit: each lobe's weight there, the metal's Fresnel taken
/// as 1, as the lobe's own split does at the macroscopic normal (`lobe`) (pbr.wgsl:
/// pbr_facet_shares).
#[inline(always)]
fn facet_shares(l: &Lobe, fd: f32) -> (f32, f32) {
    let r = l.metallic + (1.0 - l.metallic) * fd;
    let t = (1.0 - l.metallic) * (1.0 - fd) * l.transmission * l.base.dot(LUMINANCE);
    let s = r + t;
    if s > 0.0 { (r / s, t / s) } else { (1.0, 0.0) }
}

/// The probabilities of the specular and the transmission lobe at a microfacet of Fresnel
/// `fd`: their shares of the rough boundary's draw (`splits`), else `p_spec` and `p_trans`
/// (pbr.wgsl: pbr_lobe_shares).
#[inline(always)]
fn lobe_shares(l: &Lobe, fd: f32) -> (f32, f32) {
    if splits(l) {
        let (r, t) = facet_shares(l, fd);
        let p = l.p_spec + l.p_trans;
        (p * r, p * t)
    } else {
        (l.p_spec, l.p_trans)
    }
}

/// A rough boundary's draw (`splits`): a visible normal, then reflection or transmission by
/// its own Fresnel (Walter, Marschner, Li and Torrance, "Microfacet Models for Refraction
/// through Rough Surfaces", EGSR 2007, §5.3; PBRT 4th ed. §9.7.5). `pick` is uniform in
/// [0, 1). Drawn by the macroscopic normal's Fresnel instead, a facet that reflects totally
/// inside a ball was drawn with probability p_spec < 1 and weighed 1 / p_spec: a path caught
/// inside gained 1.25 a bounce and came out as a firefly (BENCHMARKS.md, "Rough glass drawn by
/// its facets"). Weighed so, each draw carries about G2/G1 (pbr.wgsl: pbr_sample_facet).
fn sample_facet(l: &Lobe, nv: f32, pick: f32, u: (f32, f32)) -> Sample {
    let h = half_vector(l, nv, l.alpha, u);
    let c = l.wo.dot(h);
    let fd = l.weight * max3(fresnel(l.f0, dielectric_x5(c, l.eta)));
    let through = pick >= facet_shares(l, fd).0;
    let wi = if !through {
        reflect(-l.wo, h)
    } else if l.eta == 0.0 {
        let r = reflect(-l.wo, h);
        r - 2.0 * r.dot(l.n) * l.n
    } else {
        match refract(-l.wo, h, c, l.eta) {
            Some(d) => d,
            None => {
                return Sample {
                    dir: h,
                    weight: Vec3A::ZERO,
                    pdf: 0.0,
                    ok: false,
                    through: false,
                };
            }
        }
    };
    drawn(l, wi, through)
}

/// A visible normal of GGX of width `alpha` seen from `wo`, in world space (pbr.wgsl:
/// pbr_half_vector).
fn half_vector(l: &Lobe, nv: f32, alpha: f32, u: (f32, f32)) -> Vec3A {
    let [t, b, n] = basis(l.n);
    let m = visible_normal(Vec3A::new(t.dot(l.wo), b.dot(l.wo), nv), alpha, u);
    t * m.x + b * m.y + n * m.z
}

/// Drawn direction `wi` as a sample: its weight f·cos/pdf and density from [`eval`], or
/// refused where it lies on the wrong side of the surface for its lobe (`through`) or has no
/// density (pbr.wgsl: pbr_drawn).
fn drawn(l: &Lobe, wi: Vec3A, through: bool) -> Sample {
    let none = Sample {
        dir: wi,
        weight: Vec3A::ZERO,
        pdf: 0.0,
        ok: false,
        through: false,
    };
    if through != (wi.dot(l.n) < 0.0) {
        return none;
    }
    let (f, pdf) = eval(l, wi);
    if pdf <= 0.0 {
        return none;
    }
    Sample {
        dir: wi,
        weight: f / pdf,
        pdf,
        ok: true,
        through,
    }
}

/// A direction from the clear coat's GGX lobe, or its mirror below [`ALPHA_MIN`] (weight 1:
/// the coat's Fresnel over the probability of drawing it) (pbr.wgsl: pbr_sample_coat).
fn sample_coat(l: &Lobe, nv: f32, u: (f32, f32)) -> Sample {
    if l.coat_alpha < ALPHA_MIN {
        return Sample {
            dir: reflect(-l.wo, l.n),
            weight: Vec3A::ONE,
            pdf: 0.0,
            ok: true,
            through: false,
        };
    }
    drawn(
        l,
        reflect(-l.wo, half_vector(l, nv, l.coat_alpha, u)),
        false,
    )
}

/// The smooth lobes' deltas (α below [`ALPHA_MIN`]): the mirror, or straight through a thin
/// wall, or refracted by a volume's boundary; each its Fresnel weight over its probability
/// (pbr.wgsl: pbr_mirror).
fn mirror(l: &Lobe, nv: f32, through: bool) -> Sample {
    if !through {
        return Sample {
            dir: reflect(-l.wo, l.n),
            weight: mirror_reflectance(l, nv) / l.p_spec,
            pdf: 0.0,
            ok: true,
            through: false,
        };
    }
    let dir = if l.eta == 0.0 {
        Some(-l.wo)
    } else {
        refract(-l.wo, l.n, nv, l.eta)
    };
    Sample {
        dir: dir.unwrap_or(l.n),
        weight: transmittance(l, nv) / l.p_trans,
        pdf: 0.0,
        ok: dir.is_some(),
        through: true,
    }
}

/// What the mirror of a smooth lobe (α below [`ALPHA_MIN`]) reflects of the light that meets
/// it at `nv` (the dielectric's Fresnel times its specular weight, and the metal's): the
/// mirror's weight times its probability (pbr.wgsl: pbr_mirror_reflectance). Light sampling
/// through a mirror sphere tints the map's light by it (`trace::sample_mirror`).
pub fn mirror_reflectance(l: &Lobe, nv: f32) -> Vec3A {
    let fd = fresnel(l.f0, dielectric_x5(nv, l.eta));
    let fm = fresnel(l.base, schlick_x5(nv));
    (1.0 - l.metallic) * l.weight * fd + l.metallic * fm
}

/// What the smooth lobe (α below [`ALPHA_MIN`]) passes of the light that meets it at `nv`, the
/// weight of its transmitted delta times its probability: KHR_materials_transmission's share
/// of the dielectric base, less what its Fresnel reflects, tinted by the base (pbr.wgsl:
/// pbr_transmittance).
pub fn transmittance(l: &Lobe, nv: f32) -> Vec3A {
    let fd = fresnel(l.f0, dielectric_x5(nv, l.eta));
    (1.0 - l.metallic) * l.transmission * (1.0 - l.weight * max3(fd)) * l.base
}

/// What a smooth transmitting ball of material `m` (`Material::is_lens`) passes along a path
/// through it that enters at cos i, reflects `inner` times (0 or 1) inside and leaves at
/// cos r′ inside: [`transmittance`] in and out, and [`mirror_reflectance`] from inside, the
/// expectation of [`sample`]'s weights along the path. Light sampling through a glass ball
/// tints the map's light by it (`trace::sample_lens`; pbr.wgsl: pbr_lens_transmittance).
pub fn lens_transmittance(m: &Material, cos_i: f32, cos_r: f32, inner: u32) -> Vec3A {
    // Only the material and the side enter what these read, not the directions.
    let outside = lobe(m, Vec3A::Z, Vec3A::Z, true);
    let inside = lobe(m, Vec3A::Z, Vec3A::Z, false);
    let through = transmittance(&outside, cos_i) * transmittance(&inside, cos_r);
    if inner == 0 {
        through
    } else {
        through * mirror_reflectance(&inside, cos_r)
    }
}

/// `d` refracted through a surface of normal `n` (on the side `d` comes from, `cos` = −d·n)
/// with index ratio `eta`; `None` at total internal reflection.
#[inline(always)]
fn refract(d: Vec3A, n: Vec3A, cos: f32, eta: f32) -> Option<Vec3A> {
    let sin2_t = eta * eta * (1.0 - cos * cos);
    if sin2_t >= 1.0 {
        return None;
    }
    Some((eta * d + (eta * cos - (1.0 - sin2_t).sqrt()) * n).normalize())
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
            transmission: 0.0,
            thin: false,
            attenuation: Vec3A::ZERO,
            clearcoat: 0.0,
            clearcoat_roughness: 0.0,
        }
    }

    /// `material(0.8, metallic, roughness)` under a clear coat of factor 1.
    fn coated(metallic: f32, roughness: f32, coat_roughness: f32) -> Material {
        Material {
            clearcoat: 1.0,
            clearcoat_roughness: coat_roughness,
            ..material(0.8, metallic, roughness)
        }
    }

    /// A material of transmission 0.8 (ior 1.5, metallic 0): a thin wall for η 0, else a
    /// volume's boundary.
    fn transmitting(roughness: f32, eta: f32) -> Material {
        Material {
            color: Vec3A::new(0.9, 0.8, 0.7),
            transmission: 0.8,
            thin: eta == 0.0,
            ..material(1.0, 0.0, roughness)
        }
    }

    /// The lobe over n = +z, seen from a direction at `cos_theta` from it, from outside.
    fn lobe_at(m: &Material, cos_theta: f32) -> Lobe {
        lobe_from(m, cos_theta, true)
    }

    fn lobe_from(m: &Material, cos_theta: f32, front: bool) -> Lobe {
        let s = (1.0 - cos_theta * cos_theta).sqrt();
        lobe(m, Vec3A::new(s, 0.0, cos_theta), Vec3A::Z, front)
    }

    /// The direction at (μ = cos θ, φ) over +z.
    fn dir(mu: f32, phi: f32) -> Vec3A {
        let s = (1.0 - mu * mu).max(0.0).sqrt();
        Vec3A::new(s * phi.cos(), s * phi.sin(), mu)
    }

    /// ∫ f·cos dω and ∫ pdf dω over the sphere, by the midpoint rule in (μ, φ)
    /// (dω = dμ dφ), on a grid fine enough for α ≥ 0.1.
    fn quadrature(l: &Lobe) -> (Vec3A, f64) {
        let (nm, np) = (1200, 600);
        let dw = (2.0 / nm as f64) * (2.0 * std::f64::consts::PI / np as f64);
        let (mut albedo, mut mass) = (glam::DVec3::ZERO, 0.0);
        for i in 0..nm {
            for j in 0..np {
                let mu = -1.0 + 2.0 * (i as f32 + 0.5) / nm as f32;
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
    fn the_sampled_albedo_through_the_surface_is_the_integral_of_the_bsdf() {
        // The same over the sphere for transmitting materials: a thin wall, a volume entered
        // and one left (η 1.5, where total internal reflection turns some light back), each
        // within 1 % + 0.002; and the density integrates to at most 1 (less where total
        // internal reflection refuses a normal, or a drawn direction leaves its side).
        for eta in [0.0, 1.0 / 1.5, 1.5] {
            for roughness in [0.4, 0.7, 1.0] {
                for cos_theta in [0.2, 0.6, 0.95] {
                    let l = lobe_from(&transmitting(roughness, eta), cos_theta, eta < 1.0);
                    assert_eq!(l.eta, eta);
                    let (exact, mass) = quadrature(&l);
                    let drawn = sampled(&l, 200_000);
                    assert!(
                        mass <= 1.0 + 2e-3,
                        "eta {eta} roughness {roughness}: {mass}"
                    );
                    for c in 0..3 {
                        assert!(
                            (drawn[c] - exact[c]).abs() <= 0.01 * exact[c] + 0.002,
                            "eta {eta} roughness {roughness} cos {cos_theta}: channel {c} \
                             drawn {} integrated {}",
                            drawn[c],
                            exact[c]
                        );
                    }
                }
            }
        }
    }

    #[test]
    fn the_sampled_albedo_under_a_coat_is_the_integral_of_the_bsdf() {
        // The same under a clear coat of factor 1 (its lobe, its weight, its share of draws).
        for (metallic, roughness, coat_roughness, _) in crate::stability::chi2::PBR_COAT_CASES {
            for cos_theta in [0.2, 0.6, 0.95] {
                let l = lobe_at(&coated(metallic, roughness, coat_roughness), cos_theta);
                let (exact, mass) = quadrature(&l);
                let drawn = sampled(&l, 200_000);
                assert!(mass <= 1.0 + 2e-3, "{mass}");
                for c in 0..3 {
                    assert!(
                        (drawn[c] - exact[c]).abs() <= 0.01 * exact[c] + 0.002,
                        "metallic {metallic} roughness {roughness} coat {coat_roughness} \
                         cos {cos_theta}: channel {c} drawn {} integrated {}",
                        drawn[c],
                        exact[c]
                    );
                }
            }
        }
        // A coat adds its Fresnel share and takes it from what lies under it: over a black
        // base without a specular layer, a polished coat returns exactly Fc(n·v) per draw
        // that takes it (weight 1) and nothing otherwise.
        let black = Material {
            color: Vec3A::ZERO,
            specular: 0.0,
            clearcoat: 1.0,
            ..material(0.0, 0.0, 0.5)
        };
        let l = lobe_at(&black, 1.0);
        assert!((l.coat - 0.04).abs() < 1e-7, "{}", l.coat);
        // Each draw weighs 1 (the coat) or 0 (the black base): 4 % of 10⁴ draws take the
        // coat, within five standard deviations (0.0098).
        let mut ones = 0;
        for i in 0..10_000 {
            let s = sample(&l, &mut Rng::new(0, i, 0));
            assert!(s.weight == Vec3A::ONE || s.weight == Vec3A::ZERO, "{s:?}");
            ones += (s.weight == Vec3A::ONE) as u32;
        }
        assert!((ones as f32 / 1e4 - 0.04).abs() < 0.0098, "{ones}");
    }

    #[test]
    fn smooth_white_glass_returns_what_it_receives() {
        // A white, smooth, fully transmitting dielectric: each draw's weight is F / p_spec or
        // (1 − F) / p_trans, both 1 (to rounding), on a thin wall and on either side of a
        // volume's boundary, total internal reflection included. At ior 1 nothing reflects:
        // the ray passes on, unbent.
        for (eta, front) in [(0.0, true), (1.0 / 1.5, true), (1.5, false)] {
            for cos_theta in [0.05, 0.3, 0.7, 1.0] {
                let m = Material {
                    color: Vec3A::ONE,
                    transmission: 1.0,
                    thin: eta == 0.0,
                    ..material(1.0, 0.0, 0.0)
                };
                let l = lobe_from(&m, cos_theta, front);
                for i in 0..200 {
                    let s = sample(&l, &mut Rng::new(1, i, 2));
                    assert!(s.ok, "{s:?}");
                    assert!((s.weight - Vec3A::ONE).abs().max_element() < 1e-5, "{s:?}");
                    assert_eq!(s.through, s.dir.z < 0.0);
                }
            }
        }
        let clear = Material {
            color: Vec3A::ONE,
            transmission: 1.0,
            thin: true,
            ior: 1.0,
            ..material(1.0, 0.0, 0.0)
        };
        let l = lobe_at(&clear, 0.6);
        let s = sample(&l, &mut Rng::new(1, 0, 2));
        assert_eq!((s.dir, s.weight, s.through), (-l.wo, Vec3A::ONE, true));
    }

    #[test]
    fn rough_white_glass_never_gains_weight() {
        // A white, rough, fully transmitting dielectric: each draw, reflected or refracted,
        // carries at most 1 (G2/G1 of its facet), on either side of a volume's boundary and on
        // a thin wall, at grazing angles where the macroscopic normal reflects totally
        // included. Drawn by the macroscopic normal's Fresnel, a facet reflecting totally
        // inside was weighed 1 / 0.8 (a path caught in a ball gained 1.25 a bounce).
        for (eta, front) in [(0.0, true), (1.0 / 1.5, true), (1.5, false)] {
            for roughness in [0.1, 0.35, 0.7] {
                for cos_theta in [0.05, 0.3, 0.7, 1.0] {
                    let m = Material {
                        color: Vec3A::ONE,
                        transmission: 1.0,
                        thin: eta == 0.0,
                        ..material(1.0, 0.0, roughness)
                    };
                    let l = lobe_from(&m, cos_theta, front);
                    let (mut most, mut sum) = (0.0f32, 0.0f64);
                    for i in 0..4000 {
                        let s = sample(&l, &mut Rng::new(3, i, 1));
                        most = most.max(s.weight.max_element());
                        sum += s.weight.y as f64;
                    }
                    assert!(
                        most <= 1.0 + 1e-4,
                        "eta {eta} roughness {roughness} cos {cos_theta}: a draw weighs {most}"
                    );
                    // What the draws carry on average is what the surface passes on, less
                    // the single-scattering model's loss (rough and grazing: most of it).
                    assert!(sum / 4000.0 > 0.5, "{eta} {roughness} {cos_theta}: {sum}");
                }
            }
        }
    }

    /// Pearson's chi-square (`stability::chi2`) of 400 000 draws from `l` against the density
    /// the sampler reports; passes at 1e-3 / `cases`.
    fn assert_draws_match(l: &Lobe, cases: usize, what: &str) {
        use crate::stability::chi2::PBR_DRAWS;
        let draws = (0..PBR_DRAWS).map(|i| {
            let s = sample(l, &mut Rng::new(5, i, 3));
            s.ok.then(|| s.dir.to_array())
        });
        let r = crate::stability::chi2::test(draws, |d| eval(l, Vec3A::from(d)).1 as f64);
        assert!(r.p > 1e-3 / cases as f64, "{what}: {r:?}");
    }

    #[test]
    fn the_sampler_draws_from_the_density_it_reports() {
        use crate::stability::chi2::PBR_CASES;
        // Each case must pass at 1e-3 / cases. tests/pbr.rs runs the same cases, and those of
        // the two tests below, on the WGSL sampler.
        for (metallic, roughness, cos_theta) in PBR_CASES {
            let l = lobe_at(&material(0.8, metallic, roughness), cos_theta);
            let what = format!("metallic {metallic} roughness {roughness} cos {cos_theta}");
            assert_draws_match(&l, PBR_CASES.len(), &what);
        }
    }

    #[test]
    fn the_transmission_sampler_draws_from_the_density_it_reports() {
        use crate::stability::chi2::PBR_THROUGH_CASES;
        // Over the sphere, on transmitting lobes.
        for (roughness, cos_theta, eta) in PBR_THROUGH_CASES {
            let l = lobe_from(&transmitting(roughness, eta), cos_theta, eta < 1.0);
            let what = format!("roughness {roughness} cos {cos_theta} eta {eta}");
            assert_draws_match(&l, PBR_THROUGH_CASES.len(), &what);
        }
    }

    #[test]
    fn the_coat_sampler_draws_from_the_density_it_reports() {
        use crate::stability::chi2::PBR_COAT_CASES;
        for (metallic, roughness, coat_roughness, cos_theta) in PBR_COAT_CASES {
            let l = lobe_at(&coated(metallic, roughness, coat_roughness), cos_theta);
            let what = format!("metallic {metallic} roughness {roughness} coat {coat_roughness}");
            assert_draws_match(&l, PBR_COAT_CASES.len(), &what);
        }
    }

    #[test]
    fn refraction_is_reciprocal_up_to_the_squared_index() {
        // Walter's BTDF without radiance's 1/η² (left out, as in the lecture's glass) is
        // reciprocal up to the squared index: from inside out it is 1/η² of its value from
        // outside in. Pairs refracted through tilted microfacets, so that both values are not 0.
        let (rough, ior) = (0.5, 1.5);
        let m = transmitting(rough, 1.0 / ior);
        for (a, tilt) in [(0.3, 0.2), (0.9, -0.4), (0.6, 0.05)] {
            let wo = dir(a, 0.3);
            let h = (Vec3A::Z + Vec3A::new(tilt, 0.5 * tilt, 0.0)).normalize();
            let wi = refract(-wo, h, wo.dot(h), 1.0 / ior).unwrap();
            let f1 = eval(&lobe(&m, wo, Vec3A::Z, true), wi).0 / -wi.z;
            let f2 = eval(&lobe(&m, wi, -Vec3A::Z, false), wo).0 / wo.z;
            let want = f1 / (ior * ior);
            assert!(
                f1.max_element() > 0.0
                    && (f2 - want).abs().max_element() <= 1e-4 * want.max_element(),
                "{f1} {f2}, ratio {}",
                f2 / f1
            );
        }
    }

    #[test]
    fn the_brdf_is_reciprocal() {
        let m = material(0.7, 0.4, 0.5);
        for (a, b) in [(0.3, 0.8), (0.9, 0.2), (0.5, 0.55)] {
            let (wo, wi) = (dir(a, 0.3), dir(b, 2.1));
            let f1 = eval(&lobe(&m, wo, Vec3A::Z, true), wi).0 / wi.z;
            let f2 = eval(&lobe(&m, wi, Vec3A::Z, true), wo).0 / wo.z;
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
