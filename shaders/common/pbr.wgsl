// #include "common/types.wgsl"
// #include "common/rng.wgsl"
// #include "common/sampling.wgsl"
// Twin: src/cpu/pbr.rs (tests/twins.rs keeps their functions paired).

// A pbr material with KHR_materials_specular in the scene: without one the lobes carry a grey
// f0 and a layer of weight 1, which the compiler folds (the extension's colour cost 6.6 % of
// the H200's samples/s on the shipped pbr scene, which does not use it).
override HAS_PBR_SPECULAR: bool = true;
// A pbr material that transmits (KHR_materials_transmission, with KHR_materials_volume's
// refracting boundary) in the scene: without one the transmission lobe is left out.
override HAS_PBR_TRANSMISSION: bool = true;
// A pbr material with a clear coat (KHR_materials_clearcoat) in the scene.
override HAS_PBR_CLEARCOAT: bool = true;
// glTF 2.0's metallic-roughness BRDF as the specification's Appendix B writes it: a
// Lambertian base under a dielectric Fresnel layer (Schlick, f0 from the ior: 0.04 at 1.5),
// mixed by metallic with a metal whose f0 is the base colour; the specular lobe is
// Trowbridge-Reitz (GGX) with α = roughness² and the height-correlated Smith visibility
// (Heitz 2014). Sampled by the distribution of visible normals (Heitz, "Sampling the GGX
// Distribution of Visible Normals", JCGT 7(4), 2018) mixed with the cosine lobe, with a
// density light sampling's MIS evaluates. Below PBR_ALPHA_MIN the specular lobe is a mirror.
// KHR_materials_transmission splits the dielectric base between the Lambertian lobe and a
// rough dielectric's transmission (Walter et al., "Microfacet Models for Refraction through
// Rough Surfaces", EGSR 2007), sampled by visible normals too. KHR_materials_clearcoat lays a
// GGX coat of ior 1.5 over it all.

// The smallest α the microfacet lobe keeps; below it the lobe is a perfect mirror (a delta,
// which light sampling cannot find): roughness 0 is a mirror, continuously.
const PBR_ALPHA_MIN: f32 = 1e-4;
// The least share of the base a rough transmission lobe is drawn by, however much the
// macroscopic Fresnel reflects.
const PBR_TRANSMISSION_FLOOR: f32 = 0.25;
// The clear coat's reflectance at normal incidence: ior 1.5, as the extension fixes it.
const PBR_COAT_F0: f32 = 0.04;
const PBR_LUMINANCE: vec3f = vec3f(0.2126, 0.7152, 0.0722);

// A pbr material at a hit, seen from `wo` (unit, towards the viewer) over the shading
// normal `n` (on the side of wo).
struct PbrLobe {
    base: vec3f,
    metallic: f32,
    n: vec3f,
    alpha: f32,
    wo: vec3f,
    // KHR_materials_specular's specularFactor: the dielectric layer's strength (1 without it).
    weight: f32,
    // The dielectric's reflectance at normal incidence, ((ior − 1)/(ior + 1))² times the
    // extension's specularColorFactor (white without it), at most 1.
    f0: vec3f,
    // The probability of sampling the specular lobe (else the transmission or cosine lobe).
    p_spec: f32,
    // KHR_materials_transmission's share of the dielectric base (0: opaque).
    transmission: f32,
    // The probability of sampling the transmission lobe.
    p_trans: f32,
    // The index ratio η_wo / η_wi across a refracting (volume) boundary; 0 for a thin wall,
    // which transmits without bending (the specification's default).
    eta: f32,
    // KHR_materials_clearcoat's mix weight, clearcoat · Fc(n·v) with Fc Schlick's of f0 0.04;
    // also the probability of sampling the coat (0: no coat).
    coat: f32,
    coat_alpha: f32,
}

// A direction drawn from the lobe: f·cos/pdf as the throughput's factor, and the density
// (0 for the mirror, which MIS cannot weigh); `through`: drawn by the transmission lobe,
// below the surface.
struct PbrSample {
    dir: vec3f,
    weight: vec3f,
    pdf: f32,
    ok: bool,
    through: bool,
}

fn pbr_pow5(x: f32) -> f32 {
    let x2 = x * x;
    return x2 * x2 * x;
}

// Schlick's Fresnel of reflectance `f0` at the angle whose (1 − cos)⁵ is `x5` (cos of V·H,
// or of n·v for the mirror): the metal's (f0 its base colour) and the dielectric's, one x5 for
// both.
fn pbr_fresnel(f0: vec3f, x5: f32) -> vec3f {
    return f0 + (1.0 - f0) * x5;
}

