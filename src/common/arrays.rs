//! The scene as both tracers read it: uniforms and the primitive, material, light and BVH
//! arrays in the layouts of [`super::layout`], converted from the host's f64 model, and the
//! frame settings beside them.

use super::layout::*;
use crate::bvh::wide::GpuBvhNode4;
use crate::bvh::{Aabb, Bvh};
use crate::scene::{Camera, Material, MaterialModel, Object, Scene, Shape, Sky, euler_xyz};
use glam::{DMat4, DVec3};
use std::hash::{Hash, Hasher};

/// What the tracer needs besides the scene itself.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FrameSettings {
    pub width: u32,
    pub height: u32,
    pub max_bounces: u32,
    pub seed: u32,
    /// Width / height of one pixel: 1 for images; a terminal's pixels are taller than wide.
    pub pixel_aspect: f64,
    /// Next-event estimation (light sampling with MIS, and Russian roulette) where the scene
    /// has lights; off gives the lecture's brute-force path tracer.
    pub nee: bool,
}

impl FrameSettings {
    /// Settings for square pixels.
    pub fn new(width: u32, height: u32, max_bounces: u32, seed: u32) -> FrameSettings {
        FrameSettings {
            width,
            height,
            max_bounces,
            seed,
            pixel_aspect: 1.0,
            nee: true,
        }
    }

    /// Width / height of the whole image, as the camera sees it.
    pub fn aspect(&self) -> f64 {
        self.width as f64 * self.pixel_aspect / self.height as f64
    }
}

/// The camera of MODEL.md as the focus-plane frame the shader uses (Shirley, Ray Tracing in
/// One Weekend §11–13), computed in f64, relative to `look_from`, and its position relative
/// to the scene's `origin` (the floating origin of `gpu::SceneBuffers`).
pub fn camera_uniforms(cam: &Camera, aspect: f64, origin: DVec3, u: &mut SceneUniforms) {
    let focus = cam.focus();
    let half_h = (cam.vfov.to_radians() / 2.0).tan();
    let view_h = 2.0 * half_h * focus;
    let view_w = aspect * view_h;
    let w = (cam.look_from - cam.look_at).normalize();
    let right = cam.up.cross(w).normalize();
    let up = w.cross(right);
    let horizontal = view_w * right;
    let vertical = view_h * up;
    let f = |v: DVec3| v.as_vec3().to_array();
    u.cam_origin = f(cam.look_from - origin);
    u.lens_radius = (cam.aperture / 2.0) as f32;
    u.cam_to_corner = f(-focus * w - horizontal / 2.0 + vertical / 2.0);
    u.cam_horizontal = f(horizontal);
    u.cam_vertical = f(vertical);
    u.cam_u = f(right);
    u.cam_v = f(up);
}

/// The uniforms of a scene rendered with `s`, positions relative to `origin`.
pub fn scene_uniforms(scene: &Scene, s: &FrameSettings, origin: DVec3) -> SceneUniforms {
    let mut u = SceneUniforms {
        width: s.width,
        height: s.height,
        max_bounces: s.max_bounces,
        seed: s.seed,
        ..Default::default()
    };
    camera_uniforms(&scene.camera, s.aspect(), origin, &mut u);
    match &scene.sky {
        Sky::Uniform(c) => {
            u.sky_uniform = 1;
            u.sky_bottom = c.to_array();
        }
        Sky::Gradient { bottom, top, sun } => {
            u.sky_bottom = bottom.to_array();
            u.sky_top = top.to_array();
            if let Some(sun) = sun {
                u.sun_dir = sun.direction.normalize().as_vec3().to_array();
                u.sun_size = sun.size;
                u.sun_radiance = (sun.color * sun.intensity).to_array();
            }
        }
    }
    u.n_lights = lights(scene, s.nee).0.len() as u32;
    u.n_mirrors = mirror_spheres(scene, s.nee).len() as u32;
    u.n_lenses = lens_spheres(scene, s.nee).len() as u32;
    if let Some(e) = &scene.environment {
        u.env_rotation = e.rotation.to_radians();
        u.env_intensity = e.intensity;
        u.env_mode = if e.visible { ENV_VISIBLE } else { ENV_HIDDEN };
        u.env_pick = env_pick(e.lights() && s.nee, u.n_lights);
    }
    let n = scene.counts();
    u.n_spheres = n.spheres as u32;
    u.n_quads = n.quads as u32;
    u.n_boxes = n.boxes as u32;
    // The top level's: an instanced mesh's triangles are reached through its copies.
    u.n_triangles = scene
        .objects
        .iter()
        .map(|o| match &o.shape {
            Shape::Mesh {
                mesh, instances, ..
            } if instances.is_empty() => mesh.triangles.len(),
            _ => 0,
        })
        .sum::<usize>() as u32;
    u.n_instances = n.instances as u32;
    u
}

