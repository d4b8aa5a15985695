//! The host's share of a graphics preview frame: a 960×608 image (the preview's largest) to
//! 8-bit sRGB, the per-pixel noise thresholds of the change test, and each protocol's escape
//! sequences (kitty and iTerm2 in bands, sixel whole), timed one by one.
//!
//! `cargo bench --bench image_path`. The image is noise, which compresses worst.

use std::time::{Duration, Instant};
use termtrace::output::{LinearImage, Transfer};
use termtrace::ui::graphics::{self, Encoder, Protocol};

const WIDTH: u32 = 960;
const HEIGHT: u32 = 608;
/// Cell rows the image covers (16 pixels each).
const ROWS: u16 = 38;
const RUNS: usize = 5;

/// The fastest of `RUNS` timings of `f`, and its result.
fn time<T>(mut f: impl FnMut() -> T) -> (Duration, T) {
    let mut best = (Duration::MAX, None);
    for _ in 0..RUNS {
        let t = Instant::now();
        let r = f();
        let d = t.elapsed();
        if d < best.0 {
            best = (d, Some(r));
        }
    }
    (best.0, best.1.expect("at least one run"))
}

fn main() {
    let mut img = LinearImage::new(WIDTH, HEIGHT);
    let mut s = 1u32;
    for c in img.pixels.iter_mut().flatten() {
        s = s.wrapping_mul(1664525).wrapping_add(1013904223);
        *c = (s >> 8) as f32 / 16777216.0 * 0.8;
    }
    let sigma = vec![0.01f32; img.pixels.len()];
    let (d, _) = time(|| img.to_rgb8(Transfer::Srgb));
    println!("to 8-bit sRGB      {:6.2} ms", d.as_secs_f64() * 1e3);
    let (d, _) = time(|| graphics::pixel_thresholds(&img, &sigma, 2));
    println!("noise thresholds   {:6.2} ms", d.as_secs_f64() * 1e3);
    for p in [Protocol::Kitty, Protocol::Iterm, Protocol::Sixel] {
        let e = Encoder {
            protocol: p,
            tmux: false,
            colors: 256,
        };
        let (d, bytes) = time(|| {
            if p == Protocol::Sixel {
                return e.frame(&img, 120, ROWS).len();
            }
            graphics::bands(p, ROWS)
                .iter()
                .enumerate()
                .map(|(i, band)| {
                    let rows = graphics::band_pixels(HEIGHT, ROWS, *band);
                    e.band(&graphics::crop_rows(&img, rows), 120, band.1, i as u32)
                        .len()
                })
                .sum::<usize>()
        });
        println!(
            "{:<18} {:6.2} ms, {bytes} bytes (one thread)",
            p.name(),
            d.as_secs_f64() * 1e3
        );
    }
}
