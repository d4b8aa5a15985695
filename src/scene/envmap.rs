//! Environment maps as the model holds them: an equirectangular image of linear radiance
//! (Radiance `.hdr` or OpenEXR, through `image`), every texel checked on load.

use std::path::Path;

/// An equirectangular map of linear RGB radiance, rows from the top (the zenith);
/// `common::envmap` maps directions onto it and samples it.
#[derive(Debug, PartialEq)]
pub struct EnvMap {
    pub width: u32,
    pub height: u32,
    pub texels: Vec<[f32; 3]>,
    /// The file, for messages.
    pub name: String,
}

impl EnvMap {
    /// Reads `path`. A texel that is NaN, infinite or negative is refused with its position:
    /// radiance cannot be any of these, and a map that holds one is broken (clamping it would
    /// hide that, and one such texel would bias every image it lights).
    pub fn load(path: &Path) -> Result<EnvMap, String> {
        let name = path.display().to_string();
        let img = image::ImageReader::open(path)
            .map_err(|e| format!("{name}: cannot read it: {e}"))?
            .with_guessed_format()
            .map_err(|e| format!("{name}: cannot read it: {e}"))?
            .decode()
            .map_err(|e| format!("{name}: not a Radiance HDR or OpenEXR image: {e}"))?;
        Self::from_image(img.to_rgb32f(), name)
    }

    /// A map of the pixels of `img`, checked as [`EnvMap::load`] does.
    pub fn from_image(img: image::Rgb32FImage, name: String) -> Result<EnvMap, String> {
        let (width, height) = img.dimensions();
        if width == 0 || height == 0 {
            return Err(format!("{name}: the image is empty"));
        }
        let mut texels = Vec::with_capacity((width * height) as usize);
        for (x, y, p) in img.enumerate_pixels() {
            let c = p.0;
            if let Some(bad) = c.iter().find(|v| !v.is_finite() || **v < 0.0) {
                return Err(format!(
                    "{name}: texel ({x}, {y}) (column, row from the top) is {bad}: radiance \
                     must be finite and not negative"
                ));
            }
            texels.push(c);
        }
        Ok(EnvMap {
            width,
            height,
            texels,
            name,
        })
    }

    /// Bytes the texels take as the tracers hold them (three f32 each).
    pub fn bytes(&self) -> usize {
        self.texels.len() * 12
    }
}
