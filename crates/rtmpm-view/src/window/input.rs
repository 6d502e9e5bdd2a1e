//! The window's keyboard and mouse as session [`Command`]s: the browser page's controls (left
//! drag orbits, right drag or Shift+drag drags the tool, the wheel pushes it deeper while held,
//! middle drag or Ctrl+drag pans, the wheel zooms; Space pauses, S or . steps, R resets, - and +
//! change the pace, C the colours, T throws a ball at the cursor) and the window's own keys for
//! what the page has fields or buttons for (1 to 5: colour modes, G: gravity presets, Home or 0:
//! the camera back, Esc or Q: quit). Pixel positions are turned from the window's
//! into the picture's.

use crate::command::{Command, Throw};
use glam::Vec3;
use rtmpm_scene::ColorBy;

/// A mouse button.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Button {
    Left,
    Middle,
    Right,
}

/// A key, as far as the window cares.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Key {
    /// A printable key (lower case).
    Char(char),
    Space,
    Escape,
    Home,
}

/// What a mouse drag does.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Drag {
    Orbit,
    Pan,
    Tool,
}

/// Zoom factor a wheel line (< 1: closer).
const ZOOM_PER_LINE: f32 = 0.9;
/// Depth factor of the held tool a wheel line (> 1: deeper).
const DEPTH_PER_LINE: f32 = 1.1;

/// The state of the input: window and picture sizes, cursor, modifiers, the drag in progress,
/// gravity presets.
#[derive(Clone, Debug)]
pub struct Input {
    window: (u32, u32),
    image: (u32, u32),
    cursor: Option<(f32, f32)>,
    shift: bool,
    ctrl: bool,
    drag: Option<(Button, Drag)>,
    /// The scene's gravity (the first of the presets), once known.
    gravity0: Option<Vec3>,
    /// Which gravity preset is set (0: the scene's).
    preset: usize,
}

impl Input {
    /// Input of a window of `window` pixels showing pictures of `image` pixels.
    pub fn new(window: (u32, u32), image: (u32, u32)) -> Input {
        Input {
            window,
            image,
            cursor: None,
            shift: false,
            ctrl: false,
            drag: None,
            gravity0: None,
            preset: 0,
        }
    }

    /// The picture's size (the session's latest).
    pub fn set_image(&mut self, image: (u32, u32)) {
        self.image = image;
    }

    /// The scene's gravity, for the gravity presets (taken once).
    pub fn set_gravity(&mut self, g: Vec3) {
        self.gravity0.get_or_insert(g);
    }

    /// The modifier keys now.
    pub fn modifiers(&mut self, shift: bool, ctrl: bool) {
        (self.shift, self.ctrl) = (shift, ctrl);
    }

    /// The window's new size: the session draws at it.
    pub fn resized(&mut self, width: u32, height: u32) -> Vec<Command> {
        if width == 0 || height == 0 {
            return Vec::new(); // minimised
        }
        self.window = (width, height);
        vec![Command::Resize { width, height }]
    }

    /// A window position (physical pixels) in the picture's pixels.
    pub fn to_image(&self, x: f32, y: f32) -> (f32, f32) {
        let sx = self.image.0 as f32 / self.window.0.max(1) as f32;
        let sy = self.image.1 as f32 / self.window.1.max(1) as f32;
        (x * sx, y * sy)
    }

    /// A button pressed at the cursor.
    pub fn press(&mut self, b: Button) -> Vec<Command> {
        if self.drag.is_some() {
            return Vec::new();
        }
        let kind = match b {
            Button::Right => Drag::Tool,
            Button::Middle => Drag::Pan,
            Button::Left if self.shift => Drag::Tool,
            Button::Left if self.ctrl => Drag::Pan,
            Button::Left => Drag::Orbit,
        };
        self.drag = Some((b, kind));
        match (kind, self.cursor) {
            (Drag::Tool, Some((x, y))) => {
                let (x, y) = self.to_image(x, y);
                vec![Command::ToolStart { x, y }]
            }
            _ => Vec::new(),
        }
    }