/// `SceneUniforms::env_mode`: no environment map, one that camera rays do not see (they see
/// the `[sky]` behind it), one that every ray sees.
pub const ENV_NONE: u32 = 0;
pub const ENV_HIDDEN: u32 = 1;
pub const ENV_VISIBLE: u32 = 2;

/// The light-selection rule of next-event estimation (docs/MODEL-NOTES.md, "Environment
/// maps"): the probability of sampling the environment map rather than the scene's lights.
/// All of it where the map is the only light, half where there are both (the scene's lights
/// then share the other half by their own rule), none where the map sends no light or light
/// sampling is off.
pub fn env_pick(map_lights: bool, scene_lights: u32) -> f32 {
    match (map_lights, scene_lights) {
        (false, _) => 0.0,
        (true, 0) => 1.0,
        (true, _) => 0.5,
    }
}

/// A sphere's anchor: the surface point nearest `toward` (the camera's `look_at`), where
/// intersections are most precise (see `hit_sphere` in intersect.wgsl).
pub fn sphere_anchor(center: DVec3, radius: f64, toward: DVec3) -> (DVec3, DVec3) {
    let d = toward - center;
    let n = if d.length() > 0.0 {
        d.normalize()
    } else {
        DVec3::Y
    };
    (center + radius.abs() * n, n)
}

/// Primitive kinds as the BVH's references encode them (top two bits; `KIND_* - 1` in
/// trace.wgsl).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(u32)]
pub enum Kind {
    Sphere = 0,
    Quad = 1,
    Box = 2,
    Triangle = 3,
}

/// A BVH reference's index in its kind's array (below the kind's two bits).
pub const REF_INDEX: u32 = (1 << 30) - 1;

/// Under the triangle kind's two bits, this bit marks a copy of a mesh: the index below it is
/// the instance's (`Primitives::instances`), whose own BVH holds the triangles.
pub const INSTANCE_BIT: u32 = 1 << 29;

/// A BVH reference: kind in the top two bits, index in its array below.
pub fn encode_ref(kind: Kind, index: usize) -> u32 {
    assert!(index < 1 << 30, "more than 2^30 primitives of one kind");
    assert!(
        kind != Kind::Triangle || index < INSTANCE_BIT as usize,
        "more than 2^29 triangles"
    );
    (kind as u32) << 30 | index as u32
}

/// The reference of instance `index`.
pub fn instance_ref(index: usize) -> u32 {
    assert!(index < INSTANCE_BIT as usize, "more than 2^29 instances");
    (Kind::Triangle as u32) << 30 | INSTANCE_BIT | index as u32
}

/// The triangles of a mesh drawn by instances: `count` of them from `first` in the triangle
/// array, in the mesh's own coordinates, and their bounds; its BVH is built apart.
pub struct MeshBlas {
    pub first: usize,
    pub bounds: Vec<Aabb>,
}

