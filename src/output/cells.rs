//! Terminal cells from linear radiance: every average is taken in linear light, and only the
//! final colours are encoded (sRGB, then truecolor or the 256-colour palette).
//!
//! A cell shows `sub.0 × sub.1` image pixels: half blocks (1×2, `▀` with fg = upper and
//! bg = lower pixel), quadrants (2×2) and sextants (2×3), for which the glyph and the fg/bg
//! pair are chosen to minimise the squared error of the cell's pixels, or ASCII (luminance
//! ramp, no colour) for dumb terminals.

use super::image::LinearImage;
use crate::scene::color::{linear_to_srgb, luminance};

/// How pixels map to glyphs.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default, clap::ValueEnum)]
pub enum CellMode {
    /// `▀` with two pixels per cell (fg upper, bg lower).
    #[default]
    Half,
    /// 2×2 pixels per cell, block quadrant glyphs.
    Quadrant,
    /// 2×3 pixels per cell, Unicode 13 sextant glyphs.
    Sextant,
    /// One luminance character per cell, no colour.
    Ascii,
}

impl CellMode {
    /// Image pixels per cell, (columns, rows).
    pub fn subpixels(self) -> (u32, u32) {
        match self {
            CellMode::Half => (1, 2),
            CellMode::Quadrant => (2, 2),
            CellMode::Sextant => (2, 3),
            CellMode::Ascii => (1, 2),
        }
    }

    /// The next mode, for the key that cycles them.
    pub fn next(self) -> CellMode {
        match self {
            CellMode::Half => CellMode::Quadrant,
            CellMode::Quadrant => CellMode::Sextant,
            CellMode::Sextant => CellMode::Ascii,
            CellMode::Ascii => CellMode::Half,
        }
    }

    pub fn name(self) -> &'static str {
        match self {
            CellMode::Half => "half",
            CellMode::Quadrant => "quadrant",
            CellMode::Sextant => "sextant",
            CellMode::Ascii => "ascii",
        }
    }
}

/// How colours reach the terminal.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum ColorMode {
    /// 24-bit colour.
    Truecolor,
    /// The 240 fixed colours of the 256-colour palette, ordered dithering.
    #[value(name = "256")]
    Ansi256,
    /// No colour escape sequences at all.
    None,
}

impl ColorMode {
    /// Truecolor when `COLORTERM` says so, 256 colours otherwise, none on a dumb terminal.
    pub fn detect(colorterm: Option<&str>, term: Option<&str>) -> ColorMode {
        if term == Some("dumb") {
            return ColorMode::None;
        }
        match colorterm {
            Some(c) if c.eq_ignore_ascii_case("truecolor") || c.eq_ignore_ascii_case("24bit") => {
                ColorMode::Truecolor
            }
            _ => ColorMode::Ansi256,
        }
    }
}

/// A terminal colour after encoding.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CellColor {
    Rgb([u8; 3]),
    Indexed(u8),
    Default,
}

/// One encoded cell.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Cell {
    pub glyph: char,
    pub fg: CellColor,
    pub bg: CellColor,
}

/// Quadrant glyphs by bit mask: bit 0 upper-left, 1 upper-right, 2 lower-left, 3 lower-right.
pub const QUADRANTS: [char; 16] = [
    ' ', '▘', '▝', '▀', '▖', '▌', '▞', '▛', '▗', '▚', '▐', '▜', '▄', '▙', '▟', '█',
];

/// The sextant glyph for a mask (bit 0 upper-left, 1 upper-right, 2 middle-left,
/// 3 middle-right, 4 lower-left, 5 lower-right). Unicode 13 "Symbols for Legacy Computing"
/// U+1FB00–U+1FB3B holds the 60 masks that are not empty, full, or one whole column.
pub fn sextant(mask: u8) -> char {
    match mask {
        0 => ' ',
        0b111111 => '█',
        0b010101 => '▌',
        0b101010 => '▐',
        m => {
            // The block skips the two column masks, so later masks shift down.
            let mut i = m as u32 - 1;
            if m > 0b010101 {
                i -= 1;
            }
            if m > 0b101010 {
                i -= 1;
            }
            char::from_u32(0x1FB00 + i).expect("sextant code point")
        }
    }
}

/// Largest sRGB difference (per 8-bit channel) between a cell's two colours that still draws
/// it as one colour.
const UNIFORM_CELL: u8 = 3;

/// ASCII ramp, dark to bright.
const RAMP: &[u8] = b" .:-=+*#%@";

