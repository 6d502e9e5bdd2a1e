//! The browser stream's protocol: what a client sends (JSON text messages, one command
//! each) and what the server sends back (JSON text messages: hello, role, status, error; and
//! binary messages: one JPEG picture each, after the status it goes with).
//!
//! Client to server, e.g. `{"cmd": "pause"}`, `{"cmd": "orbit", "dx": 12, "dy": -3}`,
//! `{"cmd": "tool_start", "x": 640, "y": 360}`, `{"cmd": "throw", "x": 640, "y": 300,
//! "material": "water"}`, `{"cmd": "gravity", "value": [0, -9.81, 0]}`: see
//! [`ClientMessage`]. Pixel coordinates are in the streamed picture (x right, y down). Every
//! number must be finite and in its range; a message that is not one of these is answered
//! with an error and changes nothing.

use crate::command::{Command, Pace, Throw};
use glam::Vec3;
use rtmpm_geometry::ToolShape;
use rtmpm_scene::ColorBy;
use serde::Deserialize;

/// Largest message a client may send (bytes); a larger one closes its connection.
pub const MAX_MESSAGE_BYTES: usize = 4096;

/// Largest mouse motion in one message (pixels).
const MAX_MOTION: f32 = 1e5;
/// Largest gravity (m/s^2), tool or ball size (m) and throwing speed (m/s) taken.
const MAX_GRAVITY: f32 = 1e4;
const MAX_SIZE: f32 = 1e4;
const MAX_SPEED: f32 = 1e5;

/// A message from a client.
/// (Commands without arguments are written as empty structs so that unknown fields are
/// refused for them too.)
#[derive(Debug, Deserialize, PartialEq)]
#[serde(tag = "cmd", rename_all = "snake_case", deny_unknown_fields)]
pub enum ClientMessage {
    Pause {},
    Resume {},
    TogglePause {},
    Step {},
    Reset {},
    Slower {},
    Faster {},
    /// Steps or frames per displayed frame: `{"cmd": "pace", "steps": 4}` or `"frames": 2`.
    Pace {
        steps: Option<u32>,
        frames: Option<u32>,
    },
    /// `value`: material, speed, J, stress or plastic.
    ColorBy {
        value: String,
    },
    CycleColor {},
    Orbit {
        dx: f32,
        dy: f32,
    },
    Pan {
        dx: f32,
        dy: f32,
    },
    /// Multiply the camera's distance by `factor` (0.01 to 100; < 1: closer).
    Zoom {
        factor: f32,
    },
    CameraReset {},
    Resize {
        width: u32,
        height: u32,
    },
    ToolStart {
        x: f32,
        y: f32,
    },
    ToolMove {
        x: f32,
        y: f32,
    },
    /// Push the held tool deeper (`factor` > 1) or nearer (< 1), 0.5 to 2 per message.
    ToolDepth {
        factor: f32,
    },
    ToolEnd {},
    /// `shape`: "sphere" (size: radius) or "box" (size: half the side), in metres.
    ToolShape {
        shape: String,
        size: f32,
    },
    /// A ball through pixel (x, y); material by name (default: the first), radius (m) and
    /// speed (m/s) optional.
    Throw {
        x: f32,
        y: f32,
        material: Option<String>,
        radius: Option<f32>,
        speed: Option<f32>,
    },
    /// Gravity (m/s^2).
    Gravity {
        value: [f32; 3],
    },
}

fn finite(what: &str, values: &[f32], max: f32) -> Result<(), String> {
    match values.iter().find(|v| !(v.is_finite() && v.abs() <= max)) {
        Some(v) => Err(format!(
            "{what} must be finite numbers of at most {max:e} in size, got {v}"
        )),
        None => Ok(()),
    }
}

fn positive(what: &str, v: f32, max: f32) -> Result<f32, String> {
    if v.is_finite() && v > 0.0 && v <= max {
        Ok(v)
    } else {
        Err(format!(
            "{what} must be positive and at most {max:e}, got {v}"
        ))
    }
}

