//! Pixel graphics for the preview: the image by the kitty graphics protocol, sixel, or
//! iTerm2's inline images, each wrapped for tmux's passthrough when inside tmux.
//!
//! Sixel goes through `icy_sixel` (Wu quantization to the terminal's colour registers with
//! Floyd–Steinberg dithering, the part worth a crate). Kitty and iTerm2 are written here:
//! a frame is one base64 payload in one escape sequence (kitty: chunks of 4096 bytes), a few
//! lines that no crate offers for a stream of frames without also taking over the terminal
//! (ratatui-image draws through its own widgets and runs its own terminal queries, which
//! would race the preview's input thread for the answers).
//! Protocols: <https://sw.kovidgoyal.net/kitty/graphics-protocol/>, VT330/VT340
//! Programmer Reference Manual ch. 14 (sixel), <https://iterm2.com/documentation-images.html>.

use crate::output::{LinearImage, Transfer};
use base64::Engine;
use std::io::Write;

/// The id of the preview image in kitty (reused, so each frame replaces the last).
pub const IMAGE_ID: u32 = 7411;
/// Base64 bytes per kitty escape sequence, as the protocol asks.
const CHUNK: usize = 4096;

/// How pixels reach the terminal.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Protocol {
    Kitty,
    Sixel,
    Iterm,
}

impl Protocol {
    pub fn name(self) -> &'static str {
        match self {
            Protocol::Kitty => "kitty",
            Protocol::Sixel => "sixel",
            Protocol::Iterm => "iTerm2",
        }
    }
}

/// Encodes preview frames for one terminal.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Encoder {
    pub protocol: Protocol,
    /// Inside tmux: every sequence goes through its passthrough.
    pub tmux: bool,
    /// Sixel colour registers (the terminal's answer, else 256).
    pub colors: u16,
}

/// Cell rows per band of a kitty or iTerm2 image: each band is its own image, resent only
/// when it changed (sixel, which cannot place an image at a pixel row that is not a multiple
/// of its six-row bands, sends whole images).
pub const BAND_ROWS: u16 = 4;

/// The bands of an image over `rows` cell rows: (first row, rows), top to bottom.
pub fn bands(protocol: Protocol, rows: u16) -> Vec<(u16, u16)> {
    if protocol == Protocol::Sixel || rows == 0 {
        return vec![(0, rows)];
    }
    (0..rows)
        .step_by(BAND_ROWS as usize)
        .map(|r| (r, BAND_ROWS.min(rows - r)))
        .collect()
}

/// `h` pixel rows cut to whole six-row sixel bands (from 6 rows on): a last partial band
/// would reach below the image area, into the status lines.
pub fn sixel_height(h: u32) -> u32 {
    if h >= 6 { h - h % 6 } else { h }
}

/// The pixel rows of `img` under cell rows `[row, row + n)` of `rows`.
pub fn band_pixels(img_height: u32, rows: u16, (row, n): (u16, u16)) -> std::ops::Range<u32> {
    let at = |r: u16| (r as u64 * img_height as u64 / rows.max(1) as u64) as u32;
    at(row)..at(row + n)
}

/// Rows `range` of `img`.
pub fn crop_rows(img: &LinearImage, range: std::ops::Range<u32>) -> LinearImage {
    let w = img.width as usize;
    LinearImage {
        width: img.width,
        height: range.end - range.start,
        pixels: img.pixels[range.start as usize * w..range.end as usize * w].to_vec(),
    }
}

impl Encoder {
    /// Sequences that show `img` over `cols × rows` cells at the cursor.
    pub fn frame(&self, img: &LinearImage, cols: u16, rows: u16) -> String {
        self.band(img, cols, rows, 0)
    }

    /// Sequences that show band `index` of an image, `img`, over `cols × rows` cells at the
    /// cursor (kitty: an image of its own, replacing that band's last one).
    pub fn band(&self, img: &LinearImage, cols: u16, rows: u16, index: u32) -> String {
        let seqs = match self.protocol {
            Protocol::Kitty => kitty(img, cols, rows, IMAGE_ID + index),
            Protocol::Sixel => vec![sixel(img, self.colors)],
            Protocol::Iterm => vec![iterm(img, cols, rows)],
        };
        self.wrap(seqs)
    }