/// Mean of linear colours.
fn mean(px: &[[f32; 3]]) -> [f32; 3] {
    let mut s = [0.0f32; 3];
    for p in px {
        for c in 0..3 {
            s[c] += p[c];
        }
    }
    let n = px.len().max(1) as f32;
    s.map(|v| v / n)
}

fn srgb8(c: [f32; 3]) -> [u8; 3] {
    c.map(|v| (linear_to_srgb(v as f64) * 255.0).round() as u8)
}

/// Fills `out` with the `sx × sy` block of pixels whose top-left is `(x0, y0)`, row by row.
fn gather_block(
    img: &LinearImage,
    (x0, y0): (u32, u32),
    (sx, sy): (u32, u32),
    out: &mut Vec<[f32; 3]>,
) {
    out.clear();
    for dy in 0..sy {
        for dx in 0..sx {
            out.push(img.get(x0 + dx, y0 + dy));
        }
    }
}

/// Downsamples by an integer factor in linear light (box filter).
pub fn downsample(img: &LinearImage, factor: u32) -> LinearImage {
    if factor <= 1 {
        return img.clone();
    }
    let (w, h) = (img.width / factor, img.height / factor);
    let mut out = LinearImage::new(w, h);
    let mut block = Vec::with_capacity((factor * factor) as usize);
    for y in 0..h {
        for x in 0..w {
            gather_block(img, (x * factor, y * factor), (factor, factor), &mut block);
            out.pixels[(y * w + x) as usize] = mean(&block);
        }
    }
    out
}

/// The two-colour split of a cell's pixels that minimises the squared error (linear light):
/// returns (mask of the pixels drawn in fg, fg mean, bg mean). Masks and their complements
/// give the same split, so only masks with the last pixel off are tried (the empty mask is
/// the one-colour cell).
fn best_split(px: &[[f32; 3]]) -> (u8, [f32; 3], [f32; 3]) {
    let n = px.len();
    let mut best = (0u8, mean(px), mean(px), f32::INFINITY);
    for mask in 0..(1u8 << (n - 1)) {
        let (mut on, mut off) = ([0.0f32; 3], [0.0f32; 3]);
        let (mut n_on, mut n_off) = (0.0f32, 0.0f32);
        for (i, p) in px.iter().enumerate() {
            let (acc, cnt) = if mask >> i & 1 == 1 {
                (&mut on, &mut n_on)
            } else {
                (&mut off, &mut n_off)
            };
            for c in 0..3 {
                acc[c] += p[c];
            }
            *cnt += 1.0;
        }
        let fg = on.map(|v| v / n_on.max(1.0));
        let bg = off.map(|v| v / n_off.max(1.0));
        let err: f32 = px
            .iter()
            .enumerate()
            .map(|(i, p)| {
                let m = if mask >> i & 1 == 1 { fg } else { bg };
                (0..3).map(|c| (p[c] - m[c]).powi(2)).sum::<f32>()
            })
            .sum();
        if err < best.3 {
            best = (mask, fg, bg, err);
        }
    }
    (best.0, best.1, best.2)
}

/// 4×4 Bayer matrix, thresholds in (0, 1).
const BAYER4: [[f32; 4]; 4] = [
    [0.5 / 16.0, 8.5 / 16.0, 2.5 / 16.0, 10.5 / 16.0],
    [12.5 / 16.0, 4.5 / 16.0, 14.5 / 16.0, 6.5 / 16.0],
    [3.5 / 16.0, 11.5 / 16.0, 1.5 / 16.0, 9.5 / 16.0],
    [15.5 / 16.0, 7.5 / 16.0, 13.5 / 16.0, 5.5 / 16.0],
];

/// The six levels of the xterm 6×6×6 colour cube.
const CUBE: [u8; 6] = [0, 95, 135, 175, 215, 255];

/// The sRGB value of palette entry 16–255.
pub fn palette_rgb(i: u8) -> [u8; 3] {
    if i >= 232 {
        let v = 8 + 10 * (i - 232);
        [v, v, v]
    } else {
        let i = i - 16;
        [
            CUBE[(i / 36) as usize],
            CUBE[(i / 6 % 6) as usize],
            CUBE[(i % 6) as usize],
        ]
    }
}

/// Nearest of the 240 fixed colours (16–255) to an sRGB colour, after ordered dithering at
/// pixel (x, y): the Bayer threshold shifts the colour by up to half a cube step, so areas
/// between two palette colours alternate between them in proportion.
pub fn dither_256(srgb: [u8; 3], x: u32, y: u32) -> u8 {
    let t = BAYER4[(y % 4) as usize][(x % 4) as usize] - 0.5;
    let shifted = srgb.map(|v| (v as f32 + t * 40.0).clamp(0.0, 255.0).round() as u8);
    nearest_256(shifted)
}

