//! The scene on the GPU: the arrays of [`crate::common::arrays`] uploaded to storage
//! buffers, and kept up to date as the scene is edited.

use crate::common::arrays::{FrameSettings, Primitives, geometry_hash, gpu_bvh, scene_uniforms};
use crate::common::layout::GpuLight;
use crate::common::textures;
use crate::scene::Scene;
use crate::scene::envmap::EnvMap;
use glam::DVec3;
use std::sync::Arc;
use wgpu::util::DeviceExt;

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

/// Whether `scene`'s environment map is `had` (the same loaded map, or both none).
fn same_map(scene: &Scene, had: &Option<Arc<EnvMap>>) -> bool {
    match (&scene.environment, had) {
        (None, None) => true,
        (Some(e), Some(m)) => Arc::ptr_eq(&e.map, m),
        _ => false,
    }
}

/// The scene's GPU buffers.
pub struct SceneBuffers {
    pub uniforms: wgpu::Buffer,
    pub materials: wgpu::Buffer,
    pub spheres: wgpu::Buffer,
    pub quads: wgpu::Buffer,
    pub boxes: wgpu::Buffer,
    pub triangles: wgpu::Buffer,
    pub nodes: wgpu::Buffer,
    pub refs: wgpu::Buffer,
    pub lights: wgpu::Buffer,
    /// Copies of instanced meshes (one zeroed record when there are none).
    pub instances: wgpu::Buffer,
    /// The texture words (`common::textures`; one word when the scene has none).
    pub tex: wgpu::Buffer,
    /// The environment map's words (`common::envmap::words`; one word without a map), and
    /// the map they were made from.
    pub env: wgpu::Buffer,
    env_map: Option<Arc<EnvMap>>,
    /// What the texture words were made from: per object, its textured material's address
    /// (0: none), and the geometry (the triangles' coordinates are in them).
    tex_key: Vec<usize>,
    geometry: u64,
    anchor_target: DVec3,
    /// The point every position is taken relative to on the GPU (a floating origin): the
    /// camera's target when the geometry was last uploaded, so that a scene far from the
    /// world's origin is as precise as one at it. Kept while only camera and materials change.
    origin: DVec3,
    /// Nodes of the BVH, for reports.
    pub node_count: usize,
    /// Seconds the last BVH build took.
    pub build_seconds: f64,
    /// Whether the lights were built for next-event estimation.
    nee: bool,
}

impl SceneBuffers {
    pub fn new(device: &wgpu::Device, scene: &Scene, s: &FrameSettings) -> SceneBuffers {
        let origin = scene.camera.look_at;
        let start = std::time::Instant::now();
        let p = Primitives::of(scene, origin, s.nee);
        let primitives_seconds = start.elapsed().as_secs_f64();
        let t = std::time::Instant::now();
        let (nodes, refs, instances) = gpu_bvh(&p);
        let build_seconds = t.elapsed().as_secs_f64();
        tracing::info!(
            "BVH over {} primitives: {} nodes in {:.1} ms",
            p.refs.len(),
            nodes.len(),
            build_seconds * 1e3
        );
        let u = scene_uniforms(scene, s, origin);
        let t = std::time::Instant::now();
        let tex = textures::words(scene).unwrap_or_else(|| vec![0]);
        tracing::info!(
            "texture words: {:.1} MiB in {:.1} ms",
            tex.len() as f64 * 4.0 / (1 << 20) as f64,
            t.elapsed().as_secs_f64() * 1e3
        );
        let t = std::time::Instant::now();
        let env_map = scene.environment.as_ref().map(|e| e.map.clone());
        let env = match &env_map {
            Some(m) => storage(
                device,
                "scene.env",
                &crate::common::envmap::words(&m.distribution, &m.rgbe),
            ),
            None => storage::<u32>(device, "scene.env", &[]),
        };
        let buffers = SceneBuffers {
            tex: storage(device, "scene.tex", &tex),
            env,
            env_map,
            tex_key: textures::material_key(scene),
            origin,
            uniforms: device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some("scene.uniforms"),
                contents: bytemuck::bytes_of(&u),
                usage: super::Values::USAGE,
            }),
            materials: storage(device, "scene.materials", &p.materials),
            spheres: storage(device, "scene.spheres", &p.spheres),
            quads: storage(device, "scene.quads", &p.quads),
            boxes: storage(device, "scene.boxes", &p.boxes),
            triangles: storage(device, "scene.triangles", &p.triangles),
            node_count: nodes.len(),
            nodes: storage(device, "scene.bvh_nodes", &nodes),
            refs: storage(device, "scene.bvh_refs", &refs),
            lights: storage(device, "scene.lights", &p.lights),
            instances: storage(device, "scene.instances", &instances),
            nee: s.nee,
            geometry: geometry_hash(scene),
            anchor_target: scene.camera.look_at,
            build_seconds,
        };
        tracing::info!(
            "scene buffers in {:.1} ms: primitives {:.1} ms, BVH {:.1} ms, upload {:.1} ms",
            start.elapsed().as_secs_f64() * 1e3,
            primitives_seconds * 1e3,
            build_seconds * 1e3,
            t.elapsed().as_secs_f64() * 1e3
        );
        buffers
    }

    /// Brings the buffers up to date with `scene`. With the same geometry only the uniforms,
    /// the materials, the lights and (when the camera's target moved) the sphere anchors are
    /// rewritten, and the BVH is kept; otherwise everything is rebuilt. Returns true if the
    /// buffers were replaced (bind groups must be made again).
    pub fn update(
        &mut self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        scene: &Scene,
        s: &FrameSettings,
    ) -> bool {
        // The triangles are not made again unless the geometry changed (a fresh
        // `SceneBuffers::new` then makes them).
        let p = Primitives::without_meshes(scene, self.origin, s.nee);
        let light_count = |l: &[GpuLight]| l.len().max(1);
        if geometry_hash(scene) != self.geometry
            || s.nee != self.nee
            || textures::material_key(scene) != self.tex_key
            || !same_map(scene, &self.env_map)
            || light_count(&p.lights) * std::mem::size_of::<GpuLight>()
                > self.lights.size() as usize
        {
            *self = SceneBuffers::new(device, scene, s);
            return true;
        }
        if !p.lights.is_empty() {
            queue.write_buffer(&self.lights, 0, bytemuck::cast_slice(&p.lights));
        }
        // A textured material's factors (the texels and coordinates are unchanged).
        if let Some((at, records)) = textures::record_words(scene) {
            queue.write_buffer(&self.tex, 4 * at as u64, bytemuck::cast_slice(&records));
        }
        queue.write_buffer(
            &self.uniforms,
            0,
            bytemuck::bytes_of(&scene_uniforms(scene, s, self.origin)),
        );
        if !p.materials.is_empty() {
            queue.write_buffer(&self.materials, 0, bytemuck::cast_slice(&p.materials));
        }
        if scene.camera.look_at != self.anchor_target && !p.spheres.is_empty() {
            queue.write_buffer(&self.spheres, 0, bytemuck::cast_slice(&p.spheres));
            self.anchor_target = scene.camera.look_at;
        }
        false
    }
}