/// The command a client's text message asks for. `materials` are the scene's material names
/// (a thrown ball names one), `max_size` the largest picture the server streams.
pub fn parse(text: &str, materials: &[String], max_size: (u32, u32)) -> Result<Command, String> {
    let m: ClientMessage = serde_json::from_str(text).map_err(|e| {
        format!(
            "cannot read the message ({e}): send one JSON object with a \"cmd\", such as \
             {{\"cmd\": \"pause\"}} (docs/viewer.md lists them)"
        )
    })?;
    command(m, materials, max_size)
}

fn command(
    m: ClientMessage,
    materials: &[String],
    max_size: (u32, u32),
) -> Result<Command, String> {
    use ClientMessage as M;
    Ok(match m {
        M::Pause {} => Command::Pause,
        M::Resume {} => Command::Resume,
        M::TogglePause {} => Command::TogglePause,
        M::Step {} => Command::Step,
        M::Reset {} => Command::Reset,
        M::Slower {} => Command::Slower,
        M::Faster {} => Command::Faster,
        M::Pace { steps, frames } => Command::SetPace(pace(steps, frames)?),
        M::ColorBy { value } => Command::ColorBy(value.parse::<ColorBy>()?),
        M::CycleColor {} => Command::CycleColor,
        M::Orbit { dx, dy } => {
            finite("orbit dx, dy", &[dx, dy], MAX_MOTION)?;
            Command::Orbit { dx, dy }
        }
        M::Pan { dx, dy } => {
            finite("pan dx, dy", &[dx, dy], MAX_MOTION)?;
            Command::Pan { dx, dy }
        }
        M::Zoom { factor } => {
            if !(factor.is_finite() && (0.01..=100.0).contains(&factor)) {
                return Err(format!("zoom factor must be in 0.01 to 100, got {factor}"));
            }
            Command::Zoom(factor)
        }
        M::CameraReset {} => Command::CameraReset,
        M::Resize { width, height } => {
            if !(16..=max_size.0).contains(&width) || !(16..=max_size.1).contains(&height) {
                return Err(format!(
                    "size {width}x{height} is out of range: 16x16 to {}x{}",
                    max_size.0, max_size.1
                ));
            }
            Command::Resize { width, height }
        }
        M::ToolStart { x, y } => {
            finite("tool x, y", &[x, y], MAX_MOTION)?;
            Command::ToolStart { x, y }
        }
        M::ToolMove { x, y } => {
            finite("tool x, y", &[x, y], MAX_MOTION)?;
            Command::ToolMove { x, y }
        }
        M::ToolDepth { factor } => {
            if !(factor.is_finite() && (0.5..=2.0).contains(&factor)) {
                return Err(format!(
                    "tool depth factor must be in 0.5 to 2, got {factor}"
                ));
            }
            Command::ToolDepth(factor)
        }
        M::ToolEnd {} => Command::ToolEnd,
        M::ToolShape { shape, size } => {
            let size = positive("tool size", size, MAX_SIZE)?;
            Command::ToolShape(match shape.as_str() {
                "sphere" => ToolShape::Sphere { radius: size },
                "box" => ToolShape::Box {
                    half: Vec3::splat(size),
                },
                s => {
                    return Err(format!(
                        "unknown tool shape `{s}`: use \"sphere\" or \"box\""
                    ));
                }
            })
        }
        M::Throw {
            x,
            y,
            material,
            radius,
            speed,
        } => {
            finite("throw x, y", &[x, y], MAX_MOTION)?;
            let material = match material {
                None => None,
                Some(name) => Some(materials.iter().position(|m| *m == name).ok_or_else(|| {
                    format!(
                        "no material `{name}` in this scene: {}",
                        materials.join(", ")
                    )
                })?),
            };
            Command::Throw(Throw {
                x,
                y,
                material,
                radius: radius
                    .map(|r| positive("ball radius", r, MAX_SIZE))
                    .transpose()?,
                speed: speed
                    .map(|s| positive("ball speed", s, MAX_SPEED))
                    .transpose()?,
            })
        }
        M::Gravity { value } => {
            finite("gravity", &value, MAX_GRAVITY)?;
            Command::Gravity(Vec3::from_array(value))
        }
    })
}

