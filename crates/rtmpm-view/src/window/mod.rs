//! The native window of a live session: winit for the window and its input, softbuffer to show
//! the session's pictures. The pictures are finished images already (drawn by the CUDA render
//! stage on the GPU, or by the CPU renderer), so showing one is a copy of its RGB bytes into the
//! window's pixel buffer, which softbuffer hands to the window system (X11 or Wayland shared
//! memory): no GPU API, no driver, the same code under a desktop, a remote X display or Xvfb.
//! Why not wgpu: see docs/viewer.md.
//!
//! [`run`] opens the window on a [`Session`]: a waker thread waits on the session's frames and
//! wakes the event loop when a new one is published (the window never polls, the session never
//! waits for the window); input becomes the session's commands ([`input`]). Closing the window
//! (or Esc, Q) ends the session.

pub mod input;

use crate::command::Command;
use crate::frame::Frame;
use crate::session::{Session, Summary};
use glam::Vec3;
use input::{Button, Input, Key};
use std::cell::RefCell;
use std::num::NonZeroU32;
use std::rc::Rc;
use std::sync::Arc;
use std::time::Duration;
use winit::application::ApplicationHandler;
use winit::dpi::PhysicalSize;
use winit::event::{ElementState, MouseButton, MouseScrollDelta, WindowEvent};
use winit::event_loop::{ActiveEventLoop, EventLoop, EventLoopProxy};
use winit::keyboard::{Key as WKey, NamedKey};
use winit::window::{Window, WindowId};

/// How the window runs.
#[derive(Clone, Debug, Default)]
pub struct WindowOptions {
    /// The window's title.
    pub title: String,
}

/// Why the event loop was woken.
#[derive(Clone, Copy, Debug)]
enum Wake {
    /// The session published a new picture.
    Frame,
    /// The session has ended.
    Ended,
}

/// True when a window can be tried here (a display is named).
pub fn display_present() -> bool {
    ["DISPLAY", "WAYLAND_DISPLAY"]
        .iter()
        .any(|v| std::env::var_os(v).is_some_and(|s| !s.is_empty()))
}

thread_local! {
    /// The thread's event loop: winit makes one per process and runs it again on demand, so a
    /// second window (Python's `Simulation.view()` called twice) reuses it.
    static LOOP: RefCell<Option<EventLoop<Wake>>> = const { RefCell::new(None) };
}

/// Show `session` in a window until it is closed or the session ends; then end the session and
/// return its summary. Errors: no display, a
/// window that cannot be opened, the session's own.
pub fn run(session: Session, options: WindowOptions) -> Result<Summary, String> {
    LOOP.with(|cell| {
        let mut slot = cell.borrow_mut();
        if slot.is_none() {
            *slot = Some(new_loop()?);
        }
        let event_loop = slot.as_mut().ok_or("no event loop")?;
        let mut app = App::new(session, options, event_loop.create_proxy());
        use winit::platform::run_on_demand::EventLoopExtRunOnDemand;
        let r = event_loop.run_app_on_demand(&mut app);
        let summary = app.finish();
        r.map_err(|e| format!("the window's event loop failed: {e}"))?;
        summary
    })
}

fn new_loop() -> Result<EventLoop<Wake>, String> {
    let mut b = EventLoop::<Wake>::with_user_event();
    // A window may be opened from any thread (Python's, a test's): X11 and Wayland allow it.
    #[cfg(target_os = "linux")]
    {
        use winit::platform::wayland::EventLoopBuilderExtWayland;
        use winit::platform::x11::EventLoopBuilderExtX11;
        EventLoopBuilderExtX11::with_any_thread(&mut b, true);
        EventLoopBuilderExtWayland::with_any_thread(&mut b, true);
    }
    b.build().map_err(|e| {
        format!(
            "cannot open a window ({e}); watch it in a browser instead: `rtmpm view SCENE --serve`"
        )
    })
}

/// The window, its pixel buffer and the session behind them.
struct App {
    session: Option<Session>,
    options: WindowOptions,
    proxy: EventLoopProxy<Wake>,
    window: Option<Rc<Window>>,
    surface: Option<softbuffer::Surface<Rc<Window>, Rc<Window>>>,
    input: Input,
    /// The picture on screen.
    shown: Option<Arc<Frame>>,
    error: Option<String>,
}

