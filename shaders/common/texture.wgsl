// #include "common/types.wgsl"
// #include "common/rng.wgsl"
// #include "common/sampling.wgsl"
// #include "common/intersect.wgsl"
// Twin: src/cpu/texture.rs (tests/twins.rs keeps their functions paired).
// Textures (src/common/textures.rs lays out the words, src/cpu/texture.rs reads them the same
// way): glTF's base colour, metallic-roughness and emissive maps, sampled bilinearly with
// their wrap modes, mapped onto the model's material at each hit; tangent-space normal maps;
// alpha cut-outs; and the files' normals for smooth shading. Every function here is called
// only under HAS_TEXTURES, HAS_CUTOUTS, HAS_NORMAL_MAPS or HAS_SMOOTH_NORMALS.

// The texture words (one word when the scene has none); the trace pass binds them.
@group(0) @binding(14) var<storage, read> tex: array<u32>;

const TEX_SRGB_LUT: u32 = 0u;
const TEX_UV_BASE: u32 = 256u;
const TEX_FRAMES: u32 = 257u;
const TEX_FRAME_WORDS: u32 = 21u;
const TEX_MATERIALS: u32 = 258u;
const TEX_NONE: u32 = 0xffffffffu;
const TEX_FLAG_BASE: u32 = 1u;
const TEX_FLAG_MR: u32 = 2u;
const TEX_FLAG_EMISSIVE: u32 = 4u;
const TEX_FLAG_NORMAL: u32 = 8u;
const TEX_FLAG_TRANSMISSION: u32 = 16u;
const TEX_FLAG_CLEARCOAT: u32 = 32u;
const TEX_FLAG_CLEARCOAT_ROUGHNESS: u32 = 64u;
const TEX_FLAG_SPECULAR: u32 = 128u;
const TEX_FLAG_SPECULAR_COLOR: u32 = 1024u;
// The record word of the first extension map's header, and its transform's index.
const TEX_EXTENSION_MAPS: u32 = 70u;
const TEX_EXTENSION_TRANSFORMS: u32 = 4u;
// Record word of the normal map's texture header (its scale follows).
const TEX_NORMAL_MAP: u32 = 14u;
// How a texel's 8-bit values are read: as [0, 1], sRGB-decoded colour, or signed with 128 as
// zero (max((b − 128) / 127, −1), as GPUs read signed-normalised bytes), for normal maps.
const TEX_UNORM: u32 = 0u;
const TEX_SRGB: u32 = 1u;
const TEX_SNORM: u32 = 2u;
// The least tangent-space z a normal map's normal keeps (about 89.4° from the surface's).
const TEX_NORMAL_MIN_Z: f32 = 0.01;
const TEX_ALPHA_SHIFT: u32 = 8u;
// Record word where the maps' texture transforms start (six words each: two rows of a 2×3).
const TEX_TRANSFORMS: u32 = 16u;
// Texture coordinates are clamped to this before texel arithmetic (a wrap mode maps any
// coordinate into the image; this only keeps the integer conversion in range).
const TEX_UV_LIMIT: f32 = 1048576.0;

fn tex_f32(i: u32) -> f32 {
    return bitcast<f32>(tex[i]);
}

// A texel index brought into [0, n) by a wrap mode: 0 repeat, 1 clamp, 2 mirrored repeat.
fn tex_wrap(i: i32, n: i32, mode: u32) -> i32 {
    if mode == 1u {
        return clamp(i, 0, n - 1);
    }
    if mode == 2u {
        let p = 2 * n;
        var k = i % p;
        if k < 0 {
            k += p;
        }
        return select(k, p - 1 - k, k >= n);
    }
    var k = i % n;
    if k < 0 {
        k += n;
    }
    return k;
}