fn pbr_schlick_x5(cos: f32) -> f32 {
    return pbr_pow5(1.0 - clamp(cos, 0.0, 1.0));
}

// (1 − cos)⁵ for the dielectric's Fresnel at a microfacet that wo meets at `cos`: from inside
// a refracting material (η > 1) Schlick's approximation takes the angle outside, and total
// internal reflection reflects everything.
fn pbr_dielectric_x5(cos: f32, eta: f32) -> f32 {
    if eta <= 1.0 {
        return pbr_schlick_x5(cos);
    }
    let cos_t2 = 1.0 - eta * eta * (1.0 - cos * cos);
    if cos_t2 <= 0.0 {
        return 1.0;
    }
    return pbr_schlick_x5(sqrt(cos_t2));
}

fn pbr_max3(v: vec3f) -> f32 {
    return max(v.x, max(v.y, v.z));
}

// The material at a hit as a lobe. KHR_materials_specular's fresnel_mix weighs the base by
// 1 − specular·max(F) and the specular layer by specular·F (F of the coloured f0); without
// the extension (specular 1, white) that is Appendix B's mix by F. KHR_materials_transmission
// gives `transmission` of the base to the transmission lobe. `front`: wo is on the outer side
// of the geometric surface.
fn pbr_lobe(m: Material, wo: vec3f, n: vec3f, front: bool) -> PbrLobe {
    let r = (m.ior - 1.0) / (m.ior + 1.0);
    var f0 = vec3f(r * r);
    var weight = 1.0;
    if HAS_PBR_SPECULAR {
        f0 = min(f0 * m.specular_color, vec3f(1.0));
        weight = m.specular;
    }
    var transmission = 0.0;
    var eta = 0.0;
    if HAS_PBR_TRANSMISSION {
        transmission = m.transmission;
        if transmission > 0.0 && m.thin == 0u {
            eta = select(m.ior, 1.0 / m.ior, front);
        }
    }
    let fd = weight * pbr_max3(pbr_fresnel(f0, pbr_dielectric_x5(dot(n, wo), eta)));
    // Each lobe in proportion to what it reflects towards wo, roughly.
    let spec_w = m.metallic + (1.0 - m.metallic) * fd;
    let rest = (1.0 - m.metallic) * (1.0 - fd);
    let diff_w = rest * (1.0 - transmission) * dot(m.color, PBR_LUMINANCE);
    // A rough boundary transmits where the macroscopic normal reflects totally (fd = 1): its
    // lobe keeps a share there, so that the facets that transmit are drawn (pbr_splits:
    // within the boundary's share, each facet's own Fresnel chooses).
    var rest_t = rest;
    if m.roughness * m.roughness >= PBR_ALPHA_MIN {
        rest_t = (1.0 - m.metallic) * max(1.0 - fd, PBR_TRANSMISSION_FLOOR);
    }
    let trans_w = rest_t * transmission * dot(m.color, PBR_LUMINANCE);
    let total = spec_w + diff_w + trans_w;
    let p_spec = select(1.0, spec_w / total, total > 0.0);
    let p_trans = select(0.0, trans_w / total, total > 0.0);
    let alpha = m.roughness * m.roughness;
    // KHR_materials_clearcoat's fresnel_coat: the coat's Fresnel at n·v (ior 1.5).
    var coat = 0.0;
    var coat_alpha = 0.0;
    if HAS_PBR_CLEARCOAT && m.clearcoat > 0.0 {
        coat = m.clearcoat * (PBR_COAT_F0 + (1.0 - PBR_COAT_F0) * pbr_schlick_x5(dot(n, wo)));
        coat_alpha = m.clearcoat_roughness * m.clearcoat_roughness;
    }
    return PbrLobe(m.color, m.metallic, n, alpha, wo, weight, f0, p_spec, transmission, p_trans, eta, coat, coat_alpha);
}

// Trowbridge-Reitz (GGX) normal distribution, from cos and sin² of the half vector's angle:
// its denominator written as sin² + cos²·α² rather than cos²(α² − 1) + 1, which cancels to 0
// in f32 for α below about 2.4e-4 (1 − α² rounds to 1) and made D infinite.
fn pbr_d(n_dot_h: f32, sin2_h: f32, alpha: f32) -> f32 {
    let a2 = alpha * alpha;
    let k = sin2_h + n_dot_h * n_dot_h * a2;
    return a2 / (PI * k * k);
}