impl App {
    fn new(session: Session, options: WindowOptions, proxy: EventLoopProxy<Wake>) -> App {
        let first = session.frames().latest();
        let size = first
            .as_ref()
            .map_or((1280, 720), |f| (f.image.width, f.image.height));
        let mut input = Input::new(size, size);
        if let Some(f) = &first {
            input.set_gravity(Vec3::from_array(f.status.gravity));
        }
        App {
            session: Some(session),
            options,
            proxy,
            window: None,
            surface: None,
            input,
            shown: None,
            error: None,
        }
    }

    /// End the session (if still running) and return its summary, or the window's error.
    fn finish(&mut self) -> Result<Summary, String> {
        let summary = match self.session.take() {
            Some(s) => s.finish(),
            None => Err("the session was already finished".into()),
        };
        match self.error.take() {
            Some(e) => Err(e),
            None => summary,
        }
    }

    fn send(&mut self, commands: Vec<Command>, el: &ActiveEventLoop) {
        let Some(s) = &self.session else { return };
        for c in commands {
            let quit = c == Command::Quit;
            // A full queue drops the command (the page does the same); an ended session closes.
            if s.send(c)
                .is_err_and(|e| e == crate::session::SendError::Ended)
                || quit
            {
                el.exit();
                return;
            }
        }
    }

    /// The waker: wait on the session's frames, wake the loop for each new one, say when the
    /// session has ended; stops when the loop is gone.
    fn start_waker(&self) {
        let Some(s) = &self.session else { return };
        let (slot, proxy) = (s.frames(), self.proxy.clone());
        std::thread::spawn(move || {
            let mut seen = 0;
            loop {
                match slot.wait_newer(seen, Duration::from_millis(250)) {
                    Ok(Some(f)) => {
                        seen = f.status.seq;
                        if proxy.send_event(Wake::Frame).is_err() {
                            return;
                        }
                    }
                    Ok(None) => {}
                    Err(_) => {
                        let _ = proxy.send_event(Wake::Ended);
                        return;
                    }
                }
            }
        });
    }

    /// Copy the latest picture into the window (nearest pixel when their sizes differ, while
    /// the session catches up with a resize).
    fn present(&mut self) -> Result<(), String> {
        let (Some(window), Some(surface), Some(s)) =
            (&self.window, &mut self.surface, &self.session)
        else {
            return Ok(());
        };
        let Some(frame) = s.frames().latest() else {
            return Ok(());
        };
        let size = window.inner_size();
        let (Some(w), Some(h)) = (NonZeroU32::new(size.width), NonZeroU32::new(size.height)) else {
            return Ok(()); // minimised
        };
        surface
            .resize(w, h)
            .map_err(|e| format!("window buffer: {e}"))?;
        let mut buf = surface
            .buffer_mut()
            .map_err(|e| format!("window buffer: {e}"))?;
        blit(&frame.image, &mut buf, size.width, size.height);
        buf.present().map_err(|e| format!("window: {e}"))?;
        self.input
            .set_image((frame.image.width, frame.image.height));
        self.shown = Some(frame);
        Ok(())
    }
}

/// The picture `img` into the window's 0RGB pixels (`w x h`), nearest pixel.
pub fn blit(img: &rtmpm_render::Image, out: &mut [u32], w: u32, h: u32) {
    let (iw, ih) = (img.width as usize, img.height as usize);
    if iw == 0 || ih == 0 {
        return;
    }
    let (w, h) = (w as usize, h as usize);
    for y in 0..h {
        let sy = (y * ih / h).min(ih - 1);
        let src = &img.rgb[3 * sy * iw..3 * (sy + 1) * iw];
        let row = &mut out[y * w..(y + 1) * w];
        if w == iw {
            for (p, c) in row.iter_mut().zip(src.chunks_exact(3)) {
                *p = (c[0] as u32) << 16 | (c[1] as u32) << 8 | c[2] as u32;
            }
        } else {
            for (x, p) in row.iter_mut().enumerate() {
                let sx = (x * iw / w).min(iw - 1);
                let c = &src[3 * sx..3 * sx + 3];
                *p = (c[0] as u32) << 16 | (c[1] as u32) << 8 | c[2] as u32;
            }
        }
    }
}

