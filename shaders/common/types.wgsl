// Twin: src/common/layout.rs (tests/twins.rs keeps their functions paired).
// Scene data as the tracer sees it. Mirrored field by field by `src/common/layout.rs`
// (byte offsets in the comments; a test checks both against naga's layout).
//
// The per-scene and per-dispatch values (`SceneUniforms`, `DispatchUniforms`, `ResolveUniforms`)
// are declared `var<uniform>`; on lavapipe they are bound as read-only storage buffers instead
// (src/gpu/mod.rs, `Values`, says why).

struct SceneUniforms {
    cam_origin: vec3f,      //   0  look_from
    lens_radius: f32,       //  12  aperture / 2
    cam_to_corner: vec3f,   //  16  upper-left corner of the focus plane, relative to cam_origin
    n_lights: u32,          //  28  lights sampled by next-event estimation (0: none)
    cam_horizontal: vec3f,  //  32  full width of the focus plane
    n_instances: u32,       //  44  copies of instanced meshes (the BVH's top level names them)
    cam_vertical: vec3f,    //  48  full height of the focus plane, pointing up
    n_mirrors: u32,         //  60  mirror spheres light sampling reflects the map in (after the lights)
    cam_u: vec3f,           //  64  lens basis (right)
    n_lenses: u32,          //  76  glass spheres light sampling refracts the map through (after the mirrors)
    cam_v: vec3f,           //  80  lens basis (up)
    _pad4: f32,             //  92
    sky_bottom: vec3f,      //  96  radiance of a uniform sky, or the gradient's bottom
    sky_uniform: u32,       // 108  1: one constant radiance (sky_bottom)
    sky_top: vec3f,         // 112
    _pad5: f32,             // 124
    sun_dir: vec3f,         // 128  unit vector towards the sun
    sun_size: f32,          // 140  exponent of max(dot(sun_dir, dir), 0)
    sun_radiance: vec3f,    // 144  colour * intensity; zero without a sun
    _pad6: f32,             // 156
    width: u32,             // 160
    height: u32,            // 164
    max_bounces: u32,       // 168
    seed: u32,              // 172
    n_spheres: u32,         // 176
    n_quads: u32,           // 180
    n_boxes: u32,           // 184
    n_triangles: u32,       // 188
    // The environment map (common/envmap.wgsl), where the scene has one.
    env_rotation: f32,      // 192  radians about +y
    env_intensity: f32,     // 196
    env_pick: f32,          // 200  probability that light sampling picks the map (0: never)
    env_mode: u32,          // 204  0: no map; 1: a map camera rays do not see; 2: seen by all
}                           // 208

// What one submission traces: rows [row_offset, row_offset + row_count) of the image,
// samples [sample_base, sample_base + sample_count) of every pixel in them.
struct DispatchUniforms {
    sample_base: u32,       //   0
    sample_count: u32,      //   4
    row_offset: u32,        //   8
    row_count: u32,         //  12
    accumulate: u32,        //  16  the lecture's should_accumulate: 0 starts the sums afresh
    lanes: u32,             //  20  invocations per pixel (samples traced in parallel; 1: none)
    row_stride: u32,        //  24  the rows are row_offset, + row_stride, …
    _pad2: u32,             //  28
}                           //  32

// The preview's resolve pass (shaders/resolve.wgsl).
struct ResolveUniforms {
    width: u32,             //   0  the traced image
    height: u32,            //   4
    factor: u32,            //   8  traced pixels per output pixel, each way
    out_width: u32,         //  12
    out_height: u32,        //  16
    mode: u32,              //  20  resolve: 1 adds the other devices' sums; denoise: the step
    _pad1: u32,             //  24
    _pad2: u32,             //  28
}                           //  32

