//! The scene on the GPU: uniforms and the primitive and material arrays, converted from the
//! host's f64 model.

use super::layout::*;
use crate::scene::{Camera, Object, Scene, Shape, Sky, euler_xyz};
use glam::DVec3;
use wgpu::util::DeviceExt;

/// What the tracer needs besides the scene itself.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FrameSettings {
    pub width: u32,
    pub height: u32,
    pub max_bounces: u32,
    pub seed: u32,
    /// Width / height of one pixel: 1 for images; a terminal's pixels are taller than wide.
    pub pixel_aspect: f64,
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
        }
    }

    /// Width / height of the whole image, as the camera sees it.
    pub fn aspect(&self) -> f64 {
        self.width as f64 * self.pixel_aspect / self.height as f64
    }
}

/// The camera of MODEL.md as the focus-plane frame the shader uses (Shirley, Ray Tracing in
/// One Weekend §11–13), computed in f64 and relative to `look_from`.
pub fn camera_uniforms(cam: &Camera, aspect: f64, u: &mut SceneUniforms) {
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
    u.cam_origin = f(cam.look_from);
    u.lens_radius = (cam.aperture / 2.0) as f32;
    u.cam_to_corner = f(-focus * w - horizontal / 2.0 + vertical / 2.0);
    u.cam_horizontal = f(horizontal);
    u.cam_vertical = f(vertical);
    u.cam_u = f(right);
    u.cam_v = f(up);
}

/// The uniforms of a scene rendered with `s`.
pub fn scene_uniforms(scene: &Scene, s: &FrameSettings) -> SceneUniforms {
    let mut u = SceneUniforms {
        width: s.width,
        height: s.height,
        max_bounces: s.max_bounces,
        seed: s.seed,
        ..Default::default()
    };
    camera_uniforms(&scene.camera, s.aspect(), &mut u);
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
    let (ns, nq, nb) = scene.counts();
    u.n_spheres = ns as u32;
    u.n_quads = nq as u32;
    u.n_boxes = nb as u32;
    u
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

/// The primitive arrays: one material per object, primitives grouped by kind.
#[derive(Default)]
pub struct Primitives {
    pub materials: Vec<GpuMaterial>,
    pub spheres: Vec<GpuSphere>,
    pub quads: Vec<GpuQuad>,
    pub boxes: Vec<GpuCuboid>,
}

impl Primitives {
    pub fn of(scene: &Scene) -> Primitives {
        let mut p = Primitives::default();
        for (i, o) in scene.objects.iter().enumerate() {
            p.materials.push(material(o));
            let mat = i as u32;
            let f = |v: DVec3| v.as_vec3().to_array();
            match &o.shape {
                Shape::Sphere { center, radius } => {
                    let (a, n) = sphere_anchor(*center, *radius, scene.camera.look_at);
                    p.spheres.push(GpuSphere {
                        anchor: f(a),
                        radius: *radius as f32,
                        anchor_normal: f(n),
                        material: mat,
                    });
                }
                Shape::Quad { q, u, v } => {
                    let n = u.cross(*v);
                    p.quads.push(GpuQuad {
                        q: f(*q),
                        material: mat,
                        u: f(*u),
                        v: f(*v),
                        normal: f(n.normalize()),
                        w: f(n / n.dot(n)),
                        ..Default::default()
                    });
                }
                Shape::Box {
                    center,
                    half_extents,
                    rotation,
                } => {
                    let r = euler_xyz(*rotation);
                    p.boxes.push(GpuCuboid {
                        center: f(*center),
                        material: mat,
                        half_extents: f(*half_extents),
                        axis_x: f(r.x_axis),
                        axis_y: f(r.y_axis),
                        axis_z: f(r.z_axis),
                        ..Default::default()
                    });
                }
            }
        }
        p
    }
}

fn material(o: &Object) -> GpuMaterial {
    let m = &o.material;
    GpuMaterial {
        color: m.color.to_array(),
        smoothness: m.smoothness,
        specular_color: m.specular_tint().to_array(),
        absorption: m.absorption,
        specular: m.specular,
        light: m.light,
        ior: m.ior,
        _pad0: 0.0,
    }
}

/// A storage buffer of `items`, or of one zeroed item when there are none (WGSL arrays
/// cannot be empty).
fn storage<T: bytemuck::Pod + Default>(
    device: &wgpu::Device,
    label: &str,
    items: &[T],
) -> wgpu::Buffer {
    let one = [T::default()];
    let data = if items.is_empty() { &one[..] } else { items };
    device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
        label: Some(label),
        contents: bytemuck::cast_slice(data),
        usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
    })
}

/// The scene's GPU buffers.
pub struct SceneBuffers {
    pub uniforms: wgpu::Buffer,
    pub materials: wgpu::Buffer,
    pub spheres: wgpu::Buffer,
    pub quads: wgpu::Buffer,
    pub boxes: wgpu::Buffer,
}

impl SceneBuffers {
    pub fn new(device: &wgpu::Device, scene: &Scene, s: &FrameSettings) -> SceneBuffers {
        let p = Primitives::of(scene);
        let u = scene_uniforms(scene, s);
        SceneBuffers {
            uniforms: device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some("scene.uniforms"),
                contents: bytemuck::bytes_of(&u),
                usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            }),
            materials: storage(device, "scene.materials", &p.materials),
            spheres: storage(device, "scene.spheres", &p.spheres),
            quads: storage(device, "scene.quads", &p.quads),
            boxes: storage(device, "scene.boxes", &p.boxes),
        }
    }
}
