// #include "common/types.wgsl"
// #include "common/rng.wgsl"
// #include "common/sampling.wgsl"
// #include "common/intersect.wgsl"
// #include "common/material.wgsl"
// #include "common/fixed.wgsl"
// #include "common/texture.wgsl"
// #include "common/envmap.wgsl"
// #include "common/mirror.wgsl"
// #include "common/lens.wgsl"
// #include "common/pbr.wgsl"
// Twin: src/cpu/trace.rs (tests/twins.rs keeps their functions paired).
// The path tracer: one invocation traces its share of a round's `sample_count` paths through
// one pixel and adds them to that pixel's running sums (src/gpu/trace.rs drives it).

// Per-scene specialization (src/common/features.rs): what a scene does not use is compiled out.
override HAS_SPHERES: bool = true;
override HAS_QUADS: bool = true;
override HAS_BOXES: bool = true;
override HAS_TRIANGLES: bool = true;
override HAS_DIELECTRICS: bool = true;
override HAS_EMITTERS: bool = true;
override HAS_NEE: bool = true;
override HAS_DOF: bool = true;
override HAS_SUN: bool = true;
// glTF materials with maps (base colour, metallic-roughness, emissive), and alpha cut-outs.
override HAS_TEXTURES: bool = true;
override HAS_CUTOUTS: bool = true;
override HAS_NORMAL_MAPS: bool = true;
// Meshes with the file's normals, interpolated across each triangle (smooth shading).
override HAS_SMOOTH_NORMALS: bool = true;
// An HDR environment map (common/envmap.wgsl): looked up by escaping rays, sampled with HAS_NEE.
override HAS_ENV_MAP: bool = true;
// Perfect mirror spheres whose reflection of the map light sampling samples (sample_mirror).
override HAS_MIRROR_NEE: bool = true;
// Clear glass spheres through which light sampling refracts the map (sample_lens).
override HAS_LENS_NEE: bool = true;
// The lecture's glossy lobe takes light samples (gloss_pdf).
override HAS_GLOSS_NEE: bool = true;
override HAS_PBR: bool = true;
override HAS_LECTURE: bool = true;
// Meshes drawn by instances: a two-level BVH (src/common/arrays.rs: gpu_bvh).
override HAS_INSTANCES: bool = true;
// Counting path segments costs an atomic per workgroup; only `bench` turns it on.
override COUNT_SEGMENTS: bool = false;
// Walk the BVH, or test every primitive in turn (tests compare the two; see src/common/features.rs).
override USE_BVH: bool = true;

@group(0) @binding(0) var<uniform> scene: SceneUniforms;
@group(0) @binding(1) var<uniform> batch: DispatchUniforms;
@group(0) @binding(2) var<storage, read> materials: array<Material>;
@group(0) @binding(3) var<storage, read> spheres: array<Sphere>;
@group(0) @binding(4) var<storage, read> quads: array<Quad>;
@group(0) @binding(5) var<storage, read> boxes: array<Cuboid>;
// Running sums of the even and odd samples of each pixel, in fixed point (see fixed_add):
// ACCUM_WORDS words per pixel, [r.frac, r.low, r.high, g…, b…, samples].
@group(0) @binding(6) var<storage, read_write> accum_even: array<u32>;
@group(0) @binding(7) var<storage, read_write> accum_odd: array<u32>;
// [0, 1]: invalid (NaN/inf) samples discarded, as lo/hi words of a u64; with COUNT_SEGMENTS
// also [2, 3] path segments, [4, 5] BVH nodes visited, [6, 7] primitives tested (benchmarks).
@group(0) @binding(8) var<storage, read_write> counters: array<atomic<u32>, 8>;
// Per-invocation tallies of node visits and primitive tests (COUNT_SEGMENTS only).
var<private> visits: u32;
var<private> tests: u32;
@group(0) @binding(9) var<storage, read> nodes: array<BvhNode4>;
// Primitive references in leaf order: kind (KIND_* - 1) in the top two bits, index below.
@group(0) @binding(10) var<storage, read> refs: array<u32>;
@group(0) @binding(11) var<storage, read> triangles: array<Triangle>;
@group(0) @binding(12) var<storage, read> lights: array<Light>;
// Per-lane sums when a pixel's samples are traced by several lanes (see fn trace).
@group(0) @binding(13) var<storage, read_write> scratch: array<u32>;
// Copies of instanced meshes (one zeroed record where there are none).
@group(0) @binding(16) var<storage, read> instances: array<Instance>;
// Binding 14, the texture words, is declared in common/texture.wgsl; binding 15, the
// environment map's, in common/envmap.wgsl.

const KIND_NONE: u32 = 0u;
const KIND_SPHERE: u32 = 1u;
const KIND_QUAD: u32 = 2u;
const KIND_BOX: u32 = 3u;
const KIND_TRIANGLE: u32 = 4u;
const T_FAR: f32 = 3.0e38;
// Pending BVH nodes of a walk: at most three pushed per level of the deepest tree the builder
// makes (src/bvh/wide.rs: STACK), so the stack never overflows. It lives at module scope:
// WGSL zeroes every variable where it is declared, and a stack declared in the walk was
// zeroed on every ray (lavapipe: 1.37x the samples/s once it moved here).
const STACK_SIZE: u32 = 220u;
const EMPTY_SLOT: u32 = 0xffffffffu;
var<private> stack_node: array<u32, STACK_SIZE>;
var<private> stack_t: array<f32, STACK_SIZE>;
// Under the triangle kind, a reference with this bit names an instance (src/common/arrays.rs:
// INSTANCE_BIT); a walk into its mesh keeps its own stack, and leaves the triangle it found.
const INSTANCE_BIT: u32 = 0x20000000u;
const NO_INSTANCE: u32 = 0xffffffffu;
var<private> instance_stack_node: array<u32, STACK_SIZE>;
var<private> instance_stack_t: array<f32, STACK_SIZE>;
var<private> instance_triangle: u32;

// A hit: its distance, kind and index in its kind's array; for a triangle of an instanced
// mesh, the instance (else NO_INSTANCE).
struct Hit {
    t: f32,
    kind: u32,
    index: u32,
    instance: u32,
}

// The nearest of instance i's triangles before t_max, or NO_HIT; the triangle is left in
// instance_triangle. The ray is taken into the mesh's coordinates without normalizing its
// direction, so that distances along it are the world's (PBRT 4th ed. §7.1.4).
fn hit_instance(i: u32, world: Ray, t_max: f32) -> f32 {
    let inst = instances[i];
    let ray = instance_ray(inst, world);
    let inv = safe_inverse(ray.dir);
    var best = t_max;
    var found = false;
    var sp = 0u;
    var node = inst.root;
    loop {
        let n = nodes[node];
        count_visit();
        let s = slabs(n, ray.origin, inv, best);
        var leaves = s.leaves;
        while leaves != 0u {
            let k = pop_slot(&leaves);
            count_tests(n.count[k]);
            for (var j = n.child[k]; j < n.child[k] + n.count[k]; j++) {
                let index = refs[j] & 0x3fffffffu;
                let tri = triangles[index];
                var t = hit_triangle(tri, ray, best);
                if HAS_CUTOUTS && t > 0.0 && tex_cut_out(tri, index, ray, t) {
                    t = NO_HIT;
                }
                if t > 0.0 {
                    best = t;
                    found = true;
                    instance_triangle = index;
                }
            }
        }
        var inner = s.inner;
        while inner != 0u {
            let k = pop_slot(&inner);
            instance_stack_node[sp] = n.child[k];
            instance_stack_t[sp] = s.near[k];
            sp += 1u;
        }
        var next = false;
        while !next && sp > 0u {
            sp -= 1u;
            if instance_stack_t[sp] < best {
                node = instance_stack_node[sp];
                next = true;
            }
        }
        if !next {
            break;
        }
    }
    return select(NO_HIT, best, found);
}

// The hit of reference r at distance t: an instance's names the triangle its walk found.
fn hit_of(r: u32, t: f32) -> Hit {
    if HAS_INSTANCES && r >> 30u == 3u && (r & INSTANCE_BIT) != 0u {
        return Hit(t, KIND_TRIANGLE, instance_triangle, r & (INSTANCE_BIT - 1u));
    }
    return Hit(t, (r >> 30u) + 1u, r & 0x3fffffffu, NO_INSTANCE);
}

// The distance to what BVH reference `r` names if nearer than t_max, else NO_HIT: a
// primitive, or (HAS_INSTANCES) the nearest of an instance's triangles. (The instance's walk is
// kept out of hit_primitive: inlined into the test of every primitive, the generic pipeline
// without a BVH lost samples on lavapipe.)
fn hit_ref(r: u32, ray: Ray, t_max: f32) -> f32 {
    if HAS_INSTANCES && r >> 30u == 3u && (r & INSTANCE_BIT) != 0u {
        return hit_instance(r & (INSTANCE_BIT - 1u), ray, t_max);
    }
    return hit_primitive(r, ray, t_max);
}

// The distance to primitive `r` (a BVH reference) if nearer than t_max, else NO_HIT.
fn hit_primitive(r: u32, ray: Ray, t_max: f32) -> f32 {
    let index = r & 0x3fffffffu;
    switch r >> 30u {
        case 0u: {
            if HAS_SPHERES {
                return hit_sphere(spheres[index], ray, t_max);
            }
        }
        case 1u: {
            if HAS_QUADS {
                return hit_quad(quads[index], ray, t_max);
            }
        }
        case 2u: {
            if HAS_BOXES {
                return hit_box(boxes[index], ray, t_max);
            }
        }
        default: {
            if HAS_TRIANGLES {
                let tri = triangles[index];
                let t = hit_triangle(tri, ray, t_max);
                if HAS_CUTOUTS && t > 0.0 && tex_cut_out(tri, index, ray, t) {
                    return NO_HIT;
                }
                return t;
            }
        }
    }
    return NO_HIT;
}