/// The primitive arrays (one material per object, primitives grouped by kind) and the
/// bounds of every primitive, in the order `refs` names them.
#[derive(Default)]
pub struct Primitives {
    pub materials: Vec<GpuMaterial>,
    pub spheres: Vec<GpuSphere>,
    pub quads: Vec<GpuQuad>,
    pub boxes: Vec<GpuCuboid>,
    pub triangles: Vec<GpuTriangle>,
    pub lights: Vec<GpuLight>,
    /// Copies of instanced meshes (`root` is the index of their mesh in `blas` until
    /// [`gpu_bvh`] builds the trees), and those meshes.
    pub instances: Vec<GpuInstance>,
    pub blas: Vec<MeshBlas>,
    /// Triangles named by the top level (those of instanced meshes follow them).
    pub top_triangles: usize,
    /// The reference and bounds of every primitive of the top level.
    pub refs: Vec<u32>,
    pub bounds: Vec<Aabb>,
}

/// The rows of an affine map as WGSL's `Instance` stores them.
fn rows(m: DMat4) -> [[f32; 4]; 3] {
    let r = m.transpose();
    [r.x_axis, r.y_axis, r.z_axis].map(|v| v.as_vec4().to_array())
}

/// A vector (a direction or an extent) in f32: never moved by the origin.
fn dir(v: DVec3) -> [f32; 3] {
    v.as_vec3().to_array()
}

/// A position in f32 (callers subtract the origin first).
fn f(v: DVec3) -> [f32; 3] {
    v.as_vec3().to_array()
}

impl Primitives {
    /// The scene's primitives with positions relative to `origin`, subtracted in f64 before
    /// the rounding to f32 (bounds stay in world coordinates relative to it too).
    pub fn of(scene: &Scene, origin: DVec3, nee: bool) -> Primitives {
        Self::build(scene, origin, nee, true)
    }

    /// [`Primitives::of`] without the meshes' triangles (and their references): what an edit
    /// that keeps the geometry changes, without transforming 10⁶ triangles per key.
    pub fn without_meshes(scene: &Scene, origin: DVec3, nee: bool) -> Primitives {
        Self::build(scene, origin, nee, false)
    }

