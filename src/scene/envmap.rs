//! Environment maps as the model holds them: an equirectangular image of linear radiance
//! (Radiance `.hdr` or OpenEXR, through `image`), every texel checked on load, packed as both
//! tracers read it, with its sampling distribution built once.

use super::envmap_sampling::{Distribution, rgbe_pack, rgbe_unpack};
use std::path::Path;

/// Why an environment map cannot be used, naming its file.
#[derive(Debug, thiserror::Error)]
pub enum EnvMapError {
    #[error("{name}: cannot read it: {source}")]
    Read {
        name: String,
        #[source]
        source: std::io::Error,
    },
    #[error("{name}: not a Radiance HDR or OpenEXR image: {source}")]
    Decode {
        name: String,
        #[source]
        source: image::ImageError,
    },
    #[error("{name}: the image is empty")]
    Empty { name: String },
    #[error(
        "{name}: texel ({x}, {y}) (column, row from the top) is {value}: radiance must be \
         finite and not negative"
    )]
    Texel {
        name: String,
        x: u32,
        y: u32,
        value: f32,
    },
    #[error("no built-in map `{0}`")]
    NoBuiltin(String),
}

/// An equirectangular map of linear RGB radiance, rows from the top (the zenith), as RGBE
/// texels (`envmap_sampling::rgbe_pack`), and the distribution that samples it, built from
/// those texels (what the tracers see).
#[derive(Debug, PartialEq)]
pub struct EnvMap {
    pub width: u32,
    pub height: u32,
    pub rgbe: Vec<u32>,
    pub distribution: Distribution,
    /// The file, for messages.
    pub name: String,
}

impl EnvMap {
    /// Reads `path`. A texel that is NaN, infinite or negative is refused with its position:
    /// radiance cannot be any of these, and a map that holds one is broken (clamping it would
    /// hide that, and one such texel would bias every image it lights).
    pub fn load(path: &Path) -> Result<EnvMap, EnvMapError> {
        let name = path.display().to_string();
        let bytes = std::fs::read(path).map_err(|source| EnvMapError::Read {
            name: name.clone(),
            source,
        })?;
        Self::from_bytes(&bytes, &name)
    }

    /// A map from a file's bytes (a built-in scene's); `name` for messages.
    pub fn from_bytes(bytes: &[u8], name: &str) -> Result<EnvMap, EnvMapError> {
        let img = image::ImageReader::new(std::io::Cursor::new(bytes))
            .with_guessed_format()
            .map_err(|source| EnvMapError::Read {
                name: name.to_string(),
                source,
            })?
            .decode()
            .map_err(|source| EnvMapError::Decode {
                name: name.to_string(),
                source,
            })?;
        Self::from_image(img.to_rgb32f(), name.to_string())
    }

    /// A map of the pixels of `img`, checked as [`EnvMap::load`] does.
    pub fn from_image(img: image::Rgb32FImage, name: String) -> Result<EnvMap, EnvMapError> {
        let (width, height) = img.dimensions();
        if width == 0 || height == 0 {
            return Err(EnvMapError::Empty { name });
        }
        let mut rgbe = Vec::with_capacity((width * height) as usize);
        for (x, y, p) in img.enumerate_pixels() {
            let c = p.0;
            if let Some(&value) = c.iter().find(|v| !v.is_finite() || **v < 0.0) {
                return Err(EnvMapError::Texel { name, x, y, value });
            }
            rgbe.push(rgbe_pack(c));
        }
        drop(img);
        let distribution = Distribution::new(width, height, &unpack_all(&rgbe));
        Ok(EnvMap {
            width,
            height,
            rgbe,
            distribution,
            name,
        })
    }

    /// A map of one radiance in every direction (`width × height` texels).
    pub fn constant(width: u32, height: u32, c: [f32; 3], name: &str) -> EnvMap {
        let img = image::Rgb32FImage::from_pixel(width, height, image::Rgb(c));
        Self::from_image(img, name.into()).expect("a finite, non-negative radiance")
    }

    /// The radiance of texel (x, y), as the tracers decode it.
    pub fn texel(&self, x: u32, y: u32) -> [f32; 3] {
        rgbe_unpack(self.rgbe[(y * self.width + x) as usize])
    }

    /// The radiance the tracers see at map coordinates (u, v) (`envmap_sampling::coordinates`
    /// of the direction, for the map turned by its rotation): bilinear between texels, see
    /// `envmap_sampling::bilinear`.
    pub fn radiance_at(&self, u: f32, v: f32) -> [f32; 3] {
        super::envmap_sampling::bilinear(self.width, self.height, u, v, |x, y| self.texel(x, y))
    }

    /// Every texel decoded, row-major.
    pub fn texels(&self) -> Vec<[f32; 3]> {
        unpack_all(&self.rgbe)
    }

    /// Bytes the tracers hold: the RGBE texels and the CDFs.
    pub fn bytes(&self) -> usize {
        self.rgbe.len() * 4 + self.distribution.bytes()
    }
}

fn unpack_all(rgbe: &[u32]) -> Vec<[f32; 3]> {
    use rayon::prelude::*;
    rgbe.par_iter().map(|&w| rgbe_unpack(w)).collect()
}