// The nearest hit by testing every primitive (USE_BVH = false).
fn intersect_all(ray: Ray) -> Hit {
    var hit = Hit(T_FAR, KIND_NONE, 0u, NO_INSTANCE);
    let counts = array<u32, 4>(scene.n_spheres, scene.n_quads, scene.n_boxes, scene.n_triangles);
    for (var kind = 0u; kind < 4u; kind++) {
        for (var i = 0u; i < counts[kind]; i++) {
            let r = kind << 30u | i;
            let t = hit_primitive(r, ray, hit.t);
            if t > 0.0 {
                hit = Hit(t, kind + 1u, i, NO_INSTANCE);
            }
        }
    }
    if HAS_INSTANCES {
        for (var i = 0u; i < scene.n_instances; i++) {
            let r = 3u << 30u | INSTANCE_BIT | i;
            let t = hit_ref(r, ray, hit.t);
            if t > 0.0 {
                hit = hit_of(r, t);
            }
        }
    }
    return hit;
}

// Tallies one BVH node visit (benchmarks only).
fn count_visit() {
    if COUNT_SEGMENTS {
        visits += 1u;
    }
}

fn count_tests(n: u32) {
    if COUNT_SEGMENTS {
        tests += n;
    }
}

// The slots where `b` is true, as a bit mask (slot k: bit k).
fn slot_bits(b: vec4<bool>) -> u32 {
    return dot(select(vec4u(0u), vec4u(1u, 2u, 4u, 8u), b), vec4u(1u));
}

// Takes the lowest slot out of a non-empty mask.
fn pop_slot(mask: ptr<function, u32>) -> u32 {
    let k = firstTrailingBit(*mask);
    *mask &= *mask - 1u;
    return k;
}

// A node's four slab tests at once (Kay & Kajiya 1986; Williams et al., "An Efficient and
// Robust Ray-Box Intersection Algorithm", JGT 2005): the leaf and the inner slots the ray
// enters before t_max, as bit masks, and the entry distances (clamped at 0).
struct Slabs {
    near: vec4f,
    leaves: u32,
    inner: u32,
}

fn slabs(n: BvhNode4, origin: vec3f, inv: vec3f, t_max: f32) -> Slabs {
    let tx0 = (n.min_x - origin.x) * inv.x;
    let tx1 = (n.max_x - origin.x) * inv.x;
    let ty0 = (n.min_y - origin.y) * inv.y;
    let ty1 = (n.max_y - origin.y) * inv.y;
    let tz0 = (n.min_z - origin.z) * inv.z;
    let tz1 = (n.max_z - origin.z) * inv.z;
    let near = max(max(min(tx0, tx1), min(ty0, ty1)), max(min(tz0, tz1), vec4f(0.0)));
    let far = min(min(max(tx0, tx1), max(ty0, ty1)), min(max(tz0, tz1), vec4f(t_max)));
    let entered = (near <= far) & (n.count != vec4u(EMPTY_SLOT));
    let leaf = slot_bits(n.count != vec4u(0u));
    let hit = slot_bits(entered);
    return Slabs(near, hit & leaf, hit & ~leaf);
}

// The nearest hit, by walking the four-wide BVH: the leaf slots a node's ray enters are tested
// at once (a few primitives, which shorten the ray for what follows); of the inner slots, the
// nearest is entered next and the others pushed, nearest on top, and skipped when popped if
// a nearer hit was found since. The CPU tracer walks the same nodes the same way
// (src/cpu/bvh.rs).
fn intersect_scene(ray: Ray) -> Hit {
    if !USE_BVH {
        return intersect_all(ray);
    }
    var hit = Hit(T_FAR, KIND_NONE, 0u, NO_INSTANCE);
    if scene.n_spheres + scene.n_quads + scene.n_boxes + scene.n_triangles + scene.n_instances == 0u {
        return hit;
    }
    let inv = safe_inverse(ray.dir);
    var sp = 0u;
    var node = 0u;
    loop {
        let n = nodes[node];
        count_visit();
        let s = slabs(n, ray.origin, inv, hit.t);
        var leaves = s.leaves;
        while leaves != 0u {
            let k = pop_slot(&leaves);
            count_tests(n.count[k]);
            for (var i = n.child[k]; i < n.child[k] + n.count[k]; i++) {
                let r = refs[i];
                let t = hit_ref(r, ray, hit.t);
                if t > 0.0 {
                    hit = hit_of(r, t);
                }
            }
        }
        var next_found = false;
        var next_t = 0.0;
        let base = sp;
        var inner = s.inner;
        while inner != 0u {
            let k = pop_slot(&inner);
            if s.near[k] < hit.t {
                var e_node = n.child[k];
                var e_t = s.near[k];
                if !next_found {
                    node = e_node;
                    next_t = e_t;
                    next_found = true;
                    continue;
                }
                if e_t < next_t {
                    let far_node = node;
                    let far_t = next_t;
                    node = e_node;
                    next_t = e_t;
                    e_node = far_node;
                    e_t = far_t;
                }
                // Below the entries of this node that are nearer than it.
                var j = sp;
                while j > base && stack_t[j - 1u] < e_t {
                    stack_node[j] = stack_node[j - 1u];
                    stack_t[j] = stack_t[j - 1u];
                    j -= 1u;
                }
                stack_node[j] = e_node;
                stack_t[j] = e_t;
                sp += 1u;
            }
        }
        // Else the nearest pending node that can still hold a nearer hit.
        while !next_found && sp > 0u {
            sp -= 1u;
            if stack_t[sp] < hit.t {
                node = stack_node[sp];
                next_found = true;
            }
        }
        if !next_found {
            break;
        }
    }
    return hit;
}

// Whether anything but primitive `skip` lies on the ray before t_max: shadow rays stop at the
// first blocker, in any order, and never look past the light.
fn occluded(ray: Ray, t_max: f32, skip: u32) -> bool {
    if !USE_BVH {
        let counts = array<u32, 4>(scene.n_spheres, scene.n_quads, scene.n_boxes, scene.n_triangles);
        for (var kind = 0u; kind < 4u; kind++) {
            for (var i = 0u; i < counts[kind]; i++) {
                let r = kind << 30u | i;
                if r != skip && hit_primitive(r, ray, t_max) > 0.0 {
                    return true;
                }
            }
        }
        if HAS_INSTANCES {
            for (var i = 0u; i < scene.n_instances; i++) {
                if hit_ref(3u << 30u | INSTANCE_BIT | i, ray, t_max) > 0.0 {
                    return true;
                }
            }
        }
        return false;
    }
    let inv = safe_inverse(ray.dir);
    var sp = 0u;
    var node = 0u;
    loop {
        let n = nodes[node];
        count_visit();
        let s = slabs(n, ray.origin, inv, t_max);
        var leaves = s.leaves;
        while leaves != 0u {
            let k = pop_slot(&leaves);
            count_tests(n.count[k]);
            for (var i = n.child[k]; i < n.child[k] + n.count[k]; i++) {
                let r = refs[i];
                if r != skip && hit_ref(r, ray, t_max) > 0.0 {
                    return true;
                }
            }
        }
        var inner = s.inner;
        while inner != 0u {
            stack_node[sp] = n.child[pop_slot(&inner)];
            sp += 1u;
        }
        if sp == 0u {
            break;
        }
        sp -= 1u;
        node = stack_node[sp];
    }
    return false;
}

// The surface point, geometric normal and material of a hit, and the point in its mesh's
// coordinates (where texture coordinates and shading frames are interpolated: an instance's
// are its mesh's; elsewhere the point itself).
struct Surface {
    point: SurfacePoint,
    material: u32,
    local: vec3f,
}

// A hit's material with a glTF material's texture maps applied, and where they were read
// (its texture record, TEX_NONE where no map applies; barycentrics; coordinates), for the
// normal map (src/cpu/trace.rs's `material_at`).
struct Shading {
    m: Material,
    rec: u32,
    bary: vec2f,
    uv: vec2f,
}

fn material_at(hit: Hit, surf: Surface) -> Shading {
    var s = Shading(materials[surf.material], TEX_NONE, vec2f(0.0), vec2f(0.0));
    if HAS_TEXTURES && hit.kind == KIND_TRIANGLE {
        s.rec = tex_record(surf.material);
        if s.rec != TEX_NONE {
            let tri = triangles[hit.index];
            s.bary = triangle_barycentrics(tri, surf.local - tri.v0);
            s.uv = tex_uv_at(hit.index, s.bary);
            s.m = tex_material(s.m, s.rec, s.uv);
        }
    }
    return s;
}

// The shading normal on the side of n at point p: a normal map's where the hit has one
// (docs/MODEL-NOTES.md, "Normal maps"), else the file's normals interpolated where its mesh
// has them ("Smooth shading"), else n (src/cpu/trace.rs's `shading_normal_at`).
// `p` is the point in the mesh's coordinates (Surface.local); an instance's frames are its
// mesh's, brought into the world by its normal matrix.
fn shading_normal_at(s: Shading, hit: Hit, p: vec3f, n_out: vec3f, n: vec3f) -> vec3f {
    let instanced = HAS_INSTANCES && hit.instance != NO_INSTANCE;
    var n_geo = n_out;
    if instanced {
        let tri = triangles[hit.index];
        n_geo = normalize(cross(tri.e1, tri.e2));
    }
    if HAS_NORMAL_MAPS && hit.kind == KIND_TRIANGLE && tex_has_normal_map(s.rec) {
        var ns: vec3f;
        if instanced {
            // The frame brought into the world first, as a flattened mesh's frames are.
            let inst = instances[hit.instance];
            let nw = instance_normal(inst, tex_smooth_normal(hit.index, s.bary, n_geo));
            ns = tex_perturbed(s.rec, s.uv, nw, instance_tangent(inst, tex_tangent(hit.index, s.bary)));
        } else {
            ns = tex_shading_normal(s.rec, hit.index, s.bary, s.uv, n_geo);
        }
        return select(-ns, ns, dot(ns, n) >= 0.0);
    }
    if HAS_SMOOTH_NORMALS && hit.kind == KIND_TRIANGLE && tex_has_frames() {
        var b = s.bary;
        if s.rec == TEX_NONE {
            let tri = triangles[hit.index];
            b = triangle_barycentrics(tri, p - tri.v0);
        }
        var ns = tex_smooth_normal(hit.index, b, n_geo);
        if instanced {
            ns = instance_normal(instances[hit.instance], ns);
        }
        return select(-ns, ns, dot(ns, n) >= 0.0);
    }
    return n;
}

