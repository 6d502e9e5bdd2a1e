//! Drawing a displayed frame: the backend's own picture ([`Backend::render_view`]) or, where
//! it does not draw, the CPU renderer from the particles; then the heads-up line and, after a
//! blow-up, its message.

use rtmpm_geometry::Collider;
use rtmpm_geometry::Tool;
use rtmpm_physics::Particles;
use rtmpm_physics::boundary::BoundaryRule;
use rtmpm_render::text::{draw_text, text_height};
use rtmpm_render::{Image, RenderInput, ViewRequest, particle_field, render};
use rtmpm_scene::Scene;
use rtmpm_sim::Backend;

/// What drawing one frame gave besides the picture.
pub struct Drawn {
    pub image: Image,
    /// The particles were read into the caller's buffer (the CPU renderer's path).
    pub read_particles: bool,
}

/// The tool as a motionless collider of the picture.
fn tool_collider(t: &Tool) -> Collider {
    Collider {
        shape: t.sdf(),
        rule: BoundaryRule::default(),
        velocity: Default::default(),
        angular_velocity: Default::default(),
        pivot: t.center,
        keyframes: None,
    }
}

/// Draw the backend's state as `req` asks: by the backend when it draws, else by the CPU
/// renderer from the particles (read into `particles`), with the rigid bodies and the tool
/// among the colliders.
pub fn draw(
    backend: &mut dyn Backend,
    scene: &Scene,
    req: &ViewRequest,
    tool: Option<&Tool>,
    particles: &mut Particles,
) -> Result<Drawn, String> {
    let mut image = Image::new(0, 0, [0; 3]);
    if backend
        .render_view(req, &mut image)
        .map_err(|e| e.to_string())?
    {
        if image.width != req.width
            || image.height != req.height
            || image.rgb.len() != 3 * req.width as usize * req.height as usize
        {
            return Err(format!(
                "the backend drew a {}x{} picture for a {}x{} view",
                image.width, image.height, req.width, req.height
            ));
        }
        return Ok(Drawn {
            image,
            read_particles: false,
        });
    }
    backend
        .read_particles(particles)
        .map_err(|e| e.to_string())?;
    let field = particle_field(particles, scene, req.color_by);
    let mut opts = req.options(scene);
    if req.colliders {
        opts.colliders
            .extend(backend.rigid_bodies().iter().map(|b| b.collider()));
        opts.colliders.extend(tool.map(tool_collider));
    }
    let image = render(
        &RenderInput {
            positions: &particles.x,
            material: &particles.material,
            field: field.as_deref(),
            surface: None,
        },
        &opts,
    )
    .map_err(|e| e.to_string())?;
    Ok(Drawn {
        image,
        read_particles: true,
    })
}

/// Text scale for an image `height` pixels high (1 up to 539 pixels, 2 at 720p, ...).
fn scale(height: u32) -> u32 {
    (height / 360).max(1)
}

/// `text` cut into lines of at most `max_chars` characters, at spaces where it can.
fn wrap(text: &str, max_chars: usize) -> Vec<String> {
    let max_chars = max_chars.max(8);
    let mut lines = Vec::new();
    for para in text.lines() {
        let mut line = String::new();
        for word in para.split(' ') {
            let mut word = word.to_string();
            while word.chars().count() > max_chars {
                if !line.is_empty() {
                    lines.push(std::mem::take(&mut line));
                }
                let head: String = word.chars().take(max_chars).collect();
                word = word.chars().skip(max_chars).collect();
                lines.push(head);
            }
            let need = line.chars().count() + usize::from(!line.is_empty()) + word.chars().count();
            if need > max_chars && !line.is_empty() {
                lines.push(std::mem::take(&mut line));
            }
            if !line.is_empty() {
                line.push(' ');
            }
            line.push_str(&word);
        }
        lines.push(line);
    }
    lines
}

/// Characters of `scale`d text that fit in `width` pixels less margins.
fn chars_across(width: u32, scale: u32) -> usize {
    (width.saturating_sub(12 * scale) / (6 * scale)) as usize
}

/// The heads-up line in the top-left corner, wrapped at its double spaces to fit.
pub fn draw_hud(img: &mut Image, hud: &str) {
    let s = scale(img.height);
    let max = chars_across(img.width, s);
    let mut lines: Vec<String> = Vec::new();
    for part in hud.split("  ") {
        match lines.last_mut() {
            Some(l) if l.chars().count() + 2 + part.chars().count() <= max => {
                l.push_str("  ");
                l.push_str(part);
            }
            _ => lines.push(part.to_string()),
        }
    }
    let m = 6 * s as i32;
    let dy = text_height(s) as i32 + 3 * s as i32;
    for (i, l) in lines.iter().enumerate() {
        draw_text(img, m, m + i as i32 * dy, l, s, [235, 235, 235]);
    }
}

/// A message box across the lower part of the picture (a blow-up's message).
pub fn draw_message(img: &mut Image, message: &str) {
    let s = scale(img.height);
    // The font has no backquotes or quotes.
    let clean: String = message
        .chars()
        .filter(|c| !matches!(c, '`' | '"' | '\''))
        .collect();
    let lines = wrap(&clean, chars_across(img.width, s).saturating_sub(2));
    let lh = text_height(s) as i32 + 3 * s as i32;
    let pad = 6 * s as i32;
    let h = lines.len() as i32 * lh + 2 * pad;
    let y0 = (img.height as i32 - h - pad).max(0);
    img.fill_rect(pad, y0, img.width as i32 - 2 * pad, h, [110, 20, 24]);
    for (i, l) in lines.iter().enumerate() {
        draw_text(
            img,
            2 * pad,
            y0 + pad + i as i32 * lh,
            l,
            s,
            [250, 235, 235],
        );
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn long_text_wraps_to_the_width_at_spaces() {
        let l = wrap(
            "simulation blew up at step 12: particle 3 of material sand",
            20,
        );
        assert!(l.iter().all(|l| l.chars().count() <= 20), "{l:?}");
        assert_eq!(
            l.join(" "),
            "simulation blew up at step 12: particle 3 of material sand"
        );
        let l = wrap("averyveryverylongwordwithoutspaces", 10);
        assert!(l.iter().all(|l| l.chars().count() <= 10), "{l:?}");
        assert_eq!(l.concat(), "averyveryverylongwordwithoutspaces");
    }

    #[test]
    fn the_hud_and_a_message_draw_inside_the_image() {
        let mut img = Image::new(200, 120, [0, 0, 0]);
        draw_hud(
            &mut img,
            "T 0.100 S  FRAME 6  STEP 60  1000 PARTICLES  500 STEPS/S  24.0 FPS",
        );
        let lit = |img: &Image, y0: u32, y1: u32| {
            (y0..y1)
                .flat_map(|y| (0..img.width).map(move |x| (x, y)))
                .filter(|&(x, y)| img.pixel(x, y) == [235, 235, 235])
                .count()
        };
        assert!(lit(&img, 0, 12) > 50, "first line");
        assert!(lit(&img, 12, 40) > 50, "wrapped onto more lines");
        draw_message(&mut img, "simulation blew up at step 12: `sand`");
        let red = img.rgb.chunks(3).filter(|p| p == &[110, 20, 24]).count();
        assert!(red > 1000, "{red}");
    }
}
