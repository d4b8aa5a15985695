//! Colour encodings: sRGB ↔ linear (IEC 61966-2-1) and the lecture's gamma 2.2.

use glam::Vec3;

/// Decodes one sRGB-encoded channel in [0, 1] to linear light (IEC 61966-2-1).
pub fn srgb_to_linear(c: f64) -> f64 {
    if c <= 0.04045 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    }
}

/// Encodes one linear channel to sRGB; input is clamped to [0, 1].
pub fn linear_to_srgb(c: f64) -> f64 {
    let c = c.clamp(0.0, 1.0);
    if c <= 0.003_130_8 {
        c * 12.92
    } else {
        1.055 * c.powf(1.0 / 2.4) - 0.055
    }
}

/// The lecture's `pow(c, 0.4545)`; input is clamped to [0, 1].
pub fn linear_to_gamma22(c: f64) -> f64 {
    c.clamp(0.0, 1.0).powf(0.4545)
}

/// Parses `"#rrggbb"` (sRGB) to a linear colour.
/// Rec. 709 luminance of a linear RGB colour.
pub fn luminance(c: [f32; 3]) -> f32 {
    0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2]
}

pub fn parse_hex(s: &str) -> Option<Vec3> {
    let h = s.strip_prefix('#')?;
    if h.len() != 6 || !h.bytes().all(|b| b.is_ascii_hexdigit()) {
        return None;
    }
    let ch = |i: usize| u8::from_str_radix(&h[i..i + 2], 16).ok();
    let (r, g, b) = (ch(0)?, ch(2)?, ch(4)?);
    let lin = |v: u8| srgb_to_linear(v as f64 / 255.0) as f32;
    Some(Vec3::new(lin(r), lin(g), lin(b)))
}

/// Formats a linear colour as `"#rrggbb"` when it is exactly representable so, else `None`.
pub fn to_hex_exact(c: Vec3) -> Option<String> {
    let mut bytes = [0u8; 3];
    for (b, v) in bytes.iter_mut().zip(c.to_array()) {
        let e = (linear_to_srgb(v as f64) * 255.0).round();
        let back = srgb_to_linear(e / 255.0) as f32;
        if back != v {
            return None;
        }
        *b = e as u8;
    }
    Some(format!("#{:02x}{:02x}{:02x}", bytes[0], bytes[1], bytes[2]))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hex_decodes_to_linear() {
        let c = parse_hex("#ff0000").unwrap();
        assert_eq!(c, Vec3::new(1.0, 0.0, 0.0));
        // sRGB 0x80 = 128/255 is linear 0.2158605 (IEC 61966-2-1).
        let g = parse_hex("#808080").unwrap();
        assert!((g.x - 0.215_860_5).abs() < 1e-6, "{g}");
        assert!(parse_hex("#80808").is_none());
        assert!(parse_hex("808080").is_none());
        assert!(parse_hex("#80808g").is_none());
    }

    #[test]
    fn srgb_round_trips_every_byte() {
        for v in 0..=255u32 {
            let lin = srgb_to_linear(v as f64 / 255.0);
            let back = (linear_to_srgb(lin) * 255.0).round() as u32;
            assert_eq!(back, v);
        }
    }

    #[test]
    fn hex_writes_back_exactly() {
        let c = parse_hex("#3a7bd5").unwrap();
        assert_eq!(to_hex_exact(c).as_deref(), Some("#3a7bd5"));
        assert_eq!(to_hex_exact(Vec3::new(0.5, 0.5, 0.5)), None);
    }
}