fn surface_in_place(p: SurfacePoint, material: u32) -> Surface {
    return Surface(p, material, p.position);
}

fn surface_at(hit: Hit, ray: Ray) -> Surface {
    if hit.kind == KIND_SPHERE {
        let s = spheres[hit.index];
        return surface_in_place(sphere_surface(s, ray, hit.t), s.material);
    }
    if hit.kind == KIND_QUAD {
        let q = quads[hit.index];
        return surface_in_place(quad_surface(q, ray, hit.t), q.material);
    }
    if hit.kind == KIND_BOX {
        let b = boxes[hit.index];
        return surface_in_place(box_surface(b, ray, hit.t), b.material);
    }
    let tri = triangles[hit.index];
    if HAS_INSTANCES && hit.instance != NO_INSTANCE {
        // Found in the mesh's coordinates, and brought into the world's.
        let inst = instances[hit.instance];
        let local = triangle_surface(tri, instance_ray(inst, ray), hit.t);
        let world = SurfacePoint(instance_point(inst, local.position), instance_normal(inst, local.normal));
        return Surface(world, tri.material, local.position);
    }
    return surface_in_place(triangle_surface(tri, ray, hit.t), tri.material);
}

// The gradient sky with optional sun, or a uniform sky (MODEL.md "Sky").
fn sky(dir: vec3f) -> vec3f {
    if scene.sky_uniform != 0u {
        return scene.sky_bottom;
    }
    let t = 0.5 * (dir.y + 1.0);
    var c = (1.0 - t) * scene.sky_bottom + t * scene.sky_top;
    if HAS_SUN {
        let cz = max(dot(scene.sun_dir, dir), 0.0);
        if cz > 0.0 {
            c += scene.sun_radiance * pow(cz, scene.sun_size);
        }
    }
    return c;
}

// Thin-lens camera (the lecture's "Desfocando"; Shirley, Ray Tracing in One Weekend §13):
// the ray starts on the lens disk and passes through the jittered pixel's point on the focus
// plane. Directions are built relative to the camera so that a far-away camera loses nothing.
fn camera_ray(px: vec2u, state: ptr<function, Rng>) -> Ray {
    let j = rand2(state);
    let s = (f32(px.x) + j.x) / f32(scene.width);
    let t = (f32(px.y) + j.y) / f32(scene.height);
    let target_rel = scene.cam_to_corner + s * scene.cam_horizontal - t * scene.cam_vertical;
    var lens = vec3f(0.0);
    if HAS_DOF && scene.lens_radius > 0.0 {
        let p = random_in_disk(state) * scene.lens_radius;
        lens = p.x * scene.cam_u + p.y * scene.cam_v;
    }
    return Ray(scene.cam_origin + lens, normalize(target_rel - lens));
}

// ---- Next-event estimation with multiple importance sampling ----
// At a bounce whose lobe has a density (the Lambertian lobe, and the specular lobe at
// smoothness 0, which is the same cosine distribution), one light is sampled (picked by
// power; a sphere within the cone it subtends, a quad by area) and, if unoccluded, weighted
// against the BSDF sample that could have found it with Veach's power heuristic (Veach &
// Guibas 1995; PBRT 4th ed. §13.4). Lobes without a usable density (the smoothness blend,
// fuzzed and perfect mirrors, glass) are treated as delta lobes: no light sample, and a
// light their bounce hits counts fully. The lobe is picked first (rand() < specular), so the
// estimator is a one-sample mixture over lobes and stays unbiased.

// Bounces after which Russian roulette may end a path, and the highest survival probability
// (under 1, so that a lossless path, e.g. trapped by total internal reflection, still ends).
const RR_START: u32 = 3u;
const RR_MAX_SURVIVAL: f32 = 0.95;

fn power_heuristic(a: f32, b: f32) -> f32 {
    let a2 = a * a;
    return a2 / (a2 + b * b);
}

fn sphere_center(s: Sphere) -> vec3f {
    return s.anchor - abs(s.radius) * s.anchor_normal;
}

// 1 - cos of the half-angle of the cone a sphere subtends from a point at squared distance
// dist2 (r² < dist2), without cancellation: sin²/(1 + cos).
fn cone_one_minus_cos(r2: f32, dist2: f32) -> f32 {
    let sin2 = r2 / dist2;
    return sin2 / (1.0 + sqrt(max(0.0, 1.0 - sin2)));
}

// Solid-angle density with which light sampling from `origin` produces the direction that
// hit light primitive `hit` at `at` (0 if it could not have: from inside an emissive sphere).
fn light_pdf(hit: Hit, origin: vec3f, at: vec3f) -> f32 {
    if hit.kind == KIND_SPHERE {
        let s = spheres[hit.index];
        let d = sphere_center(s) - origin;
        let dist2 = dot(d, d);
        let r2 = s.radius * s.radius;
        if dist2 <= r2 {
            return 0.0;
        }
        return 1.0 / (2.0 * PI * cone_one_minus_cos(r2, dist2));
    }
    if hit.kind == KIND_QUAD {
        let q = quads[hit.index];
        let to = at - origin;
        let dist2 = dot(to, to);
        let cos_l = abs(dot(q.normal, to)) * inverseSqrt(dist2);
        let area = length(cross(q.u, q.v));
        return dist2 / max(area * cos_l, 1e-30);
    }
    return 0.0;
}

// Light selection. With few lights, each is weighted as seen from the shading point p with
// normal n: its power (its share `pmf` of the total) over its squared distance (at least its
// own radius²), times 0.1 + max(cos, 0) toward it: the power-proportional choice corrected
// for distance and facing, so that a far bright panel does not draw the samples a near lamp
// needs. The 0.1 keeps every light's probability above zero (the estimator stays unbiased).
// With more than LOCAL_SELECTION_MAX lights the weights would cost a loop over all of them:
// the choice is then by power alone, from the cumulative table.
const LOCAL_SELECTION_MAX: u32 = 32u;
const BACKFACE_WEIGHT: f32 = 0.1;

fn light_weight(l: Light, p: vec3f, n: vec3f) -> f32 {
    let kind = l.prim >> 30u;
    let index = l.prim & 0x3fffffffu;
    var center: vec3f;
    var r2: f32;
    if kind == 0u {
        let s = spheres[index];
        center = sphere_center(s);
        r2 = s.radius * s.radius;
    } else {
        let q = quads[index];
        center = q.q + 0.5 * (q.u + q.v);
        r2 = 0.25 * dot(q.u + q.v, q.u + q.v);
    }
    let to = center - p;
    let d2 = dot(to, to);
    let cos_t = dot(n, to) * inverseSqrt(max(d2, 1e-30));
    return l.pmf / max(d2, r2) * (BACKFACE_WEIGHT + max(cos_t, 0.0));
}

// Index of the light picked by u in [0, 1) from the cumulative power table.
fn pick_light_by_power(u: f32) -> u32 {
    var lo = 0u;
    var hi = scene.n_lights - 1u;
    while lo < hi {
        let mid = (lo + hi) / 2u;
        if lights[mid].cdf > u {
            hi = mid;
        } else {
            lo = mid + 1u;
        }
    }
    return lo;
}

struct LightChoice {
    index: u32,
    pmf: f32,
}

fn choose_light(u: f32, p: vec3f, n: vec3f) -> LightChoice {
    // One light is chosen for certain (its weight over itself), with no weight to compute.
    if scene.n_lights == 1u {
        return LightChoice(0u, 1.0);
    }
    if scene.n_lights > LOCAL_SELECTION_MAX {
        let i = pick_light_by_power(u);
        return LightChoice(i, lights[i].pmf);
    }
    var total = 0.0;
    for (var i = 0u; i < scene.n_lights; i++) {
        total += light_weight(lights[i], p, n);
    }
    let target_w = u * total;
    var acc = 0.0;
    for (var i = 0u; i < scene.n_lights; i++) {
        let w = light_weight(lights[i], p, n);
        acc += w;
        if acc > target_w || i + 1u == scene.n_lights {
            return LightChoice(i, w / total);
        }
    }
    return LightChoice(0u, 0.0);
}

// The probability that choose_light at (p, n) picks light i.
fn light_choice_pmf(i: u32, p: vec3f, n: vec3f) -> f32 {
    if scene.n_lights == 1u {
        return 1.0;
    }
    if scene.n_lights > LOCAL_SELECTION_MAX {
        return lights[i].pmf;
    }
    var total = 0.0;
    for (var k = 0u; k < scene.n_lights; k++) {
        total += light_weight(lights[k], p, n);
    }
    return light_weight(lights[i], p, n) / total;
}