struct Material {
    color: vec3f,           //   0  albedo, emission colour or glass tint (linear)
    smoothness: f32,        //  12  0 Lambertian … 1 mirror; < 0 dielectric
    specular_color: vec3f,  //  16  tint of specular bounces
    absorption: f32,        //  28  fuzz radius
    specular: f32,          //  32  probability of the specular lobe
    light: f32,             //  36  emission strength
    ior: f32,               //  40  index of refraction
    light_slot: u32,        //  44  1 + this object's index in `lights`; 0: not sampled
    metallic: f32,          //  48  pbr: glTF's metallic factor
    roughness: f32,         //  52  pbr: glTF's perceptual roughness (α = roughness²)
    model: u32,             //  56  MODEL_LECTURE or MODEL_PBR
    transmission: f32,      //  60  pbr: KHR_materials_transmission's factor
    attenuation: vec3f,     //  64  pbr: KHR_materials_volume's coefficient per unit (0 clear)
    thin: u32,              //  76  pbr: 1 a thin wall, 0 a volume's boundary (refracts)
    clearcoat: f32,         //  80  pbr: KHR_materials_clearcoat's factor
    clearcoat_roughness: f32, // 84  pbr: its perceptual roughness
    _pad0: u32,             //  88
    _pad1: u32,             //  92
}                           //  96

// Material.model.
const MODEL_LECTURE: u32 = 0u;
const MODEL_PBR: u32 = 1u;

// A sphere stored by a point on its surface (the anchor, chosen near the part of the scene
// the camera looks at) and the outward normal there, so that ray/sphere terms are computed
// relative to the anchor: precise even for a radius of 1e6 (see intersect.wgsl).
struct Sphere {
    anchor: vec3f,          //   0
    radius: f32,            //  12  signed: negative flips the normal inward
    anchor_normal: vec3f,   //  16  outward unit normal at the anchor
    material: u32,          //  28
}                           //  32

struct Quad {
    q: vec3f,               //   0  corner
    material: u32,          //  12
    u: vec3f,               //  16  first edge
    _pad0: f32,             //  28
    v: vec3f,               //  32  second edge
    _pad1: f32,             //  44
    normal: vec3f,          //  48  unit normal of cross(u, v)
    _pad2: f32,             //  60
    w: vec3f,               //  64  cross(u, v) / |cross(u, v)|², for planar coordinates
    _pad3: f32,             //  76
}                           //  80

// An oriented box: centre, half extents, and the world-from-local rotation as three axes.
struct Cuboid {
    center: vec3f,          //   0
    material: u32,          //  12
    half_extents: vec3f,    //  16
    _pad0: f32,             //  28
    axis_x: vec3f,          //  32
    _pad1: f32,             //  44
    axis_y: vec3f,          //  48
    _pad2: f32,             //  60
    axis_z: vec3f,          //  64
    _pad3: f32,             //  76
}                           //  80

// A triangle: a vertex and the two edges from it (Möller & Trumbore 1997).
struct Triangle {
    v0: vec3f,              //   0
    material: u32,          //  12
    e1: vec3f,              //  16  v1 - v0
    _pad0: f32,             //  28
    e2: vec3f,              //  32  v2 - v0
    _pad1: f32,             //  44
}                           //  48

// A four-wide node of the BVH (src/bvh/wide.rs): the bounds of its four child slots by axis,
// and for each slot an inner node (count 0, child its index), a leaf (count references from
// refs[child]) or nothing (count EMPTY_SLOT).
struct BvhNode4 {
    min_x: vec4f,           //   0
    min_y: vec4f,           //  16
    min_z: vec4f,           //  32
    max_x: vec4f,           //  48
    max_y: vec4f,           //  64
    max_z: vec4f,           //  80
    child: vec4u,           //  96
    count: vec4u,           // 112
}                           // 128

// A copy of a mesh (src/common/arrays.rs: instances): the bottom-level BVH from node `root`
// over the mesh's triangles, in its own coordinates; rows of the affine maps into them and
// back.
struct Instance {
    object_from_world: array<vec4f, 3>, //   0
    world_from_object: array<vec4f, 3>, //  48
    root: u32,              //  96
    _pad0: u32,             // 100
    _pad1: u32,             // 104
    _pad2: u32,             // 108
}                           // 112

// A light for next-event estimation: an emissive sphere or quad, picked in proportion to its
// power (src/common/arrays.rs: lights).
struct Light {
    prim: u32,              //   0  a BVH reference: kind in the top two bits, index below
    cdf: f32,               //   4  probability of picking this light or one before it
    pmf: f32,               //   8  probability of picking this light
    area: f32,              //  12  surface area (quads)
}                           //  16
