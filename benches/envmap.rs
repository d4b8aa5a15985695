//! Building an environment map's sampling distribution (`common::envmap::Distribution`): the
//! time and the memory for a real 1k map when one is given, and for synthetic 2k and 8k maps
//! (a sky gradient with a bright sun disc, the hard case of the issue).
//!
//! `cargo bench --bench envmap [-- MAP.hdr]`.

use std::time::Instant;
use termtrace::common::envmap::Distribution;
use termtrace::scene::envmap::EnvMap;

fn synthetic(w: u32, h: u32) -> Vec<[f32; 3]> {
    let sun = (w as f32 * 0.3, h as f32 * 0.25);
    let r2 = (w as f32 / 400.0).max(1.0).powi(2);
    (0..h)
        .flat_map(|y| (0..w).map(move |x| (x, y)))
        .map(|(x, y)| {
            let t = y as f32 / h as f32;
            let d2 = (x as f32 - sun.0).powi(2) + (y as f32 - sun.1).powi(2);
            if d2 < r2 {
                [1e5, 9e4, 8e4]
            } else {
                [0.3 + 0.5 * t, 0.5 + 0.3 * t, 1.0 - 0.5 * t].map(|c| c * 1e-3 + c)
            }
        })
        .collect()
}

fn measure(what: &str, w: u32, h: u32, texels: &[[f32; 3]]) {
    let mut best = f64::INFINITY;
    let mut d = None;
    for _ in 0..3 {
        let t = Instant::now();
        d = Some(Distribution::new(w, h, texels));
        best = best.min(t.elapsed().as_secs_f64());
    }
    let d = d.expect("built");
    println!(
        "{what:<28} {w:>5}×{h:<5} build {:>8.1} ms (best of 3)   texels {:>7.1} MiB   CDFs {:>6.1} MiB",
        best * 1e3,
        (texels.len() * 4) as f64 / (1 << 20) as f64,
        d.bytes() as f64 / (1 << 20) as f64
    );
}

fn main() {
    if let Some(path) = std::env::args().skip(1).find(|a| !a.starts_with('-')) {
        let t = Instant::now();
        let m = EnvMap::load(std::path::Path::new(&path)).unwrap_or_else(|e| panic!("{e}"));
        println!("loaded {path} in {:.1} ms", t.elapsed().as_secs_f64() * 1e3);
        measure("the map given", m.width, m.height, &m.texels());
    }
    for (w, h) in [(2048, 1024), (8192, 4096)] {
        measure("synthetic sky with a sun", w, h, &synthetic(w, h));
    }
}