// The light-sampled estimate at point p with facing (shading) normal n, for the lobe light
// sampling weighs (light_weighted: the lecture's lobes with their f·cos included, their tint
// not), MIS-weighted. n_geo: the facing geometric normal; the shadow ray leaves on its side,
// never into it. `pbr`: the surface is glTF's BRDF `lobe`; else `gloss` is the lecture's
// glossy lobe where its smoothness is above 0, or the cosine lobe.
fn sample_light(p: vec3f, n: vec3f, n_geo: vec3f, pbr: bool, lobe: PbrLobe, gloss: Gloss, state: ptr<function, Rng>) -> vec3f {
    // The environment map, with probability env_pick (src/common/arrays.rs: env_pick), or
    // one of the scene's lights by choose_light; one light alone is chosen without a draw.
    let pe = env_pick();
    var pick = 0.0;
    if scene.n_lights + select(0u, 1u, pe > 0.0) > 1u {
        pick = rand(state);
    }
    if pe > 0.0 && pick < pe {
        return sample_env(p, n, n_geo, pe, pbr, lobe, gloss, state);
    }
    if pe > 0.0 {
        pick = (pick - pe) / (1.0 - pe);
    }
    let choice = choose_light(pick, p, n);
    if choice.pmf <= 0.0 {
        return vec3f(0.0);
    }
    let light = lights[choice.index];
    let kind = light.prim >> 30u;
    let index = light.prim & 0x3fffffffu;
    var dir: vec3f;
    var pdf: f32;
    var material: u32;
    if kind == 0u {
        let s = spheres[index];
        let to = sphere_center(s) - p;
        let dist2 = dot(to, to);
        let r2 = s.radius * s.radius;
        let u = rand2(state);
        let u1 = u.x;
        let u2 = u.y;
        if dist2 <= r2 {
            return vec3f(0.0);
        }
        let one_minus = cone_one_minus_cos(r2, dist2);
        let cos_t = 1.0 - u1 * one_minus;
        let sin_t = sqrt(max(0.0, 1.0 - cos_t * cos_t));
        let phi = 2.0 * PI * u2;
        dir = normalize(basis(to * inverseSqrt(dist2)) * vec3f(sin_t * cos(phi), sin_t * sin(phi), cos_t));
        pdf = 1.0 / (2.0 * PI * one_minus);
        material = s.material;
    } else {
        let q = quads[index];
        let u = rand2(state);
        let x = q.q + u.x * q.u + u.y * q.v;
        let to = x - p;
        let dist2 = dot(to, to);
        dir = to * inverseSqrt(dist2);
        let cos_l = abs(dot(q.normal, dir));
        if cos_l < 1e-6 {
            return vec3f(0.0);
        }
        pdf = dist2 / (light.area * cos_l);
        material = q.material;
    }
    let cos_s = dot(n, dir);
    let side = shadow_side(cos_s, n_geo, dir, pbr, lobe);
    if all(side == vec3f(0.0)) {
        return vec3f(0.0);
    }
    // Visible if nothing but the light lies between p and the light's own hit along dir (no
    // distance epsilon: the light is skipped by identity, not by distance).
    let shadow = Ray(offset_ray(p, side), dir);
    let t_light = hit_primitive(light.prim, shadow, T_FAR);
    if t_light <= 0.0 || occluded(shadow, t_light, light.prim) {
        return vec3f(0.0);
    }
    let m = materials[material];
    return light_weighted(m.color * m.light, dir, cos_s, (1.0 - pe) * choice.pmf * pdf, pbr, lobe, gloss);
}

// Whether light sampling also looks below the surface: glTF's BRDF (`pbr`) where it transmits
// through a rough boundary, whose density there is known (pbr_eval_through); a smooth one's
// transmission is a delta that no light sample can meet (src/cpu/trace.rs: transmits).
fn transmits(pbr: bool, lobe: PbrLobe) -> bool {
    return HAS_PBR_TRANSMISSION && pbr && lobe.transmission > 0.0 && lobe.alpha >= PBR_ALPHA_MIN;
}

// The side a light sample toward dir (cos_s against the shading normal) leaves its point on:
// the facing geometric normal n_geo where the lobe reflects, its opposite where the lobe
// transmits (transmits) and dir lies below both normals, else zero: the lobe sends nothing
// toward dir (src/cpu/trace.rs: shadow_side).
fn shadow_side(cos_s: f32, n_geo: vec3f, dir: vec3f, pbr: bool, lobe: PbrLobe) -> vec3f {
    let normals = HAS_NORMAL_MAPS || HAS_SMOOTH_NORMALS;
    if cos_s > 0.0 && !(normals && dot(n_geo, dir) <= 0.0) {
        return n_geo;
    }
    if cos_s < 0.0 && transmits(pbr, lobe) && !(normals && dot(n_geo, dir) >= 0.0) {
        return -n_geo;
    }
    return vec3f(0.0);
}

// A light sample's estimate for the lobe that light sampling weighs: radiance arriving from
// dir (cos_s against the shading normal), drawn with density pl, times glTF's BRDF (pbr) or
// the lecture's lobe's f·cos, which is its density (the glossy lobe's gloss_pdf, the cosine
// lobe's cos_s / π; its tint the caller applies), or the mixture of the glossy and the cosine
// lobe (gloss.p < 1, tints included), weighed by the power heuristic against the lobe's
// density (src/cpu/trace.rs: light_weighted).
fn light_weighted(radiance: vec3f, dir: vec3f, cos_s: f32, pl: f32, pbr: bool, lobe: PbrLobe, gloss: Gloss) -> vec3f {
    if HAS_PBR && pbr {
        let e = pbr_eval(lobe, dir);
        return radiance * e.xyz * (power_heuristic(pl, e.w) / pl);
    }
    if HAS_GLOSS_NEE && gloss.s > 0.0 {
        if gloss.p < 1.0 {
            let pg = gloss.p * gloss_pdf(dir, gloss.n, gloss.r, gloss.s);
            let pd = (1.0 - gloss.p) * (cos_s / PI);
            return radiance * (gloss.spec * pg + gloss.diff * pd) * (power_heuristic(pl, pg + pd) / pl);
        }
        let pdf = gloss_pdf(dir, gloss.n, gloss.r, gloss.s);
        return radiance * (pdf / pl * power_heuristic(pl, pdf));
    }
    return radiance * (cos_s / PI / pl * power_heuristic(pl, cos_s / PI));
}

// The density of the lecture's lobe light sampling weighs at direction dir that the path drew
// (its MIS weight against light samples; src/cpu/trace.rs: lobe_pdf).
fn lobe_pdf(gloss: Gloss, dir: vec3f, ns: vec3f) -> f32 {
    let pd = max(dot(dir, ns), 0.0) / PI;
    if HAS_GLOSS_NEE && gloss.s > 0.0 {
        let pg = gloss_pdf(dir, gloss.n, gloss.r, gloss.s);
        if gloss.p < 1.0 {
            return gloss.p * pg + (1.0 - gloss.p) * pd;
        }
        return pg;
    }
    return pd;
}

// The lecture's glossy lobe as light sampling weighs it (src/cpu/trace.rs: Weighed::Gloss and
// Weighed::Mixed): the shading normal, the mirror direction and the smoothness (s = 0 for the
// cosine lobe), and the probability p with which the material takes it: below 1, light
// sampling weighs its mixture with the cosine lobe, with their tints spec and diff, whichever
// lobe the path goes on by.
struct Gloss {
    n: vec3f,
    r: vec3f,
    s: f32,
    p: f32,
    spec: vec3f,
    diff: vec3f,
}

// The cosine lobe about n, as light sampling weighs it.
fn cosine_lobe(n: vec3f) -> Gloss {
    return Gloss(n, vec3f(0.0), 0.0, 1.0, vec3f(1.0), vec3f(1.0));
}

// SceneUniforms.env_mode (src/common/arrays.rs).
const ENV_NONE: u32 = 0u;
const ENV_VISIBLE: u32 = 2u;

// The probability that light sampling picks the environment map: 0 without one.
fn env_pick() -> f32 {
    if HAS_ENV_MAP {
        return scene.env_pick;
    }
    return 0.0;
}

// The environment map's share of sample_light, picked with probability pe: a direction from
// the map's distribution, unoccluded, MIS-weighted against the cosine lobe.
fn sample_env(p: vec3f, n: vec3f, n_geo: vec3f, pe: f32, pbr: bool, lobe: PbrLobe, gloss: Gloss, state: ptr<function, Rng>) -> vec3f {
    let s = env_sample(rand2(state), scene.env_rotation);
    let cos_s = dot(n, s.dir);
    if s.pdf <= 0.0 {
        return vec3f(0.0);
    }
    let side = shadow_side(cos_s, n_geo, s.dir, pbr, lobe);
    if all(side == vec3f(0.0)) {
        return vec3f(0.0);
    }
    if occluded(Ray(offset_ray(p, side), s.dir), T_FAR, EMPTY_SLOT) {
        return vec3f(0.0);
    }
    return light_weighted(s.radiance * scene.env_intensity, s.dir, cos_s, pe * s.pdf, pbr, lobe, gloss);
}

// Whether material m's surface follows glTF's BRDF (common/pbr.wgsl) rather than the
// lecture's lobes: a scene of glTF materials alone (no HAS_LECTURE) has no lecture
// (src/cpu/trace.rs: follows_pbr).
fn follows_pbr(m: Material) -> bool {
    return HAS_PBR && (!HAS_LECTURE || m.model == MODEL_PBR);
}

// The density, in solid angle at the point that sees it, with which sample_mirror finds the
// map's direction of density pdf in a mirror sphere of spread `spread`.
fn mirror_pdf(pdf: f32, spread: f32) -> f32 {
    return pdf / (f32(scene.n_mirrors + scene.n_lenses) * spread);
}