    fn build(scene: &Scene, origin: DVec3, nee: bool, meshes: bool) -> Primitives {
        let mut p = Primitives::default();
        let (lights, slots) = lights(scene, nee);
        p.lights = lights;
        p.lights.extend(mirror_spheres(scene, nee));
        p.lights.extend(lens_spheres(scene, nee));
        // Positions are taken relative to the origin (in f64, before rounding); directions
        // and extents go through `dir` unchanged.
        let pos = |v: DVec3| f(v - origin);
        // The triangles of instanced meshes, which follow the top level's.
        let mut instanced = Vec::new();
        for (i, o) in scene.objects.iter().enumerate() {
            p.materials.push(GpuMaterial {
                light_slot: slots[i],
                ..material(o)
            });
            let mat = i as u32;
            match &o.shape {
                Shape::Sphere { center, radius } => {
                    let (a, n) = sphere_anchor(*center, *radius, scene.camera.look_at);
                    let r = DVec3::splat(radius.abs());
                    let c = *center - origin;
                    p.push(
                        Kind::Sphere,
                        p.spheres.len(),
                        Aabb {
                            min: c - r,
                            max: c + r,
                        },
                    );
                    p.spheres.push(GpuSphere {
                        anchor: pos(a),
                        radius: *radius as f32,
                        anchor_normal: dir(n),
                        material: mat,
                    });
                }
                Shape::Quad { q, u, v } => {
                    let n = u.cross(*v);
                    let q0 = *q - origin;
                    let b = Aabb::of_points(&[q0, q0 + *u, q0 + *v, q0 + *u + *v]);
                    p.push(Kind::Quad, p.quads.len(), b);
                    p.quads.push(GpuQuad {
                        q: pos(*q),
                        material: mat,
                        u: dir(*u),
                        v: dir(*v),
                        normal: dir(n.normalize()),
                        w: dir(n / n.dot(n)),
                        ..Default::default()
                    });
                }
                Shape::Box {
                    center,
                    half_extents,
                    rotation,
                } => {
                    let r = euler_xyz(*rotation);
                    let h = *half_extents;
                    let corners: Vec<DVec3> = (0..8)
                        .map(|k| {
                            let s = DVec3::new(
                                if k & 1 == 0 { -1.0 } else { 1.0 },
                                if k & 2 == 0 { -1.0 } else { 1.0 },
                                if k & 4 == 0 { -1.0 } else { 1.0 },
                            );
                            *center - origin + r * (s * h)
                        })
                        .collect();
                    p.push(Kind::Box, p.boxes.len(), Aabb::of_points(&corners));
                    p.boxes.push(GpuCuboid {
                        center: pos(*center),
                        material: mat,
                        half_extents: dir(h),
                        axis_x: dir(r.x_axis),
                        axis_y: dir(r.y_axis),
                        axis_z: dir(r.z_axis),
                        ..Default::default()
                    });
                }
                Shape::Mesh { .. } if !meshes => {}
                Shape::Mesh {
                    mesh,
                    instances,
                    translate,
                    rotation,
                    scale,
                    ..
                } if !instances.is_empty() => {
                    // Stored once in the mesh's coordinates (its own placement goes into every
                    // copy's transform); the top level holds the copies.
                    use rayon::prelude::*;
                    let (bounds, tris): (Vec<Aabb>, Vec<GpuTriangle>) = mesh
                        .triangles
                        .par_iter()
                        .map(|&[a, b, c]| {
                            let t = GpuTriangle {
                                v0: f(a),
                                material: mat,
                                e1: dir(b - a),
                                e2: dir(c - a),
                                ..Default::default()
                            };
                            (Aabb::of_points(&[a, b, c]), t)
                        })
                        .unzip();
                    let local = bounds.iter().fold(Aabb::EMPTY, |b, t| b.union(*t));
                    let own = DMat4::from_translation(*translate)
                        * DMat4::from_mat3(euler_xyz(*rotation))
                        * DMat4::from_scale(*scale);
                    let mesh_index = p.blas.len() as u32;
                    p.blas.push(MeshBlas {
                        first: instanced.len(),
                        bounds,
                    });
                    instanced.extend(tris);
                    for m in instances.iter() {
                        let w = DMat4::from_translation(-origin) * *m * own;
                        p.refs.push(instance_ref(p.instances.len()));
                        p.bounds.push(local.transformed(&w));
                        p.instances.push(GpuInstance {
                            object_from_world: rows(w.inverse()),
                            world_from_object: rows(w),
                            root: mesh_index,
                            ..Default::default()
                        });
                    }
                }
                Shape::Mesh { .. } => {
                    // In parallel: a mesh of 10⁶ triangles is a large part of a first frame.
                    use rayon::prelude::*;
                    let made: Vec<(Aabb, GpuTriangle)> = o
                        .shape
                        .world_triangles()
                        .par_iter()
                        .map(|&[a, b, c]| {
                            let local = [a - origin, b - origin, c - origin];
                            let t = GpuTriangle {
                                v0: pos(a),
                                material: mat,
                                e1: dir(b - a),
                                e2: dir(c - a),
                                ..Default::default()
                            };
                            (Aabb::of_points(&local), t)
                        })
                        .collect();
                    let first = p.triangles.len();
                    p.refs
                        .extend((first..first + made.len()).map(|k| encode_ref(Kind::Triangle, k)));
                    p.bounds.extend(made.iter().map(|m| m.0));
                    p.triangles.extend(made.into_iter().map(|m| m.1));
                }
            }
        }
        p.push_instanced(instanced);
        p
    }

    fn push_instanced(&mut self, instanced: Vec<GpuTriangle>) {
        self.top_triangles = self.triangles.len();
        for b in &mut self.blas {
            b.first += self.top_triangles;
        }
        self.triangles.extend(instanced);
    }

    fn push(&mut self, kind: Kind, index: usize, bounds: Aabb) {
        self.refs.push(encode_ref(kind, index));
        self.bounds.push(bounds);
    }
}

