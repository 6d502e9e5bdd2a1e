//! Sphere splatting with a depth buffer, parallel over horizontal bands of rows.
//!
//! Particles are projected once into [`Splat`]s (screen centre, pixel radius, depth), binned by
//! the bands of rows they overlap, and every band is rasterised by one rayon task into its own
//! slice of the target buffer, so no locking is needed.

use rayon::prelude::*;

/// A projected particle: centre in pixels, radius in pixels, view depth of its centre, world
/// radius and particle index.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Splat {
    pub x: f32,
    pub y: f32,
    pub r: f32,
    pub z: f32,
    pub wr: f32,
    pub id: u32,
}

/// Rows per band.
const BAND: usize = 8;

/// Rasterise `splats` into `buf` (`width` x `height`, row-major). For every covered pixel,
/// `write(texel, splat, u, v)` is called with `(u, v)` the pixel centre's offset from the splat
/// centre in units of its radius (`u^2 + v^2 < 1`).
pub(crate) fn raster<T, F>(splats: &[Splat], width: usize, height: usize, buf: &mut [T], write: F)
where
    T: Send,
    F: Fn(&mut T, &Splat, f32, f32) + Sync,
{
    assert_eq!(buf.len(), width * height);
    if width == 0 || height == 0 {
        return;
    }
    let n_bands = height.div_ceil(BAND);
    // Band range of each splat (rows clipped to the image), counted then scattered.
    let rows = |s: &Splat| -> Option<(usize, usize)> {
        let y0 = (s.y - s.r).floor().max(0.0);
        let y1 = (s.y + s.r).ceil().min(height as f32 - 1.0);
        let x0 = s.x + s.r;
        let x1 = s.x - s.r;
        if y1 < y0 || x0 < 0.0 || x1 > width as f32 {
            return None;
        }
        Some((y0 as usize / BAND, y1 as usize / BAND))
    };
    let mut count = vec![0u32; n_bands + 1];
    for s in splats {
        if let Some((b0, b1)) = rows(s) {
            for c in &mut count[b0..=b1] {
                *c += 1;
            }
        }
    }
    let mut start = vec![0usize; n_bands + 1];
    for b in 0..n_bands {
        start[b + 1] = start[b] + count[b] as usize;
    }
    let mut fill = start.clone();
    let mut index = vec![0u32; start[n_bands]];
    for (i, s) in splats.iter().enumerate() {
        if let Some((b0, b1)) = rows(s) {
            for f in &mut fill[b0..=b1] {
                index[*f] = i as u32;
                *f += 1;
            }
        }
    }
    buf.par_chunks_mut(BAND * width)
        .enumerate()
        .for_each(|(b, band)| {
            let row0 = b * BAND;
            let rows_here = band.len() / width;
            for &i in &index[start[b]..start[b + 1]] {
                let s = &splats[i as usize];
                let inv = 1.0 / s.r;
                let y0 = ((s.y - s.r).floor().max(row0 as f32) as usize).max(row0);
                let y1 = ((s.y + s.r).ceil() as usize).min(row0 + rows_here - 1);
                let x0 = (s.x - s.r).floor().max(0.0) as usize;
                let x1 = ((s.x + s.r).ceil().max(0.0) as usize).min(width - 1);
                for y in y0..=y1 {
                    let v = (y as f32 + 0.5 - s.y) * inv;
                    let vv = v * v;
                    if vv >= 1.0 {
                        continue;
                    }
                    let line = &mut band[(y - row0) * width..(y - row0 + 1) * width];
                    for (x, texel) in line.iter_mut().enumerate().take(x1 + 1).skip(x0) {
                        let u = (x as f32 + 0.5 - s.x) * inv;
                        if u * u + vv < 1.0 {
                            write(texel, s, u, v);
                        }
                    }
                }
            }
        });
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn covers_disc_and_clips() {
        let splats = [
            Splat {
                x: 10.0,
                y: 10.0,
                r: 3.0,
                z: 1.0,
                wr: 0.1,
                id: 0,
            },
            // Partly outside the image.
            Splat {
                x: -1.0,
                y: 18.5,
                r: 4.0,
                z: 1.0,
                wr: 0.1,
                id: 1,
            },
        ];
        let (w, h) = (20, 20);
        let mut buf = vec![u32::MAX; w * h];
        raster(&splats, w, h, &mut buf, |t, s, _, _| *t = s.id);
        let covered0 = buf.iter().filter(|&&t| t == 0).count();
        // Area of a radius-3 disc ~ 28 pixels.
        assert!((24..=32).contains(&covered0), "{covered0}");
        assert_eq!(buf[10 * w + 10], 0);
        assert_eq!(buf[10 * w + 14], u32::MAX);
        assert!(buf.contains(&1));
    }
}