    /// A button released.
    pub fn release(&mut self, b: Button) -> Vec<Command> {
        match self.drag {
            Some((held, kind)) if held == b => {
                self.drag = None;
                if kind == Drag::Tool {
                    vec![Command::ToolEnd]
                } else {
                    Vec::new()
                }
            }
            _ => Vec::new(),
        }
    }

    /// The cursor moved to `(x, y)` (window pixels).
    pub fn moved(&mut self, x: f32, y: f32) -> Vec<Command> {
        let last = self.cursor.replace((x, y));
        let Some((kind, (lx, ly))) = self.drag.map(|d| d.1).zip(last) else {
            return Vec::new();
        };
        let (a, b) = (self.to_image(lx, ly), self.to_image(x, y));
        let (dx, dy) = (b.0 - a.0, b.1 - a.1);
        match kind {
            Drag::Orbit => vec![Command::Orbit { dx, dy }],
            Drag::Pan => vec![Command::Pan { dx, dy }],
            Drag::Tool => vec![Command::ToolMove { x: b.0, y: b.1 }],
        }
    }

    /// The cursor left the window: a drag in progress ends (its release would not come).
    pub fn left(&mut self) -> Vec<Command> {
        self.cursor = None;
        match self.drag.take() {
            Some((_, Drag::Tool)) => vec![Command::ToolEnd],
            _ => Vec::new(),
        }
    }

    /// The wheel turned by `lines` (> 0: away from the user): zoom in, or push the held tool.
    pub fn wheel(&mut self, lines: f32) -> Vec<Command> {
        if !lines.is_finite() || lines == 0.0 {
            return Vec::new();
        }
        if matches!(self.drag, Some((_, Drag::Tool))) {
            return vec![Command::ToolDepth(DEPTH_PER_LINE.powf(lines))];
        }
        vec![Command::Zoom(ZOOM_PER_LINE.powf(lines))]
    }

    /// A key pressed.
    pub fn key(&mut self, k: Key) -> Vec<Command> {
        let c = match k {
            Key::Space => Command::TogglePause,
            Key::Escape => Command::Quit,
            Key::Home => Command::CameraReset,
            Key::Char(c) => match c {
                's' | '.' => Command::Step,
                'r' => Command::Reset,
                '-' | '_' => Command::Slower,
                '+' | '=' => Command::Faster,
                'c' => Command::CycleColor,
                '0' => Command::CameraReset,
                'q' => Command::Quit,
                '1'..='5' => Command::ColorBy(ColorBy::ALL[c as usize - '1' as usize]),
                't' => match self.cursor {
                    Some((x, y)) => {
                        let (x, y) = self.to_image(x, y);
                        Command::Throw(Throw {
                            x,
                            y,
                            material: None,
                            radius: None,
                            speed: None,
                        })
                    }
                    None => return Vec::new(),
                },
                'g' => return self.next_gravity().into_iter().collect(),
                _ => return Vec::new(),
            },
        };
        vec![c]
    }