/// The lights next-event estimation samples: every emissive sphere and quad with its share
/// of the total power (luminance × light × emitting area, both faces of a quad) and the
/// cumulative table of those shares; and each object's slot (1 + its index in the table; 0
/// for objects that are not sampled: non-emitters, emissive boxes and meshes, which paths
/// still reach by scattering). Empty when `nee` is off.
pub fn lights(scene: &Scene, nee: bool) -> (Vec<GpuLight>, Vec<u32>) {
    let mut slots = vec![0u32; scene.objects.len()];
    if !nee {
        return (Vec::new(), slots);
    }
    let (mut spheres, mut quads) = (0usize, 0usize);
    // (reference, object, power, area)
    let mut found = Vec::new();
    for (i, o) in scene.objects.iter().enumerate() {
        let m = &o.material;
        let lum = |c: glam::Vec3| (0.2126 * c.x + 0.7152 * c.y + 0.0722 * c.z) as f64;
        match &o.shape {
            Shape::Sphere { radius, .. } => {
                if m.is_emitter() {
                    let area = 4.0 * std::f64::consts::PI * radius * radius;
                    found.push((
                        encode_ref(Kind::Sphere, spheres),
                        i,
                        lum(m.color) * m.light as f64 * area,
                        area,
                    ));
                }
                spheres += 1;
            }
            Shape::Quad { u, v, .. } => {
                if m.is_emitter() {
                    let area = u.cross(*v).length();
                    found.push((
                        encode_ref(Kind::Quad, quads),
                        i,
                        2.0 * lum(m.color) * m.light as f64 * area,
                        area,
                    ));
                }
                quads += 1;
            }
            _ => {}
        }
    }
    let total: f64 = found.iter().map(|l| l.2).sum();
    if found.is_empty() || total <= 0.0 {
        return (Vec::new(), slots);
    }
    let mut cdf = 0.0;
    let n = found.len();
    let table = found
        .iter()
        .enumerate()
        .map(|(k, &(prim, object, power, area))| {
            let p = power / total;
            cdf += p;
            slots[object] = k as u32 + 1;
            GpuLight {
                prim,
                // The last entry is exactly 1, whatever the rounding.
                cdf: if k + 1 == n { 1.0 } else { cdf as f32 },
                pmf: p as f32,
                area: area as f32,
            }
        })
        .collect();
    (table, slots)
}

/// The most mirror spheres light sampling reflects the map in (the first ones in the
/// scene's order; the others' reflections are found by scattering alone).
pub const MAX_MIRRORS: usize = 16;

/// The spheres through which next-event estimation also samples the environment map
/// (docs/MODEL-NOTES.md, "The map in a mirror ball"), where a map lights the scene and `nee`
/// is on: spheres of positive radius whose surface is a perfect mirror (`Material::is_mirror`:
/// the lecture's or glTF's); at most `MAX_MIRRORS`. As entries that follow the lights in the
/// lights' buffer: `prim` the sphere's reference, the rest 0.
pub fn mirror_spheres(scene: &Scene, nee: bool) -> Vec<GpuLight> {
    map_spheres(scene, nee, Material::is_mirror)
}

/// The clear glass balls through which next-event estimation also samples the environment
/// map (docs/MODEL-NOTES.md, "The map through a glass ball"), as `mirror_spheres` but for
/// `Material::is_lens`: entries that follow the mirror spheres in the lights' buffer.
pub fn lens_spheres(scene: &Scene, nee: bool) -> Vec<GpuLight> {
    map_spheres(scene, nee, Material::is_lens)
}

/// The first `MAX_MIRRORS` spheres of positive radius whose material is `kind`, where a map
/// lights the scene and `nee` is on, as entries of the lights' buffer.
fn map_spheres(scene: &Scene, nee: bool, kind: fn(&Material) -> bool) -> Vec<GpuLight> {
    if !nee || !scene.environment.as_ref().is_some_and(|e| e.lights()) {
        return Vec::new();
    }
    scene
        .objects
        .iter()
        .filter_map(|o| match &o.shape {
            Shape::Sphere { radius, .. } => Some((o, *radius)),
            _ => None,
        })
        .enumerate()
        .filter(|(_, (o, radius))| *radius > 0.0 && kind(&o.material))
        .take(MAX_MIRRORS)
        .map(|(i, _)| GpuLight {
            prim: encode_ref(Kind::Sphere, i),
            cdf: 0.0,
            pmf: 0.0,
            area: 0.0,
        })
        .collect()
}