impl ApplicationHandler<Wake> for App {
    fn resumed(&mut self, el: &ActiveEventLoop) {
        if self.window.is_some() {
            return;
        }
        let (w, h) = self
            .shown
            .as_ref()
            .or(self
                .session
                .as_ref()
                .and_then(|s| s.frames().latest())
                .as_ref())
            .map_or((1280, 720), |f| (f.image.width, f.image.height));
        let attrs = Window::default_attributes()
            .with_title(self.options.title.clone())
            .with_inner_size(PhysicalSize::new(w, h));
        let opened = el
            .create_window(attrs)
            .map_err(|e| e.to_string())
            .and_then(|win| {
                let win = Rc::new(win);
                let ctx = softbuffer::Context::new(win.clone()).map_err(|e| e.to_string())?;
                let surface =
                    softbuffer::Surface::new(&ctx, win.clone()).map_err(|e| e.to_string())?;
                Ok((win, surface))
            });
        match opened {
            Ok((win, surface)) => {
                win.request_redraw();
                self.window = Some(win);
                self.surface = Some(surface);
                self.start_waker();
            }
            Err(e) => {
                self.error = Some(format!("cannot open a window: {e}"));
                el.exit();
            }
        }
    }

    fn user_event(&mut self, el: &ActiveEventLoop, wake: Wake) {
        match wake {
            Wake::Frame => {
                if let Some(w) = &self.window {
                    w.request_redraw();
                }
            }
            Wake::Ended => el.exit(),
        }
    }

    fn window_event(&mut self, el: &ActiveEventLoop, _id: WindowId, event: WindowEvent) {
        let commands = match event {
            WindowEvent::CloseRequested => {
                el.exit();
                return;
            }
            WindowEvent::RedrawRequested => {
                if let Err(e) = self.present() {
                    self.error = Some(e);
                    el.exit();
                }
                return;
            }
            WindowEvent::Resized(s) => self.input.resized(s.width, s.height),
            WindowEvent::ModifiersChanged(m) => {
                let st = m.state();
                self.input.modifiers(st.shift_key(), st.control_key());
                return;
            }
            WindowEvent::CursorMoved { position, .. } => {
                self.input.moved(position.x as f32, position.y as f32)
            }
            WindowEvent::CursorLeft { .. } => self.input.left(),
            WindowEvent::MouseInput { state, button, .. } => {
                let b = match button {
                    MouseButton::Left => Button::Left,
                    MouseButton::Right => Button::Right,
                    MouseButton::Middle => Button::Middle,
                    _ => return,
                };
                match state {
                    ElementState::Pressed => self.input.press(b),
                    ElementState::Released => self.input.release(b),
                }
            }
            WindowEvent::MouseWheel { delta, .. } => self.input.wheel(match delta {
                MouseScrollDelta::LineDelta(_, y) => y,
                MouseScrollDelta::PixelDelta(p) => p.y as f32 / 40.0,
            }),
            WindowEvent::KeyboardInput { event, .. } if event.state == ElementState::Pressed => {
                let k = match &event.logical_key {
                    WKey::Named(NamedKey::Space) => Key::Space,
                    WKey::Named(NamedKey::Escape) => Key::Escape,
                    WKey::Named(NamedKey::Home) => Key::Home,
                    WKey::Character(s) => match s.chars().next() {
                        Some(c) => Key::Char(c.to_ascii_lowercase()),
                        None => return,
                    },
                    _ => return,
                };
                // Held keys repeat only for stepping.
                if event.repeat && k != Key::Char('s') && k != Key::Char('.') {
                    return;
                }
                self.input.key(k)
            }
            _ => return,
        };
        self.send(commands, el);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rtmpm_render::Image;

    #[test]
    fn pictures_become_0rgb_pixels_scaled_to_the_window() {
        let mut img = Image::new(2, 2, [0, 0, 0]);
        img.rgb[..3].copy_from_slice(&[255, 128, 1]);
        img.rgb[9..].copy_from_slice(&[1, 2, 3]);
        let mut same = vec![0u32; 4];
        blit(&img, &mut same, 2, 2);
        assert_eq!(same, vec![0xff8001, 0, 0, 0x010203]);
        let mut big = vec![0u32; 16];
        blit(&img, &mut big, 4, 4);
        assert_eq!(big[0], 0xff8001);
        assert_eq!(big[1], 0xff8001);
        assert_eq!(big[15], 0x010203);
        assert_eq!(big[2], 0);
    }
}