// Where a ray from a lobe light sampling weighs (prev_pdf > 0, from prev_point) meets one of
// the mirror spheres sample_mirror samples from outside: (that lobe's density, the sphere's
// spread there), else zeros (src/cpu/trace.rs: mirror_hit).
fn mirror_hit(hit: Hit, ray: Ray, position: vec3f, normal: vec3f, prev_pdf: f32, prev_point: vec3f) -> vec2f {
    if !(HAS_MIRROR_NEE && prev_pdf > 0.0 && hit.kind == KIND_SPHERE) {
        return vec2f(0.0);
    }
    var listed = false;
    for (var k = 0u; k < scene.n_mirrors + scene.n_lenses; k++) {
        listed = listed || lights[scene.n_lights + k].prim == hit.index;
    }
    if !listed {
        return vec2f(0.0);
    }
    let cos_i = -dot(ray.dir, normal);
    let spread = mirror_spread(spheres[hit.index].radius, length(position - prev_point), cos_i);
    if cos_i > 0.0 && spread > 0.0 {
        return vec2f(prev_pdf, spread);
    }
    return vec2f(0.0);
}

// The environment map's light as a mirror sphere reflects it onto p (src/cpu/trace.rs:
// sample_mirror, which says how): one of the mirror spheres chosen evenly, a direction from
// the map's distribution, the point of the sphere that reflects it to p, both legs
// unoccluded, MIS-weighted against the lobe.
fn sample_mirror(p: vec3f, n: vec3f, n_geo: vec3f, pbr: bool, lobe: PbrLobe, gloss: Gloss, view: vec2i, state: ptr<function, Rng>) -> vec3f {
    let count = scene.n_mirrors + scene.n_lenses;
    var pick = 0.0;
    if count > 1u {
        pick = rand(state);
    }
    let prim = lights[scene.n_lights + min(u32(pick * f32(count)), count - 1u)].prim;
    let sphere = spheres[prim];
    let c = sphere_center(sphere);
    // A sphere wholly behind the surface reflects nothing onto it.
    if dot(n, c - p) <= -sphere.radius {
        return vec3f(0.0);
    }
    let s = env_sample(rand2(state), scene.env_rotation);
    if s.pdf <= 0.0 {
        return vec3f(0.0);
    }
    let x = mirror_point(p, c, sphere.radius, s.dir);
    if !x.ok {
        return vec3f(0.0);
    }
    let cos_s = dot(n, x.dir);
    if cos_s <= 0.0 || ((HAS_NORMAL_MAPS || HAS_SMOOTH_NORMALS) && dot(n_geo, x.dir) <= 0.0) {
        return vec3f(0.0);
    }
    let spread = mirror_spread(sphere.radius, x.dist, x.cos_i);
    if !(spread > 0.0) {
        return vec3f(0.0);
    }
    // To the sphere (the first thing the ray meets must be it), then from its point to the map:
    // two legs, one shadow-ray walk in the code (see sample_lens).
    let to_mirror = Ray(offset_ray(p, n_geo), x.dir);
    let t_mirror = hit_sphere(sphere, to_mirror, T_FAR);
    if t_mirror <= 0.0 {
        return vec3f(0.0);
    }
    for (var leg = 0u; leg < 2u; leg++) {
        var shadow = to_mirror;
        var t = t_mirror;
        var skip = prim;
        if leg == 1u {
            shadow = Ray(offset_ray(p + x.dir * x.dist, x.normal), s.dir);
            t = T_FAR;
            skip = EMPTY_SLOT;
        }
        if occluded(shadow, t, skip) {
            return vec3f(0.0);
        }
    }
    // What the mirror reflects: the lecture's specular tint, or glTF's Fresnel at the angle
    // of incidence; glass, the chance that scatter_dielectric reflects there and its tint.
    let m = materials[sphere.material];
    var reflectance = m.specular_color;
    if m.smoothness < 0.0 {
        reflectance = m.color * schlick(x.cos_i, 1.0 / m.ior);
    } else if follows_pbr(m) {
        reflectance = pbr_mirror_reflectance(pbr_lobe(m, -x.dir, x.normal, true), x.cos_i);
    }
    let radiance = s.radiance * scene.env_intensity * reflectance;
    return weighed(radiance, p, x.dir, cos_s, mirror_pdf(s.pdf, spread), pbr, lobe, gloss, view);
}

// Where a ray from origin, a point of the camera's lens, along unit dir crosses the focus
// plane, in pixels (x to the right, y down, as camera_ray counts them), and the density in
// solid angle with which camera_ray draws dir from origin for that pixel: distance² over the
// cosine and the pixel's area on the plane; z = 0 behind the plane (src/cpu/trace.rs:
// pixel_at, which says why).
fn pixel_at(origin: vec3f, dir: vec3f) -> vec3f {
    let h = scene.cam_horizontal;
    let v = scene.cam_vertical;
    let centre = scene.cam_to_corner + 0.5 * h - 0.5 * v;
    let ahead = normalize(centre);
    let cos = dot(dir, ahead);
    if cos <= 0.0 {
        return vec3f(0.0);
    }
    let lens = origin - scene.cam_origin;
    let dist = dot(centre - lens, ahead) / cos;
    let q = lens + dist * dir - scene.cam_to_corner;
    let h2 = dot(h, h);
    let v2 = dot(v, v);
    let w = f32(scene.width);
    let ht = f32(scene.height);
    let area = sqrt(h2 * v2) / (w * ht);
    return vec3f(dot(q, h) / h2 * w, -dot(q, v) / v2 * ht, dist * dist / (cos * area));
}

// A light sample's estimate for the lobe light sampling weighs (light_weighted), or, from the
// camera (view: the pixel; x < 0 for none), for that pixel's camera rays (view_weighted)
// (src/cpu/trace.rs: weighed).
fn weighed(radiance: vec3f, p: vec3f, dir: vec3f, cos_s: f32, pl: f32, pbr: bool, lobe: PbrLobe, gloss: Gloss, view: vec2i) -> vec3f {
    if view.x >= 0 {
        return view_weighted(radiance, p, dir, pl, vec2u(view));
    }
    return light_weighted(radiance, dir, cos_s, pl, pbr, lobe, gloss);
}

// A light sample of density pl that reaches the camera's lens point p along dir, as an
// estimate of pixel px's value, weighed by the power heuristic against the pixel's camera
// rays (src/cpu/trace.rs: view_weighted).
fn view_weighted(radiance: vec3f, p: vec3f, dir: vec3f, pl: f32, px: vec2u) -> vec3f {
    let v = pixel_at(p, dir);
    if v.z > 0.0 && floor(v.x) == f32(px.x) && floor(v.y) == f32(px.y) {
        return radiance / (v.z / pl + pl / v.z);
    }
    return vec3f(0.0);
}

// The environment map's light that the camera sees in the mirror spheres and through the
// glass spheres light sampling samples, for pixel px whose camera ray is primary:
// sample_mirror and sample_lens from the ray's lens point, counted where their paths cross
// the focus plane inside the pixel (src/cpu/trace.rs: sample_view, which says why).
fn sample_view(px: vec2u, primary: Ray, state: ptr<function, Rng>) -> vec3f {
    let ahead = normalize(scene.cam_to_corner + 0.5 * scene.cam_horizontal - 0.5 * scene.cam_vertical);
    let gloss = cosine_lobe(ahead);
    var sum = vec3f(0.0);
    // Camera, mirror, map: one scattering.
    if HAS_MIRROR_NEE && scene.max_bounces >= 1u && view_meets(primary, scene.n_lights, scene.n_mirrors + scene.n_lenses) {
        sum += sample_mirror(primary.origin, ahead, ahead, false, PbrLobe(), gloss, vec2i(px), state);
    }
    // Camera, into the glass, (a reflection inside,) out, map: two scatterings (three).
    if HAS_LENS_NEE && scene.max_bounces >= 2u && view_meets(primary, scene.n_lights + scene.n_mirrors, scene.n_lenses) {
        let inner = u32(scene.max_bounces >= 3u);
        sum += sample_lens(primary.origin, ahead, ahead, false, PbrLobe(), gloss, vec2i(px), inner, state);
    }
    return sum;
}

// Whether the pixel of camera ray primary may see one of the `count` spheres whose entries in
// the lights' buffer begin at `first`: some sphere's cone from the ray's lens point meets the
// cone of the pixel's rays, within β of the ray, sin β = the pixel's diagonal / the focus
// distance (src/cpu/trace.rs: view_meets).
fn view_meets(primary: Ray, first: u32, count: u32) -> bool {
    let h = scene.cam_horizontal / f32(scene.width);
    let v = scene.cam_vertical / f32(scene.height);
    let focus = length(scene.cam_to_corner + 0.5 * scene.cam_horizontal - 0.5 * scene.cam_vertical);
    let sin_b = min(sqrt(dot(h, h) + dot(v, v)) / focus, 1.0);
    let cos_b = sqrt(1.0 - sin_b * sin_b);
    for (var k = 0u; k < count; k++) {
        let sphere = spheres[lights[first + k].prim];
        let to = sphere_center(sphere) - primary.origin;
        let d2 = dot(to, to);
        let r2 = sphere.radius * sphere.radius;
        if d2 <= r2 {
            return true;
        }
        // cos of the angle to the centre against cos(α + β), α the sphere's half-angle.
        let sin_a = sqrt(r2 / d2);
        let cos_a = sqrt(1.0 - r2 / d2);
        if dot(primary.dir, to) >= sqrt(d2) * (cos_a * cos_b - sin_a * sin_b) {
            return true;
        }
    }
    return false;
}

// The density, in solid angle at the point that sees it, with which sample_lens finds the
// map's direction of density pdf through a glass sphere of spread `spread`.
fn lens_pdf(pdf: f32, spread: f32) -> f32 {
    return pdf / (f32(scene.n_lenses) * spread);
}

// The spread of the path's glass-sphere path, which left its sphere toward dir, where
// sample_lens finds it (lens_spread_of), else 0 (src/cpu/trace.rs: lens_spread).
fn lens_spread(path: Path, dir: vec3f) -> f32 {
    let sphere = spheres[path.lens_sphere];
    let c = sphere_center(sphere);
    var f = lens_frame(path.lens_from, c, sphere.radius, materials[sphere.material].ior, dir);
    if !f.ok {
        return 0.0;
    }
    f.inner = path.lens_inner;
    return lens_spread_of(f, path.lens_from, c, sphere.radius, path.lens_dir);
}

