//! Exact-sum snapshots (`.tta`, both format versions) from memory: every input must become a
//! part whose halves hold the words its header promises, or be refused with a message, never
//! panic, and never inflate more than its header's image holds. Seeds: `fuzz/corpus/tta/`
//! (a 4×3 part in each version). Run: `cargo fuzz run tta` (README, "Fuzzing").
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    if let Ok(p) = termtrace::render::shard::parse(data) {
        assert_eq!(p.even.len(), p.odd.len());
        let pixels = p.header.width as usize * p.header.height as usize;
        assert_eq!(p.even.len(), pixels * termtrace::common::accum::ACCUM_WORDS);
    }
});