// One texel of the texture whose header is at `h`, read by `mode` (TEX_UNORM, TEX_SRGB: the
// colour decoded, alpha linear; TEX_SNORM).
fn tex_texel(h: u32, x: i32, y: i32, mode: u32) -> vec4f {
    let w = i32(tex[h]);
    let xi = tex_wrap(x, w, tex[h + 2u]);
    let yi = tex_wrap(y, i32(tex[h + 1u]), tex[h + 3u]);
    let word = tex[tex[h + 4u] + u32(yi * w + xi)];
    let b = vec4u(word & 0xffu, (word >> 8u) & 0xffu, (word >> 16u) & 0xffu, word >> 24u);
    if mode == TEX_SRGB {
        return vec4f(tex_f32(TEX_SRGB_LUT + b.x), tex_f32(TEX_SRGB_LUT + b.y), tex_f32(TEX_SRGB_LUT + b.z), f32(b.w) / 255.0);
    }
    if mode == TEX_SNORM {
        return max(vec4f(vec4i(b) - vec4i(128)) / 127.0, vec4f(-1.0));
    }
    return vec4f(b) / 255.0;
}

// Bilinear filtering with texel centres at half-integers (glTF's LINEAR), in linear values.
fn tex_sample(h: u32, uv_in: vec2f, mode: u32) -> vec4f {
    let uv = clamp(uv_in, vec2f(-TEX_UV_LIMIT), vec2f(TEX_UV_LIMIT));
    let x = uv.x * f32(tex[h]) - 0.5;
    let y = uv.y * f32(tex[h + 1u]) - 0.5;
    let x0 = floor(x);
    let y0 = floor(y);
    let fx = x - x0;
    let fy = y - y0;
    let ix = i32(x0);
    let iy = i32(y0);
    let t00 = tex_texel(h, ix, iy, mode);
    let t10 = tex_texel(h, ix + 1, iy, mode);
    let t01 = tex_texel(h, ix, iy + 1, mode);
    let t11 = tex_texel(h, ix + 1, iy + 1, mode);
    let top = t00 + (t10 - t00) * fx;
    let bottom = t01 + (t11 - t01) * fx;
    return top + (bottom - top) * fy;
}

// The record of material `material`, or TEX_NONE (also for a scene without textures, whose
// one-word buffer a generic pipeline still reads).
fn tex_record(material: u32) -> u32 {
    let at = TEX_MATERIALS + 1u + material;
    if at >= arrayLength(&tex) {
        return TEX_NONE;
    }
    return tex[at];
}

// The texture coordinates at point p (relative to the origin, as the triangles are) on
// triangle `index`: its corners' coordinates by p's barycentrics (triangle_barycentrics, as
// triangle_surface finds them).
fn tex_uv(tri: Triangle, index: u32, p_world: vec3f) -> vec2f {
    return tex_uv_at(index, triangle_barycentrics(tri, p_world - tri.v0));
}

// The texture coordinates on triangle `index` at barycentrics `b`.
fn tex_uv_at(index: u32, b: vec2f) -> vec2f {
    let at = tex[TEX_UV_BASE] + 6u * index;
    let uv0 = vec2f(tex_f32(at), tex_f32(at + 1u));
    let uv1 = vec2f(tex_f32(at + 2u), tex_f32(at + 3u));
    let uv2 = vec2f(tex_f32(at + 4u), tex_f32(at + 5u));
    let uv = uv0 + b.x * (uv1 - uv0) + b.y * (uv2 - uv0);
    // A degenerate triangle's NaN coordinates read as (0, 0) (by the exponent bits: WGSL may
    // assume floats are finite, so `uv != uv` could be folded away).
    let inf = (bitcast<vec2u>(uv) & vec2u(0x7f800000u)) == vec2u(0x7f800000u);
    return select(uv, vec2f(0.0), inf);
}

// Map k's texture coordinates: `uv` through its KHR_texture_transform.
fn tex_xform(rec: u32, k: u32, uv: vec2f) -> vec2f {
    let m = rec + TEX_TRANSFORMS + 6u * k;
    return vec2f(
        tex_f32(m) * uv.x + tex_f32(m + 1u) * uv.y + tex_f32(m + 2u),
        tex_f32(m + 3u) * uv.x + tex_f32(m + 4u) * uv.y + tex_f32(m + 5u),
    );
}

