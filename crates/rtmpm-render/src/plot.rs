//! Line charts for validation curves (simulated vs reference), drawn with the built-in font.

use crate::image::Image;
use crate::text::{draw_text, text_height, text_width};

/// How a series is drawn.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Style {
    Line,
    Markers,
}

/// One curve.
#[derive(Clone, Debug)]
pub struct Series {
    pub label: String,
    pub points: Vec<(f64, f64)>,
    pub rgb: [u8; 3],
    pub style: Style,
}

/// A chart: title, axis labels and curves.
#[derive(Clone, Debug, Default)]
pub struct Plot {
    pub title: String,
    pub x_label: String,
    pub y_label: String,
    pub series: Vec<Series>,
}

const INK: [u8; 3] = [40, 40, 40];
const GRID: [u8; 3] = [225, 225, 225];

/// A "nice" tick step for a range covered by about `n` ticks.
fn tick_step(range: f64, n: f64) -> f64 {
    let raw = (range / n).max(f64::MIN_POSITIVE);
    let mag = 10f64.powf(raw.log10().floor());
    let f = raw / mag;
    mag * if f < 1.5 {
        1.0
    } else if f < 3.5 {
        2.0
    } else if f < 7.5 {
        5.0
    } else {
        10.0
    }
}

fn label(v: f64, step: f64) -> String {
    let v = if v.abs() < 1e-6 * step { 0.0 } else { v };
    let decimals = (-step.log10().floor()).max(0.0) as usize;
    format!("{v:.decimals$}")
}

impl Plot {
    /// Render at `width` x `height`.
    pub fn render(&self, width: u32, height: u32) -> Image {
        let mut img = Image::new(width, height, [255, 255, 255]);
        let (mut x0, mut x1, mut y0, mut y1) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
        for p in self.series.iter().flat_map(|s| &s.points) {
            if p.0.is_finite() && p.1.is_finite() {
                (x0, x1, y0, y1) = (x0.min(p.0), x1.max(p.0), y0.min(p.1), y1.max(p.1));
            }
        }
        if x0 > x1 {
            (x0, x1, y0, y1) = (0.0, 1.0, 0.0, 1.0);
        }
        let pad = |a: f64, b: f64| if b > a { 0.05 * (b - a) } else { 0.5 };
        let (px, py) = (pad(x0, x1), pad(y0, y1));
        let (x0, x1, y0, y1) = (x0 - px, x1 + px, y0 - py, y1 + py);
        // Plot area.
        let (left, right, top, bottom) = (90i32, width as i32 - 20, 40i32, height as i32 - 60);
        let sx = |x: f64| left as f64 + (x - x0) / (x1 - x0) * (right - left) as f64;
        let sy = |y: f64| bottom as f64 - (y - y0) / (y1 - y0) * (bottom - top) as f64;
        // Grid and ticks.
        let (xs, ys) = (tick_step(x1 - x0, 6.0), tick_step(y1 - y0, 5.0));
        let mut t = (x0 / xs).ceil() * xs;
        while t <= x1 {
            let x = sx(t) as i32;
            img.fill_rect(x, top, 1, bottom - top, GRID);
            let l = label(t, xs);
            draw_text(
                &mut img,
                x - text_width(&l, 1) as i32 / 2,
                bottom + 6,
                &l,
                1,
                INK,
            );
            t += xs;
        }
        let mut t = (y0 / ys).ceil() * ys;
        while t <= y1 {
            let y = sy(t) as i32;
            img.fill_rect(left, y, right - left, 1, GRID);
            let l = label(t, ys);
            draw_text(
                &mut img,
                left - 6 - text_width(&l, 1) as i32,
                y - 3,
                &l,
                1,
                INK,
            );
            t += ys;
        }
        img.fill_rect(left, top, 1, bottom - top, INK);
        img.fill_rect(left, bottom, right - left, 1, INK);
        // Curves.
        for s in &self.series {
            let pts: Vec<(f64, f64)> = s.points.iter().map(|p| (sx(p.0), sy(p.1))).collect();
            match s.style {
                Style::Line => {
                    for w in pts.windows(2) {
                        line(&mut img, w[0], w[1], s.rgb);
                    }
                }
                Style::Markers => {
                    for p in &pts {
                        img.fill_rect(p.0 as i32 - 3, p.1 as i32 - 3, 7, 7, s.rgb);
                    }
                }
            }
        }
        // Title, axis labels, legend.
        let title = self.title.to_uppercase();
        draw_text(
            &mut img,
            (width as i32 - text_width(&title, 2) as i32) / 2,
            10,
            &title,
            2,
            INK,
        );
        let xl = self.x_label.to_uppercase();
        draw_text(
            &mut img,
            (left + right - text_width(&xl, 1) as i32) / 2,
            bottom + 24,
            &xl,
            1,
            INK,
        );
        draw_text(&mut img, 6, top - 16, &self.y_label.to_uppercase(), 1, INK);
        for (k, s) in self.series.iter().enumerate() {
            let y = top + 8 + k as i32 * (text_height(1) as i32 + 8);
            let l = s.label.to_uppercase();
            let x = right - text_width(&l, 1) as i32 - 8;
            img.fill_rect(x - 22, y + 2, 16, 3, s.rgb);
            draw_text(&mut img, x, y, &l, 1, INK);
        }
        img
    }
}

/// A 2-pixel-wide line (DDA), clipped by the image.
fn line(img: &mut Image, a: (f64, f64), b: (f64, f64), rgb: [u8; 3]) {
    let n = ((b.0 - a.0).abs().max((b.1 - a.1).abs()).ceil() as i32).clamp(1, 100_000);
    for i in 0..=n {
        let t = i as f64 / n as f64;
        let (x, y) = (a.0 + t * (b.0 - a.0), a.1 + t * (b.1 - a.1));
        img.fill_rect(x as i32, y as i32, 2, 2, rgb);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_rising_line_goes_from_bottom_left_to_top_right() {
        let plot = Plot {
            title: "t".into(),
            x_label: "x".into(),
            y_label: "y".into(),
            series: vec![Series {
                label: "s".into(),
                points: vec![(0.0, 0.0), (1.0, 1.0)],
                rgb: [255, 0, 0],
                style: Style::Line,
            }],
        };
        let img = plot.render(400, 300);
        let red = |x0: u32, x1: u32, y0: u32, y1: u32| {
            (x0..x1).any(|x| (y0..y1).any(|y| img.pixel(x, y) == [255, 0, 0]))
        };
        assert!(red(90, 140, 180, 240), "curve starts bottom left");
        assert!(red(330, 380, 40, 90), "curve ends top right");
        assert!(!red(330, 380, 180, 240), "nothing bottom right");
        assert_eq!(tick_step(10.0, 5.0), 2.0);
        assert_eq!(tick_step(0.07, 6.0), 0.01);
    }
}