// The path's glass-sphere path after the ray met `hit` (scattered false) or after the
// surface there scattered it toward `dir` (scattered true): a ray of a lobe light sampling
// weighs (drawn > 0: its density, or the camera's, sample_view) that meets one of the glass
// spheres from outside starts one (stage 1); it goes on while the ray refracts in (2), meets
// the sphere from inside (3), reflects there at most once (2 again) and refracts out (4), and
// ends (0) at anything else (src/cpu/trace.rs: lens_step).
fn lens_step(path: ptr<function, Path>, hit: Hit, ray: Ray, n_out: vec3f, drawn: f32, scattered: bool, dir: vec3f) {
    let stage = (*path).lens_stage;
    if scattered {
        let inward = dot(dir, n_out) < 0.0;
        if stage == 1u && inward {
            (*path).lens_stage = 2u;
        } else if stage == 3u && !inward {
            (*path).lens_stage = 4u;
        } else if stage == 3u && (*path).lens_inner == 0u {
            (*path).lens_stage = 2u;
            (*path).lens_inner = 1u;
        } else {
            (*path).lens_stage = 0u;
        }
        return;
    }
    let same = hit.kind == KIND_SPHERE && hit.index == (*path).lens_sphere;
    if stage == 2u && same && dot(ray.dir, n_out) >= 0.0 {
        (*path).lens_stage = 3u;
        return;
    }
    (*path).lens_stage = 0u;
    if drawn > 0.0 && hit.kind == KIND_SPHERE && dot(ray.dir, n_out) < 0.0 {
        var listed = false;
        let first = scene.n_lights + scene.n_mirrors;
        for (var k = 0u; k < scene.n_lenses; k++) {
            listed = listed || lights[first + k].prim == hit.index;
        }
        if listed {
            (*path).lens_stage = 1u;
            (*path).lens_sphere = hit.index;
            (*path).lens_from = (*path).prev_point;
            (*path).lens_dir = ray.dir;
            (*path).lens_pdf = drawn;
            (*path).lens_inner = 0u;
        }
    }
}

// The environment map's light as a clear glass sphere refracts it onto p (src/cpu/trace.rs:
// sample_lens, which says how): one of the glass spheres chosen evenly, a direction from the
// map's distribution, and every path from p through the sphere toward it, with up to `inner`
// reflections inside, each with its legs unoccluded, tinted by the glass at each interface
// and by the chance of the path's refractions and reflection, MIS-weighted against the lobe
// (or, from the camera, view: the pixel, against its camera rays).
fn sample_lens(p: vec3f, n: vec3f, n_geo: vec3f, pbr: bool, lobe: PbrLobe, gloss: Gloss, view: vec2i, inner: u32, state: ptr<function, Rng>) -> vec3f {
    let count = scene.n_lenses;
    var pick = 0.0;
    if count > 1u {
        pick = rand(state);
    }
    let prim = lights[scene.n_lights + scene.n_mirrors + min(u32(pick * f32(count)), count - 1u)].prim;
    let sphere = spheres[prim];
    let c = sphere_center(sphere);
    let r = sphere.radius;
    if dot(n, c - p) <= -r {
        return vec3f(0.0);
    }
    let s = env_sample(rand2(state), scene.env_rotation);
    let m = materials[sphere.material];
    if s.pdf <= 0.0 {
        return vec3f(0.0);
    }
    var f = lens_frame(p, c, r, m.ior, s.dir);
    if !f.ok {
        return vec3f(0.0);
    }
    let radiance = s.radiance * scene.env_intensity;
    // The paths through the sphere, then those with a reflection inside, in one loop: a warp
    // waits for its lanes' largest count of paths in all rather than for the largest of each
    // kind in turn. (src/cpu's sample_lens loops over the kinds; the sum's order is the same.)
    let through = lens_roots(f);
    var bounced = LensRoots(vec3f(0.0), 0u);
    if inner > 0u {
        f.inner = 1u;
        bounced = lens_roots(f);
    }
    var sum = vec3f(0.0);
    for (var k = 0u; k < through.count + bounced.count; k++) {
        let reflections = select(0u, 1u, k >= through.count);
        f.inner = reflections;
        var root: f32;
        // The lecture's glass: its tint at each interface, once more at the reflection.
        var tint = vec3f(1.0);
        if reflections == 0u {
            root = through.s[k];
        } else {
            root = bounced.s[k - through.count];
            tint = m.color;
        }
        let x = lens_path(f, p, c, r, root);
        if !x.ok {
            continue;
        }
        let cos_s = dot(n, x.dir);
        if cos_s <= 0.0 || ((HAS_NORMAL_MAPS || HAS_SMOOTH_NORMALS) && dot(n_geo, x.dir) <= 0.0) {
            continue;
        }
        // To the sphere (the first thing the ray meets must be it), across it (twice, with a
        // reflection inside), and from where it leaves to the map: its legs in that order,
        // through one call of the shadow-ray walk. (Each call site is a copy of the BVH walk
        // in the compiled kernel; written out per leg, with sample_mirror's, they cost
        // `glass` 1.7× in samples/s on an H100: BENCHMARKS.md, "Glass on the GPU".)
        let to_lens = Ray(offset_ray(p, n_geo), x.dir);
        let t_lens = hit_sphere(sphere, to_lens, T_FAR);
        if t_lens <= 0.0 {
            continue;
        }
        let entry = p + x.dir * x.dist;
        let chord = x.turn - entry;
        // Legs: 0 to the sphere, 1 across it, (2 back, after a reflection,) the last out.
        let back = x.exit - x.turn;
        let legs = 3u + min(reflections, 1u);
        var clear = true;
        for (var leg = 0u; leg < legs && clear; leg++) {
            var shadow = to_lens;
            var t = t_lens;
            if leg == 1u {
                shadow = Ray(entry, normalize(chord));
                t = length(chord);
            } else if leg + 1u == legs {
                shadow = Ray(offset_ray(x.exit, x.exit_normal), s.dir);
                t = T_FAR;
            } else if leg == 2u {
                shadow = Ray(x.turn, normalize(back));
                t = length(back);
            }
            clear = !occluded(shadow, t, prim);
        }
        if !clear {
            continue;
        }
        // The path's length inside, where the medium attenuates it.
        var inside = length(chord);
        if reflections > 0u {
            inside += length(back);
        }
        var carried: vec3f;
        if follows_pbr(m) {
            // glTF's: its Fresnel, share and tint at each interface, and the medium's
            // attenuation over the path inside (KHR_materials_volume).
            carried = radiance * pbr_lens_transmittance(m, x.cos_i, x.cos_r, reflections) * exp(-m.attenuation * inside);
        } else {
            carried = radiance * m.color * m.color * tint * lens_transmittance(m.ior, x.cos_i, x.cos_r, reflections);
        }
        sum += weighed(carried, p, x.dir, cos_s, lens_pdf(s.pdf, x.spread), pbr, lobe, gloss, view);
    }
    return sum;
}

// What a ray that leaves the scene sees: the environment map (MIS-weighted where light
// sampling could have found its direction, or where it leaves a mirror sphere or a glass
// sphere through which sample_mirror or sample_lens samples the map), or the sky; a camera
// ray sees the sky behind a map that is not visible.
fn escaped(path: Path, dir: vec3f) -> vec3f {
    if HAS_ENV_MAP && scene.env_mode != ENV_NONE && (path.bounce > 0u || scene.env_mode == ENV_VISIBLE) {
        var w = 1.0;
        let pe = env_pick();
        // The map coordinates once, for the radiance and the density.
        let c = env_coordinates(dir, scene.env_rotation);
        if HAS_NEE && path.prev_pdf > 0.0 && pe > 0.0 {
            w = power_heuristic(path.prev_pdf, pe * env_pdf_at(c));
        } else if HAS_MIRROR_NEE && path.mirror.x > 0.0 {
            w = power_heuristic(path.mirror.x, mirror_pdf(env_pdf_at(c), path.mirror.y));
        } else if HAS_LENS_NEE && path.lens_stage == 4u {
            let spread = lens_spread(path, dir);
            if spread > 0.0 {
                w = power_heuristic(path.lens_pdf, lens_pdf(env_pdf_at(c), spread));
            }
        }
        return env_lookup(c) * scene.env_intensity * w;
    }
    return sky(dir);
}

// A path being traced: the ray of its next segment and what the segments so far have found.
// MIS state: the solid-angle density with which the last bounce sampled the current ray
// (0: a delta lobe or the camera, which light sampling could not have matched), and the point
// and facing normal it sampled from (light selection depends on both).
struct Path {
    ray: Ray,
    throughput: vec3f,
    radiance: vec3f,
    bounce: u32,
    prev_pdf: f32,
    prev_point: vec3f,
    prev_normal: vec3f,
    // The last bounce ran no mirror or lens sampler for the ray it drew: drawn through the
    // surface (glTF's transmission), or from inside a volume.
    prev_unsampled: bool,
    // Where the ray leaves a mirror sphere that sample_mirror samples, met right after a lobe
    // light sampling weighs: (that lobe's density, the sphere's spread), else zeros.
    mirror: vec2f,
    // A path through a glass sphere that sample_lens samples, begun right after a lobe light
    // sampling weighs (lens_step): its stage (0: none), the sphere, the point the lobe drew
    // from, the ray's direction and the lobe's density, and its reflections inside so far.
    lens_stage: u32,
    lens_sphere: u32,
    lens_from: vec3f,
    lens_pdf: f32,
    lens_dir: vec3f,
    lens_inner: u32,
}

fn path_start(primary: Ray) -> Path {
    return Path(primary, vec3f(1.0), vec3f(0.0), 0u, 0.0, primary.origin, vec3f(0.0, 1.0, 0.0), false, vec2f(0.0), 0u, 0u, vec3f(0.0), 0.0, vec3f(0.0), 0u);
}

