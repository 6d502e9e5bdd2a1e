//! The colour bar of a field: a vertical viridis bar at the right edge with its title and
//! range.

use crate::colormap;
use crate::image::Image;
use crate::text;

/// Vertical viridis bar at the right edge, title above, max/mid/min labels to its left (what
/// [`crate::render`] draws when colouring by a field; the GPU renderers draw it with this too).
pub fn draw_color_bar(img: &mut Image, title: &str, lo: f32, hi: f32, scale: u32) {
    let (w, h) = (img.width as i32, img.height as i32);
    let s = scale as i32;
    let margin = 10 * s;
    let bar_w = 10 * s;
    let bar_h = (h / 2).max(8);
    let x1 = w - margin;
    let x0 = x1 - bar_w;
    let y0 = (h - bar_h) / 2;
    let y1 = y0 + bar_h;
    img.fill_rect(x0 - 1, y0 - 1, bar_w + 2, bar_h + 2, [235, 235, 235]);
    for y in y0..y1 {
        let t = (y1 - 1 - y) as f32 / (bar_h - 1).max(1) as f32;
        let c = colormap::viridis(t);
        img.fill_rect(x0, y, bar_w, 1, c.map(colormap::to_u8));
    }
    let white = [235, 235, 235];
    let th = text::text_height(scale) as i32;
    let tw = text::text_width(title, scale) as i32;
    text::draw_text(img, (x1 - tw).max(0), y0 - th - 4 * s, title, scale, white);
    for (v, y) in [
        (hi, y0),
        (0.5 * (lo + hi), (y0 + y1) / 2 - th / 2),
        (lo, y1 - th),
    ] {
        let t = format_value(v);
        let tw = text::text_width(&t, scale) as i32;
        text::draw_text(img, (x0 - 4 * s - tw).max(0), y, &t, scale, white);
    }
}

/// Format a colour-bar value compactly (`0.125`, `12.5`, `1.25E5`).
pub fn format_value(v: f32) -> String {
    let a = v.abs();
    if a == 0.0 {
        "0".into()
    } else if (1e-2..1e4).contains(&a) {
        let s = format!("{v:.3}");
        let s = s.trim_end_matches('0').trim_end_matches('.');
        s.to_string()
    } else {
        format!("{v:.2e}").to_uppercase()
    }
}
