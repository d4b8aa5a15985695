//! One preview frame as either tracer resolves it: the downsampled image, its noise estimate
//! and each pixel's standard error, from the terms `shaders/resolve.wgsl` computes on the GPU
//! and `cpu` on the host.

use crate::output::LinearImage;

/// pbrt's relative MSE adds this to the squared reference so that black pixels do not divide
/// by zero (pbrt-v4, `imgtool diff --metric relmse`); both tracers' noise estimates use it.
pub const REL_MSE_EPSILON: f64 = 0.01;

/// An estimated relative RMSE as the status line shows it: the value, or, where the
/// estimate is within two standard errors of zero (its noise as large as itself: few
/// samples, or a filter that removed nearly all the noise), only a bound above.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Estimate {
    Value(f64),
    Below(f64),
}

impl Estimate {
    pub fn text(self) -> String {
        match self {
            Estimate::Value(v) => format!("{:.2}%", v * 100.0),
            Estimate::Below(v) => format!("<{:.2}%", v * 100.0),
        }
    }
}

/// One resolved frame on the host.
#[derive(Clone, Debug)]
pub struct Resolved {
    pub image: LinearImage,
    /// The traced image's estimated relative RMSE (see `Snapshot::error_estimate`); `None`
    /// until every pixel has a sample in each half.
    pub noise: Option<f64>,
    /// Samples discarded as NaN or infinite since the last reset.
    pub invalid: u64,
    /// Per image pixel, the estimated standard error of its linear value (the two halves'
    /// estimate, averaged over channels and the block); 0 where not yet known.
    pub sigma: Vec<f32>,
    /// The estimated relative RMSE of the image when it is a denoised one (`denoise`).
    pub denoised: Option<Estimate>,
}

impl Resolved {
    /// The frame from the resolve's two vec4f per output pixel (see resolve.wgsl; the CPU
    /// tracer computes the same terms on the host): `out` pixels, each the mean of a
    /// `factor × factor` block.
    pub fn from_blocks(words: &[[f32; 8]], out: (u32, u32), factor: u32, invalid: u64) -> Resolved {
        let n = out.0 as usize * out.1 as usize;
        // The block's mean has 1/factor⁴ of its pixels' summed variance.
        let block = (factor * factor) as f32;
        let sigma = words
            .iter()
            .map(|w| (w[4] / (3.0 * block * block)).max(0.0).sqrt())
            .collect();
        let (mut rel, mut fewest) = (0.0f64, f32::INFINITY);
        let pixels = words
            .iter()
            .map(|w| {
                fewest = fewest.min(w[3]);
                rel += w[5] as f64;
                [w[0], w[1], w[2]]
            })
            .collect();
        // Over the traced pixels the output covers (all of them when the size divides).
        let channels = 3.0 * n as f64 * block as f64;
        Resolved {
            image: LinearImage {
                width: out.0,
                height: out.1,
                pixels,
            },
            noise: (fewest >= 1.0).then(|| (rel / channels).sqrt()),
            invalid,
            sigma,
            denoised: None,
        }
    }
}
