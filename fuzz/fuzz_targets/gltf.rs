//! glTF and GLB files from memory through the same import the scene loader uses: every input
//! must be imported or refused with a message, never panic out of it. (The KTX2 transcoder's
//! panics are caught inside the import and become the file's error; a quiet panic hook lets
//! them be caught here too, as `ktx2`'s does.) Seeds: `fuzz/corpus/gltf/` (the public Box as
//! JSON, and compressed, instanced, WebP and KTX2 files). Run: `cargo fuzz run gltf` (README,
//! "Fuzzing").
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    static QUIET: std::sync::Once = std::sync::Once::new();
    QUIET.call_once(|| std::panic::set_hook(Box::new(|_| {})));
    let _ = termtrace::scene::gltf::import_slice(
        data,
        None,
        "fuzz.gltf",
        glam::DMat4::IDENTITY,
        None,
        Default::default(),
    );
});