    /// Sequences that remove what `frame` showed (kitty keeps images beyond the text): every
    /// placement, and the images' data.
    pub fn clear(&self) -> String {
        match self.protocol {
            Protocol::Kitty => self.wrap(vec!["\x1b_Ga=d,d=A,q=2\x1b\\".to_string()]),
            Protocol::Sixel | Protocol::Iterm => String::new(),
        }
    }

    fn wrap(&self, seqs: Vec<String>) -> String {
        if self.tmux {
            seqs.iter().map(|s| tmux_wrap(s)).collect()
        } else {
            seqs.concat()
        }
    }
}

/// Per pixel, the change of its 8-bit sRGB value within its own noise: twice the standard
/// error `sigma` (linear) carried through the sRGB curve at its brightest channel, at least
/// `base` (as `cells::noise_thresholds` does for cells, here by the 8-bit table).
pub fn pixel_thresholds(img: &LinearImage, sigma: &[f32], base: u8) -> Vec<u8> {
    use rayon::prelude::*;
    img.pixels
        .par_iter()
        .enumerate()
        .map(|(i, p)| {
            let s = sigma.get(i).copied().unwrap_or(0.0);
            let l = p.iter().copied().fold(0.0f32, f32::max).clamp(0.0, 1.0);
            let step = crate::output::srgb8(l + 2.0 * s) - crate::output::srgb8(l);
            step.max(base)
        })
        .collect()
}

/// Fraction of the pixels (8-bit RGB, three bytes each) that moved from `old` to `new` by
/// more than their own threshold in some channel (`pixel_thresholds`): below a percent or
/// so the change is the noise falling, and the image need not be resent.
pub fn changed_fraction(old: &[u8], new: &[u8], thresholds: &[u8]) -> f64 {
    if old.len() != new.len() || new.is_empty() {
        return 1.0;
    }
    let moved = old
        .chunks_exact(3)
        .zip(new.chunks_exact(3))
        .zip(thresholds)
        .filter(|((a, b), t)| (0..3).any(|c| a[c].abs_diff(b[c]) > **t))
        .count();
    moved as f64 / (new.len() / 3) as f64
}

/// `img` resampled to `w × h` by nearest neighbour (sixel shows pixels one to one).
pub fn resample(img: &LinearImage, w: u32, h: u32) -> LinearImage {
    let mut out = LinearImage::new(w.max(1), h.max(1));
    for y in 0..out.height {
        let sy = (y as u64 * img.height as u64 / out.height as u64) as u32;
        for x in 0..out.width {
            let sx = (x as u64 * img.width as u64 / out.width as u64) as u32;
            out.pixels[(y * out.width + x) as usize] = img.get(sx, sy);
        }
    }
    out
}

/// The factor (1 to `max`) by which to shrink an image of `pixels` before sending so that it
/// takes at most `budget` bytes at `bytes_per_pixel`: on a slow link fewer pixels (which
/// kitty and iTerm2 scale back up over the same cells; sixel cannot, its image is smaller).
pub fn shrink_for(pixels: u64, bytes_per_pixel: f64, budget: Option<u64>, max: u32) -> u32 {
    let Some(budget) = budget else { return 1 };
    (1..=max.max(1))
        .find(|k| pixels as f64 * bytes_per_pixel / (k * k) as f64 <= budget as f64)
        .unwrap_or(max.max(1))
}

/// A band to send: its index and its cell rows (first, count).
pub type Band = (u32, (u16, u16));

/// The bands of `due` that go in this frame: in order, as many as `bytes` estimates to fit in
/// `budget`, and always the first; and the indices of the rest, for the next frames.
pub fn fit_bands(
    due: Vec<Band>,
    bytes: impl Fn((u16, u16)) -> f64,
    budget: f64,
) -> (Vec<Band>, Vec<u32>) {
    let (mut now, mut later, mut used) = (Vec::new(), Vec::new(), 0.0);
    for (index, band) in due {
        let b = bytes(band);
        if !now.is_empty() && (!later.is_empty() || used + b > budget) {
            later.push(index);
        } else {
            used += b;
            now.push((index, band));
        }
    }
    (now, later)
}

/// `seq` through tmux's passthrough (`allow-passthrough on`): a DCS `tmux;` with every ESC
/// doubled.
pub fn tmux_wrap(seq: &str) -> String {
    format!("\x1bPtmux;{}\x1b\\", seq.replace('\x1b', "\x1b\x1b"))
}