// One segment of a path (MODEL.md "Scattering"): traces its ray and either ends the path
// (true: its radiance is final) or scatters into the next ray. At most max_bounces
// scatterings, and the ray leaving the last one is still traced, so at most max_bounces + 1
// segments.
fn path_step(path: ptr<function, Path>, state: ptr<function, Rng>) -> bool {
    let ray = (*path).ray;
    let bounce = (*path).bounce;
    let nee = HAS_NEE && (scene.n_lights > 0u || env_pick() > 0.0);
    let hit = intersect_scene(ray);
    if hit.kind == KIND_NONE {
        (*path).radiance += (*path).throughput * escaped(*path, ray.dir);
        return true;
    }
    let surf = surface_at(hit, ray);
    let sh = material_at(hit, surf);
    let m = sh.m;
    // A mirror sphere met from a lobe light sampling weighs: what it reflects from the map
    // next is weighed against sample_mirror.
    // The camera ray's density (sample_view) stands for a lobe's at the first hit.
    var drawn = (*path).prev_pdf;
    if (HAS_MIRROR_NEE || HAS_LENS_NEE) && bounce == 0u && nee {
        drawn = pixel_at(ray.origin, ray.dir).z;
    }
    // A ray drawn through a surface is none that those samplers find (they sample on the
    // side of the normal), nor one drawn inside a volume, where they do not run.
    if HAS_PBR_TRANSMISSION && (*path).prev_unsampled {
        drawn = 0.0;
    }
    // Without light sampling (switched off) no sampler finds them: the lobe's paths are the
    // only ones, and weigh 1.
    if !nee {
        drawn = 0.0;
    }
    if HAS_MIRROR_NEE {
        (*path).mirror = mirror_hit(hit, ray, surf.point.position, surf.point.normal, drawn, (*path).prev_point);
    }
    if HAS_LENS_NEE {
        lens_step(path, hit, ray, surf.point.normal, drawn, false, vec3f(0.0));
    }
    // Inside a volume's boundary the medium attenuates, by Beer–Lambert's law over the
    // segment's length (KHR_materials_volume; a closed mesh, not nested).
    if HAS_PBR_TRANSMISSION && m.transmission > 0.0 && dot(ray.dir, surf.point.normal) > 0.0 {
        (*path).throughput *= exp(-m.attenuation * hit.t);
    }
    if HAS_EMITTERS && m.light > 0.0 {
        var w = 1.0;
        if nee && (*path).prev_pdf > 0.0 && m.light_slot > 0u {
            let choice = (1.0 - env_pick())
                * light_choice_pmf(m.light_slot - 1u, (*path).prev_point, (*path).prev_normal);
            let pl = choice * light_pdf(hit, (*path).prev_point, surf.point.position);
            w = power_heuristic((*path).prev_pdf, pl);
        }
        (*path).radiance += (*path).throughput * m.color * m.light * w;
        return true;
    }
    if bounce == scene.max_bounces {
        return true;
    }
    let n_out = surf.point.normal;
    var sc: Scatter;
    (*path).prev_pdf = 0.0;
    (*path).prev_unsampled = false;
    if HAS_DIELECTRICS && m.smoothness < 0.0 {
        sc = scatter_dielectric(m, ray.dir, n_out, state);
        if HAS_LENS_NEE {
            lens_step(path, hit, ray, n_out, 0.0, true, sc.dir);
        }
    } else {
        // The lecture's lobes, or glTF's BRDF (common/pbr.wgsl); one light-sampling call for
        // both (inlined once: a second call site cost the H200 half its speed on pbr scenes).
        // A scene of glTF materials alone (no HAS_LECTURE) compiles none of the lecture's
        // lobes.
        let pbr = follows_pbr(m);
        // A certain lobe takes no draw.
        let is_spec = !pbr && (m.specular >= 1.0 || (m.specular > 0.0 && rand(state) < m.specular));
        let front = dot(ray.dir, n_out) < 0.0;
        let n = select(-n_out, n_out, front);
        let ns = shading_normal_at(sh, hit, surf.local, n_out, n);
        var lobe = PbrLobe();
        // The lecture's glossy lobe: the specular one blended with the diffuse direction,
        // without fuzz (src/scene/model.rs: Material::is_glossy). Taken at a probability below
        // 1, light sampling weighs its mixture with the cosine lobe whichever lobe was drawn.
        var gloss = cosine_lobe(ns);
        var tint = select(m.color, m.specular_color, is_spec);
        if HAS_GLOSS_NEE && !pbr && m.specular > 0.0 && m.smoothness > 0.0 && m.smoothness < 1.0 && m.absorption == 0.0 {
            gloss = Gloss(ns, reflect(ray.dir, ns), m.smoothness, m.specular, m.specular_color, m.color);
            if m.specular < 1.0 {
                tint = vec3f(1.0);
            }
        }
        // A lobe with a density light sampling can weigh: the Lambertian one, the lecture's
        // specular one at smoothness 0 (the same distribution, its own tint) or glossy, or
        // glTF's but for its mirror and, where it transmits wholly (no diffuse share), its
        // glass; a rough clear coat has one over either.
        var light_lobe = !is_spec || m.smoothness == 0.0 || gloss.s > 0.0;
        var inside = false;
        if pbr {
            lobe = pbr_lobe(m, -ray.dir, ns, front);
            // Inside a volume's boundary (a solid: closed, not nested) the mirror and lens
            // spheres lie beyond the surface, which the shadow rays on this side meet first:
            // those samplers would find nothing here, and do not run.
            inside = HAS_PBR_TRANSMISSION && !front && m.transmission > 0.0 && m.thin == 0u;
            light_lobe = lobe.alpha >= PBR_ALPHA_MIN || (lobe.p_spec < 1.0 && lobe.transmission < 1.0) || (lobe.coat > 0.0 && lobe.coat_alpha >= PBR_ALPHA_MIN);
            tint = vec3f(1.0);
        }
        if nee && light_lobe {
            (*path).radiance += (*path).throughput * tint * sample_light(surf.point.position, ns, n, pbr, lobe, gloss, state);
            // The map in the mirror spheres: its paths scatter here and at the mirror, and
            // leave it, within the bounces allowed.
            if HAS_MIRROR_NEE && !inside && scene.n_mirrors + scene.n_lenses > 0u && bounce + 2u <= scene.max_bounces {
                (*path).radiance += (*path).throughput * tint * sample_mirror(surf.point.position, ns, n, pbr, lobe, gloss, vec2i(-1), state);
            }
            // The map through the glass spheres: its paths scatter here, refract in and out,
            // and leave, within the bounces allowed.
            // With a reflection inside, one bounce more.
            if HAS_LENS_NEE && !inside && scene.n_lenses > 0u && bounce + 3u <= scene.max_bounces {
                let inner = u32(bounce + 4u <= scene.max_bounces);
                (*path).radiance += (*path).throughput * tint * sample_lens(surf.point.position, ns, n, pbr, lobe, gloss, vec2i(-1), inner, state);
            }
        }
        var pbr_pdf = 0.0;
        var through = false;
        if pbr {
            let ps = pbr_sample(lobe, state);
            sc = Scatter(ps.dir, ps.weight, !ps.ok);
            // A glass-sphere path goes on through glTF's smooth glass by its deltas alone
            // (src/scene/model.rs: Material::is_lens).
            if HAS_LENS_NEE {
                if ps.pdf == 0.0 {
                    lens_step(path, hit, ray, n_out, 0.0, true, ps.dir);
                } else {
                    (*path).lens_stage = 0u;
                }
            }
            // Where light sampling finds no direction through the surface (transmits), a
            // light the transmitted ray meets counts fully.
            pbr_pdf = select(ps.pdf, 0.0, ps.through && !(nee && light_lobe && transmits(pbr, lobe)));
            through = ps.through;
        } else {
            sc = scatter_surface(m, ray.dir, ns, is_spec, state);
        }
        // A direction that the shading normal allows but that enters the surface (or, drawn
        // through it, leaves it) ends the path (the light a normal map cannot send there is
        // lost, not leaked).
        let side = dot(sc.dir, n);
        if (HAS_NORMAL_MAPS || HAS_SMOOTH_NORMALS) && select(side <= 0.0, side >= 0.0, through) {
            sc.absorbed = true;
        }
        if pbr {
            (*path).prev_pdf = pbr_pdf;
            (*path).prev_normal = ns;
            (*path).prev_unsampled = through || inside;
        } else if light_lobe {
            (*path).prev_pdf = lobe_pdf(gloss, sc.dir, ns);
            (*path).prev_normal = ns;
        }
    }
    if sc.absorbed {
        return true;
    }
    var throughput = (*path).throughput * sc.attenuation;
    (*path).prev_point = surf.point.position;
    // Russian roulette (Arvo & Kirk 1990), unbiased: a survivor's throughput is divided by
    // its survival probability. With light sampling only, so that the exact furnace tests
    // (no lights) keep zero variance.
    if nee && bounce >= RR_START {
        let q = min(max(max(throughput.x, throughput.y), throughput.z), RR_MAX_SURVIVAL);
        if rand(state) >= q {
            return true;
        }
        throughput /= q;
    }
    (*path).throughput = throughput;
    let side = select(-n_out, n_out, dot(sc.dir, n_out) > 0.0);
    (*path).ray = Ray(offset_ray(surf.point.position, side), sc.dir);
    (*path).bounce = bounce + 1u;
    return false;
}

fn fixed_load(buf: u32, pixel: u32) -> Fixed {
    let b = pixel * ACCUM_WORDS;
    var w: array<u32, 10>;
    for (var i = 0u; i < ACCUM_WORDS; i++) {
        w[i] = select(accum_odd[b + i], accum_even[b + i], buf == 0u);
    }
    return fixed_from_words(w);
}

