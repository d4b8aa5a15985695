//! `#[repr(C)]` mirrors of the WGSL structs in `shaders/common/types.wgsl`, padding spelled
//! out, as both tracers read them (the BVH's node, `GpuBvhNode4`, is `bvh::wide`'s);
//! `tests/shaders.rs` checks every size and offset against naga's layout of the WGSL.

use crate::bvh::wide::GpuBvhNode4;
use bytemuck::{Pod, Zeroable};

#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable, PartialEq)]
pub struct SceneUniforms {
    pub cam_origin: [f32; 3],
    pub lens_radius: f32,
    pub cam_to_corner: [f32; 3],
    pub n_lights: u32,
    pub cam_horizontal: [f32; 3],
    pub n_instances: u32,
    pub cam_vertical: [f32; 3],
    /// Perfect mirror spheres whose reflection of the map light sampling samples
    /// (`arrays::mirror_spheres`): they follow the lights in the lights' buffer.
    pub n_mirrors: u32,
    pub cam_u: [f32; 3],
    /// Clear glass spheres through which light sampling refracts the map
    /// (`arrays::lens_spheres`): they follow the mirror spheres in the lights' buffer.
    pub n_lenses: u32,
    pub cam_v: [f32; 3],
    pub _pad4: f32,
    pub sky_bottom: [f32; 3],
    pub sky_uniform: u32,
    pub sky_top: [f32; 3],
    pub _pad5: f32,
    pub sun_dir: [f32; 3],
    pub sun_size: f32,
    pub sun_radiance: [f32; 3],
    pub _pad6: f32,
    pub width: u32,
    pub height: u32,
    pub max_bounces: u32,
    pub seed: u32,
    pub n_spheres: u32,
    pub n_quads: u32,
    pub n_boxes: u32,
    pub n_triangles: u32,
    pub env_rotation: f32,
    pub env_intensity: f32,
    pub env_pick: f32,
    pub env_mode: u32,
}

#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable, PartialEq)]
pub struct DispatchUniforms {
    pub sample_base: u32,
    pub sample_count: u32,
    pub row_offset: u32,
    pub row_count: u32,
    pub accumulate: u32,
    /// Invocations per pixel, each tracing its share of the samples (1: no reduce pass).
    pub lanes: u32,
    /// The submission's rows are `row_offset`, `row_offset + row_stride`, … (1: contiguous).
    pub row_stride: u32,
    pub _pad: u32,
}

#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable, PartialEq)]
pub struct ResolveUniforms {
    pub width: u32,
    pub height: u32,
    pub factor: u32,
    pub out_width: u32,
    pub out_height: u32,
    /// The resolve pass: 1 when the other devices' sums are added
    /// (`gpu::resolve::ResolvePass::set_extra`); the denoiser: the à-trous step in pixels.
    pub mode: u32,
    pub _pad: [u32; 2],
}

#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable, PartialEq)]
pub struct GpuMaterial {
    pub color: [f32; 3],
    pub smoothness: f32,
    pub specular_color: [f32; 3],
    pub absorption: f32,
    pub specular: f32,
    pub light: f32,
    pub ior: f32,
    pub light_slot: u32,
    pub metallic: f32,
    pub roughness: f32,
    /// [`MODEL_LECTURE`] or [`MODEL_PBR`].
    pub model: u32,
    /// pbr: KHR_materials_transmission's factor.
    pub transmission: f32,
    /// pbr: KHR_materials_volume's attenuation coefficient per scene unit,
    /// −ln(attenuationColor) / attenuationDistance (0: clear).
    pub attenuation: [f32; 3],
    /// pbr: 1 for a thin wall (transmits without refracting), 0 for a volume's boundary.
    pub thin: u32,
    /// pbr: KHR_materials_clearcoat's factor and perceptual roughness.
    pub clearcoat: f32,
    pub clearcoat_roughness: f32,
    pub _pad0: u32,
    pub _pad1: u32,
}

/// `GpuMaterial::model`: the lecture's material model (MODEL_LECTURE in types.wgsl).
pub const MODEL_LECTURE: u32 = 0;
/// `GpuMaterial::model`: glTF's metallic-roughness BRDF (MODEL_PBR in types.wgsl).
pub const MODEL_PBR: u32 = 1;

#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable, PartialEq)]
pub struct GpuSphere {
    pub anchor: [f32; 3],
    pub radius: f32,
    pub anchor_normal: [f32; 3],
    pub material: u32,
}

#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable, PartialEq)]
pub struct GpuQuad {
    pub q: [f32; 3],
    pub material: u32,
    pub u: [f32; 3],
    pub _pad0: f32,
    pub v: [f32; 3],
    pub _pad1: f32,
    pub normal: [f32; 3],
    pub _pad2: f32,
    pub w: [f32; 3],
    pub _pad3: f32,
}