// The height-correlated Smith visibility V = G2 / (4 |n·l| |n·v|) (glTF's V_GGX).
fn pbr_v(n_dot_l: f32, n_dot_v: f32, alpha: f32) -> f32 {
    let a2 = alpha * alpha;
    let gv = n_dot_l * sqrt(n_dot_v * n_dot_v * (1.0 - a2) + a2);
    let gl = n_dot_v * sqrt(n_dot_l * n_dot_l * (1.0 - a2) + a2);
    return 0.5 / (gv + gl);
}

// Smith's masking of one direction, G1 = 2 cos / (cos + sqrt(α² + (1 − α²) cos²)).
fn pbr_g1(n_dot_v: f32, alpha: f32) -> f32 {
    let a2 = alpha * alpha;
    return 2.0 * n_dot_v / (n_dot_v + sqrt(a2 + (1.0 - a2) * n_dot_v * n_dot_v));
}

// The BSDF times the cosine towards `wi`, and the density with which pbr_sample draws wi
// (its part that can be evaluated: the deltas of the mirror and of smooth transmission are
// left out of both).
fn pbr_eval(l: PbrLobe, wi: vec3f) -> vec4f {
    let e = pbr_eval_base(l, wi);
    if !HAS_PBR_CLEARCOAT || l.coat <= 0.0 {
        return e;
    }
    // KHR_materials_clearcoat's fresnel_coat: the material weighed by 1 − coat, plus the
    // coat's GGX lobe (no F: the weight holds it) times coat; the coat is drawn with
    // probability coat, so the material's density is scaled alike.
    var r = e * (1.0 - l.coat);
    let nl = dot(l.n, wi);
    let nv = dot(l.n, l.wo);
    if nl > 0.0 && nv > 0.0 && l.coat_alpha >= PBR_ALPHA_MIN {
        let h = normalize(l.wo + wi);
        let nh = clamp(dot(l.n, h), 0.0, 1.0);
        let nxh = cross(l.n, h);
        let d = pbr_d(nh, dot(nxh, nxh), l.coat_alpha);
        r += vec4f(vec3f(l.coat * d * pbr_v(nl, nv, l.coat_alpha) * nl), l.coat * d * pbr_g1(nv, l.coat_alpha) / (4.0 * nv));
    }
    return r;
}

// The material without its coat: f·cos and the density of its lobes.
fn pbr_eval_base(l: PbrLobe, wi: vec3f) -> vec4f {
    let nl = dot(l.n, wi);
    let nv = dot(l.n, l.wo);
    if nv <= 0.0 {
        return vec4f(0.0);
    }
    if nl <= 0.0 {
        if HAS_PBR_TRANSMISSION && l.transmission > 0.0 && nl < 0.0 {
            return pbr_eval_through(l, wi, -nl, nv);
        }
        return vec4f(0.0);
    }
    let h = normalize(l.wo + wi);
    let c = dot(l.wo, h);
    let x5 = pbr_schlick_x5(c);
    var xd = x5;
    if HAS_PBR_TRANSMISSION && l.eta > 1.0 {
        xd = pbr_dielectric_x5(c, l.eta);
    }
    let fd = pbr_fresnel(l.f0, xd);
    let fm = pbr_fresnel(l.base, x5);
    var f = (1.0 - l.metallic) * (1.0 - l.weight * pbr_max3(fd)) * (1.0 - l.transmission) * l.base / PI;
    var pdf = (1.0 - l.p_spec - l.p_trans) * nl / PI;
    if l.alpha >= PBR_ALPHA_MIN {
        let nh = clamp(dot(l.n, h), 0.0, 1.0);
        let nxh = cross(l.n, h);
        let d = pbr_d(nh, dot(nxh, nxh), l.alpha);
        f += ((1.0 - l.metallic) * l.weight * fd + l.metallic * fm) * (d * pbr_v(nl, nv, l.alpha));
        let p = pbr_lobe_shares(l, l.weight * pbr_max3(fd)).x;
        pdf += p * d * pbr_g1(nv, l.alpha) / (4.0 * nv);
    }
    return vec4f(f * nl, pdf);
}