/// The BVH over `p`, as both tracers read it: four-wide nodes (`bvh::wide`), and the
/// references in leaf order, and the instances with their roots. A scene without primitives
/// gets an empty list (the buffer then holds one zeroed node, which the tracer never reads: it
/// checks the primitive counts first).
///
/// With instanced meshes the tree has two levels, as in PBRT 4th ed. §7.1.4 (and DirectX's
/// and Vulkan's acceleration structures): the top level, from node 0, over the primitives
/// and the copies; after it, each mesh's own tree over its triangles in its coordinates,
/// from the node a copy's `root` names. Its nodes and references follow the top level's.
pub fn gpu_bvh(p: &Primitives) -> (Vec<GpuBvhNode4>, Vec<u32>, Vec<GpuInstance>) {
    if p.bounds.is_empty() {
        return (Vec::new(), Vec::new(), Vec::new());
    }
    let bvh = Bvh::build(&p.bounds);
    let mut refs: Vec<u32> = bvh.order.iter().map(|&i| p.refs[i as usize]).collect();
    let mut nodes = crate::bvh::wide::collapse(&bvh);
    use rayon::prelude::*;
    let trees: Vec<(Vec<GpuBvhNode4>, Vec<u32>)> = p
        .blas
        .par_iter()
        .map(|b| {
            let bvh = Bvh::build(&b.bounds);
            let refs = bvh
                .order
                .iter()
                .map(|&i| encode_ref(Kind::Triangle, b.first + i as usize))
                .collect();
            (crate::bvh::wide::collapse(&bvh), refs)
        })
        .collect();
    let mut roots = Vec::with_capacity(trees.len());
    for (tree, tree_refs) in trees {
        let (node_base, ref_base) = (nodes.len() as u32, refs.len() as u32);
        roots.push(node_base);
        nodes.extend(tree.into_iter().map(|mut n| {
            for k in 0..4 {
                match n.count[k] {
                    crate::bvh::wide::EMPTY_SLOT => {}
                    0 => n.child[k] += node_base,
                    _ => n.child[k] += ref_base,
                }
            }
            n
        }));
        refs.extend(tree_refs);
    }
    let instances = p
        .instances
        .iter()
        .map(|i| GpuInstance {
            root: roots[i.root as usize],
            ..*i
        })
        .collect();
    (nodes, refs, instances)
}

fn material(o: &Object) -> GpuMaterial {
    let m = &o.material;
    GpuMaterial {
        color: m.color.to_array(),
        smoothness: m.smoothness,
        // The pbr model's is KHR_materials_specular's colour (white unless given); the
        // lecture's its specular tint (the colour unless given).
        specular_color: match m.model {
            MaterialModel::Pbr => m.specular_color.unwrap_or(glam::Vec3::ONE).to_array(),
            MaterialModel::Lecture => m.specular_tint().to_array(),
        },
        absorption: m.absorption,
        specular: m.specular,
        light: m.light,
        ior: m.ior,
        light_slot: 0,
        metallic: m.metallic,
        roughness: m.roughness,
        model: match m.model {
            MaterialModel::Lecture => MODEL_LECTURE,
            MaterialModel::Pbr => MODEL_PBR,
        },
        transmission: m.transmission,
        attenuation: m.volume.coefficient().to_array(),
        thin: m.volume.thin_walled as u32,
        clearcoat: m.clearcoat,
        clearcoat_roughness: m.clearcoat_roughness,
        _pad0: 0,
        _pad1: 0,
    }
}