// A glTF material's maps at `uv` applied to the model's material (docs/MODEL-NOTES.md):
// emission where the emissive map is lit; else the base colour, and for a pbr material its
// metallic, roughness and extensions' maps (a lecture material keeps its own lobes).
fn tex_material(m: Material, rec: u32, uv: vec2f) -> Material {
    let flags = tex[rec];
    var base = vec4f(tex_f32(rec + 4u), tex_f32(rec + 5u), tex_f32(rec + 6u), tex_f32(rec + 7u));
    if (flags & TEX_FLAG_BASE) != 0u {
        base *= tex_sample(tex[rec + 1u], tex_xform(rec, 0u, uv), TEX_SRGB);
    }
    var e = vec3f(tex_f32(rec + 10u), tex_f32(rec + 11u), tex_f32(rec + 12u));
    if (flags & TEX_FLAG_EMISSIVE) != 0u {
        e *= tex_sample(tex[rec + 3u], tex_xform(rec, 2u, uv), TEX_SRGB).xyz;
    }
    var out = m;
    let light = max(max(e.x, e.y), e.z);
    if light > 0.0 {
        out.color = e / light;
        out.light = light;
        return out;
    }
    out.light = 0.0;
    if m.model == MODEL_PBR {
        // The metallic-roughness map: a pbr material's alone (an emitter's or a lecture
        // material's is not read).
        var metallic = tex_f32(rec + 8u);
        var roughness = tex_f32(rec + 9u);
        if (flags & TEX_FLAG_MR) != 0u {
            let mr = tex_sample(tex[rec + 2u], tex_xform(rec, 1u, uv), TEX_UNORM);
            roughness *= mr.y;
            metallic *= mr.z;
        }
        out.color = base.xyz;
        out.metallic = metallic;
        out.roughness = roughness;
        // The material extensions' maps, each times the material's factor.
        if (flags & TEX_FLAG_TRANSMISSION) != 0u {
            out.transmission *= tex_extension_map(rec, 0u, uv, TEX_UNORM).x;
        }
        if (flags & TEX_FLAG_CLEARCOAT) != 0u {
            out.clearcoat *= tex_extension_map(rec, 1u, uv, TEX_UNORM).x;
        }
        if (flags & TEX_FLAG_CLEARCOAT_ROUGHNESS) != 0u {
            out.clearcoat_roughness *= tex_extension_map(rec, 2u, uv, TEX_UNORM).y;
        }
        if (flags & TEX_FLAG_SPECULAR) != 0u {
            out.specular *= tex_extension_map(rec, 3u, uv, TEX_UNORM).w;
        }
        if (flags & TEX_FLAG_SPECULAR_COLOR) != 0u {
            out.specular_color *= tex_extension_map(rec, 4u, uv, TEX_SRGB).xyz;
        }
        return out;
    }
    // A lecture material keeps its own lobes (`specular`, `smoothness`, …, as the user set
    // them); its maps give the colour alone.
    out.color = base.xyz;
    return out;
}

// Extension map k of record `rec` (transmission, clearcoat, clearcoat roughness, specular,
// specular colour) at `uv`, through its transform.
fn tex_extension_map(rec: u32, k: u32, uv: vec2f, mode: u32) -> vec4f {
    let h = tex[rec + TEX_EXTENSION_MAPS + k];
    return tex_sample(h, tex_xform(rec, TEX_EXTENSION_TRANSFORMS + k, uv), mode);
}

// Whether a ray's hit at distance t on triangle `tri` (number `index`) falls through
// a cut-out: alpha below the cutoff (MASK), or, for BLEND, a hashed uniform draw of the ray and
// triangle at or above alpha (a stochastic cut-out: over many rays, a share alpha is hit).
fn tex_cut_out(tri: Triangle, index: u32, ray: Ray, t: f32) -> bool {
    let rec = tex_record(tri.material);
    if rec == TEX_NONE {
        return false;
    }
    let flags = tex[rec];
    let mode = (flags >> TEX_ALPHA_SHIFT) & 3u;
    if mode == 0u {
        return false;
    }
    var alpha = tex_f32(rec + 7u);
    if (flags & TEX_FLAG_BASE) != 0u {
        let uv = tex_xform(rec, 0u, tex_uv(tri, index, ray.origin + t * ray.dir));
        alpha *= tex_sample(tex[rec + 1u], uv, TEX_UNORM).w;
    }
    if mode == 1u {
        return alpha < tex_f32(rec + 13u);
    }
    let o = bitcast<vec3u>(ray.origin);
    let d = bitcast<vec3u>(ray.dir);
    let u = unit_float(hash3(vec3u(o.x ^ d.x, o.y ^ d.y, (o.z ^ d.z) + index)));
    return u >= alpha;
}