fn fixed_store(buf: u32, pixel: u32, f: Fixed) {
    let b = pixel * ACCUM_WORDS;
    let w = fixed_to_words(f);
    for (var i = 0u; i < ACCUM_WORDS; i++) {
        if buf == 0u {
            accum_even[b + i] = w[i];
        } else {
            accum_odd[b + i] = w[i];
        }
    }
}

// One lane's sums of its samples of a pixel, even then odd: 2 * ACCUM_WORDS words per slot.
fn scratch_store(slot: u32, even: Fixed, odd: Fixed) {
    let b = slot * 2u * ACCUM_WORDS;
    let e = fixed_to_words(even);
    let o = fixed_to_words(odd);
    for (var i = 0u; i < ACCUM_WORDS; i++) {
        scratch[b + i] = e[i];
        scratch[b + ACCUM_WORDS + i] = o[i];
    }
}

// True if any component is NaN or infinite, by the exponent bits: WGSL lets compilers assume
// floats are finite, so `x != x` may be folded away.
fn not_finite(v: vec3f) -> bool {
    let e = bitcast<vec3u>(v) & vec3u(0x7f800000u);
    return any(e == vec3u(0x7f800000u));
}

fn add_u64(lo_index: u32, n: u32) {
    if n == 0u {
        return;
    }
    let old = atomicAdd(&counters[lo_index], n);
    if old > 0xffffffffu - n {
        atomicAdd(&counters[lo_index + 1u], 1u);
    }
}

var<workgroup> wg_segments: atomic<u32>;
var<workgroup> wg_visits: atomic<u32>;
var<workgroup> wg_tests: atomic<u32>;

// One invocation per pixel and lane: lane `gid.z` of `batch.lanes` traces samples
// sample_base + lane, + lanes, … of the round's sample_count. With one lane it adds them to
// the pixel's sums; with more, each lane writes its own sums to `scratch` and the reduce pass
// (src/gpu/reduce.rs) adds the lanes into the accumulation. Fixed-point sums are exact and
// every sample has its own random stream, so the result is the same bit for bit however the
// samples are spread over lanes, rounds and submissions.
@compute @workgroup_size(8, 8, 1)
fn trace(@builtin(global_invocation_id) gid: vec3u, @builtin(local_invocation_index) lid: u32) {
    let px = vec2u(gid.x, batch.row_offset + gid.y * batch.row_stride);
    let lane = gid.z;
    let in_image = gid.x < scene.width && gid.y < batch.row_count && px.y < scene.height
        && lane < batch.lanes;
    var segments = 0u;
    if in_image {
        let pixel = px.y * scene.width + px.x;
        var even = fixed_zero();
        var odd = even;
        if batch.lanes == 1u && batch.accumulate != 0u {
            even = fixed_load(0u, pixel);
            odd = fixed_load(1u, pixel);
        }
        var invalid = 0u;
        // One loop over the segments of all this lane's paths, a finished path replaced by the
        // next sample's at once (path regeneration: Novák, Havran & Dachsbacher, "Path
        // Regeneration for Interactive Path Tracing", Eurographics 2010 short papers). With a
        // loop over samples around a loop over bounces, a warp waited at every sample for its
        // longest path; here it waits once, for the lane with the most segments in all.
        var i = lane;
        var state: Rng;
        var path: Path;
        var fresh = true;
        while i < batch.sample_count {
            if fresh {
                state = rng_init(pixel, batch.sample_base + i, scene.seed);
                path = path_start(camera_ray(px, &state));
                // The map in the mirror spheres and through the glass spheres, seen from the
                // camera.
                if (HAS_MIRROR_NEE || HAS_LENS_NEE) && HAS_NEE && (scene.n_lights > 0u || env_pick() > 0.0) {
                    path.radiance += sample_view(px, path.ray, &state);
                }
                fresh = false;
            }
            segments += 1u;
            if !path_step(&path, &state) {
                continue;
            }
            let sample = batch.sample_base + i;
            if not_finite(path.radiance) {
                invalid += 1u;
            } else if (sample & 1u) == 0u {
                fixed_add(&even, path.radiance);
            } else {
                fixed_add(&odd, path.radiance);
            }
            i += batch.lanes;
            fresh = true;
        }
        if batch.lanes == 1u {
            fixed_store(0u, pixel, even);
            fixed_store(1u, pixel, odd);
        } else {
            scratch_store((lane * batch.row_count + gid.y) * scene.width + gid.x, even, odd);
        }
        add_u64(0u, invalid);
    }
    if COUNT_SEGMENTS {
        if lid == 0u {
            atomicStore(&wg_segments, 0u);
            atomicStore(&wg_visits, 0u);
            atomicStore(&wg_tests, 0u);
        }
        workgroupBarrier();
        atomicAdd(&wg_segments, segments);
        atomicAdd(&wg_visits, visits);
        atomicAdd(&wg_tests, tests);
        workgroupBarrier();
        if lid == 0u {
            add_u64(2u, atomicLoad(&wg_segments));
            add_u64(4u, atomicLoad(&wg_visits));
            add_u64(6u, atomicLoad(&wg_tests));
        }
    }
}

// ---- The denoiser's guides (src/denoise; docs/MODEL-NOTES.md, "Denoising") ----
// Per pixel, the albedo and the shading normal of the first surface that is not a perfect
// specular one, seen through mirrors and clear glass as Open Image Denoise defines its guides:
// `GUIDE_WORDS` words, the fixed-point sums (1/65535 steps, exact in any order) of the albedo's
// three channels and of the normal's mapped to [0, 1], and the sample count. Their own random
// streams (the seed xor GUIDE_SEED), so that they are independent of both halves of the
// radiance. Entry point `guides`, compiled only where a render denoises.
const GUIDE_WORDS: u32 = 7u;
const GUIDE_SEED: u32 = 0x6a09e667u;
const GUIDE_SPECULAR_DEPTH: u32 = 4u;

@group(1) @binding(0) var<storage, read_write> guide_sums: array<u32>;

struct Guide {
    albedo: vec3f,
    normal: vec3f,
}

fn guide_of(primary: Ray) -> Guide {
    var ray = primary;
    var tint = vec3f(1.0);
    for (var depth = 0u; depth <= GUIDE_SPECULAR_DEPTH; depth++) {
        let hit = intersect_scene(ray);
        if hit.kind == KIND_NONE {
            return Guide(tint, vec3f(0.0));
        }
        let surf = surface_at(hit, ray);
        let sh = material_at(hit, surf);
        let m = sh.m;
        let n_out = surf.point.normal;
        let front = dot(ray.dir, n_out) < 0.0;
        let n = select(-n_out, n_out, front);
        if HAS_EMITTERS && m.light > 0.0 {
            return Guide(tint * m.color, n);
        }
        let last = depth == GUIDE_SPECULAR_DEPTH;
        if HAS_DIELECTRICS && m.smoothness < 0.0 {
            if m.absorption > 0.0 || last {
                return Guide(tint * m.color, n);
            }
            // Clear glass: through it where it refracts, else by total internal reflection.
            let ratio = select(m.ior, 1.0 / m.ior, front);
            let cos_theta = min(dot(-ray.dir, n), 1.0);
            let sin_theta = sqrt(max(0.0, 1.0 - cos_theta * cos_theta));
            var dir = normalize(reflect(ray.dir, n));
            if ratio * sin_theta <= 1.0 {
                dir = normalize(refract_dir(ray.dir, n, cos_theta, ratio));
            }
            tint *= m.color;
            let side = select(-n_out, n_out, dot(dir, n_out) > 0.0);
            ray = Ray(offset_ray(surf.point.position, side), dir);
            continue;
        }
        let ns = shading_normal_at(sh, hit, surf.local, n_out, n);
        if m.specular >= 1.0 && m.smoothness >= 1.0 && m.absorption == 0.0 && !last {
            // A perfect mirror.
            tint *= m.specular_color;
            let dir = reflect(ray.dir, ns);
            let side = select(-n_out, n_out, dot(dir, n_out) > 0.0);
            ray = Ray(offset_ray(surf.point.position, side), dir);
            continue;
        }
        let s = clamp(m.specular, 0.0, 1.0);
        return Guide(tint * mix(m.color, m.specular_color, s), ns);
    }
    return Guide(tint, vec3f(0.0));
}

fn guide_quantize(v: f32) -> u32 {
    return u32(clamp(v, 0.0, 1.0) * 65535.0 + 0.5);
}

// One invocation per pixel of the image: adds guide samples sample_base .. + sample_count to
// the pixel's sums (restarted when `accumulate` is 0).
@compute @workgroup_size(8, 8, 1)
fn guides(@builtin(global_invocation_id) gid: vec3u) {
    if gid.x >= scene.width || gid.y >= scene.height {
        return;
    }
    let px = gid.xy;
    let pixel = px.y * scene.width + px.x;
    let b = pixel * GUIDE_WORDS;
    var sums: array<u32, 7>;
    if batch.accumulate != 0u {
        for (var i = 0u; i < GUIDE_WORDS; i++) {
            sums[i] = guide_sums[b + i];
        }
    }
    for (var i = 0u; i < batch.sample_count; i++) {
        var state = rng_init(pixel, batch.sample_base + i, scene.seed ^ GUIDE_SEED);
        let g = guide_of(camera_ray(px, &state));
        let nm = g.normal * 0.5 + 0.5;
        sums[0] += guide_quantize(g.albedo.x);
        sums[1] += guide_quantize(g.albedo.y);
        sums[2] += guide_quantize(g.albedo.z);
        sums[3] += guide_quantize(nm.x);
        sums[4] += guide_quantize(nm.y);
        sums[5] += guide_quantize(nm.z);
        sums[6] += 1u;
    }
    for (var i = 0u; i < GUIDE_WORDS; i++) {
        guide_sums[b + i] = sums[i];
    }
}
