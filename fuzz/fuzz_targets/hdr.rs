//! Environment maps from memory through the same load the scene loader uses (Radiance HDR or
//! OpenEXR, by content): every input must become a map with its sampling distribution, or be
//! refused with a message, never panic; a map that loads must give finite densities. Seeds:
//! `fuzz/corpus/hdr/` (a small map with a sun texel, and a 1×1 EXR). Run:
//! `cargo fuzz run hdr` (README, "Fuzzing").
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    if let Ok(m) = termtrace::scene::envmap::EnvMap::from_bytes(data, "fuzz.hdr") {
        let d = &m.distribution;
        for (u1, u2) in [(0.0, 0.0), (0.5, 0.5), (0.999, 0.001), (0.25, 0.75)] {
            let s = d.sample(u1, u2, 0.3);
            assert!(s.pdf.is_finite() && s.pdf >= 0.0, "{s:?}");
            assert!(d.pdf(s.dir, 0.3).is_finite());
        }
    }
});
