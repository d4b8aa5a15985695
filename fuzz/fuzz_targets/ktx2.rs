//! KTX2 / Basis Universal images (glTF's `KHR_texture_basisu`) through the decode the glTF
//! loader uses: every input must become RGBA8 texels of the size its header gives, or be
//! refused with a message, never panic. Seeds: `fuzz/corpus/ktx2/` (BoxTextured's ETC1S and
//! UASTC images, and two test images of glTF-Transform's, MIT). Run: `cargo fuzz run ktx2`
//! (README, "Fuzzing").
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    if let Ok(img) = termtrace::scene::gltf::decode_image(data) {
        assert_eq!(
            img.as_raw().len(),
            img.width() as usize * img.height() as usize * 4
        );
    }
});