/// Kitty: zlib-compressed RGB in chunks, placed over `cols × rows` cells without moving the
/// cursor (C=1), replacing the previous frame (same id), quietly (q=2).
fn kitty(img: &LinearImage, cols: u16, rows: u16, id: u32) -> Vec<String> {
    let rgb = img.to_rgb8(Transfer::Srgb).into_raw();
    let mut z = flate2::write::ZlibEncoder::new(Vec::new(), flate2::Compression::fast());
    z.write_all(&rgb).expect("writing to memory");
    let data = base64::engine::general_purpose::STANDARD.encode(z.finish().expect("zlib"));
    let chunks: Vec<&[u8]> = data.as_bytes().chunks(CHUNK).collect();
    chunks
        .iter()
        .enumerate()
        .map(|(i, chunk)| {
            let more = u8::from(i + 1 < chunks.len());
            let payload = std::str::from_utf8(chunk).expect("base64 is ASCII");
            if i == 0 {
                format!(
                    "\x1b_Ga=T,f=24,o=z,s={},v={},i={id},c={cols},r={rows},C=1,q=2,m={more};{payload}\x1b\\",
                    img.width, img.height
                )
            } else {
                format!("\x1b_Gm={more};{payload}\x1b\\")
            }
        })
        .collect()
}

/// Sixel: the image quantized to `colors` registers (at least 2), dithered.
fn sixel(img: &LinearImage, colors: u16) -> String {
    let rgba: Vec<u8> = img
        .to_rgb8(Transfer::Srgb)
        .into_raw()
        .chunks_exact(3)
        .flat_map(|p| [p[0], p[1], p[2], 255])
        .collect();
    let opts = icy_sixel::EncodeOptions {
        max_colors: colors.clamp(2, 256),
        ..Default::default()
    };
    icy_sixel::sixel_encode(&rgba, img.width as usize, img.height as usize, &opts)
        .unwrap_or_default()
}

