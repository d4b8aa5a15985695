//! Textures as the render model holds them: 8-bit RGBA images with a wrap mode per axis, and
//! the textured form of a glTF material (its maps and factors), which both tracers map onto
//! MODEL.md's material at each hit (`shaders/common/texture.wgsl`, `cpu::texture`).

use std::sync::Arc;

/// How a texture coordinate outside [0, 1] is brought back (glTF's sampler wrap modes).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(u32)]
pub enum Wrap {
    Repeat = 0,
    Clamp = 1,
    Mirror = 2,
}

/// An image: `width × height` texels, rows from the top (glTF's UV origin is the image's
/// upper-left corner), each packed `r | g << 8 | b << 16 | a << 24`, as stored (colour maps
/// are sRGB-decoded when sampled).
#[derive(Debug, PartialEq)]
pub struct Texture {
    pub width: u32,
    pub height: u32,
    pub texels: Vec<u32>,
    /// The wrap mode along u and along v.
    pub wrap: [Wrap; 2],
    /// Where it came from, for messages (`images[2] (`wood.png`)`).
    pub name: String,
}

impl Texture {
    /// Bytes the texels take.
    pub fn bytes(&self) -> usize {
        self.texels.len() * 4
    }
}

/// glTF's `alphaMode`: opaque, a cut-out at `alphaCutoff` (leaves, fences), or blended,
/// which the tracers treat as a stochastic cut-out (a ray passes with probability 1 − alpha).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum AlphaMode {
    Opaque,
    Mask(f32),
    Blend,
}

/// A glTF material with texture maps: what each hit maps onto the model's material (base
/// colour = factor × map, metallic and roughness = factors × the map's blue and green,
/// emission = factor × strength × map; docs/MODEL-NOTES.md, "glTF materials").
#[derive(Debug, PartialEq)]
pub struct Textured {
    pub base_color: Option<Arc<Texture>>,
    pub metallic_roughness: Option<Arc<Texture>>,
    pub emissive: Option<Arc<Texture>>,
    /// A tangent-space normal map (glTF's `normalTexture`).
    pub normal: Option<Arc<Texture>>,
    /// The normal map's `scale`: the tangent-space x and y are multiplied by it.
    pub normal_scale: f32,
    pub base_factor: [f32; 4],
    pub metallic: f32,
    pub roughness: f32,
    /// `emissiveFactor × emissiveStrength`.
    pub emissive_factor: [f32; 3],
    pub alpha: AlphaMode,
    /// Each map's `KHR_texture_transform` (base colour, metallic-roughness, emissive, normal), as
    /// the rows of a 2×3 matrix: u' = m[0]·u + m[1]·v + m[2], v' = m[3]·u + m[4]·v + m[5].
    pub transforms: [[f32; 6]; 4],
    /// The maps of the material extensions the pbr model reads.
    pub extensions: ExtensionMaps,
}

/// A map and its `KHR_texture_transform`.
pub type Map = (Arc<Texture>, [f32; 6]);

/// The maps of the material extensions the pbr model reads; each multiplies the material's
/// factor (which the preview edits) by one channel, as the extensions define them.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ExtensionMaps {
    /// KHR_materials_transmission's transmissionTexture: its red channel.
    pub transmission: Option<Map>,
    /// KHR_materials_clearcoat's clearcoatTexture (red) and clearcoatRoughnessTexture (green).
    pub clearcoat: Option<Map>,
    pub clearcoat_roughness: Option<Map>,
    /// KHR_materials_specular's specularTexture (alpha) and specularColorTexture (RGB, sRGB).
    pub specular: Option<Map>,
    pub specular_color: Option<Map>,
}

impl ExtensionMaps {
    /// The maps in the order of the texture words' records (`common::textures`).
    pub fn all(&self) -> [&Option<Map>; 5] {
        [
            &self.transmission,
            &self.clearcoat,
            &self.clearcoat_roughness,
            &self.specular,
            &self.specular_color,
        ]
    }
}

/// The identity texture transform.
pub const IDENTITY_TRANSFORM: [f32; 6] = [1.0, 0.0, 0.0, 0.0, 1.0, 0.0];

impl Textured {
    /// Whether some hits on it are not hits (a cut-out).
    pub fn cuts_out(&self) -> bool {
        self.alpha != AlphaMode::Opaque
    }
}

/// A material's textures, shared by every object that uses them; two are the same when they
/// are the same allocation (comparing texels on every edit would cost a frame).
#[derive(Clone, Debug)]
pub struct TexturedRef(pub Arc<Textured>);

impl PartialEq for TexturedRef {
    fn eq(&self, other: &Self) -> bool {
        Arc::ptr_eq(&self.0, &other.0)
    }
}

impl Texture {
    /// One texel of this texture's mean (of its stored values, channel by channel).
    pub fn mean(&self) -> Texture {
        let mut sum = [0u64; 4];
        for t in &self.texels {
            for (k, s) in sum.iter_mut().enumerate() {
                *s += ((t >> (8 * k)) & 0xff) as u64;
            }
        }
        let n = self.texels.len().max(1) as u64;
        let m = sum.map(|s| ((s + n / 2) / n) as u32);
        Texture {
            width: 1,
            height: 1,
            texels: vec![m[0] | m[1] << 8 | m[2] << 16 | m[3] << 24],
            wrap: self.wrap,
            name: format!("the mean of {}", self.name),
        }
    }
}
