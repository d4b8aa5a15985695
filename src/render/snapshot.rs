//! What the accumulation holds at one moment, on the host: per-pixel sums of the even and
//! odd samples, from which the image and its noise estimate are computed.

use crate::gpu::AccumData;
use crate::output::LinearImage;

#[derive(Clone, Debug)]
pub struct Snapshot {
    pub width: u32,
    pub height: u32,
    pub data: AccumData,
    /// Samples per pixel in every completed round.
    pub samples: u32,
}

impl Snapshot {
    /// The displayed image: sum / weight per pixel (the lecture's `accumulated / peso`).
    pub fn image(&self) -> LinearImage {
        let pixels = self
            .data
            .even
            .iter()
            .zip(&self.data.odd)
            .map(|(e, o)| {
                let w = e[3] as f64 + o[3] as f64;
                if w > 0.0 {
                    std::array::from_fn(|c| ((e[c] as f64 + o[c] as f64) / w) as f32)
                } else {
                    [0.0; 3]
                }
            })
            .collect();
        LinearImage {
            width: self.width,
            height: self.height,
            pixels,
        }
    }

    /// Fewest samples any pixel holds (pixels in an unfinished round hold more).
    pub fn min_samples(&self) -> u64 {
        self.data
            .even
            .iter()
            .zip(&self.data.odd)
            .map(|(e, o)| (e[3] + o[3]) as u64)
            .min()
            .unwrap_or(0)
    }

    /// Samples discarded as NaN or infinite since the last reset.
    pub fn invalid_samples(&self) -> u64 {
        self.data.invalid
    }
}