// The transmission lobe towards `wi` below the surface (|n·wi| = nl): f·cos and its density.
// A thin wall's is the specular lobe mirrored through the surface (KHR_materials_transmission,
// "thin-walled"); a volume's boundary refracts, by Walter et al. 2007, eq. 16 and 21, with
// PBRT 4th ed. §9.7's density. The base colour tints it; radiance's 1/η² across the boundary
// is left out, as the lecture's glass leaves it out (it cancels on a closed object).
fn pbr_eval_through(l: PbrLobe, wi: vec3f, nl: f32, nv: f32) -> vec4f {
    if l.alpha < PBR_ALPHA_MIN {
        return vec4f(0.0);
    }
    let tint = (1.0 - l.metallic) * l.transmission * l.base;
    if l.eta == 0.0 {
        let h = normalize(l.wo + wi + 2.0 * nl * l.n);
        let fd = pbr_fresnel(l.f0, pbr_schlick_x5(dot(l.wo, h)));
        let nh = clamp(dot(l.n, h), 0.0, 1.0);
        let nxh = cross(l.n, h);
        let d = pbr_d(nh, dot(nxh, nxh), l.alpha);
        let f = tint * (1.0 - l.weight * pbr_max3(fd)) * (d * pbr_v(nl, nv, l.alpha));
        let p = pbr_lobe_shares(l, l.weight * pbr_max3(fd)).y;
        return vec4f(f * nl, p * d * pbr_g1(nv, l.alpha) / (4.0 * nv));
    }
    var h = normalize_or(l.eta * l.wo + wi, l.n);
    if dot(h, l.n) < 0.0 {
        h = -h;
    }
    let oh = dot(l.wo, h);
    let ih = dot(wi, h);
    if oh <= 0.0 || ih >= 0.0 {
        return vec4f(0.0);
    }
    let denom = (ih + l.eta * oh) * (ih + l.eta * oh);
    let fd = pbr_fresnel(l.f0, pbr_dielectric_x5(oh, l.eta));
    let nh = clamp(dot(l.n, h), 0.0, 1.0);
    let nxh = cross(l.n, h);
    let d = pbr_d(nh, dot(nxh, nxh), l.alpha);
    let jacobian = -ih * oh / denom;
    let f = tint * (1.0 - l.weight * pbr_max3(fd)) * (4.0 * nl * pbr_v(nl, nv, l.alpha) * d * jacobian);
    let p = pbr_lobe_shares(l, l.weight * pbr_max3(fd)).y;
    return vec4f(f, p * pbr_g1(nv, l.alpha) / nv * d * jacobian);
}

// A visible normal of the GGX distribution seen from `wo` (local frame, z the normal):
// Heitz 2018, listing 1.
fn pbr_visible_normal(wo: vec3f, alpha: f32, u: vec2f) -> vec3f {
    let vh = normalize(vec3f(alpha * wo.x, alpha * wo.y, wo.z));
    let len2 = vh.x * vh.x + vh.y * vh.y;
    var t1 = vec3f(1.0, 0.0, 0.0);
    if len2 > 0.0 {
        t1 = vec3f(-vh.y, vh.x, 0.0) * inverseSqrt(len2);
    }
    let t2 = cross(vh, t1);
    let r = sqrt(u.x);
    let phi = 2.0 * PI * u.y;
    let p1 = r * cos(phi);
    let s = 0.5 * (1.0 + vh.z);
    let p2 = (1.0 - s) * sqrt(max(0.0, 1.0 - p1 * p1)) + s * r * sin(phi);
    let nh = p1 * t1 + p2 * t2 + sqrt(max(0.0, 1.0 - p1 * p1 - p2 * p2)) * vh;
    return normalize(vec3f(alpha * nh.x, alpha * nh.y, max(0.0, nh.z)));
}