/// Nearest palette entry, through a table of every colour at 5 bits per channel (the
/// palette's steps are about 40 apart; 8 levels per table cell can only pick a neighbour
/// for colours within 4 levels of a boundary, which the dither blurs anyway).
fn nearest_256(c: [u8; 3]) -> u8 {
    static TABLE: std::sync::OnceLock<Vec<u8>> = std::sync::OnceLock::new();
    let table = TABLE.get_or_init(|| {
        let mut t = vec![0u8; 32 * 32 * 32];
        for (i, e) in t.iter_mut().enumerate() {
            let q = [(i >> 10) & 31, (i >> 5) & 31, i & 31].map(|v| (v * 8 + 4) as u8);
            *e = nearest_256_exact(q);
        }
        t
    });
    let i = (c[0] as usize >> 3) << 10 | (c[1] as usize >> 3) << 5 | c[2] as usize >> 3;
    table[i]
}

fn nearest_256_exact(c: [u8; 3]) -> u8 {
    let mut best = (16u8, u32::MAX);
    for i in 16..=255u8 {
        let p = palette_rgb(i);
        let d: u32 = (0..3)
            .map(|k| (p[k] as i32 - c[k] as i32).pow(2) as u32)
            .sum();
        if d < best.1 {
            best = (i, d);
        }
    }
    best.0
}

/// Encodes an image whose size is `cols·sub.0 × rows·sub.1` into `cols × rows` cells.
pub fn encode(img: &LinearImage, mode: CellMode, color: ColorMode) -> Vec<Cell> {
    let (sx, sy) = mode.subpixels();
    let (cols, rows) = (img.width / sx, img.height / sy);
    let paint = |c: [f32; 3], x: u32, y: u32| match color {
        ColorMode::Truecolor => CellColor::Rgb(srgb8(c)),
        ColorMode::Ansi256 => CellColor::Indexed(dither_256(srgb8(c), x, y)),
        ColorMode::None => CellColor::Default,
    };
    let mut out = Vec::with_capacity((cols * rows) as usize);
    let mut px = Vec::with_capacity((sx * sy) as usize);
    for row in 0..rows {
        for col in 0..cols {
            let (x, y) = (col * sx, row * sy);
            gather_block(img, (x, y), (sx, sy), &mut px);
            let cell = match mode {
                CellMode::Half => Cell {
                    glyph: '▀',
                    fg: paint(px[0], x, y),
                    bg: paint(px[1], x, y + 1),
                },
                CellMode::Ascii => {
                    let l = linear_to_srgb(luminance(mean(&px)) as f64);
                    let i = ((l * (RAMP.len() - 1) as f64).round() as usize).min(RAMP.len() - 1);
                    Cell {
                        glyph: RAMP[i] as char,
                        fg: CellColor::Default,
                        bg: CellColor::Default,
                    }
                }
                CellMode::Quadrant | CellMode::Sextant => {
                    let (mut mask, mut fg, mut bg) = best_split(&px);
                    // Two colours that encode to nearly the same sRGB are one colour plus
                    // noise: draw the cell uniform, so noise does not flip glyphs (and cost
                    // bandwidth) from frame to frame.
                    let (ef, eb) = (srgb8(fg), srgb8(bg));
                    if (0..3).all(|c| ef[c].abs_diff(eb[c]) <= UNIFORM_CELL) {
                        let m = mean(&px);
                        (mask, fg, bg) = (0, m, m);
                    }
                    // A mask and its complement draw the same picture: draw the brighter
                    // colour as the foreground, so the choice is canonical.
                    if luminance(fg) < luminance(bg) || mask == 0 {
                        mask = !mask & ((1u8 << px.len()) - 1);
                        std::mem::swap(&mut fg, &mut bg);
                    }
                    let glyph = if mode == CellMode::Quadrant {
                        QUADRANTS[mask as usize]
                    } else {
                        sextant(mask)
                    };
                    // Dither each colour at the first pixel it covers.
                    let first = |on: bool| {
                        (0..px.len())
                            .find(|&i| (mask >> i & 1 == 1) == on)
                            .map_or((x, y), |i| (x + i as u32 % sx, y + i as u32 / sx))
                    };
                    let (fx, fy) = first(true);
                    let (bx, by) = first(false);
                    Cell {
                        glyph,
                        fg: paint(fg, fx, fy),
                        bg: paint(bg, bx, by),
                    }
                }
            };
            out.push(cell);
        }
    }
    out
}