/// iTerm2: the image as a PNG, stretched over `cols × rows` cells.
fn iterm(img: &LinearImage, cols: u16, rows: u16) -> String {
    let mut png = Vec::new();
    let rgb = img.to_rgb8(Transfer::Srgb);
    let encoder = image::codecs::png::PngEncoder::new_with_quality(
        &mut png,
        image::codecs::png::CompressionType::Fast,
        image::codecs::png::FilterType::Sub,
    );
    if image::ImageEncoder::write_image(
        encoder,
        rgb.as_raw(),
        img.width,
        img.height,
        image::ExtendedColorType::Rgb8,
    )
    .is_err()
    {
        return String::new();
    }
    format!(
        "\x1b]1337;File=inline=1;size={};width={cols};height={rows};preserveAspectRatio=0:{}\x07",
        png.len(),
        base64::engine::general_purpose::STANDARD.encode(&png)
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::io::Read;

    fn test_image(w: u32, h: u32) -> LinearImage {
        let mut img = LinearImage::new(w, h);
        for (i, p) in img.pixels.iter_mut().enumerate() {
            let (x, y) = (
                (i as u32 % w) as f32 / w as f32,
                (i as u32 / w) as f32 / h as f32,
            );
            *p = [x, y, 0.5 * (1.0 - x) * y];
        }
        img
    }

    fn encoder(protocol: Protocol, tmux: bool) -> Encoder {
        Encoder {
            protocol,
            tmux,
            colors: 256,
        }
    }

    #[test]
    fn kitty_chunks_reassemble_to_the_image() {
        let img = test_image(64, 40);
        let s = encoder(Protocol::Kitty, false).frame(&img, 32, 10);
        assert!(s.starts_with("\x1b_Ga=T,f=24,o=z,s=64,v=40,"));
        assert!(s.contains("c=32,r=10"));
        let mut payload = String::new();
        let mut last_more = None;
        for seq in s.split("\x1b\\").filter(|x| !x.is_empty()) {
            let (head, data) = seq.split_once(';').unwrap();
            assert!(data.len() <= CHUNK);
            last_more = Some(head.ends_with("m=1"));
            payload.push_str(data);
        }
        assert_eq!(last_more, Some(false), "the last chunk must say m=0");
        let z = base64::engine::general_purpose::STANDARD
            .decode(payload)
            .unwrap();
        let mut rgb = Vec::new();
        flate2::read::ZlibDecoder::new(&z[..])
            .read_to_end(&mut rgb)
            .unwrap();
        assert_eq!(rgb, img.to_rgb8(Transfer::Srgb).into_raw());
    }

    fn upside_down(img: &LinearImage) -> LinearImage {
        let mut out = img.clone();
        let w = img.width as usize;
        for (y, row) in out.pixels.chunks_exact_mut(w).enumerate() {
            let src = (img.height as usize - 1 - y) * w;
            row.copy_from_slice(&img.pixels[src..src + w]);
        }
        out
    }

    /// (mean absolute error per pixel and channel, the same over 4×4 block means) of a
    /// decoded RGBA image against the 8-bit original, in levels.
    fn errors(rgba: &[u8], want: &[u8], w: usize, h: usize) -> (f64, f64) {
        let px = |x: usize, y: usize, c: usize| {
            (
                rgba[4 * (y * w + x) + c] as f64,
                want[3 * (y * w + x) + c] as f64,
            )
        };
        let mut per_pixel = 0.0;
        for y in 0..h {
            for x in 0..w {
                for c in 0..3 {
                    let (a, b) = px(x, y, c);
                    per_pixel += (a - b).abs();
                }
            }
        }
        let mut blocks = 0.0;
        for by in 0..h / 4 {
            for bx in 0..w / 4 {
                for c in 0..3 {
                    let (mut a, mut b) = (0.0, 0.0);
                    for y in 0..4 {
                        for x in 0..4 {
                            let (p, q) = px(4 * bx + x, 4 * by + y, c);
                            a += p;
                            b += q;
                        }
                    }
                    blocks += (a - b).abs() / 16.0;
                }
            }
        }
        (
            per_pixel / (3 * w * h) as f64,
            blocks / (3 * (w / 4) * (h / 4)) as f64,
        )
    }

    #[test]
    fn sixel_decodes_back_to_the_image_within_the_palettes_error() {
        // A gradient over all three channels quantized to a palette with error diffusion:
        // each pixel is off by the dither's noise, but local means keep the image (measured
        // with 256 registers: 5.3 levels per pixel, 1.2 per 4×4 block; with 16: 16.5 and
        // 7.3; tolerances half as much again).
        let (w, h) = (96usize, 60usize);
        let img = test_image(w as u32, h as u32);
        let want = img.to_rgb8(Transfer::Srgb).into_raw();
        for (colors, pixel_tol, block_tol) in [(256, 8.0, 2.0), (16, 24.0, 11.0)] {
            let s = Encoder {
                colors,
                ..encoder(Protocol::Sixel, false)
            }
            .frame(&img, 12, 3);
            assert!(s.starts_with("\x1bP") && s.ends_with("\x1b\\"));
            let back = icy_sixel::SixelImage::decode(s.as_bytes()).expect("a valid sixel stream");
            assert_eq!((back.width, back.height), (w, h));
            let (pixel, block) = errors(&back.pixels, &want, w, h);
            assert!(
                pixel < pixel_tol && block < block_tol,
                "{colors} registers: {pixel:.2} levels per pixel, {block:.2} per block"
            );
        }
        // And the comparison sees a wrong image.
        let other = icy_sixel::SixelImage::decode(
            Encoder {
                colors: 256,
                ..encoder(Protocol::Sixel, false)
            }
            .frame(&upside_down(&img), 12, 3)
            .as_bytes(),
        )
        .unwrap();
        assert!(errors(&other.pixels, &want, w, h).1 > 20.0);
    }

    #[test]
    fn noise_alone_does_not_count_as_change_and_a_shrink_fits_the_budget() {
        let old = vec![100u8; 300];
        let mut new = old.clone();
        new[0] = 103; // one pixel of a hundred, by 3 with a threshold of 2
        assert_eq!(changed_fraction(&old, &new, &[2; 100]), 0.01);
        assert_eq!(changed_fraction(&old, &new, &[3; 100]), 0.0);
        assert_eq!(changed_fraction(&old, &new[..297], &[3; 99]), 1.0);
        // 1000 × 600 pixels at 0.5 bytes each: 300 kB; budgets of 300, 75 and 10 kB.
        let px = 600_000;
        assert_eq!(shrink_for(px, 0.5, Some(300_000), 4), 1);
        assert_eq!(shrink_for(px, 0.5, Some(75_000), 4), 2);
        assert_eq!(shrink_for(px, 0.5, Some(10_000), 4), 4);
        assert_eq!(shrink_for(px, 0.5, Some(10_000), 8), 6);
        assert_eq!(shrink_for(px, 0.5, Some(1_000), 8), 8);
        assert_eq!(shrink_for(px, 0.5, None, 8), 1);
    }

    #[test]
    fn a_frame_takes_the_bands_that_fit_and_leaves_the_rest_in_order() {
        let due: Vec<(u32, (u16, u16))> = (0..5).map(|i| (i, (4 * i as u16, 4))).collect();
        // 10 bytes a band: a budget of 25 takes two, the rest wait.
        let (now, later) = fit_bands(due.clone(), |_| 10.0, 25.0);
        assert_eq!(now, due[..2].to_vec());
        assert_eq!(later, vec![2, 3, 4]);
        // The first band goes even over budget; a small band after one that waits waits too
        // (the screen fills top to bottom).
        let (now, later) = fit_bands(due.clone(), |b| if b.0 == 4 { 100.0 } else { 1.0 }, 5.0);
        assert_eq!(now, due[..1].to_vec());
        assert_eq!(later, vec![1, 2, 3, 4]);
        let (now, later) = fit_bands(due.clone(), |_| 10.0, 1000.0);
        assert_eq!((now.len(), later.len()), (5, 0));
    }

    #[test]
    fn bands_cover_the_image_rows_once() {
        assert_eq!(bands(Protocol::Kitty, 10), vec![(0, 4), (4, 4), (8, 2)]);
        assert_eq!(bands(Protocol::Sixel, 10), vec![(0, 10)]);
        // 10 cell rows over 377 pixel rows: the bands' pixel rows tile 0..377.
        let mut next = 0;
        for b in bands(Protocol::Iterm, 10) {
            let r = band_pixels(377, 10, b);
            assert_eq!(r.start, next);
            next = r.end;
        }
        assert_eq!(next, 377);
        let img = test_image(8, 6);
        let c = crop_rows(&img, 2..5);
        assert_eq!((c.width, c.height), (8, 3));
        assert_eq!(c.get(3, 0), img.get(3, 2));
        // Each kitty band is an image of its own.
        let e = encoder(Protocol::Kitty, false);
        assert!(e.band(&c, 8, 1, 3).contains(&format!("i={}", IMAGE_ID + 3)));
    }

    #[test]
    fn iterm_carries_a_png_of_the_image() {
        let img = test_image(40, 20);
        let s = encoder(Protocol::Iterm, false).frame(&img, 20, 5);
        let body = s
            .strip_prefix("\x1b]1337;File=inline=1;")
            .and_then(|r| r.strip_suffix('\x07'))
            .expect("an OSC 1337 sequence");
        let (args, data) = body.split_once(':').unwrap();
        assert!(
            args.contains("width=20;height=5;preserveAspectRatio=0"),
            "{args}"
        );
        let png = base64::engine::general_purpose::STANDARD
            .decode(data)
            .unwrap();
        assert!(args.contains(&format!("size={}", png.len())));
        let back = image::load_from_memory(&png).unwrap().to_rgb8();
        assert_eq!(back.into_raw(), img.to_rgb8(Transfer::Srgb).into_raw());
    }

    #[test]
    fn tmux_passthrough_doubles_every_escape_and_wraps_each_sequence() {
        assert_eq!(
            tmux_wrap("\x1b_Gq=2;\x1b\\"),
            "\x1bPtmux;\x1b\x1b_Gq=2;\x1b\x1b\\\x1b\\"
        );
        let img = test_image(200, 200);
        let s = encoder(Protocol::Kitty, true).frame(&img, 40, 20);
        let plain = encoder(Protocol::Kitty, false).frame(&img, 40, 20);
        // Unwrapping gives back the plain sequences, one passthrough per chunk.
        let inner: Vec<String> = s
            .split("\x1bPtmux;")
            .filter(|p| !p.is_empty())
            .map(|p| {
                p.strip_suffix("\x1b\\")
                    .unwrap()
                    .replace("\x1b\x1b", "\x1b")
            })
            .collect();
        assert_eq!(inner.concat(), plain);
        assert_eq!(inner.len(), plain.matches("\x1b_G").count());
        assert_eq!(
            encoder(Protocol::Kitty, true).clear(),
            tmux_wrap(&encoder(Protocol::Kitty, false).clear())
        );
    }
}
