//! The `[render]` table of a scene: the pictures' camera, size and colouring.

use rtmpm_physics::math::Vec3;
use std::fmt;
use std::str::FromStr;

/// Optional `[render]` settings; `None` fields fall back to command-line flags or defaults.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct RenderSettings {
    /// Camera position (m).
    pub camera: Option<Vec3>,
    /// Point looked at (m).
    pub target: Option<Vec3>,
    /// Vertical field of view (degrees).
    pub fov: Option<f32>,
    /// Image width (pixels).
    pub width: Option<u32>,
    /// Image height (pixels).
    pub height: Option<u32>,
    /// Colouring.
    pub color_by: Option<ColorBy>,
}

/// What decides a particle's colour.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum ColorBy {
    /// A fixed colour per material (see `rtmpm_render::colormap::PALETTE`).
    #[default]
    Material,
    /// Speed `|v|` (m/s).
    Speed,
    /// Volume ratio `J = det F`.
    J,
    /// Von Mises equivalent of the Cauchy stress (Pa).
    Stress,
    /// The material's scalar plastic state.
    Plastic,
}

impl ColorBy {
    /// All choices, in the order of [`ColorBy::name`].
    pub const ALL: [ColorBy; 5] = [
        ColorBy::Material,
        ColorBy::Speed,
        ColorBy::J,
        ColorBy::Stress,
        ColorBy::Plastic,
    ];

    /// The name used on the command line and in scene files.
    pub fn name(self) -> &'static str {
        match self {
            ColorBy::Material => "material",
            ColorBy::Speed => "speed",
            ColorBy::J => "J",
            ColorBy::Stress => "stress",
            ColorBy::Plastic => "plastic",
        }
    }

    /// Title of the colour bar.
    pub fn label(self) -> &'static str {
        match self {
            ColorBy::Material => "MATERIAL",
            ColorBy::Speed => "SPEED (M/S)",
            ColorBy::J => "J = DET F",
            ColorBy::Stress => "VON MISES (PA)",
            ColorBy::Plastic => "PLASTIC",
        }
    }
}

impl fmt::Display for ColorBy {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for ColorBy {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        ColorBy::ALL
            .into_iter()
            .find(|c| c.name() == s || (s == "j" && *c == ColorBy::J))
            .ok_or_else(|| {
                format!("unknown colouring `{s}`: use material, speed, J, stress or plastic")
            })
    }
}