// Draws a direction: the specular lobe with probability p_spec (a visible normal, or the
// mirror direction below PBR_ALPHA_MIN), the transmission lobe with probability p_trans (the
// visible normal refracted, or mirrored through a thin wall), else the cosine lobe; a rough
// boundary that transmits draws the two together, a facet's Fresnel choosing
// (pbr_sample_facet). Three draws either way.
fn pbr_sample(l: PbrLobe, state: ptr<function, Rng>) -> PbrSample {
    var pick = rand(state);
    let u = rand2(state);
    let nv = dot(l.n, l.wo);
    if nv <= 0.0 {
        return PbrSample(l.n, vec3f(0.0), 0.0, false, false);
    }
    // The coat with probability coat; the material's lobes share the rest of the draw.
    if HAS_PBR_CLEARCOAT && l.coat > 0.0 {
        if pick < l.coat {
            return pbr_sample_coat(l, nv, u);
        }
        pick = (pick - l.coat) / (1.0 - l.coat);
    }
    if pbr_splits(l) && pick < l.p_spec + l.p_trans {
        return pbr_sample_facet(l, nv, pick / (l.p_spec + l.p_trans), u);
    }
    let through = HAS_PBR_TRANSMISSION && l.p_trans > 0.0 && pick >= l.p_spec && pick < l.p_spec + l.p_trans;
    var wi: vec3f;
    if pick < l.p_spec || through {
        if l.alpha < PBR_ALPHA_MIN {
            return pbr_mirror(l, nv, through);
        }
        // A rough lobe that transmits is drawn by pbr_sample_facet: this one reflects.
        wi = reflect(-l.wo, pbr_half_vector(l, nv, l.alpha, u));
    } else {
        let z = 1.0 - 2.0 * u.x;
        let phi = 2.0 * PI * u.y;
        let r = sqrt(max(0.0, 1.0 - z * z));
        wi = normalize_or(l.n + vec3f(r * cos(phi), r * sin(phi), z), l.n);
    }
    return pbr_drawn(l, wi, through);
}

// Whether the lobe draws reflection or transmission by the Fresnel of the microfacet it draws
// (pbr_sample_facet): a rough boundary that transmits (src/cpu/pbr.rs: splits).
fn pbr_splits(l: PbrLobe) -> bool {
    return HAS_PBR_TRANSMISSION && l.p_trans > 0.0 && l.alpha >= PBR_ALPHA_MIN;
}

// At a microfacet whose dielectric Fresnel is `fd` (specular · max F), the shares of the draw
// that reflect (x) and that transmit (y): each lobe's weight there, the metal's Fresnel taken
// as 1, as pbr_lobe's split does at the macroscopic normal.
fn pbr_facet_shares(l: PbrLobe, fd: f32) -> vec2f {
    let r = l.metallic + (1.0 - l.metallic) * fd;
    let t = (1.0 - l.metallic) * (1.0 - fd) * l.transmission * dot(l.base, PBR_LUMINANCE);
    let s = r + t;
    if s > 0.0 {
        return vec2f(r / s, t / s);
    }
    return vec2f(1.0, 0.0);
}

// The probabilities of the specular (x) and the transmission (y) lobe at a microfacet of
// Fresnel `fd`: their shares of the rough boundary's draw (pbr_splits), else p_spec and
// p_trans.
fn pbr_lobe_shares(l: PbrLobe, fd: f32) -> vec2f {
    if pbr_splits(l) {
        return (l.p_spec + l.p_trans) * pbr_facet_shares(l, fd);
    }
    return vec2f(l.p_spec, l.p_trans);
}

// A rough boundary's draw (pbr_splits): a visible normal, then reflection or transmission by
// its own Fresnel (Walter et al. 2007, §5.3; PBRT 4th ed. §9.7.5); `pick` is uniform in
// [0, 1). Each draw carries about G2/G1 (src/cpu/pbr.rs: sample_facet says why).
fn pbr_sample_facet(l: PbrLobe, nv: f32, pick: f32, u: vec2f) -> PbrSample {
    let h = pbr_half_vector(l, nv, l.alpha, u);
    let c = dot(l.wo, h);
    let fd = l.weight * pbr_max3(pbr_fresnel(l.f0, pbr_dielectric_x5(c, l.eta)));
    let through = pick >= pbr_facet_shares(l, fd).x;
    var wi = reflect(-l.wo, h);
    if through {
        if l.eta == 0.0 {
            wi = wi - 2.0 * dot(wi, l.n) * l.n;
        } else {
            let t = pbr_refract(-l.wo, h, c, l.eta);
            if t.w == 0.0 {
                return PbrSample(h, vec3f(0.0), 0.0, false, false);
            }
            wi = t.xyz;
        }
    }
    return pbr_drawn(l, wi, through);
}

// A visible normal of GGX of width `alpha` seen from wo, in world space.
fn pbr_half_vector(l: PbrLobe, nv: f32, alpha: f32, u: vec2f) -> vec3f {
    let b = basis(l.n);
    let wo_local = vec3f(dot(b[0], l.wo), dot(b[1], l.wo), nv);
    return b * pbr_visible_normal(wo_local, alpha, u);
}