fn pace(steps: Option<u32>, frames: Option<u32>) -> Result<Pace, String> {
    let max = crate::command::MAX_PACE;
    match (steps, frames) {
        (Some(n), None) if (1..=max).contains(&n) => Ok(Pace::Steps(n)),
        (None, Some(k)) if (1..=max).contains(&k) => Ok(Pace::Frames(k)),
        _ => Err(format!(
            "pace takes one of \"steps\" or \"frames\", 1 to {max}: e.g. {{\"cmd\": \"pace\", \
             \"frames\": 1}}"
        )),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn p(text: &str) -> Result<Command, String> {
        parse(text, &["sand".into(), "water".into()], (1920, 1080))
    }

    #[test]
    fn every_command_reads_as_documented() {
        assert_eq!(p(r#"{"cmd":"pause"}"#), Ok(Command::Pause));
        assert_eq!(p(r#"{"cmd":"step"}"#), Ok(Command::Step));
        assert_eq!(p(r#"{"cmd":"reset"}"#), Ok(Command::Reset));
        assert_eq!(
            p(r#"{"cmd":"pace","frames":2}"#),
            Ok(Command::SetPace(Pace::Frames(2)))
        );
        assert_eq!(
            p(r#"{"cmd":"color_by","value":"speed"}"#),
            Ok(Command::ColorBy(ColorBy::Speed))
        );
        assert_eq!(
            p(r#"{"cmd":"orbit","dx":3,"dy":-4.5}"#),
            Ok(Command::Orbit { dx: 3.0, dy: -4.5 })
        );
        assert_eq!(p(r#"{"cmd":"zoom","factor":0.9}"#), Ok(Command::Zoom(0.9)));
        assert_eq!(
            p(r#"{"cmd":"resize","width":640,"height":360}"#),
            Ok(Command::Resize {
                width: 640,
                height: 360
            })
        );
        assert_eq!(
            p(r#"{"cmd":"tool_shape","shape":"box","size":0.1}"#),
            Ok(Command::ToolShape(ToolShape::Box {
                half: Vec3::splat(0.1)
            }))
        );
        assert_eq!(
            p(r#"{"cmd":"throw","x":1,"y":2,"material":"water","speed":3}"#),
            Ok(Command::Throw(Throw {
                x: 1.0,
                y: 2.0,
                material: Some(1),
                radius: None,
                speed: Some(3.0)
            }))
        );
        assert_eq!(
            p(r#"{"cmd":"gravity","value":[0,-9.81,0]}"#),
            Ok(Command::Gravity(Vec3::new(0.0, -9.81, 0.0)))
        );
    }

    #[test]
    fn garbage_and_out_of_range_values_are_refused_with_the_reason() {
        for (text, says) in [
            ("", "cannot read"),
            ("not json", "cannot read"),
            ("[1,2,3]", "cannot read"),
            (r#"{"cmd":"explode"}"#, "cannot read"),
            (r#"{"cmd":"pause","extra":1}"#, "cannot read"),
            (r#"{"cmd":"orbit","dx":"a","dy":1}"#, "cannot read"),
            (r#"{"cmd":"orbit","dx":1e300,"dy":1}"#, "finite"),
            (r#"{"cmd":"zoom","factor":0}"#, "zoom"),
            (
                r#"{"cmd":"resize","width":100000,"height":10}"#,
                "out of range",
            ),
            (r#"{"cmd":"resize","width":-5,"height":10}"#, "cannot read"),
            (
                r#"{"cmd":"color_by","value":"rainbow"}"#,
                "unknown colouring",
            ),
            (
                r#"{"cmd":"tool_shape","shape":"cone","size":1}"#,
                "unknown tool shape",
            ),
            (
                r#"{"cmd":"tool_shape","shape":"sphere","size":-1}"#,
                "positive",
            ),
            (r#"{"cmd":"tool_depth","factor":50}"#, "depth"),
            (
                r#"{"cmd":"throw","x":1,"y":2,"material":"lava"}"#,
                "sand, water",
            ),
            (r#"{"cmd":"throw","x":1,"y":2,"radius":0}"#, "positive"),
            (r#"{"cmd":"gravity","value":[0,1e9,0]}"#, "gravity"),
            (r#"{"cmd":"gravity","value":[0,1]}"#, "cannot read"),
            (r#"{"cmd":"pace","steps":0}"#, "pace"),
            (r#"{"cmd":"pace","steps":2,"frames":2}"#, "pace"),
        ] {
            let e = p(text).expect_err(text);
            assert!(e.contains(says), "{text}: {e}");
        }
    }
}