fn tex_vec3(at: u32) -> vec3f {
    return vec3f(tex_f32(at), tex_f32(at + 1u), tex_f32(at + 2u));
}

// Whether the words hold the triangles' shading frames (a scene with neither textures nor
// normals binds one word: the generic pipeline asks before it reads).
fn tex_has_frames() -> bool {
    return arrayLength(&tex) > TEX_MATERIALS && tex[TEX_FRAMES] != 0u;
}

// The file's normals of triangle `index` interpolated at barycentrics `b` (smooth shading,
// docs/MODEL-NOTES.md "Smooth shading"); the geometric normal `n_geo` where the mesh has none
// or they cancel. The caller turns the result to the side it needs.
fn tex_smooth_normal(index: u32, b: vec2f, n_geo: vec3f) -> vec3f {
    let at = tex[TEX_FRAMES] + TEX_FRAME_WORDS * index;
    let n0 = tex_vec3(at);
    return normalize_or(n0 + b.x * (tex_vec3(at + 3u) - n0) + b.y * (tex_vec3(at + 6u) - n0), n_geo);
}

// Whether the material of record `rec` has a normal map.
fn tex_has_normal_map(rec: u32) -> bool {
    return rec != TEX_NONE && (tex[rec] & TEX_FLAG_NORMAL) != 0u;
}

// The shading normal at barycentrics `b` of triangle `index` (as tex_uv_at takes them), whose
// material's record `rec` has a normal map (docs/MODEL-NOTES.md, "Normal maps"): the corners'
// normals and tangents interpolated by `b` (the geometric normal `n_geo` where the file gives no normals; any tangent
// where it is degenerate), the tangent frame made orthonormal (Gram-Schmidt), and the map's
// tangent-space normal (x, y scaled by the map's scale, z at least TEX_NORMAL_MIN_Z) taken
// into it: N + (x·T + y·B) / z, normalised, B = N × T · w. A texel of (128, 128) leaves N as
// it is. The caller turns the result to the side it needs.
fn tex_shading_normal(rec: u32, index: u32, b: vec2f, uv: vec2f, n_geo: vec3f) -> vec3f {
    return tex_perturbed(rec, uv, tex_smooth_normal(index, b, n_geo), tex_tangent(index, b));
}

// The corners' tangents of triangle `index` interpolated at barycentrics `b`, and (w) the
// bitangent's sign.
fn tex_tangent(index: u32, b: vec2f) -> vec4f {
    let at = tex[TEX_FRAMES] + TEX_FRAME_WORDS * index;
    let t0 = tex_vec3(at + 9u);
    let t = t0 + b.x * (tex_vec3(at + 13u) - t0) + b.y * (tex_vec3(at + 17u) - t0);
    return vec4f(t, select(1.0, -1.0, tex_f32(at + 12u) < 0.0));
}

// The normal map of record `rec` read at `uv` and taken into the frame of normal n and
// tangent tw (tw.w: the bitangent's sign), as tex_shading_normal describes.
fn tex_perturbed(rec: u32, uv: vec2f, n: vec3f, tw: vec4f) -> vec3f {
    var t = tw.xyz;
    t -= n * dot(n, t);
    // A perpendicular of n when the tangent is missing or parallel to it.
    let other = select(vec3f(1.0, 0.0, 0.0), vec3f(0.0, 1.0, 0.0), abs(n.x) > 0.9);
    t = normalize_or(t, normalize(cross(other, n)));
    let bt = cross(n, t) * tw.w;
    let s = tex_sample(tex[rec + TEX_NORMAL_MAP], tex_xform(rec, 3u, uv), TEX_SNORM);
    let scale = tex_f32(rec + TEX_NORMAL_MAP + 1u);
    let d = (s.x * scale * t + s.y * scale * bt) / max(s.z, TEX_NORMAL_MIN_Z);
    if all(d == vec3f(0.0)) {
        return n;
    }
    return normalize_or(n + d, n);
}