/// A storage buffer of `items`, or of one zeroed item when there are none (WGSL arrays
/// cannot be empty).
/// An object's shape as numbers: its kind, then its parameters (a mesh's placement; its
/// triangles are the mesh's own).
fn shape_numbers(shape: &Shape) -> Vec<f64> {
    match shape {
        Shape::Sphere { center, radius } => vec![0.0, center.x, center.y, center.z, *radius],
        Shape::Quad { q, u, v } => [1.0]
            .into_iter()
            .chain(q.to_array())
            .chain(u.to_array())
            .chain(v.to_array())
            .collect(),
        Shape::Box {
            center,
            half_extents,
            rotation,
        } => [2.0]
            .into_iter()
            .chain(center.to_array())
            .chain(half_extents.to_array())
            .chain(rotation.to_array())
            .collect(),
        Shape::Mesh {
            translate,
            rotation,
            scale,
            ..
        } => [3.0]
            .into_iter()
            .chain(translate.to_array())
            .chain(rotation.to_array())
            .chain(scale.to_array())
            .collect(),
    }
}

/// Why `scene`'s geometry cannot be bound where one storage buffer holds at most `limit`
/// bytes: the triangle array (48 bytes a triangle, an instanced mesh's once) is the largest
/// of its buffers. `None` when it fits.
pub fn too_large(scene: &Scene, limit: u64) -> Option<String> {
    let n = scene.counts();
    let bytes = n.triangles as u64 * std::mem::size_of::<GpuTriangle>() as u64;
    let mib = |b: u64| b as f64 / (1 << 20) as f64;
    (bytes > limit).then(|| {
        format!(
            "its {} triangles take {:.1} MiB in one storage buffer, more than the {:.1} MiB \
             this adapter binds; trace on the CPU (the adapter `cpu-native`), which has no \
             such limit{}",
            n.triangles,
            mib(bytes),
            mib(limit),
            if n.drawn_triangles > n.triangles {
                ""
            } else {
                ", or let repeated meshes be instanced (`instancing` on a `[[gltf]]` table)"
            }
        )
    })
}

/// A hash of everything the BVH depends on: the shapes (not the materials, not the camera).
/// A mesh counts by its identity (the `Arc` it is shared through): cheap on every edit of a
/// scene whose meshes stay, but only within one process (`geometry_content_hash` is not).
pub fn geometry_hash(scene: &Scene) -> u64 {
    let mut h = std::collections::hash_map::DefaultHasher::new();
    for o in &scene.objects {
        if let Shape::Mesh {
            mesh, instances, ..
        } = &o.shape
        {
            (std::sync::Arc::as_ptr(mesh) as usize).hash(&mut h);
            // (Only where there are copies: the hash of every other scene is as before.)
            if !instances.is_empty() {
                (std::sync::Arc::as_ptr(instances) as usize).hash(&mut h);
            }
        }
        for x in shape_numbers(&o.shape) {
            x.to_bits().hash(&mut h);
        }
    }
    h.finish()
}

/// A CRC-32 of the geometry that is the same in every process and build: the shapes, and
/// each mesh by its triangles and their attributes (texture coordinates, normals,
/// tangents), as `render::shard`'s scene hash needs.
pub fn geometry_content_hash(scene: &Scene) -> u32 {
    let mut h = crc32fast::Hasher::new();
    for o in &scene.objects {
        for x in shape_numbers(&o.shape) {
            h.update(&x.to_bits().to_le_bytes());
        }
        if let Shape::Mesh { mesh, .. } = &o.shape {
            for t in &mesh.triangles {
                for x in t.iter().flat_map(|v| v.to_array()) {
                    h.update(&x.to_bits().to_le_bytes());
                }
            }
            h.update(bytemuck::cast_slice(&mesh.uvs));
            h.update(bytemuck::cast_slice(&mesh.normals));
            h.update(bytemuck::cast_slice(&mesh.tangents));
        }
        if let Shape::Mesh { instances, .. } = &o.shape {
            for m in instances.iter() {
                for x in m.to_cols_array() {
                    h.update(&x.to_bits().to_le_bytes());
                }
            }
        }
    }
    h.finalize()
}
