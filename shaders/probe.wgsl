// #include "common/types.wgsl"
// #include "common/sampling.wgsl"
// #include "common/intersect.wgsl"
// #include "common/material.wgsl"
// The tracer's single-ray operations run on inputs from the host, so that their float results
// can be compared with a double-precision reference (src/stability/probe.rs).

const PROBE_SPHERE: u32 = 0u;
const PROBE_QUAD: u32 = 1u;
const PROBE_SCATTER: u32 = 2u;

struct ProbeInput {
    origin: vec3f,      //   0  ray origin (sphere, quad)
    kind: u32,          //  12  PROBE_*
    dir: vec3f,         //  16  unit ray or incoming direction
    ratio: f32,         //  28  ior ratio (scatter)
    normal: vec3f,      //  32  unit normal facing the incoming direction (scatter)
    _pad0: f32,         //  44
    sphere: Sphere,     //  48
    quad: Quad,         //  80
}                       // 160

struct ProbeOutput {
    t: f32,             //   0  hit distance, or NO_HIT
    schlick: f32,       //   4
    _pad0: f32,         //   8
    _pad1: f32,         //  12
    point: vec3f,       //  16  surface point of the hit
    _pad2: f32,         //  28
    normal: vec3f,      //  32  its normal
    _pad3: f32,         //  44
    reflected: vec3f,   //  48
    _pad4: f32,         //  60
    refracted: vec3f,   //  64  (meaningless under total internal reflection)
    _pad5: f32,         //  76
}                       //  80

@group(0) @binding(0) var<storage, read> inputs: array<ProbeInput>;
@group(0) @binding(1) var<storage, read_write> outputs: array<ProbeOutput>;

@compute @workgroup_size(64, 1, 1)
fn probe(@builtin(global_invocation_id) gid: vec3u) {
    let i = gid.x;
    if i >= arrayLength(&inputs) {
        return;
    }
    let p = inputs[i];
    var o: ProbeOutput;
    o.t = NO_HIT;
    let ray = Ray(p.origin, p.dir);
    if p.kind == PROBE_SPHERE {
        o.t = hit_sphere(p.sphere, ray, 3.0e38);
        if o.t > 0.0 {
            let s = sphere_surface(p.sphere, ray, o.t);
            o.point = s.position;
            o.normal = s.normal;
        }
    } else if p.kind == PROBE_QUAD {
        o.t = hit_quad(p.quad, ray, 3.0e38);
        if o.t > 0.0 {
            let s = quad_surface(p.quad, ray, o.t);
            o.point = s.position;
            o.normal = s.normal;
        }
    } else {
        let cos_theta = min(dot(-p.dir, p.normal), 1.0);
        o.reflected = reflect(p.dir, p.normal);
        o.refracted = refract_dir(p.dir, p.normal, cos_theta, p.ratio);
        o.schlick = schlick(cos_theta, p.ratio);
    }
    outputs[i] = o;
}