/// Per cell, the colour change (per 8-bit sRGB channel) within the cell's own noise: twice
/// the standard error `sigma` of its pixels (linear, one per image pixel), carried through
/// the sRGB curve at the pixel's brightest channel; at least `base`. A cell that moved by no
/// more is not resent: its change is the noise falling, not the image.
pub fn noise_thresholds(img: &LinearImage, sigma: &[f32], mode: CellMode, base: u8) -> Vec<u8> {
    let (sx, sy) = mode.subpixels();
    let (cols, rows) = (img.width / sx, img.height / sy);
    let mut out = Vec::with_capacity((cols * rows) as usize);
    for row in 0..rows {
        for col in 0..cols {
            let mut t = base as f64;
            for dy in 0..sy {
                for dx in 0..sx {
                    let i = ((row * sy + dy) * img.width + col * sx + dx) as usize;
                    let (Some(p), Some(&s)) = (img.pixels.get(i), sigma.get(i)) else {
                        continue;
                    };
                    let l = p.iter().copied().fold(0.0f32, f32::max).clamp(0.0, 1.0) as f64;
                    let up = (l + 2.0 * s as f64).min(1.0);
                    t = t.max(255.0 * (linear_to_srgb(up) - linear_to_srgb(l)));
                }
            }
            out.push(t.ceil().min(255.0) as u8);
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sextant_code_points_cover_the_block() {
        let mut seen = std::collections::HashSet::new();
        for m in 0..64u8 {
            assert!(seen.insert(sextant(m)), "mask {m:06b} repeats a glyph");
        }
        assert_eq!(sextant(0b000001), '\u{1FB00}');
        // Names from the Unicode database: "BLOCK SEXTANT-35" is U+1FB13, "-1235" U+1FB15
        // (after the skipped left column -135), "-23456" U+1FB3B.
        assert_eq!(sextant(0b010100), '\u{1FB13}');
        assert_eq!(sextant(0b010111), '\u{1FB15}');
        assert_eq!(sextant(0b111110), '\u{1FB3B}');
    }

    #[test]
    fn palette_matches_xterm() {
        assert_eq!(palette_rgb(16), [0, 0, 0]);
        assert_eq!(palette_rgb(196), [255, 0, 0]);
        assert_eq!(palette_rgb(231), [255, 255, 255]);
        assert_eq!(palette_rgb(232), [8, 8, 8]);
        assert_eq!(palette_rgb(255), [238, 238, 238]);
    }

    #[test]
    fn dithering_mixes_neighbouring_palette_colours_in_proportion() {
        // sRGB 115 lies halfway between cube levels 95 and 135 (and near grey 118): over a
        // 4×4 tile the dither must use more than one entry.
        let tile: std::collections::HashSet<u8> = (0..16)
            .map(|i| dither_256([115, 0, 0], i % 4, i / 4))
            .collect();
        assert!(tile.len() >= 2, "{tile:?}");
        // Exact palette colours come back unchanged wherever they are.
        for (x, y) in [(0, 0), (1, 2), (3, 3)] {
            assert_eq!(dither_256([255, 0, 0], x, y), 196);
        }
    }

    #[test]
    fn colour_detection() {
        assert_eq!(
            ColorMode::detect(Some("truecolor"), Some("xterm")),
            ColorMode::Truecolor
        );
        assert_eq!(ColorMode::detect(Some("24bit"), None), ColorMode::Truecolor);
        assert_eq!(
            ColorMode::detect(None, Some("xterm-256color")),
            ColorMode::Ansi256
        );
        assert_eq!(
            ColorMode::detect(Some("truecolor"), Some("dumb")),
            ColorMode::None
        );
    }

    #[test]
    fn a_cell_within_its_own_noise_is_not_resent() {
        // Half blocks: 1×2 pixels per cell. Mid grey, no noise, then a standard error of 0.05.
        let img = LinearImage {
            width: 2,
            height: 2,
            pixels: vec![[0.2; 3]; 4],
        };
        let none = noise_thresholds(&img, &[0.0; 4], CellMode::Half, 2);
        assert_eq!(none, vec![2, 2], "no noise: the base threshold");
        let noisy = noise_thresholds(&img, &[0.05; 4], CellMode::Half, 2);
        // 2σ at linear 0.2 through the sRGB curve: 255 × (srgb(0.3) − srgb(0.2)) ≈ 25.
        let expect = (255.0 * (linear_to_srgb(0.3) - linear_to_srgb(0.2))).ceil() as u8;
        assert_eq!(noisy, vec![expect, expect]);
        assert!((20..=30).contains(&expect), "{expect}");
    }
}
