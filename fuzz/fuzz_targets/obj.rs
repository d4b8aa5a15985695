//! OBJ files with an MTL library and one image, from memory, through the same import the scene
//! loader uses: every input must be imported or refused with a message, never panic. The
//! input is the OBJ text, the library and the image, separated by the byte 0x1e (ASCII record separator): every
//! `mtllib` reads the library, every map the image. Seeds: `fuzz/corpus/obj/`. Run: `cargo
//! fuzz run obj` (README, "Fuzzing").
#![no_main]

use libfuzzer_sys::fuzz_target;
use std::path::Path;

fuzz_target!(|data: &[u8]| {
    let mut parts = data.split(|&b| b == 0x1e);
    let obj = String::from_utf8_lossy(parts.next().unwrap_or_default()).into_owned();
    let mtl = parts.next().unwrap_or_default().to_vec();
    let image = parts.next().unwrap_or_default().to_vec();
    let read = |p: &Path| -> std::io::Result<Vec<u8>> {
        match p.extension().and_then(|e| e.to_str()) {
            Some("mtl") => Ok(mtl.clone()),
            Some(_) => Ok(image.clone()),
            None => Err(std::io::ErrorKind::NotFound.into()),
        }
    };
    let _ = termtrace::scene::obj::import_from(
        "fuzz.obj",
        &obj,
        Path::new("."),
        &read,
        glam::DMat4::IDENTITY,
    );
});
