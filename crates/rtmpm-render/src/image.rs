//! RGB images: PNG encoding and decoding, area-average resizing, animated GIF movies.

use rtmpm_io::write_atomic;
use std::io;
use std::path::Path;

/// An 8-bit RGB image, row-major, top row first.
#[derive(Clone, Debug, PartialEq)]
pub struct Image {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// `3 * width * height` bytes.
    pub rgb: Vec<u8>,
}

impl Image {
    /// An image filled with one colour.
    pub fn new(width: u32, height: u32, fill: [u8; 3]) -> Image {
        let n = width as usize * height as usize;
        let mut rgb = Vec::with_capacity(3 * n);
        for _ in 0..n {
            rgb.extend_from_slice(&fill);
        }
        Image { width, height, rgb }
    }

    /// Colour of pixel `(x, y)` (panics outside the image).
    pub fn pixel(&self, x: u32, y: u32) -> [u8; 3] {
        let i = 3 * (y as usize * self.width as usize + x as usize);
        [self.rgb[i], self.rgb[i + 1], self.rgb[i + 2]]
    }

    /// Fill a rectangle, clipped to the image.
    pub fn fill_rect(&mut self, x: i32, y: i32, w: i32, h: i32, rgb: [u8; 3]) {
        let x0 = x.max(0);
        let y0 = y.max(0);
        let x1 = (x + w).min(self.width as i32);
        let y1 = (y + h).min(self.height as i32);
        for yy in y0..y1 {
            for xx in x0..x1 {
                let i = 3 * (yy as usize * self.width as usize + xx as usize);
                self.rgb[i..i + 3].copy_from_slice(&rgb);
            }
        }
    }

    /// Area-average resize (for downscaling; upscaling repeats pixels).
    pub fn resize(&self, width: u32, height: u32) -> Image {
        if width == self.width && height == self.height {
            return self.clone();
        }
        let (sw, sh) = (self.width as usize, self.height as usize);
        let (dw, dh) = (width as usize, height as usize);
        let mut out = Image::new(width, height, [0, 0, 0]);
        if sw == 0 || sh == 0 {
            return out;
        }
        for y in 0..dh {
            let y0 = y * sh / dh;
            let y1 = ((y + 1) * sh / dh).max(y0 + 1).min(sh);
            for x in 0..dw {
                let x0 = x * sw / dw;
                let x1 = ((x + 1) * sw / dw).max(x0 + 1).min(sw);
                let mut acc = [0u32; 3];
                for sy in y0..y1 {
                    for sx in x0..x1 {
                        let i = 3 * (sy * sw + sx);
                        for (a, &c) in acc.iter_mut().zip(&self.rgb[i..i + 3]) {
                            *a += c as u32;
                        }
                    }
                }
                let cnt = ((y1 - y0) * (x1 - x0)) as u32;
                let o = 3 * (y * dw + x);
                for (d, a) in out.rgb[o..o + 3].iter_mut().zip(acc) {
                    *d = ((a + cnt / 2) / cnt) as u8;
                }
            }
        }
        out
    }

    /// PNG file bytes.
    pub fn encode_png(&self) -> io::Result<Vec<u8>> {
        let mut bytes = Vec::new();
        {
            let mut enc = png::Encoder::new(&mut bytes, self.width, self.height);
            enc.set_color(png::ColorType::Rgb);
            enc.set_depth(png::BitDepth::Eight);
            enc.set_compression(png::Compression::Fast);
            let (key, text) = rtmpm_io::signature::PNG_TEXT;
            enc.add_text_chunk(key.into(), text.into())
                .map_err(io::Error::other)?;
            let mut w = enc.write_header().map_err(io::Error::other)?;
            w.write_image_data(&self.rgb).map_err(io::Error::other)?;
            w.finish().map_err(io::Error::other)?;
        }
        Ok(bytes)
    }

    /// Write a PNG file atomically (temporary file + rename).
    pub fn write_png(&self, path: &Path) -> io::Result<()> {
        write_atomic(path, &self.encode_png()?)
    }

    /// Decode an 8-bit RGB or RGBA PNG (alpha dropped).
    pub fn decode_png(bytes: &[u8]) -> io::Result<Image> {
        let dec = png::Decoder::new(io::Cursor::new(bytes));
        let mut reader = dec.read_info().map_err(io::Error::other)?;
        let size = reader
            .output_buffer_size()
            .ok_or_else(|| io::Error::other("PNG too large"))?;
        let mut buf = vec![0; size];
        let info = reader.next_frame(&mut buf).map_err(io::Error::other)?;
        let (w, h) = (info.width, info.height);
        let rgb = match (info.color_type, info.bit_depth) {
            (png::ColorType::Rgb, png::BitDepth::Eight) => buf[..3 * (w * h) as usize].to_vec(),
            (png::ColorType::Rgba, png::BitDepth::Eight) => buf[..4 * (w * h) as usize]
                .chunks(4)
                .flat_map(|p| [p[0], p[1], p[2]])
                .collect(),
            other => {
                return Err(io::Error::new(
                    io::ErrorKind::InvalidData,
                    format!("unsupported PNG pixel format {other:?}"),
                ));
            }
        };
        Ok(Image {
            width: w,
            height: h,
            rgb,
        })
    }
}

/// An animated GIF assembled in memory (each frame quantised with NeuQuant) and written
/// atomically by [`GifMovie::finish`].
pub struct GifMovie {
    encoder: gif::Encoder<Vec<u8>>,
    width: u32,
    height: u32,
    delay_cs: u16,
    frames: usize,
}

impl GifMovie {
    /// A looping movie of `width` x `height` (at most 65535 each) at `fps` frames per second
    /// (GIF delays are whole centiseconds, at least 2).
    pub fn new(width: u32, height: u32, fps: f32) -> io::Result<GifMovie> {
        if width == 0 || height == 0 || width > 65535 || height > 65535 {
            return Err(io::Error::new(
                io::ErrorKind::InvalidInput,
                format!("GIF size {width}x{height} is out of range"),
            ));
        }
        let mut encoder = gif::Encoder::new(Vec::new(), width as u16, height as u16, &[])
            .map_err(io::Error::other)?;
        encoder
            .set_repeat(gif::Repeat::Infinite)
            .map_err(io::Error::other)?;
        encoder
            .write_raw_extension(gif::AnyExtension(0xFE), &[rtmpm_io::signature::GIF_COMMENT])
            .map_err(io::Error::other)?;
        let fps = if fps.is_finite() && fps > 0.0 {
            fps
        } else {
            30.0
        };
        Ok(GifMovie {
            encoder,
            width,
            height,
            delay_cs: ((100.0 / fps).round() as u16).max(2),
            frames: 0,
        })
    }

    /// Append a frame (resized to the movie's size when needed).
    pub fn add(&mut self, img: &Image) -> io::Result<()> {
        let small = img.resize(self.width, self.height);
        let mut frame =
            gif::Frame::from_rgb_speed(self.width as u16, self.height as u16, &small.rgb, 10);
        frame.delay = self.delay_cs;
        self.encoder.write_frame(&frame).map_err(io::Error::other)?;
        self.frames += 1;
        Ok(())
    }

    /// Number of frames added so far.
    pub fn frames(&self) -> usize {
        self.frames
    }

    /// Write the file (atomically); returns the number of frames.
    pub fn finish(self, path: &Path) -> io::Result<usize> {
        let frames = self.frames;
        let bytes = self.encoder.into_inner().map_err(io::Error::other)?;
        write_atomic(path, &bytes)?;
        Ok(frames)
    }
}