#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable, PartialEq)]
pub struct GpuCuboid {
    pub center: [f32; 3],
    pub material: u32,
    pub half_extents: [f32; 3],
    pub _pad0: f32,
    pub axis_x: [f32; 3],
    pub _pad1: f32,
    pub axis_y: [f32; 3],
    pub _pad2: f32,
    pub axis_z: [f32; 3],
    pub _pad3: f32,
}

#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable, PartialEq)]
pub struct GpuTriangle {
    pub v0: [f32; 3],
    pub material: u32,
    pub e1: [f32; 3],
    pub _pad0: f32,
    pub e2: [f32; 3],
    pub _pad1: f32,
}

/// A copy of a mesh (an instance): its triangles (in the mesh's coordinates) are walked by
/// the bottom-level BVH whose root is node `root`, after the ray is taken into the mesh's
/// coordinates by `object_from_world` (three rows of an affine matrix); `world_from_object`
/// takes hit points back.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable, PartialEq)]
pub struct GpuInstance {
    pub object_from_world: [[f32; 4]; 3],
    pub world_from_object: [[f32; 4]; 3],
    pub root: u32,
    pub _pad0: u32,
    pub _pad1: u32,
    pub _pad2: u32,
}

#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable, PartialEq)]
pub struct GpuLight {
    pub prim: u32,
    pub cdf: f32,
    pub pmf: f32,
    pub area: f32,
}

/// A mirror's WGSL struct name, its size, and `(field, byte offset)` of each named field.
pub type MirrorLayout = (&'static str, usize, Vec<(&'static str, usize)>);

/// The layout of every mirror, for the test that compares them with naga's.
pub fn mirrors() -> Vec<MirrorLayout> {
    use std::mem::{offset_of, size_of};
    macro_rules! m {
        ($wgsl:literal, $t:ty, [$($f:ident),* $(,)?]) => {
            ($wgsl, size_of::<$t>(), vec![$((stringify!($f), offset_of!($t, $f))),*])
        };
    }
    vec![
        m!(
            "SceneUniforms",
            SceneUniforms,
            [
                cam_origin,
                lens_radius,
                cam_to_corner,
                n_lights,
                cam_horizontal,
                n_instances,
                cam_vertical,
                n_mirrors,
                cam_u,
                n_lenses,
                cam_v,
                sky_bottom,
                sky_uniform,
                sky_top,
                sun_dir,
                sun_size,
                sun_radiance,
                width,
                height,
                max_bounces,
                seed,
                n_spheres,
                n_quads,
                n_boxes,
                n_triangles,
                env_rotation,
                env_intensity,
                env_pick,
                env_mode,
            ]
        ),
        m!(
            "DispatchUniforms",
            DispatchUniforms,
            [
                sample_base,
                sample_count,
                row_offset,
                row_count,
                accumulate,
                lanes,
                row_stride
            ]
        ),
        m!(
            "ResolveUniforms",
            ResolveUniforms,
            [width, height, factor, out_width, out_height, mode]
        ),
        m!(
            "Material",
            GpuMaterial,
            [
                color,
                smoothness,
                specular_color,
                absorption,
                specular,
                light,
                ior,
                light_slot,
                metallic,
                roughness,
                model,
                transmission,
                attenuation,
                thin,
                clearcoat,
                clearcoat_roughness,
            ]
        ),
        m!(
            "Sphere",
            GpuSphere,
            [anchor, radius, anchor_normal, material]
        ),
        m!("Quad", GpuQuad, [q, material, u, v, normal, w]),
        m!(
            "Cuboid",
            GpuCuboid,
            [center, material, half_extents, axis_x, axis_y, axis_z]
        ),
        m!("Triangle", GpuTriangle, [v0, material, e1, e2]),
        m!(
            "BvhNode4",
            GpuBvhNode4,
            [min_x, min_y, min_z, max_x, max_y, max_z, child, count]
        ),
        m!("Light", GpuLight, [prim, cdf, pmf, area]),
        m!(
            "Instance",
            GpuInstance,
            [object_from_world, world_from_object, root]
        ),
    ]
}

const _: () = {
    assert!(std::mem::size_of::<SceneUniforms>() == 208);
    assert!(std::mem::size_of::<DispatchUniforms>() == 32);
    assert!(std::mem::size_of::<ResolveUniforms>() == 32);
    assert!(std::mem::size_of::<GpuMaterial>() == 96);
    assert!(std::mem::size_of::<GpuSphere>() == 32);
    assert!(std::mem::size_of::<GpuQuad>() == 80);
    assert!(std::mem::size_of::<GpuCuboid>() == 80);
    assert!(std::mem::size_of::<GpuTriangle>() == 48);
    assert!(std::mem::size_of::<GpuBvhNode4>() == 128);
    assert!(std::mem::size_of::<GpuLight>() == 16);
    assert!(std::mem::size_of::<GpuInstance>() == 112);
};
