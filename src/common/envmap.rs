//! An environment map as the GPU binds it: one storage buffer of a header, the sampling
//! distribution's CDFs and the RGBE texels (shaders/common/envmap.wgsl reads it), and whether
//! an adapter can bind it. The arithmetic both tracers share (directions, lookup, sampling)
//! is `scene::envmap_sampling`, re-exported here.

pub use crate::scene::envmap_sampling::*;

/// The words a map is uploaded as (one storage buffer, `env` in shaders/common/envmap.wgsl):
/// a header of [`ENV_HEADER`] words (width, height, the first word of the conditional CDFs,
/// the first word of the texels), the marginal CDF (`height + 1` f32), the conditional CDFs
/// (`height × (width + 1)` f32), then the RGBE texels, row-major from the top. An 8k map
/// (8192 × 4096) takes 256 MiB.
pub fn words(d: &Distribution, rgbe: &[u32]) -> Vec<u32> {
    debug_assert_eq!(rgbe.len(), (d.width * d.height) as usize);
    let conditional = ENV_HEADER + d.marginal.len();
    let texels = conditional + d.conditional.len();
    let mut w = Vec::with_capacity(words_len(d));
    w.extend([d.width, d.height, conditional as u32, texels as u32]);
    w.extend(d.marginal.iter().map(|x| x.to_bits()));
    w.extend(d.conditional.iter().map(|x| x.to_bits()));
    w.extend_from_slice(rgbe);
    w
}

/// The header words of [`words`]; the marginal CDF follows them.
pub const ENV_HEADER: usize = 4;

/// How many words [`words`] makes for a map.
pub fn words_len(d: &Distribution) -> usize {
    ENV_HEADER + d.marginal.len() + d.conditional.len() + (d.width * d.height) as usize
}

/// Why a map cannot be bound on an adapter that binds at most `limit` bytes in one storage
/// buffer, or None where it can (`name` names the map in the message).
pub fn too_large(d: &Distribution, name: &str, limit: u64) -> Option<String> {
    let bytes = 4 * words_len(d) as u64;
    let mib = |b: u64| b as f64 / (1 << 20) as f64;
    (bytes > limit).then(|| {
        format!(
            "the environment map {name} ({}×{}) takes {:.1} MiB in one storage buffer, more \
             than the {:.1} MiB this adapter binds. Use a smaller map, or trace on the CPU \
             (the adapter `cpu-native`), which has no such limit",
            d.width,
            d.height,
            mib(bytes),
            mib(limit)
        )
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_map_larger_than_the_adapter_binds_is_refused_by_name_and_size() {
        let d = Distribution::new(8, 4, &[[1.0; 3]; 32]);
        // 4 header words, 5 marginal, 4 × 9 conditional, 32 texels.
        let bytes = 4 * (4 + 5 + 36 + 32);
        assert_eq!(words_len(&d) * 4, bytes);
        assert!(too_large(&d, "sky.hdr", bytes as u64).is_none());
        let why = too_large(&d, "sky.hdr", bytes as u64 - 1).unwrap();
        assert!(
            why.contains("sky.hdr (8×4)") && why.contains("cpu-native"),
            "{why}"
        );
    }

    #[test]
    fn the_shaders_constants_are_these() {
        use crate::common::arrays::{ENV_NONE, ENV_VISIBLE};
        use crate::common::wgsl::u32_constant;
        assert_eq!(
            u32_constant("common/envmap.wgsl", "ENV_HEADER") as usize,
            ENV_HEADER
        );
        assert_eq!(u32_constant("trace.wgsl", "ENV_NONE"), ENV_NONE);
        assert_eq!(u32_constant("trace.wgsl", "ENV_VISIBLE"), ENV_VISIBLE);
    }
}