// Drawn direction `wi` as a sample: its weight f·cos/pdf and density from pbr_eval, or refused
// where it lies on the wrong side of the surface for its lobe (`through`) or has no density.
fn pbr_drawn(l: PbrLobe, wi: vec3f, through: bool) -> PbrSample {
    if through != (dot(wi, l.n) < 0.0) {
        return PbrSample(wi, vec3f(0.0), 0.0, false, false);
    }
    let e = pbr_eval(l, wi);
    if e.w <= 0.0 {
        return PbrSample(wi, vec3f(0.0), 0.0, false, false);
    }
    return PbrSample(wi, e.xyz / e.w, e.w, true, through);
}

// A direction from the clear coat's GGX lobe, or its mirror below PBR_ALPHA_MIN (weight 1: the
// coat's Fresnel over the probability of drawing it).
fn pbr_sample_coat(l: PbrLobe, nv: f32, u: vec2f) -> PbrSample {
    if l.coat_alpha < PBR_ALPHA_MIN {
        return PbrSample(reflect(-l.wo, l.n), vec3f(1.0), 0.0, true, false);
    }
    return pbr_drawn(l, reflect(-l.wo, pbr_half_vector(l, nv, l.coat_alpha, u)), false);
}

// The smooth lobes' deltas (α below PBR_ALPHA_MIN): the mirror, or straight through a thin
// wall, or refracted by a volume's boundary; each its Fresnel weight over its probability.
fn pbr_mirror(l: PbrLobe, nv: f32, through: bool) -> PbrSample {
    if !through {
        return PbrSample(reflect(-l.wo, l.n), pbr_mirror_reflectance(l, nv) / l.p_spec, 0.0, true, false);
    }
    var dir = vec4f(-l.wo, 1.0);
    if l.eta != 0.0 {
        dir = pbr_refract(-l.wo, l.n, nv, l.eta);
    }
    return PbrSample(select(l.n, dir.xyz, dir.w != 0.0), pbr_transmittance(l, nv) / l.p_trans, 0.0, dir.w != 0.0, true);
}

// What the smooth lobe (alpha below PBR_ALPHA_MIN) passes of the light that meets it at nv,
// the weight of its transmitted delta times its probability (src/cpu/pbr.rs: transmittance).
fn pbr_transmittance(l: PbrLobe, nv: f32) -> vec3f {
    let fd = pbr_fresnel(l.f0, pbr_dielectric_x5(nv, l.eta));
    return (1.0 - l.metallic) * l.transmission * (1.0 - l.weight * pbr_max3(fd)) * l.base;
}

// What a smooth transmitting ball of material m passes along a path through it that enters
// at cos i, reflects `inner` times (0 or 1) inside and leaves at cos r' inside: the
// expectation of pbr_sample's weights along the path (src/cpu/pbr.rs: lens_transmittance).
fn pbr_lens_transmittance(m: Material, cos_i: f32, cos_r: f32, inner: u32) -> vec3f {
    // Only the material and the side enter what these read, not the directions.
    let z = vec3f(0.0, 0.0, 1.0);
    let outside = pbr_lobe(m, z, z, true);
    let inside = pbr_lobe(m, z, z, false);
    let through = pbr_transmittance(outside, cos_i) * pbr_transmittance(inside, cos_r);
    if inner == 0u {
        return through;
    }
    return through * pbr_mirror_reflectance(inside, cos_r);
}

// What the mirror of a smooth lobe (alpha below PBR_ALPHA_MIN) reflects of the light that
// meets it at nv: the mirror's weight times its probability (src/cpu/pbr.rs:
// mirror_reflectance). Light sampling through a mirror sphere tints the map's light by it.
fn pbr_mirror_reflectance(l: PbrLobe, nv: f32) -> vec3f {
    let fd = pbr_fresnel(l.f0, pbr_dielectric_x5(nv, l.eta));
    let fm = pbr_fresnel(l.base, pbr_schlick_x5(nv));
    return (1.0 - l.metallic) * l.weight * fd + l.metallic * fm;
}

// `d` refracted through a surface of normal `n` (on the side d comes from, cos = −d·n) with
// index ratio `eta`; w = 0 at total internal reflection.
fn pbr_refract(d: vec3f, n: vec3f, cos: f32, eta: f32) -> vec4f {
    let sin2_t = eta * eta * (1.0 - cos * cos);
    if sin2_t >= 1.0 {
        return vec4f(0.0);
    }
    return vec4f(normalize(eta * d + (eta * cos - sqrt(1.0 - sin2_t)) * n), 1.0);
}
