//! The kitty terminal graphics protocol (https://sw.kovidgoyal.net/kitty/graphics-protocol/):
//! the preview as one zlib-compressed RGB image placed over the image cells.

use crate::output::{LinearImage, Transfer};
use base64::Engine;
use std::io::Write;

/// The id of the preview image (reused, so each frame replaces the last).
pub const IMAGE_ID: u32 = 7411;
/// Base64 bytes per escape sequence, as the protocol asks.
const CHUNK: usize = 4096;

/// Escape sequences that transmit `img` and show it over `cols × rows` cells at the cursor,
/// without moving the cursor.
pub fn transmit(img: &LinearImage, cols: u16, rows: u16) -> String {
    let rgb = img.to_rgb8(Transfer::Srgb).into_raw();
    let mut z = flate2::write::ZlibEncoder::new(Vec::new(), flate2::Compression::fast());
    z.write_all(&rgb).expect("writing to memory");
    let data = base64::engine::general_purpose::STANDARD.encode(z.finish().expect("zlib"));
    let chunks: Vec<&[u8]> = data.as_bytes().chunks(CHUNK).collect();
    let mut out = String::with_capacity(data.len() + 64 * chunks.len());
    for (i, chunk) in chunks.iter().enumerate() {
        let more = u8::from(i + 1 < chunks.len());
        let payload = std::str::from_utf8(chunk).expect("base64 is ASCII");
        if i == 0 {
            out.push_str(&format!(
                "\x1b_Ga=T,f=24,o=z,s={},v={},i={IMAGE_ID},c={cols},r={rows},C=1,q=2,m={more};{payload}\x1b\\",
                img.width, img.height
            ));
        } else {
            out.push_str(&format!("\x1b_Gm={more};{payload}\x1b\\"));
        }
    }
    out
}

/// Deletes the preview image and its placements.
pub fn delete_all() -> String {
    format!("\x1b_Ga=d,d=I,i={IMAGE_ID},q=2\x1b\\")
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::io::Read;

    #[test]
    fn transmits_the_image_in_chunks_that_decode_back() {
        let mut img = LinearImage::new(64, 40);
        for (i, p) in img.pixels.iter_mut().enumerate() {
            *p = [
                (i % 7) as f32 / 7.0,
                (i % 13) as f32 / 13.0,
                (i * 31 % 101) as f32 / 101.0,
            ];
        }
        let s = transmit(&img, 32, 10);
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
}
