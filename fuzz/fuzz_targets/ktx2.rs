//! KTX2 / Basis Universal images (glTF's `KHR_texture_basisu`) through the decode the glTF
//! loader uses: every input must become RGBA8 texels of the size its header gives, or be
//! refused with a message, never panic out of it. (The transcoder's own panics are caught
//! inside the decode and become the file's error; this target's quiet panic hook lets them
//! be caught, as they are in termtrace, instead of aborting at the first.) Seeds:
//! `fuzz/corpus/ktx2/` (BoxTextured's ETC1S and UASTC images, and two test images of
//! glTF-Transform's, MIT). Run: `cargo fuzz run -O ktx2` (README, "Fuzzing").
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    static QUIET: std::sync::Once = std::sync::Once::new();
    QUIET.call_once(|| std::panic::set_hook(Box::new(|_| {})));
    if let Ok(img) = termtrace::scene::gltf::decode_image(data) {
        assert_eq!(
            img.as_raw().len(),
            img.width() as usize * img.height() as usize * 4
        );
    }
});
