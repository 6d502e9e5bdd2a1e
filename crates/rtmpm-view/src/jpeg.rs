//! JPEG encoding of displayed frames for the browser stream.

use jpeg_encoder::{ColorType, Encoder, SamplingFactor};
use rtmpm_render::Image;

/// Default JPEG quality of the stream (1 to 100).
pub const DEFAULT_QUALITY: u8 = 80;

/// The image as JPEG bytes at `quality` (1 to 100; 4:2:0 chroma).
pub fn encode_jpeg(img: &Image, quality: u8) -> Result<Vec<u8>, String> {
    let (w, h) = (
        u16::try_from(img.width)
            .map_err(|_| format!("image width {} too large for JPEG", img.width))?,
        u16::try_from(img.height)
            .map_err(|_| format!("image height {} too large for JPEG", img.height))?,
    );
    let mut out = Vec::with_capacity(img.rgb.len() / 8);
    let mut enc = Encoder::new(&mut out, quality.clamp(1, 100));
    enc.set_sampling_factor(SamplingFactor::F_2_2);
    enc.encode(&img.rgb, w, h, ColorType::Rgb)
        .map_err(|e| format!("JPEG encoding failed: {e}"))?;
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_frame_encodes_to_a_jpeg_of_its_size() {
        let mut img = Image::new(96, 54, [20, 40, 60]);
        img.fill_rect(10, 10, 30, 20, [250, 200, 10]);
        let j = encode_jpeg(&img, 80).unwrap();
        assert_eq!(&j[..2], &[0xFF, 0xD8], "SOI marker");
        assert_eq!(&j[j.len() - 2..], &[0xFF, 0xD9], "EOI marker");
        // The SOF0 segment gives height then width.
        let sof = j
            .windows(2)
            .position(|w| w == [0xFF, 0xC0])
            .expect("baseline SOF");
        let h = u16::from_be_bytes([j[sof + 5], j[sof + 6]]);
        let w = u16::from_be_bytes([j[sof + 7], j[sof + 8]]);
        assert_eq!((w, h), (96, 54));
        assert!(j.len() < img.rgb.len());
    }
}