    /// The next gravity preset: the scene's, none, sideways (along +x, the scene's magnitude),
    /// upwards, then the scene's again.
    fn next_gravity(&mut self) -> Option<Command> {
        let g0 = self.gravity0?;
        let m = g0.length();
        self.preset = (self.preset + 1) % 4;
        let g = match self.preset {
            0 => g0,
            1 => Vec3::ZERO,
            2 => Vec3::new(m, 0.0, 0.0),
            _ => Vec3::new(0.0, m, 0.0),
        };
        Some(Command::Gravity(g))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn drags_orbit_pan_and_move_the_tool_in_picture_pixels() {
        // A window twice the picture's size: positions and motions are halved.
        let mut i = Input::new((1280, 720), (640, 360));
        assert!(i.moved(100.0, 100.0).is_empty(), "no drag, no command");
        assert!(i.press(Button::Left).is_empty());
        assert_eq!(
            i.moved(120.0, 90.0),
            vec![Command::Orbit { dx: 10.0, dy: -5.0 }]
        );
        assert!(i.release(Button::Left).is_empty());
        assert!(i.press(Button::Middle).is_empty());
        assert_eq!(
            i.moved(100.0, 100.0),
            vec![Command::Pan { dx: -10.0, dy: 5.0 }]
        );
        i.release(Button::Middle);
        // Ctrl + left pans too; Shift + left (or right) drags the tool.
        i.modifiers(false, true);
        i.press(Button::Left);
        assert!(matches!(i.moved(102.0, 100.0)[0], Command::Pan { .. }));
        i.release(Button::Left);
        i.modifiers(true, false);
        assert_eq!(
            i.press(Button::Left),
            vec![Command::ToolStart { x: 51.0, y: 50.0 }]
        );
        assert_eq!(
            i.moved(110.0, 100.0),
            vec![Command::ToolMove { x: 55.0, y: 50.0 }]
        );
        // The wheel pushes the held tool deeper; another button does nothing meanwhile.
        assert_eq!(i.wheel(1.0), vec![Command::ToolDepth(DEPTH_PER_LINE)]);
        assert!(i.press(Button::Right).is_empty());
        assert!(i.release(Button::Right).is_empty());
        assert_eq!(i.release(Button::Left), vec![Command::ToolEnd]);
        assert_eq!(
            i.wheel(2.0),
            vec![Command::Zoom(ZOOM_PER_LINE * ZOOM_PER_LINE)]
        );
        // Leaving the window mid-drag lets go of the tool.
        i.modifiers(false, false);
        i.press(Button::Right);
        assert_eq!(i.left(), vec![Command::ToolEnd]);
        assert!(i.release(Button::Right).is_empty());
    }

    #[test]
    fn keys_are_the_pages_controls_and_gravity_presets() {
        let mut i = Input::new((100, 100), (100, 100));
        assert_eq!(i.key(Key::Space), vec![Command::TogglePause]);
        assert_eq!(i.key(Key::Char('s')), vec![Command::Step]);
        assert_eq!(i.key(Key::Char('r')), vec![Command::Reset]);
        assert_eq!(i.key(Key::Char('-')), vec![Command::Slower]);
        assert_eq!(i.key(Key::Char('+')), vec![Command::Faster]);
        assert_eq!(i.key(Key::Char('c')), vec![Command::CycleColor]);
        assert_eq!(i.key(Key::Char('3')), vec![Command::ColorBy(ColorBy::J)]);
        assert_eq!(i.key(Key::Escape), vec![Command::Quit]);
        assert_eq!(i.key(Key::Home), vec![Command::CameraReset]);
        assert!(i.key(Key::Char('x')).is_empty());
        // A ball is thrown at the cursor, only once the cursor is known.
        assert!(i.key(Key::Char('t')).is_empty());
        i.moved(40.0, 60.0);
        assert!(matches!(
            &i.key(Key::Char('t'))[..],
            [Command::Throw(Throw {
                x: 40.0,
                y: 60.0,
                ..
            })]
        ));
        // Gravity presets once the scene's gravity is known: none, sideways, up, the scene's.
        assert!(i.key(Key::Char('g')).is_empty());
        let g = Vec3::new(0.0, -9.8, 0.0);
        i.set_gravity(g);
        i.set_gravity(Vec3::ZERO); // taken once
        let seq: Vec<Command> = (0..4).flat_map(|_| i.key(Key::Char('g'))).collect();
        assert_eq!(
            seq,
            vec![
                Command::Gravity(Vec3::ZERO),
                Command::Gravity(Vec3::new(9.8, 0.0, 0.0)),
                Command::Gravity(Vec3::new(0.0, 9.8, 0.0)),
                Command::Gravity(g),
            ]
        );
    }

    #[test]
    fn a_resized_window_asks_for_pictures_of_its_size() {
        let mut i = Input::new((100, 100), (100, 100));
        assert_eq!(
            i.resized(300, 200),
            vec![Command::Resize {
                width: 300,
                height: 200
            }]
        );
        assert!(i.resized(0, 200).is_empty(), "minimised");
        // Until the session's pictures have the new size, positions are scaled.
        assert_eq!(i.to_image(150.0, 100.0), (50.0, 50.0));
        i.set_image((300, 200));
        assert_eq!(i.to_image(150.0, 100.0), (150.0, 100.0));
    }
}
