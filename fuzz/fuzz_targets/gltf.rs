//! glTF and GLB files from memory through the same import the scene loader uses: every input
//! must be imported or refused with a message, never panic. Seeds: `fuzz/corpus/gltf/` (the
//! public Box as JSON). Run: `cargo fuzz run gltf` (README, "Fuzzing").
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let _ = termtrace::scene::gltf::import_slice(
        data,
        None,
        "fuzz.gltf",
        glam::DMat4::IDENTITY,
        None,
        Default::default(),
    );
});
